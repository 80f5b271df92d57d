"""JPDA: exact association marginals, the PDA update, tentative tracks and the output."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from support import SENSOR, make_config, make_scans

from mapassoc.errors import InputError
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.filtering import track_filter as tf
from mapassoc.models.motion import ConstantVelocity
from mapassoc.trackers.base import Tracker
from mapassoc.trackers.jpda import (
    JpdaDetails,
    JpdaTracker,
    association_clusters,
    association_marginals,
)
from mapassoc.trackers.management import MOfNRule


def _config(false_alarms: float = 2.0):
    return make_config(
        motion=ConstantVelocity(ndim=2, noise_intensity=0.01),
        noise_std=1.0,
        detection_probability=0.9,
        false_alarms_per_scan=false_alarms,
        region=[[-50.0, 50.0], [-50.0, 50.0]],
    )


def _brute_force(L: np.ndarray, miss: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Marginals by listing every feasible joint event of the whole (T, M) problem."""
    T, M = L.shape
    beta, beta0, total = np.zeros((T, M)), np.zeros(T), 0.0
    for pick in itertools.product(range(-1, M), repeat=T):
        used = [j for j in pick if j >= 0]
        if len(used) != len(set(used)) or any(j >= 0 and L[t, j] == -np.inf
                                              for t, j in enumerate(pick)):
            continue
        w = math.exp(sum(L[t, j] if j >= 0 else miss[t] for t, j in enumerate(pick)))
        total += w
        for t, j in enumerate(pick):
            if j >= 0:
                beta[t, j] += w
            else:
                beta0[t] += w
    return beta / total, beta0 / total


