"""How sure each track is: posterior marginals of a window's hypotheses, tracks and
detections.

Under the window's posterior (Perry's MAP formulation with labelled targets and a prior
on their number, ``docs/model.md`` eq. (2)) a track set omega with T(omega) tracks has
weight

    p(omega | Z)  ∝  exp(sum_{h in omega} score_h) * W(T(omega)),
    W(T) = sum_K pi(K) / p_birth(K) * Po(K - T; nu),

K summed out over the range :func:`~mapassoc.estimator.posterior.k_posterior` computes
(to double precision: the K it leaves out hold less than 1e-300 of the posterior), so
that ``p(T | Z) ∝ exp(log_mass[T]) W(T)`` is exactly ``KPosterior.track_probabilities``.
(For the ``"birth"`` prior ``W(T)`` is 1 up to the Kmax cut.)  :func:`window_marginals`
computes, for every hypothesis h,

    P(h in omega | Z) = sum_{omega ∋ h} p(omega | Z),

and from them the existence probability of every tree (track), the probability that a
tree used a detection and that a detection was a false alarm.

**How.**  The clusters of the window are independent given T, so a cluster's
hypotheses need only what the rest of the window makes of the cluster's own count k
(:func:`~mapassoc.formulations.marginals.cluster_messages`: the other clusters'
per-k masses convolved and weighted by W), and within a cluster the frontier search
runs forward and backward with that message as its seed
(:func:`~mapassoc.formulations.marginals.frontier_marginals`): about three times the
cost of the cluster's search; an exact cluster of at most
:data:`~mapassoc.formulations.marginals.ENUMERATION_MAX_HYPOTHESES` hypotheses lists its
subsets instead (:func:`~mapassoc.formulations.marginals.enumerated_marginals`, the same
sums).  Hypotheses merged as interchangeable share their merged
node's probability in proportion to ``exp(score)``.

**What is exact and what is bounded.**

* In an exact cluster of an exact window, ``probabilities`` is exact (up to round-off)
  over the hypotheses the window kept, and ``lower == upper == probabilities``.
* A hypothesis dropped by the LP-bound pruning (``ClusterSolver.bound_prune``) has
  probability 0 in the window as solved; its ``upper`` is a proven bound on the
  probability it would have with its cluster's pruned hypotheses restored (the other
  clusters as solved): the mass of the sets holding it is bounded by the Lagrangian
  product bound of its compatible hypotheses
  (:func:`~mapassoc.formulations.bounds.log_mass_upper_bounds`, zero resource
  multipliers, the best of a grid of count multipliers) and set against the mass the
  window summed.  Valid, often loose.
* Where a cluster is only bounded (status ``bounded`` or ``time_limit``), its sets are
  summed by a beam run forward and backward: ``N_h`` (captured mass holding h) and
  ``Z_lo`` (captured mass) are sums over one subset of the feasible sets, and the
  cluster's proven upper bounds per k give ``Z_hi`` and
  ``N_h <= N_h captured + sum_k (upper[k] - captured[k]) * message[k]``.  Then, proven:

      lower = N_h,lo / Z_hi  <=  P(h | Z)  <=  N_h,hi / (N_h,hi + Z_lo - N_h,lo) = upper

  (``Z_lo - N_h,lo`` is the captured mass of the sets *without* h, a lower bound on
  theirs), with the other clusters' messages taken at their lower masses for the lower
  sums and at their upper bounds for the upper ones.  Exact clusters of a window with
  a bounded cluster get the same bounds through their messages.  ``probabilities`` is
  then the posterior among the sets captured (``N_h,lo / Z_lo``), which lies between.
  An upper bound whose ``Z_lo - N_h,lo`` is lost to round-off (h in nearly every
  captured set) is 1.

Tree and detection quantities are sums of hypothesis probabilities over mutually
exclusive hypotheses (a tree holds at most one hypothesis of a set, a detection is used
at most once), so their bounds are the sums of the bounds; an upper sum above 1 is
reported as 1 (a probability is at most 1), never a lower sum.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.errors import InputError
from mapassoc.estimator.cluster_solving import ClusterStatus, WindowCluster
from mapassoc.formulations.bounds import exclusive_groups
from mapassoc.formulations.marginals import (
    ENUMERATION_MAX_HYPOTHESES,
    cluster_messages,
    enumerated_marginals,
    frontier_marginals,
    log_subtract,
)
from mapassoc.formulations.packing import MergedProblem
from mapassoc.log_space import log_sum_exp
from mapassoc.models.population import poisson_log_pmf

if TYPE_CHECKING:
    from mapassoc.estimator.pipeline import WindowSolution

__all__ = [
    "WindowMarginals",
    "window_marginals",
    "track_count_log_weights",
    "DEFAULT_BEAM_WIDTH",
    "DEFAULT_ENTRY_MARGIN",
]

DEFAULT_BEAM_WIDTH = 200
"""Frontiers the beam keeps for a bounded cluster (``EstimatorSettings.beam_width``'s
default)."""

DEFAULT_ENTRY_MARGIN = 40.0
"""The beam drops a frontier's k-entries this many nats below its heaviest one."""

