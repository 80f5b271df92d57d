"""OSPA per time and the trajectory metric OSPA(2).

OSPA (Schuhmacher, Vo and Vo, "A consistent metric for performance evaluation of multi-object
filters", IEEE Trans. Signal Processing 56(8), 2008, Definition 3) between finite sets
``X = {x_1..x_m}`` and ``Y = {y_1..y_n}`` with ``m <= n`` (swap them otherwise), cut-off
``c > 0`` and order ``1 <= p < inf`` is::

    d_p^(c)(X, Y) = ( (1/n) [ min_pi sum_{i=1}^m d^(c)(x_i, y_pi(i))^p + c^p (n - m) ] )^(1/p)

with ``d^(c)(x, y) = min(c, ||x - y||)`` and ``pi`` ranging over the injections of
``{1..m}`` into ``{1..n}``; ``d = 0`` when both sets are empty.  Its localisation and
cardinality components (Schuhmacher et al., eqs. (3.1)-(3.2)) are kept here as the two
p-th power parts ``localisation = (1/n) min_pi sum d^(c)^p`` and
``cardinality = (1/n) c^p (n - m)``, so that ``total ** p == localisation + cardinality``
(the same convention as :class:`~mapassoc.evaluation.metrics.GospaResult`).  Unlike GOSPA,
OSPA normalises by ``n``: a run with many targets and one miss scores lower than a run with
one target and one miss.

OSPA(2) (Beard, Vo and Vo, "OSPA(2): Using the OSPA metric to evaluate multi-target tracking
performance", ICCAIS 2017; also Beard, Vo and Vo, IEEE Trans. Signal Processing 68, 2020,
Sec. VI-A) is OSPA applied to sets of *trajectories*.  A trajectory ``x`` is a function from
its time domain ``D_x`` (the evaluation times it has a row at) to positions.  The base
distance between two trajectories is the time average, over the times *either* exists, of the
OSPA between the singleton-or-empty sets ``{x(t)}`` and ``{y(t)}``::

    d~^(c)(x, y) = (1 / |D_x u D_y|) sum_{t in D_x u D_y} d^(c)({x(t)}, {y(t)})

where ``d^(c)({x(t)}, {y(t)})`` is ``min(c, ||x(t) - y(t)||)`` when both exist and ``c``
when only one does (for sets of at most one element the OSPA order does not matter).
OSPA(2) is then ``d_p^(c)`` above on the two sets of trajectories with ``d~^(c)`` as base
distance (already ``<= c``, so the second cut-off changes nothing).  A track that switches
from one target to another, or a target covered by two track fragments, is paired with
one trajectory only and pays ``c`` for the times it is not: OSPA(2) penalises id switches
and fragmentation, which the per-time OSPA and GOSPA cannot see.

The sliding-window form (Beard et al. 2020) evaluates OSPA(2) at each evaluation time ``k``
on the trajectories restricted to the last ``L`` evaluation times (fewer at the start of
the run); trajectories with no row in the window are not in the sets.

Evaluation times, as in :mod:`mapassoc.evaluation.metrics`, are the sorted union of the
distinct truth and estimate times, matched exactly; trajectories are the rows sharing an id.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import _check_point_set
from mapassoc.evaluation.points import (
    TimedPoints,
    check_cost_powers,
    check_order,
    check_runs,
    readonly,
)
from mapassoc.validation import check_positive

__all__ = [
    "OspaResult",
    "OspaSeries",
    "Ospa2Series",
    "ospa",
    "ospa_over_time",
    "trajectory_base_distances",
    "ospa2",
    "ospa2_over_time",
]


@dataclass(frozen=True)
class OspaResult:
    """OSPA between two sets (of points, or of trajectories for OSPA(2)).

    Parameters
    ----------
    total : float
        ``(localisation + cardinality) ** (1/p)``, in ``[0, c]``.
    localisation : float
        ``(1/n) min_pi sum d^(c)^p`` (a p-th power part; ``n`` the larger set size).
    cardinality : float
        ``(1/n) c^p |n - m|`` (a p-th power part).
    num_truth : int
        Size of the truth set.
    num_estimates : int
        Size of the estimate set.
    """

    total: float
    localisation: float
    cardinality: float
    num_truth: int
    num_estimates: int


@dataclass(frozen=True, eq=False)
class OspaSeries:
    """OSPA per evaluation time over a run.

    Parameters
    ----------
    times : ndarray, shape (T,)
        Sorted evaluation times (union of the distinct truth and estimate times).
    total, localisation, cardinality : ndarray, shape (T,)
        Per-time OSPA and its p-th power parts (see :class:`OspaResult`).
    c : float
        Cut-off.
    p : float
        Order.
    """

    times: NDArray[np.float64]
    total: NDArray[np.float64]
    localisation: NDArray[np.float64]
    cardinality: NDArray[np.float64]
    c: float
    p: float

    @property
    def mean_total(self) -> float:
        """Mean over times of the per-time OSPA values."""
        return float(np.mean(self.total))


@dataclass(frozen=True, eq=False)
class Ospa2Series:
    """OSPA(2) over sliding windows of evaluation times.

    Parameters
    ----------
    start_times, end_times : ndarray, shape (W,)
        First and last evaluation time of each window (``W = T``: one window ends at every
        evaluation time).
    total, localisation, cardinality : ndarray, shape (W,)
        OSPA(2) of each window and its p-th power parts.
    num_truth, num_estimates : ndarray of int, shape (W,)
        Trajectories with a row in each window.
    c : float
    p : float
    window_length : int
        Evaluation times per window (the first ``window_length - 1`` windows are shorter).
    """

    start_times: NDArray[np.float64]
    end_times: NDArray[np.float64]
    total: NDArray[np.float64]
    localisation: NDArray[np.float64]
    cardinality: NDArray[np.float64]
    num_truth: NDArray[np.int64]
    num_estimates: NDArray[np.int64]
    c: float
    p: float
    window_length: int

    @property
    def mean_total(self) -> float:
        """Mean over windows of OSPA(2)."""
        return float(np.mean(self.total))


# ----------------------------------------------------------------------------------------------
# OSPA on a cost matrix
# ----------------------------------------------------------------------------------------------


def _ospa_from_costs(cost: NDArray[np.float64], c: float, p: float) -> OspaResult:
    """OSPA from the (n_truth, n_estimates) matrix of cut-off base distances (each <= c)."""
    num_truth, num_estimates = cost.shape
    larger = max(num_truth, num_estimates)
    if larger == 0:
        return OspaResult(0.0, 0.0, 0.0, 0, 0)
    assigned = 0.0
    if num_truth and num_estimates:
        powered = cost**p
        rows, cols = linear_sum_assignment(powered)
        assigned = float(powered[rows, cols].sum())
    localisation = assigned / larger
    cardinality = c**p * abs(num_truth - num_estimates) / larger
    return OspaResult(
        total=float((localisation + cardinality) ** (1.0 / p)),
        localisation=localisation,
        cardinality=cardinality,
        num_truth=num_truth,
        num_estimates=num_estimates,
    )


def _cutoff_distances(
    truth: NDArray[np.float64], estimates: NDArray[np.float64], c: float
) -> NDArray[np.float64]:
    """``min(c, ||x_i - y_j||)``, shape (n, m), for (n, d) and (m, d) arrays."""
    distance = np.linalg.norm(truth[:, None, :] - estimates[None, :, :], axis=-1)
    return np.minimum(distance, c)


def ospa(truth: ArrayLike, estimates: ArrayLike, *, c: float, p: float = 2.0) -> OspaResult:
    """OSPA (Schuhmacher, Vo and Vo 2008, Definition 3) between two point sets.

    Parameters
    ----------
    truth : array_like, shape (n, d)
        True positions; an empty set may be ``(0, d)`` or ``[]``.
    estimates : array_like, shape (m, d)
        Estimated positions, same ``d``; an empty set may be ``(0, d)`` or ``[]``.
    c : float
        Cut-off, > 0.
    p : float
        Order, ``1 <= p < inf``.

    Returns
    -------
    OspaResult
        ``total ** p == localisation + cardinality`` up to rounding; 0 for two empty sets,
        ``c`` for an empty and a non-empty set.

    Raises
    ------
    InputError
        ``c <= 0``, ``p < 1``, non-finite values, wrong shapes or different dimensions.

    Examples
    --------
    ``{0}`` vs ``{3}`` with ``c = 10``, ``p = 2``: ``(1/1 * 3^2)^(1/2) = 3``.
    """
    cutoff = check_positive("c", c)
    order = check_order(p)
    check_cost_powers(order, c=cutoff)
    truth_arr = _check_point_set("truth", truth)
    estimates_arr = _check_point_set("estimates", estimates)
    if truth_arr.ndim == 1 and estimates_arr.ndim == 1:
        return OspaResult(0.0, 0.0, 0.0, 0, 0)
    if truth_arr.ndim == 1:
        truth_arr = truth_arr.reshape(0, estimates_arr.shape[1])
    if estimates_arr.ndim == 1:
        estimates_arr = estimates_arr.reshape(0, truth_arr.shape[1])
    if truth_arr.shape[1] != estimates_arr.shape[1]:
        raise InputError(
            f"truth and estimates must have the same dimension d, got truth shape "
            f"{truth_arr.shape} and estimates shape {estimates_arr.shape}"
        )
    return _ospa_from_costs(_cutoff_distances(truth_arr, estimates_arr, cutoff), cutoff, order)


def ospa_over_time(
    truth: TimedPoints, estimates: TimedPoints, *, c: float, p: float = 2.0
) -> OspaSeries:
    """OSPA at every evaluation time of a run (the times of
    :func:`~mapassoc.evaluation.metrics.gospa_over_time`).

    Parameters
    ----------
    truth, estimates : TimedPoints
        Same position dimension; at least one row in total.
    c : float
        Cut-off, > 0.
    p : float
        Order, ``1 <= p < inf``.

    Returns
    -------
    OspaSeries
        Arrays of shape (T,).
    """
    cutoff = check_positive("c", c)
    order = check_order(p)
    check_cost_powers(order, c=cutoff)
    check_runs(truth, estimates)
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    results = [
        _ospa_from_costs(
            _cutoff_distances(truth.positions_at(t), estimates.positions_at(t), cutoff),
            cutoff,
            order,
        )
        for t in times
    ]
    return OspaSeries(
        times=readonly(np.array(times, dtype=float)),
        total=readonly(np.array([r.total for r in results])),
        localisation=readonly(np.array([r.localisation for r in results])),
        cardinality=readonly(np.array([r.cardinality for r in results])),
        c=cutoff,
        p=order,
    )


# ----------------------------------------------------------------------------------------------
# OSPA(2)
# ----------------------------------------------------------------------------------------------


def _trajectories(
    run: TimedPoints, times: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.bool_], NDArray[np.float64]]:
    """Ids (N,), presence (N, T) and positions (N, T, d) (zero where absent) of a run."""
    ids, which = np.unique(run.ids, return_inverse=True)
    when = np.searchsorted(times, run.times)
    present = np.zeros((ids.size, times.size), dtype=bool)
    positions = np.zeros((ids.size, times.size, run.dim))
    present[which, when] = True
    positions[which, when] = run.positions
    return ids, present, positions


@dataclass(frozen=True)
class _PairSums:
    """Cumulative sums over evaluation times, for every (truth, estimate) trajectory pair.

    ``cost[i, j, k]`` is the sum over the first ``k`` evaluation times of the per-time
    base distance term and ``union[i, j, k]`` the number of those times where trajectory
    ``i`` or ``j`` exists; shapes (n, m, T + 1).  ``truth_rows`` (n, T + 1) and
    ``estimate_rows`` (m, T + 1) count each trajectory's rows the same way.
    """

    cost: NDArray[np.float64]
    union: NDArray[np.int64]
    truth_rows: NDArray[np.int64]
    estimate_rows: NDArray[np.int64]


def _pair_sums(
    truth: TimedPoints, estimates: TimedPoints, times: NDArray[np.float64], c: float
) -> _PairSums:
    _, truth_present, truth_positions = _trajectories(truth, times)
    _, est_present, est_positions = _trajectories(estimates, times)
    n, m, T = truth_present.shape[0], est_present.shape[0], times.size
    cost = np.zeros((n, m, T + 1))
    union = np.zeros((n, m, T + 1), dtype=np.int64)
    for i in range(n):
        both = truth_present[i][None, :] & est_present
        either = truth_present[i][None, :] | est_present
        distance = np.linalg.norm(truth_positions[i][None, :, :] - est_positions, axis=-1)
        term = np.where(both, np.minimum(distance, c), np.where(either, c, 0.0))
        cost[i, :, 1:] = np.cumsum(term, axis=1)
        union[i, :, 1:] = np.cumsum(either, axis=1)

    def rows(present: NDArray[np.bool_]) -> NDArray[np.int64]:
        counts = np.zeros((present.shape[0], T + 1), dtype=np.int64)
        counts[:, 1:] = np.cumsum(present, axis=1)
        return counts

    return _PairSums(cost, union, rows(truth_present), rows(est_present))


def _window_ospa2(sums: _PairSums, first: int, last: int, c: float, p: float) -> OspaResult:
    """OSPA(2) on the evaluation times with indices ``first..last`` (inclusive)."""
    truth_in = (sums.truth_rows[:, last + 1] - sums.truth_rows[:, first]) > 0
    est_in = (sums.estimate_rows[:, last + 1] - sums.estimate_rows[:, first]) > 0
    total = sums.cost[:, :, last + 1] - sums.cost[:, :, first]
    count = sums.union[:, :, last + 1] - sums.union[:, :, first]
    total = total[truth_in][:, est_in]
    count = count[truth_in][:, est_in]
    # Both trajectories of every remaining pair have a row in the window, so count >= 1.
    base = total / count if total.size else np.zeros(total.shape)
    return _ospa_from_costs(base, c, p)


def trajectory_base_distances(
    truth: TimedPoints, estimates: TimedPoints, *, c: float
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """The OSPA(2) base distance ``d~^(c)`` between every truth and estimate trajectory.

    Parameters
    ----------
    truth, estimates : TimedPoints
        Same position dimension; at least one row in total.  A trajectory is the rows of
        one id.
    c : float
        Cut-off, > 0.

    Returns
    -------
    truth_ids : ndarray of int, shape (n,)
        Sorted truth trajectory ids.
    estimate_ids : ndarray of int, shape (m,)
        Sorted estimate trajectory ids.
    distances : ndarray, shape (n, m)
        ``d~^(c)`` of each pair over the whole run, in ``[0, c]``.
    """
    cutoff = check_positive("c", c)
    check_runs(truth, estimates)
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    sums = _pair_sums(truth, estimates, times, cutoff)
    # Every trajectory has a row, so every pair has at least one time in its union.
    distances = sums.cost[:, :, -1] / sums.union[:, :, -1]
    return np.unique(truth.ids), np.unique(estimates.ids), distances


def ospa2(truth: TimedPoints, estimates: TimedPoints, *, c: float, p: float = 2.0) -> OspaResult:
    """OSPA(2) (Beard, Vo and Vo 2017) over the whole run.

    Parameters
    ----------
    truth, estimates : TimedPoints
        Same position dimension; at least one row in total.  A trajectory is the rows of
        one id.
    c : float
        Cut-off, > 0 (of the per-time distance and of the trajectory OSPA).
    p : float
        Order of the trajectory OSPA, ``1 <= p < inf``.

    Returns
    -------
    OspaResult
        Over trajectory sets: ``num_truth`` and ``num_estimates`` count trajectories.

    Notes
    -----
    Memory and time grow as ``n m T`` (trajectory pairs times evaluation times).

    Over a whole run every unpaired trajectory costs ``c`` whatever its duration: one
    false track of a few scans among ``n - 1`` well-tracked targets adds ``c^p / n`` to
    ``total ** p``, as much as a target missed for the whole run.  A method that starts one
    short false track can therefore score a much larger OSPA(2) than a method with worse
    per-time errors; :func:`ospa2_over_time` weighs such a track by the windows it is in.

    Examples
    --------
    One true trajectory at 4 times, estimated 1 away at every time: OSPA(2) = 1.  The same
    estimate with its id switched after 2 times: two trajectories, each at base distance
    ``(1 + 1 + c + c) / 4`` from the truth, one unpaired: with ``c = 10``, ``p = 2``,
    ``sqrt((5.5^2 + 10^2) / 2) = sqrt(65.125)``.
    """
    cutoff = check_positive("c", c)
    order = check_order(p)
    check_cost_powers(order, c=cutoff)
    check_runs(truth, estimates)
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    sums = _pair_sums(truth, estimates, times, cutoff)
    return _window_ospa2(sums, 0, times.size - 1, cutoff, order)


def ospa2_over_time(
    truth: TimedPoints,
    estimates: TimedPoints,
    *,
    c: float,
    p: float = 2.0,
    window_length: int,
) -> Ospa2Series:
    """OSPA(2) over a sliding window ending at every evaluation time (Beard et al. 2020).

    Parameters
    ----------
    truth, estimates : TimedPoints
        Same position dimension; at least one row in total.
    c : float
        Cut-off, > 0.
    p : float
        Order, ``1 <= p < inf``.
    window_length : int
        Number of evaluation times per window, >= 1; the window ending at the k-th time
        (0-based) covers times ``max(0, k - window_length + 1) .. k``.

    Returns
    -------
    Ospa2Series
        One window per evaluation time.
    """
    cutoff = check_positive("c", c)
    order = check_order(p)
    check_cost_powers(order, c=cutoff)
    if isinstance(window_length, bool) or not isinstance(window_length, int | np.integer) or (
        window_length < 1
    ):
        raise InputError(f"window_length must be an integer >= 1, got {window_length!r}")
    check_runs(truth, estimates)
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    sums = _pair_sums(truth, estimates, times, cutoff)
    firsts = [max(0, k - int(window_length) + 1) for k in range(times.size)]
    results = [_window_ospa2(sums, a, k, cutoff, order) for k, a in enumerate(firsts)]
    return Ospa2Series(
        start_times=readonly(times[firsts].astype(float)),
        end_times=readonly(times.astype(float)),
        total=readonly(np.array([r.total for r in results])),
        localisation=readonly(np.array([r.localisation for r in results])),
        cardinality=readonly(np.array([r.cardinality for r in results])),
        num_truth=readonly(np.array([r.num_truth for r in results], dtype=np.int64)),
        num_estimates=readonly(np.array([r.num_estimates for r in results], dtype=np.int64)),
        c=cutoff,
        p=order,
        window_length=int(window_length),
    )
