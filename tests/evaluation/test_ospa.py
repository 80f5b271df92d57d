"""Tests of mapassoc.evaluation.ospa: OSPA per time and the trajectory metric OSPA(2)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import TimedPoints, gospa_over_time
from mapassoc.evaluation.ospa import (
    ospa,
    ospa2,
    ospa2_over_time,
    ospa_over_time,
    trajectory_base_distances,
)

# ----------------------------------------------------------------------------------------------
# Oracles: the definitions themselves, by enumerating every injection
# ----------------------------------------------------------------------------------------------


def brute_force_ospa_from_costs(cost: np.ndarray, c: float, p: float) -> float:
    """OSPA (Schuhmacher et al. 2008, Definition 3) from an (n, m) matrix of base distances
    already cut off at c: the minimum over every injection of the smaller set into the larger
    of the mean p-th power cost, each unmatched element of the larger set paying c^p."""
    n, m = cost.shape
    if n > m:
        cost, n, m = cost.T, m, n
    if m == 0:
        return 0.0
    best = math.inf
    for image in itertools.permutations(range(m), n):
        best = min(best, sum(cost[i, j] ** p for i, j in enumerate(image)))
    return ((best + c**p * (m - n)) / m) ** (1.0 / p)


def brute_force_ospa(x: np.ndarray, y: np.ndarray, c: float, p: float) -> float:
    cost = np.array(
        [[min(c, float(np.linalg.norm(a - b))) for b in y] for a in x], dtype=float
    ).reshape(len(x), len(y))
    return brute_force_ospa_from_costs(cost, c, p)


def as_trajectories(run: TimedPoints) -> dict[int, dict[float, np.ndarray]]:
    """id -> {time -> position} of a run."""
    out: dict[int, dict[float, np.ndarray]] = {}
    for t, i, x in zip(run.times.tolist(), run.ids.tolist(), run.positions, strict=True):
        out.setdefault(i, {})[t] = x
    return out


def brute_force_ospa2(
    truth: TimedPoints, estimates: TimedPoints, c: float, p: float, times: set[float] | None = None
) -> float:
    """OSPA(2) (Beard, Vo and Vo 2017) from its definition, on the rows whose time is in
    ``times`` (all rows when None): trajectories with no row there are not in the sets; the
    base distance of two trajectories is the mean over the times where either exists of
    min(c, |x(t) - y(t)|) (both exist) or c (only one exists)."""

    def restrict(run: TimedPoints) -> list[dict[float, np.ndarray]]:
        trajectories = []
        for rows in as_trajectories(run).values():
            kept = {t: x for t, x in rows.items() if times is None or t in times}
            if kept:
                trajectories.append(kept)
        return trajectories

    xs, ys = restrict(truth), restrict(estimates)

    def base(a: dict[float, np.ndarray], b: dict[float, np.ndarray]) -> float:
        domain = set(a) | set(b)
        total = 0.0
        for t in domain:
            if t in a and t in b:
                total += min(c, float(np.linalg.norm(a[t] - b[t])))
            else:
                total += c
        return total / len(domain)

    cost = np.array([[base(a, b) for b in ys] for a in xs], dtype=float).reshape(
        len(xs), len(ys)
    )
    return brute_force_ospa_from_costs(cost, c, p)


def run(rows: list[tuple[float, int, tuple[float, ...]]]) -> TimedPoints:
    """A TimedPoints from (time, id, position) rows in any order."""
    return TimedPoints.from_unsorted(
        times=[r[0] for r in rows], ids=[r[1] for r in rows], positions=[r[2] for r in rows]
    )


# Small integer grid so that coincident points (distance exactly 0) are common.
coordinate = st.integers(min_value=-6, max_value=6).map(float)
point_set = st.lists(st.tuples(coordinate, coordinate), min_size=0, max_size=5).map(
    lambda pts: np.array(pts, dtype=float).reshape(len(pts), 2)
)
cutoffs = st.floats(0.5, 15.0)
orders = st.floats(1.0, 4.0)


@st.composite
def timed_run(draw: st.DrawFn, max_ids: int = 3, num_times: int = 5) -> TimedPoints:
    """A random run: up to ``max_ids`` trajectories, each present at a random subset of
    ``num_times`` integer times (gaps allowed), positions on a small grid."""
    rows = []
    for ident in range(draw(st.integers(0, max_ids))):
        for t in range(num_times):
            if draw(st.booleans()):
                rows.append((float(t), ident, (draw(coordinate), draw(coordinate))))
    if not rows:
        return TimedPoints.empty(2)
    return run(rows)


# ----------------------------------------------------------------------------------------------
# OSPA at one time: hand-worked values
# ----------------------------------------------------------------------------------------------


def test_hand_worked_single_pair() -> None:
    result = ospa([[0.0]], [[3.0]], c=10.0, p=2.0)
    assert result.total == pytest.approx(3.0)
    assert result.localisation == pytest.approx(9.0)
    assert result.cardinality == 0.0
    assert (result.num_truth, result.num_estimates) == (1, 1)


def test_hand_worked_cardinality_mismatch_normalises_by_larger_set() -> None:
    # n = 2, m = 1: (1/2) [1^2 + 5^2 (2 - 1)] = 13, so OSPA = sqrt(13).
    result = ospa([[0.0, 0.0], [10.0, 0.0]], [[1.0, 0.0]], c=5.0, p=2.0)
    assert result.total == pytest.approx(math.sqrt(13.0))
    assert result.localisation == pytest.approx(0.5)
    assert result.cardinality == pytest.approx(12.5)
    # Same miss among ten well-tracked targets: the c^p penalty is divided by 10, not 2.
    many = np.array([[10.0 * k, 0.0] for k in range(10)])
    result = ospa(many, many[:9], c=5.0, p=2.0)
    assert result.total == pytest.approx(math.sqrt(25.0 / 10.0))


def test_hand_worked_cutoff() -> None:
    # A pair 20 apart costs c, not 20, and the assignment is optimal, not greedy:
    # {0, 4} vs {1, 100} with c = 10 pairs 0-1 (1) and 4-100 (cut to 10).
    assert ospa([[0.0]], [[20.0]], c=5.0).total == pytest.approx(5.0)
    assert ospa([[0.0], [4.0]], [[1.0], [100.0]], c=10.0, p=1.0).total == pytest.approx(5.5)
    assert ospa([[0.0], [4.0]], [[1.0], [100.0]], c=10.0, p=2.0).total == pytest.approx(
        math.sqrt(50.5)
    )
    # Greedy nearest-first would pair 4 with 3 and 0 with 8: the optimum pairs 0-3 and 4-8.
    assert ospa([[0.0], [4.0]], [[3.0], [8.0]], c=10.0, p=2.0).total == pytest.approx(
        math.sqrt((9.0 + 16.0) / 2.0)
    )


@pytest.mark.parametrize(
    ("p", "expected"),
    [(1.0, 3.5), (2.0, math.sqrt(12.5)), (3.0, 45.5 ** (1.0 / 3.0))],
)
def test_hand_worked_order(p: float, expected: float) -> None:
    # {0, 10} vs {3, 14}: distances 3 and 4; OSPA = ((3^p + 4^p) / 2)^(1/p).
    result = ospa([[0.0], [10.0]], [[3.0], [14.0]], c=10.0, p=p)
    assert result.total == pytest.approx(expected)
    assert result.total**p == pytest.approx(result.localisation + result.cardinality)


def test_empty_sets() -> None:
    assert ospa([], [], c=4.0).total == 0.0
    assert ospa(np.zeros((0, 2)), np.zeros((0, 2)), c=4.0).total == 0.0
    for p in (1.0, 2.0, 3.5):
        for k in (1, 3):
            points = np.arange(2.0 * k).reshape(k, 2)
            assert ospa(points, [], c=4.0, p=p).total == pytest.approx(4.0)
            assert ospa(np.zeros((0, 2)), points, c=4.0, p=p).total == pytest.approx(4.0)
    one_empty = ospa([[1.0, 2.0]], [], c=4.0)
    assert (one_empty.num_truth, one_empty.num_estimates) == (1, 0)
    assert one_empty.localisation == 0.0 and one_empty.cardinality == pytest.approx(16.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"c": 0.0}, "c"),
        ({"c": -1.0}, "c"),
        ({"c": 1.0, "p": 0.5}, "p must be >= 1"),
        ({"c": 1.0, "p": math.inf}, "p"),
        ({"c": 1e300}, r"c\^p .* overflows"),
    ],
)
def test_bad_parameters(kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        ospa([[0.0, 0.0]], [[1.0, 1.0]], **kwargs)


def test_bad_point_sets() -> None:
    with pytest.raises(InputError, match="same dimension"):
        ospa([[0.0, 0.0]], [[1.0, 1.0, 1.0]], c=1.0)
    with pytest.raises(InputError, match="finite"):
        ospa([[0.0, math.nan]], [[1.0, 1.0]], c=1.0)


# ----------------------------------------------------------------------------------------------
# OSPA at one time: brute force and metric properties
# ----------------------------------------------------------------------------------------------


@settings(max_examples=150, deadline=None)
@given(x=point_set, y=point_set, c=cutoffs, p=orders)
def test_agrees_with_brute_force_definition(
    x: np.ndarray, y: np.ndarray, c: float, p: float
) -> None:
    result = ospa(x, y, c=c, p=p)
    assert result.total == pytest.approx(brute_force_ospa(x, y, c, p), rel=1e-9, abs=1e-9)
    assert result.total**p == pytest.approx(
        result.localisation + result.cardinality, rel=1e-9, abs=1e-9
    )


@settings(max_examples=100, deadline=None)
@given(x=point_set, y=point_set, c=cutoffs, p=orders)
def test_symmetric_bounded_and_zero_iff_equal(
    x: np.ndarray, y: np.ndarray, c: float, p: float
) -> None:
    forward = ospa(x, y, c=c, p=p).total
    assert forward == pytest.approx(ospa(y, x, c=c, p=p).total, rel=1e-12, abs=1e-12)
    assert 0.0 <= forward <= c * (1 + 1e-12)
    same = x.shape == y.shape and sorted(map(tuple, x.tolist())) == sorted(map(tuple, y.tolist()))
    assert (forward == 0.0) == same


@settings(max_examples=150, deadline=None)
@given(x=point_set, y=point_set, z=point_set, c=cutoffs, p=orders)
def test_triangle_inequality(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, c: float, p: float
) -> None:
    xz = ospa(x, z, c=c, p=p).total
    assert xz <= ospa(x, y, c=c, p=p).total + ospa(y, z, c=c, p=p).total + 1e-9


# ----------------------------------------------------------------------------------------------
# OSPA over time
# ----------------------------------------------------------------------------------------------


def test_ospa_over_time_hand_worked() -> None:
    truth = run([(0.0, 1, (0.0, 0.0)), (0.0, 2, (10.0, 0.0)), (1.0, 1, (1.0, 0.0))])
    estimates = run([(0.0, 5, (1.0, 0.0)), (2.0, 5, (0.0, 0.0))])
    series = ospa_over_time(truth, estimates, c=5.0, p=2.0)
    np.testing.assert_array_equal(series.times, [0.0, 1.0, 2.0])
    # t = 0: sqrt(13) (see above); t = 1: truth only -> c; t = 2: estimate only -> c.
    np.testing.assert_allclose(series.total, [math.sqrt(13.0), 5.0, 5.0])
    np.testing.assert_allclose(series.cardinality, [12.5, 25.0, 25.0])
    assert series.mean_total == pytest.approx((math.sqrt(13.0) + 10.0) / 3.0)


@settings(max_examples=60, deadline=None)
@given(truth=timed_run(), estimates=timed_run(), c=cutoffs, p=orders)
def test_ospa_over_time_is_ospa_at_each_time(
    truth: TimedPoints, estimates: TimedPoints, c: float, p: float
) -> None:
    if truth.times.size + estimates.times.size == 0:
        return
    series = ospa_over_time(truth, estimates, c=c, p=p)
    for k, t in enumerate(series.times):
        expected = ospa(truth.positions_at(t), estimates.positions_at(t), c=c, p=p)
        assert series.total[k] == pytest.approx(expected.total, rel=1e-12, abs=1e-12)


# ----------------------------------------------------------------------------------------------
# OSPA(2): hand-worked values from the definition
# ----------------------------------------------------------------------------------------------


def two_trajectory_case() -> tuple[TimedPoints, TimedPoints]:
    """Truth A (id 1) at t = 0..3 along y = 0 and B (id 2) at t = 2..4 along y = 10;
    track 7 follows A one unit off; track 8 covers B two units off at t = 3, 4 and goes on
    alone at t = 5."""
    truth = run(
        [(float(t), 1, (float(t), 0.0)) for t in range(4)]
        + [(float(t), 2, (float(t - 2), 10.0)) for t in range(2, 5)]
    )
    estimates = run(
        [(float(t), 7, (float(t), 1.0)) for t in range(4)]
        + [(3.0, 8, (1.0, 12.0)), (4.0, 8, (2.0, 12.0)), (5.0, 8, (3.0, 10.0))]
    )
    return truth, estimates


def test_ospa2_hand_worked_two_trajectories() -> None:
    truth, estimates = two_trajectory_case()
    c = 5.0
    # Base distances, mean over D_x u D_y of min(c, |x - y|) or c where only one exists:
    #   d(A, 7): times 0..3, all 1 apart                          -> 1
    #   d(A, 8): times 0..5; A alone at 0-2, |(3,0)-(1,12)| > c at 3, 8 alone at 4, 5 -> c
    #   d(B, 7): times 0..4; 7 alone at 0, 1, > c apart at 2, 3, B alone at 4         -> c
    #   d(B, 8): times 2..5; B alone at 2 (c), 2 apart at 3 and 4, 8 alone at 5
    #            -> (5 + 2 + 2 + 5) / 4 = 3.5
    truth_ids, estimate_ids, distances = trajectory_base_distances(truth, estimates, c=c)
    np.testing.assert_array_equal(truth_ids, [1, 2])
    np.testing.assert_array_equal(estimate_ids, [7, 8])
    np.testing.assert_allclose(distances, [[1.0, 5.0], [5.0, 3.5]])
    # OSPA(2): pairs A-7 and B-8; p = 2: sqrt((1 + 3.5^2) / 2); p = 1: (1 + 3.5) / 2.
    result = ospa2(truth, estimates, c=c, p=2.0)
    assert result.total == pytest.approx(math.sqrt((1.0 + 12.25) / 2.0))
    assert (result.num_truth, result.num_estimates) == (2, 2)
    assert result.cardinality == 0.0
    assert ospa2(truth, estimates, c=c, p=1.0).total == pytest.approx(2.25)


def test_ospa2_short_false_track_costs_a_whole_trajectory() -> None:
    """A false track of a single row is one more unpaired trajectory: it adds c^p / n to
    OSPA(2)^p however short it is (while per-time OSPA pays for one time only)."""
    truth, estimates = two_trajectory_case()
    extra = run([(1.0, 9, (40.0, 40.0))])
    with_false = TimedPoints.from_unsorted(
        times=np.concatenate([estimates.times, extra.times]),
        ids=np.concatenate([estimates.ids, extra.ids]),
        positions=np.concatenate([estimates.positions, extra.positions]),
    )
    result = ospa2(truth, with_false, c=5.0, p=2.0)
    # n = 3: (1 + 3.5^2 + 5^2) / 3 = 12.75.
    assert result.total == pytest.approx(math.sqrt(12.75))
    assert result.cardinality == pytest.approx(25.0 / 3.0)
    assert (result.num_truth, result.num_estimates) == (2, 3)


def test_ospa2_docstring_example() -> None:
    truth = run([(float(t), 0, (float(t), 0.0)) for t in range(4)])
    follow = run([(float(t), 3, (float(t), 1.0)) for t in range(4)])
    assert ospa2(truth, follow, c=10.0).total == pytest.approx(1.0)
    switched = run([(float(t), 3 if t < 2 else 4, (float(t), 1.0)) for t in range(4)])
    assert ospa2(truth, switched, c=10.0).total == pytest.approx(math.sqrt(65.125))


def test_track_switch_raises_ospa2_while_per_time_ospa_is_zero() -> None:
    """Two targets 4 apart; the tracks follow them exactly but swap identities at t = 2."""
    a = [(float(t), 0.0) for t in range(4)]
    b = [(float(t), 4.0) for t in range(4)]
    truth = run([(float(t), 1, a[t]) for t in range(4)] + [(float(t), 2, b[t]) for t in range(4)])
    swapped = run(
        [(float(t), 10, a[t] if t < 2 else b[t]) for t in range(4)]
        + [(float(t), 11, b[t] if t < 2 else a[t]) for t in range(4)]
    )
    np.testing.assert_array_equal(ospa_over_time(truth, swapped, c=5.0).total, 0.0)
    np.testing.assert_array_equal(gospa_over_time(truth, swapped, c=5.0).total, 0.0)
    # Every truth-track pair: 0 at two times, 4 at the two others -> base distance 2.
    assert ospa2(truth, swapped, c=5.0).total == pytest.approx(2.0)
    # With c = 3 the 4 is cut off: (0 + 0 + 3 + 3) / 4 = 1.5.
    assert ospa2(truth, swapped, c=3.0).total == pytest.approx(1.5)
    # Without the switch the same positions give 0.
    assert ospa2(truth, truth, c=5.0).total == 0.0


def test_fragmented_track_raises_ospa2() -> None:
    truth = run([(float(t), 1, (float(t), 0.0)) for t in range(6)])
    fragments = run([(float(t), 5 if t < 3 else 6, (float(t), 0.0)) for t in range(6)])
    assert ospa_over_time(truth, fragments, c=2.0).mean_total == 0.0
    # Each fragment: 0 at 3 times and c at the 3 others -> c / 2; one fragment is unpaired.
    assert ospa2(truth, fragments, c=2.0).total == pytest.approx(math.sqrt((1.0 + 4.0) / 2.0))


def test_ospa2_empty_side_is_c() -> None:
    truth, _ = two_trajectory_case()
    empty = TimedPoints.empty(2)
    assert ospa2(truth, empty, c=5.0).total == pytest.approx(5.0)
    assert ospa2(empty, truth, c=5.0).total == pytest.approx(5.0)
    with pytest.raises(InputError, match="no rows"):
        ospa2(empty, empty, c=5.0)


# ----------------------------------------------------------------------------------------------
# OSPA(2): brute force, invariances, metric properties
# ----------------------------------------------------------------------------------------------


@settings(max_examples=120, deadline=None)
@given(truth=timed_run(), estimates=timed_run(), c=cutoffs, p=orders)
def test_ospa2_agrees_with_brute_force_definition(
    truth: TimedPoints, estimates: TimedPoints, c: float, p: float
) -> None:
    if truth.times.size + estimates.times.size == 0:
        return
    result = ospa2(truth, estimates, c=c, p=p)
    assert result.total == pytest.approx(
        brute_force_ospa2(truth, estimates, c, p), rel=1e-9, abs=1e-9
    )
    assert 0.0 <= result.total <= c * (1 + 1e-12)
    assert result.total**p == pytest.approx(
        result.localisation + result.cardinality, rel=1e-9, abs=1e-9
    )


@settings(max_examples=60, deadline=None)
@given(
    truth=timed_run(max_ids=4),
    estimates=timed_run(max_ids=4),
    seed=st.integers(0, 2**31 - 1),
    c=cutoffs,
)
def test_ospa2_is_invariant_to_id_relabelling(
    truth: TimedPoints, estimates: TimedPoints, seed: int, c: float
) -> None:
    if truth.times.size + estimates.times.size == 0:
        return
    rng = np.random.default_rng(seed)

    def relabel(points: TimedPoints) -> TimedPoints:
        new_ids = rng.permutation(100)[: 5] + 17  # a random injection of the ids 0..4
        return TimedPoints(times=points.times, ids=new_ids[points.ids], positions=points.positions)

    before = ospa2(truth, estimates, c=c)
    after = ospa2(relabel(truth), relabel(estimates), c=c)
    assert after.total == pytest.approx(before.total, rel=1e-12, abs=1e-12)
    windows_before = ospa2_over_time(truth, estimates, c=c, window_length=2)
    windows_after = ospa2_over_time(relabel(truth), relabel(estimates), c=c, window_length=2)
    np.testing.assert_allclose(windows_after.total, windows_before.total, rtol=1e-12, atol=1e-12)
    # ... and swapping the roles of truth and estimates changes nothing either.
    assert ospa2(estimates, truth, c=c).total == pytest.approx(before.total, rel=1e-12, abs=1e-12)


@settings(max_examples=80, deadline=None)
@given(x=timed_run(), y=timed_run(), z=timed_run(), c=cutoffs, p=orders)
def test_ospa2_triangle_inequality(
    x: TimedPoints, y: TimedPoints, z: TimedPoints, c: float, p: float
) -> None:
    runs = (x, y, z)
    if any(a.times.size + b.times.size == 0 for a, b in itertools.combinations(runs, 2)):
        return
    assert ospa2(x, z, c=c, p=p).total <= (
        ospa2(x, y, c=c, p=p).total + ospa2(y, z, c=c, p=p).total + 1e-9
    )


# ----------------------------------------------------------------------------------------------
# OSPA(2) over sliding windows
# ----------------------------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(
    truth=timed_run(num_times=6),
    estimates=timed_run(num_times=6),
    c=cutoffs,
    p=orders,
    window_length=st.integers(1, 7),
)
def test_windows_are_ospa2_of_the_rows_in_the_window(
    truth: TimedPoints, estimates: TimedPoints, c: float, p: float, window_length: int
) -> None:
    if truth.times.size + estimates.times.size == 0:
        return
    series = ospa2_over_time(truth, estimates, c=c, p=p, window_length=window_length)
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    assert series.total.shape == times.shape
    np.testing.assert_array_equal(series.end_times, times)
    for k in range(times.size):
        first = max(0, k - window_length + 1)
        assert series.start_times[k] == times[first]
        inside = set(times[first : k + 1].tolist())
        expected = brute_force_ospa2(truth, estimates, c, p, inside)
        assert series.total[k] == pytest.approx(expected, rel=1e-9, abs=1e-9)
        in_truth = len({i for t, i in zip(truth.times, truth.ids, strict=True) if t in inside})
        assert series.num_truth[k] == in_truth


def test_window_consistency_with_whole_run_and_per_time_ospa() -> None:
    truth, estimates = two_trajectory_case()
    whole = ospa2(truth, estimates, c=5.0).total
    # A window at least as long as the run ends, at the last time, on the whole run.
    for length in (6, 7, 100):
        series = ospa2_over_time(truth, estimates, c=5.0, window_length=length)
        assert series.total[-1] == pytest.approx(whole)
        assert series.start_times[-1] == 0.0
    # Windows of one time are per-time OSPA: a trajectory at one time is one point.
    single = ospa2_over_time(truth, estimates, c=5.0, window_length=1)
    np.testing.assert_allclose(single.total, ospa_over_time(truth, estimates, c=5.0).total)
    np.testing.assert_array_equal(single.start_times, single.end_times)
    # Window of 2 ending at t = 1: A and track 7 only, 1 apart at both times -> 1.
    pair = ospa2_over_time(truth, estimates, c=5.0, window_length=2)
    assert pair.total[1] == pytest.approx(1.0)
    assert (pair.num_truth[1], pair.num_estimates[1]) == (1, 1)
    # Ending at t = 5: B (t = 4) and track 8 (t = 4, 5): (2 + 5) / 2 = 3.5.
    assert pair.total[5] == pytest.approx(3.5)
    assert pair.mean_total == pytest.approx(float(np.mean(pair.total)))


@pytest.mark.parametrize("window_length", [0, -1, 2.0, True, None])
def test_bad_window_length(window_length: object) -> None:
    truth, estimates = two_trajectory_case()
    with pytest.raises(InputError, match="window_length"):
        ospa2_over_time(truth, estimates, c=5.0, window_length=window_length)  # type: ignore[arg-type]
