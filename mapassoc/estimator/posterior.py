"""The posterior over the number of targets K in a window (Perry's MAP formulation), under a
named prior.

Perry's MAP formulation is R. Perry, "Time-Recursive Number-of-Tracks Estimation for ..."
(Proceedings of SPIE, 2000; Villanova University): the joint MAP estimate of the number of
tracks and the track set (its eq. 14), and the marginal over track sets for p(K | Z); the
documentation's references page gives what is confirmed of the citation.

The window's per-T tables (T the number of tracks of a track set: carried tracks
alive in the window plus tracks started in it) give, for T = 0..Kmax,

* ``best[T] = max over track sets with T tracks of sum of scores`` and
* ``log_mass[T] = log sum over those track sets of exp(sum of scores)``.

The scores are log-likelihood ratios under the birth model (``mapassoc.estimator.hypotheses``,
``docs/model.md`` sections 2-3), whose targets form a Poisson process: given the
data, the targets present in the window but never detected are Poisson with mean
``nu`` (:class:`~mapassoc.models.population.WindowPopulation`), independent of the track
set.  So under the birth model

    p_birth(K, omega | Z)  ∝  exp(score(omega)) Po(K - T(omega); nu)              (1)

with K the number of targets present in the window (T of them in tracks).  A named
prior ``pi(K)`` on the number of targets replaces the birth model's own law
``p_birth(K)`` of it (the birth model conditioned on K: K interchangeable targets):

    p(K, omega | Z)  ∝  pi(K) / p_birth(K) * exp(score(omega)) Po(K - T(omega); nu)  (2)

    p(K | Z)  ∝  pi(K) / p_birth(K) * sum_T exp(log_mass[T]) Po(K - T; nu).         (3)

For ``"birth"`` the ratio is 1.  Without carried tracks ``p_birth(K) = Po(K; mu)``
(``mu`` the expected number of targets in the window), and (2) becomes

    pi(K) K! / (K - T)! * mu^(-T) q^(K - T) * exp(score(omega))

with ``q = nu / mu`` the probability that a target of the window is never detected
((1 - Pd)^N when every target lives through the window): the ``K!/(K - T)!`` ways to
give T unlabelled tracks to K labelled targets and the ``(1 - Pd)`` of every missed
scan of the undetected ones (``docs/model.md`` section 4).

The joint MAP estimate maximises (2) over (K, omega): ``joint_map_k`` and the track
count ``joint_map_tracks`` of its set.  The marginal estimate maximises (3); the track
set committed for it is the MAP set given K (``marginal_tracks``, maximising
``best[T] + log Po(K - T; nu)``).  Ties go to the smaller K, then the smaller T.

The named priors (:class:`CountLaw` and its registry) and the estimators of K
(:class:`KEstimator`) live in :mod:`mapassoc.models.target_count`, below the data layer
that names them in its settings, and are re-exported here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError
from mapassoc.log_space import log_sum_exp
from mapassoc.models.population import MAX_KMAX, WindowPopulation, poisson_log_pmf
from mapassoc.models.target_count import (
    COUNT_LAWS,
    COUNT_PRIORS,
    K_ESTIMATORS,
    BirthLaw,
    CountLaw,
    CountPrior,
    JointMapK,
    KEstimator,
    MarginalK,
    MedianK,
    PoissonLaw,
    UniformLaw,
    WeightsLaw,
)
from mapassoc.validation import check_instance, check_numeric_array

__all__ = [
    "COUNT_LAWS",
    "COUNT_PRIORS",
    "CountLaw",
    "BirthLaw",
    "UniformLaw",
    "PoissonLaw",
    "WeightsLaw",
    "K_ESTIMATORS",
    "KEstimator",
    "MarginalK",
    "JointMapK",
    "MedianK",
    "CountPrior",
    "KPosterior",
    "k_posterior",
    "PILE_UP_THRESHOLD",
    "NEGLIGIBLE_LOG_RATIO",
    "MAX_KMAX",
    "FULL_LENGTH_KMAX",
    "MAX_K_RANGE",
]

PILE_UP_THRESHOLD = 0.01
"""p(Kmax | Z) above this means Kmax probably cuts off the posterior."""

NEGLIGIBLE_LOG_RATIO = 800.0
"""A K whose weight is this many nats below the largest is below double precision's
smallest number relative to it (e^-745): the posterior stops there (see
:func:`k_posterior`)."""



MAX_K_RANGE = 2**20
"""Most K values :func:`k_posterior` computes when Kmax is larger: a posterior that has
not provably ended by then (a prior with its mass far beyond the data, such as a
Poisson prior of mean 1e15, or a uniform prior when a target is almost never
detected) is refused with an :class:`InputError` naming ``max_tracks`` instead of
filling the memory.  A Kmax up to it is always computed in full if it must be."""

FULL_LENGTH_KMAX = 4096
"""Up to this Kmax the posterior's arrays have the full length Kmax + 1 (a few pages
of memory); beyond it they stop where the posterior provably ends (:func:`k_posterior`),
so their length is what the data and the prior reach, not Kmax."""

_BLOCK = 256
"""K values per block of the (T, K) weight matrix."""


@dataclass(frozen=True, eq=False)
class KPosterior:
    """Posterior over the number of targets K = 0..Kmax of one window.

    Every array has one length L <= Kmax + 1: L = Kmax + 1 up to Kmax =
    :data:`FULL_LENGTH_KMAX`, and beyond it L is the K (and T) range the posterior
    reaches to double precision (:func:`k_posterior` says where it stops and proves that
    every K left out has p(K | Z) < 1e-300).  An entry past the end is 0 (``-inf`` for
    the log-scores), so a huge Kmax costs no memory; :attr:`max_tracks` is Kmax itself.

    Attributes
    ----------
    best_log_score : ndarray, shape (L,)
        Best total score per number of tracks T (``-inf`` where infeasible).
    log_mass : ndarray, shape (L,)
        log of the summed weight of the track sets with T tracks.
    probabilities : ndarray, shape (L,)
        p(K | Z) over the number of targets present in the window; sums to 1.
    track_probabilities : ndarray, shape (L,)
        p(T | Z) over the number of tracks of the track set; sums to 1.
    joint_map_k, joint_map_tracks : int
        K and the track count T of the joint MAP estimate of (K, track set).
    marginal_k : int
        argmax p(K | Z).
    marginal_tracks : int
        Track count of the MAP track set given ``marginal_k`` targets.
    undetected_mean : float
        Expected number of targets in the window never detected (``nu``).
    count_prior : CountPrior
    exact : bool
        Whether ``log_mass`` summed every feasible track set.
    probabilities_lower, probabilities_upper : ndarray, shape (L,)
        Proven bounds on p(K | Z) from the mass bounds (equal to ``probabilities`` up to
        round-off when exact): with weights ``L_K <= W_K <= U_K`` (eq. 3 with the lower
        and upper masses; it is increasing in every mass),
        ``L_K / (L_K + sum_{j != K} U_j) <= p(K | Z) <= U_K / (U_K + sum_{j != K} L_j)``.
    max_tracks : int
        Kmax, the largest K of the prior's range (``p_k_length`` is Kmax + 1).
    marginal_certain : bool
        Whether ``marginal_k`` is proven to be argmax p(K | Z).
    joint_certain : bool
        Whether ``joint_map_k`` is proven to be the joint MAP K.
    """

    best_log_score: FloatArray
    log_mass: FloatArray
    probabilities: FloatArray
    track_probabilities: FloatArray
    joint_map_k: int
    joint_map_tracks: int
    marginal_k: int
    marginal_tracks: int
    undetected_mean: float
    count_prior: CountPrior
    exact: bool
    probabilities_lower: FloatArray
    probabilities_upper: FloatArray
    max_tracks: int
    marginal_certain: bool = True
    joint_certain: bool = True

    @property
    def piles_up_at_kmax(self) -> bool:
        """Whether p(Kmax | Z) exceeds :data:`PILE_UP_THRESHOLD` (raise Kmax)."""
        reaches_kmax = self.probabilities.shape[0] == self.max_tracks + 1
        return reaches_kmax and bool(self.probabilities[-1] > PILE_UP_THRESHOLD) and (
            self.max_tracks > 0
        )

    @property
    def mean_k(self) -> float:
        return float(np.dot(np.arange(self.probabilities.shape[0]), self.probabilities))

    def tracks_given(self, k: int) -> int:
        """T of the MAP track set given K = k targets: argmax over T <= k of
        ``best[T] + log Po(k - T; nu)`` (eq. 2; the prior's factor is the same for every
        T).  Ties go to the smaller T.

        Raises
        ------
        InputError
            When k is outside 0..Kmax or no track set has at most k tracks.
        """
        integer = isinstance(k, (int, np.integer)) and not isinstance(k, bool)
        if not integer or not 0 <= k <= self.max_tracks:
            raise InputError(f"k must be an integer in 0..{self.max_tracks}, got {k!r}")
        return _tracks_given(self.best_log_score, self.undetected_mean, int(k))


def _argmax_first(values: FloatArray) -> int:
    return int(np.flatnonzero(values == np.max(values))[0])


def _beats_others(lower: FloatArray, upper: FloatArray, k: int) -> bool:
    """Whether entry k's lower value is at least every other entry's upper value."""
    others = np.delete(upper, k)
    return bool(others.size == 0 or lower[k] >= np.max(others))


def _probability_bounds(lower: FloatArray, upper: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Bounds on normalised weights from log-weight bounds (see :class:`KPosterior`)."""
    top = float(np.max(upper))
    lo = np.exp(lower - top)
    hi = np.exp(upper - top)
    with np.errstate(invalid="ignore", divide="ignore"):
        p_lo = np.where(lo > 0, lo / (lo + (hi.sum() - hi)), 0.0)
        p_hi = np.where(hi > 0, hi / (hi + (lo.sum() - lo)), 0.0)
    return p_lo, np.minimum(p_hi, 1.0)


