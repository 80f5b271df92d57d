"""Times as time: ISO 8601 text, datetime64 and Parquet timestamps beside plain seconds.

The estimator works in seconds.  A recording whose ``time`` column holds timestamps is
read as seconds since an *epoch*, the first timestamp of the file cut to the whole second,
and the epoch is kept in a :class:`TimeBase` so that tracks are written back with the
kind of time the input had.

Decisions
---------
* Timestamps are held as integer microseconds since 1970-01-01T00:00:00 UTC, the
  resolution of Python's :class:`datetime.datetime` and the finest Parquet and pandas
  unit that every reader of a track file understands.  Seconds since the epoch are
  ``(us - epoch_us) / 1e6``; for a recording shorter than 285 years this float64 is
  exact enough that ``round(seconds * 1e6)`` gives the microseconds back exactly, so the
  round trip (text -> seconds -> text) is exact to the microsecond.
* A timestamp without a zone is taken as UTC, and the reader warns once saying so.  A
  timestamp with a zone is converted to UTC; tracks are written in UTC (``Z``) when the
  input had zones, without a zone when it had none.
* One file holds one kind of time: a number on one line and a timestamp on another is
  an error naming the second line.
"""

from __future__ import annotations

import datetime as dt
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.errors import InputError

__all__ = [
    "TimeBase",
    "TimeKind",
    "SECONDS",
    "parse_time_cells",
    "times_from_datetime64",
    "format_times",
    "datetime64_times",
    "NAIVE_UTC_WARNING",
]

TimeKind = Literal["seconds", "iso8601", "datetime64"]
"""``seconds``: plain numbers; ``iso8601``: text timestamps; ``datetime64``: typed
timestamps (a pandas ``datetime64`` column or a Parquet timestamp column)."""

NAIVE_UTC_WARNING = (
    "timestamps without a time zone are taken as UTC; give a zone (Z or +hh:mm) to say so"
)
"""The warning given once per file whose timestamps carry no zone: they are read as UTC
rather than refused, because recorders commonly write UTC without saying so."""

_UNIX = dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
Fail = Callable[[str, int], Exception]
"""``fail(message, position)`` builds the error for the cell at 0-based ``position``."""


@dataclass(frozen=True)
class TimeBase:
    """How a recording gave its times, and the epoch its seconds count from.

    Parameters
    ----------
    kind : {"seconds", "iso8601", "datetime64"}
    epoch_us : int
        The epoch in microseconds since 1970-01-01 UTC (0 for plain seconds).
    zoned : bool
        Whether the input's timestamps carried a zone (tracks are then written with ``Z``).
    """

    kind: TimeKind = "seconds"
    epoch_us: int = 0
    zoned: bool = True

    @property
    def epoch(self) -> str | None:
        """The epoch as ISO 8601 UTC text, None for plain seconds."""
        if self.kind == "seconds":
            return None
        return _text(self.epoch_us, zoned=True)

    def to_json(self) -> dict[str, object]:
        """What a run records in ``summary.json``."""
        return {"kind": self.kind, "epoch": self.epoch, "zoned": self.zoned}

    def microseconds(self, seconds: FloatArray) -> IntArray:
        """Microseconds since 1970 UTC of ``seconds`` since the epoch, shape ``(n,)``."""
        return self.epoch_us + np.rint(np.asarray(seconds, dtype=float) * 1e6).astype(np.int64)


SECONDS = TimeBase()
"""The time base of a recording in plain seconds."""


def _text(us: int, *, zoned: bool) -> str:
    stamp = _UNIX + dt.timedelta(microseconds=int(us))
    text = stamp.replace(tzinfo=None).isoformat(timespec="microseconds")
    return text + ("Z" if zoned else "")


def _parse_stamp(cell: str) -> tuple[int, bool] | None:
    """``(microseconds since 1970 UTC, had a zone)`` of one ISO 8601 cell, or None."""
    text = cell[:-1] + "+00:00" if cell.endswith(("Z", "z")) else cell
    try:
        stamp = dt.datetime.fromisoformat(text)
    except ValueError:
        return None
    zoned = stamp.tzinfo is not None
    if not zoned:
        stamp = stamp.replace(tzinfo=dt.UTC)
    delta = stamp - _UNIX
    us = (delta.days * 86_400 + delta.seconds) * 1_000_000 + delta.microseconds
    return us, zoned


def _cell_kind(cell: str) -> str:
    return "seconds" if _NUMBER.fullmatch(cell) else "iso8601"


