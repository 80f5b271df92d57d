"""Tests of mapassoc.data.config: parsing, the TOML emitter round trip, and every bad-key case."""

from __future__ import annotations

import copy
import math
import tomllib
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support import MINIMAL_CONFIG_TOML

from mapassoc.data.config import Config, config_to_toml, load_config, parse_config, write_config
from mapassoc.data.settings import BirthModel, EstimatorSettings
from mapassoc.errors import ConfigError, InputError
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import (
    ConstantAcceleration,
    ConstantVelocity,
    CoordinatedTurn,
    RandomWalk,
)
from mapassoc.models.sensor import Region, Sensor

FULL_TOML = MINIMAL_CONFIG_TOML + """
[[sensors]]
name = "esm"
measurement = "range_bearing"
position = [0, -50.0]
range_std = 2.0
bearing_std = 0.01
detection_probability = 0.8
false_alarms_per_scan = 1e-6
region = [[0.0, 300.0], [-3.0, 3.0]]

[birth]
rate = 0.2

[estimator]
window_length = 4
stride = 2
max_tracks = 2
prune_log_ratio = inf
k_prior = "weights"
k_prior_weights = [1, 2.5, 0]
k_estimate = "joint"
"""


def _full() -> dict[str, object]:
    return tomllib.loads(FULL_TOML)


def test_full_config_parses_to_the_right_objects() -> None:
    config = parse_config(_full(), source="scenario.toml")
    assert config.source == "scenario.toml"
    assert isinstance(config.motion, ConstantVelocity)
    assert (config.motion.ndim, config.motion.noise_intensity) == (2, 0.5)
    assert list(config.sensors) == ["radar", "esm"]

    radar = config.sensors["radar"]
    assert isinstance(radar.measurement, LinearMeasurement)
    assert radar.measurement.component_names == ("x", "y")
    assert radar.measurement.H.tolist() == [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]
    assert radar.measurement.R.tolist() == [[1.0, 0.0], [0.0, 1.0]]
    assert radar.detection_probability == 0.9
    assert radar.clutter_density == 10.0 / 40000.0  # 10 false alarms over a 200 x 200 box

    esm = config.sensors["esm"]
    assert isinstance(esm.measurement, RangeBearing)
    assert esm.measurement.sensor_position.tolist() == [0.0, -50.0]
    assert esm.measurement.R.tolist() == [[4.0, 0.0], [0.0, 0.01**2]]
    assert esm.region.to_bounds() == [[0.0, 300.0], [-3.0, 3.0]]
    assert esm.clutter_density == 1e-6 / (300.0 * 6.0)

    assert config.birth == BirthModel(rate=0.2)
    assert config.estimator == EstimatorSettings(
        window_length=4,
        stride=2,
        max_tracks=2,
        prune_log_ratio=math.inf,
        k_prior="weights",
        k_prior_weights=(1.0, 2.5, 0.0),
        k_estimate="joint",
    )
    assert isinstance(config.estimator.k_prior_weights[0], float)


def test_birth_and_estimator_default_when_absent() -> None:
    data = _full()
    del data["birth"], data["estimator"]
    config = parse_config(data)
    assert config.birth == BirthModel()
    assert config.estimator == EstimatorSettings()
    assert config.source is None


def _assert_same_config(got: Config, want: Config) -> None:
    assert type(got.motion) is type(want.motion)
    assert repr(got.motion) == repr(want.motion)
    assert list(got.sensors) == list(want.sensors)
    for name, sensor in want.sensors.items():
        other = got.sensors[name]
        assert type(other.measurement) is type(sensor.measurement)
        assert np.array_equal(
            other.measurement.noise_covariance, sensor.measurement.noise_covariance
        )
        if isinstance(sensor.measurement, LinearMeasurement):
            assert np.array_equal(other.measurement.H, sensor.measurement.H)
        else:
            assert np.array_equal(
                other.measurement.sensor_position, sensor.measurement.sensor_position
            )
        assert other.detection_probability == sensor.detection_probability
        assert other.false_alarms_per_scan == sensor.false_alarms_per_scan
        assert other.region == sensor.region
    assert got.birth == want.birth
    assert got.estimator == want.estimator
    assert got.trackers == want.trackers


