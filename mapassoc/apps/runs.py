"""Running the estimator on files: what ``mapassoc run``, ``batch`` and ``demo`` share.

:func:`run_files` reads a configuration and a detections file and writes one run folder
(:mod:`mapassoc.apps.run_folders`): ``windows.jsonl`` line by line while the run goes
on, then ``tracks.csv``, ``summary.json`` and ``manifest.json``.  It checkpoints the
estimator's state every ``checkpoint_seconds``, when the forward pass is done, and
whenever it is asked to stop (``stop`` is polled between the units of every phase: a
window, a move of the refinement, a window of the confidence pass; a stop after the
forward pass keeps its checkpoint), and ``resume=True`` continues from the last
checkpoint, so that the final files are byte-identical (with ``timings=False``) to
those of a run that never stopped.  A resumed folder is checked first: the checkpoint
records the SHA-256 of ``windows.jsonl`` so far, and the manifest of a complete run the
size and SHA-256 of every output.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import hashlib
import json
import os
import sys
import threading
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

from mapassoc.apps.progress import Progress
from mapassoc.apps.run_folders import (
    RunFolder,
    file_identity,
    new_manifest,
    now_text,
    os_reason,
    write_json,
)
from mapassoc.data.formats import file_name, format_names
from mapassoc.data.recording import (
    RECORDING_TRACKS_NAME,
    RecordingBase,
    read_recording,
    write_recording_tracks,
)
from mapassoc.errors import DataFileError, InputError, MapassocError, OutputError, StopRequested
from mapassoc.trackers.registry import tracker_names
from mapassoc.validation import check_callback, check_integer, check_path

if TYPE_CHECKING:  # the models are imported when a run starts, not with this module
    from mapassoc.data.config import Config
    from mapassoc.data.scans import Scan
    from mapassoc.estimator.pipeline import EstimateResult, RunState, WindowReport

__all__ = [
    "RunOptions",
    "RunOutcome",
    "RunInterrupted",
    "StoppedBeforeRun",
    "InputWaitInterrupted",
    "read_input",
    "estimate_with_progress",
    "json_dump",
    "run_files",
    "RunInputs",
    "RunModel",
    "RunSession",
]

WINDOWS_NAME = "windows.jsonl"
SUMMARY_NAME = "summary.json"
ASSOCIATIONS_NAME = "associations.csv"
"""The refined tracks' association probabilities (``detection_id,track_id,probability``)."""


FORWARD_PHASE = "the forward pass"
"""The phase of a run's windows (what a :class:`RunInterrupted` names by default)."""


class RunInterrupted(StopRequested):
    """A run stopped on request (SIGINT, SIGTERM) between two units of work, checkpointed.

    Attributes
    ----------
    partial : Path
        The run folder holding the checkpoint (``OUT.partial``), or a batch's folder.
    scans_committed, scans_total : int
        Scans (for a batch: recordings) done and in all.
    phase : str
        What was stopped: :data:`FORWARD_PHASE`, or a later phase (the refinement, the
        confidence pass) that ``--resume`` runs again from the done forward pass.
    """

    def __init__(
        self,
        partial: Path,
        scans_committed: int,
        scans_total: int,
        *,
        unit: str = "scans",
        phase: str = FORWARD_PHASE,
    ) -> None:
        self.partial = partial
        self.scans_committed = scans_committed
        self.scans_total = scans_total
        what = "run" if unit == "scans" else "batch"
        during = "" if phase == FORWARD_PHASE or unit != "scans" else f", during {phase}"
        super().__init__(
            phase,
            f"interrupted after {scans_committed} of {scans_total} {unit}{during}; the {what} "
            f"so far is in {partial} (continue it with --resume)",
        )


class StoppedBeforeRun(RunInterrupted):
    """A run stopped on request before its first window: nothing was written."""

    def __init__(self, message: str, phase: str = FORWARD_PHASE) -> None:
        self.partial = None  # type: ignore[assignment]
        self.scans_committed = self.scans_total = 0
        StopRequested.__init__(self, phase, f"{message}; nothing was written")


class InputWaitInterrupted(StoppedBeforeRun):
    """A run stopped on request while an input was still being read.

    Attributes
    ----------
    path : str
        The input being read (for instance a named pipe no writer had opened).
    """

    def __init__(self, path: str) -> None:
        self.path = path
        super().__init__(f"stopped while waiting for input {path}")


@dataclass(frozen=True)
class RunOptions:
    """How :func:`run_files` runs and writes (the options of ``mapassoc run``).

    Parameters
    ----------
    timings : bool
        False leaves run times out of ``windows.jsonl`` and ``summary.json``.
    progress : bool
        Progress on stderr (a bar on a terminal, else a line every ``log_seconds``).
    overwrite : bool
        Replace what ``OUT`` holds (only once the new run is complete).
    resume : bool
        Continue the unfinished run in ``OUT.partial``; skip when ``OUT`` is complete
        over the same inputs; start afresh when there is nothing to continue.  Excludes
        ``overwrite``.
    checkpoint_seconds : float
        Least interval between two checkpoints (>= 0; 0 checkpoints after every window).
    log_seconds : float
        Seconds between two progress lines when stderr is not a terminal.
    segments : int
        1: the sequential run.  More: the recording in that many overlapping segments,
        solved on ``jobs`` local processes and stitched
        (:mod:`mapassoc.estimator.segments`); checkpoints then hold finished segments,
        and a stop abandons the segments in progress.
    jobs : int, optional
        Worker processes for ``segments > 1`` (default: the usable cores).
    tracks_format : {"csv", "parquet"}
        ``tracks.csv`` or ``tracks.parquet`` (extra ``parquet``).
    detections_format : {"csv", "parquet"}, optional
        The detections file's format (``--format``); None (default): by its suffix, and
        by its bytes when it has none (``/dev/stdin``, a process substitution).

    Raises
    ------
    InputError
        ``overwrite`` with ``resume``, a negative ``checkpoint_seconds``, an unknown
        ``tracks_format`` or ``detections_format``, ``segments < 1``.
    """

    timings: bool = True
    progress: bool = True
    overwrite: bool = False
    resume: bool = False
    checkpoint_seconds: float = 10.0
    log_seconds: float = 30.0
    segments: int = 1
    jobs: int | None = None
    tracks_format: str = "csv"
    detections_format: str | None = None

    def __post_init__(self) -> None:
        if self.overwrite and self.resume:
            raise InputError("--overwrite and --resume exclude each other; choose one")
        if not (self.checkpoint_seconds >= 0):
            raise InputError(f"checkpoint_seconds must be >= 0, got {self.checkpoint_seconds!r}")
        if self.tracks_format not in format_names():
            raise InputError(
                f"tracks_format must be one of {sorted(format_names())}, got {self.tracks_format!r}"
            )
        if self.detections_format is not None and self.detections_format not in format_names():
            raise InputError(
                f"detections_format must be one of {sorted(format_names())} or None, got "
                f"{self.detections_format!r}"
            )
        # Stored as an int: the run's settings record is written to JSON.
        object.__setattr__(self, "segments", check_integer("segments", self.segments, minimum=1))


