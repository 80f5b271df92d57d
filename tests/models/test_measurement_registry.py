"""Tests of the measurement-model registry and of the measurement models' own answers
(motion fit, initiation state, direct position) that replaced the isinstance checks."""

from __future__ import annotations

import copy
import math
import tomllib
from collections.abc import Iterator

import numpy as np
import pytest

from mapassoc.data.config import MEASUREMENTS, Config, config_to_toml, parse_config
from mapassoc.data.settings import BirthModel, EstimatorSettings
from mapassoc.errors import ConfigError, InputError
from mapassoc.models.birth import birth_state, birth_states, initiation_measurement
from mapassoc.models.measurement import (
    MEASUREMENT_REGISTRY,
    LinearMeasurement,
    MeasurementModel,
    RangeBearing,
    SettingsReader,
    measurement_spec,
    register_measurement_model,
    wrap_angle,
)
from mapassoc.models.motion import (
    ConstantAcceleration,
    ConstantVelocity,
    CoordinatedTurn,
    MotionModel,
)
from mapassoc.models.sensor import Region, Sensor

MOTION = {"model": "constant_velocity", "ndim": 2, "noise_intensity": 0.5}
COMMON = {"detection_probability": 0.9, "false_alarms_per_scan": 3.0}

# One example [[sensors]] table (measurement settings and region) per built-in model.
EXAMPLES: dict[str, list[dict[str, object]]] = {
    "position": [
        {"noise_std": 1.5, "region": [[-10.0, 10.0], [-10.0, 10.0]]},
        {"noise_std": [0.1, 0.3], "region": [[-10.0, 10.0], [-10.0, 10.0]]},
    ],
    "range_bearing": [
        {
            "position": [1.0, -2.5],
            "range_std": 2.0,
            "bearing_std": 0.01,
            "region": [[0.0, 100.0], [-3.0, 3.0]],
        }
    ],
}


def _document(kind: str, example: dict[str, object], motion: dict[str, object] = MOTION) -> dict:
    sensor = {"name": "s", "measurement": kind, **COMMON, **example}
    return {"motion": dict(motion), "sensors": [copy.deepcopy(sensor)]}


def _settings(config: Config) -> dict[str, object]:
    measurement = config.sensors["s"].measurement
    spec = measurement_spec(measurement)
    assert spec is not None
    written = spec.write(measurement, config.motion)
    assert written is not None
    return {key: np.asarray(value).tolist() for key, value in written.items()}


# --------------------------------------------------------------------------- throwaway model


class BearingOnly(MeasurementModel):
    """Bearing of the target from a sensor at a known 2-D position (test model)."""

    is_linear = False
    component_names = ("bearing",)
    measurement_dim = 1

    def __init__(self, *, sensor_position, bearing_std: float, scans: int, tag: str) -> None:
        if bearing_std > 1.0:
            raise InputError(f"bearing_std must be at most 1 radian, got {bearing_std!r}")
        self.sensor_position = np.asarray(sensor_position, dtype=float)
        self.R = np.array([[bearing_std**2]])
        self.scans = scans
        self.tag = tag

    @property
    def noise_covariance(self):
        return self.R

    def predict(self, x):
        x = np.asarray(x, dtype=float)
        d = x[..., :2] - self.sensor_position
        return np.arctan2(d[..., 1], d[..., 0])[..., None]

    def jacobian(self, x):
        raise NotImplementedError

    def residual(self, z, z_hat):
        return wrap_angle(np.asarray(z, dtype=float) - np.asarray(z_hat, dtype=float))

    def position_from_measurement(self, z):
        raise InputError("a bearing does not fix a position")

    def motion_mismatch(self, motion: MotionModel) -> str | None:
        if len(motion.position_indices) != 2:
            return f"bearing-only needs a 2-D position, {motion!r} has another"
        return None

    def __repr__(self) -> str:
        return f"BearingOnly({self.sensor_position.tolist()}, {math.sqrt(self.R[0, 0])})"