def _sensor(name: str, measurement: object, bounds: list[list[float]]) -> Sensor:
    return Sensor(
        name=name,
        measurement=measurement,
        detection_probability=0.75,
        false_alarms_per_scan=2.5,
        region=Region.from_bounds(bounds),
    )


def _configs() -> list[Config]:
    cv3 = ConstantVelocity(ndim=3, noise_intensity=0.1)
    turn = CoordinatedTurn(speed_noise_intensity=0.3, turn_rate_noise_intensity=1e-4)
    walk = RandomWalk(ndim=1, noise_intensity=0.35)
    accel = ConstantAcceleration(ndim=2, noise_intensity=2.0)
    box3 = [[-1.0, 1.0], [-2.0, 2.0], [0.0, 1e4]]
    return [
        parse_config(_full()),
        Config(
            motion=cv3,
            sensors={
                "a": _sensor("a", LinearMeasurement.position(cv3, noise_std=[0.1, 0.2, 0.3]), box3)
            },
            birth=BirthModel(velocity_std=3.0, survival_probability=1.0),
            estimator=EstimatorSettings(k_prior="poisson", k_prior_mean=2.5, time_limit=1e-3),
        ),
        Config(
            motion=turn,
            sensors={
                'odd "name"\\': _sensor(
                    'odd "name"\\',
                    RangeBearing(sensor_position=[1.5, -2.0], range_std=0.7, bearing_std=1e-3),
                    [[0.0, 50.0], [-math.pi, math.pi]],
                ),
                "xy": _sensor("xy", LinearMeasurement.position(turn, noise_std=2.0), box3[:2]),
            },
            birth=BirthModel(),
            estimator=EstimatorSettings(),
        ),
        Config(
            motion=walk,
            sensors={
                "line": _sensor(
                    "line", LinearMeasurement.position(walk, noise_std=1.0), [[-5.0, 5.0]]
                )
            },
            birth=BirthModel(rate=0.05),
            estimator=EstimatorSettings(window_length=1, max_tracks=0),
        ),
        Config(
            motion=accel,
            sensors={
                "r": _sensor("r", LinearMeasurement.position(accel, noise_std=[1.0, 3.0]), box3[:2])
            },
            birth=BirthModel(acceleration_std=0.5),
            estimator=EstimatorSettings(),
        ),
    ]


@pytest.mark.parametrize("config", _configs(), ids=["full", "cv3", "turn", "walk", "accel"])
def test_toml_round_trip(config: Config) -> None:
    text = config_to_toml(config)
    _assert_same_config(parse_config(tomllib.loads(text)), config)


def test_toml_golden_sections() -> None:
    text = config_to_toml(_configs()[1])
    assert '[motion]\nmodel = "constant_velocity"\nndim = 3\nnoise_intensity = 0.1\n' in text
    assert "noise_std = [0.1, 0.2, 0.3]\n" in text
    assert "region = [[-1.0, 1.0], [-2.0, 2.0], [0.0, 10000.0]]\n" in text
    assert 'k_prior = "poisson"\n' in text and "time_limit = 0.001\n" in text


def test_the_sibling_width_is_written_only_when_set() -> None:
    plain = _configs()[0]
    assert plain.estimator.sibling_prune_log_ratio is None
    assert "sibling_prune_log_ratio" not in config_to_toml(plain)  # old files write back alike
    assert plain.estimator.sibling_log_ratio == plain.estimator.prune_log_ratio
    estimator = EstimatorSettings(prune_log_ratio=6.0, sibling_prune_log_ratio=math.inf)
    config = Config(
        motion=plain.motion, sensors=plain.sensors, birth=plain.birth, estimator=estimator
    )
    text = config_to_toml(config)
    assert "prune_log_ratio = 6.0\nsibling_prune_log_ratio = inf\n" in text
    back = parse_config(tomllib.loads(text))
    assert back.estimator.sibling_log_ratio == math.inf and back.estimator.prune_log_ratio == 6.0


