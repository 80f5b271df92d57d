"""Evaluate estimated tracks against truth: file tables in, metric summaries out.

Adapts :class:`~mapassoc.data.io.TruthTable` and :class:`~mapassoc.data.io.TrackTable` to the
point sets of :mod:`mapassoc.evaluation.metrics`.  Positions are the ``x``, ``y`` (and ``z``)
state columns present in both tables.  A track written twice at one time (two sensors
scanning at the same time) is counted once, with its last row.

:func:`evaluate_tables` warns (``UserWarning``) when the tracks and the truth share no
time (:func:`disjoint_times_message`): every metric is then all missed and all false,
which almost always means files from different recordings or clocks.

:func:`pgospa_tables` scores the tracks with their existence probabilities (the tracks
file's optional ``existence`` column, :func:`track_existence`) by the probabilistic GOSPA
of Xia, García-Fernández, Karlsson, Yuan, Chang and Svensson
(:mod:`mapassoc.evaluation.pgospa`), so that the existence column is judged as well as the
positions; :func:`pgospa_summary` gives its means over time.
"""

from __future__ import annotations

import warnings

import numpy as np

from mapassoc.data.io import TrackTable, TruthTable
from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import RunEvaluation, TimedPoints, _check_alpha, evaluate
from mapassoc.evaluation.pgospa import PgospaSeries, pgospa_over_time
from mapassoc.validation import check_instance

__all__ = [
    "position_names",
    "truth_points",
    "track_points",
    "evaluate_tables",
    "track_existence",
    "pgospa_tables",
    "pgospa_summary",
    "disjoint_times_message",
]

_AXES = ("x", "y", "z")


def _check_tables(truth: object, tracks: object, caller: str = "evaluate_tables") -> None:
    """Raise an InputError unless ``truth`` is a TruthTable and ``tracks`` a TrackTable."""
    order = f"{caller}(truth, tracks, c=...): the truth comes first"
    swapped = isinstance(truth, TrackTable) and isinstance(tracks, TruthTable)
    hint = f"the two are swapped; {order}" if swapped else None
    check_instance(
        "truth", truth, TruthTable, hint=hint or "read one with mapassoc.read_truth_file(path)"
    )
    check_instance(
        "tracks", tracks, TrackTable, hint="read one with mapassoc.read_tracks_file(path)"
    )


def position_names(truth: TruthTable, tracks: TrackTable) -> tuple[str, ...]:
    """The position columns both tables have, in x, y, z order."""
    names = tuple(a for a in _AXES if a in truth.state_names and a in tracks.state_names)
    if not names:
        raise InputError(
            f"truth columns {truth.state_names} and track columns {tracks.state_names} share "
            "no position column (x, y or z)"
        )
    return names


def truth_points(truth: TruthTable, names: tuple[str, ...]) -> TimedPoints:
    """The truth's positions (the state components ``names``) as ``TimedPoints``."""
    cols = [truth.state_names.index(n) for n in names]
    return TimedPoints.from_unsorted(
        times=truth.times, ids=truth.target_ids, positions=truth.states[:, cols]
    )


def _last_rows(tracks: TrackTable) -> np.ndarray:
    """Indices, increasing, of the last row of each (track, time) of ``tracks``."""
    # Iterate in reverse and keep first occurrences.
    keys = list(zip(tracks.track_ids.tolist(), tracks.times.tolist(), strict=True))
    seen: set[tuple[int, float]] = set()
    last_rows: list[int] = []
    for i in range(len(keys) - 1, -1, -1):
        if keys[i] not in seen:
            seen.add(keys[i])
            last_rows.append(i)
    return np.array(sorted(last_rows), dtype=np.int64)


def track_points(tracks: TrackTable, names: tuple[str, ...]) -> TimedPoints:
    """The tracks' positions (the state components ``names``) as ``TimedPoints``, one point
    per track and time (its last row)."""
    cols = [tracks.state_names.index(n) for n in names]
    keep = _last_rows(tracks)
    return TimedPoints.from_unsorted(
        times=tracks.times[keep], ids=tracks.track_ids[keep], positions=tracks.states[keep][:, cols]
    )


