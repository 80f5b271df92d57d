"""One recording in overlapping segments: the plan, the stitching, agreement with a run."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.segments import (
    Segment,
    SegmentResult,
    plan_segments,
    run_segmented,
    stitch_segments,
)
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.evaluation.tables import evaluate_tables


def test_plan_by_hand() -> None:
    # 100 scans in 3: bounds 0, 33, 67, 100; overlap 10 -> cuts 28 and 62 (middles).
    assert plan_segments(100, segments=3, overlap=10) == [
        Segment(0, 0, 33, 0, 28),
        Segment(1, 23, 67, 28, 62),
        Segment(2, 57, 100, 62, 100),
    ]
    assert plan_segments(7, segments=1, overlap=5) == [Segment(0, 0, 7, 0, 7)]
    with pytest.raises(InputError, match="fewer than the overlap of 20; use at most 5"):
        plan_segments(100, segments=6, overlap=20)
    with pytest.raises(InputError, match="segments must be an integer >= 1, got 0"):
        plan_segments(100, segments=0, overlap=10)


def _line_scans(n: int) -> list[Scan]:
    """Scan k holds detections 10 k (target A) and 10 k + 1 (target B)."""
    return [
        Scan(float(k), "pos", np.array([[float(k), 0.0], [float(k), 50.0]]),
             np.array([10 * k, 10 * k + 1]))
        for k in range(n)
    ]  # fmt: skip


def test_stitching_by_hand() -> None:
    """Pieces sharing detections in the overlap chain; the owned ranges decide the rest.

    (The stitched set is not refined here: ``refine_passes = 0``.)"""
    scenario = build_scenario("crossing", 0)
    config = dataclasses.replace(
        scenario.config,
        estimator=dataclasses.replace(scenario.config.estimator, refine_passes=0),
    )
    scans = _line_scans(12)
    first, second = Segment(0, 0, 8, 0, 6), Segment(1, 4, 12, 6, 12)
    a = tuple(10 * k for k in range(12))
    b = tuple(10 * k + 1 for k in range(12))
    results = [
        # Segment 0: A whole, B from scan 0 to 5 only (it ends B early).
        SegmentResult(first, {1: a[:8], 2: b[:6]}, (), 1.0),
        # Segment 1 (scans 4..11): B is its track 1 from scan 4, A its track 2 from scan 5.
        SegmentResult(second, {1: b[4:], 2: a[5:]}, (), 2.0),
    ]
    stitched = stitch_segments(scans, results, config)
    assert stitched.track_rows == {1: a, 2: b}  # one track each, numbered by first detection
    assert stitched.seconds == 3.0
    # Without shared detections in the overlap, pieces stay apart: B's second piece starts
    # at the cut (scan 6), its own track.
    results[1] = SegmentResult(second, {1: b[7:], 2: a[5:]}, (), 2.0)
    stitched = stitch_segments(scans, results, config)
    assert stitched.track_rows == {1: a, 2: b[:6], 3: b[7:]}


def test_one_segment_is_the_sequential_run() -> None:
    scenario = build_scenario("turning", 2, scans=30)
    sequential = WindowEstimator(config=scenario.config).run(scenario.scans)
    single = run_segmented(scenario.config, scenario.scans, segments=1)
    assert single.track_rows == sequential.track_rows
    np.testing.assert_array_equal(single.tracks.states, sequential.tracks.states)
    assert [w.to_json(timings=False) for w in single.windows] == [
        w.to_json(timings=False) for w in sequential.windows
    ]


@pytest.mark.slow
def test_segments_agree_with_the_sequential_run() -> None:
    """On a long crossing recording three segments find the sequential run's tracks
    (180 scans: segments of 60, each far longer than a window)."""
    scenario = build_scenario("crossing", 1, scans=180)
    sequential = WindowEstimator(config=scenario.config).run(scenario.scans)
    segmented = run_segmented(scenario.config, scenario.scans, segments=3)
    same = set(sequential.track_rows.values()) & set(segmented.track_rows.values())
    assert len(same) >= 0.95 * len(sequential.track_rows)
    used = [row for rows in segmented.track_rows.values() for row in rows]
    assert len(used) == len(set(used)), "a detection used twice"
    ours = evaluate_tables(scenario.truth, segmented.tracks, c=10.0).gospa.mean_total
    theirs = evaluate_tables(scenario.truth, sequential.tracks, c=10.0).gospa.mean_total
    assert ours == pytest.approx(theirs, rel=0.02)
    # The owned windows tile the recording: each scan committed by exactly one window.
    committed = sum(w.committed_scans for w in segmented.windows)
    assert committed == len(scenario.scans)
    assert [w.window for w in segmented.windows] == list(range(len(segmented.windows)))
