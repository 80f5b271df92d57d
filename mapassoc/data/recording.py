"""A user's own recording: its times and coordinates to the estimator's, and tracks back.

A configuration with a ``[recording]`` section (:class:`Recording`) reads its detections
through this module: the ``time`` column may hold plain seconds, ISO 8601 timestamps or
typed timestamps (:mod:`mapassoc.data.times`), and in a ``frame = "geodetic"`` recording
the measurement columns are geodetic (:mod:`mapassoc.data.frames`):

========================  ================================  ==============================
sensor                    columns in the file               what the estimator sees
========================  ================================  ==============================
``position``              ``lat, lon[, alt]``               ``x, y[, z]``: ENU metres
``range_bearing``         ``range, azimuth[, elevation]``   ``range, bearing`` from the
                                                            site's place in the plane
========================  ================================  ==============================

In a ``frame = "local"`` recording the columns are the plain ones (``x, y[, z]``;
``range`` with ``bearing`` or with ``azimuth``, clockwise from the y axis).  A
``range_bearing`` sensor of a geodetic recording is placed by ``latitude, longitude
[, height]``; ``elevation`` needs its height.  Angles are in degrees unless the
recording says ``angles = "radians"``.

The rest is the one ingest path (:mod:`mapassoc.data.ingest`): every defect is one line
naming the file, the line (or 0-based row of a frame) and the column.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from mapassoc.array_types import BoolArray, FloatArray, IntArray
from mapassoc.data.frames import GeodeticPoint, LocalFrame, site_polar_to_plane
from mapassoc.data.ingest import DETECTION_ID, DetectionColumns, detection_columns_to_scans
from mapassoc.data.scans import Scan
from mapassoc.data.times import (
    NAIVE_UTC_WARNING,
    SECONDS,
    TimeBase,
    format_times,
    parse_time_cells,
    times_from_datetime64,
)
from mapassoc.errors import DataFileError, InputError
from mapassoc.models.measurement import RangeBearing
from mapassoc.models.sensor import Sensor

if TYPE_CHECKING:
    import pandas as pd

    from mapassoc.data.records import TrackTable

__all__ = [
    "Recording",
    "RecordingBase",
    "input_columns",
    "read_recording",
    "scans_from_recording_frame",
    "write_recording_tracks",
    "RECORDING_TRACKS_NAME",
]

RECORDING_TRACKS_NAME = "tracks_recording.csv"
"""The tracks in the recording's own time and frame, beside ``tracks.csv``."""

Fail = Callable[[str, str | None, int | None], Exception]
_GEO_POSITION = ("lat", "lon", "alt")
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_LOCAL_POSITION = ("x", "y", "z")


@dataclass(frozen=True)
class Recording:
    """The ``[recording]`` section: how the user's file gives times and places.

    Parameters
    ----------
    frame : {"local", "geodetic"}
    origin : GeodeticPoint, optional
        The origin of the east-north-up plane; None (``origin = "auto"``): the first
        site's place, else the centre of the data's latitudes and longitudes.
    angles : {"degrees", "radians"}
        Unit of azimuth and elevation columns.
    sites : mapping of str to GeodeticPoint
        The places of the ``range_bearing`` sensors of a geodetic recording.
    """

    frame: Literal["local", "geodetic"] = "local"
    origin: GeodeticPoint | None = None
    angles: Literal["degrees", "radians"] = "degrees"
    sites: Mapping[str, GeodeticPoint] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.frame not in ("local", "geodetic"):
            raise InputError(f"frame must be 'local' or 'geodetic', got {self.frame!r}")
        if self.angles not in ("degrees", "radians"):
            raise InputError(f"angles must be 'degrees' or 'radians', got {self.angles!r}")
        if self.frame == "local" and (self.origin is not None or self.sites):
            raise InputError("a local recording has no origin and no sites", key="origin")

    def angle(self, values: FloatArray) -> FloatArray:
        """``values`` in radians."""
        return np.radians(values) if self.angles == "degrees" else np.asarray(values, float)


@dataclass(frozen=True)
class RecordingBase:
    """What reading a recording found: its time base and the frame the run works in."""

    time: TimeBase = SECONDS
    frame: LocalFrame | None = None

    def to_json(self) -> dict[str, object]:
        origin = None if self.frame is None else self.frame.origin.to_json()
        return {"time": self.time.to_json(), "origin": origin}