def track_existence(tracks: TrackTable) -> np.ndarray:
    """The existence probability of every row of ``tracks``, shape ``(N,)``.

    Taken from the table's ``existence`` column.  A table without that column, and a row
    whose cell is empty (``nan``), count as existence 1: a tracker that states no
    probability reports its tracks as certain, which is how GOSPA scores them, so
    P-GOSPA then equals GOSPA (alpha = 2) at every time.

    Returns
    -------
    ndarray, shape (N,)
        In [0, 1], one per row of ``tracks`` (in its order).

    Raises
    ------
    InputError
        ``tracks`` is not a TrackTable.
    """
    check_instance(
        "tracks", tracks, TrackTable, hint="read one with mapassoc.read_tracks_file(path)"
    )
    if tracks.existence is None:
        return np.ones(tracks.size)
    values = np.array(tracks.existence, dtype=float)
    return np.where(np.isnan(values), 1.0, values)


def evaluate_tables(
    truth: TruthTable,
    tracks: TrackTable,
    *,
    c: float,
    p: float = 2.0,
    switch_cost: float | None = None,
    tgospa_method: str = "milp",
) -> RunEvaluation:
    """GOSPA (over time, with its parts), position RMSE and cardinality error of tracks vs truth.

    Evaluated at every time that has a truth or a track row (both files are written at
    scan times): a truth time without tracks counts its targets as missed, a track time
    without targets counts its tracks as false.  Warns (``UserWarning``) when the two
    share no time (:func:`disjoint_times_message`).  With a ``switch_cost`` (gamma > 0) it
    adds T-GOSPA of the trajectories (one target id, one track id = one trajectory) and the
    fragments per target (:func:`mapassoc.evaluation.metrics.evaluate`).

    Raises
    ------
    InputError
        ``truth`` not a TruthTable or ``tracks`` not a TrackTable (the message says when
        the two are swapped), or a bad ``c``, ``p``, ``switch_cost`` or ``tgospa_method``.
    """
    _check_tables(truth, tracks)
    names = position_names(truth, tracks)
    message = disjoint_times_message(truth, tracks)
    if message is not None:
        warnings.warn(message, UserWarning, stacklevel=2)
    return evaluate(
        truth_points(truth, names),
        track_points(tracks, names),
        c=c,
        p=p,
        switch_cost=switch_cost,
        tgospa_method=tgospa_method,
    )


