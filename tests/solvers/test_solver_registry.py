"""The solver registry table, the relaxation capability and the single Lagrangian bound.

* every registered name resolves to a backend whose flags are its registry row's;
* optional libraries (cvxpy, networkx) are not imported by ``import mapassoc.solvers``;
* ``solve_relaxation`` through the protocol gives the LP value and duals that the
  direct HiGHS call gave before the refactoring, and :class:`ClusterSolver` picks its LP
  backend from the integer backend;
* the Lagrangian bounds give the numbers of the previous implementations;
* a window's status is the worst of its clusters' whatever their order.
"""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import linprog
from support import random_problem

from mapassoc.estimator.cluster_solving import (
    CLUSTER_STATUSES,
    ClusterReport,
    ClusterSolver,
    default_lp_solver,
)
from mapassoc.estimator.pipeline import WINDOW_STATUSES, WindowSolution
from mapassoc.formulations.bounds import fixed_variable_bounds
from mapassoc.formulations.packing import set_packing_program
from mapassoc.formulations.program import Program
from mapassoc.solvers import (
    SOLVER_NAMES,
    SOLVERS,
    EnumerationSolver,
    HighsSolver,
    LPResult,
    SolveStatus,
    available_solvers,
    get_integer_solver,
    get_solver,
    lagrangian_bound,
    registry,
    solver_spec,
)

FLAGS = ("supports_integer", "supports_flow", "supports_relaxation", "exact")


def small_lp() -> Program:
    # max 3 x0 + 2 x1 + x2 s.t. x0 + x1 <= 1.5, x1 + x2 == 1, 0 <= x <= 1 (duals 1 and 1).
    return Program(
        objective=np.array([3.0, 2.0, 1.0]),
        A_ub=sp.csr_array(np.array([[1.0, 1.0, 0.0]])),
        b_ub=np.array([1.5]),
        A_eq=sp.csr_array(np.array([[0.0, 1.0, 1.0]])),
        b_eq=np.array([1.0]),
        lower=np.zeros(3),
        upper=np.ones(3),
        integrality=np.array([True, True, True]),
        constant=0.25,
    )


def random_program(seed: int) -> Program:
    rng = np.random.default_rng(seed)
    n, r, q = int(rng.integers(2, 9)), int(rng.integers(0, 5)), int(rng.integers(0, 3))
    lower = np.where(rng.random(n) < 0.2, -np.inf, rng.uniform(-2.0, 0.0, n))
    upper = np.where(rng.random(n) < 0.2, np.inf, rng.uniform(0.0, 2.0, n))
    return Program(
        objective=rng.normal(size=n),
        A_ub=sp.csr_array(rng.integers(-1, 3, size=(r, n)).astype(float)),
        b_ub=rng.uniform(0.0, 3.0, r),
        A_eq=sp.csr_array(rng.integers(0, 2, size=(q, n)).astype(float)),
        b_eq=rng.uniform(0.0, 2.0, q),
        lower=lower,
        upper=upper,
        integrality=rng.random(n) < 0.5,
        constant=float(rng.normal()),
    )


# ----------------------------------------------------------------------------------------------
# The table
# ----------------------------------------------------------------------------------------------


def test_names_derive_from_the_table_and_all_resolve() -> None:
    assert SOLVER_NAMES == tuple(spec.name for spec in SOLVERS)
    assert len(set(SOLVER_NAMES)) == len(SOLVER_NAMES)
    assert set(available_solvers()) <= set(SOLVER_NAMES)
    for name in available_solvers():
        spec = solver_spec(name)
        solver = get_solver(name)
        assert solver.name == name
        assert {f: getattr(solver, f) for f in FLAGS} == {f: getattr(spec, f) for f in FLAGS}


@pytest.mark.parametrize("name", SOLVER_NAMES)
def test_capabilities_match_behaviour(name: str) -> None:
    if name not in available_solvers():
        pytest.skip(f"{name} is not installed")
    solver = get_solver(name)
    program = small_lp()
    assert callable(getattr(solver, "solve_relaxation", None)) == solver.supports_relaxation
    assert callable(getattr(solver, "solve_flow", None)) == solver.supports_flow
    if solver.supports_flow:
        assert not callable(getattr(solver, "solve", None))
        return
    result = solver.solve(program if solver.supports_integer else program.relaxed())
    assert result.status is SolveStatus.OPTIMAL
    expected = 4.25 if solver.supports_integer else 4.75
    assert result.objective == pytest.approx(expected, abs=1e-6)
    if solver.supports_relaxation:
        relaxed = solver.solve_relaxation(program)  # integrality ignored
        assert isinstance(relaxed, LPResult) and relaxed.status is SolveStatus.OPTIMAL
        assert relaxed.objective == pytest.approx(4.75, abs=1e-6)
        assert relaxed.ineq_duals == pytest.approx([1.0], abs=1e-6)
        assert relaxed.eq_duals == pytest.approx([1.0], abs=1e-6)
        assert relaxed.bound >= 4.75 - 1e-9