_MU_GRID = np.linspace(-30.0, 30.0, 25)
"""Count multipliers tried for the bound of a pruned hypothesis."""

_ROUND_OFF = 1e-9
"""Relative slack within which a proven upper mass may fall below a captured one."""


@dataclass(frozen=True, eq=False)
class WindowMarginals:
    """Posterior marginals of one window (see the module docstring for what is proven).

    Attributes
    ----------
    probabilities : ndarray, shape (H,)
        P(h in the track set | Z) per hypothesis of ``solution.hypotheses``.
    lower, upper : ndarray, shape (H,)
        Proven bounds on them (equal to ``probabilities`` where exact; ``upper`` of a
        bound-pruned hypothesis bounds the probability it would have unpruned).
    exact : bool
        Whether every kept hypothesis' probability is exact (no bounded cluster).
    pruned : ndarray of bool, shape (H,)
        Hypotheses dropped by the LP-bound pruning (probability 0 as solved).
    tree_existence, tree_existence_lower, tree_existence_upper : ndarray, shape (num_trees,)
        Probability that tree t is a track of the window: the sum over its hypotheses
        that count toward K (a carried tree's "ended before the window" does not).
    association_detection, association_tree : ndarray of int, shape (n,)
        The (detection, tree) pairs some hypothesis uses, sorted by detection then tree.
    association_probability, association_lower, association_upper : ndarray, shape (n,)
        Probability that the tree's track used the detection.
    false_alarm, false_alarm_lower, false_alarm_upper : ndarray, shape (D,)
        Probability that detection d is a false alarm: 1 minus the sum over trees.
    log_total : float
        log of the window's summed weight ``sum_omega exp(score) W(T)`` (the sets
        captured, when bounded).
    seconds : float
        Time taken.
    """

    probabilities: FloatArray
    lower: FloatArray
    upper: FloatArray
    exact: bool
    pruned: NDArray[np.bool_]
    tree_existence: FloatArray
    tree_existence_lower: FloatArray
    tree_existence_upper: FloatArray
    association_detection: IntArray
    association_tree: IntArray
    association_probability: FloatArray
    association_lower: FloatArray
    association_upper: FloatArray
    false_alarm: FloatArray
    false_alarm_lower: FloatArray
    false_alarm_upper: FloatArray
    log_total: float
    seconds: float

    def association_matrix(self, num_detections: int, num_trees: int) -> FloatArray:
        """The association probabilities as a dense array, shape (D, num_trees)."""
        out = np.zeros((num_detections, num_trees))
        out[self.association_detection, self.association_tree] = self.association_probability
        return out


def track_count_log_weights(solution: WindowSolution, length: int) -> FloatArray:
    """``log W(T)`` for T = 0..length-1, with ``W(T) = sum_K pi(K)/p_birth(K) Po(K - T; nu)``.

    K runs over the range of ``solution.posterior`` (its arrays' length): the K that
    :func:`~mapassoc.estimator.posterior.k_posterior` leaves out are proven to hold
    less than 1e-300 of the posterior, so ``exp(log_mass[T]) W(T)`` normalised is its
    ``track_probabilities`` to double precision.

    Returns
    -------
    ndarray, shape (length,)
        ``-inf`` where no K >= T has prior mass.
    """
    post = solution.posterior
    top = post.probabilities.shape[0] - 1
    ratio = post.count_prior.log_ratio(solution.population, top)
    log_po = poisson_log_pmf(np.arange(top + 1, dtype=np.int64), post.undetected_mean)
    out = np.full(length, -math.inf)
    for t in range(min(length, top + 1)):
        terms = ratio[t:] + log_po[: top + 1 - t]
        if np.any(np.isfinite(terms)):
            out[t] = float(log_sum_exp(terms))
    return out


def _padded(values: FloatArray, length: int) -> FloatArray:
    out = np.full(length, -math.inf)
    n = min(length, values.shape[0])
    out[:n] = values[:n]
    return out


