"""evaluate_tables warns when the tracks and the truth share no time."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from mapassoc.data.io import TrackTable, TruthTable
from mapassoc.evaluation.tables import disjoint_times_message, evaluate_tables

NAMES = ("x", "y")


def truth(times: list[float]) -> TruthTable:
    count = len(times)
    return TruthTable(
        target_ids=np.ones(count, dtype=np.int64),
        times=np.array(times),
        states=np.zeros((count, 2)),
        state_names=NAMES,
    )


def tracks(times: list[float]) -> TrackTable:
    count = len(times)
    return TrackTable(
        track_ids=np.zeros(count, dtype=np.int64),
        times=np.array(times),
        sensors=("pos",) * count,
        states=np.zeros((count, 2)),
        variances=np.ones((count, 2)),
        detection_rows=-np.ones(count, dtype=np.int64),
        state_names=NAMES,
    )


def test_disjoint_times_warn_naming_both_ranges_and_every_point_is_missed_or_false() -> None:
    expected = (
        r"the tracks \(times 1000 to 1002 \(3 distinct\)\) and the truth \(times 0 to 1\.5 "
        r"\(4 distinct\)\) share no time: every target counts as missed and every track as "
        r"false; check that both files come from the same recording and clock"
    )
    with pytest.warns(UserWarning, match=expected):
        result = evaluate_tables(
            truth([0.0, 0.5, 1.0, 1.5]), tracks([1000.0, 1001.0, 1002.0]), c=10.0
        )
    # No time is shared, so no target is ever matched: GOSPA is all missed and false.
    assert result.num_assigned_pairs == 0 and result.position_rmse is None
    assert int(result.gospa.num_missed.sum()) == 4 and int(result.gospa.num_false.sum()) == 3


def test_one_shared_time_or_an_empty_table_gives_no_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        evaluate_tables(truth([0.0, 1.0]), tracks([1.0, 2.0]), c=10.0)
        evaluate_tables(truth([0.0, 1.0]), tracks([]), c=10.0)
    assert disjoint_times_message(truth([0.0, 1.0]), tracks([1.0])) is None
    assert disjoint_times_message(truth([0.0]), tracks([2.0, 3.0])) == (
        "the tracks (times 2 to 3 (2 distinct)) and the truth (times 0 to 0 (1 distinct)) "
        "share no time: every target counts as missed and every track as false; check that "
        "both files come from the same recording and clock"
    )


def test_an_empty_truth_is_named() -> None:
    """A header-only truth file once gave a GOSPA without a word: every track false."""
    assert disjoint_times_message(truth([]), tracks([5.0, 6.0])) == (
        "the truth has no record: the 2 track rows (times 5 to 6 (2 distinct)) all count as "
        "false; check that it is the truth file of this recording"
    )
    assert "nothing to evaluate" in (disjoint_times_message(truth([]), tracks([])) or "")
    with pytest.warns(UserWarning, match="the truth has no record"):
        result = evaluate_tables(truth([]), tracks([5.0, 6.0]), c=10.0)
    assert int(result.gospa.num_false.sum()) == 2


def test_score_tracks_warns_too() -> None:
    from mapassoc.evaluation.scoring import score_tracks
    from mapassoc.trackers.base import TrackerOutput

    output = TrackerOutput(tracks=tracks([10.0, 11.0]), seconds=0.0)
    with pytest.warns(UserWarning, match="share no time"):
        score_tracks(truth([0.0, 1.0]), output, c=5.0, clear_mot_scores=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        score_tracks(truth([10.0, 11.0]), output, c=5.0, clear_mot_scores=False)
