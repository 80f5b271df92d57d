"""Evaluate estimated tracks against truth: file tables in, metric summaries out.

Adapts :class:`~mapassoc.data.io.TruthTable` and :class:`~mapassoc.data.io.TrackTable` to the
point sets of :mod:`mapassoc.evaluation.metrics`.  Positions are the ``x``, ``y`` (and ``z``)
state columns present in both tables.  A track written twice at one time (two sensors
scanning at the same time) is counted once, with its last row.

:func:`evaluate_tables` warns (``UserWarning``) when the tracks and the truth share no
time (:func:`disjoint_times_message`): every metric is then all missed and all false,
which almost always means files from different recordings or clocks.
"""

from __future__ import annotations

import warnings

import numpy as np

from mapassoc.data.io import TrackTable, TruthTable
from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import RunEvaluation, TimedPoints, evaluate
from mapassoc.validation import check_instance

__all__ = [
    "position_names",
    "truth_points",
    "track_points",
    "evaluate_tables",
    "disjoint_times_message",
]

_AXES = ("x", "y", "z")


def _check_tables(truth: object, tracks: object) -> None:
    """Raise an InputError unless ``truth`` is a TruthTable and ``tracks`` a TrackTable."""
    order = "evaluate_tables(truth, tracks, c=...): the truth comes first"
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


def track_points(tracks: TrackTable, names: tuple[str, ...]) -> TimedPoints:
    """The tracks' positions (the state components ``names``) as ``TimedPoints``, one point
    per track and time (its last row)."""
    cols = [tracks.state_names.index(n) for n in names]
    # Last row of each (track, time): iterate in reverse and keep first occurrences.
    keys = list(zip(tracks.track_ids.tolist(), tracks.times.tolist(), strict=True))
    seen: set[tuple[int, float]] = set()
    last_rows: list[int] = []
    for i in range(len(keys) - 1, -1, -1):
        if keys[i] not in seen:
            seen.add(keys[i])
            last_rows.append(i)
    keep = np.array(sorted(last_rows), dtype=np.int64)
    return TimedPoints.from_unsorted(
        times=tracks.times[keep], ids=tracks.track_ids[keep], positions=tracks.states[keep][:, cols]
    )


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
