"""The recording objective's batched re-filtering engine: linear Kalman runs over a
recording's per-scan matrices, through the backend of :mod:`mapassoc.filtering.compiled`.

:class:`~mapassoc.estimator.objective.RecordingObjective` hands two kinds of work here,
wherever every step is a linear Kalman step in the motion model's own space (a linear
motion model and linear measurements):

* one track's run through the rest of its detections (:meth:`Refiltering.filter_path`,
  the tail of :meth:`~mapassoc.estimator.objective.RecordingObjective.trajectory`);
* the refinement's joins: many batches of tracks, each continued along a reference
  track's detections until its state has converged to the reference's
  (:meth:`Refiltering.converge`, the body of
  :meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging_many`).

Both read the recording once, as a :data:`~mapassoc.filtering.scan_steps.ScanModel`
(the motion model's F and Q per scan, each scan's H and R, the table of terms): built on
first use and kept.  The backend (compiled kernels or their numpy twin) is asked for at
each call, so the ``MAPASSOC_COMPILED`` switch is read in one place.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.converging import ConvergeRequest
from mapassoc.estimator.terms import ScanTerms
from mapassoc.estimator.track_paths import CONVERGED, PathState, TrackPath
from mapassoc.filtering.batch import KalmanFilter
from mapassoc.filtering.compiled import ScanModel, filter_backend, imm_kernels
from mapassoc.filtering.scan_steps import SetModel
from mapassoc.models.interacting import InteractingModels
from mapassoc.models.measurement import LinearMeasurement, MeasurementModel
from mapassoc.models.motion import MotionModel

__all__ = ["Refiltering"]



class Refiltering:
    """Linear Kalman runs of one recording's tracks (module docstring).

    Parameters
    ----------
    scans : sequence of Scan
    measurements : sequence of MeasurementModel
        Each scan's measurement model.
    motion : MotionModel
    terms : ScanTerms
        The recording's table of terms.
    kalman : KalmanFilter
        Its ``(F, Q)`` per time step (shared with the objective's own steps).
    """

    def __init__(
        self,
        *,
        scans: Sequence[Scan],
        measurements: Sequence[MeasurementModel],
        motion: MotionModel,
        terms: ScanTerms,
        kalman: KalmanFilter,
    ) -> None:
        self.scans = tuple(scans)
        self.measurements = tuple(measurements)
        self.motion = motion
        self.terms = terms
        self.kalman = kalman
        self.measurement_dim = max(m.measurement_dim for m in self.measurements)
        self._scan_model: ScanModel | None = None
        self._set_model: SetModel | None = None
        self._linear_set = isinstance(motion, InteractingModels) and all(
            model.is_linear for model in motion.models
        )

    def linear_suffix(self, path: TrackPath) -> int:
        """The first index of ``path`` from which every step is a linear Kalman step (a
        linear motion model and linear measurements at the path's scans); ``len(path)``
        where the motion model is not linear."""
        if not self.motion.is_linear:
            return len(path)
        k = len(path)
        while k > 0 and isinstance(self.measurements[path[k - 1][0]], LinearMeasurement):
            k -= 1
        return k

    def converges(self, path: TrackPath) -> bool:
        """Whether :meth:`converge` takes a request along ``path``: every step a linear
        Kalman step (:meth:`linear_suffix` is 0), or, for a set of linear motion models
        with the compiled kernels loaded, every measurement linear (a set's numpy twin
        is the objective's lockstep continuation, which takes everything)."""
        if self._linear_set:
            return imm_kernels() is not None and all(
                isinstance(self.measurements[m], LinearMeasurement) for m, _ in path
            )
        return self.linear_suffix(path) == 0

    def set_model(self) -> SetModel:
        """What the compiled joins of a set read of the recording per scan
        (:data:`~mapassoc.filtering.scan_steps.SetModel`), built once: each model's ``F``
        and ``Q`` and the switching matrix of the step from each scan's predecessor
        (zeros where the time step is not positive)."""
        if self._set_model is None:
            motion = self.motion
            assert isinstance(motion, InteractingModels)
            times, K, n = self.terms.times, motion.n_models, motion.state_dim
            S = len(self.scans)
            moves = np.zeros(S, dtype=bool)
            F, Q, Pi = np.zeros((S, K, n, n)), np.zeros((S, K, n, n)), np.zeros((S, K, K))
            for m in range(1, S):
                dt = float(times[m] - times[m - 1])
                if dt > 0:
                    stacked = self.kalman.stacked_motion(motion, dt)
                    assert stacked is not None  # every model is linear (converges)
                    moves[m] = True
                    F[m], Q[m] = stacked
                    Pi[m] = self.kalman.switching(motion, dt)
            self._set_model = (moves, F, Q, Pi)
        return self._set_model

    def scan_model(self) -> ScanModel:
        """What the backends read of the recording per scan
        (:data:`~mapassoc.filtering.scan_steps.ScanModel`), built once: the motion model's
        ``F`` and ``Q`` from each scan's predecessor (zeros where the time step is not
        positive), each linear measurement's ``H``, ``R`` zero-padded to the largest
        measurement dimension, the per-scan terms and gates, and the codes of equal time
        steps and equal sensors."""
        if self._scan_model is None:
            times = self.terms.times
            M, n, dz = len(self.scans), self.motion.state_dim, self.measurement_dim
            moves = np.zeros(M, dtype=bool)
            F, Q = np.zeros((M, n, n)), np.zeros((M, n, n))
            H, R = np.zeros((M, dz, n)), np.zeros((M, dz, dz))
            dims = np.zeros(M, dtype=np.int64)
            motion_code = np.zeros(M, dtype=np.int64)
            sensor_code = np.zeros(M, dtype=np.int64)
            steps: dict[float, int] = {}
            sensors: dict[str, int] = {}
            for m in range(M):
                dt = float(times[m] - times[m - 1]) if m else 0.0
                matrices = self.kalman.linear_motion(self.motion, dt) if dt > 0 else None
                if matrices is not None:
                    moves[m] = True
                    F[m], Q[m] = matrices
                    motion_code[m] = steps.setdefault(dt, len(steps))
                sensor_code[m] = sensors.setdefault(self.scans[m].sensor, len(sensors))
                measurement = self.measurements[m]
                if isinstance(measurement, LinearMeasurement):
                    d = measurement.H.shape[0]
                    dims[m] = d
                    H[m, :d] = measurement.H
                    R[m, :d, :d] = measurement.noise_covariance
            t = self.terms
            survival, miss, log_pd, log_clutter, thresholds = (
                np.ascontiguousarray(a, dtype=np.float64)
                for a in (t.survival, t.miss, t.log_pd, t.log_clutter, t.thresholds)
            )
            self._scan_model = (
                moves, F, Q, H, R, dims, survival, miss, log_pd, log_clutter, thresholds,
                motion_code, sensor_code,
            )  # fmt: skip
        return self._scan_model

    def filter_path(
        self, state: PathState, path: TrackPath
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """One track's run from ``state`` (a batch of one, in the motion model's space)
        through ``path`` (linear steps only): its means ``(L, n)``, covariances
        ``(L, n, n)`` and values ``(L,)`` after each detection."""
        detections = np.zeros((len(path), self.measurement_dim))
        for i, (m, j) in enumerate(path):
            z = self.scans[m].detections[j]
            detections[i, : z.shape[0]] = z
        means, covariances, values, positive = filter_backend().filter_along_path(
            np.array(state.means[0], dtype=np.float64),
            np.array(state.covariances[0], dtype=np.float64),
            float(state.value[0]),
            int(state.scan),
            np.array([m for m, _ in path], dtype=np.int64),
            detections,
            self.scan_model(),
        )
        if not positive:
            raise InputError("innovation covariance S is not positive-definite")
        return means, covariances, values

    def converge(
        self, requests: Sequence[ConvergeRequest], max_detections: int | None
    ) -> list[FloatArray]:
        """Each request's tracks continued along its reference until converged (linear
        steps only): what
        :meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging`
        returns for each, up to rounding.

        What each step reads of a track's reference (its detection, scan, the
        reference's state and value there) is gathered once per request into arrays
        indexed by (request, step), so a step is array indexing whatever the number of
        tracks; the tracks of every request are stacked into flat arrays, continued by
        the backend's ``continue_along_references``, and the flat result is cut back
        into one array per request.
        """
        for start, reference, first in requests:  # a path must be after its start
            if reference.path[first][0] <= start.scan:
                raise InputError(
                    f"path detection at scan {reference.path[first][0]} is not after the "
                    f"track's state at scan {start.scan}"
                )
        table = _ReferenceSteps.gather(self, requests, max_detections)
        starts = [start for start, _, _ in requests]
        sizes = np.array([len(start) for start in starts], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)])
        tracks = (
            np.ascontiguousarray(np.concatenate([s.means for s in starts]), dtype=np.float64),
            np.ascontiguousarray(np.concatenate([s.covariances for s in starts]), dtype=np.float64),
            np.ascontiguousarray(np.concatenate([s.value for s in starts]), dtype=np.float64),
            np.repeat(np.array([s.scan for s in starts], dtype=np.int64), sizes),
            np.repeat(np.arange(len(requests), dtype=np.int64), sizes),
            table.steps, table.scan, table.detection, table.rest, table.mean,
            table.covariance, table.tail, self.scan_model(),
        )  # fmt: skip
        kernels = imm_kernels() if self._linear_set else None
        if kernels is not None:
            flat, positive = kernels.continue_sets_along_references(
                *tracks, self.set_model(), CONVERGED
            )
        else:
            flat, positive = filter_backend().continue_along_references(*tracks, CONVERGED)
        if not positive:
            raise InputError("innovation covariance S is not positive-definite")
        flat = np.asarray(flat, dtype=np.float64)
        return [flat[offsets[c] : offsets[c + 1]] for c in range(len(requests))]


@dataclass(frozen=True, eq=False)
class _ReferenceSteps:
    """What the batched continuation reads of each request's reference, per step.

    Row ``c`` is request ``c``; column ``s`` its reference's detection ``first + s``, for
    ``s < steps[c]`` (up to the reference's last detection or the cap).

    Attributes
    ----------
    steps : ndarray of int, shape (C,)
    scan : ndarray of int, shape (C, W)
        The detection's scan.
    detection : ndarray, shape (C, W, dz)
        The measurement (zero-padded to the largest sensor dimension).
    rest : ndarray, shape (C, W)
        The reference's value after its last detection minus its value at this one.
    mean, covariance : ndarray, shapes (C, W, n) and (C, W, n, n)
        The reference's filtered state at this detection.
    tail : ndarray, shape (C,)
        The best ending after the reference's last detection.
    """

    steps: IntArray
    scan: IntArray
    detection: FloatArray
    rest: FloatArray
    mean: FloatArray
    covariance: FloatArray
    tail: FloatArray

    @classmethod
    def gather(
        cls,
        engine: Refiltering,
        requests: Sequence[ConvergeRequest],
        max_detections: int | None,
    ) -> _ReferenceSteps:
        C = len(requests)
        lasts = [len(reference.path) - 1 for _, reference, _ in requests]
        stops = [
            last if max_detections is None else min(last, first + max_detections - 1)
            for (_, _, first), last in zip(requests, lasts, strict=True)
        ]
        steps = np.array(
            [stop - first + 1 for (_, _, first), stop in zip(requests, stops, strict=True)],
            dtype=np.int64,
        )
        W = int(steps.max(initial=1))
        n = requests[0][0].means.shape[1]
        scan = np.zeros((C, W), dtype=np.int64)
        detection = np.zeros((C, W, engine.measurement_dim))
        rest = np.zeros((C, W))
        mean = np.zeros((C, W, n))
        covariance = np.zeros((C, W, n, n))
        tail = np.zeros(C)
        for c, (_, reference, first) in enumerate(requests):
            tail[c] = engine.terms.tails[reference.path[-1][0]]
            for s in range(int(steps[c])):
                m, j = reference.path[first + s]
                z = engine.scans[m].detections[j]
                scan[c, s] = m
                detection[c, s, : z.shape[0]] = z
                rest[c, s] = reference.values[-1] - reference.values[first + s]
                mean[c, s] = reference.means[first + s]
                covariance[c, s] = reference.covariances[first + s]
        return cls(steps, scan, detection, rest, mean, covariance, tail)
