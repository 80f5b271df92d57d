"""The pruning of a window's track trees: the bounds it rests on and which nodes of a
layer it keeps.

Pure functions of the numbers :class:`~mapassoc.estimator.hypotheses.HypothesisGenerator`
passes (its module docstring says what each rule does and why it is safe).
"""

from __future__ import annotations

import math

import numpy as np

from mapassoc.array_types import BoolArray, FloatArray, IntArray
from mapassoc.errors import InputError
from mapassoc.estimator.terms import SensorTerms
from mapassoc.models.sensor import Sensor

__all__ = [
    "continuation_gain_bound",
    "remaining_gain_bounds",
    "prune_mask",
]


def continuation_gain_bound(sensor: Sensor, terms: SensorTerms) -> float:
    """Upper bound ``b_s`` of the term a continuation by a detection of ``sensor`` adds.

    The term is ``dt log Ps + log Pd_s + log N(nu; 0, S) - log lambda_s`` (module
    table; ``docs/model.md`` section 2, ``score_tau``), and

        b_s = log Pd_s - log lambda_s - 0.5 log det(2 pi R_s)

    bounds it for every state of the track, every detection and every time step
    (proof in :func:`remaining_gain_bounds`).  ``R_s`` is the sensor's measurement
    noise covariance, for linear and range-bearing measurements alike.

    Parameters
    ----------
    sensor : Sensor
    terms : SensorTerms
        The sensor's terms under the gate (``log Pd_s``, ``log lambda_s``).

    Returns
    -------
    float
        ``b_s``; it may be negative (then a continuation always lowers the score).

    Raises
    ------
    InputError
        When ``R_s`` is not positive-definite.
    """
    R = np.asarray(sensor.measurement.noise_covariance, dtype=float)
    sign, logdet = np.linalg.slogdet(2.0 * math.pi * R)
    if sign <= 0 or not math.isfinite(logdet):
        raise InputError(
            f"sensor '{sensor.name}' measurement noise covariance R={R.tolist()} must be "
            "positive-definite (det R > 0) to bound the innovation likelihood"
        )
    return terms.log_pd - terms.log_clutter - 0.5 * logdet


def remaining_gain_bounds(bounds: FloatArray) -> FloatArray:
    """``G_j``, the most a path alive at scan ``j`` can still gain by the window's end.

    With ``b_k`` the :func:`continuation_gain_bound` of scan ``k``'s sensor and ``N``
    scans in the window,

        G_j = sum_{k = j+1}^{N-1} max(0, b_k),    G_{N-1} = 0.

    **Why this is an upper bound.**  Let ``v`` be an alive node at scan ``j`` with
    score ``s_v``.  A hypothesis grown from ``v`` adds one term at each later scan
    ``k`` it reaches (module table; ``docs/model.md`` section 3), until the window's
    end or its "ended" node:

    * ended over dt: ``log(1 - Ps^dt) <= 0``;
    * missed: ``dt log Ps + log(1 - Pd_k P_G) <= 0`` (``dt >= 0``, ``Ps <= 1``);
    * continued by a detection: ``dt log Ps + log Pd_k + log N(nu; 0, S) - log
      lambda_k``.  The Gaussian density (Afzal's survey, eq. 3) is
      ``log N(nu; 0, S) = -0.5 log det(2 pi S) - 0.5 nu^T S^-1 nu
      <= -0.5 log det(2 pi S)``.  The innovation covariance is
      ``S = H P H^T + R`` (Afzal's survey, section 4.3; for the EKF H is the Jacobian of
      the range-bearing model, the same form), and ``H P H^T`` is positive
      semidefinite, so ``det S = det R det(I + R^-1/2 H P H^T R^-1/2) >= det R``
      (the second factor is a product of eigenvalues >= 1).  With ``dt log Ps <= 0``
      the term is at most ``b_k``.

    Each term is thus at most ``max(0, b_k)``, and a path gains at most one term per
    later scan, so every hypothesis grown from ``v`` scores at most ``s_v + G_j``,
    whatever the track's covariance, the gate and the detections.  A node that has
    ended gains nothing more: its bound is its score.

    Parameters
    ----------
    bounds : ndarray, shape (N,)
        ``b_k`` of each of the window's scans, in time order.

    Returns
    -------
    ndarray, shape (N,)
        ``G_j`` for every scan position ``j``; non-increasing, last entry 0.
    """
    per_scan = np.maximum(0.0, np.asarray(bounds, dtype=float))
    # G_j = sum over k > j: reversed cumulative sum, shifted by one scan.
    from_here = np.cumsum(per_scan[::-1])[::-1]
    return np.concatenate([from_here[1:], [0.0]])


def prune_mask(
    tree: IntArray,
    score: FloatArray,
    protected: BoolArray,
    is_new_tree: BoolArray,
    gain: FloatArray,
    *,
    prune_log_ratio: float,
    sibling_prune_log_ratio: float,
    max_hypotheses_per_tree: int,
) -> tuple[BoolArray, int]:
    """Which nodes of one scan's layer are kept, and how many the cap alone cut.

    A node passes the score-ratio tests when

    * ``score >= best - sibling_prune_log_ratio``, ``best`` the highest score of its
      tree in this layer (siblings, which compete for the same detections; a
      heuristic); and, for a node of a new tree,
    * ``score + gain >= -prune_log_ratio``: ``gain`` bounds what its path can still
      add (:func:`remaining_gain_bounds`), so a node failing this has only
      descendants scoring below ``-prune_log_ratio``.  A new tree's hypothesis has no
      "exactly one" constraint, so removing such a hypothesis from a track set keeps
      the set feasible and raises its score by more than ``prune_log_ratio``: it is
      dropped by a bound on what it can add to a window's best set.

    Of the nodes that pass, the ``max_hypotheses_per_tree`` best-scoring of each tree
    are kept (ties by position); protected nodes are always kept.

    Parameters
    ----------
    tree : ndarray of int, shape (L,)
    score : ndarray, shape (L,)
    protected : ndarray of bool, shape (L,)
    is_new_tree : ndarray of bool, shape (T,)
        Per tree of the window so far.
    gain : ndarray, shape (L,)
        Upper bound of what each node's path can still gain (0 for an ended node).
    prune_log_ratio, sibling_prune_log_ratio : float
        The bound's and the siblings' widths.
    max_hypotheses_per_tree : int
        The cap.

    Returns
    -------
    keep : ndarray of bool, shape (L,)
    capped : int
        Unprotected nodes that passed the score-ratio tests but not the cap.
    """
    ratio = prune_log_ratio
    order = np.lexsort((np.arange(len(score)), -score, tree))
    t_sorted = tree[order]
    s_sorted = score[order]
    new_group = np.r_[True, t_sorted[1:] != t_sorted[:-1]]
    starts = np.flatnonzero(new_group)
    group_id = np.cumsum(new_group) - 1
    best = s_sorted[starts][group_id]
    passes = s_sorted >= best - sibling_prune_log_ratio
    passes &= ~is_new_tree[t_sorted] | (s_sorted + gain[order] >= -ratio)
    # Rank among the nodes of the tree that pass (a node dropped by the bound takes
    # no place under the cap).
    passed_before = np.cumsum(passes) - passes
    rank = passed_before - passed_before[starts][group_id]
    ok = passes & (rank < max_hypotheses_per_tree)
    keep = np.zeros(len(score), dtype=bool)
    keep[order] = ok
    cut_by_cap = np.zeros(len(score), dtype=bool)
    cut_by_cap[order] = passes & ~ok
    cut_by_cap &= ~protected
    return keep | protected, int(np.count_nonzero(cut_by_cap))
