"""How well a tracker's p(K | Z) predicts the true number of targets K.

The true K of a time span ``[start_time, end_time]`` (both ends included) is the number of
distinct truth targets with a truth record at a time in the span: a target alive at one of
the span's scans, detected or not (:func:`window_target_counts`, the definition of
``mapassoc bench``).  Against it, per span with ``p`` the predicted distribution over K
(padded with zeros up to the true K) and ``k`` the true K:

* Brier score ``sum_K (p[K] - 1[K = k])^2`` (Brier, Monthly Weather Review 78, 1950, in
  its original multi-category form): 0 for certainty on the true K, 2 for certainty on a
  wrong one;
* hit: whether the reported K (the mode of p, first of ties, or a window's ``marginal_k``)
  equals ``k``;
* ``p[k]``, the probability given to the true K.

Each is averaged over the spans.  Calibration is measured by the top-label expected
calibration error (Naeini, Cooper and Hauskrecht, "Obtaining well calibrated probabilities
using Bayesian binning", AAAI 2015; Guo, Pleiss, Sun and Weinberger, "On calibration of
modern neural networks", ICML 2017, eq. (3))::

    ECE = sum_{b=1}^{M} (|B_b| / n) |acc(B_b) - conf(B_b)|

where the confidence of a span is the probability of its reported K, ``B_b`` the spans whose
confidence falls in ``((b - 1) / M, b / M]`` (a confidence of exactly 0 in the first bin),
``acc`` the fraction of hits and ``conf`` the mean confidence of a bin.  0 for a calibrated
predictor; the value depends on the number of bins ``M``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from numbers import Real
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.data.io import TruthTable
from mapassoc.data.outputs import CountSeries
from mapassoc.errors import InputError

__all__ = [
    "CountScores",
    "count_scores",
    "count_series_scores",
    "expected_calibration_error",
    "span_target_counts",
    "window_target_counts",
]

DEFAULT_BINS = 10
"""Bins of the expected calibration error (Guo et al. 2017 use 15, Naeini et al. 10)."""


@dataclass(frozen=True)
class CountScores:
    """How well p(K | Z) predicted the true number of targets, averaged over spans.

    Parameters
    ----------
    brier : float
        Mean Brier score ``sum_K (p(K | Z) - 1[K = true K])^2``, in [0, 2] for
        probability vectors.
    hit_rate : float
        Fraction of spans whose reported K is the true K.
    mean_p_true : float
        Mean p(true K | Z).
    ece : float
        Top-label expected calibration error over ``num_bins`` equal-width bins, in [0, 1].
    num_spans : int
        Spans (windows) scored.
    num_bins : int
        Bins of ``ece``.
    """

    brier: float
    hit_rate: float
    mean_p_true: float
    ece: float
    num_spans: int
    num_bins: int


class _WindowSpan(Protocol):
    """What :func:`window_target_counts` reads of a window (e.g. a ``WindowReport``)."""

    @property
    def start_time(self) -> float: ...

    @property
    def end_time(self) -> float: ...


class _WindowCount(Protocol):
    """What :func:`count_scores` reads of a window (e.g. a ``WindowReport``)."""

    @property
    def p_k(self) -> ArrayLike: ...

    @property
    def marginal_k(self) -> int: ...


# ----------------------------------------------------------------------------------------------
# True K per span
# ----------------------------------------------------------------------------------------------


def _count_in_spans(
    truth: TruthTable, spans: Sequence[tuple[object, object]], name: str
) -> NDArray[np.int64]:
    if not isinstance(truth, TruthTable):
        raise InputError(f"truth must be a TruthTable, got {type(truth).__name__}")
    ids = np.asarray(truth.target_ids)
    times = np.asarray(truth.times, dtype=float)
    counts = np.empty(len(spans), dtype=np.int64)
    for i, (start, end) in enumerate(spans):
        if not (
            isinstance(start, Real)
            and isinstance(end, Real)
            and math.isfinite(start)
            and math.isfinite(end)
            and start <= end
        ):
            raise InputError(
                f"{name}[{i}] must have finite start_time <= end_time, got start_time "
                f"{start!r} and end_time {end!r}"
            )
        inside = (times >= start) & (times <= end)
        counts[i] = np.unique(ids[inside]).size
    return counts


def window_target_counts(truth: TruthTable, windows: Sequence[_WindowSpan]) -> NDArray[np.int64]:
    """The true number of targets in each window.

    A target is in a window when the truth has a record of it at a time in
    ``[start_time, end_time]`` of the window (both ends included).

    Parameters
    ----------
    truth : TruthTable
        One record per (target, time) at which the target is alive.
    windows : sequence of window-like
        Anything with ``start_time`` and ``end_time`` (finite, ``start_time <= end_time``),
        such as :class:`~mapassoc.estimator.pipeline.WindowReport`.

    Returns
    -------
    ndarray of int64, shape (len(windows),)
        Distinct ``truth.target_ids`` with a record in each window.

    Raises
    ------
    InputError
        ``truth`` not a TruthTable, or a window without finite times in order.

    Examples
    --------
    Target 0 alive at t = 0, 1, 2 and target 1 at t = 2, 3: the window [0, 1] holds one
    target, [1, 2] two and [3, 4] one.
    """
    return _count_in_spans(truth, [(w.start_time, w.end_time) for w in windows], "windows")


def span_target_counts(
    truth: TruthTable, start_times: ArrayLike, end_times: ArrayLike
) -> NDArray[np.int64]:
    """:func:`window_target_counts` for spans given as arrays.

    Parameters
    ----------
    truth : TruthTable
    start_times, end_times : array_like, shape (m,)
        Span ends, ``start_times[i] <= end_times[i]``.

    Returns
    -------
    ndarray of int64, shape (m,)
    """
    start = np.asarray(start_times, dtype=float)
    end = np.asarray(end_times, dtype=float)
    if start.ndim != 1 or end.shape != start.shape:
        raise InputError(
            f"start_times and end_times must be 1-D of equal length, got shapes {start.shape} "
            f"and {end.shape}"
        )
    return _count_in_spans(truth, list(zip(start.tolist(), end.tolist(), strict=True)), "spans")


# ----------------------------------------------------------------------------------------------
# Scores
# ----------------------------------------------------------------------------------------------


def _check_bins(num_bins: object) -> int:
    if isinstance(num_bins, bool) or not isinstance(num_bins, int | np.integer) or num_bins < 1:
        raise InputError(f"num_bins must be an integer >= 1, got {num_bins!r}")
    return int(num_bins)


def expected_calibration_error(
    confidences: ArrayLike, correct: ArrayLike, *, num_bins: int = DEFAULT_BINS
) -> float:
    """Expected calibration error (Naeini et al. 2015; Guo et al. 2017, eq. (3)).

    Parameters
    ----------
    confidences : array_like, shape (n,)
        Predicted probability of each reported outcome, in [0, 1]; n >= 1.
    correct : array_like of bool, shape (n,)
        Whether each reported outcome happened.
    num_bins : int
        Equal-width bins ``((b - 1) / M, b / M]`` of [0, 1] (0 goes to the first).

    Returns
    -------
    float
        ``sum_b (|B_b| / n) |acc(B_b) - conf(B_b)|``, in [0, 1].

    Examples
    --------
    Confidences 0.8 (correct) and 0.5 (wrong) with 10 bins: ``(1/2) |1 - 0.8| +
    (1/2) |0 - 0.5| = 0.35``.
    """
    bins = _check_bins(num_bins)
    conf = np.asarray(confidences, dtype=float)
    hit = np.asarray(correct)
    if conf.ndim != 1 or conf.size == 0 or not np.all(np.isfinite(conf)) or np.any(
        (conf < 0) | (conf > 1)
    ):
        raise InputError(
            f"confidences must be a non-empty 1-D array of probabilities in [0, 1], got "
            f"{confidences!r}"
        )
    if hit.shape != conf.shape or hit.dtype != bool:
        raise InputError(
            f"correct must be a boolean array of shape {conf.shape}, got {correct!r}"
        )
    edges = np.linspace(0.0, 1.0, bins + 1)
    which = np.maximum(np.digitize(conf, edges, right=True), 1) - 1  # bin ((b-1)/M, b/M]
    error = 0.0
    for b in range(bins):
        members = which == b
        if np.any(members):
            gap = abs(float(np.mean(hit[members])) - float(np.mean(conf[members])))
            error += np.count_nonzero(members) / conf.size * gap
    return float(error)


def _scores(
    distributions: Sequence[NDArray[np.float64]],
    reported: Sequence[int],
    true_counts: NDArray[np.int64],
    num_bins: int,
) -> CountScores:
    n = len(distributions)
    brier = np.empty(n)
    p_true = np.empty(n)
    confidence = np.empty(n)
    hits = np.empty(n, dtype=bool)
    for i, (p, r, k) in enumerate(zip(distributions, reported, true_counts.tolist(), strict=True)):
        full = np.zeros(max(p.size, k + 1, r + 1))
        full[: p.size] = p
        indicator = np.zeros_like(full)
        indicator[k] = 1.0
        brier[i] = float(np.sum((full - indicator) ** 2))
        p_true[i] = full[k]
        confidence[i] = full[r]
        hits[i] = r == k
    return CountScores(
        brier=float(brier.mean()),
        hit_rate=float(hits.mean()),
        mean_p_true=float(p_true.mean()),
        ece=expected_calibration_error(confidence, hits, num_bins=num_bins),
        num_spans=n,
        num_bins=num_bins,
    )


def _check_true_counts(true_counts: ArrayLike, n: int, what: str) -> NDArray[np.int64]:
    truth_k = np.asarray(true_counts)
    if (
        truth_k.shape != (n,)
        or not np.issubdtype(truth_k.dtype, np.integer)
        or np.any(truth_k < 0)
    ):
        raise InputError(
            f"true_counts must hold one integer >= 0 per {what} ({n}), got {true_counts!r}"
        )
    return truth_k.astype(np.int64)


def count_scores(
    windows: Sequence[_WindowCount], true_counts: ArrayLike, *, num_bins: int = DEFAULT_BINS
) -> CountScores:
    """Score the windows' p(K | Z) against the true numbers of targets.

    Per window, with ``p = p_k`` padded with zeros up to the true K and ``k`` the true K:
    the Brier score ``sum_K (p[K] - 1[K = k])^2``, whether ``marginal_k == k``, ``p[k]``
    and, for the ECE, the confidence ``p[marginal_k]``.

    Parameters
    ----------
    windows : sequence of window-like
        Anything with ``p_k`` (1-D, p(K | Z) for K = 0, 1, ...) and ``marginal_k`` (the
        reported K, >= 0), such as :class:`~mapassoc.estimator.pipeline.WindowReport`; at
        least one.
    true_counts : array_like of int, shape (len(windows),)
        True K of each window (:func:`window_target_counts`), >= 0.
    num_bins : int
        Bins of the expected calibration error.

    Returns
    -------
    CountScores

    Raises
    ------
    InputError
        No window, ``true_counts`` not one integer >= 0 per window, ``p_k`` not a 1-D
        vector of probabilities in [0, 1], ``marginal_k`` not an integer >= 0, or bad
        ``num_bins``.

    Examples
    --------
    Windows with p = (0.8, 0.2), marginal K 0, true K 0, and p = (0.5, 0.5), marginal K 0,
    true K 2: Brier scores 0.04 + 0.04 = 0.08 and 0.25 + 0.25 + 1 = 1.5, mean 0.79; hit
    rate 0.5; mean p(true K) (0.8 + 0) / 2 = 0.4; ECE with 10 bins 0.35.
    """
    windows = list(windows)
    if not windows:
        raise InputError("windows must contain at least one window, got none")
    bins = _check_bins(num_bins)
    truth_k = _check_true_counts(true_counts, len(windows), "window")
    distributions = []
    reported = []
    for i, window in enumerate(windows):
        p = np.asarray(window.p_k, dtype=float)
        if p.ndim != 1 or not np.all(np.isfinite(p)) or np.any((p < 0) | (p > 1)):
            raise InputError(
                f"windows[{i}].p_k must be a 1-D vector of probabilities in [0, 1], got "
                f"{window.p_k!r}"
            )
        k = window.marginal_k
        if isinstance(k, bool) or not isinstance(k, int | np.integer) or k < 0:
            raise InputError(f"windows[{i}].marginal_k must be an integer >= 0, got {k!r}")
        distributions.append(p)
        reported.append(int(k))
    return _scores(distributions, reported, truth_k, bins)


def count_series_scores(
    truth: TruthTable, counts: CountSeries, *, num_bins: int = DEFAULT_BINS
) -> CountScores:
    """Score any tracker's :class:`~mapassoc.data.outputs.CountSeries` against the truth.

    The true K of each span is :func:`span_target_counts`; the reported K is the mode of
    the span's distribution (the first of tied maxima, as ``WindowReport.marginal_k``).

    Parameters
    ----------
    truth : TruthTable
    counts : CountSeries
        At least one span.
    num_bins : int
        Bins of the expected calibration error.

    Returns
    -------
    CountScores
    """
    if not isinstance(counts, CountSeries):
        raise InputError(f"counts must be a CountSeries, got {type(counts).__name__}")
    if counts.size == 0:
        raise InputError("counts must contain at least one span, got none")
    bins = _check_bins(num_bins)
    truth_k = span_target_counts(truth, counts.start_times, counts.end_times)
    rows = [np.asarray(row, dtype=float) for row in counts.probabilities]
    modes = [int(np.flatnonzero(row == np.max(row))[0]) for row in rows]
    return _scores(rows, modes, truth_k, bins)
