"""Clusters too large for the exact search: certified bounds, the beam, the time limit.

Every approximation path is checked against the exact frontier search (itself checked
against brute force in ``test_cardinality``): a claimed bound must hold, and a best
score reported as optimal (``best == best_upper``) must be the exact one.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import replace

import numpy as np
import pytest
from support import (
    NO_TIME_LIMIT,
    brute_force_tables,
    make_config,
    random_problem,
    random_window,
)

from mapassoc.estimator.cluster_solving import ClusterSolver, best_set_by_fixing
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.formulations.bounds import (
    fixed_variable_bounds,
    greedy_packing,
    log_mass_upper_bounds,
)
from mapassoc.formulations.cardinality import exact_cardinality_table
from mapassoc.formulations.frontier import frontier_search
from mapassoc.formulations.packing import PackingProblem, resource_multipliers, set_packing_program
from mapassoc.models.motion import ConstantVelocity
from mapassoc.solvers import HighsSolver, SolveStatus, enumerate_feasible

TOLERANCE = 1e-9


def with_settings(estimator: WindowEstimator, **changes: object) -> WindowEstimator:
    config = estimator.config
    return WindowEstimator(config=replace(config, estimator=replace(config.estimator, **changes)))


def cluster_solver(beam_width: int = 4) -> ClusterSolver:
    return ClusterSolver(
        solver=HighsSolver(),
        lp_solver=HighsSolver(),
        exact_work_limit=1,
        beam_width=beam_width,
        prune_log_ratio=math.inf,
    )


def assert_bounds_hold(table, exact_best, exact_mass) -> None:  # type: ignore[no-untyped-def]
    n = table.best.shape[0]
    best, mass = exact_best[:n], exact_mass[:n]
    assert np.all(np.isneginf(exact_best[n:])), "a feasible k past the table's end"
    assert np.all(table.best <= best + TOLERANCE)
    assert np.all(best <= table.best_upper + TOLERANCE)
    assert np.all(table.log_mass <= mass + TOLERANCE)
    assert np.all(mass <= table.log_mass_upper + TOLERANCE)
    certified = table.best >= table.best_upper
    np.testing.assert_allclose(table.best[certified], best[certified], atol=TOLERANCE)
    for k in range(n):
        chosen = table.best_sets[k]
        if chosen is not None:
            assert math.isfinite(table.best[k])


@pytest.mark.parametrize("seed", range(40))
def test_bounded_path_bounds_hold_against_brute_force(seed: int) -> None:
    rng = np.random.default_rng(700 + seed)
    problem = random_problem(rng, int(rng.integers(6, 14)), D=int(rng.integers(3, 7)), G=2)
    kmax = int(rng.integers(1, 8))
    best, mass = brute_force_tables(problem, kmax)
    table, report = cluster_solver().solve(problem, kmax, deadline=math.inf)
    assert report.status in ("bounded", "exact")
    assert_bounds_hold(table, best, mass)
    assert report.log_captured <= TOLERANCE
    # Far from the deadline, every k within the margin of the best set is optimal.
    top = float(np.max(table.best))
    near = table.best_upper >= top - 30.0
    assert np.all(table.best[near] >= table.best_upper[near])


@pytest.mark.clock_dependent
@pytest.mark.parametrize("seed", range(20))
def test_time_limited_cluster_still_gives_valid_bounds(seed: int) -> None:
    """A deadline already past: no LP runs, a narrow beam and the LP-free mass bound."""
    rng = np.random.default_rng(900 + seed)
    problem = random_problem(rng, int(rng.integers(6, 14)), D=int(rng.integers(3, 7)), G=2)
    best, mass = brute_force_tables(problem, 6)
    table, report = cluster_solver().solve(problem, 6, deadline=time.perf_counter() - 1.0)
    assert report.status == "time_limit"
    assert report.solves == 0
    assert_bounds_hold(table, best, mass)


@pytest.mark.parametrize("seed", range(20))
def test_beam_sums_distinct_feasible_sets(seed: int) -> None:
    rng = np.random.default_rng(1100 + seed)
    problem = random_problem(rng, int(rng.integers(6, 14)), D=int(rng.integers(3, 7)), G=2)
    best, mass = brute_force_tables(problem, 8)
    for width in (1, 3, 10**6):
        beam = frontier_search(problem, 8, max_frontiers=width)
        n = beam.best.shape[0]
        assert np.all(beam.log_mass <= mass[:n] + TOLERANCE)
        assert np.all(beam.best <= best[:n] + TOLERANCE)
        for k, chosen in enumerate(beam.best_sets):
            if chosen is not None:
                assert problem.is_feasible(np.array(chosen, dtype=np.int64), k)
                value = problem.value(np.array(chosen, dtype=np.int64))
                assert value == pytest.approx(beam.best[k])
        if beam.exact:
            np.testing.assert_allclose(beam.log_mass, mass[:n], atol=TOLERANCE)


@pytest.mark.parametrize("seed", range(30))
def test_mass_upper_bound_holds_for_any_multipliers(seed: int) -> None:
    rng = np.random.default_rng(1300 + seed)
    problem = random_problem(rng, int(rng.integers(3, 12)), D=int(rng.integers(2, 6)), G=2)
    _, mass = brute_force_tables(problem, problem.num_hypotheses)
    ks = np.arange(mass.shape[0])
    for _ in range(5):
        y = rng.normal(0.0, 2.0, size=problem.num_resources)
        mu = float(rng.normal(0.0, 2.0))
        bound = log_mass_upper_bounds(problem, y, mu, ks)
        assert np.all(mass <= bound + TOLERANCE)


def test_mass_upper_bound_is_exact_for_one_exclusive_group() -> None:
    """Three hypotheses sharing one detection: sets are {} or one of them, no slack."""
    from mapassoc.formulations.packing import PackingProblem

    scores = np.array([0.3, -1.0, 2.0])
    problem = PackingProblem(
        scores, np.array([0, 1, 2, 3]), np.zeros(3, dtype=np.int64), np.zeros(1, bool),
        np.ones(3, bool),
    )
    bound = log_mass_upper_bounds(problem, np.zeros(1), 0.0, np.array([0]))
    assert bound[0] == pytest.approx(math.log(1 + np.exp(scores).sum()))


@pytest.mark.parametrize("seed", range(25))
def test_forced_bounded_windows_bound_the_exact_posterior(seed: int) -> None:
    """Whole windows with every multi-hypothesis cluster forced onto the bounded path."""
    case = random_window(seed)
    exact = case.estimator.solve_window(case.scans, case.carried)
    forced = with_settings(case.estimator, exact_work_limit=1, beam_width=2)
    bounded = forced.solve_window(case.scans, case.carried)
    assert bounded.status in ("exact", "capped", "bounded")
    table, post = bounded.table, bounded.posterior
    assert np.all(table.best <= exact.table.best + TOLERANCE)
    assert np.all(exact.table.best <= table.best_upper + TOLERANCE)
    assert np.all(table.log_mass <= exact.table.log_mass + TOLERANCE)
    assert np.all(exact.table.log_mass <= table.log_mass_upper + TOLERANCE)
    p = exact.posterior.probabilities
    assert np.all(post.probabilities_lower <= p + 1e-9)
    assert np.all(p <= post.probabilities_upper + 1e-9)
    if post.marginal_certain:
        assert post.marginal_k == exact.posterior.marginal_k
    if post.joint_certain:
        assert post.joint_map_k == exact.posterior.joint_map_k
    assert 0.0 < bounded.captured_mass <= 1.0
    if bounded.bounded_clusters and not post.exact:
        assert bounded.status == "bounded"


def test_bounded_path_is_exercised_by_the_random_windows() -> None:
    used = 0
    for seed in range(25):
        case = random_window(seed)
        forced = with_settings(case.estimator, exact_work_limit=1, beam_width=2)
        used += bool(forced.solve_window(case.scans, case.carried).bounded_clusters)
    assert used >= 10


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
    solver = ClusterSolver(
        solver=HighsSolver(),
        lp_solver=HighsSolver(),
        exact_work_limit=10**8,
        beam_width=1,
        prune_log_ratio=config.estimator.prune_log_ratio,
        bound_prune_min_hypotheses=30,
    )
    keep = solver.bound_prune(problem, deadline=math.inf)
    assert keep is not None, "nothing pruned: the test would check nothing"
    full = exact_cardinality_table(problem, 12, work_limit=10**8)
    kept = problem.subproblem(np.flatnonzero(keep))
    pruned = exact_cardinality_table(kept, 12, work_limit=10**8)
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


@pytest.mark.parametrize("seed", range(30))
def test_greedy_packing_gives_a_feasible_set(seed: int) -> None:
    rng = np.random.default_rng(500 + seed)
    problem = random_problem(rng, int(rng.integers(3, 16)), D=int(rng.integers(2, 7)), G=2)
    chosen = greedy_packing(problem, rng.random(problem.num_hypotheses))
    # Every exactly-one group of random_problem has a member that uses no detection,
    # so the greedy order always covers it.
    assert chosen is not None
    assert problem.is_feasible(chosen)
    # Nothing is left out that could be added: every other hypothesis with a positive
    # score clashes with the set.
    owner = np.repeat(np.arange(problem.num_hypotheses), np.diff(problem.resource_indptr))
    taken = set(problem.resource_indices[np.isin(owner, chosen)].tolist())
    for h in np.setdiff1d(np.flatnonzero(problem.scores > 0), chosen):
        assert taken & set(problem.resources_of(h).tolist())


def test_greedy_packing_says_none_when_it_misses_an_exactly_once_resource() -> None:
    # h0 takes detection 0 first; h1, the only user of the exactly-once resource 1,
    # also needs detection 0.
    problem = PackingProblem(
        scores=np.array([5.0, 1.0]),
        resource_indptr=np.array([0, 1, 3]),
        resource_indices=np.array([0, 0, 1]),
        exactly_one=np.array([False, True]),
        counts=np.ones(2, dtype=bool),
    )
    assert greedy_packing(problem, np.array([1.0, 0.0])) is None
    assert greedy_packing(problem, np.array([0.0, 1.0])).tolist() == [1]  # type: ignore[union-attr]
    with pytest.raises(ValueError, match="priority"):
        greedy_packing(problem, np.array([np.nan, 0.0]))


def _fixing_prunes(problem: PackingProblem) -> bool:
    """Whether best_set_by_fixing's reduced-cost step drops a hypothesis of ``problem``
    (its LP relaxation is fractional and some bound is below the greedy incumbent)."""
    program = set_packing_program(problem, None)
    lp = HighsSolver().solve_relaxation(program)
    x = lp.solution
    if lp.status is not SolveStatus.OPTIMAL or np.all(np.abs(x - np.round(x)) <= 1e-9):
        return False
    incumbent = greedy_packing(problem, x)
    if incumbent is None:
        return False
    bounds = fixed_variable_bounds(program, lp.ineq_duals, lp.eq_duals)
    return bool(np.any(bounds < np.sum(problem.scores[incumbent]) - 1e-6))


@pytest.mark.parametrize("seed", range(40))
def test_best_set_by_fixing_is_the_brute_force_best(seed: int) -> None:
    rng = np.random.default_rng(900 + seed)
    problem = random_problem(rng, int(rng.integers(6, 15)), D=int(rng.integers(3, 7)), G=2)
    chosen, optimal = best_set_by_fixing(
        problem, solver=HighsSolver(), lp_solver=HighsSolver(), time_limit=None
    )
    best, _ = brute_force_tables(problem, problem.num_hypotheses)
    assert optimal and chosen is not None
    assert problem.is_feasible(chosen)
    assert float(np.sum(problem.scores[chosen])) == pytest.approx(np.max(best), abs=1e-7)


def test_best_set_by_fixing_is_exercised_by_the_random_problems() -> None:
    fractional = sum(
        _fixing_prunes(
            random_problem(
                rng := np.random.default_rng(900 + seed),
                int(rng.integers(6, 15)),
                D=int(rng.integers(3, 7)),
                G=2,
            )
        )
        for seed in range(40)
    )
    assert fractional >= 3


def test_best_set_by_fixing_reports_an_infeasible_problem() -> None:
    # Both exactly-once resources 1 and 2 must be covered, but their only users, h0 and
    # h1, share detection 0.
    problem = PackingProblem(
        scores=np.array([1.0, 1.0]),
        resource_indptr=np.array([0, 2, 4]),
        resource_indices=np.array([0, 1, 0, 2]),
        exactly_one=np.array([False, True, True]),
        counts=np.ones(2, dtype=bool),
    )
    chosen, optimal = best_set_by_fixing(
        problem, solver=HighsSolver(), lp_solver=HighsSolver(), time_limit=None
    )
    assert chosen is None and optimal


def test_frontier_search_has_no_recursion_limit() -> None:
    """A chain of 5,000 hypotheses, each sharing a detection with the next."""
    from mapassoc.formulations.packing import PackingProblem

    n = 5000
    pairs = [[i, i + 1] for i in range(n)]
    problem = PackingProblem(
        np.full(n, 0.5), np.arange(0, 2 * n + 1, 2), np.array(list(itertools.chain(*pairs))),
        np.zeros(n + 1, bool), np.ones(n, bool),
    )
    table = exact_cardinality_table(problem, 3)
    # Best with k chosen: any k non-adjacent links, score 0.5 k.
    np.testing.assert_allclose(table.best, [0.0, 0.5, 1.0, 1.5])


@pytest.mark.clock_dependent
@pytest.mark.parametrize("seed", range(15))
def test_window_past_its_time_limit_says_so_and_keeps_valid_bounds(seed: int) -> None:
    """A time limit of a nanosecond has passed before any cluster is solved (the
    generation alone takes longer), so the outcome does not depend on the machine; a
    work limit of one transition sends every multi-hypothesis cluster to the path that
    the deadline cuts short."""
    case = random_window(seed)
    exact = case.estimator.solve_window(case.scans, case.carried)
    limited = with_settings(case.estimator, time_limit=1e-9, exact_work_limit=1).solve_window(
        case.scans, case.carried
    )
    assert limited.timed_out
    assert all(c.status in ("time_limit", "exact") for c in limited.bounded_clusters)
    if limited.bounded_clusters:
        assert limited.status == "time_limit"
    table = limited.table
    assert np.all(table.best <= exact.table.best + TOLERANCE)
    assert np.all(exact.table.best <= table.best_upper + TOLERANCE)
    assert np.all(table.log_mass <= exact.table.log_mass + TOLERANCE)
    assert np.all(exact.table.log_mass <= table.log_mass_upper + TOLERANCE)
    p = exact.posterior.probabilities
    assert np.all(limited.posterior.probabilities_lower <= p + 1e-9)
    assert np.all(p <= limited.posterior.probabilities_upper + 1e-9)
    # The chosen K always has a feasible set to commit.
    assert limited.table.best_set(limited.posterior.marginal_k) is not None


@pytest.mark.clock_dependent
def test_time_limit_path_is_exercised() -> None:
    statuses = []
    for seed in range(15):
        case = random_window(seed)
        limited = with_settings(case.estimator, time_limit=1e-9, exact_work_limit=1)
        statuses.append(limited.solve_window(case.scans, case.carried).status)
    assert statuses.count("time_limit") >= 5


@pytest.mark.clock_dependent
def test_a_window_that_only_ran_long_keeps_its_exact_status() -> None:
    """Past the limit but every cluster solved exactly (they are small): not time_limit."""
    case = random_window(0)
    exact = case.estimator.solve_window(case.scans, case.carried)
    late = with_settings(case.estimator, time_limit=1e-9).solve_window(case.scans, case.carried)
    assert late.timed_out
    assert not late.bounded_clusters  # its clusters are all small enough to finish
    assert late.status == exact.status
    np.testing.assert_allclose(late.table.log_mass, exact.table.log_mass, atol=1e-12)


@pytest.mark.parametrize("seed", range(30))
def test_relaxed_problem_bounds_every_k(seed: int) -> None:
    """Dropping some constraints and pricing them by any multipliers >= 0 bounds both the
    best score and the log-mass of every k from above."""
    from mapassoc.formulations.bounds import relaxed_problem

    rng = np.random.default_rng(1500 + seed)
    problem = random_problem(rng, int(rng.integers(4, 12)), D=int(rng.integers(2, 6)), G=2)
    kmax = problem.num_hypotheses
    best, mass = brute_force_tables(problem, kmax)
    for _ in range(4):
        relax = (rng.random(problem.num_resources) < 0.5) & ~problem.exactly_one
        y = np.abs(rng.normal(0.0, 2.0, size=problem.num_resources))
        relaxed, constant = relaxed_problem(problem, relax, y)
        table = exact_cardinality_table(relaxed, kmax)
        assert np.all(best <= table.best + constant + TOLERANCE)
        assert np.all(mass <= table.log_mass + constant + TOLERANCE)
    with pytest.raises(ValueError, match="exactly-once"):
        relaxed_problem(problem, problem.exactly_one.copy(), np.zeros(problem.num_resources))


def test_bounded_window_lines_carry_their_bounds() -> None:
    """Windows forced onto the bounded path write p_k and best-objective bounds that
    contain the exact window's values."""
    checked: list[int] = []
    for seed in range(10):
        case = random_window(seed)
        exact = case.estimator.solve_window(case.scans, case.carried)
        forced = with_settings(
            case.estimator, exact_work_limit=1, beam_width=1, time_limit=NO_TIME_LIMIT
        )
        bounded = forced.solve_window(case.scans, case.carried)
        if bounded.posterior.exact:
            continue
        checked.append(seed)
        p = exact.posterior.probabilities
        assert np.all(bounded.posterior.probabilities_lower <= p + 1e-9)
        assert np.all(p <= bounded.posterior.probabilities_upper + 1e-9)
        assert np.all(exact.table.best <= bounded.table.best_upper + TOLERANCE)
    assert len(checked) >= 3, "too few windows took the bounded path"
    # And a run's JSON lines carry the bounds.
    from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario

    scenario = truncate_scenario(build_scenario("crossing", 0), 8)
    estimator = WindowEstimator(config=scenario.config)
    run = with_settings(
        estimator, exact_work_limit=1, beam_width=1, time_limit=NO_TIME_LIMIT
    ).run(scenario.scans)
    lines = [w.to_json(timings=False) for w in run.windows if not w.marginal_exact]
    assert lines and all("p_k_lower" in line and "p_k_upper" in line for line in lines)
    for w in run.windows:
        line = w.to_json(timings=False)
        if np.any(w.best_objective_upper > w.best_objective):
            assert len(line["best_objective_upper"]) == len(w.best_objective)  # type: ignore[arg-type]


def test_resource_multipliers_follow_the_programs_row_layout() -> None:
    # Resources: 0 and 2 at most once and used, 1 unused, 3 exactly once.
    problem = PackingProblem(
        scores=np.array([1.0, 2.0, 0.5]),
        resource_indptr=np.array([0, 2, 3, 4]),
        resource_indices=np.array([0, 3, 2, 3]),
        exactly_one=np.array([False, False, False, True]),
        counts=np.ones(3, dtype=bool),
    )
    program = set_packing_program(problem, 2)
    assert program.A_ub.shape[0] == 2 and program.A_eq.shape[0] == 2  # {0, 2}; {3, count}
    y, mu = resource_multipliers(problem, np.array([0.7, 0.2]), np.array([-1.5, 3.0]))
    assert y.tolist() == [0.7, 0.0, 0.2, -1.5] and mu == 3.0
    free = set_packing_program(problem, None)
    assert free.A_eq.shape[0] == 1
    y, mu = resource_multipliers(problem, np.array([0.7, 0.2]), np.array([-1.5]))
    assert y.tolist() == [0.7, 0.0, 0.2, -1.5] and mu == 0.0
