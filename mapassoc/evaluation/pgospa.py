"""Probabilistic GOSPA (P-GOSPA): GOSPA for estimates that carry existence probabilities.

Xia, García-Fernández, Karlsson, Yuan, Chang and Svensson, "Probabilistic GOSPA: a metric for
performance evaluation of multi-object filters with uncertainties" (arXiv 2412.11482), extend
GOSPA (Rahmathullah, García-Fernández and Svensson, "Generalized optimal sub-pattern assignment
metric") to multi-Bernoulli densities.  With ``alpha = 2`` it is an optimisation over partial
assignments ``g`` between Bernoulli components ``(r_i, x_i)`` and ``(s_j, y_j)``::

    d^p = min_g [ sum_{(i,j) in g} ( min(r_i, s_j) ||x_i - y_j||^p + |r_i - s_j| c^p / 2 )
                  + (c^p / 2) ( sum_{i unassigned} r_i + sum_{j unassigned} s_j ) ]

The parts are the expected localisation error, the existence-probability mismatch, the expected
missed and the expected false detection error.  Here the single-object densities are points
(mapassoc reports a position per track), so the paper's Wasserstein base distance is the
Euclidean distance.  Truth points have ``r = 1`` unless told otherwise.

Assigning a pair instead of leaving both unassigned changes the cost by
``min(r, s) (||x - y||^p - c^p)`` (because ``|r - s| + 2 min(r, s) = r + s``), so an assigned
pair pays only when ``||x - y|| < c``.  A complete rectangular assignment of the costs
``min(r, s) min(||x - y||, c)^p + |r - s| c^p / 2 - (r + s) c^p / 2`` plus the constant
``(c^p / 2)(sum r + sum s)`` therefore attains the minimum, which
:func:`scipy.optimize.linear_sum_assignment` solves exactly, as :func:`gospa` does; pairs at
distance ``>= c`` are then counted unassigned.  With every ``r = s = 1`` this is GOSPA.

What the existence column buys: an estimate at distance ``d < c`` from a lone target costs
``r d^p + (1 - r) c^p / 2`` against ``c^p / 2`` for omitting it, and a false estimate costs
``r c^p / 2``.  If the estimate is a true target's with probability ``q``, the expected cost of
reporting it with ``r`` minus that of omitting it is ``r (q d^p + (1 - 2 q) c^p / 2)``: linear in
``r``, negative exactly when ``q > c^p / (2 (c^p - d^p))`` (``q > 1/2`` at ``d = 0``).  The metric
rewards a low ``r`` on doubtful tracks but, being linear in ``r``, is not a proper scoring rule:
the expected-cost optimum reports ``r = 1`` above that threshold and omits the track below it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import _check_point_set, _group_by_time
from mapassoc.evaluation.points import (
    TimedPoints,
    check_cost_powers,
    check_order,
    check_runs,
    float_array,
    readonly,
)
from mapassoc.validation import check_positive

__all__ = ["PgospaResult", "PgospaSeries", "pgospa", "pgospa_over_time"]


@dataclass(frozen=True, eq=False)
class PgospaResult:
    """P-GOSPA between truth points and estimates with existence probabilities, one time step.

    Parameters
    ----------
    total : float
        ``(localisation + existence_mismatch + missed + false)^(1/p)``.
    localisation : float
        Sum over assigned pairs of ``min(r, s) ||x - y||^p``.
    existence_mismatch : float
        Sum over assigned pairs of ``|r - s| c^p / 2``.
    missed : float
        ``(c^p / 2)`` times the summed existence of the unassigned truth points.
    false : float
        ``(c^p / 2)`` times the summed existence of the unassigned estimates.
    assignments : ndarray of int, shape (k, 2)
        ``(truth index, estimate index)`` of each assigned pair (distance ``< c``).
    """

    total: float
    localisation: float
    existence_mismatch: float
    missed: float
    false: float
    assignments: NDArray[np.int64]


@dataclass(frozen=True, eq=False)
class PgospaSeries:
    """P-GOSPA per evaluation time over a run.

    Parameters
    ----------
    times : ndarray, shape (T,)
        Sorted union of the distinct truth and estimate times.
    total, localisation, existence_mismatch, missed, false : ndarray, shape (T,)
        Per-time value and its p-th power parts (see :class:`PgospaResult`).
    c, p : float
        Cut-off and order used.
    """

    times: NDArray[np.float64]
    total: NDArray[np.float64]
    localisation: NDArray[np.float64]
    existence_mismatch: NDArray[np.float64]
    missed: NDArray[np.float64]
    false: NDArray[np.float64]
    c: float
    p: float

    @property
    def mean_total(self) -> float:
        """Mean over times of the per-time P-GOSPA values (not of their p-th powers)."""
        return float(np.mean(self.total))


def _pgospa_unchecked(
    truth: NDArray[np.float64],
    truth_existence: NDArray[np.float64],
    estimates: NDArray[np.float64],
    existence: NDArray[np.float64],
    c: float,
    p: float,
) -> PgospaResult:
    """P-GOSPA on validated arrays; see the module docstring for the padded assignment."""
    half = c**p / 2.0
    rows = cols = np.zeros(0, dtype=np.int64)
    if truth.shape[0] and estimates.shape[0]:
        distance = np.linalg.norm(truth[:, None, :] - estimates[None, :, :], axis=-1)
        low = np.minimum(truth_existence[:, None], existence[None, :])
        mismatch = np.abs(truth_existence[:, None] - existence[None, :]) * half
        unassigned = (truth_existence[:, None] + existence[None, :]) * half
        cost = low * np.minimum(distance, c) ** p + mismatch - unassigned
        rows, cols = linear_sum_assignment(cost)
        kept = distance[rows, cols] < c
        rows, cols = rows[kept], cols[kept]
        pair_distance = distance[rows, cols]
        localisation = float(np.sum(low[rows, cols] * pair_distance**p))
        existence_mismatch = float(np.sum(mismatch[rows, cols]))
    else:
        localisation = existence_mismatch = 0.0
    missed = half * float(np.sum(np.delete(truth_existence, rows)))
    false = half * float(np.sum(np.delete(existence, cols)))
    total = (localisation + existence_mismatch + missed + false) ** (1.0 / p)
    order = np.argsort(rows, kind="stable")
    assignments = np.stack([rows[order], cols[order]], axis=1).astype(np.int64).reshape(-1, 2)
    return PgospaResult(
        total=float(total),
        localisation=localisation,
        existence_mismatch=existence_mismatch,
        missed=missed,
        false=false,
        assignments=readonly(assignments),
    )


def _check_existence(name: str, value: ArrayLike, count: int) -> NDArray[np.float64]:
    arr = float_array(name, value)
    if arr.shape != (count,):
        raise InputError(f"{name} must have shape ({count},), one per point, got {arr.shape}")
    if np.any((arr < 0.0) | (arr > 1.0)):
        bad = int(np.flatnonzero((arr < 0.0) | (arr > 1.0))[0])
        raise InputError(f"{name} must lie in [0, 1], got {arr[bad]!r} at index {bad}")
    return arr


def _check_sets(truth: ArrayLike, estimates: ArrayLike) -> tuple[NDArray, NDArray]:
    truth_arr = _check_point_set("truth", truth)
    estimates_arr = _check_point_set("estimates", estimates)
    dim = next((a.shape[1] for a in (truth_arr, estimates_arr) if a.ndim == 2), 1)
    truth_arr = truth_arr.reshape(-1, dim) if truth_arr.ndim == 1 else truth_arr
    estimates_arr = estimates_arr.reshape(-1, dim) if estimates_arr.ndim == 1 else estimates_arr
    if truth_arr.shape[1] != estimates_arr.shape[1]:
        raise InputError(
            f"truth and estimates must have the same dimension d, got truth shape "
            f"{truth_arr.shape} and estimates shape {estimates_arr.shape}"
        )
    return truth_arr, estimates_arr


def pgospa(
    truth: ArrayLike,
    estimates: ArrayLike,
    existence: ArrayLike,
    *,
    c: float,
    p: float = 2.0,
    truth_existence: ArrayLike | None = None,
) -> PgospaResult:
    """P-GOSPA (alpha = 2) of Xia, García-Fernández, Karlsson, Yuan, Chang and Svensson at one
    time step, exact (see the module docstring).

    Parameters
    ----------
    truth : array_like, shape (n, d)
        True positions; an empty set as ``(0, d)`` or ``[]``.
    estimates : array_like, shape (m, d)
        Estimated positions, same ``d``.
    existence : array_like, shape (m,)
        Existence probability of each estimate, in [0, 1].
    c : float
        Cut-off distance, > 0.
    p : float
        Order, ``1 <= p < inf``.
    truth_existence : array_like, shape (n,), optional
        Existence probabilities of the truth side (default all 1).  Given, the function is the
        metric between two multi-Bernoulli sets of points, symmetric in its two sides.

    Returns
    -------
    PgospaResult

    Raises
    ------
    InputError
        Bad ``c`` or ``p``, non-finite values, wrong shapes, existence outside [0, 1].
    """
    cutoff = check_positive("c", c)
    order = check_order(p)
    check_cost_powers(order, c=cutoff)
    truth_arr, estimates_arr = _check_sets(truth, estimates)
    r_est = _check_existence("existence", existence, estimates_arr.shape[0])
    r_truth = (
        np.ones(truth_arr.shape[0])
        if truth_existence is None
        else _check_existence("truth_existence", truth_existence, truth_arr.shape[0])
    )
    return _pgospa_unchecked(truth_arr, r_truth, estimates_arr, r_est, cutoff, order)


def pgospa_over_time(
    truth: TimedPoints,
    estimates: TimedPoints,
    existence: ArrayLike,
    *,
    c: float,
    p: float = 2.0,
) -> PgospaSeries:
    """P-GOSPA at every evaluation time of a run, as :func:`gospa_over_time` evaluates GOSPA.

    Evaluation times are the sorted union of the distinct truth and estimate times (matched
    exactly); truth points have existence 1.

    Parameters
    ----------
    truth, estimates : TimedPoints
        The runs, same position dimension; at least one has a row.
    existence : array_like, shape (N,)
        Existence probability of each row of ``estimates``, in [0, 1].
    c : float
        Cut-off distance, > 0.
    p : float
        Order, ``1 <= p < inf``.

    Returns
    -------
    PgospaSeries
        Arrays of shape (T,).

    Raises
    ------
    InputError
        Bad ``c``, ``p`` or ``existence``, inputs that are not TimedPoints, different
        dimensions, or no rows at all.
    """
    cutoff = check_positive("c", c)
    order = check_order(p)
    check_cost_powers(order, c=cutoff)
    check_runs(truth, estimates)
    r_all = _check_existence("existence", existence, estimates.times.shape[0])
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    truth_at = _group_by_time(truth)
    results = []
    for t in times:
        here = estimates.times == t
        points = truth_at.get(float(t), np.zeros((0, truth.dim)))
        results.append(
            _pgospa_unchecked(
                points,
                np.ones(points.shape[0]),
                estimates.positions[here],
                r_all[here],
                cutoff,
                order,
            )
        )

    def parts(name: str) -> NDArray[np.float64]:
        return readonly(np.array([getattr(r, name) for r in results], dtype=float))

    return PgospaSeries(
        times=readonly(np.array(times, dtype=float)),
        total=parts("total"),
        localisation=parts("localisation"),
        existence_mismatch=parts("existence_mismatch"),
        missed=parts("missed"),
        false=parts("false"),
        c=cutoff,
        p=order,
    )
