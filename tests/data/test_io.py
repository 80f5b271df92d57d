"""Tests of mapassoc.data.io: exact round trips, golden files and every malformed-input case."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mapassoc.data.io import (
    Origins,
    TrackTable,
    TruthTable,
    number_rows,
    read_detections,
    read_origins,
    read_tracks,
    read_truth,
    write_detections,
    write_origins,
    write_tracks,
    write_truth,
)
from mapassoc.data.scans import Scan
from mapassoc.errors import DataFileError, InputError
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.sensor import Region, Sensor


def _sensor(name: str, kind: str) -> Sensor:
    if kind == "range_bearing":
        measurement = RangeBearing(sensor_position=[0.0, 0.0], range_std=1.0, bearing_std=0.01)
        region = Region.from_bounds([[0.0, 100.0], [-np.pi, np.pi]])
    else:
        ndim = 3 if kind == "xyz" else 2
        motion = ConstantVelocity(ndim=ndim, noise_intensity=1.0)
        measurement = LinearMeasurement.position(motion, noise_std=1.0)
        region = Region.from_bounds([[-10.0, 10.0]] * ndim)
    return Sensor(
        name=name,
        measurement=measurement,
        detection_probability=0.9,
        false_alarms_per_scan=1.0,
        region=region,
    )


# Component names differ between sensors: the union is range,bearing,x,y,z.
SENSORS = {
    "esm": _sensor("esm", "range_bearing"),
    "radar": _sensor("radar", "xy"),
    "lidar": _sensor("lidar", "xyz"),
}
RADAR_ONLY = {"radar": SENSORS["radar"]}
HEADER = "time,sensor,range,bearing,x,y,z"

finite = st.floats(allow_nan=False, allow_infinity=False)


def _same_float_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _scan(time: float, sensor: str, detections: list[list[float]], dim: int) -> Scan:
    det = np.array(detections, dtype=float).reshape(len(detections), dim)
    return Scan(time=time, sensor=sensor, detections=det, rows=np.arange(len(detections)))


def _write_text(directory: Path, text: str, name: str = "data.csv") -> str:
    path = directory / name
    path.write_text(text, encoding="utf-8")
    return str(path)


# ------------------------------------------------------------------------ detections


@st.composite
def scan_lists(draw: st.DrawFn) -> list[Scan]:
    """Scans sorted by (time, sensor), unique pairs, some empty, three kinds of sensor; at
    least one (a detections file holds at least one scan)."""
    times = sorted(set(draw(st.lists(finite, min_size=1, max_size=5))))
    scans = []
    for time in times:
        names = draw(st.lists(st.sampled_from(sorted(SENSORS)), unique=True, min_size=1))
        for name in sorted(names):
            dim = SENSORS[name].measurement.measurement_dim
            count = draw(st.integers(0, 3))
            det = draw(arrays(np.float64, (count, dim), elements=finite))
            scans.append(Scan(time=time, sensor=name, detections=det, rows=np.arange(count)))
    return scans


@settings(max_examples=60, deadline=None)
@given(scan_lists())
def test_detections_round_trip_is_exact(scans: list[Scan]) -> None:
    numbered = number_rows(scans)
    with tempfile.TemporaryDirectory() as directory:
        path = os.path.join(directory, "detections.csv")
        write_detections(path, numbered, SENSORS)
        back = read_detections(path, SENSORS)
        with open(path, encoding="utf-8") as handle:
            lines = handle.read().splitlines()
    assert len(back) == len(numbered)
    for got, want in zip(back, numbered, strict=True):
        assert got.sensor == want.sensor
        assert np.float64(got.time).tobytes() == np.float64(want.time).tobytes()
        assert _same_float_bits(got.detections, want.detections)
        assert np.array_equal(got.rows, want.rows)
        # rows are real line numbers: the line at each row holds that detection's sensor
        for row in got.rows.tolist():
            assert lines[row - 1].split(",")[1] == got.sensor
    # one line per detection, one per empty scan, plus the header
    assert len(lines) == 1 + sum(max(scan.size, 1) for scan in scans)


def test_number_rows_golden() -> None:
    scans = [
        _scan(0.0, "radar", [[1.0, 2.0], [3.0, 4.0]], 2),
        _scan(0.0, "esm", [], 2),
        _scan(1.0, "radar", [[5.0, 6.0]], 2),
    ]
    numbered = number_rows(scans)
    assert [s.rows.tolist() for s in numbered] == [[2, 3], [], [5]]
    assert [s.sensor for s in numbered] == ["radar", "esm", "radar"]
    assert all(
        np.array_equal(a.detections, b.detections) for a, b in zip(scans, numbered, strict=True)
    )


def test_write_detections_golden_text(tmp_path: Path) -> None:
    scans = [
        _scan(0.0, "radar", [[1.5, -2.0], [0.1, 1e-05]], 2),
        _scan(0.0, "esm", [[120.0, 0.7853981633974483]], 2),
        _scan(0.5, "lidar", [[1.0, 2.0, -0.0]], 3),
        _scan(1.0, "radar", [], 2),
    ]
    path = tmp_path / "d.csv"
    write_detections(path, number_rows(scans), SENSORS)  # ids = lines: no id column
    assert path.read_text(encoding="utf-8") == (
        f"{HEADER}\n"
        "0.0,radar,,,1.5,-2.0,\n"
        "0.0,radar,,,0.1,1e-05,\n"
        "0.0,esm,120.0,0.7853981633974483,,,\n"
        "0.5,lidar,,,1.0,2.0,-0.0\n"
        "1.0,radar,,,,,\n"
    )
    back = read_detections(path, SENSORS)
    # sorted by (time, sensor name): esm before radar at time 0
    assert [(s.time, s.sensor, s.rows.tolist()) for s in back] == [
        (0.0, "esm", [4]),
        (0.0, "radar", [2, 3]),
        (0.5, "lidar", [5]),
        (1.0, "radar", []),
    ]
    assert back[1].detections.tolist() == [[1.5, -2.0], [0.1, 1e-05]]
    assert back[3].detections.shape == (0, 2)
    assert np.signbit(back[2].detections[0, 2])


def test_ids_other_than_the_line_numbers_are_written_and_read_back(tmp_path: Path) -> None:
    scans = [
        Scan(0.0, "radar", np.array([[1.5, -2.0], [0.1, 1e-05]]), np.array([10, 0])),
        Scan(0.0, "esm", np.zeros((0, 2)), np.zeros(0, dtype=np.int64)),
        Scan(1.0, "radar", np.array([[5.0, 6.0]]), np.array([7])),
    ]
    path = tmp_path / "ids.csv"
    write_detections(path, scans, SENSORS)
    assert path.read_text(encoding="utf-8") == (
        f"{HEADER},detection_id\n"
        "0.0,radar,,,1.5,-2.0,,10\n"
        "0.0,radar,,,0.1,1e-05,,0\n"
        "0.0,esm,,,,,,\n"
        "1.0,radar,,,5.0,6.0,,7\n"
    )
    back = read_detections(path, SENSORS)
    assert [(s.time, s.sensor, s.rows.tolist()) for s in back] == [
        (0.0, "esm", []),
        (0.0, "radar", [10, 0]),
        (1.0, "radar", [7]),
    ]


def test_single_sensor_without_sensor_column(tmp_path: Path) -> None:
    path = _write_text(tmp_path, "x,time,y\n1,0,2\n 3 , 0 , 4 \n,1,\n5,2,6\n")
    scans = read_detections(path, RADAR_ONLY)
    assert [(s.time, s.sensor, s.rows.tolist()) for s in scans] == [
        (0.0, "radar", [2, 3]),
        (1.0, "radar", []),
        (2.0, "radar", [5]),
    ]
    # columns reordered to the sensor's component order (x, y)
    assert scans[0].detections.tolist() == [[1.0, 2.0], [3.0, 4.0]]


def test_interleaved_sensors_at_equal_time_form_one_scan_each(tmp_path: Path) -> None:
    text = f"{HEADER}\n0,radar,,,1,1,\n0,esm,5,0.1,,,\n0,radar,,,2,2,\n"
    scans = read_detections(_write_text(tmp_path, text), SENSORS)
    assert [(s.sensor, s.rows.tolist()) for s in scans] == [("esm", [3]), ("radar", [2, 4])]


def test_byte_order_mark_is_ignored(tmp_path: Path) -> None:
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbftime,x,y\n0,1,2\n")
    (scan,) = read_detections(path, RADAR_ONLY)
    assert scan.rows.tolist() == [2]


def test_header_only_file_is_an_error_naming_the_file(tmp_path: Path) -> None:
    path = _write_text(tmp_path, f"{HEADER}\n", name="header_only.csv")
    with pytest.raises(DataFileError) as info:
        read_detections(path, SENSORS)
    message = str(info.value)
    assert info.value.path == path and message.startswith(path)
    assert "no detection lines after the header" in message
    assert "empty measurement cells" in message  # says how to write an empty scan


def test_a_single_empty_scan_is_a_valid_file(tmp_path: Path) -> None:
    (scan,) = read_detections(_write_text(tmp_path, f"{HEADER}\n2.5,radar,,,,,\n"), SENSORS)
    assert (scan.time, scan.sensor, scan.size, scan.detections.shape) == (2.5, "radar", 0, (0, 2))


BAD_DETECTIONS = [
    # (file text, line, column, text the message must contain)
    ("", 1, None, "empty"),
    ("0.0,radar,,,1,2,\n", 1, None, "not a header"),
    ("when,sensor,range,bearing,x,y,z\n", 1, "time", "no 'time' column"),
    ("time,sensor,range,bearing,x,y\n", 1, "z", "sensor 'lidar'"),
    (f"{HEADER},w\n", 1, "w", "unknown column 'w'"),
    ("time,sensor,x,time,y\n", 1, "time", "twice"),
    ("time,range,bearing,x,y,z\n", 1, "sensor", "3 sensors"),
    (f"{HEADER}\n0,sonar,,,1,2,\n", 2, "sensor", "unknown sensor 'sonar'"),
    (f"{HEADER}\n0,,,,1,2,\n", 2, "sensor", "unknown sensor ''"),
    (f"{HEADER}\n0,radar,,,abc,2,\n", 2, "x", "'abc' is not a number"),
    (f"{HEADER}\n0,radar,,,1_0,2,\n", 2, "x", "'1_0' is not a number"),
    (f"{HEADER}\n0,radar,,,1,nan,\n", 2, "y", "'nan' is not finite"),
    (f"{HEADER}\n0,radar,,,1,-inf,\n", 2, "y", "'-inf' is not finite"),
    (f"{HEADER}\n0,radar,,,1,1e999,\n", 2, "y", "'1e999' overflows"),
    (f"{HEADER}\nabc,radar,,,1,2,\n", 2, "time", "'abc' is not a number"),
    (f"{HEADER}\n,radar,,,1,2,\n", 2, "time", "empty cell"),
    (f"{HEADER}\n0,radar,,,1,,\n", 2, "y", "needs all of x,y"),
    (f"{HEADER}\n0,lidar,,,,2,3\n", 2, "x", "needs all of x,y,z"),
    (f"{HEADER}\n0,radar,5,,1,2,\n", 2, "range", "5.0 in a column sensor 'radar' does not"),
    (f"{HEADER}\n0,radar,,,1,2,7\n", 2, "z", "value 7.0"),
    (f"{HEADER}\n1,radar,,,1,2,\n0.5,radar,,,1,2,\n", 3, "time", "goes backwards: line 2"),
    (f"{HEADER}\n1,radar,,,1,2,\n1,esm,1,1,,,\n0,esm,1,1,,,\n", 4, "time", "backwards"),
    (f"{HEADER}\n0,radar,,,1,2,,9\n", 2, "z", "8 cells, expected 7"),
    (f"{HEADER}\n0,radar,,,1,2\n", 2, "z", "6 cells, expected 7"),
    (f"{HEADER}\n0,radar,,,1,2,\n\n1,radar,,,1,2,\n", 3, "time", "blank line"),
    # an empty-scan line and detections of the same scan: the empty line is named
    (f"{HEADER}\n0,radar,,,,,\n0,radar,,,1,2,\n", 2, "x", "which has detections (line 3)"),
    (f"{HEADER}\n0,radar,,,,,\n0,radar,,,,,\n", 3, "time", "declared empty at line 2"),
    (f"{HEADER}\n0,radar,,,1,2,\n0,radar,,,,,\n", 3, "x", "which has detections (line 2)"),
    # the optional detection_id column, as in Parquet files and DataFrames
    (f"{HEADER},detection_id\n0,radar,,,1,2,,\n", 2, "detection_id", "empty cell on a detection"),
    (f"{HEADER},detection_id\n0,radar,,,,,,4\n", 2, "detection_id", "without measurements"),
    (f"{HEADER},detection_id\n0,radar,,,1,2,,-4\n", 2, "detection_id", "below the minimum"),
    (f"{HEADER},detection_id\n0,radar,,,1,2,,x\n", 2, "detection_id", "not an integer"),
    # ids are int64: 2^63 and 2^70 once ended in an OverflowError traceback
    (f"{HEADER},detection_id\n0,radar,,,1,2,,{2**63}\n", 2, "detection_id", "too large"),
    (f"{HEADER},detection_id\n0,radar,,,1,2,,{2**70}\n", 2, "detection_id", "to 2^63 - 1"),
    (f"{HEADER},detection_id\n0,radar,,,1,2,,{'9' * 5000}\n", 2, "detection_id", "too large"),
    (f"{HEADER},detection_id\n0,radar,,,1,2,,-{'9' * 5000}\n", 2, "detection_id", "below"),
    (
        f"{HEADER},detection_id\n0,radar,,,1,2,,7\n1,radar,,,1,2,,7\n",
        3,
        "detection_id",
        "already names the detection at line 2",
    ),
    (f'{HEADER}\n0,"radar,,,1,2,\n', 2, None, "malformed CSV"),
]


def test_the_largest_id_is_read(tmp_path: Path) -> None:
    """2^63 - 1 (int64's largest), leading zeros and all, is an id like any other."""
    text = f"{HEADER},detection_id\n0,radar,,,1,2,,{'0' * 30}{2**63 - 1}\n"
    (scan,) = read_detections(_write_text(tmp_path, text), SENSORS)
    assert scan.rows.tolist() == [2**63 - 1]


@pytest.mark.parametrize(("text", "line", "column", "fragment"), BAD_DETECTIONS)
def test_bad_detections_file(
    tmp_path: Path, text: str, line: int, column: str | None, fragment: str
) -> None:
    path = _write_text(tmp_path, text)
    with pytest.raises(DataFileError) as info:
        read_detections(path, SENSORS)
    err = info.value
    message = str(err)
    assert err.path == path and message.startswith(path)
    assert err.row == line and f"line {line}" in message
    assert err.column == column
    if column is not None:
        assert f"column '{column}'" in message
    assert fragment in message


def test_missing_file_is_a_data_file_error(tmp_path: Path) -> None:
    path = str(tmp_path / "absent.csv")
    with pytest.raises(DataFileError, match="cannot read") as info:
        read_detections(path, SENSORS)
    assert info.value.path == path


def test_non_utf8_file_is_a_data_file_error(tmp_path: Path) -> None:
    path = tmp_path / "latin1.csv"
    path.write_bytes(b"time,x,y\n0,1,2\n0,\xe9,2\n")
    with pytest.raises(DataFileError, match="not UTF-8") as info:
        read_detections(path, RADAR_ONLY)
    # the bad byte is on line 3, though the decoder fails before csv has read line 2
    assert info.value.path == str(path) and info.value.row == 3
    assert str(info.value).startswith(f"{path}, line 3: not UTF-8 text")
    assert "0xe9 at byte offset 17" in str(info.value)


@pytest.mark.parametrize(
    ("prefix", "newline", "line"),
    [
        (b"", b"\n", 5),
        (b"\xef\xbb\xbf", b"\n", 5),  # the byte-order mark is not a line
        (b"", b"\r\n", 5),  # \r\n is one line break
        (b"", b"\r", 5),  # old Mac line ends
    ],
)
def test_non_utf8_byte_is_reported_on_its_line(
    tmp_path: Path, prefix: bytes, newline: bytes, line: int
) -> None:
    lines = [b"time,x,y", b"0,1,2", b'1,"3",4', b"2,5,6", b"3,7,\xff8", b"4,9,10"]
    path = tmp_path / "bad.csv"
    path.write_bytes(prefix + newline.join(lines) + newline)
    with pytest.raises(DataFileError) as info:
        read_detections(path, RADAR_ONLY)
    assert info.value.row == line and f"line {line}: not UTF-8" in str(info.value)


def test_non_utf8_byte_far_down_a_large_file_is_reported_on_its_line(tmp_path: Path) -> None:
    # far beyond the text reader's decoding block, and after a quoted cell spanning two lines
    body = b"".join(b"%d,1,2\n" % t for t in range(20_000))
    path = tmp_path / "big.csv"
    path.write_bytes(b'time,x,y\n0,"1\n",2\n' + body + b"20000,\x80,2\n")
    with pytest.raises(DataFileError) as info:
        read_detections(path, RADAR_ONLY)
    assert info.value.row == 1 + 2 + 20_000 + 1


def test_write_detections_refuses_unreadable_input(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    radar = _scan(1.0, "radar", [[1.0, 2.0]], 2)
    with pytest.raises(InputError, match="before the previous scan"):
        write_detections(path, [radar, _scan(0.0, "esm", [], 2)], SENSORS)
    with pytest.raises(InputError, match="repeats sensor 'radar' at time 1.0"):
        write_detections(path, [radar, radar], SENSORS)
    with pytest.raises(InputError, match="measures 3 components"):
        write_detections(path, [_scan(0.0, "lidar", [[1.0, 2.0]], 2)], SENSORS)
    with pytest.raises(InputError, match="sensor 'sonar'"):
        write_detections(path, [_scan(0.0, "sonar", [[1.0, 2.0]], 2)], SENSORS)
    with pytest.raises(InputError, match="differs from the sensor's name"):
        write_detections(path, [radar], {"other": SENSORS["radar"]})
    assert not path.exists()
    with pytest.raises(InputError, match="scans is empty"):
        write_detections(path, [], SENSORS)
    assert not path.exists()


# ------------------------------------------------------------------------ truth


@st.composite
def truth_tables(draw: st.DrawFn) -> TruthTable:
    names = draw(st.sampled_from([("x",), ("x", "y", "vx", "vy"), ("x", "y", "z", "speed")]))
    keys = draw(st.lists(st.tuples(st.integers(0, 10**12), finite), unique=True, max_size=8))
    states = draw(arrays(np.float64, (len(keys), len(names)), elements=finite))
    return TruthTable(
        target_ids=np.array([k[0] for k in keys], dtype=np.int64),
        times=np.array([k[1] for k in keys], dtype=float),
        states=states,
        state_names=names,
    )


@settings(max_examples=40, deadline=None)
@given(truth_tables())
def test_truth_round_trip_is_exact(table: TruthTable) -> None:
    with tempfile.TemporaryDirectory() as directory:
        path = os.path.join(directory, "truth.csv")
        write_truth(path, table)
        back = read_truth(path)
    assert back.state_names == table.state_names
    assert np.array_equal(back.target_ids, table.target_ids)
    assert _same_float_bits(back.times, table.times)
    assert _same_float_bits(back.states, table.states)


def test_truth_golden_and_positions(tmp_path: Path) -> None:
    path = _write_text(tmp_path, "target_id,time,x,y,vx,vy\n7,0.0,1,2,3,4\n7,1.0,4,6,3,4\n")
    table = read_truth(path)
    assert table.size == 2 and table.target_ids.tolist() == [7, 7]
    assert table.positions().tolist() == [[1.0, 2.0], [4.0, 6.0]]
    assert table.positions(("y",)).tolist() == [[2.0], [6.0]]
    with pytest.raises(InputError, match="no position columns"):
        table.positions(("range",))


BAD_TRUTH = [
    ("id,time,x\n", 1, "target_id", "expected 'target_id'"),
    ("target_id\n", 1, "time", "expected 'time'"),
    ("target_id,time\n", 1, None, "no state columns"),
    ("target_id,time,x\n1.5,0,1\n", 2, "target_id", "'1.5' is not an integer"),
    ("target_id,time,x\n-2,0,1\n", 2, "target_id", "'-2' is below the minimum"),
    ("target_id,time,x\n1,0,inf\n", 2, "x", "not finite"),
    ("target_id,time,x\n1,0,1\n1,0.0,2\n", 3, "time", "already has a state at line 2"),
    ("target_id,time,x\n1,0\n", 2, "x", "2 cells, expected 3"),
]


@pytest.mark.parametrize(("text", "line", "column", "fragment"), BAD_TRUTH)
def test_bad_truth_file(
    tmp_path: Path, text: str, line: int, column: str | None, fragment: str
) -> None:
    path = _write_text(tmp_path, text)
    with pytest.raises(DataFileError) as info:
        read_truth(path)
    message = str(info.value)
    assert message.startswith(path) and f"line {line}" in message and fragment in message
    assert info.value.row == line and info.value.column == column
    if column is not None:
        assert f"column '{column}'" in message


def test_truth_table_validates() -> None:
    with pytest.raises(InputError, match="appears more than once"):
        TruthTable(target_ids=[1, 1], times=[0.0, 0.0], states=[[1.0], [2.0]], state_names=("x",))
    with pytest.raises(InputError, match="shape"):
        TruthTable(target_ids=[1], times=[0.0], states=[[1.0, 2.0]], state_names=("x",))
    with pytest.raises(InputError, match="integer array"):
        TruthTable(target_ids=[1.5], times=[0.0], states=[[1.0]], state_names=("x",))
    with pytest.raises(InputError, match="clashes"):
        TruthTable(target_ids=[1], times=[0.0], states=[[1.0]], state_names=("time",))


# ------------------------------------------------------------------------ origins


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 10**9), st.integers(-1, 10**9)),
        max_size=10,
        unique_by=lambda pair: pair[0],
    )
)
def test_origins_round_trip_is_exact(pairs: list[tuple[int, int]]) -> None:
    origins = Origins(
        rows=np.array([p[0] for p in pairs], dtype=np.int64),
        target_ids=np.array([p[1] for p in pairs], dtype=np.int64),
    )
    with tempfile.TemporaryDirectory() as directory:
        path = os.path.join(directory, "origins.csv")
        write_origins(path, origins)
        back = read_origins(path)
    assert np.array_equal(back.rows, origins.rows)
    assert np.array_equal(back.target_ids, origins.target_ids)
    assert back.rows.dtype == np.int64 and back.target_ids.dtype == np.int64


