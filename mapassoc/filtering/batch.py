"""The batched filter interface: predict, innovation, gate, log-likelihood, update.

Every Kalman step of the package goes through :class:`KalmanFilter` and the
:class:`Innovation` it forms: the hypothesis trees (:mod:`mapassoc.estimator.hypotheses`),
the recording objective J (:mod:`mapassoc.estimator.objective`), the refinement's joins,
the smoother (:mod:`mapassoc.filtering.smoothing`) and the scan-by-scan trackers
(:mod:`mapassoc.filtering.track_filter`).  A detection's score is therefore computed by
one formula wherever it is asked for, and J of a recording no longer than one window is
the window's best objective by construction, not by agreement of two codes.

Equations (Afzal's survey, section 4.3):

* prediction ``x = f(x)``, ``P = F P F^T + Q``
  (:func:`~mapassoc.filtering.kalman.predicted_covariance`);
* innovation ``nu = z - h(x)`` and ``S = H P H^T + R``, formed once per predicted state
  (:func:`~mapassoc.filtering.kalman.innovation_covariance`), with ``S^-1`` and
  ``log det S``: closed forms for ``dz = 1, 2`` (the usual position and range-bearing
  measurements), a Cholesky factor otherwise;
* squared Mahalanobis distance ``d2 = nu^T S^-1 nu`` summed entry by entry over the
  ``dz (dz + 1) / 2`` entries of ``S^-1``, so that a pair's ``d2`` has the same bits
  whether it is computed alone, among all the pairs of a scan, or in a gate's strip;
* log-likelihood ``log N(nu; 0, S) = -0.5 (dz log 2 pi + log det S + d2)`` (Afzal's
  survey, eq. 3);
* gain ``K = P H^T S^-1`` and the Joseph-form covariance
  ``(I - K H) P (I - K H)^T + K R K^T``.

Batches: states ``(B, n)``, covariances ``(B, n, n)``.  An :class:`Innovation` holds one
measurement model's predicted measurements of a batch; a gated pair ``(row, detection)``
is scored and updated by its row of the batch.

A model *set* (:class:`~mapassoc.models.interacting.InteractingModels`) sits behind the
same calls, so the trees, J and the refinement run it without a second code path.  A
track in the set has one filter state of length ``M n + M`` (the model-conditioned
moments and log model probabilities, packed by
:func:`~mapassoc.models.interacting.pack_models`); a :class:`KalmanFilter` built with
the set (``KalmanFilter(motion=...)``) recognises such states by their length:

* :meth:`KalmanFilter.predict` mixes (:func:`mapassoc.filtering.imm.mix`) and predicts
  each model's moments with that model's own step;
* :meth:`KalmanFilter.innovation` forms each model's :class:`Innovation` and returns a
  :class:`MixtureInnovation`: its ``z_hat`` and ``S`` are the moment-matched mean and
  covariance of the predicted measurement mixture, which give the residual ``nu`` and
  the gate's ``d2`` (a chi-square gate on the mixture's first two moments, the usual
  IMM gate: the mixture is not Gaussian, so the gate probability ``P_G`` of the miss
  term is that of the moment-matched Gaussian, an approximation); its log-likelihood is
  the IMM's predictive likelihood ``log sum_j c_j N(nu_j; 0, S_j)`` (Blom and
  Bar-Shalom, 1988), each ``nu_j`` the detection's residual against model ``j``;
* :meth:`KalmanFilter.update` updates each model's moments with its own gain and the
  model probabilities by Bayes' rule (:func:`mapassoc.filtering.imm.model_log_probabilities`).

A set of identical models is therefore the single model, score for score (tested).

The compiled backend (:mod:`mapassoc.filtering.compiled`) runs the same algebra over a
recording's per-scan matrices; the numpy twin of its loops
(:mod:`mapassoc.filtering.scan_steps`) is written with the functions here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.errors import InputError
from mapassoc.filtering.compiled import imm_kernels
from mapassoc.filtering.imm import mix, model_log_probabilities
from mapassoc.filtering.kalman import (
    gaussian_terms,
    innovation_covariance,
    inverse_and_logdet,
    joseph_update,
    predicted_covariance,
    strip_gate,
)
from mapassoc.log_space import log_sum_exp
from mapassoc.models.interacting import InteractingModels, pack_models, unpack_models
from mapassoc.models.measurement import MeasurementModel
from mapassoc.models.motion import MotionModel

__all__ = ["DENSE_GATING_PAIRS", "GatedPairs", "Innovation", "KalmanFilter", "MixtureInnovation"]

DENSE_GATING_PAIRS = 4096
"""Above this many (row, detection) pairs, a linear measurement's gate first keeps the
detections in a strip around each prediction (:meth:`Innovation.gate`); the pairs and
their numbers are the same either way."""

_MOTION_CACHE_SIZE = 256
"""Most (model, time step) pairs whose F and Q a :class:`KalmanFilter` keeps."""


@dataclass(frozen=True, eq=False)
class GatedPairs:
    """The (row, detection) pairs inside a gate, sorted by row then detection.

    Attributes
    ----------
    row, detection : ndarray of int, shape (K,)
    nu : ndarray, shape (K, dz)
        Innovations (residuals wrapped by the measurement model).
    d2, loglik : ndarray, shape (K,)
    """

    row: IntArray
    detection: IntArray
    nu: FloatArray
    d2: FloatArray
    loglik: FloatArray

    def __len__(self) -> int:
        return int(self.row.shape[0])


@dataclass(frozen=True, eq=False)
class Innovation:
    """A batch of predicted states under one measurement model: the one place ``S`` is
    formed, with ``S^-1`` and ``log det S``.

    Attributes
    ----------
    measurement : MeasurementModel
    z_hat : ndarray, shape (B, dz)
        Predicted measurements ``h(x)``.
    H : ndarray, shape (B, dz, n)
        Measurement matrix or Jacobian at each predicted mean.
    S, S_inv : ndarray, shape (B, dz, dz)
    logdet : ndarray, shape (B,)
    """

    measurement: MeasurementModel
    z_hat: FloatArray
    H: FloatArray
    S: FloatArray
    S_inv: FloatArray
    logdet: FloatArray

    def __len__(self) -> int:
        return int(self.z_hat.shape[0])

    def residuals(self, Z: FloatArray, rows: IntArray | None = None) -> FloatArray:
        """``nu = z - h(x)`` (wrapped), of detection ``Z[k]`` against row ``rows[k]``
        (every row when ``rows`` is None: ``Z`` then broadcasts against the batch).

        Parameters
        ----------
        Z : ndarray, shape (K, dz) or (dz,)
        rows : ndarray of int, shape (K,), optional
        """
        z_hat = self.z_hat if rows is None else self.z_hat[rows]
        return np.asarray(self.measurement.residual(Z, z_hat), dtype=np.float64)

    def scores(self, nu: FloatArray, rows: IntArray | None = None) -> tuple[FloatArray, FloatArray]:
        """``d2`` and ``log N(nu; 0, S)`` of innovations ``nu`` of rows ``rows``
        (:func:`gaussian_terms`; every row in order when ``rows`` is None)."""
        if rows is None:
            return gaussian_terms(nu, self.S_inv, self.logdet)
        return gaussian_terms(nu, self.S_inv[rows], self.logdet[rows])

    def gate(self, Z: FloatArray, threshold: float) -> GatedPairs:
        """Every (row, detection) pair with ``d2 <= threshold``, scored.

        A linear measurement with a finite gate and more than :data:`DENSE_GATING_PAIRS`
        pairs keeps only the detections within ``r = sqrt(threshold lambda_max(S))`` of
        each prediction in every coordinate (a pair outside cannot pass:
        ``|nu| <= r`` follows from ``d2 <= threshold``), found on detections sorted
        along their widest coordinate; the others are all scored.  The kept pairs and
        their numbers are the same either way.

        Parameters
        ----------
        Z : ndarray, shape (M, dz)
        threshold : float
            Chi-square gate (``inf``: no gate).
        """
        B, M = len(self), Z.shape[0]
        if self.measurement.is_linear and math.isfinite(threshold) and B * M > DENSE_GATING_PAIRS:
            row, detection, nu, d2, loglik = strip_gate(
                self.z_hat, self.S, self.S_inv, self.logdet, Z, threshold
            )
            return GatedPairs(row, detection, nu, d2, loglik)
        nu_all = np.asarray(
            self.measurement.residual(Z[None, :, :], self.z_hat[:, None, :]), dtype=np.float64
        )
        d2_all, loglik_all = gaussian_terms(nu_all, self.S_inv[:, None], self.logdet[:, None])
        row, detection = np.nonzero(d2_all <= threshold)
        return GatedPairs(
            row.astype(np.int64),
            detection.astype(np.int64),
            nu_all[row, detection],
            d2_all[row, detection],
            loglik_all[row, detection],
        )


@dataclass(frozen=True, eq=False)
class MixtureInnovation(Innovation):
    """The predicted measurements of a batch of tracks in a model set (module docstring).

    ``z_hat``, ``S``, ``S_inv`` and ``logdet`` are the moment-matched mixture's (they
    give the residuals and the gate); ``H`` is the Jacobian of the mixture's ``z_hat``
    with respect to the filter state, ``[c_1 H_1, ..., c_M H_M, 0]``.

    Attributes
    ----------
    models : Innovation
        Every model's predicted measurements of the batch in one: its arrays have the
        leading axes ``(B, M)`` (``z_hat`` of shape ``(B, M, dz)``, ...), so each step
        is one numpy call for all the models rather than one per model.
    log_c : ndarray, shape (B, M)
        Log predicted model probabilities.
    """

    models: Innovation
    log_c: FloatArray

    def model_residuals(self, nu: FloatArray, rows: IntArray | None = None) -> FloatArray:
        """Each model's residual of the detections ``z_hat + nu`` (rows ``rows``).

        Parameters
        ----------
        nu : ndarray, shape (K, dz)
        rows : ndarray of int, shape (K,), optional

        Returns
        -------
        ndarray, shape (K, M, dz)
        """
        z_hat = self.z_hat if rows is None else self.z_hat[rows]
        return self.models.residuals((z_hat + nu)[..., None, :], rows)

    def model_scores(self, nu: FloatArray, rows: IntArray | None = None) -> FloatArray:
        """``log c_j + log N(nu_j; 0, S_j)`` of each model, shape ``nu.shape[:-1] + (M,)``."""
        log_c = self.log_c if rows is None else self.log_c[rows]
        return self.models.scores(self.model_residuals(nu, rows), rows)[1] + log_c

    def scores(self, nu: FloatArray, rows: IntArray | None = None) -> tuple[FloatArray, FloatArray]:
        """``d2`` against the mixture's moments and the IMM predictive log-likelihood."""
        d2, _ = super().scores(nu, rows)
        return d2, log_sum_exp(self.model_scores(nu, rows), axis=-1)

    def gate(self, Z: FloatArray, threshold: float) -> GatedPairs:
        """The pairs inside the mixture's gate, with the IMM predictive log-likelihood."""
        pairs = super().gate(Z, threshold)
        if len(pairs) == 0:
            return pairs
        _, loglik = self.scores(pairs.nu, pairs.row)
        return GatedPairs(pairs.row, pairs.detection, pairs.nu, pairs.d2, loglik)