def pgospa_tables(
    truth: TruthTable,
    tracks: TrackTable,
    *,
    c: float,
    p: float = 2.0,
    alpha: float = 2.0,
) -> PgospaSeries:
    """P-GOSPA of the tracks, with their existence probabilities, against the truth, at every
    time that has a truth or a track row.

    The probabilistic GOSPA of Xia, García-Fernández, Karlsson, Yuan, Chang and Svensson
    (:func:`mapassoc.evaluation.pgospa.pgospa_over_time`): the truth has existence 1 and
    each track point the existence of its row (:func:`track_existence`; 1 without the
    column).  A track written twice at one time counts once, with its last row, as in
    :func:`evaluate_tables`.  With every existence 1 it equals GOSPA (alpha = 2) at every
    time; an existence ``r < 1`` on a track near a target costs ``(1 - r) c^p / 2`` of
    existence mismatch (less localisation), and on a false track saves ``(1 - r) c^p / 2``
    of its false part.  Warns
    (``UserWarning``) when the two tables share no time (:func:`disjoint_times_message`).

    Parameters
    ----------
    truth : TruthTable
    tracks : TrackTable
        Its ``existence`` column, where present, is scored.
    c : float
        Cut-off distance, > 0.
    p : float
        Order, ``1 <= p < inf``.
    alpha : float
        Must be 2, the only value for which P-GOSPA is defined by Xia et al. (and GOSPA
        splits into its parts).

    Returns
    -------
    PgospaSeries
        Per evaluation time, shape (T,) each.

    Raises
    ------
    InputError
        ``truth`` not a TruthTable or ``tracks`` not a TrackTable (the message says when
        the two are swapped), a bad ``c``, ``p`` or ``alpha``, no shared position column,
        or no row in either table.
    """
    _check_tables(truth, tracks, caller="pgospa_tables")
    _check_alpha(alpha)
    names = position_names(truth, tracks)
    message = disjoint_times_message(truth, tracks)
    if message is not None:
        warnings.warn(message, UserWarning, stacklevel=2)
    keep = _last_rows(tracks)
    cols = [tracks.state_names.index(n) for n in names]
    times = tracks.times[keep]
    # The same stable sort by time as TimedPoints.from_unsorted, so that the existence
    # values stay with their rows.
    order = np.argsort(times, kind="stable")
    estimates = TimedPoints(
        times=times[order],
        ids=tracks.track_ids[keep][order],
        positions=tracks.states[keep][:, cols][order],
    )
    existence = track_existence(tracks)[keep][order]
    return pgospa_over_time(truth_points(truth, names), estimates, existence, c=c, p=p)


def pgospa_summary(series: PgospaSeries) -> dict[str, float | int]:
    """The means over time of a P-GOSPA series, JSON-ready (``mapassoc evaluate --json``
    writes it as ``"pgospa"``).

    Returns
    -------
    dict
        ``c``, ``p``, ``alpha`` (2), ``num_times``, ``mean_total`` (mean of the per-time
        P-GOSPA values), and the means over time of its p-th power parts
        ``mean_localisation``, ``mean_existence_mismatch``, ``mean_missed`` and
        ``mean_false`` (at each time they add up to P-GOSPA^p).

    Raises
    ------
    InputError
        ``series`` is not a PgospaSeries.
    """
    check_instance("series", series, PgospaSeries, hint="compute one with pgospa_tables")
    return {
        "c": float(series.c),
        "p": float(series.p),
        "alpha": 2.0,
        "num_times": int(series.times.shape[0]),
        "mean_total": series.mean_total,
        "mean_localisation": float(np.mean(series.localisation)),
        "mean_existence_mismatch": float(np.mean(series.existence_mismatch)),
        "mean_missed": float(np.mean(series.missed)),
        "mean_false": float(np.mean(series.false)),
    }


def _time_range(times: np.ndarray) -> str:
    distinct = np.unique(times)
    return f"times {distinct[0]:.10g} to {distinct[-1]:.10g} ({distinct.size} distinct)"


def disjoint_times_message(truth: TruthTable, tracks: TrackTable) -> str | None:
    """A warning when the truth is empty, or when tracks and truth share no time.

    Evaluation pairs tracks with targets at equal times, so with no common time every
    target counts as missed and every track as false.  A truth with no record at all
    (a header-only file) makes every track false and is almost always the wrong file, so
    it gets a message too; empty tracks get none (no tracks is a legitimate result).

    Returns
    -------
    str or None
        The message, naming the time ranges, or None when a time is shared (or only the
        tracks are empty).
    """
    if truth.size == 0:
        counted = (
            f"the {tracks.size} track rows ({_time_range(tracks.times)}) all count as false"
            if tracks.size
            else "there is nothing to evaluate (the tracks are empty too)"
        )
        return (
            f"the truth has no record: {counted}; check that it is the truth file of this "
            "recording"
        )
    if tracks.size == 0:
        return None
    if np.intersect1d(truth.times, tracks.times).size:
        return None
    return (
        f"the tracks ({_time_range(tracks.times)}) and the truth ({_time_range(truth.times)}) "
        "share no time: every target counts as missed and every track as false; check that "
        "both files come from the same recording and clock"
    )
