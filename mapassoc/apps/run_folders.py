"""Run folders that never mix runs: a temporary sibling, a manifest, checkpoints.

A run into ``OUT`` works in the sibling folder ``OUT.partial`` and renames it to ``OUT``
only when every output is written, so ``OUT`` holds either nothing, or one complete run
(or, with ``--overwrite``, the previous complete run until the new one is done).  Both
folders hold ``manifest.json``::

    {"format": "mapassoc-run/1", "status": "running" | "complete" | "interrupted" | "failed",
     "mapassoc_version": ..., "inputs": {"config": {"path", "sha256", "bytes"},
     "detections": {...}}, "settings": {...}, "started": ..., "ended": ..., "sessions": n,
     "scans_committed": ..., "scans_total": ..., "windows_committed": ..., "error": ...}

While a run goes on, ``OUT.partial/checkpoint.pickle`` holds the estimator's state after
the last checkpointed window and the length ``windows.jsonl`` had then; ``--resume``
cuts ``windows.jsonl`` back to that length and steps on from that state, so a resumed
run writes exactly the files an uninterrupted one would.  The checkpoint is a pickle:
resume only run folders you (or your own batch) wrote.

Writes of the manifest and the checkpoint go to a temporary file that is renamed over
the old one (atomic on POSIX), so a kill at any moment leaves the previous version whole.

Nothing is deleted that mapassoc did not write: a folder is replaced (``--overwrite``) or
emptied only when it is absent, empty, or holds a manifest of this folder's kind
(:func:`is_own_folder`), and never when it holds one of the run's own inputs
(:meth:`RunFolder.check_replaceable`).  ``mapassoc demo`` uses the same folders with a
manifest of its own kind (``mapassoc-demo/1``).
"""

from __future__ import annotations

import datetime
import errno
import fcntl
import hashlib
import json
import os
import pickle
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mapassoc.errors import InputError, OutputError
from mapassoc.version import __version__

__all__ = [
    "MANIFEST_NAME",
    "CHECKPOINT_NAME",
    "RUN_STATUSES",
    "RunFolder",
    "RUN_FORMAT",
    "DEMO_FORMAT",
    "file_identity",
    "is_own_folder",
    "inside",
    "os_reason",
    "write_atomically",
    "read_manifest",
]

MANIFEST_NAME = "manifest.json"
CHECKPOINT_NAME = "checkpoint.pickle"
RUN_FORMAT = "mapassoc-run/1"
"""``manifest.json`` format of a ``mapassoc run`` folder."""
DEMO_FORMAT = "mapassoc-demo/1"
"""``manifest.json`` format of a ``mapassoc demo`` folder."""
RUN_STATUSES = ("running", "complete", "interrupted", "failed")
"""A run's ``manifest.json`` status."""


def now_text() -> str:
    """The current UTC time, ISO 8601 to the second."""
    return datetime.datetime.now(datetime.UTC).replace(microsecond=0).isoformat()


def os_reason(exc: OSError) -> str:
    """The operating system's reason, as the user knows it ("No space left on device")."""
    if exc.errno is not None:
        return os.strerror(exc.errno)
    return str(exc)


def file_identity(path: str | os.PathLike[str], content: bytes) -> dict[str, object]:
    """``{"path", "bytes", "sha256"}`` of an input file, from its bytes (read once)."""
    return {
        "path": os.fspath(path),
        "bytes": len(content),
        "sha256": hashlib.sha256(content).hexdigest(),
    }


def write_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file renamed over it.

    Raises
    ------
    OutputError
        The folder is not writable, the disk is full, ...: names ``path``.
    """
    temporary = path.with_name(path.name + ".tmp")
    try:
        with open(temporary, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except OSError as exc:
        raise OutputError(str(path), f"cannot write: {os_reason(exc)}") from None


def read_manifest(folder: Path, *, kind: str = RUN_FORMAT) -> dict[str, Any] | None:
    """The manifest of a run folder, or None when it has none.

    Parameters
    ----------
    folder : Path
    kind : str
        The manifest ``format`` expected (:data:`RUN_FORMAT` or :data:`DEMO_FORMAT`).

    Raises
    ------
    InputError
        The manifest exists but is not a mapassoc manifest of that kind.
    """
    path = folder / MANIFEST_NAME
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise OutputError(str(path), f"cannot read: {os_reason(exc)}") from None
    try:
        manifest = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not a mapassoc run manifest (invalid JSON: {exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != kind:
        found = manifest.get("format") if isinstance(manifest, dict) else None
        what = f"format {found!r}" if isinstance(found, str) else "no format"
        raise InputError(f"{path}: not a mapassoc run manifest ({what}, expected {kind!r})")
    if manifest.get("status") not in RUN_STATUSES:
        raise InputError(
            f"{path}: status {manifest.get('status')!r} is not one of {list(RUN_STATUSES)}"
        )
    return manifest


def _is_empty_folder(path: Path) -> bool:
    return path.is_dir() and not any(path.iterdir())


def is_own_folder(path: Path, *, kind: str = RUN_FORMAT) -> bool:
    """Whether mapassoc may replace or empty ``path``: absent, empty, or of ``kind``.

    A folder of ``kind`` is one whose ``manifest.json`` has ``"format": kind`` (what a
    run or a demo writes first); anything else (a folder of the user's, a file, another
    kind of mapassoc folder) is not mapassoc's to delete.
    """
    if not path.exists():
        return True
    if not path.is_dir():
        return False
    if not any(path.iterdir()):
        return True
    try:
        manifest = json.loads((path / MANIFEST_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(manifest, dict) and manifest.get("format") == kind


def inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` is ``folder`` or below it (links resolved)."""
    return Path(os.path.realpath(path)).is_relative_to(os.path.realpath(folder))


