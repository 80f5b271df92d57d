"""The posterior over the number of tracks K in a window (seed 002).

With hypothesis scores that are log-likelihood ratios (``mapassoc.hypotheses``), the
window's per-K tables give, for K = 0..Kmax,

* ``best[K] = max over track sets with K tracks of sum of scores``, so that
  ``log p(K, track set | Z) = log p(K) + best[K] + const`` at the best set
  (seed 002, eqs. 8 and 14);
* ``log_mass[K] = log sum over track sets with K tracks of exp(sum of scores)``, so that
  ``p(K | Z) ∝ p(K) exp(log_mass[K])`` with the track sets summed out (seed 002,
  "Marginalization for Number of tracks").

The constant (all detections false alarms: ``prod_m e^(-lambda_bar) lambda^(m_m) / m_m!``)
is the same for every K and track set, so it cancels on normalising.  The joint MAP K
maximises ``log p(K) + best[K]``; the marginal estimate maximises ``p(K | Z)``; ties go
to the smaller K.  A K with no feasible track set gets probability exactly 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.errors import InputError

__all__ = ["KPosterior", "k_posterior", "PILE_UP_THRESHOLD"]

PILE_UP_THRESHOLD = 0.01
"""p(Kmax | Z) above this means Kmax probably cuts off the posterior."""


@dataclass(frozen=True, eq=False)
class KPosterior:
    """Posterior over K = 0..Kmax for one window.

    Attributes
    ----------
    log_prior : ndarray, shape (Kmax + 1,)
    best_log_score : ndarray, shape (Kmax + 1,)
        Best total score per K (``-inf`` where infeasible): the objective per K.
    log_mass : ndarray, shape (Kmax + 1,)
    probabilities : ndarray, shape (Kmax + 1,)
        p(K | Z); sums to 1.
    joint_map_k : int
        K of the joint MAP estimate of (K, track set).
    marginal_k : int
        argmax p(K | Z).
    exact : bool
        Whether ``log_mass`` summed every feasible track set.
    probabilities_lower, probabilities_upper : ndarray, shape (Kmax + 1,)
        Proven bounds on p(K | Z) from the mass bounds (equal to ``probabilities`` up to
        round-off when exact): with masses ``L_K <= M_K <= U_K`` and prior ``pi_K``,
        ``L_K pi_K / (L_K pi_K + sum_{j != K} U_j pi_j) <= p(K | Z) <=
        U_K pi_K / (U_K pi_K + sum_{j != K} L_j pi_j)``.
    marginal_certain : bool
        Whether ``marginal_k`` is proven to be argmax p(K | Z) (its lower bound beats
        every other K's upper bound, or everything is exact).
    joint_certain : bool
        Whether ``joint_map_k`` is proven to be the joint MAP K (likewise with the best
        scores and their upper bounds).
    """

    log_prior: NDArray[np.float64]
    best_log_score: NDArray[np.float64]
    log_mass: NDArray[np.float64]
    probabilities: NDArray[np.float64]
    joint_map_k: int
    marginal_k: int
    exact: bool
    probabilities_lower: NDArray[np.float64] | None = None
    probabilities_upper: NDArray[np.float64] | None = None
    marginal_certain: bool = True
    joint_certain: bool = True

    def __post_init__(self) -> None:
        for name in ("probabilities_lower", "probabilities_upper"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, self.probabilities)

    @property
    def max_tracks(self) -> int:
        return int(self.probabilities.shape[0]) - 1

    @property
    def piles_up_at_kmax(self) -> bool:
        """Whether p(Kmax | Z) exceeds :data:`PILE_UP_THRESHOLD` (raise Kmax)."""
        return bool(self.probabilities[-1] > PILE_UP_THRESHOLD) and self.max_tracks > 0

    @property
    def mean_k(self) -> float:
        return float(np.dot(np.arange(self.max_tracks + 1), self.probabilities))


def _argmax_first(values: NDArray[np.float64]) -> int:
    return int(np.flatnonzero(values == np.max(values))[0])


def _beats_others(lower: NDArray[np.float64], upper: NDArray[np.float64], k: int) -> bool:
    """Whether entry k's lower value is at least every other entry's upper value."""
    others = np.delete(upper, k)
    return bool(others.size == 0 or lower[k] >= np.max(others))


def _probability_bounds(
    lower: NDArray[np.float64], upper: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Bounds on normalised weights from log-weight bounds (see :class:`KPosterior`)."""
    top = float(np.max(upper))
    lo = np.exp(lower - top)
    hi = np.exp(upper - top)
    with np.errstate(invalid="ignore", divide="ignore"):
        p_lo = np.where(lo > 0, lo / (lo + (hi.sum() - hi)), 0.0)
        p_hi = np.where(hi > 0, hi / (hi + (lo.sum() - lo)), 0.0)
    return p_lo, np.minimum(p_hi, 1.0)


def k_posterior(
    best: NDArray[np.float64],
    log_mass: NDArray[np.float64],
    log_prior: NDArray[np.float64] | list[float],
    *,
    exact: bool = True,
    best_upper: NDArray[np.float64] | None = None,
    log_mass_upper: NDArray[np.float64] | None = None,
) -> KPosterior:
    """Combine per-K tables with the prior p(K).

    Parameters
    ----------
    best, log_mass : ndarray, shape (Kmax + 1,)
        Per-K best score and log-mass of the window (``log_mass`` a lower bound when
        not exact: the sets summed).
    log_prior : array_like, shape (Kmax + 1,)
        log p(K); ``-inf`` allowed.
    exact : bool
        Whether ``log_mass`` is exact.
    best_upper, log_mass_upper : ndarray, shape (Kmax + 1,), optional
        Proven upper bounds (default: ``best`` and ``log_mass``, i.e. exact).

    Raises
    ------
    InputError
        Shapes disagree, or no K has both a feasible track set and prior mass.
    """
    best = np.asarray(best, dtype=float)
    log_mass = np.asarray(log_mass, dtype=float)
    log_prior = np.asarray(log_prior, dtype=float)
    best_upper = best if best_upper is None else np.asarray(best_upper, dtype=float)
    mass_upper = log_mass if log_mass_upper is None else np.asarray(log_mass_upper, dtype=float)
    if (
        not (best.shape == log_mass.shape == log_prior.shape == best_upper.shape)
        or mass_upper.shape != best.shape
        or best.ndim != 1
    ):
        raise InputError(
            f"best, log_mass, log_prior and their bounds must be 1-D of one length, got "
            f"{best.shape}, {log_mass.shape}, {log_prior.shape}, {best_upper.shape}, "
            f"{mass_upper.shape}"
        )
    joint = log_prior + log_mass
    if not np.any(np.isfinite(joint)):
        raise InputError(
            "no K in 0..Kmax has a feasible track set with positive prior probability; "
            "raise max_tracks or check k_prior_weights"
        )
    top = np.max(joint)
    weights = np.exp(joint - top)  # exp(-inf) is exactly 0 for infeasible K
    probabilities = weights / weights.sum()
    joint_scores = log_prior + best
    joint_map_k = _argmax_first(joint_scores)
    marginal_k = _argmax_first(probabilities)
    joint_upper = log_prior + mass_upper
    p_lower, p_upper = _probability_bounds(joint, joint_upper)
    return KPosterior(
        log_prior=log_prior,
        best_log_score=best,
        log_mass=log_mass,
        probabilities=probabilities,
        joint_map_k=joint_map_k,
        marginal_k=marginal_k,
        exact=exact,
        probabilities_lower=p_lower,
        probabilities_upper=p_upper,
        marginal_certain=_beats_others(joint, joint_upper, marginal_k),
        joint_certain=_beats_others(joint_scores, log_prior + best_upper, joint_map_k),
    )


def log_sum_exp(values: NDArray[np.float64]) -> float:
    """Stable ``log sum exp(values)``; ``-inf`` for an empty or all ``-inf`` input."""
    values = np.asarray(values, dtype=float)
    if values.size == 0 or not np.any(np.isfinite(values)):
        return -math.inf
    top = float(np.max(values))
    return top + math.log(float(np.sum(np.exp(values - top))))
