"""The numpy backend of a recording's linear Kalman runs, over its per-scan matrices.

The same two functions, with the same arguments and returns, as the compiled kernels of
:mod:`mapassoc.filtering.compiled_kernels`; :func:`mapassoc.filtering.compiled.filter_backend`
chooses between the two modules.  Every step here is the batched interface's algebra
(:mod:`mapassoc.filtering.batch`: ``S`` from
:func:`~mapassoc.filtering.kalman.innovation_covariance`, its inverse from
:func:`~mapassoc.filtering.kalman.inverse_and_logdet`, the scores from
:func:`~mapassoc.filtering.kalman.gaussian_terms`, the Joseph update), so a track's run
here has the bits of the hypothesis trees' steps.  A batch of tracks is taken one step
for all at once (each track at its own scan), grouped by the scan's motion step and
sensor, so one numpy call serves every track of a group.

Neither function raises on an ``S`` that is not positive-definite: it returns the flag
``positive = False``, as the kernels do, and the caller raises.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import BoolArray, FloatArray, IntArray
from mapassoc.errors import NotPositiveDefiniteError
from mapassoc.filtering.kalman import (
    gaussian_terms,
    innovation_covariance,
    inverse_and_logdet,
    joseph_update,
    predicted_covariance,
)

__all__ = [
    "ScanModel",
    "SetModel",
    "filter_along_path",
    "continue_along_references",
    "advance",
    "detect",
    "states_agree",
]

ScanModel = tuple[
    NDArray[np.bool_],
    FloatArray,
    FloatArray,
    FloatArray,
    FloatArray,
    IntArray,
    FloatArray,
    FloatArray,
    FloatArray,
    FloatArray,
    FloatArray,
    IntArray,
    IntArray,
]
"""What every backend reads of the recording, per scan ``m`` (M scans), in this order:

* ``moves`` (M,) bool: whether the step from scan ``m - 1`` to ``m`` has a positive
  time step; ``F``, ``Q`` (M, n, n): the motion model's matrices of that step;
* ``H`` (M, dz, n), ``R`` (M, dz, dz), ``dims`` (M,) int: the scan's linear
  measurement, in its first ``dims[m]`` rows and columns;
* ``survival``, ``miss``, ``log_pd``, ``log_clutter``, ``thresholds`` (M,): the
  per-scan terms and the gate, from the recording's table of terms
  (``mapassoc.estimator.terms.ScanTerms``);
* ``motion_code``, ``sensor_code`` (M,) int: scans with equal codes have the same
  ``F``, ``Q`` (the same time step), respectively the same ``H``, ``R`` (the same
  sensor), so the numpy backend takes their tracks' steps together.

