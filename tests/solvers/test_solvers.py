"""Tests of mapassoc.solvers: every backend against the exact enumerator and against each other.

Oracles: brute force over ``itertools.product`` for the enumerator; the enumerator for HiGHS,
cvxpy-HiGHS and k-best; HiGHS solving the flow LP for the networkx flow solver; hand-derived
values for the small cases.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from mapassoc.formulations.program import FlowProgram, Program
from mapassoc.solvers import (
    SOLVER_NAMES,
    CvxpySolver,
    EnumerationResult,
    EnumerationSolver,
    FlowResult,
    HighsSolver,
    LPResult,
    NetworkxFlowSolver,
    SolverError,
    SolveResult,
    SolveStatus,
    available_solvers,
    enumerate_feasible,
    get_solver,
    lagrangian_bound,
    no_good_cut,
    solve_k_best,
)

HIGHS = HighsSolver()
ENUMERATOR = EnumerationSolver()
CLARABEL = CvxpySolver(backend="CLARABEL")
CVXPY_HIGHS = CvxpySolver(backend="HIGHS")
NUM_RANDOM_PROGRAMS = 120


# ----------------------------------------------------------------------------------------------
# Program builders
# ----------------------------------------------------------------------------------------------


def make_program(
    objective: list[float] | np.ndarray,
    *,
    A_ub: list[list[float]] | np.ndarray | None = None,
    b_ub: list[float] | np.ndarray | None = None,
    A_eq: list[list[float]] | np.ndarray | None = None,
    b_eq: list[float] | np.ndarray | None = None,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
    integer: bool = True,
    constant: float = 0.0,
) -> Program:
    """A program from dense lists; binary by default."""
    c = np.asarray(objective, dtype=float)
    n = c.shape[0]

    def block(A: object, b: object) -> tuple[sp.csr_array, np.ndarray]:
        if A is None:
            return sp.csr_array((0, n)), np.zeros(0)
        return sp.csr_array(np.asarray(A, dtype=float).reshape(len(b), n)), np.asarray(b, float)

    A_ub_s, b_ub_a = block(A_ub, b_ub)
    A_eq_s, b_eq_a = block(A_eq, b_eq)
    return Program(
        objective=c,
        A_ub=A_ub_s,
        b_ub=b_ub_a,
        A_eq=A_eq_s,
        b_eq=b_eq_a,
        lower=np.zeros(n) if lower is None else lower,
        upper=np.ones(n) if upper is None else upper,
        integrality=np.full(n, integer),
        constant=constant,
    )


def random_set_packing(seed: int, *, general: bool = False) -> Program:
    """A small binary set-packing program like the window programs.

    Rows "each element used at most once" (0/1 coefficients, rhs 1), one or two "exactly
    one of group" equality rows, a cardinality row ``Σ x == K``, objectives of both signs.
    With ``general`` the coefficients and right-hand sides are arbitrary reals instead and
    some variables are fixed by their bounds.
    """
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 13))
    num_elements = int(rng.integers(2, 7))
    cover = (rng.random((num_elements, n)) < 0.3).astype(float)
    b_ub = np.ones(num_elements)
    groups = []
    for _ in range(int(rng.integers(1, 3))):
        members = rng.choice(n, size=int(rng.integers(2, 4)), replace=False)
        row = np.zeros(n)
        row[members] = 1.0
        groups.append(row)
    cardinality = np.ones((1, n))
    A_eq = np.vstack([*groups, cardinality])
    b_eq = np.concatenate([np.ones(len(groups)), [float(rng.integers(0, 5))]])
    lower, upper = np.zeros(n), np.ones(n)
    if general:
        cover = np.round(rng.normal(0.0, 1.5, size=(num_elements, n)), 2) * (
            rng.random((num_elements, n)) < 0.6
        )
        b_ub = np.round(rng.normal(0.5, 1.5, size=num_elements), 2)
        A_eq = A_eq[:1] * np.round(rng.uniform(0.5, 2.0, size=n), 1)
        b_eq = np.array([float(A_eq[0, : int(rng.integers(0, 4))].sum())])
        fixed = rng.choice(n, size=2, replace=False)
        lower[fixed[0]] = 1.0
        upper[fixed[1]] = 0.0
    objective = rng.normal(0.0, 2.0, size=n)
    return make_program(
        objective, A_ub=cover, b_ub=b_ub, A_eq=A_eq, b_eq=b_eq, lower=lower, upper=upper,
        constant=float(rng.normal()),
    )


def brute_force(program: Program) -> list[tuple[tuple[int, ...], float]]:
    """Every feasible 0/1 point in lexicographic order with its value (the definition)."""
    points = []
    for candidate in itertools.product((0, 1), repeat=program.num_variables):
        x = np.array(candidate, dtype=float)
        if program.is_feasible(x, tol=1e-9):
            points.append((candidate, program.value(x)))
    return points


# ----------------------------------------------------------------------------------------------
# HiGHS vs the enumerator on random set packing; LP relaxations bound the optimum
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(NUM_RANDOM_PROGRAMS))
def test_highs_matches_enumerator_on_random_set_packing(seed: int) -> None:
    program = random_set_packing(seed)
    exact = ENUMERATOR.solve(program)
    highs = HIGHS.solve(program)
    assert highs.status is exact.status
    if exact.status is SolveStatus.INFEASIBLE:
        assert highs.solution is None and math.isnan(highs.objective)
        return
    assert exact.status is SolveStatus.OPTIMAL
    assert highs.objective == pytest.approx(exact.objective, abs=1e-9)
    for result in (exact, highs):
        assert program.is_feasible(result.solution)
        assert program.value(result.solution) == pytest.approx(result.objective, abs=1e-12)
        assert set(np.unique(result.solution)) <= {0.0, 1.0}
    assert highs.bound >= exact.objective - 1e-9
    assert exact.bound == exact.objective

    lp = HIGHS.solve(program.relaxed())
    assert lp.status is SolveStatus.OPTIMAL
    assert lp.objective >= exact.objective - 1e-9
    assert lp.bound == pytest.approx(lp.objective, abs=1e-9)
    if seed % 4 == 0:  # interior point and cvxpy are slower: a quarter of the programs
        clarabel = CLARABEL.solve(program.relaxed())
        assert clarabel.status is SolveStatus.OPTIMAL
        assert clarabel.objective == pytest.approx(lp.objective, abs=1e-6)
        assert clarabel.bound >= lp.objective - 1e-9  # a Lagrangian bound is rigorous
        assert clarabel.bound == pytest.approx(lp.objective, abs=1e-6)
        via_cvxpy = CVXPY_HIGHS.solve(program)
        assert via_cvxpy.status is SolveStatus.OPTIMAL
        assert via_cvxpy.objective == pytest.approx(exact.objective, abs=1e-9)
        assert program.is_feasible(via_cvxpy.solution)


@pytest.mark.parametrize("seed", range(0, NUM_RANDOM_PROGRAMS, 3))
def test_relaxation_first_agrees_with_branch_and_bound(seed: int) -> None:
    """The integral-relaxation shortcut changes nothing but the time: same status and
    optimum as HiGHS's branch and bound alone, on programs whose LP is integral and on
    those where it is fractional (which fall through to milp)."""
    for program in (random_set_packing(seed), independent_set_program(seed, n=12)):
        plain = HighsSolver(relaxation_first=False).solve(program)
        first = HIGHS.solve(program)
        assert first.status is plain.status
        if plain.status is SolveStatus.OPTIMAL:
            assert first.objective == pytest.approx(plain.objective, abs=1e-9)
            assert program.is_feasible(first.solution)
            assert first.bound >= first.objective - 1e-12


def test_relaxation_first_takes_an_integral_lp_and_not_a_fractional_one() -> None:
    # Two disjoint pairs: the LP optimum is the integral point (1, 0, 0, 1).
    pairs = make_program([2.0, 1.0, 1.0, 3.0], A_ub=[[1, 1, 0, 0], [0, 0, 1, 1]], b_ub=[1, 1])
    result = HIGHS.solve(pairs)
    assert result.status is SolveStatus.OPTIMAL and list(result.solution) == [1, 0, 0, 1]
    assert "relaxation" in result.message and result.bound == pytest.approx(5.0)
    # A triangle of conflicts with unit weights: the LP takes 1/2 of each (1.5), the
    # integer optimum is one vertex (1); the answer comes from branch and bound.
    triangle = make_program([1.0, 1.0, 1.0], A_ub=[[1, 1, 0], [0, 1, 1], [1, 0, 1]],
                            b_ub=[1, 1, 1])
    result = HIGHS.solve(triangle)
    assert result.status is SolveStatus.OPTIMAL and result.objective == pytest.approx(1.0)
    assert "relaxation" not in result.message
    # An infeasible relaxation is an infeasible program.
    infeasible = make_program([1.0, 1.0], A_eq=[[1, 1]], b_eq=[3])
    assert HIGHS.solve(infeasible).status is SolveStatus.INFEASIBLE
    with pytest.raises(ValueError, match="relaxation_first"):
        HighsSolver(relaxation_first=1)  # type: ignore[arg-type]


def test_random_programs_cover_both_outcomes() -> None:
    statuses = [ENUMERATOR.solve(random_set_packing(s)).status for s in range(NUM_RANDOM_PROGRAMS)]
    assert statuses.count(SolveStatus.OPTIMAL) >= 60
    assert statuses.count(SolveStatus.INFEASIBLE) >= 5


@pytest.mark.parametrize("seed", range(10))
def test_mixed_integer_program_matches_enumerated_integer_part(seed: int) -> None:
    # x0..x3 binary, y continuous in [0, 1] with y <= x0 + x1: for fixed integers the best y is
    # min(1, x0 + x1) if its coefficient is positive, else 0.
    rng = np.random.default_rng(100 + seed)
    c = rng.normal(size=5)
    program = Program(
        objective=c, A_ub=sp.csr_array(np.array([[-1.0, -1, 0, 0, 1], [1, 1, 1, 1, 0]])),
        b_ub=np.array([0.0, 2.0]), A_eq=sp.csr_array((0, 5)), b_eq=np.zeros(0),
        lower=np.zeros(5), upper=np.ones(5), integrality=np.array([True] * 4 + [False]),
    )
    best = -math.inf
    for bits in itertools.product((0, 1), repeat=4):
        if sum(bits) <= 2:
            y = min(1.0, bits[0] + bits[1]) if c[4] > 0 else 0.0
            best = max(best, float(c[:4] @ np.array(bits)) + c[4] * y)
    for solver in (HIGHS, CVXPY_HIGHS):
        result = solver.solve(program)
        assert result.status is SolveStatus.OPTIMAL
        assert result.objective == pytest.approx(best, abs=1e-9)


# ----------------------------------------------------------------------------------------------
# The enumerator against brute force
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("general", [False, True], ids=["set-packing", "general-coefficients"])
@pytest.mark.parametrize("seed", range(20))
def test_enumerator_matches_brute_force(seed: int, general: bool) -> None:
    program = random_set_packing(1000 + seed, general=general)
    points = brute_force(program)
    result = ENUMERATOR.solve(program)
    listed = [tuple(int(v) for v in x) for x in enumerate_feasible(program)]
    assert listed == [p for p, _ in points]  # same points, lexicographic order
    assert result.num_feasible == len(points)
    if not points:
        assert result.status is SolveStatus.INFEASIBLE
        assert result.log_sum_exp == -math.inf
        return
    values = np.array([v for _, v in points])
    expected_lse = values.max() + math.log(np.sum(np.exp(values - values.max())))
    assert result.log_sum_exp == pytest.approx(expected_lse, abs=1e-12)
    first_best = points[int(np.argmax(values))][0]  # argmax takes the first maximum
    assert tuple(result.solution.astype(int)) == first_best
    assert result.objective == pytest.approx(values.max(), abs=1e-12)


def test_enumerator_golden_values_and_lexicographic_ties() -> None:
    # x0 + x1 <= 1, objective [1, 2], constant 0.5: points 00, 01, 10 with values 0.5, 2.5, 1.5.
    program = make_program([1.0, 2.0], A_ub=[[1, 1]], b_ub=[1], constant=0.5)
    result = ENUMERATOR.solve(program)
    assert result.status is SolveStatus.OPTIMAL
    assert result.num_feasible == 3
    assert list(result.solution) == [0.0, 1.0]
    assert result.objective == 2.5
    expected_lse = math.log(math.exp(0.5) + math.exp(1.5) + math.exp(2.5))
    assert result.log_sum_exp == pytest.approx(expected_lse, rel=1e-15)
    # Tie: objective [1, 1] -> 01 and 10 both optimal; 01 is lexicographically smaller.
    tied = ENUMERATOR.solve(make_program([1.0, 1.0], A_ub=[[1, 1]], b_ub=[1]))
    assert list(tied.solution) == [0.0, 1.0]
    # Ties are exact for the real sum of the coefficients.  Variables (d, a, b, c) =
    # (1e16 + 2, 1e16, 1, 1) with d excluding a, b and c: {a, b, c} and {d} both sum to
    # 1e16 + 2 as real numbers, but sequential float addition gives a + b + c = 1e16.
    # The tie goes to the lexicographically smaller point (0, 1, 1, 1).
    big = 1e16
    order_tie = ENUMERATOR.solve(
        make_program([big + 2.0, big, 1.0, 1.0], A_ub=[[1, 1, 0, 0], [1, 0, 1, 0], [1, 0, 0, 1]],
                     b_ub=[1, 1, 1])
    )
    assert list(order_tie.solution) == [0.0, 1.0, 1.0, 1.0]
    assert order_tie.objective == big + 2.0


def test_enumerator_log_sum_exp_is_stable_for_large_values() -> None:
    # No constraints, objective [800, 800]: values 0, 800, 800, 1600; exp(1600) overflows.
    result = ENUMERATOR.solve(make_program([800.0, 800.0]))
    assert result.num_feasible == 4
    assert result.log_sum_exp == pytest.approx(1600.0 + math.log1p(2 * math.exp(-800.0)))
    assert math.isfinite(result.log_sum_exp)
    # Increasing values force rescaling of the running sum: objective [-700, 700]
    # visits 00 (0), 01 (700), 10 (-700), 11 (0).
    rescaled = ENUMERATOR.solve(make_program([-700.0, 700.0]))
    expected = 700.0 + math.log1p(2 * math.exp(-700.0) + math.exp(-1400.0))
    assert rescaled.log_sum_exp == pytest.approx(expected, rel=1e-15)


def test_enumerator_refuses_non_binary_and_oversized_programs() -> None:
    continuous = make_program([1.0, 1.0], integer=False)
    with pytest.raises(SolverError, match=r"enumeration: .*variable 0 .*continuous"):
        ENUMERATOR.solve(continuous)
    wide = make_program([1.0, 1.0], upper=np.array([1.0, 2.0]))
    with pytest.raises(SolverError, match=r"variable 1 .*bounds \[0.0, 2.0\]"):
        ENUMERATOR.solve(wide)
    with pytest.raises(SolverError, match="enumeration"):
        list(enumerate_feasible(wide))
    with pytest.raises(SolverError, match="max_variables=3"):
        EnumerationSolver(max_variables=3).solve(make_program(np.ones(4)))
    with pytest.raises(ValueError, match="node_limit"):
        EnumerationSolver(node_limit=0)


def test_enumerator_node_limit_reports_partial_sums() -> None:
    program = make_program(np.linspace(-1.0, 1.0, 12))  # 4096 feasible points
    complete = ENUMERATOR.solve(program)
    assert complete.num_feasible == 4096
    limited = EnumerationSolver(node_limit=200).solve(program)
    assert limited.status is SolveStatus.WORK_LIMIT
    assert 0 < limited.num_feasible < 4096
    assert limited.log_sum_exp < complete.log_sum_exp
    assert limited.objective <= complete.objective
    assert program.is_feasible(limited.solution)
    assert math.isnan(limited.bound)


def test_enumerator_fixed_bounds_and_empty_domains() -> None:
    # lower = 0.5 forces x0 = 1; bounds [0.2, 0.8] leave no integer: infeasible.
    forced = ENUMERATOR.solve(make_program([-1.0, 1.0], lower=np.array([0.5, 0.0])))
    assert list(forced.solution) == [1.0, 1.0] and forced.num_feasible == 2
    empty = ENUMERATOR.solve(make_program([1.0], lower=np.array([0.2]), upper=np.array([0.8])))
    assert empty.status is SolveStatus.INFEASIBLE
    assert HIGHS.solve(make_program([1.0], lower=np.array([0.2]), upper=np.array([0.8]))).status \
        is SolveStatus.INFEASIBLE


# ----------------------------------------------------------------------------------------------
# Infeasible, unbounded, empty and time-limited programs
# ----------------------------------------------------------------------------------------------


def test_infeasible_program_is_infeasible_for_every_backend() -> None:
    # Σ x == 2 but x0 + x1 + x2 <= 1: infeasible, also in the LP relaxation.
    program = make_program([1.0, -1.0, 0.5], A_ub=[[1, 1, 1]], b_ub=[1], A_eq=[[1, 1, 1]],
                           b_eq=[2])
    results = [
        HIGHS.solve(program), HIGHS.solve(program.relaxed()), ENUMERATOR.solve(program),
        CVXPY_HIGHS.solve(program), CLARABEL.solve(program.relaxed()),
    ]
    for result in results:
        assert result.status is SolveStatus.INFEASIBLE, result.solver
        assert result.solution is None and math.isnan(result.objective)
        assert math.isnan(result.bound)
    assert solve_k_best(program, 3, solver=HIGHS) == []


def test_unbounded_lp_is_reported_unbounded() -> None:
    program = make_program([1.0, 1.0], A_ub=[[1, -1]], b_ub=[1], integer=False,
                           upper=np.full(2, np.inf))
    for solver in (HIGHS, CLARABEL, CVXPY_HIGHS):
        result = solver.solve(program)
        assert result.status is SolveStatus.UNBOUNDED, solver.name
        assert result.solution is None


def test_program_without_variables() -> None:
    feasible = make_program(np.zeros(0), A_ub=np.zeros((1, 0)), b_ub=[0.0], constant=1.5)
    infeasible = make_program(np.zeros(0), A_eq=np.zeros((1, 0)), b_eq=[1.0])
    for solver in (HIGHS, ENUMERATOR, CVXPY_HIGHS):
        result = solver.solve(feasible)
        assert result.status is SolveStatus.OPTIMAL and result.objective == 1.5
        assert solver.solve(infeasible).status is SolveStatus.INFEASIBLE
    assert ENUMERATOR.solve(feasible).log_sum_exp == 1.5


def independent_set_program(seed: int, n: int = 30, density: float = 0.3) -> Program:
    """Maximum-weight independent set on a random graph: fractional LP, many B&B nodes."""
    rng = np.random.default_rng(seed)
    edges = [(i, j) for i in range(n) for j in range(i + 1, n) if rng.random() < density]
    A = np.zeros((len(edges), n))
    for row, (i, j) in enumerate(edges):
        A[row, i] = A[row, j] = 1.0
    return make_program(rng.uniform(0.5, 1.5, n), A_ub=A, b_ub=np.ones(len(edges)))


def test_tiny_time_limit_never_claims_a_wrong_optimum() -> None:
    program = independent_set_program(7)
    exact = EnumerationSolver(max_variables=40).solve(program)
    assert exact.status is SolveStatus.OPTIMAL
    lp = HIGHS.solve(program.relaxed())
    assert lp.objective > exact.objective + 1e-3  # the LP is fractional: B&B must branch
    # Outcomes depend on the machine's speed; the properties below must hold for every one.
    # (Measured here: 1e-4 s stops before an incumbent, 2e-3 s with incumbent 1.38 and bound
    # 13.0, while the optimum is 9.60.)
    runs = [(HIGHS, limit) for limit in (1e-4, 2e-3, 1e-2)] + [(CVXPY_HIGHS, 1e-4)]
    for solver, limit in runs:
        result = solver.solve(program, time_limit=limit)
        assert result.status in (SolveStatus.TIME_LIMIT, SolveStatus.WORK_LIMIT,
                                 SolveStatus.OPTIMAL), (solver, limit)
        if result.status is SolveStatus.OPTIMAL:
            assert result.objective == pytest.approx(exact.objective, abs=1e-9)
        if result.solution is not None:
            assert program.is_feasible(result.solution)
            assert result.objective <= exact.objective + 1e-9
        if math.isfinite(result.bound):
            assert result.bound >= exact.objective - 1e-9
    limited = ENUMERATOR.solve(program, time_limit=1e-4)
    assert limited.status in (SolveStatus.TIME_LIMIT, SolveStatus.OPTIMAL)
    assert limited.num_feasible <= exact.num_feasible
    if limited.status is SolveStatus.TIME_LIMIT:
        assert limited.objective <= exact.objective


def test_limit_statuses_keep_only_feasible_integral_incumbents() -> None:
    # Feed HiGHS-style runs to the status translation: a time-limited MILP whose point is
    # feasible keeps it as incumbent (never OPTIMAL); an infeasible or fractional point is
    # dropped.  x0 + x1 <= 1, objective [1, 2], constant 0.5.
    from mapassoc.solvers.highs import _MipRun

    program = make_program([1.0, 2.0], A_ub=[[1, 1]], b_ub=[1], constant=0.5)

    def run(x: list[float] | None, status: str) -> _MipRun:
        return _MipRun(status, "limit reached", None if x is None else np.array(x), -3.0)

    kept = HIGHS._translate(program, run([1.0, 1e-9], "kTimeLimit"), 0.1)
    assert kept.status is SolveStatus.TIME_LIMIT and list(kept.solution) == [1.0, 0.0]
    assert kept.objective == 1.5 and kept.bound == 3.5
    for bad in ([1.0, 1.0], [0.5, 0.5]):
        dropped = HIGHS._translate(program, run(bad, "kSolutionLimit"), 0.1)
        assert dropped.status is SolveStatus.WORK_LIMIT and dropped.solution is None
        assert "not kept" in dropped.message


def test_node_limit_and_probing_reach_highs() -> None:
    """The node limit stops branch and bound with WORK_LIMIT (HiGHS's status at
    ``mip_max_nodes``), and probing on or off gives the same optimum."""
    program = independent_set_program(5, n=40)
    exact = HighsSolver(relaxation_first=False).solve(program)
    probed = HighsSolver(relaxation_first=False, probing=True).solve(program)
    assert exact.status is probed.status is SolveStatus.OPTIMAL
    assert probed.objective == pytest.approx(exact.objective, abs=1e-9)
    # Without presolve this program needs more than its root node (measured: the root's
    # bound 11.416 against the optimum 11.395).
    limited = HighsSolver(relaxation_first=False, node_limit=1, presolve=False).solve(program)
    assert limited.status is SolveStatus.WORK_LIMIT and "limit" in limited.message.lower()
    assert limited.bound >= exact.objective - 1e-9
    if limited.solution is not None:
        assert program.is_feasible(limited.solution)
        assert limited.objective <= exact.objective + 1e-9


def test_invalid_time_limit_is_rejected() -> None:
    program = make_program([1.0])
    for bad in (0.0, -1.0, math.inf, math.nan):
        for solver in (HIGHS, ENUMERATOR):
            with pytest.raises(ValueError, match="time_limit"):
                solver.solve(program, time_limit=bad)


# ----------------------------------------------------------------------------------------------
# cvxpy: Clarabel ties, duals and the Lagrangian bound
# ----------------------------------------------------------------------------------------------


def test_clarabel_tie_gives_midpoint_with_the_simplex_objective() -> None:
    program = make_program([1.0, 1.0], A_ub=[[1, 1]], b_ub=[1], integer=False)
    interior = CLARABEL.solve(program)
    simplex = HIGHS.solve(program)
    assert interior.status is simplex.status is SolveStatus.OPTIMAL
    assert interior.objective == pytest.approx(simplex.objective, abs=1e-6)
    assert interior.solution == pytest.approx([0.5, 0.5], abs=1e-4)  # the midpoint
    assert sorted(simplex.solution) == [0.0, 1.0]  # a vertex
    assert not CLARABEL.exact and HIGHS.exact


def test_clarabel_refuses_integer_programs() -> None:
    with pytest.raises(SolverError, match=r"cvxpy-clarabel: .*program.relaxed\(\)"):
        CLARABEL.solve(make_program([1.0, 1.0]))


def test_lp_duals_are_sensitivities_of_the_optimum() -> None:
    # max 3 x0 + 2 x1 + x2 s.t. x0 + x1 <= 1.5, x1 + x2 == 1, 0 <= x <= 1.
    # Optimum x = (1, 0.5, 0.5), value 4.5; raising b_ub by e moves x1 up (+2 - 1 = +1 per
    # unit); raising b_eq by e moves x2 up (+1 per unit).  Hand-derived duals: 1 and 1.
    def program(b_ub: float, b_eq: float) -> Program:
        return make_program([3.0, 2.0, 1.0], A_ub=[[1, 1, 0]], b_ub=[b_ub], A_eq=[[0, 1, 1]],
                            b_eq=[b_eq], integer=False)

    base = program(1.5, 1.0)
    step = 1e-3
    finite_ub = (HIGHS.solve(program(1.5 + step, 1.0)).objective - 4.5) / step
    finite_eq = (HIGHS.solve(program(1.5, 1.0 + step)).objective - 4.5) / step
    assert finite_ub == pytest.approx(1.0) and finite_eq == pytest.approx(1.0)
    for solver in (CLARABEL, CVXPY_HIGHS):
        result = solver.solve(base)
        assert isinstance(result, LPResult)
        assert result.objective == pytest.approx(4.5, abs=1e-7)
        assert result.ineq_duals == pytest.approx([1.0], abs=1e-6)
        assert result.eq_duals == pytest.approx([1.0], abs=1e-6)
        assert result.bound == pytest.approx(4.5, abs=1e-6) and result.bound >= 4.5 - 1e-12


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, NUM_RANDOM_PROGRAMS - 1),
    scale=st.floats(0.0, 5.0),
    shift=st.floats(-5.0, 5.0),
)
def test_lagrangian_bound_holds_for_any_multipliers(seed: int, scale: float, shift: float) -> None:
    program = random_set_packing(seed)
    exact = ENUMERATOR.solve(program)
    lp = HIGHS.solve(program.relaxed())
    rng = np.random.default_rng(seed)
    y = scale * rng.random(program.A_ub.shape[0])
    w = shift + rng.normal(size=program.A_eq.shape[0])
    bound = lagrangian_bound(program, y, w)
    if lp.status is SolveStatus.OPTIMAL:
        assert bound >= lp.objective - 1e-9  # weak duality, LP
    if exact.status is SolveStatus.OPTIMAL:
        assert bound >= exact.objective - 1e-9  # and the integer optimum below it


def test_lagrangian_bound_rejects_wrong_shapes() -> None:
    program = make_program([1.0, 1.0], A_ub=[[1, 1]], b_ub=[1])
    with pytest.raises(ValueError, match="ineq_duals"):
        lagrangian_bound(program, np.zeros(2), np.zeros(0))


# ----------------------------------------------------------------------------------------------
# networkx min-cost flow for every K vs the flow LP solved by HiGHS
# ----------------------------------------------------------------------------------------------


def random_dag_flow(seed: int, *, negative_cycle: bool = False) -> FlowProgram:
    rng = np.random.default_rng(seed)
    num_nodes = int(rng.integers(4, 9))
    tails, heads = [], []
    for i in range(num_nodes):
        for j in range(i + 1, num_nodes):
            if rng.random() < 0.5:
                tails.append(i)
                heads.append(j)
    tails.append(0)  # a parallel edge
    heads.append(num_nodes - 1)
    tails.append(0)
    heads.append(num_nodes - 1)
    if negative_cycle:  # 1 -> 2 -> 1 with negative total cost and finite capacity
        tails += [1, 2]
        heads += [2, 1]
    costs = rng.normal(0.0, 1.0, size=len(tails))
    if negative_cycle:
        costs[-2:] = [-1.25, 0.5]
    return FlowProgram(
        num_nodes=num_nodes, source=0, sink=num_nodes - 1, tails=np.array(tails),
        heads=np.array(heads), capacities=rng.integers(0, 4, size=len(tails)),
        costs=costs, max_flow=int(rng.integers(3, 9)),
    )


def flow_lp(flow: FlowProgram, k: int) -> Program:
    """Minimum cost flow of value k as an LP: maximise -cost, conservation as equalities."""
    incidence = np.zeros((flow.num_nodes, flow.num_edges))
    for e, (t, h) in enumerate(zip(flow.tails, flow.heads, strict=True)):
        incidence[t, e] -= 1.0  # out of t
        incidence[h, e] += 1.0  # into h
    supply = np.zeros(flow.num_nodes)
    supply[flow.source], supply[flow.sink] = -k, k
    return make_program(-flow.costs, A_eq=incidence, b_eq=supply, integer=False,
                        upper=flow.capacities.astype(float))


@pytest.mark.parametrize("negative_cycle", [False, True], ids=["dag", "negative-cycle"])
@pytest.mark.parametrize("seed", range(12))
def test_flow_costs_match_the_flow_lp_for_every_k(seed: int, negative_cycle: bool) -> None:
    flow = random_dag_flow(seed, negative_cycle=negative_cycle)
    solver = NetworkxFlowSolver()
    result = solver.solve_flow(flow)
    assert isinstance(result, FlowResult) and result.max_flow == flow.max_flow
    tolerance = float(flow.capacities.sum()) / solver.cost_scale + 1e-12
    for k in range(flow.max_flow + 1):
        lp = HIGHS.solve(flow_lp(flow, k))
        if lp.status is SolveStatus.INFEASIBLE:
            assert result.statuses[k] is SolveStatus.INFEASIBLE and result.costs[k] == np.inf
            assert not result.edge_flows[k].any()
            continue
        assert result.statuses[k] is SolveStatus.OPTIMAL
        assert result.costs[k] == pytest.approx(-lp.objective, abs=tolerance)
        f = result.edge_flows[k]
        assert flow_lp(flow, k).is_feasible(f.astype(float), tol=0)
        assert result.costs[k] == pytest.approx(float(flow.costs @ f), abs=1e-12)
    feasible = np.isfinite(result.costs)
    assert feasible[0]  # zero flow is always feasible
    assert np.all(np.diff(feasible.astype(int)) <= 0)  # feasible K form an interval from 0
    costs = result.costs[feasible]
    if costs.size >= 3:  # convex in K
        assert np.all(np.diff(costs, 2) >= -2 * tolerance)


def test_flow_golden_two_paths() -> None:
    # 0 -> 1 -> 3 costs 1 + 1, 0 -> 2 -> 3 costs 0.5 + 3, capacities 1: K = 0, 1, 2 cost
    # 0, 2, 5.5; K = 3 infeasible.
    flow = FlowProgram(num_nodes=4, source=0, sink=3, tails=np.array([0, 1, 0, 2]),
                       heads=np.array([1, 3, 2, 3]), capacities=np.ones(4, int),
                       costs=np.array([1.0, 1.0, 0.5, 3.0]), max_flow=3)
    result = NetworkxFlowSolver().solve_flow(flow)
    assert list(result.costs) == [0.0, 2.0, 5.5, np.inf]
    assert result.edge_flows.tolist() == [[0, 0, 0, 0], [1, 1, 0, 0], [1, 1, 1, 1], [0, 0, 0, 0]]
    assert result.statuses == (SolveStatus.OPTIMAL,) * 3 + (SolveStatus.INFEASIBLE,)


def test_flow_rejects_costs_too_large_for_the_scale() -> None:
    flow = FlowProgram(num_nodes=2, source=0, sink=1, tails=np.array([0]), heads=np.array([1]),
                       capacities=np.array([1]), costs=np.array([1e10]), max_flow=1)
    with pytest.raises(ValueError, match="cost_scale"):
        NetworkxFlowSolver().solve_flow(flow)
    assert NetworkxFlowSolver(cost_scale=1.0).solve_flow(flow).costs.tolist() == [0.0, 1e10]


# ----------------------------------------------------------------------------------------------
# k-best by no-good cuts vs the enumerator
# ----------------------------------------------------------------------------------------------


def test_no_good_cut_excludes_exactly_one_point() -> None:
    point = np.array([1.0, 0.0, 1.0])
    row, rhs = no_good_cut(point)
    for candidate in itertools.product((0, 1), repeat=3):
        x = np.array(candidate, dtype=float)
        assert ((row @ x)[0] <= rhs[0]) == (not np.array_equal(x, point))


@pytest.mark.parametrize("seed", range(15))
def test_k_best_matches_the_enumerators_top_values(seed: int) -> None:
    program = random_set_packing(2000 + seed)
    m = 6
    values = sorted((v for _, v in brute_force(program)), reverse=True)[:m]
    for solver in (HIGHS, ENUMERATOR):
        results = solve_k_best(program, m, solver=solver)
        assert len(results) == len(values)
        assert all(r.status is SolveStatus.OPTIMAL for r in results)
        assert [r.objective for r in results] == pytest.approx(values, abs=1e-9)
        points = {tuple(r.solution) for r in results}
        assert len(points) == len(results)
        assert all(program.is_feasible(r.solution) for r in results)


def test_k_best_stops_on_a_limit_and_returns_it_last() -> None:
    program = make_program(np.linspace(-1.0, 1.0, 12))
    results = solve_k_best(program, 5, solver=EnumerationSolver(node_limit=30))
    assert results[-1].status is SolveStatus.WORK_LIMIT
    assert all(r.status is SolveStatus.OPTIMAL for r in results[:-1])


def test_k_best_validates_its_arguments() -> None:
    program = make_program([1.0, 2.0])
    with pytest.raises(SolverError, match="exact"):
        solve_k_best(program, 2, solver=CLARABEL)
    with pytest.raises(ValueError, match="binary"):
        solve_k_best(program.relaxed(), 2, solver=HIGHS)
    with pytest.raises(ValueError, match="m must be"):
        solve_k_best(program, 0, solver=HIGHS)


# ----------------------------------------------------------------------------------------------
# Registry and result types
# ----------------------------------------------------------------------------------------------


def test_registry_lists_and_builds_every_solver() -> None:
    assert available_solvers() == list(SOLVER_NAMES)
    program = make_program([1.0, -2.0, 3.0], A_ub=[[1, 0, 1]], b_ub=[1])
    for name in SOLVER_NAMES:
        solver = get_solver(name)
        assert solver.name == name
        if solver.supports_flow:
            continue
        target = program if solver.supports_integer else program.relaxed()
        result = solver.solve(target)
        assert isinstance(result, SolveResult) and result.solver == name
        assert result.objective == pytest.approx(3.0, abs=1e-6)
    flags = {n: (get_solver(n).supports_integer, get_solver(n).exact) for n in SOLVER_NAMES}
    assert flags["cvxpy-clarabel"] == (False, False)
    assert flags["highs"] == flags["enumeration"] == flags["cvxpy-highs"] == (True, True)
    assert isinstance(get_solver("enumeration").solve(program), EnumerationResult)


def test_registry_rejects_unknown_names() -> None:
    with pytest.raises(ValueError, match=r"unknown solver 'gurobi'; available solvers: highs"):
        get_solver("gurobi")
    with pytest.raises(ValueError, match=r"backend must be one of \['CLARABEL', 'HIGHS'\]"):
        CvxpySolver(backend="SCS")


def test_result_invariants() -> None:
    with pytest.raises(ValueError, match="objective must be nan"):
        SolveResult(status=SolveStatus.INFEASIBLE, objective=1.0, solution=None,
                    solve_seconds=0.0, solver="x")
    with pytest.raises(ValueError, match="OPTIMAL"):
        SolveResult(status=SolveStatus.OPTIMAL, objective=math.nan, solution=None,
                    solve_seconds=0.0, solver="x")
    result = HIGHS.solve(make_program([1.0]))
    with pytest.raises(ValueError, match="read-only"):
        result.solution[0] = 5.0
