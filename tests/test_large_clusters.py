"""Paths for clusters too large to enumerate exactly: the solver fallback, LP-bound pruning."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from test_cardinality import random_problem
from test_window_model import make_config, random_window

from mapassoc.formulations.bounds import fixed_variable_bounds
from mapassoc.formulations.cardinality import exact_cardinality_table
from mapassoc.formulations.packing import set_packing_program
from mapassoc.motion import ConstantVelocity
from mapassoc.pipeline import WindowEstimator
from mapassoc.solvers import HighsSolver, SolveStatus, enumerate_feasible


def with_settings(estimator: WindowEstimator, **changes: object) -> WindowEstimator:
    config = estimator.config
    return WindowEstimator(config=replace(config, estimator=replace(config.estimator, **changes)))


def test_solver_fallback_with_enough_sets_is_exact() -> None:
    """Forced to the integer-program path, with m large enough to list every set.

    Listing a set costs one MILP solve, so the check runs on the first 15 random windows
    with at most 150 feasible sets (of the packing program with K free).
    """
    checked = 0
    seed = 0
    while checked < 15:
        case = random_window(seed)
        seed += 1
        exact = case.estimator.solve_window(case.scans, case.carried)
        program = set_packing_program(exact.problem, None)
        if sum(1 for _ in zip(range(151), enumerate_feasible(program), strict=False)) > 150:
            continue
        checked += 1
        forced = with_settings(case.estimator, exact_node_limit=1, m_best=10_000)
        fallback = forced.solve_window(case.scans, case.carried)
        multi = [s for s in exact.cluster_sizes if s > 1]
        # Clusters of interchangeable hypotheses merge to one and never need the solver.
        assert len(fallback.solver_clusters) <= len(multi)
        assert np.array_equal(np.isneginf(fallback.table.best), np.isneginf(exact.table.best))
        finite = np.isfinite(exact.table.best)
        np.testing.assert_allclose(fallback.table.best[finite], exact.table.best[finite], atol=1e-9)
        np.testing.assert_allclose(
            fallback.table.log_mass[finite], exact.table.log_mass[finite], atol=1e-9
        )
        assert fallback.posterior.exact and fallback.captured_mass == 1.0
        assert fallback.status in ("exact", "optimal")
    assert seed < 200, "too few small random windows"


def test_fallback_is_exercised_by_the_random_windows() -> None:
    used = 0
    for seed in range(30):
        case = random_window(seed)
        forced = with_settings(case.estimator, exact_node_limit=1, m_best=2)
        used += bool(forced.solve_window(case.scans, case.carried).solver_clusters)
    assert used >= 15


@pytest.mark.parametrize("seed", range(30))
def test_solver_fallback_with_few_sets_bounds_the_mass(seed: int) -> None:
    """With m = 2 the MAP per K is still exact; the mass is a lower bound, flagged as such."""
    case = random_window(seed)
    exact = case.estimator.solve_window(case.scans, case.carried)
    fallback = with_settings(case.estimator, exact_node_limit=1, m_best=2).solve_window(
        case.scans, case.carried
    )
    finite = np.isfinite(exact.table.best)
    np.testing.assert_allclose(fallback.table.best[finite], exact.table.best[finite], atol=1e-9)
    assert np.all(fallback.table.log_mass[finite] <= exact.table.log_mass[finite] + 1e-9)
    assert 0.0 <= fallback.captured_mass <= 1.0
    if not fallback.posterior.exact:
        assert fallback.captured_mass < 1.0
    else:
        np.testing.assert_allclose(
            fallback.table.log_mass[finite], exact.table.log_mass[finite], atol=1e-9
        )


@pytest.mark.parametrize("seed", range(40))
def test_fixed_variable_bounds_hold_for_every_feasible_set(seed: int) -> None:
    rng = np.random.default_rng(seed)
    problem = random_problem(rng, int(rng.integers(3, 12)), D=int(rng.integers(2, 7)), G=2)
    program = set_packing_program(problem, None)
    lp = HighsSolver().solve_relaxation(program)
    assert lp.status is SolveStatus.OPTIMAL
    bounds = fixed_variable_bounds(program, lp.ineq_duals, lp.eq_duals)
    # With the optimal duals, the bound of an LP-optimal variable is the LP optimum.
    assert np.max(bounds) == pytest.approx(lp.objective, abs=1e-7)
    for x in enumerate_feasible(program):
        value = program.value(x)
        for h in np.flatnonzero(x > 0.5):
            assert value <= bounds[h] + 1e-7


@pytest.mark.parametrize("seed", range(10))
def test_bound_pruning_keeps_the_best_set(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    problem = random_problem(rng, 36, D=14, G=2)
    config = make_config(
        motion=ConstantVelocity(ndim=1, noise_intensity=1.0),
        noise_std=1.0,
        detection_probability=0.9,
        false_alarms_per_scan=1.0,
        region=[[-10.0, 10.0]],
        prune_log_ratio=2.0,
        max_tracks=12,
    )
    estimator = WindowEstimator(config=config)
    keep = estimator._bound_prune(problem)
    full = exact_cardinality_table(problem, 12, node_limit=10**6)
    if keep is None:
        return
    kept = problem.subproblem(np.flatnonzero(keep))
    pruned = exact_cardinality_table(kept, 12, node_limit=10**6)
    assert np.max(pruned.best) == pytest.approx(np.max(full.best), abs=1e-9)
    assert np.all(pruned.best <= full.best + 1e-9)
    # Every dropped hypothesis is in no set within the ratio of the best.
    best_all = float(np.max(full.best))
    for h in np.flatnonzero(~keep):
        program = set_packing_program(problem, None)
        forced = program.with_constraints(A_eq=np.eye(problem.num_hypotheses)[[h]], b_eq=np.ones(1))
        result = HighsSolver().solve(forced)
        assert result.status is SolveStatus.INFEASIBLE or result.objective < best_all - 2.0 + 1e-9
    assert math.isfinite(best_all)
