"""``mapassoc batch``: many recordings, each in its own run folder, in parallel.

Recordings come from a folder or from a recordings list:

* a **folder** holding, for each recording, either a sub-folder ``NAME/`` with
  ``detections.csv`` (or ``detections.parquet``) and optionally its own ``config.toml``
  (what ``mapassoc simulate`` writes), or a file ``NAME.csv`` / ``NAME.parquet`` with
  optionally ``NAME.toml`` beside it;
* a **recordings list**: a CSV file with the columns ``name,detections`` and optionally
  ``config`` (paths relative to the list's folder; an empty ``config`` cell means the
  shared one).

A recording without its own configuration uses the shared ``--config``.  Each recording
is one :func:`~mapassoc.apps.runs.run_files` run into ``OUT/NAME/`` (a run folder with its
manifest and status); a recording that fails is reported in its row and the batch goes
on.  ``OUT/batch_summary.csv`` gets one row per recording (status, scans, windows,
tracks, seconds, scans per second, warnings, error).

``OUT`` is a :class:`~mapassoc.apps.run_folders.WorkFolder`: its ``manifest.json``
(format ``mapassoc-batch/1``, status, version, start and end) marks it as a batch folder,
the only kind a batch writes into when it is not empty (``--resume``, ``--overwrite``),
besides one an older version wrote (a ``batch_summary.csv`` with this version's columns
and no manifest); and one batch at a time writes it (``.OUT.lock`` beside it).

Recordings run on a local process pool (one process per core by default) or, given a
scheduler address, on a Dask distributed cluster (``pip install 'mapassoc[dask]'``).
Resuming a batch resumes every recording: complete ones are skipped, interrupted ones
continue from their checkpoints.
"""

from __future__ import annotations

import csv
import io
import os
import sys
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from mapassoc.apps.progress import Progress
from mapassoc.apps.run_folders import (
    BATCH_FORMAT,
    WorkFolder,
    inside,
    now_text,
    os_reason,
    write_atomically,
)
from mapassoc.apps.runs import RunInterrupted, RunOptions, run_files
from mapassoc.apps.stopping import StopFlag, stop_on_signals
from mapassoc.apps.workers import check_jobs, run_on_pool, worker_stop_requested
from mapassoc.data.formats import detection_formats
from mapassoc.errors import DataFileError, InputError, MapassocError, OutputError
from mapassoc.validation import check_callback, check_instance, check_path, check_text, shown
from mapassoc.version import __version__

__all__ = [
    "Recording",
    "BatchOptions",
    "BATCH_SUMMARY_NAME",
    "SUMMARY_COLUMNS",
    "find_recordings",
    "run_batch",
]

BATCH_SUMMARY_NAME = "batch_summary.csv"
"""Name of the file a batch writes in its output folder: one row per recording."""
SUMMARY_COLUMNS = (
    "name",
    "status",
    "scans",
    "windows",
    "tracks",
    "seconds",
    "scans_per_second",
    "resumed_at",
    "warnings",
    "warning_messages",
    "error",
    "out",
    "detections",
    "config",
)
"""Columns of the batch summary, in file order."""
LIST_COLUMNS = ("name", "detections", "config")


@dataclass(frozen=True)
class Recording:
    """One recording of a batch.

    Attributes
    ----------
    name : str
        Unique within the batch; its run folder is ``OUT/name``.
    detections : Path
    config : Path or None
        Its own configuration; None: the batch's shared one.
    """

    name: str
    detections: Path
    config: Path | None


BatchOptions = RunOptions
"""The options every recording of a batch runs with: :class:`~mapassoc.apps.runs.RunOptions`
(``progress`` is off for each recording, the batch reports per recording; ``segments``
must be 1, a batch runs its recordings in parallel instead)."""


def _check_name(name: str, where: str) -> str:
    if not name or name in (".", "..") or "/" in name or os.sep in name:
        raise InputError(f"{where}: recording name {name!r} is not a plain folder name")
    return name


def _detections_in(folder: Path) -> Path | None:
    found = [folder / f"detections{suffix}" for suffix in detection_formats()]
    existing = [path for path in found if path.is_file()]
    if len(existing) > 1:
        raise InputError(f"{folder}: holds {len(existing)} detections files; keep one")
    return existing[0] if existing else None


