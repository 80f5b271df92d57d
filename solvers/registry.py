"""Solver names, availability and construction.

========================  ==========================  =======  ====  =====
name                      class                       integer  flow  exact
========================  ==========================  =======  ====  =====
``"highs"``               HighsSolver                 yes      no    yes
``"cvxpy-clarabel"``      CvxpySolver("CLARABEL")     no       no    no
``"cvxpy-highs"``         CvxpySolver("HIGHS")        yes      no    yes
``"enumeration"``         EnumerationSolver           binary   no    yes
``"networkx-flow"``       NetworkxFlowSolver          no       yes   yes
========================  ==========================  =======  ====  =====

Program solvers expose ``.solve(program, *, time_limit=None)``; the flow solver exposes
``.solve_flow(flow_program, *, time_limit=None)``.  Every solver carries ``name``,
``supports_integer``, ``supports_flow`` and ``exact`` (see :class:`ProgramSolver`).
"""

from __future__ import annotations

import importlib

from mapassoc.solvers.cvxpy_backend import CvxpySolver
from mapassoc.solvers.enumeration import EnumerationSolver
from mapassoc.solvers.highs import HighsSolver
from mapassoc.solvers.networkx_flow import NetworkxFlowSolver

__all__ = ["SOLVER_NAMES", "available_solvers", "get_solver"]

#: Every solver name this package knows, in preference order.
SOLVER_NAMES: tuple[str, ...] = (
    "highs",
    "cvxpy-clarabel",
    "cvxpy-highs",
    "enumeration",
    "networkx-flow",
)

# Modules each solver needs at solve time.
_REQUIRED_MODULES: dict[str, tuple[str, ...]] = {
    "highs": ("scipy.optimize",),
    "cvxpy-clarabel": ("cvxpy", "clarabel"),
    "cvxpy-highs": ("cvxpy", "highspy"),
    "enumeration": (),
    "networkx-flow": ("networkx",),
}


def _importable(module: str) -> bool:
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True


def available_solvers() -> list[str]:
    """Names of the solvers whose libraries import on this machine.

    Returns
    -------
    list of str
        A subsequence of :data:`SOLVER_NAMES`.  (Importing cvxpy the first time takes
        about a second.)
    """
    return [
        name for name in SOLVER_NAMES if all(_importable(m) for m in _REQUIRED_MODULES[name])
    ]


def get_solver(
    name: str,
) -> HighsSolver | CvxpySolver | EnumerationSolver | NetworkxFlowSolver:
    """A solver instance with default settings.

    Parameters
    ----------
    name : str
        One of :func:`available_solvers`.

    Raises
    ------
    ValueError
        Unknown or unavailable name; the message lists the available names.
    """
    if name not in SOLVER_NAMES:
        raise ValueError(
            f"unknown solver {name!r}; available solvers: {', '.join(available_solvers())}"
        )
    if name not in available_solvers():
        missing = [m for m in _REQUIRED_MODULES[name] if not _importable(m)]
        raise ValueError(
            f"solver {name!r} is unavailable (cannot import {', '.join(missing)}); "
            f"available solvers: {', '.join(available_solvers())}"
        )
    if name == "highs":
        return HighsSolver()
    if name == "cvxpy-clarabel":
        return CvxpySolver(backend="CLARABEL")
    if name == "cvxpy-highs":
        return CvxpySolver(backend="HIGHS")
    if name == "enumeration":
        return EnumerationSolver()
    return NetworkxFlowSolver()