def input_columns(sensor: Sensor, recording: Recording) -> tuple[str, ...]:
    """The columns a recording's file holds for ``sensor`` (measurement components)."""
    names = sensor.measurement.component_names
    if isinstance(sensor.measurement, RangeBearing):
        if recording.frame == "geodetic":
            return ("range", "azimuth")
        return names
    if recording.frame == "geodetic" and names == _LOCAL_POSITION[: len(names)]:
        return _GEO_POSITION[: len(names)]
    return names


def _optional_columns(sensor: Sensor, recording: Recording) -> tuple[str, ...]:
    if isinstance(sensor.measurement, RangeBearing):
        return ("elevation",) if recording.frame == "geodetic" else ("azimuth",)
    return ()


# --------------------------------------------------------------------------- columns


class _Columns:
    """A recording's table: columns by name, each a float array with its null mask."""

    def __init__(self, frame: pd.DataFrame, fail: Fail, text: bool) -> None:
        self.frame = frame
        self.fail = fail
        self.text = text  # cells are strings (a CSV file)
        self.names = tuple(str(name) for name in frame.columns)
        self._parsed: dict[str, tuple[FloatArray, BoolArray]] = {}

    def floats(self, name: str) -> tuple[FloatArray, BoolArray]:
        """A column as float64 with its null mask (parsed once; read-only arrays)."""
        if name not in self._parsed:
            values, null = self._floats(name)
            values.setflags(write=False)
            null.setflags(write=False)
            self._parsed[name] = (values, null)
        return self._parsed[name]

    def _floats(self, name: str) -> tuple[FloatArray, BoolArray]:
        import pandas as pd

        series = self.frame[name]
        if self.text or series.dtype == object:
            values = np.full(len(series), math.nan)
            for position, cell in enumerate(series.tolist()):
                if cell is None or cell == "" or (isinstance(cell, float) and math.isnan(cell)):
                    continue
                values[position] = self._number(cell, name, position)
            return values, np.isnan(values)
        if pd.api.types.is_bool_dtype(series.dtype) or not pd.api.types.is_numeric_dtype(
            series.dtype
        ):
            raise self.fail(f"dtype {series.dtype}; expected numbers", name, None)
        null = series.isna().to_numpy(dtype=bool)
        return series.to_numpy(dtype=np.float64, na_value=np.nan), null

    def _number(self, cell: object, name: str, position: int) -> float:
        """A finite decimal number (text cells as the CSV reader reads them)."""
        if isinstance(cell, int | float) and not isinstance(cell, bool):
            value = float(cell)
        elif isinstance(cell, str) and _NUMBER.fullmatch(cell.strip()):
            value = float(cell)
        else:
            raise self.fail(
                f"value {cell!r} is not a number; expected a decimal number such as 1.5e-3",
                name,
                position,
            )
        if not math.isfinite(value):
            raise self.fail(f"value {cell!r} is not finite; expected a finite number", name,
                            position)  # fmt: skip
        return value

    def times(self) -> tuple[FloatArray, TimeBase]:
        import pandas as pd

        series = self.frame["time"]
        if isinstance(series.dtype, pd.DatetimeTZDtype):
            utc = series.dt.tz_convert("UTC").dt.tz_localize(None)
            return times_from_datetime64(utc.to_numpy(dtype="datetime64[us]"), zoned=True)
        if pd.api.types.is_datetime64_any_dtype(series.dtype):
            warnings.warn(NAIVE_UTC_WARNING, UserWarning, stacklevel=4)
            return times_from_datetime64(series.to_numpy(dtype="datetime64[us]"), zoned=False)
        if pd.api.types.is_numeric_dtype(series.dtype) and not self.text:
            values, _ = self.floats("time")
            return values, SECONDS
        cells = ["" if _missing(c) else str(c).strip() for c in series.tolist()]
        seconds, base = parse_time_cells(cells, lambda m, p: self.fail(m, "time", p))
        if base.kind != "seconds" and not base.zoned:
            warnings.warn(NAIVE_UTC_WARNING, UserWarning, stacklevel=4)
        return seconds, base


def _missing(cell: object) -> bool:
    return cell is None or (isinstance(cell, float) and math.isnan(cell))


def _sensor_codes(columns: _Columns, sensors: Mapping[str, Sensor]) -> list[str | None]:
    n = len(columns.frame)
    if "sensor" not in columns.names:
        only = next(iter(sensors)) if len(sensors) == 1 else None
        return [only] * n
    return [None if _missing(v) else str(v).strip() for v in columns.frame["sensor"].tolist()]