def _tracks_given(best: FloatArray, nu: float, k: int) -> int:
    """argmax over T <= k of ``best[T] + log Po(k - T; nu)`` (eq. 2), the smaller T on ties."""
    tracks = np.arange(min(k + 1, best.shape[0]), dtype=np.int64)
    scores = best[: tracks.shape[0]] + poisson_log_pmf(k - tracks, nu)
    if not np.any(np.isfinite(scores)):
        raise InputError(f"no track set of this window has at most {k} tracks")
    return _argmax_first(scores)


def _poisson_reach(nu: float) -> int:
    """Smallest u >= 1 with ``Po(u; nu)`` :data:`NEGLIGIBLE_LOG_RATIO` nats below the mode."""
    if nu <= 0:
        return 1
    mode = math.floor(nu)
    peak = mode * math.log(nu) - nu - math.lgamma(mode + 1)
    u = max(1, mode)
    while u * math.log(nu) - nu - math.lgamma(u + 1) > peak - NEGLIGIBLE_LOG_RATIO:
        u = 2 * u
    return u


@dataclass
class _Sweep:
    """Per-K reductions of the (T, K) weight matrix over K = 0..top."""

    mass_lower: FloatArray
    mass_upper: FloatArray
    joint: FloatArray
    joint_upper: FloatArray
    joint_tracks: NDArray[np.int64]
    tracks: FloatArray  # per T: log sum over K of the lower weights


