"""The record types of the data files and their column layout, apart from any file format.

:class:`TruthTable`, :class:`Origins` and :class:`TrackTable` are what every reader
returns and every writer takes (CSV in :mod:`mapassoc.data.io`, Parquet in
:mod:`mapassoc.data.parquet`, in-memory tables in :mod:`mapassoc.data.tables`); the column
names, the checks of a sensor mapping and of scans to write, and the parsing of a truth or
tracks header into state names are shared by all of them from here.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.data.scans import Scan
from mapassoc.errors import DataFileError, InputError
from mapassoc.models.sensor import Sensor
from mapassoc.validation import check_numeric_array

__all__ = [
    "TruthTable",
    "Origins",
    "TrackTable",
    "TRUTH_FIXED_COLUMNS",
    "ORIGINS_COLUMNS",
    "TRACK_FIXED_COLUMNS",
    "TRACK_ROW_COLUMN",
    "EXISTENCE_COLUMN",
    "VARIANCE_PREFIX",
    "MODEL_PROBABILITY_PREFIX",
    "TRUTH_HEADER",
    "TRACKS_HEADER",
    "check_sensors",
    "measurement_columns",
    "check_scans_for_writing",
    "truth_state_names",
    "track_state_names",
    "track_model_names",
]

TRUTH_FIXED_COLUMNS = ("target_id", "time")
"""The first columns of a truth table; its state columns follow."""
ORIGINS_COLUMNS = ("row", "target_id")
"""The columns of an origins table."""
TRACK_FIXED_COLUMNS = ("track_id", "time", "sensor")
"""The first columns of a tracks table; its state and variance columns follow."""
TRACK_ROW_COLUMN = "detection_row"
"""The tracks table's column of the detection each row is updated with."""
EXISTENCE_COLUMN = "existence"
"""The tracks table's optional last column (the refined tracks' existence)."""
VARIANCE_PREFIX = "var_"
"""Prefix of a state component's variance column in a tracks table."""
MODEL_PROBABILITY_PREFIX = "p_"
"""Prefix of a model's probability column in a tracks table of a model set: the optional
columns ``p_<model name>`` after ``detection_row`` (and before ``existence``, which stays
the last column, so that a reader that looks for it there still finds it)."""
MODEL_PROBABILITY_TOLERANCE = 1e-6
"""How far from 1 a record's model probabilities may sum (the smoother normalises in log
space, so its rows are within rounding of 1; a file written by hand to 6 digits is too)."""


def check_sensors(sensors: Mapping[str, Sensor]) -> list[Sensor]:
    """The sensors of ``sensors`` as a list, refusing an empty mapping or a value that is
    not a ``Sensor``."""
    if not isinstance(sensors, Mapping) or len(sensors) == 0:
        raise InputError(f"sensors must be a non-empty mapping name -> Sensor, got {sensors!r}")
    for name, sensor in sensors.items():
        if not isinstance(sensor, Sensor):
            raise InputError(f"sensors[{name!r}] must be a Sensor, got {sensor!r}")
        if sensor.name != name:
            raise InputError(
                f"sensors mapping key {name!r} differs from the sensor's name {sensor.name!r}"
            )
    return list(sensors.values())


def measurement_columns(sensors: Sequence[Sensor]) -> list[str]:
    """Measurement component names of all sensors, first-sensor order, no repeats."""
    union: list[str] = []
    for sensor in sensors:
        for name in sensor.measurement.component_names:
            if name in ("time", "sensor"):
                raise InputError(
                    f"sensor {sensor.name!r} has a measurement component named {name!r}, "
                    "which is reserved for the detections file"
                )
            if name not in union:
                union.append(name)
    return union

