"""Fixed-interval smoothing of tracks whose detections are known.

Every tracker that ends with a set of detection sequences (the MAP window estimator, the
oracle on true associations, the baselines of :mod:`mapassoc.trackers`) gets its reported
states here, so all of them are smoothed the same way and compared on association alone.

For each track:

1. The track starts at its first detection with the single-point initiation of
   :func:`mapassoc.models.birth.birth_state` (the detection fixes the position; this is already the
   posterior given that detection, so it is not updated with it again).
2. Every later scan of *any* sensor up to the track's last detection is one step: a
   prediction over ``dt`` (skipped when ``dt == 0``, two sensors scanning at the same
   time), then a Kalman/EKF update when the track has a detection in that scan, both
   through the batched filter interface the trees and the recording objective use
   (:class:`mapassoc.filtering.batch.KalmanFilter`); a scan without one is a pure
   prediction.
3. Rauch-Tung-Striebel smoothing (:func:`mapassoc.filtering.kalman.rts_smooth`).

Coordinated turn.  A coordinated-turn track starts in the constant-velocity initiation
model (:func:`mapassoc.models.birth.initiation_model`; a position measurement's H is re-indexed
onto that state) and is converted by :func:`mapassoc.models.birth.convert_initiated` right after
its first detection update at a time later than its first detection (normally its second
detection).  Detections at the *same* time as the first one cannot reveal the velocity,
whose mean is then still exactly zero and has no heading, so they do not trigger the
conversion.  The whole track is smoothed: the turn-state part with
:func:`~mapassoc.filtering.kalman.rts_smooth`; then, because the conversion is only a change of
variables plus an independent turn-rate prior (it adds no information), the smoothed
turn state at the conversion step is mapped back to the constant-velocity state by the
inverse change of variables (which is what the RTS step through a linear change of
variables reduces to), and the backward pass continues through the constant-velocity
part.  Those early smoothed states are reported in the turn state through
:func:`~mapassoc.models.birth.convert_initiated` (linearised at the smoothed velocity), with the
smoothed turn rate (mean and variance) of the conversion step.  Reported turn states are
canonical: speed >= 0 (an EKF can settle on the equivalent ``(-speed, heading + pi)``) and
heading wrapped to (-pi, pi].  A coordinated-turn track detected at a single time has no
velocity information: its rows report speed, heading and turn rate 0 with the variances
``speed_std^2``, ``pi^2 / 3`` (a heading uniform on (-pi, pi]) and ``turn_rate_std^2`` of
the birth model.

The model-specific pieces of this (initiation model, conversion and its inverse,
the turn rate taken from the conversion step, canonical form, states of unconverted tracks)
are methods of the motion model (:class:`mapassoc.models.motion.MotionModel`); the code here
works for any model that converts, with dimensions from ``state_dim``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.data.config import Config
from mapassoc.data.io import TrackTable
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.filtering.batch import KalmanFilter
from mapassoc.filtering.imm import (
    IMMRun,
    IMMState,
    imm_filter,
    imm_predict,
    imm_smooth,
    model_log_probabilities,
    predictive_log_likelihood,
)
from mapassoc.filtering.kalman import (
    FilterStep,
    innovation,
    innovation_covariance,
    inverse_and_logdet,
    log_gaussian,
    rts_cross_covariances,
    rts_smooth,
    update,
)
from mapassoc.models.birth import (
    birth_state,
    convert_initiated,
    initiation_measurement,
    initiation_model,
    needs_conversion,
)
from mapassoc.models.interacting import InteractingModels
from mapassoc.models.measurement import LinearMeasurement, MeasurementModel
from mapassoc.models.motion import MotionModel
from mapassoc.models.population import BirthModel

__all__ = [
    "Associations",
    "DetectionWeights",
    "LagOneTrack",
    "weighted_measurement",
    "SmoothedTrack",
    "smooth_track",
    "smooth_track_lag_one",
    "track_log_likelihood",
    "interacting_log_likelihoods",
    "smooth_tracks",
    "smoothed_track",
]

#: Track id -> {scan index -> index of the track's detection in that scan}.
Associations = Mapping[int, Mapping[int, int]]

#: Scan index -> weight in (0, 1] of the track's detection there (absent: 1).
DetectionWeights = Mapping[int, float]

_KALMAN = KalmanFilter()
"""The batched filter interface, on batches of one track (the steps of the trees)."""


def _predict(
    motion: MotionModel, x: FloatArray, P: FloatArray, dt: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """One track's prediction over ``dt > 0`` and its transition matrix or Jacobian."""
    x_pred, P_pred, F = _KALMAN.predict(motion, x[None], P[None], dt)
    return x_pred[0], P_pred[0], F.reshape(P.shape)


