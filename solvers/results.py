"""Result types shared by every solver backend.

A solve never raises because the program is infeasible, unbounded or ran out of time:
those outcomes are :class:`SolveStatus` values.  :class:`SolverError` is raised only when
a backend is missing, broken or misused (for example an integer program handed to a
continuous solver).

Conventions (all backends)
--------------------------
* ``objective`` is the value of ``solution`` for the program as given, *including* its
  ``constant`` (``program.value(solution)``); it is ``nan`` exactly when ``solution`` is
  ``None``.
* ``bound`` is an upper bound on the optimum (the problems are maximisations) that the
  backend proved, including the constant: the MIP dual bound of branch and bound, the LP
  optimum of a simplex solve, a Lagrangian bound computed from interior-point duals.  It is
  ``nan`` when the backend gives none (always for INFEASIBLE and FAILED).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.formulations.program import FlowProgram, Program

__all__ = [
    "SolveStatus",
    "SolveResult",
    "LPResult",
    "EnumerationResult",
    "FlowResult",
    "SolverError",
    "ProgramSolver",
    "RelaxationSolver",
    "FlowSolver",
    "validate_time_limit",
]


class SolverError(RuntimeError):
    """A backend is unavailable, broken or misused.

    The message starts with the backend name (``"highs: ..."``).  Infeasible, unbounded
    and time-limited solves are *not* errors; they are :class:`SolveStatus` values.
    """


class SolveStatus(enum.Enum):
    """How a solve ended.

    OPTIMAL
        The solution is a proven optimum (to the backend's documented tolerance).
    INFEASIBLE
        The backend proved that no point satisfies the constraints.  No solution.
    UNBOUNDED
        The objective is unbounded above on the feasible set.  No solution.
    TIME_LIMIT
        The wall-clock time limit stopped the solve before optimality was proven.
        ``solution`` holds the incumbent if one was found (never claimed optimal) and
        ``bound`` the best proven bound if known.
    WORK_LIMIT
        A work limit other than time stopped the solve before optimality was proven:
        branch-and-bound nodes, solver iterations, or the enumerator's ``node_limit``.
        Same fields as TIME_LIMIT.
    FAILED
        The backend stopped without a trustworthy answer (numerical trouble, an
        "inaccurate" status, an ambiguous "infeasible or unbounded").  ``message`` says
        why; ``solution`` may hold the last iterate for diagnosis only.
    """

    OPTIMAL = "optimal"
    INFEASIBLE = "infeasible"
    UNBOUNDED = "unbounded"
    TIME_LIMIT = "time_limit"
    WORK_LIMIT = "work_limit"
    FAILED = "failed"


def _readonly(array: ArrayLike, dtype: type) -> NDArray[Any]:
    frozen: NDArray[Any] = np.array(array, dtype=dtype, copy=True)
    frozen.setflags(write=False)
    return frozen


def _readonly_or_none(array: ArrayLike | None, dtype: type) -> NDArray[Any] | None:
    return None if array is None else _readonly(array, dtype)


@dataclass(frozen=True, eq=False, kw_only=True)
class SolveResult:
    """Outcome of one solve of a :class:`~mapassoc.formulations.program.Program`.

    Parameters
    ----------
    status : SolveStatus
    objective : float
        ``program.value(solution)`` (constant included); ``nan`` when there is no solution.
    solution : ndarray, shape (n,), or None
        The returned point; integer variables hold exact integers.
    solve_seconds : float
        Wall-clock seconds spent in the backend call (model building included).
    solver : str
        Registry name of the backend (``"highs"``, ``"enumeration"``, ...).
    message : str
        Human-readable detail from the backend.
    bound : float
        Proven upper bound on the optimum (constant included), ``nan`` when unknown.
    """

    status: SolveStatus
    objective: float
    solution: NDArray[np.float64] | None
    solve_seconds: float
    solver: str
    message: str = ""
    bound: float = math.nan

    def __post_init__(self) -> None:
        if not isinstance(self.status, SolveStatus):
            raise TypeError(f"status must be a SolveStatus, got {self.status!r}")
        object.__setattr__(self, "objective", float(self.objective))
        object.__setattr__(self, "bound", float(self.bound))
        object.__setattr__(self, "solve_seconds", float(self.solve_seconds))
        object.__setattr__(self, "solution", _readonly_or_none(self.solution, np.float64))
        if self.solution is None and not math.isnan(self.objective):
            raise ValueError(
                f"objective must be nan when there is no solution, got {self.objective}"
            )
        if self.solution is not None and self.solution.ndim != 1:
            raise ValueError(f"solution must be 1-D, got shape {self.solution.shape}")
        if self.status is SolveStatus.OPTIMAL and self.solution is None:
            raise ValueError("an OPTIMAL result must carry a solution")

    @property
    def is_optimal(self) -> bool:
        """Whether the status is :attr:`SolveStatus.OPTIMAL`."""
        return self.status is SolveStatus.OPTIMAL

    @property
    def has_solution(self) -> bool:
        """Whether a point (optimal or incumbent) is attached."""
        return self.solution is not None


@dataclass(frozen=True, eq=False, kw_only=True)
class LPResult(SolveResult):
    """A :class:`SolveResult` with the constraint duals of a continuous solve.

    Parameters
    ----------
    ineq_duals : ndarray, shape (r,), or None
        One multiplier per row of ``A_ub``: the sensitivity of the optimum to ``b_ub``
        (``d optimum / d b_ub[i]``), so ``>= 0`` up to solver tolerance.  ``None`` for
        integer programs and when the solve did not end OPTIMAL.
    eq_duals : ndarray, shape (q,), or None
        One multiplier per row of ``A_eq``: ``d optimum / d b_eq[j]`` (any sign).
    """

    ineq_duals: NDArray[np.float64] | None = None
    eq_duals: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "ineq_duals", _readonly_or_none(self.ineq_duals, np.float64))
        object.__setattr__(self, "eq_duals", _readonly_or_none(self.eq_duals, np.float64))


@dataclass(frozen=True, eq=False, kw_only=True)
class EnumerationResult(SolveResult):
    """A :class:`SolveResult` with the partition function of a binary program.

    Parameters
    ----------
    log_sum_exp : float
        ``log Σ_x exp(program.value(x))`` over every feasible 0/1 point ``x`` (constant
        included); ``-inf`` when infeasible.  When the status is TIME_LIMIT or
        WORK_LIMIT it covers only the points found before stopping (a lower bound).
    num_feasible : int
        Number of feasible points (found before stopping, for TIME_LIMIT/WORK_LIMIT).
    """

    log_sum_exp: float = -math.inf
    num_feasible: int = 0

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "log_sum_exp", float(self.log_sum_exp))
        if self.num_feasible < 0:
            raise ValueError(f"num_feasible must be >= 0, got {self.num_feasible}")


@dataclass(frozen=True, eq=False, kw_only=True)
class FlowResult:
    """Min-cost flows of a :class:`~mapassoc.formulations.program.FlowProgram` for every K.

    Parameters
    ----------
    costs : ndarray, shape (max_flow + 1,)
        ``costs[K]`` is the minimum total cost (float, recomputed from the integer flows
        and the program's float costs) of a flow of value K from source to sink; ``inf``
        where flow K is infeasible, ``nan`` where it was not solved (time limit),
        ``-inf`` where unbounded (only possible with a negative-cost cycle of unbounded
        capacity, which integer capacities exclude).
    edge_flows : ndarray of int64, shape (max_flow + 1, E)
        The optimal flow on each edge for each K (zeros where infeasible or unsolved).
    statuses : tuple of SolveStatus, length max_flow + 1
        OPTIMAL, INFEASIBLE, UNBOUNDED or TIME_LIMIT for each K.
    solve_seconds : float
    solver : str
    message : str
    """

    costs: NDArray[np.float64]
    edge_flows: NDArray[np.int64]
    statuses: tuple[SolveStatus, ...]
    solve_seconds: float
    solver: str
    message: str = ""

    def __post_init__(self) -> None:
        costs = _readonly(self.costs, np.float64)
        flows = _readonly(self.edge_flows, np.int64)
        if costs.ndim != 1 or flows.ndim != 2 or flows.shape[0] != costs.shape[0]:
            raise ValueError(
                f"costs must be (K+1,) and edge_flows (K+1, E), got {costs.shape} and "
                f"{flows.shape}"
            )
        if len(self.statuses) != costs.shape[0]:
            raise ValueError(
                f"statuses must have {costs.shape[0]} entries, got {len(self.statuses)}"
            )
        object.__setattr__(self, "costs", costs)
        object.__setattr__(self, "edge_flows", flows)
        object.__setattr__(self, "statuses", tuple(self.statuses))
        object.__setattr__(self, "solve_seconds", float(self.solve_seconds))

    @property
    def max_flow(self) -> int:
        """The largest flow value solved for."""
        return int(self.costs.shape[0] - 1)


class ProgramSolver(Protocol):
    """What every :class:`Program` backend exposes (see :mod:`mapassoc.solvers.registry`).

    ``supports_integer``: accepts programs with integer variables.  ``exact``: an OPTIMAL
    status is a proven optimum at a vertex / integer point, fit to serve as an oracle and
    for k-best enumeration (interior-point backends are not exact: on ties they return
    the midpoint of the optimal face).  ``supports_relaxation``: the backend also is a
    :class:`RelaxationSolver` (it has ``solve_relaxation``, returning duals).
    """

    name: str
    supports_integer: bool
    supports_flow: bool
    supports_relaxation: bool
    exact: bool

    def solve(self, program: Program, *, time_limit: float | None = None) -> SolveResult: ...


class RelaxationSolver(ProgramSolver, Protocol):
    """A :class:`ProgramSolver` that solves LP relaxations with their duals.

    Backends with ``supports_relaxation = True`` implement it.  ``solve_relaxation``
    ignores the program's integrality and returns an :class:`LPResult` whose
    ``ineq_duals`` / ``eq_duals`` are ``d optimum / d b`` (set when OPTIMAL) and whose
    ``bound`` is a proven upper bound on the relaxation's optimum.
    """

    def solve_relaxation(
        self, program: Program, *, time_limit: float | None = None
    ) -> LPResult: ...


class FlowSolver(Protocol):
    """What a :class:`FlowProgram` backend exposes."""

    name: str
    supports_integer: bool
    supports_flow: bool
    supports_relaxation: bool
    exact: bool

    def solve_flow(
        self, flow_program: FlowProgram, *, time_limit: float | None = None
    ) -> FlowResult: ...


def validate_time_limit(time_limit: float | None) -> float | None:
    """Check a time limit argument.

    Parameters
    ----------
    time_limit : float or None
        Seconds; ``None`` means no limit.

    Returns
    -------
    float or None
        The limit as a float.

    Raises
    ------
    ValueError
        If the limit is not a positive finite number.
    """
    if time_limit is None:
        return None
    limit = float(time_limit)
    if not (math.isfinite(limit) and limit > 0):
        raise ValueError(
            f"time_limit must be a positive finite number of seconds, got {time_limit!r}"
        )
    return limit