@dataclass(frozen=True)
class RunOutcome:
    """What :func:`run_files` did.

    Attributes
    ----------
    out : Path
        The run folder.
    status : str
        ``"complete"`` (ran to the end now) or ``"skipped"`` (``resume`` found the run
        complete already).
    summary : dict
        The run's ``summary.json``.
    resumed_at : int
        Scans committed before this session (0 for a run from the start).
    seconds : float
        Wall time of this session.
    """

    out: Path
    status: str
    summary: dict[str, Any]
    resumed_at: int
    seconds: float


def read_input(
    path: str | os.PathLike[str],
    *,
    stop: Callable[[], bool] | None = None,
    poll_seconds: float = 0.1,
) -> tuple[bytes, dict[str, object]]:
    """Read an input file once: its bytes and ``{"path", "bytes", "sha256"}``.

    Every input of a run is read through this once, then parsed from the bytes and
    hashed for the manifest, so a stream (a named pipe, a process substitution) works
    like a file.  The read runs on a helper thread while this one polls ``stop`` every
    ``poll_seconds``: a stop request (SIGINT, SIGTERM) is honoured even while the read
    waits, for instance on a named pipe no writer has opened yet.

    Raises
    ------
    DataFileError
        The file cannot be read (names it and the system's reason).
    InputWaitInterrupted
        ``stop`` returned True before the read finished; the helper thread is left
        blocked in its read (a daemon thread: it does not keep the process alive).
    """
    name = os.fspath(path)
    outcome: list[bytes | OSError] = []

    def read() -> None:
        try:
            with open(name, "rb") as handle:
                outcome.append(handle.read())
        except OSError as exc:
            outcome.append(exc)

    reader = threading.Thread(target=read, name=f"read {name}", daemon=True)
    reader.start()
    while reader.is_alive():
        reader.join(poll_seconds)
        if reader.is_alive() and stop is not None and stop():
            raise InputWaitInterrupted(name)
    result = outcome[0]
    if isinstance(result, OSError):
        raise DataFileError(name, f"cannot read the file: {os_reason(result)}")
    return result, file_identity(name, result)


def estimate_with_progress(
    config: Any,
    scans: list[Any],
    *,
    stop: Callable[[], bool] | None,
    progress: bool,
    every_sensor: bool = False,
) -> Any:
    """The configuration's "auto" sensor parameters from the recording, a line per pass.

    The last pass is left unfinished (``last_run``, not ``result``): a run refines it
    itself, after checkpointing it.

    ``every_sensor``: estimate every sensor's rate and ``Pd``, not only the "auto" ones
    (an "auto" ``Pd`` starts at its ``detection_probability_start``, a configured one at
    its number, which is also what it keeps when the recording cannot estimate it).

    Raises
    ------
    StoppedBeforeRun
        ``stop`` asked to stop (nothing is written).
    """
    from mapassoc.estimator.parameters import estimate_parameters

    def report(record: Any) -> None:
        if not progress or sys.stderr is None:
            return
        moves = "; ".join(
            f"{name}: false_alarms_per_scan {used[0]:.4g} -> {record.updated[name][0]:.4g}, "
            f"detection_probability {used[1]:.3f} -> {record.updated[name][1]:.3f}"
            for name, used in record.used.items()
        )
        if record.noise_used is not None and record.noise_updated is not None:
            moves += ("; " if moves else "") + (
                f"noise {record.noise_used.vector().round(6).tolist()} -> "
                f"{record.noise_updated.vector().round(6).tolist()}"
            )
        if record.birth_used is not None and record.birth_updated is not None:
            moves += ("; " if moves else "") + "birth " + ", ".join(
                f"{key} {value:.4g} -> {record.birth_updated.values[key]:.4g}"
                for key, value in record.birth_used.values.items()
            )
        print(
            f"mapassoc: parameters pass {record.index + 1}: {moves} ({record.tracks} tracks, "
            f"{record.seconds:.1f} s)",
            file=sys.stderr,
            flush=True,
        )

    rates, pds = config.auto.false_alarms, config.auto.pd_starts()
    if every_sensor:
        rates = tuple(config.sensors)
        pds = {name: pds[name] if name in pds else sensor.detection_probability
               for name, sensor in config.sensors.items()}  # fmt: skip
    try:
        return estimate_parameters(
            config, scans, false_alarms=rates, detection_probability=pds, on_pass=report,
            stop=stop, finish=False,
        )  # fmt: skip
    except StopRequested as exc:
        raise StoppedBeforeRun(str(exc), exc.phase) from None


