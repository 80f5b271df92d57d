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
(:meth:`RunFolder.check_replaceable`).  ``mapassoc demo`` and ``mapassoc compare`` use
the same folders with a manifest of their own kind (``mapassoc-demo/1``,
``mapassoc-compare/1``).  ``mapassoc batch`` writes its folder in place
(:class:`WorkFolder`, ``mapassoc-batch/1``) under the same rule: it writes into a folder
only when it is absent, empty or a batch folder, and one batch at a time.

An ``--out`` that is a symbolic link is followed (:func:`followed`): the folder it points
to is the one written, replaced or resumed, and the link stays as it is, still pointing
at it.  (Replacing the link itself by a folder would silently move the outputs off the
disk the user chose; refusing would break the common ``out -> /scratch/out`` set-up.)
The working sibling and the lock are beside the target, so a run through the link and
one through the target share them.

Every single file mapassoc writes on its own (``evaluate --json``, ``estimate-parameters
--write``, a batch summary, a manifest) goes through :func:`write_atomically`: a failure
(a full disk, a signal) leaves the previous file whole, or no file, and no temporary.
"""

from __future__ import annotations

import datetime
import errno
import fcntl
import hashlib
import json
import os
import pickle
import secrets
import shutil
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

from mapassoc.errors import InputError, OutputError
from mapassoc.version import __version__

__all__ = [
    "MANIFEST_NAME",
    "CHECKPOINT_NAME",
    "RUN_STATUSES",
    "RunFolder",
    "RUN_FORMAT",
    "DEMO_FORMAT",
    "COMPARE_FORMAT",
    "BATCH_FORMAT",
    "WorkFolder",
    "file_identity",
    "followed",
    "is_own_folder",
    "inside",
    "os_reason",
    "take_lock",
    "write_atomically",
    "write_json",
    "read_manifest",
]

MANIFEST_NAME = "manifest.json"
"""File of a run folder that says what the run was (inputs, configuration, state)."""
CHECKPOINT_NAME = "checkpoint.pickle"
"""File of a run folder that holds the pickled state a resumed run continues from."""
RUN_FORMAT = "mapassoc-run/1"
"""``manifest.json`` format of a ``mapassoc run`` folder."""
DEMO_FORMAT = "mapassoc-demo/1"
"""``manifest.json`` format of a ``mapassoc demo`` folder."""
COMPARE_FORMAT = "mapassoc-compare/1"
"""``manifest.json`` format of a ``mapassoc compare`` folder."""
BATCH_FORMAT = "mapassoc-batch/1"
"""``manifest.json`` format of a ``mapassoc batch`` folder."""
_NOUNS = {RUN_FORMAT: "run", DEMO_FORMAT: "demo", COMPARE_FORMAT: "comparison",
          BATCH_FORMAT: "batch"}  # fmt: skip
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


def followed(path: str | os.PathLike[str]) -> Path:
    """``path``, or where it points when it is a symbolic link (module docstring)."""
    given = Path(path)
    return Path(os.path.realpath(given)) if given.is_symlink() else given


def write_atomically(path: Path, data: bytes, *, new: bool = False) -> None:
    """Write ``data`` to ``path`` through a temporary file renamed over it.

    The temporary file (``.NAME.<random>.tmp`` beside the target, so that the rename
    stays on one file system) is flushed to the disk before the rename, and removed
    whatever the failure, a signal included: ``path`` holds either its previous bytes
    (or nothing, when it was absent) or all of ``data``.  A ``path`` that is a symbolic
    link is followed, the link kept.

    Parameters
    ----------
    path : Path
    data : bytes
    new : bool
        Refuse to replace an existing ``path`` (checked again just before the rename).

    Raises
    ------
    OutputError
        The folder is not writable, the disk is full, ``path`` exists and ``new``, ...:
        names ``path``.
    """
    target = followed(path)
    temporary = target.with_name(f".{target.name}.{secrets.token_hex(4)}.tmp")
    created = False
    try:
        # O_EXCL: never write through a file of the same name; mode 0o666 less the
        # umask, as an ordinary open() would create the file.
        descriptor = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        created = True
        with open(descriptor, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        if new and os.path.lexists(target):
            raise OutputError(str(path), "exists already; name a new file to write")
        os.replace(temporary, target)
        created = False
    except OSError as exc:
        raise OutputError(str(path), f"cannot write: {os_reason(exc)}") from None
    finally:
        if created:
            try:
                temporary.unlink()
            except OSError:
                pass


def write_json(path: Path, data: object, *, allow_nan: bool = False) -> None:
    """Write ``data`` as indented JSON to ``path`` (:func:`write_atomically`).

    Raises
    ------
    OutputError
        The file cannot be written: names ``path``.
    """
    text = json.dumps(data, indent=2, allow_nan=allow_nan) + "\n"
    write_atomically(path, text.encode("utf-8"))


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


def _folder_path(path: str | os.PathLike[str]) -> Path:
    """``--out`` as a folder path, a symbolic link followed; InputError for ``.``, ``..``."""
    given = Path(path)
    folder = followed(given)
    if given.name in ("", ".", "..") or folder.name in ("", ".", ".."):
        raise InputError(f"--out must name a folder, got {os.fspath(path)!r}")
    return folder


def _is_empty_folder(path: Path) -> bool:
    return path.is_dir() and not any(path.iterdir())


def is_own_folder(
    path: Path, *, kind: str = RUN_FORMAT, adopt: Callable[[Path], bool] | None = None
) -> bool:
    """Whether mapassoc may replace or empty ``path``: absent, empty, or of ``kind``.

    A folder of ``kind`` is one whose ``manifest.json`` has ``"format": kind`` (what a
    run or a demo writes first), or, with no ``manifest.json``, one ``adopt`` recognises
    as written by an older version that wrote none; anything else (a folder of the
    user's, a file, another kind of mapassoc folder) is not mapassoc's to delete.
    """
    if not path.exists():
        return True
    if not path.is_dir():
        return False
    if not any(path.iterdir()):
        return True
    try:
        manifest = json.loads((path / MANIFEST_NAME).read_text(encoding="utf-8"))
    except FileNotFoundError:
        return adopt is not None and adopt(path)
    except (OSError, ValueError):
        return False
    return isinstance(manifest, dict) and manifest.get("format") == kind


def inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` is ``folder`` or below it (links resolved)."""
    return Path(os.path.realpath(path)).is_relative_to(os.path.realpath(folder))


def take_lock(folder: Path, named: Path, *, noun: str) -> tuple[Path, IO[str]]:
    """Take the lock of ``folder`` (the file ``.NAME.lock`` beside it) or raise OutputError.

    The lock is an ``flock``, which the system releases when its process ends, however
    it ends: a lock file left by a process that died (``kill -9``, a power cut) blocks
    nothing, the next taker simply takes it.  The file holds the holder's pid, for the
    message of a second taker, which names ``named`` and the ``noun`` ("run", "batch").
    """
    path = folder.with_name(f".{folder.name}.lock")
    for _ in range(10):
        try:
            path.parent.mkdir(parents=True, exist_ok=True)  # --out a/b with no a/ yet
            handle = open(path, "a+", encoding="utf-8")  # noqa: SIM115 - held until release
        except OSError as exc:
            raise OutputError(str(path), f"cannot create the lock: {os_reason(exc)}") from None
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.seek(0)
            owner = handle.read().strip()
            handle.close()
            pid = f" (pid {owner})" if owner.isdigit() else ""
            raise OutputError(
                str(named),
                f"another mapassoc {noun}{pid} is writing it; wait for it to end or stop it",
            ) from None
        if _same_file(handle, path):
            handle.seek(0)
            handle.truncate()
            handle.write(f"{os.getpid()}\n")
            handle.flush()
            return path, handle
        # The holder released (and unlinked) the file between our open and our flock:
        # this lock guards nothing any more; take the new file's.
        handle.close()
    raise OutputError(str(path), "cannot take the lock: it keeps being replaced")


def _same_file(handle: IO[str], path: Path) -> bool:
    try:
        return os.path.samestat(os.fstat(handle.fileno()), os.stat(path))
    except OSError:
        return False


def drop_lock(lock: tuple[Path, IO[str]] | None) -> None:
    """Release a lock of :func:`take_lock` and remove its file (None: a no-op)."""
    if lock is None:
        return
    path, handle = lock
    path.unlink(missing_ok=True)
    handle.close()


class RunFolder:
    """The output folder ``OUT`` of one run and its working sibling ``OUT.partial``.

    Parameters
    ----------
    path : path
        ``OUT``, as given to ``--out``; a symbolic link is followed (module docstring).
    kind : str
        The manifest format of the folder (:data:`RUN_FORMAT`, :data:`DEMO_FORMAT`,
        :data:`COMPARE_FORMAT`): only a folder of this kind is ever replaced or emptied.
    adopt : callable, optional
        Whether a folder without ``manifest.json`` is one an older version wrote
        (:func:`is_own_folder`).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        kind: str = RUN_FORMAT,
        adopt: Callable[[Path], bool] | None = None,
    ) -> None:
        self.path = _folder_path(path)
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.kind = kind
        self.adopt = adopt
        self.noun = _NOUNS.get(kind, "run")
        self._lock: tuple[Path, IO[str]] | None = None

    # -- checks before anything is computed ------------------------------------------
    def check_writable_place(self) -> None:
        """Raise OutputError when ``OUT`` cannot be a folder (a file, below a file)."""
        if self.partial.is_symlink():
            raise OutputError(
                str(self.partial),
                "is a symbolic link, which mapassoc never makes; remove it or choose "
                "another --out",
            )
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
            if not is_own_folder(folder, kind=self.kind, adopt=self.adopt):
                raise OutputError(
                    str(folder),
                    f"is not empty and is not a mapassoc {self.noun} folder (no "
                    f"manifest.json of format {self.kind!r}); mapassoc replaces only its own "
                    "outputs: choose another --out, or empty it yourself",
                )

    def refuse_existing(self) -> None:
        """Raise OutputError unless both ``OUT`` and ``OUT.partial`` are absent or empty."""
        if self.partial.exists() and not _is_empty_folder(self.partial):
            if not is_own_folder(self.partial, kind=self.kind, adopt=self.adopt):
                self.check_replaceable()  # raises, naming the folder
            manifest = self.partial_manifest()
            status = manifest["status"] if manifest else "unknown"
            resume = "--resume to continue it or " if self.kind == RUN_FORMAT else ""
            raise OutputError(
                str(self.partial),
                f"holds an unfinished {self.noun} (status {status}); pass {resume}"
                "--overwrite to start again",
            )
        if self.path.exists() and not _is_empty_folder(self.path):
            if not is_own_folder(self.path, kind=self.kind, adopt=self.adopt):
                raise OutputError(
                    str(self.path),
                    f"is not empty and holds no mapassoc {self.noun}; choose another --out",
                )
            manifest = self.final_manifest()
            status = manifest["status"] if manifest else "unknown"
            resume = " (or --resume to finish or skip it)" if self.kind == RUN_FORMAT else ""
            raise OutputError(
                str(self.path),
                f"holds a {status} {self.noun}; pass --overwrite to replace it{resume}, or "
                "choose another --out",
            )

    # -- the working folder ----------------------------------------------------------
    def lock(self) -> None:
        """Take the run's lock (``.OUT.lock`` beside it), or raise OutputError.

        Two runs into the same folder would wipe or interleave each other's files; the
        lock (:func:`take_lock`) lets only one of them write.  Idempotent.
        """
        if self._lock is None:
            self._lock = take_lock(self.path, self.partial, noun=self.noun)

    def release(self) -> None:
        """Drop the lock file and the lock (a no-op when not held)."""
        lock, self._lock = self._lock, None
        drop_lock(lock)

    def begin(self, *, fresh: bool) -> None:
        """Take the lock and create ``OUT.partial`` (emptied first when ``fresh``)."""
        self.lock()
        if fresh and not is_own_folder(self.partial, kind=self.kind, adopt=self.adopt):
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
        if not is_own_folder(self.path, kind=self.kind, adopt=self.adopt):
            self.check_replaceable()  # raises, naming the folder: never delete another's
        aside = None
        try:
            (self.partial / CHECKPOINT_NAME).unlink(missing_ok=True)
            if self.path.exists():
                aside = self.path.with_name(f"{self.path.name}.old-{os.getpid()}")
                os.replace(self.path, aside)
            try:
                os.replace(self.partial, self.path)
            except OSError:
                if aside is not None:  # put the previous run back: OUT is never left empty
                    os.replace(aside, self.path)
                raise
            if aside is not None:
                shutil.rmtree(aside)
        except OSError as exc:
            where = exc.filename if isinstance(exc.filename, str) else str(self.path)
            if exc.errno in (errno.ENOTEMPTY, errno.EEXIST):
                raise OutputError(where, "cannot replace the folder: not empty") from None
            raise OutputError(where, f"cannot finish the run folder: {os_reason(exc)}") from None


class WorkFolder:
    """A folder mapassoc writes in place, file by file and over sessions (a batch).

    It is mapassoc's when it holds ``manifest.json`` of its ``kind``, written before
    anything else; it is written only when absent, empty or mapassoc's (or, for folders
    an older version wrote without a manifest, when ``adopt`` recognises it), and by one
    process at a time (:func:`take_lock`, ``.OUT.lock`` beside it).

    Parameters
    ----------
    path : path
        ``OUT``, as given to ``--out``; a symbolic link is followed (module docstring).
    kind : str
        The manifest format (:data:`BATCH_FORMAT`).
    adopt : callable, optional
        Whether a non-empty folder without a manifest is one an older version wrote.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        kind: str = BATCH_FORMAT,
        adopt: Callable[[Path], bool] | None = None,
    ) -> None:
        self.path = _folder_path(path)
        self.kind = kind
        self.noun = _NOUNS.get(kind, "batch")
        self.adopt = adopt
        self._lock: tuple[Path, IO[str]] | None = None

    def is_own(self) -> bool:
        """Whether the folder is absent, empty, of this kind, or adopted."""
        return is_own_folder(self.path, kind=self.kind, adopt=self.adopt)

    def check(self, *, again: bool, hint: str) -> None:
        """Raise OutputError unless the folder may be written (before anything is computed).

        ``again``: the user asked to write into a previous folder of this kind
        (``--overwrite``, ``--resume``); without it only an absent or empty folder is
        written, and ``hint`` says what to pass.
        """
        if self.path.exists() and not self.path.is_dir():
            raise OutputError(str(self.path), "is a file, not a folder; choose another --out")
        if not self.path.exists() or _is_empty_folder(self.path):
            return
        if not self.is_own():
            raise OutputError(
                str(self.path),
                f"is not empty and is not a mapassoc {self.noun} folder (no manifest.json "
                f"of format {self.kind!r}); mapassoc writes only into its own folders: "
                "choose another --out, or empty it yourself",
            )
        if not again:
            raise OutputError(str(self.path), f"is not empty; {hint}")

    def claim(self, manifest: Mapping[str, object], *, again: bool, hint: str) -> None:
        """Take the lock, check again, create the folder and write ``manifest``."""
        self._lock = self._lock or take_lock(self.path, self.path, noun=self.noun)
        try:
            self.check(again=again, hint=hint)  # another process may have written it since
            try:
                self.path.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise OutputError(
                    str(self.path), f"cannot create the folder: {os_reason(exc)}"
                ) from None
            self.write_manifest(manifest)
        except BaseException:
            self.release()
            raise

    def write_manifest(self, manifest: Mapping[str, object]) -> None:
        """Write ``OUT/manifest.json`` atomically."""
        text = json.dumps(dict(manifest), indent=2, allow_nan=False) + "\n"
        write_atomically(self.path / MANIFEST_NAME, text.encode("utf-8"))

    def release(self) -> None:
        """Drop the lock file and the lock (a no-op when not held)."""
        lock, self._lock = self._lock, None
        drop_lock(lock)


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
