"""Process and measurement noise levels from smoothed tracks: the M step of an EM.

Shumway and Stoffer's EM for linear state-space models ("An approach to time series
smoothing and forecasting using the EM algorithm", J. Time Series Analysis 1982)
alternates a Rauch-Tung-Striebel smoother under the current parameters (the E step:
smoothed means ``x_k``, covariances ``P_k`` and lag-one cross-covariances ``C_k =
Cov(x_k, x_{k-1})``, :func:`mapassoc.filtering.smoothing.smooth_track_lag_one`) with the
closed-form maximisers of the expected complete-data log-likelihood (the M step, here).
Two of the configuration's numbers are estimated this way:

* the process-noise intensity ``q`` of a model whose noise is ``Q(dt) = q Q1(dt)``
  (``constant_velocity``, ``constant_acceleration``, ``random_walk``)::

      q = sum_k tr(Q1(dt_k)^+ E[w_k w_k^T]) / sum_k rank Q1(dt_k)

  with the expected squared process noise under the smoothed posterior::

      E[w_k w_k^T] = (x_k - F x_{k-1})(x_k - F x_{k-1})^T + P_k - F C_k^T - C_k F^T
                     + F P_{k-1} F^T

  ``Q1`` is taken through its pseudo-inverse and its rank: it is positive definite for
  these models at every ``dt > 0``, but a step with ``dt = 0`` (two sensors scanning at
  the same time) has ``Q1 = 0``, no process noise and no information about ``q``, and
  ``Q1`` of a higher-order model over a short step is close to singular; the
  pseudo-inverse on the numerically non-zero eigenvalues is the maximiser of the
  Gaussian on its support, and a zero step drops out (rank 0) instead of needing a
  special case.

* the measurement-noise standard deviation of a position sensor (``z = H x + v``, ``v ~
  N(0, R)``, ``R`` diagonal)::

      sigma_i^2 = sum_detections [(z - H x)_i^2 + (H P H^T)_ii] / count

  per position component ``i``, or pooled over the ``d`` components (the sum over
  ``i`` divided by ``d count``) when ``R = sigma^2 I``.  Which of the two the estimator
  uses follows the configuration: one ``noise_std`` number pools, one per component
  estimates each (:meth:`MeasurementNoiseSums.stds`).

The birth state of a track is the single-point initiation at its first detection (a
prior with position covariance ``R``), so the first detection enters the complete-data
likelihood through that prior exactly as a detection does; it is counted as one, and the
formula above is the exact maximiser.  Models whose noise is not one scaled matrix
(coordinated turn, Singer, a model set) are refused by :func:`unit_process_noise`.

Association weights.  A track's detection may enter with a weight ``w`` in (0, 1], the
probability that it is the track's own (the parameter EM takes it from the confidence
pass, :mod:`mapassoc.estimator.noise_levels`): the smoother then sees it with noise
covariance ``R / w`` (:func:`~mapassoc.filtering.smoothing.weighted_measurement`, the
synthetic measurement of Streit and Luginbuhl's probabilistic multi-hypothesis tracking)
and the ``sigma`` sums count ``w`` times its squares over ``sum w`` detections: the
expected complete-data statistics under the association probabilities, as in the EM of
Dempster, Laird and Rubin ("Maximum likelihood from incomplete data via the EM
algorithm", JRSS B 1977).  A false alarm taken into a track with a low weight then neither
bends the smoothed path (whose accelerations are the ``q`` sums) nor counts its residual
as the sensor's noise.  Without weights every detection counts 1.

Sums rather than estimates are returned so that tracks, sample blocks and passes can be
pooled before dividing (:meth:`ProcessNoiseSums.plus`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.filtering.smoothing import (
    Associations,
    DetectionWeights,
    LagOneTrack,
    smooth_track_lag_one,
)
from mapassoc.models.interacting import InteractingModels
from mapassoc.models.measurement import LinearMeasurement, MeasurementModel
from mapassoc.models.motion import ConstantAcceleration, ConstantVelocity, MotionModel, RandomWalk

__all__ = [
    "EIGEN_TOLERANCE",
    "ProcessNoiseSums",
    "MeasurementNoiseSums",
    "NoiseSums",
    "scalable_process_noise",
    "unit_process_noise",
    "position_sensor",
    "process_noise_sums",
    "measurement_noise_sums",
    "track_noise_sums",
    "noise_sums",
    "MAX_STEP",
    "Iterated",
    "accelerated_em",
]

EIGEN_TOLERANCE = 1e-10
"""Eigenvalues of ``Q1`` below this share of its largest are taken as zero."""

_SCALABLE = (ConstantVelocity, ConstantAcceleration, RandomWalk)


@dataclass(frozen=True)
class ProcessNoiseSums:
    """The sums of the ``q`` update (module docstring).

    Attributes
    ----------
    total : float
        ``sum_k tr(Q1^+ E[w_k w_k^T])``.
    degrees : float
        ``sum_k rank Q1(dt_k)``.
    """

    total: float = 0.0
    degrees: float = 0.0

    def plus(self, other: ProcessNoiseSums) -> ProcessNoiseSums:
        """The sums of both."""
        return ProcessNoiseSums(self.total + other.total, self.degrees + other.degrees)

    @property
    def intensity(self) -> float | None:
        """``total / degrees``, None without a transition."""
        return self.total / self.degrees if self.degrees > 0 else None


@dataclass(frozen=True)
class MeasurementNoiseSums:
    """The sums of one sensor's ``sigma`` update (module docstring).

    Attributes
    ----------
    squares : ndarray, shape (d,)
        Per position component, ``sum w [(z - H x)_i^2 + (H P H^T)_ii]``.
    count : float
        Detections summed (their weights ``w`` summed; 1 each without weights).
    """

    squares: FloatArray
    count: float = 0.0

    def plus(self, other: MeasurementNoiseSums) -> MeasurementNoiseSums:
        """The sums of both (same number of components)."""
        return MeasurementNoiseSums(self.squares + other.squares, self.count + other.count)

    def stds(self, *, pooled: bool) -> FloatArray | None:
        """The standard deviations, shape (d,): each component's own, or (``pooled``)
        one value for all; None without a detection."""
        if self.count == 0:
            return None
        if pooled:
            return np.full(self.squares.shape, np.sqrt(self.squares.sum() / self.squares.size
                                                       / self.count))  # fmt: skip
        return np.sqrt(self.squares / self.count)


@dataclass(frozen=True)
class NoiseSums:
    """The sums of a set of tracks.

    Attributes
    ----------
    process : ProcessNoiseSums
    measurement : dict of str to MeasurementNoiseSums
        Per sensor asked for.
    """

    process: ProcessNoiseSums
    measurement: dict[str, MeasurementNoiseSums]

    def plus(self, other: NoiseSums) -> NoiseSums:
        """The sums of both (same sensors)."""
        return NoiseSums(
            self.process.plus(other.process),
            {k: v.plus(other.measurement[k]) for k, v in self.measurement.items()},
        )


def scalable_process_noise(motion: object) -> bool:
    """Whether ``motion``'s noise is ``noise_intensity`` times a fixed ``Q1(dt)``
    (constant velocity, constant acceleration, random walk)."""
    return isinstance(motion, _SCALABLE)


def unit_process_noise(motion: MotionModel, dt: float) -> FloatArray:
    """``Q1(dt) = Q(dt) / noise_intensity``, shape (n, n); zero for ``dt == 0``.

    Raises
    ------
    InputError
        ``motion`` is not one of :func:`scalable_process_noise`'s (key
        ``motion.noise_intensity``).
    """
    if not scalable_process_noise(motion) or isinstance(motion, InteractingModels):
        raise InputError(
            f'motion.noise_intensity = "auto" needs a motion model whose process noise is '
            f"noise_intensity times a fixed matrix (constant_velocity, constant_acceleration, "
            f"random_walk); got {motion!r}",
            key="motion.noise_intensity",
        )
    n = motion.state_dim
    if dt == 0:
        return np.zeros((n, n))
    return np.asarray(motion.process_noise(dt), dtype=float) / float(motion.noise_intensity)  # type: ignore[attr-defined]


def position_sensor(measurement: MeasurementModel) -> bool:
    """Whether ``measurement`` is a position measurement (``measurement = "position"``)."""
    return isinstance(measurement, LinearMeasurement) and measurement.measures_position_directly


def _pseudo_inverses(Q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Batched pseudo-inverses and ranks of symmetric positive-semidefinite ``Q``, shape
    (m, n, n): eigenvalues below :data:`EIGEN_TOLERANCE` of the largest count as zero."""
    w, V = np.linalg.eigh(Q)
    top = np.max(w, axis=-1, keepdims=True)
    keep = (w > EIGEN_TOLERANCE * top) & (top > 0)
    inv_w = np.where(keep, 1.0 / np.where(keep, w, 1.0), 0.0)
    return np.einsum("mij,mj,mkj->mik", V, inv_w, V), keep.sum(axis=-1).astype(float)