def check_scans_for_writing(scans: Sequence[Scan], sensors: Mapping[str, Sensor]) -> None:
    """Refuse scans that cannot be written for ``sensors`` (not a sequence of ``Scan``,
    empty, or of an unknown sensor), naming the problem."""
    if isinstance(scans, str) or not isinstance(scans, Sequence):
        raise InputError(f"scans must be a sequence of Scan, got {scans!r}")
    if len(scans) == 0:
        raise InputError(
            "scans is empty; a detections file needs at least one scan (the readers refuse a "
            "file without one)"
        )
    seen: set[tuple[str, float]] = set()
    previous_time = -math.inf
    for index, scan in enumerate(scans):
        if not isinstance(scan, Scan):
            raise InputError(f"scans[{index}] must be a Scan, got {scan!r}")
        if scan.sensor not in sensors:
            raise InputError(
                f"scans[{index}] is from sensor {scan.sensor!r}; expected one of {list(sensors)}"
            )
        dim = sensors[scan.sensor].measurement.measurement_dim
        if scan.detections.shape[1] != dim:
            raise InputError(
                f"scans[{index}] detections have shape {scan.detections.shape}; sensor "
                f"{scan.sensor!r} measures {dim} components, expected shape ({scan.size}, {dim})"
            )
        if scan.time < previous_time:
            raise InputError(
                f"scans[{index}] time {scan.time!r} is before the previous scan's time "
                f"{previous_time!r}; scans must be written in non-decreasing time"
            )
        previous_time = scan.time
        key = (scan.sensor, scan.time)
        if key in seen:
            raise InputError(
                f"scans[{index}] repeats sensor {scan.sensor!r} at time {scan.time!r}; "
                "expected one scan per (sensor, time)"
            )
        seen.add(key)

def _check_plain_name(what: str, name: object, forbidden: str, described: str) -> None:
    """Refuse a column or sensor name a CSV cell cannot hold as it is."""
    if (
        not isinstance(name, str)
        or not name
        or name != name.strip()
        or any(ch in name for ch in forbidden)
    ):
        raise InputError(
            f"{what} name {name!r} must be a non-empty string without {described} or "
            "surrounding spaces"
        )


def _check_state_names(names: object, reserved: Sequence[str]) -> tuple[str, ...]:
    if isinstance(names, str) or not isinstance(names, Sequence):
        raise InputError(f"state_names must be a tuple of column names, got {names!r}")
    out = tuple(names)
    if not out:
        raise InputError("state_names must name at least one state component, got ()")
    for name in out:
        _check_plain_name("state", name, ',"\r\n', "commas, quotes, line breaks")
        if name in reserved:
            raise InputError(f"state name {name!r} clashes with the fixed column {name!r}")
    if len(set(out)) != len(out):
        raise InputError(f"state_names must be distinct, got {out!r}")
    return out


def _int_array(
    name: str,
    value: ArrayLike,
    *,
    minimum: int,
    length: int | None,
    expected: str | None = None,
) -> IntArray:
    arr = np.asarray(value)
    if arr.size == 0:
        arr = arr.astype(np.int64)
    if arr.ndim != 1 or not np.issubdtype(arr.dtype, np.integer):
        raise InputError(
            f"{name} must be a 1-D integer array, got dtype {arr.dtype} and shape {arr.shape}"
        )
    if length is not None and arr.shape[0] != length:
        raise InputError(f"{name} must have shape ({length},), got {arr.shape}")
    if arr.size and int(arr.min()) < minimum:
        raise InputError(
            f"{name} must be {expected or f'>= {minimum}'}, got the value {int(arr.min())}"
        )
    out = arr.astype(np.int64)
    out.setflags(write=False)
    return out


def _float_array(name: str, value: ArrayLike, shape: tuple[int, ...]) -> FloatArray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a numeric array, got {value!r}") from None
    if arr.size == 0 and arr.shape != shape:
        arr = arr.reshape(shape)
    if arr.shape != shape:
        raise InputError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must contain only finite values")
    arr.setflags(write=False)
    return arr


def _check_model_names(value: object, state_names: tuple[str, ...]) -> tuple[str, ...]:
    """``model_names`` as a tuple: plain, distinct names whose ``p_`` columns clash with
    no other column of the table."""
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise InputError(f"model_names must be a tuple of model names, got {value!r}")
    out = tuple(value)
    for name in out:
        _check_plain_name("model", name, ',"\r\n', "commas, quotes, line breaks")
    if len(set(out)) != len(out):
        raise InputError(f"model_names must be distinct, got {out!r}")
    taken = {
        *TRACK_FIXED_COLUMNS, TRACK_ROW_COLUMN, EXISTENCE_COLUMN, *state_names,
        *(VARIANCE_PREFIX + name for name in state_names),
    }  # fmt: skip
    for name in out:
        if MODEL_PROBABILITY_PREFIX + name in taken:
            raise InputError(
                f"model_names entry {name!r} gives the column "
                f"{MODEL_PROBABILITY_PREFIX + name!r}, which the table already has; expected "
                "a name whose probability column is new"
            )
    return out