def _mixture_innovation(
    models: Innovation, log_c: FloatArray, measurement: MeasurementModel
) -> MixtureInnovation:
    """The moment-matched predicted measurement of the models' innovations ``models``
    (arrays with leading axes ``(B, M)``)."""
    c = np.exp(log_c)  # (B, M)
    z_parts = models.z_hat  # (B, M, dz)
    z_hat = np.einsum("bj,bjd->bd", c, z_parts)
    d = np.asarray(measurement.residual(z_parts, z_hat[:, None, :]), dtype=np.float64)
    z_hat = z_hat + np.einsum("bj,bjd->bd", c, d)  # a wrapped angle's circular mean
    d = np.asarray(measurement.residual(z_parts, z_hat[:, None, :]), dtype=np.float64)
    B, M, dz, n = models.H.shape
    S = (c[:, None, :] @ models.S.reshape(B, M, dz * dz)).reshape(B, dz, dz)
    S = S + np.swapaxes(c[:, :, None] * d, 1, 2) @ d  # sum_j c_j d_j d_j^T
    S = 0.5 * (S + np.swapaxes(S, -1, -2))
    S_inv, logdet = inverse_and_logdet(S)
    weighted = np.swapaxes(c[:, :, None, None] * models.H, 1, 2).reshape(B, dz, M * n)
    H = np.concatenate([weighted, np.zeros((B, dz, M))], axis=2)
    return MixtureInnovation(measurement, z_hat, H, S, S_inv, logdet, models, log_c)


