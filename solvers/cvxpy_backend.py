"""Programs through cvxpy: Clarabel (interior point, continuous only) or HiGHS.

Use the Clarabel backend for LP *bounds and duals*, not for solutions to round: an
interior-point method converges to the analytic centre of the optimal face, so on ties
it returns a midpoint (``max x0 + x1`` s.t. ``x0 + x1 <= 1`` gives ``x = [0.5, 0.5]``
where simplex returns the vertex ``[1, 0]``).  Its objective value is still the LP
optimum to solver tolerance (~1e-8).  An integer program given to the Clarabel backend
raises :class:`SolverError`; pass ``program.relaxed()`` to bound it.

``backend="HIGHS"`` uses cvxpy's HiGHS interface (integer programs allowed, with
``mip_rel_gap = mip_abs_gap = 0`` as in :mod:`mapassoc.solvers.highs`).  cvxpy returns
no incumbent when HiGHS stops on a time limit, so that case reports TIME_LIMIT with no
solution but with HiGHS's MIP dual bound.

Both backends return :class:`LPResult`.  For continuous programs that end OPTIMAL it
carries the duals of the ``A_ub`` and ``A_eq`` rows (``d optimum / d b``) and ``bound``
is :func:`lagrangian_bound` evaluated at those duals, a bound that is valid whatever the
duals' accuracy.  :meth:`CvxpySolver.solve_relaxation` solves ``program.relaxed()``
with either backend (the relaxation capability of the solver protocol).  cvxpy is
imported on first use (it takes about a second).
"""

from __future__ import annotations

import math
import time
import warnings
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from mapassoc.formulations.program import Program, lagrangian_bound
from mapassoc.solvers._common import (
    all_bounds_finite,
    empty_program_is_feasible,
    snap_integer_variables,
)
from mapassoc.solvers.results import LPResult, SolverError, SolveStatus, validate_time_limit

if TYPE_CHECKING:
    import cvxpy

__all__ = ["CvxpySolver", "lagrangian_bound", "CVXPY_BACKENDS"]

_CVXPY_STATUS_WARNINGS = (
    r"Solution may be inaccurate",
    r"\s*The problem is either infeasible or unbounded",
)

#: cvxpy solver names this module drives, and whether each accepts integer variables.
CVXPY_BACKENDS: dict[str, bool] = {"CLARABEL": False, "HIGHS": True}

#: cvxpy status strings (``cvxpy.settings``) with an unambiguous :class:`SolveStatus`.
#: ``infeasible_or_unbounded`` and ``user_limit`` depend on the program and the clock
#: (see :meth:`CvxpySolver._translate`); every other string (``*_inaccurate``,
#: ``solver_error``, ...) is FAILED.
_CVXPY_STATUSES: dict[str, SolveStatus] = {
    "optimal": SolveStatus.OPTIMAL,
    "infeasible": SolveStatus.INFEASIBLE,
    "unbounded": SolveStatus.UNBOUNDED,
}
_CVXPY_INFEASIBLE_OR_UNBOUNDED = "infeasible_or_unbounded"
_CVXPY_USER_LIMIT = "user_limit"


def _selection(indices: NDArray[np.intp], n: int) -> sp.csr_matrix:
    """Sparse (n, len(indices)) matrix placing a sub-vector at ``indices`` of an n-vector."""
    k = indices.size
    return sp.csr_matrix((np.ones(k), (indices, np.arange(k))), shape=(n, k))


def _cvxpy_problem(
    cp: Any, program: Program
) -> tuple[Any, list[tuple[NDArray[np.intp], cvxpy.Variable]], Any, Any]:
    """``program`` as a cvxpy maximisation: the problem, its variable blocks (the
    integer then the continuous variables, each with the indices it places), and its
    inequality and equality rows (``None`` where the program has none) for the duals."""
    n = program.num_variables
    integer_idx = np.flatnonzero(program.integrality)
    continuous_idx = np.flatnonzero(~program.integrality)
    blocks: list[tuple[NDArray[np.intp], cvxpy.Variable]] = []
    if integer_idx.size:
        blocks.append((integer_idx, cp.Variable(integer_idx.size, integer=True)))
    if continuous_idx.size:
        blocks.append((continuous_idx, cp.Variable(continuous_idx.size)))
    x = sum(_selection(idx, n) @ var for idx, var in blocks)

    ub_rows = eq_rows = None
    constraints = []
    if program.A_ub.shape[0]:
        ub_rows = sp.csr_matrix(program.A_ub) @ x <= program.b_ub
        constraints.append(ub_rows)
    if program.A_eq.shape[0]:
        eq_rows = sp.csr_matrix(program.A_eq) @ x == program.b_eq
        constraints.append(eq_rows)
    for values, is_lower in ((program.lower, True), (program.upper, False)):
        finite = np.flatnonzero(np.isfinite(values))
        if finite.size:
            picked = _selection(finite, n).T @ x
            constraints.append(picked >= values[finite] if is_lower else picked <= values[finite])
    problem = cp.Problem(cp.Maximize(program.objective @ x), constraints)
    return problem, blocks, ub_rows, eq_rows


