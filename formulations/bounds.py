"""Upper bounds from LP duals, for pruning hypotheses that cannot be in a good set.

For a maximisation program with binary bounds and any multipliers ``y >= 0`` (rows of
``A_ub``) and ``w`` (rows of ``A_eq``), weak duality gives, for every feasible ``x``::

    c x = d x + y A_ub x + w A_eq x <= d x + y b_ub + w b_eq,   d = c - A_ubᵀ y - A_eqᵀ w

so a feasible point with ``x_h = 1`` scores at most
``y b_ub + w b_eq + sum_i max(d_i, 0) - max(d_h, 0) + d_h`` — the Lagrangian bound with
variable h fixed to 1.  With the optimal LP duals this is the classical reduced-cost
bound of integer programming.  Negative ``y`` entries (solver round-off) are replaced by
0 for the evaluation: any non-negative multipliers give a valid bound.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from mapassoc.formulations.program import Program

__all__ = ["fixed_variable_bounds"]


def fixed_variable_bounds(
    program: Program, ineq_duals: NDArray[np.float64], eq_duals: NDArray[np.float64]
) -> NDArray[np.float64]:
    """For each variable h, an upper bound on the objective of any feasible x with x_h = 1.

    Parameters
    ----------
    program : Program
        Variables bounded in [0, 1].
    ineq_duals : ndarray, shape (r,)
        Multipliers of the ``A_ub`` rows (``d optimum / d b_ub``).
    eq_duals : ndarray, shape (q,)
        Multipliers of the ``A_eq`` rows.

    Returns
    -------
    ndarray, shape (n,)
        Includes ``program.constant``.
    """
    y = np.maximum(np.asarray(ineq_duals, dtype=float), 0.0)
    w = np.asarray(eq_duals, dtype=float)
    if y.shape != (program.A_ub.shape[0],) or w.shape != (program.A_eq.shape[0],):
        raise ValueError(
            f"ineq_duals must have shape ({program.A_ub.shape[0]},) and eq_duals "
            f"({program.A_eq.shape[0]},), got {y.shape} and {w.shape}"
        )
    if np.any(program.lower < 0) or np.any(program.upper > 1):
        raise ValueError("fixed_variable_bounds needs every variable bounded in [0, 1]")
    d = program.objective - program.A_ub.T @ y - program.A_eq.T @ w
    total = float(y @ program.b_ub + w @ program.b_eq + np.sum(np.maximum(d, 0.0)))
    return total - np.maximum(d, 0.0) + d + program.constant
