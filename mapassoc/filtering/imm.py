"""Interacting multiple model (IMM) filtering and smoothing: pure functions on numpy arrays.

A target's motion switches between ``M`` models (for instance constant velocity with a
low and with a high process noise) by a Markov chain with switching matrix
``Pi[i, j] = P(model j at scan k | model i at scan k - 1)``.  The IMM filter (Blom and
Bar-Shalom, "The interacting multiple model algorithm for systems with Markovian
switching coefficients", IEEE Trans. Automatic Control 33(8), 1988; Bar-Shalom, Li and
Kirubarajan, *Estimation with Applications to Tracking and Navigation*, 2001, chapter
11) carries, per model j, a probability ``mu_j`` and a Gaussian ``(x_j, P_j)``; one
cycle is

1. mixing (:func:`mix`): predicted model probabilities ``c_j = sum_i Pi_ij mu_i``,
   mixing weights ``mu_(i|j) = Pi_ij mu_i / c_j``, mixed moments
   ``x0_j = sum_i mu_(i|j) x_i`` and
   ``P0_j = sum_i mu_(i|j) (P_i + (x_i - x0_j)(x_i - x0_j)^T)``;
2. model-matched prediction (:func:`predict_models`, through
   :func:`mapassoc.filtering.kalman.predict_motion`) and, with a detection, model-matched
   update (:func:`update_models`, :func:`mapassoc.filtering.kalman.update`);
3. model likelihoods ``Lambda_j = N(nu_j; 0, S_j)`` (:func:`model_log_likelihoods`, with
   ``S_j`` from :func:`mapassoc.filtering.kalman.innovation_covariance`), the track's
   predictive likelihood of the detection ``sum_j Lambda_j c_j``
   (:func:`predictive_log_likelihood`) and the model probabilities
   ``mu_j = Lambda_j c_j / sum_l Lambda_l c_l`` (:func:`model_log_probabilities`);
4. without a detection (:func:`imm_miss`) the model probabilities are the predicted ones,
   ``mu_j = c_j``: with a detection probability that does not depend on the model, the
   miss likelihood ``1 - Pd`` is the same for every model and cancels.

Probabilities are carried as logarithms (a model can become very unlikely).  Every
function takes any leading batch axes ``...`` (hypotheses of a tree, tracks), then the
model axis ``M``, then the state: means ``(..., M, n)``, covariances ``(..., M, n, n)``.

What is exact and what is approximate.  With one model, or with models that are
identical, the IMM is the Kalman filter and its predictive likelihood is exact.  With
distinct models the exact posterior is a mixture of ``M^k`` Gaussians (one per model
sequence); the IMM merges it to ``M`` Gaussians at each mixing step (moment matching),
which is its approximation: the predictive likelihoods are exact up to the second
detection after a common prior (the first mixing merges identical Gaussians) and
approximate from the third on.  The tests compare them with the exact sum over model
sequences (:mod:`tests.filtering.test_imm`).

State spaces.  Every model must use the same state space (the same ``state_names``):
mixing adds model-conditioned means and covariances, which is only meaningful in one
space.  Constant velocity ``(x, y, vx, vy)`` and the coordinated turn ``(x, y, speed,
heading, turn_rate)`` are related by a nonlinear change of variables (polar velocity),
which a Gaussian mixture can only take through a linearisation; that pairing is refused
here rather than approximated silently.

Switching law: :class:`~mapassoc.models.switching.SwitchingLaw` (the law per unit of
time, taken to each scan interval), part of the model
:class:`~mapassoc.models.interacting.InteractingModels`.

Smoother (:func:`imm_smooth`): Kim's fixed-interval smoother for Markov-switching linear
models (C.-J. Kim, "Dynamic linear models with Markov-switching", Journal of
Econometrics 60(1-2), 1994), a per-model Rauch-Tung-Striebel smoother with smoothed
model probabilities.  Backwards from the last scan: the smoothed probabilities
``mu^s_k(i) = mu_k(i) sum_j Pi_ij mu^s_(k+1)(j) / c_(k+1)(j)``; for each pair (i at k,
j at k + 1) an RTS step of model i's filtered moments against model j's smoothed ones
through model j's dynamics; the pairs merged over j with the weights
``Pi_ij mu^s_(k+1)(j) / c_(k+1)(j)`` (normalised).  Its approximations: the filter's
merges, and ``p(s_k | s_(k+1), Z_N) ~ p(s_k | s_(k+1), Z_k)`` (the future detections
inform the model at k only through the model at k + 1).  It is exact with one model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError
from mapassoc.filtering.kalman import (
    FilterStep,
    cholesky,
    innovation,
    log_gaussian,
    predict_motion,
    update,
)
from mapassoc.log_space import log_sum_exp
from mapassoc.models.measurement import MeasurementModel
from mapassoc.models.motion import MotionModel
from mapassoc.models.switching import SwitchingLaw, check_switching_matrix

__all__ = [
    "SwitchingLaw",
    "check_switching_matrix",
    "check_models",
    "mix",
    "predict_models",
    "model_log_likelihoods",
    "update_models",
    "predictive_log_likelihood",
    "model_log_probabilities",
    "combine",
    "IMMState",
    "IMMPrediction",
    "imm_predict",
    "imm_update",
    "imm_miss",
    "IMMRun",
    "imm_filter",
    "IMMSmoothed",
    "imm_smooth",
]

def check_models(models: Sequence[MotionModel]) -> tuple[MotionModel, ...]:
    """The models as a tuple, refused unless there is at least one and all share one
    state space (the same ``state_names``; module docstring)."""
    if isinstance(models, MotionModel) or not isinstance(models, Sequence) or not models:
        raise InputError(f"models must be a non-empty sequence of motion models, got {models!r}")
    out = tuple(models)
    for i, model in enumerate(out):
        if not isinstance(model, MotionModel):
            raise InputError(f"models[{i}] must be a motion model, got {model!r}")
        if tuple(model.state_names) != tuple(out[0].state_names):
            raise InputError(
                f"models[{i}] ({model!r}) has the state {tuple(model.state_names)}, models[0] "
                f"({out[0]!r}) {tuple(out[0].state_names)}: IMM mixing needs one state space"
            )
    return out


def mix(
    log_mu: FloatArray, x: FloatArray, P: FloatArray, Pi: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """IMM mixing (module docstring, step 1).

    Parameters
    ----------
    log_mu : ndarray, shape (..., M)
        Log model probabilities at the previous scan.
    x : ndarray, shape (..., M, n)
    P : ndarray, shape (..., M, n, n)
    Pi : ndarray, shape (M, M)
        Switching matrix over the interval.

    Returns
    -------
    log_c : ndarray, shape (..., M)
        Log predicted model probabilities.
    x0 : ndarray, shape (..., M, n)
    P0 : ndarray, shape (..., M, n, n)
        Mixed moments, the start of each model-matched prediction.
    """
    with np.errstate(divide="ignore"):
        log_joint = log_mu[..., :, None] + np.log(Pi)  # (..., i, j)
    log_c = log_sum_exp(log_joint, axis=-2)
    with np.errstate(invalid="ignore"):
        w = np.exp(log_joint - log_c[..., None, :])
    # A model no one can be in (c_j = 0) gets any weights: its probability stays 0.
    w = np.where(np.isfinite(log_c)[..., None, :], w, 1.0 / Pi.shape[0])
    # Matrix products rather than einsum (numpy's einsum of three operands is a plain
    # loop): x0_j = sum_i w_ij x_i, P0_j = sum_i w_ij (P_i + d_ji d_ji^T).
    wt = np.swapaxes(w, -1, -2)  # (..., j, i)
    x0 = wt @ x
    d = x[..., None, :, :] - x0[..., :, None, :]  # (..., j, i, n)
    *lead, M, n = x.shape
    P0 = (wt @ P.reshape(*lead, M, n * n)).reshape(*lead, M, n, n)
    P0 = P0 + np.swapaxes(wt[..., :, :, None] * d, -1, -2) @ d
    return log_c, x0, 0.5 * (P0 + np.swapaxes(P0, -1, -2))


def predict_models(
    models: Sequence[MotionModel], x0: FloatArray, P0: FloatArray, dt: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Model-matched prediction: model j predicts its own mixed moments over ``dt``.

    Parameters
    ----------
    models : sequence of M MotionModel
    x0 : ndarray, shape (..., M, n)
    P0 : ndarray, shape (..., M, n, n)
    dt : float

    Returns
    -------
    x_pred : ndarray, shape (..., M, n)
    P_pred : ndarray, shape (..., M, n, n)
    F : ndarray, shape (..., M, n, n)
        Transition matrices or Jacobians (the smoother needs them).
    """
    parts = [predict_motion(m, x0[..., j, :], P0[..., j, :, :], dt) for j, m in enumerate(models)]
    x_pred = np.stack([part[0] for part in parts], axis=-2)
    P_pred = np.stack([part[1] for part in parts], axis=-3)
    F = np.stack([part[2] for part in parts], axis=-3)
    return x_pred, P_pred, F