class CvxpySolver:
    """Program backend through cvxpy.

    Parameters
    ----------
    backend : {"CLARABEL", "HIGHS"}, default "CLARABEL"
        cvxpy solver.  CLARABEL is continuous only and not ``exact`` (ties give
        midpoints); HIGHS accepts integer programs.

    Raises
    ------
    ValueError
        Unknown backend.
    SolverError
        cvxpy or the chosen solver is not installed.
    """

    supports_flow = False
    supports_relaxation = True

    def __init__(self, *, backend: str = "CLARABEL") -> None:
        if backend not in CVXPY_BACKENDS:
            raise ValueError(
                f"backend must be one of {sorted(CVXPY_BACKENDS)}, got {backend!r}"
            )
        self.backend = backend
        self.name = f"cvxpy-{backend.lower()}"
        self.supports_integer = CVXPY_BACKENDS[backend]
        self.exact = backend == "HIGHS"
        cp = self._cvxpy()
        if backend not in cp.installed_solvers():
            raise SolverError(
                f"{self.name}: cvxpy does not find the {backend} solver (installed: "
                f"{cp.installed_solvers()})"
            )

    def __repr__(self) -> str:
        return f"CvxpySolver(backend={self.backend!r})"

    def _cvxpy(self) -> Any:
        try:
            import cvxpy as cp
        except ImportError as error:
            raise SolverError(f"{self.name}: cvxpy is not importable ({error})") from error
        return cp

    def solve(self, program: Program, *, time_limit: float | None = None) -> LPResult:
        """Maximise ``program`` through cvxpy.

        Parameters
        ----------
        program : Program
            Continuous for CLARABEL (use ``program.relaxed()``).
        time_limit : float or None
            Wall-clock seconds passed to the solver.

        Returns
        -------
        LPResult

        Raises
        ------
        SolverError
            An integer program given to a continuous backend.
        """
        if not isinstance(program, Program):
            raise TypeError(f"program must be a Program, got {type(program).__name__}")
        limit = validate_time_limit(time_limit)
        if program.is_integer and not self.supports_integer:
            raise SolverError(
                f"{self.name}: {self.backend} is a continuous solver and this program has "
                f"{int(program.integrality.sum())} integer variables; pass "
                "program.relaxed() to bound it, or use backend='HIGHS' / the 'highs' solver"
            )
        started = time.perf_counter()
        if program.num_variables == 0:
            return self._empty(program, time.perf_counter() - started)
        cp = self._cvxpy()
        n = program.num_variables
        problem, blocks, ub_rows, eq_rows = _cvxpy_problem(cp, program)

        options: dict[str, float] = {}
        if limit is not None:
            options["time_limit"] = limit
        if self.backend == "HIGHS":
            options.update(mip_rel_gap=0.0, mip_abs_gap=0.0)
        try:
            with warnings.catch_warnings():
                # cvxpy warns about inexact or ambiguous statuses; _translate reports them
                # as the result's status and message instead.
                for text in _CVXPY_STATUS_WARNINGS:
                    warnings.filterwarnings("ignore", message=text, category=UserWarning)
                problem.solve(solver=self.backend, **options)
        except cp.error.SolverError as error:
            return LPResult(
                status=SolveStatus.FAILED, objective=math.nan, solution=None,
                solve_seconds=time.perf_counter() - started, solver=self.name,
                message=f"cvxpy reported a solver failure: {error}",
            )
        seconds = time.perf_counter() - started
        point = None
        if all(var.value is not None for _, var in blocks):
            point = np.zeros(n)
            for idx, var in blocks:
                point[idx] = np.asarray(var.value, dtype=float).reshape(-1)
            point = snap_integer_variables(program, point, self.name)
        return self._translate(program, problem, point, ub_rows, eq_rows, limit, seconds)

    def solve_relaxation(self, program: Program, *, time_limit: float | None = None) -> LPResult:
        """Solve the LP relaxation (``program.relaxed()``) and return it with its duals.

        Parameters
        ----------
        program : Program
            Integrality, if any, is ignored (the relaxation is solved).
        time_limit : float or None

        Returns
        -------
        LPResult
            Duals set when OPTIMAL; ``bound`` is :func:`lagrangian_bound` at those duals.
        """
        if not isinstance(program, Program):
            raise TypeError(f"program must be a Program, got {type(program).__name__}")
        return self.solve(program.relaxed() if program.is_integer else program,
                          time_limit=time_limit)

    def _empty(self, program: Program, seconds: float) -> LPResult:
        if empty_program_is_feasible(program, 1e-9):
            return LPResult(
                status=SolveStatus.OPTIMAL, objective=program.constant, solution=np.zeros(0),
                solve_seconds=seconds, solver=self.name, bound=program.constant,
                message="program has no variables; the empty point is feasible",
                ineq_duals=np.zeros(program.A_ub.shape[0]),
                eq_duals=np.zeros(program.A_eq.shape[0]),
            )
        return LPResult(
            status=SolveStatus.INFEASIBLE, objective=math.nan, solution=None,
            solve_seconds=seconds, solver=self.name,
            message="program has no variables and its right-hand sides exclude the empty point",
        )

    def _translate(
        self,
        program: Program,
        problem: Any,
        point: NDArray[np.float64] | None,
        ub_rows: Any,
        eq_rows: Any,
        limit: float | None,
        seconds: float,
    ) -> LPResult:
        """Map cvxpy's status strings (cvxpy.settings) to :class:`SolveStatus`."""
        status_text = str(problem.status)
        message = f"cvxpy status {status_text!r}"
        bound = math.nan
        ineq_duals = eq_duals = None
        stats = problem.solver_stats.extra_stats if problem.solver_stats else None
        mip_dual_bound = getattr(stats, "mip_dual_bound", None) if program.is_integer else None

        status = _CVXPY_STATUSES.get(status_text, SolveStatus.FAILED)
        if status is SolveStatus.OPTIMAL:
            if program.is_integer:
                if mip_dual_bound is not None:
                    bound = -float(mip_dual_bound) + program.constant
            else:
                ineq_duals = self._duals(ub_rows, program.A_ub.shape[0])
                eq_duals = self._duals(eq_rows, program.A_eq.shape[0])
                bound = lagrangian_bound(program, ineq_duals, eq_duals)
        elif status in (SolveStatus.INFEASIBLE, SolveStatus.UNBOUNDED):
            point = None
        elif status_text == _CVXPY_INFEASIBLE_OR_UNBOUNDED and all_bounds_finite(program):
            status, point = SolveStatus.INFEASIBLE, None
            message += "; all variables have finite bounds, so the program is infeasible"
        elif status_text == _CVXPY_USER_LIMIT:
            # cvxpy merges time and iteration limits into user_limit; elapsed time (which
            # includes cvxpy's compilation) tells them apart.
            timed_out = limit is not None and seconds >= limit
            status = SolveStatus.TIME_LIMIT if timed_out else SolveStatus.WORK_LIMIT
            if mip_dual_bound is not None:
                bound = -float(mip_dual_bound) + program.constant
        else:  # *_inaccurate, solver_error, unknown, ambiguous infeasible_or_unbounded
            status = SolveStatus.FAILED
            if status_text == _CVXPY_INFEASIBLE_OR_UNBOUNDED:
                message += (
                    "; the solver cannot tell infeasible from unbounded because some "
                    "variable bounds are infinite"
                )
            if point is not None:
                message += "; the solution is the solver's last iterate, for diagnosis only"
        objective = math.nan if point is None else program.value(point)
        return LPResult(
            status=status, objective=objective, solution=point, solve_seconds=seconds,
            solver=self.name, message=message, bound=bound,
            ineq_duals=ineq_duals, eq_duals=eq_duals,
        )

    def _duals(self, rows: Any, count: int) -> NDArray[np.float64]:
        if rows is None:
            return np.zeros(0)
        values = rows.dual_value
        if values is None:
            raise SolverError(f"{self.name}: the solver returned no duals for an optimal LP")
        duals = np.asarray(values, dtype=float).reshape(-1)
        if duals.shape != (count,):
            raise SolverError(
                f"{self.name}: expected {count} duals, the solver returned {duals.shape}"
            )
        return duals
