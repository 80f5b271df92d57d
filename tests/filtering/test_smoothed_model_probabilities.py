"""Each scan's smoothed model probabilities of a set of motion models (Kim's smoother,
:func:`mapassoc.filtering.smoothing.smooth_tracks`): what the tracks file reports."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from support import make_config, make_scans

from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.filtering.smoothing import smooth_track, smooth_tracks, smoothed_track
from mapassoc.models.interacting import InteractingModels
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.switching import SwitchingLaw

MATRIX = [[0.9, 0.1], [0.2, 0.8]]
"""A switching matrix per unit time whose stationary law is (2/3, 1/3)."""
STATIONARY = np.array([2.0 / 3.0, 1.0 / 3.0])


def test_identical_models_keep_a_stationary_prior_at_every_scan() -> None:
    """Identical models give every detection the same likelihood, so the filtered
    probabilities are the predicted ones, ``mu Pi(dt)``, which a prior stationary for the
    chain keeps (``pi G = 0`` for the generator G, so ``pi Pi(dt) = pi`` for every ``dt``,
    and a ``dt = 0`` step of a second sensor neither moves nor switches).  Kim's backward
    step ``mu_s(k)_i = mu_f(k)_i sum_j Pi_ij mu_s(k+1)_j / c(k+1)_j`` then multiplies by
    ``sum_j Pi_ij = 1``: the smoothed probabilities are the prior too."""
    scenario = build_scenario("two_sensors", seed=0)
    cv = scenario.config.motion
    models = [ConstantVelocity(ndim=cv.ndim, noise_intensity=cv.noise_intensity)] * 2
    same = InteractingModels(models=models, switching=SwitchingLaw(2, matrix=MATRIX),
                             initial_probabilities=STATIONARY)  # fmt: skip
    tracks = oracle_tracks(scenario.scans, scenario.origins,
                           dataclasses.replace(scenario.config, motion=same))  # fmt: skip
    assert tracks.size > 20
    assert tracks.model_names == ("constant_velocity_0", "constant_velocity_1")
    assert tracks.model_probabilities is not None
    assert tracks.model_probabilities.shape == (tracks.size, 2)
    np.testing.assert_allclose(
        tracks.model_probabilities, np.broadcast_to(STATIONARY, (tracks.size, 2)), atol=1e-9
    )


def test_a_single_model_reports_no_model_probabilities() -> None:
    scenario = build_scenario("two_sensors", seed=0)
    tracks = oracle_tracks(scenario.scans, scenario.origins, scenario.config)
    assert tracks.model_probabilities is None and tracks.model_names == ()


def _turning_track(seed: int) -> tuple[np.ndarray, list[list[list[float]]]]:
    """Detections every second of a target flying east at 10 for 25 s, turning north
    within 3 s (a 90 degree turn at about 5 m/s^2), then north for 25 s; noise std 0.5."""
    rng = np.random.default_rng(seed)
    times = np.arange(0.0, 53.0)
    points = []
    for t in times:
        if t <= 25.0:
            p = np.array([10.0 * t, 0.0])
        elif t <= 28.0:
            angle = (t - 25.0) / 3.0 * (np.pi / 2)
            radius = 30.0 / (np.pi / 2)  # 10 m/s over a quarter circle in 3 s
            p = np.array([250.0 + radius * np.sin(angle), radius * (1 - np.cos(angle))])
        else:
            p = np.array([250.0 + 30.0 / (np.pi / 2), 30.0 / (np.pi / 2) + 10.0 * (t - 28.0)])
        points.append([(p + rng.normal(0.0, 0.5, size=2)).tolist()])
    return times, points


@pytest.mark.parametrize("seed", range(3))
def test_the_loud_model_is_likelier_in_the_turn_than_on_the_straight_legs(seed: int) -> None:
    """A quiet and a loud constant-velocity model: the smoothed probability of the loud
    one is higher over the turn than on either straight leg (away from the turn)."""
    times, points = _turning_track(seed)
    quiet = ConstantVelocity(ndim=2, noise_intensity=0.01)
    loud = ConstantVelocity(ndim=2, noise_intensity=10.0)
    motion = InteractingModels(models=[quiet, loud],
                               switching=SwitchingLaw(2, switch_probability=0.05))  # fmt: skip
    config = make_config(motion=motion, noise_std=0.5, detection_probability=0.9,
                         false_alarms_per_scan=0.1, region=[[-100.0, 600.0]] * 2,
                         velocity_std=20.0)  # fmt: skip
    scans = make_scans(times.tolist(), points, 2)
    tracks = smooth_tracks(scans, {0: {k: 0 for k in range(len(scans))}}, config)
    assert tracks.model_probabilities is not None
    np.testing.assert_allclose(tracks.model_probabilities.sum(axis=1), 1.0, atol=1e-12)
    loud_p = tracks.model_probabilities[:, 1]
    turn = (tracks.times >= 25.0) & (tracks.times <= 28.0)
    first_leg = (tracks.times >= 3.0) & (tracks.times <= 18.0)
    second_leg = (tracks.times >= 35.0) & (tracks.times <= 50.0)
    assert loud_p[turn].mean() > loud_p[first_leg].mean() + 0.3
    assert loud_p[turn].mean() > loud_p[second_leg].mean() + 0.3


def test_smooth_track_keeps_its_four_values_and_smoothed_track_adds_the_probabilities() -> None:
    times, points = _turning_track(0)
    motion = InteractingModels(
        models=[ConstantVelocity(ndim=2, noise_intensity=q) for q in (0.01, 10.0)],
        switching=SwitchingLaw(2, switch_probability=0.05),
    )
    config = make_config(motion=motion, noise_std=0.5, detection_probability=0.9,
                         false_alarms_per_scan=0.1, region=[[-100.0, 600.0]] * 2)  # fmt: skip
    scans = make_scans(times[:6].tolist(), points[:6], 2)
    detections = {0: 0, 2: 0, 5: 0}
    indices, states, covariances, rows = smooth_track(scans, detections, config)
    track = smoothed_track(scans, detections, config)
    assert indices == track.scan_indices == list(range(6))
    np.testing.assert_array_equal(states, track.states)
    np.testing.assert_array_equal(covariances, track.covariances)
    assert rows == track.rows and rows[1] == -1
    assert track.model_probabilities is not None and track.model_probabilities.shape == (6, 2)
