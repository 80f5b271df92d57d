"""Tests of mapassoc.evaluation.clear_mot: CLEAR-MOT (Bernardin and Stiefelhagen 2008) and
the mostly tracked / lost and fragmentation counts (Li, Huang and Nevatia 2009)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import TimedPoints

pytest.importorskip("motmetrics")

from mapassoc.evaluation.clear_mot import clear_mot, motmetrics_available  # noqa: E402


def run(rows: list[tuple[float, int, tuple[float, ...]]]) -> TimedPoints:
    """A TimedPoints from (time, id, position) rows in any order."""
    return TimedPoints.from_unsorted(
        times=[r[0] for r in rows], ids=[r[1] for r in rows], positions=[r[2] for r in rows]
    )


def hand_worked_sequence() -> tuple[TimedPoints, TimedPoints]:
    """Targets 1 (y = 0) and 2 (y = 5) at frames 0..3, moving one unit per frame in x.

    frame 0: track 1 on target 1 (0.1 off), track 2 on target 2 (0.2 off)
    frame 1: track 1 (0.1), target 2 now matched by track 3 (0.3 off): an id switch
    frame 2: track 1 (0.1), target 2 not covered: a miss (and a fragmentation of target 2)
    frame 3: track 1 (0.1), track 3 on target 2 again (0.4 off), track 4 far away: a false
             positive
    """
    truth = run(
        [(float(t), 1, (float(t), 0.0)) for t in range(4)]
        + [(float(t), 2, (float(t), 5.0)) for t in range(4)]
    )
    estimates = run(
        [(float(t), 1, (float(t), 0.1)) for t in range(4)]
        + [
            (0.0, 2, (0.0, 5.2)),
            (1.0, 3, (1.0, 5.3)),
            (3.0, 3, (3.0, 5.4)),
            (3.0, 4, (50.0, 50.0)),
        ]
    )
    return truth, estimates


def test_engine_is_available() -> None:
    assert motmetrics_available()


def test_hand_worked_switch_fragmentation_false_positive_and_miss() -> None:
    truth, estimates = hand_worked_sequence()
    result = clear_mot(truth, estimates, threshold=1.0)
    assert result.num_objects == 8  # sum_t g_t
    assert result.num_unique_objects == 2
    assert result.num_misses == 1
    assert result.num_false_positives == 1
    assert result.num_switches == 1
    assert result.num_fragmentations == 1
    assert result.num_matches == 6  # correspondences that are not switches
    # MOTA = 1 - (FN + FP + IDSW) / GT = 1 - (1 + 1 + 1) / 8.
    assert result.mota == pytest.approx(0.625)
    # MOTP: mean Euclidean distance over the 7 correspondences (the switch included):
    # track 1 at 0.1 four times, then 0.2, 0.3 and 0.4 on target 2.
    assert result.motp == pytest.approx((4 * 0.1 + 0.2 + 0.3 + 0.4) / 7)
    # Target 1 matched at 4/4 frames (mostly tracked), target 2 at 3/4 (partially).
    assert (result.mostly_tracked, result.partially_tracked, result.mostly_lost) == (1, 1, 0)
    assert result.threshold == 1.0


def test_threshold_is_strict_and_decides_correspondence() -> None:
    truth = run([(0.0, 1, (0.0, 0.0)), (1.0, 1, (1.0, 0.0))])
    estimates = run([(0.0, 9, (0.0, 2.0)), (1.0, 9, (1.0, 2.0))])
    # At distance exactly the threshold no pair may correspond: 2 misses + 2 false positives.
    at = clear_mot(truth, estimates, threshold=2.0)
    assert (at.num_misses, at.num_false_positives, at.num_matches) == (2, 2, 0)
    assert at.mota == pytest.approx(1.0 - 4.0 / 2.0)  # MOTA may be negative
    assert math.isnan(at.motp)
    assert at.mostly_lost == 1
    above = clear_mot(truth, estimates, threshold=2.5)
    assert (above.num_misses, above.num_false_positives, above.num_matches) == (0, 0, 2)
    assert above.mota == 1.0
    assert above.motp == pytest.approx(2.0)


def test_mapping_persistence_keeps_a_valid_correspondence() -> None:
    """Bernardin and Stiefelhagen Sec. 2.1: a correspondence that stays within the threshold
    is kept even when another hypothesis comes closer; that hypothesis is a false positive."""
    truth = run([(0.0, 1, (0.0, 0.0)), (1.0, 1, (1.0, 0.0))])
    estimates = run(
        [(0.0, 5, (0.0, 0.5)), (1.0, 5, (1.0, 0.5)), (1.0, 6, (1.0, 0.1))]
    )
    result = clear_mot(truth, estimates, threshold=1.0)
    assert result.num_switches == 0
    assert result.num_false_positives == 1
    assert result.motp == pytest.approx(0.5)


def test_switch_is_counted_against_the_last_correspondence_across_a_miss() -> None:
    """Target matched by track 5, missed, then matched by track 6: one switch, one
    fragmentation; matched again by 6 afterwards: nothing more."""
    truth = run([(float(t), 1, (float(t), 0.0)) for t in range(4)])
    estimates = run(
        [(0.0, 5, (0.0, 0.0)), (2.0, 6, (2.0, 0.0)), (3.0, 6, (3.0, 0.0))]
    )
    result = clear_mot(truth, estimates, threshold=1.0)
    assert (result.num_switches, result.num_fragmentations, result.num_misses) == (1, 1, 1)
    assert result.mota == pytest.approx(1.0 - 2.0 / 4.0)
    assert result.motp == 0.0


@pytest.mark.parametrize(
    ("tracked_frames", "expected"),
    [
        (5, (1, 0, 0)),
        (4, (1, 0, 0)),  # 4/5 = 80 %: mostly tracked (>= 80 %)
        (3, (0, 1, 0)),
        (1, (0, 1, 0)),  # 1/5 = 20 %: partially tracked (>= 20 %)
        (0, (0, 0, 1)),  # < 20 %: mostly lost
    ],
)
def test_mostly_tracked_partially_tracked_mostly_lost(
    tracked_frames: int, expected: tuple[int, int, int]
) -> None:
    truth = run([(float(t), 1, (float(t), 0.0)) for t in range(5)])
    estimates = run(
        [(float(t), 3, (float(t), 0.2)) for t in range(tracked_frames)]
        + [(float(t), 4, (float(t), 30.0)) for t in range(tracked_frames, 5)]
    )
    result = clear_mot(truth, estimates, threshold=1.0)
    assert (result.mostly_tracked, result.partially_tracked, result.mostly_lost) == expected
    assert result.num_misses == 5 - tracked_frames
    assert result.num_false_positives == 5 - tracked_frames


def test_truth_against_itself_is_perfect() -> None:
    truth, _ = hand_worked_sequence()
    result = clear_mot(truth, truth, threshold=0.5)
    assert result.mota == 1.0 and result.motp == 0.0
    assert (result.num_switches, result.num_fragmentations) == (0, 0)
    assert result.mostly_tracked == 2


def test_frames_with_estimates_only_count_false_positives() -> None:
    truth = run([(0.0, 1, (0.0, 0.0))])
    estimates = run([(0.0, 2, (0.0, 0.0)), (1.0, 2, (1.0, 0.0))])
    result = clear_mot(truth, estimates, threshold=1.0)
    assert result.num_false_positives == 1
    assert result.mota == pytest.approx(0.0)
    empty = clear_mot(truth, TimedPoints.empty(2), threshold=1.0)
    assert empty.num_misses == 1 and empty.mota == 0.0 and math.isnan(empty.motp)


def test_bad_inputs() -> None:
    truth, estimates = hand_worked_sequence()
    with pytest.raises(InputError, match="threshold"):
        clear_mot(truth, estimates, threshold=0.0)
    with pytest.raises(InputError, match="truth has no rows"):
        clear_mot(TimedPoints.empty(2), estimates, threshold=1.0)
    with pytest.raises(InputError, match="TimedPoints"):
        clear_mot(np.zeros((2, 2)), estimates, threshold=1.0)  # type: ignore[arg-type]
