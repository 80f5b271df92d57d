"""P-GOSPA of file tables (:func:`pgospa_tables`, :func:`track_existence`,
:func:`pgospa_summary`): hand-worked values, equality with GOSPA when the table has no
existence column, the existence staying with its row through the time sort and the
last-row rule, and the argument checks."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from mapassoc.data.io import TrackTable, TruthTable
from mapassoc.errors import InputError
from mapassoc.evaluation.tables import (
    evaluate_tables,
    pgospa_summary,
    pgospa_tables,
    track_existence,
)

NAMES = ("x", "y")
C = 10.0  # c^p / 2 = 50 at p = 2, 5 at p = 1


def truth_table(rows: list[tuple[int, float, float, float]]) -> TruthTable:
    """``rows`` of (target id, time, x, y)."""
    return TruthTable(
        target_ids=np.array([r[0] for r in rows], dtype=np.int64),
        times=np.array([r[1] for r in rows], dtype=float),
        states=np.array([[r[2], r[3]] for r in rows], dtype=float).reshape(-1, 2),
        state_names=NAMES,
    )


def track_table(
    rows: list[tuple[int, float, float, float]],
    existence: list[float] | None = None,
    sensors: tuple[str, ...] | None = None,
) -> TrackTable:
    """``rows`` of (track id, time, x, y)."""
    count = len(rows)
    return TrackTable(
        track_ids=np.array([r[0] for r in rows], dtype=np.int64),
        times=np.array([r[1] for r in rows], dtype=float),
        sensors=sensors or ("pos",) * count,
        states=np.array([[r[2], r[3]] for r in rows], dtype=float).reshape(-1, 2),
        variances=np.ones((count, 2)),
        detection_rows=-np.ones(count, dtype=np.int64),
        state_names=NAMES,
        existence=None if existence is None else np.array(existence, dtype=float),
    )


ONE_TARGET = truth_table([(0, 0.0, 0.0, 0.0)])


@pytest.mark.parametrize(
    ("r", "expected_power"),
    [
        # d = 3 < c: r d^2 + (1 - r) c^2 / 2 = 0.5 * 9 + 0.5 * 50 = 29.5.
        (0.5, 29.5),
        # r = 1: the GOSPA value d^2 = 9.
        (1.0, 9.0),
        # r = 0.2: 0.2 * 9 + 0.8 * 50 = 41.8 (omitting it would cost 50).
        (0.2, 41.8),
    ],
)
def test_one_target_one_track_at_distance_three(r: float, expected_power: float) -> None:
    series = pgospa_tables(ONE_TARGET, track_table([(7, 0.0, 3.0, 0.0)], [r]), c=C)
    assert series.total.tolist() == pytest.approx([math.sqrt(expected_power)])
    assert series.localisation.tolist() == pytest.approx([9.0 * r])
    assert series.existence_mismatch.tolist() == pytest.approx([(1.0 - r) * 50.0])
    assert (series.missed.tolist(), series.false.tolist()) == ([0.0], [0.0])


def test_a_false_track_costs_its_existence_times_half_the_cut_off_power() -> None:
    # d = 12 >= c: a miss (50) and a false track of weight 0.3 (0.3 * 50 = 15); p = 1: 5 + 1.5.
    tracks = track_table([(1, 0.0, 12.0, 0.0)], [0.3])
    two = pgospa_tables(ONE_TARGET, tracks, c=C)
    assert (two.missed[0], two.false[0], two.total[0]) == pytest.approx((50.0, 15.0, math.sqrt(65)))
    one = pgospa_tables(ONE_TARGET, tracks, c=C, p=1.0)
    assert one.total[0] == pytest.approx(6.5)


def scenario() -> tuple[TruthTable, list[tuple[int, float, float, float]]]:
    """Two targets over three times; tracks with a miss, a false track and an error."""
    truth = truth_table(
        [(0, 0.0, 0.0, 0.0), (1, 0.0, 50.0, 0.0), (0, 1.0, 1.0, 0.0), (1, 1.0, 51.0, 0.0),
         (0, 2.0, 2.0, 0.0)]
    )
    rows = [(5, 0.0, 0.5, 0.0), (5, 1.0, 1.0, 2.0), (6, 1.0, 80.0, 0.0), (5, 2.0, 2.0, 1.0),
            (9, 3.0, 0.0, 0.0)]
    return truth, rows


def test_without_an_existence_column_it_equals_gospa_at_every_time() -> None:
    truth, rows = scenario()
    gospa = evaluate_tables(truth, track_table(rows), c=C).gospa
    series = pgospa_tables(truth, track_table(rows), c=C)
    np.testing.assert_array_equal(series.times, gospa.times)
    np.testing.assert_allclose(series.total, gospa.total)
    np.testing.assert_allclose(series.localisation, gospa.localisation)
    np.testing.assert_allclose(series.missed, gospa.missed)
    np.testing.assert_allclose(series.false, gospa.false)
    assert not np.any(series.existence_mismatch)
    summary = pgospa_summary(series)
    assert summary["mean_total"] == pytest.approx(gospa.mean_total)


def test_unknown_existence_cells_count_as_one() -> None:
    truth, rows = scenario()
    with_nan = track_table(rows, [math.nan] * len(rows))
    assert track_existence(with_nan).tolist() == [1.0] * len(rows)
    assert track_existence(track_table(rows)).tolist() == [1.0] * len(rows)
    plain = pgospa_tables(truth, track_table(rows), c=C)
    np.testing.assert_allclose(pgospa_tables(truth, with_nan, c=C).total, plain.total)


def test_existence_stays_with_its_row_when_the_rows_are_not_in_time_order() -> None:
    # Time 1 first: track 2 (r = 0.25) on the target, then time 0: track 3 (r = 1) 12 away.
    truth = truth_table([(0, 0.0, 0.0, 0.0), (0, 1.0, 0.0, 0.0)])
    tracks = track_table([(2, 1.0, 0.0, 0.0), (3, 0.0, 12.0, 0.0)], [0.25, 1.0])
    series = pgospa_tables(truth, tracks, c=C)
    assert series.times.tolist() == [0.0, 1.0]
    # Time 0: a miss (50) and a whole false track (50).  Time 1: (1 - 0.25) * 50 = 37.5.
    assert series.total.tolist() == pytest.approx([10.0, math.sqrt(37.5)])
    assert series.existence_mismatch.tolist() == pytest.approx([0.0, 37.5])


def test_a_track_written_twice_at_one_time_counts_once_with_its_last_row() -> None:
    tracks = track_table(
        [(4, 0.0, 9.0, 0.0), (4, 0.0, 3.0, 0.0)], [1.0, 0.5], sensors=("a", "b")
    )
    series = pgospa_tables(ONE_TARGET, tracks, c=C)
    assert series.total.tolist() == pytest.approx([math.sqrt(29.5)])


def test_the_summary_means_add_up_to_the_mean_power() -> None:
    truth, rows = scenario()
    series = pgospa_tables(truth, track_table(rows, [0.9, 0.9, 0.4, 0.8, 0.1]), c=C)
    summary = pgospa_summary(series)
    parts = sum(
        float(summary[key])
        for key in ("mean_localisation", "mean_existence_mismatch", "mean_missed", "mean_false")
    )
    assert parts == pytest.approx(float(np.mean(series.total**2)))
    assert summary["mean_total"] == pytest.approx(float(np.mean(series.total)))
    assert (summary["c"], summary["p"], summary["alpha"], summary["num_times"]) == (C, 2.0, 2.0, 4)
    # Lowering the existence of the false track (track 6, 30 from target 1) lowers P-GOSPA.
    lower = pgospa_tables(truth, track_table(rows, [0.9, 0.9, 0.1, 0.8, 0.1]), c=C)
    assert lower.total[1] < series.total[1]
    np.testing.assert_allclose(np.delete(lower.total, 1), np.delete(series.total, 1))


def test_arguments_are_checked() -> None:
    tracks = track_table([(1, 0.0, 0.0, 0.0)])
    with pytest.raises(InputError, match="swapped; pgospa_tables"):
        pgospa_tables(tracks, ONE_TARGET, c=C)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="alpha must be 2"):
        pgospa_tables(ONE_TARGET, tracks, c=C, alpha=1.0)
    with pytest.raises(InputError, match="c"):
        pgospa_tables(ONE_TARGET, tracks, c=-1.0)
    with pytest.raises(InputError, match="tracks"):
        track_existence(ONE_TARGET)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="series"):
        pgospa_summary({"mean_total": 1.0})  # type: ignore[arg-type]


def test_disjoint_times_warn() -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        series = pgospa_tables(ONE_TARGET, track_table([(1, 5.0, 0.0, 0.0)], [0.5]), c=C)
    assert any("share no time" in str(w.message) for w in caught)
    # Time 0: the target missed (50); time 5: a false track of weight 0.5 (25).
    assert series.total.tolist() == pytest.approx([math.sqrt(50.0), 5.0])