def test_origins_golden(tmp_path: Path) -> None:
    path = tmp_path / "o.csv"
    write_origins(path, Origins(rows=[2, 3, 5], target_ids=[4, -1, 0]))
    assert path.read_text(encoding="utf-8") == "row,target_id\n2,4\n3,\n5,0\n"


def test_origins_accept_any_detection_id_from_zero() -> None:
    origins = Origins(rows=[0, 1, 7], target_ids=[3, -1, 3])
    assert origins.rows.tolist() == [0, 1, 7]
    with pytest.raises(InputError, match="rows must be detection ids >= 0, got the value -1"):
        Origins(rows=[0, -1], target_ids=[3, 3])


BAD_ORIGINS = [
    ("row,target\n", 1, "target", "expected row,target_id"),
    ("row,target_id\n-1,3\n", 2, "row", "'-1' is below the minimum"),
    ("row,target_id\n2,-1\n", 2, "target_id", "'-1' is below the minimum"),
    ("row,target_id\n2,x\n", 2, "target_id", "'x' is not an integer"),
    ("row,target_id\n2,1\n2,\n", 3, "row", "already has an origin at line 2"),
]


@pytest.mark.parametrize(("text", "line", "column", "fragment"), BAD_ORIGINS)
def test_bad_origins_file(tmp_path: Path, text: str, line: int, column: str, fragment: str) -> None:
    path = _write_text(tmp_path, text)
    with pytest.raises(DataFileError) as info:
        read_origins(path)
    message = str(info.value)
    assert message.startswith(path) and f"line {line}" in message
    assert f"column '{column}'" in message and fragment in message
    assert info.value.row == line and info.value.column == column


