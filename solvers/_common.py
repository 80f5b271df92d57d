"""Helpers shared by the backends (private)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mapassoc.formulations.program import Program
from mapassoc.solvers.results import SolverError

#: Largest distance from an integer that a backend may return for an integer variable
#: (HiGHS's default ``mip_feasibility_tolerance``).  Farther means the backend is broken.
INTEGRALITY_TOLERANCE = 1e-6


def all_bounds_finite(program: Program) -> bool:
    """Whether every variable has finite lower and upper bounds (so no ray is unbounded)."""
    return bool(np.all(np.isfinite(program.lower)) and np.all(np.isfinite(program.upper)))


def integrality_violation(program: Program, x: NDArray[np.float64]) -> float:
    """Largest distance of an integer variable of ``x`` (shape (n,)) from an integer."""
    values = np.asarray(x, dtype=float)[program.integrality]
    return float(np.max(np.abs(values - np.round(values)), initial=0.0))


def snap_integer_variables(
    program: Program, x: NDArray[np.float64], backend: str
) -> NDArray[np.float64]:
    """Round the integer variables of a backend's point to exact integers.

    Parameters
    ----------
    program : Program
    x : ndarray, shape (n,)
        Point returned by the backend.
    backend : str
        Name used in the error message.

    Returns
    -------
    ndarray, shape (n,)
        ``x`` with ``x[program.integrality]`` rounded and ``-0.0`` normalised to ``0.0``.

    Raises
    ------
    SolverError
        If an integer variable is farther than :data:`INTEGRALITY_TOLERANCE` from an
        integer: the backend did not honour integrality.
    """
    point = np.array(x, dtype=float, copy=True)
    if point.shape != (program.num_variables,):
        raise SolverError(
            f"{backend}: returned a point of shape {point.shape}, expected "
            f"({program.num_variables},)"
        )
    worst = integrality_violation(program, point)
    if worst > INTEGRALITY_TOLERANCE:
        raise SolverError(
            f"{backend}: an integer variable is {worst:.3g} from an integer, more than the "
            f"integrality tolerance {INTEGRALITY_TOLERANCE}"
        )
    point[program.integrality] = np.round(point[program.integrality])
    return point + 0.0  # normalises -0.0 to 0.0


def empty_program_is_feasible(program: Program, tolerance: float) -> bool:
    """Whether a program with no variables is feasible: ``0 <= b_ub`` and ``0 == b_eq``.

    Parameters
    ----------
    program : Program
        Must have ``num_variables == 0`` (the backends' solver libraries reject it).
    tolerance : float
        Feasibility tolerance on the right-hand sides.
    """
    return bool(
        np.all(program.b_ub >= -tolerance) and np.all(np.abs(program.b_eq) <= tolerance)
    )
