"""Data files by suffix: one call reads or writes CSV or Parquet.

================  ======================================  ==========================
suffix            format                                  module
================  ======================================  ==========================
``.csv``          CSV text                                :mod:`mapassoc.data.io`
``.parquet``      Parquet (needs the optional pyarrow)    :mod:`mapassoc.data.parquet`
``.pq``           Parquet                                 :mod:`mapassoc.data.parquet`
================  ======================================  ==========================

Suffixes are compared case-insensitively.  Both formats hold the same columns (a Parquet
detections file adds ``detection_id``); they differ in the detection ids a reader gives
(CSV: line numbers, from 2; Parquet: the ``detection_id`` column, else the 0-based row
index) and in the row order they accept (CSV: times never decrease down the file;
Parquet: any order).  An unknown suffix raises
:class:`~mapassoc.errors.DataFileError` naming the file and the known suffixes.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import PurePath
from typing import Any

from mapassoc.data import io as csv_io
from mapassoc.data.io import Origins, TrackTable, TruthTable
from mapassoc.data.scans import Scan
from mapassoc.errors import DataFileError
from mapassoc.models.sensor import Sensor

__all__ = [
    "detection_formats",
    "file_format",
    "read_detections_file",
    "write_detections_file",
    "read_tracks_file",
    "write_tracks_file",
    "read_truth_file",
    "write_truth_file",
    "read_origins_file",
    "write_origins_file",
]

PathLike = str | os.PathLike[str]

_FORMAT_OF_SUFFIX: dict[str, str] = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet"}


def detection_formats() -> tuple[str, ...]:
    """The file suffixes the ``*_file`` functions know, e.g. ``(".csv", ".parquet", ".pq")``."""
    return tuple(_FORMAT_OF_SUFFIX)


def file_format(path: PathLike) -> str:
    """``"csv"`` or ``"parquet"``: the format of ``path`` by its suffix.

    Raises
    ------
    DataFileError
        The suffix is none of :func:`detection_formats`.
    """
    text = os.fspath(path)
    suffix = PurePath(text).suffix.lower()
    kind = _FORMAT_OF_SUFFIX.get(suffix)
    if kind is None:
        what = f"unknown file suffix {suffix!r}" if suffix else "no file suffix"
        raise DataFileError(
            text,
            f"{what}; expected one of {', '.join(detection_formats())} (CSV or Parquet)",
        )
    return kind


def _dispatch(
    path: PathLike, csv_function: Callable[..., Any], parquet_name: str
) -> Callable[..., Any]:
    if file_format(path) == "csv":
        return csv_function
    from mapassoc.data import parquet

    return getattr(parquet, parquet_name)


def read_detections_file(
    path: PathLike, sensors: Mapping[str, Sensor], *, content: bytes | None = None
) -> list[Scan]:
    """Read a detections file, CSV or Parquet by its suffix.

    ``content``: the file's bytes when the caller has read them already (``path`` then
    only names the file and its format).  See :func:`mapassoc.data.io.read_detections`
    and :func:`mapassoc.data.parquet.read_detections_parquet`.
    """
    reader = _dispatch(path, csv_io.read_detections, "read_detections_parquet")
    return reader(path, sensors, content=content)


def write_detections_file(
    path: PathLike, scans: Sequence[Scan], sensors: Mapping[str, Sensor]
) -> None:
    """Write a detections file, CSV or Parquet by its suffix.

    A CSV file does not hold the detection ids: reading it gives the line numbers (call
    :func:`mapassoc.data.io.number_rows` first to keep them equal); a Parquet file keeps
    them.  See :func:`mapassoc.data.io.write_detections` and
    :func:`mapassoc.data.parquet.write_detections_parquet`.
    """
    writer = _dispatch(path, csv_io.write_detections, "write_detections_parquet")
    writer(path, scans, sensors)


def read_tracks_file(path: PathLike) -> TrackTable:
    """Read a tracks file, CSV or Parquet by its suffix."""
    return _dispatch(path, csv_io.read_tracks, "read_tracks_parquet")(path)


def write_tracks_file(path: PathLike, table: TrackTable) -> None:
    """Write a tracks file, CSV or Parquet by its suffix."""
    _dispatch(path, csv_io.write_tracks, "write_tracks_parquet")(path, table)


def read_truth_file(path: PathLike) -> TruthTable:
    """Read a truth file, CSV or Parquet by its suffix."""
    return _dispatch(path, csv_io.read_truth, "read_truth_parquet")(path)


def write_truth_file(path: PathLike, table: TruthTable) -> None:
    """Write a truth file, CSV or Parquet by its suffix."""
    _dispatch(path, csv_io.write_truth, "write_truth_parquet")(path, table)


def read_origins_file(path: PathLike) -> Origins:
    """Read an origins file, CSV or Parquet by its suffix."""
    return _dispatch(path, csv_io.read_origins, "read_origins_parquet")(path)


def write_origins_file(path: PathLike, origins: Origins) -> None:
    """Write an origins file, CSV or Parquet by its suffix."""
    _dispatch(path, csv_io.write_origins, "write_origins_parquet")(path, origins)