def _read_bearing_only(settings: SettingsReader, motion: MotionModel) -> BearingOnly:
    return BearingOnly(
        sensor_position=settings.finite_vector("position", ("x", "y")),
        bearing_std=settings.positive("bearing_std"),
        scans=settings.integer("scans"),
        tag=settings.string("tag"),
    )


def _write_bearing_only(measurement: MeasurementModel, motion: MotionModel) -> dict | None:
    assert isinstance(measurement, BearingOnly)
    return {
        "position": measurement.sensor_position,
        "bearing_std": math.sqrt(measurement.R[0, 0]),
        "scans": measurement.scans,
        "tag": measurement.tag,
    }


@pytest.fixture
def bearing_only() -> Iterator[str]:
    register_measurement_model(
        "bearing_only",
        BearingOnly,
        ("position", "bearing_std", "scans", "tag"),
        read=_read_bearing_only,
        write=_write_bearing_only,
    )
    try:
        yield "bearing_only"
    finally:
        del MEASUREMENT_REGISTRY["bearing_only"]


BEARING_ONLY = {
    "position": [3.0, 4.0],
    "bearing_std": 0.02,
    "scans": 7,
    "tag": 'say "hi"',
    "region": [[-3.0, 3.0]],
}


# --------------------------------------------------------------------------- registry


def test_the_built_in_models_are_registered_in_order() -> None:
    assert MEASUREMENTS == ("position", "range_bearing")
    assert tuple(MEASUREMENT_REGISTRY) == MEASUREMENTS
    assert MEASUREMENT_REGISTRY["position"].cls is LinearMeasurement
    assert MEASUREMENT_REGISTRY["position"].keys == ("noise_std",)
    assert MEASUREMENT_REGISTRY["range_bearing"].cls is RangeBearing
    assert MEASUREMENT_REGISTRY["range_bearing"].keys == ("position", "range_std", "bearing_std")


@pytest.mark.parametrize(
    ("kind", "example"),
    [(kind, example) for kind, examples in EXAMPLES.items() for example in examples],
)
def test_every_registered_model_round_trips_through_config(
    kind: str, example: dict[str, object]
) -> None:
    assert set(MEASUREMENT_REGISTRY) <= set(EXAMPLES), "add an example for every model"
    first = parse_config(_document(kind, example))
    text = config_to_toml(first)
    assert f'measurement = "{kind}"' in text
    second = parse_config(tomllib.loads(text))
    assert type(second.sensors["s"].measurement) is MEASUREMENT_REGISTRY[kind].cls
    assert _settings(second) == _settings(first)
    assert config_to_toml(second) == text
    # the settings written are the ones read
    assert _settings(first) == {key: example[key] for key in MEASUREMENT_REGISTRY[kind].keys}


def test_a_model_registered_in_a_test_is_read_and_written(bearing_only: str) -> None:
    config = parse_config(_document(bearing_only, BEARING_ONLY))
    model = config.sensors["s"].measurement
    assert isinstance(model, BearingOnly)
    assert model.sensor_position.tolist() == [3.0, 4.0]
    assert model.scans == 7 and model.tag == 'say "hi"'
    text = config_to_toml(config)
    assert (
        'measurement = "bearing_only"\nposition = [3.0, 4.0]\nbearing_std = 0.02\n'
        'scans = 7\ntag = "say \\"hi\\""\n'
    ) in text
    again = parse_config(tomllib.loads(text))
    assert _settings(again) == _settings(config)
    assert config_to_toml(again) == text