def _check_stack(name: str, value: object, shape: tuple[int, ...]) -> FloatArray:
    array = np.asarray(value, dtype=float)
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise InputError(f"{name} must be a finite array of shape {shape}, got shape {array.shape}")
    return array


def process_noise_sums(
    *,
    means: FloatArray,
    covariances: FloatArray,
    cross_covariances: FloatArray,
    transitions: FloatArray,
    unit_noises: FloatArray,
) -> ProcessNoiseSums:
    """The sums of the ``q`` update over one smoothed track (module docstring).

    Parameters
    ----------
    means : ndarray, shape (T, n)
        Smoothed means.
    covariances : ndarray, shape (T, n, n)
        Smoothed covariances.
    cross_covariances : ndarray, shape (T, n, n)
        Entry k (k >= 1): ``Cov(x_k, x_{k-1})`` under the smoothed posterior; entry 0
        unused.
    transitions : ndarray, shape (T, n, n)
        Entry k: ``F`` from step k-1 to k; entry 0 unused.
    unit_noises : ndarray, shape (T, n, n)
        Entry k: ``Q1(dt_k)`` (zero for ``dt_k = 0``); entry 0 unused.

    Returns
    -------
    ProcessNoiseSums

    Raises
    ------
    InputError
        Arrays of other shapes, or values that are not finite.
    """
    x = np.asarray(means, dtype=float)
    if x.ndim != 2:
        raise InputError(f"means must be an array of shape (T, n), got shape {x.shape}")
    T, n = x.shape
    P = _check_stack("covariances", covariances, (T, n, n))
    C = _check_stack("cross_covariances", cross_covariances, (T, n, n))[1:]
    F = _check_stack("transitions", transitions, (T, n, n))[1:]
    Q1 = _check_stack("unit_noises", unit_noises, (T, n, n))[1:]
    if T < 2:
        return ProcessNoiseSums()
    r = x[1:] - np.einsum("kij,kj->ki", F, x[:-1])
    FC = F @ np.swapaxes(C, -1, -2)
    E = (
        r[:, :, None] * r[:, None, :] + P[1:] - FC - np.swapaxes(FC, -1, -2)
        + F @ P[:-1] @ np.swapaxes(F, -1, -2)
    )  # fmt: skip
    Q_inv, rank = _pseudo_inverses(Q1)
    return ProcessNoiseSums(float(np.einsum("kij,kji->", Q_inv, E)), float(rank.sum()))


