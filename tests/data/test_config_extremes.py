"""Values at the ends of double precision fail at load, naming the key (issue 19).

A region whose volume overflows or underflows, a false-alarm density that underflows,
a standard deviation whose square overflows or underflows, a birth count past 2**53:
each once passed the checks and failed deep inside a window (a ValueError from the
scores, ZeroDivisionError, OverflowError), or silently gave a singular covariance.
"""

from __future__ import annotations

import re
import tomllib

import pytest

from mapassoc.data.config import config_to_toml, parse_config
from mapassoc.data.settings import BirthModel
from mapassoc.errors import ConfigError, InputError
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity, Singer
from mapassoc.models.sensor import Region, Sensor
from mapassoc.validation import check_standard_deviation

REGION = "region = [[-100.0, 100.0], [-100.0, 100.0]]"


def _text(scenario: str) -> str:
    return config_to_toml(build_scenario(scenario, 0).config)


def _edit(text: str, pattern: str, replacement: str) -> str:
    """``text`` with the first line matching ``pattern`` (a regular expression) replaced."""
    edited, count = re.subn(pattern, replacement, text, count=1, flags=re.MULTILINE)
    assert count == 1, pattern
    return edited


CASES = [
    # (scenario, line pattern, replacement, key, value as written in the message)
    ("crossing", re.escape(REGION), "region = [[-1e308, 1e308], [-1e308, 1e308]]",
     "sensors[0].region", "inf"),
    ("crossing", re.escape(REGION), "region = [[-1e200, 1e200], [-1e200, 1e200]]",
     "sensors[0].region", "inf"),
    ("crossing", re.escape(REGION), "region = [[0.0, 1e-300], [0.0, 1e-300]]",
     "sensors[0].region", "1e-300"),
    ("crossing", r"^false_alarms_per_scan = .*$", "false_alarms_per_scan = 1e-320",
     "sensors[0].false_alarms_per_scan", "1e-320"),
    ("crossing", r"^noise_std = .*$", "noise_std = 1e300", "sensors[0].noise_std", "1e+300"),
    ("crossing", r"^noise_std = .*$", "noise_std = 1e-300", "sensors[0].noise_std", "1e-300"),
    ("crossing", r"^noise_std = .*$", "noise_std = [1.0, 1e200]",
     "sensors[0].noise_std[1]", "1e+200"),
    ("two_sensors", r"^range_std = .*$", "range_std = 1e300", "sensors[1].range_std", "1e+300"),
    ("two_sensors", r"^bearing_std = .*$", "bearing_std = 1e-200",
     "sensors[1].bearing_std", "1e-200"),
    ("crossing", r"^velocity_std = .*$", "velocity_std = 1e300", "birth.velocity_std", "1e+300"),
    ("crossing", r"^velocity_std = .*$", "velocity_std = 1e-300",
     "birth.velocity_std", "1e-300"),
    ("crossing", r"^acceleration_std = .*$", "acceleration_std = 1e160",
     "birth.acceleration_std", "1e+160"),
    ("turning", r"^speed_std = .*$", "speed_std = 1e300", "birth.speed_std", "1e+300"),
    ("turning", r"^turn_rate_std = .*$", "turn_rate_std = 1e-170",
     "birth.turn_rate_std", "1e-170"),
    ("crossing", r"^rate = .*$", "rate = 1e308", "birth.rate", "1e+308"),
    ("crossing", r"^initial_count = .*$", "initial_count = 1e300",
     "birth.initial_count", "1e+300"),
]  # fmt: skip


@pytest.mark.parametrize(("scenario", "pattern", "replacement", "key", "value"), CASES)
def test_an_extreme_value_is_one_config_error_naming_key_and_value(
    scenario: str, pattern: str, replacement: str, key: str, value: str
) -> None:
    text = _edit(_text(scenario), pattern, replacement)
    with pytest.raises(ConfigError) as info:
        parse_config(tomllib.loads(text), source="extreme.toml")
    message = str(info.value)
    assert info.value.key == key
    assert message.startswith(f"extreme.toml: config key '{key}': ")
    assert value in message and "\n" not in message
    assert "expected" in message


