"""Shared fixtures: scenario runs computed once per test session; the clock guard.

Markers: ``slow`` marks the tests that take a second or more each (full scenario runs,
calibration over hundreds of windows).  A plain ``pytest`` skips them (``addopts`` in
``pyproject.toml``); ``make test`` and CI run everything (``-m ""``), slow tests first
and on every core (pytest-xdist).

``clock_dependent`` marks the tests that exercise ``EstimatorSettings.time_limit``
itself.  Every other test fails if, while it ran, a window ran past its time limit
(``WindowSolution.timed_out``) or a cluster ended with status ``time_limit``
(:func:`pytest_runtest_makereport`): what such a window returns depends on how fast
the machine is, so a test that compares its numbers would pass on one machine and fail
on another.  Such a test gives its estimator a time limit no window reaches
(``support.NO_TIME_LIMIT``), so that only the deterministic work limits
(``exact_work_limit``, ``beam_width``, ``max_hypotheses_per_tree``) bound the work.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, replace

import pytest
from support import NO_TIME_LIMIT

from mapassoc.estimator.cluster_solving import ClusterSolver, ClusterStatus
from mapassoc.estimator.pipeline import EstimateResult, WindowEstimator
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.evaluation.simulate import Scenario
from mapassoc.evaluation.tables import evaluate_tables

GOSPA_CUTOFF = 10.0

_CLOCK_EVENTS: list[str] = []
"""What the wall clock changed since the last test's check (filled by the wrappers that
:func:`pytest_configure` installs, emptied by :func:`pytest_runtest_makereport`)."""


def _guard_solve_window(original: Callable) -> Callable:  # type: ignore[type-arg]
    @functools.wraps(original)
    def solve_window(self, scans, *args, **kwargs):  # type: ignore[no-untyped-def]
        solution = original(self, scans, *args, **kwargs)
        if solution.timed_out:
            _CLOCK_EVENTS.append(
                f"a window of {len(scans)} scans from t = {scans[0].time:g} ran past its "
                f"time_limit of {self.settings.time_limit:g} s (status {solution.status})"
            )
        return solution

    return solve_window


def _guard_cluster_solve(original: Callable) -> Callable:  # type: ignore[type-arg]
    @functools.wraps(original)
    def solve(self, problem, kmax, deadline):  # type: ignore[no-untyped-def]
        table, report = original(self, problem, kmax, deadline)
        if report.status is ClusterStatus.TIME_LIMIT:
            _CLOCK_EVENTS.append(
                f"a cluster of {report.size} hypotheses ended with status time_limit"
            )
        return table, report

    return solve


def pytest_configure(config: pytest.Config) -> None:
    """Wrap the two seams where the wall clock can change a result:
    :meth:`WindowEstimator.solve_window` (the window's deadline) and
    :meth:`ClusterSolver.solve` (for tests that call it with a deadline of their own).

    The wrappers only record; :func:`pytest_runtest_makereport` fails the test.  They
    are installed once per test process (every xdist worker loads this file), before any
    fixture runs, so scenario runs computed in session fixtures are watched too.
    Windows solved in other processes (process pools, Dask) are not: the tests that use
    them give those runs a time limit no window reaches.
    """
    WindowEstimator.solve_window = _guard_solve_window(WindowEstimator.solve_window)
    ClusterSolver.solve = _guard_cluster_solve(ClusterSolver.solve)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Slow tests first, each group in its collected order: under pytest-xdist
    (``make test`` runs ``-n auto``) the long ones then start early on every worker
    instead of one of them trailing alone at the end of the run."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


_SETUP_EVENTS = pytest.StashKey[list[str]]()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):  # type: ignore[no-untyped-def]
    """The clock guard: a test during which (its fixtures included) the wall clock
    changed a result fails, unless it is marked ``clock_dependent``."""
    outcome = yield
    report = outcome.get_result()
    events = list(_CLOCK_EVENTS)
    _CLOCK_EVENTS.clear()
    if call.when == "setup":
        item.stash[_SETUP_EVENTS] = events  # judged with the test's own call
        return
    if call.when == "call":
        events = item.stash.get(_SETUP_EVENTS, []) + events
    if not events or not report.passed or item.get_closest_marker("clock_dependent"):
        return
    events = list(dict.fromkeys(events))
    shown = "\n  ".join(events[:10])
    more = f"\n  ... and {len(events) - 10} more" if len(events) > 10 else ""
    report.outcome = "failed"
    report.longrepr = (
        "the wall clock changed what this test computed, so its result depends on the "
        f"machine's speed:\n  {shown}{more}\nGive the estimator a time limit no window "
        f"reaches (time_limit = support.NO_TIME_LIMIT = {NO_TIME_LIMIT:g} s) and let the "
        "deterministic work limits bound the work, or mark the test clock_dependent if it "
        "tests the time limit itself and asserts only what holds whatever the clock did"
    )


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
    settings = replace(config.estimator, time_limit=NO_TIME_LIMIT)
    if window_length is not None:
        settings = replace(settings, window_length=window_length)
    config = replace(config, estimator=settings)
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