def _from_folder(source: Path) -> list[Recording]:
    recordings: list[Recording] = []
    for entry in sorted(source.iterdir()):
        if entry.name.startswith("."):
            continue
        if entry.is_dir():
            detections = _detections_in(entry)
            if detections is None:
                continue
            config = entry / "config.toml"
            recordings.append(
                Recording(entry.name, detections, config if config.is_file() else None)
            )
        elif entry.suffix.lower() in detection_formats():
            config = entry.with_suffix(".toml")
            recordings.append(
                Recording(entry.stem, entry, config if config.is_file() else None)
            )
    return recordings


def _from_list(source: Path) -> list[Recording]:
    base = source.parent
    try:
        with open(source, encoding="utf-8-sig", newline="") as handle:
            rows = list(csv.reader(handle, strict=True))
    except (OSError, csv.Error, UnicodeDecodeError) as exc:
        reason = os_reason(exc) if isinstance(exc, OSError) else str(exc)
        raise DataFileError(str(source), f"cannot read the recordings list: {reason}") from None
    if not rows:
        raise DataFileError(str(source), "empty; expected a header name,detections[,config]")
    header = [cell.strip() for cell in rows[0]]
    if header[:2] != ["name", "detections"] or not set(header) <= set(LIST_COLUMNS):
        raise DataFileError(
            str(source),
            f"header {','.join(header)}; expected name,detections[,config]",
            row=1,
        )
    recordings: list[Recording] = []
    for line, cells in enumerate(rows[1:], start=2):
        if len(cells) != len(header):
            raise DataFileError(
                str(source), f"{len(cells)} cells, expected {len(header)}", row=line
            )
        record = dict(zip(header, (cell.strip() for cell in cells), strict=True))
        name = _check_name(record["name"], f"{source}, line {line}")
        config = record.get("config", "")
        recordings.append(
            Recording(name, base / record["detections"], base / config if config else None)
        )
    return recordings


def find_recordings(source: str | os.PathLike[str]) -> list[Recording]:
    """The recordings of a folder or a recordings list (module docstring).

    Raises
    ------
    InputError, DataFileError
        No recordings, repeated names, a missing detections file.
    """
    path = Path(check_path("find_recordings: source", source))
    if path.is_dir():
        recordings = _from_folder(path)
    elif path.is_file():
        recordings = _from_list(path)
    else:
        raise InputError(f"recordings source {str(path)!r} is neither a folder nor a file")
    if not recordings:
        raise InputError(
            f"{path}: no recordings found; expected sub-folders with detections.csv, "
            "files NAME.csv / NAME.parquet, or a list with the columns name,detections[,config]"
        )
    names: dict[str, Recording] = {}
    for recording in recordings:
        if recording.name in names:
            raise InputError(
                f"{path}: recording name {recording.name!r} appears twice "
                f"({names[recording.name].detections} and {recording.detections})"
            )
        names[recording.name] = recording
    return recordings


# ------------------------------------------------------------------------- one recording

_ONE_AT_A_TIME = threading.Lock()
"""Runs in one process go one at a time (warnings capture is process-wide)."""


def run_recording(
    recording: Recording,
    shared_config: Path | None,
    out: Path,
    options: RunOptions,
    stop: Callable[[], bool] | None = None,
) -> dict[str, object]:
    """Run one recording into ``out / recording.name``; return its summary row.

    Every failure of the recording (bad input, a write error, even a bug) becomes its
    row's ``status = "failed"`` and ``error``, so that the batch goes on.
    """
    if stop is None:
        stop = worker_stop_requested
    config = recording.config or shared_config
    row = _blank_row(recording, out, config="" if config is None else str(config))
    started = time.perf_counter()
    try:
        if config is None:
            raise InputError(
                f"recording {recording.name!r} has no config.toml of its own and the batch "
                "has no shared --config"
            )
        with _ONE_AT_A_TIME:
            run_options = replace(options, progress=False)
            outcome = run_files(
                config, recording.detections, out / recording.name, run_options, stop=stop
            )
    except RunInterrupted as exc:
        row.update(status="interrupted", scans=exc.scans_committed, error=str(exc))
    except MapassocError as exc:
        row.update(status="failed", error=str(exc))
    except Exception as exc:  # a bug: reported in the row, the batch goes on
        row.update(status="failed", error=f"{type(exc).__name__}: {exc}")
    else:
        summary = outcome.summary
        seconds = time.perf_counter() - started
        warnings_list = [str(w) for w in summary.get("warnings", [])]
        row.update(
            status=outcome.status,
            scans=summary["scans"],
            windows=summary["windows"],
            tracks=summary["tracks"],
            resumed_at=outcome.resumed_at,
            warnings=len(warnings_list),
            warning_messages=" | ".join(warnings_list),
        )
        if outcome.status == "complete":
            done = int(summary["scans"]) - outcome.resumed_at
            row.update(seconds=round(seconds, 3),
                       scans_per_second=round(done / seconds, 2) if seconds > 0 else "")
    return row