def _check_model_probabilities(
    value: ArrayLike | None, names: tuple[str, ...], count: int
) -> FloatArray | None:
    """``model_probabilities`` as a read-only ``(count, len(names))`` array of probability
    rows, or ``None`` (then ``names`` must be empty)."""
    if value is None:
        if names:
            raise InputError(
                f"model_names is {names!r} but model_probabilities is None; expected no "
                "model names without their probabilities"
            )
        return None
    arr = check_numeric_array("model_probabilities", value)
    if not names or arr.shape != (count, len(names)):
        raise InputError(
            f"model_probabilities must have shape ({count}, {len(names)}) (records, "
            f"model_names), got {arr.shape}"
            + ("; model_names must name its columns" if not names else "")
        )
    if not np.all(np.isfinite(arr)):
        raise InputError("model_probabilities must contain only finite values, got nan or inf")
    if np.any((arr < 0) | (arr > 1)):
        bad = float(arr[(arr < 0) | (arr > 1)][0])
        raise InputError(
            f"model_probabilities must hold probabilities in [0, 1], got the value {bad!r}"
        )
    sums = arr.sum(axis=1)
    off = np.abs(sums - 1.0) > MODEL_PROBABILITY_TOLERANCE
    if np.any(off):
        row = int(np.argmax(off))
        raise InputError(
            f"model_probabilities row {row} sums to {float(sums[row])!r}; expected each row "
            f"to sum to 1 within {MODEL_PROBABILITY_TOLERANCE:g}"
        )
    out = arr.copy()
    out.setflags(write=False)
    return out


def _positions(
    state_names: tuple[str, ...], states: FloatArray, position_names: Sequence[str]
) -> FloatArray:
    indices = [state_names.index(name) for name in position_names if name in state_names]
    if not indices:
        raise InputError(
            f"no position columns: none of {tuple(position_names)} is among the state "
            f"names {state_names}"
        )
    return states[:, indices]


def _duplicate(keys: Sequence[tuple[object, ...]]) -> tuple[object, ...] | None:
    seen: set[tuple[object, ...]] = set()
    for key in keys:
        if key in seen:
            return key
        seen.add(key)
    return None


class _StateRecords:
    """What truth and track tables share: one record per row, with ``times``, ``states``
    of shape ``(N, n)`` and their ``state_names``."""

    times: FloatArray
    states: FloatArray
    state_names: tuple[str, ...]

    @property
    def size(self) -> int:
        """Number of records N."""
        return int(self.times.shape[0])

    def positions(self, position_names: Sequence[str] = ("x", "y", "z")) -> FloatArray:
        """Position columns present among ``position_names``, shape ``(N, d)``.

        Raises
        ------
        InputError
            None of ``position_names`` is a state name.
        """
        return _positions(self.state_names, self.states, position_names)


@dataclass(frozen=True, eq=False)
class TruthTable(_StateRecords):
    """True target states (truth file, format 2).

    Parameters
    ----------
    target_ids : ndarray of int64, shape (N,)
        Target of each record, >= 0.
    times : ndarray, shape (N,)
        Time of each record.
    states : ndarray, shape (N, n)
        True state of the target at that time.
    state_names : tuple of str, length n
        Column names of the state components (e.g. ``("x", "y", "vx", "vy")``).

    A (target_id, time) pair appears at most once.
    """

    target_ids: IntArray
    times: FloatArray
    states: FloatArray
    state_names: tuple[str, ...]

    def __post_init__(self) -> None:
        names = _check_state_names(self.state_names, TRUTH_FIXED_COLUMNS)
        ids = _int_array("target_ids", self.target_ids, minimum=0, length=None)
        count = ids.shape[0]
        times = _float_array("times", self.times, (count,))
        states = _float_array("states", self.states, (count, len(names)))
        repeated = _duplicate(list(zip(ids.tolist(), times.tolist(), strict=True)))
        if repeated is not None:
            raise InputError(f"(target_id, time) = {repeated} appears more than once")
        object.__setattr__(self, "state_names", names)
        object.__setattr__(self, "target_ids", ids)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "states", states)


