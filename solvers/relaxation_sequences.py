"""LP relaxations of one program solved again and again with other equality right-hand sides.

A walk over the number of tracks k solves the same LP relaxation with the cardinality
row's right-hand side at k, k + 1, ...: only ``b_eq`` changes.  A backend that can keep
the LP between solves (:meth:`~mapassoc.solvers.HighsSolver.relaxation_sequence`: HiGHS
restarts the dual simplex from the last optimal basis) does the walk in a few simplex
iterations per k; :func:`relaxation_sequence` returns that, or, for any other
:class:`~mapassoc.solvers.RelaxationSolver`, a :class:`ColdRelaxationSequence` that
solves each one from scratch.  Both answer the same LP at every step; on a degenerate LP
the duals may differ (any optimal duals give valid bounds).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from mapassoc.formulations.program import Program
from mapassoc.solvers.results import LPResult, RelaxationSolver

__all__ = [
    "ColdRelaxationSequence",
    "RelaxationSequence",
    "checked_b_eq",
    "relaxation_sequence",
]


class RelaxationSequence(Protocol):
    """The LP relaxation of :attr:`program`, solvable for other equality right-hand sides.

    ``solve(b_eq, time_limit=...)`` solves the relaxation of ``program`` with its
    ``A_eq`` rows' right-hand sides set to ``b_eq`` (shape ``(q,)``; ``None``: as in the
    previous solve, ``program.b_eq`` at first) and returns what
    :meth:`~mapassoc.solvers.RelaxationSolver.solve_relaxation` would for that program.
    """

    program: Program

    def solve(
        self, b_eq: NDArray[np.float64] | None = None, *, time_limit: float | None = None
    ) -> LPResult: ...


class ColdRelaxationSequence:
    """A :class:`RelaxationSequence` for any relaxation backend: every solve from scratch.

    Parameters
    ----------
    solver : RelaxationSolver
    program : Program
    """

    def __init__(self, solver: RelaxationSolver, program: Program) -> None:
        self.solver = solver
        self.program = program
        self._current = program

    def solve(
        self, b_eq: NDArray[np.float64] | None = None, *, time_limit: float | None = None
    ) -> LPResult:
        """Solve the relaxation with ``b_eq`` (see :class:`RelaxationSequence`)."""
        if b_eq is not None:
            self._current = replace(self.program, b_eq=checked_b_eq(b_eq, self.program))
        return self.solver.solve_relaxation(self._current, time_limit=time_limit)


def checked_b_eq(b_eq: NDArray[np.float64], program: Program) -> NDArray[np.float64]:
    """A copy of ``b_eq`` (the caller may reuse its array), after checking that it holds
    one finite value per ``A_eq`` row of ``program``; ValueError naming ``b_eq`` if not."""
    new = np.array(b_eq, dtype=float)
    if new.shape != program.b_eq.shape:
        raise ValueError(
            f"b_eq must have shape {program.b_eq.shape} (one value per A_eq row), got "
            f"shape {new.shape}"
        )
    if not np.all(np.isfinite(new)):
        raise ValueError(f"b_eq must be finite, got {new!r}")
    return new


def relaxation_sequence(solver: RelaxationSolver, program: Program) -> RelaxationSequence:
    """The backend's warm-started :class:`RelaxationSequence` for ``program`` (its
    ``relaxation_sequence`` method), else a :class:`ColdRelaxationSequence`."""
    if not isinstance(program, Program):
        raise TypeError(f"program must be a Program, got {type(program).__name__}")
    build = getattr(solver, "relaxation_sequence", None)
    if callable(build):
        sequence: RelaxationSequence = build(program)
        return sequence
    return ColdRelaxationSequence(solver, program)