# ------------------------------------------------------------------------- the batch


def _write_summary(path: Path, rows: Iterable[dict[str, object]]) -> None:
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomically(path, text.getvalue().encode("utf-8"))


def written_by_an_older_batch(folder: Path) -> bool:
    """Whether ``folder`` is a batch folder of a version that wrote no manifest: its
    ``batch_summary.csv`` starts with this version's header line."""
    header = ",".join(SUMMARY_COLUMNS)
    try:
        with open(folder / BATCH_SUMMARY_NAME, encoding="utf-8", newline="") as handle:
            return handle.readline(len(header) + 2).rstrip("\r\n") == header
    except (OSError, UnicodeDecodeError):
        return False


_AGAIN = (
    "pass --resume to finish the batch (complete recordings are skipped) or --overwrite to "
    "run every recording again"
)


def _claim_out(
    out: Path,
    options: RunOptions,
    recordings: Sequence[Recording],
    manifest: dict[str, object],
) -> WorkFolder:
    """The batch folder, checked, locked and marked, or OutputError.

    Refused: a file, a folder that is not empty and holds no batch (whatever the
    options), a batch folder without ``--resume``/``--overwrite``, a folder another batch
    is writing, and a batch folder that is or holds a recording's detections or
    configuration (``batch recs --out recs``), since each recording's run folder
    ``out/NAME`` would then be the recording's own folder.
    """
    folder = WorkFolder(out, kind=BATCH_FORMAT, adopt=written_by_an_older_batch)
    for recording in recordings:
        for source in (recording.detections, recording.config):
            if source is not None and inside(source, folder.path):
                raise OutputError(
                    str(out),
                    f"holds the input {source} of recording {recording.name!r}; the batch "
                    "folder must be outside the recordings: choose another --out",
                )
    again = options.overwrite or options.resume
    folder.check(again=again, hint=_AGAIN)
    folder.claim(manifest, again=again, hint=_AGAIN)
    return folder


def _batch_manifest(status: str, recordings: int) -> dict[str, object]:
    """The batch folder's ``manifest.json`` as a session starts (module docstring)."""
    return {
        "format": BATCH_FORMAT,
        "status": status,
        "mapassoc_version": __version__,
        "recordings": recordings,
        "started": now_text(),
        "ended": None,
    }


def _check_recordings(recordings: object) -> list[Recording]:
    """``recordings`` as a non-empty list of :class:`Recording`, or an InputError."""
    hint = "list the recordings of a folder or a list file with mapassoc.find_recordings(path)"
    if isinstance(recordings, (str, bytes, os.PathLike)) or not isinstance(recordings, Iterable):
        raise InputError(
            f"run_batch: recordings must be a sequence of Recording, got {shown(recordings)}; "
            f"{hint}"
        )
    listed = list(recordings)
    if not listed:
        raise InputError("recordings is empty: there is nothing to run")
    for i, recording in enumerate(listed):
        check_instance(f"run_batch: recordings[{i}]", recording, Recording, hint=hint)
    return listed


def _check_batch_arguments(scheduler: object, progress: object, on_row: object) -> None:
    """The checks of :func:`run_batch`'s keyword arguments not checked elsewhere."""
    if scheduler is not None:
        check_text("run_batch: scheduler", scheduler)
    check_instance("run_batch: progress", progress, bool, expected="True or False")
    check_callback("run_batch: on_row", on_row)


