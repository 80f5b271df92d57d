"""Scans: the detections one sensor delivered at one time.

A run is a list of scans sorted by time (ties broken by sensor name).  Every
detection carries an id, ``Scan.rows`` (the historical name is kept: it is used all over
the package), so that tracks and origins can name the detections they use.

Detection ids are unique non-negative int64 keys of the detections table; nothing else is
assumed about them (they need not be contiguous or sorted).  Where they come from:

* the CSV reader (:func:`mapassoc.data.io.read_detections`) uses the file's 1-based line
  numbers, so CSV ids start at 2 (line 1 is the header), and
  :func:`mapassoc.data.io.number_rows` gives scans the ids the CSV writer will give them;
* the Parquet reader (:mod:`mapassoc.data.parquet`) uses the ``detection_id`` column if
  the file has one, else the 0-based row index;
* in-memory input (:mod:`mapassoc.data.tables`) uses the ids it is given, else 0..n-1.

:class:`Scan` refuses negative ids and ids repeated within the scan; ids repeated across
the scans of a run are refused by :func:`check_scan_order`.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.errors import InputError
from mapassoc.validation import check_number, check_numeric_array, check_text

__all__ = ["Scan", "check_scan_order", "check_scans"]


@dataclass(frozen=True, eq=False)
class Scan:
    """Detections of one sensor at one time.

    Parameters
    ----------
    time : float
        Scan time.
    sensor : str
        Name of the sensor that produced the scan.
    detections : ndarray, shape (m, dz)
        Measurements; ``m`` may be 0.
    rows : ndarray of int, shape (m,)
        Detection ids: unique non-negative int64 keys of the detections table (see the
        module docstring; for a CSV file, its line numbers).  Integer arrays, and float
        arrays of whole numbers, are accepted and stored as int64.  Unique within a run
        (checked here within the scan, across scans by :func:`check_scan_order`).

    Raises
    ------
    InputError
        A time that is not a finite number (text such as ``"12:00"`` included), a sensor
        that is not a non-empty string, detections not a finite ``(m, dz)`` array of
        numbers, ``rows`` not of shape ``(m,)``, not integers, negative or repeated within
        the scan.
    """

    time: float
    sensor: str
    detections: NDArray[np.float64]
    rows: NDArray[np.int64]

    def __post_init__(self) -> None:
        t = check_number("scan time", self.time)
        check_text("scan sensor", self.sensor)
        det = check_numeric_array("scan detections", self.detections)
        if det.ndim != 2:
            raise InputError(
                f"scan detections must be a (m, dz) array, got shape {det.shape} "
                f"(sensor '{self.sensor}', time {t})"
            )
        if not np.all(np.isfinite(det)):
            raise InputError(f"scan detections must be finite (sensor '{self.sensor}', time {t})")
        rows = _detection_ids(self.rows, det.shape[0], self.sensor, t)
        det.setflags(write=False)
        rows.setflags(write=False)
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "detections", det)
        object.__setattr__(self, "rows", rows)

    @property
    def size(self) -> int:
        """Number of detections m."""
        return int(self.detections.shape[0])

    def __repr__(self) -> str:
        return f"Scan(time={self.time}, sensor={self.sensor!r}, detections={self.size})"


def _detection_ids(value: object, count: int, sensor: str, time: float) -> NDArray[np.int64]:
    """``value`` as an int64 array of ``count`` distinct ids >= 0, or an InputError."""
    where = f"(sensor {sensor!r}, time {time!r})"
    raw = np.asarray(value)
    if raw.shape != (count,):
        raise InputError(f"scan rows must have shape ({count},), got {raw.shape} {where}")
    if count == 0:
        return np.zeros(0, dtype=np.int64)
    if np.issubdtype(raw.dtype, np.floating):
        whole = np.isfinite(raw) & (raw == np.round(raw)) & (np.abs(raw) < 2.0**63)
        if not np.all(whole):
            bad = raw[~whole][:5].tolist()
            raise InputError(f"scan rows must be whole numbers (detection ids), got {bad} {where}")
    elif not np.issubdtype(raw.dtype, np.integer):
        raise InputError(f"scan rows must be integer detection ids, got dtype {raw.dtype} {where}")
    elif raw.dtype == np.uint64 and int(raw.max()) > np.iinfo(np.int64).max:
        raise InputError(f"scan rows must fit in int64, got the id {int(raw.max())} {where}")
    rows = raw.astype(np.int64)
    if int(rows.min()) < 0:
        negative = sorted(set(rows[rows < 0].tolist()))[:5]
        raise InputError(f"scan rows (detection ids) must be >= 0, got {negative} {where}")
    ordered = np.sort(rows)
    repeated = ordered[1:][ordered[1:] == ordered[:-1]]
    if repeated.size:
        raise InputError(
            f"scan rows (detection ids) must be distinct, got {sorted(set(repeated.tolist()))[:5]} "
            f"more than once {where}"
        )
    return rows


def check_scan_order(scans: Sequence[Scan]) -> None:
    """Raise unless scans are sorted by (time, sensor) with unique pairs and detection ids.

    Parameters
    ----------
    scans : sequence of Scan
    """
    seen_rows: set[int] = set()
    for i, scan in enumerate(scans):
        if i > 0:
            prev = scans[i - 1]
            if (scan.time, scan.sensor) <= (prev.time, prev.sensor):
                raise InputError(
                    f"scans must be sorted by (time, sensor) without repeats: scan {i} "
                    f"({scan.sensor!r} at {scan.time}) follows ({prev.sensor!r} at {prev.time})"
                )
        dup = seen_rows.intersection(scan.rows.tolist())
        if dup:
            raise InputError(
                f"detection ids (rows) {sorted(dup)[:5]} appear in more than one scan; "
                f"scan {i} ({scan.sensor!r} at {scan.time}) repeats them"
            )
        seen_rows.update(scan.rows.tolist())


def _not_scans(value: object, argument: str) -> str | None:
    """Why ``value`` is not a sequence of :class:`Scan` (None: it is), saying what to pass."""
    convert = (
        "read a detections file with mapassoc.read_detections_file(path, config.sensors), "
        "a pandas DataFrame with mapassoc.scans_from_frame(frame, config.sensors), "
        "arrays with mapassoc.scans_from_arrays(times, measurements, config.sensors)"
    )
    kind = type(value).__name__
    if isinstance(value, (str, bytes)) or hasattr(value, "__fspath__"):
        return (
            f"{argument} must be a sequence of mapassoc.Scan, got the {kind} {value!r}; to "
            f"estimate from a file, read it first: "
            f"mapassoc.read_detections_file(path, config.sensors)"
        )
    if hasattr(value, "columns") and hasattr(value, "iloc"):
        return (
            f"{argument} must be a sequence of mapassoc.Scan, got a {kind}; convert a table "
            "of detections with mapassoc.scans_from_frame(frame, config.sensors)"
        )
    if isinstance(value, np.ndarray):
        return (
            f"{argument} must be a sequence of mapassoc.Scan, got a numpy array of shape "
            f"{value.shape}; convert arrays of detections with "
            "mapassoc.scans_from_arrays(times, measurements, config.sensors)"
        )
    if isinstance(value, Scan):
        return f"{argument} must be a sequence of mapassoc.Scan, got one Scan; pass [scan]"
    if not isinstance(value, Sequence):
        return (
            f"{argument} must be a sequence of mapassoc.Scan, got {kind} {value!r:.80}; "
            f"{convert}"
        )
    for i, item in enumerate(value):
        if not isinstance(item, Scan):
            return (
                f"{argument}[{i}] must be a mapassoc.Scan, got {type(item).__name__} "
                f"{item!r:.80}; {convert}"
            )
    return None


def check_scans(
    scans: object,
    sensors: Collection[str],
    *,
    argument: str = "scans",
    what: str = "estimate",
) -> list[Scan]:
    """The scans as a list, after the checks every entry point makes up front.

    One check for :meth:`~mapassoc.estimator.pipeline.WindowEstimator.start`,
    :meth:`~mapassoc.estimator.pipeline.WindowEstimator.solve_window` and every
    tracker's ``track`` (:func:`mapassoc.trackers.base.check_scans`).

    Parameters
    ----------
    scans : sequence of Scan
        Sorted by (time, sensor), without repeats (:func:`check_scan_order`).
    sensors : collection of str
        The configured sensor names (``Config.sensors``).
    argument : str
        The argument's name in messages.
    what : str
        What the caller does with the scans, for the message about no scans.

    Raises
    ------
    InputError
        Not a sequence of :class:`Scan` (the message says how to make one from a file,
        a DataFrame or arrays), no scans, scans out of (time, sensor) order or repeated,
        detection ids repeated across scans, or a scan of a sensor the configuration does
        not define.
    """
    problem = _not_scans(scans, argument)
    if problem is not None:
        raise InputError(problem)
    listed = list(scans)  # type: ignore[call-overload]
    if not listed:
        raise InputError(f"{argument} is empty: there is nothing to {what}")
    check_scan_order(listed)
    for scan in listed:
        if scan.sensor not in sensors:
            raise InputError(
                f"scan at time {scan.time} names sensor '{scan.sensor}', which the "
                f"configuration does not define (known: {sorted(sensors)})"
            )
    return listed
