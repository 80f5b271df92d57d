"""Exceptions raised by mapassoc for bad input and for outputs that cannot be written.

Every error names what is wrong: the argument, file, row, column or configuration
key, the offending value and what was expected.  Solver failures live in
:mod:`mapassoc.solvers.results` (the solver package never imports domain code).
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = [
    "MapassocError",
    "InputError",
    "ConfigError",
    "DataFileError",
    "NotPositiveDefiniteError",
    "OutputError",
    "StopRequested",
    "check_stop",
]


class MapassocError(Exception):
    """Base class of every error mapassoc raises on purpose."""


class InputError(MapassocError, ValueError):
    """A public function was called with an argument it cannot accept.

    Parameters
    ----------
    message : str
        What is wrong: the argument, the value received and what was expected.
    key : str, optional
        Name of the offending field when a settings dataclass raised it (for example
        ``"rate"`` or ``"max_tracks"``), followed by an element index for an entry of a
        sequence field (``"k_prior_weights[1]"``); ``None`` otherwise.
        :mod:`mapassoc.data.config` reports it as the configuration key.
    """

    def __init__(self, message: str, *, key: str | None = None) -> None:
        self.key = key
        super().__init__(message)


class ConfigError(MapassocError, ValueError):
    """A configuration file or mapping has a missing, unknown or invalid key.

    Parameters
    ----------
    key : str
        Path of the offending key, for example ``"sensors[0].detection_probability"``.
    message : str
        What is wrong and what was expected.
    source : str, optional
        The file the configuration came from.
    """

    def __init__(self, key: str, message: str, *, source: str | None = None) -> None:
        self.key = key
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(f"{where}config key '{key}': {message}")


class DataFileError(MapassocError, ValueError):
    """A data file (detections, truth, tracks) has a malformed row or column.

    Parameters
    ----------
    path : str
        The file.
    message : str
        What is wrong and what was expected.
    row : int, optional
        1-based line number in the file (the header is line 1).
    column : str, optional
        Column name.
    """

    def __init__(
        self, path: str, message: str, *, row: int | None = None, column: str | None = None
    ) -> None:
        self.path = path
        self.row = row
        self.column = column
        where = str(path)
        if row is not None:
            where += f", line {row}"
        if column is not None:
            where += f", column '{column}'"
        super().__init__(f"{where}: {message}")


class NotPositiveDefiniteError(MapassocError, ValueError):
    """A covariance matrix that must be symmetric positive-definite is not."""


class OutputError(MapassocError):
    """An output (a file, a run folder, standard output) cannot be written.

    Parameters
    ----------
    path : str
        The file or folder (``"<stdout>"`` for standard output).
    message : str
        What is wrong (the operating system's reason) and what to do.
    """

    def __init__(self, path: str, message: str) -> None:
        self.path = path
        super().__init__(f"{path}: {message}")


class StopRequested(MapassocError):
    """A stop request ended a computation between two units of its work.

    Every long phase (the forward pass, the parameter estimation, the whole recording's
    refinement, the confidence pass) polls the same ``stop`` callable between its units
    (a window, a re-solve or a link, an estimation window, a confidence window) and raises
    this when it returns True; the caller (``mapassoc run``) checkpoints what it had.

    Parameters
    ----------
    phase : str
        What was stopped, as a phrase ("the refinement of the whole recording").
    message : str, optional
        The whole message (default: ``"stopped during <phase>"``).
    """

    def __init__(self, phase: str, message: str | None = None) -> None:
        self.phase = phase
        super().__init__(message or f"stopped during {phase}")


def check_stop(stop: Callable[[], bool] | None, phase: str) -> None:
    """Raise :class:`StopRequested` for ``phase`` when ``stop`` is given and returns True."""
    if stop is not None and stop():
        raise StopRequested(phase)
