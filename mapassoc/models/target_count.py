"""Priors on the number of targets K in a window, and estimators of K from its posterior.

A prior on K (``EstimatorSettings.k_prior``) is a :class:`CountLaw` registered in
:data:`COUNT_LAWS`; an estimator of K (``EstimatorSettings.k_estimate``) is a
:class:`KEstimator` registered in :data:`K_ESTIMATORS`.  Adding either is one class and
one registry entry here.  How a prior enters the posterior over K (Perry's MAP
formulation, eqs. 2-3 of :mod:`mapassoc.estimator.posterior`) and the posterior itself
(:class:`~mapassoc.estimator.posterior.KPosterior`) are the estimator's; the estimators
here read only what :class:`CountPosterior` names, so the settings that name them need
nothing above the models.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError
from mapassoc.models.population import MAX_KMAX, WindowPopulation, poisson_log_pmf
from mapassoc.validation import check_number, check_positive, shown

__all__ = [
    "COUNT_LAWS",
    "COUNT_PRIORS",
    "CountLaw",
    "BirthLaw",
    "UniformLaw",
    "PoissonLaw",
    "WeightsLaw",
    "CountPrior",
    "check_weights",
    "CountPosterior",
    "K_ESTIMATORS",
    "KEstimator",
    "MarginalK",
    "JointMapK",
    "MedianK",
]


class CountLaw:
    """A named prior law of the number of targets K (``EstimatorSettings.k_prior``).

    A new prior is one subclass with a ``name``, :meth:`log_prior` and, if it has
    parameters, :meth:`check`, registered in :data:`COUNT_LAWS`.
    """

    name: str = ""

    def check(self, prior: CountPrior) -> None:
        """Raise :class:`InputError` (with ``key``) if ``prior``'s parameters do not fit."""

    def log_prior(self, prior: CountPrior, population: WindowPopulation, top: int) -> FloatArray:
        """log pi(K) for K = 0..top (top <= kmax), up to an additive constant."""
        raise NotImplementedError

    def tail_step(
        self, prior: CountPrior, population: WindowPopulation, top: int, tracks: NDArray[np.int64]
    ) -> FloatArray | None:
        """An upper bound ``r_T``, for every K >= ``top`` and each track count T of
        ``tracks`` (all <= top), on the step ``W_T(K + 1) / W_T(K)`` of the term

            W_T(K) = pi(K) / p_birth(K) * Po(K - T; nu)

        of eq. (3) (the term of T without its mass); :func:`k_posterior` cuts the K
        range where the geometric tails these steps bound are negligible.  ``None``
        (the default, for a law that cannot bound it): the range is never cut, K runs
        to kmax.

        Every bound below uses the step of the birth law's p_birth = (sum of the carried
        Bernoullis) + Po(mu): with ``b_c`` the law of the Bernoulli sum,
        ``p_birth(K + 1) = sum_c b_c Po(K - c; mu) mu / (K + 1 - c) >= p_birth(K) mu /
        (K + 1)``, so ``p_birth(K) / p_birth(K + 1) <= (K + 1) / mu``; and the Poisson
        step ``Po(K + 1 - T; nu) / Po(K - T; nu) = nu / (K + 1 - T)``.
        """
        return None

    def log_ratio(self, prior: CountPrior, population: WindowPopulation, top: int) -> FloatArray:
        """``log pi(K) - log p_birth(K)`` for K = 0..top, up to a constant (eq. 2);
        ``-inf`` where either law gives K no probability."""
        law = self.log_prior(prior, population, top)
        birth = population.log_count_prior(top)
        possible = np.isfinite(law) & np.isfinite(birth)
        out = np.full(top + 1, -math.inf)
        out[possible] = law[possible] - birth[possible]
        return out


class BirthLaw(CountLaw):
    """The law the birth model implies (initial population, births, survival, carried
    tracks; :meth:`WindowPopulation.log_count_prior`), cut at kmax: no extra factor."""

    name = "birth"

    def log_prior(self, prior: CountPrior, population: WindowPopulation, top: int) -> FloatArray:
        return population.log_count_prior(top)

    def log_ratio(self, prior: CountPrior, population: WindowPopulation, top: int) -> FloatArray:
        return np.where(np.isfinite(population.log_count_prior(top)), 0.0, -math.inf)

    def tail_step(
        self, prior: CountPrior, population: WindowPopulation, top: int, tracks: NDArray[np.int64]
    ) -> FloatArray:
        """``nu / (top + 1 - T)``: W_T is the Poisson term alone, whose step
        ``nu / (K + 1 - T)`` falls with K."""
        return np.asarray(population.undetected_mean / (top + 1.0 - tracks), dtype=np.float64)


