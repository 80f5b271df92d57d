"""One track's recursive filter, as scan-by-scan trackers (GNN, JPDA, MHT) run it.

The same models as the window estimator: a track starts at a detection with the
single-point initiation of :func:`mapassoc.models.birth.birth_state`, in the motion
model's initiation space; a model that converts (coordinated turn) is converted by
:func:`mapassoc.models.birth.convert_initiated` at the first update at a later time than
the first detection, exactly as :func:`mapassoc.filtering.smoothing.smooth_track` does.

A :class:`FilteredTrack` is immutable: every step returns a new one, so a hypothesis tree
(track-oriented MHT) can branch from any node.

Scores follow the track-score (log-likelihood-ratio) convention of Blackman & Popoli,
*Design and Analysis of Modern Tracking Systems* (1999), section 6.2, on the models of
Afzal's survey, eqs. (9)-(13): a detection ``z`` in a track's gate adds
``log Pd + log N(z; h(x), S) - log lambda`` (lambda the clutter intensity, eq. 13) and a
miss adds ``log(1 - Pd P_G)``, with P_G the gate probability.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.filtering.batch import KalmanFilter
from mapassoc.filtering.kalman import _symmetrize, inverse_and_logdet
from mapassoc.models.birth import (
    birth_state,
    convert_initiated,
    initiation_measurement,
    initiation_model,
    needs_conversion,
)
from mapassoc.models.interacting import InteractingModels
from mapassoc.models.measurement import MeasurementModel

_FILTERS: dict[int, tuple[object, KalmanFilter]] = {}
"""The batched filter of each motion model in use (on batches of one track, the steps
of the trees), by the model's id; a model set needs its own (it unpacks its states)."""


def _kalman(config: Config) -> KalmanFilter:
    """The batched filter for ``config.motion`` (kept: it caches F and Q per step)."""
    found = _FILTERS.get(id(config.motion))
    if found is None or found[0] is not config.motion:
        if len(_FILTERS) >= 16:
            _FILTERS.clear()
        found = _FILTERS[id(config.motion)] = (config.motion, KalmanFilter(motion=config.motion))
    return found[1]

__all__ = [
    "FilteredTrack",
    "Innovations",
    "innovations",
    "predict_track",
    "start_track",
    "update_track",
    "update_track_mixture",
]


@dataclass(frozen=True, eq=False)
class FilteredTrack:
    """Filtered moments of one track after its latest scan.

    Attributes
    ----------
    x : ndarray, shape (n,)
        Mean, in the initiation model's space until the track is converted.
    P : ndarray, shape (n, n)
    time : float
        Time of the moments.
    first_time : float
        Time of the track's first detection.
    converted : bool
        Whether ``x`` is in the motion model's own space (always true for models that do
        not convert).
    """

    x: FloatArray
    P: FloatArray
    time: float
    first_time: float
    converted: bool


@dataclass(frozen=True, eq=False)
class Innovations:
    """Every detection of one scan against one predicted track.

    Attributes
    ----------
    nu : ndarray, shape (m, dz)
        Innovations (residuals wrapped by the measurement model).
    S : ndarray, shape (dz, dz)
        Innovation covariance.
    H : ndarray, shape (dz, n)
        Measurement matrix or Jacobian at the predicted mean.
    d2 : ndarray, shape (m,)
        Squared Mahalanobis distances ``nu^T S^-1 nu``.
    log_likelihood : ndarray, shape (m,)
        ``log N(nu; 0, S)`` (Afzal's survey, eq. 3).
    """

    nu: FloatArray
    S: FloatArray
    H: FloatArray
    d2: FloatArray
    log_likelihood: FloatArray


def _measurement(config: Config, track: FilteredTrack, scan: Scan) -> MeasurementModel:
    measurement = config.sensors[scan.sensor].measurement
    if track.converted:
        return measurement
    return initiation_measurement(config.motion, measurement)


def start_track(config: Config, scan: Scan, detection: int) -> FilteredTrack:
    """A track born at detection ``detection`` of ``scan`` (single-point initiation).

    Parameters
    ----------
    config : Config
    scan : Scan
    detection : int
        Index into ``scan.detections``.
    """
    if not 0 <= detection < scan.size:
        raise InputError(
            f"detection {detection} does not exist in the scan at time {scan.time} "
            f"({scan.size} detections)"
        )
    sensor = config.sensors[scan.sensor]
    x, P = birth_state(config.motion, sensor.measurement, scan.detections[detection], config.birth)
    return FilteredTrack(
        x=x,
        P=P,
        time=scan.time,
        first_time=scan.time,
        converted=not needs_conversion(config.motion),
    )