def _relevant_rows(
    ratio: FloatArray,
    log_po: FloatArray,
    mass: FloatArray,
    mass_upper: FloatArray,
    best: FloatArray,
    best_upper: FloatArray,
) -> NDArray[np.int64]:
    """The track counts T whose terms can matter for some K <= top.

    Row T adds ``mass[T] + ratio(K) + log Po(K - T; nu)`` to column K >= T, at most
    ``mass_upper[T] + max_{K >= T} ratio(K) + max_u log Po(u; nu)``; and the largest
    column is at least ``mass[T'] + ratio(T') + log Po(0; nu)`` for every T'.  A row whose
    bound is :data:`NEGLIGIBLE_LOG_RATIO` below that is below double precision relative
    to the peak in every column, and a row whose best-score bound is below the joint
    peak's lower bound cannot hold the joint MAP: both kinds are left out.  (Clutter
    bursts make thousands of T reachable, nearly all of them hopeless.)
    """
    suffix = np.maximum.accumulate(ratio[::-1])[::-1][: mass.shape[0]]
    reach = suffix + float(np.max(log_po))
    here = ratio[: mass.shape[0]] + log_po[0]
    with np.errstate(invalid="ignore"):
        peak_mass = float(np.max(mass + here))
        peak_joint = float(np.max(best + here))
        keep = (mass_upper + reach >= peak_mass - NEGLIGIBLE_LOG_RATIO) | (
            best_upper + reach >= peak_joint
        )
    return np.flatnonzero(keep & np.isfinite(mass_upper)).astype(np.int64)


