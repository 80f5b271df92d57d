"""Solver backends for the programs of :mod:`mapassoc.formulations`.

Backends (one module each) consume :class:`~mapassoc.formulations.program.Program` /
:class:`~mapassoc.formulations.program.FlowProgram` and know nothing about tracks:

* :class:`HighsSolver` (``"highs"``): HiGHS, exact MILP (``scipy.optimize.milp``) and LP
  relaxations (``highspy``, warm-started when only equality right-hand sides change).
* :class:`CvxpySolver` (``"cvxpy-clarabel"``, ``"cvxpy-highs"``): cvxpy; Clarabel for LP
  bounds and duals (interior point: midpoints on ties), HiGHS for MILPs.
* :class:`EnumerationSolver` (``"enumeration"``): exact oracle for small binary programs,
  with the partition function ``log Σ exp(value)`` and the feasible count.
* :class:`NetworkxFlowSolver` (``"networkx-flow"``): min-cost flow for every K.
* :func:`solve_k_best`: the m best distinct points of a binary program by no-good cuts.

One table, :data:`SOLVERS` (:mod:`mapassoc.solvers.registry`), names every backend with
its capabilities; :func:`get_solver` builds one.  Backends with ``supports_relaxation``
are :class:`RelaxationSolver`: ``solve_relaxation`` returns the LP relaxation with duals;
:func:`relaxation_sequence` keeps one relaxation for solves with other equality
right-hand sides (warm-started where the backend can).
Optional libraries (cvxpy, networkx) are imported on first use, not by this package.

Infeasible, unbounded and limited solves are :class:`SolveStatus` values; only a broken
or misused backend raises :class:`SolverError`.
"""

from mapassoc.solvers.cvxpy_backend import CvxpySolver, lagrangian_bound
from mapassoc.solvers.enumeration import EnumerationSolver, enumerate_feasible
from mapassoc.solvers.highs import HighsSolver
from mapassoc.solvers.k_best import no_good_cut, solve_k_best
from mapassoc.solvers.networkx_flow import NetworkxFlowSolver
from mapassoc.solvers.registry import (
    SOLVER_NAMES,
    SOLVERS,
    SolverSpec,
    available_solvers,
    get_integer_solver,
    get_solver,
    solver_spec,
)
from mapassoc.solvers.relaxation_sequences import (
    ColdRelaxationSequence,
    RelaxationSequence,
    relaxation_sequence,
)
from mapassoc.solvers.results import (
    EnumerationResult,
    FlowResult,
    FlowSolver,
    LPResult,
    ProgramSolver,
    RelaxationSolver,
    SolverError,
    SolveResult,
    SolveStatus,
)

__all__ = [
    "ColdRelaxationSequence",
    "CvxpySolver",
    "EnumerationResult",
    "EnumerationSolver",
    "FlowResult",
    "FlowSolver",
    "HighsSolver",
    "LPResult",
    "NetworkxFlowSolver",
    "ProgramSolver",
    "RelaxationSequence",
    "RelaxationSolver",
    "SOLVERS",
    "SOLVER_NAMES",
    "SolveResult",
    "SolveStatus",
    "SolverError",
    "SolverSpec",
    "available_solvers",
    "enumerate_feasible",
    "get_integer_solver",
    "get_solver",
    "lagrangian_bound",
    "no_good_cut",
    "relaxation_sequence",
    "solve_k_best",
    "solver_spec",
]