# ------------------------------------------------------------------------ tracks


@st.composite
def track_tables(draw: st.DrawFn) -> TrackTable:
    names = draw(
        st.sampled_from([("x", "y", "vx", "vy"), ("x", "y", "speed", "heading", "turn_rate")])
    )
    keys = draw(
        st.lists(
            st.tuples(st.integers(0, 1000), finite, st.sampled_from(["radar", "esm"])),
            unique=True,
            max_size=8,
        )
    )
    count, n = len(keys), len(names)
    return TrackTable(
        track_ids=np.array([k[0] for k in keys], dtype=np.int64),
        times=np.array([k[1] for k in keys], dtype=float),
        sensors=tuple(k[2] for k in keys),
        states=draw(arrays(np.float64, (count, n), elements=finite)),
        variances=draw(arrays(np.float64, (count, n), elements=finite.map(abs))),
        detection_rows=np.array(
            draw(
                st.lists(
                    st.one_of(st.just(-1), st.integers(0, 10**6)), min_size=count, max_size=count
                )
            ),
            dtype=np.int64,
        ),
        state_names=names,
    )


@settings(max_examples=40, deadline=None)
@given(track_tables())
def test_tracks_round_trip_is_exact(table: TrackTable) -> None:
    with tempfile.TemporaryDirectory() as directory:
        path = os.path.join(directory, "tracks.csv")
        write_tracks(path, table)
        back = read_tracks(path)
    assert back.state_names == table.state_names
    assert back.sensors == table.sensors
    assert np.array_equal(back.track_ids, table.track_ids)
    assert np.array_equal(back.detection_rows, table.detection_rows)
    assert _same_float_bits(back.times, table.times)
    assert _same_float_bits(back.states, table.states)
    assert _same_float_bits(back.variances, table.variances)


