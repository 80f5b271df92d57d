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

A model *set* (interacting multiple models) sits behind the same calls: each model of
the set is a :class:`KalmanFilter` step on the rows of that model (predict and update
per model), the mixing and the model probabilities of each node are carried beside the
states; nothing here assumes one motion model per batch beyond the ``model`` argument of
:meth:`KalmanFilter.predict`.

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
from mapassoc.filtering.kalman import (
    gaussian_terms,
    innovation_covariance,
    inverse_and_logdet,
    joseph_update,
    predicted_covariance,
    strip_gate,
)
from mapassoc.models.measurement import MeasurementModel
from mapassoc.models.motion import MotionModel

__all__ = ["DENSE_GATING_PAIRS", "GatedPairs", "Innovation", "KalmanFilter"]

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


class KalmanFilter:
    """The Kalman / extended Kalman steps of a batch (module docstring).

    Holds nothing but a cache of linear models' ``(F, Q)`` per time step (a recording
    has few distinct steps, and the trees predict with them thousands of times).
    """

    def __init__(self) -> None:
        self._motion: dict[tuple[int, float], tuple[MotionModel, FloatArray, FloatArray]] = {}

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
            The transition matrix (linear model) or each mean's Jacobian (EKF).
        """
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
        return joseph_update(
            x[rows],
            P[rows],
            nu,
            innovation.S_inv[rows],
            innovation.H[rows],
            innovation.measurement.noise_covariance,
        )
