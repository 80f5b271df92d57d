"""The one ingest path: every detections reader gives the same scans and the same verdicts.

The same detections table is read as a CSV file, a Parquet file (when pyarrow is
installed), a DataFrame and arrays; the scans must agree exactly (times, sensors, values
bit for bit, ids), and a defect of the table must get the same message from each reader,
only the place (line, row) named in the reader's own terms.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mapassoc.data.ingest import DETECTION_ID
from mapassoc.data.io import read_detections
from mapassoc.data.scans import Scan
from mapassoc.data.tables import scans_from_arrays, scans_from_frame
from mapassoc.errors import DataFileError, InputError
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.sensor import Region, Sensor

MOTION = ConstantVelocity(ndim=2, noise_intensity=1.0)
SENSORS = {
    "radar": Sensor(
        name="radar",
        measurement=LinearMeasurement.position(MOTION, noise_std=1.0),
        detection_probability=0.9,
        false_alarms_per_scan=1.0,
        region=Region.from_bounds([[-10.0, 10.0]] * 2),
    ),
    "esm": Sensor(
        name="esm",
        measurement=RangeBearing(sensor_position=[0.0, 0.0], range_std=1.0, bearing_std=0.01),
        detection_probability=0.9,
        false_alarms_per_scan=1.0,
        region=Region.from_bounds([[0.0, 100.0], [-np.pi, np.pi]]),
    ),
}
HEADER = "time,sensor,x,y,range,bearing,detection_id"
# times non-decreasing (the CSV rule), -0.0 and 0.0 one time, an empty radar scan at 2
LINES = [
    "-0.0,radar,1.5,-2.0,,,10",
    "0.0,esm,,,120.0,0.7853981633974483,3",
    "0.0,radar,0.1,1e-05,,,0",
    "1.0,radar,3.0,4.0,,,7",
    "2.0,radar,,,,,",
    "2.5,esm,,,5.5,-0.25,8",
]
PYARROW = importlib.util.find_spec("pyarrow") is not None


def _summary(scans: list[Scan]) -> list[tuple[float, str, bytes, list[int]]]:
    return [(s.time, s.sensor, s.detections.tobytes(), s.rows.tolist()) for s in scans]


def _frame(lines: list[str]) -> pd.DataFrame:
    rows = [line.split(",") for line in lines]
    frame = pd.DataFrame(rows, columns=HEADER.split(","))
    for name in ("time", "x", "y", "range", "bearing"):
        frame[name] = pd.to_numeric(frame[name].replace("", None))
    frame[DETECTION_ID] = pd.to_numeric(frame[DETECTION_ID].replace("", None)).astype("Int64")
    return frame


def _csv(tmp_path: Path, lines: list[str]) -> Path:
    path = tmp_path / "detections.csv"
    path.write_text("\n".join([HEADER, *lines]) + "\n")
    return path


def _parquet(tmp_path: Path, lines: list[str]) -> Path:
    path = tmp_path / "detections.parquet"
    _frame(lines).to_parquet(path, index=False)
    return path


def test_every_reader_gives_the_same_scans(tmp_path: Path) -> None:
    from_csv = read_detections(_csv(tmp_path, LINES), SENSORS)
    assert [(s.time, s.sensor, s.rows.tolist()) for s in from_csv] == [
        (0.0, "esm", [3]),
        (0.0, "radar", [10, 0]),  # row order within a scan, whatever the ids
        (1.0, "radar", [7]),
        (2.0, "radar", []),
        (2.5, "esm", [8]),
    ]
    assert from_csv[1].detections.tolist() == [[1.5, -2.0], [0.1, 1e-05]]
    assert _summary(scans_from_frame(_frame(LINES), SENSORS)) == _summary(from_csv)
    detections = [line.split(",") for line in LINES if line.split(",")[2:6] != [""] * 4]
    values = [[float(c) for c in cells[2:6] if c] for cells in detections]
    # arrays need one measurement dimension per call: both sensors measure two here
    from_arrays = scans_from_arrays(
        [float(cells[0]) for cells in detections],
        values,
        SENSORS,
        sensor_names=[cells[1] for cells in detections],
        ids=[int(cells[6]) for cells in detections],
        scan_times={"radar": [2.0]},
    )
    assert _summary(from_arrays) == _summary(from_csv)
    if PYARROW:
        from mapassoc.data.parquet import read_detections_parquet

        from_parquet = read_detections_parquet(_parquet(tmp_path, LINES), SENSORS)
        assert _summary(from_parquet) == _summary(from_csv)


def test_without_an_id_column_a_csv_numbers_by_line_and_a_frame_by_position(
    tmp_path: Path,
) -> None:
    lines = [line.rsplit(",", 1)[0] for line in LINES]
    path = tmp_path / "plain.csv"
    path.write_text("\n".join([HEADER.rsplit(",", 1)[0], *lines]) + "\n")
    from_csv = read_detections(path, SENSORS)
    from_frame = scans_from_frame(_frame(LINES).drop(columns=DETECTION_ID), SENSORS)
    assert [s.rows.tolist() for s in from_csv] == [[3], [2, 4], [5], [], [7]]
    assert [s.rows.tolist() for s in from_frame] == [[1], [0, 2], [3], [], [5]]
    assert _summary(from_frame) != _summary(from_csv)  # the ids differ, nothing else:
    assert [(s.time, s.sensor, s.detections.tobytes()) for s in from_frame] == [
        (s.time, s.sensor, s.detections.tobytes()) for s in from_csv
    ]


DEFECTS = [
    # (lines, 0-based row of the defect, column, message common to every reader)
    (["0,radar,1,,,,1"], 0, "y", "empty cell; sensor 'radar' needs all of x,y"),
    (["0,radar,1,2,5,,1"], 0, "range", "in a column sensor 'radar' does not measure"),
    (["0,sonar,1,2,,,1"], 0, "sensor", "unknown sensor 'sonar'; expected one of"),
    (["0,radar,1,2,,,1", "1,radar,1,2,,,1"], 1, DETECTION_ID, "already names the detection"),
    (["0,radar,1,2,,,"], 0, DETECTION_ID, "empty cell on a detection"),
    (["0,radar,,,,,", "0,radar,,,,,"], 1, "time", "was declared empty at"),
    (["0,radar,,,,,", "0,radar,1,2,,,1"], 0, "x", "which has detections"),
]


@pytest.mark.parametrize(("lines", "row", "column", "message"), DEFECTS)
def test_a_defect_gets_one_message_from_every_reader(
    tmp_path: Path, lines: list[str], row: int, column: str, message: str
) -> None:
    with pytest.raises(DataFileError) as from_csv:
        read_detections(_csv(tmp_path, lines), SENSORS)
    assert from_csv.value.row == row + 2 and from_csv.value.column == column
    assert message in str(from_csv.value)
    with pytest.raises(InputError) as from_frame:
        scans_from_frame(_frame(lines), SENSORS)
    assert f"frame row {row} (0-based position), column {column!r}: " in str(from_frame.value)
    assert message in str(from_frame.value)
    if PYARROW:
        from mapassoc.data.parquet import read_detections_parquet

        with pytest.raises(DataFileError) as from_parquet:
            read_detections_parquet(_parquet(tmp_path, lines), SENSORS)
        assert from_parquet.value.column == column and message in str(from_parquet.value)