@dataclass
class _Factor:
    """One factor of the window product: a part, or one lone hypothesis of a part."""

    part: int
    lower: FloatArray  # per-k log-mass (lower bound)
    upper: FloatArray  # per-k log-mass upper bound
    hypothesis: int = -1  # lone hypothesis (window index) or -1


def window_marginals(
    solution: WindowSolution,
    *,
    beam_width: int = DEFAULT_BEAM_WIDTH,
    entry_margin: float = DEFAULT_ENTRY_MARGIN,
) -> WindowMarginals:
    """Posterior marginals of the hypotheses, trees and detections of a solved window.

    Parameters
    ----------
    solution : WindowSolution
        From :meth:`WindowEstimator.solve_window` (its ``clusters`` records).
    beam_width : int
        Frontiers of the beam run over a bounded cluster.
    entry_margin : float
        Nats below a frontier's heaviest entry at which the beam drops an entry.

    Returns
    -------
    WindowMarginals

    Raises
    ------
    InputError
        The solution carries no cluster records (built by hand, not by
        ``solve_window``).
    """
    started = time.perf_counter()
    hyps = solution.hypotheses
    problem = solution.problem
    H = hyps.count
    covered = sum(p.members.size for p in solution.clusters)
    if covered != H:
        raise InputError(
            f"the solution's cluster records cover {covered} of {H} hypotheses: "
            "window_marginals needs a solution from WindowEstimator.solve_window"
        )
    if beam_width < 1:
        raise InputError(f"beam_width must be >= 1, got {beam_width!r}")
    length = solution.table.kmax + 1
    log_w = track_count_log_weights(solution, length)
    weights = problem.weights
    counts = problem.counts.astype(np.int64)

    # The product's factors, each with its per-k lower and upper log-masses.
    factors: list[_Factor] = []
    for index, part in enumerate(solution.clusters):
        if part.kind == "independent":
            for h in part.members.tolist():
                mass = np.array([0.0, float(weights[h])])
                factors.append(_Factor(index, mass, mass, h))
            continue
        size = part.table.kmax + 1
        if part.kind == "cluster" and part.kept is not None and part.merged is not None:
            # Room for the counts the pruned hypotheses could add (their bounds).
            size = min(length, int(np.count_nonzero(part.merged.problem.counts)) + 1)
        factors.append(
            _Factor(
                index,
                _padded(part.table.log_mass, size),
                _padded(part.table.log_mass_upper, size),  # type: ignore[arg-type]
            )
        )
    lower_msgs, log_total = cluster_messages([f.lower for f in factors], log_w)
    upper_msgs, log_total_upper = cluster_messages([f.upper for f in factors], log_w)

    n_lo = np.full(H, -math.inf)  # log N_h with lower masses
    n_hi = np.full(H, -math.inf)  # log N_h upper bound
    z_lo = np.full(H, -math.inf)  # log Z_lo of h's factor (captured, lower messages)
    pruned = np.zeros(H, dtype=bool)
    exact = True
    for f, g_lo, g_hi in zip(factors, lower_msgs, upper_msgs, strict=True):
        part = solution.clusters[f.part]
        if f.hypothesis >= 0 or part.kind == "single":
            h = f.hypothesis if f.hypothesis >= 0 else int(part.members[0])
            c = int(counts[h])
            n_lo[h] = weights[h] + g_lo[c] if c < g_lo.shape[0] else -math.inf
            n_hi[h] = weights[h] + g_hi[c] if c < g_hi.shape[0] else -math.inf
            z_lo[h] = float(log_sum_exp(f.lower + g_lo))
            continue
        exact &= _cluster_marginals(
            part, f, g_lo, g_hi, weights, beam_width, entry_margin, n_lo, n_hi, z_lo, pruned
        )

    if exact:
        probabilities = np.exp(n_lo - z_lo)
        probabilities[pruned] = 0.0
        lower = probabilities.copy()
        upper = probabilities.copy()
    else:
        probabilities = np.exp(n_lo - z_lo)
        lower = np.exp(n_lo - log_total_upper)
        upper = _upper(n_lo, n_hi, z_lo)
        probabilities[pruned] = lower[pruned] = 0.0
    if np.any(pruned):
        upper[pruned] = _upper(n_lo[pruned], n_hi[pruned], z_lo[pruned], pruned_only=True)
    return _derived(
        solution, probabilities, lower, upper, exact, pruned, log_total, started
    )


