"""In-memory detections: scans from numpy arrays or a pandas DataFrame (for notebooks).

Two entry points, both returning the list of :class:`~mapassoc.data.scans.Scan` that
:func:`mapassoc.data.io.read_detections` returns for a file: sorted by ``(time, sensor
name)``, one scan per distinct ``(time, sensor)``, detections in input order within a scan.

* :func:`scans_from_arrays`: ``times`` of shape ``(N,)`` and ``measurements`` of shape
  ``(N, dz)``, one row per detection, with per-detection sensor names when several
  sensors are configured.  Every row is a detection; scans without detections are asked
  for with ``scan_times``.
* :func:`scans_from_frame`: a DataFrame with the columns of the detections file
  (:mod:`mapassoc.data.io`, format 1): ``time``, ``sensor`` (optional with one sensor),
  the measurement components of the sensors, and optionally ``detection_id``.  A row
  whose measurement cells are all empty (NaN / None / ``pd.NA``) is a scan without
  detections, as in the file.

Rules shared by both (they differ from the CSV reader in one point: rows may come in
any order; they are sorted here):

* Times and measurements must be finite; detection ids are int64 >= 0 and distinct.
* Detection ids (``Scan.rows``): the given ``ids`` / ``detection_id`` column, else the
  0-based position of the detection among the inputs (for a DataFrame, the row
  position, so the rows of empty scans use up a number as the CSV's lines do).
* At least one scan: empty input is refused, as the CSV reader refuses a file without a
  line after the header.

Every problem raises :class:`~mapassoc.errors.InputError` naming the argument (or the
DataFrame column and row position), the value and what was expected.

The column-table engine (:func:`detection_columns_to_scans`) is shared with the Parquet
reader (:mod:`mapassoc.data.parquet`), which reports the same problems as
:class:`~mapassoc.errors.DataFileError`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from mapassoc.array_types import BoolArray, FloatArray, IntArray
from mapassoc.data.records import check_sensors, measurement_columns
from mapassoc.data.scans import Scan, check_scan_order
from mapassoc.errors import InputError
from mapassoc.models.sensor import Sensor

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["scans_from_arrays", "scans_from_frame", "DETECTION_ID"]

DETECTION_ID = "detection_id"
"""Optional column of a detections table (DataFrame, Parquet) holding the detection ids."""

Fail = Callable[[str, str | None, int | None], Exception]
"""``fail(message, column, row)`` builds the error to raise (the caller raises it)."""


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


def _first_repeated(values: IntArray) -> tuple[int, int, int] | None:
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
    """

    names: tuple[str, ...]
    times: FloatArray
    time_null: BoolArray
    sensors: Sequence[object] | None
    components: Mapping[str, tuple[FloatArray, BoolArray]]
    ids: tuple[IntArray, BoolArray] | None


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
    table: DetectionColumns, sensors: Mapping[str, Sensor], fail: Fail
) -> list[Scan]:
    """Validate a detections table and group it into scans.

    Parameters
    ----------
    table : DetectionColumns
    sensors : mapping of str to Sensor
    fail : callable
        ``fail(message, column, row)`` returns the error to raise; ``row`` is the 0-based
        row position.

    Returns
    -------
    list of Scan
        Sorted by ``(time, sensor name)``; see the module docstring.
    """
    check_detection_columns(table.names, sensors, fail)
    sensor_list = check_sensors(sensors)
    union = measurement_columns(sensor_list)
    times = table.times
    n = times.shape[0]
    if n == 0:
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

    # sensor codes
    if table.sensors is None:
        codes = np.zeros(n, dtype=np.int64)
    else:
        code_of = {sensor.name: k for k, sensor in enumerate(sensor_list)}
        codes = np.fromiter(
            (code_of.get(v, -1) if isinstance(v, str) else -1 for v in table.sensors),
            dtype=np.int64,
            count=n,
        )
        if np.any(codes < 0):
            i = int(np.argmax(codes < 0))
            value = table.sensors[i]
            what = "empty cell" if _is_missing(value) else f"unknown sensor {value!r}"
            raise fail(f"{what}; expected one of {list(sensors)}", "sensor", i)

    # measurement cells: all or none of a row's own components, none of the others
    is_detection = np.zeros(n, dtype=bool)
    values: list[FloatArray] = []
    for code, sensor in enumerate(sensor_list):
        own_names = sensor.measurement.component_names
        mine = codes == code
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
        is_detection |= filled
        values.append(stacked)

    # detection ids
    positions = np.arange(n, dtype=np.int64)
    if table.ids is None:
        ids = positions
    else:
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
                f"detection id {int(ids[i])} is negative; expected an integer >= 0",
                DETECTION_ID,
                i,
            )
        detection_positions = np.flatnonzero(is_detection)
        repeated = _first_repeated(ids[detection_positions])
        if repeated is not None:
            value, first, second = repeated
            raise fail(
                f"detection id {value} already names the detection at row "
                f"{int(detection_positions[first])}; expected distinct ids",
                DETECTION_ID,
                int(detection_positions[second]),
            )

    rank = _sensor_ranks(sensor_list)
    groups = _detection_groups(times, codes, rank, np.flatnonzero(is_detection))
    empty_seen: dict[tuple[float, int], int] = {}
    for i in np.flatnonzero(~is_detection).tolist():
        key = (float(times[i]), int(codes[i]))
        name = sensor_list[key[1]].name
        if key in groups:
            raise fail(
                f"row without measurements (a scan without detections) for sensor {name!r} "
                f"at time {key[0]!r}, which has detections (row {int(groups[key][0])})",
                sensor_list[key[1]].measurement.component_names[0],
                i,
            )
        if key in empty_seen:
            raise fail(
                f"scan of sensor {name!r} at time {key[0]!r} was declared empty at row "
                f"{empty_seen[key]}; expected one row for a scan without detections",
                "time",
                i,
            )
        empty_seen[key] = i
    return _build_scans(groups, list(empty_seen), values, ids, sensor_list)