def _update(
    measurement: MeasurementModel, x: FloatArray, P: FloatArray, z: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """One track's update by detection ``z``."""
    innovation = _KALMAN.innovation(measurement, x[None], P[None])
    nu = innovation.residuals(z[None])
    x_post, P_post = _KALMAN.update(x[None], P[None], innovation, np.zeros(1, np.int64), nu)
    return x_post[0], P_post[0]


def weighted_measurement(measurement: MeasurementModel, weight: float) -> MeasurementModel:
    """``measurement`` with its noise covariance ``R / weight``: a detection that is the
    track's own with probability ``weight``.

    This is the synthetic measurement of Streit and Luginbuhl's probabilistic
    multi-hypothesis tracking ("Probabilistic multi-hypothesis tracking", NUWC-NPT
    Technical Report 10,428, 1995): in the EM's expected complete-data log-likelihood a
    detection assigned with probability ``w`` enters as ``w (z - Hx)^T R^-1 (z - Hx)``,
    which is a Gaussian measurement of covariance ``R / w``, so a smoother run with it is
    the exact E step under those weights.  Only linear measurements are weighted (the
    noise-level EM takes position sensors only); a weight of 1 returns ``measurement``.

    Raises
    ------
    InputError
        A weight outside (0, 1], or a weight below 1 for a measurement that is not linear.
    """
    if not 0.0 < weight <= 1.0:
        raise InputError(f"a detection weight must be in (0, 1], got {weight!r}")
    if weight == 1.0:
        return measurement
    if not isinstance(measurement, LinearMeasurement):
        raise InputError(f"only a linear measurement can be weighted, got {measurement!r}")
    return LinearMeasurement(
        H=measurement.H, R=measurement.R / weight, component_names=measurement.component_names,
        position_indices=measurement.position_indices,
    )  # fmt: skip


class _Segment:
    """Filtered and predicted moments of consecutive steps in one state space.

    Parameters
    ----------
    x, P : ndarray, shapes (n,), (n, n)
        Filtered moments of the segment's first step.
    """

    def __init__(self, *, x: FloatArray, P: FloatArray) -> None:
        # Entry 0 of the predicted moments and transitions is unused by rts_smooth.
        self.x_filtered = [x]
        self.P_filtered = [P]
        self.x_predicted = [x]
        self.P_predicted = [P]
        self.transitions = [np.eye(x.shape[0])]

    def append(
        self, *, x: FloatArray, P: FloatArray, x_pred: FloatArray, P_pred: FloatArray, F: FloatArray
    ) -> None:
        """Add a step: filtered ``x, P``, predicted ``x_pred, P_pred``, transition ``F``."""
        self.x_filtered.append(x)
        self.P_filtered.append(P)
        self.x_predicted.append(x_pred)
        self.P_predicted.append(P_pred)
        self.transitions.append(F)

    def smooth(
        self, last_x: FloatArray | None = None, last_P: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """RTS-smooth the segment; ``last_x, last_P`` replace the final filtered moments
        by already smoothed ones (the segment then continues a smoothed later segment)."""
        xf = np.array(self.x_filtered)
        Pf = np.array(self.P_filtered)
        if last_x is not None and last_P is not None:
            xf[-1], Pf[-1] = last_x, last_P
        return rts_smooth(
            xf,
            Pf,
            np.array(self.x_predicted),
            np.array(self.P_predicted),
            np.array(self.transitions),
        )


def _to_model_space(
    motion: MotionModel,
    x0: FloatArray,
    P0: FloatArray,
    birth: BirthModel,
    x_conv: FloatArray,
    P_conv: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """A smoothed initiation-model state expressed in ``motion``'s space.

    The components the conversion draws from the birth prior
    (``motion.conversion_prior_indices``) are taken from the smoothed state ``x_conv,
    P_conv`` at the conversion step instead.
    """
    x, P = convert_initiated(motion, x0, P0, birth)
    x = np.array(x, copy=True)
    P = np.array(P, copy=True)
    idx = list(motion.conversion_prior_indices)
    if idx:
        x[idx] = x_conv[idx]
        P[np.ix_(idx, idx)] = P_conv[np.ix_(idx, idx)]
    return x, P


@dataclass(frozen=True, eq=False)
class SmoothedTrack:
    """One track smoothed over the scans from its first to its last detection.

    Attributes
    ----------
    scan_indices : list of int, length T
    states : ndarray, shape (T, n)
    covariances : ndarray, shape (T, n, n)
    rows : list of int, length T
        Detection id used at each scan, -1 for a miss.
    model_probabilities : ndarray, shape (T, M), or None
        For a set of models, Kim's smoothed model probabilities at each scan (each row a
        probability vector); ``None`` for a single model, which has nothing to weigh.
    """

    scan_indices: list[int]
    states: FloatArray
    covariances: FloatArray
    rows: list[int]
    model_probabilities: FloatArray | None = None


def _filter_track(
    scans: Sequence[Scan],
    detections: Mapping[int, int],
    config: Config,
    weights: DetectionWeights | None = None,
) -> tuple[list[int], _Segment, _Segment | None]:
    """The forward pass of :func:`smooth_track` (steps 1 and 2 of the module docstring),
    each detection's noise covariance divided by its weight (:func:`weighted_measurement`;
    the first detection's too, through the birth state's position covariance).

    Returns
    -------
    scan_indices : list of int
        The scans from the first to the last detection.
    early : _Segment
        The steps before the conversion (all of them for a model that does not convert).
    late : _Segment or None
        The steps from the conversion on (``early`` itself for a model that does not
        convert; None when a converting track never converted).
    """
    motion, birth = config.motion, config.birth
    converts = needs_conversion(motion)
    model = initiation_model(motion)
    first, last = min(detections), max(detections)
    scan_indices = list(range(first, last + 1))
    first_scan = scans[first]
    z0 = first_scan.detections[detections[first]]
    weight = {} if weights is None else weights
    x, P = birth_state(
        motion,
        weighted_measurement(config.sensors[first_scan.sensor].measurement, weight.get(first, 1.0)),
        z0,
        birth,
    )
    early = _Segment(x=x, P=P)
    late: _Segment | None = None if converts else early
    for k in scan_indices[1:]:
        scan = scans[k]
        dt = scan.time - scans[k - 1].time
        current_model = motion if late is not None else model
        if dt > 0.0:
            x_pred, P_pred, F = _predict(current_model, x, P, dt)
        else:
            x_pred, P_pred, F = x, P, np.eye(x.shape[0])
        if k in detections:
            measurement = weighted_measurement(
                config.sensors[scan.sensor].measurement, weight.get(k, 1.0)
            )
            if late is None:
                measurement = initiation_measurement(motion, measurement)
            x, P = _update(measurement, x_pred, P_pred, scan.detections[detections[k]])
        else:
            x, P = x_pred, P_pred
        segment = early if late is None else late
        segment.append(x=x, P=P, x_pred=x_pred, P_pred=P_pred, F=F)
        if late is None and k in detections and scan.time > first_scan.time:
            x, P = convert_initiated(motion, x, P, birth)
            late = _Segment(x=x, P=P)
    return scan_indices, early, late


def smooth_track(
    scans: Sequence[Scan],
    detections: Mapping[int, int],
    config: Config,
) -> tuple[list[int], FloatArray, FloatArray, list[int]]:
    """Smoothed moments of one track over the scans from its first to its last detection.

    The moments of :func:`smoothed_track` as a tuple (the model probabilities of a set
    left out), kept for the callers that unpack four values.

    Parameters
    ----------
    scans : sequence of Scan
    detections : mapping of int to int
        Scan index -> index of the track's detection in that scan.
    config : Config

    Returns
    -------
    scan_indices : list of int, length T
    states : ndarray, shape (T, n)
    covariances : ndarray, shape (T, n, n)
    rows : list of int, length T (-1 for a miss)
    """
    track = smoothed_track(scans, detections, config)
    return track.scan_indices, track.states, track.covariances, track.rows


def smoothed_track(
    scans: Sequence[Scan], detections: Mapping[int, int], config: Config
) -> SmoothedTrack:
    """One track smoothed (module docstring), with a set's model probabilities.

    Parameters
    ----------
    scans : sequence of Scan
    detections : mapping of int to int
        Scan index -> index of the track's detection in that scan.
    config : Config

    Returns
    -------
    SmoothedTrack
    """
    motion = config.motion
    if isinstance(motion, InteractingModels):
        return _smooth_interacting(scans, detections, config, motion)
    return SmoothedTrack(*_smooth_single(scans, detections, config))


def _smooth_single(
    scans: Sequence[Scan], detections: Mapping[int, int], config: Config
) -> tuple[list[int], FloatArray, FloatArray, list[int]]:
    """:func:`smoothed_track` for one motion model: RTS, through a conversion if any."""
    motion = config.motion
    birth = config.birth
    converts = needs_conversion(motion)
    scan_indices, early, late = _filter_track(scans, detections, config)
    rows = [int(scans[k].rows[detections[k]]) if k in detections else -1 for k in scan_indices]
    if not converts:
        states, covariances = early.smooth()
        return scan_indices, states, covariances, rows
    if late is None:
        # Never converted (detected at a single time): e.g. no velocity, hence no heading.
        xs_0, Ps_0 = early.smooth()
        pairs = [motion.unconverted_state(a, b, birth) for a, b in zip(xs_0, Ps_0, strict=True)]
        return scan_indices, np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs]), rows
    n = motion.state_dim
    xs_late, Ps_late = late.smooth()
    x_join, P_join = motion.revert_conversion(xs_late[0], Ps_late[0])
    xs_0, Ps_0 = early.smooth(x_join, P_join)
    early_states = [
        _to_model_space(motion, a, b, birth, xs_late[0], Ps_late[0])
        for a, b in zip(xs_0[:-1], Ps_0[:-1], strict=True)
    ]
    states = np.concatenate([np.array([s[0] for s in early_states]).reshape(-1, n), xs_late])
    covariances = np.concatenate(
        [np.array([s[1] for s in early_states]).reshape(-1, n, n), Ps_late]
    )
    states, covariances = motion.canonical_states(states, covariances)
    return scan_indices, states, covariances, rows


@dataclass(frozen=True)
class LagOneTrack:
    """One track's smoothed moments with the lag-one cross-covariances (the sufficient
    statistics of the EM of noise levels, :mod:`mapassoc.filtering.noise_estimation`).

    Attributes
    ----------
    scan_indices : list of int, length T
        The scans from the track's first to its last detection.
    means : ndarray, shape (T, n)
    covariances : ndarray, shape (T, n, n)
        As :func:`smooth_track`'s (identical to them).
    cross_covariances : ndarray, shape (T, n, n)
        Entry k (k >= 1): ``Cov(x_k, x_{k-1} | the track's detections)``; entry 0 zero.
    transitions : ndarray, shape (T, n, n)
        Entry k: the transition matrix from step k-1 to k (the identity where ``dt`` is
        0); entry 0 the identity.
    dts : ndarray, shape (T,)
        Entry k: the time from step k-1 to k; entry 0 is 0.
    detections : dict of int to int
        Step index (0..T-1) -> index of the track's detection in that step's scan.
    weights : dict of int to float
        Step index -> weight of the detection there, for the detections smoothed with a
        weight below 1 (:func:`weighted_measurement`); absent: 1.
    """

    scan_indices: list[int]
    means: FloatArray
    covariances: FloatArray
    cross_covariances: FloatArray
    transitions: FloatArray
    dts: FloatArray
    detections: dict[int, int]
    weights: dict[int, float] = field(default_factory=dict)


def smooth_track_lag_one(
    scans: Sequence[Scan],
    detections: Mapping[int, int],
    config: Config,
    weights: DetectionWeights | None = None,
) -> LagOneTrack:
    """:func:`smooth_track` of a model that does not convert, with the lag-one
    cross-covariances (:func:`~mapassoc.filtering.kalman.rts_cross_covariances`).

    The forward pass and the smoother are :func:`smooth_track`'s own, so ``means`` and
    ``covariances`` are exactly its results.  Only single models that do not convert
    their initiation state are taken (constant velocity or acceleration, random walk,
    Singer): a converted track's early steps live in another state space, and a model
    set's smoother gives a mixture, neither of which has one transition per step.

    Parameters
    ----------
    scans : sequence of Scan
    detections : mapping of int to int
        Scan index -> index of the track's detection in that scan.
    config : Config
    weights : mapping of int to float, optional
        Scan index -> weight in (0, 1] of the detection there (absent: 1): the
        probability that it is the track's own, its noise covariance divided by it
        (:func:`weighted_measurement`).

    Returns
    -------
    LagOneTrack

    Raises
    ------
    InputError
        A model set, or a motion model that converts its initiation state.
    """
    _check_single_model(config, "smooth_track_lag_one")
    scan_indices, segment, _ = _filter_track(scans, detections, config, weights)
    means, covariances = segment.smooth()
    Pf, Pp, F = (np.array(a) for a in (segment.P_filtered, segment.P_predicted,
                                        segment.transitions))  # fmt: skip
    times = np.array([scans[k].time for k in scan_indices])
    first = scan_indices[0]
    return LagOneTrack(
        scan_indices=scan_indices, means=means, covariances=covariances,
        cross_covariances=rts_cross_covariances(Pf, Pp, F, covariances), transitions=F,
        dts=np.r_[0.0, np.diff(times)], detections={k - first: j for k, j in detections.items()},
        weights={k - first: float(w) for k, w in (weights or {}).items()
                 if k in detections and w != 1.0},
    )  # fmt: skip


def _check_single_model(config: Config, caller: str) -> None:
    """Raise unless the motion model is one model that does not convert its initiation
    state (the lag-one statistics and the prediction-error likelihood need one space)."""
    motion = config.motion
    if isinstance(motion, InteractingModels) or needs_conversion(motion):
        raise InputError(
            f"{caller}: motion model {motion!r} is a model set or converts its "
            "initiation state; expected a single model that does not (e.g. constant_velocity)"
        )


def track_log_likelihood(
    scans: Sequence[Scan],
    detections: Mapping[int, int],
    config: Config,
    weights: DetectionWeights | None = None,
) -> float:
    """The log-likelihood of a track's detections after its first, given the first:
    the prediction-error decomposition of the forward pass of :func:`smooth_track`,
    ``sum_k log N(z_k; H x_k|k-1, H P_k|k-1 H^T + R / w_k)``.

    The observed-data likelihood of the noise levels given the associations (the first
    detection's term, the birth prior, does not depend on them), which the noise-level
    EM maximises over the process noise directly (ECME,
    :mod:`mapassoc.estimator.noise_levels`).  For a set of models
    (:class:`InteractingModels`) it is the IMM's predictive likelihood of the same
    detections, ``sum_k log sum_j c_j N(z_k; H x_jk|k-1, S_jk)`` (the run of
    :func:`smoothed_track`; the IMM's Gaussian merging is its one approximation,
    :mod:`mapassoc.filtering.imm`), which the noise levels of a set are fitted to.

    Raises
    ------
    InputError
        A single motion model that converts its initiation state.
    """
    if isinstance(config.motion, InteractingModels):
        return _interacting_run(scans, detections, config, config.motion, weights).log_likelihood
    _check_single_model(config, "track_log_likelihood")
    scan_indices, segment, _ = _filter_track(scans, detections, config, weights)
    weight = {} if weights is None else weights
    total = 0.0
    for step, k in enumerate(scan_indices[1:], start=1):
        if k not in detections:
            continue
        scan = scans[k]
        measurement = weighted_measurement(
            config.sensors[scan.sensor].measurement, weight.get(k, 1.0)
        )
        x, P = segment.x_predicted[step], segment.P_predicted[step]
        nu, S, _ = innovation(measurement, x, P, scan.detections[detections[k]])
        S_inv, logdet = inverse_and_logdet(S[None])
        total -= 0.5 * (float(nu @ S_inv[0] @ nu) + float(logdet[0]) + nu.size * _LOG_2PI)
    return total


_LOG_2PI = float(np.log(2.0 * np.pi))


def _interacting_run(
    scans: Sequence[Scan],
    detections: Mapping[int, int],
    config: Config,
    motion: InteractingModels,
    weights: DetectionWeights | None = None,
) -> IMMRun:
    """The IMM filter over a track's scans, from the first detection to the last: every
    model starts at the single-point initiation of the first detection with the prior
    model probabilities, each detection's noise covariance divided by its weight
    (:func:`weighted_measurement`, as :func:`_filter_track` does)."""
    weight = {} if weights is None else weights
    first, last = min(detections), max(detections)
    first_scan = scans[first]
    z0 = first_scan.detections[detections[first]]
    x0, P0 = birth_state(
        motion,
        weighted_measurement(config.sensors[first_scan.sensor].measurement, weight.get(first, 1.0)),
        z0,
        config.birth,
    )
    steps = [FilterStep(first_scan.time)]
    for k in range(first + 1, last + 1):
        scan = scans[k]
        if k in detections:
            measurement = weighted_measurement(
                config.sensors[scan.sensor].measurement, weight.get(k, 1.0)
            )
            steps.append(FilterStep(scan.time, measurement, scan.detections[detections[k]]))
        else:
            steps.append(FilterStep(scan.time))
    with np.errstate(divide="ignore"):
        log_mu0 = np.log(motion.initial_probabilities)
    return imm_filter(motion.models, motion.switching, x0, P0, steps, log_mu0=log_mu0)


def interacting_log_likelihoods(
    scans: Sequence[Scan],
    tracks: Sequence[Mapping[int, int]],
    config: Config,
    weights: Sequence[DetectionWeights | None] | None = None,
) -> FloatArray:
    """:func:`track_log_likelihood` of many tracks under a set of models, in lockstep.

    Every track steps through every scan from its first detection to its last, so at a
    scan all tracks alive there share the interval since the scan before: one batched IMM
    step (:mod:`mapassoc.filtering.imm`, leading axis the tracks) serves them all, where
    a filter per track would make one step per track and scan.  The steps are those of
    :func:`_interacting_run`, so the sums are its to rounding (a test compares them).

    Parameters
    ----------
    scans : sequence of Scan
    tracks : sequence of mapping of int to int
        Each track's scan index -> detection index (at least one detection).
    config : Config
        Its motion an :class:`InteractingModels`.
    weights : sequence of DetectionWeights or None, optional
        Per track, the weights of its detections (default: every detection 1).

    Returns
    -------
    ndarray, shape (len(tracks),)
    """
    motion = config.motion
    if not isinstance(motion, InteractingModels):
        raise InputError(f"interacting_log_likelihoods: motion must be a set of models "
                         f"(InteractingModels), got {motion!r}")  # fmt: skip
    per_track = [{} if w is None else w for w in (weights or [None] * len(tracks))]
    firsts = [min(t) for t in tracks]
    lasts = [max(t) for t in tracks]
    M, n = motion.n_models, motion.state_dim
    log_mu = np.zeros((len(tracks), M))
    x = np.zeros((len(tracks), M, n))
    P = np.zeros((len(tracks), M, n, n))
    total = np.zeros(len(tracks))
    with np.errstate(divide="ignore"):
        log_mu0 = np.log(motion.initial_probabilities)
    for k in range(min(firsts, default=0), max(lasts, default=-1) + 1):
        alive = np.array([i for i in range(len(tracks)) if firsts[i] < k <= lasts[i]], int)
        dt = scans[k].time - scans[k - 1].time if k else 0.0
        if alive.size and dt > 0:
            step = imm_predict(IMMState(log_mu[alive], x[alive], P[alive]), motion.models,
                               motion.switching.at(dt), dt)  # fmt: skip
            log_mu[alive], x[alive], P[alive] = step.log_predicted, step.means, step.covariances
        seen = np.array([i for i in alive if k in tracks[i]], int)
        if seen.size:
            total[seen] += _weighted_update(scans[k], k, config, tracks, per_track, seen,
                                            log_mu, x, P)  # fmt: skip
        for i in (i for i in range(len(tracks)) if firsts[i] == k):
            x0, P0 = birth_state(motion, weighted_measurement(
                config.sensors[scans[k].sensor].measurement, per_track[i].get(k, 1.0)),
                scans[k].detections[tracks[i][k]], config.birth)  # fmt: skip
            log_mu[i], x[i], P[i] = log_mu0, x0, P0
    return total


def _weighted_update(
    scan: Scan,
    k: int,
    config: Config,
    tracks: Sequence[Mapping[int, int]],
    weights: Sequence[DetectionWeights],
    seen: IntArray,
    log_mu: FloatArray,
    x: FloatArray,
    P: FloatArray,
) -> FloatArray:
    """The IMM update of the tracks ``seen`` at ``scan`` (index ``k``) in place
    (:func:`~mapassoc.filtering.imm.imm_update`'s algebra with each track's noise
    covariance ``R / w``, :func:`weighted_measurement`), and their predictive
    log-likelihoods of the detections."""
    measurement = config.sensors[scan.sensor].measurement
    z = scan.detections[[tracks[i][k] for i in seen]]
    w = np.array([weights[i].get(k, 1.0) for i in seen])
    if np.any(w != 1.0):
        weighted_measurement(measurement, float(np.min(w)))  # refuses what cannot be weighted
    R = measurement.noise_covariance[None, None] / w[:, None, None, None]
    H = measurement.jacobian(x[seen])
    nu = measurement.residual(z[:, None, :], measurement.predict(x[seen]))
    S = innovation_covariance(H, P[seen], R)
    loglik = log_gaussian(nu, S)
    x[seen], P[seen] = update(x[seen], P[seen], nu, S, H, R)
    found = predictive_log_likelihood(log_mu[seen], loglik)
    log_mu[seen] = model_log_probabilities(log_mu[seen], loglik)
    return found


def _smooth_interacting(
    scans: Sequence[Scan], detections: Mapping[int, int], config: Config, motion: InteractingModels
) -> SmoothedTrack:
    """:func:`smoothed_track` for a model set: Kim's IMM smoother, the models' combination
    and their smoothed probabilities.

    The run (:func:`_interacting_run`) starts every model at the first detection with the
    prior model probabilities (the trees start a track with the first model alone and
    enter the set at its second detection; the two differ only in the first interval's
    process noise).  The probabilities are the smoother's log probabilities
    exponentiated and each row divided by its sum: the smoother normalises in log space,
    and the division removes the rounding of ``exp`` so that a row sums to 1 as closely
    as floats allow.
    """
    first, last = min(detections), max(detections)
    scan_indices = list(range(first, last + 1))
    run = _interacting_run(scans, detections, config, motion)
    smoothed = imm_smooth(motion.models, motion.switching, run)
    rows = [int(scans[k].rows[detections[k]]) if k in detections else -1 for k in scan_indices]
    probabilities = np.exp(smoothed.log_probabilities)
    probabilities /= probabilities.sum(axis=1, keepdims=True)
    return SmoothedTrack(scan_indices, smoothed.x, smoothed.P, rows, probabilities)


def smooth_tracks(scans: Sequence[Scan], associations: Associations, config: Config) -> TrackTable:
    """Smoothed tracks of the given detection sequences.

    Parameters
    ----------
    scans : sequence of Scan
        Sorted by (time, sensor) (:func:`mapassoc.data.scans.check_scan_order`).
    associations : mapping of int to mapping of int to int
        Track id -> {scan index -> index of the track's detection in ``scans[scan index]``};
        a track needs at least one detection and has at most one per scan.
    config : Config
        Motion model, sensors and birth model (single-point initiation priors).

    Returns
    -------
    TrackTable
        One row per track per scan from its first to its last detection (scans of every
        sensor count): ``states`` the smoothed mean in the motion model's state space,
        ``variances`` the smoothed covariance diagonal, ``detection_rows`` the row used or
        ``-1``, and for a set of models (:class:`InteractingModels`)
        ``model_probabilities`` each record's smoothed model probabilities with
        ``model_names`` from the set; ``None`` for a single model, so that its tracks
        file keeps its columns.  Sorted by (time, track_id), then scan order.

    Raises
    ------
    InputError
        A track without detections, or a scan or detection index out of range.
    """
    ids: list[int] = []
    times: list[float] = []
    sensors: list[str] = []
    order_keys: list[int] = []
    states: list[FloatArray] = []
    variances: list[FloatArray] = []
    rows: list[int] = []
    probabilities: list[FloatArray] = []
    for track_id in sorted(associations):
        detections = associations[track_id]
        if not detections:
            raise InputError(f"track {track_id} has no detections to smooth")
        for k, j in detections.items():
            if not 0 <= k < len(scans) or not 0 <= j < scans[k].size:
                raise InputError(
                    f"track {track_id} names detection {j} of scan {k}, which does not exist "
                    f"({len(scans)} scans)"
                )
        track = smoothed_track(scans, detections, config)
        if track.model_probabilities is not None:
            probabilities.extend(track.model_probabilities)
        for k, mean, covariance, row in zip(
            track.scan_indices, track.states, track.covariances, track.rows, strict=True
        ):
            ids.append(int(track_id))
            times.append(scans[k].time)
            sensors.append(scans[k].sensor)
            order_keys.append(k)
            states.append(mean)
            variances.append(np.diagonal(covariance).copy())
            rows.append(row)
    return TrackTable.from_steps(
        track_ids=ids,
        times=times,
        sensors=sensors,
        scan_indices=order_keys,
        states=states,
        variances=variances,
        detection_rows=rows,
        state_names=tuple(config.motion.state_names),
        model_probabilities=_model_probabilities(config.motion, probabilities),
        model_names=_model_names(config.motion),
    )


def _model_names(motion: MotionModel) -> tuple[str, ...]:
    """A set's model names; none for a single model."""
    return motion.model_names if isinstance(motion, InteractingModels) else ()


def _model_probabilities(motion: MotionModel, rows: list[FloatArray]) -> FloatArray | None:
    """The records' model probabilities, shape ``(N, M)``: a set's even without records
    (so that the columns of a set's file do not depend on whether it has tracks), none
    for a single model."""
    if not isinstance(motion, InteractingModels):
        return None
    return np.array(rows, dtype=float).reshape(-1, motion.n_models)