def _sweep(
    top: int,
    ratio: FloatArray,
    nu: float,
    mass: FloatArray,
    mass_upper: FloatArray,
    best: FloatArray,
    best_upper: FloatArray,
) -> _Sweep:
    n = top + 1
    log_po = poisson_log_pmf(np.arange(n, dtype=np.int64), nu)
    rows = _relevant_rows(ratio, log_po, mass, mass_upper, best, best_upper)
    out = _Sweep(
        np.full(n, -math.inf),
        np.full(n, -math.inf),
        np.full(n, -math.inf),
        np.full(n, -math.inf),
        np.zeros(n, dtype=np.int64),
        np.full(mass.shape[0], -math.inf),
    )
    if rows.size == 0:
        return out
    ts = rows[:, None]

    def weights(ks: NDArray[np.int64]) -> FloatArray:
        u = ks[None, :] - ts
        po = np.where(u >= 0, log_po[np.clip(u, 0, top)], -math.inf)
        return ratio[ks][None, :] + po  # (rows, block)

    m, mu, b, bu = mass[rows], mass_upper[rows], best[rows], best_upper[rows]
    tracks = np.full(rows.size, -math.inf)
    for k0 in range(int(rows[0]), n, _BLOCK):
        ks = np.arange(k0, min(n, k0 + _BLOCK), dtype=np.int64)
        weight = weights(ks)
        lower = m[:, None] + weight
        out.mass_lower[ks] = log_sum_exp(lower, axis=0)
        out.mass_upper[ks] = log_sum_exp(mu[:, None] + weight, axis=0)
        scored = b[:, None] + weight
        out.joint[ks] = np.max(scored, axis=0)
        out.joint_tracks[ks] = rows[np.argmax(scored, axis=0)]
        out.joint_upper[ks] = np.max(bu[:, None] + weight, axis=0)
        tracks = np.logaddexp(tracks, log_sum_exp(lower, axis=1))
    out.tracks[rows] = tracks
    return out


def _log_tail(values: FloatArray, steps: FloatArray) -> float:
    """log of ``sum_T exp(values[T]) r_T / (1 - r_T)``: the geometric tails beyond top of
    terms whose value at top is ``values`` and whose step is at most ``steps`` (``inf``
    where a live term's step is not below 1: no bound)."""
    live = np.isfinite(values)
    if not np.any(live):
        return -math.inf
    r = steps[live]
    if np.any(r >= 1.0) or np.any(~np.isfinite(r)):
        return math.inf
    with np.errstate(divide="ignore"):
        factor = np.log(r) - np.log1p(-r)
    return float(log_sum_exp(values[live] + factor))


def _tail_is_negligible(
    top: int,
    ratio: FloatArray,
    nu: float,
    steps: FloatArray | None,
    sweep: _Sweep,
    mass_upper: FloatArray,
    best_upper: FloatArray,
) -> bool:
    """Whether every K > top can be left out (the proof is in :func:`k_posterior`)."""
    if steps is None or not math.isfinite(ratio[top]):
        return False
    tracks = np.arange(mass_upper.shape[0], dtype=np.int64)
    at_top = ratio[top] + poisson_log_pmf(top - tracks, nu)
    with np.errstate(invalid="ignore"):
        mass_tail = _log_tail(mass_upper + at_top, steps)
        joint_tail = _log_tail(best_upper + at_top, steps)
    total = float(log_sum_exp(sweep.mass_lower))
    return mass_tail < total - NEGLIGIBLE_LOG_RATIO and joint_tail < float(np.max(sweep.joint))


