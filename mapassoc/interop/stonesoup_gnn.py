"""Stone Soup's global-nearest-neighbour tracker on our scans, as a baseline to measure against.

A standard Stone Soup GNN built from its public components (Stone Soup 1.x):

* ``KalmanPredictor`` with a ``CombinedLinearGaussianTransitionModel`` of one
  ``ConstantVelocity`` per axis, whose ``noise_diff_coeff`` is the configuration's
  :class:`~mapassoc.models.motion.ConstantVelocity` ``noise_intensity`` (both discretise
  continuous white-noise acceleration: the same Q(dt));
* ``ExtendedKalmanUpdater`` (exact Kalman for linear measurements, the EKF for the
  range-bearing radar);
* ``DistanceHypothesiser`` with the ``Mahalanobis`` measure and
  :attr:`StoneSoupGNN.gate` as the missed distance (a detection further than that from
  a track's predicted measurement is not a candidate);
* ``GNNWith2DAssignment``: each scan, the best one-to-one assignment of tracks and
  detections;
* ``MultiMeasurementInitiator``: tracks held until :attr:`StoneSoupGNN.min_points`
  detections (each held track started by a ``SimpleMeasurementInitiator`` at a detection,
  the unmeasured velocity ``N(0, velocity_std^2)`` from the configuration's birth model),
  held tracks dropped after :attr:`StoneSoupGNN.hold_steps` scans without a detection;
* ``UpdateTimeStepsDeleter``: a confirmed track ends after
  :attr:`StoneSoupGNN.delete_steps` scans without a detection;
* ``MultiTargetTracker``, fed scan by scan (``update_tracker``).

Its tracks come back as a :class:`~mapassoc.data.io.TrackTable`: every record from a
track's first to its last detection (the predictions Stone Soup appends after the last
one, before it deletes the track, are left out, as our tracks files leave them out), the
detection id of every update (carried in the Stone Soup detections' metadata by
:func:`~mapassoc.interop.stonesoup.scans_to_stonesoup`), ``-1`` for a miss.  It is a
filter, not a smoother: the states are Stone Soup's filtered estimates.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np

from mapassoc.data.config import Config
from mapassoc.data.io import TrackTable
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.interop.stonesoup import (
    _import,
    _permutation,
    scans_to_stonesoup,
)
from mapassoc.models.motion import ConstantVelocity
from mapassoc.validation import check_integer, check_positive

__all__ = ["StoneSoupGNN", "stonesoup_gnn_tracks"]

_ROW_KEY = "row"
_EPOCH = datetime(2000, 1, 1)


@dataclass(frozen=True)
class StoneSoupGNN:
    """Settings of the Stone Soup GNN baseline (module docstring).

    Parameters
    ----------
    gate : float
        Mahalanobis distance beyond which a detection is not a candidate for a track (3:
        Stone Soup's tutorials' value).
    min_points : int
        Detections that confirm a held track, >= 1.
    hold_steps : int
        Scans without a detection after which a held track is dropped, >= 1.
    delete_steps : int
        Scans without a detection after which a confirmed track ends, >= 1.
    """

    gate: float = 3.0
    min_points: int = 3
    hold_steps: int = 2
    delete_steps: int = 3

    def __post_init__(self) -> None:
        check_positive("gate", self.gate)
        for name in ("min_points", "hold_steps", "delete_steps"):
            check_integer(name, getattr(self, name), minimum=1)


def _tracker(config: Config, settings: StoneSoupGNN) -> Any:
    """The Stone Soup ``MultiTargetTracker`` of the module docstring."""
    motion = config.motion
    if type(motion) is not ConstantVelocity:
        raise InputError(
            f"the Stone Soup GNN baseline needs a constant_velocity motion model, got "
            f"{type(motion).__name__}"
        )
    models = _import("models.transition.linear")
    transition = models.CombinedLinearGaussianTransitionModel(
        [models.ConstantVelocity(motion.noise_intensity) for _ in range(motion.ndim)]
    )
    predictor = _import("predictor.kalman").KalmanPredictor(transition)
    updater = _import("updater.kalman").ExtendedKalmanUpdater(measurement_model=None)
    hypothesiser = _import("hypothesiser.distance").DistanceHypothesiser(
        predictor, updater, measure=_import("measures").Mahalanobis(),
        missed_distance=settings.gate,
    )  # fmt: skip
    associator = _import("dataassociator.neighbour").GNNWith2DAssignment(hypothesiser)
    deleters = _import("deleter.time")
    types = _import("types.state")
    n = motion.state_dim
    velocity_variance = config.birth.velocity_std**2
    prior = types.GaussianState(
        np.zeros((n, 1)), np.diag([0.0 if i % 2 == 0 else velocity_variance for i in range(n)])
    )
    initiator = _import("initiator.simple").MultiMeasurementInitiator(
        prior_state=prior,
        deleter=deleters.UpdateTimeStepsDeleter(time_steps_since_update=settings.hold_steps),
        data_associator=associator,
        updater=updater,
        min_points=settings.min_points,
    )
    return _import("tracker.simple").MultiTargetTracker(
        initiator=initiator,
        deleter=deleters.UpdateTimeStepsDeleter(time_steps_since_update=settings.delete_steps),
        detector=None,
        data_associator=associator,
        updater=updater,
    )


def stonesoup_gnn_tracks(
    scans: Sequence[Scan], config: Config, *, settings: StoneSoupGNN | None = None
) -> TrackTable:
    """Track ``scans`` with Stone Soup's GNN (module docstring) and return its tracks.

    Parameters
    ----------
    scans : sequence of Scan
        Sorted by time.
    config : Config
        A 2-D or 3-D ``constant_velocity`` motion model; its sensors; ``birth.velocity_std``.
    settings : StoneSoupGNN, optional

    Returns
    -------
    TrackTable
        Track ids ``0, 1, ...`` in the order of the tracks' first detections.

    Raises
    ------
    InputError
        Another motion model, or scans the Stone Soup bridge refuses.
    ImportError
        Stone Soup is not installed.
    """
    chosen = StoneSoupGNN() if settings is None else settings
    if not isinstance(chosen, StoneSoupGNN):
        raise InputError(f"settings must be a StoneSoupGNN, got {settings!r}")
    tracker = _tracker(config, chosen)
    pairs = scans_to_stonesoup(scans, config=config, epoch=_EPOCH, row_key=_ROW_KEY)
    seen: dict[int, Any] = {}
    for when, detections in pairs:
        _, tracks = tracker.update_tracker(when, detections)
        for track in tracks:
            seen.setdefault(id(track), track)
    sensor_at = {_microseconds(scan.time): scan.sensor for scan in scans}
    return _track_table(list(seen.values()), config, sensor_at)


def _microseconds(time: float) -> int:
    """A scan time in whole microseconds, the resolution of Stone Soup's datetimes."""
    return int(round(time * 1e6))