def _resolve_frame(
    columns: _Columns, config: Any, owners: list[str | None]
) -> LocalFrame | None:
    """The run's plane: the configured origin, the first site, or the data's centre."""
    recording: Recording = config.recording
    if recording.frame != "geodetic":
        return None
    if recording.origin is not None:
        return LocalFrame(origin=recording.origin)
    if recording.sites:
        return LocalFrame(origin=next(iter(recording.sites.values())))
    lat, lat_null = columns.floats("lat")
    lon, _ = columns.floats("lon")
    if np.all(lat_null):
        raise columns.fail("no latitude to place an automatic origin", "lat", None)
    keep = ~lat_null
    centre_lat = float((np.min(lat[keep]) + np.max(lat[keep])) / 2)
    centre_lon = float((np.min(lon[keep]) + np.max(lon[keep])) / 2)
    height = 0.0
    if "alt" in columns.names:
        alt, alt_null = columns.floats("alt")
        height = float(np.mean(alt[~alt_null])) if np.any(~alt_null) else 0.0
    return LocalFrame(origin=GeodeticPoint(centre_lat, centre_lon, height))


def _input_name(internal: str, recording: Recording, names: tuple[str, ...]) -> str:
    """The file's column that holds the internal component ``internal``."""
    if recording.frame == "geodetic" and internal in _LOCAL_POSITION:
        return _GEO_POSITION[_LOCAL_POSITION.index(internal)]
    if internal == "bearing" and (recording.frame == "geodetic" or "bearing" not in names):
        return "azimuth"
    return internal


def _check_input_columns(
    columns: _Columns, sensors: Mapping[str, Sensor], recording: Recording
) -> None:
    names = columns.names
    required = ["time"] + (["sensor"] if len(sensors) > 1 else [])
    allowed = {"time", "sensor", DETECTION_ID}
    for sensor in sensors.values():
        own = list(input_columns(sensor, recording))
        if recording.frame == "local" and isinstance(sensor.measurement, RangeBearing):
            own = ["range", "azimuth" if "azimuth" in names else "bearing"]
        required += own
        allowed |= {*own, *_optional_columns(sensor, recording)}
    expected = ",".join(dict.fromkeys(required))
    for name in dict.fromkeys(required):
        if name not in names:
            raise columns.fail(f"no column {name!r}; expected the columns {expected}", name, None)
    for name in names:
        if name not in allowed:
            raise columns.fail(
                f"unknown column {name!r}; expected the columns {expected}", name, None
            )


def _polar_rows(
    columns: _Columns, sensor: Sensor, recording: Recording, frame: LocalFrame | None,
    take: BoolArray, key: str,
) -> tuple[FloatArray, FloatArray]:  # fmt: skip
    """Range and bearing (radians, counter-clockwise from east) of the rows ``take``."""
    r = columns.floats("range")[0][take]
    measurement = sensor.measurement
    assert isinstance(measurement, RangeBearing)
    if recording.frame == "local":
        if "azimuth" not in columns.names:
            return r, columns.floats("bearing")[0][take]
        return r, np.pi / 2 - recording.angle(columns.floats("azimuth")[0][take])
    assert frame is not None
    site = recording.sites[sensor.name]
    az = recording.angle(columns.floats("azimuth")[0][take])
    el = None
    if "elevation" in columns.names:
        raw, null = columns.floats("elevation")
        if site.height is None:
            raise columns.fail(
                f"sensor {sensor.name!r} measures elevation but its site has no height; "
                f"give {key}.height (metres above the WGS-84 ellipsoid)",
                "elevation", int(np.argmax(take)),
            )  # fmt: skip
        if np.any(null[take]):
            i = int(np.flatnonzero(take)[np.argmax(null[take])])
            raise columns.fail("empty cell; expected the plot's elevation", "elevation", i)
        el = recording.angle(raw[take])
    plane = site_polar_to_plane(frame, site, r, az, el)
    dx = plane[:, 0] - measurement.sensor_position[0]
    dy = plane[:, 1] - measurement.sensor_position[1]
    return np.hypot(dx, dy), np.arctan2(dy, dx)