def _range_error(prior: CountPrior, nu: float, top: int) -> InputError:
    """The error of a posterior that does not end within :data:`MAX_K_RANGE`."""
    return InputError(
        f"p(K | Z) under k_prior = {prior.kind!r} does not provably end before K = {top} "
        f"(max_tracks = {prior.kmax}, expected undetected targets nu = {nu!r}, "
        f"k_prior_mean = {prior.mean!r}): computing it further needs more than "
        f"{MAX_K_RANGE} values of K; lower max_tracks to at most {MAX_K_RANGE}, or choose "
        "a prior whose mass ends earlier",
        key="max_tracks",
    )


@dataclass(frozen=True, eq=False)
class _Tables:
    """A window's per-T tables, cut after the last track count with a feasible track set.

    Attributes
    ----------
    best, log_mass, best_upper, mass_upper : ndarray, shape (n_tracks,)
        Best score, log-mass and their proven upper bounds per T = 0..n_tracks-1.
    """

    best: FloatArray
    log_mass: FloatArray
    best_upper: FloatArray
    mass_upper: FloatArray

    @property
    def n_tracks(self) -> int:
        """Track counts kept: the largest feasible T plus one."""
        return int(self.best.shape[0])


def _window_tables(
    best: FloatArray,
    log_mass: FloatArray,
    best_upper: FloatArray | None,
    log_mass_upper: FloatArray | None,
    kmax: int,
) -> _Tables:
    """Check :func:`k_posterior`'s tables (shapes (T,), T <= kmax + 1) and cut them after
    the last feasible T."""
    best, log_mass, best_upper, mass_upper = _score_arrays(
        best, log_mass, best_upper, log_mass_upper
    )
    if (
        best.ndim != 1
        or not (best.shape == log_mass.shape == best_upper.shape == mass_upper.shape)
        or not 1 <= best.shape[0] <= kmax + 1
    ):
        raise InputError(
            f"best, log_mass and their bounds best_upper, log_mass_upper must be 1-D of one "
            f"length in 1..kmax + 1 = {kmax + 1}, got shapes {best.shape}, {log_mass.shape}, "
            f"{best_upper.shape}, {mass_upper.shape}"
        )
    reachable = np.flatnonzero(np.isfinite(mass_upper))
    if reachable.size == 0:
        raise InputError("the window has no feasible track set for any number of tracks")
    n_tracks = int(reachable[-1]) + 1
    return _Tables(
        best=best[:n_tracks],
        log_mass=log_mass[:n_tracks],
        best_upper=best_upper[:n_tracks],
        mass_upper=mass_upper[:n_tracks],
    )


def _first_top(prior: CountPrior, population: WindowPopulation, tables: _Tables) -> int:
    """The first K range 0..top to compute (:func:`k_posterior`): kmax when the prior
    bounds no step, else the largest T plus the Poisson reach of ``nu``.

    Raises the range error at once when kmax is beyond :data:`MAX_K_RANGE` and the
    posterior cannot end within it.
    """
    kmax = prior.kmax
    tracks_range = np.arange(tables.n_tracks, dtype=np.int64)
    if prior.law.tail_step(prior, population, tables.n_tracks - 1, tracks_range) is None:
        top = kmax
    else:
        top = min(kmax, tables.n_tracks - 1 + _poisson_reach(population.undetected_mean))
    no_births = population.new_target_mean <= 0
    if kmax > MAX_K_RANGE and not no_births:
        # Every step bound falls with K: one not below 1 at MAX_K_RANGE is not below 1
        # anywhere before it, so the tail cannot be bounded in range (fail at once).
        far = prior.law.tail_step(prior, population, MAX_K_RANGE, tracks_range)
        if far is not None and np.any(far[np.isfinite(tables.mass_upper)] >= 1.0):
            raise _range_error(prior, population.undetected_mean, MAX_K_RANGE)
    return top