def _upper(
    n_lo: FloatArray, n_hi: FloatArray, z_lo: FloatArray, *, pruned_only: bool = False
) -> FloatArray:
    """``N_hi / (N_hi + Z_lo - N_lo)`` (``N_lo = 0`` for pruned hypotheses: every set
    captured is without them)."""
    if pruned_only:
        rest = z_lo
    else:
        lost = n_lo >= z_lo  # h in (nearly) every captured set: Z_lo - N_lo lost
        rest = np.full(n_lo.shape, -math.inf)
        ok = ~lost
        rest[ok] = log_subtract(z_lo[ok], n_lo[ok])
    with np.errstate(invalid="ignore"):
        out = np.exp(n_hi - np.logaddexp(n_hi, rest))
    out[~np.isfinite(n_hi)] = 0.0
    return out


def _cluster_marginals(
    part: WindowCluster,
    factor: _Factor,
    g_lo: FloatArray,
    g_hi: FloatArray,
    weights: FloatArray,
    beam_width: int,
    entry_margin: float,
    n_lo: FloatArray,
    n_hi: FloatArray,
    z_lo: FloatArray,
    pruned: NDArray[np.bool_],
) -> bool:
    """Fill ``n_lo``, ``n_hi``, ``z_lo`` (and ``pruned``) for one searched cluster.

    Returns whether the cluster's sums are exact.
    """
    merged = part.merged
    assert merged is not None
    kept = (
        np.arange(merged.problem.num_hypotheses)
        if part.kept is None
        else np.flatnonzero(part.kept)
    )
    sub = merged.problem if part.kept is None else merged.problem.subproblem(kept)
    bounded = bool(part.table.bounded) or part.status is not ClusterStatus.EXACT
    size = g_lo.shape[0]
    same = np.array_equal(g_lo, g_hi)
    seeds = np.stack([g_lo] if same else [g_lo, g_hi])
    if not bounded and sub.num_hypotheses <= ENUMERATION_MAX_HYPOTHESES:
        found = enumerated_marginals(sub, seeds)  # every subset listed
    else:
        found = frontier_marginals(
            sub,
            seeds,
            max_frontiers=beam_width if bounded else None,
            entry_margin=entry_margin if bounded else None,
        )
    hi = 0 if same else 1
    node_lo = found.log_containing[0]
    node_hi = found.log_containing[hi]
    cluster_z_lo = float(found.log_total[0])
    exact = found.exact and same
    if not found.exact:
        # Mass of the sets the beam missed, per k: at most upper - captured.
        upper = _padded(part.table.log_mass_upper, size)  # type: ignore[arg-type]
        captured = _padded(found.log_mass, size)
        slack = _ROUND_OFF * (1.0 + np.abs(np.where(np.isfinite(captured), captured, 0.0)))
        if np.any(upper < captured - slack):
            raise RuntimeError("a cluster's proven upper mass lies below the mass captured")
        missing = log_subtract(np.maximum(upper, captured), captured)
        delta = float(log_sum_exp(missing + g_hi)) if np.any(np.isfinite(missing)) else -math.inf
        node_hi = np.logaddexp(node_hi, delta)
    # Merged nodes to the window's hypotheses: shares in proportion to exp(weight).
    window_of = part.members
    for i, m in enumerate(kept.tolist()):
        originals = window_of[merged.members[m]]
        share = weights[originals] - sub.weights[i]
        n_lo[originals] = node_lo[i] + share
        n_hi[originals] = node_hi[i] + share
        z_lo[originals] = cluster_z_lo
    if part.kept is not None:
        _pruned_bounds(part, merged, g_hi, weights, cluster_z_lo, n_lo, n_hi, z_lo, pruned)
    return exact