def measurement_noise_sums(
    *, residuals: FloatArray, projected_covariances: FloatArray, weights: FloatArray | None = None
) -> MeasurementNoiseSums:
    """The sums of a sensor's ``sigma`` update (module docstring).

    Parameters
    ----------
    residuals : ndarray, shape (m, d)
        ``z - H x`` of each detection, ``x`` the smoothed mean at its scan.
    projected_covariances : ndarray, shape (m, d, d)
        ``H P H^T``, ``P`` the smoothed covariance there.
    weights : ndarray, shape (m,), optional
        Each detection's weight in (0, 1] (module docstring); default 1 each.

    Returns
    -------
    MeasurementNoiseSums

    Raises
    ------
    InputError
        Arrays of other shapes, or values that are not finite.
    """
    r = np.asarray(residuals, dtype=float)
    if r.ndim != 2:
        raise InputError(f"residuals must be an array of shape (m, d), got shape {r.shape}")
    m, d = r.shape
    S = _check_stack("projected_covariances", projected_covariances, (m, d, d))
    _check_stack("residuals", r, (m, d))
    w = np.ones(m) if weights is None else _check_stack("weights", weights, (m,))
    if np.any(w <= 0) or np.any(w > 1):
        raise InputError("weights must be in (0, 1]")
    squares = w @ (r**2) + w @ np.diagonal(S, axis1=-2, axis2=-1)
    return MeasurementNoiseSums(squares=squares, count=float(w.sum()))


