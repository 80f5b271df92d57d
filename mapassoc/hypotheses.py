"""Track hypotheses of one window: track trees grown scan by scan, Kalman-scored.

A window is a run of consecutive scans.  Every track tree of the window is either

* a **carried track**, committed by earlier windows, whose filtered state at its last
  committed scan is the prior; its hypotheses include ending before the window; or
* a **new track**, born at one detection of the window (single-point initiation,
  :mod:`mapassoc.birth`).

Each alive leaf grows at each scan into: the track ended (alive at the previous scan,
dead at this one), the track missed, or the track continued by one gated detection.
The score of a hypothesis (a root-to-leaf path) is its log-likelihood ratio against
"all its detections are false alarms and the track does not exist"; it is a sum of
the terms below (derivation: ``docs/model.md``; the sum over a track set plus a
constant is ``log p(track set, K | Z)`` of seed 002, eqs. 8-14):

====================================  ===============================================
event at a scan of sensor s           term
====================================  ===============================================
first detection z at scan j           ``log u_j + log Pd_s - log lambda_bar_s``
                                      (density ``u_j Pd_s / V_s`` of a target never
                                      detected before, ``u_j`` the undetected-target
                                      mean of :mod:`mapassoc.population`, over the
                                      clutter density ``lambda_s = lambda_bar_s / V_s``)
survival over dt                      ``dt log Ps``
continued by detection z              ``log Pd_s + log N(nu; 0, S) - log lambda_s``
                                      (seed 001 weight; seed 000 eq. 11)
missed                                ``log(1 - Pd_s P_G)`` (P_G: gate probability)
ended over dt                         ``log(1 - Ps^dt)``
====================================  ===============================================

Growth is bounded by a chi-square gate and by pruning, which compares like with like.
At each scan a node is dropped

* against its **siblings**, the nodes of the same tree at the same scan (they compete
  for the same detections: at most one hypothesis of a tree is selected), when its
  score is more than ``prune_log_ratio`` below the best of them;
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
  the cap are counted in :attr:`WindowHypotheses.capped`, so that a caller can report
  that the window's hypotheses are not all those within the ratio.

A carried tree always keeps a leaf that uses no detection (ended before the window, or
all misses), so pruning never makes a window infeasible.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.birth import (
    birth_states,
    convert_initiated,
    initiation_measurement,
    initiation_model,
    needs_conversion,
)
from mapassoc.errors import InputError
from mapassoc.kalman import (
    gate_threshold,
    gated_pairs_and_loglik,
    pairwise_gate_and_loglik,
    predict_motion,
    update,
)
from mapassoc.motion import MotionModel
from mapassoc.population import (
    UndetectedTargets,
    WindowPopulation,
    recording_start,
    window_population,
)
from mapassoc.scans import Scan
from mapassoc.sensor import Sensor
from mapassoc.settings import BirthModel

__all__ = [
    "CarriedTrack",
    "WindowDetections",
    "HypothesisNodes",
    "WindowHypotheses",
    "HypothesisGenerator",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_LAYER_FIELDS = (
    "parent",
    "detection",
    "alive",
    "tree",
    "initiated",
    "num_detections",
    "first_time",
    "score",
    "protected",
)
"""Per-node fields of a layer that are concatenated, pruned and stored together."""

_DENSE_GATING_PAIRS = 4096
"""Above this many (node, detection) pairs per scan, linear gating goes through a k-d tree."""


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
    """Every kept node of a window's track trees (a node = a track's state at one scan).

    States of different state spaces (coordinated turn before and after initiation)
    share padded arrays; ``state_dims`` says how many leading entries are used.

    Attributes
    ----------
    parent : ndarray of int, shape (V,)
        Parent node, -1 for a root.
    layer : ndarray of int, shape (V,)
        Scan position in the window.
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
    means : ndarray, shape (V, n_max)
    covariances : ndarray, shape (V, n_max, n_max)
    state_dims : ndarray of int, shape (V,)
    """

    parent: IntArray
    layer: IntArray
    detection: IntArray
    alive: NDArray[np.bool_]
    tree: IntArray
    initiated: NDArray[np.bool_]
    num_detections: IntArray
    first_time: FloatArray
    means: FloatArray
    covariances: FloatArray
    state_dims: IntArray

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
    generated : int
        Nodes created (before pruning).
    pruned : int
        Nodes dropped, by the score-ratio tests and by the cap together.
    capped : int
        Of the ``pruned`` nodes, those dropped only by the per-tree cap
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
    counts_toward_k: NDArray[np.bool_]
    detection_indptr: IntArray
    detection_indices: IntArray
    nodes: HypothesisNodes
    generated: int
    pruned: int
    capped: int = 0

    @property
    def count(self) -> int:
        return int(self.scores.shape[0])

    def detections_of(self, h: int) -> IntArray:
        return self.detection_indices[self.detection_indptr[h] : self.detection_indptr[h + 1]]


@dataclass
class _Layer:
    """Nodes created at one scan, before they are stored (mutable scratch)."""

    parent: list[IntArray]
    detection: list[IntArray]
    alive: list[NDArray[np.bool_]]
    tree: list[IntArray]
    initiated: list[NDArray[np.bool_]]
    num_detections: list[IntArray]
    first_time: list[FloatArray]
    score: list[FloatArray]
    protected: list[NDArray[np.bool_]]
    means: list[FloatArray]
    covs: list[FloatArray]

    @classmethod
    def empty(cls) -> _Layer:
        return cls([], [], [], [], [], [], [], [], [], [], [])

    def add(
        self,
        *,
        parent: IntArray,
        detection: IntArray,
        alive: bool,
        tree: IntArray,
        initiated: NDArray[np.bool_],
        num_detections: IntArray,
        first_time: FloatArray,
        score: FloatArray,
        protected: NDArray[np.bool_],
        means: FloatArray,
        covs: FloatArray,
    ) -> None:
        k = len(score)
        if k == 0:
            return
        self.parent.append(np.asarray(parent, dtype=np.int64))
        self.detection.append(np.asarray(detection, dtype=np.int64))
        self.alive.append(np.full(k, alive))
        self.tree.append(np.asarray(tree, dtype=np.int64))
        self.initiated.append(np.asarray(initiated, dtype=bool))
        self.num_detections.append(np.asarray(num_detections, dtype=np.int64))
        self.first_time.append(np.broadcast_to(np.asarray(first_time, dtype=float), (k,)).copy())
        self.score.append(np.asarray(score, dtype=float))
        self.protected.append(np.asarray(protected, dtype=bool))
        self.means.append(means)
        self.covs.append(covs)


def _pad(means: FloatArray, covs: FloatArray, n_max: int) -> tuple[FloatArray, FloatArray]:
    k, d = means.shape
    if d == n_max:
        return means, covs
    m = np.zeros((k, n_max))
    c = np.zeros((k, n_max, n_max))
    m[:, :d] = means
    c[:, :d, :d] = covs
    return m, c


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
        Nodes scoring more than this below the best node of their tree at the same scan
        are dropped, and so are nodes of new trees whose optimistic final score (score
        plus :meth:`remaining_gain_bounds`) is below minus this (module docstring).
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
    ) -> None:
        self.motion = motion
        self.sensors = dict(sensors)
        for name, sensor in self.sensors.items():
            if not sensor.false_alarms_per_scan > 0:
                raise InputError(
                    f"sensor '{name}' has false_alarms_per_scan = "
                    f"{sensor.false_alarms_per_scan}; the estimator scores detections against "
                    "the false-alarm density and needs a positive rate (use a small value such "
                    "as 1e-6 for nearly clutter-free data)"
                )
        self.birth = birth
        if not 0 < gate_probability <= 1:
            raise InputError(f"gate_probability must be in (0, 1], got {gate_probability!r}")
        self.gate_probability = float(gate_probability)
        self.max_hypotheses_per_tree = int(max_hypotheses_per_tree)
        self.prune_log_ratio = float(prune_log_ratio)
        self._init_model = initiation_model(motion)
        self._converts = needs_conversion(motion)
        self._n_max = max(motion.state_dim, self._init_model.state_dim)
        self._log_survival = math.log(birth.survival_probability)

    # -- scoring terms ---------------------------------------------------------------
    def _log_end(self, dt: FloatArray) -> FloatArray:
        """log(1 - Ps^dt); -inf where ending is impossible (dt = 0 or Ps = 1)."""
        with np.errstate(divide="ignore"):
            return np.log(-np.expm1(dt * self._log_survival))

    def _log_miss(self, sensor: Sensor) -> float:
        p = sensor.detection_probability * self.gate_probability
        return math.log1p(-p) if p < 1.0 else -math.inf

    # -- bounds for pruning ----------------------------------------------------------
    def continuation_gain_bound(self, sensor: Sensor) -> float:
        """Upper bound ``b_s`` of the term a continuation by a detection of ``sensor`` adds.

        The term is ``dt log Ps + log Pd_s + log N(nu; 0, S) - log lambda_s`` (module
        table; ``docs/model.md`` section 2, ``score_tau``), and

            b_s = log Pd_s - log lambda_s - 0.5 log det(2 pi R_s)

        bounds it for every state of the track, every detection and every time step
        (proof in :meth:`remaining_gain_bounds`).  ``R_s`` is the sensor's measurement
        noise covariance, for linear and range-bearing measurements alike.

        Parameters
        ----------
        sensor : Sensor

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
        return math.log(sensor.detection_probability) - sensor.log_clutter_density - 0.5 * logdet

    def remaining_gain_bounds(self, scans: Sequence[Scan]) -> FloatArray:
        """``G_j``, the most a path alive at scan ``j`` can still gain by the window's end.

        With ``b_k`` the :meth:`continuation_gain_bound` of scan ``k``'s sensor and ``N``
        scans in the window,

            G_j = sum_{k = j+1}^{N-1} max(0, b_k),    G_{N-1} = 0.

        **Why this is an upper bound.**  Let ``v`` be an alive node at scan ``j`` with
        score ``s_v``.  A hypothesis grown from ``v`` adds one term at each later scan
        ``k`` it reaches (module table; ``docs/model.md`` section 3), until the window's
        end or its "ended" node:

        * ended over dt: ``log(1 - Ps^dt) <= 0``;
        * missed: ``dt log Ps + log(1 - Pd_k P_G) <= 0`` (``dt >= 0``, ``Ps <= 1``);
        * continued by a detection: ``dt log Ps + log Pd_k + log N(nu; 0, S) - log
          lambda_k``.  The Gaussian density (seed 000, eq. 3) is
          ``log N(nu; 0, S) = -0.5 log det(2 pi S) - 0.5 nu^T S^-1 nu
          <= -0.5 log det(2 pi S)``.  The innovation covariance is
          ``S = H P H^T + R`` (seed 000, section 4.3; for the EKF H is the Jacobian of
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
        scans : sequence of Scan
            The window's scans in time order.

        Returns
        -------
        ndarray, shape (N,)
            ``G_j`` for every scan position ``j``; non-increasing, last entry 0.

        Raises
        ------
        InputError
            When a scan names a sensor the generator does not know.
        """
        per_scan = np.zeros(len(scans))
        for k, scan in enumerate(scans):
            sensor = self.sensors.get(scan.sensor)
            if sensor is None:
                raise InputError(
                    f"scan at time {scan.time} names sensor '{scan.sensor}', which is not "
                    f"configured (known: {sorted(self.sensors)})"
                )
            per_scan[k] = max(0.0, self.continuation_gain_bound(sensor))
        # G_j = sum over k > j: reversed cumulative sum, shifted by one scan.
        from_here = np.cumsum(per_scan[::-1])[::-1]
        return np.concatenate([from_here[1:], [0.0]])

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

        Returns
        -------
        WindowHypotheses
        """
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
        det_counts = [s.size for s in scans]
        offsets = np.concatenate([[0], np.cumsum(det_counts)]).astype(np.int64)
        detections = WindowDetections(
            scan_position=np.repeat(np.arange(len(scans)), det_counts).astype(np.int64),
            index_in_scan=np.concatenate(
                [np.arange(c, dtype=np.int64) for c in det_counts] or [np.zeros(0, np.int64)]
            ),
            rows=np.concatenate([s.rows for s in scans] or [np.zeros(0, np.int64)]),
        )

        tree_track_ids: list[int] = [t.track_id for t in carried]
        # Stored nodes, appended layer by layer.
        store: dict[str, list[np.ndarray]] = {
            k: []
            for k in (
                "parent",
                "layer",
                "detection",
                "alive",
                "tree",
                "initiated",
                "num_detections",
                "first_time",
                "means",
                "covs",
                "dims",
                "score",
                "protected",
            )
        }
        node_count = 0
        generated = 0
        pruned = 0
        capped = 0
        remaining_gain = self.remaining_gain_bounds(scans)

        # Frontier: alive nodes to grow at the next scan.
        frontier = self._carried_frontier(carried)
        for j, scan in enumerate(scans):
            sensor = self.sensors[scan.sensor]
            layer = _Layer.empty()
            self._grow(layer, frontier, scan, sensor, j, offsets[j])
            num_trees_before = len(tree_track_ids)
            self._births(
                layer, scan, sensor, offsets[j], num_trees_before, float(first_detection[j])
            )
            tree_track_ids.extend([-1] * scan.size)
            is_new_tree = np.array([tid < 0 for tid in tree_track_ids], dtype=bool)
            if not layer.score:
                frontier = None
                continue
            cat = {name: np.concatenate(getattr(layer, name)) for name in _LAYER_FIELDS}
            dims = np.where(
                cat["initiated"], self.motion.state_dim, self._init_model.state_dim
            ).astype(np.int64)
            padded = [_pad(m, c, self._n_max) for m, c in zip(layer.means, layer.covs, strict=True)]
            means = np.concatenate([p[0] for p in padded])
            covs = np.concatenate([p[1] for p in padded])
            generated += len(cat["score"])
            # An ended node gains nothing more; an alive one at most G_j.
            gain = np.where(cat["alive"], remaining_gain[j], 0.0)
            keep, cut_by_cap = self._prune_mask(
                cat["tree"], cat["score"], cat["protected"], is_new_tree, gain
            )
            pruned += int(np.count_nonzero(~keep))
            capped += cut_by_cap
            ids = node_count + np.arange(int(np.count_nonzero(keep)))
            node_count += len(ids)
            for name in _LAYER_FIELDS:
                store[name].append(cat[name][keep])
            store["layer"].append(np.full(len(ids), j, dtype=np.int64))
            store["means"].append(means[keep])
            store["covs"].append(covs[keep])
            store["dims"].append(dims[keep])
            alive = cat["alive"][keep]
            frontier = {
                "node": ids[alive],
                "tree": cat["tree"][keep][alive],
                "initiated": cat["initiated"][keep][alive],
                "num_detections": cat["num_detections"][keep][alive],
                "first_time": cat["first_time"][keep][alive],
                "score": cat["score"][keep][alive],
                "protected": cat["protected"][keep][alive],
                "means": means[keep][alive],
                "covs": covs[keep][alive],
                "dims": dims[keep][alive],
                "time": np.full(int(np.count_nonzero(alive)), scan.time),
            }

        def _cat(name: str, dtype: type, shape_tail: tuple[int, ...] = ()) -> np.ndarray:
            parts = store[name]
            if not parts:
                return np.zeros((0,) + shape_tail, dtype=dtype)
            return np.concatenate(parts).astype(dtype, copy=False)

        nodes = HypothesisNodes(
            parent=_cat("parent", np.int64),
            layer=_cat("layer", np.int64),
            detection=_cat("detection", np.int64),
            alive=_cat("alive", bool),
            tree=_cat("tree", np.int64),
            initiated=_cat("initiated", bool),
            num_detections=_cat("num_detections", np.int64),
            first_time=_cat("first_time", float),
            means=_cat("means", float, (self._n_max,)),
            covariances=_cat("covs", float, (self._n_max, self._n_max)),
            state_dims=_cat("dims", np.int64),
        )
        scores_all = _cat("score", float)
        last = len(scans) - 1
        is_leaf = (~nodes.alive) | (nodes.layer == last)
        leaf_nodes = np.flatnonzero(is_leaf)
        self._check_carried_have_leaves(nodes.tree[leaf_nodes], len(carried))
        # Canonical order, independent of the order of detections within a scan (so
        # that ties between equal-scoring sets are broken the same way whatever the file
        # order): carried trees by track id, then new trees by their birth detection's
        # row; within a tree by the rows along the path (-1 for a miss, a shorter path
        # first), alive last.  Paths are walked for all leaves at once, one layer a step.
        row_of = detections.rows
        n_leaves = leaf_nodes.size
        path_rows = np.full((n_leaves, len(scans)), -2, dtype=np.int64)  # -2: no node
        path_dets = np.full((n_leaves, len(scans)), -1, dtype=np.int64)
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
        is_new = leaf_tree >= len(carried)
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
        leaves = leaf_nodes[order]
        counts = nodes.alive[leaves] | (nodes.parent[leaves] >= 0)
        used = path_dets[order]
        used_mask = used >= 0
        indptr = np.concatenate([[0], np.cumsum(used_mask.sum(axis=1))])
        indices = used[used_mask]
        return WindowHypotheses(
            scans=scans,
            detections=detections,
            tree_track_ids=np.asarray(tree_track_ids, dtype=np.int64),
            scores=scores_all[leaves],
            tree=nodes.tree[leaves],
            leaf=leaves.astype(np.int64),
            counts_toward_k=counts,
            detection_indptr=np.asarray(indptr, dtype=np.int64),
            detection_indices=np.asarray(indices, dtype=np.int64),
            nodes=nodes,
            generated=generated,
            pruned=pruned,
            capped=capped,
        )

    # -- pieces ----------------------------------------------------------------------
    def _carried_frontier(self, carried: Sequence[CarriedTrack]) -> dict[str, np.ndarray] | None:
        if not carried:
            return None
        means, covs, dims = [], [], []
        for t in carried:
            d = self.motion.state_dim if t.initiated else self._init_model.state_dim
            m = np.asarray(t.mean, dtype=float)
            c = np.asarray(t.covariance, dtype=float)
            if m.shape != (d,) or c.shape != (d, d):
                raise InputError(
                    f"carried track {t.track_id} state has shape {m.shape}, covariance "
                    f"{c.shape}; expected ({d},) and ({d}, {d})"
                )
            pm, pc = _pad(m[None], c[None], self._n_max)
            means.append(pm[0])
            covs.append(pc[0])
            dims.append(d)
        k = len(carried)
        return {
            "node": np.full(k, -1, dtype=np.int64),
            "tree": np.arange(k, dtype=np.int64),
            "initiated": np.array([t.initiated for t in carried], dtype=bool),
            "num_detections": np.array([t.num_detections for t in carried], dtype=np.int64),
            "first_time": np.array([t.first_detection_time for t in carried], dtype=float),
            "score": np.zeros(k),
            "protected": np.ones(k, dtype=bool),
            "means": np.array(means),
            "covs": np.array(covs),
            "dims": np.array(dims, dtype=np.int64),
            "time": np.array([t.time for t in carried], dtype=float),
        }

    def _grow(
        self,
        layer: _Layer,
        frontier: dict[str, np.ndarray] | None,
        scan: Scan,
        sensor: Sensor,
        j: int,
        det_offset: int,
    ) -> None:
        """Children of every frontier node at scan ``j``: end, miss, each gated detection."""
        if frontier is None or len(frontier["score"]) == 0:
            return
        dt = scan.time - frontier["time"]
        # Ended between the previous state and this scan.
        log_end = self._log_end(dt)
        can_end = np.isfinite(log_end)
        # A carried track that can end keeps its "ended before the window" leaf protected;
        # otherwise its all-miss path carries the protection.
        protect_end = frontier["protected"] & can_end
        protect_miss = frontier["protected"] & ~can_end
        idx = np.flatnonzero(can_end)
        layer.add(
            parent=frontier["node"][idx],
            detection=np.full(len(idx), -1),
            alive=False,
            tree=frontier["tree"][idx],
            initiated=frontier["initiated"][idx],
            num_detections=frontier["num_detections"][idx],
            first_time=frontier["first_time"][idx],
            score=frontier["score"][idx] + log_end[idx],
            protected=protect_end[idx],
            means=frontier["means"][idx],
            covs=frontier["covs"][idx],
        )
        log_miss = self._log_miss(sensor)
        log_pd = math.log(sensor.detection_probability)
        log_lambda = sensor.log_clutter_density
        threshold = gate_threshold(self.gate_probability, sensor.measurement.measurement_dim)
        R = sensor.measurement.noise_covariance
        Z = scan.detections
        for initiated in (False, True):
            group = np.flatnonzero(frontier["initiated"] == initiated)
            if len(group) == 0:
                continue
            model = self.motion if initiated else self._init_model
            measurement = (
                sensor.measurement
                if initiated
                else initiation_measurement(self.motion, sensor.measurement)
            )
            d = model.state_dim
            x = frontier["means"][group, :d]
            P = frontier["covs"][group, :d, :d]
            gdt = dt[group]
            # Predict, grouped by distinct dt (one value except at a window's start).
            for value in np.unique(gdt):
                sel = np.flatnonzero(gdt == value)
                if value > 0:
                    x[sel], P[sel], _ = predict_motion(model, x[sel], P[sel], float(value))
            base = frontier["score"][group] + gdt * self._log_survival
            # Missed at this scan.
            if math.isfinite(log_miss):
                mm, mc = _pad(x, P, self._n_max)
                layer.add(
                    parent=frontier["node"][group],
                    detection=np.full(len(group), -1),
                    alive=True,
                    tree=frontier["tree"][group],
                    initiated=np.full(len(group), initiated),
                    num_detections=frontier["num_detections"][group],
                    first_time=frontier["first_time"][group],
                    score=base + log_miss,
                    protected=protect_miss[group],
                    means=mm,
                    covs=mc,
                )
            if scan.size == 0:
                continue
            # Gate and score every (node, detection) pair at once.
            H = measurement.jacobian(x)
            z_hat = measurement.predict(x)
            S = H @ P @ np.swapaxes(H, -1, -2) + R
            S = 0.5 * (S + np.swapaxes(S, -1, -2))
            if (
                measurement.is_linear
                and math.isfinite(threshold)
                and len(x) * scan.size > _DENSE_GATING_PAIRS
            ):
                li, mi, nu_pairs, _, pair_loglik = gated_pairs_and_loglik(z_hat, S, Z, threshold)
            else:
                nu = measurement.residual(Z[None, :, :], z_hat[:, None, :])
                d2, loglik = pairwise_gate_and_loglik(nu, S)
                li, mi = np.nonzero(d2 <= threshold)
                nu_pairs, pair_loglik = nu[li, mi], loglik[li, mi]
            if len(li) == 0:
                continue
            xu, Pu = update(x[li], P[li], nu_pairs, S[li], H[li], R)
            ndet = frontier["num_detections"][group][li] + 1
            um, uc = _pad(xu, Pu, self._n_max)
            init_flags = np.full(len(li), initiated)
            if not initiated:
                # Only coordinated-turn tracks are ever uninitiated.  One enters the turn
                # state at its first detection later in time than its first one (the
                # velocity is then observed); the padded rows take the converted state.
                init_flags = scan.time > frontier["first_time"][group][li]
                for k in np.flatnonzero(init_flags):
                    um[k], uc[k] = convert_initiated(self.motion, xu[k], Pu[k], self.birth)
            layer.add(
                parent=frontier["node"][group][li],
                detection=det_offset + mi,
                alive=True,
                tree=frontier["tree"][group][li],
                initiated=init_flags,
                num_detections=ndet,
                first_time=frontier["first_time"][group][li],
                score=base[li] + log_pd + pair_loglik - log_lambda,
                protected=np.zeros(len(li), dtype=bool),
                means=um,
                covs=uc,
            )

    def _births(
        self,
        layer: _Layer,
        scan: Scan,
        sensor: Sensor,
        det_offset: int,
        first_tree: int,
        undetected_mean: float,
    ) -> None:
        """One new tree rooted at every detection of the scan.

        The first detection of a target not detected before has density
        ``u Pd / V`` (``u`` = ``undetected_mean``, the expected number of targets alive
        at this scan and never detected, :mod:`mapassoc.population`) against the clutter
        density ``lambda_bar / V``: score ``log u + log Pd - log lambda_bar``.
        """
        m = scan.size
        if m == 0:
            return
        if undetected_mean == 0.0:
            return  # no undetected target can be here: no detection starts a track
        score = (
            math.log(undetected_mean)
            + math.log(sensor.detection_probability)
            - math.log(sensor.false_alarms_per_scan)
        )
        x, P = birth_states(self.motion, sensor.measurement, scan.detections, self.birth)
        initiated = not self._converts
        mm, mc = _pad(x, P, self._n_max)
        layer.add(
            parent=np.full(m, -1),
            detection=det_offset + np.arange(m),
            alive=True,
            tree=first_tree + np.arange(m),
            initiated=np.full(m, initiated),
            num_detections=np.ones(m, dtype=np.int64),
            first_time=np.full(m, scan.time),
            score=np.full(m, score),
            protected=np.zeros(m, dtype=bool),
            means=mm,
            covs=mc,
        )

    def _prune_mask(
        self,
        tree: IntArray,
        score: FloatArray,
        protected: NDArray[np.bool_],
        is_new_tree: NDArray[np.bool_],
        gain: FloatArray,
    ) -> tuple[NDArray[np.bool_], int]:
        """Which nodes of one scan's layer are kept, and how many the cap alone cut.

        A node passes the score-ratio tests when

        * ``score >= best - prune_log_ratio``, ``best`` the highest score of its tree in
          this layer (siblings, which compete for the same detections); and, for a node
          of a new tree,
        * ``score + gain >= -prune_log_ratio``: ``gain`` bounds what its path can still
          add (:meth:`remaining_gain_bounds`), so a node failing this has only
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

        Returns
        -------
        keep : ndarray of bool, shape (L,)
        capped : int
            Unprotected nodes that passed the score-ratio tests but not the cap.
        """
        ratio = self.prune_log_ratio
        order = np.lexsort((np.arange(len(score)), -score, tree))
        t_sorted = tree[order]
        s_sorted = score[order]
        new_group = np.r_[True, t_sorted[1:] != t_sorted[:-1]]
        starts = np.flatnonzero(new_group)
        group_id = np.cumsum(new_group) - 1
        best = s_sorted[starts][group_id]
        passes = s_sorted >= best - ratio
        passes &= ~is_new_tree[t_sorted] | (s_sorted + gain[order] >= -ratio)
        # Rank among the nodes of the tree that pass (a node dropped by the bound takes
        # no place under the cap).
        passed_before = np.cumsum(passes) - passes
        rank = passed_before - passed_before[starts][group_id]
        ok = passes & (rank < self.max_hypotheses_per_tree)
        keep = np.zeros(len(score), dtype=bool)
        keep[order] = ok
        cut_by_cap = np.zeros(len(score), dtype=bool)
        cut_by_cap[order] = passes & ~ok
        cut_by_cap &= ~protected
        return keep | protected, int(np.count_nonzero(cut_by_cap))

    @staticmethod
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