def test_write_and_load_config(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    config = _configs()[2]
    write_config(path, config)
    loaded = load_config(path)
    assert loaded.source == str(path)
    _assert_same_config(loaded, config)


positive = st.floats(min_value=1e-6, max_value=1e6, allow_subnormal=False)


@settings(max_examples=50, deadline=None)
@given(
    intensity=positive,
    std=st.lists(positive, min_size=2, max_size=2),
    range_std=positive,
    pd=st.floats(min_value=1e-9, max_value=1.0, exclude_min=False),
    low=st.floats(-1e6, 1e6),
    width=positive,
)
def test_round_trip_reproduces_floats_exactly(
    intensity: float, std: list[float], range_std: float, pd: float, low: float, width: float
) -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=intensity)
    bounds = [[low, low + width], [low, low + 2 * width]]
    config = Config(
        motion=motion,
        sensors={
            "p": _sensor("p", LinearMeasurement.position(motion, noise_std=std), bounds),
            "rb": Sensor(
                name="rb",
                measurement=RangeBearing(
                    sensor_position=[low, width], range_std=range_std, bearing_std=std[0]
                ),
                detection_probability=pd,
                false_alarms_per_scan=width,
                region=Region.from_bounds(bounds),
            ),
        },
        birth=BirthModel(rate=intensity),
        estimator=EstimatorSettings(prune_log_ratio=width, gate_probability=min(pd, 0.5)),
    )
    _assert_same_config(parse_config(tomllib.loads(config_to_toml(config))), config)


# ------------------------------------------------------------------------ bad configurations


def _set(path: tuple[object, ...], value: object) -> Callable[[dict], None]:
    def apply(data: dict) -> None:
        target = data
        for step in path[:-1]:
            target = target[step]
        target[path[-1]] = value

    return apply


def _delete(path: tuple[object, ...]) -> Callable[[dict], None]:
    def apply(data: dict) -> None:
        target = data
        for step in path[:-1]:
            target = target[step]
        del target[path[-1]]

    return apply


def _one_dimensional(data: dict) -> None:
    data["motion"]["ndim"] = 1
    data["sensors"] = data["sensors"][1:]  # only the range-bearing sensor


def _duplicate_names(data: dict) -> None:
    data["sensors"][1]["name"] = "radar"