def test_tracks_golden(tmp_path: Path) -> None:
    table = TrackTable(
        track_ids=[0, 0],
        times=[0.0, 1.0],
        sensors=("radar", "radar"),
        states=[[1.0, 2.0, 0.5, 0.25], [1.5, 2.25, 0.5, 0.25]],
        variances=[[1.0, 1.0, 100.0, 100.0], [0.5, 0.5, 2.0, 2.0]],
        detection_rows=[2, -1],
        state_names=("x", "y", "vx", "vy"),
    )
    path = tmp_path / "t.csv"
    write_tracks(path, table)
    assert path.read_text(encoding="utf-8") == (
        "track_id,time,sensor,x,y,vx,vy,var_x,var_y,var_vx,var_vy,detection_row\n"
        "0,0.0,radar,1.0,2.0,0.5,0.25,1.0,1.0,100.0,100.0,2\n"
        "0,1.0,radar,1.5,2.25,0.5,0.25,0.5,0.5,2.0,2.0,\n"
    )
    back = read_tracks(path)
    assert back.positions().tolist() == [[1.0, 2.0], [1.5, 2.25]]
    assert back.detection_rows.tolist() == [2, -1]


TRACKS_HEADER = "track_id,time,sensor,x,y,var_x,var_y,detection_row"
BAD_TRACKS = [
    ("track_id,time,x,y,var_x,var_y,detection_row\n", 1, "sensor", "expected 'sensor'"),
    ("track_id,time,sensor,x,y,var_x,var_y\n", 1, "detection_row", "last column"),
    ("track_id,time,sensor,x,y,var_x,detection_row\n", 1, "var_x", "3 state and variance"),
    ("track_id,time,sensor,x,y,var_y,var_x,detection_row\n", 1, "var_y", "'var_x' was expected"),
    (f"{TRACKS_HEADER}\n0,0,radar,1,2,-1,1,2\n", 2, "var_x", "'-1' is negative"),
    (f"{TRACKS_HEADER}\n0,0,radar,1,2,1,1,-1\n", 2, "detection_row", "'-1' is below"),
    (f"{TRACKS_HEADER}\n0,0,,1,2,1,1,2\n", 2, "sensor", "expected a sensor name"),
    (f"{TRACKS_HEADER}\nx,0,radar,1,2,1,1,2\n", 2, "track_id", "'x' is not an integer"),
    (f"{TRACKS_HEADER}\n0,0,radar,1,2,1,1,\n0,0,radar,1,2,1,1,3\n", 3, "time", "line 2"),
]


