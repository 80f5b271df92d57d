"""The one window solver (``ClusterSolver``): its settings, its K-free best set under a
deadline, and the refinement's account of its statuses."""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import pytest
from support import brute_force_tables, random_problem

from mapassoc.data.settings import SearchSettings
from mapassoc.errors import InputError
from mapassoc.estimator.cluster_solving import (
    CLUSTER_STATUSES,
    ClusterSolver,
    ClusterStatus,
    count_multiplier_grid,
    uncounted,
)
from mapassoc.estimator.objective import RecordingObjective, paths_from_rows
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.refinement import RefinementSettings, Refiner
from mapassoc.evaluation.scenarios import build_scenario


def test_the_search_settings_configure_every_path_of_the_window_solver() -> None:
    search = SearchSettings(
        beam_entry_margin=7.5, mass_bound_multiplier_limit=3.0, mass_bound_multipliers=4
    )
    solver = ClusterSolver.from_settings(search)
    assert solver.beam_entry_margin == 7.5
    np.testing.assert_allclose(solver.count_multipliers, [-3.0, -1.0, 1.0, 3.0])
    bounded = solver._bounded_search()
    assert bounded.beam_entry_margin == 7.5
    np.testing.assert_allclose(bounded.count_multipliers, [-3.0, -1.0, 1.0, 3.0])
    for n in range(1, 8):  # symmetric about 0 at every size
        grid = count_multiplier_grid(dataclasses.replace(search, mass_bound_multipliers=n))
        assert grid.size == n
        np.testing.assert_allclose(np.sort(-grid), grid, atol=1e-12)
        assert np.all(np.abs(grid) <= 3.0)


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("beam_entry_margin", 0.0),
        ("beam_entry_margin", -1.0),
        ("mass_bound_multiplier_limit", 0.0),
        ("mass_bound_multipliers", 0),
    ],
)
def test_the_search_settings_reject_a_bad_tuning_naming_its_key(key: str, value: float) -> None:
    with pytest.raises(InputError) as error:
        SearchSettings(**{key: value})  # type: ignore[arg-type]
    assert error.value.key == key


@pytest.mark.parametrize("seed", range(10))
def test_a_best_set_after_its_deadline_is_exact_only_where_it_is_the_best(seed: int) -> None:
    """With the deadline already passed, the solver either still proves its answer (and
    then it is the enumerated best) or says ``time_limit``, never ``bounded``: the
    clock, not a deterministic limit, cut it short.  A set it returns is feasible."""
    rng = np.random.default_rng(700 + seed)
    H = int(rng.integers(13, 17))  # past the frontier search's small clusters
    problem = random_problem(rng, H, int(rng.integers(H // 2, H + 1)), 0)
    solver = ClusterSolver.from_settings(SearchSettings())
    solved = solver.best_set(problem, time.perf_counter() - 1.0)
    assert solved.status in (ClusterStatus.EXACT, ClusterStatus.TIME_LIMIT)
    best, _ = brute_force_tables(uncounted(problem), 0)
    if solved.selection is not None:
        assert problem.is_feasible(solved.selection)
    if solved.status is ClusterStatus.EXACT:
        assert solved.selection is not None
        assert problem.value(solved.selection) == pytest.approx(best[0], abs=1e-9)


def _refined(program_time_limit: float) -> tuple[Refiner, object]:
    scenario = build_scenario("converging", seed=0)
    scans = scenario.scans[25:40]
    config = scenario.config
    est = dataclasses.replace(config.estimator, refine_passes=0, time_limit=600.0)
    # (the flat ``time_limit`` sets the re-solves' limit too: this one after it)
    est = dataclasses.replace(
        est, search=dataclasses.replace(est.search, program_time_limit=program_time_limit)
    )
    config = dataclasses.replace(config, estimator=est)
    forward = WindowEstimator(config=config).run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    paths = paths_from_rows(objective, forward.track_rows)
    refiner = Refiner(config=config, scans=scans, settings=RefinementSettings(passes=3))
    return refiner, refiner.refine(paths)[1]


@pytest.mark.parametrize("limit", [2.0, 1e-9])
def test_the_refinement_counts_every_resolve_by_its_window_solves_status(limit: float) -> None:
    refiner, report = _refined(limit)
    assert refiner.time_limit == limit
    counts = report.status_counts  # type: ignore[attr-defined]
    assert set(counts) == {status.value for status in CLUSTER_STATUSES}
    assert sum(counts.values()) == report.windows_solved > 0  # type: ignore[attr-defined]
    assert counts["time_limit"] == report.windows_time_limited  # type: ignore[attr-defined]
    assert report.to_json(timings=False)["window_statuses"] == counts  # type: ignore[attr-defined]
    # Whatever the deadline did, a move is taken only where the exact J rises.
    history = [report.objective_forward, *report.objective_after_pass]  # type: ignore[attr-defined]
    assert all(b >= a - 1e-9 for a, b in zip(history, history[1:], strict=False))
    assert math.isfinite(history[-1])
