"""Exact data-association posteriors of the works the estimator follows, by full enumeration.

These functions enumerate *every* association and are the exact reference against
which the approximate (pruned, windowed, optimised) estimators are checked.  Their
cost grows combinatorially; use them on small problems only.  Each counts, exactly,
what it would enumerate before it starts (:func:`association_count`,
:func:`sequence_count`) and refuses more than ``limit`` terms
(:data:`ENUMERATION_LIMIT` unless raised), rather than allocating until memory runs out.

* :func:`enumerate_associations` and :func:`association_table`: the data association
  vectors theta of W. Afzal, "Track Association Problems in AD" (2022), section 5.2
  (eq. 18-20), and the object/clutter split of its Table 1.
* :func:`n_object_posterior`: the posterior of n objects with independent Gaussian
  priors after one scan (the n-object posterior of L. Svensson et al., "Multi-Object
  Tracking for Automotive Systems", Chalmers University of Technology).  For each theta
  the unnormalised weight is::

      w~_theta = (1 - Pd)^(#missed) * (Pd / lambda)^(#detected)
                 * prod_{i detected} N(z_theta_i; z^_i, S_i)

  (the combinatorial factors of the Poisson clutter cancel between the clutter's count
  and its ordering), normalised as ``w_theta = w~_theta / sum_theta' w~_theta'``, and every
  object's density given theta is its Kalman update with ``z_theta_i`` (prior when
  missed).
* :func:`single_object_sequences`: one object in clutter over several scans, one
  hypothesis per sequence of associations theta_1:k (single-object tracking in clutter,
  from the same course)::

      w~_theta_1:k = w~_theta_1:k-1 * (1 - Pd)                        if theta_k = 0
      w~_theta_1:k = w~_theta_1:k-1 * (Pd / lambda) N(z_theta_k; z^, S)  otherwise

Weights are carried in log space and normalised with a log-sum-exp.  A detection
probability of exactly 1 gives missed detections ``log 0 = -inf``, hence weight exactly
0, without numerical warnings.

Measurement indices follow those works: 1-based, with 0 meaning "missed".  The clutter
intensity lambda is per unit measurement volume (the course's two-object example uses
lambda = 0.3 per unit length on [-5, 5], not 0.3 / 10).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError
from mapassoc.filtering.kalman import innovation, log_gaussian, predict_motion, update
from mapassoc.models.measurement import MeasurementModel
from mapassoc.models.motion import MotionModel
from mapassoc.validation import (
    check_covariance,
    check_finite_array,
    check_integer,
    check_positive,
    check_probability,
    shown,
)

__all__ = [
    "AssociationRow",
    "ENUMERATION_LIMIT",
    "association_count",
    "sequence_count",
    "enumerate_associations",
    "association_table",
    "GaussianMixture",
    "NObjectPosterior",
    "n_object_posterior",
    "SequencePosterior",
    "single_object_sequences",
]


def _check_count(name: str, value: object) -> int:
    """Return ``value`` as an int after checking it is a non-negative integer."""
    return check_integer(name, value, minimum=0)


def _frozen(array: ArrayLike, dtype: type = float) -> NDArray:
    """A read-only copy of ``array`` (so that frozen dataclasses stay frozen)."""
    out: NDArray = np.array(array, dtype=dtype, copy=True)
    out.flags.writeable = False
    return out


ENUMERATION_LIMIT = 1_000_000
"""Most associations or sequences the exact references enumerate unless given a larger
``limit``: each holds a Python tuple and a mean and covariance per object, so a million
already take hundreds of megabytes."""


def association_count(num_objects: int, num_measurements: int) -> int:
    """The number of association vectors theta of n objects and m measurements:
    ``sum_k C(n, k) m! / (m - k)!`` over the number k of detected objects, exactly (a
    Python integer, however large)."""
    n = _check_count("num_objects", num_objects)
    m = _check_count("num_measurements", num_measurements)
    return sum(math.comb(n, k) * math.perm(m, k) for k in range(min(n, m) + 1))


def sequence_count(measurements_per_scan: Sequence[int]) -> int:
    """The number of association sequences of one object over scans of ``m_k``
    measurements: ``prod_k (m_k + 1)``, exactly (a Python integer)."""
    counts = [
        _check_count(f"measurements_per_scan[{k}]", m) for k, m in enumerate(measurements_per_scan)
    ]
    return math.prod(m + 1 for m in counts)


def _sizes_text(sizes: Sequence[int]) -> str:
    """``"5"`` when every scan has 5 measurements, else ``"3, 0, 7"``."""
    if len(set(sizes)) == 1:
        return str(sizes[0])
    return ", ".join(str(m) for m in sizes)


def _check_enumeration(what: str, count: int, limit: object) -> None:
    """Refuse to enumerate ``count`` terms past ``limit`` (checked, an integer >= 1)."""
    most = check_integer("limit", limit, minimum=1)
    if count > most:
        raise InputError(
            f"{what} would enumerate {count:,} terms, more than limit={most:,}; pass a "
            "larger limit to enumerate them anyway (memory grows with the count)"
        )


# --------------------------------------------------------------------------------------
# Association vectors (Afzal's survey, section 5.2)
# --------------------------------------------------------------------------------------


def enumerate_associations(
    num_objects: int, num_measurements: int, *, limit: int = ENUMERATION_LIMIT
) -> list[tuple[int, ...]]:
    """Every data association vector theta, in lexicographic order (Afzal's survey, eq. 18-20).

    ``theta[i]`` is 0 when object i is missed and ``j`` in ``1..m`` when it is
    associated with measurement j; no measurement index appears twice (point objects).
    The number of vectors is ``sum_k C(n, k) m! / (m - k)!`` over the number k of
    detected objects.

    Parameters
    ----------
    num_objects : int
        Number of objects n >= 0.
    num_measurements : int
        Number of measurements m >= 0.
    limit : int
        Most vectors to list (:data:`ENUMERATION_LIMIT` by default).

    Returns
    -------
    list of tuple of int
        Each tuple has length n.  ``n = 0`` gives ``[()]``.

    Raises
    ------
    InputError
        Bad counts, or more than ``limit`` vectors (:func:`association_count`).

    Examples
    --------
    >>> enumerate_associations(2, 2)
    [(0, 0), (0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)]
    """
    n = _check_count("num_objects", num_objects)
    m = _check_count("num_measurements", num_measurements)
    _check_enumeration(
        f"enumerate_associations(num_objects={n}, num_measurements={m})",
        association_count(n, m),
        limit,
    )
    out: list[tuple[int, ...]] = []
    prefix: list[int] = []
    used = [False] * (m + 1)

    def extend(depth: int) -> None:
        if depth == n:
            out.append(tuple(prefix))
            return
        for j in range(m + 1):
            if j > 0 and used[j]:
                continue
            prefix.append(j)
            used[j] = j > 0
            extend(depth + 1)
            used[j] = False
            prefix.pop()

    extend(0)
    return out


@dataclass(frozen=True)
class AssociationRow:
    """One row of Afzal's survey, Table 1: who generated which measurement under theta.

    Parameters
    ----------
    theta : tuple of int, length n
        The data association vector (0 = missed, j = measurement j, 1-based).
    object_measurements : tuple of (int or None), length n
        For each object, the 1-based index of its measurement, or ``None`` if missed
        (the columns O^1 ... O^n of Table 1).
    clutter_measurements : tuple of int
        1-based indices of the measurements not associated with any object, increasing
        (the column C).
    num_detected : int
        m^o, the number of detected objects.
    num_clutter : int
        m^c, the number of clutter measurements.
    """

    theta: tuple[int, ...]
    object_measurements: tuple[int | None, ...]
    clutter_measurements: tuple[int, ...]
    num_detected: int
    num_clutter: int


def association_table(theta: Sequence[int], num_measurements: int) -> AssociationRow:
    """The object and clutter measurements implied by theta (Afzal's survey, Table 1).

    Parameters
    ----------
    theta : sequence of int, length n
        Data association vector: entries in ``0..m``, non-zero entries distinct.
    num_measurements : int
        Number of measurements m >= 0.

    Returns
    -------
    AssociationRow

    Raises
    ------
    InputError
        An entry outside ``0..m``, not an integer, or a measurement used twice.
    """
    m = _check_count("num_measurements", num_measurements)
    entries = tuple(theta)
    for i, value in enumerate(entries):
        check_integer(f"theta[{i}] (0 = missed)", value, minimum=0, maximum=m)
    values = tuple(int(v) for v in entries)
    detected = [v for v in values if v > 0]
    if len(set(detected)) != len(detected):
        raise InputError(
            f"theta {values!r} associates one measurement with two objects; each "
            "measurement index may appear at most once"
        )
    object_measurements = tuple(None if v == 0 else v for v in values)
    clutter = tuple(j for j in range(1, m + 1) if j not in set(detected))
    return AssociationRow(
        theta=values,
        object_measurements=object_measurements,
        clutter_measurements=clutter,
        num_detected=len(detected),
        num_clutter=len(clutter),
    )


# --------------------------------------------------------------------------------------
# Gaussian mixtures
# --------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class GaussianMixture:
    """A normalised Gaussian mixture ``sum_c w_c N(x; mu_c, P_c)`` (Afzal's survey, Appendix A).

    Parameters
    ----------
    weights : ndarray, shape (C,)
        Non-negative, summing to 1 (components may have weight exactly 0).
    means : ndarray, shape (C, dx)
    covariances : ndarray, shape (C, dx, dx)
        Symmetric positive-definite.
    """

    weights: FloatArray
    means: FloatArray
    covariances: FloatArray

    def __post_init__(self) -> None:
        w = check_finite_array("weights", self.weights, shape=(None,))
        c = w.shape[0]
        if c == 0:
            raise InputError("a Gaussian mixture needs at least one component, got 0 weights")
        mu = check_finite_array("means", self.means, shape=(c, None))
        dx = mu.shape[1]
        cov = check_finite_array("covariances", self.covariances, shape=(c, dx, dx))
        if np.any(w < 0):
            raise InputError(f"weights must be non-negative, got {w.tolist()!r}")
        if abs(float(w.sum()) - 1.0) > 1e-9:
            raise InputError(f"weights must sum to 1, got sum {float(w.sum())!r}")
        for k in range(c):
            check_covariance(f"covariances[{k}]", cov[k], dim=dx)
        object.__setattr__(self, "weights", _frozen(w))
        object.__setattr__(self, "means", _frozen(mu))
        object.__setattr__(self, "covariances", _frozen(cov))

    @property
    def dim(self) -> int:
        """State dimension dx."""
        return int(self.means.shape[1])

    def merged(self) -> tuple[FloatArray, FloatArray]:
        """Moment-matched single Gaussian.

        Returns
        -------
        mean : ndarray, shape (dx,)
            ``sum_c w_c mu_c``.
        covariance : ndarray, shape (dx, dx)
            ``sum_c w_c (P_c + (mu_c - mean)(mu_c - mean)^T)``.
        """
        mean = self.weights @ self.means
        spread = self.means - mean
        cov = np.einsum("c,cij->ij", self.weights, self.covariances) + np.einsum(
            "c,ci,cj->ij", self.weights, spread, spread
        )
        return mean, 0.5 * (cov + cov.T)

    def pdf(self, x: ArrayLike) -> float | FloatArray:
        """Mixture density at one or many points.

        Parameters
        ----------
        x : array_like
            For ``dx == 1``: scalars of any shape ``(...)``.  For ``dx > 1``: points of
            shape ``(..., dx)``.

        Returns
        -------
        float or ndarray, shape (...)
            A float for a single point.
        """
        points = check_finite_array("x", x)
        dx = self.dim
        if dx == 1:
            points = points[..., None]
        elif points.ndim == 0 or points.shape[-1] != dx:
            raise InputError(f"x must have shape (..., {dx}), got shape {points.shape}")
        batch = points.shape[:-1]
        flat = points.reshape(-1, 1, dx)  # (N, 1, dx) against (C, dx)
        residual = flat - self.means[None, :, :]
        cov = np.broadcast_to(self.covariances, residual.shape[:2] + (dx, dx))
        densities = np.exp(log_gaussian(residual, cov))  # (N, C)
        values = (densities @ self.weights).reshape(batch)
        if values.ndim == 0:
            return float(values)
        return values


# --------------------------------------------------------------------------------------
# Shared numerics
# --------------------------------------------------------------------------------------


def _log_miss(detection_probability: float) -> float:
    """log(1 - Pd), exactly -inf for Pd == 1 (no warning)."""
    if detection_probability == 1.0:
        return -math.inf
    return math.log1p(-detection_probability)


def _normalise(log_weights: FloatArray, what: str) -> tuple[FloatArray, float]:
    """Normalised weights and log normaliser ``log sum exp(log_weights)``.

    Entries of -inf get weight exactly 0.  Raises if every entry is -inf.
    """
    top = float(np.max(log_weights))
    if top == -math.inf:
        raise InputError(
            f"every {what} has probability 0 (detection_probability is 1 and some object "
            "or scan has no measurement to explain it); the posterior is undefined"
        )
    scaled = np.exp(log_weights - top)  # -inf - finite = -inf, exp(-inf) = 0
    total = float(scaled.sum())
    return scaled / total, top + math.log(total)


def _check_model_dims(measurement_model: MeasurementModel, means: FloatArray) -> int:
    """Check the measurement model maps the states ``means`` (k, dx); return dz."""
    if not isinstance(measurement_model, MeasurementModel):
        raise InputError(
            "measurement_model must be a MeasurementModel (for example LinearMeasurement), "
            f"got {type(measurement_model).__name__}"
        )
    dz = int(measurement_model.measurement_dim)
    num_states, state_dim = means.shape
    expected = f"a Jacobian of shape ({dz}, {state_dim})"
    try:
        jac = np.asarray(measurement_model.jacobian(means))
    except (IndexError, ValueError) as exc:
        raise InputError(
            f"measurement_model does not fit states of length {state_dim}: expected "
            f"{expected}, but evaluating it failed ({exc})"
        ) from exc
    if jac.shape != (num_states, dz, state_dim):
        raise InputError(
            f"measurement_model does not fit states of length {state_dim}: expected "
            f"{expected}, got shape {jac.shape[1:]}"
        )
    return dz


def _all_updates(
    measurement_model: MeasurementModel,
    means: FloatArray,
    covs: FloatArray,
    measurements: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Kalman update of every prior against every measurement.

    Parameters
    ----------
    means : ndarray, shape (H, dx)
    covs : ndarray, shape (H, dx, dx)
    measurements : ndarray, shape (m, dz)

    Returns
    -------
    log_likelihood : ndarray, shape (H, m)
        ``log N(z_j; z^_h, S_h)`` (Afzal's survey, eq. 3).
    post_means : ndarray, shape (H, m, dx)
    post_covs : ndarray, shape (H, m, dx, dx)
    """
    num_priors, dx = means.shape
    m = measurements.shape[0]
    x = np.broadcast_to(means[:, None, :], (num_priors, m, dx))
    P = np.broadcast_to(covs[:, None, :, :], (num_priors, m, dx, dx))
    z = np.broadcast_to(measurements[None, :, :], (num_priors, m, measurements.shape[1]))
    nu, S, H = innovation(measurement_model, x, P, z)
    log_likelihood = log_gaussian(nu, S)
    post_means, post_covs = update(x, P, nu, S, H, measurement_model.noise_covariance)
    return log_likelihood, post_means, post_covs


# --------------------------------------------------------------------------------------
# n objects, one scan (the n-object posterior)
# --------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class NObjectPosterior:
    """Exact posterior of n objects after one scan: a mixture over associations (the
    n-object posterior).

    Parameters
    ----------
    associations : tuple of tuple of int, length A
        Every theta, in the order of :func:`enumerate_associations`.
    log_weights : ndarray, shape (A,)
        Unnormalised ``log w~_theta`` (-inf where the weight is exactly 0).
    weights : ndarray, shape (A,)
        Normalised weights ``w~_theta / sum w~``, summing to 1.
    log_normalizer : float
        ``log sum_theta w~_theta``.
    means : ndarray, shape (A, n, dx)
        Mean of each object given each theta (Kalman update, prior mean when missed).
    covariances : ndarray, shape (A, n, dx, dx)
        Covariance of each object given each theta.
    """

    associations: tuple[tuple[int, ...], ...]
    log_weights: FloatArray
    weights: FloatArray
    log_normalizer: float
    means: FloatArray
    covariances: FloatArray

    @property
    def num_objects(self) -> int:
        """Number of objects n."""
        return int(self.means.shape[1])

    def weight_of(self, theta: Sequence[int]) -> float:
        """Normalised weight of one association vector theta (0 = missed, 1-based)."""
        key = tuple(int(v) for v in theta)
        try:
            index = self.associations.index(key)
        except ValueError:
            raise InputError(
                f"theta {key!r} is not an association of this posterior "
                f"({self.num_objects} objects)"
            ) from None
        return float(self.weights[index])

    def marginal(self, i: int) -> GaussianMixture:
        """Marginal posterior of object i: one Gaussian component per theta (the n-object
        posterior).

        Parameters
        ----------
        i : int
            Object index, 0-based, in ``0..n-1``.

        Returns
        -------
        GaussianMixture
            Weights ``(A,)`` (the association weights), means ``(A, dx)``,
            covariances ``(A, dx, dx)``.
        """
        n = self.num_objects
        i = check_integer("object index i", i, minimum=0, maximum=n - 1)
        return GaussianMixture(
            weights=self.weights, means=self.means[:, i], covariances=self.covariances[:, i]
        )


def n_object_posterior(
    prior_means: ArrayLike,
    prior_covs: ArrayLike,
    measurements: ArrayLike,
    measurement_model: MeasurementModel,
    detection_probability: float,
    clutter_intensity: float,
    *,
    limit: int = ENUMERATION_LIMIT,
) -> NObjectPosterior:
    """Exact n-object posterior after one scan, enumerating every association.

    For each theta (Afzal's survey, eq. 18-20), the unnormalised weight is (the n-object
    posterior)::

        log w~_theta = #missed * log(1 - Pd) + #detected * log(Pd / lambda)
                       + sum_{i: theta_i > 0} log N(z_theta_i; z^_i, S_i)

    with ``z^_i, S_i`` the predicted measurement and innovation covariance of object i
    (Afzal's survey, section 4.3), and the normalised weight is ``w~_theta / sum w~``.  Given
    theta, object i has the Kalman-updated mean and covariance with ``z_theta_i`` if
    ``theta_i > 0`` and its prior otherwise.  Nonlinear measurement models give the
    extended-Kalman approximation of these quantities.

    Parameters
    ----------
    prior_means : array_like, shape (n, dx)
        Prior (predicted) means of the n objects.
    prior_covs : array_like, shape (n, dx, dx)
        Prior covariances, symmetric positive-definite.
    measurements : array_like, shape (m, dz)
        The scan; ``m`` may be 0 (pass an array of shape ``(0, dz)``).
    measurement_model : MeasurementModel
        For example :class:`~mapassoc.models.measurement.LinearMeasurement`.
    detection_probability : float
        Pd in (0, 1].
    clutter_intensity : float
        lambda > 0, false alarms per unit measurement volume.
    limit : int
        Most associations to enumerate (:data:`ENUMERATION_LIMIT` by default): past it
        the call refuses at once, naming the count (:func:`association_count`).

    Returns
    -------
    NObjectPosterior

    Raises
    ------
    InputError
        Bad shapes, Pd outside (0, 1], lambda <= 0, Pd == 1 with more objects than
        measurements (every association then has a miss of probability 0), or more
        than ``limit`` associations.
    NotPositiveDefiniteError
        A prior covariance that is not symmetric positive-definite.
    """
    pd = check_probability("detection_probability", detection_probability, allow_zero=False)
    lam = check_positive("clutter_intensity", clutter_intensity)
    means = check_finite_array("prior_means", prior_means, shape=(None, None))
    n, dx = means.shape
    covs = check_finite_array("prior_covs", prior_covs, shape=(n, dx, dx))
    for i in range(n):
        check_covariance(f"prior_covs[{i}]", covs[i], dim=dx)
    dz = _check_model_dims(measurement_model, means)
    z = check_finite_array("measurements", measurements, shape=(None, dz))
    m = z.shape[0]
    count = association_count(n, m)
    _check_enumeration(f"n_object_posterior with {n} objects and {m} measurements", count, limit)

    log_likelihood, post_means, post_covs = _all_updates(measurement_model, means, covs, z)

    # Per-object score of each choice: column 0 = missed, column j = measurement j.
    scores = np.empty((n, m + 1))
    scores[:, 0] = _log_miss(pd)
    scores[:, 1:] = math.log(pd) - math.log(lam) + log_likelihood
    cand_means = np.concatenate([means[:, None, :], post_means], axis=1)  # (n, m+1, dx)
    cand_covs = np.concatenate([covs[:, None], post_covs], axis=1)  # (n, m+1, dx, dx)

    associations = enumerate_associations(n, m, limit=max(count, 1))
    theta = np.array(associations, dtype=np.int64).reshape(len(associations), n)
    objects = np.arange(n)[None, :]
    log_w = scores[objects, theta].sum(axis=1)
    weights, log_normalizer = _normalise(log_w, "association")
    return NObjectPosterior(
        associations=tuple(associations),
        log_weights=_frozen(log_w),
        weights=_frozen(weights),
        log_normalizer=log_normalizer,
        means=_frozen(cand_means[objects, theta]),
        covariances=_frozen(cand_covs[objects, theta]),
    )


# --------------------------------------------------------------------------------------
# One object, several scans (single-object tracking in clutter)
# --------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class SequencePosterior:
    """Exact single-object posterior at the last scan, one term per association sequence.

    Parameters
    ----------
    sequences : tuple of tuple of int, length H
        Every sequence ``(theta_1, ..., theta_K)`` (0 = missed, j = measurement j of that
        scan, 1-based), in lexicographic order.
    log_weights : ndarray, shape (H,)
        Unnormalised ``log w~_theta_1:K`` (single-object tracking in clutter), -inf where exactly 0.
    weights : ndarray, shape (H,)
        Normalised weights, summing to 1.
    log_normalizer : float
        ``log sum w~``.
    means : ndarray, shape (H, dx)
        Posterior mean at the last scan given each sequence.
    covariances : ndarray, shape (H, dx, dx)
        Posterior covariance at the last scan given each sequence.
    """

    sequences: tuple[tuple[int, ...], ...]
    log_weights: FloatArray
    weights: FloatArray
    log_normalizer: float
    means: FloatArray
    covariances: FloatArray

    def weight_of(self, sequence: Sequence[int]) -> float:
        """Normalised weight of one association sequence."""
        key = tuple(int(v) for v in sequence)
        try:
            index = self.sequences.index(key)
        except ValueError:
            raise InputError(f"sequence {key!r} is not a hypothesis of this posterior") from None
        return float(self.weights[index])

    def mixture(self) -> GaussianMixture:
        """The posterior density at the last scan as a Gaussian mixture (one term per sequence)."""
        return GaussianMixture(weights=self.weights, means=self.means, covariances=self.covariances)


def single_object_sequences(
    prior_mean: ArrayLike,
    prior_cov: ArrayLike,
    scans: Sequence[ArrayLike],
    motion: MotionModel,
    measurement_model: MeasurementModel,
    detection_probability: float,
    clutter_intensity: float,
    dt: float = 1.0,
    *,
    limit: int = ENUMERATION_LIMIT,
) -> SequencePosterior:
    """Exact single-object tracking in clutter: every association sequence.

    The prior is the *predicted* density at the first scan (single-object tracking in
    clutter: "the prior mean at time 1 being 0.5").  Before every later scan each
    hypothesis is predicted through ``motion`` over ``dt``; then each hypothesis
    theta_1:k-1 spawns one child per theta_k in ``{0, 1..m_k}``::

        theta_k = 0:  log w~ += log(1 - Pd),  density = predicted density
        theta_k = j:  log w~ += log(Pd / lambda) + log N(z_j; z^, S),  Kalman update

    Unnormalised weights are the cumulative products; normalising them gives the same
    weights as the course's recursion on normalised parent weights.  The number of
    hypotheses is ``prod_k (m_k + 1)``.

    Parameters
    ----------
    prior_mean : array_like, shape (dx,)
        Predicted mean at the first scan.
    prior_cov : array_like, shape (dx, dx)
        Predicted covariance at the first scan, symmetric positive-definite.
    scans : sequence of array_like, each shape (m_k, dz)
        The measurements of each scan, at least one scan; ``m_k`` may be 0.
    motion : MotionModel
        For example ``RandomWalk(ndim=1, noise_intensity=0.35)``.
    measurement_model : MeasurementModel
    detection_probability : float
        Pd in (0, 1].
    clutter_intensity : float
        lambda > 0, false alarms per unit measurement volume.
    dt : float
        Interval between consecutive scans, > 0.
    limit : int
        Most sequences to enumerate (:data:`ENUMERATION_LIMIT` by default): past it the
        call refuses at once, naming the count (:func:`sequence_count`).

    Returns
    -------
    SequencePosterior

    Raises
    ------
    InputError
        Bad shapes, no scan, Pd outside (0, 1], lambda <= 0, dt <= 0, Pd == 1 with an
        empty scan (every sequence then has probability 0), or more than ``limit``
        sequences.
    NotPositiveDefiniteError
        A prior covariance that is not symmetric positive-definite.
    """
    pd = check_probability("detection_probability", detection_probability, allow_zero=False)
    lam = check_positive("clutter_intensity", clutter_intensity)
    step = check_positive("dt", dt)
    x0, P0, scan_arrays = _checked_single_object_inputs(
        prior_mean, prior_cov, scans, motion, measurement_model
    )
    sizes = [z.shape[0] for z in scan_arrays]
    _check_enumeration(
        f"single_object_sequences over {len(sizes)} scans of {_sizes_text(sizes)} measurements",
        sequence_count(sizes),
        limit,
    )

    sequences, log_w, means, covs = _grown_sequences(
        x0,
        P0,
        scan_arrays,
        motion,
        measurement_model,
        log_miss=_log_miss(pd),
        log_detect=math.log(pd) - math.log(lam),
        step=step,
    )
    weights, log_normalizer = _normalise(log_w, "association sequence")
    return SequencePosterior(
        sequences=tuple(sequences),
        log_weights=_frozen(log_w),
        weights=_frozen(weights),
        log_normalizer=log_normalizer,
        means=_frozen(means),
        covariances=_frozen(covs),
    )


def _checked_single_object_inputs(
    prior_mean: ArrayLike,
    prior_cov: ArrayLike,
    scans: Sequence[ArrayLike],
    motion: MotionModel,
    measurement_model: MeasurementModel,
) -> tuple[FloatArray, FloatArray, list[FloatArray]]:
    """The prior mean (dx,), prior covariance (dx, dx) and scans (each (m_k, dz)) of
    :func:`single_object_sequences` as checked arrays, refused (naming the argument)
    where the shapes, the motion model or the measurement model do not fit together
    or there is no scan."""
    x0 = check_finite_array("prior_mean", prior_mean, shape=(None,))
    dx = x0.shape[0]
    P0 = check_covariance("prior_cov", prior_cov, dim=dx)
    if not isinstance(motion, MotionModel):
        raise InputError(
            f"motion must be a MotionModel (for example RandomWalk), got {type(motion).__name__}"
        )
    if motion.state_dim != dx:
        raise InputError(
            f"motion has state dimension {motion.state_dim} but prior_mean has length {dx}"
        )
    dz = _check_model_dims(measurement_model, x0[None, :])
    if isinstance(scans, (str, bytes)) or not isinstance(scans, (Sequence, np.ndarray)):
        raise InputError(f"scans must be a sequence of (m_k, dz) arrays, got {shown(scans)}")
    scan_arrays = [
        check_finite_array(f"scans[{k}]", scan, shape=(None, dz)) for k, scan in enumerate(scans)
    ]
    if not scan_arrays:
        raise InputError("scans must contain at least one (m_k, dz) array, got none")
    return x0, P0, scan_arrays


def _grown_sequences(
    x0: FloatArray,
    P0: FloatArray,
    scan_arrays: list[FloatArray],
    motion: MotionModel,
    measurement_model: MeasurementModel,
    *,
    log_miss: float,
    log_detect: float,
    step: float,
) -> tuple[list[tuple[int, ...]], FloatArray, FloatArray, FloatArray]:
    """Every association sequence over ``scan_arrays`` with its unnormalised log
    weight (shape (N,)), posterior mean (N, dx) and covariance (N, dx, dx) at the last
    scan: each sequence's children are its miss (``log_miss``) and one Kalman update
    per measurement (``log_detect`` plus the measurement's log-likelihood), in that
    order, as :func:`single_object_sequences` states."""
    dx = x0.shape[0]
    sequences: list[tuple[int, ...]] = [()]
    log_w = np.zeros(1)
    means = x0[None, :]
    covs = P0[None, :, :]
    for k, z in enumerate(scan_arrays):
        if k > 0:
            means, covs, _ = predict_motion(motion, means, covs, step)
        m = z.shape[0]
        log_likelihood, post_means, post_covs = _all_updates(measurement_model, means, covs, z)
        child_log_w = np.empty((len(sequences), m + 1))
        child_log_w[:, 0] = log_w + log_miss
        child_log_w[:, 1:] = log_w[:, None] + log_detect + log_likelihood
        means = np.concatenate([means[:, None, :], post_means], axis=1).reshape(-1, dx)
        covs = np.concatenate([covs[:, None], post_covs], axis=1).reshape(-1, dx, dx)
        log_w = child_log_w.reshape(-1)
        sequences = [parent + (j,) for parent in sequences for j in range(m + 1)]
    return sequences, log_w, means, covs