def run_batch(
    recordings: Sequence[Recording],
    out: str | os.PathLike[str],
    *,
    shared_config: str | os.PathLike[str] | None = None,
    options: RunOptions | None = None,
    jobs: int | None = None,
    scheduler: str | None = None,
    progress: bool = True,
    on_row: Callable[[dict[str, object]], None] | None = None,
) -> list[dict[str, object]]:
    """Run every recording into ``out/NAME/`` and write ``out/batch_summary.csv``.

    Parameters
    ----------
    recordings : sequence of Recording
        From :func:`find_recordings` (names unique).
    out : path
        The batch folder.
    shared_config : path, optional
        Configuration of the recordings without their own.
    options : RunOptions, optional
        How every recording runs and writes (``mapassoc run``'s options; each
        recording's own progress is off, and ``segments`` must be 1); default
        ``RunOptions()``.
    jobs : int, optional
        Worker processes of the local pool (default: the usable cores); 1 runs in this
        process, one recording after the other.
    scheduler : str, optional
        Address of a Dask distributed scheduler (``tcp://host:8786``); the recordings
        run as tasks there instead of on the local pool (``jobs`` is then ignored).
        Workers with one thread each suit this CPU-bound work best.
    progress : bool
        Progress over recordings on stderr.
    on_row : callable, optional
        Called with each recording's row as it finishes.

    Returns
    -------
    list of dict
        One row per recording, in the order of ``recordings`` (the CSV's rows).

    Raises
    ------
    RunInterrupted
        SIGINT or SIGTERM: the running recordings stopped at a window boundary with a
        checkpoint; the summary written says which are ``interrupted`` or ``pending``.
    """
    recordings = _check_recordings(recordings)
    out_path = Path(check_path("run_batch: out", out, hint="the batch folder to write"))
    config = None
    if shared_config is not None:
        config = Path(check_path("run_batch: shared_config", shared_config))
    _check_batch_arguments(scheduler, progress, on_row)
    workers = check_jobs(jobs)
    options = RunOptions() if options is None else options
    if not isinstance(options, RunOptions):
        raise InputError(f"options must be a RunOptions, got {options!r}")
    if options.segments != 1:
        raise InputError(
            f"options.segments must be 1 in a batch (it runs recordings in parallel "
            f"instead), got {options.segments}"
        )
    manifest = _batch_manifest("running", len(recordings))
    folder = _claim_out(out_path, options, recordings, manifest)
    try:
        ordered, stopped = _run_all(recordings, config, out_path, options, workers, scheduler,
                           progress, on_row)  # fmt: skip
        statuses = {str(row["status"]) for row in ordered}
        status = (
            "interrupted" if stopped or statuses & {"interrupted", "pending"}
            else "failed" if "failed" in statuses
            else "complete"
        )  # fmt: skip
        folder.write_manifest({**manifest, "status": status, "ended": now_text()})
    finally:
        folder.release()
    if stopped or any(row["status"] in ("interrupted", "pending") for row in ordered):
        done = sum(1 for row in ordered if row["status"] in ("complete", "skipped"))
        raise RunInterrupted(out_path, done, len(recordings), unit="recordings") from None
    return ordered


def _run_all(
    recordings: Sequence[Recording],
    config: Path | None,
    out_path: Path,
    options: RunOptions,
    workers: int,
    scheduler: str | None,
    progress: bool,
    on_row: Callable[[dict[str, object]], None] | None,
) -> tuple[list[dict[str, object]], bool]:
    """Every recording's row, in order, and whether a signal stopped the batch;
    ``batch_summary.csv`` is written whatever happens."""
    rows: dict[str, dict[str, object]] = {}
    ticker = Progress(sys.stderr, label="batch", unit="recordings", enabled=progress)

    def finished(row: dict[str, object]) -> None:
        rows[str(row["name"])] = row
        if on_row is not None:
            on_row(row)
        # An interrupted recording is not done: it would read "1/1 (100%)" before the
        # line saying the batch stopped after 0 of 1.
        ticker(sum(r["status"] != "interrupted" for r in rows.values()), len(recordings))

    with stop_on_signals(StopFlag(), notice=progress) as stop:
        try:
            if scheduler is not None:
                _on_dask(scheduler, recordings, config, out_path, options, stop, finished)
            elif workers == 1:
                for recording in recordings:
                    if stop():
                        break
                    finished(run_recording(recording, config, out_path, options, stop))
            else:
                _on_pool(workers, recordings, config, out_path, options, stop, finished)
        finally:
            ticker.close()
            ordered = [
                rows.get(r.name) or _blank_row(r, out_path, status="pending") for r in recordings
            ]
            _write_summary(out_path / BATCH_SUMMARY_NAME, ordered)
    return ordered, stop()