Built once per recording by ``mapassoc.estimator.refiltering``."""

SetModel = tuple[NDArray[np.bool_], FloatArray, FloatArray, FloatArray]
"""What the compiled joins of a set of linear motion models read per scan ``m``
(:mod:`mapassoc.filtering.compiled_imm`): ``moves`` (M,) as in :data:`ScanModel`; each
model's ``F`` and ``Q`` (M, K, n, n) of the step from scan ``m - 1``; the switching
matrix over that step (M, K, K), for the K models of the set.  Built once per recording
by ``mapassoc.estimator.refiltering``; its numpy twin is the batched lockstep
continuation, which reads the models themselves."""


def advance(
    x: FloatArray,
    P: FloatArray,
    value: FloatArray,
    scan: IntArray,
    target: IntArray,
    scan_model: ScanModel,
) -> None:
    """Each track predicted scan by scan from its ``scan`` to its ``target`` scan, with
    the survival and miss terms of the scans in between added to ``value``; in place
    (``scan`` ends equal to ``target``)."""
    moves, F, Q = scan_model[0], scan_model[1], scan_model[2]
    survival, miss, motion_code = scan_model[6], scan_model[7], scan_model[11]
    while True:
        moving = np.flatnonzero(scan < target)
        if moving.size == 0:
            return
        nxt = scan[moving] + 1
        steps = moves[nxt]
        codes = motion_code[nxt]
        for code in np.unique(codes[steps]).tolist():
            chosen = steps & (codes == code)
            rows = moving[chosen]
            m = int(nxt[chosen][0])
            x[rows] = x[rows] @ F[m].T
            P[rows] = predicted_covariance(F[m], P[rows], Q[m])
        missed = nxt < target[moving]
        value[moving[missed]] += survival[nxt[missed]] + miss[nxt[missed]]
        scan[moving] = nxt


def detect(
    x: FloatArray,
    P: FloatArray,
    value: FloatArray,
    target: IntArray,
    z: FloatArray,
    scan_model: ScanModel,
) -> None:
    """Each track, predicted to its ``target`` scan, updated by its detection ``z[b]``
    (zero-padded), with the survival and detection terms added to ``value`` (``-inf``
    outside the gate); in place, one sensor at a time.

    Raises
    ------
    NotPositiveDefiniteError
        Where an ``S`` is not positive-definite.
    """
    H_all, R_all, dims = scan_model[3], scan_model[4], scan_model[5]
    survival, log_pd, log_clutter = scan_model[6], scan_model[8], scan_model[9]
    thresholds, sensor_code = scan_model[10], scan_model[12]
    codes = sensor_code[target]
    for code in np.unique(codes).tolist():
        rows = np.flatnonzero(codes == code)
        m = int(target[rows[0]])
        d = int(dims[m])
        H, R = H_all[m, :d], R_all[m, :d, :d]
        Pr = P[rows]
        S_inv, logdet = inverse_and_logdet(innovation_covariance(H, Pr, R))
        nu = z[rows, :d] - x[rows] @ H.T
        d2, loglik = gaussian_terms(nu, S_inv, logdet)
        x[rows], P[rows] = joseph_update(x[rows], Pr, nu, S_inv, H, R)
        t = target[rows]
        # mapassoc.estimator.terms.detection_term, with the table's numbers.
        term = np.where(d2 <= thresholds[t], log_pd[t] + loglik - log_clutter[t], -math.inf)
        value[rows] += survival[t] + term


def filter_along_path(
    x: FloatArray,
    P: FloatArray,
    value: float,
    scan: int,
    path_scans: IntArray,
    detections: FloatArray,
    scan_model: ScanModel,
) -> tuple[FloatArray, FloatArray, FloatArray, bool]:
    """One track's filter run through its detections
    (:func:`mapassoc.filtering.compiled_kernels.filter_along_path`: the same arguments and
    returns)."""
    L, n = path_scans.shape[0], x.shape[0]
    means, covariances, values = np.empty((L, n)), np.empty((L, n, n)), np.empty(L)
    xt, Pt = np.array(x, dtype=np.float64)[None], np.array(P, dtype=np.float64)[None]
    v = np.array([float(value)])
    cur = np.array([scan], dtype=np.int64)
    for i in range(L):
        target = path_scans[i : i + 1]
        advance(xt, Pt, v, cur, target, scan_model)
        try:
            detect(xt, Pt, v, target, detections[i : i + 1], scan_model)
        except NotPositiveDefiniteError:
            return means, covariances, values, False
        means[i], covariances[i], values[i] = xt[0], Pt[0], v[0]
    return means, covariances, values, True


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
    """Each track continued along its request's reference detections
    (:func:`mapassoc.filtering.compiled_kernels.continue_along_references`: the same
    arguments and returns), one reference detection per round for every track still
    going; the arrays of the tracks are changed in place."""
    track = np.arange(value.size)  # position in the flat output
    out = np.full(value.size, -math.inf)
    step = np.zeros(track.size, dtype=np.int64)  # detections of the reference taken
    while track.size:
        target = ref_scan[request, step]
        advance(x, P, value, scan, target, scan_model)
        try:
            detect(x, P, value, target, detection[request, step], scan_model)
        except NotPositiveDefiniteError:
            return out, False
        leave = ~np.isfinite(value) | (step == steps[request] - 1)
        leave |= _converged(x, P, leave, mean[request, step], covariance[request, step], converged)
        result = np.where(
            np.isfinite(value), value + rest[request, step] + tail[request], -math.inf
        )
        out[track[leave]] = result[leave]
        keep = np.flatnonzero(~leave)
        track, request, x, P, value = track[keep], request[keep], x[keep], P[keep], value[keep]
        scan, step = scan[keep], step[keep] + 1
    return out, True


def _converged(
    x: FloatArray,
    P: FloatArray,
    leaving: BoolArray,
    mean: FloatArray,
    covariance: FloatArray,
    tolerance: float,
) -> BoolArray:
    """Which tracks not already ``leaving`` have the reference's state: every entry of
    the mean and covariance within ``tolerance`` relative to ``1 + |entry|``."""
    same = np.zeros(x.shape[0], dtype=bool)
    check = np.flatnonzero(~leaving)
    if check.size:
        same[check] = states_agree(x[check], P[check], mean[check], covariance[check], tolerance)
    return same


def states_agree(
    x: FloatArray, P: FloatArray, mean: FloatArray, covariance: FloatArray, tolerance: float
) -> BoolArray:
    """Which states of a batch equal a reference's: every entry of the mean and the
    covariance within ``tolerance`` relative to ``1 + |entry|`` (the convergence test of
    the refinement's joins, here and in
    :func:`mapassoc.estimator.converging.converge_in_lockstep`).

    Parameters
    ----------
    x : ndarray, shape (B, n)
    P : ndarray, shape (B, n, n)
    mean : ndarray, shape (n,) or (B, n)
    covariance : ndarray, shape (n, n) or (B, n, n)
    tolerance : float

    Returns
    -------
    ndarray of bool, shape (B,)
    """
    close_mean = np.all(np.abs(x - mean) <= tolerance * (1.0 + np.abs(mean)), axis=1)
    close_cov = np.all(np.abs(P - covariance) <= tolerance * (1.0 + np.abs(covariance)),
                       axis=(1, 2))  # fmt: skip
    return close_mean & close_cov
