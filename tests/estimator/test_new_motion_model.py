"""A new motion model is one class plus one registry row.

The model below exists only in this file: nearly constant velocity with the *discrete*
white-noise acceleration process noise (Bar-Shalom, Li and Kirubarajan, "Estimation with
Applications to Tracking and Navigation", section 6.3.3: the acceleration is constant
over a scan interval, ``Q = q [[dt^4/4, dt^3/2], [dt^3/2, dt^2]]`` per axis) instead of
the continuous form of :class:`~mapassoc.models.motion.ConstantVelocity`.  It is
registered with one :func:`~mapassoc.models.motion.register_motion_model` call and
nothing else of the package is told about it.  The tests check that every layer picks
it up through that row alone:

* the configuration reader and writer (a TOML round trip through the registry);
* the hypothesis trees and the recording objective J: J of a recording no longer than
  a window equals the window's best objective, numba on and off, and differs from J
  under the continuous-noise model (the model's own Q is what every layer used);
* the filter run J takes equals an independent Kalman filter written here with the
  model's own matrices (the compiled kernels and the numpy steps alike);
* the whole estimator (forward pass, refinement, smoother) gives the same tracks and J
  with the compiled kernels and with numpy, the refinement's J is the objective's J,
  and the smoother's last state of a track is its filter's last state (Rauch, Tung and
  Striebel: the smoothed and filtered estimates agree at the last measurement).
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from collections.abc import Iterator

import numpy as np
import pytest
from support import NO_TIME_LIMIT

from mapassoc.accelerate import COMPILED_SWITCH, compiled_module
from mapassoc.data.config import Config, config_to_toml, parse_config
from mapassoc.estimator.objective import RecordingObjective, paths_from_rows
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.models.motion import (
    MOTION_REGISTRY,
    ConstantVelocity,
    MotionModel,
    MotionSetting,
    register_motion_model,
)
from mapassoc.models.population import BirthModel

NAME = "discrete_white_noise_velocity"
"""The throwaway model's configuration name."""


class DiscreteWhiteNoiseVelocity(MotionModel):
    """Nearly constant velocity with piecewise-constant white acceleration (module
    docstring); state ``[positions, velocities]``."""

    def __init__(self, *, ndim: int = 2, noise_intensity: float) -> None:
        self.ndim = int(ndim)
        self.noise_intensity = float(noise_intensity)

    @property
    def state_dim(self) -> int:
        return 2 * self.ndim

    @property
    def state_names(self) -> tuple[str, ...]:
        axes = "xyz"[: self.ndim]
        return tuple(axes) + tuple("v" + a for a in axes)

    @property
    def position_indices(self) -> tuple[int, ...]:
        return tuple(range(self.ndim))

    @property
    def velocity_indices(self) -> tuple[int, ...]:
        return tuple(range(self.ndim, 2 * self.ndim))

    @property
    def is_linear(self) -> bool:
        return True

    def transition_matrix(self, dt: float) -> np.ndarray:
        return np.kron(np.array([[1.0, dt], [0.0, 1.0]]), np.eye(self.ndim))

    def transition(self, x: np.ndarray, dt: float) -> np.ndarray:
        return np.asarray(x, dtype=float) @ self.transition_matrix(dt).T

    def jacobian(self, x: np.ndarray, dt: float) -> np.ndarray:
        F = self.transition_matrix(dt)
        return np.broadcast_to(F, np.shape(x)[:-1] + F.shape).copy()

    def process_noise(self, dt: float) -> np.ndarray:
        block = np.array([[dt**4 / 4.0, dt**3 / 2.0], [dt**3 / 2.0, dt**2]])
        return self.noise_intensity * np.kron(block, np.eye(self.ndim))

    def birth_prior(self, birth: BirthModel) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(self.ndim), birth.velocity_std**2 * np.eye(self.ndim)


@pytest.fixture
def registered() -> Iterator[None]:
    """The model's one registry row, for the test's duration."""
    register_motion_model(
        NAME,
        DiscreteWhiteNoiseVelocity,
        (MotionSetting("ndim", "ndim"), MotionSetting("noise_intensity", "positive")),
    )
    try:
        yield
    finally:
        del MOTION_REGISTRY[NAME]


def _with_new_model(config: Config, *, refine: bool) -> Config:
    """``config`` with the throwaway model of the same noise intensity, no clock limit
    and (``refine`` False) the forward pass alone."""
    old = config.motion
    assert isinstance(old, ConstantVelocity)
    estimator = dataclasses.replace(config.estimator, time_limit=NO_TIME_LIMIT)
    if not refine:
        estimator = dataclasses.replace(estimator, refine_passes=0)
    return dataclasses.replace(
        config,
        motion=DiscreteWhiteNoiseVelocity(ndim=old.ndim, noise_intensity=old.noise_intensity),
        estimator=estimator,
    )


def _kalman_path(monkeypatch: pytest.MonkeyPatch, path: str) -> None:
    if path == "compiled":
        pytest.importorskip("numba")
    monkeypatch.setenv(COMPILED_SWITCH, "1" if path == "compiled" else "0")
    loaded = compiled_module("mapassoc.filtering.compiled_kernels") is not None
    assert loaded == (path == "compiled")