def test_a_singer_acceleration_std_that_overflows_its_square_names_the_motion_key() -> None:
    text = _edit(
        _text("crossing"),
        r"^\[motion\]\n(?:.*\n)*?noise_intensity = .*$",
        '[motion]\nmodel = "singer"\nndim = 2\ntime_constant = 5.0\nacceleration_std = 1e200',
    )
    with pytest.raises(ConfigError) as info:
        parse_config(tomllib.loads(text))
    assert info.value.key == "motion.acceleration_std"
    assert "1e+200" in str(info.value)


def test_values_just_inside_double_precision_are_accepted() -> None:
    """The checks refuse only what cannot be represented: no clamping, no margins."""
    text = _text("crossing")
    for pattern, replacement in [
        (re.escape(REGION), "region = [[-1e150, 1e150], [-1e150, 1e150]]"),
        (r"^noise_std = .*$", "noise_std = 1e150"),
        (r"^velocity_std = .*$", "velocity_std = 1e-150"),
        (r"^false_alarms_per_scan = .*$", "false_alarms_per_scan = 1e-5"),
        (r"^rate = .*$", "rate = 1e15"),
    ]:
        text = _edit(text, pattern, replacement)
    config = parse_config(tomllib.loads(text))
    sensor = config.sensors["pos"]
    assert sensor.region.volume == pytest.approx(4e300)
    assert 0.0 < sensor.clutter_density < 1e-300  # 1e-5 / 4e300, still a positive double
    assert config.birth.rate == 1e15


def test_the_model_constructors_refuse_the_same_values_with_keys() -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=0.01)
    with pytest.raises(InputError, match="volume inf"):
        Region.from_bounds([[-1e308, 1e308], [-1e308, 1e308]])
    with pytest.raises(InputError, match="volume 0.0"):
        Region.from_bounds([[0.0, 1e-300], [0.0, 1e-300]])
    measurement = LinearMeasurement.position(motion, noise_std=1.0)
    with pytest.raises(InputError, match="false-alarm density 0.0") as info:
        Sensor(
            name="s",
            measurement=measurement,
            detection_probability=0.9,
            false_alarms_per_scan=1e-320,
            region=Region.from_bounds([[0.0, 1e4], [0.0, 1e4]]),
        )
    assert info.value.key == "false_alarms_per_scan"
    no_clutter = Sensor(
        name="s",
        measurement=measurement,
        detection_probability=0.9,
        false_alarms_per_scan=0.0,
        region=Region.from_bounds([[0.0, 1e4], [0.0, 1e4]]),
    )
    assert no_clutter.clutter_density == 0.0
    with pytest.raises(InputError) as info:
        LinearMeasurement.position(motion, noise_std=1e-300)
    assert info.value.key == "noise_std"
    with pytest.raises(InputError) as info:
        RangeBearing(sensor_position=[0.0, 0.0], range_std=1e200, bearing_std=0.01)
    assert info.value.key == "range_std"
    with pytest.raises(InputError) as info:
        Singer(ndim=2, time_constant=1.0, acceleration_std=1e300)
    assert info.value.key == "acceleration_std"
    with pytest.raises(InputError) as info:
        BirthModel(velocity_std=1e300)
    assert info.value.key == "velocity_std"
    with pytest.raises(InputError) as info:
        BirthModel(rate=2.0**54)
    assert info.value.key == "rate"


@pytest.mark.parametrize(
    ("value", "ok"),
    [(1.0, True), (1e154, True), (1e-154, True), (1e155, False), (1e-170, False),
     (float("inf"), False), (0.0, False), (-1.0, False)],
)  # fmt: skip
def test_check_standard_deviation_accepts_exactly_the_squarable_values(
    value: float, ok: bool
) -> None:
    if ok:
        assert check_standard_deviation("s", value) == value
        assert 0.0 < value * value < float("inf")
    else:
        with pytest.raises(InputError, match="s "):
            check_standard_deviation("s", value, key="k")
