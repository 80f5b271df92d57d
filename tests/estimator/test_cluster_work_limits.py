"""An integer backend stopped by its own deterministic work limit (a node limit, say)
leaves the cluster ``bounded`` with the backend's proven bound, never ``time_limit``:
only the wall clock makes a result depend on the machine's speed."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from support import brute_force_tables, random_problem

from mapassoc.estimator.cluster_solving import ClusterSolver
from mapassoc.formulations.packing import set_packing_program
from mapassoc.formulations.program import Program
from mapassoc.solvers import HighsSolver, SolveResult, SolveStatus

TOLERANCE = 1e-9
SLACK = 0.25
"""How far above the optimum the stub's proven bound lies."""


class WorkLimitedSolver:
    """HiGHS whose every feasible integer solve reports WORK_LIMIT: the optimum as the
    incumbent (or no incumbent) and the optimum + :data:`SLACK` as the proven bound."""

    name = "work-limited"
    supports_integer = True
    supports_flow = False
    supports_relaxation = False
    exact = False

    def __init__(self, *, keep_incumbent: bool) -> None:
        self.keep_incumbent = keep_incumbent
        self.solved: dict[int, float] = {}  # k -> the bound reported

    def solve(self, program: Program, *, time_limit: float | None = None) -> SolveResult:
        result = HighsSolver().solve(program, time_limit=time_limit)
        if result.status is not SolveStatus.OPTIMAL:
            return result
        bound = result.objective + SLACK
        self.solved[int(round(program.b_eq[-1]))] = bound
        if self.keep_incumbent:
            return replace(result, status=SolveStatus.WORK_LIMIT, bound=bound)
        return replace(
            result, status=SolveStatus.WORK_LIMIT, bound=bound, solution=None, objective=math.nan
        )


SEEDS = range(40)
"""Enough problems for the integer path to run: most LP optima over k are integral, and
an integral optimum needs no integer solve."""


@pytest.mark.parametrize("keep_incumbent", [True, False])
@pytest.mark.parametrize("seed", SEEDS)
def test_work_limited_integer_solves_leave_the_cluster_bounded(
    seed: int, keep_incumbent: bool
) -> None:
    rng = np.random.default_rng(700 + seed)
    problem = random_problem(rng, int(rng.integers(8, 16)), D=int(rng.integers(3, 7)), G=2)
    kmax = 8
    exact_best, exact_mass = brute_force_tables(problem, kmax)
    integer = WorkLimitedSolver(keep_incumbent=keep_incumbent)
    solver = ClusterSolver(
        solver=integer,
        lp_solver=HighsSolver(),
        exact_work_limit=1,
        beam_width=1,
        prune_log_ratio=math.inf,
    )
    table, report = solver.solve(problem, kmax, deadline=math.inf)
    assert report.status == "bounded"
    n = table.best.shape[0]
    assert np.all(table.best <= exact_best[:n] + TOLERANCE)
    assert np.all(exact_best[:n] <= table.best_upper + TOLERANCE)
    assert np.all(table.log_mass <= exact_mass[:n] + TOLERANCE)
    assert np.all(exact_mass[:n] <= table.log_mass_upper + TOLERANCE)
    for k, bound in integer.solved.items():
        # The backend's bound is used: never above it, and it is proven.
        assert table.best_upper[k] <= bound + TOLERANCE
        if keep_incumbent:
            assert table.best[k] == pytest.approx(exact_best[k], abs=TOLERANCE)


def test_work_limited_solves_are_exercised() -> None:
    """The beam of width 1 misses the LP bound, at a fractional LP optimum, often enough
    that integer solves run."""
    solved = 0
    for seed in SEEDS:
        rng = np.random.default_rng(700 + seed)
        problem = random_problem(rng, int(rng.integers(8, 16)), D=int(rng.integers(3, 7)), G=2)
        integer = WorkLimitedSolver(keep_incumbent=False)
        ClusterSolver(
            solver=integer,
            lp_solver=HighsSolver(),
            exact_work_limit=1,
            beam_width=1,
            prune_log_ratio=math.inf,
        ).solve(problem, 8, deadline=math.inf)
        solved += len(integer.solved)
    assert solved >= 12


def test_program_cardinality_row_is_the_last_equality() -> None:
    """What the stub reads k from: the last row of A_eq counts the tracks, b_eq is k."""
    rng = np.random.default_rng(0)
    problem = random_problem(rng, 10, D=4, G=2)
    program = set_packing_program(problem, 3)
    assert program.b_eq[-1] == 3.0
    np.testing.assert_array_equal(
        program.A_eq.toarray()[-1], problem.counts.astype(float)
    )
