"""The benchmark's T-GOSPA fields: what evaluate_tables gives for the estimate and the oracle."""

from __future__ import annotations

import json
from dataclasses import asdict, replace

import pytest

from mapassoc.apps.bench import GOSPA_CUTOFF, bench_scenario
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import build_scenario, generic_config, truncate_scenario
from mapassoc.evaluation.tables import evaluate_tables


def test_a_bench_run_reports_tgospa_of_the_estimate_and_the_oracle() -> None:
    run = bench_scenario("crossing", 0, 5, time_limit=5.0, scans=12)
    assert run.tgospa is not None and run.oracle_tgospa is not None
    assert run.tgospa >= 0.0 and run.oracle_tgospa > 0.0
    assert run.fragments_per_target is not None and run.fragments_per_target >= 1.0
    assert run.tgospa_id_switches is not None and run.tgospa_id_switches >= 0
    scenario = truncate_scenario(build_scenario("crossing", 0), 12)
    oracle = evaluate_tables(
        scenario.truth,
        oracle_tracks(scenario.scans, scenario.origins, scenario.config),
        c=GOSPA_CUTOFF,
        switch_cost=GOSPA_CUTOFF,
    )
    assert oracle.tgospa is not None
    assert run.oracle_tgospa == pytest.approx(oracle.tgospa.total, rel=1e-12)
    config = generic_config(scenario, window_length=5, time_limit=5.0)
    config = replace(config, estimator=replace(config.estimator, k_prior="birth"))
    tracks = WindowEstimator(config=config).run(scenario.scans).tracks
    mine = evaluate_tables(scenario.truth, tracks, c=GOSPA_CUTOFF, switch_cost=GOSPA_CUTOFF)
    assert mine.tgospa is not None
    assert run.tgospa == pytest.approx(mine.tgospa.total, rel=1e-9)
    row = json.loads(json.dumps(asdict(run), allow_nan=False))
    assert row["tgospa"] == pytest.approx(run.tgospa)
