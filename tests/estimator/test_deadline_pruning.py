"""A cluster left unpruned because the deadline had passed makes the window `time_limit`.

The LP-bound pruning changes which hypotheses a cluster's mass sums; skipping it for the
clock makes the answer depend on the machine's speed even where every cluster is then
solved exactly, so the status must say so.
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from mapassoc.estimator.pipeline import WindowEstimator, WindowSolution, WindowStatus
from mapassoc.evaluation.scenarios import build_scenario


def _window(time_limit: float) -> WindowSolution:
    scenario = build_scenario("scale20", 0)  # a first window with clusters of ~500
    settings = replace(scenario.config.estimator, time_limit=time_limit)
    estimator = WindowEstimator(config=replace(scenario.config, estimator=settings))
    return estimator.solve_window(scenario.scans[: settings.window_length])


@pytest.mark.clock_dependent
def test_pruning_skipped_for_the_clock_is_time_limit() -> None:
    window = _window(1e-9)  # the deadline has passed before the first cluster
    assert window.pruning_cut_short
    assert window.status is WindowStatus.TIME_LIMIT


def test_without_a_clock_nothing_is_cut_short() -> None:
    window = _window(600.0)
    assert window.bound_pruned > 0  # the pruning ran on this window
    assert not window.pruning_cut_short
    assert window.status is not WindowStatus.TIME_LIMIT
