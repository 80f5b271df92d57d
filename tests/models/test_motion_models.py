"""The motion-model protocol, the registry of configuration names and the Singer model."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from scipy.linalg import expm

from mapassoc.data.config import Config, config_to_toml, parse_config
from mapassoc.data.settings import BirthModel, EstimatorSettings
from mapassoc.errors import ConfigError, InputError
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import birth_model_for
from mapassoc.evaluation.simulate import TargetSpec, scan_plan_regular, simulate
from mapassoc.models import birth as birth_module
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import (
    MOTION_REGISTRY,
    ConstantAcceleration,
    ConstantVelocity,
    CoordinatedTurn,
    MotionModel,
    MotionSetting,
    Singer,
    motion_spec,
    register_motion_model,
)
from mapassoc.models.sensor import Region, Sensor

# One example of every registered model (a new registration without an example fails
# test_every_registered_model_has_an_example).
EXAMPLES: dict[str, list[dict[str, object]]] = {
    "constant_velocity": [{"ndim": d, "noise_intensity": 0.5} for d in (1, 2, 3)],
    "constant_acceleration": [{"ndim": d, "noise_intensity": 0.1} for d in (1, 2, 3)],
    "random_walk": [{"ndim": d, "noise_intensity": 0.35} for d in (1, 2, 3)],
    "coordinated_turn": [{"speed_noise_intensity": 0.01, "turn_rate_noise_intensity": 1e-4}],
    "constant_turn": [{"turn_rate": w, "noise_intensity": 0.5} for w in (0.0, 0.05, -0.3)],
    "singer": [
        {"ndim": d, "time_constant": tau, "acceleration_std": 0.7}
        for d, tau in ((1, 5.0), (2, 20.0), (3, 0.3))
    ],
}
CASES = [(name, kwargs) for name, items in EXAMPLES.items() for kwargs in items]
BIRTH = BirthModel(velocity_std=3.0, acceleration_std=0.4, speed_std=2.5, turn_rate_std=0.05)


def _model(name: str, kwargs: dict[str, object]) -> MotionModel:
    return MOTION_REGISTRY[name].cls(**kwargs)


def _is_positive_definite(P: np.ndarray) -> bool:
    return bool(np.allclose(P, P.T) and np.all(np.linalg.eigvalsh(P) > 0.0))


def _position_sensor(motion: MotionModel, half_width: float = 200.0) -> Sensor:
    dim = len(motion.position_indices)
    return Sensor(
        name="pos",
        measurement=LinearMeasurement.position(motion, noise_std=1.0),
        detection_probability=0.95,
        false_alarms_per_scan=0.5,
        region=Region.from_bounds([[-half_width, half_width]] * dim),
    )


def _config(motion: MotionModel, birth: BirthModel = BIRTH) -> Config:
    sensor = _position_sensor(motion)
    return Config(
        motion=motion,
        sensors={sensor.name: sensor},
        birth=birth,
        estimator=EstimatorSettings(window_length=3, max_tracks=6),
    )


def _van_loan(A: np.ndarray, G: np.ndarray, q: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """F and Q of dx = A x dt + G dw (PSD q) by Van Loan's matrix exponential (1978).

    The exponential of the Van Loan matrix has entries of order exp(|A| dt), so long
    steps are composed of m short ones: F = F_h^m, Q_{k+1} = F_h Q_k F_h^T + Q_h.
    """
    n = A.shape[0]
    m = max(1, math.ceil(np.abs(A).max() * dt))
    h = dt / m
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -A
    M[:n, n:] = q * G @ G.T
    M[n:, n:] = A.T
    E = expm(M * h)
    F_h = E[n:, n:].T
    Q_h = F_h @ E[:n, n:]
    F, Q = np.eye(n), np.zeros((n, n))
    for _ in range(m):
        F, Q = F_h @ F, F_h @ Q @ F_h.T + Q_h
    return F, Q


# --------------------------------------------------------------------------- registry


def test_every_registered_model_has_an_example() -> None:
    assert set(EXAMPLES) == set(MOTION_REGISTRY)
    assert list(MOTION_REGISTRY)[:4] == [
        "constant_velocity",
        "constant_acceleration",
        "random_walk",
        "coordinated_turn",
    ]


@pytest.mark.parametrize(("name", "kwargs"), CASES)
def test_registry_spec_matches_the_class(name: str, kwargs: dict[str, object]) -> None:
    model = _model(name, kwargs)
    spec = motion_spec(model)
    assert spec is not None and spec.name == name and type(model) is spec.cls
    assert spec.keys == ("model", *kwargs)
    for setting in spec.settings:
        assert getattr(model, setting.attribute or setting.key) == kwargs[setting.key]


def test_a_new_registration_is_read_and_written() -> None:
    class Drift(ConstantVelocity):
        """A model added by one class and one registration."""

    settings = (MotionSetting("ndim", "ndim"), MotionSetting("noise_intensity", "positive"))
    register_motion_model("drift", Drift, settings)
    try:
        config = _config(Drift(ndim=2, noise_intensity=0.25))
        text = config_to_toml(config)
        assert '[motion]\nmodel = "drift"\nndim = 2\nnoise_intensity = 0.25\n' in text
        assert type(parse_config(tomllib.loads(text)).motion) is Drift
        with pytest.raises(InputError, match="already registered"):
            register_motion_model("drift2", Drift, ())
    finally:
        del MOTION_REGISTRY["drift"]


# --------------------------------------------------------------------------- protocol


@pytest.mark.parametrize(("name", "kwargs"), CASES)
def test_protocol_conformance(name: str, kwargs: dict[str, object]) -> None:
    model = _model(name, kwargs)
    assert isinstance(model, MotionModel)
    init = model.initiation_model()
    assert isinstance(init, MotionModel)
    assert birth_module.initiation_model(model) is init or type(
        birth_module.initiation_model(model)
    ) is type(init)
    # The initiation model starts in its own space.
    assert not init.needs_conversion()
    assert birth_module.needs_conversion(model) == model.needs_conversion()
    assert len(init.position_indices) == len(model.position_indices)
    if not model.needs_conversion():
        assert init is model
        assert model.conversion_prior_indices == ()


@pytest.mark.parametrize(("name", "kwargs"), CASES)
def test_birth_prior_shapes_and_positive_definite(name: str, kwargs: dict[str, object]) -> None:
    init = _model(name, kwargs).initiation_model()
    m = init.state_dim - len(init.position_indices)
    mean, cov = init.birth_prior(BIRTH)
    assert mean.shape == (m,) and cov.shape == (m, m)
    assert np.all(mean == 0.0)
    if m:
        assert _is_positive_definite(cov)
    # Through mapassoc.models.birth: position from the detection, the rest from the prior.
    model = _model(name, kwargs)
    sensor = _position_sensor(model)
    z = np.arange(1.0, len(model.position_indices) + 1.0)
    x, P = birth_module.birth_state(model, sensor.measurement, z, BIRTH)
    assert x.shape == (init.state_dim,) and P.shape == (init.state_dim,) * 2
    assert _is_positive_definite(P)
    np.testing.assert_array_equal(x[list(init.position_indices)], z)


def test_birth_prior_values_of_the_cartesian_models() -> None:
    _, cov = ConstantAcceleration(ndim=2, noise_intensity=1.0).birth_prior(BIRTH)
    np.testing.assert_array_equal(np.diag(cov), [9.0, 9.0, 0.4**2, 0.4**2])
    _, cov = Singer(ndim=3, time_constant=2.0, acceleration_std=1.0).birth_prior(BIRTH)
    np.testing.assert_array_equal(np.diag(cov), [9.0] * 3 + [0.4**2] * 3)
    _, cov = ConstantVelocity(ndim=1, noise_intensity=1.0).birth_prior(BIRTH)
    np.testing.assert_array_equal(cov, [[9.0]])


def test_coordinated_turn_has_no_birth_prior_of_its_own() -> None:
    turn = CoordinatedTurn(speed_noise_intensity=0.1, turn_rate_noise_intensity=0.01)
    with pytest.raises(InputError, match="no birth prior is defined for motion model"):
        turn.birth_prior(BIRTH)
    init = turn.initiation_model()
    assert isinstance(init, ConstantVelocity)
    assert (init.ndim, init.noise_intensity) == (2, 0.1)


@pytest.mark.parametrize(("name", "kwargs"), CASES)
def test_conversion(name: str, kwargs: dict[str, object]) -> None:
    model = _model(name, kwargs)
    init = model.initiation_model()
    rng = np.random.default_rng(3)
    x0 = rng.normal(size=init.state_dim) + 1.0
    A = rng.normal(size=(init.state_dim, init.state_dim))
    P0 = A @ A.T + np.eye(init.state_dim)
    x, P = birth_module.convert_initiated(model, x0, P0, BIRTH)
    assert x.shape == (model.state_dim,) and P.shape == (model.state_dim,) * 2
    assert _is_positive_definite(P)
    if not model.needs_conversion():
        assert x is x0 and P is P0
        return
    # The inverse change of variables recovers the initiation state.
    back_x, back_P = model.revert_conversion(x, P)
    np.testing.assert_allclose(back_x, x0, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(back_P, P0, rtol=1e-10, atol=1e-10)
    for i in model.conversion_prior_indices:
        assert x[i] == 0.0
    unconverted_x, unconverted_P = model.unconverted_state(x0, P0, BIRTH)
    assert unconverted_x.shape == (model.state_dim,)
    assert _is_positive_definite(unconverted_P)
    states, covs = model.canonical_states(x[None, :], P[None, :, :])
    assert states.shape == (1, model.state_dim) and covs.shape == (1,) + P.shape


@pytest.mark.parametrize(("name", "kwargs"), CASES)
def test_config_round_trip(name: str, kwargs: dict[str, object]) -> None:
    config = _config(_model(name, kwargs))
    text = config_to_toml(config)
    assert f'model = "{name}"' in text
    parsed = parse_config(tomllib.loads(text))
    assert type(parsed.motion) is type(config.motion)
    assert repr(parsed.motion) == repr(config.motion)
    assert config_to_toml(parsed) == text  # parse -> write -> parse is a fixed point


# --------------------------------------------------------------------------- Singer


SINGER_TOML = """
[motion]
model = "singer"
ndim = 2
time_constant = 8.0
acceleration_std = 0.05