def _with_estimates(config: Any, parameters: dict[str, Any]) -> Any:
    """``config`` with the sensor values, noise levels and birth keys of a ``parameters``
    record (ParameterEstimate)."""
    from mapassoc.estimator.birth_estimation import BirthLevels, with_birth_levels
    from mapassoc.estimator.noise_levels import NoiseLevels, with_noise_levels
    from mapassoc.estimator.parameters import with_sensor_parameters

    values = {
        name: (float(entry["false_alarms_per_scan"]), float(entry["detection_probability"]))
        for name, entry in parameters["sensors"].items()
    }
    noise = parameters.get("noise")
    levels = None if noise is None else NoiseLevels(
        None if noise.get("noise_intensity") is None else float(noise["noise_intensity"]),
        {name: tuple(float(v) for v in stds) for name, stds in noise["noise_std"].items()},
    )  # fmt: skip
    birth = parameters.get("birth")
    found = None if birth is None else BirthLevels({k: float(v) for k, v in birth.items()})
    config = with_noise_levels(with_sensor_parameters(config, values), levels)
    return with_birth_levels(config, found)


def _integer_solvers() -> tuple[str, ...]:
    """The solvers ``estimator.search.solver`` may name (the estimator solves integer programs).

    Imported when a run starts, not with this module: the solver backends import
    scipy.optimize and cvxpy, which every command line start-up would otherwise pay.
    """
    from mapassoc.solvers import SOLVERS

    return tuple(spec.name for spec in SOLVERS if spec.supports_integer)


def _ignore_resource_warnings() -> None:
    """Leave ResourceWarnings out of a run's recorded warnings: they report objects the
    interpreter finalises while the run goes on (an unclosed pipe of the caller, say),
    not the run's input or output, and would make ``summary.json`` depend on when the
    garbage collector ran."""
    warnings.filterwarnings("ignore", category=ResourceWarning)


def json_dump(data: object, path: Path) -> None:
    """Write ``data`` as indented JSON, atomically; an OSError becomes an OutputError
    naming ``path``."""
    write_json(path, data)


def _settings_record(
    config: Any, timings: bool, segments: int, tracks_format: str
) -> dict[str, object]:
    """The settings a resumed run must share with its first session, as JSON holds them
    (``prune_log_ratio = inf`` as ``"inf"``: compared on resume in this form)."""
    from mapassoc.data.settings import settings_to_json

    return {
        "timings": timings,
        "segments": segments,
        "tracks_format": tracks_format,
        "estimator": settings_to_json(config.estimator),
        "birth": settings_to_json(config.birth),
    }


def _same_run(
    manifest: dict[str, Any], inputs: dict[str, Any], settings: dict[str, Any], folder: Path
) -> None:
    """Raise InputError unless ``manifest`` is of a run over the same inputs and settings."""
    for kind in ("config", "detections"):
        before = manifest["inputs"][kind]
        if before["sha256"] != inputs[kind]["sha256"]:
            raise InputError(
                f"cannot resume {folder}: the {kind} file {inputs[kind]['path']} differs from "
                f"the one the run started with ({before['path']}, sha256 "
                f"{before['sha256'][:12]}...); pass --overwrite to start again"
            )
    if manifest["settings"] != json.loads(json.dumps(settings)):
        changed = sorted(key for key in settings if manifest["settings"].get(key) != settings[key])
        raise InputError(
            f"cannot resume {folder}: settings {changed} differ from those the run started "
            "with (for example --no-timings or --segments); resume with the same options, "
            "or --overwrite"
        )


class _RunRecord:
    """The record of one session of a run in ``OUT.partial``: its manifest, warnings
    and checkpoints."""

    def __init__(
        self, folder: RunFolder, manifest: dict[str, Any], messages: list[str], total: int
    ) -> None:
        self.folder = folder
        self.manifest = manifest
        self.messages = messages
        self.total = total
        self.scans_committed = int(manifest["scans_committed"])
        self.windows_committed = int(manifest["windows_committed"])
        self.writing = folder.partial / WINDOWS_NAME  # the file an OSError is about

    def save(self, status: str, error: BaseException | None = None) -> None:
        self.manifest.update(
            status=status,
            scans_committed=self.scans_committed,
            windows_committed=self.windows_committed,
            error=None if error is None else str(error),
        )
        if status != "running":
            self.manifest["ended"] = now_text()
        self.folder.write_manifest(self.manifest)

    def checkpoint(self, content: dict[str, Any]) -> None:
        self.folder.write_checkpoint({**content, "warnings": list(self.messages)})
        self.save("running")

    def interrupted(self, phase: str = FORWARD_PHASE) -> RunInterrupted:
        return RunInterrupted(self.folder.partial, self.scans_committed, self.total, phase=phase)


def _check_run_files(
    config_path: object, detections_path: object, out_dir: object, stop: object
) -> None:
    """The argument checks of :func:`run_files`, before anything is read or created."""
    check_path(
        "run_files: config_path",
        config_path,
        hint="run_files reads a TOML file; an in-memory Config runs with "
        "mapassoc.WindowEstimator(config=config).run(scans)",
    )
    check_path(
        "run_files: detections_path",
        detections_path,
        hint="run_files reads a detections file; in-memory scans run with "
        "mapassoc.WindowEstimator(config=config).run(scans)",
    )
    check_path("run_files: out_dir", out_dir, hint="the run folder to write")
    check_callback("run_files: stop", stop)


