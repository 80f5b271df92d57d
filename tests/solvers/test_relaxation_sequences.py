"""LP relaxations solved again with other equality right-hand sides.

* HiGHS's warm-started sequence and the cold fallback give, at every k of a walk over
  the cardinality row (down from the middle, then up, as the cluster solver walks),
  the status and optimum of a relaxation solved from scratch, with optimal duals;
* the caller may reuse (mutate) its right-hand-side array between solves;
* bad right-hand sides are rejected naming ``b_eq``; a program without variables has
  its known answer;
* building the first HiGHS instance prints nothing on standard output.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
import scipy.sparse as sp
from support import random_problem

from mapassoc.formulations.packing import set_packing_program
from mapassoc.formulations.program import Program, lagrangian_bound
from mapassoc.solvers import (
    ColdRelaxationSequence,
    HighsSolver,
    LPResult,
    SolveStatus,
    relaxation_sequence,
)


class _FreshOnly:
    """A relaxation backend without ``relaxation_sequence`` (so it gets the fallback)."""

    name = "fresh-only"
    supports_integer = True
    supports_flow = False
    supports_relaxation = True
    exact = True

    def __init__(self) -> None:
        self.inner = HighsSolver()

    def solve(self, program: Program, *, time_limit: float | None = None):  # type: ignore[no-untyped-def]
        return self.inner.solve(program, time_limit=time_limit)

    def solve_relaxation(self, program: Program, *, time_limit: float | None = None) -> LPResult:
        return self.inner.solve_relaxation(program, time_limit=time_limit)


def _walk(top: int, start: int) -> list[int]:
    return list(range(start, -1, -1)) + list(range(start + 1, top + 1))


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("backend", ["highs", "fallback"])
def test_a_walk_over_k_matches_solves_from_scratch(seed: int, backend: str) -> None:
    rng = np.random.default_rng(seed)
    problem = random_problem(rng, int(rng.integers(8, 30)), D=int(rng.integers(3, 8)), G=3)
    top = int(np.count_nonzero(problem.counts)) + 1  # one k past every set: infeasible
    start = int(rng.integers(0, top))
    solver = HighsSolver() if backend == "highs" else _FreshOnly()
    lps = relaxation_sequence(solver, set_packing_program(problem, start))
    assert isinstance(lps, ColdRelaxationSequence) == (backend == "fallback")
    rhs = np.array(lps.program.b_eq, dtype=float)  # reused, as the cluster solver does
    for k in _walk(top, start):
        rhs[-1] = k
        warm = lps.solve(rhs)
        program = set_packing_program(problem, k)
        fresh = HighsSolver().solve_relaxation(program)
        assert warm.status is fresh.status, k
        if fresh.status is not SolveStatus.OPTIMAL:
            assert warm.solution is None and warm.ineq_duals is None
            continue
        assert warm.objective == pytest.approx(fresh.objective, abs=1e-9)
        assert warm.bound == warm.objective
        assert warm.solution is not None and program.relaxed().is_feasible(warm.solution)
        assert program.value(warm.solution) == pytest.approx(warm.objective, abs=1e-9)
        assert warm.ineq_duals is not None and warm.eq_duals is not None
        assert np.all(warm.ineq_duals >= -1e-9)
        # Optimal duals: their Lagrangian bound is the optimum (strong duality).
        bound = lagrangian_bound(program, warm.ineq_duals, warm.eq_duals)
        assert bound == pytest.approx(fresh.objective, abs=1e-7)


def test_the_warm_walk_takes_few_simplex_iterations_per_k() -> None:
    """What the sequence is for: each later solve starts from the last basis (checked
    on HiGHS's own iteration count, not on the clock)."""
    problem = random_problem(np.random.default_rng(5), 60, D=25, G=3)
    top = int(np.count_nonzero(problem.counts))
    lps = HighsSolver().relaxation_sequence(set_packing_program(problem, top // 2))
    rhs = np.array(lps.program.b_eq, dtype=float)
    iterations = []
    for k in _walk(top, top // 2):
        rhs[-1] = k
        assert lps.solve(rhs).status in (SolveStatus.OPTIMAL, SolveStatus.INFEASIBLE)
        iterations.append(int(lps._model().getInfo().simplex_iteration_count))
    first = iterations[0]
    assert first > 0
    assert np.median(iterations[1:]) < first


def test_bad_right_hand_sides_are_rejected_naming_b_eq() -> None:
    problem = random_problem(np.random.default_rng(0), 10, D=4, G=2)
    for lps in (
        HighsSolver().relaxation_sequence(set_packing_program(problem, 2)),
        ColdRelaxationSequence(_FreshOnly(), set_packing_program(problem, 2)),  # type: ignore[arg-type]
    ):
        q = lps.program.b_eq.shape[0]
        with pytest.raises(ValueError, match=r"b_eq must have shape"):
            lps.solve(np.ones(q + 1))
        bad = np.ones(q)
        bad[-1] = np.nan
        with pytest.raises(ValueError, match=r"b_eq must be finite"):
            lps.solve(bad)
    with pytest.raises(TypeError, match="program must be a Program"):
        relaxation_sequence(HighsSolver(), "not a program")  # type: ignore[arg-type]


def test_a_program_without_variables_has_its_known_answer() -> None:
    empty = Program(
        objective=np.zeros(0),
        A_ub=sp.csr_array((1, 0)),
        b_ub=np.array([1.0]),
        A_eq=sp.csr_array((1, 0)),
        b_eq=np.array([0.0]),
        lower=np.zeros(0),
        upper=np.zeros(0),
        integrality=np.zeros(0, dtype=bool),
        constant=2.5,
    )
    lps = HighsSolver().relaxation_sequence(empty)
    result = lps.solve()
    assert result.status is SolveStatus.OPTIMAL and result.objective == 2.5
    assert result.ineq_duals is not None and result.ineq_duals.shape == (1,)
    assert lps.solve(np.array([1.0])).status is SolveStatus.INFEASIBLE  # 0 == 1 fails
    assert lps.solve(np.array([0.0])).status is SolveStatus.OPTIMAL


def test_the_first_highs_instance_prints_nothing_on_standard_output() -> None:
    script = textwrap.dedent(
        """
        import numpy as np, scipy.sparse as sp
        from mapassoc.formulations.program import Program
        from mapassoc.solvers import HighsSolver
        program = Program(
            objective=np.array([1.0, 2.0]), A_ub=sp.csr_array(np.ones((1, 2))),
            b_ub=np.array([1.0]), A_eq=sp.csr_array((0, 2)), b_eq=np.zeros(0),
            lower=np.zeros(2), upper=np.ones(2), integrality=np.zeros(2, dtype=bool))
        print("value", HighsSolver().solve_relaxation(program).objective)
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "value 2.0"
