"""Numba kernels of the refinement's joins under a set of linear motion models (IMM).

Imported only through :func:`mapassoc.filtering.compiled.imm_kernels` (numba is an
optional accelerator).  The kernel :func:`continue_sets_along_references` is
:func:`mapassoc.filtering.compiled_kernels.continue_along_references` for filter states
of an :class:`~mapassoc.models.interacting.InteractingModels` set: each step is the
IMM's mixing, each model's prediction, the mixture's gate and predictive likelihood and
each model's update (Blom and Bar-Shalom, "The interacting multiple model algorithm for
systems with Markovian switching coefficients", IEEE TAC 1988), the same algebra as the
batched interface (:meth:`mapassoc.filtering.batch.KalmanFilter.predict`,
``innovation`` and ``update`` of a set) written as loops over small matrices.  Its numpy
twin is the batched lockstep continuation
(:func:`mapassoc.estimator.converging.converge_in_lockstep`), which takes every set, also
one with a nonlinear model; results agree to rounding.

A set's filter state is packed as :func:`mapassoc.models.interacting.pack_models` packs
it: the M model means, then the M log-probabilities; the covariance block-diagonal with
each model's covariance and zeros for the probabilities.  The kernels unpack a track
once, step its parts, and compare them with the reference's packed state (the
off-diagonal blocks are zero on both sides, so the parts are the whole test).

The kernels do not raise: a step whose innovation covariance is not positive-definite
sets a flag, and the caller raises.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.filtering.compiled_kernels import (
    _inverse_and_logdet,
    _predict_one,
    _scratch,
    _update_one,
)
from mapassoc.filtering.scan_steps import ScanModel, SetModel

_LOG_2PI = math.log(2.0 * math.pi)


@njit(cache=True)
def _log_sum_exp(values: FloatArray, count: int) -> float:
    """``log sum exp`` of the leading ``count`` entries (``-inf`` when all are)."""
    top = -math.inf
    for i in range(count):
        if values[i] > top:
            top = values[i]
    if top == -math.inf:
        return -math.inf
    total = 0.0
    for i in range(count):
        total += math.exp(values[i] - top)
    return top + math.log(total)


@njit(cache=True)
def _mix(
    log_mu: FloatArray, x: FloatArray, P: FloatArray, Pi: FloatArray,
    x0: FloatArray, P0: FloatArray, joint: FloatArray, w: FloatArray, log_c: FloatArray,
) -> None:  # fmt: skip
    """IMM mixing in place: ``log_mu`` becomes the predicted log-probabilities
    ``log c_j``, ``x0``, ``P0`` (M, n), (M, n, n) the mixed moments
    (:func:`mapassoc.filtering.imm.mix`); ``joint``, ``w`` and ``log_c`` (M,) are work
    arrays (passed in: the kernels call this once per track and step).  A model no one
    can be in (``c_j = 0``) mixes with equal weights, as numpy's does."""
    M, n = x.shape
    for j in range(M):
        for i in range(M):
            joint[i] = log_mu[i] + math.log(Pi[i, j]) if Pi[i, j] > 0 else -math.inf
        log_c[j] = _log_sum_exp(joint, M)
        for i in range(M):
            w[i] = math.exp(joint[i] - log_c[j]) if log_c[j] > -math.inf else 1.0 / M
        for a in range(n):
            total = 0.0
            for i in range(M):
                total += w[i] * x[i, a]
            x0[j, a] = total
        for a in range(n):
            for b in range(n):
                total = 0.0
                for i in range(M):
                    total += w[i] * P[i, a, b]
                for i in range(M):
                    total += w[i] * (x[i, a] - x0[j, a]) * (x[i, b] - x0[j, b])
                P0[j, a, b] = total
        for a in range(n):
            for b in range(a + 1, n):
                mean = 0.5 * (P0[j, a, b] + P0[j, b, a])
                P0[j, a, b] = mean
                P0[j, b, a] = mean
    for j in range(M):
        log_mu[j] = log_c[j]