def _random_problem(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    T, M = int(rng.integers(1, 5)), int(rng.integers(0, 5))
    L = rng.normal(1.0, 2.0, size=(T, M))
    L[rng.random((T, M)) < 0.35] = -np.inf
    return L, rng.normal(-2.0, 1.0, size=T)


def test_marginals_match_brute_force_enumeration_and_sum_to_one() -> None:
    rng = np.random.default_rng(7)
    for _ in range(60):
        L, miss = _random_problem(rng)
        beta, beta0 = association_marginals(L, miss)
        np.testing.assert_allclose(beta0 + beta.sum(axis=1), 1.0, atol=1e-12)
        # A detection is shared out at most once across tracks.
        assert np.all(beta.sum(axis=0) <= 1.0 + 1e-12)
        assert np.all(beta[np.isinf(L)] == 0.0)
        bf, bf0 = _brute_force(L, miss)
        np.testing.assert_allclose(beta, bf, atol=1e-12)
        np.testing.assert_allclose(beta0, bf0, atol=1e-12)


def test_marginals_are_invariant_to_track_and_detection_order() -> None:
    rng = np.random.default_rng(11)
    for _ in range(20):
        L, miss = _random_problem(rng)
        pt, pm = rng.permutation(L.shape[0]), rng.permutation(L.shape[1])
        beta, beta0 = association_marginals(L, miss)
        beta_p, beta0_p = association_marginals(L[np.ix_(pt, pm)], miss[pt])
        np.testing.assert_allclose(beta_p, beta[np.ix_(pt, pm)], atol=1e-12)
        np.testing.assert_allclose(beta0_p, beta0[pt], atol=1e-12)


def test_clusters_are_the_connected_components_of_the_gate_graph() -> None:
    inf = -np.inf
    L = np.array([
        [1.0, inf, inf, inf],
        [inf, inf, 2.0, inf],
        [0.5, inf, inf, inf],
        [inf, inf, 1.0, 3.0],
        [inf, inf, inf, inf],
    ])
    clusters = [(t.tolist(), d.tolist()) for t, d in association_clusters(L)]
    assert clusters == [([0, 2], [0]), ([1, 3], [2, 3]), ([4], [])]
    beta, beta0 = association_marginals(L, np.full(5, -1.0))
    assert beta0[4] == 1.0 and np.all(beta[:, 1] == 0.0)
    # Clusters are independent: each alone gives the same marginals.
    b_a, b0_a = association_marginals(L[np.ix_([1, 3], [2, 3])], np.full(2, -1.0))
    np.testing.assert_allclose(beta[np.ix_([1, 3], [2, 3])], b_a, atol=1e-15)
    np.testing.assert_allclose(beta0[[1, 3]], b0_a, atol=1e-15)


def test_one_track_one_detection_is_the_pdaf_formula() -> None:
    # Bar-Shalom, Daum & Huang (2009): with L = Pd N(nu; 0, S) / lambda,
    # beta_1 = L / (1 - Pd P_G + L), beta_0 = (1 - Pd P_G) / (1 - Pd P_G + L).
    pd, pg, log_n, lam = 0.9, 0.99, -4.2, 0.02
    L = pd * math.exp(log_n) / lam
    beta, beta0 = association_marginals(
        np.array([[math.log(L)]]), np.array([math.log(1 - pd * pg)])
    )
    assert beta[0, 0] == pytest.approx(L / (1 - pd * pg + L))
    assert beta0[0] == pytest.approx((1 - pd * pg) / (1 - pd * pg + L))


def test_tracker_update_with_one_track_and_one_detection_is_the_pdaf_by_hand() -> None:
    # Dense clutter so that beta_1 is well below 1.  A 1-of-1 rule confirms the track at
    # birth; scan 1 has one detection 3 units away.
    config = _config(false_alarms=200.0)
    scans = make_scans([0.0, 1.0], [[[0.0, 0.0]], [[3.0, 0.5]]], 2)
    rule = MOfNRule(confirm_hits=1, confirm_scans=1, delete_misses=1)
    out = JpdaTracker(config=config, management=rule).track(scans)

    sensor = config.sensors[SENSOR]
    x0 = tf.start_track(config, scans[0], 0)
    pred = tf.predict_track(config, x0, 1.0)
    x, P = pred.x, pred.P
    H = sensor.measurement.H
    R = sensor.measurement.noise_covariance
    S = H @ P @ H.T + R
    nu = scans[1].detections[0] - H @ x
    N = math.exp(-0.5 * nu @ np.linalg.solve(S, nu)) / (2 * math.pi * math.sqrt(np.linalg.det(S)))
    L = 0.9 * N / sensor.clutter_density
    b1 = L / (1 - 0.9 * 1.0 + L)  # P_G = 1 (no gate) in make_config
    b0 = 1 - b1
    assert 0.6 < b1 < 0.95
    K = P @ H.T @ np.linalg.inv(S)
    x_new = x + K @ (b1 * nu)
    P_c = P - K @ S @ K.T
    P_new = b0 * P + b1 * P_c + K @ (b1 * np.outer(nu, nu) - np.outer(b1 * nu, b1 * nu)) @ K.T

    t = out.tracks
    assert t.track_ids.tolist() == [t.track_ids[0]] * 2  # one track, two rows
    np.testing.assert_allclose(t.states[1], x_new, atol=1e-10)
    np.testing.assert_allclose(t.variances[1], np.diag(P_new), atol=1e-10)
    np.testing.assert_allclose(t.states[0], x0.x, atol=1e-12)
    assert t.detection_rows.tolist() == [2, 3]  # beta_1 > 1/2 reports the detection
    assert out.associations is None


def test_only_detections_probably_from_confirmed_tracks_are_reserved() -> None:
    # A confirmed track at the origin (1-of-1).  Scan 1: a detection right on it, one
    # inside its gate but far less likely than the first (beta < 1/2), and one far
    # outside.  The first is the confirmed track's; the other two start tracks.
    config = make_config(
        motion=ConstantVelocity(ndim=2, noise_intensity=0.01),
        noise_std=1.0,
        detection_probability=0.9,
        false_alarms_per_scan=2.0,
        region=[[-50.0, 50.0], [-50.0, 50.0]],
        gate_probability=0.999,
    )
    scans = make_scans([0.0, 1.0], [[[0.0, 0.0]], [[0.5, 0.5], [5.0, 0.0], [30.0, 30.0]]], 2)
    predicted = tf.predict_track(config, tf.start_track(config, scans[0], 0), 1.0)
    innov = tf.innovations(config, predicted, scans[1])
    assert innov.d2[1] < 13.8  # inside the 0.999 gate (chi-square, 2 dof)
    rule = MOfNRule(confirm_hits=1, confirm_scans=1, delete_misses=3)
    out = JpdaTracker(config=config, management=rule).track(scans)
    assert out.details.tracks_started == 3
    history = out.details.manager.history
    first = sorted((steps[0].scan_index, steps[0].detection) for steps in history.values())
    assert first == [(0, 0), (1, 1), (1, 2)]
    # The confirmed track reports the detection it most probably took.
    origin_track = next(s for s in history.values() if s[0].scan_index == 0)
    assert origin_track[1].detection == 0 and not origin_track[1].hard


def test_too_many_joint_events_raise_and_name_the_cluster() -> None:
    L = np.zeros((4, 4))  # every track gates every detection: 209 events
    with pytest.raises(InputError, match="4 tracks and 4 detections"):
        association_marginals(L, np.full(4, -1.0), max_events=100)
    beta, _ = association_marginals(L, np.full(4, -1.0), max_events=209)
    assert beta.shape == (4, 4)
    with pytest.raises(InputError, match="max_events"):
        JpdaTracker(config=_config(), max_events=0)


def test_bad_marginal_arguments_are_refused() -> None:
    with pytest.raises(InputError, match="log_miss must have shape"):
        association_marginals(np.zeros((2, 1)), np.zeros(1))
    with pytest.raises(InputError, match="no feasible joint event"):
        # Two tracks that cannot miss, one detection.
        association_marginals(np.zeros((2, 1)), np.full(2, -np.inf))


def test_jpda_on_crossing_reports_filtered_tracks_with_soft_rows() -> None:
    s = build_scenario("crossing", seed=0)
    tracker = JpdaTracker(config=s.config)
    assert isinstance(tracker, Tracker) and tracker.name == "jpda"
    out = tracker.track(s.scans)
    assert out.associations is None and isinstance(out.details, JpdaDetails)
    # Every reported row names a detection of the scan at its time, or -1; each track
    # ends with a row whose step counted as a detection.
    rows_at = {scan.time: set(scan.rows.tolist()) for scan in s.scans}
    t = out.tracks
    for time, row in zip(t.times.tolist(), t.detection_rows.tolist(), strict=True):
        assert row == -1 or row in rows_at[time]
    assert out.details.tracks_confirmed == len(np.unique(t.track_ids)) >= 4
