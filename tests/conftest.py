"""Shared fixtures: scenario runs computed once per test session.

Markers: ``slow`` marks the tests that take a second or more each (full scenario runs,
calibration over hundreds of windows).  A plain ``pytest`` skips them (``addopts`` in
``pyproject.toml``); ``make test`` and CI run everything (``-m ""``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, replace

import pytest

from mapassoc.estimator.pipeline import EstimateResult, WindowEstimator
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.evaluation.simulate import Scenario
from mapassoc.evaluation.tables import evaluate_tables

GOSPA_CUTOFF = 10.0


@dataclass(frozen=True)
class ScenarioRun:
    """A built-in scenario estimated with its own configuration, and its GOSPA."""

    scenario: Scenario
    result: EstimateResult
    estimate: dict
    oracle: dict

    @property
    def gospa_ratio(self) -> float:
        return self.estimate.gospa.mean_total / self.oracle.gospa.mean_total


@functools.cache
def _run(name: str, seed: int, window_length: int | None) -> ScenarioRun:
    scenario = build_scenario(name, seed)
    config = scenario.config
    if window_length is not None:
        config = replace(config, estimator=replace(config.estimator, window_length=window_length))
    result = WindowEstimator(config=config).run(scenario.scans)
    estimate = evaluate_tables(scenario.truth, result.tracks, c=GOSPA_CUTOFF)
    oracle = evaluate_tables(
        scenario.truth,
        oracle_tracks(scenario.scans, scenario.origins, scenario.config),
        c=GOSPA_CUTOFF,
    )
    return ScenarioRun(scenario, result, estimate, oracle)


@pytest.fixture(scope="session")
def scenario_run() -> Callable[..., ScenarioRun]:
    """``scenario_run(name, seed=0, window_length=None)``: the run, computed once."""

    def run(name: str, seed: int = 0, window_length: int | None = None) -> ScenarioRun:
        return _run(name, seed, window_length)

    return run
