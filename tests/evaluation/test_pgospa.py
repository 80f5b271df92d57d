"""P-GOSPA (Xia, García-Fernández, Karlsson, Yuan, Chang and Svensson, "Probabilistic GOSPA: a
metric for performance evaluation of multi-object filters with uncertainties"): hand-worked
values, agreement with GOSPA when every existence is 1, a brute-force oracle over all partial
assignments, the metric properties, and the report-or-omit threshold."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import TimedPoints, gospa, gospa_over_time
from mapassoc.evaluation.pgospa import pgospa, pgospa_over_time

# With c = 2 and p = 2 a miss or a whole false estimate costs c^p / 2 = 2.
C, P = 2.0, 2.0


@pytest.mark.parametrize(
    ("r", "expected_power"),
    [
        # d = 1 < c.  r = 1: assigned, r d^p = 1 (the GOSPA value).
        (1.0, 1.0),
        # r = 0.5: assigned, min(1, .5) * 1 + |1 - .5| * 2 = 0.5 + 1 = 1.5 (unassigned: 2 + 1 = 3).
        (0.5, 1.5),
        # r = 0: assigned 0 + 1 * 2 = 2, unassigned 2 + 0 = 2: the same, 2.
        (0.0, 2.0),
    ],
)
def test_one_target_one_estimate_inside_the_cut_off(r: float, expected_power: float) -> None:
    result = pgospa([[0.0, 0.0]], [[1.0, 0.0]], [r], c=C, p=P)
    assert result.total == pytest.approx(math.sqrt(expected_power))
    parts = result.localisation + result.existence_mismatch + result.missed + result.false
    assert parts == pytest.approx(expected_power)


def test_the_parts_at_half_existence_inside_the_cut_off() -> None:
    result = pgospa([[0.0, 0.0]], [[1.0, 0.0]], [0.5], c=C, p=P)
    assert (result.localisation, result.existence_mismatch) == pytest.approx((0.5, 1.0))
    assert (result.missed, result.false) == (0.0, 0.0)
    assert result.assignments.tolist() == [[0, 0]]


@pytest.mark.parametrize(
    # d = 3 >= c: never assigned; a miss (2) plus a false estimate of weight r (2 r).
    ("r", "expected_power"),
    [(1.0, 4.0), (0.5, 3.0), (0.0, 2.0)],
)
def test_one_target_one_estimate_outside_the_cut_off(r: float, expected_power: float) -> None:
    result = pgospa([[0.0, 0.0]], [[3.0, 0.0]], [r], c=C, p=P)
    assert result.total == pytest.approx(math.sqrt(expected_power))
    assert result.missed == pytest.approx(2.0)
    assert result.false == pytest.approx(2.0 * r)
    assert result.assignments.shape == (0, 2)


def test_empty_sets() -> None:
    assert pgospa([], [], [], c=C, p=P).total == 0.0
    # Two estimates and no truth: false = 2 * (0.3 + 1) = 2.6.
    only_false = pgospa(np.zeros((0, 2)), [[0.0, 0.0], [5.0, 5.0]], [0.3, 1.0], c=C, p=P)
    assert only_false.false == pytest.approx(2.6)
    assert only_false.total == pytest.approx(math.sqrt(2.6))
    # Two targets and no estimates: missed = 2 * 2 = 4.
    only_missed = pgospa([[0.0, 0.0], [1.0, 1.0]], [], [], c=C, p=P)
    assert only_missed.missed == pytest.approx(4.0)
    assert only_missed.total == pytest.approx(2.0)


def _random_set(rng: np.random.Generator, size: int) -> np.ndarray:
    return rng.uniform(0.0, 4.0, size=(size, 2))


def test_with_every_existence_one_it_is_gospa() -> None:
    rng = np.random.default_rng(0)
    for _ in range(200):
        truth = _random_set(rng, int(rng.integers(0, 6)))
        estimates = _random_set(rng, int(rng.integers(0, 6)))
        p = float(rng.choice([1.0, 2.0, 3.0]))
        got = pgospa(truth, estimates, np.ones(len(estimates)), c=1.5, p=p)
        want = gospa(truth, estimates, c=1.5, p=p)
        assert got.total == pytest.approx(want.total, rel=1e-12, abs=1e-12)
        assert got.existence_mismatch == pytest.approx(0.0, abs=1e-12)


def _brute_force(x, rx, y, ry, c: float, p: float) -> float:
    """Minimum over every partial assignment of the P-GOSPA p-th power (its definition)."""
    half = c**p / 2.0
    best = math.inf
    n, m = len(x), len(y)
    for k in range(min(n, m) + 1):
        for rows in itertools.combinations(range(n), k):
            for cols in itertools.permutations(range(m), k):
                cost = half * (sum(rx) + sum(ry))
                for i, j in zip(rows, cols, strict=True):
                    d = float(np.linalg.norm(x[i] - y[j]))
                    # Assigning (i, j) replaces their unassigned costs (r_i + s_j) c^p / 2.
                    cost += min(rx[i], ry[j]) * d**p + abs(rx[i] - ry[j]) * half
                    cost -= (rx[i] + ry[j]) * half
                best = min(best, cost)
    return best ** (1.0 / p)


def test_the_exact_value_equals_brute_force_over_all_assignments() -> None:
    rng = np.random.default_rng(1)
    for _ in range(150):
        x = _random_set(rng, int(rng.integers(0, 5)))
        y = _random_set(rng, int(rng.integers(0, 5)))
        rx, ry = rng.uniform(size=len(x)), rng.uniform(size=len(y))
        p = float(rng.choice([1.0, 2.0]))
        got = pgospa(x, y, ry, c=1.5, p=p, truth_existence=rx).total
        assert got == pytest.approx(_brute_force(x, rx, y, ry, 1.5, p), rel=1e-10, abs=1e-12)


def test_symmetric_with_existence_on_both_sides_and_zero_on_itself() -> None:
    rng = np.random.default_rng(2)
    for _ in range(100):
        x, y = _random_set(rng, 3), _random_set(rng, 4)
        rx, ry = rng.uniform(size=3), rng.uniform(size=4)
        forward = pgospa(x, y, ry, c=1.5, p=2.0, truth_existence=rx).total
        backward = pgospa(y, x, rx, c=1.5, p=2.0, truth_existence=ry).total
        assert forward == pytest.approx(backward, rel=1e-12)
        assert pgospa(x, x, rx, c=1.5, p=2.0, truth_existence=rx).total == pytest.approx(0.0)


def test_triangle_inequality_on_random_triples() -> None:
    rng = np.random.default_rng(3)
    for _ in range(300):
        sets = [_random_set(rng, int(rng.integers(0, 4))) for _ in range(3)]
        probs = [rng.uniform(size=len(s)) for s in sets]
        p = float(rng.choice([1.0, 2.0]))

        d = {
            (a, b): pgospa(sets[a], sets[b], probs[b], c=1.5, p=p, truth_existence=probs[a]).total
            for a, b in ((0, 1), (1, 2), (0, 2))
        }
        assert d[0, 2] <= d[0, 1] + d[1, 2] + 1e-9


@pytest.mark.parametrize("p", [1.0, 2.0])
def test_report_or_omit_a_lone_estimate(p: float) -> None:
    # A lone target and an estimate at d < c with existence r:
    #   report: r d^p + (1 - r) c^p / 2;  omit: c^p / 2;  difference r (d^p - c^p / 2).
    # So with the target present, reporting costs less for every r > 0 exactly when
    # d < c / 2^(1/p), and the saving grows with r.
    c = 2.0
    threshold = c / 2.0 ** (1.0 / p)
    omit = pgospa([[0.0]], [], [], c=c, p=p).total
    for d in (0.5 * threshold, 0.99 * threshold, 1.01 * threshold, 0.99 * c):
        for r in (0.1, 0.5, 1.0):
            report = pgospa([[0.0]], [[d]], [r], c=c, p=p).total
            assert (report < omit) == (d < threshold)
    # If the estimate is real with probability q, the expected cost of reporting minus that
    # of omitting is r (q d^p + (1 - 2 q) c^p / 2): negative exactly when
    # q > c^p / (2 (c^p - d^p)).
    d = 0.5 * threshold
    q_star = c**p / (2.0 * (c**p - d**p))
    for q in (q_star - 0.02, q_star + 0.02):
        for r in (0.3, 1.0):
            present = pgospa([[0.0]], [[d]], [r], c=c, p=p).total ** p
            absent = pgospa(np.zeros((0, 1)), [[d]], [r], c=c, p=p).total ** p
            expected_report = q * present + (1 - q) * absent
            expected_omit = q * omit**p
            assert (expected_report < expected_omit) == (q > q_star)


def test_over_time_equals_per_time_values_and_gospa_at_existence_one() -> None:
    rng = np.random.default_rng(4)
    truth = TimedPoints.from_unsorted(
        times=[0, 0, 1, 2], ids=[1, 2, 1, 1], positions=rng.uniform(0, 3, (4, 2))
    )
    estimates = TimedPoints.from_unsorted(
        times=[0, 1, 1, 3], ids=[7, 7, 8, 7], positions=rng.uniform(0, 3, (4, 2))
    )
    r = np.array([0.9, 0.2, 0.6, 0.4])
    series = pgospa_over_time(truth, estimates, r, c=1.5, p=2.0)
    assert series.times.tolist() == [0.0, 1.0, 2.0, 3.0]
    for k, t in enumerate(series.times):
        here = estimates.times == t
        one = pgospa(truth.positions_at(t), estimates.positions[here], r[here], c=1.5, p=2.0)
        assert series.total[k] == pytest.approx(one.total)
    ones = pgospa_over_time(truth, estimates, np.ones(4), c=1.5, p=2.0)
    np.testing.assert_allclose(ones.total, gospa_over_time(truth, estimates, c=1.5).total)


def test_validation_names_the_argument() -> None:
    with pytest.raises(InputError, match="existence must lie in"):
        pgospa([[0.0]], [[0.0]], [1.5], c=1.0)
    with pytest.raises(InputError, match="existence must have shape"):
        pgospa([[0.0]], [[0.0]], [0.5, 0.5], c=1.0)
    with pytest.raises(InputError, match="truth_existence"):
        pgospa([[0.0]], [[0.0]], [0.5], c=1.0, truth_existence=[-0.1])
    with pytest.raises(InputError, match="c must"):
        pgospa([[0.0]], [[0.0]], [0.5], c=0.0)
    run = TimedPoints.from_unsorted(times=[0], ids=[1], positions=[[0.0]])
    with pytest.raises(InputError, match="existence must have shape"):
        pgospa_over_time(run, run, [0.5, 0.5], c=1.0)