def test_a_registered_model_gets_the_schema_errors(bearing_only: str) -> None:
    def error(**changes: object) -> ConfigError:
        example = {**BEARING_ONLY, **changes}
        with pytest.raises(ConfigError) as info:
            parse_config(_document(bearing_only, example))
        return info.value

    unknown = error(noise_std=1.0)
    assert unknown.key == "sensors[0].noise_std"
    assert (
        "allowed keys for a bearing_only sensor: name, measurement, detection_probability, "
        "detection_probability_start, false_alarms_per_scan, region, position, bearing_std, "
        "scans, tag"
    ) in str(unknown)
    assert error(position=[1.0]).key == "sensors[0].position"
    assert "must be [x, y], got [1.0]" in str(error(position=[1.0]))
    assert error(position=[1.0, math.nan]).key == "sensors[0].position[1]"
    assert error(bearing_std=0.0).key == "sensors[0].bearing_std"
    assert error(scans=7.0).key == "sensors[0].scans"
    assert error(tag=3).key == "sensors[0].tag"
    crossed = error(bearing_std=2.0)  # the model's own check: reported at the sensor
    assert crossed.key == "sensors[0]" and "at most 1 radian" in str(crossed)
    data = _document(bearing_only, BEARING_ONLY)
    del data["sensors"][0]["scans"]
    with pytest.raises(ConfigError, match="missing required key") as info:
        parse_config(data)
    assert info.value.key == "sensors[0].scans"
    data = _document("sonar", {})
    with pytest.raises(ConfigError) as info:
        parse_config(data)
    assert "must be one of position, range_bearing, bearing_only; got 'sonar'" in str(info.value)


def test_a_registered_model_says_whether_it_fits_the_motion(bearing_only: str) -> None:
    walk = {"model": "random_walk", "ndim": 1, "noise_intensity": 1.0}
    with pytest.raises(InputError, match="sensor 's': bearing-only needs a 2-D position"):
        parse_config(_document(bearing_only, BEARING_ONLY, walk))


def test_registration_refuses_duplicates() -> None:
    def read(settings: SettingsReader, motion: MotionModel) -> MeasurementModel:
        raise AssertionError

    with pytest.raises(InputError, match="new, non-empty"):
        register_measurement_model("position", BearingOnly, (), read=read, write=read)
    with pytest.raises(InputError, match="already registered"):
        register_measurement_model("other", RangeBearing, (), read=read, write=read)
    with pytest.raises(InputError, match="distinct"):
        register_measurement_model("other", BearingOnly, ("a", "a"), read=read, write=read)
    assert tuple(MEASUREMENT_REGISTRY) == ("position", "range_bearing")


def test_unregistered_and_unwritable_models_are_refused_by_the_writer() -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=1.0)
    model = BearingOnly(sensor_position=[0.0, 0.0], bearing_std=0.1, scans=1, tag="")
    assert measurement_spec(model) is None
    config = Config(
        motion=motion,
        sensors={
            "s": Sensor(
                name="s",
                measurement=model,
                detection_probability=0.9,
                false_alarms_per_scan=1.0,
                region=Region.from_bounds([[-3.0, 3.0]]),
            )
        },
        birth=BirthModel(),
        estimator=EstimatorSettings(),
    )
    with pytest.raises(ConfigError, match="cannot write BearingOnly") as info:
        config_to_toml(config)
    assert info.value.key == "sensors[0].measurement"
    correlated = LinearMeasurement.position(motion, noise_std=1.0)
    correlated.R = np.array([[1.0, 0.5], [0.5, 1.0]])
    assert MEASUREMENT_REGISTRY["position"].write(correlated, motion) is None


def test_a_subclass_of_a_registered_model_is_written_like_it() -> None:
    class Tagged(RangeBearing):
        pass

    model = Tagged(sensor_position=[0.0, 1.0], range_std=1.0, bearing_std=0.1)
    assert measurement_spec(model) is MEASUREMENT_REGISTRY["range_bearing"]


# --------------------------------------------------------------------------- model answers


def test_linear_position_measurement_on_the_coordinated_turn_initiation_state() -> None:
    turn = CoordinatedTurn(speed_noise_intensity=1.0, turn_rate_noise_intensity=0.1)
    lin = LinearMeasurement.position(turn, noise_std=[2.0, 3.0])
    init = initiation_measurement(turn, lin)
    assert isinstance(init, LinearMeasurement)
    assert init.H.tolist() == [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]
    assert init.R.tolist() == [[4.0, 0.0], [0.0, 9.0]]
    assert init.component_names == ("x", "y")
    assert init.position_indices == (0, 1)
    direct = lin.on_initiation_state(turn, turn.initiation_model())
    assert np.array_equal(direct.H, init.H) and np.array_equal(direct.R, init.R)


