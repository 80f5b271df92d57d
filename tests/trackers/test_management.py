"""Shared track management (start, confirm, delete) against hand-computed values.

Wald's SPRT thresholds, the score-drop deletion, M-of-N confirmation and deletion, the
first-detection score ``log u + log Pd - log lambda_bar`` of the birth model, and the
manager's bookkeeping, all pinned to numbers worked out by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import SENSOR, make_config, make_scans

from mapassoc.errors import InputError
from mapassoc.filtering import track_filter as tf
from mapassoc.models.motion import ConstantVelocity
from mapassoc.trackers.management import (
    MOfNRule,
    ScoreRule,
    StepOutcome,
    TrackManager,
    check_tracker_config,
    gated_log_ratios,
    management_rule,
)


def _config(**changes):
    settings = {
        "motion": ConstantVelocity(ndim=2, noise_intensity=0.01),
        "noise_std": 1.0,
        "detection_probability": 0.8,
        "false_alarms_per_scan": 5.0,
        "region": [[-50.0, 50.0], [-50.0, 50.0]],
        "initial_count": 2.0,
        "rate": 0.1,
        "survival_probability": 0.95,
        "gate_probability": 0.99,
    }
    settings.update(changes)
    return make_config(**settings)


# ------------------------------------------------------------------ score rule


def test_score_thresholds_are_walds_computed_by_hand() -> None:
    rule = ScoreRule(false_track_probability=1e-3, missed_track_probability=0.1)
    # T2 = log((1 - beta) / alpha) = log(0.9 / 0.001) = log 900 = 6.8023947633...
    assert rule.confirmation_threshold == pytest.approx(6.802394763324311, rel=1e-14)
    # T1 = log(beta / (1 - alpha)) = log 0.1 - log 0.999 = -2.302585093 + 0.001000500
    assert rule.rejection_threshold == pytest.approx(-2.3015845928, rel=1e-10)
    # The defaults: T2 = log(0.95 / 1e-4) = 9.1590...
    assert ScoreRule().confirmation_threshold == pytest.approx(math.log(9500.0), rel=1e-14)


def test_score_sequence_confirms_at_the_threshold_and_is_deleted_after_the_drop() -> None:
    rule = ScoreRule(false_track_probability=1e-3, missed_track_probability=0.1,
                     deletion_drop=7.0)  # T2 = 6.80
    life = rule.start(2.0)
    trace = [(life.score, life.max_score, life.confirmed, rule.deleted(life))]
    for increment, hit in [(3.0, True), (2.0, True), (-2.3, False), (-2.3, False),
                           (1.0, True), (-2.3, False), (-2.3, False), (-2.3, False)]:
        life = rule.step(life, detected=hit, increment=increment)
        trace.append((life.score, life.max_score, life.confirmed, rule.deleted(life)))
    want = [
        (2.0, 2.0, False, False),
        (5.0, 5.0, False, False),
        (7.0, 7.0, True, False),    # 7.0 >= 6.80: confirmed at the third scan
        (4.7, 7.0, True, False),
        (2.4, 7.0, True, False),
        (3.4, 7.0, True, False),    # a hit below the maximum leaves the maximum alone
        (1.1, 7.0, True, False),
        (-1.2, 7.0, True, True),    # 8.2 below the maximum > 7: deleted
        (-3.5, 7.0, True, True),
    ]
    assert [(pytest.approx(s), pytest.approx(m), c, d) for s, m, c, d in want] == trace
    assert life.hits == 4 and life.scans == 9 and life.consecutive_misses == 3


def test_score_rule_boundaries() -> None:
    rule = ScoreRule(false_track_probability=1e-3, missed_track_probability=0.1,
                     deletion_drop=4.0)
    t2 = rule.confirmation_threshold
    assert rule.start(t2).confirmed                       # reaching T2 confirms
    assert not rule.start(math.nextafter(t2, 0.0)).confirmed
    life = rule.step(rule.start(1.0), detected=False, increment=-4.0)  # drop exactly 4
    assert not rule.deleted(life)
    life = rule.step(life, detected=False, increment=-1e-9)
    assert rule.deleted(life) and not life.confirmed      # tentative tracks drop too


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"false_track_probability": 0.0}, "false_track_probability"),
        ({"false_track_probability": 1.0}, "false_track_probability"),
        ({"missed_track_probability": 0.0}, "missed_track_probability"),
        ({"missed_track_probability": -0.1}, "missed_track_probability"),
        ({"false_track_probability": 0.5, "missed_track_probability": 0.5}, "< 1"),
        ({"deletion_drop": 0.0}, "deletion_drop"),
        ({"deletion_drop": -1.0}, "deletion_drop"),
        ({"deletion_drop": math.nan}, "deletion_drop"),
    ],
)
def test_score_rule_refuses_bad_parameters(kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        ScoreRule(**kwargs)


# ------------------------------------------------------------------ M of N


def walk(rule: MOfNRule, hits: list[bool]) -> list[tuple[bool, bool]]:
    """(confirmed, deleted) after the birth and after each later scan (True = a hit)."""
    life = rule.start(0.0)
    out = [(life.confirmed, rule.deleted(life))]
    for hit in hits:
        life = rule.step(life, detected=hit, increment=0.0)
        out.append((life.confirmed, rule.deleted(life)))
    return out


def test_m_of_n_confirms_with_exactly_m_hits_in_the_first_n_scans() -> None:
    rule = MOfNRule(confirm_hits=3, confirm_scans=5, delete_misses=2)
    T, F = True, False
    # Birth and two hits: 3 of 3, confirmed at the third scan.
    assert walk(rule, [T, T])[-1] == (True, False)
    assert walk(rule, [T])[-1] == (False, False)
    # The third hit at the fifth scan (the last of N) still confirms.
    assert walk(rule, [F, F, T, T]) == [(False, False)] * 4 + [(True, False)]
    # Two hits in five: deleted at the fifth scan; a hit at the sixth would be too late.
    assert walk(rule, [T, F, F, F]) == [(False, False)] * 4 + [(False, True)]


def test_m_of_n_deletes_a_tentative_track_as_soon_as_m_is_out_of_reach() -> None:
    rule = MOfNRule(confirm_hits=3, confirm_scans=5, delete_misses=2)
    F = False
    # Birth, miss, miss: 1 hit + 2 scans left = 3, still reachable.  A third miss: 1 + 1
    # < 3, deleted at the fourth scan, before N.
    assert walk(rule, [F, F, F]) == [(False, False)] * 3 + [(False, True)]


def test_m_of_n_deletes_a_confirmed_track_after_consecutive_misses() -> None:
    rule = MOfNRule(confirm_hits=2, confirm_scans=3, delete_misses=3)
    T, F = True, False
    trace = walk(rule, [T, F, F, T, F, F, F])
    assert trace == [
        (False, False), (True, False),                # confirmed at the second scan
        (True, False), (True, False),                 # two misses: kept
        (True, False),                                # a hit resets the count
        (True, False), (True, False), (True, True),   # the third miss in a row deletes
    ]
    assert MOfNRule(confirm_hits=1, confirm_scans=1).start(-5.0).confirmed


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"confirm_hits": 0}, "confirm_hits must be an integer >= 1"),
        ({"confirm_scans": 0}, "confirm_scans must be an integer >= 1"),
        ({"delete_misses": 0}, "delete_misses must be an integer >= 1"),
        ({"confirm_hits": 2.0}, "confirm_hits must be an integer"),
        ({"delete_misses": True}, "delete_misses must be an integer"),
        ({"confirm_hits": 5, "confirm_scans": 4}, r"confirm_hits \(M = 5\) must be <="),
    ],
)
def test_m_of_n_refuses_bad_parameters(kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        MOfNRule(**kwargs)


def test_management_rule_default_and_refusal() -> None:
    assert management_rule(None) == ScoreRule()
    rule = MOfNRule()
    assert management_rule(rule) is rule
    with pytest.raises(InputError, match="management must be a ScoreRule or an MOfNRule"):
        management_rule("score")  # type: ignore[arg-type]


# ------------------------------------------------------------------ the manager


def test_first_detection_score_is_log_u_plus_log_pd_minus_log_lambda_bar() -> None:
    # initial_count 2, rate 0.1, Pd 0.8, lambda_bar 5, Ps 0.95 per unit time.
    # Scan 0 (t = 0): u = 2 + 0.1 = 2.1.
    # Scan 1 (t = 2): u = 2.1 (1 - 0.8) 0.95^2 + 0.1 = 0.37905 + 0.1 = 0.47905.
    config = _config()
    scans = make_scans([0.0, 2.0], [[[0.0, 0.0]], [[30.0, 30.0]]], 2)
    manager = TrackManager(config=config, rule=ScoreRule())
    assert manager.predict(0, scans[0]) == []
    manager.commit(scans[0], [], np.array([True]))
    assert manager.live[0].life.score == pytest.approx(
        math.log(2.1) + math.log(0.8) - math.log(5.0), rel=1e-12
    )
    live = manager.predict(1, scans[1])
    assert live[0].filtered.time == 2.0  # predicted to the scan
    miss = StepOutcome(live[0].filtered, -1, False, manager.miss_log_ratio(scans[1]))
    assert miss.increment == pytest.approx(math.log(1.0 - 0.8 * 0.99))
    manager.commit(scans[1], [miss], np.array([True]))
    assert [t.track_id for t in manager.live] == [1, 2]
    assert manager.live[1].life.score == pytest.approx(
        math.log(0.47905) + math.log(0.8) - math.log(5.0), rel=1e-12
    )
    assert manager.live[0].life.score == pytest.approx(
        math.log(2.1 * 0.8 / 5.0) + math.log(1.0 - 0.8 * 0.99), rel=1e-12
    )
    assert manager.tracks_started == 2


def test_no_births_when_no_target_can_be_undetected() -> None:
    config = _config(initial_count=0.0, rate=0.0)
    scans = make_scans([0.0], [[[0.0, 0.0], [5.0, 5.0]]], 2)
    manager = TrackManager(config=config, rule=ScoreRule())
    manager.predict(0, scans[0])
    manager.commit(scans[0], [], np.array([True, True]))
    assert manager.live == [] and manager.tracks_started == 0


def test_manager_keeps_histories_and_every_confirmed_track_after_deletion() -> None:
    # 1-of-1 confirms at birth; deleted after 2 misses.  Track 1 is born at scan 0 and
    # deleted at scan 2; track 2 (scan 1's free detection) lives on.
    config = _config()
    scans = make_scans([0.0, 1.0, 2.0], [[[0.0, 0.0]], [[20.0, 20.0]], []], 2)
    manager = TrackManager(
        config=config, rule=MOfNRule(confirm_hits=1, confirm_scans=1, delete_misses=2)
    )
    manager.predict(0, scans[0])
    manager.commit(scans[0], [], np.array([True]))
    for k in (1, 2):
        live = manager.predict(k, scans[k])
        outcomes = [StepOutcome(t.filtered, -1, False, manager.miss_log_ratio(scans[k]))
                    for t in live]
        manager.commit(scans[k], outcomes, np.ones(scans[k].size, dtype=bool))
    assert [t.track_id for t in manager.live] == [2]
    history = manager.confirmed_histories()
    assert list(history) == [1, 2]
    assert [(s.scan_index, s.detection, s.detected) for s in history[1]] == [
        (0, 0, True), (1, -1, False), (2, -1, False)
    ]
    assert [(s.scan_index, s.detection) for s in history[2]] == [(1, 0), (2, -1)]
    assert all(s.confirmed for s in history[1])


def test_manager_refuses_out_of_order_scans_and_mismatched_outcomes() -> None:
    config = _config()
    scans = make_scans([0.0, 1.0], [[[0.0, 0.0]], [[0.0, 0.0]]], 2)
    manager = TrackManager(config=config, rule=ScoreRule())
    with pytest.raises(InputError, match="expected scan 0, got 1"):
        manager.predict(1, scans[1])
    manager.predict(0, scans[0])
    with pytest.raises(InputError, match=r"free must have shape \(1,\)"):
        manager.commit(scans[0], [], np.ones(2, dtype=bool))
    manager.commit(scans[0], [], np.ones(1, dtype=bool))
    manager.predict(1, scans[1])
    with pytest.raises(InputError, match=r"one entry per live track \(1\), got 0"):
        manager.commit(scans[1], [], np.ones(1, dtype=bool))


def test_gated_log_ratios_are_log_pd_plus_log_likelihood_minus_log_lambda() -> None:
    config = _config()
    scans = make_scans([0.0, 1.0], [[[0.0, 0.0]], [[0.5, -0.3], [40.0, 40.0]]], 2)
    track = tf.predict_track(config, tf.start_track(config, scans[0], 0), 1.0)
    ratios, innov = gated_log_ratios(config, [track], scans[1])
    assert ratios.shape == (1, 2) and len(innov) == 1
    lam = 5.0 / (100.0 * 100.0)
    expected = math.log(0.8) + float(innov[0].log_likelihood[0]) - math.log(lam)
    assert ratios[0, 0] == pytest.approx(expected, rel=1e-12)
    assert ratios[0, 1] == -math.inf  # far outside the 99% gate


def test_tracker_config_checks() -> None:
    with pytest.raises(InputError, match="false_alarms_per_scan = 0.0"):
        check_tracker_config(_config(false_alarms_per_scan=0.0))
    with pytest.raises(InputError, match="never miss"):
        check_tracker_config(_config(detection_probability=1.0, gate_probability=1.0))
    with pytest.raises(InputError, match="config must be a Config"):
        TrackManager(config="config", rule=ScoreRule())  # type: ignore[arg-type]
    assert SENSOR in _config().sensors
