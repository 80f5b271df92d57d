"""windows.jsonl: every key is the name of the WindowReport field it comes from."""

from __future__ import annotations

import dataclasses

from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario


def test_json_keys_are_field_names_and_only_optional_ones_are_left_out() -> None:
    scenario = truncate_scenario(build_scenario("crossing", 0), 8)
    result = WindowEstimator(config=scenario.config).run(scenario.scans)
    fields = {f.name for f in dataclasses.fields(result.windows[0])}
    optional = {"p_k_lower", "p_k_upper", "best_objective_upper"}
    timing = {"over_time_limit", "generate_seconds", "solve_seconds"}
    for report in result.windows:
        with_timings = set(report.to_json(timings=True))
        assert with_timings <= fields
        assert fields - with_timings <= optional
        assert set(report.to_json(timings=False)) == with_timings - timing
