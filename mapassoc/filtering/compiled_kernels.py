"""Numba kernels of the linear Kalman steps that refinement takes track by track.

Imported only through :func:`mapassoc.filtering.compiled.kalman_kernels` (numba is an
optional accelerator: ``pip install 'mapassoc[accelerate]'``; chosen by
:func:`mapassoc.filtering.compiled.filter_backend`).  Each kernel is the same algebra
as its numpy twin in :mod:`mapassoc.filtering.scan_steps` and the batched interface
:mod:`mapassoc.filtering.batch` (gain through ``S^-1``, Joseph-form covariance,
closed-form inverses for d = 1 and 2, the same gate and terms), written as loops over
small matrices so that one track's step costs arithmetic rather than numpy's per-call
overhead.  Results agree with the numpy path to
rounding (sums are taken in another order).

The kernels do not raise: a step whose innovation covariance is not positive-definite
sets a flag, and the caller raises.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.filtering.scan_steps import ScanModel

_LOG_2PI = math.log(2.0 * math.pi)


@njit(cache=True)
def _inverse_and_logdet(S: FloatArray, out: FloatArray, d: int) -> tuple[float, bool]:
    """``out = S^-1`` of the symmetric leading (d, d) block of ``S`` (into the leading
    block of ``out``); returns ``(log det S, positive)``: closed forms for d = 1 and 2,
    Cholesky otherwise."""
    if d == 1:
        det = S[0, 0]
        if not det > 0:
            return 0.0, False
        out[0, 0] = 1.0 / det
        return math.log(det), True
    if d == 2:
        a, b, c = S[0, 0], S[0, 1], S[1, 1]
        det = a * c - b * b
        if not (a > 0 and det > 0):
            return 0.0, False
        scale = 1.0 / det
        out[0, 0] = c * scale
        out[1, 1] = a * scale
        out[0, 1] = -b * scale
        out[1, 0] = -b * scale
        return math.log(det), True
    L = np.zeros((d, d))
    for i in range(d):
        for j in range(i + 1):
            total = S[i, j]
            for k in range(j):
                total -= L[i, k] * L[j, k]
            if i == j:
                if not total > 0:
                    return 0.0, False
                L[i, i] = math.sqrt(total)
            else:
                L[i, j] = total / L[j, j]
    logdet = 0.0
    for i in range(d):
        logdet += 2.0 * math.log(L[i, i])
    # S^-1 = L^-T L^-1, column by column of the identity.
    for col in range(d):
        y = np.zeros(d)
        for i in range(d):
            total = 1.0 if i == col else 0.0
            for k in range(i):
                total -= L[i, k] * y[k]
            y[i] = total / L[i, i]
        for i in range(d - 1, -1, -1):
            total = y[i]
            for k in range(i + 1, d):
                total -= L[k, i] * out[k, col]
            out[i, col] = total / L[i, i]
    return logdet, True


@njit(cache=True)
def _scratch(n: int, dz: int) -> tuple[FloatArray, ...]:
    """Work arrays of :func:`_update_one` for states of size n and measurements of size
    up to dz, allocated once per kernel call."""
    return (
        np.empty((dz, n)),
        np.empty((dz, dz)),
        np.empty(dz),
        np.empty((dz, dz)),
        np.empty((n, dz)),
        np.empty((n, n)),
        np.empty((n, n)),
        np.empty((n, dz)),
    )


@njit(cache=True)
def _innovation(
    x: FloatArray, P: FloatArray, z: FloatArray, H: FloatArray, R: FloatArray, d: int,
    HP: FloatArray, S: FloatArray, nu: FloatArray,
) -> None:  # fmt: skip
    """``HP = H P``, ``S = H P H^T + R`` (symmetrised) and ``nu = z - H x`` of a
    measurement of dimension ``d``, into the leading blocks of the work arrays."""
    n = x.shape[0]
    for i in range(d):
        for k in range(n):
            total = 0.0
            for j in range(n):
                total += H[i, j] * P[j, k]
            HP[i, k] = total
    for i in range(d):
        for m in range(d):
            total = R[i, m]
            for k in range(n):
                total += HP[i, k] * H[m, k]
            S[i, m] = total
    for i in range(d):
        for m in range(i + 1, d):
            mean = 0.5 * (S[i, m] + S[m, i])
            S[i, m] = mean
            S[m, i] = mean
    for i in range(d):
        total = z[i]
        for j in range(n):
            total -= H[i, j] * x[j]
        nu[i] = total


@njit(cache=True)
def _gain_and_mean(
    x: FloatArray, HP: FloatArray, S_inv: FloatArray, nu: FloatArray, d: int,
    K: FloatArray, x_out: FloatArray,
) -> None:  # fmt: skip
    """``K = (H P)^T S^-1`` and ``x_out = x + K nu``."""
    n = x.shape[0]
    for a in range(n):
        for i in range(d):
            total = 0.0
            for k in range(d):
                total += HP[k, a] * S_inv[k, i]
            K[a, i] = total
    for a in range(n):
        total = x[a]
        for i in range(d):
            total += K[a, i] * nu[i]
        x_out[a] = total


@njit(cache=True)
def _joseph(
    P: FloatArray, H: FloatArray, R: FloatArray, K: FloatArray, d: int,
    A: FloatArray, AP: FloatArray, KR: FloatArray, P_out: FloatArray,
) -> None:  # fmt: skip
    """``P_out = (I - K H) P (I - K H)^T + K R K^T``, symmetrised (Joseph form)."""
    n = P.shape[0]
    for a in range(n):
        for b in range(n):
            total = 1.0 if a == b else 0.0
            for i in range(d):
                total -= K[a, i] * H[i, b]
            A[a, b] = total
    for a in range(n):
        for b in range(n):
            total = 0.0
            for k in range(n):
                total += A[a, k] * P[k, b]
            AP[a, b] = total
    for a in range(n):
        for i in range(d):
            total = 0.0
            for k in range(d):
                total += K[a, k] * R[k, i]
            KR[a, i] = total
    for a in range(n):
        for b in range(n):
            total = 0.0
            for k in range(n):
                total += AP[a, k] * A[b, k]
            for i in range(d):
                total += KR[a, i] * K[b, i]
            P_out[a, b] = total
    for a in range(n):
        for b in range(a + 1, n):
            mean = 0.5 * (P_out[a, b] + P_out[b, a])
            P_out[a, b] = mean
            P_out[b, a] = mean


@njit(cache=True)
def _update_one(
    x: FloatArray,
    P: FloatArray,
    z: FloatArray,
    H: FloatArray,
    R: FloatArray,
    d: int,
    x_out: FloatArray,
    P_out: FloatArray,
    scratch: tuple[FloatArray, ...],
) -> tuple[float, float, bool]:
    """One track's Kalman update by one detection of dimension ``d`` (the leading
    entries of ``z``, rows of ``H`` and block of ``R``; no slices, so every array keeps
    one layout and the function one compiled version): writes the posterior into
    ``x_out``, ``P_out`` (n,) and (n, n); returns ``(d2, loglik, positive)``.
    ``scratch`` is :func:`_scratch`'s work arrays."""
    HP, S, nu, S_inv = scratch[0], scratch[1], scratch[2], scratch[3]
    _innovation(x, P, z, H, R, d, HP, S, nu)
    logdet, positive = _inverse_and_logdet(S, S_inv, d)
    if not positive:
        return 0.0, 0.0, False
    d2 = 0.0
    for i in range(d):
        total = 0.0
        for m in range(d):
            total += S_inv[i, m] * nu[m]
        d2 += nu[i] * total
    loglik = -0.5 * (d * _LOG_2PI + logdet + d2)
    K = scratch[4]
    _gain_and_mean(x, HP, S_inv, nu, d, K, x_out)
    _joseph(P, H, R, K, d, scratch[5], scratch[6], scratch[7], P_out)
    return d2, loglik, True