BAD_CONFIGS = [
    # (mutation, dotted key, text the message must contain: the value or what is wrong)
    (_delete(("motion",)), "motion", "missing required section [motion]"),
    (_delete(("sensors",)), "sensors", "missing"),
    (_set(("sensors",), []), "sensors", "at least one"),
    (_set(("colour",), "red"), "colour", "unknown key (value 'red')"),
    (_set(("motion", "speed"), 3), "motion.speed", "unknown key (value 3)"),
    (_set(("sensors", 0, "colour"), 1), "sensors[0].colour", "unknown key"),
    (_set(("sensors", 1, "noise_std"), 1.0), "sensors[1].noise_std", "unknown key"),
    (_set(("estimator", "window"), 3), "estimator.window", "unknown key (value 3)"),
    (_set(("birth", "rates"), 3), "birth.rates", "unknown key"),
    (_set(("motion", "model"), "bicycle"), "motion.model", "'bicycle'"),
    (_delete(("motion", "model")), "motion.model", "missing required key"),
    (_set(("motion", "ndim"), 4), "motion.ndim", "got 4"),
    (_set(("motion", "ndim"), 2.0), "motion.ndim", "got 2.0"),
    (_set(("motion", "noise_intensity"), 0), "motion.noise_intensity", "got 0"),
    (_set(("motion", "noise_intensity"), "0.5"), "motion.noise_intensity", "'0.5'"),
    (
        _set(("sensors", 0, "detection_probability"), 1.5),
        "sensors[0].detection_probability",
        "got 1.5",
    ),
    (
        _set(("sensors", 0, "detection_probability"), 0.0),
        "sensors[0].detection_probability",
        "got 0.0",
    ),
    (
        _set(("sensors", 0, "detection_probability"), True),
        "sensors[0].detection_probability",
        "got True",
    ),
    (
        _set(("sensors", 0, "detection_probability"), math.nan),
        "sensors[0].detection_probability",
        "nan",
    ),
    (
        _set(("sensors", 0, "false_alarms_per_scan"), -1.0),
        "sensors[0].false_alarms_per_scan",
        "got -1.0",
    ),
    (
        _set(("sensors", 0, "false_alarms_per_scan"), 0),
        "sensors[0].false_alarms_per_scan",
        "must be > 0, got 0: the estimator and the trackers weigh each detection",
    ),
    (_set(("sensors", 0, "noise_std"), 0.0), "sensors[0].noise_std", "got 0.0"),
    (_set(("sensors", 0, "noise_std"), [1.0, -2.0]), "sensors[0].noise_std[1]", "got -2.0"),
    (_set(("sensors", 0, "noise_std"), [1.0, 1.0, 1.0]), "sensors[0].noise_std", "3 entries"),
    (_set(("sensors", 1, "range_std"), 0), "sensors[1].range_std", "got 0"),
    (_set(("sensors", 1, "bearing_std"), math.inf), "sensors[1].bearing_std", "inf"),
    (_set(("sensors", 1, "position"), [1.0]), "sensors[1].position", "[1.0]"),
    (
        _set(("sensors", 0, "region"), [[0.0, 0.0], [-1.0, 1.0]]),
        "sensors[0].region[0]",
        "[0.0, 0.0]",
    ),
    (_set(("sensors", 0, "region"), [[-1.0, 1.0]]), "sensors[0].region", "1 rows"),
    (
        _set(("sensors", 0, "region"), [[-1.0, 1.0], [0.0, 1.0, 2.0]]),
        "sensors[0].region[1]",
        "[0.0, 1.0, 2.0]",
    ),
    (_set(("sensors", 0, "region"), [[-1.0, 1.0], [0.0, "a"]]), "sensors[0].region[1][1]", "'a'"),
    (_set(("sensors", 0, "measurement"), "sonar"), "sensors[0].measurement", "'sonar'"),
    (_set(("sensors", 0, "name"), "a,b"), "sensors[0].name", "'a,b'"),
    (_delete(("sensors", 0, "name")), "sensors[0].name", "missing required key"),
    (_delete(("sensors", 0, "region")), "sensors[0].region", "missing required key"),
    (_duplicate_names, "sensors[1].name", "duplicate sensor name 'radar'"),
    (_one_dimensional, "sensors[0].measurement", "'range_bearing' needs"),
    (_set(("estimator", "stride"), 6), "estimator.stride", "got 6"),
    (_set(("estimator", "window_length"), 4.0), "estimator.window_length", "got 4.0"),
    (_set(("estimator", "max_tracks"), True), "estimator.max_tracks", "got True"),
    (
        _set(("estimator", "k_prior_weights"), [1, -1, 0]),
        "estimator.k_prior_weights[1]",
        "got -1.0",
    ),
    (_set(("estimator", "k_prior_weights"), [1]), "estimator.k_prior_weights", "got 1"),
    (_set(("estimator", "k_prior"), "flat"), "estimator.k_prior", "'flat'"),
    (
        _set(("estimator", "sibling_prune_log_ratio"), -1.0),
        "estimator.sibling_prune_log_ratio",
        "got -1.0",
    ),
    (_set(("estimator", "gate_probability"), 0.0), "estimator.gate_probability", "got 0.0"),
    (_set(("estimator", "solver"), 3), "estimator.solver", "got 3"),
    (_set(("birth", "rate"), -0.1), "birth.rate", "got -0.1"),
    (_set(("birth", "survival_probability"), 0), "birth.survival_probability", "got 0"),
    (_set(("birth",), 5), "birth", "must be a table, got 5"),
]


@pytest.mark.parametrize(("mutate", "key", "fragment"), BAD_CONFIGS)
def test_bad_config_names_key_and_value(
    mutate: Callable[[dict], None], key: str, fragment: str
) -> None:
    data = copy.deepcopy(_full())
    mutate(data)
    with pytest.raises(ConfigError) as info:
        parse_config(data, source="bad.toml")
    message = str(info.value)
    assert info.value.key == key
    assert message.startswith(f"bad.toml: config key '{key}': ")
    assert fragment in message


def test_coordinated_turn_refuses_linear_keys() -> None:
    data = _full()
    data["motion"] = {"model": "coordinated_turn", "ndim": 2, "speed_noise_intensity": 1.0}
    with pytest.raises(ConfigError) as info:
        parse_config(data)
    assert info.value.key == "motion.ndim"
    data["motion"] = {"model": "coordinated_turn", "speed_noise_intensity": 1.0}
    with pytest.raises(ConfigError) as info:
        parse_config(data)
    assert info.value.key == "motion.turn_rate_noise_intensity"


def test_load_config_reports_syntax_and_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "broken.toml"
    path.write_text("[motion\nmodel = 1\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="invalid TOML") as info:
        load_config(path)
    assert info.value.source == str(path) and str(path) in str(info.value)
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "absent.toml")


