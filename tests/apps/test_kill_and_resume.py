"""Stop ``mapassoc run`` at any moment and in every phase, resume until done.

SIGKILL, SIGINT and SIGTERM at random moments, in the whole recording's refinement and
its confidence pass, and right after the command starts.  Nothing may be lost or
duplicated: the final files equal, byte for byte, those of a run that was never
interrupted (timings off).  And a run folder that does not hold what its checkpoint or
its manifest says is never taken for one that does.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from support import polling_unit

from mapassoc.apps.cli import main
from mapassoc.apps.run_folders import CHECKPOINT_NAME, MANIFEST_NAME, read_manifest
from mapassoc.apps.runs import RunInterrupted, RunOptions, run_files
from mapassoc.apps.stopping import StopFlag, stop_on_signals
from mapassoc.errors import InputError, OutputError
from mapassoc.estimator.refinement import CONFIDENCE_PHASE, REFINEMENT_PHASE

RESULT_FILES = ("tracks.csv", "associations.csv", "windows.jsonl", "summary.json")


def _command(scenario: Path, out: Path) -> list[str]:
    return [
        sys.executable, "-m", "mapassoc", "run",
        str(scenario / "config.toml"), str(scenario / "detections.csv"),
        "--out", str(out), "--no-timings", "--no-progress", "--resume",
        "--checkpoint-seconds", "0",
    ]  # fmt: skip


def _no_time_limit(config: Path) -> None:
    """A time limit no window reaches: the windows the wall clock cuts short (status
    time_limit) differ from run to run under load, and these tests compare bytes."""
    text = config.read_text()
    assert "time_limit = 2.0" in text
    config.write_text(text.replace("time_limit = 2.0", "time_limit = 600.0"))


def _windows_written(partial: Path) -> int:
    """Lines of the run's windows.jsonl so far (0 before the run has started)."""
    try:
        return (partial / "windows.jsonl").read_bytes().count(b"\n")
    except FileNotFoundError:
        return 0


