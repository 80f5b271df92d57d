"""Scans: the detections one sensor delivered at one time.

A run is a list of scans sorted by time (ties broken by sensor name).  Every
detection keeps ``row``, the 1-based line of the detections file it came from
(for simulated data: the line the writer gives it), so that tracks can name the
detections they use.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.errors import InputError

__all__ = ["Scan", "check_scan_order"]


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
        Line numbers of the detections in their file (unique within a run).
    """

    time: float
    sensor: str
    detections: NDArray[np.float64]
    rows: NDArray[np.int64]

    def __post_init__(self) -> None:
        t = float(self.time)
        if not np.isfinite(t):
            raise InputError(f"scan time must be finite, got {self.time!r}")
        det = np.asarray(self.detections, dtype=float)
        if det.ndim != 2:
            raise InputError(
                f"scan detections must be a (m, dz) array, got shape {det.shape} "
                f"(sensor '{self.sensor}', time {t})"
            )
        if not np.all(np.isfinite(det)):
            raise InputError(f"scan detections must be finite (sensor '{self.sensor}', time {t})")
        rows = np.asarray(self.rows, dtype=np.int64)
        if rows.shape != (det.shape[0],):
            raise InputError(
                f"scan rows must have shape ({det.shape[0]},), got {rows.shape} "
                f"(sensor '{self.sensor}', time {t})"
            )
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


def check_scan_order(scans: Sequence[Scan]) -> None:
    """Raise unless scans are sorted by (time, sensor) with unique pairs and rows.

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
            raise InputError(f"detection rows {sorted(dup)[:5]} appear in more than one scan")
        seen_rows.update(scan.rows.tolist())