def run_files(
    config_path: str | os.PathLike[str],
    detections_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    options: RunOptions | None = None,
    *,
    stop: Callable[[], bool] | None = None,
) -> RunOutcome:
    """Read a configuration and a detections file, estimate tracks, write a run folder.

    The steps are those of a :class:`RunSession`: open the folder and read the inputs,
    take a resumed run's checkpoint (or find it complete), read the scans, estimate the
    "auto" sensor parameters, then run and write.

    Parameters
    ----------
    config_path, detections_path : path
        The TOML configuration and the detections file (CSV or Parquet: by
        ``options.detections_format``, else its suffix, else its bytes).
    out_dir : path
        The run folder ``OUT`` (see :mod:`mapassoc.apps.run_folders`).
    options : RunOptions, optional
        How to run and write (default ``RunOptions()``).
    stop : callable, optional
        Polled between the units of every phase (a window of the forward pass or of the
        parameter estimation, a re-solve or linking round of the refinement, a window of
        the confidence pass); when it returns True the run checkpoints and raises
        :class:`RunInterrupted`.

    Raises
    ------
    InputError, DataFileError, ConfigError
        Bad inputs (nothing is created then); with ``resume``, a ``windows.jsonl`` that
        does not hold what the checkpoint recorded.
    OutputError
        ``OUT`` is unusable or a write failed (the manifest says ``failed`` where it can
        be written; the last checkpoint stays, so ``resume`` continues after the fix);
        with ``resume``, an ``OUT`` that says complete but is not whole.
    RunInterrupted
        ``stop`` returned True (its ``phase`` says in which phase).
    """
    _check_run_files(config_path, detections_path, out_dir, stop)
    if options is None:
        options = RunOptions()
    elif not isinstance(options, RunOptions):
        raise InputError(f"options must be a RunOptions, got {type(options).__name__}")
    session = RunSession(options, stop=stop)
    session.open(config_path, detections_path, out_dir)
    done = session.resume()
    if done is not None:
        return done
    session.read_scans()
    session.estimate_parameters()
    return session.execute()


@dataclass(frozen=True)
class RunInputs:
    """What a run session read before anything is written (:meth:`RunSession.open`).

    Attributes
    ----------
    detections_path : path
        The detections file (its name and format for the parser).
    config : Config
        The configuration as loaded ("auto" sensor parameters still open).
    messages : tuple of str
        The warnings of loading it.
    identities : dict
        ``{"config": ..., "detections": ...}``: each input's path, size and SHA-256.
    settings : dict
        The settings a resumed run must share (:func:`_settings_record`).
    """

    detections_path: str | os.PathLike[str]
    config: Config
    messages: tuple[str, ...]
    identities: dict[str, Any]
    settings: dict[str, object]


@dataclass(frozen=True)
class RunModel:
    """The model a run session runs (:meth:`RunSession.estimate_parameters`).

    Attributes
    ----------
    config : Config
        The configuration with no "auto" value left.
    parameters : dict or None
        The ``parameters`` record of the estimates (None: nothing was "auto").
    precomputed : (RunState, tuple of WindowReport) or None
        The estimation's last pass when it was the whole forward pass with the final
        values (written, not solved again).
    messages : tuple of str
        The warnings so far: loading the configuration, then estimating.
    """

    config: Config
    parameters: dict[str, Any] | None
    precomputed: tuple[RunState, tuple[WindowReport, ...]] | None
    messages: tuple[str, ...]