class RunFolder:
    """The output folder ``OUT`` of one run and its working sibling ``OUT.partial``.

    Parameters
    ----------
    path : path
        ``OUT``, as given to ``--out``.
    kind : str
        The manifest format of the folder (:data:`RUN_FORMAT`, :data:`DEMO_FORMAT`):
        only a folder of this kind is ever replaced or emptied.
    """

    def __init__(self, path: str | os.PathLike[str], *, kind: str = RUN_FORMAT) -> None:
        self.path = Path(path)
        if self.path.name in ("", ".", ".."):
            raise InputError(f"--out must name a folder, got {os.fspath(path)!r}")
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.kind = kind
        self.noun = "demo" if kind == DEMO_FORMAT else "run"
        self._lock: tuple[Path, Any] | None = None

    # -- checks before anything is computed ------------------------------------------
    def check_writable_place(self) -> None:
        """Raise OutputError when ``OUT`` cannot be a folder (a file, below a file)."""
        for candidate in (self.path, self.partial):
            if candidate.exists() and not candidate.is_dir():
                raise OutputError(
                    str(candidate), "is a file, not a folder; choose another --out"
                )
        parent = self.path.parent
        while not parent.exists() and parent != parent.parent:
            parent = parent.parent
        if parent.exists() and not parent.is_dir():
            raise OutputError(str(parent), f"is a file, so {self.path} cannot be a folder")

    def final_manifest(self) -> dict[str, Any] | None:
        """The manifest of ``OUT`` (None: no run there)."""
        return read_manifest(self.path, kind=self.kind) if self.path.is_dir() else None

    def partial_manifest(self) -> dict[str, Any] | None:
        """The manifest of ``OUT.partial`` (None: no unfinished run)."""
        return read_manifest(self.partial, kind=self.kind) if self.partial.is_dir() else None

    def check_replaceable(self, inputs: Sequence[str | os.PathLike[str]] = ()) -> None:
        """Raise OutputError unless ``OUT`` and ``OUT.partial`` may be replaced.

        What ``--overwrite`` and a fresh start may delete: each folder must be absent,
        empty or a folder of this kind (:func:`is_own_folder`), and neither may hold one
        of ``inputs`` (a run's own configuration or detections).  Checked before
        anything is computed, and again just before a folder is deleted.
        """
        for folder in (self.path, self.partial):
            for source in inputs:
                if folder.exists() and inside(Path(source), folder):
                    raise OutputError(
                        str(folder),
                        f"holds the input {os.fspath(source)}; mapassoc never replaces a "
                        "folder holding its own inputs: choose another --out",
                    )
            if not is_own_folder(folder, kind=self.kind):
                raise OutputError(
                    str(folder),
                    f"is not empty and is not a mapassoc {self.noun} folder (no "
                    f"manifest.json of format {self.kind!r}); mapassoc replaces only its own "
                    "outputs: choose another --out, or empty it yourself",
                )

    def refuse_existing(self) -> None:
        """Raise OutputError unless both ``OUT`` and ``OUT.partial`` are absent or empty."""
        if self.partial.exists() and not _is_empty_folder(self.partial):
            if not is_own_folder(self.partial, kind=self.kind):
                self.check_replaceable()  # raises, naming the folder
            manifest = self.partial_manifest()
            status = manifest["status"] if manifest else "unknown"
            raise OutputError(
                str(self.partial),
                f"holds an unfinished run (status {status}); pass --resume to continue it "
                "or --overwrite to start again",
            )
        if self.path.exists() and not _is_empty_folder(self.path):
            if not is_own_folder(self.path, kind=self.kind):
                raise OutputError(
                    str(self.path),
                    f"is not empty and holds no mapassoc {self.noun}; choose another --out",
                )
            manifest = self.final_manifest()
            status = manifest["status"] if manifest else "unknown"
            raise OutputError(
                str(self.path),
                f"holds a {status} {self.noun}; pass --overwrite to replace it (or --resume "
                "to finish or skip it), or choose another --out",
            )

    # -- the working folder ----------------------------------------------------------
    def lock(self) -> None:
        """Take the run's lock (``.OUT.lock`` beside it), or raise OutputError.

        Two runs into the same folder would wipe or interleave each other's files; the
        lock (an ``flock``, released by the system when its process ends, however it
        ends) lets only one of them write.  Idempotent.
        """
        if self._lock is not None:
            return
        path = self.path.with_name(f".{self.path.name}.lock")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)  # --out a/b with no a/ yet
            handle = open(path, "a+", encoding="utf-8")
        except OSError as exc:
            raise OutputError(str(path), f"cannot create the lock: {os_reason(exc)}") from None
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.seek(0)
            owner = handle.read().strip() or "unknown"
            handle.close()
            raise OutputError(
                str(self.partial),
                f"another mapassoc run (pid {owner}) is writing it; wait for it to end or "
                "stop it",
            ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()}\n")
        handle.flush()
        self._lock = (path, handle)

    def release(self) -> None:
        """Drop the lock file and the lock (a no-op when not held)."""
        if self._lock is None:
            return
        path, handle = self._lock
        self._lock = None
        path.unlink(missing_ok=True)
        handle.close()

    def begin(self, *, fresh: bool) -> None:
        """Take the lock and create ``OUT.partial`` (emptied first when ``fresh``)."""
        self.lock()
        if fresh and not is_own_folder(self.partial, kind=self.kind):
            self.release()
            self.check_replaceable()  # raises, naming the folder
        try:
            if fresh and self.partial.exists():
                shutil.rmtree(self.partial)
            self.partial.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            self.release()
            raise OutputError(
                str(self.partial), f"cannot create the run folder: {os_reason(exc)}"
            ) from None

    def write_manifest(self, manifest: Mapping[str, object]) -> None:
        """Write ``OUT.partial/manifest.json`` atomically."""
        text = json.dumps(dict(manifest), indent=2, allow_nan=False) + "\n"
        write_atomically(self.partial / MANIFEST_NAME, text.encode("utf-8"))

    def write_checkpoint(self, checkpoint: object) -> None:
        """Write ``OUT.partial/checkpoint.pickle`` atomically."""
        data = pickle.dumps(checkpoint, protocol=pickle.HIGHEST_PROTOCOL)
        write_atomically(self.partial / CHECKPOINT_NAME, data)

    def read_checkpoint(self) -> object | None:
        """The checkpoint of ``OUT.partial`` (None: none written yet)."""
        path = self.partial / CHECKPOINT_NAME
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            return None
        except OSError as exc:
            raise OutputError(str(path), f"cannot read: {os_reason(exc)}") from None
        try:
            return pickle.loads(data)  # noqa: S301 - our own checkpoint (module docstring)
        except Exception as exc:  # a checkpoint of another version, or a damaged file
            raise InputError(
                f"{path}: cannot restore the checkpoint ({type(exc).__name__}: {exc}); "
                "pass --overwrite to start the run again"
            ) from None

    def complete(self) -> None:
        """Drop the checkpoint and move ``OUT.partial`` into place as ``OUT``.

        A previous ``OUT`` (``--overwrite``) is moved aside first and deleted after the
        rename, so ``OUT`` always holds one whole run.
        """
        self.lock()
        if not is_own_folder(self.path, kind=self.kind):
            self.check_replaceable()  # raises, naming the folder: never delete another's
        try:
            (self.partial / CHECKPOINT_NAME).unlink(missing_ok=True)
            aside = None
            if self.path.exists():
                aside = self.path.with_name(f"{self.path.name}.old-{os.getpid()}")
                os.replace(self.path, aside)
            os.replace(self.partial, self.path)
            if aside is not None:
                shutil.rmtree(aside)
        except OSError as exc:
            where = exc.filename if isinstance(exc.filename, str) else str(self.path)
            if exc.errno in (errno.ENOTEMPTY, errno.EEXIST):
                raise OutputError(where, "cannot replace the folder: not empty") from None
            raise OutputError(where, f"cannot finish the run folder: {os_reason(exc)}") from None


def new_manifest(
    *,
    inputs: Mapping[str, object],
    settings: Mapping[str, object],
    scans_total: int,
    kind: str = RUN_FORMAT,
) -> dict[str, object]:
    """The manifest of a run that starts now (status ``running``, first session)."""
    return {
        "format": kind,
        "status": "running",
        "mapassoc_version": __version__,
        "inputs": dict(inputs),
        "settings": dict(settings),
        "started": now_text(),
        "ended": None,
        "sessions": 1,
        "scans_total": scans_total,
        "scans_committed": 0,
        "windows_committed": 0,
        "error": None,
    }
