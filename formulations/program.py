"""Solver-neutral programs.

:class:`Program` is a mixed-integer linear program in the form the solvers of
:mod:`mapassoc.solvers` accept::

    maximise    objective @ x + constant
    subject to  A_ub @ x <= b_ub
                A_eq @ x == b_eq
                lower <= x <= upper
                x[i] integer where integrality[i]

:class:`FlowProgram` is a min-cost flow network solved for every flow value
0..max_flow.  Neither type knows about tracks: formulations build them and decode
solutions; solvers only see arrays.  This module imports no solver library.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

__all__ = ["Program", "FlowProgram", "lagrangian_bound", "lagrangian_terms"]


def _frozen(a: NDArray) -> NDArray:
    a = np.array(a, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Program:
    """A maximisation MILP (or LP when no variable is integral).

    Parameters
    ----------
    objective : ndarray, shape (n,)
        Coefficients c of the objective ``c @ x`` to maximise.
    A_ub : scipy.sparse.csr_array, shape (r, n)
    b_ub : ndarray, shape (r,)
    A_eq : scipy.sparse.csr_array, shape (q, n)
    b_eq : ndarray, shape (q,)
    lower, upper : ndarray, shape (n,)
        Variable bounds.
    integrality : ndarray of bool, shape (n,)
        Which variables must be integer.
    constant : float
        Offset added to the objective value.
    variable_labels : tuple of str, optional
        Human-readable names, for messages and debugging.
    """

    objective: NDArray[np.float64]
    A_ub: sp.csr_array
    b_ub: NDArray[np.float64]
    A_eq: sp.csr_array
    b_eq: NDArray[np.float64]
    lower: NDArray[np.float64]
    upper: NDArray[np.float64]
    integrality: NDArray[np.bool_]
    constant: float = 0.0
    variable_labels: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        c = np.asarray(self.objective, dtype=float)
        n = c.shape[0] if c.ndim == 1 else -1
        if c.ndim != 1:
            raise ValueError(f"objective must be 1-D, got shape {c.shape}")
        if not np.all(np.isfinite(c)):
            raise ValueError("objective must be finite")
        A_ub = sp.csr_array(self.A_ub if self.A_ub is not None else (0, n), dtype=float)
        A_eq = sp.csr_array(self.A_eq if self.A_eq is not None else (0, n), dtype=float)
        for name, A, b in (("A_ub", A_ub, self.b_ub), ("A_eq", A_eq, self.b_eq)):
            b = np.asarray(b, dtype=float)
            if A.shape[1] != n or b.shape != (A.shape[0],):
                raise ValueError(
                    f"{name} must be ({b.shape[0] if b.ndim else '?'}, {n}) with a matching "
                    f"right-hand side, got {A.shape} and {b.shape}"
                )
        lower = np.asarray(self.lower, dtype=float)
        upper = np.asarray(self.upper, dtype=float)
        integ = np.asarray(self.integrality, dtype=bool)
        for name, a in (("lower", lower), ("upper", upper), ("integrality", integ)):
            if a.shape != (n,):
                raise ValueError(f"{name} must have shape ({n},), got {a.shape}")
        if np.any(lower > upper):
            raise ValueError("lower bounds must not exceed upper bounds")
        if self.variable_labels and len(self.variable_labels) != n:
            raise ValueError(f"variable_labels must have {n} entries")
        object.__setattr__(self, "objective", _frozen(c))
        object.__setattr__(self, "A_ub", A_ub)
        object.__setattr__(self, "A_eq", A_eq)
        object.__setattr__(self, "b_ub", _frozen(np.asarray(self.b_ub, dtype=float)))
        object.__setattr__(self, "b_eq", _frozen(np.asarray(self.b_eq, dtype=float)))
        object.__setattr__(self, "lower", _frozen(lower))
        object.__setattr__(self, "upper", _frozen(upper))
        object.__setattr__(self, "integrality", _frozen(integ))
        object.__setattr__(self, "constant", float(self.constant))

    @property
    def num_variables(self) -> int:
        return int(self.objective.shape[0])

    @property
    def is_integer(self) -> bool:
        """Whether any variable is integral (a MILP rather than an LP)."""
        return bool(np.any(self.integrality))

    @property
    def is_binary(self) -> bool:
        """Whether every variable is integral with bounds within [0, 1]."""
        return bool(
            np.all(self.integrality) and np.all(self.lower >= 0) and np.all(self.upper <= 1)
        )

    def relaxed(self) -> Program:
        """The linear-programming relaxation (integrality dropped, bounds kept)."""
        return replace(self, integrality=np.zeros(self.num_variables, dtype=bool))

    def with_constraints(
        self,
        *,
        A_ub: sp.csr_array | None = None,
        b_ub: NDArray[np.float64] | None = None,
        A_eq: sp.csr_array | None = None,
        b_eq: NDArray[np.float64] | None = None,
    ) -> Program:
        """A copy with extra rows appended to the inequality and/or equality blocks."""
        new_ub, new_bub = self.A_ub, self.b_ub
        if A_ub is not None:
            new_ub = sp.vstack([self.A_ub, sp.csr_array(A_ub)], format="csr")
            new_bub = np.concatenate([self.b_ub, np.asarray(b_ub, dtype=float)])
        new_eq, new_beq = self.A_eq, self.b_eq
        if A_eq is not None:
            new_eq = sp.vstack([self.A_eq, sp.csr_array(A_eq)], format="csr")
            new_beq = np.concatenate([self.b_eq, np.asarray(b_eq, dtype=float)])
        return replace(self, A_ub=new_ub, b_ub=new_bub, A_eq=new_eq, b_eq=new_beq)

    def is_feasible(self, x: NDArray[np.float64], tol: float = 1e-7) -> bool:
        """Whether ``x`` satisfies every constraint, bound and integrality to ``tol``."""
        x = np.asarray(x, dtype=float)
        if x.shape != (self.num_variables,):
            return False
        if np.any(x < self.lower - tol) or np.any(x > self.upper + tol):
            return False
        if np.any(np.abs(x[self.integrality] - np.round(x[self.integrality])) > tol):
            return False
        if self.A_ub.shape[0] and np.any(self.A_ub @ x > self.b_ub + tol):
            return False
        return not (self.A_eq.shape[0] and np.any(np.abs(self.A_eq @ x - self.b_eq) > tol))

    def value(self, x: NDArray[np.float64]) -> float:
        """Objective value ``objective @ x + constant``."""
        return float(self.objective @ np.asarray(x, dtype=float) + self.constant)


@dataclass(frozen=True, eq=False)
class FlowProgram:
    """A min-cost flow network from ``source`` to ``sink``, solved for each flow 0..max_flow.

    Parameters
    ----------
    num_nodes : int
        Nodes are ``0..num_nodes-1``.
    source, sink : int
    tails, heads : ndarray of int, shape (E,)
        Directed edges ``tails[e] -> heads[e]``.
    capacities : ndarray of int, shape (E,)
        Edge capacities (>= 0).
    costs : ndarray of float, shape (E,)
        Cost per unit of flow on each edge (to minimise).
    max_flow : int
        Largest flow value asked for.
    """

    num_nodes: int
    source: int
    sink: int
    tails: NDArray[np.int64]
    heads: NDArray[np.int64]
    capacities: NDArray[np.int64]
    costs: NDArray[np.float64]
    max_flow: int

    def __post_init__(self) -> None:
        tails = np.asarray(self.tails, dtype=np.int64)
        heads = np.asarray(self.heads, dtype=np.int64)
        caps = np.asarray(self.capacities, dtype=np.int64)
        costs = np.asarray(self.costs, dtype=float)
        E = tails.shape[0]
        for name, a in (("heads", heads), ("capacities", caps), ("costs", costs)):
            if a.shape != (E,):
                raise ValueError(f"{name} must have shape ({E},), got {a.shape}")
        if E and (
            min(tails.min(), heads.min()) < 0 or max(tails.max(), heads.max()) >= self.num_nodes
        ):
            raise ValueError("edge endpoints must be node indices in 0..num_nodes-1")
        if np.any(caps < 0) or not np.all(np.isfinite(costs)):
            raise ValueError("capacities must be >= 0 and costs finite")
        if not (0 <= self.source < self.num_nodes and 0 <= self.sink < self.num_nodes):
            raise ValueError("source and sink must be node indices")
        if self.source == self.sink or self.max_flow < 0:
            raise ValueError("source and sink must differ and max_flow must be >= 0")
        object.__setattr__(self, "tails", _frozen(tails))
        object.__setattr__(self, "heads", _frozen(heads))
        object.__setattr__(self, "capacities", _frozen(caps))
        object.__setattr__(self, "costs", _frozen(costs))

    @property
    def num_edges(self) -> int:
        return int(self.tails.shape[0])


def lagrangian_terms(
    program: Program,
    ineq_duals: NDArray[np.float64],
    eq_duals: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Multipliers and reduced objective of the Lagrangian of ``program``.

    For ``y >= 0`` (one per ``A_ub`` row) and any ``w`` (one per ``A_eq`` row), every
    feasible ``x`` has ``c x <= b_ub y + b_eq w + r x`` with ``r = c - A_ubᵀ y - A_eqᵀ w``
    (weak duality).  Negative entries of ``ineq_duals`` (solver round-off) are replaced by
    0: any non-negative multipliers give a valid bound.

    Returns
    -------
    y : ndarray, shape (r,)
        ``max(ineq_duals, 0)``.
    w : ndarray, shape (q,)
    reduced : ndarray, shape (n,)
        ``r``.

    Raises
    ------
    ValueError
        Wrong shapes or non-finite multipliers.
    """
    y = np.asarray(ineq_duals, dtype=float)
    w = np.asarray(eq_duals, dtype=float)
    if y.shape != (program.A_ub.shape[0],) or w.shape != (program.A_eq.shape[0],):
        raise ValueError(
            f"ineq_duals must have shape ({program.A_ub.shape[0]},) and eq_duals "
            f"({program.A_eq.shape[0]},), got {y.shape} and {w.shape}"
        )
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(w))):
        raise ValueError("duals must be finite")
    y_nonnegative = np.maximum(y, 0.0)
    reduced = program.objective - program.A_ub.T @ y_nonnegative - program.A_eq.T @ w
    return y_nonnegative, w, reduced


def lagrangian_bound(
    program: Program,
    ineq_duals: NDArray[np.float64],
    eq_duals: NDArray[np.float64],
) -> float:
    """Upper bound on the program's optimum from any multipliers (weak duality).

    ::

        max {c x + const : A_ub x <= b_ub, A_eq x = b_eq, l <= x <= u}
            <= const + b_ub y + b_eq w + Σ_i max_{l_i <= x_i <= u_i} r_i x_i,

    with ``y, w, r`` of :func:`lagrangian_terms`; it also bounds the integer optimum.

    Returns
    -------
    float
        The bound; ``inf`` if some ``r_i`` pushes towards an infinite variable bound.
    """
    y, w, reduced = lagrangian_terms(program, ineq_duals, eq_duals)
    box_terms = np.zeros(program.num_variables)
    up, down = reduced > 0, reduced < 0
    with np.errstate(invalid="ignore"):
        box_terms[up] = reduced[up] * program.upper[up]
        box_terms[down] = reduced[down] * program.lower[down]
    return float(
        math.fsum(
            [
                program.constant,
                float(program.b_ub @ y),
                float(program.b_eq @ w),
                *box_terms.tolist(),
            ]
        )
    )