@njit(cache=True)
def _predict_one(
    x: FloatArray, P: FloatArray, F: FloatArray, Q: FloatArray,
    x_tmp: FloatArray, P_tmp: FloatArray, FP: FloatArray,
) -> None:  # fmt: skip
    """``x = F x`` and ``P = F P F^T + Q`` (symmetrised), in place; ``x_tmp``, ``P_tmp``
    and ``FP`` are work arrays."""
    n = x.shape[0]
    for a in range(n):
        total = 0.0
        for k in range(n):
            total += F[a, k] * x[k]
        x_tmp[a] = total
    for a in range(n):
        x[a] = x_tmp[a]
    for a in range(n):
        for b in range(n):
            total = 0.0
            for k in range(n):
                total += F[a, k] * P[k, b]
            FP[a, b] = total
    for a in range(n):
        for b in range(n):
            total = Q[a, b]
            for k in range(n):
                total += FP[a, k] * F[b, k]
            P_tmp[a, b] = total
    for a in range(n):
        for b in range(n):
            P[a, b] = 0.5 * (P_tmp[a, b] + P_tmp[b, a])


@njit(cache=True)
def _step_to(
    xt: FloatArray,
    Pt: FloatArray,
    v: float,
    cur: int,
    target: int,
    z: FloatArray,
    scan_model: ScanModel,
    x_tmp: FloatArray,
    P_tmp: FloatArray,
    FP: FloatArray,
    scratch: tuple[FloatArray, ...],
) -> tuple[float, bool]:
    """One track from scan ``cur`` to its detection ``z`` at scan ``target``: predicted
    scan by scan (a miss at every scan in between), then updated; ``xt``, ``Pt`` in
    place.  Returns the value with the step's terms added (``-inf`` outside the gate)
    and whether ``S`` was positive-definite.  ``x_tmp``, ``P_tmp``, ``FP`` and
    ``scratch`` are work arrays."""
    moves, F, Q, H, R, dims, survival, miss, log_pd, log_clutter, thresholds, _, _ = scan_model
    n = xt.shape[0]
    while cur < target:
        nxt = cur + 1
        if moves[nxt]:
            _predict_one(xt, Pt, F[nxt], Q[nxt], x_tmp, P_tmp, FP)
        if nxt < target:
            v += survival[nxt] + miss[nxt]
        cur = nxt
    d2, loglik, positive = _update_one(
        xt, Pt, z, H[target], R[target], dims[target], x_tmp, P_tmp, scratch
    )
    if not positive:
        return v, False
    for a in range(n):
        xt[a] = x_tmp[a]
        for b in range(n):
            Pt[a, b] = P_tmp[a, b]
    term = -math.inf
    if d2 <= thresholds[target]:
        # mapassoc.estimator.terms.detection_term, with the table's numbers.
        term = log_pd[target] + loglik - log_clutter[target]
    return v + survival[target] + term, True