def _track_table(tracks: list[Any], config: Config, sensor_at: dict[int, str]) -> TrackTable:
    """Our track table of Stone Soup tracks, trailing predictions left out."""
    update_type = _import("types.update").Update
    names = config.motion.state_names
    inverse = np.argsort(_permutation(names))  # our vector = stonesoup vector[inverse]
    records: list[tuple[float, int, Any]] = []  # (first time, track order key, states)
    for track in tracks:
        states = list(track.states)
        updated = [i for i, s in enumerate(states) if isinstance(s, update_type)]
        if not updated:
            continue
        kept = states[: updated[-1] + 1]
        first = (kept[0].timestamp - _EPOCH).total_seconds()
        records.append((first, len(records), kept))
    records.sort(key=lambda r: (r[0], float(np.asarray(r[2][0].state_vector)[0, 0])))
    ids, times, sensors, means, variances, rows = [], [], [], [], [], []
    for track_id, (_, _, kept) in enumerate(records):
        for state in kept:
            time = (state.timestamp - _EPOCH).total_seconds()
            vector = np.asarray(state.state_vector, dtype=float)[:, 0]
            covariance = np.asarray(state.covar, dtype=float)
            ids.append(track_id)
            times.append(time)
            sensors.append(sensor_at.get(_microseconds(time), next(iter(config.sensors))))
            means.append(vector[inverse])
            variances.append(np.diag(covariance)[inverse])
            rows.append(_detection_row(state, update_type))
    n = len(names)
    return TrackTable(
        track_ids=np.array(ids, dtype=np.int64),
        times=np.array(times, dtype=float),
        sensors=tuple(sensors),
        states=np.array(means, dtype=float).reshape(-1, n),
        variances=np.clip(np.array(variances, dtype=float).reshape(-1, n), 0.0, None),
        detection_rows=np.array(rows, dtype=np.int64),
        state_names=tuple(names),
    )


def _detection_row(state: Any, update_type: Any) -> int:
    """The detection id an update used, -1 for a prediction (a miss)."""
    if not isinstance(state, update_type):
        return -1
    return int(state.hypothesis.measurement.metadata[_ROW_KEY])