class RunSession:
    """One session of :func:`run_files`, in its steps, each a method called in order.

    :meth:`open` checks the folder and reads the inputs once; :meth:`resume` finds what
    ``--resume`` continues; :meth:`read_scans` parses the detections;
    :meth:`estimate_parameters` settles the "auto" sensor parameters; :meth:`execute`
    starts the estimator, opens the run's record in ``OUT.partial`` and runs
    (:meth:`run_windows`, or :meth:`run_segments`), then :meth:`write_outputs`.

    Parameters
    ----------
    options : RunOptions
    stop : callable, optional
        Polled between the units of every phase (see :func:`run_files`).
    """

    def __init__(self, options: RunOptions, *, stop: Callable[[], bool] | None = None) -> None:
        self.options = options
        self.stop = stop
        self.started = time.perf_counter()
        self.point = _ResumePoint()
        self.resumed_at = 0
        self._detections: bytes | None = None
        self.recording_base: RecordingBase | None = None
        self.scans: list[Scan] = []

    def seconds(self) -> float:
        """Wall time since the session began."""
        return time.perf_counter() - self.started

    def open(
        self,
        config_path: str | os.PathLike[str],
        detections_path: str | os.PathLike[str],
        out_dir: str | os.PathLike[str],
    ) -> RunInputs:
        """Check the run folder, then read each input once and load the configuration.

        Each input is read once (a named pipe cannot be read twice), hashed for the
        manifest, then parsed from its bytes; a stop request is honoured while reading.

        Raises
        ------
        OutputError
            ``out_dir`` is unusable, or holds a run the options do not allow to replace.
        DataFileError, ConfigError, InputWaitInterrupted
            An input cannot be read or loaded, or ``stop`` asked to stop while reading.
        """
        options = self.options
        self.folder = folder = RunFolder(out_dir)
        folder.check_writable_place()
        if options.overwrite or options.resume:
            folder.check_replaceable((config_path, detections_path))
        else:
            folder.refuse_existing()
        config_bytes, config_identity = read_input(config_path, stop=self.stop)
        # The models (numpy, scipy.linalg) are imported only once there is something to parse.
        from mapassoc.data.config import load_config

        with warnings.catch_warnings(record=True) as config_warnings:
            warnings.simplefilter("always")
            _ignore_resource_warnings()
            config = load_config(
                config_path,
                solver_names=_integer_solvers(),
                tracker_names=tracker_names(),
                content=config_bytes,
            )
        self._detections, detections_identity = read_input(detections_path, stop=self.stop)
        self.inputs = RunInputs(
            detections_path=detections_path,
            config=config,
            messages=tuple(str(w.message) for w in config_warnings),
            identities={"config": config_identity, "detections": detections_identity},
            settings=_settings_record(
                config, options.timings, options.segments, options.tracks_format
            ),
        )
        return self.inputs

    def resume(self) -> RunOutcome | None:
        """With ``resume``, what the run continues from (kept as :attr:`point`); the
        outcome when the run is complete already (``"skipped"``, or ``"complete"`` when
        it was finished now by moving it into place), else None: run."""
        if not self.options.resume:
            return None
        self.point = _resume_point(self.folder, self.inputs.identities, self.inputs.settings)
        outcome = self.point.outcome
        if outcome is None or outcome.status == "skipped":
            return outcome
        return dataclasses.replace(outcome, seconds=self.seconds())

    def read_scans(self) -> list[Scan]:
        """Parse the detections read by :meth:`open` (then let their bytes go)."""
        from mapassoc.data.formats import read_detections_file

        assert self._detections is not None, "read_scans follows open, once"
        if self.inputs.config.recording is not None:  # a user's own file: times and frame
            self.scans, self.recording_base = read_recording(
                self.inputs.detections_path, self.inputs.config, content=self._detections,
                format_name=self.options.detections_format,
            )  # fmt: skip
            self._detections = None
            return self.scans
        self.scans = read_detections_file(
            self.inputs.detections_path, self.inputs.config.sensors, content=self._detections,
            format_name=self.options.detections_format,
        )  # fmt: skip
        self._detections = None  # parsed: the scans are what the run needs from here on
        return self.scans

    def estimate_parameters(self) -> RunModel:
        """The configuration's "auto" sensor parameters: estimated from the scans (a line
        per pass on stderr), or, for a resumed run, the estimates it started with.

        Raises
        ------
        StoppedBeforeRun
            ``stop`` asked to stop during the estimation (nothing is written).
        """
        config, options, manifest = self.inputs.config, self.options, self.point.manifest
        messages = list(self.inputs.messages)
        parameters: dict[str, Any] | None = None
        precomputed = None
        if config.auto.pending:
            if manifest is not None and manifest.get("parameters") is not None:
                parameters = manifest["parameters"]  # a resumed run keeps its estimates
            else:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")  # the passes' own, kept for summary.json
                    _ignore_resource_warnings()
                    estimate = estimate_with_progress(
                        config, self.scans, stop=self.stop, progress=options.progress
                    )
                parameters = estimate.to_json(timings=options.timings)
                precomputed = estimate.last_run if options.segments == 1 else None
                messages += [str(w.message) for w in caught]
                messages += estimate.warnings
            assert parameters is not None
            config = _with_estimates(config, parameters)
        self.model = RunModel(config, parameters, precomputed, tuple(messages))
        return self.model

    def execute(self) -> RunOutcome:
        """Start the estimator (every check of the whole run, before anything is
        written), open the run's record, run and write; print the run's warnings.

        Warnings are recorded from the estimator's start to the end of the run, for
        ``summary.json`` (and the checkpoints).
        """
        from mapassoc.estimator.pipeline import WindowEstimator

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _ignore_resource_warnings()
            self.estimator = WindowEstimator(config=self.model.config)
            # A resumed run steps on from its checkpoint's state instead of this fresh one.
            fresh_state = self.estimator.start(self.scans)
            self.folder.begin(fresh=self.point.checkpoint is None)
            try:
                record = self.open_record(caught)
                summary = self.run_and_write(fresh_state, caught)
            finally:
                self.folder.release()
        for message in record.messages:
            print(f"mapassoc: warning: {message}", file=sys.stderr)
        return RunOutcome(self.folder.path, "complete", summary, self.resumed_at, self.seconds())

    def open_record(self, caught: list[warnings.WarningMessage]) -> _RunRecord:
        """The run's manifest in ``OUT.partial``, marked running: a new one, or the
        resumed run's for one more session (with the warnings of its checkpoint).

        ``caught``: the warnings recorded so far (the estimator's start), emptied here.
        """
        checkpoint, model = self.point.checkpoint, self.model
        manifest: dict[str, Any]
        if checkpoint is None:
            manifest = new_manifest(
                inputs=self.inputs.identities, settings=self.inputs.settings,
                scans_total=len(self.scans),
            )  # fmt: skip
            if model.parameters is not None:
                manifest["parameters"] = model.parameters
            from mapassoc.data.checks import detections_outside_region

            messages = [*model.messages, *(str(w.message) for w in caught)]
            messages += detections_outside_region(self.scans, model.config.sensors)
        else:
            assert self.point.manifest is not None
            manifest = self.point.manifest
            sessions = int(manifest["sessions"]) + 1
            manifest.update(status="running", sessions=sessions, error=None)
            messages = list(checkpoint["warnings"])
        del caught[:]
        self.record = _RunRecord(self.folder, manifest, messages, len(self.scans))
        self.record.save("running")
        self.resumed_at = self.record.scans_committed
        return self.record

    def run_and_write(
        self, fresh_state: RunState, caught: list[warnings.WarningMessage]
    ) -> dict[str, Any]:
        """Run (windows or segments), then write the outputs; the run's summary.

        Every way out is recorded in the manifest: a stop as ``interrupted`` (raised as
        :class:`RunInterrupted`; a stop after the forward pass keeps its checkpoint), a
        failed write as ``failed`` (an :class:`OutputError`), any other error as ``failed``.
        """
        record = self.record
        self.ticker = Progress(
            sys.stderr, label="run", unit="scans", enabled=self.options.progress,
            log_seconds=self.options.log_seconds, initial=self.resumed_at,
        )  # fmt: skip
        try:
            if self.options.segments == 1:
                result = self.run_windows(fresh_state, caught)
            else:
                result = self.run_segments()
            return self.write_outputs(result, caught)
        except RunInterrupted:
            raise
        except StopRequested as exc:  # after the forward pass: its checkpoint stands
            _mark(record.save, "interrupted")
            raise record.interrupted(exc.phase) from None
        except KeyboardInterrupt:
            _mark(record.save, "interrupted")
            raise record.interrupted() from None
        except OSError as exc:
            error = OutputError(str(record.writing), f"cannot write: {os_reason(exc)}")
            _mark(record.save, "failed", error)
            raise error from None
        except MapassocError as exc:
            _mark(record.save, "failed", exc)
            raise
        except Exception as exc:  # a bug or a crashed worker: still say so in the manifest
            _mark(record.save, "failed", exc)
            raise
        finally:
            self.ticker.close()

    def run_windows(
        self, fresh_state: RunState, caught: list[warnings.WarningMessage]
    ) -> EstimateResult:
        """The sequential run, window by window, writing ``windows.jsonl`` as it goes,
        then the whole recording's refinement.

        The forward pass checkpoints every ``checkpoint_seconds`` and once more when it
        is done, so a stop during the refinement (which polls ``stop`` between its moves
        and raises StopRequested) resumes from the done forward pass.  The model's
        ``precomputed`` forward pass (the parameter estimation's last pass covered every
        scan with the final values) is written, not solved again.  A resumed run goes on
        from its checkpoint's state and the SHA-256 of ``windows.jsonl`` up to it
        (:func:`_checked_windows`), carried on as lines are added.

        Raises
        ------
        RunInterrupted
            ``stop`` returned True between two windows (checkpointed first).
        """
        record, checkpoint, estimator, scans = (
            self.record,
            self.point.checkpoint,
            self.estimator,
            self.scans,
        )
        timings, stop = self.options.timings, self.stop
        if checkpoint is None:
            state, windows_bytes, digest = fresh_state, 0, hashlib.sha256()
        else:
            state, windows_bytes = checkpoint["state"], int(checkpoint["windows_bytes"])
            digest = self.point.digest

        def save_checkpoint(stream: BinaryIO) -> None:
            stream.flush()
            os.fsync(stream.fileno())
            record.scans_committed, record.windows_committed = state.next_scan, state.tally.windows
            record.checkpoint(
                {
                    "state": state,
                    "windows_bytes": stream.tell(),
                    "windows_sha256": digest.hexdigest(),
                }
            )

        def write(stream: BinaryIO, report: WindowReport) -> None:
            line = _window_line(report, timings)
            stream.write(line)
            digest.update(line)

        with _open_windows(self.folder.partial / WINDOWS_NAME, windows_bytes) as stream:
            if self.model.precomputed is not None and checkpoint is None:
                state, reports = self.model.precomputed
                for report in reports:
                    write(stream, report)
                self.ticker(state.next_scan, state.total_scans)
            last_checkpoint = time.monotonic()
            while not state.done:
                if stop is not None and stop():
                    save_checkpoint(stream)
                    record.save("interrupted")
                    raise record.interrupted()
                write(stream, estimator.step(scans, state))
                stream.flush()
                record.messages.extend(str(w.message) for w in caught)
                del caught[:]
                self.ticker(state.next_scan, state.total_scans)
                if time.monotonic() - last_checkpoint >= self.options.checkpoint_seconds:
                    save_checkpoint(stream)
                    last_checkpoint = time.monotonic()
            save_checkpoint(stream)
        return estimator.finish(scans, state, stop=stop)

    def run_segments(self) -> EstimateResult:
        """The run in overlapping segments on local processes, checkpointing finished
        ones; then stitched, and ``windows.jsonl`` written whole.

        Raises
        ------
        RunInterrupted
            ``stop`` returned True before every segment was done (the finished ones are
            checkpointed).
        """
        from mapassoc.estimator.segments import plan_segments, stitch_segments

        config, scans, record = self.model.config, self.scans, self.record
        plan = plan_segments(
            len(scans), segments=self.options.segments,
            overlap=4 * config.estimator.windows.window_length,
        )  # fmt: skip
        checkpoint = self.point.checkpoint
        done: dict[int, Any] = dict(checkpoint["segments"]) if checkpoint is not None else {}
        self._solve_segments([segment for segment in plan if segment.index not in done], done)
        if len(done) < len(plan):
            record.save("interrupted")
            raise record.interrupted()
        stitched = stitch_segments(scans, [done[s.index] for s in plan], config, stop=self._stopped)
        message = stitched.tally.kmax_warning(config.estimator.count.max_tracks)
        if message is not None:
            record.messages.append(message)
        record.windows_committed = stitched.tally.windows
        with _open_windows(self.folder.partial / WINDOWS_NAME, 0) as stream:
            for report in stitched.windows:
                stream.write(_window_line(report, self.options.timings))
        return stitched

    def _stopped(self) -> bool:
        return self.stop is not None and self.stop()

    def _solve_segments(self, todo: list[Any], done: dict[int, Any]) -> None:
        """Solve the segments ``todo`` (on ``jobs`` processes when more than one is
        useful), adding each result to ``done`` and checkpointing it as it comes; a stop
        leaves the rest undone."""
        from mapassoc.apps.workers import check_jobs, run_on_pool, worker_stop_requested
        from mapassoc.estimator.segments import solve_segment

        config, scans, record = self.model.config, self.scans, self.record
        workers = min(check_jobs(self.options.jobs), len(todo)) if todo else 1

        def keep(result: Any) -> None:
            done[result.segment.index] = result
            owned = sum(r.segment.own_stop - r.segment.own_first for r in done.values())
            record.scans_committed = owned
            record.checkpoint({"segments": dict(done)})
            self.ticker(owned, len(scans))

        if workers <= 1:
            for segment in todo:
                result = solve_segment(
                    config, scans[segment.first : segment.stop], segment, stop=self._stopped
                )
                if result is None:
                    break
                keep(result)
            return

        def on_done(index: int, future: concurrent.futures.Future[Any]) -> None:
            result = future.result()
            if result is not None:  # None: stopped at a window boundary
                keep(result)

        run_on_pool(
            workers,
            [
                (solve_segment, (config, scans[s.first : s.stop], s),
                 {"stop": worker_stop_requested})
                for s in todo
            ],
            on_done=on_done,
            stop=self._stopped,
        )  # fmt: skip

    def _recording_summary(self) -> dict[str, Any]:
        """``{"recording": ...}`` for a recording read with its own times and frame: the
        epoch and kind of its times, the origin of the plane, the tracks file in them."""
        base = self.recording_base
        if base is None:
            return {}
        return {"recording": {**base.to_json(), "tracks": RECORDING_TRACKS_NAME}}

    def write_outputs(
        self, result: EstimateResult, caught: list[warnings.WarningMessage]
    ) -> dict[str, Any]:
        """Write ``tracks``, ``associations.csv`` (when the run has a confidence pass) and
        ``summary.json`` into ``OUT.partial``, record their sizes and SHA-256 in the
        manifest, mark it complete and move the folder into place; the summary."""
        from mapassoc.data.formats import write_tracks_file
        from mapassoc.data.io import write_associations

        record, folder, manifest = self.record, self.folder, self.record.manifest
        messages, tracks_format = record.messages, self.options.tracks_format
        messages.extend(str(w.message) for w in caught)
        # One line per message: segments (and sessions) repeat start()'s warnings.
        messages[:] = dict.fromkeys(messages)
        parameters = self.model.parameters
        summary = {
            "mapassoc_version": manifest["mapassoc_version"],
            "config": manifest["inputs"]["config"]["path"],
            "detections": manifest["inputs"]["detections"]["path"],
            **result.summary(timings=self.options.timings),
            **({"parameters": parameters} if parameters is not None else {}),
            **self._recording_summary(),
            "warnings": messages,
        }
        record.writing = folder.partial / file_name("tracks", tracks_format)
        write_tracks_file(record.writing, result.tracks)
        if self.recording_base is not None:
            record.writing = folder.partial / RECORDING_TRACKS_NAME
            write_recording_tracks(record.writing, result.tracks, self.recording_base)
        if result.confidence is not None:
            record.writing = folder.partial / ASSOCIATIONS_NAME
            kept = {
                tid: rows
                for tid, rows in result.confidence.associations.items()
                if tid in result.track_rows
            }
            write_associations(record.writing, kept)
        record.writing = folder.partial / SUMMARY_NAME
        json_dump(summary, record.writing)
        manifest["outputs"] = _output_records(folder.partial, summary, tracks_format)
        record.save("complete")
        folder.complete()
        return summary