def _is_missing(value: object) -> bool:
    if value is None:
        return True
    if isinstance(value, float) and math.isnan(value):
        return True
    try:
        import pandas as pd
    except ImportError:  # pragma: no cover - pandas is a core dependency
        return False
    return value is pd.NA or value is pd.NaT


# --------------------------------------------------------------------------- arrays


def _times_array(name: str, value: ArrayLike, *, length: int | None) -> FloatArray:
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a 1-D array of finite times, got {value!r}") from None
    if arr.ndim != 1 or (length is not None and arr.shape[0] != length):
        want = f"({length},)" if length is not None else "(k,)"
        raise InputError(f"{name} must have shape {want}, got shape {arr.shape}")
    if arr.size and (arr.dtype.kind not in "iuf"):
        raise InputError(f"{name} must hold numbers, got dtype {arr.dtype}")
    out = arr.astype(np.float64)
    bad = ~np.isfinite(out)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise InputError(f"{name}[{i}] is {float(out[i])!r}; expected a finite time")
    return out


def scans_from_arrays(
    times: ArrayLike,
    measurements: ArrayLike,
    sensors: Mapping[str, Sensor],
    *,
    sensor_names: str | Sequence[str] | None = None,
    ids: ArrayLike | None = None,
    scan_times: ArrayLike | Mapping[str, ArrayLike] | None = None,
) -> list[Scan]:
    """Scans from arrays with one row per detection.

    Parameters
    ----------
    times : array_like, shape (N,)
        Time of each detection, finite, in any order.
    measurements : array_like, shape (N, dz)
        Measurement of each detection, finite, columns in the sensor's
        ``measurement.component_names`` order.  Every sensor the detections name must
        measure ``dz`` components (for sensors of different dimensions use
        :func:`scans_from_frame`, which has one column per component).
    sensors : mapping of str to Sensor
        The configured sensors (``Config.sensors``).
    sensor_names : str or sequence of str (length N), optional
        Sensor of each detection, or one name for all of them; may be left out when
        ``sensors`` has exactly one entry.
    ids : array_like of int, shape (N,), optional
        Detection ids (``Scan.rows``): distinct integers >= 0.  Default ``0..N-1`` in input
        order.
    scan_times : array_like of float, or mapping of str to array_like of float, optional
        Scans that must exist even without detections: a sequence of times (every sensor of
        ``sensors`` scans at each), or a mapping sensor name -> its scan times.  Scans with
        detections need not be listed; a listed scan without detections comes out empty.
        Rows cannot express a scan without detections, so this is the way to give them
        (the estimator counts them: a scan that saw nothing is evidence).

    Returns
    -------
    list of Scan
        Sorted by ``(time, sensor name)``, one per distinct (time, sensor) of the
        detections and of ``scan_times``; detections in input order within a scan.

    Raises
    ------
    InputError
        A wrong shape or dtype, a non-finite time or measurement, an unknown sensor, a
        sensor of another dimension, a negative or repeated id, or no scan at all.
    """
    sensor_list = check_sensors(sensors)
    code_of = {sensor.name: k for k, sensor in enumerate(sensor_list)}
    t = _times_array("times", times, length=None)
    n = t.shape[0]
    try:
        z = np.asarray(measurements)
    except (TypeError, ValueError):
        raise InputError(
            f"measurements must be a numeric array of shape ({n}, dz), got {measurements!r}"
        ) from None
    if z.ndim != 2 or z.shape[0] != n:
        raise InputError(
            f"measurements must have shape ({n}, dz) (one row per entry of times), got shape "
            f"{z.shape}; a single component is a column: measurements.reshape(-1, 1)"
        )
    if z.size and z.dtype.kind not in "iuf":
        raise InputError(f"measurements must hold numbers, got dtype {z.dtype}")
    z = z.astype(np.float64)
    bad = ~np.isfinite(z)
    if np.any(bad):
        i, j = (int(v) for v in np.argwhere(bad)[0])
        raise InputError(
            f"measurements[{i}, {j}] is {float(z[i, j])!r}; expected a finite number (every "
            "row is a detection; a scan without detections is given by scan_times)"
        )

    # sensor of each detection
    if sensor_names is None:
        if len(sensor_list) > 1:
            raise InputError(
                f"sensor_names is required: {len(sensor_list)} sensors are configured "
                f"({', '.join(sensors)}); give the sensor of each detection or one name"
            )
        codes = np.zeros(n, dtype=np.int64)
    elif isinstance(sensor_names, str):
        if sensor_names not in code_of:
            raise InputError(f"sensor_names is {sensor_names!r}; expected one of {list(sensors)}")
        codes = np.full(n, code_of[sensor_names], dtype=np.int64)
    else:
        names = np.asarray(sensor_names, dtype=object)
        if names.shape != (n,):
            raise InputError(
                f"sensor_names must be one name or a sequence of {n} names (one per entry "
                f"of times), got shape {names.shape}"
            )
        codes = np.empty(n, dtype=np.int64)
        for i, name in enumerate(names.tolist()):
            if not isinstance(name, str) or name not in code_of:
                raise InputError(f"sensor_names[{i}] is {name!r}; expected one of {list(sensors)}")
            codes[i] = code_of[name]
    for code in np.unique(codes).tolist():
        sensor = sensor_list[code]
        dim = sensor.measurement.measurement_dim
        if n and z.shape[1] != dim:
            i = int(np.argmax(codes == code))
            raise InputError(
                f"measurements have {z.shape[1]} columns, but sensor {sensor.name!r} "
                f"(detection {i}) measures {dim} ({','.join(sensor.measurement.component_names)}); "
                "for sensors of different dimensions use scans_from_frame"
            )

    # ids
    if ids is None:
        id_array = np.arange(n, dtype=np.int64)
    else:
        raw = np.asarray(ids)
        if raw.shape != (n,):
            raise InputError(f"ids must have shape ({n},), got shape {raw.shape}")
        if n and not np.issubdtype(raw.dtype, np.integer):
            raise InputError(f"ids must be integers, got dtype {raw.dtype}")
        if n and raw.dtype == np.uint64 and int(raw.max()) > np.iinfo(np.int64).max:
            raise InputError(f"ids must fit in int64, got {int(raw.max())}")
        id_array = raw.astype(np.int64)
        if n and int(id_array.min()) < 0:
            i = int(np.argmax(id_array < 0))
            raise InputError(f"ids[{i}] is {int(id_array[i])}; expected an integer >= 0")
        repeated = _first_repeated(id_array)
        if repeated is not None:
            value, first, second = repeated
            raise InputError(f"ids[{second}] is {value}, as is ids[{first}]; expected distinct ids")

    # scans that must exist
    empty: list[tuple[float, int]] = []
    if scan_times is not None:
        if isinstance(scan_times, Mapping):
            for name, listed in scan_times.items():
                if name not in code_of:
                    raise InputError(
                        f"scan_times has the key {name!r}; expected sensor names from "
                        f"{list(sensors)}"
                    )
                for time in _times_array(f"scan_times[{name!r}]", listed, length=None):
                    empty.append((float(time), code_of[name]))
        else:
            for time in _times_array("scan_times", scan_times, length=None):
                empty.extend((float(time), code) for code in range(len(sensor_list)))
    if n == 0 and not empty:
        raise InputError(
            "no detections and no scan_times: there is no scan to make (give scan_times for "
            "scans without detections)"
        )

    rank = _sensor_ranks(sensor_list)
    groups = _detection_groups(t, codes, rank, np.arange(n, dtype=np.int64))
    values = [z] * len(sensor_list)
    return _build_scans(groups, empty, values, id_array, sensor_list)