def _components(
    columns: _Columns, config: Any, owners: list[str | None], frame: LocalFrame | None
) -> dict[str, tuple[FloatArray, BoolArray]]:
    """Every internal component column: converted values, nulls as the file's cells."""
    recording: Recording = config.recording
    sensors: Mapping[str, Sensor] = config.sensors
    internal = list(
        dict.fromkeys(c for s in sensors.values() for c in s.measurement.component_names)
    )
    out = {}
    for name in internal:
        source = _input_name(name, recording, columns.names)
        if source in columns.names:
            null = columns.floats(source)[1].copy()
        else:
            null = np.ones(len(owners), dtype=bool)
        out[name] = (np.full(len(owners), math.nan), null)
    if "lat" in columns.names:
        lat, lat_null = columns.floats("lat")
        bad = ~lat_null & ~((lat >= -90.0) & (lat <= 90.0))
        if np.any(bad):
            i = int(np.argmax(bad))
            raise columns.fail(f"latitude {float(lat[i])!r} is outside [-90, 90]", "lat", i)
    owner = np.array([o or "" for o in owners], dtype=object)
    for index, sensor in enumerate(sensors.values()):
        names = sensor.measurement.component_names
        complete = (owner == sensor.name) & ~np.column_stack([out[n][1] for n in names]).any(1)
        if not np.any(complete):
            continue
        if isinstance(sensor.measurement, RangeBearing):
            key = f"sensors[{index}]"
            values = np.column_stack(_polar_rows(columns, sensor, recording, frame, complete, key))
        elif recording.frame == "geodetic":
            assert frame is not None
            geo = [columns.floats(_GEO_POSITION[k])[0][complete] for k in range(len(names))]
            enu = frame.to_local(geo[0], geo[1], geo[2] if len(names) == 3 else None)
            values = enu[:, : len(names)]
        else:
            values = np.column_stack([columns.floats(n)[0][complete] for n in names])
        for k, name in enumerate(names):
            out[name][0][complete] = values[:, k]
    return out


def scans_from_recording_frame(
    frame: pd.DataFrame,
    config: Any,
    *,
    fail: Fail | None = None,
    row_ids: IntArray | None = None,
    text: bool = False,
) -> tuple[list[Scan], RecordingBase]:
    """Scans in the estimator's frame from a table of a recording, and its base.

    Parameters
    ----------
    frame : pandas.DataFrame
        The recording's columns (see the module docstring); ``time`` numbers, ISO 8601
        text or ``datetime64`` (naive: UTC, with a warning; zoned: converted to UTC).
    config : Config
        With a ``recording`` (:class:`Recording`).
    fail : callable, optional
        ``fail(message, column, row)`` builds the error (default: an InputError naming
        the 0-based row and the column).
    row_ids : ndarray of int64, optional
        The detection id of each row (a CSV file's line numbers); default the positions.
    text : bool
        Whether every cell is text (read from a CSV file).

    Returns
    -------
    scans : list of Scan
    base : RecordingBase
    """
    import pandas as pd

    if not isinstance(frame, pd.DataFrame):
        raise InputError(f"frame must be a pandas DataFrame, got {type(frame).__name__}")
    recording = getattr(config, "recording", None)
    if not isinstance(recording, Recording):
        raise InputError("config has no [recording] section (Config.recording is None)")
    base_fail = fail if fail is not None else _frame_fail
    columns = _Columns(frame, base_fail, text)
    _check_input_columns(columns, config.sensors, recording)
    owners = _sensor_codes(columns, config.sensors)
    local = _resolve_frame(columns, config, owners)
    times, time_base = columns.times()
    renamed = {n: _input_name(n, recording, columns.names) for n in _LOCAL_POSITION + ("bearing",)}

    def mapped(message: str, column: str | None, row: int | None) -> Exception:
        return base_fail(message, renamed.get(column or "", column), row)

    columns.fail = mapped
    components = _components(columns, config, owners, local)
    ids = _ids(columns) if DETECTION_ID in columns.names else None
    names = ("time",) + (("sensor",) if "sensor" in columns.names else ()) + tuple(components)
    table = DetectionColumns(
        names=names + ((DETECTION_ID,) if ids is not None else ()),
        times=np.where(np.isnan(times), 0.0, times),
        time_null=np.isnan(times),
        sensors=owners if "sensor" in columns.names else None,
        components=components,
        ids=ids,
        row_ids=row_ids,
    )
    scans = detection_columns_to_scans(table, config.sensors, mapped)
    return scans, RecordingBase(time=time_base, frame=local)


def _ids(columns: _Columns) -> tuple[IntArray, BoolArray]:
    """The ``detection_id`` column: whole numbers (the ingest path checks the rest)."""
    values, null = columns.floats(DETECTION_ID)
    whole = null | ((values == np.round(values)) & (np.abs(values) < 2.0**53))
    if not np.all(whole):
        i = int(np.argmax(~whole))
        raise columns.fail(
            f"value {float(values[i])!r} is not a whole number; expected a detection id",
            DETECTION_ID,
            i,
        )
    return np.where(null, -1, values).astype(np.int64), null


