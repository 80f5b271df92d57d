"""mapassoc.data.checks: detections outside their sensor's region."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mapassoc.data.checks import MOSTLY_OUTSIDE_SHARE, detections_outside_region, inside_region
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.sensor import Region, Sensor

MOTION = ConstantVelocity(ndim=2, noise_intensity=0.1)


def position_sensor(name: str = "pos") -> Sensor:
    return Sensor(
        name=name,
        measurement=LinearMeasurement.position(MOTION, noise_std=1.0),
        detection_probability=0.9,
        false_alarms_per_scan=5.0,
        region=Region.from_bounds([[-100.0, 100.0], [-50.0, 50.0]]),
    )


def radar(bearings: tuple[float, float] = (0.5, 2.65)) -> Sensor:
    return Sensor(
        name="radar",
        measurement=RangeBearing(sensor_position=[0.0, -160.0], range_std=1.0, bearing_std=0.01),
        detection_probability=0.9,
        false_alarms_per_scan=5.0,
        region=Region.from_bounds([[50.0, 290.0], list(bearings)]),
    )


def scans_of(sensor: str, points: list[list[float]], per_scan: int = 2) -> list[Scan]:
    z = np.asarray(points, dtype=float)
    return [
        Scan(time=float(i), sensor=sensor, detections=z[k : k + per_scan],
             rows=np.arange(k, k + len(z[k : k + per_scan])))
        for i, k in enumerate(range(0, len(z), per_scan))
    ]


def test_simulated_data_is_inside_its_regions() -> None:
    scenario = build_scenario("two_sensors", 0)
    assert detections_outside_region(scenario.scans, scenario.config.sensors) == []


def test_every_detection_outside_names_the_sensor_the_count_the_region_and_the_span() -> None:
    sensors = {"pos": position_sensor()}
    scans = scans_of("pos", [[500.0, 0.0], [600.0, 10.0], [700.0, -20.0]])
    assert detections_outside_region(scans, sensors) == [
        "sensor 'pos': all 3 detections lie outside its region (x [-100, 100], y [-50, 50]); "
        "the detections span x 500 to 700, y -20 to 10; check the region's units and "
        "component order (a range-bearing region is a box in range and bearing, radians)"
    ]


def test_more_than_half_outside_gets_its_own_message_and_half_gets_none() -> None:
    sensors = {"pos": position_sensor()}
    inside, outside = [0.0, 0.0], [0.0, 80.0]  # y 80 is outside [-50, 50]
    (message,) = detections_outside_region(scans_of("pos", [inside, outside, outside]), sensors)
    assert message.startswith(
        "sensor 'pos': 2 of 3 detections (66.7%, more than 50%) lie outside its region "
        "(x [-100, 100], y [-50, 50]); the detections span x 0 to 0, y 0 to 80;"
    )
    assert MOSTLY_OUTSIDE_SHARE == 0.5
    assert detections_outside_region(scans_of("pos", [inside, outside]), sensors) == []
    lower = detections_outside_region(scans_of("pos", [inside, outside]), sensors, share=0.25)
    assert len(lower) == 1 and "1 of 2 detections (50.0%, more than 25%)" in lower[0]


def test_a_range_bearing_sensor_is_judged_in_range_and_bearing() -> None:
    sensors = {"radar": radar()}
    good = [[100.0, 1.5], [280.0, 0.6]]
    assert detections_outside_region(scans_of("radar", good), sensors) == []
    # Cartesian positions written where range and bearing belong: ranges < 50 or bearings
    # far outside [0.5, 2.65].
    cartesian = [[-40.0, 30.0], [20.0, -10.0], [10.0, 70.0]]
    (message,) = detections_outside_region(scans_of("radar", cartesian), sensors)
    assert message.startswith(
        "sensor 'radar': all 3 detections lie outside its region (range [50, 290], bearing "
        "[0.5, 2.65]); the detections span range -40 to 20, bearing -10 to 70;"
    )


def test_bearings_count_inside_whatever_their_2pi_representation() -> None:
    sensor = radar(bearings=(4.0, 5.0))  # holds 3 pi / 2, written -pi / 2 by the simulation
    z = np.array([[100.0, -math.pi / 2], [100.0, 3 * math.pi / 2], [100.0, 0.0], [40.0, 4.5]])
    assert inside_region(sensor, z).tolist() == [True, True, False, False]
    # Linear components keep their exact value: the boundary is inside.
    assert inside_region(position_sensor(), np.array([[100.0, -50.0]])).tolist() == [True]


def test_each_sensor_gets_its_own_message_and_sensors_without_detections_none() -> None:
    sensors = {"pos": position_sensor(), "radar": radar(), "idle": position_sensor("idle")}
    scans = scans_of("pos", [[0.0, 99.0]]) + [
        Scan(time=5.0, sensor="radar", detections=np.array([[10.0, 1.0]]), rows=[7]),
        Scan(time=6.0, sensor="idle", detections=np.empty((0, 2)), rows=[]),
    ]
    messages = detections_outside_region(scans, sensors)
    assert [m.split(":")[0] for m in messages] == ["sensor 'pos'", "sensor 'radar'"]


def test_bad_input_is_named() -> None:
    with pytest.raises(InputError, match=r"scans\[0\] \(time 0.0\) is of sensor 'pos', which is "
                       r"not in the configuration \(sensors: radar\)"):
        detections_outside_region(scans_of("pos", [[0.0, 0.0]]), {"radar": radar()})
    with pytest.raises(InputError, match=r"share must be a number in \[0, 1\), got 1"):
        detections_outside_region([], {"pos": position_sensor()}, share=1)
    with pytest.raises(InputError, match=r"detections of sensor 'pos' must have shape \(m, 2\)"):
        inside_region(position_sensor(), np.zeros((3, 3)))