def _on_pool(
    workers: int,
    recordings: Sequence[Recording],
    config: Path | None,
    out: Path,
    options: RunOptions,
    stop: StopFlag,
    finished: Callable[[dict[str, object]], None],
) -> None:
    """The recordings on a local process pool; a stop request reaches every worker."""
    run_on_pool(
        min(workers, len(recordings)),
        [(run_recording, (recording, config, out, options), {}) for recording in recordings],
        on_done=lambda i, future: finished(_row_of(future, recordings[i], out, what="worker")),
        stop=stop,
    )


def _blank_row(
    recording: Recording, out: Path, *, status: str = "", error: str = "", config: str = ""
) -> dict[str, object]:
    """A summary row of ``recording`` with its name, folder and detections; the counts
    empty."""
    row: dict[str, object] = {column: "" for column in SUMMARY_COLUMNS}
    row.update(name=recording.name, status=status, error=error, out=str(out / recording.name),
               detections=str(recording.detections), config=config)
    return row


def _row_of(future: Any, recording: Recording, out: Path, *, what: str) -> dict[str, object]:
    """The row of a finished task (a local or a Dask future); a task that raised past
    :func:`run_recording` (a dead worker, a lost task) becomes a failed row."""
    try:
        return future.result()
    except Exception as exc:  # e.g. BrokenProcessPool: the worker died
        return _blank_row(recording, out, status="failed",
                          error=f"{what} failed: {type(exc).__name__}: {exc}")


def _dask_stop(event_name: str) -> Callable[[], bool]:
    """A stop request read from a Dask ``Event`` at most once a second."""
    from distributed import Event

    event = Event(event_name)
    last = [0.0, False]

    def stop() -> bool:
        now = time.monotonic()
        if now - float(last[0]) >= 1.0:
            last[0], last[1] = now, event.is_set()
        return bool(last[1])

    return stop


def _dask_task(
    recording: Recording, config: Path | None, out: Path, options: RunOptions, event_name: str
) -> dict[str, object]:
    return run_recording(recording, config, out, options, _dask_stop(event_name))


def _on_dask(
    scheduler: str,
    recordings: Sequence[Recording],
    config: Path | None,
    out: Path,
    options: RunOptions,
    stop: StopFlag,
    finished: Callable[[dict[str, object]], None],
) -> None:
    """The recordings as tasks of a Dask distributed cluster."""
    try:
        from distributed import Client, Event, wait
    except ImportError:
        raise InputError(
            "--scheduler needs Dask distributed: pip install 'mapassoc[dask]'"
        ) from None
    import uuid

    try:
        client = Client(scheduler, timeout=30)
    except (OSError, TimeoutError, ValueError) as exc:  # ValueError: a malformed address
        raise InputError(f"cannot reach the Dask scheduler {scheduler!r}: {exc}") from None
    event_name = f"mapassoc-stop-{uuid.uuid4().hex}"
    with client:
        event = Event(event_name, client=client)
        futures = {
            client.submit(
                _dask_task, recording, config, out.resolve(), options, event_name,
                key=f"mapassoc-{recording.name}-{uuid.uuid4().hex[:8]}", pure=False,
            ): recording
            for recording in recordings
        }  # fmt: skip
        pending = set(futures)
        while pending:
            try:
                done, pending = wait(list(pending), timeout=0.5, return_when="FIRST_COMPLETED")
            except TimeoutError:  # distributed.wait's timeout
                done = set()
            pending = set(pending)
            for future in done:
                finished(_row_of(future, futures[future], out, what="task"))
            if stop() and not event.is_set():
                event.set()  # running tasks stop at their next window, waiting ones at once