class UniformLaw(CountLaw):
    """Uniform on 0..kmax (Perry's MAP formulation)."""

    name = "uniform"

    def log_prior(self, prior: CountPrior, population: WindowPopulation, top: int) -> FloatArray:
        return np.zeros(top + 1)

    def tail_step(
        self, prior: CountPrior, population: WindowPopulation, top: int, tracks: NDArray[np.int64]
    ) -> FloatArray:
        """``q (top + 1) / (top + 1 - T)`` with ``q = nu / mu`` (< 1: the probability
        that a target of the window is never detected): the step is at most
        ``(K + 1) / mu * nu / (K + 1 - T)``, which falls with K.  With ``mu = 0`` the
        birth law gives no K beyond the carried tracks and ``nu = 0``: 0."""
        mu = population.new_target_mean
        if mu <= 0:
            return np.zeros(tracks.shape[0])
        q = population.undetected_mean / mu
        return np.asarray(q * (top + 1.0) / (top + 1.0 - tracks), dtype=np.float64)


class PoissonLaw(CountLaw):
    """Poisson with mean ``CountPrior.mean``, cut at kmax."""

    name = "poisson"

    def log_prior(self, prior: CountPrior, population: WindowPopulation, top: int) -> FloatArray:
        return poisson_log_pmf(np.arange(top + 1), prior.mean)

    def tail_step(
        self, prior: CountPrior, population: WindowPopulation, top: int, tracks: NDArray[np.int64]
    ) -> FloatArray:
        """``(mean / mu) nu / (top + 1 - T)``: the prior's step ``mean / (K + 1)`` times
        the birth law's inverse step, at most ``(K + 1) / mu``, times the Poisson step."""
        mu = population.new_target_mean
        if mu <= 0:
            return np.zeros(tracks.shape[0])
        step = prior.mean / mu * population.undetected_mean / (top + 1.0 - tracks)
        return np.asarray(step, dtype=np.float64)


class WeightsLaw(CountLaw):
    """Proportional to ``CountPrior.weights`` (kmax + 1 non-negative numbers)."""

    name = "weights"

    def check(self, prior: CountPrior) -> None:
        if len(prior.weights) != prior.kmax + 1:
            raise InputError(
                f"k_prior_weights must have max_tracks + 1 = {prior.kmax + 1} entries, "
                f"got {len(prior.weights)}",
                key="k_prior_weights",
            )
        for i, v in enumerate(prior.weights):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(
                    f"k_prior_weights[{i}] must be a number >= 0, got {v!r}",
                    key=f"k_prior_weights[{i}]",
                )
        if not any(v > 0 for v in prior.weights):
            raise InputError(
                "k_prior_weights must have at least one positive entry", key="k_prior_weights"
            )

    def log_prior(self, prior: CountPrior, population: WindowPopulation, top: int) -> FloatArray:
        with np.errstate(divide="ignore"):
            return np.log(np.asarray(prior.weights[: top + 1], dtype=float))


COUNT_LAWS: dict[str, CountLaw] = {
    law.name: law for law in (BirthLaw(), UniformLaw(), PoissonLaw(), WeightsLaw())
}
"""Priors on the number of targets by the name ``EstimatorSettings.k_prior`` uses."""

COUNT_PRIORS = tuple(COUNT_LAWS)
"""Their names."""