@pytest.mark.slow
def test_killed_at_random_points_then_resumed_is_byte_identical(tmp_path: Path) -> None:
    scenario = tmp_path / "scen"
    # 'parallel' runs for a few seconds: long enough to be killed mid-run several times.
    assert main(["simulate", "parallel", "--out", str(scenario), "--seed", "1"]) == 0
    _no_time_limit(scenario / "config.toml")
    reference = tmp_path / "reference"
    assert main(["run", str(scenario / "config.toml"), str(scenario / "detections.csv"),
                 "--out", str(reference), "--no-timings", "--no-progress"]) == 0
    out = tmp_path / "out"
    rng = np.random.default_rng(7)
    kills = {"SIGKILL": 0, "SIGINT": 0}
    committed: list[int] = []
    partial = out.with_name("out.partial")
    for attempt in range(60):
        before = _windows_written(partial)
        process = subprocess.Popen(
            _command(scenario, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        # The random moment counts from this attempt's first committed window, not from
        # its start: however slow the machine (imports under load take seconds), every
        # attempt gets on, so the run finishes within one attempt per window.
        while process.poll() is None and _windows_written(partial) <= before:
            time.sleep(0.02)
        time.sleep(float(rng.uniform(0.0, 1.6)))
        sig = signal.SIGKILL if attempt % 2 == 0 else signal.SIGINT
        if process.poll() is None:
            process.send_signal(sig)
            kills[sig.name] += 1
        _, err = process.communicate(timeout=120)
        if process.returncode == 0:
            break
        if sig is signal.SIGINT:
            assert process.returncode == 130, err
            assert "interrupted after" in err and "--resume" in err
        else:
            assert process.returncode == -signal.SIGKILL, err
        manifest = read_manifest(out.with_name("out.partial"))
        if manifest is not None:
            assert manifest["status"] in ("running", "interrupted")
            committed.append(int(manifest["scans_committed"]))
    else:
        pytest.fail(f"the run never finished in 60 attempts ({kills})")
    assert kills["SIGKILL"] >= 1 and kills["SIGINT"] >= 1, kills
    assert committed == sorted(committed), "a resumed run went back"
    for name in ("tracks.csv", "windows.jsonl", "summary.json"):
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name
    lines = (out / "windows.jsonl").read_text().splitlines()
    assert [json.loads(line)["window"] for line in lines] == list(range(len(lines)))
    manifest = read_manifest(out)
    assert manifest is not None and manifest["status"] == "complete"
    assert manifest["sessions"] >= 2


# -- a stop in the later phases, in this process ----------------------------------------


@pytest.fixture(scope="module")
def small(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 30-scan crossing scenario (26 windows) without a clock limit."""
    out = tmp_path_factory.mktemp("scen") / "small"
    assert main(["simulate", "crossing", "--out", str(out), "--seed", "2", "--scans", "30"]) == 0
    _no_time_limit(out / "config.toml")
    return out


@pytest.fixture(scope="module")
def small_reference(small: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An uninterrupted run of ``small``, timings off."""
    out = tmp_path_factory.mktemp("ref") / "run"
    _run(small, out)
    return out


def _run(
    scenario: Path,
    out: Path,
    *,
    stop: Callable[[], bool] | None = None,
    resume: bool = False,
    overwrite: bool = False,
    config: str = "config.toml",
) -> object:
    options = RunOptions(
        timings=False, progress=False, resume=resume, overwrite=overwrite, checkpoint_seconds=0.0
    )
    return run_files(scenario / config, scenario / "detections.csv", out, options, stop=stop)


def _same_results(a: Path, b: Path) -> None:
    for name in RESULT_FILES:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


_UNITS = ("link_fragments", "refine", "confidence", "run_windows", "_forward_run")


def _unit() -> str:
    """The phase method that polled ``stop`` (the innermost of :data:`_UNITS` on the stack)."""
    return polling_unit(_UNITS)


class _SignalAt:
    """The run's stop flag, which sends this process ``sig`` at the n-th poll of ``unit``.

    The signal goes through the command line's handlers (:func:`stop_on_signals`), so
    the stop is exactly a user's, at a moment chosen by the unit of work, not a timer.
    """

    def __init__(self, flag: StopFlag, sig: signal.Signals, unit: str, n: int = 1) -> None:
        self.flag, self.sig, self.unit, self.n = flag, sig, unit, n
        self.polls: dict[str, int] = {}
        self.after = 0  # polls once the flag is set: the phase ends at that same poll

    def __call__(self) -> bool:
        if self.flag():
            self.after += 1
            return True
        unit = _unit()
        self.polls[unit] = self.polls.get(unit, 0) + 1
        if unit == self.unit and self.polls[unit] == self.n:
            os.kill(os.getpid(), self.sig)
        return self.flag()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sig", "unit", "n", "phase"),
    [
        (signal.SIGINT, "refine", 1, REFINEMENT_PHASE),
        (signal.SIGTERM, "refine", 7, REFINEMENT_PHASE),
        (signal.SIGINT, "link_fragments", 1, REFINEMENT_PHASE),
        (signal.SIGTERM, "confidence", 2, CONFIDENCE_PHASE),
    ],
)
def test_a_signal_in_a_later_phase_stops_at_once_and_resumes_byte_identical(
    small: Path, small_reference: Path, tmp_path: Path,
    sig: signal.Signals, unit: str, n: int, phase: str,
) -> None:  # fmt: skip
    out = tmp_path / "out"
    with stop_on_signals(StopFlag(), notice=False) as flag:
        stop = _SignalAt(flag, sig, unit, n)
        with pytest.raises(RunInterrupted) as stopped:
            _run(small, out, stop=stop)
    assert flag.signal_name == sig.name
    assert stop.polls[unit] == n and stop.after == 0  # no unit of work after the signal
    message = str(stopped.value)
    assert f"interrupted after 30 of 30 scans, during {phase}" in message
    assert "--resume" in message and stopped.value.phase == phase
    partial = out.with_name("out.partial")
    manifest = read_manifest(partial)
    assert manifest is not None and manifest["status"] == "interrupted"
    assert manifest["scans_committed"] == 30 and (partial / CHECKPOINT_NAME).exists()
    assert len((partial / "windows.jsonl").read_bytes().splitlines()) == 26
    outcome = _run(small, out, resume=True)
    assert outcome.resumed_at == 30  # type: ignore[attr-defined]
    _same_results(out, small_reference)
    manifest = read_manifest(out)
    assert manifest is not None and manifest["status"] == "complete"
    assert manifest["sessions"] == 2


def _auto_config(scenario: Path) -> str:
    """``auto.toml``: the scenario's configuration with the sensor parameters "auto"."""
    text = (scenario / "config.toml").read_text()
    lines = [
        'false_alarms_per_scan = "auto"' if line.startswith("false_alarms_per_scan =")
        else 'detection_probability = "auto"' if line.startswith("detection_probability =")
        else line
        for line in text.splitlines()
    ]  # fmt: skip
    (scenario / "auto.toml").write_text("\n".join(lines) + "\n")
    return "auto.toml"


@pytest.mark.slow
def test_a_stop_in_the_refinement_after_the_parameter_estimation_keeps_its_passes(
    small: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The estimation's last pass is the run's forward pass: written and checkpointed
    before the refinement, so a stop there neither loses nor repeats the passes."""
    from mapassoc.estimator import parameters

    config = _auto_config(small)
    whole = tmp_path / "whole"
    _run(small, whole, config=config)
    calls: list[int] = []
    estimate = parameters.estimate_parameters

    def counted(*args: object, **kwargs: object) -> object:
        calls.append(1)
        return estimate(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(parameters, "estimate_parameters", counted)
    out = tmp_path / "out"
    with stop_on_signals(StopFlag(), notice=False) as flag:
        stop = _SignalAt(flag, signal.SIGINT, "refine")
        with pytest.raises(RunInterrupted, match=REFINEMENT_PHASE):
            _run(small, out, stop=stop, config=config)
    assert stop.polls["_forward_run"] >= 26 and "run_windows" not in stop.polls
    assert calls == [1]
    manifest = read_manifest(out.with_name("out.partial"))
    assert manifest is not None and manifest["parameters"] is not None
    _run(small, out, resume=True, config=config)
    assert calls == [1]  # the resumed session kept the estimates and the forward pass
    _same_results(out, whole)


# -- signals to the command, from outside -----------------------------------------------


def _poll_until(condition: Callable[[], bool], process: subprocess.Popen[str]) -> None:
    while process.poll() is None and not condition():
        time.sleep(0.005)


def _forward_pass_done(partial: Path, session: int) -> bool:
    """Whether session ``session`` of the run in ``partial`` is past its forward pass."""
    try:
        manifest = read_manifest(partial)
    except Exception:  # written atomically, but read while the folder is being created
        return False
    return (
        manifest is not None
        and (manifest["sessions"], manifest["status"]) == (session, "running")
        and manifest["scans_committed"] == manifest["scans_total"]
    )


@pytest.mark.slow
def test_signals_during_the_refinement_of_the_command_then_resume(
    small: Path, small_reference: Path, tmp_path: Path
) -> None:
    """SIGINT, then (in the resumed session) SIGTERM, each as soon as the forward pass
    is done: one line, status 130; a third session finishes byte-identical."""
    out = tmp_path / "out"
    partial = out.with_name("out.partial")
    for session, sig in enumerate((signal.SIGINT, signal.SIGTERM), start=1):
        process = subprocess.Popen(
            _command(small, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        _poll_until(lambda: _forward_pass_done(partial, session), process)  # noqa: B023
        assert process.poll() is None, "the run ended before the refinement could be stopped"
        process.send_signal(sig)
        _, err = process.communicate(timeout=120)
        assert process.returncode == 130, err
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert "interrupted after 30 of 30 scans, during the" in err and "--resume" in err
    done = subprocess.run(_command(small, out), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    _same_results(out, small_reference)
    manifest = read_manifest(out)
    assert manifest is not None and manifest["sessions"] == 3


def _handles_sigterm(pid: int) -> bool:
    """Whether the process has a handler for SIGTERM (what :mod:`mapassoc.apps.launch`
    installs before it imports anything heavy; Python itself installs none)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    caught = next(line for line in status.splitlines() if line.startswith("SigCgt:"))
    return bool(int(caught.split()[1], 16) >> (signal.SIGTERM - 1) & 1)


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc")
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_right_after_start_is_one_line(
    small: Path, tmp_path: Path, sig: signal.Signals
) -> None:
    """The signal as soon as mapassoc's own code runs, while numpy and the run machinery
    are still being imported (the interpreter's own start is beyond any program's reach)."""
    out = tmp_path / "out"
    process = subprocess.Popen(
        _command(small, out), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    _poll_until(lambda: _handles_sigterm(process.pid), process)
    process.send_signal(sig)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    if "before the command started" in err:
        assert f"mapassoc: {sig.name}: stopped" in err
        assert not out.exists() and not out.with_name("out.partial").exists()


# -- folders that do not hold what they say -------------------------------------------


def _interrupted(small: Path, out: Path, windows: int) -> Path:
    """``out.partial`` of a run stopped after ``windows`` windows (a checkpoint after each)."""
    polls = iter(range(10**6))
    with pytest.raises(RunInterrupted):
        _run(small, out, stop=lambda: next(polls) >= windows)
    return out.with_name(out.name + ".partial")


@pytest.mark.slow
def test_resume_refuses_a_windows_file_shorter_or_other_than_its_checkpoint(
    small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    partial = _interrupted(small, out, 12)
    windows = partial / "windows.jsonl"
    written = windows.read_bytes()
    assert written.count(b"\n") == 12
    windows.write_bytes(written[: len(written) // 2])  # a copy cut short, a restored backup
    with pytest.raises(InputError, match=r"windows.jsonl holds \d+ bytes where the checkpoint"):
        _run(small, out, resume=True)
    assert windows.read_bytes() == written[: len(written) // 2]  # not padded, not touched
    args = ["run", str(small / "config.toml"), str(small / "detections.csv"), "--out",
            str(out), "--no-timings", "--no-progress", "--resume"]  # fmt: skip
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot resume" in err and "--overwrite" in err
    changed = bytearray(written)
    changed[len(written) // 2] ^= 0x01  # same length, other bytes
    windows.write_bytes(bytes(changed))
    with pytest.raises(InputError, match="SHA-256 differs"):
        _run(small, out, resume=True)
    assert (read_manifest(partial) or {})["status"] == "interrupted"


@pytest.mark.slow
@pytest.mark.parametrize("checkpoint", [True, False])
def test_a_partial_folder_that_says_complete_but_is_not_is_run_to_the_end(
    small: Path, small_reference: Path, tmp_path: Path,
    capsys: pytest.CaptureFixture[str], checkpoint: bool,
) -> None:  # fmt: skip
    out = tmp_path / "out"
    partial = _interrupted(small, out, 19)
    manifest = json.loads((partial / MANIFEST_NAME).read_text())
    (partial / MANIFEST_NAME).write_text(json.dumps({**manifest, "status": "complete"}))
    if not checkpoint:
        (partial / CHECKPOINT_NAME).unlink()
    outcome = _run(small, out, resume=True)
    err = capsys.readouterr().err
    assert "says the run is complete but summary.json is missing" in err
    assert outcome.resumed_at == (19 if checkpoint else 0)  # type: ignore[attr-defined]
    _same_results(out, small_reference)


@pytest.mark.slow
def test_a_complete_folder_that_is_not_whole_is_refused(
    small: Path, small_reference: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import shutil

    out = tmp_path / "out"
    shutil.copytree(small_reference, out)
    assert _run(small, out, resume=True).status == "skipped"  # type: ignore[attr-defined]
    lines = (out / "windows.jsonl").read_bytes().splitlines(keepends=True)
    (out / "windows.jsonl").write_bytes(b"".join(lines[:19]))
    with pytest.raises(OutputError, match="windows.jsonl holds 19 whole lines where summary"):
        _run(small, out, resume=True)
    (out / "tracks.csv").unlink()
    args = ["run", str(small / "config.toml"), str(small / "detections.csv"), "--out",
            str(out), "--no-timings", "--no-progress", "--resume"]  # fmt: skip
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tracks.csv is missing" in err and "--overwrite" in err
    _run(small, out, overwrite=True)
    _same_results(out, small_reference)
    # A file changed in place, same length: the manifest's SHA-256 tells.
    tracks = bytearray((out / "tracks.csv").read_bytes())
    tracks[-3] = ord("7") if tracks[-3] != ord("7") else ord("8")
    (out / "tracks.csv").write_bytes(bytes(tracks))
    with pytest.raises(OutputError, match="tracks.csv is not the file the run wrote"):
        _run(small, out, resume=True)