class KalmanFilter:
    """The Kalman / extended Kalman steps of a batch (module docstring).

    Holds nothing but a cache of linear models' ``(F, Q)`` per time step (a recording
    has few distinct steps, and the trees predict with them thousands of times).
    """

    def __init__(self, *, motion: MotionModel | None = None) -> None:
        self._motion: dict[tuple[int, float], tuple[MotionModel, FloatArray, FloatArray]] = {}
        self._switching: dict[float, FloatArray] = {}
        self._stacked: dict[float, tuple[InteractingModels, FloatArray, FloatArray]] = {}
        self.models = motion if isinstance(motion, InteractingModels) else None
        """The model set whose filter states :meth:`innovation` recognises, or None."""

    def linear_motion(self, model: MotionModel, dt: float) -> tuple[FloatArray, FloatArray] | None:
        """``(F(dt), Q(dt))`` of a linear model (cached), None for a nonlinear one."""
        if not model.is_linear:
            return None
        key = (id(model), float(dt))
        found = self._motion.get(key)
        if found is None or found[0] is not model:
            if len(self._motion) >= _MOTION_CACHE_SIZE:
                self._motion.clear()
            # A linear model's Jacobian is F(dt), wherever it is taken.
            F = np.asarray(model.jacobian(np.zeros(model.state_dim), float(dt)), dtype=np.float64)
            Q = np.asarray(model.process_noise(float(dt)), dtype=np.float64)
            found = self._motion[key] = (model, F, Q)
        return found[1], found[2]

    def predict(
        self, model: MotionModel, x: FloatArray, P: FloatArray, dt: float
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Predict a batch over ``dt > 0`` through ``model``.

        Parameters
        ----------
        model : MotionModel
        x : ndarray, shape (B, n)
        P : ndarray, shape (B, n, n)
        dt : float

        Returns
        -------
        x_pred : ndarray, shape (B, n)
        P_pred : ndarray, shape (B, n, n)
        F : ndarray, shape (n, n) or (B, n, n)
            The transition matrix (linear model) or each mean's Jacobian (EKF); empty,
            shape (0, 0), for a model set (mixing is not one linear map).
        """
        if isinstance(model, InteractingModels):
            return self._predict_set(model, x, P, dt)
        matrices = self.linear_motion(model, dt)
        if matrices is None:
            x = np.asarray(x, dtype=np.float64)
            F = model.jacobian(x, float(dt))
            x_new = model.transition(x, float(dt))
            return x_new, predicted_covariance(F, P, model.process_noise(float(dt))), F
        F, Q = matrices
        return x @ F.T, predicted_covariance(F, P, Q), F

    def innovation(self, measurement: MeasurementModel, x: FloatArray, P: FloatArray) -> Innovation:
        """The predicted measurements of a batch, ``S = H P H^T + R``, ``S^-1`` and
        ``log det S``.

        Parameters
        ----------
        measurement : MeasurementModel
        x : ndarray, shape (B, n)
        P : ndarray, shape (B, n, n)
        """
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 2 or P.shape != x.shape + x.shape[-1:]:
            raise InputError(f"x must be (B, n) and P (B, n, n), got {x.shape} and {P.shape}")
        if self.models is not None and x.shape[1] == self.models.filter_state_dim:
            log_c, xs, Ps = unpack_models(x, P, self.models.n_models)
            (B, M, n), dz = xs.shape, measurement.measurement_dim
            flat = self.innovation(measurement, xs.reshape(B * M, n), Ps.reshape(B * M, n, n))
            models = Innovation(
                measurement,
                flat.z_hat.reshape(B, M, dz),
                flat.H.reshape(B, M, dz, n),
                flat.S.reshape(B, M, dz, dz),
                flat.S_inv.reshape(B, M, dz, dz),
                flat.logdet.reshape(B, M),
            )
            return _mixture_innovation(models, log_c, measurement)
        H = np.asarray(measurement.jacobian(x), dtype=np.float64)
        S = innovation_covariance(H, P, measurement.noise_covariance)
        S_inv, logdet = inverse_and_logdet(S)
        return Innovation(measurement, measurement.predict(x), H, S, S_inv, logdet)

    def update(
        self,
        x: FloatArray,
        P: FloatArray,
        innovation: Innovation,
        rows: IntArray,
        nu: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:
        """Rows ``rows`` of the predicted batch updated by innovations ``nu``.

        Parameters
        ----------
        x : ndarray, shape (B, n)
        P : ndarray, shape (B, n, n)
            The batch ``innovation`` was formed from.
        innovation : Innovation
        rows : ndarray of int, shape (K,)
        nu : ndarray, shape (K, dz)

        Returns
        -------
        x_post : ndarray, shape (K, n)
        P_post : ndarray, shape (K, n, n)
        """
        if isinstance(innovation, MixtureInnovation):
            return self._update_set(x, P, innovation, rows, nu)
        return joseph_update(
            x[rows],
            P[rows],
            nu,
            innovation.S_inv[rows],
            innovation.H[rows],
            innovation.measurement.noise_covariance,
        )

    def _predict_set(
        self, models: InteractingModels, x: FloatArray, P: FloatArray, dt: float
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """IMM mixing, then each model's prediction of its mixed moments."""
        if x.shape[-1] != models.filter_state_dim:
            raise InputError(
                f"states of a set of {models.n_models} models must have length "
                f"{models.filter_state_dim}, got {x.shape}"
            )
        key = float(dt)
        stacked = self.stacked_motion(models, key)
        kernels = imm_kernels() if stacked is not None and x.ndim == 2 else None
        if kernels is not None and stacked is not None:  # the same steps, compiled
            x_new, P_new = kernels.predict_sets(
                np.ascontiguousarray(x, dtype=np.float64),
                np.ascontiguousarray(P, dtype=np.float64),
                *stacked, self.switching(models, key),
            )
            return x_new, P_new, np.zeros((0, 0))
        log_c, x0, P0 = mix(*unpack_models(x, P, models.n_models), self.switching(models, key))
        if stacked is not None:  # every model linear: one prediction for all of them
            F, Q = stacked
            xs = np.einsum("jab,...jb->...ja", F, x0)
            Ps = predicted_covariance(F, P0, Q)
        else:
            moved = [
                self.predict(model, x0[:, j], P0[:, j], dt)[:2]
                for j, model in enumerate(models.models)
            ]
            xs = np.stack([m[0] for m in moved], axis=1)
            Ps = np.stack([m[1] for m in moved], axis=1)
        x_new, P_new = pack_models(log_c, xs, Ps)
        return x_new, P_new, np.zeros((0, 0))

    def switching(self, models: InteractingModels, dt: float) -> FloatArray:
        """The set's switching matrix over ``dt > 0``, shape ``(M, M)`` (cached)."""
        key = float(dt)
        Pi = self._switching.get(key)
        if Pi is None or len(Pi) != models.n_models:
            if len(self._switching) >= _MOTION_CACHE_SIZE:
                self._switching.clear()
            Pi = self._switching[key] = models.switching.at(key)
        return Pi

    def stacked_motion(
        self, models: InteractingModels, dt: float
    ) -> tuple[FloatArray, FloatArray] | None:
        """Every model's ``(F(dt), Q(dt))`` stacked, shapes ``(M, n, n)``, or None when
        a model is nonlinear (cached with the models' own matrices)."""
        found = self._stacked.get(dt)
        if found is not None and found[0] is models:
            return found[1], found[2]
        matrices = [self.linear_motion(model, dt) for model in models.models]
        if any(m is None for m in matrices):
            return None
        if len(self._stacked) >= _MOTION_CACHE_SIZE:
            self._stacked.clear()
        F = np.stack([m[0] for m in matrices if m is not None])
        Q = np.stack([m[1] for m in matrices if m is not None])
        self._stacked[dt] = (models, F, Q)
        return F, Q

    def _update_set(
        self,
        x: FloatArray,
        P: FloatArray,
        innovation: MixtureInnovation,
        rows: IntArray,
        nu: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:
        """Each model's update with its own residual, and the model probabilities."""
        M = innovation.log_c.shape[1]
        _, xs, Ps = unpack_models(x[rows], P[rows], M)
        parts = innovation.models
        x_post, P_post = joseph_update(
            xs,
            Ps,
            innovation.model_residuals(nu, rows),
            parts.S_inv[rows],
            parts.H[rows],
            parts.measurement.noise_covariance,
        )
        log_mu = model_log_probabilities(
            innovation.log_c[rows], innovation.model_scores(nu, rows) - innovation.log_c[rows]
        )
        return pack_models(log_mu, x_post, P_post)
