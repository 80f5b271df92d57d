"""The table of the model's score terms (mapassoc.estimator.terms): each term against a
value worked by hand, the tails against enumeration of a track's endings, and the
hypothesis trees, J and the network-flow tracker reading their numbers from it."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from support import make_config, make_scans

from mapassoc.errors import InputError
from mapassoc.estimator.hypotheses import HypothesisGenerator
from mapassoc.estimator.objective import RecordingObjective
from mapassoc.estimator.terms import (
    ScanTerms,
    SensorTerms,
    best_endings,
    birth_term,
    end_term,
    ending_masses,
    miss_term,
    survival_term,
)
from mapassoc.models.motion import ConstantVelocity

PD, PG, PS, DT, CLUTTER, AREA = 0.9, 0.99, 0.99, 2.0, 10.0, 200.0 * 200.0


def _config(**overrides: float):
    settings = dict(
        detection_probability=PD,
        false_alarms_per_scan=CLUTTER,
        rate=0.0,
        initial_count=2.0,
        survival_probability=PS,
        gate_probability=PG,
    )
    settings.update(overrides)
    return make_config(
        motion=ConstantVelocity(ndim=2, noise_intensity=1.0),
        noise_std=1.0,
        region=[[-100.0, 100.0], [-100.0, 100.0]],
        **settings,
    )


def _two_scans():
    return make_scans([0.0, DT], [[[0.0, 0.0]], [[1.0, 1.0], [5.0, 5.0]]], 2)


def test_each_term_of_a_two_scan_recording_equals_its_hand_worked_value() -> None:
    terms = ScanTerms.of_recording(_config(), _two_scans())
    miss = math.log(1 - PD * PG)  # log 0.109
    survive = DT * math.log(PS)
    end = math.log(1 - PS**DT)  # log 0.0199
    assert terms.miss.tolist() == pytest.approx([miss, miss], abs=1e-14)
    assert terms.survival.tolist() == pytest.approx([0.0, survive], abs=1e-14)
    assert terms.end[0] == pytest.approx(end, abs=1e-12) and terms.end[1] == -math.inf
    assert terms.log_pd.tolist() == pytest.approx([math.log(PD)] * 2, abs=1e-14)
    assert terms.log_clutter.tolist() == pytest.approx([math.log(CLUTTER / AREA)] * 2)
    # The chi-square quantile in two dimensions is -2 log(1 - P_G).
    assert terms.thresholds.tolist() == pytest.approx([-2 * math.log(1 - PG)] * 2)
    # Two targets present at the start and no births: u_0 = 2, and u_1 = 2 Ps^dt (1 - Pd)
    # (survived, not detected at scan 0).
    u1 = 2 * PS**DT * (1 - PD)
    assert terms.birth.tolist() == pytest.approx(
        [math.log(2 * PD / CLUTTER), math.log(u1 * PD / CLUTTER)], abs=1e-12
    )
    # After scan 0: end in the gap, or survive, be missed at scan 1, the recording's end.
    assert terms.tails.tolist() == pytest.approx([max(end, survive + miss), 0.0], abs=1e-12)
    assert terms.tail_masses[0] == pytest.approx(
        math.log(1 - PS**DT + PS**DT * (1 - PD * PG)), abs=1e-12
    )
    assert terms.tail_masses[1] == 0.0
    assert [u.expected_count for u in terms.undetected_after][0] == pytest.approx(
        2 * (1 - PD), abs=1e-12
    )


def test_the_equations_at_their_edges() -> None:
    assert miss_term(PD, PG) == math.log1p(-PD * PG)
    assert miss_term(1.0, 1.0) == -math.inf
    assert birth_term(0.0, math.log(PD), math.log(CLUTTER)) == -math.inf
    assert end_term(np.array([0.0, 1.0]), math.log(PS))[0] == -math.inf
    assert end_term(np.array([1.0]), 0.0)[0] == -math.inf  # Ps = 1: a target never ends
    assert survival_term(DT, math.log(PS)) == DT * math.log(PS)


def test_a_sensor_without_false_alarms_is_refused_by_name() -> None:
    config = _config(false_alarms_per_scan=0.0)
    with pytest.raises(InputError, match="sensor 's' has false_alarms_per_scan = 0.0"):
        SensorTerms.of(config.sensors["s"], PG)


def _endings_by_enumeration(survival, miss, end, m: int) -> list[float]:
    """Every ending of a track whose last detection is at scan m: ended in the gap after
    scan g >= m (missed at m+1..g), or missed at every later scan to the last."""
    n = len(end)
    values = []
    for g in range(m, n):
        missed = sum(survival[k] + miss[k] for k in range(m + 1, g + 1))
        values.append(missed + (end[g] if g < n - 1 else 0.0))
    return values


@pytest.mark.parametrize("seed", range(5))
def test_tails_and_masses_equal_enumeration_of_the_endings(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 7))
    times = np.cumsum(rng.uniform(0.0, 3.0, n))
    times[rng.random(n) < 0.2] = times[0]  # some zero time steps
    times.sort()
    log_ps = math.log(rng.uniform(0.5, 1.0))
    survival = np.concatenate([[0.0], survival_term(np.diff(times), log_ps)])
    end = np.concatenate([end_term(np.diff(times), log_ps), [-math.inf]])
    miss = np.array([miss_term(rng.uniform(0.1, 1.0), 1.0) for _ in range(n)])
    tails, masses = best_endings(survival, miss, end), ending_masses(survival, miss, end)
    for m in range(n):
        values = _endings_by_enumeration(survival, miss, end, m)
        assert tails[m] == pytest.approx(max(values), abs=1e-12)
        with np.errstate(divide="ignore"):
            assert masses[m] == pytest.approx(np.logaddexp.reduce(values), abs=1e-12)


def test_a_windows_tails_and_the_endings_before_a_scan_equal_enumeration() -> None:
    rng = np.random.default_rng(7)
    times = np.cumsum(rng.uniform(0.5, 2.0, 8)).tolist()
    scans = make_scans(times, [[[0.0, 0.0]]] * len(times), 2)
    terms = ScanTerms.of_recording(_config(), scans)
    for start, stop in itertools.combinations(range(len(times) + 1), 2):
        window = terms.window_tails(start, stop)
        for m in range(stop - start):
            values = _endings_by_enumeration(
                terms.survival[start:stop], terms.miss[start:stop], terms.end[start:stop], m
            )
            assert window[m] == pytest.approx(max(values), abs=1e-12)
        # Ended in a gap after scans start..stop-1 (never lived to scan stop).
        best, mass = terms.endings_before(1.5, start, stop)
        ended = [
            1.5 + terms.misses_between(start + 1, g) + terms.end[g] for g in range(start, stop)
        ]
        assert best == pytest.approx(max(ended), abs=1e-12)
        assert mass == pytest.approx(np.logaddexp.reduce(ended), abs=1e-12)
    assert terms.endings_before(0.0, 3, 3) == (-math.inf, -math.inf)


def test_the_trees_and_j_score_with_the_tables_numbers() -> None:
    config = _config()
    scans = _two_scans()
    terms = ScanTerms.of_recording(config, scans)
    generator = HypothesisGenerator(
        motion=config.motion,
        sensors=config.sensors,
        birth=config.birth,
        gate_probability=PG,
        max_hypotheses_per_tree=10**6,
        prune_log_ratio=math.inf,
    )
    hyps = generator.generate(scans)
    nodes = hyps.nodes
    root = int(np.flatnonzero(nodes.layer == 0)[0])
    assert nodes.score[root] == terms.birth[0]
    children = np.flatnonzero(nodes.parent == root)
    ended = children[~nodes.alive[children]]
    missed = children[nodes.alive[children] & (nodes.detection[children] < 0)]
    assert nodes.score[ended] == [terms.birth[0] + terms.end[0]]
    assert nodes.score[missed] == [terms.birth[0] + terms.survival[1] + terms.miss[1]]
    # Births at scan 1 score against u_1.
    assert set(nodes.score[(nodes.layer == 1) & (nodes.parent < 0)]) == {terms.birth[1]}
    objective = RecordingObjective(config=config, scans=scans)
    assert objective.terms.birth.tolist() == terms.birth.tolist()
    assert objective.track_value(((0, 0),)) == terms.birth[0] + terms.tails[0]
    assert objective.track_value(((1, 1),)) == terms.birth[1]


def test_best_endings_hand_worked() -> None:
    # Ps = 0.9 per unit, scans at 0, 1, 3; log(1 - Pd P_G) = log 0.2 at every scan.
    log_ps, log_miss = math.log(0.9), math.log(0.2)
    gaps = np.array([1.0, 2.0])
    survival = np.concatenate([[0.0], survival_term(gaps, log_ps)])
    end = np.concatenate([end_term(gaps, log_ps), [-math.inf]])
    tails = best_endings(survival, np.full(3, log_miss), end)
    # tail_2 = 0; tail_1 = max(log(1 - 0.81), 2 log 0.9 + log 0.2) = log 0.19;
    # tail_0 = max(log 0.1, log 0.9 + log 0.2 + log 0.19) = log 0.1.
    assert tails.tolist() == pytest.approx([math.log(0.1), math.log(0.19), 0.0])