def _pruned_bounds(
    part: WindowCluster,
    merged: MergedProblem,
    g_hi: FloatArray,
    weights: FloatArray,
    cluster_z_lo: float,
    n_lo: FloatArray,
    n_hi: FloatArray,
    z_lo: FloatArray,
    pruned: NDArray[np.bool_],
) -> None:
    """Upper bounds on the mass of the sets holding each bound-pruned merged hypothesis
    p (its cluster unpruned): ``w_p`` times the product bound of
    :func:`~mapassoc.formulations.bounds.log_mass_upper_bounds` (zero resource
    multipliers, the best count multiplier of a grid) over the hypotheses compatible
    with p, whose exclusive groups are those of the whole cluster: a closed group whose
    exactly-once resource p uses has no compatible member and factor 1 (p satisfies
    it), any other closed group without a compatible member makes p infeasible."""
    assert part.kept is not None
    full = merged.problem
    Hf = full.num_hypotheses
    targets = np.flatnonzero(~part.kept)
    incidence = full.incidence()
    conflicts = (incidence.T @ incidence).toarray() > 0  # shares a resource (and itself)
    compatible = ~conflicts[targets]  # (P, Hf)
    group_of, closed = exclusive_groups(full)
    # The exactly-once resource of each closed group (the lowest of its first member's,
    # the one exclusive_groups grouped by).
    owner = np.repeat(np.arange(Hf), np.diff(full.resource_indptr))
    required = np.full(Hf, full.num_resources, dtype=np.int64)
    is_required = full.exactly_one[full.resource_indices]
    np.minimum.at(required, owner[is_required], full.resource_indices[is_required])
    group_resource = np.full(closed.size, -1, dtype=np.int64)
    group_resource[group_of[::-1]] = required[::-1]  # first member's, per group
    uses = incidence[:, targets].toarray().T > 0  # (P, R)
    covered = np.zeros((targets.size, closed.size), dtype=bool)
    has = closed & (group_resource < full.num_resources)
    covered[:, has] = uses[:, group_resource[has]]
    order = np.argsort(group_of, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(group_of[order]) != 0])
    strict = closed[None, :] & ~covered
    size = g_hi.shape[0]
    ks = np.arange(size, dtype=float)
    log_w = full.weights
    bound = np.full((targets.size, size), math.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for mu in _MU_GRID:
            reduced = np.where(compatible, (log_w - mu * full.counts)[None, :], -math.inf)
            lse = np.logaddexp.reduceat(reduced[:, order], starts, axis=1)
            factors = np.where(strict, lse, np.logaddexp(0.0, lse))
            constant = np.sum(factors, axis=1)  # (P,)
            bound = np.minimum(bound, constant[:, None] + mu * ks[None, :])
    reach = compatible.astype(np.int64) @ full.counts.astype(np.int64)
    bound[ks[None, :] > reach[:, None]] = -math.inf
    for row, p in enumerate(targets.tolist()):
        c = int(full.counts[p])
        shifted = np.full(size, -math.inf)
        shifted[c:] = bound[row, : size - c]
        terms = shifted + g_hi
        reached = np.any(np.isfinite(terms))
        node = float(log_w[p]) + float(log_sum_exp(terms)) if reached else -math.inf
        originals = part.members[merged.members[p]]
        share = weights[originals] - log_w[p]
        n_hi[originals] = node + share
        n_lo[originals] = -math.inf
        z_lo[originals] = cluster_z_lo
        pruned[originals] = True


def _derived(
    solution: WindowSolution,
    probabilities: FloatArray,
    lower: FloatArray,
    upper: FloatArray,
    exact: bool,
    pruned: NDArray[np.bool_],
    log_total: float,
    started: float,
) -> WindowMarginals:
    """Tree existence, (detection, tree) association and false-alarm probabilities."""
    hyps = solution.hypotheses
    num_trees = int(hyps.tree_track_ids.shape[0])
    D = hyps.detections.count
    counted = hyps.counts_toward_k.astype(bool)
    tree = hyps.tree.astype(np.int64)

    def per_tree(values: FloatArray) -> FloatArray:
        sums = np.bincount(tree[counted], weights=values[counted], minlength=num_trees)
        return np.asarray(sums, dtype=np.float64)  # weighted counts are float already

    lengths = np.diff(hyps.detection_indptr)
    owner = np.repeat(np.arange(hyps.count), lengths)
    dets = hyps.detection_indices.astype(np.int64)
    key = dets * max(num_trees, 1) + tree[owner]
    pairs, slot = np.unique(key, return_inverse=True)

    def per_pair(values: FloatArray) -> FloatArray:
        return np.asarray(np.bincount(slot, weights=values[owner], minlength=pairs.size), float)

    def per_detection(values: FloatArray) -> FloatArray:
        return np.asarray(np.bincount(dets, weights=values[owner], minlength=D), float)

    assoc = per_pair(probabilities)
    return WindowMarginals(
        probabilities=probabilities,
        lower=lower,
        upper=upper,
        exact=exact,
        pruned=pruned,
        tree_existence=per_tree(probabilities),
        tree_existence_lower=per_tree(lower),
        tree_existence_upper=np.minimum(per_tree(upper), 1.0),
        association_detection=(pairs // max(num_trees, 1)).astype(np.int64),
        association_tree=(pairs % max(num_trees, 1)).astype(np.int64),
        association_probability=assoc,
        association_lower=per_pair(lower),
        association_upper=np.minimum(per_pair(upper), 1.0),
        false_alarm=1.0 - per_detection(probabilities),
        false_alarm_lower=1.0 - np.minimum(per_detection(upper), 1.0),
        false_alarm_upper=1.0 - per_detection(lower),
        log_total=log_total,
        seconds=time.perf_counter() - started,
    )
