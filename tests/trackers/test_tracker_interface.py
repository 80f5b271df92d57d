"""The tracker interface, the shared smoother and the recursive track filter."""

from __future__ import annotations

import numpy as np
import pytest
from support import SENSOR, make_config

from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.filtering import track_filter as tf
from mapassoc.filtering.smoothing import smooth_tracks
from mapassoc.models.motion import ConstantVelocity
from mapassoc.trackers.base import CountSeries, Tracker, TrackerOutput, check_scans
from mapassoc.trackers.map_estimator import MapTracker
from mapassoc.trackers.oracle import OracleTracker


def _config(pd: float = 0.9):
    return make_config(
        motion=ConstantVelocity(ndim=2, noise_intensity=0.1),
        noise_std=1.0,
        detection_probability=pd,
        false_alarms_per_scan=2.0,
        region=[[-50.0, 50.0], [-50.0, 50.0]],
    )


def _scan(t: float, points: list[list[float]], first_row: int) -> Scan:
    z = np.array(points, dtype=float).reshape(-1, 2)
    return Scan(t, SENSOR, z, np.arange(first_row, first_row + z.shape[0]))


def test_count_series_pads_rows_and_refuses_bad_distributions() -> None:
    s = CountSeries.from_rows([0.0, 1.0], [2.0, 3.0], [np.array([0.5, 0.5]), np.array([1.0])])
    assert s.probabilities.tolist() == [[0.5, 0.5], [1.0, 0.0]]
    with pytest.raises(InputError, match="sum to 1"):
        CountSeries(np.zeros(1), np.ones(1), np.array([[0.5, 0.2]]))
    with pytest.raises(InputError, match="start_time <= end_time"):
        CountSeries(np.ones(1), np.zeros(1), np.array([[1.0]]))


def test_check_scans_refuses_empty_unsorted_and_unknown_sensor() -> None:
    config = _config()
    with pytest.raises(InputError, match="empty"):
        check_scans([], config)
    with pytest.raises(InputError, match="sensor 'other'"):
        check_scans([Scan(0.0, "other", np.zeros((0, 2)), np.zeros(0, int))], config)
    with pytest.raises(InputError):
        check_scans([_scan(1.0, [], 2), _scan(0.0, [], 2)], config)


def test_mixture_update_with_all_weight_on_one_detection_is_the_kalman_update() -> None:
    config = _config()
    scans = [_scan(0.0, [[0.0, 0.0]], 2), _scan(1.0, [[1.0, 0.5], [3.0, -2.0]], 3)]
    track = tf.start_track(config, scans[0], 0)
    predicted = tf.predict_track(config, track, 1.0)
    innov = tf.innovations(config, predicted, scans[1])
    hard = tf.update_track(config, predicted, scans[1], 1)
    soft = tf.update_track_mixture(config, predicted, scans[1], innov, np.array([0.0, 1.0]), 0.0)
    np.testing.assert_allclose(soft.x, hard.x, atol=1e-12)
    np.testing.assert_allclose(soft.P, hard.P, atol=1e-12)
    unchanged = tf.update_track_mixture(config, predicted, scans[1], innov, np.zeros(2), 1.0)
    assert unchanged is predicted
    # A split weight moves the mean to the weighted innovation and widens P by the spread.
    half = tf.update_track_mixture(config, predicted, scans[1], innov, np.array([0.5, 0.5]), 0.0)
    both = [tf.update_track(config, predicted, scans[1], j).x for j in (0, 1)]
    np.testing.assert_allclose(half.x, 0.5 * (both[0] + both[1]), atol=1e-12)
    assert np.all(np.linalg.eigvalsh(half.P - hard.P) > -1e-12)
    with pytest.raises(InputError, match="sum with the miss weight to 1"):
        tf.update_track_mixture(config, predicted, scans[1], innov, np.array([0.5, 0.6]), 0.0)


def test_innovations_match_the_gaussian_log_likelihood() -> None:
    config = _config()
    scans = [_scan(0.0, [[0.0, 0.0]], 2), _scan(1.0, [[1.0, 0.5], [3.0, -2.0]], 3)]
    predicted = tf.predict_track(config, tf.start_track(config, scans[0], 0), 1.0)
    innov = tf.innovations(config, predicted, scans[1])
    S = innov.S
    for j in range(2):
        nu = innov.nu[j]
        d2 = float(nu @ np.linalg.solve(S, nu))
        expected = -0.5 * (2 * np.log(2 * np.pi) + np.log(np.linalg.det(S)) + d2)
        assert innov.d2[j] == pytest.approx(d2)
        assert innov.log_likelihood[j] == pytest.approx(expected)
    with pytest.raises(InputError, match="predict first"):
        tf.innovations(config, tf.start_track(config, scans[0], 0), scans[1])


def test_smooth_tracks_refuses_a_track_without_detections_or_a_missing_detection() -> None:
    config = _config()
    scans = [_scan(0.0, [[0.0, 0.0]], 2)]
    with pytest.raises(InputError, match="no detections"):
        smooth_tracks(scans, {1: {}}, config)
    with pytest.raises(InputError, match="does not exist"):
        smooth_tracks(scans, {1: {0: 3}}, config)


@pytest.mark.slow
def test_map_and_oracle_trackers_report_associations_behind_their_tracks() -> None:
    scenario = build_scenario("crossing", seed=1)
    for tracker in (
        MapTracker(config=scenario.config),
        OracleTracker(config=scenario.config, origins=scenario.origins),
    ):
        assert isinstance(tracker, Tracker)
        out = tracker.track(scenario.scans)
        assert isinstance(out, TrackerOutput) and out.associations
        # The smoothed table is exactly the shared smoother on the reported associations.
        again = smooth_tracks(scenario.scans, out.associations, scenario.config)
        np.testing.assert_array_equal(again.states, out.tracks.states)
        used = {int(r) for r in out.tracks.detection_rows if r >= 0}
        from_assoc = {
            int(scenario.scans[k].rows[j]) for a in out.associations.values() for k, j in a.items()
        }
        assert used == from_assoc
    counts = MapTracker(config=scenario.config).track(scenario.scans).counts
    assert counts is not None and counts.size > 0
