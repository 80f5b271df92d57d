"""T-GOSPA: hand-worked values, brute force over assignment sequences, metric properties."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from mapassoc.errors import InputError
from mapassoc.evaluation import tgospa as tgospa_module
from mapassoc.evaluation.metrics import TimedPoints, evaluate, format_report
from mapassoc.evaluation.tgospa import fragmentation_of, tgospa, track_fragmentation


def run(trajectories: dict[int, dict[int, tuple[float, ...]]]) -> TimedPoints:
    """TimedPoints from ``{id: {time: position}}``."""
    times, ids, positions = [], [], []
    for ident, points in trajectories.items():
        for time, position in points.items():
            times.append(float(time))
            ids.append(ident)
            positions.append(position)
    if not times:
        return TimedPoints.empty(2)
    return TimedPoints.from_unsorted(times=times, ids=ids, positions=positions)


def line(times: range, y: float, x0: float = 0.0) -> dict[int, tuple[float, float]]:
    return {t: (x0 + float(t), y) for t in times}


# ----------------------------------------------------------------------------------------------
# Hand-worked cases
# ----------------------------------------------------------------------------------------------


def test_identical_trajectories_are_at_distance_zero() -> None:
    truth = run({1: line(range(5), 0.0), 2: line(range(2, 7), 5.0)})
    estimates = run({7: line(range(5), 0.0), 9: line(range(2, 7), 5.0)})
    result = tgospa(truth, estimates, c=3.0, gamma=2.0, p=2.0)
    assert result.total == pytest.approx(0.0, abs=1e-12)
    assert result.switching == 0.0 and result.num_missed == 0.0 and result.num_false == 0.0


@pytest.mark.parametrize("p", [1.0, 2.0, 3.0])
def test_a_fully_missed_target_costs_half_c_to_the_p_per_step(p: float) -> None:
    steps, c = 6, 4.0
    truth = run({1: line(range(steps), 0.0)})
    result = tgospa(truth, TimedPoints.empty(2), c=c, gamma=1.0, p=p)
    assert result.total == pytest.approx((steps * c**p / 2.0) ** (1.0 / p), rel=1e-12)
    assert result.missed == pytest.approx(steps * c**p / 2.0)
    assert result.num_missed == steps
    np.testing.assert_allclose(result.missed_per_time, c**p / 2.0)


def test_a_false_track_costs_half_c_to_the_p_per_step() -> None:
    truth = run({1: line(range(4), 0.0)})
    estimates = run({3: line(range(4), 0.0), 4: line(range(1, 4), 50.0)})
    result = tgospa(truth, estimates, c=2.0, gamma=1.0, p=2.0)
    assert result.false == pytest.approx(3 * 2.0**2 / 2.0)
    np.testing.assert_allclose(result.false_per_time, [0.0, 2.0, 2.0, 2.0])
    assert result.total == pytest.approx(math.sqrt(6.0))


def test_localisation_is_capped_at_c() -> None:
    # One target, one estimate 10 away at every step: never closer than c, so missed + false.
    truth = run({1: line(range(3), 0.0)})
    estimates = run({2: line(range(3), 10.0)})
    result = tgospa(truth, estimates, c=2.0, gamma=1.0, p=1.0)
    assert result.total == pytest.approx(3 * 2.0)  # c^p per step, not the distance 10
    assert result.localisation == 0.0 and result.num_missed == 3 and result.num_false == 3
    near = tgospa(truth, run({2: line(range(3), 1.5)}), c=2.0, gamma=1.0, p=1.0)
    assert near.total == pytest.approx(3 * 1.5) and near.localisation == pytest.approx(4.5)


def test_two_tracks_that_swap_targets_once_cost_exactly_two_switches() -> None:
    # Parallel targets 10 apart; the tracks exchange them after step 1.  Staying would cost
    # c^p per target per step after the swap (here 2 * 2 * 9 = 36), switching costs gamma^p per
    # target.
    c, gamma, p = 3.0, 2.0, 2.0
    truth = run({1: line(range(4), 0.0), 2: line(range(4), 10.0)})
    a = {t: (float(t), 0.0 if t < 2 else 10.0) for t in range(4)}
    b = {t: (float(t), 10.0 if t < 2 else 0.0) for t in range(4)}
    result = tgospa(truth, run({5: a, 6: b}), c=c, gamma=gamma, p=p)
    assert result.total**p == pytest.approx(2 * gamma**p)
    assert result.switching == pytest.approx(2 * gamma**p) and result.num_switches == 2.0
    np.testing.assert_allclose(result.switching_per_step, [0.0, 2 * gamma**p, 0.0])
    assert result.localisation == 0.0 and result.num_missed == 0.0
    # A switch dearer than the misses it avoids is not taken.
    stay = tgospa(truth, run({5: a, 6: b}), c=c, gamma=10.0, p=p)
    assert stay.switching == 0.0 and stay.total**p == pytest.approx(2 * 2 * c**p)


def test_an_assignment_that_begins_or_ends_costs_half_a_switch() -> None:
    # One track follows target 1 for two steps, then target 2: target 1's assignment ends and
    # target 2's begins, gamma^p / 2 each, a full gamma^p in total.
    c, gamma, p = 3.0, 1.0, 2.0
    truth = run({1: line(range(4), 0.0), 2: line(range(4), 10.0)})
    track = {t: (float(t), 0.0 if t < 2 else 10.0) for t in range(4)}
    result = tgospa(truth, run({5: track}), c=c, gamma=gamma, p=p)
    assert result.switching == pytest.approx(gamma**p)
    assert result.num_switches == 1.0
    assert result.missed == pytest.approx(4 * c**p / 2.0)


def test_an_assignment_survives_a_gap_of_the_track_without_switching() -> None:
    # The track skips step 2: one missed step, and no switch cost (assignments persist).
    truth = run({1: line(range(5), 0.0)})
    track = {t: (float(t), 0.5) for t in range(5) if t != 2}
    result = tgospa(truth, run({5: track}), c=2.0, gamma=1.0, p=2.0)
    assert result.switching == 0.0
    assert result.total**2 == pytest.approx(4 * 0.25 + 2.0)
    assert fragmentation_of(result).num_id_switches == 0


def test_the_parts_add_up_and_per_time_parts_sum_to_the_totals() -> None:
    rng = np.random.default_rng(3)
    truth, estimates = random_pair(rng, 3, 3, 5)
    result = tgospa(truth, estimates, c=2.0, gamma=1.5, p=2.0)
    parts = result.localisation + result.missed + result.false + result.switching
    assert result.total**2 == pytest.approx(parts)
    assert np.sum(result.localisation_per_time) == pytest.approx(result.localisation)
    assert np.sum(result.switching_per_step) == pytest.approx(result.switching)


# ----------------------------------------------------------------------------------------------
# Brute force over all assignment sequences (the paper's definition, written independently)
# ----------------------------------------------------------------------------------------------


def as_arrays(points: TimedPoints, times: np.ndarray) -> np.ndarray:
    ids = np.unique(points.ids)
    out = np.full((times.size, ids.size, points.dim), np.nan)
    for time, ident, position in zip(points.times, points.ids, points.positions, strict=True):
        out[np.searchsorted(times, time), np.searchsorted(ids, ident)] = position
    return out


def brute_force(truth: TimedPoints, estimates: TimedPoints, c: float, gamma: float, p: float):
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    x = as_arrays(truth, times)
    y = as_arrays(estimates, times)
    nx, ny = x.shape[1], y.shape[1]
    # Every partial injective map of the nx true indices to {-1 (none), 0..ny-1}.
    maps = [
        m
        for m in itertools.product(range(-1, ny), repeat=nx)
        if len([j for j in m if j >= 0]) == len({j for j in m if j >= 0})
    ]

    def step_cost(t: int, m: tuple[int, ...]) -> float:
        cost = 0.0
        for i in range(nx):
            xi = x[t, i]
            if m[i] < 0:
                cost += 0.0 if np.isnan(xi[0]) else c**p / 2
                continue
            yj = y[t, m[i]]
            if np.isnan(xi[0]) and np.isnan(yj[0]):
                continue
            if np.isnan(xi[0]) or np.isnan(yj[0]):
                cost += c**p / 2
            else:
                cost += min(float(np.linalg.norm(xi - yj)), c) ** p
        for j in range(ny):
            if j not in m and not np.isnan(y[t, j, 0]):
                cost += c**p / 2
        return cost

    def switch(m: tuple[int, ...], n: tuple[int, ...]) -> float:
        s = 0.0
        for a, b in zip(m, n, strict=True):
            if a != b:
                s += 1.0 if (a >= 0 and b >= 0) else 0.5
        return s

    costs = [[step_cost(t, m) for m in maps] for t in range(times.size)]
    best = math.inf
    for sequence in itertools.product(range(len(maps)), repeat=times.size):
        total = sum(costs[t][k] for t, k in enumerate(sequence))
        total += gamma**p * sum(switch(maps[a], maps[b]) for a, b in itertools.pairwise(sequence))
        best = min(best, total)
    return best ** (1.0 / p)


def random_pair(
    rng: np.random.Generator, nx: int, ny: int, steps: int, spread: float = 3.0
) -> tuple[TimedPoints, TimedPoints]:
    def trajectories(n: int, first_id: int) -> TimedPoints:
        data = {}
        for k in range(n):
            start = int(rng.integers(0, steps))
            end = int(rng.integers(start, steps))
            data[first_id + k] = {
                t: tuple(rng.uniform(0.0, spread, size=2))
                for t in range(start, end + 1)
                if rng.random() > 0.15 or t == start
            }
        return run(data)

    return trajectories(nx, 0), trajectories(ny, 100)


@pytest.mark.parametrize(
    ("seed", "nx", "ny", "steps", "p"),
    [(0, 2, 2, 3, 2.0), (1, 2, 2, 4, 1.0), (2, 2, 3, 3, 2.0), (3, 3, 2, 3, 1.5), (4, 1, 3, 4, 2.0)],
)
@pytest.mark.parametrize("solver", ["dynamic programming", "integer program"])
def test_the_exact_metric_equals_brute_force(seed, nx, ny, steps, p, solver, monkeypatch) -> None:
    if solver == "integer program":  # no component is small enough for the Viterbi path
        monkeypatch.setattr(tgospa_module, "_MAX_DP_STATES", 0)
    rng = np.random.default_rng(seed)
    for _ in range(3):
        truth, estimates = random_pair(rng, nx, ny, steps)
        c, gamma = 2.0, float(rng.uniform(0.3, 2.0))
        expected = brute_force(truth, estimates, c, gamma, p)
        result = tgospa(truth, estimates, c=c, gamma=gamma, p=p)
        assert result.total == pytest.approx(expected, abs=1e-9)
        relaxed = tgospa(truth, estimates, c=c, gamma=gamma, p=p, method="lp")
        assert relaxed.total <= result.total + 1e-9
        assert relaxed.method == "lp" and result.method == "milp"


# ----------------------------------------------------------------------------------------------
# Metric properties
# ----------------------------------------------------------------------------------------------


def test_symmetric_and_zero_on_itself() -> None:
    rng = np.random.default_rng(11)
    for _ in range(5):
        x, y = random_pair(rng, 3, 4, 6)
        forward = tgospa(x, y, c=2.0, gamma=1.0, p=2.0)
        backward = tgospa(y, x, c=2.0, gamma=1.0, p=2.0)
        assert forward.total == pytest.approx(backward.total, abs=1e-9)
        assert forward.missed == pytest.approx(backward.false, abs=1e-9)
        assert tgospa(x, x, c=2.0, gamma=1.0, p=2.0).total == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("method", ["milp", "lp"])
def test_triangle_inequality_on_random_triples(method: str) -> None:
    rng = np.random.default_rng(12)
    for _ in range(8):
        x, y = random_pair(rng, 3, 3, 5)
        z, _ = random_pair(rng, 2, 0, 5)

        def d(a: TimedPoints, b: TimedPoints) -> float:
            return tgospa(a, b, c=2.0, gamma=1.0, p=2.0, method=method).total

        assert d(x, z) <= d(x, y) + d(y, z) + 1e-9


# ----------------------------------------------------------------------------------------------
# Fragmentation
# ----------------------------------------------------------------------------------------------


def test_fragmentation_of_a_target_covered_by_two_tracks_in_turn() -> None:
    truth = run({1: line(range(6), 0.0), 2: line(range(6), 20.0)})
    tracks = run(
        {
            10: {t: (float(t), 0.2) for t in range(3)},
            11: {t: (float(t), 0.1) for t in range(3, 6)},
            12: line(range(6), 20.3),
        }
    )
    fragmentation = track_fragmentation(truth, tracks, c=2.0)
    np.testing.assert_array_equal(fragmentation.truth_ids, [1, 2])
    np.testing.assert_array_equal(fragmentation.fragments, [2, 1])
    np.testing.assert_array_equal(fragmentation.id_switches, [1, 0])
    assert fragmentation.fragments_per_target == pytest.approx(1.5)
    assert fragmentation.summary() == {
        "num_targets": 2,
        "num_tracked_targets": 2,
        "fragments_per_target": 1.5,
        "id_switches": 1,
    }


def test_fragmentation_with_a_gap_counts_fragments_but_no_switch() -> None:
    # Track 10 until step 1, nothing at step 2, track 11 from step 3: two fragments, and no
    # identity switch because the target is not assigned at two consecutive steps across it.
    truth = run({1: line(range(5), 0.0)})
    tracks = run({10: {0: (0.0, 0.1), 1: (1.0, 0.1)}, 11: {3: (3.0, 0.1), 4: (4.0, 0.1)}})
    fragmentation = track_fragmentation(truth, tracks, c=2.0)
    np.testing.assert_array_equal(fragmentation.fragments, [2])
    np.testing.assert_array_equal(fragmentation.id_switches, [0])


def test_fragmentation_of_an_untracked_run_is_nan_per_target() -> None:
    fragmentation = track_fragmentation(run({1: line(range(3), 0.0)}), TimedPoints.empty(2), c=1.0)
    assert math.isnan(fragmentation.fragments_per_target)
    assert fragmentation.summary()["fragments_per_target"] is None


# ----------------------------------------------------------------------------------------------
# Validation
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("arguments", "name"),
    [
        ({"c": 0.0, "gamma": 1.0}, "c"),
        ({"c": math.inf, "gamma": 1.0}, "c"),
        ({"c": 1.0, "gamma": 0.0}, "gamma"),
        ({"c": 1.0, "gamma": -2.0}, "gamma"),
        ({"c": 1.0, "gamma": 1.0, "p": 0.5}, "p"),
        ({"c": 1.0, "gamma": 1.0, "method": "exact"}, "method"),
        ({"c": 1e300, "gamma": 1.0}, r"c\^p"),
        ({"c": 1.0, "gamma": 1e300}, r"gamma\^p"),
    ],
)
def test_bad_arguments_name_the_argument(arguments: dict, name: str) -> None:
    truth = run({1: line(range(2), 0.0)})
    with pytest.raises(InputError, match=rf"^{name} "):
        tgospa(truth, truth, **arguments)


def test_bad_inputs_are_refused() -> None:
    truth = run({1: line(range(2), 0.0)})
    with pytest.raises(InputError, match="truth must be a TimedPoints"):
        tgospa(np.zeros((2, 2)), truth, c=1.0, gamma=1.0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="same position dimension"):
        tgospa(truth, run({1: {0: (0.0,)}}), c=1.0, gamma=1.0)
    with pytest.raises(InputError, match="no rows"):
        tgospa(TimedPoints.empty(2), TimedPoints.empty(2), c=1.0, gamma=1.0)


# ----------------------------------------------------------------------------------------------
# In evaluate and its report
# ----------------------------------------------------------------------------------------------


def test_evaluate_adds_tgospa_and_fragmentation_only_with_a_switch_cost() -> None:
    truth = run({1: line(range(4), 0.0), 2: line(range(4), 10.0)})
    a = {t: (float(t), 0.0 if t < 2 else 10.0) for t in range(4)}
    b = {t: (float(t), 10.0 if t < 2 else 0.0) for t in range(4)}
    estimates = run({5: a, 6: b})
    plain = evaluate(truth, estimates, c=3.0, p=2.0)
    assert plain.tgospa is None and plain.fragmentation is None
    assert "tgospa" not in plain.to_json() and "fragmentation" not in plain.to_json()
    full = evaluate(truth, estimates, c=3.0, p=2.0, switch_cost=2.0)
    assert full.to_json()["gospa"] == plain.to_json()["gospa"]  # existing keys unchanged
    summary = full.to_json()
    assert json.loads(json.dumps(summary, allow_nan=False)) == summary
    assert summary["tgospa"]["total"] == pytest.approx(math.sqrt(8.0))
    assert summary["tgospa"]["num_switches"] == 2.0 and summary["tgospa"]["gamma"] == 2.0
    assert summary["fragmentation"]["fragments_per_target"] == 2.0
    assert summary["fragmentation"]["id_switches"] == 2
    report = format_report(full).splitlines()
    assert len({len(line) for line in report}) == 1
    before = [line.split() for line in format_report(plain).splitlines()]
    assert [line.split() for line in report[: len(before)]] == before  # the old rows first
    tg = next(line for line in report if line.startswith("T-GOSPA (c=3, p=2, gamma=2)"))
    assert tg.endswith(f"{math.sqrt(8.0):.4f}")
    assert any(line.startswith("identity switches") and line.endswith(" 2") for line in report)
    lower = evaluate(truth, estimates, c=3.0, switch_cost=2.0, tgospa_method="lp")
    assert "LP lower bound" in format_report(lower)
    with pytest.raises(InputError, match="^switch_cost "):
        evaluate(truth, estimates, c=3.0, switch_cost=0.0)
    with pytest.raises(InputError, match="^tgospa_method "):
        evaluate(truth, estimates, c=3.0, switch_cost=1.0, tgospa_method="simplex")