@dataclass(frozen=True, eq=False)
class Origins:
    """True origin of each detection (origins file, format 3).

    Parameters
    ----------
    rows : ndarray of int64, shape (M,)
        Detection ids (``Scan.rows``: any int64 >= 0; for a detections CSV file, its line
        numbers), distinct.
    target_ids : ndarray of int64, shape (M,)
        Target that produced the detection, or -1 for a false alarm.
    """

    rows: IntArray
    target_ids: IntArray

    def __post_init__(self) -> None:
        rows = _int_array("rows", self.rows, minimum=0, length=None, expected="detection ids >= 0")
        ids = _int_array("target_ids", self.target_ids, minimum=-1, length=rows.shape[0])
        repeated = _duplicate([(row,) for row in rows.tolist()])
        if repeated is not None:
            raise InputError(f"row {repeated[0]} appears more than once in origins")
        object.__setattr__(self, "rows", rows)
        object.__setattr__(self, "target_ids", ids)

    @property
    def size(self) -> int:
        """Number of detections M."""
        return int(self.rows.shape[0])


@dataclass(frozen=True, eq=False)
class TrackTable(_StateRecords):
    """Estimated tracks (tracks file, format 4).

    Parameters
    ----------
    track_ids : ndarray of int64, shape (N,)
        Track of each record, >= 0.
    times : ndarray, shape (N,)
        Scan time.
    sensors : tuple of str, length N
        Sensor of the scan.
    states : ndarray, shape (N, n)
        Estimated state.
    variances : ndarray, shape (N, n)
        Marginal variances (covariance diagonal), >= 0.
    detection_rows : ndarray of int64, shape (N,)
        Id of the detection used at this scan (``Scan.rows``: any int64 >= 0; for a
        detections CSV file, its line), or -1 for a miss.
    state_names : tuple of str, length n
        Column names of the state components.
    existence : ndarray, shape (N,), optional
        The track's existence probability (the same on every record of a track; ``nan``
        where it is unknown), written as the optional last column ``existence``.
    model_probabilities : ndarray, shape (N, M), optional
        For a motion model that is a set of ``M`` models (interacting multiple models):
        each record's smoothed model probabilities, a probability vector per row (entries
        in [0, 1] summing to 1 within ``MODEL_PROBABILITY_TOLERANCE``), written as the
        optional columns ``p_<model name>`` after ``detection_row``.  ``None`` (the
        default) for a single model, whose files have no such columns.  Unlike
        ``existence`` there is no ``nan`` for unknown: every smoothed record of a set
        has its probabilities, and a partial row would not be a distribution.
    model_names : tuple of str, length M
        The models' names, naming the columns (``p_`` + name; for a set,
        :attr:`mapassoc.models.interacting.InteractingModels.model_names`); empty exactly
        when ``model_probabilities`` is ``None``.

    A (track_id, time, sensor) triple appears at most once.
    """

    track_ids: IntArray
    times: FloatArray
    sensors: tuple[str, ...]
    states: FloatArray
    variances: FloatArray
    detection_rows: IntArray
    state_names: tuple[str, ...]
    existence: FloatArray | None = None
    model_probabilities: FloatArray | None = None
    model_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        names = _check_state_names(
            self.state_names, (*TRACK_FIXED_COLUMNS, TRACK_ROW_COLUMN, EXISTENCE_COLUMN)
        )
        ids = _int_array("track_ids", self.track_ids, minimum=0, length=None)
        count = ids.shape[0]
        times = _float_array("times", self.times, (count,))
        if isinstance(self.sensors, str) or not isinstance(self.sensors, Sequence):
            raise InputError(f"sensors must be a tuple of sensor names, got {self.sensors!r}")
        sensors = tuple(self.sensors)
        if len(sensors) != count:
            raise InputError(f"sensors must have {count} entries, got {len(sensors)}")
        for name in sensors:
            _check_plain_name("sensor", name, ",\r\n", "commas, line breaks")
        states = _float_array("states", self.states, (count, len(names)))
        variances = _float_array("variances", self.variances, (count, len(names)))
        if np.any(variances < 0):
            raise InputError(f"variances must be >= 0, got minimum {float(variances.min())!r}")
        rows = _int_array(
            "detection_rows",
            self.detection_rows,
            minimum=-1,
            length=count,
            expected="-1 (a miss) or a detection id >= 0",
        )
        repeated = _duplicate(list(zip(ids.tolist(), times.tolist(), sensors, strict=True)))
        if repeated is not None:
            raise InputError(f"(track_id, time, sensor) = {repeated} appears more than once")
        object.__setattr__(self, "state_names", names)
        object.__setattr__(self, "track_ids", ids)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "sensors", sensors)
        object.__setattr__(self, "states", states)
        object.__setattr__(self, "variances", variances)
        object.__setattr__(self, "detection_rows", rows)
        if self.existence is not None:
            existence = check_numeric_array("existence", self.existence)
            if existence.shape != (count,):
                raise InputError(
                    f"existence must have shape ({count},), got {existence.shape}"
                )
            if np.any(~np.isnan(existence) & ((existence < 0) | (existence > 1))):
                raise InputError("existence must hold probabilities in [0, 1] (or nan)")
            existence = existence.copy()
            existence.setflags(write=False)
            object.__setattr__(self, "existence", existence)
        model_names = _check_model_names(self.model_names, names)
        object.__setattr__(self, "model_names", model_names)
        object.__setattr__(
            self,
            "model_probabilities",
            _check_model_probabilities(self.model_probabilities, model_names, count),
        )

    def select(self, keep: ArrayLike) -> TrackTable:
        """The records where the boolean mask ``keep`` (shape ``(N,)``) is true, every
        column carried along (existence and model probabilities included), in order."""
        mask = np.asarray(keep)
        if mask.dtype != np.bool_ or mask.shape != (self.size,):
            raise InputError(
                f"keep must be a boolean mask of shape ({self.size},), got dtype {mask.dtype} "
                f"and shape {mask.shape}"
            )
        probabilities = self.model_probabilities
        return dataclasses.replace(
            self,
            track_ids=self.track_ids[mask],
            times=self.times[mask],
            sensors=tuple(s for s, k in zip(self.sensors, mask.tolist(), strict=True) if k),
            states=self.states[mask],
            variances=self.variances[mask],
            detection_rows=self.detection_rows[mask],
            existence=None if self.existence is None else self.existence[mask],
            model_probabilities=None if probabilities is None else probabilities[mask],
        )

    def with_existence(self, by_track: Mapping[int, float]) -> TrackTable:
        """This table with each record's ``existence`` taken from ``by_track`` (track id ->
        probability; ``nan`` for a track it does not name)."""
        values = np.array([by_track.get(int(t), math.nan) for t in self.track_ids], dtype=float)
        return dataclasses.replace(self, existence=values)

    @classmethod
    def from_steps(
        cls,
        *,
        track_ids: Sequence[int],
        times: Sequence[float],
        sensors: Sequence[str],
        scan_indices: Sequence[int],
        states: Sequence[FloatArray],
        variances: Sequence[FloatArray],
        detection_rows: Sequence[int],
        state_names: tuple[str, ...],
        model_probabilities: ArrayLike | None = None,
        model_names: tuple[str, ...] = (),
    ) -> TrackTable:
        """A table from one record per (track, scan) in any order, sorted by (time, track
        id, scan index): the order every tracker writes.

        ``states`` and ``variances`` hold one ``(n,)`` vector per record, ``n =
        len(state_names)``; ``scan_indices`` only breaks ties between the scans of two
        sensors at one time.  ``model_probabilities``, for a set of models, holds one
        ``(M,)`` vector per record, ``M = len(model_names)``, sorted with the rest.
        """
        n = len(state_names)
        count = len(track_ids)
        order = np.lexsort(
            (
                np.asarray(scan_indices, dtype=np.int64),
                np.asarray(track_ids, dtype=np.int64),
                np.asarray(times, dtype=float),
            )
        )
        return cls(
            track_ids=np.asarray(track_ids, dtype=np.int64)[order],
            times=np.asarray(times, dtype=float)[order],
            sensors=tuple(sensors[i] for i in order),
            states=np.asarray(states, dtype=float).reshape(count, n)[order],
            variances=np.asarray(variances, dtype=float).reshape(count, n)[order],
            detection_rows=np.asarray(detection_rows, dtype=np.int64)[order],
            state_names=tuple(state_names),
            model_probabilities=(
                None
                if model_probabilities is None
                else np.asarray(model_probabilities, dtype=float).reshape(
                    count, len(model_names)
                )[order]
            ),
            model_names=tuple(model_names),
        )


