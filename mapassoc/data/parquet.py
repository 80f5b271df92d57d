"""Data files as Parquet: detections, tracks and truth (needs the optional ``pyarrow``).

The tables have the columns of the CSV files of :mod:`mapassoc.data.io`, typed:

1. Detections: ``time`` (float64), ``sensor`` (string), the measurement components of
   the sensors (float64; the union in first-sensor order, as in the CSV), and
   ``detection_id`` (int64).  One row per detection; a scan without detections is one row
   with ``time`` and ``sensor`` and every measurement cell null (and ``detection_id``
   null), like the CSV's line of empty cells.  Null is the empty cell; a NaN value is an
   error, as are infinities.  Unlike a CSV file, rows may come in any order: they are
   grouped by ``(time, sensor)`` and the scans sorted by ``(time, sensor name)``,
   detections in row order within a scan.  The detection ids (``Scan.rows``) are the
   ``detection_id`` column if the file has one, else the 0-based row index (the rows of
   empty scans use up an index, as they use up a line in a CSV file).  The writer always
   writes ``detection_id``, so write-then-read keeps every id.  The ``sensor`` column may
   be left out when one sensor is configured.
2. Truth: ``target_id`` (int64), ``time`` (float64), the state components (float64).
3. Tracks: ``track_id`` (int64), ``time`` (float64), ``sensor`` (string), the state
   components, ``var_`` + each state component (float64), ``detection_row`` (int64, the id
   of the detection used; null for a miss), for a set of motion models optionally
   ``p_`` + each model name (float64, the smoothed model probabilities; never null, in
   [0, 1], a row's summing to 1 within 1e-6), and optionally ``existence`` (float64, the
   track's existence probability; null where unknown), last.

Readers accept any integer type for integer columns and any numeric type for float
columns, and string or dictionary-encoded string columns for ``sensor``; a column that
pandas wrote for a DataFrame index is ignored.  Floats are stored as float64, so write
then read is exact (bit for bit, including ``-0.0``).

pyarrow is imported when a function is called; without it they raise
:class:`~mapassoc.errors.InputError` saying how to install it.  Every problem with a file
raises :class:`~mapassoc.errors.DataFileError` naming the file, the column and, where one
row is at fault, its 0-based row index.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import BoolArray, FloatArray, IntArray
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
    TRUTH_FIXED_COLUMNS,
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
    "read_detections_parquet",
    "write_detections_parquet",
    "read_tracks_parquet",
    "write_tracks_parquet",
    "read_truth_parquet",
    "write_truth_parquet",
    "read_origins_parquet",
    "write_origins_parquet",
]

PathLike = str | os.PathLike[str]
_INT64_MAX = np.iinfo(np.int64).max
_ORIGINS_COLUMNS = ORIGINS_COLUMNS


def _pyarrow(verb: str) -> tuple[Any, Any, Any]:
    """``(pyarrow, pyarrow.compute, pyarrow.parquet)``, or an InputError saying how to
    install pyarrow; ``verb`` is "reading" or "writing"."""
    try:
        import pyarrow as pa
        import pyarrow.compute as pc
        import pyarrow.parquet as pq
    except ImportError:
        raise InputError(f"{verb} Parquet needs pyarrow: pip install 'mapassoc[parquet]'") from None
    return pa, pc, pq


def _error(
    path: str, message: str, column: str | None = None, row: int | None = None
) -> DataFileError:
    """A DataFileError; ``row`` is a 0-based row index (Parquet has no lines)."""
    if row is not None:
        message = f"row index {row} (0-based): {message}"
    return DataFileError(path, message, column=column)


# --------------------------------------------------------------------------- reading


class _Reader:
    """One Parquet table being read, with typed column access that names the file."""

    def __init__(self, path: str, content: bytes | None = None) -> None:
        self.path = path
        self.pa, self.pc, pq = _pyarrow("reading")
        try:
            table = pq.read_table(path if content is None else self.pa.BufferReader(content))
        except OSError as exc:
            raise DataFileError(path, f"cannot read the file: {exc}") from None
        except self.pa.ArrowException as exc:
            raise DataFileError(path, f"not a readable Parquet file: {exc}") from None
        index_columns = (table.schema.pandas_metadata or {}).get("index_columns", [])
        self.names = tuple(
            name
            for name in table.column_names
            if not (isinstance(name, str) and name in index_columns)
        )
        self.table = table
        self.size = table.num_rows

    def check_distinct(self, expected: str) -> None:
        seen: set[str] = set()
        for name in self.names:
            if name in seen:
                raise _error(self.path, f"column {name!r} appears twice; expected {expected}", name)
            seen.add(name)

    def _column(self, name: str) -> Any:
        return self.table.column(name)

    def nulls(self, name: str) -> BoolArray:
        return np.asarray(
            self._column(name).is_null().to_numpy(zero_copy_only=False), dtype=bool
        ).reshape(self.size)

    def floats(
        self, name: str, *, nullable: bool, finite: bool = True
    ) -> tuple[FloatArray, BoolArray]:
        """float64 values (0 where null) and the null mask of column ``name``."""
        pa, pc = self.pa, self.pc
        column = self._column(name)
        kind = column.type
        if pa.types.is_null(kind):
            values = np.zeros(self.size)
        elif pa.types.is_floating(kind) or pa.types.is_integer(kind):
            try:
                cast = pc.cast(column, pa.float64())
            except pa.ArrowException as exc:
                raise _error(self.path, f"cannot be read as float64: {exc}", name) from None
            values = np.asarray(
                pc.fill_null(cast, 0.0).to_numpy(zero_copy_only=False), dtype=np.float64
            ).reshape(self.size)
        else:
            raise _error(self.path, f"type {kind}; expected float64 (or another number type)", name)
        null = self.nulls(name)
        if not nullable and np.any(null):
            raise _error(self.path, "empty (null) cell; expected a number", name, _first(null))
        if finite:
            bad = ~null & ~np.isfinite(values)
            if np.any(bad):
                i = _first(bad)
                raise _error(
                    self.path,
                    f"value {float(values[i])!r} is not finite; expected a finite number",
                    name,
                    i,
                )
        return values, null

    def ints(self, name: str, *, nullable: bool, minimum: int) -> tuple[IntArray, BoolArray]:
        """int64 values (-1 where null) and the null mask of column ``name``."""
        pa, pc = self.pa, self.pc
        column = self._column(name)
        kind = column.type
        null = self.nulls(name)
        if pa.types.is_null(kind):
            values = np.full(self.size, -1, dtype=np.int64)
        elif pa.types.is_integer(kind):
            raw = np.asarray(pc.fill_null(column, 0).to_numpy(zero_copy_only=False))
            raw = raw.reshape(self.size)
            if raw.dtype == np.uint64 and raw.size and int(raw.max()) > _INT64_MAX:
                i = _first(raw > _INT64_MAX)
                raise _error(self.path, f"value {int(raw[i])} does not fit in int64", name, i)
            values = np.where(null, -1, raw.astype(np.int64))
        else:
            raise _error(self.path, f"type {kind}; expected int64 (or another integer type)", name)
        if not nullable and np.any(null):
            raise _error(
                self.path,
                f"empty (null) cell; expected an integer >= {minimum}",
                name,
                _first(null),
            )
        below = ~null & (values < minimum)
        if np.any(below):
            i = _first(below)
            raise _error(
                self.path,
                f"value {int(values[i])} is below the minimum; expected an integer >= {minimum}",
                name,
                i,
            )
        return values, null

    def strings(self, name: str, *, nullable: bool) -> list[object]:
        """The values of a string column (None where null)."""
        pa = self.pa
        kind = self._column(name).type
        is_text = getattr(pa.types, "is_string_view", lambda _: False)
        if pa.types.is_dictionary(kind):
            kind = kind.value_type
        if not (pa.types.is_string(kind) or pa.types.is_large_string(kind) or is_text(kind)):
            if not pa.types.is_null(kind):
                raise _error(self.path, f"type {kind}; expected strings (sensor names)", name)
        values = self._column(name).to_pylist()
        if not nullable:
            for i, value in enumerate(values):
                if value is None or value == "":
                    raise _error(self.path, "empty cell; expected a sensor name", name, i)
        return values


def _first(mask: NDArray[np.bool_]) -> int:
    return int(np.argmax(mask))


def _pairs_repeated(path: str, keys: Sequence[tuple[object, ...]], what: str, column: str) -> None:
    first: dict[tuple[object, ...], int] = {}
    for i, key in enumerate(keys):
        if key in first:
            raise _error(path, f"{what} {key} already appears at row index {first[key]}", column, i)
        first[key] = i


def read_detections_parquet(
    path: PathLike, sensors: Mapping[str, Sensor], *, content: bytes | None = None
) -> list[Scan]:
    """Read a detections Parquet file (format 1 of the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    sensors : mapping of str to Sensor
        The configured sensors by name.
    content : bytes, optional
        The file's bytes, read already (see :func:`mapassoc.data.io.read_detections`);
        ``path`` then only names it in errors.

    Returns
    -------
    list of Scan
        Sorted by ``(time, sensor name)``, at least one; ``rows`` the ``detection_id``
        values, else the 0-based row indices of the detections.

    Raises
    ------
    InputError
        pyarrow is not installed, or ``sensors`` is empty or inconsistent.
    DataFileError
        The file cannot be read, a column is missing, unknown, repeated or of the wrong
        type, a time is empty or not finite, a sensor unknown, a measurement partly
        filled, in another sensor's column or not finite (NaN included), an id missing,
        negative or repeated, or the file has no row.
    """
    path = check_path("read_detections_parquet: path", path)
    if content is not None:
        check_instance(
            "read_detections_parquet: content", content, bytes, expected="bytes (the file's)"
        )
    _pyarrow("reading")
    sensor_list = check_sensors(sensors)
    reader = _Reader(path, content)

    def fail(message: str, column: str | None, row: int | None) -> DataFileError:
        return _error(path, message, column, row)

    check_detection_columns(reader.names, sensors, fail)
    union = measurement_columns(sensor_list)
    times, time_null = reader.floats("time", nullable=True, finite=False)
    table = DetectionColumns(
        names=reader.names,
        times=times,
        time_null=time_null,
        sensors=reader.strings("sensor", nullable=True) if "sensor" in reader.names else None,
        components={name: reader.floats(name, nullable=True, finite=False) for name in union},
        ids=(
            reader.ints(DETECTION_ID, nullable=True, minimum=0)
            if DETECTION_ID in reader.names
            else None
        ),
    )
    return detection_columns_to_scans(table, sensors, fail)


def read_tracks_parquet(path: PathLike) -> TrackTable:
    """Read a tracks Parquet file (format 3 of the module docstring).

    Returns
    -------
    TrackTable
        In file order; a null ``detection_row`` (miss) becomes -1.

    Raises
    ------
    InputError
        pyarrow is not installed.
    DataFileError
        The file cannot be read; columns missing, out of order (the ``var_`` columns follow
        the state columns in the same order) or of the wrong type; an empty or non-finite
        value, a negative track id, variance or detection id, an empty sensor, or a repeated
        (track_id, time, sensor).
    """
    path = check_path("read_tracks_parquet: path", path)
    reader = _Reader(path)
    names, var_names = track_state_names(path, list(reader.names), row=None)
    model_names = track_model_names(list(reader.names))
    existence = None
    if reader.names and reader.names[-1] == EXISTENCE_COLUMN:
        values, missing = reader.floats(EXISTENCE_COLUMN, nullable=True)
        existence = np.where(missing, np.nan, values)
        bad = ~np.isnan(existence) & ((existence < 0) | (existence > 1))
        if np.any(bad):
            i = _first(bad)
            raise _error(
                path, f"existence {float(existence[i])!r} is not in [0, 1]", EXISTENCE_COLUMN, i
            )
    reader.check_distinct(",".join(reader.names))
    ids, _ = reader.ints("track_id", nullable=False, minimum=0)
    times, _ = reader.floats("time", nullable=False)
    sensors = reader.strings("sensor", nullable=False)
    states = _stack([reader.floats(name, nullable=False)[0] for name in names], reader.size)
    variances = []
    for name in var_names:
        values, _ = reader.floats(name, nullable=False)
        if np.any(values < 0):
            i = _first(values < 0)
            raise _error(path, f"variance {float(values[i])!r} is negative; expected >= 0", name, i)
        variances.append(values)
    rows, _ = reader.ints(TRACK_ROW_COLUMN, nullable=True, minimum=0)
    probabilities = _model_probabilities(reader, model_names)
    _pairs_repeated(
        path,
        list(zip(ids.tolist(), times.tolist(), sensors, strict=True)),
        "(track_id, time, sensor)",
        "time",
    )
    try:
        return TrackTable(
            track_ids=ids,
            times=times,
            sensors=tuple(str(s) for s in sensors),
            states=states,
            variances=_stack(variances, reader.size),
            detection_rows=rows,
            state_names=tuple(names),
            existence=existence,
            model_probabilities=probabilities,
            model_names=tuple(model_names),
        )
    except InputError as exc:
        raise DataFileError(path, str(exc)) from None


def read_truth_parquet(path: PathLike) -> TruthTable:
    """Read a truth Parquet file (format 2 of the module docstring).

    Returns
    -------
    TruthTable
        In file order.

    Raises
    ------
    InputError
        pyarrow is not installed.
    DataFileError
        The file cannot be read; columns missing or of the wrong type; an empty or
        non-finite value, a negative target id, or a repeated (target_id, time).
    """
    path = check_path("read_truth_parquet: path", path)
    reader = _Reader(path)
    names = truth_state_names(path, list(reader.names), row=None)
    reader.check_distinct(",".join(reader.names))
    ids, _ = reader.ints("target_id", nullable=False, minimum=0)
    times, _ = reader.floats("time", nullable=False)
    states = _stack([reader.floats(name, nullable=False)[0] for name in names], reader.size)
    _pairs_repeated(
        path, list(zip(ids.tolist(), times.tolist(), strict=True)), "(target_id, time)", "time"
    )
    try:
        return TruthTable(target_ids=ids, times=times, states=states, state_names=tuple(names))
    except InputError as exc:
        raise DataFileError(path, str(exc)) from None


def read_origins_parquet(path: PathLike) -> Origins:
    """Read an origins Parquet file: columns ``row`` (detection id) and ``target_id`` (null
    for a false alarm), like the CSV origins file.

    Returns
    -------
    Origins
        In file order; a null ``target_id`` becomes -1.

    Raises
    ------
    InputError
        pyarrow is not installed.
    DataFileError
        The file cannot be read; other columns than ``row,target_id``; a null or negative
        ``row``, a negative ``target_id``, or a repeated ``row``.
    """
    path = check_path("read_origins_parquet: path", path)
    reader = _Reader(path)
    if sorted(reader.names) != sorted(_ORIGINS_COLUMNS):
        raise DataFileError(
            path, f"columns {','.join(reader.names)}; expected {','.join(_ORIGINS_COLUMNS)}"
        )
    rows, _ = reader.ints("row", nullable=False, minimum=0)
    ids, _ = reader.ints("target_id", nullable=True, minimum=0)
    try:
        return Origins(rows=rows, target_ids=ids)
    except InputError as exc:
        raise DataFileError(path, str(exc)) from None


def _stack(columns: Sequence[FloatArray], size: int) -> FloatArray:
    return np.column_stack(columns) if columns else np.zeros((size, 0))


# --------------------------------------------------------------------------- writing


def _write(pq: Any, pa: Any, path: str, table: Any) -> None:
    try:
        pq.write_table(table, path)
    except (OSError, pa.ArrowException) as exc:
        raise DataFileError(path, f"cannot write the file: {exc}") from None


def write_detections_parquet(
    path: PathLike, scans: Sequence[Scan], sensors: Mapping[str, Sensor]
) -> None:
    """Write scans as a detections Parquet file (format 1 of the module docstring).

    Scans are written in the given order, one row per detection (with its id) and one row
    per empty scan.  Reading the file back gives the same scans, sorted by (time, sensor
    name), with the same ids.

    Parameters
    ----------
    path : str or os.PathLike
        The file (overwritten).
    scans : sequence of Scan
        At least one, in non-decreasing time, one scan per (sensor, time), detection ids
        distinct across scans.
    sensors : mapping of str to Sensor
        The configured sensors (fixes the column order: ``time,sensor,<component union>,
        detection_id``).

    Raises
    ------
    InputError
        pyarrow is not installed; no scan; a scan of an unknown sensor, of the wrong
        dimension, out of time order or repeated; a detection id in two scans.
    DataFileError
        The file cannot be written.
    """
    path = check_path("write_detections_parquet: path", path)
    pa, _, pq = _pyarrow("writing")
    sensor_list = check_sensors(sensors)
    union = measurement_columns(sensor_list)
    check_scans_for_writing(scans, sensors)
    all_ids = np.concatenate([scan.rows for scan in scans])
    if np.unique(all_ids).size != all_ids.size:
        ordered = np.sort(all_ids)
        repeated = sorted(set(ordered[1:][ordered[1:] == ordered[:-1]].tolist()))[:5]
        raise InputError(f"detection ids (Scan.rows) {repeated} appear in more than one scan")

    sizes = np.array([max(scan.size, 1) for scan in scans], dtype=np.int64)
    count = int(sizes.sum())
    times = np.repeat(np.array([scan.time for scan in scans], dtype=np.float64), sizes)
    names = np.repeat(np.array([scan.sensor for scan in scans], dtype=object), sizes)
    values = {name: np.zeros(count) for name in union}
    nulls = {name: np.ones(count, dtype=bool) for name in union}
    ids = np.zeros(count, dtype=np.int64)
    id_null = np.ones(count, dtype=bool)
    start = 0
    for scan, size in zip(scans, sizes.tolist(), strict=True):
        if scan.size:
            stop = start + scan.size
            components = sensors[scan.sensor].measurement.component_names
            for j, name in enumerate(components):
                values[name][start:stop] = scan.detections[:, j]
                nulls[name][start:stop] = False
            ids[start:stop] = scan.rows
            id_null[start:stop] = False
        start += size
    columns = {
        "time": pa.array(times, type=pa.float64()),
        "sensor": pa.array(names.tolist(), type=pa.string()),
        **{name: pa.array(values[name], type=pa.float64(), mask=nulls[name]) for name in union},
        DETECTION_ID: pa.array(ids, type=pa.int64(), mask=id_null),
    }
    _write(pq, pa, path, pa.table(columns))


def _model_probabilities(reader: _Reader, model_names: Sequence[str]) -> FloatArray | None:
    """The ``p_<model>`` columns as an ``(N, M)`` array (``None`` without them): never
    null, each in [0, 1], each row summing to 1 within the tolerance of a TrackTable."""
    if not model_names:
        return None
    columns = []
    for name in model_names:
        column = MODEL_PROBABILITY_PREFIX + name
        values, _ = reader.floats(column, nullable=False)
        bad = (values < 0) | (values > 1)
        if np.any(bad):
            i = _first(bad)
            raise _error(
                reader.path, f"model probability {float(values[i])!r} is not in [0, 1]",
                column, i,
            )  # fmt: skip
        columns.append(values)
    out = _stack(columns, reader.size)
    sums = out.sum(axis=1)
    off = np.abs(sums - 1.0) > MODEL_PROBABILITY_TOLERANCE
    if np.any(off):
        i = _first(off)
        raise _error(
            reader.path,
            f"model probabilities sum to {float(sums[i])!r}; expected 1 within "
            f"{MODEL_PROBABILITY_TOLERANCE:g}",
            MODEL_PROBABILITY_PREFIX + model_names[0],
            i,
        )
    return out


def write_tracks_parquet(path: PathLike, table: TrackTable) -> None:
    """Write a tracks Parquet file (format 3) in the table's record order; a miss gets a
    null ``detection_row``.

    Raises
    ------
    InputError
        pyarrow is not installed, or ``table`` is not a TrackTable.
    DataFileError
        The file cannot be written.
    """
    path = check_path("write_tracks_parquet: path", path)
    pa, _, pq = _pyarrow("writing")
    if not isinstance(table, TrackTable):
        raise InputError(f"table must be a TrackTable, got {table!r}")
    rows = table.detection_rows
    columns = {
        TRACK_FIXED_COLUMNS[0]: pa.array(table.track_ids, type=pa.int64()),
        TRACK_FIXED_COLUMNS[1]: pa.array(table.times, type=pa.float64()),
        TRACK_FIXED_COLUMNS[2]: pa.array(list(table.sensors), type=pa.string()),
        **_float_columns(pa, table.state_names, table.states),
        **_float_columns(pa, table.state_names, table.variances, prefix=VARIANCE_PREFIX),
        TRACK_ROW_COLUMN: pa.array(rows, type=pa.int64(), mask=rows < 0),
    }
    if table.model_probabilities is not None:
        columns.update(
            _float_columns(
                pa, table.model_names, table.model_probabilities, prefix=MODEL_PROBABILITY_PREFIX
            )
        )
    if table.existence is not None:
        columns[EXISTENCE_COLUMN] = pa.array(
            table.existence, type=pa.float64(), mask=np.isnan(table.existence)
        )
    _write(pq, pa, path, pa.table(columns))


def _float_columns(
    pa: Any, names: Sequence[str], values: FloatArray, *, prefix: str = ""
) -> dict[str, Any]:
    """One float64 column ``prefix + name`` per column of ``values`` (shape ``(n, len(names))``)."""
    return {
        prefix + name: pa.array(values[:, k], type=pa.float64()) for k, name in enumerate(names)
    }


def write_truth_parquet(path: PathLike, table: TruthTable) -> None:
    """Write a truth Parquet file (format 2) in the table's record order.

    Raises
    ------
    InputError
        pyarrow is not installed, or ``table`` is not a TruthTable.
    DataFileError
        The file cannot be written.
    """
    path = check_path("write_truth_parquet: path", path)
    pa, _, pq = _pyarrow("writing")
    if not isinstance(table, TruthTable):
        raise InputError(f"table must be a TruthTable, got {table!r}")
    columns = {
        TRUTH_FIXED_COLUMNS[0]: pa.array(table.target_ids, type=pa.int64()),
        TRUTH_FIXED_COLUMNS[1]: pa.array(table.times, type=pa.float64()),
        **_float_columns(pa, table.state_names, table.states),
    }
    _write(pq, pa, path, pa.table(columns))


def write_origins_parquet(path: PathLike, origins: Origins) -> None:
    """Write an origins Parquet file (a false alarm's ``target_id`` is null).

    Raises
    ------
    InputError
        pyarrow is not installed, or ``origins`` is not an Origins.
    DataFileError
        The file cannot be written.
    """
    path = check_path("write_origins_parquet: path", path)
    pa, _, pq = _pyarrow("writing")
    if not isinstance(origins, Origins):
        raise InputError(f"origins must be an Origins, got {origins!r}")
    ids = origins.target_ids
    columns = {
        "row": pa.array(origins.rows, type=pa.int64()),
        "target_id": pa.array(ids, type=pa.int64(), mask=ids < 0),
    }
    _write(pq, pa, path, pa.table(columns))