def track_noise_sums(
    scans: Sequence[Scan], track: LagOneTrack, config: Config, sensors: Collection[str]
) -> NoiseSums:
    """The sums of one smoothed track: its transitions (when the motion model's noise is
    scalable; else none) and its detections by the ``sensors`` (position sensors), each
    weighted by ``track.weights`` (module docstring)."""
    motion = config.motion
    process = ProcessNoiseSums()
    if scalable_process_noise(motion):
        unit = np.array([unit_process_noise(motion, float(dt)) for dt in track.dts])
        process = process_noise_sums(
            means=track.means, covariances=track.covariances,
            cross_covariances=track.cross_covariances, transitions=track.transitions,
            unit_noises=unit,
        )  # fmt: skip
    residuals: dict[str, list[FloatArray]] = {name: [] for name in sensors}
    projected: dict[str, list[FloatArray]] = {name: [] for name in sensors}
    weights: dict[str, list[float]] = {name: [] for name in sensors}
    for step, j in track.detections.items():
        scan = scans[track.scan_indices[step]]
        if scan.sensor not in residuals:
            continue
        H = config.sensors[scan.sensor].measurement.H  # type: ignore[attr-defined]
        residuals[scan.sensor].append(scan.detections[j] - H @ track.means[step])
        projected[scan.sensor].append(H @ track.covariances[step] @ H.T)
        weights[scan.sensor].append(track.weights.get(step, 1.0))
    measurement = {}
    for name in sensors:
        d = config.sensors[name].measurement.measurement_dim
        measurement[name] = measurement_noise_sums(
            residuals=np.array(residuals[name]).reshape(-1, d),
            projected_covariances=np.array(projected[name]).reshape(-1, d, d),
            weights=np.array(weights[name], dtype=float),
        )
    return NoiseSums(process, measurement)


def noise_sums(
    scans: Sequence[Scan],
    associations: Associations,
    config: Config,
    sensors: Collection[str],
    weights: Mapping[int, DetectionWeights] | None = None,
) -> NoiseSums:
    """The sums of every track of ``associations``, each smoothed under ``config``
    (:func:`~mapassoc.filtering.smoothing.smooth_track_lag_one`).

    Parameters
    ----------
    scans : sequence of Scan
        Sorted by (time, sensor).
    associations : mapping of int to mapping of int to int
        Track id -> {scan index -> index of the track's detection in that scan}.
    config : Config
        The current parameters.
    sensors : collection of str
        The position sensors whose ``sigma`` sums to collect.
    weights : mapping of int to mapping of int to float, optional
        Track id -> {scan index -> weight in (0, 1] of its detection there} (module
        docstring); a track or scan not given counts 1.

    Returns
    -------
    NoiseSums

    Raises
    ------
    InputError
        A sensor that is not configured or not a position sensor, or a motion model
        :func:`~mapassoc.filtering.smoothing.smooth_track_lag_one` does not take.
    """
    for name in sensors:
        if name not in config.sensors or not position_sensor(config.sensors[name].measurement):
            raise InputError(
                f"sensors: {name!r} is not a configured position sensor (known: "
                f"{sorted(config.sensors)}); noise_std is estimated for position sensors only",
                key="noise_std",
            )
    out = NoiseSums(
        ProcessNoiseSums(),
        {
            name: MeasurementNoiseSums(np.zeros(config.sensors[name].measurement.measurement_dim))
            for name in sensors
        },
    )
    for track_id in sorted(associations):
        detections = associations[track_id]
        if detections:
            track = smooth_track_lag_one(
                scans, detections, config, None if weights is None else weights.get(track_id)
            )
            out = out.plus(track_noise_sums(scans, track, config, sensors))
    return out


