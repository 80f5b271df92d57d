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

from mapassoc.formulations.packing import PackingProblem
from mapassoc.formulations.program import Program, lagrangian_terms

__all__ = [
    "fixed_variable_bounds",
    "greedy_packing",
    "exclusive_groups",
    "log_mass_upper_bounds",
    "relaxed_problem",
]


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
    y, w, d = lagrangian_terms(program, ineq_duals, eq_duals)
    if np.any(program.lower < 0) or np.any(program.upper > 1):
        raise ValueError("fixed_variable_bounds needs every variable bounded in [0, 1]")
    total = float(y @ program.b_ub + w @ program.b_eq + np.sum(np.maximum(d, 0.0)))
    return total - np.maximum(d, 0.0) + d + program.constant


def greedy_packing(
    problem: PackingProblem, priority: NDArray[np.float64]
) -> NDArray[np.int64] | None:
    """A feasible set picked greedily: an incumbent for :func:`fixed_variable_bounds`.

    Hypotheses are taken in decreasing ``priority`` (ties: higher score first, then lower
    index) when none of their resources is taken yet; one with a negative score is
    taken only when it covers a still uncovered exactly-once resource (leaving it out
    could only raise the set's score otherwise).

    Parameters
    ----------
    problem : PackingProblem
    priority : ndarray, shape (H,)
        For instance an LP relaxation's solution.

    Returns
    -------
    ndarray of int or None
        The chosen hypotheses in increasing order; ``None`` when the greedy order leaves
        an exactly-once resource uncovered (no incumbent, not a proof of infeasibility).
    """
    priority = np.asarray(priority, dtype=float)
    H = problem.num_hypotheses
    if priority.shape != (H,) or np.any(np.isnan(priority)):
        raise ValueError(f"priority must have shape ({H},) without NaN, got {priority.shape}")
    taken = np.zeros(problem.num_resources, dtype=bool)
    indptr, indices = problem.resource_indptr, problem.resource_indices
    chosen: list[int] = []
    for h in np.lexsort((np.arange(H), -problem.scores, -priority)).tolist():
        resources = indices[indptr[h] : indptr[h + 1]]
        if taken[resources].any():
            continue
        if problem.scores[h] < 0 and not problem.exactly_one[resources].any():
            continue
        taken[resources] = True
        chosen.append(h)
    if not taken[problem.exactly_one].all():
        return None
    return np.sort(np.asarray(chosen, dtype=np.int64))


