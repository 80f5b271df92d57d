"""HiGHS through :func:`scipy.optimize.milp` (MILPs and LPs).

Gaps.  HiGHS stops branch and bound when the relative gap ``|bound - incumbent| /
|incumbent|`` or the absolute gap ``|bound - incumbent|`` falls below ``mip_rel_gap`` /
``mip_abs_gap`` (defaults 1e-4 and 1e-6).  Our objectives are log-likelihood sums that
can be near zero or negative, where a relative gap means nothing, so both default to 0
here: OPTIMAL means the incumbent met the dual bound.  scipy's ``milp`` documents
``mip_rel_gap`` but not ``mip_abs_gap``; it passes options it does not recognise "to HiGHS
verbatim" with a RuntimeWarning, which this module expects and filters for that one
option only.

Relaxation first.  An integer program is first solved as its LP relaxation (dual
simplex, no MIP presolve); when the LP optimum is a vertex whose integer variables are
integral to :data:`RELAXATION_INTEGRALITY` and the rounded point is feasible with the LP's
value, that point is optimal (no integer point can beat the relaxation) and is returned
as OPTIMAL with the LP optimum as its bound.  Otherwise ``milp`` solves the program.  On
the set-packing programs of track association the relaxation is mostly integral, and
HiGHS's MIP presolve alone can cost twenty times the LP (about 1 s against 0.05 s on
programs of 3,000 hypotheses and 200 detections); ``relaxation_first=False`` turns this
off.

Integer variables of an OPTIMAL point are rounded to exact integers (HiGHS returns them
within its integrality tolerance 1e-6; farther raises :class:`SolverError`) and the
objective is recomputed from the rounded point with the program's constant.  A point
returned with a limit status is kept as the incumbent only if it is integral to 1e-6 and
feasible (``Program.is_feasible``, tolerance 1e-7).
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import Bounds, LinearConstraint, OptimizeResult, linprog, milp

from mapassoc.formulations.program import Program
from mapassoc.solvers._common import (
    INTEGRALITY_TOLERANCE,
    all_bounds_finite,
    empty_program_is_feasible,
    integrality_violation,
    snap_integer_variables,
)
from mapassoc.solvers.results import LPResult, SolveResult, SolveStatus, validate_time_limit

__all__ = ["HighsSolver", "RELAXATION_INTEGRALITY"]

RELAXATION_INTEGRALITY = 1e-9
"""Largest distance from an integer of an integer variable of an LP optimum taken as
integral by the relaxation-first solve (module docstring)."""

# scipy.optimize.milp status codes (scipy/optimize/_milp.py).
_SCIPY_OPTIMAL = 0
_SCIPY_LIMIT = 1
_SCIPY_INFEASIBLE = 2
_SCIPY_UNBOUNDED = 3

# linprog(method="highs") uses the same codes; a limit is refined to TIME_LIMIT by message.
_LINPROG_STATUSES: dict[int, SolveStatus] = {
    _SCIPY_OPTIMAL: SolveStatus.OPTIMAL,
    _SCIPY_LIMIT: SolveStatus.WORK_LIMIT,
    _SCIPY_INFEASIBLE: SolveStatus.INFEASIBLE,
    _SCIPY_UNBOUNDED: SolveStatus.UNBOUNDED,
}


class HighsSolver:
    """Exact MILP/LP backend: HiGHS branch and bound / simplex via ``scipy.optimize.milp``.

    Parameters
    ----------
    mip_rel_gap : float, default 0.0
        Relative optimality gap at which branch and bound stops (>= 0).
    mip_abs_gap : float, default 0.0
        Absolute optimality gap at which branch and bound stops (>= 0).
    presolve : bool, default True
        Whether HiGHS presolves.
    node_limit : int or None, default None
        Maximum branch-and-bound nodes; reaching it gives :attr:`SolveStatus.WORK_LIMIT`.
    relaxation_first : bool, default True
        Solve an integer program's LP relaxation first and return its optimum when it is
        integral (module docstring).
    """

    name = "highs"
    supports_integer = True
    supports_flow = False
    supports_relaxation = True
    exact = True

    def __init__(
        self,
        *,
        mip_rel_gap: float = 0.0,
        mip_abs_gap: float = 0.0,
        presolve: bool = True,
        node_limit: int | None = None,
        relaxation_first: bool = True,
    ) -> None:
        for label, gap in (("mip_rel_gap", mip_rel_gap), ("mip_abs_gap", mip_abs_gap)):
            if not (math.isfinite(gap) and gap >= 0):
                raise ValueError(f"{label} must be a finite number >= 0, got {gap!r}")
        if node_limit is not None and (int(node_limit) != node_limit or node_limit < 1):
            raise ValueError(f"node_limit must be a positive integer or None, got {node_limit!r}")
        self.mip_rel_gap = float(mip_rel_gap)
        self.mip_abs_gap = float(mip_abs_gap)
        self.presolve = bool(presolve)
        self.node_limit = None if node_limit is None else int(node_limit)
        if not isinstance(relaxation_first, bool):
            raise ValueError(f"relaxation_first must be a bool, got {relaxation_first!r}")
        self.relaxation_first = relaxation_first

    def __repr__(self) -> str:
        return (
            f"HighsSolver(mip_rel_gap={self.mip_rel_gap}, mip_abs_gap={self.mip_abs_gap}, "
            f"presolve={self.presolve}, node_limit={self.node_limit}, "
            f"relaxation_first={self.relaxation_first})"
        )

    def solve(self, program: Program, *, time_limit: float | None = None) -> SolveResult:
        """Maximise ``program`` with HiGHS.

        Parameters
        ----------
        program : Program
        time_limit : float or None
            Wall-clock seconds for HiGHS; reaching it gives TIME_LIMIT with the incumbent
            (if any) and the MIP dual bound.

        Returns
        -------
        SolveResult
            ``bound`` is the MIP dual bound for integer programs and the LP optimum for
            continuous ones.
        """
        if not isinstance(program, Program):
            raise TypeError(f"program must be a Program, got {type(program).__name__}")
        limit = validate_time_limit(time_limit)
        started = time.perf_counter()
        if program.num_variables == 0:
            return self._empty(program, time.perf_counter() - started)
        if self.relaxation_first and program.is_integer:
            relaxed = self._integral_relaxation(program, limit, started)
            if relaxed is not None:
                return relaxed
            if limit is not None:
                limit = max(0.0, limit - (time.perf_counter() - started))

        constraints = []
        if program.A_ub.shape[0]:
            constraints.append(LinearConstraint(program.A_ub, -np.inf, program.b_ub))
        if program.A_eq.shape[0]:
            constraints.append(LinearConstraint(program.A_eq, program.b_eq, program.b_eq))
        options: dict[str, float | bool | int] = {
            "mip_rel_gap": self.mip_rel_gap,
            "mip_abs_gap": self.mip_abs_gap,
            "presolve": self.presolve,
        }
        if limit is not None:
            options["time_limit"] = limit
        if self.node_limit is not None:
            options["node_limit"] = self.node_limit
        with warnings.catch_warnings():
            # milp warns that it passes mip_abs_gap to HiGHS verbatim; that is the intent.
            warnings.filterwarnings(
                "ignore",
                message=r"Unrecognized options detected: \{'mip_abs_gap'\}",
                category=RuntimeWarning,
            )
            raw = milp(
                -program.objective,  # milp minimises
                integrality=program.integrality.astype(np.uint8),
                bounds=Bounds(program.lower, program.upper),
                constraints=constraints,
                options=options,
            )
        seconds = time.perf_counter() - started
        return self._translate(program, raw, seconds)

    def solve_relaxation(self, program: Program, *, time_limit: float | None = None) -> LPResult:
        """Solve the LP relaxation with HiGHS simplex and return it with its duals.

        Uses :func:`scipy.optimize.linprog` (``method="highs"``), which reports the
        constraint marginals that ``milp`` does not.  ``ineq_duals`` and ``eq_duals`` are
        ``d optimum / d b`` of the maximisation (so ``ineq_duals >= 0``), set only when
        the solve is OPTIMAL.

        Parameters
        ----------
        program : Program
            Integrality, if any, is ignored (the relaxation is solved).
        time_limit : float or None
        """
        if not isinstance(program, Program):
            raise TypeError(f"program must be a Program, got {type(program).__name__}")
        limit = validate_time_limit(time_limit)
        started = time.perf_counter()
        options: dict[str, float | bool] = {"presolve": self.presolve}
        if limit is not None:
            options["time_limit"] = limit
        has_ub, has_eq = program.A_ub.shape[0] > 0, program.A_eq.shape[0] > 0
        raw = linprog(
            -program.objective,
            A_ub=program.A_ub if has_ub else None,
            b_ub=program.b_ub if has_ub else None,
            A_eq=program.A_eq if has_eq else None,
            b_eq=program.b_eq if has_eq else None,
            bounds=np.column_stack([program.lower, program.upper]),
            method="highs",
            options=options,
        )
        seconds = time.perf_counter() - started
        code = int(raw.status)
        status = _LINPROG_STATUSES.get(code, SolveStatus.FAILED)
        if status is SolveStatus.WORK_LIMIT and "time limit" in str(raw.message).lower():
            status = SolveStatus.TIME_LIMIT
        if status is not SolveStatus.OPTIMAL:
            return LPResult(
                status=status,
                objective=math.nan,
                solution=None,
                solve_seconds=seconds,
                solver=self.name,
                message=str(raw.message),
                bound=math.nan,
            )
        value = -float(raw.fun) + program.constant
        return LPResult(
            status=status,
            objective=value,
            solution=np.asarray(raw.x, dtype=float),
            solve_seconds=seconds,
            solver=self.name,
            message=str(raw.message),
            bound=value,
            ineq_duals=-np.asarray(raw.ineqlin.marginals) if has_ub else np.zeros(0),
            eq_duals=-np.asarray(raw.eqlin.marginals) if has_eq else np.zeros(0),
        )

    def _integral_relaxation(
        self, program: Program, limit: float | None, started: float
    ) -> SolveResult | None:
        """The LP relaxation's optimum as the integer optimum, when it is integral; an
        INFEASIBLE result when the relaxation is infeasible; None otherwise (``milp``
        decides)."""
        lp = self.solve_relaxation(program, time_limit=limit)
        if lp.status is SolveStatus.INFEASIBLE:
            return SolveResult(
                status=SolveStatus.INFEASIBLE,
                objective=math.nan,
                solution=None,
                solve_seconds=time.perf_counter() - started,
                solver=self.name,
                message=f"LP relaxation infeasible: {lp.message}",
            )
        if lp.status is not SolveStatus.OPTIMAL or lp.solution is None:
            return None
        if integrality_violation(program, lp.solution) > RELAXATION_INTEGRALITY:
            return None
        point = snap_integer_variables(program, lp.solution, self.name)
        value = program.value(point)
        if not program.is_feasible(point) or value < lp.objective - 1e-9 * (
            1.0 + abs(lp.objective)
        ):
            return None
        return SolveResult(
            status=SolveStatus.OPTIMAL,
            objective=value,
            solution=point,
            solve_seconds=time.perf_counter() - started,
            solver=self.name,
            message="LP relaxation optimum is integral",
            bound=max(value, lp.objective),
        )

    def _empty(self, program: Program, seconds: float) -> SolveResult:
        if empty_program_is_feasible(program, 1e-9):
            return SolveResult(
                status=SolveStatus.OPTIMAL,
                objective=program.constant,
                solution=np.zeros(0),
                solve_seconds=seconds,
                solver=self.name,
                bound=program.constant,
                message="program has no variables; the empty point is feasible",
            )
        return SolveResult(
            status=SolveStatus.INFEASIBLE,
            objective=math.nan,
            solution=None,
            solve_seconds=seconds,
            solver=self.name,
            message="program has no variables and its right-hand sides exclude the empty point",
        )

    def _translate(self, program: Program, raw: OptimizeResult, seconds: float) -> SolveResult:
        """Map a ``scipy.optimize.OptimizeResult`` from ``milp`` to a :class:`SolveResult`."""
        code = int(raw.status)
        message = str(raw.message)
        point = None
        if raw.x is not None and code == _SCIPY_OPTIMAL:
            point = snap_integer_variables(program, raw.x, self.name)
        elif raw.x is not None and code == _SCIPY_LIMIT:
            point = _usable_incumbent(program, raw.x)
            if point is None:
                message += " The point HiGHS returned is not feasible and was not kept."
        objective = math.nan if point is None else program.value(point)

        bound = math.nan
        if raw.mip_dual_bound is not None and program.is_integer:
            bound = -float(raw.mip_dual_bound) + program.constant
        elif code == _SCIPY_OPTIMAL and not program.is_integer:
            bound = -float(raw.fun) + program.constant  # simplex optimum certifies itself

        if code == _SCIPY_OPTIMAL:
            status = SolveStatus.OPTIMAL
        elif code == _SCIPY_LIMIT:
            status = (
                SolveStatus.TIME_LIMIT
                if "time limit" in message.lower()
                else SolveStatus.WORK_LIMIT
            )
        elif code == _SCIPY_INFEASIBLE:
            status, bound = SolveStatus.INFEASIBLE, math.nan
        elif code == _SCIPY_UNBOUNDED:
            status, bound = SolveStatus.UNBOUNDED, math.nan
        elif "unbounded or infeasible" in message.lower() and all_bounds_finite(program):
            # Every variable is boxed, so the objective cannot be unbounded.
            status, bound = SolveStatus.INFEASIBLE, math.nan
            message += " All variables have finite bounds, so the program is infeasible."
        else:
            status, bound = SolveStatus.FAILED, math.nan
            if "unbounded or infeasible" in message.lower():
                message += " HiGHS cannot tell which because some variable bounds are infinite."
        return SolveResult(
            status=status,
            objective=objective,
            solution=point,
            solve_seconds=seconds,
            solver=self.name,
            message=message,
            bound=bound,
        )


def _usable_incumbent(program: Program, x: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The point of a limit-stopped solve if it is integral and feasible, else ``None``.

    An interrupted (dual) simplex can leave a primal-infeasible point; it is no incumbent.
    """
    if integrality_violation(program, x) > INTEGRALITY_TOLERANCE:
        return None
    point = snap_integer_variables(program, x, HighsSolver.name)
    return point if program.is_feasible(point) else None