@njit(cache=True)
def _predict_set(
    log_mu: FloatArray, x: FloatArray, P: FloatArray, F: FloatArray, Q: FloatArray,
    Pi: FloatArray, work: tuple[FloatArray, ...],
) -> None:  # fmt: skip
    """Mixing, then each model's prediction of its mixed moments (in place); ``F``,
    ``Q`` (M, n, n), ``Pi`` (M, M) of the step; ``work`` is :func:`_set_work`'s."""
    M = x.shape[0]
    x0, P0, joint, w, x_tmp, P_tmp, FP = work[:7]
    _mix(log_mu, x, P, Pi, x0, P0, joint, w, work[14])
    for j in range(M):
        _predict_one(x0[j], P0[j], F[j], Q[j], x_tmp, P_tmp, FP)
    x[:] = x0
    P[:] = P0


@njit(cache=True)
def _set_work(M: int, n: int, dz: int) -> tuple[FloatArray, ...]:
    """Work arrays of one track's set steps: mixed moments, weights, prediction work,
    each model's predicted measurement and ``S``, the mixture's ``S`` and inverse, each
    model's posterior and scores, the mixing's ``log c`` and the mixture's mean and
    shift."""
    return (
        np.empty((M, n)), np.empty((M, n, n)), np.empty(M), np.empty(M), np.empty(n),
        np.empty((n, n)), np.empty((n, n)), np.empty((M, dz)), np.empty((M, dz, dz)),
        np.empty((dz, dz)), np.empty((dz, dz)), np.empty((M, n)), np.empty((M, n, n)),
        np.empty(M), np.empty(M), np.empty(dz), np.empty(dz),
    )  # fmt: skip


@njit(cache=True)
def _mixture_d2(
    log_c: FloatArray, z: FloatArray, z_hat: FloatArray, S_parts: FloatArray, d: int,
    S: FloatArray, S_inv: FloatArray, mean: FloatArray, shift: FloatArray,
) -> tuple[float, bool]:  # fmt: skip
    """``d2 = nu^T S^-1 nu`` of the moment-matched predicted measurement: ``z_hat``
    (M, dz) and ``S_parts`` (M, dz, dz) each model's, weighted by ``c = exp(log_c)``
    (``batch._mixture_innovation``'s algebra); ``mean`` and ``shift`` (at least d,) are
    work arrays; returns ``(d2, positive)``."""
    M = log_c.shape[0]
    mean[:d] = 0.0
    for j in range(M):
        for i in range(d):
            mean[i] += math.exp(log_c[j]) * z_hat[j, i]
    shift[:d] = 0.0  # the circular-mean correction, zero up to rounding here
    for j in range(M):
        for i in range(d):
            shift[i] += math.exp(log_c[j]) * (z_hat[j, i] - mean[i])
    for i in range(d):
        mean[i] += shift[i]
    for i in range(d):
        for k in range(d):
            total = 0.0
            for j in range(M):
                c = math.exp(log_c[j])
                total += c * S_parts[j, i, k]
                total += c * (z_hat[j, i] - mean[i]) * (z_hat[j, k] - mean[k])
            S[i, k] = total
    for i in range(d):
        for k in range(i + 1, d):
            half = 0.5 * (S[i, k] + S[k, i])
            S[i, k] = half
            S[k, i] = half
    _, positive = _inverse_and_logdet(S, S_inv, d)
    d2 = 0.0
    for i in range(d):
        for k in range(d):
            d2 += (z[i] - mean[i]) * S_inv[i, k] * (z[k] - mean[k])
    return d2, positive


@njit(cache=True)
def _update_set(
    log_mu: FloatArray, x: FloatArray, P: FloatArray, z: FloatArray, H: FloatArray,
    R: FloatArray, d: int, work: tuple[FloatArray, ...], scratch: tuple[FloatArray, ...],
) -> tuple[float, float, bool]:  # fmt: skip
    """Each model's Kalman update by ``z`` and the posterior model probabilities, in
    place; returns ``(d2, loglik, positive)``: the mixture's gate distance and the IMM
    predictive log-likelihood ``log sum_j c_j N(z; H x_j, S_j)``."""
    M, n = x.shape
    z_hat, S_parts, S, S_inv = work[7], work[8], work[9], work[10]
    x_post, P_post, scores = work[11], work[12], work[13]
    for j in range(M):
        _, score, positive = _update_one(x[j], P[j], z, H, R, d, x_post[j], P_post[j], scratch)
        if not positive:
            return 0.0, 0.0, False
        scores[j] = log_mu[j] + score
        for i in range(d):
            z_hat[j, i] = z[i] - scratch[2][i]  # nu_j = z - H x_j
            for k in range(d):
                S_parts[j, i, k] = scratch[1][i, k]
    d2, positive = _mixture_d2(log_mu, z, z_hat, S_parts, d, S, S_inv, work[15], work[16])
    if not positive:
        return 0.0, 0.0, False
    loglik = _log_sum_exp(scores, M)
    for j in range(M):
        log_mu[j] = scores[j] - loglik
    x[:] = x_post
    P[:] = P_post
    return d2, loglik, True