@njit(cache=True)
def filter_along_path(
    x: FloatArray,
    P: FloatArray,
    value: float,
    scan: int,
    path_scans: IntArray,
    detections: FloatArray,
    scan_model: ScanModel,
) -> tuple[FloatArray, FloatArray, FloatArray, bool]:
    """One track's filter run through its detections, as ``RecordingObjective.trajectory``
    takes it once the track's state is in the motion model's space.

    Parameters
    ----------
    x, P : ndarray, shapes (n,) and (n, n)
        The state at scan ``scan``, with the value ``value`` so far.
    path_scans : ndarray of int, shape (L,)
        The scans of the next detections (increasing, after ``scan``).
    detections : ndarray, shape (L, dz)
        The detections (zero-padded to dz).
    scan_model : ScanModel

    Returns
    -------
    means, covariances : ndarray, shapes (L, n) and (L, n, n)
        The filtered state after each detection.
    values : ndarray, shape (L,)
        The value after each detection (``-inf`` from a detection outside the gate on).
    positive : bool
        False where some ``S`` is not positive-definite.
    """
    n = x.shape[0]
    L = path_scans.shape[0]
    means = np.empty((L, n))
    covariances = np.empty((L, n, n))
    values = np.empty(L)
    xt = x.copy()
    Pt = P.copy()
    x_tmp = np.empty(n)
    P_tmp = np.empty((n, n))
    FP = np.empty((n, n))
    scratch = _scratch(n, detections.shape[1])
    v = value
    cur = scan
    for i in range(L):
        target = path_scans[i]
        v, positive = _step_to(
            xt,
            Pt,
            v,
            cur,
            target,
            detections[i],
            scan_model,
            x_tmp,
            P_tmp,
            FP,
            scratch,
        )
        if not positive:
            return means, covariances, values, False
        cur = target
        for a in range(n):
            means[i, a] = xt[a]
            for b in range(n):
                covariances[i, a, b] = Pt[a, b]
        values[i] = v
    return means, covariances, values, True