@dataclass(frozen=True)
class _ResumePoint:
    """Where ``--resume`` picks a run up (all None: from the start)."""

    checkpoint: dict[str, Any] | None = None
    manifest: dict[str, Any] | None = None
    digest: Any = None
    """SHA-256 (a hashlib object) of ``windows.jsonl`` up to the checkpoint."""
    outcome: RunOutcome | None = None
    """The run is complete already: nothing to do."""


def _resume_point(
    folder: RunFolder, inputs: dict[str, Any], settings: dict[str, Any]
) -> _ResumePoint:
    """What ``--resume`` continues, after checking that the folder is what it says.

    A folder is taken as complete only when it is whole (:func:`_missing_parts`); an
    ``OUT.partial`` that says complete but is not is continued from its checkpoint (or
    started again without one), and an ``OUT`` that says complete but is not is refused.

    Raises
    ------
    InputError
        Other inputs or settings, or a ``windows.jsonl`` that disagrees with the
        checkpoint (:func:`_checked_windows`).
    OutputError
        ``OUT`` says complete but is not whole, or is not a run folder.
    """
    partial = folder.partial_manifest()
    final = folder.final_manifest()
    if partial is not None:
        _same_run(partial, inputs, settings, folder.partial)
        says_complete = partial["status"] == "complete"
        problems = _missing_parts(folder.partial, partial) if says_complete else []
        if says_complete and not problems:  # stopped between its last two renames
            folder.complete()
            folder.release()
            summary = _read_summary(folder.path)
            return _ResumePoint(outcome=RunOutcome(
                folder.path, "complete", summary, int(partial["scans_total"]), 0.0
            ))  # fmt: skip
        checkpoint: Any = folder.read_checkpoint()
        if problems:
            what = "continuing from its checkpoint" if checkpoint else "starting the run again"
            print(
                f"mapassoc: warning: {folder.partial} says the run is complete but "
                f"{'; '.join(problems)}; {what}",
                file=sys.stderr,
            )
        if checkpoint is None:
            return _ResumePoint()
        digest = _checked_windows(folder.partial, checkpoint)
        return _ResumePoint(checkpoint=checkpoint, manifest=partial, digest=digest)
    if final is not None and final["status"] == "complete":
        _same_run(final, inputs, settings, folder.path)
        problems = _missing_parts(folder.path, final)
        if problems:
            raise OutputError(
                str(folder.path),
                f"says the run is complete but {'; '.join(problems)}; pass --overwrite to run "
                "it again",
            )
        summary = _read_summary(folder.path)
        return _ResumePoint(outcome=RunOutcome(
            folder.path, "skipped", summary, int(final["scans_total"]), 0.0
        ))  # fmt: skip
    if folder.path.exists() and final is None and any(folder.path.iterdir()):
        raise OutputError(
            str(folder.path), "is not empty and holds no mapassoc run; choose another --out"
        )
    return _ResumePoint()