def predict_track(config: Config, track: FilteredTrack, time: float) -> FilteredTrack:
    """The track predicted to ``time`` (unchanged when ``time`` equals its time)."""
    dt = time - track.time
    if dt < 0.0:
        raise InputError(f"cannot predict a track at time {track.time} back to time {time}")
    if dt == 0.0:
        return track
    motion = config.motion if track.converted else initiation_model(config.motion)
    x, P, _ = _kalman(config).predict(motion, track.x[None], track.P[None], dt)
    return FilteredTrack(
        x=x[0], P=P[0], time=time, first_time=track.first_time, converted=track.converted
    )


def innovations(config: Config, track: FilteredTrack, scan: Scan) -> Innovations:
    """Innovations of every detection of ``scan`` against ``track`` predicted to the scan."""
    if track.time != scan.time:
        raise InputError(
            f"the track is at time {track.time} but the scan is at {scan.time}; predict first"
        )
    measurement = _measurement(config, track, scan)
    innovation = _kalman(config).innovation(measurement, track.x[None], track.P[None])
    Z = scan.detections
    nu = innovation.residuals(Z[None], np.zeros(1, dtype=np.int64))[0]
    d2, loglik = innovation.scores(nu, np.zeros(Z.shape[0], dtype=np.int64))
    return Innovations(nu=nu, S=innovation.S[0], H=innovation.H[0], d2=d2, log_likelihood=loglik)


def _converted_after_update(
    config: Config, track: FilteredTrack, x: FloatArray, P: FloatArray
) -> FilteredTrack:
    if not track.converted and track.time > track.first_time:
        x, P = convert_initiated(config.motion, x, P, config.birth)
        return FilteredTrack(x=x, P=P, time=track.time, first_time=track.first_time, converted=True)
    return FilteredTrack(
        x=x, P=P, time=track.time, first_time=track.first_time, converted=track.converted
    )


def update_track(config: Config, track: FilteredTrack, scan: Scan, detection: int) -> FilteredTrack:
    """Kalman/EKF update of the predicted ``track`` with one detection of ``scan``.

    A converting model is converted after its first update at a time later than its
    first detection.
    """
    measurement = _measurement(config, track, scan)
    kalman = _kalman(config)
    innovation = kalman.innovation(measurement, track.x[None], track.P[None])
    nu = innovation.residuals(scan.detections[detection][None])
    x, P = kalman.update(track.x[None], track.P[None], innovation, np.zeros(1, np.int64), nu)
    return _converted_after_update(config, track, x[0], P[0])


def update_track_mixture(
    config: Config,
    track: FilteredTrack,
    scan: Scan,
    innov: Innovations,
    weights: FloatArray,
    miss_weight: float,
) -> FilteredTrack:
    """Probabilistic-data-association update with association weights.

    Bar-Shalom, Daum & Huang, "The probabilistic data association filter", IEEE Control
    Systems Magazine 29(6), 2009, eqs. (30)-(36): with ``beta_j`` the probability that
    detection j is the track's and ``beta_0`` that none is,
    ``x+ = x + K nu_c`` with ``nu_c = sum_j beta_j nu_j`` and
    ``P+ = beta_0 P + (1 - beta_0) P_c + K (sum_j beta_j nu_j nu_j^T - nu_c nu_c^T) K^T``,
    ``P_c`` the covariance of a single update.

    Parameters
    ----------
    config : Config
    track : FilteredTrack
        Predicted to the scan's time.
    scan : Scan
    innov : Innovations
        From :func:`innovations` for this track and scan.
    weights : ndarray, shape (m,)
        ``beta_j`` for every detection of the scan (zero outside the gate).
    miss_weight : float
        ``beta_0``; ``miss_weight + weights.sum()`` must be 1.
    """
    weights = np.asarray(weights, dtype=float)
    total = miss_weight + float(weights.sum())
    if weights.shape != (innov.nu.shape[0],) or not math.isclose(total, 1.0, abs_tol=1e-9):
        raise InputError(
            f"association weights must have one entry per detection ({innov.nu.shape[0]}) "
            f"and sum with the miss weight to 1, got shape {weights.shape} and sum {total}"
        )
    if miss_weight >= 1.0 or not np.any(weights > 0.0):
        return track
    if isinstance(config.motion, InteractingModels) and track.converted:
        raise InputError(
            f"the probabilistic-data-association update is defined here for one motion model, "
            f"not for the model set {config.motion!r}; track with gnn or mht, or the MAP "
            "estimator, under a model set"
        )
    measurement = _measurement(config, track, scan)
    R = measurement.noise_covariance
    x, P, S, H = track.x, track.P, innov.S, innov.H
    Kt = inverse_and_logdet(S)[0] @ (H @ P)  # K^T = S^-1 H P
    K = Kt.T
    nu_c = weights @ innov.nu
    x_new = x + K @ nu_c
    A = np.eye(P.shape[0]) - K @ H
    P_single = A @ P @ A.T + K @ R @ Kt
    spread = (innov.nu.T * weights) @ innov.nu - np.outer(nu_c, nu_c)
    P_new = miss_weight * P + (1.0 - miss_weight) * P_single + K @ spread @ K.T
    return _converted_after_update(config, track, x_new, _symmetrize(P_new))
