"""Data files: detections, truth, origins and tracks, as CSV.

The same tables as Parquet are in :mod:`mapassoc.data.parquet`; :mod:`mapassoc.data.formats`
picks the format by the file suffix; :mod:`mapassoc.data.tables` builds scans in memory.

Common rules
------------
* UTF-8 text (a leading byte-order mark is ignored on reading), comma separated, read and
  written with the standard :mod:`csv` module.
* Line 1 is the header naming the columns; every further line is one record.  Line numbers
  are 1-based, so the first data line is line 2.
* Detections are named by their detection id (``Scan.rows``; see :mod:`mapassoc.data.scans`):
  a unique non-negative int64 key.  In a detections CSV without a ``detection_id`` column
  (the usual case, and what :func:`write_detections` writes) a detection's id is its line
  number (so CSV ids start at 2).  The origins file (``row``) and the tracks
  file (``detection_row``) refer to detections by these ids; they accept any id >= 0, so
  that they also serve detections read from Parquet or built in memory, whose ids start
  at 0 (:mod:`mapassoc.data.parquet`, :mod:`mapassoc.data.tables`).
* Every line has exactly as many cells as the header.  Blank lines are errors.  Spaces
  around a cell are ignored.
* Floats are decimal numbers (``1``, ``-0.5``, ``2.5e-3``); writers use ``repr``, the
  shortest string that reads back to the same float, so write-then-read is exact (including
  ``-0.0``).  NaN and infinities are refused.  Integers are plain decimal digits.
* Every problem raises :class:`~mapassoc.errors.DataFileError` naming the file, the line,
  the column, the offending value and what was expected.

1. Detections file
------------------
Columns ``time``, ``sensor`` and the measurement components of the configured sensors
(``sensor.measurement.component_names``: ``x,y[,z]`` for a position sensor,
``range,bearing`` for a range-bearing sensor).  With several sensors the header holds the
union of their component names in first-sensor order, for example
``time,sensor,x,y,range,bearing``; each line fills the components of its own sensor and
leaves the other cells empty.  The ``sensor`` column may be left out when exactly one
sensor is configured.  An optional ``detection_id`` column holds the detection ids
(integers >= 0, distinct, empty on the lines of empty scans), as in a Parquet file.
Readers accept the columns in any order; writers always write ``time,sensor,<union>``.

One line per detection.  The lines with the same ``(sensor, time)`` form one scan.  A scan
without detections is one line with ``time`` and ``sensor`` and every measurement cell
empty (so that empty scans are not lost).  A file needs at least one line after the
header.  Times never decrease down the file (lines of different sensors may interleave at
equal times), so a scan cannot reappear once a later scan of its sensor has started.
:func:`read_detections` returns the scans sorted by ``(time, sensor name)``; ``Scan.rows``
holds the detection ids, which for this file are the line numbers of the scan's
detections unless a ``detection_id`` column gives them.  The rules a file shares with
every other source of detections (which cells a line fills, empty scans, ids) are
checked by the one ingest path, :mod:`mapassoc.data.ingest`; this reader checks the
text: cells, widths, and times that never decrease.

Example::

    time,sensor,x,y,range,bearing
    0.0,radar,1.5,-2.0,,
    0.0,radar,30.25,7.0,,
    0.0,esm,,,120.0,0.7853981633974483
    1.0,radar,,,,

2. Truth file
-------------
``target_id,time,<state names>``, state names from the motion model (``x,y,vx,vy`` for a
2-D constant-velocity model); one line per target per time.  Target ids are integers
>= 0; a (target, time) pair appears once.  Read into :class:`TruthTable`.

3. Origins file
---------------
``row,target_id``: for each detection id ``row`` (for a detections CSV file, the detection's
line), the id of the target that produced it, or an empty cell for a false alarm.  Read
into :class:`Origins` (false alarms get target id -1).

4. Tracks file
--------------
``track_id,time,sensor,<state names>,<var_ + state name, for each>,detection_row``: one line
per track per scan (``time``, ``sensor``) at which the track is alive; ``var_*`` are the
marginal variances (diagonal of the covariance); ``detection_row`` is the id of the
detection the track used at that scan (for a detections CSV file, its line), empty when
the track missed.  For a motion model that is a set of models (interacting multiple
models), optional columns ``p_<model name>`` follow ``detection_row``, one per model
(``p_constant_velocity_0,p_constant_velocity_1``: the names of
:attr:`~mapassoc.models.interacting.InteractingModels.model_names`), holding each line's
smoothed model probabilities: never empty, each in [0, 1], a line's summing to 1 within
1e-6.  An optional last column ``existence`` holds the track's existence probability
(empty where unknown); it stays last, after any model columns.  A file of one model has
no model columns, so its bytes are those it had before the columns existed, and a
reader that ignores unknown trailing columns still reads a set's file.  Read into
:class:`TrackTable`.

Example (a 1-D constant-velocity pair, refined tracks; the header is one line)::

    track_id,time,sensor,x,vx,var_x,var_vx,detection_row,
        p_constant_velocity_0,p_constant_velocity_1,existence
    0,0.0,radar,1.5,0.0,1.0,4.0,2,0.5,0.5,0.98
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TextIO

import numpy as np

from mapassoc.data.ingest import (
    DETECTION_ID,
    DetectionColumns,
    check_detection_columns,
    detection_columns_to_scans,
)
from mapassoc.data.records import (
    EXISTENCE_COLUMN,
    MODEL_PROBABILITY_PREFIX,
    MODEL_PROBABILITY_TOLERANCE,
    ORIGINS_COLUMNS,
    TRACK_FIXED_COLUMNS,
    TRACK_ROW_COLUMN,
    TRACKS_HEADER,
    TRUTH_FIXED_COLUMNS,
    TRUTH_HEADER,
    VARIANCE_PREFIX,
    Origins,
    TrackTable,
    TruthTable,
    check_scans_for_writing,
    check_sensors,
    measurement_columns,
    track_model_names,
    track_state_names,
    truth_state_names,
)
from mapassoc.data.scans import Scan
from mapassoc.errors import DataFileError, InputError
from mapassoc.models.sensor import Sensor
from mapassoc.validation import check_instance, check_path

__all__ = [
    "FIRST_DATA_LINE",
    "TruthTable",
    "Origins",
    "TrackTable",
    "read_detections",
    "read_cells",
    "write_detections",
    "number_rows",
    "read_truth",
    "write_truth",
    "read_origins",
    "write_origins",
    "read_tracks",
    "write_tracks",
    "ASSOCIATIONS_HEADER",
    "write_associations",
]

PathLike = str | os.PathLike[str]
FIRST_DATA_LINE = 2
"""Line number of the first record (line 1 is the header): the first detection id that
:func:`number_rows` and :func:`read_detections` give.  Other sources number detections from
0, and every table accepts any id >= 0."""


_FLOAT_PATTERN = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_INT_PATTERN = re.compile(r"[+-]?\d+")
_INT64_MAX = int(np.iinfo(np.int64).max)
"""The largest id a file may hold: ids are kept as int64 (2^63 - 1)."""
_NON_FINITE_WORDS = ("nan", "inf", "infinity")


# --------------------------------------------------------------------------- cells


def _float_cell(path: str, line: int, column: str, cell: str) -> float:
    """Parse one float cell or raise a DataFileError naming line, column and value."""
    if cell == "":
        raise DataFileError(path, "empty cell; expected a number", row=line, column=column)
    if _FLOAT_PATTERN.fullmatch(cell):
        value = float(cell)
        if math.isfinite(value):
            return value
        raise DataFileError(
            path,
            f"value {cell!r} overflows to infinity; expected a finite number",
            row=line,
            column=column,
        )
    if cell.lower().lstrip("+-") in _NON_FINITE_WORDS:
        raise DataFileError(
            path,
            f"value {cell!r} is not finite; expected a finite number",
            row=line,
            column=column,
        )
    raise DataFileError(
        path,
        f"value {cell!r} is not a number; expected a decimal number such as 1.5e-3",
        row=line,
        column=column,
    )


def _int_cell(path: str, line: int, column: str, cell: str, *, minimum: int) -> int:
    """Parse one integer cell >= ``minimum`` or raise a DataFileError."""
    if cell == "":
        raise DataFileError(
            path, f"empty cell; expected an integer >= {minimum}", row=line, column=column
        )
    if not _INT_PATTERN.fullmatch(cell):
        raise DataFileError(
            path,
            f"value {cell!r} is not an integer; expected an integer >= {minimum}",
            row=line,
            column=column,
        )
    digits = cell.lstrip("+-").lstrip("0")
    # int() refuses more than 4300 digits: a longer cell is out of range either way.
    value = int(cell) if len(digits) <= 20 else (-1 if cell[0] == "-" else _INT64_MAX + 1)
    if value < minimum:
        raise DataFileError(
            path,
            f"value {cell!r} is below the minimum; expected an integer >= {minimum}",
            row=line,
            column=column,
        )
    if value > _INT64_MAX:
        raise DataFileError(
            path,
            f"value {cell!r} is too large; expected an integer from {minimum} to 2^63 - 1 "
            f"= {_INT64_MAX} (ids are 64-bit)",
            row=line,
            column=column,
        )
    return value


def _float_text(value: float) -> str:
    """Shortest decimal string that reads back to exactly ``value``."""
    return repr(float(value))


# --------------------------------------------------------------------------- files


def _decode_error_line(path: str, fallback: int, content: bytes | None) -> tuple[int, str]:
    """Line number and description of the first byte of ``path`` that is not UTF-8.

    The text reader decodes ahead of the csv module in blocks, so the line it is at when
    decoding fails is not the line of the bad byte.  Only on that error path, this takes
    the whole file as bytes (``content`` when the caller read it already, else the file is
    read again: for a 100 MB file, about twice that in memory once, at the moment the read
    is failing anyway) and counts the line breaks before the bad byte: ``\\r\\n``,
    ``\\r`` and ``\\n``, the breaks the text reader recognises, so a quoted cell
    spanning lines counts them as the csv module's line numbers do.  ``fallback`` is
    returned if the bytes cannot be read again or now decode (the file changed).
    """
    data = content
    if data is None:
        try:
            with open(path, "rb") as handle:
                data = handle.read()
        except OSError:
            return fallback, "undecodable bytes"
    try:
        data.decode("utf-8")  # a leading byte-order mark is valid UTF-8
    except UnicodeDecodeError as exc:
        start = exc.start
        breaks = data.count(b"\n", 0, start) + data.count(b"\r", 0, start)
        breaks -= data.count(b"\r\n", 0, start)
        byte = data[start : start + 1].hex()
        return breaks + 1, f"{exc.reason}: byte 0x{byte} at byte offset {start}"
    return fallback, "undecodable bytes"


def _open_text(path: str, content: bytes | None) -> TextIO:
    """``path`` (or ``content``, its bytes read already) as UTF-8 text for :mod:`csv`."""
    if content is not None:
        return io.TextIOWrapper(io.BytesIO(content), encoding="utf-8-sig", newline="")
    return open(path, encoding="utf-8-sig", newline="")


def _lines(path: str, content: bytes | None = None) -> Iterator[tuple[int, list[str]]]:
    """Yield ``(line number, stripped cells)`` for every CSV line of ``path``.

    ``content``: the file's bytes, when the caller has read them (a stream such as a
    named pipe can be read only once); ``path`` then only names the file in errors.
    """
    try:
        with _open_text(path, content) as handle:
            reader = csv.reader(handle, strict=True)
            last_line = 0
            while True:
                try:
                    cells = next(reader)
                except StopIteration:
                    return
                except csv.Error as exc:
                    raise DataFileError(path, f"malformed CSV: {exc}", row=last_line + 1) from None
                except UnicodeDecodeError:
                    line, what = _decode_error_line(path, last_line + 1, content)
                    raise DataFileError(path, f"not UTF-8 text ({what})", row=line) from None
                line = last_line + 1
                last_line = reader.line_num
                yield line, [cell.strip() for cell in cells]
    except OSError as exc:
        raise DataFileError(path, f"cannot read the file: {exc.strerror or exc}") from None


def _read_header(path: str, lines: Iterator[tuple[int, list[str]]], expected: str) -> list[str]:
    """The header of a file: non-empty, distinct column names."""
    try:
        line, header = next(lines)
    except StopIteration:
        raise DataFileError(
            path, f"file is empty; expected a header line {expected}", row=1
        ) from None
    if not header or all(name == "" for name in header):
        raise DataFileError(path, f"header line is blank; expected {expected}", row=line)
    if any(_FLOAT_PATTERN.fullmatch(name) for name in header):
        raise DataFileError(
            path,
            f"line 1 holds data {','.join(header)}, not a header; expected {expected}",
            row=line,
        )
    seen: set[str] = set()
    for position, name in enumerate(header):
        if name == "":
            raise DataFileError(
                path, f"header cell {position + 1} is empty; expected {expected}", row=line
            )
        if name in seen:
            raise DataFileError(
                path, f"column {name!r} appears twice in the header", row=line, column=name
            )
        seen.add(name)
    return header


def _check_width(path: str, line: int, cells: list[str], header: list[str]) -> None:
    if len(cells) == len(header):
        return
    columns = ",".join(header)
    if len(cells) < len(header):
        missing = header[len(cells)]
        what = "blank line" if not cells else f"{len(cells)} cells"
        raise DataFileError(
            path,
            f"{what}, expected {len(header)} cells ({columns}); no cell for column {missing!r}",
            row=line,
            column=missing,
        )
    raise DataFileError(
        path,
        f"{len(cells)} cells, expected {len(header)} ({columns}); extra value "
        f"{cells[len(header)]!r} after the last column {header[-1]!r}",
        row=line,
        column=header[-1],
    )


def _write_rows(path: str, header: Sequence[str], rows: Iterator[list[str]]) -> None:
    try:
        with open(path, "w", encoding="utf-8", newline="") as handle:
            writer = csv.writer(handle, lineterminator="\n")
            writer.writerow(list(header))
            writer.writerows(rows)
    except OSError as exc:
        raise DataFileError(path, f"cannot write the file: {exc.strerror or exc}") from None


# --------------------------------------------------------------------------- detections


def read_detections(
    path: PathLike, sensors: Mapping[str, Sensor], *, content: bytes | None = None
) -> list[Scan]:
    """Read a detections file (format 1 of the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    sensors : mapping of str to Sensor
        Configured sensors by name (the order fixes the canonical column order).
    content : bytes, optional
        The file's bytes, read already (for instance while hashing it, or from a named
        pipe, which can be read only once); ``path`` then only names it in errors.

    Returns
    -------
    list of Scan
        Sorted by ``(time, sensor name)``, at least one; ``detections`` of shape ``(m, dz)``
        with the columns in the sensor's ``component_names`` order, ``rows`` the detection
        ids: the ``detection_id`` column if the file has one, else the line numbers (>= 2).

    Raises
    ------
    DataFileError
        Any malformed header, line or cell (see the module docstring), or no line after the
        header.
    InputError
        ``sensors`` is empty or inconsistent.
    """
    path = check_path("read_detections: path", path)
    if content is not None:
        check_instance("read_detections: content", content, bytes, expected="bytes (the file's)")
    union = measurement_columns(check_sensors(sensors))
    lines = _lines(path, content)
    header = _read_header(path, lines, "time,sensor," + ",".join(union))

    def header_fail(message: str, column: str | None, row: int | None) -> DataFileError:
        return DataFileError(path, message, row=1, column=column)

    check_detection_columns(header, sensors, header_fail)
    table = _detection_table(path, header, lines, union)
    line_numbers = table.row_ids
    assert line_numbers is not None

    # every cell a number where a number is due: the rest is the one ingest path's
    def fail(message: str, column: str | None, row: int | None) -> DataFileError:
        return DataFileError(
            path, message, row=1 if row is None else int(line_numbers[row]), column=column
        )

    def line_name(row: int) -> str:
        return f"line {line_numbers[row]}"

    return detection_columns_to_scans(table, sensors, fail, row_name=line_name)


def _detection_table(
    path: str, header: list[str], lines: Iterator[tuple[int, list[str]]], union: Sequence[str]
) -> DetectionColumns:
    """The detection lines after the header as columns (cells parsed, times checked)."""
    column_of = {name: index for index, name in enumerate(header)}
    time_column, sensor_column = column_of["time"], column_of.get("sensor")
    id_column = column_of.get(DETECTION_ID)
    measured = [(name, column_of[name]) for name in union]
    line_numbers: list[int] = []
    times: list[float] = []
    sensor_cells: list[str] = []
    values: dict[str, list[float]] = {name: [] for name in union}
    ids: list[int] = []
    for line, cells in lines:
        _check_width(path, line, cells, header)
        time = _float_cell(path, line, "time", cells[time_column])
        if times and time < times[-1]:
            raise DataFileError(
                path,
                f"time {cells[time_column]} goes backwards: line {line_numbers[-1]} has time "
                f"{times[-1]!r}; times must not decrease down the file",
                row=line,
                column="time",
            )
        line_numbers.append(line)
        times.append(time)
        if sensor_column is not None:
            sensor_cells.append(cells[sensor_column])
        for name, index in measured:
            cell = cells[index]
            values[name].append(math.nan if cell == "" else _float_cell(path, line, name, cell))
        if id_column is not None:
            cell = cells[id_column]
            ids.append(-1 if cell == "" else _int_cell(path, line, DETECTION_ID, cell, minimum=0))
    if not line_numbers:
        raise DataFileError(path, _NO_LINES)
    return _columns_of(header, times, sensor_cells if sensor_column is not None else None,
                       values, ids if id_column is not None else None, line_numbers)  # fmt: skip


_NO_LINES = (
    "no detection lines after the header; a scan without detections is a line with "
    "time and sensor and empty measurement cells"
)


def _columns_of(
    header: list[str],
    times: list[float],
    sensor_cells: list[str] | None,
    values: Mapping[str, list[float]],
    ids: list[int] | None,
    line_numbers: list[int],
) -> DetectionColumns:
    components = {}
    for name, cells in values.items():
        column = np.array(cells, dtype=np.float64)
        components[name] = (column, np.isnan(column))  # cells are finite or empty
    id_values = None if ids is None else np.array(ids, dtype=np.int64)
    return DetectionColumns(
        names=tuple(header),
        times=np.array(times, dtype=np.float64),
        time_null=np.zeros(len(times), dtype=bool),
        sensors=sensor_cells,
        components=components,
        ids=None if id_values is None else (id_values, id_values < 0),
        row_ids=np.array(line_numbers, dtype=np.int64),
    )


def read_cells(
    path: PathLike, content: bytes | None = None
) -> tuple[list[str], list[int], list[list[str]]]:
    """A CSV file as text: its header, the line number of each record and the columns.

    The file rules of the module docstring (UTF-8, a header of distinct names, every
    line as wide as the header, at least one record) are checked here; the cells are
    left as stripped text for a reader that parses them itself
    (:func:`mapassoc.data.recording.read_recording`).

    Returns
    -------
    header : list of str
    lines : list of int, length n
    columns : list of list of str, one per header name, each of length n
    """
    path = check_path("read_cells: path", path)
    lines = _lines(path, content)
    header = _read_header(path, lines, "time,sensor,<measurement columns>")
    numbers: list[int] = []
    columns: list[list[str]] = [[] for _ in header]
    for line, cells in lines:
        _check_width(path, line, cells, header)
        numbers.append(line)
        for column, cell in zip(columns, cells, strict=True):
            column.append(cell)
    if not numbers:
        raise DataFileError(path, _NO_LINES)
    return header, numbers, columns


def write_detections(path: PathLike, scans: Sequence[Scan], sensors: Mapping[str, Sensor]) -> None:
    """Write scans as a detections file (format 1 of the module docstring).

    Scans are written in the given order, one line per detection and one line per empty
    scan, always with the ``sensor`` column.  The detection ids (``Scan.rows``) survive
    the round trip: when they are the line numbers reading the file would give (scans
    from a CSV file, or after :func:`number_rows`) the file has no id column, as it
    always had; otherwise a last ``detection_id`` column holds them (empty on the lines
    of empty scans), as the Parquet writer keeps them.

    Parameters
    ----------
    path : str or os.PathLike
        The file (overwritten).
    scans : sequence of Scan
        At least one, in non-decreasing time, one scan per (sensor, time); ``detections``
        of shape ``(m, dz)`` with ``dz`` the sensor's measurement dimension.
    sensors : mapping of str to Sensor
        Configured sensors (fixes the column order: ``time,sensor,<component union>``).

    Raises
    ------
    InputError
        No scan, or a scan of an unknown sensor, of the wrong dimension, out of time order
        or repeated.
    DataFileError
        The file cannot be written.
    """
    path = check_path("write_detections: path", path)
    sensor_list = check_sensors(sensors)
    union = measurement_columns(sensor_list)
    check_scans_for_writing(scans, sensors)
    position_of = {name: index for index, name in enumerate(union)}
    with_ids = not _rows_are_line_numbers(scans)

    def rows() -> Iterator[list[str]]:
        for scan in scans:
            names = sensors[scan.sensor].measurement.component_names
            prefix = [_float_text(scan.time), scan.sensor]
            if scan.size == 0:
                yield prefix + [""] * (len(union) + with_ids)
                continue
            for detection, row in zip(scan.detections, scan.rows.tolist(), strict=True):
                cells = [""] * len(union)
                for name, value in zip(names, detection, strict=True):
                    cells[position_of[name]] = _float_text(value)
                yield prefix + cells + ([str(int(row))] if with_ids else [])

    header = ["time", "sensor", *union] + ([DETECTION_ID] if with_ids else [])
    _write_rows(path, header, rows())


def _rows_are_line_numbers(scans: Sequence[Scan]) -> bool:
    """Whether every detection id is the line number the detections file gives it."""
    line = FIRST_DATA_LINE
    for scan in scans:
        if scan.size == 0:
            line += 1
            continue
        expected = np.arange(line, line + scan.size, dtype=np.int64)
        if not np.array_equal(scan.rows, expected):
            return False
        line += scan.size
    return True


def number_rows(scans: Sequence[Scan]) -> list[Scan]:
    """Copies of ``scans`` whose ``rows`` are the ids reading the file that
    :func:`write_detections` writes gives them: their line numbers.

    Detections are numbered from line 2 (``FIRST_DATA_LINE``, after the header) in order; an
    empty scan uses one line and gets no id.

    Parameters
    ----------
    scans : sequence of Scan
        In the order they will be written.

    Returns
    -------
    list of Scan
        Same times, sensors and detections; ``rows`` of shape ``(m,)``.
    """
    numbered: list[Scan] = []
    next_line = FIRST_DATA_LINE
    for index, scan in enumerate(scans):
        if not isinstance(scan, Scan):
            raise InputError(f"scans[{index}] must be a Scan, got {scan!r}")
        rows = np.arange(next_line, next_line + scan.size, dtype=np.int64)
        next_line += max(scan.size, 1)
        numbered.append(
            Scan(time=scan.time, sensor=scan.sensor, detections=scan.detections, rows=rows)
        )
    return numbered


def write_truth(path: PathLike, table: TruthTable) -> None:
    """Write a truth file (format 2) in the table's record order.

    Parameters
    ----------
    path : str or os.PathLike
        The file (overwritten).
    table : TruthTable
    """
    path = check_path("write_truth: path", path)
    if not isinstance(table, TruthTable):
        raise InputError(f"table must be a TruthTable, got {table!r}")

    def rows() -> Iterator[list[str]]:
        for target, time, state in zip(
            table.target_ids.tolist(), table.times.tolist(), table.states, strict=True
        ):
            yield [str(target), _float_text(time), *(_float_text(v) for v in state)]

    _write_rows(path, [*TRUTH_FIXED_COLUMNS, *table.state_names], rows())


def read_truth(path: PathLike) -> TruthTable:
    """Read a truth file (format 2); the state names are the columns after ``target_id,time``.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    TruthTable
        Records in file order.

    Raises
    ------
    DataFileError
        Malformed header, line or cell, or a repeated (target_id, time).
    """
    path = check_path("read_truth: path", path)
    lines = _lines(path)
    header = _read_header(path, lines, TRUTH_HEADER)
    names = truth_state_names(path, header, row=1)
    ids: list[int] = []
    times: list[float] = []
    states: list[list[float]] = []
    first_line: dict[tuple[int, float], int] = {}
    for line, cells in lines:
        _check_width(path, line, cells, header)
        target = _int_cell(path, line, "target_id", cells[0], minimum=0)
        time = _float_cell(path, line, "time", cells[1])
        key = (target, time)
        if key in first_line:
            raise DataFileError(
                path,
                f"target {target} at time {time!r} already has a state at line "
                f"{first_line[key]}; expected one line per (target_id, time)",
                row=line,
                column="time",
            )
        first_line[key] = line
        ids.append(target)
        times.append(time)
        states.append(
            [
                _float_cell(path, line, name, cell)
                for name, cell in zip(names, cells[2:], strict=True)
            ]
        )
    return TruthTable(
        target_ids=np.array(ids, dtype=np.int64),
        times=np.array(times, dtype=float),
        states=np.array(states, dtype=float).reshape(len(states), len(names)),
        state_names=tuple(names),
    )


# --------------------------------------------------------------------------- origins


def write_origins(path: PathLike, origins: Origins) -> None:
    """Write an origins file (format 3); false alarms (id -1) get an empty cell.

    Parameters
    ----------
    path : str or os.PathLike
        The file (overwritten).
    origins : Origins
    """
    path = check_path("write_origins: path", path)
    if not isinstance(origins, Origins):
        raise InputError(f"origins must be an Origins, got {origins!r}")

    def rows() -> Iterator[list[str]]:
        for row, target in zip(origins.rows.tolist(), origins.target_ids.tolist(), strict=True):
            yield [str(row), "" if target < 0 else str(target)]

    _write_rows(path, list(ORIGINS_COLUMNS), rows())


def read_origins(path: PathLike) -> Origins:
    """Read an origins file (format 3).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    Origins
        In file order; an empty ``target_id`` cell (false alarm) becomes -1.

    Raises
    ------
    DataFileError
        Malformed header, line or cell, or a repeated row.
    """
    path = check_path("read_origins: path", path)
    expected = ",".join(ORIGINS_COLUMNS)
    lines = _lines(path)
    header = _read_header(path, lines, expected)
    if tuple(header) != ORIGINS_COLUMNS:
        wrong = next(
            (name for name, want in zip(header, ORIGINS_COLUMNS, strict=False) if name != want),
            header[-1],
        )
        raise DataFileError(
            path, f"header is {','.join(header)}; expected {expected}", row=1, column=wrong
        )
    rows: list[int] = []
    ids: list[int] = []
    first_line: dict[int, int] = {}
    for line, cells in lines:
        _check_width(path, line, cells, header)
        row = _int_cell(path, line, "row", cells[0], minimum=0)
        if row in first_line:
            raise DataFileError(
                path,
                f"row {row} already has an origin at line {first_line[row]}; expected each "
                "detection row once",
                row=line,
                column="row",
            )
        first_line[row] = line
        rows.append(row)
        ids.append(
            -1 if cells[1] == "" else _int_cell(path, line, "target_id", cells[1], minimum=0)
        )
    return Origins(rows=np.array(rows, dtype=np.int64), target_ids=np.array(ids, dtype=np.int64))


# --------------------------------------------------------------------------- tracks


def _tracks_header(
    state_names: Sequence[str], existence: bool = False, model_names: Sequence[str] = ()
) -> list[str]:
    return [
        *TRACK_FIXED_COLUMNS,
        *state_names,
        *(VARIANCE_PREFIX + name for name in state_names),
        TRACK_ROW_COLUMN,
        *(MODEL_PROBABILITY_PREFIX + name for name in model_names),
        *((EXISTENCE_COLUMN,) if existence else ()),
    ]


def write_tracks(path: PathLike, table: TrackTable) -> None:
    """Write a tracks file (format 4) in the table's record order; misses get an empty cell.

    Parameters
    ----------
    path : str or os.PathLike
        The file (overwritten).
    table : TrackTable
    """
    path = check_path("write_tracks: path", path)
    if not isinstance(table, TrackTable):
        raise InputError(f"table must be a TrackTable, got {table!r}")

    existence = table.existence
    probabilities = table.model_probabilities

    def rows() -> Iterator[list[str]]:
        for index in range(table.size):
            row = int(table.detection_rows[index])
            cells = [
                str(int(table.track_ids[index])),
                _float_text(table.times[index]),
                table.sensors[index],
                *(_float_text(v) for v in table.states[index]),
                *(_float_text(v) for v in table.variances[index]),
                "" if row < 0 else str(row),
            ]
            if probabilities is not None:
                cells.extend(_float_text(v) for v in probabilities[index])
            if existence is not None:
                value = float(existence[index])
                cells.append("" if math.isnan(value) else _float_text(value))
            yield cells

    header = _tracks_header(table.state_names, existence is not None, table.model_names)
    _write_rows(path, header, rows())


ASSOCIATIONS_HEADER = ("detection_id", "track_id", "probability")
"""Columns of an associations file: the probability that a detection belongs to a track."""


def write_associations(path: PathLike, by_track: Mapping[int, Mapping[int, float]]) -> None:
    """Write an associations file: one line per (detection, track) pair with its probability.

    Parameters
    ----------
    path : str or os.PathLike
        The file (overwritten).
    by_track : mapping of int to mapping of int to float
        Track id -> detection id -> probability in [0, 1]
        (:attr:`mapassoc.estimator.refinement.TrackConfidence.associations`).  Lines are
        sorted by detection id, then track id.
    """
    path = check_path("write_associations: path", path)
    pairs = sorted(
        (int(row), int(track), float(p))
        for track, rows in by_track.items()
        for row, p in rows.items()
    )
    for row, track, p in pairs:
        if not 0.0 <= p <= 1.0:
            raise InputError(
                f"association probability {p!r} of detection {row} and track {track} is not "
                "in [0, 1]"
            )
    rows = ([str(row), str(track), _float_text(p)] for row, track, p in pairs)
    _write_rows(path, ASSOCIATIONS_HEADER, rows)


def read_tracks(path: PathLike) -> TrackTable:
    """Read a tracks file (format 4); state names come from the header.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    TrackTable
        In file order; an empty ``detection_row`` (miss) becomes -1.

    Raises
    ------
    DataFileError
        Malformed header (the ``var_`` columns must follow the state columns in the same
        order), line or cell, negative variance, or a repeated (track_id, time, sensor).
    """
    path = check_path("read_tracks: path", path)
    lines = _lines(path)
    header = _read_header(path, lines, TRACKS_HEADER)
    names, var_names = track_state_names(path, header, row=1)
    columns = _TrackColumns(names, var_names, track_model_names(header),
                            header[-1] == EXISTENCE_COLUMN)  # fmt: skip
    records: list[_TrackLine] = []
    first_line: dict[tuple[int, float, str], int] = {}
    for line, cells in lines:
        _check_width(path, line, cells, header)
        key = _track_key(path, line, cells)
        if key in first_line:
            raise DataFileError(
                path,
                f"track {key[0]} at time {key[1]!r} of sensor {key[2]!r} already appears at "
                f"line {first_line[key]}; expected one line per track per scan",
                row=line,
                column="time",
            )
        first_line[key] = line
        records.append(_track_line(path, line, cells, key, columns))
    size, count = len(records), len(names)
    models = columns.model_names
    return TrackTable(
        track_ids=np.array([r.track for r in records], dtype=np.int64),
        times=np.array([r.time for r in records], dtype=float),
        sensors=tuple(r.sensor for r in records),
        states=np.array([r.state for r in records], dtype=float).reshape(size, count),
        variances=np.array([r.variance for r in records], dtype=float).reshape(size, count),
        detection_rows=np.array([r.detection_row for r in records], dtype=np.int64),
        state_names=tuple(names),
        existence=(
            np.array([r.existence for r in records], dtype=float)
            if columns.has_existence
            else None
        ),
        model_probabilities=(
            np.array([r.model_probabilities for r in records], dtype=float).reshape(
                size, len(models)
            )
            if models
            else None
        ),
        model_names=tuple(models),
    )


@dataclass(frozen=True)
class _TrackColumns:
    """The columns of a tracks file after its key, from its header."""

    names: Sequence[str]
    var_names: Sequence[str]
    model_names: Sequence[str]
    has_existence: bool


@dataclass(frozen=True)
class _TrackLine:
    """One parsed line of a tracks file."""

    track: int
    time: float
    sensor: str
    state: list[float]
    variance: list[float]
    detection_row: int
    existence: float
    model_probabilities: list[float]


def _track_key(path: str, line: int, cells: list[str]) -> tuple[int, float, str]:
    """``(track_id, time, sensor)`` of a tracks-file line."""
    track = _int_cell(path, line, "track_id", cells[0], minimum=0)
    time = _float_cell(path, line, "time", cells[1])
    sensor = cells[2]
    if sensor == "":
        raise DataFileError(path, "empty cell; expected a sensor name", row=line, column="sensor")
    return track, time, sensor


def _track_line(
    path: str,
    line: int,
    cells: list[str],
    key: tuple[int, float, str],
    columns: _TrackColumns,
) -> _TrackLine:
    """The cells of one tracks-file line after its key, parsed (format 4)."""
    track, time, sensor = key
    names, var_names = columns.names, columns.var_names
    fixed, count = len(TRACK_FIXED_COLUMNS), len(names)
    state_cells = cells[fixed : fixed + count]
    existence = math.nan
    if columns.has_existence:
        cell = cells[-1]
        existence = math.nan if cell == "" else _float_cell(path, line, EXISTENCE_COLUMN, cell)
        if not (math.isnan(existence) or 0.0 <= existence <= 1.0):
            raise DataFileError(
                path,
                f"existence {cell!r} is not a probability; expected a value in [0, 1]",
                row=line,
                column=EXISTENCE_COLUMN,
            )
        cells = cells[:-1]
    models = len(columns.model_names)
    probabilities = _model_cells(path, line, columns.model_names, cells[len(cells) - models :])
    cells = cells[: len(cells) - models]
    state = [_float_cell(path, line, n, c) for n, c in zip(names, state_cells, strict=True)]
    variance = []
    for name, cell in zip(var_names, cells[fixed + count : -1], strict=True):
        value = _float_cell(path, line, name, cell)
        if value < 0:
            raise DataFileError(
                path, f"variance {cell!r} is negative; expected a value >= 0", row=line,
                column=name,
            )  # fmt: skip
        variance.append(value)
    row_cell = cells[-1]
    detection_row = (
        -1 if row_cell == "" else _int_cell(path, line, TRACK_ROW_COLUMN, row_cell, minimum=0)
    )
    return _TrackLine(
        track, time, sensor, state, variance, detection_row, existence, probabilities
    )


def _model_cells(
    path: str, line: int, model_names: Sequence[str], cells: Sequence[str]
) -> list[float]:
    """A line's model probabilities: each a number in [0, 1] (an empty cell is an error:
    every record of a set has its probabilities), summing to 1 within 1e-6."""
    values = []
    for name, cell in zip(model_names, cells, strict=True):
        column = MODEL_PROBABILITY_PREFIX + name
        if cell == "":
            raise DataFileError(
                path, "empty cell; expected a model probability in [0, 1]", row=line,
                column=column,
            )  # fmt: skip
        value = _float_cell(path, line, column, cell)
        if not 0.0 <= value <= 1.0:
            raise DataFileError(
                path, f"model probability {cell!r} is not in [0, 1]", row=line, column=column
            )
        values.append(value)
    total = math.fsum(values)
    if values and abs(total - 1.0) > MODEL_PROBABILITY_TOLERANCE:
        raise DataFileError(
            path,
            f"model probabilities {','.join(cells)} sum to {total!r}; expected 1 within "
            f"{MODEL_PROBABILITY_TOLERANCE:g}",
            row=line,
            column=MODEL_PROBABILITY_PREFIX + model_names[0],
        )
    return values