def _read_summary(folder: Path) -> dict[str, Any]:
    """``summary.json`` of a run folder (None-free: the caller checked it is whole)."""
    summary: dict[str, Any] = json.loads((folder / SUMMARY_NAME).read_text(encoding="utf-8"))
    return summary


def _sha256_file(path: Path) -> tuple[int, str]:
    """Size and SHA-256 of a file, read in blocks."""
    digest = hashlib.sha256()
    size = 0
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
            size += len(block)
    return size, digest.hexdigest()


def _output_names(summary: dict[str, Any], tracks_format: str) -> list[str]:
    """The files a complete run folder holds besides its manifest."""
    names = [file_name("tracks", tracks_format), WINDOWS_NAME, SUMMARY_NAME]
    if "confidence" in summary:
        names.append(ASSOCIATIONS_NAME)
    if "recording" in summary:
        names.append(str(summary["recording"]["tracks"]))
    return names


def _output_records(
    folder: Path, summary: dict[str, Any], tracks_format: str
) -> dict[str, dict[str, object]]:
    """The manifest's ``outputs``: size and SHA-256 of every file the run wrote."""
    records: dict[str, dict[str, object]] = {}
    for name in _output_names(summary, tracks_format):
        try:
            size, sha256 = _sha256_file(folder / name)
        except OSError as exc:
            raise OutputError(str(folder / name), f"cannot read: {os_reason(exc)}") from None
        records[name] = {"bytes": size, "sha256": sha256}
    return records


