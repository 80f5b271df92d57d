"""Tests of mapassoc.data.parquet: exact round trips, ids, empty scans, named errors."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mapassoc.data.io import (
    TrackTable,
    TruthTable,
    number_rows,
    read_detections,
    write_detections,
)
from mapassoc.data.parquet import (
    read_detections_parquet,
    read_tracks_parquet,
    read_truth_parquet,
    write_detections_parquet,
    write_tracks_parquet,
    write_truth_parquet,
)
from mapassoc.data.scans import Scan
from mapassoc.errors import DataFileError, InputError
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.sensor import Region, Sensor


@pytest.fixture(scope="module")
def pa() -> Any:
    return pytest.importorskip("pyarrow")


def _sensor(name: str, ndim: int) -> Sensor:
    motion = ConstantVelocity(ndim=ndim, noise_intensity=1.0)
    return Sensor(
        name=name,
        measurement=LinearMeasurement.position(motion, noise_std=1.0),
        detection_probability=0.9,
        false_alarms_per_scan=1.0,
        region=Region.from_bounds([[-10.0, 10.0]] * ndim),
    )


SENSORS = {
    "esm": Sensor(
        name="esm",
        measurement=RangeBearing(sensor_position=[0.0, 0.0], range_std=1.0, bearing_std=0.01),
        detection_probability=0.9,
        false_alarms_per_scan=1.0,
        region=Region.from_bounds([[0.0, 100.0], [-np.pi, np.pi]]),
    ),
    "radar": _sensor("radar", 2),
    "lidar": _sensor("lidar", 3),
}
RADAR = {"radar": SENSORS["radar"]}
finite = st.floats(allow_nan=False, allow_infinity=False)


def _same_scans(got: list[Scan], want: list[Scan]) -> None:
    """Equal times (bitwise), sensors, detections (bitwise, dtype, shape) and ids."""
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        assert a.sensor == b.sensor
        assert np.float64(a.time).tobytes() == np.float64(b.time).tobytes()
        assert a.detections.shape == b.detections.shape
        assert a.detections.dtype == b.detections.dtype == np.float64
        assert a.detections.tobytes() == b.detections.tobytes()
        assert a.rows.dtype == np.int64 and np.array_equal(a.rows, b.rows)


def _empty(scan: Scan) -> Scan:
    dim = scan.detections.shape[1]
    return Scan(scan.time, scan.sensor, np.zeros((0, dim)), np.zeros(0, dtype=np.int64))


# ------------------------------------------------------------------------ detections


def test_csv_to_scans_to_parquet_to_scans_is_exact_on_a_scenario(pa: Any, tmp_path: Path) -> None:
    scenario = build_scenario("two_sensors", 0)
    sensors = scenario.config.sensors
    scans = list(scenario.scans)
    for k in (0, 5, 6, len(scans) - 1):  # empty scans of both sensors, first and last
        scans[k] = _empty(scans[k])
    csv_path = tmp_path / "detections.csv"
    write_detections(csv_path, number_rows(scans), sensors)
    from_csv = read_detections(csv_path, sensors)
    assert sum(scan.size == 0 for scan in from_csv) == 4
    parquet_path = tmp_path / "detections.parquet"
    write_detections_parquet(parquet_path, from_csv, sensors)
    _same_scans(read_detections_parquet(parquet_path, sensors), from_csv)
    # and the scans are the scenario's (number_rows gave the CSV's ids)
    _same_scans(from_csv, number_rows(scans))


@st.composite
def scan_lists(draw: st.DrawFn) -> list[Scan]:
    """Scans sorted by (time, sensor), some empty, with arbitrary distinct ids >= 0."""
    times = sorted(set(draw(st.lists(finite, min_size=1, max_size=4))))
    keys = []
    for time in times:
        names = draw(st.lists(st.sampled_from(sorted(SENSORS)), unique=True, min_size=1))
        keys.extend((time, name) for name in sorted(names))
    counts = [draw(st.integers(0, 3)) for _ in keys]
    ids = draw(
        st.lists(st.integers(0, 2**63 - 1), unique=True, min_size=sum(counts), max_size=sum(counts))
    )
    scans, start = [], 0
    for (time, name), count in zip(keys, counts, strict=True):
        dim = SENSORS[name].measurement.measurement_dim
        det = draw(arrays(np.float64, (count, dim), elements=finite))
        scans.append(Scan(time, name, det, np.array(ids[start : start + count], np.int64)))
        start += count
    return scans


@settings(max_examples=40, deadline=None)
@given(scans=scan_lists())
def test_detections_round_trip_is_exact_with_any_ids(
    pa: Any, tmp_path_factory: pytest.TempPathFactory, scans: list[Scan]
) -> None:
    path = tmp_path_factory.mktemp("rt") / "d.parquet"
    write_detections_parquet(path, scans, SENSORS)
    _same_scans(read_detections_parquet(path, SENSORS), scans)


def test_written_columns_and_nulls(pa: Any, tmp_path: Path) -> None:
    import pyarrow.parquet as pq

    scans = [
        Scan(0.0, "radar", np.array([[1.0, -0.0]]), np.array([5])),
        Scan(0.5, "esm", np.zeros((0, 2)), np.zeros(0)),
    ]
    path = tmp_path / "d.parquet"
    write_detections_parquet(path, scans, SENSORS)
    table = pq.read_table(path)
    assert table.column_names == ["time", "sensor", "range", "bearing", "x", "y", "z"] + [
        "detection_id"
    ]
    assert str(table.schema.field("x").type) == "double"
    assert str(table.schema.field("detection_id").type) == "int64"
    assert table.to_pydict() == {
        "time": [0.0, 0.5],
        "sensor": ["radar", "esm"],
        "range": [None, None],
        "bearing": [None, None],
        "x": [1.0, None],
        "y": [-0.0, None],
        "z": [None, None],
        "detection_id": [5, None],
    }


def _write_table(path: Path, columns: dict[str, Any]) -> str:
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table(columns), path)
    return str(path)


def test_without_detection_id_the_ids_are_row_indices_and_rows_may_be_unsorted(
    pa: Any, tmp_path: Path
) -> None:
    path = _write_table(
        tmp_path / "d.parquet",
        {
            "x": pa.array([1.0, None, 3.0, 4.0]),
            "y": pa.array([1.5, None, 3.5, 4.5]),
            "time": pa.array([2, 1, 0, 2], type=pa.int32()),  # integer times are read as floats
        },
    )
    scans = read_detections_parquet(path, RADAR)
    assert [(s.time, s.detections.tolist(), s.rows.tolist()) for s in scans] == [
        (0.0, [[3.0, 3.5]], [2]),
        (1.0, [], []),
        (2.0, [[1.0, 1.5], [4.0, 4.5]], [0, 3]),
    ]


def test_a_parquet_file_written_by_pandas_reads(pa: Any, tmp_path: Path) -> None:
    frame = pd.DataFrame(
        {
            "time": [0.0, 1.0, 1.0],
            "sensor": pd.Categorical(["radar", "radar", "esm"]),  # dictionary-encoded
            "x": [1.0, np.nan, np.nan],  # pandas writes NaN as null
            "y": [2.0, np.nan, np.nan],
            "range": [np.nan, np.nan, 9.0],
            "bearing": [np.nan, np.nan, 0.5],
            "z": [np.nan] * 3,
        },
        index=[10, 20, 30],  # written as an index column, which the reader ignores
    )
    path = tmp_path / "pandas.parquet"
    frame.to_parquet(path)
    scans = read_detections_parquet(path, {**SENSORS})
    assert [(s.time, s.sensor, s.rows.tolist()) for s in scans] == [
        (0.0, "radar", [0]),
        (1.0, "esm", [2]),
        (1.0, "radar", []),
    ]


GOOD_COLUMNS: dict[str, list[Any]] = {
    "time": [0.0, 1.0],
    "sensor": ["radar", "radar"],
    "x": [1.0, 2.0],
    "y": [1.0, 2.0],
}
BAD_PARQUET = [
    # (columns over GOOD_COLUMNS, column, row index, message fragment)
    ({"x": [1.0, float("nan")]}, "x", 1, "value nan is not finite"),
    ({"time": [0.0, float("nan")]}, "time", 1, "value nan is not finite"),
    ({"time": [0.0, None]}, "time", 1, "empty cell; expected a finite time"),
    ({"x": ["1", "2"]}, "x", None, "type string; expected float64"),
    ({"sensor": [1, 2]}, "sensor", None, "type int64; expected strings"),
    ({"sensor": ["radar", "sonar"]}, "sensor", 1, "unknown sensor 'sonar'"),
    ({"y": [1.0, None]}, "y", 1, "sensor 'radar' needs all of x,y"),
    ({"detection_id": [7, 7]}, "detection_id", 1, "id 7 already names the detection at row 0"),
    ({"detection_id": [0, -3]}, "detection_id", 1, "value -3 is below the minimum"),
    ({"detection_id": [0.0, 1.0]}, "detection_id", None, "type double; expected int64"),
    ({"w": [0.0, 1.0]}, "w", None, "unknown column 'w'"),
]


@pytest.mark.parametrize(("change", "column", "row", "fragment"), BAD_PARQUET)
def test_bad_detections_parquet(
    pa: Any,
    tmp_path: Path,
    change: dict[str, list[Any]],
    column: str,
    row: int | None,
    fragment: str,
) -> None:
    path = _write_table(tmp_path / "bad.parquet", {**GOOD_COLUMNS, **change})
    with pytest.raises(DataFileError) as info:
        read_detections_parquet(path, RADAR)
    error = info.value
    where = f"{path}, column '{column}': " + (
        f"row index {row} (0-based): " if row is not None else ""
    )
    assert error.path == path and error.column == column and error.row is None
    assert str(error).startswith(where), str(error)
    assert fragment in str(error)


def test_missing_column_no_rows_and_unreadable_files(pa: Any, tmp_path: Path) -> None:
    path = _write_table(tmp_path / "a.parquet", {"time": [0.0], "x": [1.0]})
    with pytest.raises(DataFileError, match=r"column 'y': no column 'y', which sensor 'radar'"):
        read_detections_parquet(path, RADAR)
    path = _write_table(
        tmp_path / "b.parquet",
        {"time": pa.array([], pa.float64()), "x": pa.array([], pa.float64()), "y": pa.array([])},
    )
    with pytest.raises(DataFileError, match=r"b\.parquet: no rows; a scan without detections"):
        read_detections_parquet(path, RADAR)
    text = tmp_path / "c.parquet"
    text.write_text("time,x,y\n0,1,2\n", encoding="utf-8")
    with pytest.raises(DataFileError, match=r"c\.parquet: not a readable Parquet file"):
        read_detections_parquet(text, RADAR)
    with pytest.raises(DataFileError, match=r"absent\.parquet: cannot read the file"):
        read_detections_parquet(tmp_path / "absent.parquet", RADAR)


def test_write_detections_parquet_refuses_what_cannot_be_read_back(pa: Any, tmp_path: Path) -> None:
    path = tmp_path / "out.parquet"
    first = Scan(0.0, "radar", np.array([[1.0, 2.0]]), np.array([3]))
    again = Scan(1.0, "radar", np.array([[1.0, 2.0]]), np.array([3]))
    with pytest.raises(InputError, match=r"detection ids \(Scan.rows\) \[3\] appear in more"):
        write_detections_parquet(path, [first, again], RADAR)
    with pytest.raises(InputError, match="scans is empty"):
        write_detections_parquet(path, [], RADAR)
    with pytest.raises(InputError, match="before the previous scan"):
        write_detections_parquet(path, [again, first], {"radar": SENSORS["radar"]})
    assert not path.exists()
    with pytest.raises(DataFileError, match="cannot write the file"):
        write_detections_parquet(tmp_path / "no" / "dir.parquet", [first], RADAR)


# ------------------------------------------------------------------------ tracks, truth


def _tracks(rows: list[int]) -> TrackTable:
    count = len(rows)
    rng = np.random.default_rng(1)
    return TrackTable(
        track_ids=np.arange(count) // 2,
        times=np.arange(count) * 0.1,
        sensors=tuple("radar" if k % 3 else "esm" for k in range(count)),
        states=rng.normal(size=(count, 4)),
        variances=rng.uniform(0.0, 2.0, size=(count, 4)),
        detection_rows=rows,
        state_names=("x", "y", "vx", "vy"),
    )


@pytest.mark.parametrize("rows", [[0, -1, 7, 2**62, -1], []])
def test_tracks_round_trip_is_exact(pa: Any, tmp_path: Path, rows: list[int]) -> None:
    table = _tracks(rows)
    path = tmp_path / "tracks.parquet"
    write_tracks_parquet(path, table)
    back = read_tracks_parquet(path)
    assert back.state_names == table.state_names and back.sensors == table.sensors
    assert np.array_equal(back.track_ids, table.track_ids)
    assert np.array_equal(back.detection_rows, table.detection_rows)  # misses stay -1
    for name in ("times", "states", "variances"):
        assert getattr(back, name).tobytes() == getattr(table, name).tobytes()


def test_bad_tracks_parquet(pa: Any, tmp_path: Path) -> None:
    good: dict[str, list[Any]] = {
        "track_id": [0, 0],
        "time": [0.0, 1.0],
        "sensor": ["radar", "radar"],
        "x": [1.0, 2.0],
        "var_x": [1.0, 1.0],
        "detection_row": [4, None],
    }
    cases = [
        ({"var_x": [1.0, -0.5]}, "var_x", "row index 1 (0-based): variance -0.5 is negative"),
        ({"x": [float("nan"), 2.0]}, "x", "row index 0 (0-based): value nan is not finite"),
        ({"time": [1.0, 1.0]}, "time", "(track_id, time, sensor) (0, 1.0, 'radar') already"),
        ({"detection_row": [-2, None]}, "detection_row", "value -2 is below the minimum"),
        ({"sensor": ["radar", None]}, "sensor", "empty cell; expected a sensor name"),
        ({"track_id": [0.0, 1.0]}, "track_id", "type double; expected int64"),
    ]
    for change, column, fragment in cases:
        path = _write_table(tmp_path / "t.parquet", {**good, **change})
        with pytest.raises(DataFileError) as info:
            read_tracks_parquet(path)
        assert info.value.column == column and fragment in str(info.value), str(info.value)
    layout = {k: v for k, v in good.items() if k != "var_x"}
    path = _write_table(tmp_path / "t.parquet", layout)
    with pytest.raises(DataFileError, match="1 state and variance columns"):
        read_tracks_parquet(path)


def test_truth_round_trip_and_errors(pa: Any, tmp_path: Path) -> None:
    table = TruthTable(
        target_ids=[3, 3, 0],
        times=[0.0, 1.0, -0.0],
        states=[[1.0, 2.5e-300], [-0.0, 3.0], [7.0, 1e300]],
        state_names=("x", "speed"),
    )
    path = tmp_path / "truth.parquet"
    write_truth_parquet(path, table)
    back = read_truth_parquet(path)
    assert back.state_names == ("x", "speed")
    assert back.target_ids.tolist() == [3, 3, 0]
    assert back.times.tobytes() == table.times.tobytes()
    assert back.states.tobytes() == table.states.tobytes()
    bad = _write_table(
        tmp_path / "t.parquet", {"target_id": [1, 1], "time": [0.0, 0.0], "x": [1, 2]}
    )
    with pytest.raises(DataFileError, match=r"row index 1 .*\(target_id, time\) \(1, 0.0\)"):
        read_truth_parquet(bad)
    bad = _write_table(tmp_path / "t.parquet", {"id": [1], "time": [0.0], "x": [1.0]})
    with pytest.raises(DataFileError, match="column 1 is 'id'; expected 'target_id'"):
        read_truth_parquet(bad)


# ------------------------------------------------------------------------ no pyarrow


def test_without_pyarrow_the_message_says_how_to_install_it(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    for name in ("pyarrow", "pyarrow.parquet", "pyarrow.compute"):
        monkeypatch.setitem(sys.modules, name, None)  # import raises ImportError
    path = tmp_path / "d.parquet"
    scan = Scan(0.0, "radar", np.zeros((0, 2)), np.zeros(0))
    expected = "reading Parquet needs pyarrow: pip install 'mapassoc[parquet]'"
    for read in (
        lambda: read_detections_parquet(path, RADAR),
        lambda: read_tracks_parquet(path),
        lambda: read_truth_parquet(path),
    ):
        with pytest.raises(InputError) as info:
            read()
        assert str(info.value) == expected
    with pytest.raises(InputError) as info:
        write_detections_parquet(path, [scan], RADAR)
    assert str(info.value) == "writing Parquet needs pyarrow: pip install 'mapassoc[parquet]'"
    assert not path.exists()


def test_origins_round_trip_with_false_alarms(tmp_path: Path, pa: Any) -> None:
    from mapassoc.data.formats import read_origins_file, write_origins_file
    from mapassoc.data.io import Origins

    scenario = build_scenario("crossing", 0)
    origins = scenario.origins
    assert np.any(origins.target_ids < 0)  # false alarms are in it
    for name in ("origins.parquet", "origins.csv"):
        write_origins_file(tmp_path / name, origins)
        back = read_origins_file(tmp_path / name)
        np.testing.assert_array_equal(back.rows, origins.rows)
        np.testing.assert_array_equal(back.target_ids, origins.target_ids)
    # Ids from 0 are fine; a repeated row is not.
    write_origins_file(tmp_path / "zero.parquet",
                       Origins(rows=np.array([0, 1]), target_ids=np.array([-1, 3])))
    assert read_origins_file(tmp_path / "zero.parquet").rows.tolist() == [0, 1]
    import pyarrow.parquet as pq

    pq.write_table(pa.table({"row": [4, 4], "target_id": [1, None]}), tmp_path / "rep.parquet")
    with pytest.raises(DataFileError, match="rep.parquet"):
        read_origins_file(tmp_path / "rep.parquet")
    pq.write_table(pa.table({"row": [4], "target": [1]}), tmp_path / "cols.parquet")
    with pytest.raises(DataFileError, match="expected row,target_id"):
        read_origins_file(tmp_path / "cols.parquet")
