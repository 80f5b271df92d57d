"""The m best distinct feasible points of a binary program by no-good cuts.

After a solve returns the optimum ``x*`` with support ``S = {i : x*_i = 1}``, the cut

    Σ_{i in S} x_i - Σ_{i not in S} x_i <= |S| - 1

removes exactly the point ``x*`` from the binary feasible set (every other 0/1 point
differs from ``x*`` in some coordinate and so satisfies it), and the program is
re-solved.  The optimum of the j-th program is therefore the j-th best objective value
of the original, and the objectives come out non-increasing.  Each step adds one dense
row, so this suits small m on small programs; the solver must be exact (a MILP optimum,
not an interior-point midpoint).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from mapassoc.formulations.program import Program
from mapassoc.solvers.results import (
    ProgramSolver,
    SolverError,
    SolveResult,
    SolveStatus,
    validate_time_limit,
)

__all__ = ["solve_k_best", "no_good_cut"]


def no_good_cut(point: np.ndarray) -> tuple[sp.csr_array, np.ndarray]:
    """The row that excludes one 0/1 point and no other.

    Parameters
    ----------
    point : ndarray, shape (n,)
        A 0/1 vector.

    Returns
    -------
    A_row : scipy.sparse.csr_array, shape (1, n)
        ``+1`` where ``point`` is 1, ``-1`` where it is 0.
    b_row : ndarray, shape (1,)
        ``|{i : point_i = 1}| - 1``.
    """
    x = np.asarray(point, dtype=float)
    if x.ndim != 1 or not np.all((x == 0) | (x == 1)):
        raise ValueError(f"point must be a 1-D 0/1 vector, got {x!r}")
    coefficients = np.where(x == 1, 1.0, -1.0)
    return sp.csr_array(coefficients[np.newaxis, :]), np.array([x.sum() - 1.0])


def solve_k_best(
    program: Program,
    m: int,
    *,
    solver: ProgramSolver,
    time_limit: float | None = None,
) -> list[SolveResult]:
    """The ``m`` best distinct feasible points of a binary program, best first.

    Parameters
    ----------
    program : Program
        Binary: every variable integer with bounds within [0, 1].
    m : int
        How many points to find (>= 1).
    solver : ProgramSolver
        An ``exact`` backend that supports integer programs (``"highs"``,
        ``"cvxpy-highs"``, ``"enumeration"``).
    time_limit : float or None
        Total wall-clock budget in seconds, shared by the successive solves (each gets
        what remains).

    Returns
    -------
    list of SolveResult
        Up to ``m`` OPTIMAL results with non-increasing objectives and distinct solutions.
        The list is shorter when the program has fewer than ``m`` feasible points (the
        INFEASIBLE solve that showed it is not included).  Any other non-OPTIMAL outcome
        (TIME_LIMIT, WORK_LIMIT, FAILED, ...) stops the search and is returned as the last
        element; an exhausted budget appears as a TIME_LIMIT result with no solution.

    Raises
    ------
    ValueError
        If ``m < 1`` or the program is not binary.
    SolverError
        If ``solver`` is not exact or does not support integer programs.
    """
    if int(m) != m or m < 1:
        raise ValueError(f"m must be an integer >= 1, got {m!r}")
    if not isinstance(program, Program):
        raise TypeError(f"program must be a Program, got {type(program).__name__}")
    if not program.is_binary:
        raise ValueError(
            "program must be binary (every variable integer with bounds within [0, 1]) for "
            "no-good cuts"
        )
    if not (getattr(solver, "exact", False) and getattr(solver, "supports_integer", False)):
        raise SolverError(
            f"{getattr(solver, 'name', type(solver).__name__)}: k-best needs an exact solver "
            "that supports integer programs (e.g. 'highs' or 'enumeration')"
        )
    budget = validate_time_limit(time_limit)
    started = time.perf_counter()
    results: list[SolveResult] = []
    current = program
    for _ in range(int(m)):
        remaining = None
        if budget is not None:
            remaining = budget - (time.perf_counter() - started)
            if remaining <= 0:
                results.append(
                    SolveResult(
                        status=SolveStatus.TIME_LIMIT, objective=float("nan"), solution=None,
                        solve_seconds=0.0, solver=solver.name,
                        message=f"k-best time budget of {budget} s exhausted after "
                        f"{len(results)} solutions",
                    )
                )
                break
        result = solver.solve(current, time_limit=remaining)
        if result.status is SolveStatus.INFEASIBLE:
            break
        results.append(result)
        if result.status is not SolveStatus.OPTIMAL:
            break
        if result.solution is None:
            raise SolverError(f"{solver.name}: an OPTIMAL result without its solution")
        cut_row, cut_rhs = no_good_cut(result.solution)
        current = current.with_constraints(A_ub=cut_row, b_ub=cut_rhs)
    return results