def test_the_registry_row_reads_and_writes_the_model(registered: None) -> None:
    scenario = build_scenario("crossing", seed=1)
    config = _with_new_model(scenario.config, refine=True)
    text = config_to_toml(config)
    assert f'model = "{NAME}"' in text
    motion = parse_config(tomllib.loads(text)).motion
    assert type(motion) is DiscreteWhiteNoiseVelocity
    assert (motion.ndim, motion.noise_intensity) == (2, config.motion.noise_intensity)


@pytest.mark.parametrize("kalman_path", ["compiled", "numpy"])
@pytest.mark.parametrize("name", ["crossing", "two_sensors"])
def test_one_windows_J_equals_its_best_objective_under_the_new_model(
    registered: None, monkeypatch: pytest.MonkeyPatch, name: str, kalman_path: str
) -> None:
    _kalman_path(monkeypatch, kalman_path)
    scenario = build_scenario(name, seed=1)
    config = _with_new_model(scenario.config, refine=False)
    scans = scenario.scans[: config.estimator.window_length]
    estimator = WindowEstimator(config=config)
    solution = estimator.solve_window(scans)
    _, tracks = estimator.k_estimator.choose(solution.posterior)
    result = estimator.run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    paths = paths_from_rows(objective, result.track_rows)
    assert paths
    value = objective.value(paths)
    assert value == pytest.approx(float(solution.table.best[tracks]), abs=1e-9)
    # The same track set under the continuous-noise model scores otherwise, by far more
    # than the agreement above: the trees and J both used the new model's Q.
    continuous = dataclasses.replace(config, motion=scenario.config.motion)
    other = RecordingObjective(config=continuous, scans=scans).value(paths)
    assert abs(other - value) > 1e-5


def _independent_filter_means(
    objective: RecordingObjective, path: tuple[tuple[int, int], ...]
) -> list[np.ndarray]:
    """The filtered mean after each of the track's detections, by a Kalman filter written
    here with the model's own F and Q (from the objective's birth state; linear position
    measurement)."""
    model = objective.motion
    start = objective.start_path(path)
    x, P = start.means[0].copy(), start.covariances[0].copy()
    scan = path[0][0]
    means = [x.copy()]
    for m, j in path[1:]:
        for k in range(scan + 1, m + 1):
            dt = float(objective.times[k] - objective.times[k - 1])
            if dt > 0:
                F = model.transition_matrix(dt)
                x, P = F @ x, F @ P @ F.T + model.process_noise(dt)
        sensor = objective.config.sensors[objective.scans[m].sensor]
        H, R = sensor.measurement.H, sensor.measurement.noise_covariance
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        x = x + K @ (objective.scans[m].detections[j] - H @ x)
        A = np.eye(len(x)) - K @ H
        P = A @ P @ A.T + K @ R @ K.T
        scan = m
        means.append(x.copy())
    return means


@pytest.mark.parametrize("kalman_path", ["compiled", "numpy"])
def test_the_filter_run_is_the_new_models_kalman_filter(
    registered: None, monkeypatch: pytest.MonkeyPatch, kalman_path: str
) -> None:
    _kalman_path(monkeypatch, kalman_path)
    scenario = build_scenario("crossing", seed=1)
    config = _with_new_model(scenario.config, refine=False)
    scans = scenario.scans[:30]
    result = WindowEstimator(config=config).run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    paths = [p for p in paths_from_rows(objective, result.track_rows).values() if len(p) > 5]
    assert paths
    for path in paths:
        run = objective.trajectory(path)
        expected = _independent_filter_means(objective, path)
        for got, want in zip(run.means, expected, strict=True):
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


def test_the_estimator_gives_the_same_tracks_and_J_compiled_and_in_numpy(
    registered: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("numba")
    scenario = build_scenario("crossing", seed=1)
    config = _with_new_model(scenario.config, refine=True)
    scans = scenario.scans[:40]
    runs = {}
    for path in ("compiled", "numpy"):
        _kalman_path(monkeypatch, path)
        result = WindowEstimator(config=config).run(scans)
        objective = RecordingObjective(config=config, scans=scans)
        paths = paths_from_rows(objective, result.track_rows)
        runs[path] = (result, objective.value(paths))
        assert result.refinement is not None
        assert result.refinement.objective_after_pass[-1] == pytest.approx(runs[path][1], abs=1e-9)
        # The smoother ran the new model's filter: at each track's last detection the
        # smoothed state is the filtered one.
        table = result.tracks
        assert tuple(table.state_names) == config.motion.state_names
        for track_id, track_path in paths.items():
            rows = np.flatnonzero(np.asarray(table.track_ids) == track_id)
            last = rows[np.argmax(np.asarray(table.times)[rows])]
            filtered = objective.trajectory(track_path).means[-1]
            np.testing.assert_allclose(table.states[last], filtered, rtol=1e-7, atol=1e-7)
    (compiled, j_compiled), (plain, j_plain) = runs["compiled"], runs["numpy"]
    assert compiled.track_rows == plain.track_rows
    assert j_compiled == pytest.approx(j_plain, abs=1e-9)
    assert math.isfinite(j_compiled) and len(compiled.track_rows) >= 2
