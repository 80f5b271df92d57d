"""Global nearest neighbour (GNN): one best 2-D assignment per scan.

At each scan (Blackman & Popoli, *Design and Analysis of Modern Tracking Systems*, 1999,
section 7.2): every live track (tentative and confirmed) is predicted and gated; the
tracks and the scan's detections are matched by the assignment that maximises the sum of
track-score increments, solved exactly by :func:`scipy.optimize.linear_sum_assignment`
(:func:`gnn_assignment`); assigned tracks get a Kalman/EKF update, the others a miss;
the shared management (:mod:`mapassoc.trackers.management`) confirms and deletes tracks
and starts a tentative track at every unassigned detection.

The output is every track that was ever confirmed, with all its detections (its
tentative history included), smoothed by :func:`mapassoc.filtering.smoothing.smooth_tracks`
like every hard-association method.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.data.config import Config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.filtering.smoothing import smooth_tracks
from mapassoc.filtering.track_filter import update_track
from mapassoc.trackers.base import TrackerOutput, check_scans
from mapassoc.trackers.management import (
    ManagedTrack,
    ManagementRule,
    StepOutcome,
    TrackManager,
    check_tracker_config,
    gated_log_ratios,
    management_rule,
    with_own_gate,
)

__all__ = ["GnnTracker", "gnn_assignment", "hard_step", "check_ratio_matrix"]


def check_ratio_matrix(log_lik_ratio: FloatArray, log_miss: FloatArray) -> tuple[
    FloatArray, FloatArray
]:
    """Validate a (T, M) log-likelihood-ratio matrix and its (T,) miss terms.

    Entries may be finite or ``-inf`` (outside the gate); ``log_miss`` may be ``-inf``
    only where a caller accepts it.  Raises :class:`~mapassoc.errors.InputError` for a
    wrong shape, NaN or ``+inf``.
    """
    L = np.asarray(log_lik_ratio, dtype=float)
    miss = np.asarray(log_miss, dtype=float)
    if L.ndim != 2:
        raise InputError(f"log_lik_ratio must be a (T, M) array, got shape {L.shape}")
    if miss.shape != (L.shape[0],):
        raise InputError(
            f"log_miss must have shape ({L.shape[0]},) (one entry per track), got {miss.shape}"
        )
    for name, a in (("log_lik_ratio", L), ("log_miss", miss)):
        if np.any(np.isnan(a)) or np.any(a == math.inf):
            raise InputError(f"{name} must be finite or -inf, got NaN or +inf entries")
    return L, miss


def gnn_assignment(log_lik_ratio: FloatArray, log_miss: FloatArray) -> IntArray:
    """The track-to-detection assignment with the largest total score.

    Maximises ``sum over assigned (t, j) of log_lik_ratio[t, j] + sum over unassigned t
    of log_miss[t]`` with each track and each detection used at most once: a 2-D
    assignment on the cost matrix ``[C | D]`` of shape (T, M + T), ``C = -log_lik_ratio``
    (infeasible outside the gate) and ``D`` diagonal with ``-log_miss`` (a track's own
    "miss" column; Blackman & Popoli 1999, section 7.2, the auction/JVC formulation with
    dummy columns), solved exactly by :func:`scipy.optimize.linear_sum_assignment`.

    Parameters
    ----------
    log_lik_ratio : ndarray, shape (T, M)
        ``log Pd + log N(nu; 0, S) - log lambda`` inside the gate, ``-inf`` outside.
    log_miss : ndarray, shape (T,)
        ``log(1 - Pd P_G)``, finite.

    Returns
    -------
    ndarray of int64, shape (T,)
        The detection of each track, ``-1`` for a miss.
    """
    L, miss = check_ratio_matrix(log_lik_ratio, log_miss)
    if not np.all(np.isfinite(miss)):
        raise InputError("log_miss must be finite for the assignment (every track may miss)")
    T, M = L.shape
    out = np.full(T, -1, dtype=np.int64)
    if T == 0 or M == 0:
        return out
    cost = np.full((T, M + T), math.inf)
    cost[:, :M] = -L
    cost[np.arange(T), M + np.arange(T)] = -miss
    rows, cols = linear_sum_assignment(cost)
    hit = cols < M
    out[rows[hit]] = cols[hit]
    return out


def hard_step(
    config: Config,
    track: ManagedTrack,
    scan: Scan,
    log_ratio: FloatArray,
    detection: int,
    log_miss: float,
) -> StepOutcome:
    """The outcome of a hard assignment: Kalman update with ``detection`` or a miss.

    Parameters
    ----------
    config : Config
    track : ManagedTrack
        Predicted to the scan.
    scan : Scan
    log_ratio : ndarray, shape (M,)
        The track's row of the gated log-likelihood ratios.
    detection : int
        Assigned detection, or -1.
    log_miss : float
        ``log(1 - Pd P_G)``.
    """
    if detection < 0:
        return StepOutcome(filtered=track.filtered, detection=-1, detected=False,
                           increment=log_miss)
    return StepOutcome(
        filtered=update_track(config, track.filtered, scan, detection),
        detection=detection,
        detected=True,
        increment=float(log_ratio[detection]),
    )


class GnnTracker:
    """Global-nearest-neighbour tracker with score-based or M-of-N track management.

    Parameters
    ----------
    config : Config
        Motion, sensor, clutter and birth models; ``config.estimator.pruning.gate_probability``
        is the gate.  Every sensor needs ``false_alarms_per_scan > 0`` and
        ``Pd * P_G < 1`` (:func:`~mapassoc.trackers.management.check_tracker_config`).
    gate_probability : float, optional
        This tracker's own gate probability, in (0, 1]; default
        ``config.estimator.pruning.gate_probability``.
    management : ScoreRule or MOfNRule, optional
        Confirmation and deletion rule; default :class:`~.management.ScoreRule` ().
    name : str
        Label in comparisons.
    """

    def __init__(
        self,
        *,
        config: Config,
        gate_probability: float | None = None,
        management: ManagementRule | None = None,
        name: str = "gnn",
    ) -> None:
        config = with_own_gate(config, gate_probability)
        check_tracker_config(config)
        self.config = config
        self.management = management_rule(management)
        self.name = name

    def track(self, scans: Sequence[Scan]) -> TrackerOutput:
        """Track over ``scans``; ``associations`` are the confirmed tracks' detections.

        ``details`` is the :class:`~mapassoc.trackers.management.TrackManager` at the end
        (every track's steps and its life).
        """
        scans = check_scans(scans, self.config)
        start = time.perf_counter()
        manager = TrackManager(config=self.config, rule=self.management)
        for k, scan in enumerate(scans):
            live = manager.predict(k, scan)
            log_ratio, _ = gated_log_ratios(self.config, [t.filtered for t in live], scan)
            log_miss = manager.miss_log_ratio(scan)
            assigned = gnn_assignment(log_ratio, np.full(len(live), log_miss))
            outcomes = [
                hard_step(self.config, track, scan, log_ratio[t], int(assigned[t]), log_miss)
                for t, track in enumerate(live)
            ]
            free = np.ones(scan.size, dtype=bool)
            free[assigned[assigned >= 0]] = False
            manager.commit(scan, outcomes, free)
        associations = {
            tid: {step.scan_index: step.detection for step in steps if step.detection >= 0}
            for tid, steps in manager.confirmed_histories().items()
        }
        tracks = smooth_tracks(scans, associations, self.config)
        return TrackerOutput(
            tracks=tracks,
            seconds=time.perf_counter() - start,
            associations=associations,
            details=manager,
        )
