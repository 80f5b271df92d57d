"""Tests of mapassoc.evaluation.metrics: GOSPA (alpha = 2), RMSE, cardinality error, report."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import (
    GospaResult,
    TimedPoints,
    cardinality_error,
    evaluate,
    format_report,
    gospa,
    gospa_over_time,
    position_rmse,
)

# ----------------------------------------------------------------------------------------------
# Oracle: the definition itself, by enumerating every partial assignment
# ----------------------------------------------------------------------------------------------


def brute_force_gospa(truth: np.ndarray, estimates: np.ndarray, c: float, p: float) -> float:
    """GOSPA alpha = 2 by its definition: min over all partial injective assignments g of
    sum_{(i,j) in g} d(x_i, y_j)^p + (c^p / 2)(n + m - 2|g|), without any cut-off trick."""
    n, m = len(truth), len(estimates)
    best = c**p / 2.0 * (n + m)
    for k in range(1, min(n, m) + 1):
        for truth_idx in itertools.combinations(range(n), k):
            for est_idx in itertools.permutations(range(m), k):
                cost = sum(
                    np.linalg.norm(truth[i] - estimates[j]) ** p
                    for i, j in zip(truth_idx, est_idx, strict=True)
                )
                best = min(best, cost + c**p / 2.0 * (n + m - 2 * k))
    return best ** (1.0 / p)


# Small integer grid so that coincident points (distance exactly 0) are common.
coordinate = st.integers(min_value=-6, max_value=6).map(float)
point = st.tuples(coordinate, coordinate)
point_set = st.lists(point, min_size=0, max_size=5).map(
    lambda pts: np.array(pts, dtype=float).reshape(len(pts), 2)
)
real_point_set = st.lists(
    st.tuples(
        st.floats(-20, 20, allow_nan=False, allow_infinity=False),
        st.floats(-20, 20, allow_nan=False, allow_infinity=False),
    ),
    min_size=0,
    max_size=5,
).map(lambda pts: np.array(pts, dtype=float).reshape(len(pts), 2))
cutoffs = st.floats(0.5, 15.0)
orders = st.floats(1.0, 4.0)


def same_multiset(a: np.ndarray, b: np.ndarray) -> bool:
    if a.shape != b.shape:
        return False
    return sorted(map(tuple, a.tolist())) == sorted(map(tuple, b.tolist()))


# ----------------------------------------------------------------------------------------------
# Single time step: hand-worked values
# ----------------------------------------------------------------------------------------------


def test_hand_worked_one_missed() -> None:
    result = gospa([[0.0, 0.0], [10.0, 0.0]], [[1.0, 0.0]], c=5.0, p=2.0)
    assert result.localisation == pytest.approx(1.0)
    assert result.missed == pytest.approx(12.5)  # (5^2 / 2) * 1
    assert result.false == 0.0
    assert result.total == pytest.approx(math.sqrt(13.5))
    assert (result.num_missed, result.num_false, result.num_assigned) == (1, 0, 1)
    np.testing.assert_array_equal(result.assignments, [[0, 0]])
    np.testing.assert_allclose(result.distances, [1.0])


def test_hand_worked_p1_two_pairs_and_a_false() -> None:
    # truth (0,0),(0,4); estimates (3,0) [d=3], (0,4.5) [d=0.5], (100,100) [false].
    # p = 1, c = 4: localisation 3.5, false 4/2 = 2, total 5.5.
    result = gospa([[0, 0], [0, 4]], [[3, 0], [0, 4.5], [100, 100]], c=4.0, p=1.0)
    assert result.localisation == pytest.approx(3.5)
    assert result.false == pytest.approx(2.0)
    assert result.missed == 0.0
    assert result.total == pytest.approx(5.5)
    np.testing.assert_array_equal(result.assignments, [[0, 0], [1, 1]])


def test_assignment_is_optimal_not_greedy() -> None:
    # Greedy nearest-neighbour pairs truth 0 with its nearest estimate 0 first; the optimum
    # pairs it with estimate 1 instead.
    truth = np.array([[0.0, 0.0], [2.0, 0.0]])
    estimates = np.array([[1.0, 0.0], [-1.5, 0.0]])
    # pairing A: t0-e0 (1), t1-e1 (3.5) -> 1 + 12.25 = 13.25
    # pairing B: t0-e1 (1.5), t1-e0 (1) -> 2.25 + 1 = 3.25
    result = gospa(truth, estimates, c=10.0, p=2.0)
    assert result.total == pytest.approx(math.sqrt(3.25))
    np.testing.assert_array_equal(result.assignments, [[0, 1], [1, 0]])


def test_pair_at_or_beyond_cutoff_is_missed_plus_false() -> None:
    for distance in (5.0, 7.0):
        result = gospa([[0.0, 0.0]], [[distance, 0.0]], c=5.0, p=2.0)
        assert result.num_assigned == 0
        assert (result.num_missed, result.num_false) == (1, 1)
        assert result.localisation == 0.0
        assert result.missed == pytest.approx(12.5)
        assert result.false == pytest.approx(12.5)
        assert result.total == pytest.approx(5.0)
        assert result.assignments.shape == (0, 2)
    just_inside = gospa([[0.0, 0.0]], [[4.999, 0.0]], c=5.0, p=2.0)
    assert just_inside.num_assigned == 1
    assert just_inside.total == pytest.approx(4.999)


def test_empty_sets() -> None:
    both = gospa(np.zeros((0, 2)), np.zeros((0, 2)), c=3.0)
    assert both.total == 0.0
    assert (both.num_missed, both.num_false, both.num_assigned) == (0, 0, 0)

    no_estimates = gospa([[0, 0], [1, 1], [2, 2]], np.zeros((0, 2)), c=3.0, p=2.0)
    assert (no_estimates.num_missed, no_estimates.num_false) == (3, 0)
    assert no_estimates.missed == pytest.approx(3 * 9 / 2)
    assert no_estimates.total == pytest.approx(math.sqrt(13.5))

    no_truth = gospa([], [[0, 0], [1, 1]], c=3.0, p=1.0)
    assert (no_truth.num_missed, no_truth.num_false) == (0, 2)
    assert no_truth.false == pytest.approx(3.0)
    assert no_truth.total == pytest.approx(3.0)
    assert gospa([], [], c=1.0).total == 0.0


def test_result_arrays_are_read_only() -> None:
    result = gospa([[0, 0]], [[1, 0]], c=5.0)
    assert isinstance(result, GospaResult)
    with pytest.raises(ValueError):
        result.assignments[0, 0] = 3


# ----------------------------------------------------------------------------------------------
# Single time step: properties
# ----------------------------------------------------------------------------------------------


@settings(max_examples=150, deadline=None)
@given(x=real_point_set, y=real_point_set, c=cutoffs, p=orders)
def test_agrees_with_brute_force_definition(
    x: np.ndarray, y: np.ndarray, c: float, p: float
) -> None:
    assert gospa(x, y, c=c, p=p).total == pytest.approx(
        brute_force_gospa(x, y, c, p), rel=1e-9, abs=1e-9
    )


@settings(max_examples=150, deadline=None)
@given(x=point_set, y=point_set, c=cutoffs, p=orders)
def test_parts_and_counts_are_consistent(x: np.ndarray, y: np.ndarray, c: float, p: float) -> None:
    r = gospa(x, y, c=c, p=p)
    assert r.total**p == pytest.approx(r.localisation + r.missed + r.false, rel=1e-9, abs=1e-12)
    assert r.num_assigned + r.num_missed == len(x)
    assert r.num_assigned + r.num_false == len(y)
    assert r.missed == pytest.approx(c**p / 2 * r.num_missed)
    assert r.false == pytest.approx(c**p / 2 * r.num_false)
    assert np.all(r.distances < c)
    assert len(set(r.assignments[:, 0].tolist())) == r.num_assigned
    assert len(set(r.assignments[:, 1].tolist())) == r.num_assigned
    recomputed = np.linalg.norm(x[r.assignments[:, 0]] - y[r.assignments[:, 1]], axis=1)
    np.testing.assert_allclose(r.distances, recomputed)
    assert r.localisation == pytest.approx(float(np.sum(recomputed**p)))


@settings(max_examples=150, deadline=None)
@given(x=point_set, y=point_set, c=cutoffs, p=orders)
def test_symmetry(x: np.ndarray, y: np.ndarray, c: float, p: float) -> None:
    forward = gospa(x, y, c=c, p=p)
    backward = gospa(y, x, c=c, p=p)
    assert forward.total == pytest.approx(backward.total, rel=1e-12, abs=1e-12)


@settings(max_examples=150, deadline=None)
@given(x=point_set, y=point_set, c=cutoffs, p=orders)
def test_zero_iff_equal_as_multisets(x: np.ndarray, y: np.ndarray, c: float, p: float) -> None:
    assert (gospa(x, y, c=c, p=p).total == 0.0) == same_multiset(x, y)
    assert gospa(x, x[::-1], c=c, p=p).total == 0.0


@settings(max_examples=200, deadline=None)
@given(x=point_set, y=point_set, z=point_set, c=cutoffs, p=orders)
def test_triangle_inequality(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, c: float, p: float
) -> None:
    direct = gospa(x, z, c=c, p=p).total
    via_y = gospa(x, y, c=c, p=p).total + gospa(y, z, c=c, p=p).total
    assert direct <= via_y + 1e-9 * max(1.0, via_y)


@settings(max_examples=100, deadline=None)
@given(
    x=real_point_set,
    y=real_point_set,
    c=cutoffs,
    p=orders,
    angle=st.floats(0.0, 2 * math.pi),
    shift=st.tuples(st.floats(-50, 50), st.floats(-50, 50)),
    scale=st.floats(0.1, 10.0),
)
def test_rigid_motion_and_scale_invariance(
    x: np.ndarray,
    y: np.ndarray,
    c: float,
    p: float,
    angle: float,
    shift: tuple[float, float],
    scale: float,
) -> None:
    base = gospa(x, y, c=c, p=p).total
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])

    def move(points: np.ndarray) -> np.ndarray:
        return points @ rotation.T + np.array(shift)

    assert gospa(move(x), move(y), c=c, p=p).total == pytest.approx(base, rel=1e-7, abs=1e-7)
    # Scaling every distance and the cut-off by s scales GOSPA by s.
    assert gospa(scale * x, scale * y, c=scale * c, p=p).total == pytest.approx(
        scale * base, rel=1e-9, abs=1e-12
    )
    # Row order is irrelevant.
    assert gospa(x[::-1], y[::-1], c=c, p=p).total == pytest.approx(base, rel=1e-12, abs=1e-12)


def test_total_is_at_most_cardinality_bound() -> None:
    # Everything unassigned costs (c^p / 2)(n + m): an upper bound reached only when all pairs
    # are at distance >= c.
    rng = np.random.default_rng(3)
    for _ in range(20):
        x = rng.uniform(-10, 10, size=(rng.integers(0, 6), 3))
        y = rng.uniform(-10, 10, size=(rng.integers(0, 6), 3))
        bound = (2.0**2 / 2 * (len(x) + len(y))) ** 0.5
        assert gospa(x, y, c=2.0).total <= bound + 1e-12


# ----------------------------------------------------------------------------------------------
# Single time step: bad input
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"c": 5.0, "alpha": 1.0}, r"alpha must be 2.*got 1\.0"),
        ({"c": 5.0, "alpha": -1.0}, r"alpha must be positive, got -1\.0"),
        ({"c": 0.0}, r"c must be positive, got 0\.0"),
        ({"c": -2.0}, r"c must be positive, got -2\.0"),
        ({"c": float("nan")}, r"c must be finite"),
        ({"c": 5.0, "p": 0.5}, r"p must be >= 1.*got 0\.5"),
        ({"c": 5.0, "p": float("inf")}, r"p must be finite"),
        ({"c": 1e300}, r"c\^p = 1e\+300\^2\.0 overflows"),
        ({"c": 10.0, "p": 2000.0}, r"c\^p = 10\.0\^2000\.0 overflows"),
        ({"c": 1e-150}, r"c\^p = 1e-150\^2\.0 underflows"),
    ],
)
def test_bad_parameters(kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        gospa([[0, 0]], [[1, 1]], **kwargs)


@pytest.mark.parametrize(
    ("truth", "estimates", "message"),
    [
        ([0.0, 1.0], [[0, 0]], r"truth must have shape \(k, d\).*got shape \(2,\)"),
        ([[0, 0]], [[[0, 0]]], r"estimates must have shape \(k, d\).*got shape \(1, 1, 2\)"),
        ([[0, 0]], [[0, 0, 0]], r"same dimension d.*\(1, 2\).*\(1, 3\)"),
        (np.zeros((0, 3)), [[0, 0]], r"same dimension d.*\(0, 3\).*\(1, 2\)"),
        ([[0, float("nan")]], [[0, 0]], r"truth must contain only finite values.*nan"),
        ([[0, 0]], [[float("inf"), 0]], r"estimates must contain only finite values.*inf"),
        ([["a", "b"]], [[0, 0]], r"truth must be a numeric array"),
        (np.zeros((2, 0)), [[0, 0]], r"truth must have shape \(k, d\) with d >= 1"),
    ],
)
def test_bad_point_sets(truth: object, estimates: object, message: str) -> None:
    with pytest.raises(InputError, match=message):
        gospa(truth, estimates, c=5.0)


# ----------------------------------------------------------------------------------------------
# Runs
# ----------------------------------------------------------------------------------------------


def hand_run() -> tuple[TimedPoints, TimedPoints]:
    # Truth at times 0, 1, 2; estimates at 0, 1, 3.  Rows grouped but not sorted in truth.
    truth = TimedPoints(
        times=np.array([1.0, 0.0, 0.0, 2.0]),
        ids=np.array([1, 1, 2, 1]),
        positions=np.array([[0.0, 0.0], [0.0, 0.0], [10.0, 0.0], [5.0, 5.0]]),
    )
    estimates = TimedPoints(
        times=np.array([0.0, 1.0, 3.0]),
        ids=np.array([7, 7, 7]),
        positions=np.array([[1.0, 0.0], [0.0, 0.5], [9.0, 9.0]]),
    )
    return truth, estimates


def test_gospa_over_time_hand_worked() -> None:
    truth, estimates = hand_run()
    series = gospa_over_time(truth, estimates, c=5.0, p=2.0)
    np.testing.assert_array_equal(series.times, [0.0, 1.0, 2.0, 3.0])
    # t=0: the single-step hand case; t=1: one pair at 0.5; t=2: only truth (missed);
    # t=3: only an estimate (false).
    np.testing.assert_allclose(series.localisation, [1.0, 0.25, 0.0, 0.0])
    np.testing.assert_allclose(series.missed, [12.5, 0.0, 12.5, 0.0])
    np.testing.assert_allclose(series.false, [0.0, 0.0, 0.0, 12.5])
    np.testing.assert_allclose(
        series.total, [math.sqrt(13.5), 0.5, math.sqrt(12.5), math.sqrt(12.5)]
    )
    np.testing.assert_array_equal(series.num_missed, [1, 0, 1, 0])
    np.testing.assert_array_equal(series.num_false, [0, 0, 0, 1])
    np.testing.assert_array_equal(series.num_assigned, [1, 1, 0, 0])
    assert series.num_times == 4
    assert series.mean_total == pytest.approx((math.sqrt(13.5) + 0.5 + 2 * math.sqrt(12.5)) / 4)
    assert series.mean_localisation == pytest.approx(1.25 / 4)
    assert series.mean_missed == pytest.approx(25.0 / 4)
    assert series.mean_false == pytest.approx(12.5 / 4)
    summary = series.summary()
    assert summary["num_times"] == 4
    assert summary["mean_num_missed"] == pytest.approx(0.5)
    assert summary["mean_num_false"] == pytest.approx(0.25)
    assert all(type(v) in (int, float) for v in summary.values())


def test_time_only_in_truth_is_all_missed() -> None:
    truth = TimedPoints(
        times=np.array([0.0, 0.0, 1.0]),
        ids=np.array([1, 2, 1]),
        positions=np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 0.0]]),
    )
    estimates = TimedPoints(times=np.array([1.0]), ids=np.array([4]), positions=[[0.0, 0.0]])
    series = gospa_over_time(truth, estimates, c=2.0, p=1.0)
    np.testing.assert_array_equal(series.times, [0.0, 1.0])
    np.testing.assert_array_equal(series.num_missed, [2, 0])
    np.testing.assert_allclose(series.total, [2.0, 0.0])  # (2^1/2) * 2 missed = 2


def test_times_match_only_exactly() -> None:
    truth = TimedPoints(times=[0.1 + 0.2], ids=[1], positions=[[0.0, 0.0]])
    estimates = TimedPoints(times=[0.3], ids=[1], positions=[[0.0, 0.0]])
    series = gospa_over_time(truth, estimates, c=4.0)
    assert series.num_times == 2  # 0.30000000000000004 != 0.3
    np.testing.assert_array_equal(series.num_missed + series.num_false, [1, 1])


@settings(max_examples=40, deadline=None)
@given(
    frames=st.lists(st.tuples(point_set, point_set), min_size=1, max_size=5),
    c=cutoffs,
    p=orders,
)
def test_gospa_over_time_agrees_with_per_step_gospa(
    frames: list[tuple[np.ndarray, np.ndarray]], c: float, p: float
) -> None:
    def run(sets: list[np.ndarray]) -> TimedPoints:
        times = np.concatenate([np.full(len(s), 10.0 * k) for k, s in enumerate(sets)])
        ids = np.concatenate([np.arange(len(s)) for s in sets]).astype(np.int64)
        return TimedPoints(times=times, ids=ids, positions=np.concatenate(sets).reshape(-1, 2))

    truth = run([f[0] for f in frames])
    estimates = run([f[1] for f in frames])
    if truth.times.size == 0 and estimates.times.size == 0:
        with pytest.raises(InputError, match="no rows"):
            gospa_over_time(truth, estimates, c=c, p=p)
        return
    series = gospa_over_time(truth, estimates, c=c, p=p)
    present = [k for k, (a, b) in enumerate(frames) if len(a) or len(b)]
    np.testing.assert_array_equal(series.times, [10.0 * k for k in present])
    for position, k in enumerate(present):
        step = gospa(frames[k][0], frames[k][1], c=c, p=p)
        assert series.total[position] == pytest.approx(step.total)
        assert series.num_missed[position] == step.num_missed
        assert series.num_false[position] == step.num_false


def test_position_rmse_and_cardinality_hand_worked() -> None:
    truth, estimates = hand_run()
    # Assigned pairs: d = 1 (t=0), d = 0.5 (t=1): RMSE = sqrt((1 + 0.25) / 2).
    assert position_rmse(truth, estimates, c=5.0) == pytest.approx(math.sqrt(0.625))
    # A tight cut-off drops the d = 1 pair.
    assert position_rmse(truth, estimates, c=0.9) == pytest.approx(0.5)
    # No pair within the cut-off: nan.
    assert math.isnan(position_rmse(truth, estimates, c=0.1))
    cardinality = cardinality_error(truth, estimates)
    np.testing.assert_array_equal(cardinality.times, [0.0, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(cardinality.difference, [-1, 0, -1, 1])
    assert cardinality.mean_absolute == pytest.approx(0.75)


def test_evaluate_is_typed_json_ready_and_consistent() -> None:
    truth, estimates = hand_run()
    evaluation = evaluate(truth, estimates, c=5.0, p=2.0)
    assert evaluation.num_times == 4
    assert evaluation.num_assigned_pairs == 2
    assert evaluation.position_rmse == pytest.approx(math.sqrt(0.625))
    assert evaluation.mean_abs_cardinality_error == pytest.approx(0.75)
    series = gospa_over_time(truth, estimates, c=5.0, p=2.0)
    np.testing.assert_array_equal(evaluation.gospa.total, series.total)
    result = evaluation.to_json()
    text = json.dumps(result, allow_nan=False)
    assert json.loads(text) == result
    assert result["num_times"] == 4
    assert result["num_assigned_pairs"] == 2
    assert result["position_rmse"] == pytest.approx(math.sqrt(0.625))
    assert result["mean_abs_cardinality_error"] == pytest.approx(0.75)
    assert result["gospa"] == series.summary()
    # No assigned pair: RMSE is null, and the dictionary is still strict JSON.
    far = evaluate(truth, estimates, c=0.1, p=2.0)
    assert far.position_rmse is None
    assert far.to_json()["position_rmse"] is None
    json.dumps(far.to_json(), allow_nan=False)


def test_format_report_is_aligned_and_complete() -> None:
    truth, estimates = hand_run()
    report = format_report(evaluate(truth, estimates, c=5.0, p=2.0))
    lines = report.splitlines()
    assert len(lines) == 10
    assert len({len(line) for line in lines}) == 1  # values right-aligned in one column
    assert lines[0].startswith("GOSPA mean (c=5, p=2, alpha=2)")
    assert lines[0].endswith(f"{(math.sqrt(13.5) + 0.5 + 2 * math.sqrt(12.5)) / 4:.4f}")
    assert any(line.startswith("position RMSE") and line.endswith("0.7906") for line in lines)
    assert lines[-1].startswith("evaluation times") and lines[-1].endswith(" 4")
    far = format_report(evaluate(truth, estimates, c=0.1, p=2.0))
    assert any(
        line.startswith("position RMSE") and line.endswith("n/a") for line in far.splitlines()
    )


def test_format_report_rejects_incomplete_summary() -> None:
    truth, estimates = hand_run()
    summary = evaluate(truth, estimates, c=5.0, p=2.0).to_json()
    del summary["position_rmse"]
    del summary["gospa"]["mean_total"]
    with pytest.raises(InputError, match=r"position_rmse.*gospa\.mean_total"):
        format_report(summary)
    with pytest.raises(InputError, match="summary must be what evaluate returns"):
        format_report([1, 2])  # type: ignore[arg-type]


# ----------------------------------------------------------------------------------------------
# Runs: bad input
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("times", "ids", "positions", "message"),
    [
        ([0.0, 1.0], [1], [[0, 0], [1, 1]], r"ids must have shape \(2,\).*got shape \(1,\)"),
        ([0.0, 1.0], [1, 2], [[0, 0]], r"positions must have shape \(2, d\).*got shape \(1, 2\)"),
        ([0.0], [1.5], [[0, 0]], r"ids must be an integer array, got dtype float64"),
        ([float("nan")], [1], [[0, 0]], r"times must contain only finite values"),
        ([[0.0]], [1], [[0, 0]], r"times must have shape \(N,\), got shape \(1, 1\)"),
        ([0.0], [1], [[0, float("inf")]], r"positions must contain only finite values.*inf"),
        (
            [0.0, 1.0, 0.0],
            [1, 1, 2],
            [[0, 0], [1, 1], [2, 2]],
            r"grouped by time.*\[0\.0\] appear in more than one block",
        ),
        ([2.0, 2.0], [5, 5], [[0, 0], [1, 1]], r"id 5 appears more than once at time 2\.0"),
    ],
)
def test_bad_timed_points(times: object, ids: object, positions: object, message: str) -> None:
    with pytest.raises(InputError, match=message):
        TimedPoints(times=times, ids=ids, positions=positions)  # type: ignore[arg-type]


def test_bad_runs() -> None:
    truth, estimates = hand_run()
    three_d = TimedPoints(times=[0.0], ids=[1], positions=[[0.0, 0.0, 0.0]])
    with pytest.raises(InputError, match=r"same position dimension.*truth 2 and estimates 3"):
        gospa_over_time(truth, three_d, c=1.0)
    with pytest.raises(InputError, match="no rows"):
        evaluate(TimedPoints.empty(2), TimedPoints.empty(2), c=1.0, p=2.0)
    with pytest.raises(InputError, match=r"estimates must be a TimedPoints, got ndarray"):
        position_rmse(truth, np.zeros((1, 2)), c=1.0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"p must be >= 1.*got 0\.9"):
        evaluate(truth, estimates, c=1.0, p=0.9)
    with pytest.raises(InputError, match=r"c must be positive, got 0"):
        gospa_over_time(truth, estimates, c=0)
    with pytest.raises(InputError, match=r"dim must be an integer >= 1, got 0"):
        TimedPoints.empty(0)


def test_empty_estimates_run_is_all_missed() -> None:
    truth, _ = hand_run()
    series = gospa_over_time(truth, TimedPoints.empty(2), c=2.0, p=2.0)
    np.testing.assert_array_equal(series.times, [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(series.num_missed, [2, 1, 1])
    np.testing.assert_allclose(series.missed, [4.0, 2.0, 2.0])
    assert series.num_false.sum() == 0
    assert math.isnan(position_rmse(truth, TimedPoints.empty(2), c=2.0))


def test_from_unsorted_groups_rows_by_time() -> None:
    run = TimedPoints.from_unsorted(
        times=[1.0, 0.0, 1.0, 0.0], ids=[3, 3, 4, 4], positions=[[1, 0], [0, 0], [1, 1], [0, 1]]
    )
    np.testing.assert_array_equal(run.times, [0.0, 0.0, 1.0, 1.0])
    np.testing.assert_array_equal(run.ids, [3, 4, 3, 4])
    np.testing.assert_array_equal(run.positions, [[0, 0], [0, 1], [1, 0], [1, 1]])
    np.testing.assert_array_equal(run.positions_at(1.0), [[1, 0], [1, 1]])
    with pytest.raises(InputError, match=r"same number of rows.*\(2,\), \(1,\)"):
        TimedPoints.from_unsorted(times=[0.0, 1.0], ids=[1], positions=[[0, 0], [1, 1]])