@pytest.mark.parametrize(("text", "line", "column", "fragment"), BAD_TRACKS)
def test_bad_tracks_file(tmp_path: Path, text: str, line: int, column: str, fragment: str) -> None:
    path = _write_text(tmp_path, text)
    with pytest.raises(DataFileError) as info:
        read_tracks(path)
    message = str(info.value)
    assert message.startswith(path) and f"line {line}" in message
    assert f"column '{column}'" in message and fragment in message
    assert info.value.row == line and info.value.column == column


def test_track_table_validates() -> None:
    good = dict(
        track_ids=[0],
        times=[0.0],
        sensors=("radar",),
        states=[[1.0]],
        variances=[[1.0]],
        detection_rows=[2],
        state_names=("x",),
    )
    TrackTable(**good)
    with pytest.raises(InputError, match="variances must be >= 0"):
        TrackTable(**{**good, "variances": [[-1.0]]})
    with pytest.raises(InputError, match=r"detection_rows must be -1 \(a miss\) or a detection id"):
        TrackTable(**{**good, "detection_rows": [-2]})
    # any id >= 0 names a detection (Parquet and in-memory ids start at 0)
    assert TrackTable(**{**good, "detection_rows": [0]}).detection_rows.tolist() == [0]
    with pytest.raises(InputError, match="sensors must have 1 entries"):
        TrackTable(**{**good, "sensors": ("radar", "esm")})
    with pytest.raises(InputError, match="sensor name"):
        TrackTable(**{**good, "sensors": ("a,b",)})