@njit(cache=True)
def _same_state(
    x: FloatArray, P: FloatArray, mean: FloatArray, covariance: FloatArray, converged: float
) -> bool:
    """Whether every entry of ``x``, ``P`` is within ``converged`` of the reference's
    ``mean``, ``covariance``, relative to ``1 + |entry|``."""
    n = x.shape[0]
    for a in range(n):
        if abs(x[a] - mean[a]) > converged * (1.0 + abs(mean[a])):
            return False
    for a in range(n):
        for b in range(n):
            ref = covariance[a, b]
            if abs(P[a, b] - ref) > converged * (1.0 + abs(ref)):
                return False
    return True


@njit(cache=True)
def continue_along_references(
    x: FloatArray,
    P: FloatArray,
    value: FloatArray,
    scan: IntArray,
    request: IntArray,
    steps: IntArray,
    ref_scan: IntArray,
    detection: FloatArray,
    rest: FloatArray,
    mean: FloatArray,
    covariance: FloatArray,
    tail: FloatArray,
    scan_model: ScanModel,
    converged: float,
) -> tuple[FloatArray, bool]:
    """Each track continued along its request's reference detections, as the batched
    numpy body of ``RecordingObjective.continue_converging_many`` does.

    A track predicts scan by scan to the reference's next detection (a miss at every
    scan in between), is updated by it, and leaves when its value is ``-inf`` (out of
    gate), at the reference's last step, or when its state has converged to the
    reference's (then its value is the reference's from there on).

    Parameters
    ----------
    x, P : ndarray, shapes (T, n) and (T, n, n)
        The tracks' states (overwritten).
    value : ndarray, shape (T,)
    scan, request : ndarray of int, shape (T,)
        Each track's scan and its request's row of the reference tables.
    steps, ref_scan, detection, rest, mean, covariance, tail
        The reference tables (``_ReferenceSteps``), shapes (C,), (C, W), (C, W, dz),
        (C, W), (C, W, n), (C, W, n, n), (C,).
    scan_model : ScanModel
    converged : float
        Relative tolerance of the converged test.

    Returns
    -------
    out : ndarray, shape (T,)
        Each track's value continued along its reference (``-inf`` where it left the
        gate).
    positive : bool
        False where some ``S`` is not positive-definite.
    """
    T, n = x.shape
    out = np.empty(T)
    x_post = np.empty(n)
    P_post = np.empty((n, n))
    FP = np.empty((n, n))
    scratch = _scratch(n, detection.shape[2])
    for t in range(T):
        c = request[t]
        xt = x[t]
        Pt = P[t]
        v = value[t]
        cur = scan[t]
        s = 0
        while True:
            target = ref_scan[c, s]
            v, positive = _step_to(
                xt,
                Pt,
                v,
                cur,
                target,
                detection[c, s],
                scan_model,
                x_post,
                P_post,
                FP,
                scratch,
            )
            if not positive:
                return out, False
            cur = target
            if not math.isfinite(v):
                out[t] = -math.inf
                break
            result = v + rest[c, s] + tail[c]
            if s == steps[c] - 1:
                out[t] = result
                break
            same = _same_state(xt, Pt, mean[c, s], covariance[c, s], converged)
            if same:
                out[t] = result
                break
            s += 1
    return out, True


def _warm_up() -> None:
    """Compile (or load) the kernels for the argument types the objective passes."""
    n, dz, M = 2, 1, 3
    F = np.tile(np.eye(n), (M, 1, 1))
    terms = np.zeros(M)
    scan_model = (
        np.ones(M, dtype=np.bool_), F, F, np.tile(np.eye(dz, n), (M, 1, 1)),
        np.tile(np.eye(dz), (M, 1, 1)), np.full(M, dz, dtype=np.int64),
        terms, terms, terms, terms, np.full(M, 10.0), np.zeros(M, dtype=np.int64),
        np.zeros(M, dtype=np.int64),
    )  # fmt: skip
    path = np.array([1, 2], dtype=np.int64)
    filter_along_path(np.zeros(n), np.eye(n), 0.0, 0, path, np.zeros((2, dz)), scan_model)
    continue_along_references(
        np.zeros((1, n)), np.eye(n)[None], np.zeros(1), np.zeros(1, dtype=np.int64),
        np.zeros(1, dtype=np.int64), np.array([2], dtype=np.int64), path[None],
        np.zeros((1, 2, dz)), np.zeros((1, 2)), np.zeros((1, 2, n)),
        np.zeros((1, 2, n, n)), np.zeros(1), scan_model, 1e-9,
    )  # fmt: skip


_warm_up()
