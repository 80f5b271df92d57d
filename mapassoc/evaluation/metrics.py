"""Multi-target performance metrics: GOSPA, position RMSE and cardinality error.

GOSPA with ``alpha = 2`` (Rahmathullah, García-Fernández, Svensson, "Generalized optimal
sub-pattern assignment metric", FUSION 2017, the ``alpha = 2`` form of Proposition 1) between a
truth set ``X = {x_1..x_n}`` and an estimate set ``Y = {y_1..y_m}`` is::

    d(X, Y) = ( min over partial assignments g of
                [ sum_{(i, j) in g} ||x_i - y_j||^p + (c^p / 2) (n + m - 2 |g|) ] )^(1/p)

An assigned pair at distance ``>= c`` costs at least ``c^p``, which is what leaving both
points unassigned costs (one missed target and one false estimate, ``c^p / 2`` each).  So the
minimum equals the minimum over *complete* rectangular assignments of the cut-off costs
``min(||x_i - y_j||, c)^p`` plus ``(c^p / 2) |n - m|``, which is what
:func:`scipy.optimize.linear_sum_assignment` solves.  Pairs it returns at distance ``>= c`` are
then counted as one missed target plus one false estimate.

The metric is a metric for ``1 <= p < inf`` and ``alpha = 2`` (symmetric, zero exactly when the
two multisets are equal, triangle inequality).  The split of the value into localisation, missed
and false parts is that of the optimal assignment found; when several assignments tie, the total
is unique but the split may depend on which one the solver returns.

Runs of points are :class:`TimedPoints`.  Two rows are at the same time step only when their
times are *exactly* equal: truth and track files are both written at scan times, so the same
floating-point scan time appears in both.  Times are never rounded or matched within a tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from mapassoc.errors import InputError
from mapassoc.evaluation.points import (
    TimedPoints,
    check_cost_powers,
    check_order,
    check_runs,
    float_array,
    readonly,
)
from mapassoc.validation import check_positive

if TYPE_CHECKING:
    from mapassoc.evaluation.tgospa import TgospaResult, TrackFragmentation

__all__ = [
    "GospaResult",
    "GospaSeries",
    "TimedPoints",
    "CardinalityError",
    "RunEvaluation",
    "gospa",
    "gospa_over_time",
    "position_rmse",
    "cardinality_error",
    "evaluate",
    "format_report",
]


# ----------------------------------------------------------------------------------------------
# Data
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class GospaResult:
    """GOSPA between two point sets at one time step.

    Parameters
    ----------
    total : float
        The GOSPA value ``(localisation + missed + false)^(1/p)``.
    localisation : float
        Sum over assigned pairs of ``||x - y||^p`` (a part of the p-th power sum).
    missed : float
        ``(c^p / 2) * num_missed``.
    false : float
        ``(c^p / 2) * num_false``.
    num_missed : int
        Truth points left unassigned.
    num_false : int
        Estimates left unassigned.
    num_assigned : int
        Assigned pairs (all at distance ``< c``).
    assignments : ndarray of int, shape (k, 2)
        ``(truth index, estimate index)`` of each assigned pair, sorted by truth index.
    distances : ndarray, shape (k,)
        Euclidean distance of each assigned pair, in the order of ``assignments``.
    """

    total: float
    localisation: float
    missed: float
    false: float
    num_missed: int
    num_false: int
    num_assigned: int
    assignments: NDArray[np.int64]
    distances: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class GospaSeries:
    """GOSPA per evaluation time over a run.

    Parameters
    ----------
    times : ndarray, shape (T,)
        Evaluation times, sorted: the union of the distinct truth and estimate times.
    total, localisation, missed, false : ndarray, shape (T,)
        Per-time GOSPA value and its three p-th power parts (see :class:`GospaResult`).
    num_missed, num_false, num_assigned : ndarray of int, shape (T,)
        Per-time counts.
    c : float
        Cut-off distance used.
    p : float
        Order used.
    """

    times: NDArray[np.float64]
    total: NDArray[np.float64]
    localisation: NDArray[np.float64]
    missed: NDArray[np.float64]
    false: NDArray[np.float64]
    num_missed: NDArray[np.int64]
    num_false: NDArray[np.int64]
    num_assigned: NDArray[np.int64]
    c: float
    p: float

    @property
    def num_times(self) -> int:
        """Number of evaluation times T."""
        return int(self.times.shape[0])

    @property
    def mean_total(self) -> float:
        """Mean over times of the per-time GOSPA values (not of their p-th powers)."""
        return float(np.mean(self.total))

    @property
    def mean_localisation(self) -> float:
        """Mean over times of the localisation part (a p-th power quantity)."""
        return float(np.mean(self.localisation))

    @property
    def mean_missed(self) -> float:
        """Mean over times of the missed-target part (a p-th power quantity)."""
        return float(np.mean(self.missed))

    @property
    def mean_false(self) -> float:
        """Mean over times of the false-estimate part (a p-th power quantity)."""
        return float(np.mean(self.false))

    @property
    def mean_num_missed(self) -> float:
        """Mean number of missed targets per time."""
        return float(np.mean(self.num_missed))

    @property
    def mean_num_false(self) -> float:
        """Mean number of false estimates per time."""
        return float(np.mean(self.num_false))

    @property
    def mean_num_assigned(self) -> float:
        """Mean number of assigned pairs per time."""
        return float(np.mean(self.num_assigned))

    def summary(self) -> dict[str, float | int]:
        """Return the means as a JSON-ready dictionary of plain floats and ints."""
        return {
            "c": float(self.c),
            "p": float(self.p),
            "alpha": 2.0,
            "num_times": self.num_times,
            "mean_total": self.mean_total,
            "mean_localisation": self.mean_localisation,
            "mean_missed": self.mean_missed,
            "mean_false": self.mean_false,
            "mean_num_missed": self.mean_num_missed,
            "mean_num_false": self.mean_num_false,
            "mean_num_assigned": self.mean_num_assigned,
        }


@dataclass(frozen=True, eq=False)
class CardinalityError:
    """Per-time difference between the number of estimates and the number of truth points.

    Parameters
    ----------
    times : ndarray, shape (T,)
        Evaluation times (as in :func:`gospa_over_time`).
    difference : ndarray of int, shape (T,)
        ``#estimates - #truth`` at each time (positive: too many estimates).
    mean_absolute : float
        Mean of ``|difference|``.
    """

    times: NDArray[np.float64]
    difference: NDArray[np.int64]
    mean_absolute: float


# ----------------------------------------------------------------------------------------------
# Validation helpers
# ----------------------------------------------------------------------------------------------


def _check_point_set(name: str, value: ArrayLike) -> NDArray[np.float64]:
    arr = float_array(name, value)
    if arr.ndim == 1 and arr.shape[0] == 0:
        return arr  # an empty set given as []; its dimension is taken from the other set
    if arr.ndim != 2 or arr.shape[1] < 1:
        raise InputError(f"{name} must have shape (k, d) with d >= 1, got shape {arr.shape}")
    return arr


def _check_alpha(alpha: object) -> None:
    value = check_positive("alpha", alpha)
    if value != 2.0:
        raise InputError(
            f"alpha must be 2: only alpha = 2 is supported (the only value for which GOSPA "
            f"splits into localisation, missed and false parts), got {alpha!r}"
        )


# ----------------------------------------------------------------------------------------------
# GOSPA
# ----------------------------------------------------------------------------------------------


def _gospa_unchecked(
    truth: NDArray[np.float64], estimates: NDArray[np.float64], c: float, p: float
) -> GospaResult:
    """GOSPA (alpha = 2) on validated (n, d) and (m, d) arrays; see :func:`gospa`."""
    num_truth = truth.shape[0]
    num_estimates = estimates.shape[0]
    half_penalty = c**p / 2.0
    if num_truth and num_estimates:
        distance = np.linalg.norm(truth[:, None, :] - estimates[None, :, :], axis=-1)
        # Cut-off cost min(d, c)^p: with alpha = 2 an assigned pair at d >= c costs c^p, the
        # same as one miss plus one false estimate, so a complete rectangular assignment of
        # these costs attains the minimum over partial assignments (module docstring).
        cost = np.minimum(distance, c) ** p
        rows, cols = linear_sum_assignment(cost)
        pair_distance = distance[rows, cols]
        kept = pair_distance < c
        assignments = np.stack([rows[kept], cols[kept]], axis=1).astype(np.int64)
        distances = pair_distance[kept]
    else:
        assignments = np.zeros((0, 2), dtype=np.int64)
        distances = np.zeros(0)
    num_assigned = int(assignments.shape[0])
    num_missed = num_truth - num_assigned
    num_false = num_estimates - num_assigned
    localisation = float(np.sum(distances**p))
    missed = half_penalty * num_missed
    false = half_penalty * num_false
    total = (localisation + missed + false) ** (1.0 / p)
    return GospaResult(
        total=float(total),
        localisation=localisation,
        missed=float(missed),
        false=float(false),
        num_missed=num_missed,
        num_false=num_false,
        num_assigned=num_assigned,
        assignments=readonly(assignments),
        distances=readonly(distances),
    )


def gospa(
    truth: ArrayLike, estimates: ArrayLike, *, c: float, p: float = 2.0, alpha: float = 2.0
) -> GospaResult:
    """GOSPA metric (alpha = 2) between two point sets at one time step.

    Implements the alpha = 2 form (Proposition 1) of Rahmathullah, García-Fernández and
    Svensson (FUSION 2017)::

        d = ( min_g [ sum_{(i,j) in g} min(||x_i - y_j||, c)^p + (c^p/2)(#missed + #false) ] )^(1/p)

    Pairs at distance ``>= c`` are reported as unassigned (one missed + one false).

    Parameters
    ----------
    truth : array_like, shape (n, d)
        True positions.  An empty set may be given as shape ``(0, d)`` or as ``[]``.
    estimates : array_like, shape (m, d)
        Estimated positions, same ``d``.  An empty set may be given as ``(0, d)`` or ``[]``.
    c : float
        Cut-off distance, > 0.  A miss or a false estimate costs ``c^p / 2``.
    p : float
        Order, ``1 <= p < inf``.
    alpha : float
        Must be 2 (the only supported value).

    Returns
    -------
    GospaResult
        ``total ** p == localisation + missed + false`` up to rounding.

    Raises
    ------
    InputError
        ``alpha != 2``, ``c <= 0``, ``p < 1``, non-finite values, wrong shapes or different
        dimensions.
    """
    _check_alpha(alpha)
    cutoff = check_positive("c", c)
    order = check_order(p)
    check_cost_powers(order, c=cutoff)
    truth_arr = _check_point_set("truth", truth)
    estimates_arr = _check_point_set("estimates", estimates)
    if truth_arr.ndim == 1 and estimates_arr.ndim == 1:
        truth_arr = truth_arr.reshape(0, 1)
        estimates_arr = estimates_arr.reshape(0, 1)
    elif truth_arr.ndim == 1:
        truth_arr = truth_arr.reshape(0, estimates_arr.shape[1])
    elif estimates_arr.ndim == 1:
        estimates_arr = estimates_arr.reshape(0, truth_arr.shape[1])
    if truth_arr.shape[1] != estimates_arr.shape[1]:
        raise InputError(
            f"truth and estimates must have the same dimension d, got truth shape "
            f"{truth_arr.shape} and estimates shape {estimates_arr.shape}"
        )
    return _gospa_unchecked(truth_arr, estimates_arr, cutoff, order)


def _group_by_time(run: TimedPoints) -> dict[float, NDArray[np.float64]]:
    unique_times, inverse = np.unique(run.times, return_inverse=True)
    return {float(t): run.positions[inverse == k] for k, t in enumerate(unique_times)}


def _per_time_gospa(
    truth: TimedPoints, estimates: TimedPoints, c: float, p: float
) -> tuple[NDArray[np.float64], list[GospaResult]]:
    """Evaluation times and the GOSPA result at each; inputs already validated."""
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    truth_at = _group_by_time(truth)
    estimates_at = _group_by_time(estimates)
    empty = np.zeros((0, truth.dim))
    results = [
        _gospa_unchecked(truth_at.get(float(t), empty), estimates_at.get(float(t), empty), c, p)
        for t in times
    ]
    return times, results


def _series(
    times: NDArray[np.float64], results: list[GospaResult], c: float, p: float
) -> GospaSeries:
    def floats(attribute: str) -> NDArray[np.float64]:
        values = np.array([getattr(r, attribute) for r in results], dtype=float)
        return readonly(values)

    def ints(attribute: str) -> NDArray[np.int64]:
        values = np.array([getattr(r, attribute) for r in results], dtype=np.int64)
        return readonly(values)

    return GospaSeries(
        times=readonly(np.array(times, dtype=float)),
        total=floats("total"),
        localisation=floats("localisation"),
        missed=floats("missed"),
        false=floats("false"),
        num_missed=ints("num_missed"),
        num_false=ints("num_false"),
        num_assigned=ints("num_assigned"),
        c=c,
        p=p,
    )


def gospa_over_time(
    truth: TimedPoints, estimates: TimedPoints, *, c: float, p: float = 2.0
) -> GospaSeries:
    """GOSPA (alpha = 2) at every evaluation time of a run.

    Evaluation times are the sorted union of the distinct times of ``truth`` and
    ``estimates``; a time present in only one of them is still evaluated (everything there is
    missed, or everything false).  Times match only when exactly equal.  A time at which both
    sets are empty appears in neither input and is therefore not evaluated.

    Parameters
    ----------
    truth, estimates : TimedPoints
        The runs, same position dimension; at least one has a row.
    c : float
        Cut-off distance, > 0.
    p : float
        Order, ``1 <= p < inf``.

    Returns
    -------
    GospaSeries
        Arrays of shape (T,).

    Raises
    ------
    InputError
        Bad ``c`` or ``p``, inputs that are not TimedPoints, different dimensions, or no rows
        at all.
    """
    cutoff = check_positive("c", c)
    order = check_order(p)
    check_cost_powers(order, c=cutoff)
    check_runs(truth, estimates)
    times, results = _per_time_gospa(truth, estimates, cutoff, order)
    return _series(times, results, cutoff, order)


# ----------------------------------------------------------------------------------------------
# RMSE and cardinality
# ----------------------------------------------------------------------------------------------


def _rmse(results: list[GospaResult]) -> tuple[float, int]:
    distances = np.concatenate([r.distances for r in results]) if results else np.zeros(0)
    if distances.size == 0:
        return math.nan, 0
    return float(np.sqrt(np.mean(distances**2))), int(distances.size)


def position_rmse(truth: TimedPoints, estimates: TimedPoints, *, c: float, p: float = 2.0) -> float:
    """Root-mean-square position error over the GOSPA-assigned pairs of all times.

    Parameters
    ----------
    truth, estimates : TimedPoints
        The runs (see :func:`gospa_over_time`).
    c : float
        GOSPA cut-off; only pairs at distance ``< c`` count.
    p : float
        GOSPA order that decides the assignment (default 2, the order that minimises the sum
        of squared errors under the cut-off).

    Returns
    -------
    float
        ``sqrt(mean of squared distances)`` over all assigned pairs; ``nan`` if there are none.
    """
    cutoff = check_positive("c", c)
    order = check_order(p)
    check_cost_powers(order, c=cutoff)
    check_runs(truth, estimates)
    _, results = _per_time_gospa(truth, estimates, cutoff, order)
    return _rmse(results)[0]


def cardinality_error(truth: TimedPoints, estimates: TimedPoints) -> CardinalityError:
    """Per-time ``#estimates - #truth`` at the evaluation times of :func:`gospa_over_time`.

    Parameters
    ----------
    truth, estimates : TimedPoints
        The runs; same position dimension, at least one row in total.

    Returns
    -------
    CardinalityError
    """
    check_runs(truth, estimates)
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    truth_count = np.array([np.count_nonzero(truth.times == t) for t in times], dtype=np.int64)
    estimate_count = np.array(
        [np.count_nonzero(estimates.times == t) for t in times], dtype=np.int64
    )
    difference = estimate_count - truth_count
    return CardinalityError(
        times=readonly(times),
        difference=readonly(difference),
        mean_absolute=float(np.mean(np.abs(difference))),
    )


@dataclass(frozen=True, eq=False)
class RunEvaluation:
    """Every metric of one run against the truth (what :func:`evaluate` returns).

    Parameters
    ----------
    gospa : GospaSeries
        GOSPA per evaluation time, with its parts and means.
    position_rmse : float or None
        Position RMSE over the pairs GOSPA assigned; ``None`` when no pair was assigned.
    num_assigned_pairs : int
        Pairs the RMSE is taken over.
    cardinality : CardinalityError
        Per-time ``#estimates - #truth``.
    tgospa : TgospaResult or None
        T-GOSPA of the trajectories (:mod:`mapassoc.evaluation.tgospa`); ``None`` unless
        :func:`evaluate` was given a ``switch_cost``.
    fragmentation : TrackFragmentation or None
        Fragments per true target and identity switches of the T-GOSPA assignment; ``None``
        with ``tgospa``.
    """

    gospa: GospaSeries
    position_rmse: float | None
    num_assigned_pairs: int
    cardinality: CardinalityError
    tgospa: TgospaResult | None = None
    fragmentation: TrackFragmentation | None = None

    @property
    def num_times(self) -> int:
        """Number of evaluation times."""
        return self.gospa.num_times

    @property
    def mean_abs_cardinality_error(self) -> float:
        """Mean over times of ``|#estimates - #truth|``."""
        return self.cardinality.mean_absolute

    def to_json(self) -> dict[str, object]:
        """The means as a JSON-ready dictionary of plain numbers (``mapassoc evaluate --json``):
        ``{"num_times", "gospa": GospaSeries.summary(), "position_rmse" (null without pairs),
        "num_assigned_pairs", "mean_abs_cardinality_error"}``, plus ``"tgospa"``
        (:meth:`TgospaResult.summary`) and ``"fragmentation"``
        (:meth:`TrackFragmentation.summary`) when T-GOSPA was computed."""
        out: dict[str, object] = {
            "num_times": self.num_times,
            "gospa": self.gospa.summary(),
            "position_rmse": self.position_rmse,
            "num_assigned_pairs": self.num_assigned_pairs,
            "mean_abs_cardinality_error": self.mean_abs_cardinality_error,
        }
        if self.tgospa is not None:
            out["tgospa"] = self.tgospa.summary()
        if self.fragmentation is not None:
            out["fragmentation"] = self.fragmentation.summary()
        return out


def evaluate(
    truth: TimedPoints,
    estimates: TimedPoints,
    *,
    c: float,
    p: float = 2.0,
    switch_cost: float | None = None,
    tgospa_method: str = "milp",
) -> RunEvaluation:
    """All metrics of a run: GOSPA over time, position RMSE, cardinality error, and with a
    ``switch_cost`` T-GOSPA of the trajectories with the fragments per target.

    Parameters
    ----------
    truth, estimates : TimedPoints
        The runs (see :func:`gospa_over_time`).
    c : float
        GOSPA cut-off distance, > 0.
    p : float
        GOSPA order, ``1 <= p < inf``; it also decides the pairs the RMSE is taken over.
    switch_cost : float, optional
        T-GOSPA switching cost gamma > 0 (same ``c`` and ``p``); ``None`` skips T-GOSPA and
        fragmentation (their fields are then ``None``).
    tgospa_method : {"milp", "lp"}
        ``milp``: exact T-GOSPA; ``lp``: its LP relaxation (a lower bound, for very large
        runs).  Fragmentation comes from the assignment of the method chosen.

    Returns
    -------
    RunEvaluation
        Typed; :meth:`RunEvaluation.to_json` gives the dictionary the command line writes.
    """
    from mapassoc.evaluation.tgospa import _check_method, fragmentation_of, tgospa

    cutoff = check_positive("c", c)
    order = check_order(p)
    gamma = None if switch_cost is None else check_positive("switch_cost", switch_cost)
    check_cost_powers(order, c=cutoff, **({} if gamma is None else {"switch_cost": gamma}))
    method = _check_method(tgospa_method, "tgospa_method")
    check_runs(truth, estimates)
    times, results = _per_time_gospa(truth, estimates, cutoff, order)
    series = _series(times, results, cutoff, order)
    rmse, num_pairs = _rmse(results)
    trajectory = (
        None
        if gamma is None
        else tgospa(truth, estimates, c=cutoff, gamma=gamma, p=order, method=method)
    )
    return RunEvaluation(
        gospa=series,
        position_rmse=None if math.isnan(rmse) else rmse,
        num_assigned_pairs=num_pairs,
        cardinality=cardinality_error(truth, estimates),
        tgospa=trajectory,
        fragmentation=None if trajectory is None else fragmentation_of(trajectory),
    )


# ----------------------------------------------------------------------------------------------
# Report
# ----------------------------------------------------------------------------------------------

_REQUIRED_KEYS = (
    "num_times",
    "gospa",
    "position_rmse",
    "num_assigned_pairs",
    "mean_abs_cardinality_error",
)
_REQUIRED_GOSPA_KEYS = (
    "c",
    "p",
    "mean_total",
    "mean_localisation",
    "mean_missed",
    "mean_false",
    "mean_num_missed",
    "mean_num_false",
)


def _number(value: object) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    return f"{float(value):.4f}"  # type: ignore[arg-type]


def _pgospa_rows(pg: object) -> list[tuple[str, object]]:
    """The report's P-GOSPA lines from ``summary["pgospa"]`` (none when it is absent)."""
    if not isinstance(pg, dict):
        return []
    p = f"{float(pg['p']):g}"
    return [
        (f"P-GOSPA mean (c={float(pg['c']):g}, p={p}, alpha=2)", pg["mean_total"]),
        (f"  localisation part of P-GOSPA^{p}, mean", pg["mean_localisation"]),
        (f"  existence mismatch part of P-GOSPA^{p}, mean", pg["mean_existence_mismatch"]),
        (f"  missed part of P-GOSPA^{p}, mean", pg["mean_missed"]),
        (f"  false part of P-GOSPA^{p}, mean", pg["mean_false"]),
    ]


def format_report(summary: RunEvaluation | dict) -> str:
    """Format an evaluation as an aligned plain-text table.

    Parameters
    ----------
    summary : RunEvaluation or dict
        Output of :func:`evaluate`, or its :meth:`~RunEvaluation.to_json` dictionary; a
        ``"pgospa"`` entry (:func:`mapassoc.evaluation.tables.pgospa_summary`) adds the
        P-GOSPA lines after GOSPA's.

    Returns
    -------
    str
        One metric per line, names left-aligned, values right-aligned; no trailing newline.

    Raises
    ------
    InputError
        A required key is missing.
    """
    if isinstance(summary, RunEvaluation):
        summary = summary.to_json()
    if not isinstance(summary, dict):
        raise InputError(f"summary must be what evaluate returns, got {summary!r}")
    missing = [key for key in _REQUIRED_KEYS if key not in summary]
    gospa_summary = summary.get("gospa")
    if isinstance(gospa_summary, dict):
        missing += [f"gospa.{key}" for key in _REQUIRED_GOSPA_KEYS if key not in gospa_summary]
    if missing:
        raise InputError(f"summary is missing the keys {missing} (expected evaluate's output)")
    if not isinstance(gospa_summary, dict):
        raise InputError(
            f"summary['gospa'] must be a dictionary (evaluate's output), got {gospa_summary!r}"
        )
    g = gospa_summary
    p = f"{float(g['p']):g}"
    rows = [
        (f"GOSPA mean (c={float(g['c']):g}, p={float(g['p']):g}, alpha=2)", g["mean_total"]),
        (f"  localisation part of GOSPA^{p}, mean", g["mean_localisation"]),
        (f"  missed part of GOSPA^{p}, mean", g["mean_missed"]),
        (f"  false part of GOSPA^{p}, mean", g["mean_false"]),
    ]
    rows += _pgospa_rows(summary.get("pgospa"))
    rows += [
        ("missed targets per time", g["mean_num_missed"]),
        ("false estimates per time", g["mean_num_false"]),
        ("position RMSE", summary["position_rmse"]),
        ("assigned pairs", summary["num_assigned_pairs"]),
        ("mean |cardinality error|", summary["mean_abs_cardinality_error"]),
        ("evaluation times", summary["num_times"]),
    ]
    tg = summary.get("tgospa")
    if isinstance(tg, dict):
        bound = "" if tg.get("method") == "milp" else ", LP lower bound"
        rows += [
            (
                f"T-GOSPA (c={float(tg['c']):g}, p={float(tg['p']):g}, "
                f"gamma={float(tg['gamma']):g}{bound})",
                tg["total"],
            ),
            (f"  localisation part of T-GOSPA^{p}", tg["localisation"]),
            (f"  missed part of T-GOSPA^{p}", tg["missed"]),
            (f"  false part of T-GOSPA^{p}", tg["false"]),
            (f"  switching part of T-GOSPA^{p}", tg["switching"]),
            ("  switches (full 1, start or end 1/2)", tg["num_switches"]),
        ]
    fragmentation = summary.get("fragmentation")
    if isinstance(fragmentation, dict):
        rows += [
            ("fragments per tracked target", fragmentation["fragments_per_target"]),
            ("identity switches", fragmentation["id_switches"]),
        ]
    texts = [(name, _number(value)) for name, value in rows]
    name_width = max(len(name) for name, _ in texts)
    value_width = max(len(text) for _, text in texts)
    return "\n".join(f"{name:<{name_width}}  {text:>{value_width}}" for name, text in texts)