# --------------------------------------------------------------------------- truth

TRUTH_HEADER = "target_id,time,<state names>"
"""The header of a truth file, as error messages state it."""


def truth_state_names(path: str, header: Sequence[str], *, row: int | None) -> list[str]:
    """The state names of a truth table's columns ``header`` (also used for Parquet)."""
    for position, name in enumerate(TRUTH_FIXED_COLUMNS):
        if position >= len(header) or header[position] != name:
            found = header[position] if position < len(header) else None
            raise DataFileError(
                path,
                f"column {position + 1} is {found!r}; expected {name!r} "
                f"(columns {TRUTH_HEADER})",
                row=row,
                column=name,
            )
    names = list(header[len(TRUTH_FIXED_COLUMNS) :])
    if not names:
        raise DataFileError(
            path, f"no state columns after target_id,time; expected {TRUTH_HEADER}", row=row
        )
    return names

TRACKS_HEADER = (
    "track_id,time,sensor,<state names>,<var_ + each state name>,detection_row"
    "[,<p_ + each model name>][,existence]"
)
"""The header of a tracks file, as error messages state it."""


def track_state_names(
    path: str, header: Sequence[str], *, row: int | None
) -> tuple[list[str], list[str]]:
    """State and variance column names of a tracks table's columns ``header`` (also used
    for Parquet)."""
    expected = TRACKS_HEADER
    if header and header[-1] == EXISTENCE_COLUMN:
        header = header[:-1]
    end = _track_row_end(header)
    for name in header[end:]:
        if not name.startswith(MODEL_PROBABILITY_PREFIX) or name == MODEL_PROBABILITY_PREFIX:
            raise DataFileError(
                path,
                f"column {name!r} after {TRACK_ROW_COLUMN!r}; expected only model probability "
                f"columns {MODEL_PROBABILITY_PREFIX}<model name>, then {EXISTENCE_COLUMN!r} "
                f"last (header {expected})",
                row=row,
                column=name,
            )
    header = header[:end]
    for position, name in enumerate(TRACK_FIXED_COLUMNS):
        if position >= len(header) or header[position] != name:
            found = header[position] if position < len(header) else None
            raise DataFileError(
                path,
                f"column {position + 1} is {found!r}; expected {name!r} (header {expected})",
                row=row,
                column=name,
            )
    if header[-1] != TRACK_ROW_COLUMN:
        raise DataFileError(
            path,
            f"last column is {header[-1]!r}; expected {TRACK_ROW_COLUMN!r} (header {expected})",
            row=row,
            column=TRACK_ROW_COLUMN,
        )
    middle = header[len(TRACK_FIXED_COLUMNS) : -1]
    if not middle or len(middle) % 2:
        raise DataFileError(
            path,
            f"{len(middle)} state and variance columns ({','.join(middle)}); expected n state "
            f"columns followed by their n var_ columns (header {expected})",
            row=row,
            column=middle[-1] if middle else TRACK_ROW_COLUMN,
        )
    count = len(middle) // 2
    names = middle[:count]
    for name, found in zip(names, middle[count:], strict=True):
        if found != VARIANCE_PREFIX + name:
            raise DataFileError(
                path,
                f"column {found!r} where {VARIANCE_PREFIX + name!r} was expected: the variance "
                f"columns must follow the state columns {','.join(names)} in the same order",
                row=row,
                column=found,
            )
    var_names = middle[count:]
    return list(names), list(var_names)


def _track_row_end(header: Sequence[str]) -> int:
    """Index just after a tracks header's last ``detection_row`` column (``existence``
    already left out), or its length when it has none: the model probability columns
    follow.  ``detection_row`` cannot be a state name, so its position is unambiguous."""
    for position in range(len(header) - 1, -1, -1):
        if header[position] == TRACK_ROW_COLUMN:
            return position + 1
    return len(header)


def track_model_names(header: Sequence[str]) -> list[str]:
    """The model names of the ``p_<model name>`` columns of a tracks header already
    checked by :func:`track_state_names` (empty for a single model's file)."""
    if header and header[-1] == EXISTENCE_COLUMN:
        header = header[:-1]
    return [name[len(MODEL_PROBABILITY_PREFIX) :] for name in header[_track_row_end(header) :]]
