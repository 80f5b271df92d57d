"""Data files by suffix: one table of formats, and one call to read or write each kind of
file in any of them.

=========== ============================  ===================================  ============
name        suffixes                      module                               extra
=========== ============================  ===================================  ============
``csv``     ``.csv``                      :mod:`mapassoc.data.io`              (none)
``parquet`` ``.parquet``, ``.pq``         :mod:`mapassoc.data.parquet`         ``parquet``
=========== ============================  ===================================  ============

Each row of :data:`FILE_FORMATS` names a module holding ``read_<kind><functions>`` and
``write_<kind><functions>`` for the four kinds of file (``detections``, ``tracks``,
``truth``, ``origins``; ``functions`` is the row's name suffix, ``""`` for CSV and
``"_parquet"`` for Parquet).  The command line's ``--format`` choices, the run folder's
tracks file, the files a batch finds and the files ``mapassoc simulate`` writes all come
from the table, so a new format is one module and one row (its module is imported only
when a file of that format is read or written: this table is read when the command
line's parser is built).

Suffixes are compared case-insensitively.  Both built-in formats hold the same columns (a
Parquet detections file adds ``detection_id``); they differ in the detection ids a reader
gives (CSV: line numbers, from 2; Parquet: the ``detection_id`` column, else the 0-based
row index) and in the row order they accept (CSV: times never decrease down the file;
Parquet: any order).  An unknown suffix raises :class:`~mapassoc.errors.DataFileError`
naming the file and the known suffixes.

A detections file may also be a stream without a suffix (``/dev/stdin``, a process
substitution ``<(zcat detections.csv.gz)``, a named pipe): :func:`read_detections_file`
takes its format from ``format_name`` (``--format``) or, without one, from its bytes
(:func:`sniff_format`: Parquet's magic ``PAR1``, else CSV), read once.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import PurePath
from typing import TYPE_CHECKING, Any

from mapassoc.errors import DataFileError, InputError
from mapassoc.validation import check_path

if TYPE_CHECKING:  # the table is read by the command line's parser: keep it light
    from mapassoc.data.io import Origins, TrackTable, TruthTable
    from mapassoc.data.scans import Scan
    from mapassoc.models.sensor import Sensor

__all__ = [
    "FILE_FORMATS",
    "FileFormat",
    "format_names",
    "detection_formats",
    "file_format",
    "file_name",
    "sniff_format",
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

FILE_KINDS = ("detections", "tracks", "truth", "origins")
"""The kinds of data file every format reads and writes."""


@dataclass(frozen=True)
class FileFormat:
    """One row of :data:`FILE_FORMATS`.

    Parameters
    ----------
    name : str
        What ``--format`` and ``tracks_format`` call it.
    suffixes : tuple of str
        Lower-case file suffixes, the first one the suffix files are written with.
    module : str
        The module of its readers and writers (imported on first use).
    functions : str
        Name suffix of its functions: ``read_<kind><functions>``,
        ``write_<kind><functions>``.
    description : str
        Words for messages and help (``"CSV"``).
    extra : str or None
        The optional dependency group it needs (``pip install mapassoc[extra]``).
    """

    name: str
    suffixes: tuple[str, ...]
    module: str
    functions: str
    description: str
    extra: str | None = None

    def function(self, verb: str, kind: str) -> Callable[..., Any]:
        """``read`` or ``write`` of one kind of file in this format."""
        if verb not in ("read", "write") or kind not in FILE_KINDS:
            raise InputError(f"no {verb} function for {kind!r} files")
        function: Callable[..., Any] = getattr(
            importlib.import_module(self.module), f"{verb}_{kind}{self.functions}"
        )
        return function


FILE_FORMATS: dict[str, FileFormat] = {
    row.name: row
    for row in (
        FileFormat("csv", (".csv",), "mapassoc.data.io", "", "CSV"),
        FileFormat(
            "parquet", (".parquet", ".pq"), "mapassoc.data.parquet", "_parquet", "Parquet",
            extra="parquet",
        ),
    )
}
"""Data file formats by name (module docstring)."""


def format_names() -> tuple[str, ...]:
    """The names of :data:`FILE_FORMATS`, in table order (``("csv", "parquet")``)."""
    return tuple(FILE_FORMATS)


def detection_formats() -> tuple[str, ...]:
    """The file suffixes the ``*_file`` functions know, e.g. ``(".csv", ".parquet", ".pq")``."""
    return tuple(suffix for row in FILE_FORMATS.values() for suffix in row.suffixes)


def _format_of_path(
    path: PathLike, function: str = "file_format", *, hint: str = ""
) -> FileFormat:
    text = check_path(f"{function}: path", path)
    suffix = PurePath(text).suffix.lower()
    for row in FILE_FORMATS.values():
        if suffix in row.suffixes:
            return row
    what = f"unknown file suffix {suffix!r}" if suffix else "no file suffix"
    kinds = " or ".join(row.description for row in FILE_FORMATS.values())
    raise DataFileError(
        text, f"{what}; expected one of {', '.join(detection_formats())} ({kinds}){hint}"
    )


PARQUET_MAGIC = b"PAR1"
"""The four bytes every Parquet file starts (and ends) with."""


def sniff_format(content: bytes) -> str:
    """The format of a file's bytes: ``"parquet"`` when they start with Parquet's magic
    ``PAR1``, else ``"csv"`` (the CSV reader then names whatever is wrong)."""
    return "parquet" if content[: len(PARQUET_MAGIC)] == PARQUET_MAGIC else "csv"


def _named_format(format_name: str) -> FileFormat:
    row = FILE_FORMATS.get(format_name) if isinstance(format_name, str) else None
    if row is None:
        raise InputError(
            f"format_name must be one of {', '.join(FILE_FORMATS)}, got {format_name!r}"
        )
    return row


def file_format(path: PathLike) -> str:
    """The name of the format of ``path`` by its suffix (``"csv"``, ``"parquet"``).

    Raises
    ------
    DataFileError
        The suffix is none of :func:`detection_formats`.
    """
    return _format_of_path(path).name


def file_name(stem: str, format_name: str) -> str:
    """``stem`` with the suffix files of ``format_name`` are written with
    (``file_name("tracks", "parquet") == "tracks.parquet"``).

    Raises
    ------
    InputError
        ``format_name`` is not in :data:`FILE_FORMATS`.
    """
    return stem + _named_format(format_name).suffixes[0]


def _function(path: PathLike, verb: str, kind: str) -> Callable[..., Any]:
    return _format_of_path(path, f"{verb}_{kind}_file").function(verb, kind)


def read_detections_file(
    path: PathLike,
    sensors: Mapping[str, Sensor],
    *,
    content: bytes | None = None,
    format_name: str | None = None,
) -> list[Scan]:
    """Read a detections file in the format ``format_name``, else that of its suffix, else
    (no suffix: a stream such as ``/dev/stdin``) that of its bytes (:func:`sniff_format`).

    ``content``: the file's bytes when the caller has read them already (``path`` then
    only names the file); a file without a suffix, or with ``format_name``, is otherwise
    read once here, then sniffed and parsed from those bytes.  See
    :func:`mapassoc.data.io.read_detections` and
    :func:`mapassoc.data.parquet.read_detections_parquet`.

    Raises
    ------
    InputError
        ``format_name`` is not in :data:`FILE_FORMATS`.
    DataFileError
        An unknown suffix without ``format_name``, an unreadable file, a malformed one.
    """
    text = check_path("read_detections_file: path", path)
    named = None if format_name is None else _named_format(format_name)
    if named is None and PurePath(text).suffix:
        row = _format_of_path(
            path, "read_detections_file", hint="; or name its format: --format csv|parquet"
        )
    else:  # perhaps a stream, which can be read only once and not sought in
        if content is None:
            content = _read_bytes(path)
        row = named or FILE_FORMATS[sniff_format(content)]
    scans: list[Scan] = row.function("read", "detections")(path, sensors, content=content)
    return scans


def _read_bytes(path: PathLike) -> bytes:
    try:
        with open(path, "rb") as handle:
            return handle.read()
    except OSError as exc:
        raise DataFileError(
            os.fspath(path), f"cannot read the file: {exc.strerror or exc}"
        ) from None


def write_detections_file(
    path: PathLike, scans: Sequence[Scan], sensors: Mapping[str, Sensor]
) -> None:
    """Write a detections file in the format of its suffix.

    Both formats keep the detection ids: a CSV file gets a ``detection_id`` column
    unless the ids are its line numbers (:func:`mapassoc.data.io.number_rows`).  See
    :func:`mapassoc.data.io.write_detections` and
    :func:`mapassoc.data.parquet.write_detections_parquet`.
    """
    _function(path, "write", "detections")(path, scans, sensors)


def read_tracks_file(path: PathLike) -> TrackTable:
    """Read a tracks file in the format of its suffix."""
    table: TrackTable = _function(path, "read", "tracks")(path)
    return table


def write_tracks_file(path: PathLike, table: TrackTable) -> None:
    """Write a tracks file in the format of its suffix."""
    _function(path, "write", "tracks")(path, table)


def read_truth_file(path: PathLike) -> TruthTable:
    """Read a truth file in the format of its suffix."""
    table: TruthTable = _function(path, "read", "truth")(path)
    return table


def write_truth_file(path: PathLike, table: TruthTable) -> None:
    """Write a truth file in the format of its suffix."""
    _function(path, "write", "truth")(path, table)


def read_origins_file(path: PathLike) -> Origins:
    """Read an origins file in the format of its suffix."""
    origins: Origins = _function(path, "read", "origins")(path)
    return origins


def write_origins_file(path: PathLike, origins: Origins) -> None:
    """Write an origins file in the format of its suffix."""
    _function(path, "write", "origins")(path, origins)