def test_optional_flag_marks_the_lazily_imported_libraries() -> None:
    optional = {spec.name for spec in SOLVERS if spec.optional}
    assert optional == {"cvxpy-clarabel", "cvxpy-highs", "networkx-flow"}
    for spec in SOLVERS:
        heavy = any(m.split(".")[0] in ("cvxpy", "networkx") for m in spec.requires)
        assert heavy == spec.optional, spec.name


def test_error_messages_list_the_available_solvers(monkeypatch: pytest.MonkeyPatch) -> None:
    listed = ", ".join(available_solvers())
    with pytest.raises(ValueError) as unknown:
        get_solver("gurobi")
    assert str(unknown.value) == f"unknown solver 'gurobi'; available solvers: {listed}"

    real = registry._importable
    monkeypatch.setattr(registry, "_importable", lambda m: m != "networkx" and real(m))
    remaining = ", ".join(n for n in available_solvers())
    assert "networkx-flow" not in remaining
    with pytest.raises(ValueError) as missing:
        get_solver("networkx-flow")
    assert str(missing.value) == (
        "solver 'networkx-flow' is unavailable (cannot import networkx); "
        f"available solvers: {remaining}"
    )


def test_integer_solvers_are_the_rows_with_the_capabilities() -> None:
    integer = [s.name for s in SOLVERS if s.supports_integer]
    exact = [s.name for s in SOLVERS if s.supports_integer and s.exact]
    assert "highs" in exact and "networkx-flow" not in integer
    assert "cvxpy-clarabel" not in integer  # an interior-point LP solver
    for name in set(available_solvers()) & set(integer):
        backend = get_integer_solver(name)
        assert backend.name == name and backend.supports_integer
    with pytest.raises(ValueError) as flow:
        get_integer_solver("networkx-flow")
    assert str(flow.value) == (
        f"solver 'networkx-flow' is not a solver of integer programs; choose one of "
        f"{', '.join(integer)}"
    )
    inexact = [s.name for s in SOLVERS if s.supports_integer and not s.exact]
    for name in inexact:
        with pytest.raises(ValueError, match="not an exact solver of integer programs"):
            get_integer_solver(name, exact=True)
    with pytest.raises(ValueError, match="unknown solver 'gurobi'"):
        get_integer_solver("gurobi")