def test_a_linear_measurement_of_the_speed_cannot_act_on_the_initiation_state() -> None:
    turn = CoordinatedTurn(speed_noise_intensity=1.0, turn_rate_noise_intensity=0.1)
    speed = LinearMeasurement(H=[[0.0, 0.0, 1.0, 0.0, 0.0]], R=[[1.0]], component_names=("s",))
    with pytest.raises(InputError) as info:
        initiation_measurement(turn, speed)
    assert str(info.value) == (
        "the linear measurement H=[[0.0, 0.0, 1.0, 0.0, 0.0]] reads state components other "
        "than the position ['x', 'y'], so it cannot be applied to a ConstantVelocity "
        "initiation state"
    )


def test_initiation_measurement_is_the_measurement_itself_otherwise() -> None:
    turn = CoordinatedTurn(speed_noise_intensity=1.0, turn_rate_noise_intensity=0.1)
    cv = ConstantVelocity(ndim=2, noise_intensity=1.0)
    rb = RangeBearing(sensor_position=[0.0, 0.0], range_std=1.0, bearing_std=0.1)
    lin = LinearMeasurement.position(cv, noise_std=1.0)
    assert initiation_measurement(turn, rb) is rb
    assert initiation_measurement(cv, lin) is lin
    assert initiation_measurement(cv, rb) is rb


def test_motion_mismatch_messages() -> None:
    cv = ConstantVelocity(ndim=2, noise_intensity=1.0)
    ca = ConstantAcceleration(ndim=2, noise_intensity=1.0)
    lin = LinearMeasurement.position(cv, noise_std=1.0)
    assert lin.motion_mismatch(cv) is None
    assert lin.motion_mismatch(ca) == (
        f"measurement matrix H has 4 columns but the motion model {ca!r} has 6 states"
    )
    rb = RangeBearing(
        sensor_position=[0.0, 0.0], range_std=1.0, bearing_std=0.1, position_indices=(0, 5)
    )
    assert rb.motion_mismatch(ca) is None
    assert rb.motion_mismatch(cv) == (
        "range-bearing position indices (0, 5) exceed the motion model's 4 states"
    )
    sensor = Sensor(
        name="p",
        measurement=lin,
        detection_probability=0.9,
        false_alarms_per_scan=1.0,
        region=Region.from_bounds([[-1.0, 1.0], [-1.0, 1.0]]),
    )
    with pytest.raises(InputError) as info:
        Config(motion=ca, sensors={"p": sensor}, birth=BirthModel(), estimator=EstimatorSettings())
    assert str(info.value) == (
        f"sensor 'p': measurement matrix H has 4 columns but the motion model {ca!r} has 6 states"
    )


def test_measures_position_directly_and_the_batch_of_births() -> None:
    cv = ConstantVelocity(ndim=2, noise_intensity=1.0)
    lin = LinearMeasurement.position(cv, noise_std=[1.0, 2.0])
    general = LinearMeasurement(H=lin.H, R=lin.R, component_names=("a", "b"))
    rb = RangeBearing(sensor_position=[0.0, 0.0], range_std=1.0, bearing_std=0.1)
    assert lin.measures_position_directly is True
    assert general.measures_position_directly is False
    assert rb.measures_position_directly is False
    birth = BirthModel()
    Z = np.array([[1.0, 2.0], [-3.0, 4.5], [0.0, 0.0]])
    xs, Ps = birth_states(cv, lin, Z, birth)
    for z, x, P in zip(Z, xs, Ps, strict=True):
        x1, P1 = birth_state(cv, lin, z, birth)
        assert np.array_equal(x, x1) and np.array_equal(P, P1)
        assert x.tolist() == [z[0], z[1], 0.0, 0.0]
    polar = np.array([[10.0, 0.3], [5.0, -2.0]])
    xs, Ps = birth_states(cv, rb, polar, birth)
    for z, x, P in zip(polar, xs, Ps, strict=True):
        x1, P1 = birth_state(cv, rb, z, birth)
        assert np.array_equal(x, x1) and np.array_equal(P, P1)
