"""Tests of mapassoc.data.tables: scans from arrays and DataFrames, and their validation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from support import make_config

from mapassoc.data.io import number_rows, read_detections, write_detections
from mapassoc.data.scans import Scan
from mapassoc.data.tables import scans_from_arrays, scans_from_frame
from mapassoc.errors import InputError
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.sensor import Region, Sensor


def _position(name: str, ndim: int = 2) -> Sensor:
    motion = ConstantVelocity(ndim=ndim, noise_intensity=1.0)
    return Sensor(
        name=name,
        measurement=LinearMeasurement.position(motion, noise_std=1.0),
        detection_probability=0.9,
        false_alarms_per_scan=1.0,
        region=Region.from_bounds([[-10.0, 10.0]] * ndim),
    )


RANGE_BEARING = Sensor(
    name="esm",
    measurement=RangeBearing(sensor_position=[0.0, 0.0], range_std=1.0, bearing_std=0.01),
    detection_probability=0.9,
    false_alarms_per_scan=1.0,
    region=Region.from_bounds([[0.0, 100.0], [-np.pi, np.pi]]),
)
RADAR = {"radar": _position("radar")}
# names sort as esm < radar < sonar; the mapping order is not the sorted order
TWO_2D = {"sonar": _position("sonar"), "radar": _position("radar")}
MIXED = {"radar": _position("radar"), "esm": RANGE_BEARING}


def _summary(scans: list[Scan]) -> list[tuple[float, str, list[list[float]], list[int]]]:
    return [(s.time, s.sensor, s.detections.tolist(), s.rows.tolist()) for s in scans]


# ------------------------------------------------------------------------ arrays


def test_arrays_golden_unsorted_input_is_grouped_and_sorted() -> None:
    times = [2.0, 0.0, 2.0, 1.0, 0.0]
    z = [[1.0, 1.5], [2.0, 2.5], [3.0, 3.5], [4.0, 4.5], [5.0, 5.5]]
    scans = scans_from_arrays(times, z, RADAR)
    # ids are input positions; within a scan detections keep input order
    assert _summary(scans) == [
        (0.0, "radar", [[2.0, 2.5], [5.0, 5.5]], [1, 4]),
        (1.0, "radar", [[4.0, 4.5]], [3]),
        (2.0, "radar", [[1.0, 1.5], [3.0, 3.5]], [0, 2]),
    ]
    assert all(s.detections.dtype == np.float64 for s in scans)


def test_arrays_with_ids_sensor_names_and_scan_times() -> None:
    scans = scans_from_arrays(
        np.array([1.0, 1.0, 0.0]),
        np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]]),
        TWO_2D,
        sensor_names=["sonar", "radar", "sonar"],
        ids=np.array([10, 0, 7]),
        scan_times={"radar": [0.0, 3.0], "sonar": [1.0]},
    )
    # sorted by (time, sensor name), not by mapping order; listed scans without
    # detections are empty, listed scans with detections are not duplicated
    assert _summary(scans) == [
        (0.0, "radar", [], []),
        (0.0, "sonar", [[5.0, 6.0]], [7]),
        (1.0, "radar", [[3.0, 4.0]], [0]),
        (1.0, "sonar", [[1.0, 2.0]], [10]),
        (3.0, "radar", [], []),
    ]
    assert scans[0].detections.shape == (0, 2)


def test_arrays_scan_times_sequence_gives_every_sensor_a_scan() -> None:
    scans = scans_from_arrays(
        [0.5], [[1.0, 2.0]], TWO_2D, sensor_names="sonar", scan_times=[0.5, 1.5]
    )
    assert [(s.time, s.sensor, s.size) for s in scans] == [
        (0.5, "radar", 0),
        (0.5, "sonar", 1),
        (1.5, "radar", 0),
        (1.5, "sonar", 0),
    ]


def test_arrays_only_empty_scans() -> None:
    scans = scans_from_arrays(np.zeros(0), np.zeros((0, 2)), RADAR, scan_times=[1.0, 0.0])
    assert [(s.time, s.size) for s in scans] == [(0.0, 0), (1.0, 0)]


BAD_ARRAYS = [
    # (keyword arguments over the good ones, message fragment)
    ({"times": [0.0, 1.0]}, r"measurements must have shape \(2, dz\).*got shape \(3, 2\)"),
    ({"times": [[0.0, 1.0, 2.0]]}, r"times must have shape \(k,\), got shape \(1, 3\)"),
    ({"times": [0.0, np.inf, 1.0]}, r"times\[1\] is inf; expected a finite time"),
    ({"times": ["a", "b", "c"]}, "times must hold numbers, got dtype <U1"),
    ({"measurements": [0.0, 1.0, 2.0]}, r"reshape\(-1, 1\)"),
    ({"measurements": [[0, 1], [2, np.nan], [4, 5]]}, r"measurements\[1, 1\] is nan"),
    ({"measurements": [[0, 1, 9], [2, 3, 9], [4, 5, 9]]}, "3 columns, but sensor 'radar'"),
    ({"sensor_names": ["radar", "lidar", "radar"]}, r"sensor_names\[1\] is 'lidar'"),
    ({"sensor_names": ["radar"]}, r"sequence of 3 names .*got shape \(1,\)"),
    ({"sensor_names": "lidar"}, "sensor_names is 'lidar'; expected one of"),
    ({"ids": [0, 1]}, r"ids must have shape \(3,\), got shape \(2,\)"),
    ({"ids": [0.0, 1.0, 2.0]}, "ids must be integers, got dtype float64"),
    ({"ids": [0, -4, 2]}, r"ids\[1\] is -4; expected an integer >= 0"),
    ({"ids": [5, 6, 5]}, r"ids\[2\] is 5, as is ids\[0\]; expected distinct ids"),
    ({"scan_times": {"lidar": [0.0]}}, "scan_times has the key 'lidar'"),
    ({"scan_times": [np.nan]}, r"scan_times\[0\] is nan"),
]


@pytest.mark.parametrize(("change", "fragment"), BAD_ARRAYS)
def test_bad_arrays(change: dict[str, object], fragment: str) -> None:
    arguments: dict[str, object] = {
        "times": [0.0, 1.0, 2.0],
        "measurements": [[0.0, 1.0], [2.0, 3.0], [4.0, 5.0]],
        "sensors": RADAR,
        **change,
    }
    with pytest.raises(InputError, match=fragment):
        scans_from_arrays(**arguments)  # type: ignore[arg-type]


def test_arrays_need_sensor_names_with_several_sensors_and_some_scan() -> None:
    with pytest.raises(InputError, match="sensor_names is required: 2 sensors"):
        scans_from_arrays([0.0], [[1.0, 2.0]], TWO_2D)
    with pytest.raises(InputError, match="no detections and no scan_times"):
        scans_from_arrays(np.zeros(0), np.zeros((0, 2)), RADAR)
    two_dims = {"radar": _position("radar"), "lidar": _position("lidar", ndim=3)}
    with pytest.raises(InputError, match=r"sensor 'lidar' \(detection 1\) measures 3 .*frame"):
        scans_from_arrays([0.0, 1.0], [[1.0, 2.0]] * 2, two_dims, sensor_names=["radar", "lidar"])


def test_ids_from_zero_run_through_the_estimator() -> None:
    # One target moving at unit speed, no clutter: the track uses every detection, so the
    # table the run ends with holds ids 0 and 1 (refused before ids were opaque).
    config = make_config(
        motion=ConstantVelocity(ndim=1, noise_intensity=0.01),
        noise_std=0.1,
        detection_probability=0.9,
        false_alarms_per_scan=0.01,
        region=[[-10.0, 10.0]],
        initial_count=1.0,
        velocity_std=2.0,
    )
    scans = scans_from_arrays([0.0, 1.0, 2.0, 3.0], [[0.0], [1.0], [2.0], [3.0]], config.sensors)
    result = WindowEstimator(config=config).run(scans)
    assert sorted(result.tracks.detection_rows.tolist()) == [0, 1, 2, 3]


# ------------------------------------------------------------------------ DataFrame


def _frame(**columns: object) -> pd.DataFrame:
    return pd.DataFrame(columns)


NAN = np.nan


def test_frame_golden_with_empty_scans_and_two_sensors() -> None:
    frame = _frame(
        time=[1.0, 0.0, 0.0, 1.0, 2.0],
        sensor=["radar", "esm", "radar", "radar", "esm"],
        x=[1.0, NAN, 3.0, NAN, NAN],
        y=[2.0, NAN, 4.0, NAN, NAN],
        range=[NAN, 50.0, NAN, NAN, NAN],
        bearing=[NAN, 0.25, NAN, NAN, NAN],
    )
    # row 3 is not an empty scan: time 1 of the radar has row 0, so it is refused below;
    # drop it here
    scans = scans_from_frame(frame.drop(index=3), MIXED)
    assert _summary(scans) == [
        (0.0, "esm", [[50.0, 0.25]], [1]),
        (0.0, "radar", [[3.0, 4.0]], [2]),
        (1.0, "radar", [[1.0, 2.0]], [0]),
        (2.0, "esm", [], []),  # row position 3 (after the drop): an empty scan uses it up
    ]
    with pytest.raises(InputError, match=r"row 3 .*which has detections \(row 0\)"):
        scans_from_frame(frame, MIXED)


def test_frame_detection_id_column_and_missing_sensor_column() -> None:
    frame = _frame(
        x=[1.0, 2.0, None],
        y=[1.5, 2.5, None],
        time=[0.0, 0.0, 1.0],
        detection_id=[40, 0, None],  # float with NaN: whole numbers are ids
    )
    scans = scans_from_frame(frame, RADAR)
    assert _summary(scans) == [
        (0.0, "radar", [[1.0, 1.5], [2.0, 2.5]], [40, 0]),
        (1.0, "radar", [], []),
    ]
    nullable = frame.assign(detection_id=pd.array([40, 0, None], dtype="Int64"))
    assert _summary(scans_from_frame(nullable, RADAR)) == _summary(scans)


def test_frame_of_a_csv_file_equals_the_csv_reader_up_to_the_id_offset(tmp_path: Path) -> None:
    scenario = build_scenario("two_sensors", 0)
    sensors = scenario.config.sensors
    scans = list(scenario.scans[:12])
    scans[3] = Scan(scans[3].time, scans[3].sensor, np.zeros((0, 2)), np.zeros(0))
    path = tmp_path / "detections.csv"
    write_detections(path, number_rows(scans), sensors)
    from_csv = read_detections(path, sensors)
    from_frame = scans_from_frame(pd.read_csv(path), sensors)
    assert len(from_frame) == len(from_csv) == 12 and from_frame[3].size == 0
    for got, want in zip(from_frame, from_csv, strict=True):
        assert (got.time, got.sensor) == (want.time, want.sensor)
        assert got.detections.tobytes() == want.detections.tobytes()
        # frame ids are 0-based row positions, CSV ids line numbers: header + 1 apart
        assert np.array_equal(got.rows + 2, want.rows)


GOOD = {
    "time": [0.0, 1.0],
    "sensor": ["radar", "esm"],
    "x": [1.0, NAN],
    "y": [2.0, NAN],
    "range": [NAN, 5.0],
    "bearing": [NAN, 0.5],
}
BAD_FRAMES = [
    # (columns over GOOD, row, column, message fragment)
    ({"time": [0.0, NAN]}, 1, "time", "empty cell; expected a finite time"),
    ({"time": [0.0, -np.inf]}, 1, "time", "value -inf is not finite"),
    ({"time": ["0", "1"]}, None, "time", "dtype"),
    ({"sensor": ["radar", "lidar"]}, 1, "sensor", "unknown sensor 'lidar'"),
    ({"sensor": ["radar", None]}, 1, "sensor", "empty cell; expected one of"),
    ({"x": [1.0, 3.0]}, 1, "x", "value 3.0 in a column sensor 'esm' does not measure"),
    ({"y": [NAN, NAN]}, 0, "y", "sensor 'radar' needs all of x,y"),
    ({"x": [np.inf, NAN]}, 0, "x", "value inf is not finite"),
    ({"x": [True, False]}, None, "x", "dtype bool"),
    ({"detection_id": [3, 3]}, 1, "detection_id", "id 3 already names the detection at row 0"),
    ({"detection_id": [-1, 2]}, 0, "detection_id", "detection id -1 is negative"),
    ({"detection_id": [0.5, 2.0]}, 0, "detection_id", "0.5 is not a whole number"),
    ({"detection_id": [0, None]}, 1, "detection_id", "empty cell on a detection"),
    ({"detection_id": ["a", "b"]}, None, "detection_id", "expected integer detection ids"),
    ({"z": [1.0, 2.0]}, None, "z", "unknown column 'z'"),
]


@pytest.mark.parametrize(("change", "row", "column", "fragment"), BAD_FRAMES)
def test_bad_frames(change: dict[str, object], row: int | None, column: str, fragment: str) -> None:
    with pytest.raises(InputError) as info:
        scans_from_frame(_frame(**{**GOOD, **change}), MIXED)
    message = str(info.value)
    where = "frame" + (f" row {row} (0-based position)" if row is not None else "")
    assert message.startswith(f"{where}, column {column!r}: "), message
    assert fragment in message


def test_frame_empty_scan_rules() -> None:
    empty_twice = _frame(time=[1.0, 1.0], x=[NAN, NAN], y=[NAN, NAN])
    with pytest.raises(InputError, match=r"row 1 .*declared empty at row 0"):
        scans_from_frame(empty_twice, RADAR)
    id_on_empty = _frame(time=[1.0], x=[NAN], y=[NAN], detection_id=[4])
    with pytest.raises(InputError, match="detection id 4 on a row without measurements"):
        scans_from_frame(id_on_empty, RADAR)


def test_frame_columns_and_argument_checks() -> None:
    with pytest.raises(InputError, match="no 'sensor' column, but 2 sensors"):
        scans_from_frame(_frame(time=[0.0], x=[1.0], y=[1.0], range=[NAN], bearing=[NAN]), MIXED)
    with pytest.raises(InputError, match="no column 'range', which sensor 'esm' measures"):
        scans_from_frame(_frame(time=[0.0], sensor=["radar"], x=[1.0], y=[1.0]), MIXED)
    with pytest.raises(InputError, match="no 'time' column"):
        scans_from_frame(_frame(x=[1.0], y=[1.0]), RADAR)
    twice = pd.DataFrame([[0.0, 1.0, 2.0]], columns=["time", "x", "x"])
    with pytest.raises(InputError, match="column 'x' appears twice"):
        scans_from_frame(twice, RADAR)
    with pytest.raises(InputError, match=r"frame: no rows; a scan without detections is a row"):
        scans_from_frame(_frame(time=[], x=[], y=[]), RADAR)
    with pytest.raises(InputError, match="frame must be a pandas DataFrame, got dict"):
        scans_from_frame(GOOD, MIXED)  # type: ignore[arg-type]