@njit(cache=True)
def _set_step_to(
    log_mu: FloatArray, x: FloatArray, P: FloatArray, v: float, cur: int, target: int,
    z: FloatArray, scan_model: ScanModel, set_model: SetModel,
    work: tuple[FloatArray, ...], scratch: tuple[FloatArray, ...],
) -> tuple[float, bool]:  # fmt: skip
    """One track of a set from scan ``cur`` to its detection ``z`` at scan ``target``:
    mixed and predicted scan by scan (a miss at every scan in between), then updated; in
    place.  Returns the value with the step's terms added (``-inf`` outside the gate)
    and whether every ``S`` was positive-definite (``compiled_kernels._step_to`` for a
    set)."""
    _, _, _, H, R, dims, survival, miss, log_pd, log_clutter, thresholds, _, _ = scan_model
    moves, F, Q, Pi = set_model
    while cur < target:
        nxt = cur + 1
        if moves[nxt]:
            _predict_set(log_mu, x, P, F[nxt], Q[nxt], Pi[nxt], work)
        if nxt < target:
            v += survival[nxt] + miss[nxt]
        cur = nxt
    d2, loglik, positive = _update_set(
        log_mu, x, P, z, H[target], R[target], dims[target], work, scratch
    )
    if not positive:
        return v, False
    term = -math.inf
    if d2 <= thresholds[target]:
        # mapassoc.estimator.terms.detection_term, with the table's numbers.
        term = log_pd[target] + loglik - log_clutter[target]
    return v + survival[target] + term, True


@njit(cache=True)
def _unpack(
    state: FloatArray, covariance: FloatArray, log_mu: FloatArray, x: FloatArray, P: FloatArray
) -> None:
    """A packed filter state's parts into ``log_mu`` (M,), ``x`` (M, n), ``P`` (M, n, n)."""
    M, n = x.shape
    for j in range(M):
        log_mu[j] = state[M * n + j]
        for a in range(n):
            x[j, a] = state[j * n + a]
            for b in range(n):
                P[j, a, b] = covariance[j * n + a, j * n + b]


@njit(cache=True)
def _same_set_state(
    log_mu: FloatArray, x: FloatArray, P: FloatArray, mean: FloatArray,
    covariance: FloatArray, converged: float,
) -> bool:  # fmt: skip
    """Whether the parts are within ``converged`` of the packed reference, relative to
    ``1 + |entry|`` (``scan_steps.states_agree`` on the packed states: the blocks off
    the diagonal are zero on both sides)."""
    M, n = x.shape
    for j in range(M):
        ref = mean[M * n + j]
        if abs(log_mu[j] - ref) > converged * (1.0 + abs(ref)):
            return False
        for a in range(n):
            ref = mean[j * n + a]
            if abs(x[j, a] - ref) > converged * (1.0 + abs(ref)):
                return False
    for j in range(M):
        for a in range(n):
            for b in range(n):
                ref = covariance[j * n + a, j * n + b]
                if abs(P[j, a, b] - ref) > converged * (1.0 + abs(ref)):
                    return False
    return True


@njit(cache=True)
def continue_sets_along_references(
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
    set_model: SetModel,
    converged: float,
) -> tuple[FloatArray, bool]:
    """``compiled_kernels.continue_along_references`` for packed states of a set of
    ``M = set_model[3].shape[1]`` linear models (module docstring).

    Parameters
    ----------
    x, P : ndarray, shapes (T, M (n + 1)) and (T, M (n + 1), M (n + 1))
        The tracks' packed states (read only).
    value, scan, request, steps, ref_scan, detection, rest, mean, covariance, tail
        As for ``continue_along_references`` (the reference's states packed).
    scan_model : ScanModel
        The recording's measurement matrices and terms (its motion entries are unused).
    set_model : SetModel
        Per scan: whether the step moves, each model's ``F`` and ``Q`` (S, M, n, n), and
        the switching matrix (S, M, M).
    converged : float

    Returns
    -------
    out : ndarray, shape (T,)
    positive : bool
    """
    T, N = x.shape
    M = set_model[3].shape[1]
    n = N // M - 1
    out = np.empty(T)
    log_mu, xs, Ps = np.empty(M), np.empty((M, n)), np.empty((M, n, n))
    work = _set_work(M, n, detection.shape[2])
    scratch = _scratch(n, detection.shape[2])
    for t in range(T):
        c = request[t]
        _unpack(x[t], P[t], log_mu, xs, Ps)
        v = value[t]
        cur = scan[t]
        s = 0
        while True:
            target = ref_scan[c, s]
            v, positive = _set_step_to(
                log_mu, xs, Ps, v, cur, target, detection[c, s], scan_model, set_model,
                work, scratch,
            )  # fmt: skip
            if not positive:
                return out, False
            cur = target
            if not math.isfinite(v):
                out[t] = -math.inf
                break
            result = v + rest[c, s] + tail[c]
            if s == steps[c] - 1 or _same_set_state(
                log_mu, xs, Ps, mean[c, s], covariance[c, s], converged
            ):
                out[t] = result
                break
            s += 1
    return out, True