def exclusive_groups(problem: PackingProblem) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Split the hypotheses into groups of which a feasible set holds at most one each.

    Hypothesis h joins the group of one of its resources (two users of a resource never
    share a set): its exactly-once resource if it has one, else its resource with the
    most users (lowest index on ties).  A hypothesis with no resource is a group alone.

    Returns
    -------
    group_of : ndarray of int, shape (H,)
        Group index of each hypothesis, 0..G-1.
    closed : ndarray of bool, shape (G,)
        Groups of which every feasible set holds *exactly* one: an exactly-once resource
        all of whose users are in the group.
    """
    H = problem.num_hypotheses
    R = problem.num_resources
    usage = np.bincount(problem.resource_indices, minlength=R)
    owner = np.repeat(np.arange(H), np.diff(problem.resource_indptr))
    resources = problem.resource_indices
    # Exactly-once resource (the lowest if several), else the most used (lowest on ties).
    required = np.full(H, R, dtype=np.int64)
    is_required = problem.exactly_one[resources]
    np.minimum.at(required, owner[is_required], resources[is_required])
    rank = usage[resources] * (R + 1) + (R - resources)
    top = np.full(H, -1, dtype=np.int64)
    np.maximum.at(top, owner, rank)
    most_used = np.where(top >= 0, R - top % (R + 1), 0)
    key = np.where(
        required < R, required, np.where(top >= 0, most_used, R + np.arange(H))
    ).astype(np.int64)
    labels, group_of = np.unique(key, return_inverse=True)
    members = np.bincount(group_of, minlength=labels.size)
    closed = np.zeros(labels.size, dtype=bool)
    is_resource = labels < R
    closed[is_resource] = problem.exactly_one[labels[is_resource]] & (
        members[is_resource] == usage[labels[is_resource]]
    )
    return group_of.astype(np.int64), closed


def log_mass_upper_bounds(
    problem: PackingProblem,
    resource_multipliers: NDArray[np.float64],
    count_multiplier: float,
    ks: NDArray[np.int64],
    groups: tuple[NDArray[np.int64], NDArray[np.bool_]] | None = None,
) -> NDArray[np.float64]:
    """Upper bounds on the log-mass of the feasible sets with k counted, for each k in ks.

    For multipliers ``y_r`` (``>= 0`` on at-most-once resources, any sign on
    exactly-once ones) and ``mu``, every feasible set S with k counted satisfies
    ``sum_h∈S w_h <= sum_r y_r + mu k + sum_h∈S a_h`` with the reduced log-weights
    ``a_h = w_h - sum_{r used by h} y_r - mu [h counts]`` (the Lagrangian terms
    ``y_r (1 - use_r(S))`` and ``mu (k - count(S))`` are >= 0 and 0).  A feasible set
    holds at most one hypothesis of each group of :func:`exclusive_groups` (exactly
    one of a closed group), so summing ``exp`` over the feasible sets is at most the
    product over groups of ``[not closed] + sum_h∈g exp(a_h)``:

        log_mass[k] <= sum_r y_r + mu k + sum_g log([not closed_g] + sum_h∈g e^(a_h))

    Valid for any such multipliers; LP duals make it tight where the mass is
    concentrated on few sets.  Negative multipliers of at-most-once resources (solver
    round-off) are replaced by 0, which keeps the bound valid.

    Parameters
    ----------
    problem : PackingProblem
    resource_multipliers : ndarray, shape (R,)
    count_multiplier : float
    ks : ndarray of int, shape (m,)
    groups : tuple, optional
        :func:`exclusive_groups` of the problem, when the caller has it already.

    Returns
    -------
    ndarray, shape (m,)
    """
    y = np.asarray(resource_multipliers, dtype=float)
    if y.shape != (problem.num_resources,) or not np.all(np.isfinite(y)):
        raise ValueError(
            f"resource_multipliers must be finite with shape ({problem.num_resources},), "
            f"got {y.shape}"
        )
    y = np.where(problem.exactly_one, y, np.maximum(y, 0.0))
    mu = float(count_multiplier)
    H = problem.num_hypotheses
    owner = np.repeat(np.arange(H), np.diff(problem.resource_indptr))
    charged = np.bincount(owner, weights=y[problem.resource_indices], minlength=H)
    reduced = problem.weights - charged - mu * problem.counts
    group_of, closed = exclusive_groups(problem) if groups is None else groups
    order = np.argsort(group_of, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(group_of[order]) != 0]) if H else np.zeros(0, int)
    group_lse = np.logaddexp.reduceat(reduced[order], starts) if H else np.zeros(0)
    factors = np.where(closed, group_lse, np.logaddexp(0.0, group_lse))
    constant = float(np.sum(y) + np.sum(factors))
    return constant + mu * np.asarray(ks, dtype=float)


def relaxed_problem(
    problem: PackingProblem, relaxed: NDArray[np.bool_], multipliers: NDArray[np.float64]
) -> tuple[PackingProblem, float]:
    """The problem without some resources' constraints, priced by Lagrange multipliers.

    For multipliers ``y_r >= 0`` of the relaxed at-most-once resources, every feasible
    set S of ``problem`` is feasible for the relaxed problem and, since
    ``y_r (1 - use_r(S)) >= 0``,

        sum_h∈S w_h <= sum_r relaxed y_r + sum_h∈S (w_h - sum_{r relaxed, used by h} y_r)

    (likewise for the scores).  So the relaxed problem's per-k best scores and
    log-masses plus the returned constant bound the original's from above, for every k.
    Relaxing the resources that make the frontier search wide keeps the search cheap
    while most constraints stay exact: a Lagrangian relaxation whose subproblem is
    solved exactly (the analogue of mini-bucket elimination for this search).

    Parameters
    ----------
    problem : PackingProblem
    relaxed : ndarray of bool, shape (R,)
        Resources whose constraint is dropped; exactly-once resources may not be relaxed.
    multipliers : ndarray, shape (R,)
        ``y_r`` (only the relaxed entries are used; negative ones are replaced by 0).

    Returns
    -------
    PackingProblem
        Same hypotheses (and indices), without the relaxed resources, scores and
        log-weights reduced by the multipliers of the relaxed resources they use.
    float
        ``sum of y_r`` over the relaxed resources.
    """
    relaxed = np.asarray(relaxed, dtype=bool)
    R = problem.num_resources
    if relaxed.shape != (R,):
        raise ValueError(f"relaxed must have shape ({R},), got {relaxed.shape}")
    if np.any(relaxed & problem.exactly_one):
        raise ValueError("exactly-once resources cannot be relaxed")
    y = np.where(relaxed, np.maximum(np.asarray(multipliers, dtype=float), 0.0), 0.0)
    if y.shape != (R,) or not np.all(np.isfinite(y)):
        raise ValueError(f"multipliers must be finite with shape ({R},)")
    H = problem.num_hypotheses
    owner = np.repeat(np.arange(H), np.diff(problem.resource_indptr))
    charge = np.bincount(owner, weights=y[problem.resource_indices], minlength=H)
    kept_entry = ~relaxed[problem.resource_indices]
    remap = np.full(R, -1, dtype=np.int64)
    remap[~relaxed] = np.arange(int(np.count_nonzero(~relaxed)))
    lengths = np.bincount(owner[kept_entry], minlength=H)
    out = PackingProblem.derived(
        scores=problem.scores - charge,
        resource_indptr=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
        resource_indices=remap[problem.resource_indices[kept_entry]],
        exactly_one=problem.exactly_one[~relaxed],
        counts=problem.counts,
        log_weights=problem.weights - charge,
    )
    return out, float(np.sum(y))