def _frame_fail(message: str, column: str | None, row: int | None) -> InputError:
    where = "frame" + ("" if row is None else f" row {row} (0-based position)")
    where += "" if column is None else f", column {column!r}"
    return InputError(f"{where}: {message}")


def read_recording(
    path: str | os.PathLike[str], config: Any, *, content: bytes | None = None,
    format_name: str | None = None,
) -> tuple[list[Scan], RecordingBase]:  # fmt: skip
    """Read a recording's detections file (CSV, or Parquet by suffix or ``format_name``).

    Errors are :class:`~mapassoc.errors.DataFileError` naming the file, the line (CSV;
    the row position + 2 for Parquet, as its readers number rows from the header) and
    the column.  Detection ids are the CSV line numbers, or a ``detection_id`` column.
    """
    import io as std_io

    import pandas as pd

    from mapassoc.data.io import read_cells

    name = os.fspath(path)
    parquet = (format_name or "").lower() == "parquet" or (
        format_name is None and name.lower().endswith((".parquet", ".pq"))
    )
    if parquet:
        try:
            frame = pd.read_parquet(name if content is None else std_io.BytesIO(content))
        except Exception as exc:  # pyarrow's own errors: not a Parquet file and so on
            raise DataFileError(name, f"cannot read the Parquet file: {exc}") from None

        def fail(message: str, column: str | None, row: int | None) -> Exception:
            return DataFileError(name, message + ("" if row is None else f" (row {row})"),
                                 column=column)  # fmt: skip

        return scans_from_recording_frame(frame, config, fail=fail)
    header, lines_list, cells = read_cells(name, content)
    frame = pd.DataFrame({column: cells[k] for k, column in enumerate(header)}, dtype=object)
    lines = np.array(lines_list, dtype=np.int64)

    def fail_line(message: str, column: str | None, row: int | None) -> Exception:
        return DataFileError(name, message, row=1 if row is None else int(lines[row]),
                             column=column)  # fmt: skip

    return scans_from_recording_frame(frame, config, fail=fail_line, row_ids=lines, text=True)


# --------------------------------------------------------------------------- tracks


def recording_track_columns(
    table: TrackTable, base: RecordingBase
) -> dict[str, list[str]]:
    """The columns of the recording's tracks file as text cells."""
    columns: dict[str, list[str]] = {
        "track_id": [str(int(v)) for v in table.track_ids],
        "time": format_times(table.times, base.time),
        "sensor": list(table.sensors),
    }
    names = list(table.state_names)
    if base.frame is not None and {"x", "y"} <= set(names):
        x = table.states[:, names.index("x")]
        y = table.states[:, names.index("y")]
        if "z" in names:
            geo = base.frame.to_geodetic(
                np.column_stack([x, y, table.states[:, names.index("z")]])
            )
            columns["alt"] = [repr(float(v)) for v in geo[:, 2]]
        else:
            geo = base.frame.plane_to_geodetic(x, y) if table.size else np.zeros((0, 2))
        columns["lat"] = [repr(float(v)) for v in geo[:, 0]]
        columns["lon"] = [repr(float(v)) for v in geo[:, 1]]
        order = ["track_id", "time", "sensor", "lat", "lon"] + (["alt"] if "z" in names else [])
        columns = {key: columns[key] for key in order}
    for k, state in enumerate(names):
        columns[state] = [repr(float(v)) for v in table.states[:, k]]
    columns["detection_row"] = ["" if r < 0 else str(int(r)) for r in table.detection_rows]
    return columns


def write_recording_tracks(
    path: str | os.PathLike[str], table: TrackTable, base: RecordingBase
) -> None:
    """Write the tracks in the recording's time and frame (:data:`RECORDING_TRACKS_NAME`).

    Columns ``track_id, time, sensor[, lat, lon[, alt]], <state names>, detection_row``:
    ``time`` of the input's kind (ISO 8601 UTC for timestamps), ``lat, lon`` (degrees)
    of each track point in a geodetic recording, beside the local state in metres from
    the origin that ``summary.json`` records.
    """
    import csv

    columns = recording_track_columns(table, base)
    try:
        with open(path, "w", encoding="utf-8", newline="") as handle:
            writer = csv.writer(handle, lineterminator="\n")
            writer.writerow(list(columns))
            writer.writerows(zip(*columns.values(), strict=True))
    except OSError as exc:
        reason = exc.strerror or exc
        raise DataFileError(os.fspath(path), f"cannot write the file: {reason}") from None