# --------------------------------------------------------------------------- DataFrame


def _frame_fail(message: str, column: str | None, row: int | None) -> InputError:
    where = "frame"
    if row is not None:
        where += f" row {row} (0-based position)"
    if column is not None:
        where += f", column {column!r}"
    return InputError(f"{where}: {message}")


def _frame_float(frame: pd.DataFrame, name: str) -> tuple[FloatArray, BoolArray]:
    import pandas as pd

    series = frame[name]
    dtype = series.dtype
    if pd.api.types.is_bool_dtype(dtype) or not pd.api.types.is_numeric_dtype(dtype):
        if not series.isna().all():
            raise _frame_fail(f"dtype {dtype}; expected numbers (float or integer)", name, None)
    null = series.isna().to_numpy(dtype=bool)
    values = series.to_numpy(dtype=np.float64, na_value=np.nan)
    return values, null


def _frame_ids(frame: pd.DataFrame) -> tuple[IntArray, BoolArray]:
    import pandas as pd

    series = frame[DETECTION_ID]
    dtype = series.dtype
    null = series.isna().to_numpy(dtype=bool)
    if null.all():
        return np.zeros(len(series), dtype=np.int64), null
    if pd.api.types.is_bool_dtype(dtype) or not pd.api.types.is_numeric_dtype(dtype):
        raise _frame_fail(f"dtype {dtype}; expected integer detection ids", DETECTION_ID, None)
    if pd.api.types.is_integer_dtype(dtype):
        values = series.to_numpy(dtype=np.int64, na_value=-1)
        return values, null
    # a float column (NaN marks the rows of empty scans): whole numbers only
    raw = series.to_numpy(dtype=np.float64, na_value=np.nan)
    whole = null | (np.isfinite(raw) & (raw == np.round(raw)) & (np.abs(raw) < 2.0**53))
    if not np.all(whole):
        i = int(np.argmax(~whole))
        raise _frame_fail(
            f"value {float(raw[i])!r} is not a whole number; expected an integer detection id",
            DETECTION_ID,
            i,
        )
    return np.where(null, -1, raw).astype(np.int64), null


