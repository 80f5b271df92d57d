"""HiGHS: integer programs and LP relaxations through ``highspy`` (HiGHS's own Python
interface).

Gaps.  HiGHS stops branch and bound when the relative gap ``|bound - incumbent| /
|incumbent|`` or the absolute gap ``|bound - incumbent|`` falls below ``mip_rel_gap`` /
``mip_abs_gap`` (defaults 1e-4 and 1e-6).  Our objectives are log-likelihood sums that
can be near zero or negative, where a relative gap means nothing, so both default to 0
here: OPTIMAL means the incumbent met the dual bound.

Probing.  HiGHS's MIP presolve probes binary variables (fixes one, propagates, learns
implications).  On the set-packing programs of track association it finds nothing
(0 rows and 0 columns deleted by 1,001 probing evaluations on a 3,788-hypothesis
program of the converging bench family) and costs most of the solve: the 12 integer
programs of the converging family's first seed took 5.1 s with it and 1.9 s without,
the same optima; parallel 1.23 -> 0.86 s, dense_radar 0.15 -> 0.09 s, scale100
1.84 -> 1.71 s (switching presolve off altogether helped converging as much but made
scale100's programs of 12,000 hypotheses twice as slow).  So :class:`HighsSolver` turns
this one presolve rule off (``probing=False``, HiGHS option ``presolve_rule_off``, which
:func:`scipy.optimize.milp` does not pass on: hence ``highspy`` for integer programs too).

Relaxation first.  An integer program is first solved as its LP relaxation (dual
simplex, no MIP presolve); when the LP optimum is a vertex whose integer variables are
integral to :data:`RELAXATION_INTEGRALITY` and the rounded point is feasible with the LP's
value, that point is optimal (no integer point can beat the relaxation) and is returned
as OPTIMAL with the LP optimum as its bound.  Otherwise branch and bound solves it.  On
the set-packing programs of track association the relaxation is mostly integral, and
HiGHS's MIP presolve alone can cost twenty times the LP (about 1 s against 0.05 s on
programs of 3,000 hypotheses and 200 detections); ``relaxation_first=False`` turns this
off.

Integer variables of an OPTIMAL point are rounded to exact integers (HiGHS returns them
within its integrality tolerance 1e-6; farther raises :class:`SolverError`) and the
objective is recomputed from the rounded point with the program's constant.  A point
returned with a limit status is kept as the incumbent only if it is integral to 1e-6 and
feasible (``Program.is_feasible``, tolerance 1e-7).

LP relaxations.  :meth:`HighsSolver.solve_relaxation` and
:meth:`HighsSolver.relaxation_sequence` keep the program in a ``highspy.Highs`` instance
(:class:`HighsRelaxation`): the model is passed once, and solving it again with other
equality right-hand sides (the cardinality row of a walk over k) changes those row
bounds and restarts the dual simplex from the last optimal basis, a few iterations
instead of a solve from scratch.  On a 1,081-hypothesis cluster of the dense_pd08 bench
family, 35 relaxations over k took 0.245 s through :func:`scipy.optimize.linprog`,
0.177 s solved afresh through ``highspy`` and 0.021 s warm-started.  The duals of a
warm-started solve are optimal duals of the same LP, but on a degenerate LP not
necessarily the ones a solve from scratch picks; every bound built from them is valid
either way, and the sequence of solves (so the duals) is deterministic.  LP relaxations
skip HiGHS's presolve by default (``lp_presolve``): on these programs it costs several
times the simplex solve it spares.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from dataclasses import dataclass, replace

import highspy
import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from mapassoc.formulations.program import Program
from mapassoc.solvers._common import (
    INTEGRALITY_TOLERANCE,
    all_bounds_finite,
    empty_program_is_feasible,
    integrality_violation,
    snap_integer_variables,
)
from mapassoc.solvers.relaxation_sequences import checked_b_eq
from mapassoc.solvers.results import (
    LPResult,
    SolverError,
    SolveResult,
    SolveStatus,
    validate_time_limit,
)

__all__ = ["HighsRelaxation", "HighsSolver", "RELAXATION_INTEGRALITY"]

RELAXATION_INTEGRALITY = 1e-9
"""Largest distance from an integer of an integer variable of an LP optimum taken as
integral by the relaxation-first solve (module docstring)."""

_PROBING_RULE = 1 << 15
"""Bit of HiGHS's probing in its ``presolve_rule_off`` mask (rule 15 in the table HiGHS
prints with ``presolve_rule_logging``; module docstring)."""

_LIMIT_STATUSES: dict[str, SolveStatus] = {
    "kTimeLimit": SolveStatus.TIME_LIMIT,
    "kSolutionLimit": SolveStatus.WORK_LIMIT,  # HiGHS's status at mip_max_nodes
    "kIterationLimit": SolveStatus.WORK_LIMIT,
}


class HighsSolver:
    """Exact MILP/LP backend: HiGHS branch and bound / simplex through ``highspy``.

    Parameters
    ----------
    mip_rel_gap : float, default 0.0
        Relative optimality gap at which branch and bound stops (>= 0).
    mip_abs_gap : float, default 0.0
        Absolute optimality gap at which branch and bound stops (>= 0).
    presolve : bool, default True
        Whether HiGHS presolves integer programs.
    probing : bool, default False
        Whether HiGHS's MIP presolve probes binary variables (off: on set-packing programs
        it finds nothing and costs most of the solve; module docstring).
    lp_presolve : bool, default False
        Whether HiGHS presolves LP relaxations (``solve_relaxation``, the relaxation-first
        step and :meth:`relaxation_sequence`).  Off by default: on the set-packing
        relaxations of track association presolve costs several times the dual simplex
        it spares (182 relaxations of dense_radar's first 50 scans, 2,241 variables on
        average: 1.53 s with presolve, 0.20 s without, the same optima).
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
        probing: bool = False,
        lp_presolve: bool = False,
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
        self.probing = bool(probing)
        self.lp_presolve = bool(lp_presolve)
        self.node_limit = None if node_limit is None else int(node_limit)
        if not isinstance(relaxation_first, bool):
            raise ValueError(f"relaxation_first must be a bool, got {relaxation_first!r}")
        self.relaxation_first = relaxation_first

    def __repr__(self) -> str:
        return (
            f"HighsSolver(mip_rel_gap={self.mip_rel_gap}, mip_abs_gap={self.mip_abs_gap}, "
            f"presolve={self.presolve}, probing={self.probing}, "
            f"lp_presolve={self.lp_presolve}, "
            f"node_limit={self.node_limit}, "
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

        highs = _silent_highs()
        _load_program(highs, program, program.b_eq, integrality=program.integrality)
        options: dict[str, float | int | str] = {
            "mip_rel_gap": self.mip_rel_gap,
            "mip_abs_gap": self.mip_abs_gap,
            "presolve": "on" if self.presolve else "off",
            "presolve_rule_off": 0 if self.probing else _PROBING_RULE,
        }
        if limit is not None:
            options["time_limit"] = limit
        if self.node_limit is not None:
            options["mip_max_nodes"] = self.node_limit
        for option, value in options.items():
            if highs.setOptionValue(option, value) != highspy.HighsStatus.kOk:
                raise SolverError(f"{self.name}: HiGHS rejected option {option}={value!r}")
        highs.run()
        seconds = time.perf_counter() - started
        return self._translate(program, _MipRun.read(highs, program), seconds)

    def solve_relaxation(self, program: Program, *, time_limit: float | None = None) -> LPResult:
        """Solve the LP relaxation with HiGHS simplex and return it with its duals.

        ``ineq_duals`` and ``eq_duals`` are ``d optimum / d b`` of the maximisation (so
        ``ineq_duals >= 0``), set only when the solve is OPTIMAL.

        Parameters
        ----------
        program : Program
            Integrality, if any, is ignored (the relaxation is solved).
        time_limit : float or None
        """
        return self.relaxation_sequence(program).solve(time_limit=time_limit)

    def relaxation_sequence(self, program: Program) -> HighsRelaxation:
        """The LP relaxation of ``program`` kept for solves with other equality
        right-hand sides, each warm-started from the last one's basis
        (:class:`HighsRelaxation`; module docstring)."""
        if not isinstance(program, Program):
            raise TypeError(f"program must be a Program, got {type(program).__name__}")
        return HighsRelaxation(program, presolve=self.lp_presolve)

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

    def _translate(self, program: Program, run: _MipRun, seconds: float) -> SolveResult:
        """Map what a HiGHS run of ``program`` left (:class:`_MipRun`) to a
        :class:`SolveResult`."""
        message = run.message
        point = None
        if run.x is not None and run.status == "kOptimal":
            point = snap_integer_variables(program, run.x, self.name)
        elif run.x is not None and run.status in _LIMIT_STATUSES:
            point = _usable_incumbent(program, run.x)
            if point is None:
                message += " The point HiGHS returned is not feasible and was not kept."
        objective = math.nan if point is None else program.value(point)

        bound = math.nan
        if program.is_integer and math.isfinite(run.dual_bound):
            bound = -run.dual_bound + program.constant
        elif run.status == "kOptimal" and not program.is_integer:
            bound = objective  # the simplex optimum certifies itself

        if run.status == "kOptimal":
            status = SolveStatus.OPTIMAL
        elif run.status in _LIMIT_STATUSES:
            status = _LIMIT_STATUSES[run.status]
        elif run.status == "kInfeasible":
            status, bound = SolveStatus.INFEASIBLE, math.nan
        elif run.status == "kUnbounded":
            status, bound = SolveStatus.UNBOUNDED, math.nan
        elif run.status == "kUnboundedOrInfeasible" and all_bounds_finite(program):
            # Every variable is boxed, so the objective cannot be unbounded.
            status, bound = SolveStatus.INFEASIBLE, math.nan
            message += ". All variables have finite bounds, so the program is infeasible."
        else:
            status, bound = SolveStatus.FAILED, math.nan
            if run.status == "kUnboundedOrInfeasible":
                message += ". HiGHS cannot tell which because some variable bounds are infinite."
        return SolveResult(
            status=status,
            objective=objective,
            solution=point,
            solve_seconds=seconds,
            solver=self.name,
            message=message,
            bound=bound,
        )


@dataclass(frozen=True)
class _MipRun:
    """What one HiGHS run of a program left: the model status's name (``"kOptimal"``,
    ``"kTimeLimit"``, ...), its text, the point (None when HiGHS has none) and the dual
    bound of the minimisation HiGHS solved (``nan`` when there is none)."""

    status: str
    message: str
    x: NDArray[np.float64] | None
    dual_bound: float

    @classmethod
    def read(cls, highs: highspy.Highs, program: Program) -> _MipRun:
        model_status = highs.getModelStatus()
        solution = highs.getSolution()
        x = np.asarray(solution.col_value, dtype=float) if solution.value_valid else None
        dual_bound = math.nan
        if program.is_integer:
            dual_bound = float(highs.getInfo().mip_dual_bound)
        return cls(model_status.name, highs.modelStatusToString(model_status), x, dual_bound)


def _usable_incumbent(program: Program, x: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The point of a limit-stopped solve if it is integral and feasible, else ``None``.

    An interrupted (dual) simplex can leave a primal-infeasible point; it is no incumbent.
    """
    if integrality_violation(program, x) > INTEGRALITY_TOLERANCE:
        return None
    point = snap_integer_variables(program, x, HighsSolver.name)
    return point if program.is_feasible(point) else None


_FIRST_INSTANCE = threading.Lock()
_banner_silenced = False


def _silent_highs() -> highspy.Highs:
    """A ``highspy.Highs`` instance with its output off.

    ``highspy.Highs()`` prints the HiGHS banner to the process's standard output when the
    first instance of a process is built, before any option can turn its output off (the
    banner would land in the middle of a command's output, e.g. a piped CSV).  The first
    construction therefore runs with file descriptor 1 pointed at the null device; later
    ones print nothing anyway.
    """
    global _banner_silenced
    if not _banner_silenced:
        with _FIRST_INSTANCE:
            if not _banner_silenced:
                highs = _construct_with_stdout_closed()
                _banner_silenced = True
                return highs
    highs = highspy.Highs()
    highs.setOptionValue("output_flag", False)
    return highs


def _construct_with_stdout_closed() -> highspy.Highs:
    """``highspy.Highs()`` with file descriptor 1 on the null device for the construction
    (see :func:`_silent_highs`); as is, when descriptor 1 cannot be redirected."""
    try:
        sys.stdout.flush()
        saved = os.dup(1)
    except (OSError, ValueError, AttributeError):
        highs = highspy.Highs()
    else:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 1)
            highs = highspy.Highs()
        finally:
            os.dup2(saved, 1)
            os.close(saved)
            os.close(null)
    highs.setOptionValue("output_flag", False)
    return highs


def _load_program(
    highs: highspy.Highs,
    program: Program,
    b_eq: NDArray[np.float64],
    *,
    integrality: NDArray[np.bool_] | None,
) -> None:
    """Pass ``program`` (rows ``A_ub`` then ``A_eq``, the latter with right-hand sides
    ``b_eq``) to ``highs`` as the minimisation of ``-objective``; ``integrality`` None
    passes every variable as continuous (the LP relaxation)."""
    rows = sp.vstack([program.A_ub, program.A_eq], format="csc")
    n = program.num_variables
    kinds = np.zeros(n, dtype=np.int32) if integrality is None else integrality.astype(np.int32)
    b_eq = np.asarray(b_eq, dtype=float)
    # The array form of passModel: numpy buffers, no per-field conversion of a HighsLp.
    status = highs.passModel(
        n,
        rows.shape[0],
        rows.nnz,
        int(highspy.MatrixFormat.kColwise),
        int(highspy.ObjSense.kMinimize),  # of -objective
        0.0,
        -np.asarray(program.objective, dtype=float),
        np.asarray(program.lower, dtype=float),
        np.asarray(program.upper, dtype=float),
        np.concatenate([np.full(program.A_ub.shape[0], -np.inf), b_eq]),
        np.concatenate([np.asarray(program.b_ub, dtype=float), b_eq]),
        rows.indptr.astype(np.int32),
        rows.indices.astype(np.int32),
        rows.data.astype(float),
        kinds,  # HiGHS's variable types: 0 continuous, 1 integer
    )
    if status != highspy.HighsStatus.kOk:
        raise SolverError(f"{HighsSolver.name}: HiGHS rejected the program's model")


_MODEL_STATUSES: dict[str, SolveStatus] = {
    "kOptimal": SolveStatus.OPTIMAL,
    "kInfeasible": SolveStatus.INFEASIBLE,
    "kUnbounded": SolveStatus.UNBOUNDED,
    "kTimeLimit": SolveStatus.TIME_LIMIT,
    "kIterationLimit": SolveStatus.WORK_LIMIT,
}


class HighsRelaxation:
    """The LP relaxation of one program held by HiGHS, solved for equality right-hand
    sides that may change between solves, each solve warm-started from the last basis.

    Built by :meth:`HighsSolver.relaxation_sequence` (and, for one solve, by
    :meth:`HighsSolver.solve_relaxation`).  The rows are ``A_ub`` (``-inf <= row <=
    b_ub``) then ``A_eq`` (``b_eq <= row <= b_eq``); integrality is ignored.

    Parameters
    ----------
    program : Program
    presolve : bool
        Whether HiGHS presolves the first solve (a warm-started solve skips presolve).
    """

    name = HighsSolver.name

    def __init__(self, program: Program, *, presolve: bool) -> None:
        self.program = program
        self._num_ub = program.A_ub.shape[0]
        self._b_eq = np.array(program.b_eq, dtype=float)
        self._highs: highspy.Highs | None = None
        self._presolve = presolve

    def _model(self) -> highspy.Highs:
        """The HiGHS instance holding the program (built on the first solve)."""
        if self._highs is not None:
            return self._highs
        highs = _silent_highs()
        highs.setOptionValue("presolve", "on" if self._presolve else "off")
        _load_program(highs, self.program, self._b_eq, integrality=None)
        self._highs = highs
        return highs

    def solve(
        self, b_eq: NDArray[np.float64] | None = None, *, time_limit: float | None = None
    ) -> LPResult:
        """Solve the relaxation, with the equality right-hand sides ``b_eq``.

        Parameters
        ----------
        b_eq : ndarray, shape (q,), optional
            Right-hand sides of the ``A_eq`` rows for this solve and the next ones
            (default: as they are, the program's ``b_eq`` at first).
        time_limit : float or None
            Seconds for this solve.

        Returns
        -------
        LPResult
            The relaxation's optimum and duals (``d optimum / d b``) when OPTIMAL.
        """
        limit = validate_time_limit(time_limit)
        started = time.perf_counter()
        new = None if b_eq is None else checked_b_eq(b_eq, self.program)
        if self.program.num_variables == 0:  # HiGHS wants a column; the answer is known
            if new is not None:
                self._b_eq = new
            return self._empty(time.perf_counter() - started)
        highs = self._model()
        if new is not None:
            self._change_equalities(highs, new)
        # HiGHS compares its time limit with the instance's run time summed over solves.
        spent = float(highs.getRunTime())
        highs.setOptionValue("time_limit", math.inf if limit is None else spent + limit)
        highs.run()
        seconds = time.perf_counter() - started
        model_status = highs.getModelStatus()
        status = _MODEL_STATUSES.get(model_status.name, SolveStatus.FAILED)
        message = highs.modelStatusToString(model_status)
        if model_status.name == "kUnboundedOrInfeasible" and all_bounds_finite(self.program):
            status = SolveStatus.INFEASIBLE  # every variable is boxed: not unbounded
            message += "; all variables have finite bounds, so the LP is infeasible"
        solution = highs.getSolution()
        if status is not SolveStatus.OPTIMAL or not (solution.value_valid and solution.dual_valid):
            if status is SolveStatus.OPTIMAL:
                raise SolverError(f"{self.name}: an OPTIMAL LP came without its point or duals")
            return LPResult(
                status=status,
                objective=math.nan,
                solution=None,
                solve_seconds=seconds,
                solver=self.name,
                message=message,
                bound=math.nan,
            )
        value = -float(highs.getInfo().objective_function_value) + self.program.constant
        duals = -np.asarray(solution.row_dual, dtype=float)
        return LPResult(
            status=status,
            objective=value,
            solution=np.asarray(solution.col_value, dtype=float),
            solve_seconds=seconds,
            solver=self.name,
            message=message,
            bound=value,
            ineq_duals=duals[: self._num_ub],
            eq_duals=duals[self._num_ub :],
        )

    def _empty(self, seconds: float) -> LPResult:
        """The relaxation of a program without variables: its constant, or infeasible."""
        program = replace(self.program, b_eq=self._b_eq)
        if not empty_program_is_feasible(program, 1e-9):
            return LPResult(
                status=SolveStatus.INFEASIBLE,
                objective=math.nan,
                solution=None,
                solve_seconds=seconds,
                solver=self.name,
                message="program has no variables and its right-hand sides exclude 0",
                bound=math.nan,
            )
        return LPResult(
            status=SolveStatus.OPTIMAL,
            objective=program.constant,
            solution=np.zeros(0),
            solve_seconds=seconds,
            solver=self.name,
            message="program has no variables; the empty point is feasible",
            bound=program.constant,
            ineq_duals=np.zeros(self._num_ub),
            eq_duals=np.zeros(self._b_eq.shape[0]),
        )

    def _change_equalities(self, highs: highspy.Highs, new: NDArray[np.float64]) -> None:
        """Set the ``A_eq`` rows' right-hand sides to ``new`` (only the changed rows); the
        sequence keeps ``new`` (a checked copy, :func:`checked_b_eq`)."""
        changed = np.flatnonzero(new != self._b_eq)
        for row in changed.tolist():  # one row, the cardinality row, in a walk over k
            value = float(new[row])
            highs.changeRowBounds(self._num_ub + row, value, value)
        self._b_eq = new
