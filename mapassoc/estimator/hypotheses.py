"""Track hypotheses of one window: track trees grown scan by scan, Kalman-scored.

A window is a run of consecutive scans.  Every track tree of the window is either

* a **carried track**, committed by earlier windows, whose filtered state at its last
  committed scan is the prior; its hypotheses include ending before the window; or
* a **new track**, born at one detection of the window (single-point initiation,
  :mod:`mapassoc.models.birth`).

Each alive leaf grows at each scan into: the track ended (alive at the previous scan,
dead at this one), the track missed, or the track continued by one gated detection.
The score of a hypothesis (a root-to-leaf path) is its log-likelihood ratio against
"all its detections are false alarms and the track does not exist"; it is a sum of
the terms below (derivation: ``docs/model.md``; the sum over a track set plus a
constant is ``log p(track set, K | Z)`` of Perry's MAP formulation, eqs. 8-14):

====================================  ===============================================
event at a scan of sensor s           term
====================================  ===============================================
first detection z at scan j           ``log u_j + log Pd_s - log lambda_bar_s``
                                      (density ``u_j Pd_s / V_s`` of a target never
                                      detected before, ``u_j`` the undetected-target
                                      mean of :mod:`mapassoc.models.population`, over the
                                      clutter density ``lambda_s = lambda_bar_s / V_s``)
survival over dt                      ``dt log Ps``
continued by detection z              ``log Pd_s + log N(nu; 0, S) - log lambda_s``
                                      (the n-object posterior weight; Afzal's survey eq. 11)
missed                                ``log(1 - Pd_s P_G)`` (P_G: gate probability)
ended over dt                         ``log(1 - Ps^dt)``
====================================  ===============================================

Each term is computed by its function in :mod:`mapassoc.estimator.terms`, the one place
the trees, the recording objective and the trackers that share the model take it from.
Every Kalman step (prediction, the innovation and its ``S``, the gate with the
log-likelihoods of the pairs in it, the update) is a call of the batched filter interface
:mod:`mapassoc.filtering.batch`, which the recording objective calls too.

Growth is bounded by a chi-square gate and by pruning, which compares like with like.
At each scan a node is dropped

* against its **siblings**, the nodes of the same tree at the same scan (they compete
  for the same detections: at most one hypothesis of a tree is selected), when its
  score is more than ``sibling_prune_log_ratio`` (by default ``prune_log_ratio``)
  below the best of them.  A heuristic: the best sibling may conflict with another
  track, and the branch dropped may then belong to the best set;
* for a **new tree**, by a **bound on what it can add to a window's best set**: when
  even an optimistic bound of its final score, its score plus the most its path can
  still gain over the window's remaining scans
  (:meth:`HypothesisGenerator.remaining_gain_bounds`), is below ``-prune_log_ratio``.
  Every hypothesis grown from it then scores below ``-prune_log_ratio``, and removing
  it from any track set keeps the set feasible (with one track fewer) and raises its
  score by more than ``prune_log_ratio``: every set containing it is that far below
  the window's best set over all T.  At the window's last scan the remaining gain is
  0, so this is a comparison with 0, the score of not selecting the tree.  An earlier
  node is not compared with 0 directly: a birth among many false alarms scores far
  below 0 at its first detection (``log(u Pd / lambda_bar)``, whatever the region's
  size) and each later detection adds up to
  ``log Pd - log lambda - 0.5 log det(2 pi R)``;
* by the cap: at most ``max_hypotheses_per_tree`` nodes per tree and scan survive,
  the best-scoring ones among those that pass the two tests above.  Nodes cut only by
  the cap are counted in :attr:`WindowHypotheses.nodes_capped`, so that a caller can report
  that the window's hypotheses are not all those within the ratio.

A carried tree always keeps a leaf that uses no detection (ended before the window, or
all misses), so pruning never makes a window infeasible.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import BoolArray, FloatArray, IntArray
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.terms import (
    SensorTerms,
    birth_term,
    detection_term,
    end_term,
    survival_term,
)
from mapassoc.estimator.tree_pruning import (
    continuation_gain_bound,
    prune_mask,
    remaining_gain_bounds,
)
from mapassoc.filtering.batch import GatedPairs, Innovation, KalmanFilter
from mapassoc.models.birth import (
    birth_states,
    convert_initiated_many,
    initiation_measurement,
    initiation_model,
    needs_conversion,
)
from mapassoc.models.interacting import filter_state_dim
from mapassoc.models.motion import MotionModel
from mapassoc.models.population import (
    BirthModel,
    UndetectedTargets,
    WindowPopulation,
    recording_start,
    window_population,
)
from mapassoc.models.sensor import Sensor

__all__ = [
    "CarriedTrack",
    "WindowDetections",
    "HypothesisNodes",
    "CommittedTrack",
    "WindowHypotheses",
    "HypothesisGenerator",
]


@dataclass(frozen=True, eq=False)
class CarriedTrack:
    """A track committed by earlier windows, entering the next window as a prior.

    Parameters
    ----------
    track_id : int
        Stable track identifier.
    mean : ndarray, shape (n,)
        Filtered state at ``time`` (in the initiation-model space while
        ``initiated`` is False).
    covariance : ndarray, shape (n, n)
    time : float
        Time of the last committed scan.
    initiated : bool
        Whether the state is in the motion model's own space (always True except for
        a coordinated-turn track with a single detection so far).
    num_detections : int
        Detections the track has used so far.
    first_detection_time : float
        Time of the track's first detection (a coordinated-turn track converts to the
        turn state at its first detection later than this).
    """

    track_id: int
    mean: FloatArray
    covariance: FloatArray
    time: float
    initiated: bool
    num_detections: int
    first_detection_time: float


@dataclass(frozen=True, eq=False)
class WindowDetections:
    """The detections of a window, indexed 0..D-1 in scan order.

    Attributes
    ----------
    scan_position : ndarray of int, shape (D,)
        Position of the detection's scan within the window.
    index_in_scan : ndarray of int, shape (D,)
    rows : ndarray of int, shape (D,)
        Line numbers in the detections file.
    """

    scan_position: IntArray
    index_in_scan: IntArray
    rows: IntArray

    @property
    def count(self) -> int:
        return int(self.rows.shape[0])


@dataclass(frozen=True, eq=False)
class HypothesisNodes:
    """Nodes of a window's track trees (a node = a track's state at one scan).

    One record of equal-length arrays, used for every set of nodes the generator
    handles: the nodes created at one scan (a layer, before pruning), the frontier of
    alive nodes grown at the next scan, and the window's kept nodes
    (:attr:`WindowHypotheses.nodes`, where a node's id is its position and children
    follow their parents).  Build records with :meth:`empty`, :meth:`concat` and
    :meth:`take`.

    States of different state spaces (coordinated turn before and after initiation)
    share padded arrays; ``state_dims`` says how many leading entries are used.

    Attributes
    ----------
    parent : ndarray of int, shape (V,)
        Parent node, -1 for a root.
    layer : ndarray of int, shape (V,)
        Scan position in the window (-1 for a carried track's prior, before the window).
    detection : ndarray of int, shape (V,)
        Window detection used at this node, -1 for a miss or an end.
    alive : ndarray of bool, shape (V,)
        False for an "ended" node.
    tree : ndarray of int, shape (V,)
    initiated : ndarray of bool, shape (V,)
    num_detections : ndarray of int, shape (V,)
        Detections used along the path including this node (carried history included).
    first_time : ndarray, shape (V,)
        Time of the track's first detection.
    score : ndarray, shape (V,)
        Log-likelihood ratio of the path from the root to this node.
    protected : ndarray of bool, shape (V,)
        Never pruned (the leaf of a carried tree that uses no detection).
    means : ndarray, shape (V, n_max)
    covariances : ndarray, shape (V, n_max, n_max)
    state_dims : ndarray of int, shape (V,)
    """

    parent: IntArray
    layer: IntArray
    detection: IntArray
    alive: BoolArray
    tree: IntArray
    initiated: BoolArray
    num_detections: IntArray
    first_time: FloatArray
    score: FloatArray
    protected: BoolArray
    means: FloatArray
    covariances: FloatArray
    state_dims: IntArray

    def __post_init__(self) -> None:
        n = len(self.parent)
        for name in _NODE_FIELDS:
            if len(getattr(self, name)) != n:
                raise ValueError(
                    f"node field '{name}' has {len(getattr(self, name))} entries, 'parent' has {n}"
                )

    def __len__(self) -> int:
        return int(self.parent.shape[0])

    @classmethod
    def empty(cls, state_dim: int = 0) -> HypothesisNodes:
        """No nodes; states padded to ``state_dim``."""
        i = np.zeros(0, dtype=np.int64)
        b = np.zeros(0, dtype=bool)
        f = np.zeros(0, dtype=float)
        return cls(
            parent=i,
            layer=i.copy(),
            detection=i.copy(),
            alive=b,
            tree=i.copy(),
            initiated=b.copy(),
            num_detections=i.copy(),
            first_time=f,
            score=f.copy(),
            protected=b.copy(),
            means=np.zeros((0, state_dim)),
            covariances=np.zeros((0, state_dim, state_dim)),
            state_dims=i.copy(),
        )

    @classmethod
    def concat(cls, records: Sequence[HypothesisNodes], *, state_dim: int = 0) -> HypothesisNodes:
        """The nodes of ``records`` one after the other (:meth:`empty` of ``state_dim`` if none).

        Node ids are positions: ``parent`` is kept as it is, so it refers to the
        concatenated record only when the records were numbered that way.
        """
        if not records:
            return cls.empty(state_dim)
        return cls(
            **{name: np.concatenate([getattr(r, name) for r in records]) for name in _NODE_FIELDS}
        )

    def take(self, index: IntArray | BoolArray) -> HypothesisNodes:
        """The nodes at ``index`` (positions, or a boolean mask of length ``len(self)``)."""
        chosen = np.asarray(index)
        if chosen.dtype == bool and chosen.shape != (len(self),):
            raise ValueError(f"mask has shape {chosen.shape}, expected ({len(self)},)")
        return type(self)(**{name: getattr(self, name)[chosen] for name in _NODE_FIELDS})

    def path(self, leaf: int) -> list[int]:
        """Node ids from the root to ``leaf``."""
        out = []
        node = int(leaf)
        while node >= 0:
            out.append(node)
            node = int(self.parent[node])
        return out[::-1]

    def state(self, node: int) -> tuple[FloatArray, FloatArray]:
        d = int(self.state_dims[node])
        return self.means[node, :d].copy(), self.covariances[node, :d, :d].copy()


_NODE_FIELDS = tuple(f.name for f in fields(HypothesisNodes))
"""The arrays of a :class:`HypothesisNodes` record, all indexed by node."""


@dataclass(frozen=True, eq=False)
class CommittedTrack:
    """What committing a window's first scans keeps of one selected hypothesis.

    Attributes
    ----------
    hypothesis : int
        The selected hypothesis.
    track_id : int
        Track id of a carried tree; -1 for a new tree, born within the committed scans
        (the caller gives it an id).
    detections : ndarray of int, shape (m,)
        Window detections the track uses at the committed scans, in scan order.
    rows : ndarray of int, shape (m,)
        Their line numbers in the detections file.
    scan_positions : ndarray of int, shape (m,)
        Positions of their scans in the window.
    ended : bool
        Whether the track ended within the committed scans.
    state : CarriedTrack or None
        The track's state at the last committed scan if it is alive there (to be
        carried into the next window), else None.  Its ``track_id`` is ``track_id``
        (-1 for a new tree: use :meth:`carried`).
    """

    hypothesis: int
    track_id: int
    detections: IntArray
    rows: IntArray
    scan_positions: IntArray
    ended: bool
    state: CarriedTrack | None

    @property
    def is_new(self) -> bool:
        """Whether the track was born in the window (it has no track id yet)."""
        return self.track_id < 0

    def carried(self, track_id: int) -> CarriedTrack | None:
        """:attr:`state` under ``track_id``, or None when the track is not alive there."""
        if self.state is None:
            return None
        return replace(self.state, track_id=track_id)


@dataclass(frozen=True, eq=False)
class WindowHypotheses:
    """All hypotheses of one window, ready to be turned into a set-packing program.

    Attributes
    ----------
    scans : tuple of Scan
    detections : WindowDetections
    tree_track_ids : ndarray of int, shape (T,)
        Track id of each carried tree, -1 for a new tree.
    scores : ndarray, shape (H,)
        Log-likelihood ratio of each hypothesis.
    tree : ndarray of int, shape (H,)
    leaf : ndarray of int, shape (H,)
        Node id of each hypothesis' last node.
    counts_toward_k : ndarray of bool, shape (H,)
        False only for "carried track ended before the window".
    detection_indptr : ndarray of int, shape (H + 1,)
    detection_indices : ndarray of int, shape (nnz,)
        Window detections used by hypothesis h: ``indices[indptr[h]:indptr[h+1]]``.
    nodes : HypothesisNodes
    nodes_generated : int
        Tree nodes created (before pruning); not hypotheses (a hypothesis is a
        root-to-leaf path, ``count`` of them are kept).
    nodes_pruned : int
        Nodes dropped, by the score-ratio tests and by the cap together.
    nodes_capped : int
        Of the ``nodes_pruned``, those dropped only by the per-tree cap
        (``max_hypotheses_per_tree``): they passed the score-ratio tests.  Nonzero means
        the cap, not the ratio, decided which hypotheses the window has, so the window's
        tables are not exact over the hypotheses within ``prune_log_ratio``.  (Every
        node below a capped node is never generated and is not counted.)
    """

    scans: tuple[Scan, ...]
    detections: WindowDetections
    tree_track_ids: IntArray
    scores: FloatArray
    tree: IntArray
    leaf: IntArray
    counts_toward_k: BoolArray
    detection_indptr: IntArray
    detection_indices: IntArray
    nodes: HypothesisNodes
    nodes_generated: int
    nodes_pruned: int
    nodes_capped: int = 0

    @property
    def count(self) -> int:
        return int(self.scores.shape[0])

    def detections_of(self, h: int) -> IntArray:
        return self.detection_indices[self.detection_indptr[h] : self.detection_indptr[h + 1]]

    def commit(
        self, selection: Sequence[int] | IntArray, committed_scans: int
    ) -> list[CommittedTrack]:
        """Commit the first ``committed_scans`` scans of the selected hypotheses.

        Parameters
        ----------
        selection : sequence of int
            Selected hypotheses (indices into this window's hypotheses).
        committed_scans : int
            How many of the window's first scans are committed, 1 to ``len(scans)``.

        Returns
        -------
        list of CommittedTrack
            One per selected hypothesis, in ``selection`` order, except the new trees
            born after the committed scans: a later window decides them.  A track's
            committed part is its path up to the last committed scan, stopped at an
            "ended" node; its state is carried when the path is alive at that scan.
        """
        num_scans = len(self.scans)
        if not 1 <= committed_scans <= num_scans:
            raise InputError(
                f"committed_scans must be in 1..{num_scans} (the window's scans), "
                f"got {committed_scans}"
            )
        nodes = self.nodes
        last = committed_scans - 1
        time = self.scans[last].time
        out: list[CommittedTrack] = []
        for h in np.asarray(selection, dtype=np.int64).tolist():
            if not 0 <= h < self.count:
                raise InputError(f"hypothesis {h} is not in 0..{self.count - 1}")
            path = nodes.path(int(self.leaf[h]))
            track_id = int(self.tree_track_ids[int(self.tree[h])])
            if track_id < 0 and nodes.layer[path[0]] > last:
                continue  # born after the committed scans: decided by a later window
            used: list[int] = []
            ended = False
            carry = -1
            for v in path:
                layer = int(nodes.layer[v])
                if layer > last:
                    break
                if not nodes.alive[v]:
                    ended = True
                    break
                det = int(nodes.detection[v])
                if det >= 0:
                    used.append(det)
                if layer == last:
                    carry = v
            state = None
            if carry >= 0:
                mean, cov = nodes.state(carry)
                state = CarriedTrack(
                    track_id=track_id,
                    mean=mean,
                    covariance=cov,
                    time=time,
                    initiated=bool(nodes.initiated[carry]),
                    num_detections=int(nodes.num_detections[carry]),
                    first_detection_time=float(nodes.first_time[carry]),
                )
            dets = np.asarray(used, dtype=np.int64)
            out.append(
                CommittedTrack(
                    hypothesis=h,
                    track_id=track_id,
                    detections=dets,
                    rows=self.detections.rows[dets],
                    scan_positions=self.detections.scan_position[dets],
                    ended=ended,
                    state=state,
                )
            )
        return out


@dataclass(frozen=True, eq=False)
class _Frontier:
    """Alive nodes to grow at the next scan.

    ``ids`` are their stored node ids (-1 for a carried track's prior), ``time`` the
    times of their states.
    """

    nodes: HypothesisNodes
    ids: IntArray
    time: FloatArray

    def __len__(self) -> int:
        return len(self.nodes)

    @classmethod
    def empty(cls, state_dim: int) -> _Frontier:
        return cls(HypothesisNodes.empty(state_dim), np.zeros(0, np.int64), np.zeros(0))

    @classmethod
    def of_layer(cls, kept: HypothesisNodes, first_id: int, time: float) -> _Frontier:
        """The alive nodes of a pruned layer stored with ids ``first_id, first_id + 1, ...``."""
        alive = kept.alive
        ids = first_id + np.arange(len(kept))
        return cls(kept.take(alive), ids[alive], np.full(int(np.count_nonzero(alive)), time))


StatesOf = Callable[[IntArray], tuple[FloatArray, FloatArray]]
"""Computes the states of some of a group's new nodes: positions in the group ->
means ``(k, n_max)`` and covariances ``(k, n_max, n_max)``."""


@dataclass(frozen=True, eq=False)
class _NewNodes:
    """A group of one scan's new nodes before pruning: what pruning reads, and how to
    compute the states of the nodes it keeps.

    Pruning reads only scores, trees and flags, and in dense clutter drops about half
    of the nodes generated, while the children's Kalman updates are the largest part of
    growing them: states are computed for the kept nodes only, row by row the same as
    for all of them.
    """

    parent: IntArray
    detection: IntArray
    alive: bool
    tree: IntArray
    initiated: BoolArray
    num_detections: IntArray
    first_time: FloatArray
    score: FloatArray
    protected: BoolArray
    states: StatesOf

    def __len__(self) -> int:
        return int(self.score.shape[0])


def _window_detections(scans: Sequence[Scan]) -> tuple[WindowDetections, IntArray]:
    """The window's detections, and the window index of each scan's first detection."""
    det_counts = [s.size for s in scans]
    offsets = np.concatenate([[0], np.cumsum(det_counts)]).astype(np.int64)
    detections = WindowDetections(
        scan_position=np.repeat(np.arange(len(scans)), det_counts).astype(np.int64),
        index_in_scan=np.concatenate(
            [np.arange(c, dtype=np.int64) for c in det_counts] or [np.zeros(0, np.int64)]
        ),
        rows=np.concatenate([s.rows for s in scans] or [np.zeros(0, np.int64)]),
    )
    return detections, offsets


def _pad(means: FloatArray, covs: FloatArray, n_max: int) -> tuple[FloatArray, FloatArray]:
    k, d = means.shape
    if d == n_max:
        return means, covs
    m = np.zeros((k, n_max))
    c = np.zeros((k, n_max, n_max))
    m[:, :d] = means
    c[:, :d, :d] = covs
    return m, c


def _gathered(means: FloatArray, covs: FloatArray, rows: IntArray) -> StatesOf:
    """States of the nodes whose states are rows ``rows`` of ``means``, ``covs``."""

    def states(index: IntArray) -> tuple[FloatArray, FloatArray]:
        return means[rows[index]], covs[rows[index]]

    return states


def _node_record(
    dims: tuple[int, int],
    *,
    parent: IntArray,
    layer: int,
    detection: IntArray,
    alive: bool | BoolArray,
    tree: IntArray,
    initiated: BoolArray,
    num_detections: IntArray,
    first_time: FloatArray | float,
    score: FloatArray,
    protected: BoolArray,
    means: FloatArray,
    covs: FloatArray,
) -> HypothesisNodes:
    """A record of new nodes at scan ``layer``; states already padded to ``n_max``;
    ``dims`` the state dimensions before and after initiation."""
    k = len(score)
    initiated = np.asarray(initiated, dtype=bool)
    return HypothesisNodes(
        parent=np.asarray(parent, dtype=np.int64),
        layer=np.full(k, layer, dtype=np.int64),
        detection=np.asarray(detection, dtype=np.int64),
        alive=np.broadcast_to(np.asarray(alive, dtype=bool), (k,)).copy(),
        tree=np.asarray(tree, dtype=np.int64),
        initiated=initiated,
        num_detections=np.asarray(num_detections, dtype=np.int64),
        first_time=np.broadcast_to(np.asarray(first_time, dtype=float), (k,)).copy(),
        score=np.asarray(score, dtype=float),
        protected=np.asarray(protected, dtype=bool),
        means=means,
        covariances=covs,
        state_dims=np.where(initiated, dims[1], dims[0]).astype(np.int64),
    )


def _carried_frontier(
    carried: Sequence[CarriedTrack], dims: tuple[int, int], n_max: int
) -> _Frontier:
    """The frontier of the carried tracks' priors (before the window's first scan)."""
    if not carried:
        return _Frontier.empty(n_max)
    means, covs = [], []
    for t in carried:
        d = dims[1] if t.initiated else dims[0]
        m = np.asarray(t.mean, dtype=float)
        c = np.asarray(t.covariance, dtype=float)
        if m.shape != (d,) or c.shape != (d, d):
            raise InputError(
                f"carried track {t.track_id} state has shape {m.shape}, covariance "
                f"{c.shape}; expected ({d},) and ({d}, {d})"
            )
        pm, pc = _pad(m[None], c[None], n_max)
        means.append(pm[0])
        covs.append(pc[0])
    k = len(carried)
    nodes = _node_record(
        dims,
        parent=np.full(k, -1),
        layer=-1,
        detection=np.full(k, -1),
        alive=True,
        tree=np.arange(k),
        initiated=np.array([t.initiated for t in carried], dtype=bool),
        num_detections=np.array([t.num_detections for t in carried], dtype=np.int64),
        first_time=np.array([t.first_detection_time for t in carried], dtype=float),
        score=np.zeros(k),
        protected=np.ones(k, dtype=bool),
        means=np.array(means),
        covs=np.array(covs),
    )
    return _Frontier(
        nodes, np.full(k, -1, dtype=np.int64), np.array([t.time for t in carried], dtype=float)
    )


def _ended_nodes(frontier: _Frontier, log_end: FloatArray, protect: BoolArray) -> list[_NewNodes]:
    """The "ended" children of the frontier nodes that can end (a finite term)."""
    f = frontier.nodes
    idx = np.flatnonzero(np.isfinite(log_end))
    if len(idx) == 0:
        return []
    return [
        _NewNodes(
            parent=frontier.ids[idx],
            detection=np.full(len(idx), -1, dtype=np.int64),
            alive=False,
            tree=f.tree[idx],
            initiated=f.initiated[idx],
            num_detections=f.num_detections[idx],
            first_time=f.first_time[idx],
            score=f.score[idx] + log_end[idx],
            protected=protect[idx],
            states=_gathered(f.means, f.covariances, idx),
        )
    ]


def _padded(x: FloatArray, P: FloatArray, n_max: int) -> StatesOf:
    """States of the nodes at given rows of ``x``, ``P``, padded to ``n_max``."""

    def states(index: IntArray) -> tuple[FloatArray, FloatArray]:
        return _pad(x[index], P[index], n_max)

    return states


def _roots(
    scan: Scan, det_offset: int, first_tree: int, score: float, initiated: bool, states: StatesOf
) -> _NewNodes:
    """The roots of new trees, one at each detection of ``scan``, scored ``score``."""
    m = scan.size
    return _NewNodes(
        parent=np.full(m, -1, dtype=np.int64),
        detection=det_offset + np.arange(m),
        alive=True,
        tree=first_tree + np.arange(m),
        initiated=np.full(m, initiated),
        num_detections=np.ones(m, dtype=np.int64),
        first_time=np.full(m, scan.time),
        score=np.full(m, score),
        protected=np.zeros(m, dtype=bool),
        states=states,
    )


class HypothesisGenerator:
    """Grows and scores the track trees of a window.

    Parameters
    ----------
    motion : MotionModel
    sensors : mapping of str to Sensor
        Every sensor named by a scan.  Each needs ``false_alarms_per_scan > 0``: the
        scores are ratios against "false alarm", which has no density without clutter.
    birth : BirthModel
    gate_probability : float
        P_G in (0, 1]; 1 disables gating.
    max_hypotheses_per_tree : int
        Most new nodes kept per tree and scan.
    prune_log_ratio : float
        Nodes of new trees whose optimistic final score (score plus
        :meth:`remaining_gain_bounds`) is below minus this are dropped (module
        docstring), and, unless ``sibling_prune_log_ratio`` says otherwise, so are nodes
        scoring more than this below the best node of their tree at the same scan.
    sibling_prune_log_ratio : float or None, default None
        The sibling rule's own width (``inf`` disables it); ``None``: ``prune_log_ratio``.
    """

    def __init__(
        self,
        *,
        motion: MotionModel,
        sensors: Mapping[str, Sensor],
        birth: BirthModel,
        gate_probability: float,
        max_hypotheses_per_tree: int,
        prune_log_ratio: float,
        sibling_prune_log_ratio: float | None = None,
    ) -> None:
        self.motion = motion
        self.sensors = dict(sensors)
        self.birth = birth
        if not 0 < gate_probability <= 1:
            raise InputError(f"gate_probability must be in (0, 1], got {gate_probability!r}")
        self.gate_probability = float(gate_probability)
        self._terms = SensorTerms.of_all(self.sensors, self.gate_probability)
        self.max_hypotheses_per_tree = int(max_hypotheses_per_tree)
        self.prune_log_ratio = float(prune_log_ratio)
        self.sibling_prune_log_ratio = float(
            prune_log_ratio if sibling_prune_log_ratio is None else sibling_prune_log_ratio
        )
        if not self.sibling_prune_log_ratio >= 0:
            raise InputError(
                "sibling_prune_log_ratio must be >= 0 (inf disables), got "
                f"{sibling_prune_log_ratio!r}"
            )
        self._init_model = initiation_model(motion)
        self._converts = needs_conversion(motion)
        self._dims = (self._init_model.state_dim, filter_state_dim(motion))
        self._n_max = max(self._dims)
        self._log_survival = math.log(birth.survival_probability)
        self._filter = KalmanFilter(motion=motion)

    # -- bounds for pruning ----------------------------------------------------------
    def continuation_gain_bound(self, sensor: Sensor) -> float:
        """Upper bound ``b_s`` of the term a continuation by a detection of ``sensor``
        adds (:func:`~mapassoc.estimator.tree_pruning.continuation_gain_bound`, with the
        generator's terms of the sensor)."""
        terms = self._terms.get(sensor.name)
        if terms is None or self.sensors[sensor.name] is not sensor:
            terms = SensorTerms.of(sensor, self.gate_probability)
        return continuation_gain_bound(sensor, terms)

    def remaining_gain_bounds(self, scans: Sequence[Scan]) -> FloatArray:
        """``G_j``, the most a path alive at scan ``j`` can still gain by the window's end
        (:func:`~mapassoc.estimator.tree_pruning.remaining_gain_bounds` of the scans'
        :meth:`continuation_gain_bound`).

        Raises
        ------
        InputError
            When a scan names a sensor the generator does not know.
        """
        bounds = np.zeros(len(scans))
        for k, scan in enumerate(scans):
            sensor = self.sensors.get(scan.sensor)
            if sensor is None:
                raise InputError(
                    f"scan at time {scan.time} names sensor '{scan.sensor}', which is not "
                    f"configured (known: {sorted(self.sensors)})"
                )
            bounds[k] = self.continuation_gain_bound(sensor)
        return remaining_gain_bounds(bounds)

    # -- main entry ------------------------------------------------------------------
    def population(
        self,
        scans: Sequence[Scan],
        carried: Sequence[CarriedTrack] = (),
        undetected: UndetectedTargets | None = None,
    ) -> WindowPopulation:
        """The birth model's undetected targets and target counts for a window.

        Parameters
        ----------
        scans : sequence of Scan
            The window's scans in time order (at least one).
        carried : sequence of CarriedTrack
            Tracks entering the window.
        undetected : UndetectedTargets, optional
            The undetected targets just after the scan before the window; default: the
            recording starts at the window's first scan (``BirthModel.initial_count``
            targets present).

        Returns
        -------
        WindowPopulation
        """
        scans = tuple(scans)
        if not scans:
            raise InputError("a window needs at least one scan")
        self._check_scans(scans)
        start = recording_start(self.birth, scans[0].time) if undetected is None else undetected
        return window_population(
            scans,
            [self.sensors[s.sensor].detection_probability for s in scans],
            self.birth,
            start,
            [t.time for t in carried],
        )

    def _check_scans(self, scans: Sequence[Scan]) -> None:
        for scan in scans:
            if scan.sensor not in self.sensors:
                raise InputError(
                    f"scan at time {scan.time} names sensor '{scan.sensor}', which is not "
                    f"configured (known: {sorted(self.sensors)})"
                )
            dz = self.sensors[scan.sensor].measurement.measurement_dim
            if scan.size and scan.detections.shape[1] != dz:
                raise InputError(
                    f"scan at time {scan.time} of sensor '{scan.sensor}' has detections of "
                    f"dimension {scan.detections.shape[1]}, expected {dz}"
                )

    # -- main entry ------------------------------------------------------------------
    def generate(
        self,
        scans: Sequence[Scan],
        carried: Sequence[CarriedTrack] = (),
        *,
        population: WindowPopulation | None = None,
        end_gain: float = 0.0,
    ) -> WindowHypotheses:
        """Build every kept hypothesis of the window.

        Parameters
        ----------
        scans : sequence of Scan
            The window's scans in time order (at least one).
        carried : sequence of CarriedTrack
            Tracks entering the window; each must end before the window's first scan
            time or at it.
        population : WindowPopulation, optional
            The undetected-target intensity of the window's scans (a new track's first
            detection at scan ``j`` is scored against ``first_detection_means[j]``);
            default: :meth:`population` of a window that starts the recording.
        end_gain : float
            What a path alive at the window's last scan may still gain after it, >= 0
            (0 for a sliding window, whose later scans are another window's business;
            the refinement of the whole recording, :mod:`mapassoc.estimator.refinement`,
            passes what joining a track that continues after the window can add).  It is
            added to every :meth:`remaining_gain_bounds` of the bound pruning.

        Returns
        -------
        WindowHypotheses
        """
        scans, first_detection = self._validated(scans, carried, population)
        if not (end_gain >= 0 and math.isfinite(end_gain)):
            raise InputError(f"end_gain must be a finite number >= 0, got {end_gain!r}")
        detections, offsets = _window_detections(scans)
        tree_track_ids: list[int] = [t.track_id for t in carried]
        remaining_gain = self.remaining_gain_bounds(scans) + end_gain
        frontier = _carried_frontier(carried, self._dims, self._n_max)
        kept_layers: list[HypothesisNodes] = []
        node_count = generated = pruned = capped = 0
        for j, scan in enumerate(scans):
            layer = self._grow_scan(
                frontier, scan, j, offsets[j], len(tree_track_ids), float(first_detection[j])
            )
            tree_track_ids.extend([-1] * scan.size)
            size = sum(len(group) for group in layer)
            if size == 0:
                frontier = _Frontier.empty(self._n_max)
                continue
            generated += size
            is_new_tree = np.array([tid < 0 for tid in tree_track_ids], dtype=bool)
            kept, cut, cut_by_cap = self._prune_layer(layer, j, is_new_tree, remaining_gain[j])
            pruned += cut
            capped += cut_by_cap
            kept_layers.append(kept)
            frontier = _Frontier.of_layer(kept, node_count, scan.time)
            node_count += len(kept)
        nodes = HypothesisNodes.concat(kept_layers, state_dim=self._n_max)
        leaves, used = _canonical_leaves(
            nodes, detections, tree_track_ids, len(carried), len(scans)
        )
        used_mask = used >= 0
        indptr = np.concatenate([[0], np.cumsum(used_mask.sum(axis=1))])
        return WindowHypotheses(
            scans=scans,
            detections=detections,
            tree_track_ids=np.asarray(tree_track_ids, dtype=np.int64),
            scores=nodes.score[leaves],
            tree=nodes.tree[leaves],
            leaf=leaves.astype(np.int64),
            counts_toward_k=nodes.alive[leaves] | (nodes.parent[leaves] >= 0),
            detection_indptr=np.asarray(indptr, dtype=np.int64),
            detection_indices=np.asarray(used[used_mask], dtype=np.int64),
            nodes=nodes,
            nodes_generated=generated,
            nodes_pruned=pruned,
            nodes_capped=capped,
        )

    # -- steps of generate -----------------------------------------------------------
    def _validated(
        self,
        scans: Sequence[Scan],
        carried: Sequence[CarriedTrack],
        population: WindowPopulation | None,
    ) -> tuple[tuple[Scan, ...], FloatArray]:
        """The window's scans, checked, and the first-detection means of its scans."""
        scans = tuple(scans)
        if not scans:
            raise InputError("a window needs at least one scan")
        self._check_scans(scans)
        if population is None:
            population = self.population(scans, carried)
        first_detection = np.asarray(population.first_detection_means, dtype=float)
        if first_detection.shape != (len(scans),):
            raise InputError(
                f"population has first-detection means for {first_detection.shape} scans, "
                f"the window has {len(scans)}"
            )
        for track in carried:
            if track.time > scans[0].time:
                raise InputError(
                    f"carried track {track.track_id} has time {track.time}, after the "
                    f"window's first scan at {scans[0].time}"
                )
        return scans, first_detection

    def _grow_scan(
        self,
        frontier: _Frontier,
        scan: Scan,
        j: int,
        det_offset: int,
        first_tree: int,
        undetected_mean: float,
    ) -> list[_NewNodes]:
        """The nodes created at scan ``j``, states not yet computed: children of the
        frontier, then births."""
        sensor = self.sensors[scan.sensor]
        groups = self._grow(frontier, scan, sensor, det_offset)
        groups += self._births(scan, sensor, det_offset, first_tree, undetected_mean)
        return groups

    def _prune_layer(
        self, layer: Sequence[_NewNodes], j: int, is_new_tree: BoolArray, remaining_gain: float
    ) -> tuple[HypothesisNodes, int, int]:
        """The kept nodes of one scan's layer (their states computed), how many were
        dropped and how many by the cap."""

        def joined(name: str) -> NDArray[Any]:
            return np.concatenate([getattr(group, name) for group in layer])

        sizes = [len(group) for group in layer]
        alive = np.repeat([group.alive for group in layer], sizes)
        tree, score, protected = joined("tree"), joined("score"), joined("protected")
        # An ended node gains nothing more; an alive one at most G_j.
        gain = np.where(alive, remaining_gain, 0.0)
        keep, cut_by_cap = self._prune_mask(tree, score, protected, is_new_tree, gain)
        means: list[FloatArray] = [np.zeros((0, self._n_max))]
        covs: list[FloatArray] = [np.zeros((0, self._n_max, self._n_max))]
        start = 0
        for group, size in zip(layer, sizes, strict=True):
            index = np.flatnonzero(keep[start : start + size])
            start += size
            if index.size:
                group_means, group_covs = group.states(index)
                means.append(group_means)
                covs.append(group_covs)
        nodes = _node_record(
            self._dims,
            parent=joined("parent")[keep],
            layer=j,
            detection=joined("detection")[keep],
            alive=alive[keep],
            tree=tree[keep],
            initiated=joined("initiated")[keep],
            num_detections=joined("num_detections")[keep],
            first_time=joined("first_time")[keep],
            score=score[keep],
            protected=protected[keep],
            means=np.concatenate(means),
            covs=np.concatenate(covs),
        )
        return nodes, int(np.count_nonzero(~keep)), cut_by_cap

    # -- pieces ----------------------------------------------------------------------
    def _grow(
        self,
        frontier: _Frontier,
        scan: Scan,
        sensor: Sensor,
        det_offset: int,
    ) -> list[_NewNodes]:
        """Children of every frontier node at the scan: end, miss, each gated detection."""
        if len(frontier) == 0:
            return []
        f = frontier.nodes
        dt = scan.time - frontier.time
        # Ended between the previous state and this scan.
        log_end = end_term(dt, self._log_survival)
        can_end = np.isfinite(log_end)
        # A carried track that can end keeps its "ended before the window" leaf protected;
        # otherwise its all-miss path carries the protection.
        groups = _ended_nodes(frontier, log_end, f.protected & can_end)
        protect_miss = f.protected & ~can_end
        for initiated in (False, True):
            group = np.flatnonzero(f.initiated == initiated)
            if len(group):
                groups += self._grown_group(
                    frontier, group, initiated, dt[group], protect_miss[group], scan, sensor,
                    det_offset,
                )  # fmt: skip
        return groups

    def _grown_group(
        self,
        frontier: _Frontier,
        group: IntArray,
        initiated: bool,
        dt: FloatArray,
        protect_miss: BoolArray,
        scan: Scan,
        sensor: Sensor,
        det_offset: int,
    ) -> list[_NewNodes]:
        """The missed and continued children of the frontier nodes ``group``, all in one
        state space (``initiated``), ``dt`` after their states."""
        f = frontier.nodes
        model = self.motion if initiated else self._init_model
        d = self._dims[int(initiated)]
        x = f.means[group, :d]
        P = f.covariances[group, :d, :d]
        # Predict, grouped by distinct dt (one value except at a window's start).
        for value in np.unique(dt):
            sel = np.flatnonzero(dt == value)
            if value > 0:
                x[sel], P[sel], _ = self._filter.predict(model, x[sel], P[sel], float(value))
        base = f.score[group] + survival_term(dt, self._log_survival)
        groups: list[_NewNodes] = []
        log_miss = self._terms[scan.sensor].miss
        if math.isfinite(log_miss):
            groups.append(
                _NewNodes(
                    parent=frontier.ids[group],
                    detection=np.full(len(group), -1, dtype=np.int64),
                    alive=True,
                    tree=f.tree[group],
                    initiated=np.full(len(group), initiated),
                    num_detections=f.num_detections[group],
                    first_time=f.first_time[group],
                    score=base + log_miss,
                    protected=protect_miss,
                    states=_padded(x, P, self._n_max),
                )
            )
        if scan.size:
            groups += self._continued(frontier, group, initiated, x, P, base, scan, sensor,
                                      det_offset)  # fmt: skip
        return groups

    def _continued(
        self,
        frontier: _Frontier,
        group: IntArray,
        initiated: bool,
        x: FloatArray,
        P: FloatArray,
        base: FloatArray,
        scan: Scan,
        sensor: Sensor,
        det_offset: int,
    ) -> list[_NewNodes]:
        """The children of the predicted nodes ``group`` (states ``x``, ``P``, scores so
        far ``base``) continued by each detection of the scan in their gate."""
        f = frontier.nodes
        measurement = (
            sensor.measurement
            if initiated
            else initiation_measurement(self.motion, sensor.measurement)
        )
        terms = self._terms[scan.sensor]
        innovation = self._filter.innovation(measurement, x, P)
        pairs = innovation.gate(scan.detections, terms.threshold)
        if len(pairs) == 0:
            return []
        li = pairs.row
        first_time = f.first_time[group][li]
        # Only coordinated-turn tracks are ever uninitiated.  One enters the turn state at
        # its first detection later in time than its first one (the velocity is then
        # observed); its padded row takes the converted state.
        init_flags = np.full(len(li), True) if initiated else scan.time > first_time
        return [
            _NewNodes(
                parent=frontier.ids[group][li],
                detection=det_offset + pairs.detection,
                alive=True,
                tree=f.tree[group][li],
                initiated=init_flags,
                num_detections=f.num_detections[group][li] + 1,
                first_time=first_time,
                score=base[li] + detection_term(terms.log_pd, pairs.loglik, terms.log_clutter),
                protected=np.zeros(len(li), dtype=bool),
                states=self._updated(x, P, innovation, pairs, None if initiated else init_flags),
            )
        ]

    def _updated(
        self,
        x: FloatArray,
        P: FloatArray,
        innovation: Innovation,
        pairs: GatedPairs,
        convert: BoolArray | None,
    ) -> StatesOf:
        """States of the gated pairs' children: the update of row ``pairs.row[i]`` of
        the prediction ``x``, ``P`` by its innovation ``pairs.nu[i]``, padded to
        ``n_max``; a child flagged in ``convert`` (an uninitiated track initiated by this
        detection) takes the converted state."""

        def states(index: IntArray) -> tuple[FloatArray, FloatArray]:
            xu, Pu = self._filter.update(x, P, innovation, pairs.row[index], pairs.nu[index])
            means, covs = _pad(xu, Pu, self._n_max)
            chosen = np.flatnonzero(convert[index]) if convert is not None else ()
            if len(chosen):
                cx, cP = convert_initiated_many(self.motion, xu[chosen], Pu[chosen], self.birth)
                means[chosen], covs[chosen] = _pad(cx, cP, self._n_max)
            return means, covs

        return states

    def _births(
        self,
        scan: Scan,
        sensor: Sensor,
        det_offset: int,
        first_tree: int,
        undetected_mean: float,
    ) -> list[_NewNodes]:
        """One new tree rooted at every detection of the scan.

        The first detection of a target not detected before has density
        ``u Pd / V`` (``u`` = ``undetected_mean``, the expected number of targets alive
        at this scan and never detected, :mod:`mapassoc.models.population`) against the clutter
        density ``lambda_bar / V``: score ``log u + log Pd - log lambda_bar``.
        """
        m = scan.size
        if m == 0:
            return []
        if undetected_mean == 0.0:
            return []  # no undetected target can be here: no detection starts a track
        terms = self._terms[scan.sensor]
        score = birth_term(undetected_mean, terms.log_pd, terms.log_false_alarms)

        def states(index: IntArray) -> tuple[FloatArray, FloatArray]:
            detections = scan.detections[index]
            x, P = birth_states(self.motion, sensor.measurement, detections, self.birth)
            return _pad(x, P, self._n_max)

        return [_roots(scan, det_offset, first_tree, score, not self._converts, states)]

    def _prune_mask(
        self,
        tree: IntArray,
        score: FloatArray,
        protected: BoolArray,
        is_new_tree: BoolArray,
        gain: FloatArray,
    ) -> tuple[BoolArray, int]:
        """:func:`~mapassoc.estimator.tree_pruning.prune_mask` with the generator's
        ratios and cap."""
        return prune_mask(
            tree, score, protected, is_new_tree, gain,
            prune_log_ratio=self.prune_log_ratio,
            sibling_prune_log_ratio=self.sibling_prune_log_ratio,
            max_hypotheses_per_tree=self.max_hypotheses_per_tree,
        )  # fmt: skip


def _check_carried_have_leaves(leaf_trees: IntArray, num_carried: int) -> None:
    """Every carried tree must keep a leaf (pruning protects one; only the model can fail)."""
    if num_carried == 0:
        return
    present = np.zeros(num_carried, dtype=bool)
    present[leaf_trees[leaf_trees < num_carried]] = True
    if not np.all(present):
        missing = np.flatnonzero(~present)
        raise InputError(
            f"carried track tree(s) {missing.tolist()} have no possible hypothesis: "
            "detection probability x gate probability is 1 (a miss is impossible) and the "
            "track cannot end (survival_probability 1 or zero time step); lower one of them"
        )


def _canonical_leaves(
    nodes: HypothesisNodes,
    detections: WindowDetections,
    tree_track_ids: Sequence[int],
    num_carried: int,
    num_scans: int,
) -> tuple[IntArray, IntArray]:
    """The window's leaves in canonical order, and the detections along each path.

    Returns
    -------
    leaves : ndarray of int, shape (H,)
    used : ndarray of int, shape (H, num_scans)
        Window detection of each leaf's path at each scan, -1 for none.
    """
    last = num_scans - 1
    is_leaf = (~nodes.alive) | (nodes.layer == last)
    leaf_nodes = np.flatnonzero(is_leaf)
    _check_carried_have_leaves(nodes.tree[leaf_nodes], num_carried)
    # Canonical order, independent of the order of detections within a scan (so
    # that ties between equal-scoring sets are broken the same way whatever the file
    # order): carried trees by track id, then new trees by their birth detection's
    # row; within a tree by the rows along the path (-1 for a miss, a shorter path
    # first), alive last.  Paths are walked for all leaves at once, one layer a step.
    row_of = detections.rows
    n_leaves = leaf_nodes.size
    path_rows = np.full((n_leaves, num_scans), -2, dtype=np.int64)  # -2: no node
    path_dets = np.full((n_leaves, num_scans), -1, dtype=np.int64)
    root = leaf_nodes.copy()
    current = leaf_nodes.copy()
    walking = np.arange(n_leaves)
    while walking.size:
        at = current[walking]
        det = nodes.detection[at]
        layer = nodes.layer[at]
        path_dets[walking, layer] = det
        rows_here = np.full(det.shape, -1, dtype=np.int64)
        rows_here[det >= 0] = row_of[det[det >= 0]]
        path_rows[walking, layer] = rows_here
        root[walking] = at
        current[walking] = nodes.parent[at]
        walking = walking[current[walking] >= 0]
    leaf_tree = nodes.tree[leaf_nodes]
    is_new = leaf_tree >= num_carried
    root_layer = nodes.layer[root]
    ids = np.asarray(tree_track_ids, dtype=np.int64)
    owner = np.where(is_new, path_rows[np.arange(n_leaves), root_layer], ids[leaf_tree])
    order = np.lexsort(
        (
            nodes.alive[leaf_nodes],
            *path_rows.T[::-1],
            root_layer,
            owner,
            is_new,
        )
    )
    return leaf_nodes[order], path_dets[order]
