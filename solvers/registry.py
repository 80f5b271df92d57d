"""Solver names, capabilities, availability and construction: one table, :data:`SOLVERS`.

Each :class:`SolverSpec` row names a backend, the module and class that build it (imported
only when the solver is built), the libraries it needs at solve time and its
capabilities.  :data:`SOLVER_NAMES`, :func:`available_solvers`, :func:`get_solver` and
their error messages all derive from it:

========================  ==========================  =======  ====  ==========  =====  ========
name                      class                       integer  flow  relaxation  exact  optional
========================  ==========================  =======  ====  ==========  =====  ========
``"highs"``               HighsSolver                 yes      no    yes         yes    no
``"cvxpy-clarabel"``      CvxpySolver("CLARABEL")     no       no    yes         no     yes
``"cvxpy-highs"``         CvxpySolver("HIGHS")        yes      no    yes         yes    yes
``"enumeration"``         EnumerationSolver           binary   no    no          yes    no
``"networkx-flow"``       NetworkxFlowSolver          no       yes   no          yes    yes
========================  ==========================  =======  ====  ==========  =====  ========

Program solvers expose ``.solve(program, *, time_limit=None)``; those with
``supports_relaxation`` also ``.solve_relaxation(program, *, time_limit=None)`` (an LP
relaxation with duals, see :class:`~mapassoc.solvers.results.RelaxationSolver`); the flow
solver exposes ``.solve_flow(flow_program, *, time_limit=None)``.  Every solver carries
``name``, ``supports_integer``, ``supports_flow``, ``supports_relaxation`` and ``exact``,
equal to its row here.  Optional backends' libraries (cvxpy, networkx) are imported only
when such a solver is built or used, or by :func:`available_solvers`.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, cast

if TYPE_CHECKING:
    from mapassoc.solvers.cvxpy_backend import CvxpySolver
    from mapassoc.solvers.enumeration import EnumerationSolver
    from mapassoc.solvers.highs import HighsSolver
    from mapassoc.solvers.networkx_flow import NetworkxFlowSolver
    from mapassoc.solvers.results import ProgramSolver

__all__ = [
    "SOLVERS",
    "SOLVER_NAMES",
    "SolverSpec",
    "available_solvers",
    "get_integer_solver",
    "get_solver",
    "solver_spec",
]


@dataclass(frozen=True)
class SolverSpec:
    """One registered backend.

    Attributes
    ----------
    name : str
        Registry name (also the instance's ``name``).
    module, class_name : str
        Where the backend class lives; imported by :meth:`build` only.
    options : Mapping
        Keyword arguments of the class for this name.
    requires : tuple of str
        Modules the backend needs at solve time (checked by :func:`available_solvers`).
    supports_integer, supports_flow, supports_relaxation, exact : bool
        The instance's capability flags (see :class:`~mapassoc.solvers.ProgramSolver`).
    optional : bool
        Whether the backend's library is an optional dependency, imported lazily.
    """

    name: str
    module: str
    class_name: str
    requires: tuple[str, ...]
    supports_integer: bool
    supports_flow: bool
    supports_relaxation: bool
    exact: bool
    optional: bool
    options: Mapping[str, Any] = field(default_factory=dict)

    def missing_modules(self) -> list[str]:
        """The modules of :attr:`requires` that do not import on this machine."""
        return [m for m in self.requires if not _importable(m)]

    def build(self) -> HighsSolver | CvxpySolver | EnumerationSolver | NetworkxFlowSolver:
        """A new instance of the backend with this row's options."""
        cls = getattr(importlib.import_module(self.module), self.class_name)
        return cls(**self.options)


#: Every registered backend, in preference order.
SOLVERS: tuple[SolverSpec, ...] = (
    SolverSpec(
        name="highs",
        module="mapassoc.solvers.highs",
        class_name="HighsSolver",
        requires=("scipy.optimize",),
        supports_integer=True,
        supports_flow=False,
        supports_relaxation=True,
        exact=True,
        optional=False,
    ),
    SolverSpec(
        name="cvxpy-clarabel",
        module="mapassoc.solvers.cvxpy_backend",
        class_name="CvxpySolver",
        options=MappingProxyType({"backend": "CLARABEL"}),
        requires=("cvxpy", "clarabel"),
        supports_integer=False,
        supports_flow=False,
        supports_relaxation=True,
        exact=False,
        optional=True,
    ),
    SolverSpec(
        name="cvxpy-highs",
        module="mapassoc.solvers.cvxpy_backend",
        class_name="CvxpySolver",
        options=MappingProxyType({"backend": "HIGHS"}),
        requires=("cvxpy", "highspy"),
        supports_integer=True,
        supports_flow=False,
        supports_relaxation=True,
        exact=True,
        optional=True,
    ),
    SolverSpec(
        name="enumeration",
        module="mapassoc.solvers.enumeration",
        class_name="EnumerationSolver",
        requires=(),
        supports_integer=True,
        supports_flow=False,
        supports_relaxation=False,
        exact=True,
        optional=False,
    ),
    SolverSpec(
        name="networkx-flow",
        module="mapassoc.solvers.networkx_flow",
        class_name="NetworkxFlowSolver",
        requires=("networkx",),
        supports_integer=False,
        supports_flow=True,
        supports_relaxation=False,
        exact=True,
        optional=True,
    ),
)

_BY_NAME: Mapping[str, SolverSpec] = MappingProxyType({spec.name: spec for spec in SOLVERS})

#: Every solver name this package knows, in preference order.
SOLVER_NAMES: tuple[str, ...] = tuple(_BY_NAME)


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
    return [spec.name for spec in SOLVERS if not spec.missing_modules()]


def solver_spec(name: str) -> SolverSpec:
    """The registry row of ``name``.

    Raises
    ------
    ValueError
        Unknown name; the message lists the available names.
    """
    spec = _BY_NAME.get(name)
    if spec is None:
        raise ValueError(
            f"unknown solver {name!r}; available solvers: {', '.join(available_solvers())}"
        )
    return spec


def get_solver(
    name: str,
) -> HighsSolver | CvxpySolver | EnumerationSolver | NetworkxFlowSolver:
    """A solver instance with default settings.

    Only the requested backend's libraries are imported (an unknown or unavailable name
    imports every backend's, to list the available ones).

    Parameters
    ----------
    name : str
        One of :func:`available_solvers`.

    Raises
    ------
    ValueError
        Unknown or unavailable name; the message lists the available names.
    """
    spec = solver_spec(name)
    missing = spec.missing_modules()
    if missing:
        raise ValueError(
            f"solver {name!r} is unavailable (cannot import {', '.join(missing)}); "
            f"available solvers: {', '.join(available_solvers())}"
        )
    return spec.build()


def get_integer_solver(name: str, *, exact: bool = False) -> ProgramSolver:
    """A backend that solves integer programs (``supports_integer``), with default settings.

    Parameters
    ----------
    name : str
        One of :func:`available_solvers`.
    exact : bool
        Also require ``exact`` (an OPTIMAL status is a proven optimum at an integer point).

    Raises
    ------
    ValueError
        Unknown or unavailable name, or a backend without the capabilities; the message
        names the backends that have them.
    """
    spec = solver_spec(name)
    if not spec.supports_integer or (exact and not spec.exact):
        wanted = "an exact solver of integer programs" if exact else "a solver of integer programs"
        capable = [s.name for s in SOLVERS if s.supports_integer and (s.exact or not exact)]
        raise ValueError(f"solver {name!r} is not {wanted}; choose one of {', '.join(capable)}")
    # The row's capability flags say the backend implements ProgramSolver.
    return cast("ProgramSolver", get_solver(name))