@dataclass(frozen=True)
class Iterated:
    """What :func:`accelerated_em` ended with.

    Attributes
    ----------
    values : ndarray, shape (p,)
        The parameters.
    updates : int
        Calls of the update (each one smoothing of every track).
    converged : bool
        Whether the last update moved every parameter by at most the tolerance.
    """

    values: FloatArray
    updates: int
    converged: bool


def accelerated_em(
    update: Callable[[FloatArray], FloatArray],
    start: FloatArray,
    *,
    tolerance: float,
    max_updates: int,
) -> Iterated:
    """Iterate an EM update of positive parameters to its fixed point, accelerated.

    The plain EM of noise levels converges linearly and slowly where the measurement
    noise hides the process noise (each update closing a few per cent of the distance),
    so the iteration is Varadhan and Roland's SQUAREM ("Simple and globally convergent
    methods for accelerating the convergence of any EM algorithm", Scandinavian Journal
    of Statistics 2008, scheme SqS3): two updates ``r = M(t) - t``, ``v = M(M(t)) -
    2 M(t) + t``, a step ``t - 2 a r + a^2 v`` with ``a = -|r| / |v|`` (at most -1: the
    plain double update), then one update of that point.  It runs in log space, so
    every value stays positive, and the step length ``|a|`` is capped at
    :data:`MAX_STEP` so that a near-zero ``v`` does not throw the parameters far off.

    Parameters
    ----------
    update : callable
        The EM update (one E and M step), shape (p,) to shape (p,), positive values.
    start : ndarray, shape (p,)
        Positive starting values.
    tolerance : float
        Relative change of every parameter below which the iteration stops (> 0).
    max_updates : int
        Most calls of ``update`` (>= 1).

    Returns
    -------
    Iterated

    Raises
    ------
    InputError
        A start that is not positive and finite, a tolerance <= 0 or a count < 1.
    """
    theta = np.log(_check_positive_vector("start", start))
    if not tolerance > 0:
        raise InputError(f"tolerance must be > 0, got {tolerance!r}")
    if max_updates < 1:
        raise InputError(f"max_updates must be >= 1, got {max_updates!r}")
    step = math.log1p(tolerance)

    def log_update(t: FloatArray) -> FloatArray:
        return np.log(_check_positive_vector("update(values)", update(np.exp(t))))

    updates = 0
    while updates < max_updates:
        first = log_update(theta)
        updates += 1
        if np.max(np.abs(first - theta)) <= step or updates + 2 > max_updates:
            return Iterated(np.exp(first), updates, bool(np.max(np.abs(first - theta)) <= step))
        second = log_update(first)
        r, v = first - theta, second - 2 * first + theta
        a = -float(np.linalg.norm(r) / max(float(np.linalg.norm(v)), 1e-300))
        a = max(min(a, -1.0), -MAX_STEP)
        theta = log_update(theta - 2 * a * r + a * a * v)
        updates += 2
    return Iterated(np.exp(theta), updates, False)


MAX_STEP = 20.0
"""The largest SQUAREM step length :func:`accelerated_em` takes (in units of ``r``)."""


def _check_positive_vector(name: str, value: object) -> FloatArray:
    array = np.atleast_1d(np.asarray(value, dtype=float))
    if array.ndim != 1 or not np.all(np.isfinite(array)) or np.any(array <= 0):
        raise InputError(f"{name} must be positive finite numbers, shape (p,), got {value!r}")
    return array