def model_log_likelihoods(
    measurement: MeasurementModel, x_pred: FloatArray, P_pred: FloatArray, z: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Model likelihoods ``log Lambda_j = log N(nu_j; 0, S_j)`` of one detection.

    Parameters
    ----------
    measurement : MeasurementModel
    x_pred : ndarray, shape (..., M, n)
    P_pred : ndarray, shape (..., M, n, n)
    z : ndarray, shape (dz,) or broadcastable to (..., M, dz)

    Returns
    -------
    loglik : ndarray, shape (..., M)
    nu : ndarray, shape (..., M, dz)
    S : ndarray, shape (..., M, dz, dz)
    H : ndarray, shape (..., M, dz, n)
    """
    nu, S, H = innovation(measurement, x_pred, P_pred, np.asarray(z, dtype=float))
    return log_gaussian(nu, S), nu, S, H


def update_models(
    x_pred: FloatArray,
    P_pred: FloatArray,
    nu: FloatArray,
    S: FloatArray,
    H: FloatArray,
    R: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Model-matched Kalman updates (Joseph form), shapes ``(..., M, n)``, ``(..., M, n, n)``."""
    return update(x_pred, P_pred, nu, S, H, R)


def predictive_log_likelihood(log_c: FloatArray, loglik: FloatArray) -> FloatArray:
    """The track's predictive log-likelihood of a detection, ``log sum_j Lambda_j c_j``.

    Parameters
    ----------
    log_c : ndarray, shape (..., M)
        Log predicted model probabilities (:func:`mix`).
    loglik : ndarray, shape (..., M)
        Log model likelihoods (:func:`model_log_likelihoods`).

    Returns
    -------
    ndarray, shape (...)
    """
    return log_sum_exp(log_c + loglik, axis=-1)


def model_log_probabilities(log_c: FloatArray, loglik: FloatArray) -> FloatArray:
    """Log posterior model probabilities ``log(Lambda_j c_j / sum_l Lambda_l c_l)``, (..., M)."""
    joint = log_c + loglik
    return np.asarray(joint - log_sum_exp(joint, axis=-1)[..., None], dtype=np.float64)


def combine(log_mu: FloatArray, x: FloatArray, P: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The moment-matched single Gaussian of the model mixture (the IMM's output estimate).

    Parameters
    ----------
    log_mu : ndarray, shape (..., M)
    x : ndarray, shape (..., M, n)
    P : ndarray, shape (..., M, n, n)

    Returns
    -------
    mean : ndarray, shape (..., n)
    covariance : ndarray, shape (..., n, n)
    """
    mu = np.exp(log_mu)
    mean = np.einsum("...j,...jn->...n", mu, x)
    d = x - mean[..., None, :]
    cov = np.einsum("...j,...jnm->...nm", mu, P) + np.einsum("...j,...jn,...jm->...nm", mu, d, d)
    return mean, 0.5 * (cov + np.swapaxes(cov, -1, -2))


@dataclass(frozen=True, eq=False)
class IMMState:
    """Model probabilities and model-conditioned moments after a scan.

    Attributes
    ----------
    log_probabilities : ndarray, shape (..., M)
    means : ndarray, shape (..., M, n)
    covariances : ndarray, shape (..., M, n, n)
    """

    log_probabilities: FloatArray
    means: FloatArray
    covariances: FloatArray


@dataclass(frozen=True, eq=False)
class IMMPrediction:
    """An IMM state mixed and predicted to the next scan, before its detection (or miss).

    Attributes
    ----------
    log_predicted : ndarray, shape (..., M)
        Log predicted model probabilities ``log c_j``.
    means, covariances : ndarray, shapes (..., M, n), (..., M, n, n)
        Model-matched predictions.
    transitions : ndarray, shape (..., M, n, n)
    """

    log_predicted: FloatArray
    means: FloatArray
    covariances: FloatArray
    transitions: FloatArray


def imm_predict(
    state: IMMState, models: Sequence[MotionModel], Pi: FloatArray, dt: float
) -> IMMPrediction:
    """Mix and predict one IMM state over ``dt`` with switching matrix ``Pi`` (M, M)."""
    log_c, x0, P0 = mix(state.log_probabilities, state.means, state.covariances, Pi)
    x_pred, P_pred, F = predict_models(models, x0, P0, dt)
    return IMMPrediction(log_c, x_pred, P_pred, F)


def imm_update(
    prediction: IMMPrediction, measurement: MeasurementModel, z: FloatArray
) -> tuple[IMMState, FloatArray]:
    """Update a prediction with a detection ``z`` (dz,).

    Returns
    -------
    state : IMMState
    log_likelihood : ndarray, shape (...)
        The track's predictive log-likelihood of ``z`` (:func:`predictive_log_likelihood`).
    """
    loglik, nu, S, H = model_log_likelihoods(
        measurement, prediction.means, prediction.covariances, z
    )
    x, P = update_models(prediction.means, prediction.covariances, nu, S, H,
                         measurement.noise_covariance)  # fmt: skip
    log_mu = model_log_probabilities(prediction.log_predicted, loglik)
    return IMMState(log_mu, x, P), predictive_log_likelihood(prediction.log_predicted, loglik)


def imm_miss(prediction: IMMPrediction) -> IMMState:
    """The state after a scan without a detection: the prediction, ``mu_j = c_j``."""
    return IMMState(prediction.log_predicted, prediction.means, prediction.covariances)


@dataclass(frozen=True, eq=False)
class IMMRun:
    """An IMM filtering run over T scans (model axis M, state n).

    Attributes
    ----------
    times : ndarray, shape (T,)
    log_filtered : ndarray, shape (T, M)
        Log model probabilities after each scan.
    x_filtered, P_filtered : ndarray, shapes (T, M, n), (T, M, n, n)
    log_predicted : ndarray, shape (T, M)
        Log predicted model probabilities at each scan (entry 0: the prior's).
    log_likelihoods : ndarray, shape (T,)
        The predictive log-likelihood of each scan's detection (0 at a miss).
    """

    times: FloatArray
    log_filtered: FloatArray
    x_filtered: FloatArray
    P_filtered: FloatArray
    log_predicted: FloatArray
    log_likelihoods: FloatArray

    @property
    def log_likelihood(self) -> float:
        """The IMM's log-likelihood of all the detections (the sum over scans)."""
        return float(np.sum(self.log_likelihoods))


def _start(
    models: tuple[MotionModel, ...], x0: FloatArray, P0: FloatArray, log_mu0: FloatArray | None
) -> IMMPrediction:
    """The prior as a prediction at the first scan: every model starts from ``(x0, P0)``."""
    M, n = len(models), models[0].state_dim
    x = np.asarray(x0, dtype=float)
    P = np.asarray(P0, dtype=float)
    if x.shape != (n,) or P.shape != (n, n):
        raise InputError(f"x0 must be ({n},) and P0 ({n}, {n}), got {x.shape} and {P.shape}")
    cholesky(P, "prior covariance P0")
    log_mu = np.full(M, -math.log(M)) if log_mu0 is None else np.asarray(log_mu0, dtype=float)
    if log_mu.shape != (M,) or not np.isclose(log_sum_exp(log_mu), 0.0):
        raise InputError(f"log_mu0 must be ({M},) log-probabilities summing to 1, got {log_mu!r}")
    xs, Ps = np.broadcast_to(x, (M, n)).copy(), np.broadcast_to(P, (M, n, n)).copy()
    return IMMPrediction(log_mu, xs, Ps, np.broadcast_to(np.eye(n), (M, n, n)).copy())


def _unmoved(state: IMMState) -> IMMPrediction:
    """The prediction over no time: the state itself (no motion, no switching)."""
    n = state.means.shape[-1]
    eye = np.broadcast_to(np.eye(n), state.covariances.shape).copy()
    return IMMPrediction(state.log_probabilities, state.means, state.covariances, eye)


def imm_filter(
    models: Sequence[MotionModel],
    switching: SwitchingLaw,
    x0: FloatArray,
    P0: FloatArray,
    steps: Sequence[FilterStep],
    *,
    log_mu0: FloatArray | None = None,
) -> IMMRun:
    """Run the IMM filter over a sequence of detections and misses.

    As :func:`mapassoc.filtering.kalman.filter_sequence`: ``(x0, P0)`` is the prior at
    ``steps[0].time`` for every model (no motion before the first step).

    Parameters
    ----------
    models : sequence of M MotionModel
        Sharing one state space (:func:`check_models`).
    switching : SwitchingLaw
        For M models.
    x0 : ndarray, shape (n,)
    P0 : ndarray, shape (n, n)
    steps : sequence of FilterStep
        Non-decreasing times; a step at the time of the one before (two sensors scanning
        at once) neither moves nor switches the models.
    log_mu0 : ndarray, shape (M,), optional
        Log prior model probabilities (default uniform).
    """
    chosen = check_models(models)
    if not isinstance(switching, SwitchingLaw) or switching.n_models != len(chosen):
        raise InputError(f"switching must be a SwitchingLaw for {len(chosen)} models, got "
                         f"{switching!r}")  # fmt: skip
    if not steps:
        raise InputError("steps must contain at least one FilterStep")
    times = np.array([s.time for s in steps], dtype=float)
    if np.any(np.diff(times) < 0):
        raise InputError(f"steps must have non-decreasing times, got {times.tolist()}")
    prediction = _start(chosen, x0, P0, log_mu0)
    states: list[IMMState] = []
    predicted, logliks = [], []
    for k, step in enumerate(steps):
        if k:
            dt = float(times[k] - times[k - 1])
            prediction = (
                imm_predict(states[-1], chosen, switching.at(dt), dt)
                if dt > 0
                else _unmoved(states[-1])
            )
        predicted.append(prediction.log_predicted)
        if step.z is None:
            states.append(imm_miss(prediction))
            logliks.append(0.0)
            continue
        if step.measurement is None:
            raise InputError(f"step {k} has a detection but no measurement model")
        state, loglik = imm_update(prediction, step.measurement, step.z)
        states.append(state)
        logliks.append(float(loglik))
    return IMMRun(
        times=times,
        log_filtered=np.stack([s.log_probabilities for s in states]),
        x_filtered=np.stack([s.means for s in states]),
        P_filtered=np.stack([s.covariances for s in states]),
        log_predicted=np.stack(predicted),
        log_likelihoods=np.array(logliks),
    )


@dataclass(frozen=True, eq=False)
class IMMSmoothed:
    """Kim's smoothed IMM moments over T scans.

    Attributes
    ----------
    log_probabilities : ndarray, shape (T, M)
        Log smoothed model probabilities.
    x_models, P_models : ndarray, shapes (T, M, n), (T, M, n, n)
        Smoothed model-conditioned moments.
    x, P : ndarray, shapes (T, n), (T, n, n)
        Their moment-matched combination (the smoothed estimate).
    """

    log_probabilities: FloatArray
    x_models: FloatArray
    P_models: FloatArray
    x: FloatArray
    P: FloatArray


def _pair_step(
    models: tuple[MotionModel, ...],
    x_f: FloatArray,
    P_f: FloatArray,
    x_next: FloatArray,
    P_next: FloatArray,
    dt: float,
) -> tuple[FloatArray, FloatArray]:
    """RTS steps of every pair (i at k, j at k + 1): shapes (M_i, M_j, n), (M_i, M_j, n, n).

    Model i's filtered moments ``x_f[i]`` are predicted through model j; the gain
    ``G = P_f F_j^T P_pred^-1`` pulls them towards model j's smoothed ``x_next[j]``.
    """
    M, n = len(models), x_f.shape[-1]
    xs = np.empty((M, M, n))
    Ps = np.empty((M, M, n, n))
    for j, model in enumerate(models):
        x_pred, P_pred, F = predict_motion(model, x_f, P_f, dt)  # batch over i
        L = cholesky(P_pred, "predicted covariance of a model pair")
        B = F @ P_f  # (i, n, n) = F P_f, so G^T = P_pred^-1 F P_f
        Gt = np.linalg.solve(np.swapaxes(L, -1, -2), np.linalg.solve(L, B))
        G = np.swapaxes(Gt, -1, -2)
        xs[:, j] = x_f + np.einsum("inm,im->in", G, x_next[j] - x_pred)
        Ps[:, j] = P_f + G @ (P_next[j] - P_pred) @ Gt
    return xs, 0.5 * (Ps + np.swapaxes(Ps, -1, -2))


def imm_smooth(models: Sequence[MotionModel], switching: SwitchingLaw, run: IMMRun) -> IMMSmoothed:
    """Kim's fixed-interval smoother of an IMM run (module docstring).

    Parameters
    ----------
    models : sequence of M MotionModel
        Those of the run.
    switching : SwitchingLaw
        That of the run.
    run : IMMRun
    """
    chosen = check_models(models)
    T, M = run.log_filtered.shape
    log_s = run.log_filtered.copy()
    xs, Ps = run.x_filtered.copy(), run.P_filtered.copy()
    for k in range(T - 2, -1, -1):
        dt = float(run.times[k + 1] - run.times[k])
        if dt == 0:  # no motion and no switching between the two steps
            log_s[k], xs[k], Ps[k] = log_s[k + 1], xs[k + 1], Ps[k + 1]
            continue
        with np.errstate(divide="ignore"):
            log_Pi = np.log(switching.at(dt))
        # log Pi_ij + log mu^s_(k+1)(j) - log c_(k+1)(j): the backward weights of each pair.
        with np.errstate(invalid="ignore"):
            log_back = log_Pi + (log_s[k + 1] - run.log_predicted[k + 1])[None, :]
        log_back = np.where(np.isfinite(log_back), log_back, -np.inf)
        log_row = log_sum_exp(log_back, axis=1)  # (i,)
        log_s[k] = run.log_filtered[k] + log_row
        log_s[k] -= log_sum_exp(log_s[k])
        with np.errstate(invalid="ignore"):
            w = np.exp(log_back - log_row[:, None])  # (i, j), rows sum to 1
        w = np.where(np.isfinite(log_row)[:, None], w, 1.0 / M)
        pair_x, pair_P = _pair_step(chosen, run.x_filtered[k], run.P_filtered[k], xs[k + 1],
                                    Ps[k + 1], dt)  # fmt: skip
        xs[k] = np.einsum("ij,ijn->in", w, pair_x)
        d = pair_x - xs[k][:, None, :]
        Ps[k] = np.einsum("ij,ijnm->inm", w, pair_P) + np.einsum("ij,ijn,ijm->inm", w, d, d)
    x, P = combine(log_s, xs, Ps)
    return IMMSmoothed(log_s, xs, Ps, x, P)
