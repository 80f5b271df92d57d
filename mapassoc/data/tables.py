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

Both end in the one ingest path of every detections reader
(:func:`mapassoc.data.ingest.detection_columns_to_scans`), so they follow its rules;
they differ from the CSV reader in one point: rows may come in any order (they are
sorted).  Detection ids (``Scan.rows``) are the given ``ids`` / ``detection_id`` column,
else the 0-based position of the detection among the inputs (for a DataFrame, the row
position, so the rows of empty scans use up a number as the CSV's lines do).  At least
one scan: empty input is refused, as the CSV reader refuses a file without a line after
the header.

Every problem raises :class:`~mapassoc.errors.InputError` naming the argument (or the
DataFrame column and row position), the value and what was expected.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from mapassoc.array_types import BoolArray, FloatArray, IntArray
from mapassoc.data.ingest import (
    DETECTION_ID,
    DetectionColumns,
    check_detection_columns,
    detection_columns_to_scans,
    first_repeated,
)
from mapassoc.data.records import check_sensors, measurement_columns
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.models.sensor import Sensor

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["scans_from_arrays", "scans_from_frame", "DETECTION_ID"]


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
    z = _measurements_array(measurements, n)
    codes = _sensor_codes(sensor_names, n, sensors, code_of)
    _check_dimensions(z, codes, sensor_list)
    id_array = np.arange(n, dtype=np.int64) if ids is None else _ids_array(ids, n)
    empty = [] if scan_times is None else _listed_scans(scan_times, sensors, code_of)
    if n == 0 and not empty:
        raise InputError(
            "no detections and no scan_times: there is no scan to make (give scan_times for "
            "scans without detections)"
        )
    table = _arrays_table(t, z, codes, id_array, empty, sensor_list)
    return detection_columns_to_scans(table, sensors, _arrays_fail)


def _measurements_array(measurements: ArrayLike, n: int) -> FloatArray:
    """``measurements`` as finite float64 of shape ``(n, dz)`` (raises InputError)."""
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
    return z


def _sensor_codes(
    sensor_names: str | Sequence[str] | None,
    n: int,
    sensors: Mapping[str, Sensor],
    code_of: Mapping[str, int],
) -> IntArray:
    """The position in ``sensors`` of each detection's sensor, shape ``(n,)``."""
    if sensor_names is None:
        if len(code_of) > 1:
            raise InputError(
                f"sensor_names is required: {len(code_of)} sensors are configured "
                f"({', '.join(sensors)}); give the sensor of each detection or one name"
            )
        return np.zeros(n, dtype=np.int64)
    if isinstance(sensor_names, str):
        if sensor_names not in code_of:
            raise InputError(f"sensor_names is {sensor_names!r}; expected one of {list(sensors)}")
        return np.full(n, code_of[sensor_names], dtype=np.int64)
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
    return codes


def _check_dimensions(z: FloatArray, codes: IntArray, sensor_list: Sequence[Sensor]) -> None:
    """Every sensor the detections name measures ``z.shape[1]`` components."""
    for code in np.unique(codes).tolist():
        sensor = sensor_list[code]
        dim = sensor.measurement.measurement_dim
        if z.shape[0] and z.shape[1] != dim:
            i = int(np.argmax(codes == code))
            raise InputError(
                f"measurements have {z.shape[1]} columns, but sensor {sensor.name!r} "
                f"(detection {i}) measures {dim} ({','.join(sensor.measurement.component_names)}); "
                "for sensors of different dimensions use scans_from_frame"
            )


def _ids_array(ids: ArrayLike, n: int) -> IntArray:
    """``ids`` as distinct int64 >= 0 of shape ``(n,)`` (raises InputError)."""
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
    repeated = first_repeated(id_array)
    if repeated is not None:
        value, first, second = repeated
        raise InputError(f"ids[{second}] is {value}, as is ids[{first}]; expected distinct ids")
    return id_array


def _listed_scans(
    scan_times: ArrayLike | Mapping[str, ArrayLike],
    sensors: Mapping[str, Sensor],
    code_of: Mapping[str, int],
) -> list[tuple[float, int]]:
    """``(time, sensor code)`` of the scans ``scan_times`` says must exist."""
    empty: list[tuple[float, int]] = []
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
            empty.extend((float(time), code) for code in range(len(code_of)))
    return empty


def _arrays_fail(message: str, column: str | None, row: int | None) -> InputError:
    # scans_from_arrays checked its arguments in their own terms; a problem found only
    # here would be a defect of that translation
    return InputError(f"detections from arrays, input row {row}, column {column!r}: {message}")


def _arrays_table(
    times: FloatArray,
    measurements: FloatArray,
    codes: IntArray,
    ids: IntArray,
    listed: Sequence[tuple[float, int]],
    sensor_list: Sequence[Sensor],
) -> DetectionColumns:
    """The detections table of checked arrays: one row per detection, then one empty
    row per listed scan (``(time, sensor code)``) that has no detection, once each."""
    n = times.shape[0]
    has_detections = set(zip(times.tolist(), codes.tolist(), strict=True))
    empty = list(dict.fromkeys(key for key in listed if key not in has_detections))
    m = len(empty)
    all_times = np.concatenate([times, np.array([t for t, _ in empty], dtype=np.float64)])
    all_codes = np.concatenate([codes, np.array([c for _, c in empty], dtype=np.int64)])
    union = measurement_columns(sensor_list)
    components: dict[str, tuple[FloatArray, BoolArray]] = {
        name: (np.full(n + m, np.nan), np.ones(n + m, dtype=bool)) for name in union
    }
    for code, sensor in enumerate(sensor_list):
        mine = np.flatnonzero(codes == code)
        for j, name in enumerate(sensor.measurement.component_names):
            values, null = components[name]
            values[mine] = measurements[mine, j]
            null[mine] = False
    return DetectionColumns(
        names=("time", "sensor", *union, DETECTION_ID),
        times=all_times,
        time_null=np.zeros(n + m, dtype=bool),
        sensors=[sensor_list[code].name for code in all_codes.tolist()],
        components=components,
        ids=(
            np.concatenate([ids, np.zeros(m, dtype=np.int64)]),
            np.concatenate([np.zeros(n, dtype=bool), np.ones(m, dtype=bool)]),
        ),
    )


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