def test_load_config_names_the_file_in_schema_errors(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(FULL_TOML.replace("stride = 2", "stride = 9"), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert info.value.key == "estimator.stride" and info.value.source == str(path)


def test_emitter_refuses_models_outside_the_schema() -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=1.0)
    velocity = LinearMeasurement(
        H=[[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]], R=np.eye(2), component_names=("vx", "vy")
    )
    config = Config(
        motion=motion,
        sensors={"doppler": _sensor("doppler", velocity, [[-1.0, 1.0], [-1.0, 1.0]])},
        birth=BirthModel(),
        estimator=EstimatorSettings(),
    )
    with pytest.raises(ConfigError) as info:
        config_to_toml(config)
    assert info.value.key == "sensors[0].measurement"


def test_config_constructor_validates() -> None:
    good = parse_config(_full())
    radar = good.sensors["radar"]
    with pytest.raises(InputError, match="differs from the sensor's name"):
        Config(motion=good.motion, sensors={"x": radar}, birth=good.birth, estimator=good.estimator)
    with pytest.raises(InputError, match="non-empty"):
        Config(motion=good.motion, sensors={}, birth=good.birth, estimator=good.estimator)
    with pytest.raises(InputError, match="has 2 states"):
        Config(
            motion=RandomWalk(ndim=2, noise_intensity=1.0),
            sensors={"radar": radar},
            birth=good.birth,
            estimator=good.estimator,
        )


TRACKERS_TOML = MINIMAL_CONFIG_TOML + """
[trackers.mht]
n_scan = 4
prune_log_ratio = inf
m_best_pruning = true
solver = "highs"

[trackers."my tracker"]
level = 0.25
"""


def test_tracker_tables_parse_and_round_trip() -> None:
    config = parse_config(tomllib.loads(TRACKERS_TOML))
    assert config.trackers == {
        "mht": {
            "n_scan": 4,
            "prune_log_ratio": math.inf,
            "m_best_pruning": True,
            "solver": "highs",
        },
        "my tracker": {"level": 0.25},
    }
    assert isinstance(config.trackers["mht"]["n_scan"], int)
    text = config_to_toml(config)
    assert '[trackers.mht]\nn_scan = 4\nprune_log_ratio = inf\nm_best_pruning = true\n' in text
    assert '[trackers."my tracker"]\nlevel = 0.25\n' in text
    _assert_same_config(parse_config(tomllib.loads(text)), config)
    # No table: nothing written, nothing read.
    plain = parse_config(tomllib.loads(MINIMAL_CONFIG_TOML))
    assert plain.trackers == {} and "[trackers" not in config_to_toml(plain)


_SCALAR = "a number, a boolean or a string"


@pytest.mark.parametrize(
    ("extra", "key", "message"),
    [
        ("[trackers]\nmht = 3\n", "trackers.mht", "must be a table"),
        ("[trackers.mht]\nn_scan = [1, 2]\n", "trackers.mht.n_scan", _SCALAR),
        ("[trackers.mht]\nlevel = nan\n", "trackers.mht.level", _SCALAR),
        ("[trackers.mht.inner]\nx = 1\n", "trackers.mht.inner", _SCALAR),
        ("trackers = 1\n", "trackers", "must be a table"),
    ],
)
def test_bad_tracker_tables_name_their_key(extra: str, key: str, message: str) -> None:
    # A top-level key must come before the first table of the document.
    top_level = extra.startswith("trackers =")
    text = extra + MINIMAL_CONFIG_TOML if top_level else MINIMAL_CONFIG_TOML + extra
    with pytest.raises(ConfigError, match=message) as info:
        parse_config(tomllib.loads(text))
    assert info.value.key == key


def test_tracker_names_are_checked_against_the_callers_registry() -> None:
    data = tomllib.loads(MINIMAL_CONFIG_TOML + "[trackers.mhtt]\nn_scan = 4\n")
    with pytest.raises(ConfigError, match="unknown tracker; known trackers: gnn, mht") as info:
        parse_config(data, tracker_names=("mht", "gnn"))
    assert info.value.key == "trackers.mhtt"
    assert parse_config(data).trackers == {"mhtt": {"n_scan": 4}}  # no registry: kept