def _sweep_to_end(
    prior: CountPrior, population: WindowPopulation, tables: _Tables, top: int
) -> tuple[int, _Sweep]:
    """Sweep K = 0..top, doubling top until every K beyond is negligible or top is kmax
    (or, without births, covers the carried tracks); returns the final top and sweep."""
    kmax, nu = prior.kmax, population.undetected_mean
    tracks_range = np.arange(tables.n_tracks, dtype=np.int64)
    no_births = population.new_target_mean <= 0
    while True:
        ratio = prior.log_ratio(population, top)
        sweep = _sweep(
            top, ratio, nu, tables.log_mass, tables.mass_upper, tables.best, tables.best_upper
        )
        if top == kmax or (no_births and top >= population.carried_alive.size):
            return top, sweep
        steps = prior.law.tail_step(prior, population, top, tracks_range)
        if _tail_is_negligible(top, ratio, nu, steps, sweep, tables.mass_upper, tables.best_upper):
            return top, sweep
        grown = min(kmax, 2 * top + 1)
        if grown > MAX_K_RANGE:
            raise _range_error(prior, nu, top)
        top = grown


def _padded(values: FloatArray, length: int, fill: float) -> FloatArray:
    """``values`` followed by ``fill`` up to ``length``, shape (length,)."""
    out = np.full(length, fill)
    out[: values.shape[0]] = values
    return out


def _normalised(log_weights: FloatArray) -> FloatArray:
    """``exp(log_weights)`` normalised to sum 1, same shape."""
    weights = np.exp(log_weights - np.max(log_weights))
    return weights / weights.sum()


def _posterior(
    tables: _Tables,
    sweep: _Sweep,
    top: int,
    *,
    prior: CountPrior,
    population: WindowPopulation,
    exact: bool,
) -> KPosterior:
    """The :class:`KPosterior` of a sweep over K = 0..top, its arrays padded to the
    length L (module and class docstrings)."""
    kmax, nu = prior.kmax, population.undetected_mean
    joint = sweep.mass_lower
    length = max(top, min(kmax, FULL_LENGTH_KMAX)) + 1
    probabilities = _padded(_normalised(joint), length, 0.0)
    p_lower_part, p_upper_part = _probability_bounds(joint, sweep.mass_upper)
    marginal_k = _argmax_first(probabilities)
    joint_map_k = _argmax_first(sweep.joint)
    return KPosterior(
        best_log_score=_padded(tables.best, length, -math.inf),
        log_mass=_padded(tables.log_mass, length, -math.inf),
        probabilities=probabilities,
        track_probabilities=_padded(_normalised(sweep.tracks), length, 0.0),
        joint_map_k=joint_map_k,
        joint_map_tracks=int(sweep.joint_tracks[joint_map_k]),
        marginal_k=marginal_k,
        marginal_tracks=_tracks_given(tables.best, nu, marginal_k),
        undetected_mean=nu,
        count_prior=prior,
        exact=exact,
        probabilities_lower=_padded(p_lower_part, length, 0.0),
        probabilities_upper=_padded(p_upper_part, length, 0.0),
        max_tracks=kmax,
        marginal_certain=_beats_others(joint, sweep.mass_upper, marginal_k),
        joint_certain=_beats_others(sweep.joint, sweep.joint_upper, joint_map_k),
    )


