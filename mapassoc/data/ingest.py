"""One ingest path: every detections reader ends here, with the same rules and messages.

A reader turns its source into a :class:`DetectionColumns` record (the columns of the
detections table: ``time``, ``sensor``, the measurement components of the sensors and
optionally ``detection_id``, each with a null mask) and hands it to
:func:`detection_columns_to_scans`, which validates it and groups it into scans.  The
readers are the CSV file (:func:`mapassoc.data.io.read_detections`), the Parquet file
(:func:`mapassoc.data.parquet.read_detections_parquet`), a pandas DataFrame and numpy
arrays (:mod:`mapassoc.data.tables`).  What a reader checks itself is only what its source
alone can get wrong: a CSV cell that is not a number, a Parquet column of the wrong type,
an array of the wrong shape, times going backwards down a CSV file.

Rules (one place for all readers):

* Required columns: ``time``; ``sensor`` unless exactly one sensor is configured; every
  measurement component of every sensor.  Allowed besides: ``detection_id``.  Distinct
  names.
* Times are finite; a sensor is one of the configured ones.
* A row fills all of its own sensor's components and none of the others; a row whose own
  components are all empty is a scan without detections (at most one such row per scan,
  and none for a scan that has detections).  Measurements are finite.
* Detection ids (``Scan.rows``): the ``detection_id`` column (integers >= 0, distinct,
  empty on the rows of empty scans), else the reader's row ids (a CSV file's line
  numbers), else the 0-based row positions.
* At least one row.
* Scans come out sorted by ``(time, sensor name)``, one per distinct ``(time, sensor)``
  (``-0.0`` and ``0.0`` are one time), detections in row order within a scan.

Every problem is raised as the error the reader's ``fail(message, column, row)`` builds,
``row`` the 0-based row position; messages that refer to a second row name it with the
reader's ``row_name`` (``"row 3"``, or ``"line 5"`` in a CSV file).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import BoolArray, FloatArray, IntArray
from mapassoc.data.records import check_sensors, measurement_columns
from mapassoc.data.scans import Scan, check_scan_order
from mapassoc.errors import InputError
from mapassoc.models.sensor import Sensor

__all__ = [
    "DETECTION_ID",
    "Fail",
    "DetectionColumns",
    "check_detection_columns",
    "detection_columns_to_scans",
    "first_repeated",
    "is_missing",
]

DETECTION_ID = "detection_id"
"""Optional column of a detections table holding the detection ids."""

Fail = Callable[[str, str | None, int | None], Exception]
"""``fail(message, column, row)`` builds the error to raise (the caller raises it)."""


def _position_name(row: int) -> str:
    return f"row {row}"


# --------------------------------------------------------------------------- grouping


def _sensor_ranks(sensor_list: Sequence[Sensor]) -> IntArray:
    """Rank of each sensor (by position in ``sensor_list``) in sorted name order."""
    order = sorted(range(len(sensor_list)), key=lambda k: sensor_list[k].name)
    rank = np.empty(len(sensor_list), dtype=np.int64)
    rank[order] = np.arange(len(sensor_list))
    return rank


def _detection_groups(
    times: FloatArray, codes: IntArray, rank: IntArray, rows: IntArray
) -> dict[tuple[float, int], IntArray]:
    """Input positions ``rows`` grouped by (time, sensor code), groups in (time, sensor
    name) order, positions increasing within a group.  The group key's time is the time of
    its first position (``-0.0`` and ``0.0`` are one time, as in the CSV reader)."""
    if rows.size == 0:
        return {}
    order = np.lexsort((rows, rank[codes[rows]], times[rows]))
    ordered = rows[order]
    t = times[ordered]
    c = codes[ordered]
    cuts = np.flatnonzero((t[1:] != t[:-1]) | (c[1:] != c[:-1])) + 1
    groups: dict[tuple[float, int], IntArray] = {}
    for part in np.split(ordered, cuts):
        first = int(part.min())
        groups[(float(times[first]), int(codes[first]))] = np.sort(part)
    return groups


def _build_scans(
    groups: Mapping[tuple[float, int], IntArray],
    empty: Sequence[tuple[float, int]],
    values: Sequence[FloatArray],
    ids: IntArray,
    sensor_list: Sequence[Sensor],
) -> list[Scan]:
    """Scans of the detection ``groups`` plus an empty scan for every key of ``empty``
    without detections; ``values[code]`` holds the ``(n, dz)`` measurements of sensor
    ``code`` by input position, ``ids`` the detection id of each input position."""
    keys: dict[tuple[float, int], IntArray | None] = dict(groups)
    for key in empty:
        keys.setdefault(key, None)
    scans = []
    for (time, code), positions in keys.items():
        sensor = sensor_list[code]
        dim = sensor.measurement.measurement_dim
        if positions is None:
            detections = np.zeros((0, dim))
            rows = np.zeros(0, dtype=np.int64)
        else:
            detections = values[code][positions].reshape(positions.size, dim)
            rows = ids[positions]
        scans.append(Scan(time=time, sensor=sensor.name, detections=detections, rows=rows))
    scans.sort(key=lambda scan: (scan.time, scan.sensor))
    check_scan_order(scans)
    return scans


def first_repeated(values: IntArray) -> tuple[int, int, int] | None:
    """``(value, first position, second position)`` of the first repeated value."""
    if values.size < 2:
        return None
    order = np.argsort(values, kind="stable")
    ordered = values[order]
    same = np.flatnonzero(ordered[1:] == ordered[:-1])
    if same.size == 0:
        return None
    # the repeat found earliest in input order
    second = order[same + 1]
    k = int(np.argmin(second))
    value = int(ordered[same[k]])
    first = int(order[np.searchsorted(ordered, value)])
    return value, first, int(second[k])


# --------------------------------------------------------------------------- columns


@dataclass(frozen=True)
class DetectionColumns:
    """A detections table as columns, ``n`` rows (what a DataFrame or a Parquet file
    holds), before validation.

    Parameters
    ----------
    names : tuple of str
        Column names in table order (may hold unknown or repeated names: they are
        reported).
    times : ndarray, shape (n,)
        The ``time`` column as float64 (anything where ``time_null``).
    time_null : ndarray of bool, shape (n,)
    sensors : sequence of object, length n, or None
        The ``sensor`` column (None where empty), or None if the table has none.
    components : mapping of str to (ndarray (n,), ndarray of bool (n,))
        Every measurement component column present: float64 values and null mask.
    ids : (ndarray of int64 (n,), ndarray of bool (n,)), optional
        The ``detection_id`` column (values, null mask), if present.
    row_ids : ndarray of int64 (n,), optional
        The detection id of each row when there is no ``detection_id`` column (a CSV
        file's line numbers); default the 0-based row positions.
    """

    names: tuple[str, ...]
    times: FloatArray
    time_null: BoolArray
    sensors: Sequence[object] | None
    components: Mapping[str, tuple[FloatArray, BoolArray]]
    ids: tuple[IntArray, BoolArray] | None
    row_ids: IntArray | None = None


def check_detection_columns(
    names: Sequence[object], sensors: Mapping[str, Sensor], fail: Fail
) -> None:
    """Refuse a detections table whose columns do not fit the configured sensors.

    Required: ``time``; ``sensor`` unless exactly one sensor is configured; every
    measurement component of every sensor.  Allowed besides: ``detection_id``.  Column
    names must be distinct.
    """
    sensor_list = check_sensors(sensors)
    union = measurement_columns(sensor_list)
    if DETECTION_ID in union:
        raise InputError(
            f"a sensor has a measurement component named {DETECTION_ID!r}, which is "
            "reserved for the detection ids of a detections table"
        )
    canonical = ",".join(["time", "sensor", *union]) + f"[,{DETECTION_ID}]"
    seen: set[object] = set()
    for name in names:
        if name in seen:
            raise fail(f"column {name!r} appears twice; expected {canonical}", str(name), None)
        seen.add(name)
    if "time" not in seen:
        raise fail(f"no 'time' column among {list(names)}; expected {canonical}", "time", None)
    if "sensor" not in seen and len(sensor_list) > 1:
        raise fail(
            f"no 'sensor' column, but {len(sensor_list)} sensors are configured "
            f"({', '.join(sensors)}); expected {canonical}",
            "sensor",
            None,
        )
    for sensor in sensor_list:
        for name in sensor.measurement.component_names:
            if name not in seen:
                raise fail(
                    f"no column {name!r}, which sensor {sensor.name!r} measures; "
                    f"expected {canonical}",
                    name,
                    None,
                )
    allowed = {"time", "sensor", DETECTION_ID, *union}
    for name in names:
        if name not in allowed:
            raise fail(
                f"unknown column {name!r}; expected the columns {canonical}", str(name), None
            )


def detection_columns_to_scans(
    table: DetectionColumns,
    sensors: Mapping[str, Sensor],
    fail: Fail,
    *,
    row_name: Callable[[int], str] = _position_name,
) -> list[Scan]:
    """Validate a detections table and group it into scans.

    Parameters
    ----------
    table : DetectionColumns
    sensors : mapping of str to Sensor
    fail : callable
        ``fail(message, column, row)`` returns the error to raise; ``row`` is the 0-based
        row position.
    row_name : callable, optional
        How a message names another row, from its 0-based position (default
        ``"row 3"``; a CSV file says ``"line 5"``).

    Returns
    -------
    list of Scan
        Sorted by ``(time, sensor name)``; see the module docstring.
    """
    check_detection_columns(table.names, sensors, fail)
    sensor_list = check_sensors(sensors)
    union = measurement_columns(sensor_list)
    times = table.times
    _check_times(table, fail)
    codes = _codes(table, sensor_list, sensors, fail)
    is_detection = np.zeros(times.shape[0], dtype=bool)
    values: list[FloatArray] = []
    for code, sensor in enumerate(sensor_list):
        filled, stacked = _sensor_values(table, codes == code, sensor, union, fail)
        is_detection |= filled
        values.append(stacked)
    ids = _detection_ids(table, is_detection, fail, row_name)
    rank = _sensor_ranks(sensor_list)
    groups = _detection_groups(times, codes, rank, np.flatnonzero(is_detection))
    empty = _empty_scans(times, codes, is_detection, groups, sensor_list, fail, row_name)
    return _build_scans(groups, empty, values, ids, sensor_list)


def _check_times(table: DetectionColumns, fail: Fail) -> None:
    """At least one row; every time present and finite."""
    times = table.times
    if times.shape[0] == 0:
        raise fail(
            "no rows; a scan without detections is a row with time and sensor and empty "
            "measurement cells",
            None,
            None,
        )
    if np.any(table.time_null):
        raise fail("empty cell; expected a finite time", "time", int(np.argmax(table.time_null)))
    bad = ~np.isfinite(times)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise fail(f"value {float(times[i])!r} is not finite; expected a finite time", "time", i)


def _codes(
    table: DetectionColumns,
    sensor_list: Sequence[Sensor],
    sensors: Mapping[str, Sensor],
    fail: Fail,
) -> IntArray:
    """The position in ``sensor_list`` of each row's sensor."""
    n = table.times.shape[0]
    if table.sensors is None:
        return np.zeros(n, dtype=np.int64)
    code_of = {sensor.name: k for k, sensor in enumerate(sensor_list)}
    codes = np.fromiter(
        (code_of.get(v, -1) if isinstance(v, str) else -1 for v in table.sensors),
        dtype=np.int64,
        count=n,
    )
    if np.any(codes < 0):
        i = int(np.argmax(codes < 0))
        value = table.sensors[i]
        what = "empty cell" if is_missing(value) else f"unknown sensor {value!r}"
        raise fail(f"{what}; expected one of {list(sensors)}", "sensor", i)
    return codes


def _sensor_values(
    table: DetectionColumns, mine: BoolArray, sensor: Sensor, union: Sequence[str], fail: Fail
) -> tuple[BoolArray, FloatArray]:
    """Which of a sensor's rows (``mine``) are detections, and its ``(n, dz)`` values:
    all or none of a row's own components, none of the others, finite."""
    own_names = sensor.measurement.component_names
    for name in union:
        if name in own_names:
            continue
        present = mine & ~table.components[name][1]
        if np.any(present):
            i = int(np.argmax(present))
            raise fail(
                f"value {float(table.components[name][0][i])!r} in a column sensor "
                f"{sensor.name!r} does not measure; expected an empty cell",
                name,
                i,
            )
    nulls = np.column_stack([table.components[name][1] for name in own_names])
    filled = mine & ~nulls.any(axis=1)
    partial = mine & nulls.any(axis=1) & ~nulls.all(axis=1)
    if np.any(partial):
        i = int(np.argmax(partial))
        empty_name = own_names[int(np.argmax(nulls[i]))]
        raise fail(
            f"empty cell; sensor {sensor.name!r} needs all of {','.join(own_names)} "
            "(a scan without detections leaves all of them empty)",
            empty_name,
            i,
        )
    stacked = np.column_stack([table.components[name][0] for name in own_names])
    infinite = filled[:, None] & ~np.isfinite(stacked)
    if np.any(infinite):
        i, j = (int(v) for v in np.argwhere(infinite)[0])
        raise fail(
            f"value {float(stacked[i, j])!r} is not finite; expected a finite number",
            own_names[j],
            i,
        )
    return filled, stacked


def _detection_ids(
    table: DetectionColumns,
    is_detection: BoolArray,
    fail: Fail,
    row_name: Callable[[int], str],
) -> IntArray:
    """The detection id of each row (module docstring)."""
    n = table.times.shape[0]
    if table.ids is None:
        return np.arange(n, dtype=np.int64) if table.row_ids is None else table.row_ids
    ids, id_null = table.ids
    missing = is_detection & id_null
    if np.any(missing):
        raise fail(
            "empty cell on a detection; expected a detection id >= 0",
            DETECTION_ID,
            int(np.argmax(missing)),
        )
    extra = ~is_detection & ~id_null
    if np.any(extra):
        i = int(np.argmax(extra))
        raise fail(
            f"detection id {int(ids[i])} on a row without measurements (a scan without "
            "detections); expected an empty cell",
            DETECTION_ID,
            i,
        )
    negative = is_detection & (ids < 0)
    if np.any(negative):
        i = int(np.argmax(negative))
        raise fail(
            f"detection id {int(ids[i])} is negative; expected an integer >= 0", DETECTION_ID, i
        )
    detection_positions = np.flatnonzero(is_detection)
    repeated = first_repeated(ids[detection_positions])
    if repeated is not None:
        value, first, second = repeated
        raise fail(
            f"detection id {value} already names the detection at "
            f"{row_name(int(detection_positions[first]))}; expected distinct ids",
            DETECTION_ID,
            int(detection_positions[second]),
        )
    return ids


def _empty_scans(
    times: FloatArray,
    codes: IntArray,
    is_detection: BoolArray,
    groups: Mapping[tuple[float, int], IntArray],
    sensor_list: Sequence[Sensor],
    fail: Fail,
    row_name: Callable[[int], str],
) -> list[tuple[float, int]]:
    """The ``(time, code)`` of the rows without measurements: one per scan, none for a
    scan with detections."""
    empty_seen: dict[tuple[float, int], int] = {}
    for i in np.flatnonzero(~is_detection).tolist():
        key = (float(times[i]), int(codes[i]))
        name = sensor_list[key[1]].name
        if key in groups:
            raise fail(
                f"row without measurements (a scan without detections) for sensor {name!r} "
                f"at time {key[0]!r}, which has detections ({row_name(int(groups[key][0]))})",
                sensor_list[key[1]].measurement.component_names[0],
                i,
            )
        if key in empty_seen:
            raise fail(
                f"scan of sensor {name!r} at time {key[0]!r} was declared empty at "
                f"{row_name(empty_seen[key])}; expected one row for a scan without detections",
                "time",
                i,
            )
        empty_seen[key] = i
    return list(empty_seen)


def is_missing(value: object) -> bool:
    """Whether a table cell is empty: None, a float NaN, or pandas' NA or NaT."""
    if value is None:
        return True
    if isinstance(value, float) and math.isnan(value):
        return True
    try:
        import pandas as pd
    except ImportError:  # pragma: no cover - pandas is a core dependency
        return False
    return value is pd.NA or value is pd.NaT