[[sensors]]
name = "radar"
measurement = "position"
noise_std = 1.0
detection_probability = 0.95
false_alarms_per_scan = 1.0
region = [[-150.0, 150.0], [-150.0, 150.0]]

[birth]
rate = 0.05
initial_count = 3.0
velocity_std = 3.0
acceleration_std = 0.1

[estimator.windows]
window_length = 3

[estimator.count]
max_tracks = 8
"""


@pytest.mark.parametrize("tau", [0.05, 0.7, 1.0, 3.0, 40.0, 1e4])
@pytest.mark.parametrize("dt", [0.01, 0.5, 1.0, 2.5])
def test_singer_matrices_match_van_loan(tau: float, dt: float) -> None:
    sigma = 1.3
    model = Singer(ndim=1, time_constant=tau, acceleration_std=sigma)
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0 / tau]])
    G = np.array([[0.0], [0.0], [1.0]])
    F_ref, Q_ref = _van_loan(A, G, 2.0 * sigma**2 / tau, dt)
    F, Q = model.transition_matrix(dt), model.process_noise(dt)
    np.testing.assert_allclose(F, F_ref, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(Q, Q_ref, rtol=1e-10, atol=1e-10)
    assert np.array_equal(Q, Q.T)
    assert np.all(np.linalg.eigvalsh(Q) > 0.0)


def test_singer_layout_in_several_dimensions() -> None:
    model = Singer(ndim=3, time_constant=2.0, acceleration_std=0.5)
    one = Singer(ndim=1, time_constant=2.0, acceleration_std=0.5)
    assert model.state_names == ("x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az")
    assert model.position_indices == (0, 1, 2) and model.velocity_indices == (3, 4, 5)
    np.testing.assert_array_equal(
        model.process_noise(1.5), np.kron(one.process_noise(1.5), np.eye(3))
    )
    np.testing.assert_array_equal(
        model.transition_matrix(1.5), np.kron(one.transition_matrix(1.5), np.eye(3))
    )


def test_singer_series_and_closed_form_agree_at_the_switch() -> None:
    tau = 1.0
    model = Singer(ndim=1, time_constant=tau, acceleration_std=1.0)
    below, above = np.nextafter(1.0, 0.0), np.nextafter(1.0, 2.0)  # x = dt / tau
    for a, b in (
        (model.process_noise(below), model.process_noise(above)),
        (model.transition_matrix(below), model.transition_matrix(above)),
    ):
        np.testing.assert_allclose(a, b, rtol=1e-13)


def test_singer_tends_to_constant_acceleration_for_long_time_constants() -> None:
    # Singer (1970): as tau -> infinity with q = 2 sigma^2 / tau fixed, the acceleration
    # becomes a Wiener process, i.e. the constant-acceleration (white jerk) model.
    q, tau = 0.3, 1e8
    singer = Singer(ndim=2, time_constant=tau, acceleration_std=math.sqrt(q * tau / 2.0))
    accel = ConstantAcceleration(ndim=2, noise_intensity=q)
    for dt in (0.1, 1.0, 4.0):
        np.testing.assert_allclose(
            singer.transition_matrix(dt), accel.transition_matrix(dt), rtol=1e-7, atol=0
        )
        np.testing.assert_allclose(
            singer.process_noise(dt), accel.process_noise(dt), rtol=1e-7, atol=0
        )


def test_singer_acceleration_variance_is_stationary() -> None:
    sigma, tau = 0.8, 2.0
    model = Singer(ndim=1, time_constant=tau, acceleration_std=sigma)
    F, Q = model.transition_matrix(1.0), model.process_noise(1.0)
    # var(a') = e^-2x var(a) + Q_aa keeps sigma^2 fixed.
    assert F[2, 2] ** 2 * sigma**2 + Q[2, 2] == pytest.approx(sigma**2, rel=1e-14)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"time_constant": 0.0, "acceleration_std": 1}, "time_constant must be positive, got 0.0$"),
        ({"time_constant": -2, "acceleration_std": 1.0}, "time_constant must be positive, got -2"),
        ({"time_constant": 1.0, "acceleration_std": 0}, "acceleration_std must be positive, got 0"),
        ({"time_constant": math.inf, "acceleration_std": 1.0}, "time_constant"),
        ({"time_constant": 1.0, "acceleration_std": 1.0, "ndim": 4}, "ndim must be 1, 2 or 3"),
    ],
)
def test_singer_validation_messages(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(InputError, match=message):
        Singer(**kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("change", "key", "message"),
    [
        ({"time_constant": 0}, "motion.time_constant", "time_constant must be positive, got 0"),
        ({"acceleration_std": "1"}, "motion.acceleration_std", "must be a number, got '1'"),
        ({"ndim": 4}, "motion.ndim", "must be 1, 2 or 3 spatial dimensions, got 4"),
        (
            {"noise_intensity": 0.5},
            "motion.noise_intensity",
            "allowed keys for singer: model, ndim, time_constant, acceleration_std",
        ),
        ({"time_constant": None}, "motion.time_constant", "missing required key"),
    ],
)
def test_singer_config_errors(change: dict[str, object], key: str, message: str) -> None:
    data = tomllib.loads(SINGER_TOML)
    for name, value in change.items():
        if value is None:
            del data["motion"][name]
        else:
            data["motion"][name] = value
    with pytest.raises(ConfigError) as info:
        parse_config(data)
    assert info.value.key == key
    assert message in str(info.value)


def test_singer_config_text_round_trip() -> None:
    config = parse_config(tomllib.loads(SINGER_TOML))
    assert isinstance(config.motion, Singer)
    assert (config.motion.time_constant, config.motion.acceleration_std) == (8.0, 0.05)
    text = config_to_toml(config)
    assert '[motion]\nmodel = "singer"\nndim = 2\ntime_constant = 8.0\n' in text
    again = parse_config(tomllib.loads(text))
    assert repr(again.motion) == repr(config.motion)
    assert config_to_toml(again) == text


def test_singer_end_to_end() -> None:
    config = parse_config(tomllib.loads(SINGER_TOML))
    starts = [
        ([-60.0, -40.0, 2.0, 1.0, 0.0, 0.0], 0.0),
        ([50.0, -30.0, -1.5, 1.5, 0.0, 0.0], 0.0),
        ([0.0, 60.0, 0.5, -2.0, 0.0, 0.0], 3.0),
    ]
    targets = [
        TargetSpec(initial_state=np.array(state), birth_time=born, death_time=math.inf)
        for state, born in starts
    ]
    plan = scan_plan_regular(["radar"], 0.0, 1.0, 20)
    scenario = simulate(config, targets, plan, seed=7, name="singer")
    result = WindowEstimator(config=config).run(scenario.scans)
    tracks = result.tracks
    assert tracks.state_names == config.motion.state_names
    assert tracks.states.shape[1] == 6
    assert len(np.unique(tracks.track_ids)) == len(targets)
    oracle = oracle_tracks(scenario.scans, scenario.origins, config)
    assert set(np.unique(oracle.track_ids).tolist()) == set(np.unique(scenario.truth.target_ids))
    assert np.all(np.isfinite(oracle.states)) and np.all(oracle.variances > 0.0)
    # The scenario helpers ask the model for speeds and turn rates.
    birth = birth_model_for(config.motion, targets, plan)
    assert birth.velocity_std == pytest.approx(1.5 * math.hypot(2.0, 1.0))
    assert birth.turn_rate_std == 0.02