def check_weights(value: object) -> tuple[float, ...]:
    """``k_prior_weights`` as a tuple of floats: a list, tuple or 1-D array of numbers
    (their range is the ``"weights"`` law's to check); text, ``None`` or a single number
    is an InputError naming the field."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        raise InputError(
            f"k_prior_weights must be a list or tuple of numbers, got {shown(value)}",
            key="k_prior_weights",
        )
    return tuple(
        check_number(f"k_prior_weights[{i}]", v, key=f"k_prior_weights[{i}]")
        for i, v in enumerate(value)
    )


@dataclass(frozen=True)
class CountPrior:
    """The prior on the number K of targets present in a window, K = 0..kmax.

    Parameters
    ----------
    kind : str
        A name of :data:`COUNT_LAWS`: ``"birth"`` (the law the birth model implies),
        ``"uniform"`` (Perry's MAP formulation), ``"poisson"`` (mean ``mean``) or ``"weights"``.
    kmax : int
        Largest K, >= 0.
    mean : float
        Mean of the ``"poisson"`` prior, > 0.
    weights : tuple of float
        ``kmax + 1`` non-negative weights for ``"weights"``, not all 0.
    """

    kind: str = "birth"
    kmax: int = 20
    mean: float = 5.0
    weights: tuple[float, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if self.kind not in COUNT_LAWS:
            raise InputError(
                f"k_prior must be one of {tuple(COUNT_LAWS)}, got {self.kind!r}", key="k_prior"
            )
        if isinstance(self.kmax, bool) or not isinstance(self.kmax, int) or self.kmax < 0:
            raise InputError(
                f"max_tracks must be an integer >= 0, got {self.kmax!r}", key="max_tracks"
            )
        if self.kmax > MAX_KMAX:
            raise InputError(
                f"max_tracks must be at most 2**53 = {MAX_KMAX} (every K exact in double "
                f"precision), got {self.kmax!r}",
                key="max_tracks",
            )
        check_positive("k_prior_mean", self.mean, key="k_prior_mean")
        object.__setattr__(self, "weights", check_weights(self.weights))
        self.law.check(self)

    @property
    def law(self) -> CountLaw:
        """The registered law this prior names."""
        return COUNT_LAWS[self.kind]

    def log_prior(self, population: WindowPopulation, top: int) -> FloatArray:
        """log pi(K) for K = 0..top (top <= kmax), up to an additive constant."""
        return self.law.log_prior(self, population, top)

    def log_ratio(self, population: WindowPopulation, top: int) -> FloatArray:
        """``log pi(K) - log p_birth(K)`` for K = 0..top, up to a constant (eq. 2).

        ``-inf`` where either law gives K no probability.
        """
        return self.law.log_ratio(self, population, top)


class CountPosterior(Protocol):
    """What an estimator of K reads of a window's posterior over K
    (:class:`~mapassoc.estimator.posterior.KPosterior` has it all)."""

    @property
    def probabilities(self) -> FloatArray: ...

    @property
    def marginal_k(self) -> int: ...

    @property
    def marginal_tracks(self) -> int: ...

    @property
    def joint_map_k(self) -> int: ...

    @property
    def joint_map_tracks(self) -> int: ...

    def tracks_given(self, k: int) -> int: ...


class KEstimator:
    """An estimate of the number of targets K from a window's posterior, and the number
    of tracks T of the track set committed for it (``WindowEstimator.run``).

    A new estimator is one subclass with a ``name`` and :meth:`choose`, registered in
    :data:`K_ESTIMATORS`; ``EstimatorSettings.k_estimate`` names it.
    """

    name: str = ""

    def choose(self, posterior: CountPosterior) -> tuple[int, int]:
        """``(K, T)``: the estimate of K and the track count of the set to commit."""
        raise NotImplementedError


class MarginalK(KEstimator):
    """argmax p(K | Z) (Perry's MAP formulation: the track sets summed out), with the MAP set
    given K."""

    name = "marginal"

    def choose(self, posterior: CountPosterior) -> tuple[int, int]:
        return posterior.marginal_k, posterior.marginal_tracks


class JointMapK(KEstimator):
    """K and the track set of the joint MAP estimate of (K, track set) (Perry's MAP
    formulation, eq. 14)."""

    name = "joint"

    def choose(self, posterior: CountPosterior) -> tuple[int, int]:
        return posterior.joint_map_k, posterior.joint_map_tracks


class MedianK(KEstimator):
    """The posterior median of K (it minimises the expected absolute error ``|K - K_hat|``):
    the smallest K with p(K' <= K | Z) >= 1/2, with the MAP set given that K."""

    name = "median"

    def choose(self, posterior: CountPosterior) -> tuple[int, int]:
        cdf = np.cumsum(posterior.probabilities)
        k = int(np.searchsorted(cdf, 0.5 - 1e-12))
        return k, posterior.tracks_given(k)


K_ESTIMATORS: dict[str, KEstimator] = {e.name: e for e in (MarginalK(), JointMapK(), MedianK())}
"""Estimators of K by the name ``EstimatorSettings.k_estimate`` uses."""
