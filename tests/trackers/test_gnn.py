"""GNN tracker and the shared track management (score and M-of-N rules)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from support import SENSOR, make_config, make_scans

from mapassoc.data.config import Config
from mapassoc.data.settings import EstimatorSettings
from mapassoc.errors import InputError
from mapassoc.evaluation.scenarios import birth_model_for, build_scenario
from mapassoc.evaluation.simulate import TargetSpec, scan_plan_regular, simulate
from mapassoc.filtering import track_filter as tf
from mapassoc.filtering.smoothing import smooth_tracks
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.sensor import Region, Sensor
from mapassoc.trackers.base import Tracker
from mapassoc.trackers.gnn import GnnTracker, gnn_assignment
from mapassoc.trackers.management import MOfNRule, ScoreRule, TrackLife, TrackManager


def _config(*, false_alarms: float = 2.0, pd: float = 0.9, gate: float = 1.0) -> Config:
    return make_config(
        motion=ConstantVelocity(ndim=2, noise_intensity=0.01),
        noise_std=1.0,
        detection_probability=pd,
        false_alarms_per_scan=false_alarms,
        region=[[-50.0, 50.0], [-50.0, 50.0]],
        gate_probability=gate,
    )


# ------------------------------------------------------------------ assignment


def test_assignment_beats_greedy_on_a_hand_worked_two_by_two_case() -> None:
    # Track B's best detection (ratio 6) is also track A's only one (ratio 5); B can take
    # detection 2 instead (ratio 4).  Greedy (best pair first): B-1, A misses:
    # 6 - 2.3 = 3.7.  Optimal: A-1, B-2: 5 + 4 = 9.
    L = np.array([[5.0, -np.inf], [6.0, 4.0]])
    miss = np.full(2, -2.3)
    assert gnn_assignment(L, miss).tolist() == [0, 1]
    # A detection worse than a miss is left unassigned (it then starts a track).
    assert gnn_assignment(np.array([[-3.0, -np.inf]]), np.array([-2.3])).tolist() == [-1]
    assert gnn_assignment(np.zeros((2, 0)), miss).tolist() == [-1, -1]


def test_assignment_is_the_best_of_all_feasible_joint_assignments() -> None:
    rng = np.random.default_rng(3)
    for _ in range(30):
        T, M = rng.integers(1, 4), rng.integers(0, 4)
        L = rng.normal(0.0, 3.0, size=(T, M))
        L[rng.random((T, M)) < 0.3] = -np.inf
        miss = rng.normal(-2.0, 1.0, size=T)
        best = -np.inf
        for pick in itertools.product(range(-1, M), repeat=T):
            used = [j for j in pick if j >= 0]
            if len(used) != len(set(used)):
                continue
            total = sum(L[t, j] if j >= 0 else miss[t] for t, j in enumerate(pick))
            best = max(best, total)
        got = gnn_assignment(L, miss)
        value = sum(L[t, j] if j >= 0 else miss[t] for t, j in enumerate(got.tolist()))
        assert value == pytest.approx(best)


def test_assignment_refuses_bad_arguments() -> None:
    with pytest.raises(InputError, match="log_miss must have shape"):
        gnn_assignment(np.zeros((2, 2)), np.zeros(3))
    with pytest.raises(InputError, match="NaN"):
        gnn_assignment(np.array([[np.nan]]), np.zeros(1))
    with pytest.raises(InputError, match="finite"):
        gnn_assignment(np.zeros((1, 1)), np.array([-np.inf]))


def test_tracker_takes_the_optimal_not_the_greedy_pairing() -> None:
    # Two tracks confirmed at birth (1-of-1) at x = 0 and x = 2.6 (zero mean velocity:
    # both predict to where they started, with the same S).  Detections at x = 1.5 and
    # x = 4.2: the nearest pair is B-1.5 (distance 1.1), after which A would take 4.2;
    # the optimal assignment is, B-4.2 (squared distances 2.25 + 2.56 < 1.21 +
    # 17.64).
    config = _config()
    scans = make_scans([0.0, 1.0], [[[0.0, 0.0], [2.6, 0.0]], [[1.5, 0.0], [4.2, 0.0]]], 2)
    rule = MOfNRule(confirm_hits=1, confirm_scans=1, delete_misses=2)
    out = GnnTracker(config=config, management=rule).track(scans)
    by_start = {a[0]: a for a in out.associations.values()}
    assert by_start[0] == {0: 0, 1: 0} and by_start[1] == {0: 1, 1: 1}
    # The greedy nearest neighbour would have paired them the other way.
    tracks = [scans[0].detections[0], scans[0].detections[1]]
    d = np.array([[np.linalg.norm(z - x) for z in scans[1].detections] for x in tracks])
    t, j = np.unravel_index(np.argmin(d), d.shape)
    assert (t, j) == (1, 0)


# ------------------------------------------------------------------ whole runs


def _clutter_free_scenario(seed: int):
    motion = ConstantVelocity(ndim=2, noise_intensity=0.002)
    sensor = Sensor(
        name="pos",
        measurement=LinearMeasurement.position(motion, noise_std=1.0),
        detection_probability=0.9,
        false_alarms_per_scan=1e-6,
        region=Region.from_bounds([[-100.0, 100.0], [-100.0, 100.0]]),
    )
    # Two targets crossing at right angles (passing the crossing point 3 scans apart)
    # and one far away.
    targets = [
        TargetSpec(np.array([-40.0, 0.0, 2.0, 0.0]), 0.0, math.inf),
        TargetSpec(np.array([0.0, -46.0, 0.0, 2.0]), 0.0, math.inf),
        TargetSpec(np.array([50.0, 60.0, -1.0, -0.5]), 0.0, math.inf),
    ]
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 40)
    config = Config(
        motion=motion,
        sensors={"pos": sensor},
        birth=birth_model_for(motion, targets, plan),
        estimator=EstimatorSettings(),
    )
    return simulate(config, targets, plan, seed=seed)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gnn_without_clutter_reproduces_the_true_associations(seed: int) -> None:
    s = _clutter_free_scenario(seed)
    assert np.all(s.origins.target_ids > 0)  # no false alarm was drawn
    out = GnnTracker(config=s.config).track(s.scans)
    got = {
        frozenset(int(s.scans[k].rows[j]) for k, j in a.items())
        for a in out.associations.values()
    }
    truth: dict[int, set[int]] = {}
    for row, target in zip(s.origins.rows.tolist(), s.origins.target_ids.tolist(), strict=True):
        truth.setdefault(target, set()).add(row)
    assert got == {frozenset(rows) for rows in truth.values()}


def test_gnn_output_is_the_shared_smoother_on_its_confirmed_associations() -> None:
    s = build_scenario("crossing", seed=0)
    tracker = GnnTracker(config=s.config)
    assert isinstance(tracker, Tracker) and tracker.name == "gnn"
    out = tracker.track(s.scans)
    again = smooth_tracks(s.scans, out.associations, s.config)
    np.testing.assert_array_equal(again.states, out.tracks.states)
    np.testing.assert_array_equal(again.detection_rows, out.tracks.detection_rows)
    manager = out.details
    assert set(out.associations) == manager.confirmed_ids
    # Every reported track went through confirmation; its tentative history is included.
    for tid, assoc in out.associations.items():
        steps = manager.history[tid]
        assert min(assoc) == steps[0].scan_index
    # Each detection is used by at most one reported track.
    used = [(k, j) for a in out.associations.values() for k, j in a.items()]
    assert len(used) == len(set(used))


def test_two_sensor_scans_are_processed_in_time_order() -> None:
    s = build_scenario("two_sensors", seed=0)
    out = GnnTracker(config=s.config).track(s.scans[:20])
    sensors_used = {s.scans[k].sensor for a in out.associations.values() for k in a}
    assert sensors_used == {"pos", "radar"}


def test_tracker_refuses_models_without_clutter_or_without_misses() -> None:
    with pytest.raises(InputError, match="false_alarms_per_scan = 0"):
        GnnTracker(config=_config(false_alarms=0.0))
    with pytest.raises(InputError, match="never miss"):
        GnnTracker(config=_config(pd=1.0, gate=1.0))
    with pytest.raises(InputError, match="ScoreRule or an MOfNRule"):
        GnnTracker(config=_config(), management="score")  # type: ignore[arg-type]


# ------------------------------------------------------------------ management rules


def _walk(rule, detections: list[bool]) -> list[tuple[bool, bool]]:
    """(confirmed, deleted) after each step of a hit/miss sequence (first = birth)."""
    life = rule.start(0.0)
    out = [(life.confirmed, rule.deleted(life))]
    for hit in detections[1:]:
        life = rule.step(life, detected=hit, increment=0.0)
        out.append((life.confirmed, rule.deleted(life)))
        if out[-1][1]:
            break
    return out


def test_m_of_n_confirms_with_m_hits_in_the_first_n_scans_and_deletes_after_misses() -> None:
    rule = MOfNRule(confirm_hits=2, confirm_scans=3, delete_misses=2)
    # birth, miss, hit -> 2 hits in 3 scans: confirmed; then two misses: deleted.
    assert _walk(rule, [True, False, True, False, False]) == [
        (False, False), (False, False), (True, False), (True, False), (True, True)
    ]
    # birth, miss, miss: 2 hits can no longer fall in 3 scans: deleted at once.
    assert _walk(rule, [True, False, False]) == [(False, False), (False, False), (False, True)]
    # A hit between misses resets the consecutive-miss count.
    assert _walk(rule, [True, True, False, True, False, True]) == [
        (False, False), (True, False), (True, False), (True, False), (True, False),
        (True, False),
    ]
    assert MOfNRule(confirm_hits=1, confirm_scans=1).start(0.0).confirmed
    with pytest.raises(InputError, match="confirm_hits"):
        MOfNRule(confirm_hits=4, confirm_scans=3)


def test_m_of_n_through_the_tracker_on_a_hand_made_sequence() -> None:
    # One target at rest near the origin.  Detections at scans 0, 2, 3, 6, 7 (misses at
    # 1, 4, 5, 8, 9).  2-of-3, deleted after 2 misses: the track of scan 0 is confirmed at
    # scan 2 and deleted at scan 5; the detection of scan 6 starts a new track, confirmed
    # at scan 7 and deleted at scan 9.
    here = [[0.1, -0.2]]
    dets = [here, [], here, here, [], [], here, here, [], []]
    scans = make_scans([float(t) for t in range(10)], dets, 2)
    rule = MOfNRule(confirm_hits=2, confirm_scans=3, delete_misses=2)
    out = GnnTracker(config=_config(), management=rule).track(scans)
    assert sorted(sorted(a) for a in out.associations.values()) == [[0, 2, 3], [6, 7]]
    assert out.details.live == []


def test_score_rule_thresholds_are_walds_sprt_thresholds() -> None:
    rule = ScoreRule(false_track_probability=1e-4, missed_track_probability=0.05,
                     deletion_drop=5.0)
    assert rule.confirmation_threshold == pytest.approx(math.log(0.95 / 1e-4))
    assert rule.rejection_threshold == pytest.approx(math.log(0.05 / (1 - 1e-4)))
    t2 = rule.confirmation_threshold
    life = rule.start(t2 - 1.0)
    assert not life.confirmed
    life = rule.step(life, detected=True, increment=0.999)
    assert not life.confirmed
    life = rule.step(life, detected=True, increment=0.002)
    assert life.confirmed and life.max_score == pytest.approx(t2 + 0.001)
    life = rule.step(life, detected=False, increment=-4.9)
    assert not rule.deleted(life)
    life = rule.step(life, detected=False, increment=-0.2)
    assert rule.deleted(life) and life.confirmed
    assert rule.start(t2).confirmed
    assert isinstance(life, TrackLife)
    with pytest.raises(InputError, match="< 1"):
        ScoreRule(false_track_probability=0.6, missed_track_probability=0.5)


def test_track_score_is_the_sum_of_the_log_likelihood_ratios() -> None:
    # Birth score log(u Pd / lambda_bar) with u = initial_count + rate at the first scan,
    # then log Pd + log N(nu; 0, S) - log lambda for the continuing detection.
    config = _config()
    scans = make_scans([0.0, 1.0], [[[0.0, 0.0]], [[1.0, 0.5]]], 2)
    sensor = config.sensors[SENSOR]
    u = config.birth.initial_count + config.birth.rate
    birth = math.log(u * 0.9 / sensor.false_alarms_per_scan)
    predicted = tf.predict_track(config, tf.start_track(config, scans[0], 0), 1.0)
    loglik = float(tf.innovations(config, predicted, scans[1]).log_likelihood[0])
    step = math.log(0.9) + loglik - math.log(sensor.clutter_density)
    # A threshold T2 = log((1 - beta) / alpha) between the two scores (T2 > 0 always):
    # confirmed at the second scan, not the first.
    assert birth < 0.0 < birth + step
    alpha = 0.9 / math.exp((birth + step) / 2)
    rule = ScoreRule(false_track_probability=alpha, missed_track_probability=0.1)
    assert birth < rule.confirmation_threshold < birth + step
    manager = TrackManager(config=config, rule=rule)
    manager.predict(0, scans[0])
    manager.commit(scans[0], [], np.ones(1, dtype=bool))
    assert manager.live[0].life.score == pytest.approx(birth)
    assert not manager.live[0].life.confirmed
    out = GnnTracker(config=config, management=rule).track(scans)
    track = out.details.live[0]
    assert track.life.score == pytest.approx(birth + step)
    assert track.life.confirmed
    assert out.associations == {track.track_id: {0: 0, 1: 0}}