@njit(cache=True)
def _pack(log_mu: FloatArray, x: FloatArray, P: FloatArray, state: FloatArray,
          covariance: FloatArray) -> None:  # fmt: skip
    """The parts into a packed state and its block-diagonal covariance (zeroed here)."""
    M, n = x.shape
    covariance[:] = 0.0
    for j in range(M):
        state[M * n + j] = log_mu[j]
        for a in range(n):
            state[j * n + a] = x[j, a]
            for b in range(n):
                covariance[j * n + a, j * n + b] = P[j, a, b]


@njit(cache=True)
def predict_sets(
    x: FloatArray, P: FloatArray, F: FloatArray, Q: FloatArray, Pi: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """IMM mixing and each model's prediction of a batch of packed states over one step
    (what ``KalmanFilter.predict`` does for a set of linear models).

    Parameters
    ----------
    x, P : ndarray, shapes (B, M (n + 1)) and (B, M (n + 1), M (n + 1))
    F, Q : ndarray, shape (M, n, n)
        Each model's matrices over the step.
    Pi : ndarray, shape (M, M)
        The switching matrix over the step.

    Returns
    -------
    x_pred, P_pred : ndarray, the shapes of ``x`` and ``P``
    """
    B, N = x.shape
    M = Pi.shape[0]
    n = N // M - 1
    x_out, P_out = np.empty((B, N)), np.empty((B, N, N))
    log_mu, xs, Ps = np.empty(M), np.empty((M, n)), np.empty((M, n, n))
    work = _set_work(M, n, 1)
    for b in range(B):
        _unpack(x[b], P[b], log_mu, xs, Ps)
        _predict_set(log_mu, xs, Ps, F, Q, Pi, work)
        _pack(log_mu, xs, Ps, x_out[b], P_out[b])
    return x_out, P_out


def _warm_up() -> None:
    """Compile (or load) the kernel for the argument types the objective passes."""
    n, dz, S, M = 2, 1, 3, 2
    eye = np.tile(np.eye(n), (S, 1, 1))
    terms = np.zeros(S)
    scan_model = (
        np.ones(S, dtype=np.bool_), eye, eye, np.tile(np.eye(dz, n), (S, 1, 1)),
        np.tile(np.eye(dz), (S, 1, 1)), np.full(S, dz, dtype=np.int64),
        terms, terms, terms, terms, np.full(S, 10.0), np.zeros(S, dtype=np.int64),
        np.zeros(S, dtype=np.int64),
    )  # fmt: skip
    models = np.tile(np.eye(n), (S, M, 1, 1))
    set_model = (np.ones(S, dtype=np.bool_), models, models, np.full((S, M, M), 1.0 / M))
    N = M * (n + 1)
    path = np.array([[1, 2]], dtype=np.int64)
    continue_sets_along_references(
        np.zeros((1, N)), np.eye(N)[None], np.zeros(1), np.zeros(1, dtype=np.int64),
        np.zeros(1, dtype=np.int64), np.array([2], dtype=np.int64), path,
        np.zeros((1, 2, dz)), np.zeros((1, 2)), np.zeros((1, 2, N)),
        np.zeros((1, 2, N, N)), np.zeros(1), scan_model, set_model, 1e-9,
    )  # fmt: skip
    predict_sets(np.zeros((1, N)), np.eye(N)[None], models[0], models[0], set_model[3][0])


_warm_up()