def scans_from_frame(frame: pd.DataFrame, sensors: Mapping[str, Sensor]) -> list[Scan]:
    """Scans from a DataFrame with the columns of the detections file.

    Parameters
    ----------
    frame : pandas.DataFrame
        Columns ``time``; ``sensor`` (may be left out when ``sensors`` has one entry); the
        measurement components of every sensor (``x,y[,z]``, ``range,bearing``: the
        union, as in the detections file; a row fills its own sensor's and leaves the
        others empty, i.e. NaN / None); optionally ``detection_id`` (integers >= 0, empty
        on the rows of empty scans).  No other columns.  Rows in any order.  A row whose
        own measurement cells are all empty is a scan without detections (at most one
        such row per scan, and none for a scan with detections).  The index is ignored.
    sensors : mapping of str to Sensor
        The configured sensors (``Config.sensors``).

    Returns
    -------
    list of Scan
        Sorted by ``(time, sensor name)``; ``rows`` the ``detection_id`` values, else the
        0-based row positions of the detections.

    Raises
    ------
    InputError
        A missing, unknown or repeated column, a non-numeric column, an empty or
        non-finite time, an unknown sensor, a partly filled measurement, a value in another
        sensor's column, a non-finite measurement, a missing, negative or repeated id,
        or no rows; the message names the column and the row position.
    """
    import pandas as pd

    if not isinstance(frame, pd.DataFrame):
        raise InputError(f"frame must be a pandas DataFrame, got {type(frame).__name__}")
    names = tuple(frame.columns)
    check_detection_columns(names, sensors, _frame_fail)
    union = measurement_columns(check_sensors(sensors))
    times, time_null = _frame_float(frame, "time")
    sensor_values = frame["sensor"].tolist() if "sensor" in names else None
    table = DetectionColumns(
        names=tuple(str(name) for name in names),
        times=times,
        time_null=time_null,
        sensors=sensor_values,
        components={name: _frame_float(frame, name) for name in union},
        ids=_frame_ids(frame) if DETECTION_ID in names else None,
    )
    return detection_columns_to_scans(table, sensors, _frame_fail)
