"""The one builder of a window's packing problem, for the forward pass and the refinement.

Resources ``0..D-1`` are the window's detections (at most once); resource ``D + t`` is
carried tree ``t`` (exactly once).  The refinement's re-solves add, after them, one
resource per anchor (a track piece after the window that a hypothesis may join: at most
once, or exactly once when the piece cannot stand alone) and one program hypothesis per
join, which uses its hypothesis' resources and its anchor's.  The forward pass and the
refinement thus solve one kind of program, with the same resource layout, by the same
window solver (:class:`~mapassoc.estimator.cluster_solving.ClusterSolver`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.estimator.hypotheses import WindowHypotheses
from mapassoc.formulations.packing import PackingProblem, gather_rows

__all__ = ["Joins", "packing_problem"]


@dataclass(frozen=True, eq=False)
class Joins:
    """The joins of a re-solved window's hypotheses to the anchors after it.

    Attributes
    ----------
    hypotheses : ndarray of int, shape (J,)
        The window hypothesis of each join.
    anchors : ndarray of int, shape (J,)
        The anchor of each join.
    scores : ndarray, shape (J,)
        Each join's score (its exact change of J); its log-weight too.
    required : ndarray of bool, shape (A,)
        Per anchor: whether it must be joined (its resource is exactly-once).
    """

    hypotheses: IntArray
    anchors: IntArray
    scores: FloatArray
    required: NDArray[np.bool_]


def packing_problem(
    hypotheses: WindowHypotheses,
    *,
    carried: int | None = None,
    scores: FloatArray | None = None,
    log_weights: FloatArray | None = None,
    counts: NDArray[np.bool_] | None = None,
    joins: Joins | None = None,
) -> PackingProblem:
    """The packing problem of a window's hypotheses (module docstring for the layout).

    Parameters
    ----------
    hypotheses : WindowHypotheses
    carried : int, optional
        Carried trees (trees ``0..carried-1``); default: the trees with a track id.
    scores, log_weights : ndarray, shape (H,), optional
        The hypotheses' scores (default: ``hypotheses.scores``) and log-weights
        (default: the scores); the joins' follow them.
    counts : ndarray of bool, shape (H,), optional
        Which hypotheses count toward K (default: ``hypotheses.counts_toward_k``; every
        join counts).
    joins : Joins, optional
        The refinement's joins to anchors, as program hypotheses ``H..H+J-1``.
    """
    D = hypotheses.detections.count
    C = int(np.count_nonzero(hypotheses.tree_track_ids >= 0)) if carried is None else carried
    tree = hypotheses.tree
    indptr, indices = gather_rows(
        hypotheses.detection_indptr,
        hypotheses.detection_indices,
        np.arange(hypotheses.count),
        np.where(tree < C, D + tree, -1),
    )
    scores = hypotheses.scores if scores is None else scores
    counts = hypotheses.counts_toward_k if counts is None else counts
    exactly_one = np.r_[np.zeros(D, dtype=bool), np.ones(C, dtype=bool)]
    if joins is not None:
        join_ptr, join_indices = gather_rows(
            indptr, indices, joins.hypotheses, D + C + joins.anchors
        )
        indptr = np.concatenate([indptr, indptr[-1] + join_ptr[1:]])
        indices = np.concatenate([indices, join_indices])
        scores = np.concatenate([scores, joins.scores])
        if log_weights is not None:
            log_weights = np.concatenate([log_weights, joins.scores])
        counts = np.r_[counts, np.ones(joins.hypotheses.size, dtype=bool)]
        exactly_one = np.r_[exactly_one, joins.required]
    return PackingProblem(
        scores=scores,
        log_weights=log_weights,
        resource_indptr=indptr,
        resource_indices=indices,
        exactly_one=exactly_one,
        counts=counts,
    )
