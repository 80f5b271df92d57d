"""Kalman and extended Kalman filtering, gating and Rauch-Tung-Striebel smoothing.

Pure functions on numpy arrays.  States are ``(..., n)``, covariances ``(..., n, n)``;
any leading axes are a batch.  Equations follow Afzal's survey, section 4.3:

* prediction ``x = f(x)``, ``P = F P F^T + Q`` (linear: ``f(x) = F x``; EKF: F is the
  Jacobian of f at the prior mean);
* innovation ``nu = z - h(x)``, ``S = H P H^T + R``;
* gain ``K = P H^T S^-1``; update ``x + K nu`` and the Joseph form
  ``(I - K H) P (I - K H)^T + K R K^T``, which stays symmetric positive-definite where
  the textbook ``P - K H P`` can lose definiteness to round-off;
* predicted likelihood (Afzal's survey, eq. 3) ``log N(nu; 0, S)``.

``S^-1`` and ``log det S`` come from one function (:func:`inverse_and_logdet`: closed
forms for ``dz <= 2``, a Cholesky factor otherwise) and ``nu^T S^-1 nu`` with the
log-likelihood from another (:func:`gaussian_terms`), which every gate, score and update
of the package calls, batched through :mod:`mapassoc.filtering.batch`.

A covariance that is not positive-definite raises
:class:`~mapassoc.errors.NotPositiveDefiniteError` naming the batch index; nothing is
clamped or pseudo-inverted.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import gammaincinv

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.errors import InputError, NotPositiveDefiniteError
from mapassoc.models.measurement import MeasurementModel
from mapassoc.models.motion import MotionModel

__all__ = [
    "cholesky",
    "predict",
    "predict_motion",
    "predicted_covariance",
    "innovation",
    "innovation_covariance",
    "update",
    "inverse_and_logdet",
    "gaussian_terms",
    "joseph_update",
    "log_gaussian",
    "pairwise_gate_and_loglik",
    "gated_pairs_and_loglik",
    "strip_gate",
    "gate_threshold",
    "rts_smooth",
    "rts_cross_covariances",
    "FilterStep",
    "FilterResult",
    "filter_sequence",
]

_LOG_2PI = math.log(2.0 * math.pi)


def cholesky(S: FloatArray, name: str = "covariance") -> FloatArray:
    """Lower Cholesky factor of each matrix in a batch.

    Parameters
    ----------
    S : ndarray, shape (..., d, d)
        Symmetric positive-definite matrices.
    name : str
        Name used in the error message.

    Returns
    -------
    ndarray, shape (..., d, d)

    Raises
    ------
    NotPositiveDefiniteError
        Naming the first batch index whose matrix is not positive-definite.
    """
    S = np.asarray(S, dtype=float)
    try:
        return np.asarray(np.linalg.cholesky(S), dtype=np.float64)
    except np.linalg.LinAlgError:
        pass
    flat = S.reshape((-1,) + S.shape[-2:])
    for i, M in enumerate(flat):
        try:
            np.linalg.cholesky(M)
        except np.linalg.LinAlgError:
            index = [int(j) for j in np.unravel_index(i, S.shape[:-2])] if S.ndim > 2 else []
            raise NotPositiveDefiniteError(
                f"{name}{index if index else ''} is not positive-definite: {M.tolist()!r}"
            ) from None
    raise NotPositiveDefiniteError(f"{name} is not positive-definite")  # pragma: no cover


def _symmetrize(P: FloatArray) -> FloatArray:
    return 0.5 * (P + np.swapaxes(P, -1, -2))


def predict(
    x: FloatArray, P: FloatArray, F: FloatArray, Q: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Linear prediction ``x = F x``, ``P = F P F^T + Q``.

    Parameters
    ----------
    x : ndarray, shape (..., n)
    P : ndarray, shape (..., n, n)
    F : ndarray, shape (n, n) or (..., n, n)
    Q : ndarray, shape (n, n) or (..., n, n)
    """
    x_new = np.einsum("...ij,...j->...i", F, x)
    return x_new, predicted_covariance(F, P, Q)