def test_importing_the_solvers_does_not_import_optional_libraries() -> None:
    code = textwrap.dedent(
        """
        import sys
        import mapassoc.solvers
        import mapassoc.estimator.cluster_solving
        from mapassoc.solvers import get_solver
        get_solver("highs"); get_solver("enumeration")
        print(sorted(m for m in ("networkx", "cvxpy") if m in sys.modules))
        get_solver("networkx-flow")
        print("networkx" in sys.modules)
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split("\n")
    assert out[0] == "[]"
    assert out[1] == "True"  # get_solver checks the library of the backend it builds


# ----------------------------------------------------------------------------------------------
# Relaxation through the protocol
# ----------------------------------------------------------------------------------------------


def reference_relaxation(program: Program) -> float:
    """The LP optimum from another route to HiGHS: scipy's ``linprog``."""
    raw = linprog(
        -program.objective,
        A_ub=program.A_ub if program.A_ub.shape[0] else None,
        b_ub=program.b_ub if program.A_ub.shape[0] else None,
        A_eq=program.A_eq if program.A_eq.shape[0] else None,
        b_eq=program.b_eq if program.A_eq.shape[0] else None,
        bounds=np.column_stack([program.lower, program.upper]),
        method="highs",
    )
    assert raw.status == 0
    return -float(raw.fun) + program.constant


@pytest.mark.parametrize("seed", range(4))
def test_relaxation_through_the_protocol_is_the_lp_optimum_with_optimal_duals(seed: int) -> None:
    """The LP value agrees with scipy's linprog, and the duals are optimal: nonnegative on
    the inequality rows and, by strong duality, their Lagrangian bound equals the value
    (on a degenerate LP any optimal duals will do; the bounds built from them are valid)."""
    problem = random_problem(np.random.default_rng(seed), 30, 12, 3)
    for k in (None, 2):
        program = set_packing_program(problem, k)
        lp_solver = default_lp_solver(get_solver("highs"))
        result = lp_solver.solve_relaxation(program)
        value = reference_relaxation(program)
        assert result.status is SolveStatus.OPTIMAL
        assert result.objective == pytest.approx(value, abs=1e-9)
        assert result.bound == result.objective
        assert result.ineq_duals is not None and result.eq_duals is not None
        assert np.all(result.ineq_duals >= -1e-9)
        bound = lagrangian_bound(program, result.ineq_duals, result.eq_duals)
        assert bound == pytest.approx(value, abs=1e-7)
        for name in ("cvxpy-clarabel", "cvxpy-highs"):
            if name in available_solvers():
                other = get_solver(name).solve_relaxation(program)
                assert other.objective == pytest.approx(value, abs=1e-6)
                assert other.bound >= value - 1e-9


def test_cluster_solver_picks_its_lp_backend_from_the_integer_backend() -> None:
    def build(solver: object, **extra: object) -> ClusterSolver:
        return ClusterSolver(
            solver=solver,  # type: ignore[arg-type]
            exact_work_limit=1,
            beam_width=4,
            prune_log_ratio=math.inf,
            **extra,  # type: ignore[arg-type]
        )

    highs = HighsSolver()
    assert build(highs).lp_solver is highs
    assert isinstance(build(EnumerationSolver()).lp_solver, HighsSolver)
    explicit = HighsSolver(presolve=False)
    assert build(highs, lp_solver=explicit).lp_solver is explicit  # the pipeline's call
    if "cvxpy-highs" in available_solvers():
        cvxpy_highs = get_solver("cvxpy-highs")
        assert build(cvxpy_highs).lp_solver is cvxpy_highs

    # The default gives the same tables as the pipeline's explicit HighsSolver().
    problem = random_problem(np.random.default_rng(3), 40, 14, 3)
    default_table, default_report = build(HighsSolver()).solve(problem, 8, deadline=math.inf)
    table, report = build(HighsSolver(), lp_solver=HighsSolver()).solve(
        problem, 8, deadline=math.inf
    )
    assert report.status == default_report.status == "bounded"
    for field in ("best", "log_mass", "best_upper", "log_mass_upper"):
        np.testing.assert_array_equal(getattr(table, field), getattr(default_table, field))
    assert table.best_sets == default_table.best_sets


# ----------------------------------------------------------------------------------------------
# The Lagrangian bounds
# ----------------------------------------------------------------------------------------------


def reference_lagrangian_bound(program: Program, y: np.ndarray, w: np.ndarray) -> float:
    """The cvxpy backend's bound as it was before the refactoring."""
    y = np.maximum(y, 0.0)
    reduced = program.objective - program.A_ub.T @ y - program.A_eq.T @ w
    box = np.zeros(program.num_variables)
    up, down = reduced > 0, reduced < 0
    with np.errstate(invalid="ignore"):
        box[up] = reduced[up] * program.upper[up]
        box[down] = reduced[down] * program.lower[down]
    return float(
        math.fsum([program.constant, float(program.b_ub @ y), float(program.b_eq @ w),
                   *box.tolist()])
    )


def reference_fixed_variable_bounds(program: Program, y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """formulations.bounds.fixed_variable_bounds as it was before the refactoring."""
    y = np.maximum(y, 0.0)
    d = program.objective - program.A_ub.T @ y - program.A_eq.T @ w
    total = float(y @ program.b_ub + w @ program.b_eq + np.sum(np.maximum(d, 0.0)))
    return total - np.maximum(d, 0.0) + d + program.constant


@pytest.mark.parametrize("seed", range(8))
def test_lagrangian_bound_gives_the_previous_numbers(seed: int) -> None:
    program = random_program(seed)
    rng = np.random.default_rng(100 + seed)
    y = rng.normal(size=program.A_ub.shape[0])
    w = rng.normal(size=program.A_eq.shape[0])
    assert lagrangian_bound(program, y, w) == reference_lagrangian_bound(program, y, w)


@pytest.mark.parametrize("seed", range(6))
def test_fixed_variable_bounds_give_the_previous_numbers(seed: int) -> None:
    rng = np.random.default_rng(seed)
    program = set_packing_program(random_problem(rng, 25, 10, 2), int(rng.integers(0, 4)))
    y = rng.normal(size=program.A_ub.shape[0])
    w = rng.normal(size=program.A_eq.shape[0])
    fixed = fixed_variable_bounds(program, y, w)
    np.testing.assert_array_equal(fixed, reference_fixed_variable_bounds(program, y, w))
    # Both are the same Lagrangian: fixing x_h = 1 swaps max(d_h, 0) for d_h.
    d = program.objective - program.A_ub.T @ np.maximum(y, 0.0) - program.A_eq.T @ w
    np.testing.assert_allclose(
        fixed + np.maximum(d, 0.0) - d, lagrangian_bound(program, y, w), rtol=0, atol=1e-9
    )


# ----------------------------------------------------------------------------------------------
# Statuses
# ----------------------------------------------------------------------------------------------


def test_window_status_is_the_worst_cluster_status_in_any_order() -> None:
    def report(status: str) -> ClusterReport:
        return ClusterReport(size=1, status=status, work=0, solves=0, log_captured=0.0,
                             seconds=0.0)

    status_of = WindowSolution.status.fget  # type: ignore[attr-defined]
    worst_first = (report("time_limit"), report("bounded"), report("exact"))
    for clusters in (worst_first, worst_first[::-1], worst_first[1:], ()):
        for capped in (False, True):
            window = SimpleNamespace(hypotheses=SimpleNamespace(nodes_capped=capped),
                                     bounded_clusters=clusters, pruning_cut_short=False)
            expected = max(
                [WINDOW_STATUSES.index("capped" if capped else "exact")]
                + [WINDOW_STATUSES.index(c.status) for c in clusters]
            )
            assert status_of(window) == WINDOW_STATUSES[expected]
    assert list(CLUSTER_STATUSES) == ["exact", "bounded", "time_limit"]