def _score_arrays(
    best: ArrayLike,
    log_mass: ArrayLike,
    best_upper: ArrayLike | None,
    log_mass_upper: ArrayLike | None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """:func:`k_posterior`'s four arrays as floats (a bound left None: the value itself)."""
    lower = check_numeric_array("best", best), check_numeric_array("log_mass", log_mass)
    upper = [
        low if value is None else check_numeric_array(name, value)
        for name, value, low in (
            ("best_upper", best_upper, lower[0]),
            ("log_mass_upper", log_mass_upper, lower[1]),
        )
    ]
    return lower[0], lower[1], upper[0], upper[1]


def k_posterior(
    best: FloatArray,
    log_mass: FloatArray,
    *,
    prior: CountPrior,
    population: WindowPopulation,
    exact: bool = True,
    best_upper: FloatArray | None = None,
    log_mass_upper: FloatArray | None = None,
) -> KPosterior:
    """p(K | Z), the joint MAP and the marginal estimates (eqs. 2-3 of the module).

    The K range is 0..kmax, but the weights are computed only up to the K where the
    posterior provably ends to double precision, and beyond :data:`FULL_LENGTH_KMAX` the
    arrays returned stop there too (``KPosterior.max_tracks`` is still kmax), so a huge
    kmax costs nothing: the work and memory are those of the K the data and the prior
    can reach.  Track counts whose terms cannot reach that precision for any K
    are skipped likewise (:func:`_relevant_rows`).

    **Where the K range is cut.**  Write eq. (3) as ``W(K) = sum_T m_T W_T(K)`` with
    ``m_T = exp(log_mass_upper[T])`` and ``W_T(K) = pi(K) / p_birth(K) Po(K - T; nu)``.
    The weights are computed for K = 0..top, with top grown by doubling from
    ``T_max + u`` (``u``: the Poisson reach of ``nu``, :func:`_poisson_reach`), and
    the K > top are left out once

    1. the prior's law bounds the steps: ``W_T(K + 1) <= r_T W_T(K)`` for every
       K >= top with ``r_T < 1`` (:meth:`CountLaw.tail_step`: ``nu / (top + 1 - T)``
       for ``"birth"``, ``q (top + 1) / (top + 1 - T)`` with ``q = nu / mu < 1`` for
       ``"uniform"``, ``(mean / mu) nu / (top + 1 - T)`` for ``"poisson"``; the
       ``"weights"`` prior gives none, so it always runs to kmax), and
       ``p_birth(top) > 0`` (then ``p_birth(K) > 0`` for every K >= top);
    2. the geometric tails they imply,
       ``sum_{K > top} W(K) <= sum_T m_T W_T(top) r_T / (1 - r_T)``,
       are :data:`NEGLIGIBLE_LOG_RATIO` (800) nats below the summed weight of 0..top,
       i.e. below ``e^-800 < 1e-347`` of the total: every left-out p(K | Z), and their
       sum, is below 1e-300, and the kept ones are exact to that relative precision;
    3. the same bound with the best scores (a maximum is at most the sum) is below the
       joint MAP's weight within 0..top, so the joint MAP K is not in the tail.

    With ``mu = 0`` (no births, no initial targets) the birth law gives no K beyond the
    carried tracks C, and the range stops at C exactly.  A range that would grow past
    :data:`MAX_K_RANGE` without ending is refused (InputError, key ``max_tracks``).

    Parameters
    ----------
    best, log_mass : ndarray, shape (T,)
        Per track count T = 0..T-1 (T <= kmax + 1): best score and log-mass of the window
        (``log_mass`` a lower bound when not exact: the sets summed).
    prior : CountPrior
    population : WindowPopulation
        The window's undetected-target mean and the birth model's law of K.
    exact : bool
        Whether ``log_mass`` is exact.
    best_upper, log_mass_upper : ndarray, shape (T,), optional
        Proven upper bounds (default: ``best`` and ``log_mass``, i.e. exact).

    Raises
    ------
    InputError
        Shapes disagree, or no K has both a feasible track set and prior mass.
    """
    check_instance("k_posterior: prior", prior, CountPrior)
    check_instance("k_posterior: population", population, WindowPopulation)
    check_instance("k_posterior: exact", exact, (bool, np.bool_), expected="True or False")
    tables = _window_tables(best, log_mass, best_upper, log_mass_upper, prior.kmax)
    top = _first_top(prior, population, tables)
    top, sweep = _sweep_to_end(prior, population, tables, top)
    if not np.any(np.isfinite(sweep.mass_lower)):
        raise InputError(
            "no K in 0..Kmax has a feasible track set with positive prior probability; "
            "raise max_tracks or check k_prior_weights"
        )
    return _posterior(tables, sweep, top, prior=prior, population=population, exact=exact)