def _missing_parts(folder: Path, manifest: dict[str, Any]) -> list[str]:
    """What keeps a run folder whose manifest says complete from being whole (empty: whole).

    Every output must be there with the size and SHA-256 the manifest's ``outputs``
    recorded (a manifest written before they were recorded: every expected file there),
    and ``windows.jsonl`` must hold one whole line per window of ``summary.json``.
    """
    try:
        summary = json.loads((folder / SUMMARY_NAME).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        summary = None
    if not isinstance(summary, dict) or not isinstance(summary.get("windows"), int):
        return [f"{SUMMARY_NAME} is missing or unreadable"]
    tracks_format = str(manifest.get("settings", {}).get("tracks_format", "csv"))
    problems = []
    recorded = manifest.get("outputs") or {}
    for name in _output_names(summary, tracks_format):
        path = folder / name
        if not path.is_file():
            problems.append(f"{name} is missing")
        elif name in recorded and _sha256_file(path) != (
            recorded[name]["bytes"],
            recorded[name]["sha256"],
        ):
            problems.append(f"{name} is not the file the run wrote (its size or SHA-256 differs)")
    windows = folder / WINDOWS_NAME
    if windows.is_file():
        data = windows.read_bytes()
        lines = data.count(b"\n")
        if lines != summary["windows"] or b"\0" in data or not data.endswith(b"\n") and data:
            problems.append(
                f"{WINDOWS_NAME} holds {lines} whole lines where {SUMMARY_NAME} says "
                f"{summary['windows']} windows"
            )
    return problems


def _checked_windows(partial: Path, checkpoint: dict[str, Any]) -> Any:
    """The SHA-256 (hashlib object) of ``windows.jsonl`` up to the checkpoint's length,
    after checking that the file holds what the run had written then (None for a
    segmented run's checkpoint, which holds no windows).

    Raises
    ------
    InputError
        The file is shorter than the checkpoint recorded, or differs from what was
        written (its SHA-256; a checkpoint without one: its line count or a NUL byte).
    """
    if "windows_bytes" not in checkpoint:
        return None
    keep = int(checkpoint["windows_bytes"])
    path = partial / WINDOWS_NAME
    try:
        with open(path, "rb") as handle:
            prefix = handle.read(keep)
    except FileNotFoundError:
        prefix = b""
    except OSError as exc:
        raise OutputError(str(path), f"cannot read: {os_reason(exc)}") from None
    digest = hashlib.sha256(prefix)
    recorded = checkpoint.get("windows_sha256")
    windows = int(checkpoint["state"].tally.windows)
    problem = None
    if len(prefix) < keep:
        problem = f"holds {len(prefix)} bytes where the checkpoint recorded {keep}"
    elif recorded is not None and digest.hexdigest() != recorded:
        problem = "is not what the run had written at its checkpoint (its SHA-256 differs)"
    elif recorded is None and (prefix.count(b"\n") != windows or b"\0" in prefix):
        problem = f"does not hold the {windows} windows the checkpoint recorded"
    if problem is not None:
        raise InputError(
            f"cannot resume {partial}: {WINDOWS_NAME} {problem}, so the windows computed "
            "before the checkpoint are lost; pass --overwrite to start the run again"
        )
    return digest


def _window_line(report: Any, timings: bool) -> bytes:
    """One ``windows.jsonl`` line of a WindowReport, UTF-8."""
    return (json.dumps(report.to_json(timings=timings), allow_nan=False) + "\n").encode("utf-8")


def _open_windows(path: Path, keep_bytes: int) -> BinaryIO:
    """``windows.jsonl`` for appending, cut back to ``keep_bytes`` (the checkpoint's)."""
    try:
        if keep_bytes == 0:
            return open(path, "wb")
        stream = open(path, "r+b")
        stream.truncate(keep_bytes)
        stream.seek(keep_bytes)
        return stream
    except OSError as exc:
        raise OutputError(str(path), f"cannot write: {os_reason(exc)}") from None


def _mark(
    save: Callable[[str, BaseException | None], None],
    status: str,
    error: BaseException | None = None,
) -> None:
    """Record a run's end in its manifest; a failure to do so joins the error's notes."""
    try:
        save(status, error)
    except MapassocError as exc:
        if error is not None:
            error.add_note(f"the manifest could not be marked {status}: {exc}")