def predicted_covariance(F: FloatArray, P: FloatArray, Q: FloatArray) -> FloatArray:
    """The predicted covariance ``F P F^T + Q``, symmetrised: the one place it is formed.

    Parameters
    ----------
    F : ndarray, shape (n, n) or (..., n, n)
        Transition matrix or Jacobian.
    P : ndarray, shape (..., n, n)
    Q : ndarray, shape (n, n) or (..., n, n)

    Returns
    -------
    ndarray, shape (..., n, n)
    """
    return _symmetrize(F @ P @ np.swapaxes(F, -1, -2) + Q)


def predict_motion(
    motion: MotionModel, x: FloatArray, P: FloatArray, dt: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Predict through a motion model (Kalman for linear, EKF for nonlinear ones).

    Returns
    -------
    x_pred : ndarray, shape (..., n)
    P_pred : ndarray, shape (..., n, n)
    F : ndarray, shape (..., n, n)
        The transition matrix or Jacobian used (needed by the smoother).
    """
    x = np.asarray(x, dtype=float)
    F = motion.jacobian(x, dt)
    x_new = motion.transition(x, dt)
    return x_new, predicted_covariance(F, P, motion.process_noise(dt)), F


def innovation(
    measurement: MeasurementModel, x: FloatArray, P: FloatArray, z: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Innovation ``nu = z - h(x)``, its covariance ``S = H P H^T + R`` and H.

    Parameters
    ----------
    measurement : MeasurementModel
    x : ndarray, shape (..., n)
        Predicted state means.
    P : ndarray, shape (..., n, n)
        Predicted covariances.
    z : ndarray, shape (..., dz)
        Measurements (broadcast against the batch of x).

    Returns
    -------
    nu : ndarray, shape (..., dz)
    S : ndarray, shape (..., dz, dz)
    H : ndarray, shape (..., dz, n)
    """
    H = measurement.jacobian(x)
    nu = measurement.residual(z, measurement.predict(x))
    return nu, innovation_covariance(H, P, measurement.noise_covariance), H


def innovation_covariance(H: FloatArray, P: FloatArray, R: FloatArray) -> FloatArray:
    """The innovation covariance ``S = H P H^T + R``, symmetrised.

    The one place the package forms S (the hypothesis trees, the recording objective and
    the filters call it), so that every score of a detection sees the same matrix to the
    last bit.

    Parameters
    ----------
    H : ndarray, shape (dz, n) or (..., dz, n)
        Measurement matrix or Jacobian.
    P : ndarray, shape (..., n, n)
        Predicted covariances.
    R : ndarray, shape (dz, dz)
        Measurement noise covariance.

    Returns
    -------
    ndarray, shape (..., dz, dz)
    """
    return _symmetrize(H @ P @ np.swapaxes(H, -1, -2) + R)


def inverse_and_logdet(S: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``S^-1`` and ``log det S`` of a batch of symmetric positive-definite matrices.

    Closed forms for ``d = 1`` and ``2`` (``S^-1 = adj(S) / det S``: numpy's batched
    solves cost far more than this arithmetic), a Cholesky factor ``L`` otherwise
    (``S^-1 = L^-T L^-1``, ``log det S = 2 sum log L_ii``).  The one inverse of an
    innovation covariance in the package.

    Parameters
    ----------
    S : ndarray, shape (..., d, d)

    Returns
    -------
    S_inv : ndarray, shape (..., d, d)
    logdet : ndarray, shape (...)

    Raises
    ------
    NotPositiveDefiniteError
        Where an ``S`` is not positive-definite (naming its batch index).
    """
    S = np.asarray(S, dtype=np.float64)
    d = S.shape[-1]
    if d == 1:
        a = S[..., 0, 0]
        if np.all(a > 0):
            return 1.0 / S, np.log(a)
    elif d == 2:
        a, b, c = S[..., 0, 0], S[..., 0, 1], S[..., 1, 1]
        det = a * c - b * b
        if np.all(a > 0) and np.all(det > 0):
            inverse = np.empty_like(S)
            inverse[..., 0, 0] = c / det
            inverse[..., 1, 1] = a / det
            inverse[..., 0, 1] = inverse[..., 1, 0] = -b / det
            return inverse, np.log(det)
    L = cholesky(S, "innovation covariance S")  # raises, naming the index, if not PD
    Linv = np.linalg.inv(L)
    logdet = 2.0 * np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)
    return np.swapaxes(Linv, -1, -2) @ Linv, logdet


def gaussian_terms(
    nu: FloatArray, S_inv: FloatArray, logdet: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """``d2 = nu^T S^-1 nu`` and ``log N(nu; 0, S)`` (Afzal's survey, eq. 3), pair by pair.

    ``d2`` is summed entry by entry of ``S^-1`` (each diagonal entry, then twice each
    entry right of it, row by row), so a pair's numbers have the same bits whether it is
    scored alone, among all the pairs of a scan or in a gate's strip: the trees, the
    recording objective and the gates agree exactly.

    Parameters
    ----------
    nu : ndarray, shape (..., d)
    S_inv : ndarray, shape (..., d, d)
        Broadcast against ``nu``'s leading axes.
    logdet : ndarray, shape (...)
        ``log det S``, broadcast likewise.

    Returns
    -------
    d2, loglik : ndarray, shape (...)
    """
    d = nu.shape[-1]
    d2 = np.zeros(np.broadcast_shapes(nu.shape[:-1], S_inv.shape[:-2]))
    for i in range(d):
        d2 += S_inv[..., i, i] * nu[..., i] ** 2
        for j in range(i + 1, d):
            d2 += 2.0 * S_inv[..., i, j] * nu[..., i] * nu[..., j]
    return d2, -0.5 * (d * _LOG_2PI + logdet + d2)


def joseph_update(
    x: FloatArray, P: FloatArray, nu: FloatArray, S_inv: FloatArray, H: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Kalman update: gain ``K = P H^T S^-1`` through ``S^-1``, Joseph-form covariance.

    Parameters
    ----------
    x : ndarray, shape (..., n)
    P : ndarray, shape (..., n, n)
    nu : ndarray, shape (..., dz)
    S_inv : ndarray, shape (..., dz, dz)
    H : ndarray, shape (..., dz, n) or (dz, n)
    R : ndarray, shape (dz, dz) or (..., dz, dz)

    Returns
    -------
    x_post : ndarray, shape (..., n)
    P_post : ndarray, shape (..., n, n)
    """
    Kt = S_inv @ (H @ P)  # K^T = S^-1 H P
    K = np.swapaxes(Kt, -1, -2)
    x_post = x + np.einsum("...ij,...j->...i", K, nu)
    A = np.eye(P.shape[-1]) - K @ H
    P_post = A @ P @ np.swapaxes(A, -1, -2) + K @ R @ Kt
    return x_post, _symmetrize(P_post)


def update(
    x: FloatArray, P: FloatArray, nu: FloatArray, S: FloatArray, H: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Kalman update with the Joseph-form covariance (:func:`joseph_update` with the
    :func:`inverse_and_logdet` of S).

    Parameters
    ----------
    x : ndarray, shape (..., n)
    P : ndarray, shape (..., n, n)
    nu : ndarray, shape (..., dz)
    S : ndarray, shape (..., dz, dz)
    H : ndarray, shape (..., dz, n)
    R : ndarray, shape (dz, dz)

    Returns
    -------
    x_post : ndarray, shape (..., n)
    P_post : ndarray, shape (..., n, n)
    """
    return joseph_update(x, P, nu, inverse_and_logdet(S)[0], H, R)


def log_gaussian(nu: FloatArray, S: FloatArray) -> FloatArray:
    """``log N(nu; 0, S)`` (Afzal's survey, eq. 3; :func:`gaussian_terms`).

    Parameters
    ----------
    nu : ndarray, shape (..., d)
    S : ndarray, shape (..., d, d)

    Returns
    -------
    ndarray, shape (...)
    """
    nu = np.asarray(nu, dtype=float)
    S_inv, logdet = inverse_and_logdet(S)
    return gaussian_terms(nu, S_inv, logdet)[1]


def pairwise_gate_and_loglik(nu: FloatArray, S: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Squared Mahalanobis distances and log-likelihoods for every (track, detection) pair.

    One inverse per track (:func:`inverse_and_logdet`), then :func:`gaussian_terms` over
    all pairs.

    Parameters
    ----------
    nu : ndarray, shape (T, M, d)
        Innovation of detection m against track t (residuals already wrapped).
    S : ndarray, shape (T, d, d)
        Innovation covariance of each track.

    Returns
    -------
    d2 : ndarray, shape (T, M)
        ``nu^T S^-1 nu``.
    loglik : ndarray, shape (T, M)
        ``log N(nu; 0, S)``.
    """
    nu = np.asarray(nu, dtype=float)
    S = np.asarray(S, dtype=float)
    if nu.ndim != 3 or S.ndim != 3 or nu.shape[0] != S.shape[0] or nu.shape[2] != S.shape[1]:
        raise InputError(
            f"nu must be (T, M, d) and S (T, d, d) with matching T and d, got {nu.shape} "
            f"and {S.shape}"
        )
    S_inv, logdet = inverse_and_logdet(S)
    return gaussian_terms(nu, S_inv[:, None], logdet[:, None])


def gated_pairs_and_loglik(
    z_hat: FloatArray, S: FloatArray, Z: FloatArray, threshold: float
) -> tuple[IntArray, IntArray, FloatArray, FloatArray, FloatArray]:
    """Gated (track, detection) pairs of a linear measurement, found on sorted detections.

    A pair can pass the gate ``nu^T S^-1 nu <= threshold`` only if
    ``|nu| <= r = sqrt(threshold * lambda_max(S))``, so every coordinate of ``nu`` is
    within ``r`` too.  The detections are sorted along the coordinate where they spread
    most; each track's candidates are the run of detections within ``r`` of its
    prediction there (two binary searches), the other coordinates filter them, and only
    the rest are scored (:func:`gaussian_terms`).  Cost grows with the number of
    candidates in the strips, not with tracks x detections; a k-d tree radius query per
    prediction finds the same pairs, but its lists of hits cost more than the search.
    For residuals that are plain differences ``z - z_hat`` only (no angle wrapping).

    Parameters
    ----------
    z_hat : ndarray, shape (T, d)
        Predicted measurements.
    S : ndarray, shape (T, d, d)
    Z : ndarray, shape (M, d)
    threshold : float
        Finite chi-square gate.

    Returns
    -------
    track, detection : ndarray of int, shape (P,)
        The gated pairs, sorted by track then detection.
    nu : ndarray, shape (P, d)
    d2, loglik : ndarray, shape (P,)
    """
    if not math.isfinite(threshold):
        raise InputError("gated_pairs_and_loglik needs a finite gate threshold")
    S_inv, logdet = inverse_and_logdet(S)
    return strip_gate(z_hat, S, S_inv, logdet, Z, threshold)


def strip_gate(
    z_hat: FloatArray,
    S: FloatArray,
    S_inv: FloatArray,
    logdet: FloatArray,
    Z: FloatArray,
    threshold: float,
) -> tuple[IntArray, IntArray, FloatArray, FloatArray, FloatArray]:
    """:func:`gated_pairs_and_loglik` given each ``S``'s inverse and log-determinant
    (:func:`inverse_and_logdet`); the same returns."""
    if S.shape[-1] == 2:
        # The largest eigenvalue of each 2 x 2 S in closed form.
        a, b, c = S[:, 0, 0], S[:, 0, 1], S[:, 1, 1]
        largest = 0.5 * (a + c) + np.sqrt((0.5 * (a - c)) ** 2 + b * b)
    else:
        largest = np.asarray(np.linalg.eigvalsh(S)[:, -1], dtype=np.float64)
    radius = np.sqrt(threshold * largest)
    track, detection = _strip_candidates(z_hat, radius, Z)
    nu = Z[detection] - z_hat[track]
    d2, loglik = gaussian_terms(nu, S_inv[track], logdet[track])
    keep = d2 <= threshold
    return track[keep], detection[keep], nu[keep], d2[keep], loglik[keep]


_STRIP_BLOCK = 1 << 20
"""Most candidate pairs :func:`_strip_candidates` holds at once (tracks are taken in
blocks, so that detections bunched along one line cost time, not memory)."""


def _strip_candidates(
    z_hat: FloatArray, radius: FloatArray, Z: FloatArray
) -> tuple[IntArray, IntArray]:
    """Every (track, detection) pair with ``|Z[detection] - z_hat[track]|`` at most
    ``radius[track]`` in every coordinate, sorted by track then detection.

    Parameters
    ----------
    z_hat : ndarray, shape (T, d)
    radius : ndarray, shape (T,)
    Z : ndarray, shape (M, d)

    Returns
    -------
    track, detection : ndarray of int, shape (P,)
    """
    T, M = z_hat.shape[0], Z.shape[0]
    if T == 0 or M == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    axis = int(np.argmax(np.ptp(Z, axis=0)))
    order = np.argsort(Z[:, axis], kind="stable")
    along = Z[order, axis]
    low = np.searchsorted(along, z_hat[:, axis] - radius, side="left")
    high = np.searchsorted(along, z_hat[:, axis] + radius, side="right")
    counts = np.maximum(high - low, 0)
    ends = np.cumsum(counts)
    tracks_out: list[IntArray] = []
    detections_out: list[IntArray] = []
    first = 0
    while first < T:
        # Tracks first..last-1: at least one, and no more than a block of candidates.
        done = int(ends[first - 1]) if first else 0
        last = max(first + 1, int(np.searchsorted(ends, done + _STRIP_BLOCK, side="right")))
        track = np.repeat(np.arange(first, last, dtype=np.int64), counts[first:last])
        # Position of each candidate in the sorted detections: its track's run start
        # plus its place in the run.
        detection = order[low[track] + np.arange(track.size) - (ends[track] - counts[track] - done)]
        for other in range(Z.shape[1]):
            if other != axis:
                near = np.abs(Z[detection, other] - z_hat[track, other]) <= radius[track]
                track, detection = track[near], detection[near]
        ranked = np.lexsort((detection, track))
        tracks_out.append(track[ranked])
        detections_out.append(detection[ranked])
        first = last
    return np.concatenate(tracks_out), np.concatenate(detections_out)


def gate_threshold(probability: float, dim: int) -> float:
    """Chi-square gate: the ``d2`` below which a true detection falls with ``probability``.

    Parameters
    ----------
    probability : float
        Gate probability P_G in (0, 1]; 1 gives an infinite threshold (no gate).
    dim : int
        Measurement dimension dz.
    """
    if not (0.0 < probability <= 1.0):
        raise InputError(f"gate probability must be in (0, 1], got {probability!r}")
    if dim < 1:
        raise InputError(f"gate dimension must be >= 1, got {dim!r}")
    if probability == 1.0:
        return math.inf
    # The chi-square quantile with dim degrees of freedom, as scipy.stats.chi2.ppf
    # computes it (2 P^-1(dim / 2, probability), P the regularised lower incomplete
    # gamma function), without importing scipy.stats (a slow import).
    return float(2.0 * gammaincinv(dim / 2.0, probability))


def rts_smooth(
    x_filt: FloatArray,
    P_filt: FloatArray,
    x_pred: FloatArray,
    P_pred: FloatArray,
    F: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Rauch-Tung-Striebel smoother.

    Parameters
    ----------
    x_filt, P_filt : ndarray, shapes (T, n), (T, n, n)
        Filtered means and covariances at steps 0..T-1.
    x_pred, P_pred : ndarray, shapes (T, n), (T, n, n)
        Predicted means and covariances at each step (entry 0 is unused).
    F : ndarray, shape (T, n, n)
        ``F[k]`` is the transition (or EKF Jacobian) from step k-1 to k (entry 0 unused).

    Returns
    -------
    x_smooth : ndarray, shape (T, n)
    P_smooth : ndarray, shape (T, n, n)
    """
    T = x_filt.shape[0]
    xs = np.array(x_filt, dtype=float, copy=True)
    Ps = np.array(P_filt, dtype=float, copy=True)
    for k in range(T - 2, -1, -1):
        Lp = cholesky(P_pred[k + 1], f"predicted covariance at step {k + 1}")
        # G = P_f F^T P_pred^-1, via the Cholesky factor of P_pred.
        B = F[k + 1] @ P_filt[k]
        Gt = np.linalg.solve(Lp.T, np.linalg.solve(Lp, B))
        G = Gt.T
        xs[k] = x_filt[k] + G @ (xs[k + 1] - x_pred[k + 1])
        Ps[k] = _symmetrize(P_filt[k] + G @ (Ps[k + 1] - P_pred[k + 1]) @ Gt)
    return xs, Ps


def rts_cross_covariances(
    P_filt: FloatArray, P_pred: FloatArray, F: FloatArray, P_smooth: FloatArray
) -> FloatArray:
    """Lag-one smoothed cross-covariances ``Cov(x_k, x_{k-1} | all data)`` of an RTS run.

    ``C_k = P_{k|N} G_{k-1}^T`` with the smoother gain ``G_{k-1} = P_{k-1|k-1} F_k^T
    P_{k|k-1}^{-1}`` (the lag-one covariance that Shumway and Stoffer's EM needs, "An
    approach to time series smoothing and forecasting using the EM algorithm", J. Time
    Series Analysis 1982).  It is computed from :func:`rts_smooth`'s inputs and output,
    with the gain formed exactly as there, so the smoother itself is left as it is:
    callers that do not need the cross-covariances pay nothing for them.

    Parameters
    ----------
    P_filt, P_pred, F : ndarray, shape (T, n, n)
        As :func:`rts_smooth`'s (entry 0 of ``P_pred`` and ``F`` unused).
    P_smooth : ndarray, shape (T, n, n)
        :func:`rts_smooth`'s smoothed covariances.

    Returns
    -------
    ndarray, shape (T, n, n)
        Entry k (k >= 1) is ``Cov(x_k, x_{k-1} | all data)``; entry 0 is zero.
    """
    T = P_filt.shape[0]
    C = np.zeros_like(np.asarray(P_filt, dtype=float))
    for k in range(1, T):
        Lp = cholesky(P_pred[k], f"predicted covariance at step {k}")
        Gt = np.linalg.solve(Lp.T, np.linalg.solve(Lp, F[k] @ P_filt[k - 1]))
        C[k] = P_smooth[k] @ Gt
    return C


@dataclass(frozen=True)
class FilterStep:
    """One step of a single-object filtering run.

    Parameters
    ----------
    time : float
        Scan time.
    measurement : MeasurementModel or None
        Model of the detection used at this step; ``None`` for a missed detection.
    z : ndarray, shape (dz,), or None
        The detection; ``None`` for a miss.
    """

    time: float
    measurement: MeasurementModel | None = None
    z: FloatArray | None = None


@dataclass(frozen=True)
class FilterResult:
    """Filtered, predicted and (optionally) smoothed moments of a filtering run.

    Attributes have a leading axis of length T (one entry per step).
    """

    times: FloatArray
    x_filtered: FloatArray
    P_filtered: FloatArray
    x_predicted: FloatArray
    P_predicted: FloatArray
    transitions: FloatArray
    log_likelihood: float
    x_smoothed: FloatArray | None = None
    P_smoothed: FloatArray | None = None


def filter_sequence(
    motion: MotionModel,
    x0: FloatArray,
    P0: FloatArray,
    steps: Sequence[FilterStep],
    *,
    smooth: bool = True,
) -> FilterResult:
    """Filter (and smooth) one object through a sequence of detections and misses.

    The prior ``(x0, P0)`` is the *predicted* state at ``steps[0].time`` (no motion is
    applied before the first step).  ``log_likelihood`` sums ``log N(nu; 0, S)`` over
    the steps with a detection.

    Parameters
    ----------
    motion : MotionModel
    x0 : ndarray, shape (n,)
    P0 : ndarray, shape (n, n)
    steps : sequence of FilterStep
        Strictly increasing times.
    smooth : bool
        Also run the RTS smoother.
    """
    if not steps:
        raise InputError("steps must contain at least one FilterStep")
    n = motion.state_dim
    T = len(steps)
    xf = np.empty((T, n))
    Pf = np.empty((T, n, n))
    xp = np.empty((T, n))
    Pp = np.empty((T, n, n))
    Fs = np.zeros((T, n, n))
    Fs[0] = np.eye(n)
    x = np.asarray(x0, dtype=float)
    P = np.asarray(P0, dtype=float)
    cholesky(P, "prior covariance P0")
    loglik = 0.0
    times = np.array([s.time for s in steps], dtype=float)
    for k, step in enumerate(steps):
        if k > 0:
            dt = times[k] - times[k - 1]
            if not dt > 0:
                raise InputError(
                    f"filter steps must have strictly increasing times, step {k} has time "
                    f"{times[k]} after {times[k - 1]}"
                )
            x, P, Fs[k] = predict_motion(motion, x, P, dt)
        xp[k], Pp[k] = x, P
        if step.z is not None:
            if step.measurement is None:
                raise InputError(f"step {k} has a detection but no measurement model")
            z = np.asarray(step.z, dtype=float)
            nu, S, H = innovation(step.measurement, x, P, z)
            loglik += float(log_gaussian(nu, S))
            x, P = update(x, P, nu, S, H, step.measurement.noise_covariance)
        xf[k], Pf[k] = x, P
    xs = Ps = None
    if smooth:
        xs, Ps = rts_smooth(xf, Pf, xp, Pp, Fs)
    return FilterResult(times, xf, Pf, xp, Pp, Fs, loglik, xs, Ps)