def parse_time_cells(cells: Sequence[str], fail: Fail) -> tuple[FloatArray, TimeBase]:
    """Seconds since the epoch of a ``time`` column of text cells, and its time base.

    Parameters
    ----------
    cells : sequence of str, length n
        The stripped cells; the first non-empty cell fixes the kind.
    fail : callable
        ``fail(message, position)`` builds the error for the cell at ``position``.

    Returns
    -------
    seconds : ndarray, shape (n,)
        Plain numbers as they are; timestamps as seconds since the epoch (the first
        timestamp cut to the whole second).  An empty cell is NaN (the ingest path
        reports it).
    base : TimeBase
    """
    first = next((cell for cell in cells if cell != ""), "0")
    kind = _cell_kind(first)
    out = np.full(len(cells), math.nan)
    if kind == "seconds":
        for position, cell in enumerate(cells):
            if cell == "":
                continue
            if _cell_kind(cell) != "seconds":
                raise fail(_mixed(cell, "a number", first), position)
            value = float(cell)
            if not math.isfinite(value):
                raise fail(f"time {cell!r} is not finite; expected a finite number", position)
            out[position] = value
        return out, SECONDS
    return _parse_stamps(cells, first, fail)


def _mixed(cell: str, expected: str, first: str) -> str:
    return (
        f"time {cell!r} is of another kind than the file's first time {first!r}; "
        f"expected {expected} (one kind of time per file)"
    )


def _parse_stamps(cells: Sequence[str], first: str, fail: Fail) -> tuple[FloatArray, TimeBase]:
    us = np.zeros(len(cells), dtype=np.int64)
    empty = np.zeros(len(cells), dtype=bool)
    first_zoned: bool | None = None
    for position, cell in enumerate(cells):
        if cell == "":
            empty[position] = True
            continue
        if _cell_kind(cell) == "seconds":
            raise fail(_mixed(cell, "an ISO 8601 timestamp", first), position)
        parsed = _parse_stamp(cell)
        if parsed is None:
            raise fail(
                f"time {cell!r} is not an ISO 8601 timestamp; expected for example "
                "2024-05-01T12:00:00.250Z",
                position,
            )
        us[position], zoned = parsed
        if first_zoned is None:
            first_zoned = zoned
        elif zoned != first_zoned:
            raise fail(
                f"time {cell!r} mixes timestamps with and without a time zone (the first, "
                f"{first!r}, has {'a' if first_zoned else 'no'} zone); expected all alike",
                position,
            )
    epoch = (int(us[~empty].min()) // 1_000_000) * 1_000_000 if np.any(~empty) else 0
    seconds = (us - epoch) / 1e6
    seconds[empty] = math.nan
    return seconds, TimeBase(kind="iso8601", epoch_us=epoch, zoned=first_zoned is not False)


def times_from_datetime64(values: object, *, zoned: bool) -> tuple[FloatArray, TimeBase]:
    """Seconds since the epoch of a ``datetime64`` column (NaT -> NaN), and its time base.

    Parameters
    ----------
    values : array_like of datetime64, shape (n,)
        Naive values are UTC; zone-aware pandas values are converted to UTC first by the
        caller.
    zoned : bool
        Whether the column carried a zone.
    """
    array = np.asarray(values, dtype="datetime64[us]")
    null = np.isnat(array)
    us = array.astype(np.int64)
    epoch = (int(us[~null].min()) // 1_000_000) * 1_000_000 if np.any(~null) else 0
    seconds = (us - epoch) / 1e6
    seconds[null] = math.nan
    return seconds, TimeBase(kind="datetime64", epoch_us=epoch, zoned=zoned)


def format_times(seconds: FloatArray, base: TimeBase) -> list[str]:
    """``seconds`` since the epoch as text cells of the base's kind.

    Plain seconds are written with ``repr`` (exact); timestamps as ISO 8601 with
    microseconds (``Z`` when the input had zones).
    """
    if not isinstance(base, TimeBase):
        raise InputError(f"base must be a TimeBase, got {base!r}")
    if base.kind == "seconds":
        return [repr(float(value)) for value in np.asarray(seconds, dtype=float)]
    return [_text(int(us), zoned=base.zoned) for us in base.microseconds(seconds)]


def datetime64_times(seconds: FloatArray, base: TimeBase) -> np.ndarray:
    """``seconds`` since the epoch as ``datetime64[us]`` (UTC), shape ``(n,)``."""
    return base.microseconds(seconds).astype("datetime64[us]")
