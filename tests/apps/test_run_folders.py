"""Run folders: refusing to mix runs, manifests, stop and resume, output failures.

The resumed runs are compared byte for byte with a run that never stopped (timings off).
"""

from __future__ import annotations

import errno
import io
import json
from collections.abc import Callable
from pathlib import Path

import pytest

from mapassoc.apps import runs
from mapassoc.apps.cli import main
from mapassoc.apps.run_folders import CHECKPOINT_NAME, MANIFEST_NAME, read_manifest
from mapassoc.apps.runs import RunInterrupted, RunOptions, run_files
from mapassoc.errors import InputError, OutputError

RESULT_FILES = ("tracks.csv", "associations.csv", "windows.jsonl", "summary.json")


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scen") / "crossing"
    assert main(["simulate", "crossing", "--out", str(out), "--seed", "2"]) == 0
    return out


@pytest.fixture(scope="module")
def reference(scenario: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An uninterrupted run with timings off."""
    out = tmp_path_factory.mktemp("ref") / "run"
    run_files(
        scenario / "config.toml",
        scenario / "detections.csv",
        out,
        RunOptions(timings=False, progress=False),
    )
    return out


def _run(
    scenario: Path,
    out: Path,
    *,
    stop: Callable[[], bool] | None = None,
    overwrite: bool = False,
    resume: bool = False,
    checkpoint_seconds: float = 10.0,
    segments: int = 1,
    jobs: int | None = None,
) -> runs.RunOutcome:
    """A run of ``scenario`` into ``out`` with timings and progress off."""
    options = RunOptions(
        timings=False,
        progress=False,
        overwrite=overwrite,
        resume=resume,
        checkpoint_seconds=checkpoint_seconds,
        segments=segments,
        jobs=jobs,
    )
    return run_files(scenario / "config.toml", scenario / "detections.csv", out, options, stop=stop)


def _same_results(a: Path, b: Path) -> None:
    for name in RESULT_FILES:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


def test_complete_folder_holds_results_and_manifest(reference: Path, scenario: Path) -> None:
    assert sorted(p.name for p in reference.iterdir()) == sorted([*RESULT_FILES, MANIFEST_NAME])
    manifest = read_manifest(reference)
    assert manifest is not None and manifest["status"] == "complete"
    assert manifest["sessions"] == 1
    summary = json.loads((reference / "summary.json").read_text())
    assert manifest["scans_committed"] == manifest["scans_total"] == summary["scans"]
    assert manifest["windows_committed"] == summary["windows"]
    import hashlib

    digest = hashlib.sha256((scenario / "detections.csv").read_bytes()).hexdigest()
    assert manifest["inputs"]["detections"]["sha256"] == digest
    assert manifest["settings"]["timings"] is False
    assert manifest["ended"] >= manifest["started"]
    assert not reference.with_name("run.partial").exists()


def test_a_folder_that_is_no_run_is_never_replaced(
    scenario: Path, reference: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("keep me")
    args = ["run", str(scenario / "config.toml"), str(scenario / "detections.csv"),
            "--out", str(out), "--no-progress", "--no-timings"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(out) in err and "holds no mapassoc run" in err
    assert "--overwrite" not in err  # no advice that would delete the user's files
    for again in ("--overwrite", "--resume"):
        assert main([*args, again]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "not a mapassoc run folder" in err, again
        assert (out / "mine.txt").read_text() == "keep me"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_run_folder_is_refused_then_overwritten(
    scenario: Path, reference: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    _run(scenario, out)
    (out / "note.txt").write_text("a note kept in a run folder goes with it")
    args = ["run", str(scenario / "config.toml"), str(scenario / "detections.csv"),
            "--out", str(out), "--no-progress", "--no-timings"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "holds a complete run" in err and "--overwrite" in err
    assert main([*args, "--overwrite"]) == 0
    assert not (out / "note.txt").exists()
    _same_results(out, reference)


@pytest.mark.parametrize("where", ["out", "partial"])
def test_a_folder_holding_the_inputs_is_never_replaced(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], where: str
) -> None:
    """`run scen/config.toml scen/detections.csv --out scen --overwrite` once deleted the
    inputs; now it is refused before anything is computed, even where the folder is a
    mapassoc run folder (a manifest of the right format)."""
    scen = tmp_path / "scen"
    scen.mkdir()
    for name in ("config.toml", "detections.csv", "truth.csv"):
        (scen / name).write_bytes((scenario / name).read_bytes())
    (scen / MANIFEST_NAME).write_text(json.dumps({"format": "mapassoc-run/1"}))
    before = {p.name: p.read_bytes() for p in scen.iterdir()}
    out = scen if where == "out" else tmp_path / "x"
    if where == "partial":
        scen.rename(tmp_path / "x.partial")
        scen = tmp_path / "x.partial"
    args = ["run", str(scen / "config.toml"), str(scen / "detections.csv"),
            "--out", str(out), "--no-progress", "--no-timings"]
    for again in ("--overwrite", "--resume"):
        assert main([*args, again]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "holds the input" in err and str(scen) in err
    assert {p.name: p.read_bytes() for p in scen.iterdir()} == before


def test_a_foreign_partial_folder_is_never_emptied(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    partial = tmp_path / "out.partial"
    partial.mkdir()
    (partial / "mine.txt").write_text("keep me")
    args = ["run", str(scenario / "config.toml"), str(scenario / "detections.csv"),
            "--out", str(out), "--no-progress", "--no-timings"]
    for again in ((), ("--overwrite",), ("--resume",)):
        assert main([*args, *again]) == 2
        err = capsys.readouterr().err
        assert "out.partial" in err and "not a mapassoc run folder" in err, again
    assert (partial / "mine.txt").read_text() == "keep me"
    assert not out.exists()


def test_out_parents_are_created(scenario: Path, reference: Path, tmp_path: Path) -> None:
    out = tmp_path / "a" / "b" / "run"
    assert main(["run", str(scenario / "config.toml"), str(scenario / "detections.csv"),
                 "--out", str(out), "--no-progress", "--no-timings"]) == 0
    _same_results(out, reference)


def test_a_failed_overwrite_keeps_the_previous_run(
    scenario: Path, reference: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "out"
    _run(scenario, out)
    before = {name: (out / name).read_bytes() for name in RESULT_FILES}
    _fail_windows_after(monkeypatch, lines=3, code=errno.ENOSPC)
    with pytest.raises(OutputError, match="windows.jsonl: cannot write: No space left"):
        _run(scenario, out, overwrite=True)
    assert {name: (out / name).read_bytes() for name in RESULT_FILES} == before
    manifest = read_manifest(out.with_name("out.partial"))
    assert manifest is not None and manifest["status"] == "failed"
    assert "No space left" in manifest["error"]


class _FailingStream(io.BufferedIOBase):
    """A windows.jsonl stream whose write fails after ``lines`` lines."""

    def __init__(self, inner: io.BufferedRandom, lines: int, code: int) -> None:
        self.inner, self.left, self.code = inner, lines, code

    def write(self, data: bytes) -> int:  # type: ignore[override]
        if self.left == 0:
            raise OSError(self.code, "injected")
        self.left -= 1
        return self.inner.write(data)

    def flush(self) -> None:
        self.inner.flush()

    def fileno(self) -> int:
        return self.inner.fileno()

    def tell(self) -> int:
        return self.inner.tell()

    def close(self) -> None:
        self.inner.close()


def _fail_windows_after(monkeypatch: pytest.MonkeyPatch, *, lines: int, code: int) -> None:
    real = runs._open_windows
    monkeypatch.setattr(
        runs, "_open_windows", lambda path, keep: _FailingStream(real(path, keep), lines, code)
    )


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS, errno.EACCES])
def test_a_write_failure_is_one_line_and_resumable(
    scenario: Path,
    reference: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    code: int,
) -> None:
    out = tmp_path / "out"
    args = ["run", str(scenario / "config.toml"), str(scenario / "detections.csv"),
            "--out", str(out), "--no-progress", "--no-timings", "--checkpoint-seconds", "0"]
    with monkeypatch.context() as patch:
        _fail_windows_after(patch, lines=7, code=code)
        assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert "windows.jsonl" in err and __import__("os").strerror(code) in err
    assert not out.exists()
    partial = out.with_name("out.partial")
    assert (read_manifest(partial) or {})["status"] == "failed"
    assert main([*args, "--resume"]) == 0
    _same_results(out, reference)


def test_out_that_is_a_file_or_below_one_is_one_line(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    afile = tmp_path / "afile"
    afile.write_text("x")
    for out in (afile, afile / "below"):
        args = ["run", str(scenario / "config.toml"), str(scenario / "detections.csv"),
                "--out", str(out), "--no-progress"]
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and str(afile) in err and "is a file" in err
        assert main(["simulate", "crossing", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and str(afile) in err


@pytest.mark.parametrize("after", [0, 1, 9, 30, 55])
def test_stop_then_resume_is_byte_identical(
    scenario: Path, reference: Path, tmp_path: Path, after: int
) -> None:
    """Stop at a window boundary after ``after`` windows, resume, compare bytes."""
    out = tmp_path / "out"
    polls = iter(range(10**6))
    with pytest.raises(RunInterrupted) as stopped:
        _run(scenario, out, checkpoint_seconds=3600.0, stop=lambda: next(polls) >= after)
    partial = out.with_name("out.partial")
    manifest = read_manifest(partial)
    assert manifest is not None and manifest["status"] == "interrupted"
    assert (partial / CHECKPOINT_NAME).exists()
    assert stopped.value.scans_committed == manifest["scans_committed"]
    lines = (partial / "windows.jsonl").read_text().splitlines()
    assert len(lines) == after == manifest["windows_committed"]
    outcome = _run(scenario, out, resume=True)
    assert outcome.resumed_at == stopped.value.scans_committed
    _same_results(out, reference)
    manifest = read_manifest(out)
    assert manifest is not None and manifest["status"] == "complete"
    assert manifest["sessions"] == 2
    assert not partial.exists() and not (out / CHECKPOINT_NAME).exists()
    # Resuming a complete run does nothing.
    assert _run(scenario, out, resume=True).status == "skipped"


def test_resume_cuts_windows_written_after_the_checkpoint(
    scenario: Path, reference: Path, tmp_path: Path
) -> None:
    """Lines written after the last checkpoint (a kill) are cut and written again once."""
    out = tmp_path / "out"
    polls = iter(range(10**6))
    with pytest.raises(RunInterrupted):
        _run(scenario, out, stop=lambda: next(polls) >= 12)
    partial = out.with_name("out.partial")
    with (partial / "windows.jsonl").open("a") as stream:
        stream.write('{"window": 12, "half a line')  # what a kill leaves
    _run(scenario, out, resume=True)
    _same_results(out, reference)


def test_resume_refuses_other_inputs_or_settings(
    scenario: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    polls = iter(range(10**6))
    with pytest.raises(RunInterrupted):
        _run(scenario, out, stop=lambda: next(polls) >= 3)
    changed = tmp_path / "detections.csv"
    lines = (scenario / "detections.csv").read_text().splitlines()
    changed.write_text("\n".join(lines[:-1]) + "\n")
    with pytest.raises(InputError, match="detections file .* differs"):
        run_files(
            scenario / "config.toml",
            changed,
            out,
            RunOptions(timings=False, progress=False, resume=True),
        )
    with pytest.raises(InputError, match="timings"):
        run_files(
            scenario / "config.toml",
            scenario / "detections.csv",
            out,
            RunOptions(timings=True, progress=False, resume=True),
        )
    with pytest.raises(InputError, match="exclude each other"):
        _run(scenario, out, resume=True, overwrite=True)


def test_bad_input_creates_nothing(scenario: Path, tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time,sensor,x,y\n0.0,radar,1.0,nan\n")
    out = tmp_path / "out"
    with pytest.raises(Exception, match="bad.csv"):
        run_files(scenario / "config.toml", bad, out, RunOptions(progress=False))
    assert not out.exists() and not out.with_name("out.partial").exists()


def test_broken_pipe_is_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    class Closed(io.StringIO):
        def write(self, text: str) -> int:
            raise BrokenPipeError(errno.EPIPE, "Broken pipe")

    monkeypatch.setattr("sys.stdout", Closed())
    monkeypatch.setattr("mapassoc.apps.cli._close_stdout_quietly", lambda: None)
    assert main(["scenarios"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "<stdout>" in err and "broken pipe" in err


@pytest.fixture(scope="module")
def long_scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scen") / "long"
    assert main(["simulate", "crossing", "--scans", "150", "--out", str(out), "--seed", "4"]) == 0
    return out


@pytest.mark.slow
def test_segmented_run_stops_and_resumes_to_the_same_files(
    long_scenario: Path, tmp_path: Path
) -> None:
    """Segments on two processes; a stop after the first finished segment, then resume."""
    whole = tmp_path / "whole"
    _run(long_scenario, whole, segments=3, jobs=2)
    manifest = read_manifest(whole)
    assert manifest is not None and manifest["settings"]["segments"] == 3
    lines = (whole / "windows.jsonl").read_text().splitlines()
    assert sum(json.loads(line)["committed_scans"] for line in lines) == 150

    out = tmp_path / "out"
    polls = iter(range(10**6))
    # In this process (jobs=1) the stop is polled at every window: stop inside segment 2.
    with pytest.raises(RunInterrupted) as stopped:
        _run(long_scenario, out, segments=3, jobs=1, stop=lambda: next(polls) >= 56)
    partial = out.with_name("out.partial")
    assert (read_manifest(partial) or {})["status"] == "interrupted"
    assert 0 < stopped.value.scans_committed < 150
    with pytest.raises(InputError, match="segments"):
        _run(long_scenario, out, segments=2, resume=True)
    outcome = _run(long_scenario, out, segments=3, jobs=2, resume=True)
    assert outcome.resumed_at == stopped.value.scans_committed
    _same_results(out, whole)


def test_a_second_run_into_the_same_folder_is_refused(
    scenario: Path, reference: Path, tmp_path: Path
) -> None:
    from mapassoc.apps.run_folders import RunFolder

    out = tmp_path / "out"
    polls = iter(range(10**6))
    with pytest.raises(RunInterrupted):
        _run(scenario, out, stop=lambda: next(polls) >= 5)
    other = RunFolder(out)  # what a run in another process holds while it writes
    other.lock()
    try:
        for options in ({"overwrite": True}, {"resume": True}):
            with pytest.raises(OutputError, match=r"another mapassoc run \(pid \d+\) is writing"):
                _run(scenario, out, **options)
        # Nothing was wiped: the interrupted run is still there to resume.
        assert (read_manifest(out.with_name("out.partial")) or {})["status"] == "interrupted"
    finally:
        other.release()
    _run(scenario, out, resume=True)
    _same_results(out, reference)
    assert not out.with_name(".out.lock").exists()


def test_signals_set_the_flag_and_a_second_sigint_stops_at_once() -> None:
    import os
    import signal

    from mapassoc.apps.stopping import StopFlag, stop_on_signals

    before = signal.getsignal(signal.SIGINT)
    with stop_on_signals(StopFlag()) as stop:
        assert not stop()
        os.kill(os.getpid(), signal.SIGTERM)
        assert stop() and stop.signal_name == "SIGTERM"
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
    assert signal.getsignal(signal.SIGINT) is before


def test_an_abort_mid_run_keeps_the_last_checkpoint(
    scenario: Path, reference: Path, tmp_path: Path
) -> None:
    """Ctrl-C twice (KeyboardInterrupt inside a window): interrupted, resumable."""
    out = tmp_path / "out"
    polls = iter(range(10**6))

    def abort() -> bool:
        if next(polls) == 20:
            raise KeyboardInterrupt
        return False

    with pytest.raises(RunInterrupted):
        _run(scenario, out, checkpoint_seconds=0.0, stop=abort)
    manifest = read_manifest(out.with_name("out.partial"))
    assert manifest is not None and manifest["status"] == "interrupted"
    assert manifest["scans_committed"] == 20  # the checkpoint after window 19
    _run(scenario, out, resume=True)
    _same_results(out, reference)


# ------------------------------------------------------------ one rule for every output


def test_write_atomically_keeps_the_old_file_or_none_on_a_full_disk(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A write that fails (the disk fills up at the flush) leaves the previous file whole,
    or no file, and no temporary file; a user's ``NAME.tmp`` is never touched."""
    from mapassoc.apps.run_folders import write_atomically

    old = tmp_path / "old.json"
    old.write_bytes(b"previous\n")
    (tmp_path / "old.json.tmp").write_bytes(b"the user's own")

    def full(descriptor: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("os.fsync", full)
    for path in (old, tmp_path / "new.json"):
        with pytest.raises(OutputError, match=f"{path.name}: cannot write: No space left"):
            write_atomically(path, b"x" * 100)
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.json", "old.json.tmp"]
    assert old.read_bytes() == b"previous\n"
    assert (tmp_path / "old.json.tmp").read_bytes() == b"the user's own"
    write_atomically(old, b"new\n")
    assert old.read_bytes() == b"new\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.json", "old.json.tmp"]


def test_write_atomically_removes_its_temporary_on_a_signal(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from mapassoc.apps.run_folders import write_atomically

    def interrupted(source: object, target: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr("os.replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_atomically(tmp_path / "a.json", b"{}\n")
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []


def test_write_atomically_refuses_an_existing_file_when_new(tmp_path: Path) -> None:
    from mapassoc.apps.run_folders import write_atomically

    (tmp_path / "a.toml").write_text("mine")
    with pytest.raises(OutputError, match="exists already"):
        write_atomically(tmp_path / "a.toml", b"theirs", new=True)
    assert [p.name for p in tmp_path.iterdir()] == ["a.toml"]
    assert (tmp_path / "a.toml").read_text() == "mine"


def test_an_out_that_is_a_link_is_followed_and_kept(
    scenario: Path, reference: Path, tmp_path: Path
) -> None:
    """`run --out lnk --overwrite`, lnk a link to a complete run folder: the folder it
    points to is replaced, the link stays a link to it, and nothing else appears."""
    target = tmp_path / "disk" / "run"
    _run(scenario, target)
    (target / "note.txt").write_text("goes with the replaced run")
    link = tmp_path / "lnk"
    link.symlink_to(target, target_is_directory=True)
    outcome = _run(scenario, link, overwrite=True)
    assert outcome.status == "complete"
    assert link.is_symlink() and link.resolve() == target.resolve()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["disk", "lnk"]
    assert sorted(p.name for p in (tmp_path / "disk").iterdir()) == ["run"]
    assert not (target / "note.txt").exists()
    _same_results(link, reference)
    # Without --overwrite the link's folder is refused like the folder itself.
    with pytest.raises(OutputError, match="holds a complete run"):
        _run(scenario, link)
    # And --resume through the link finds the target's run complete.
    assert _run(scenario, link, resume=True).status == "skipped"


def test_a_partial_sibling_that_is_a_link_is_refused(scenario: Path, tmp_path: Path) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "keep.txt").write_text("mine")
    (tmp_path / "out.partial").symlink_to(elsewhere, target_is_directory=True)
    for options in ({}, {"overwrite": True}, {"resume": True}):
        with pytest.raises(OutputError, match="out.partial: is a symbolic link"):
            _run(scenario, tmp_path / "out", **options)
    assert [p.name for p in elsewhere.iterdir()] == ["keep.txt"]


def test_a_lock_left_by_a_dead_process_blocks_nothing(
    scenario: Path, reference: Path, tmp_path: Path
) -> None:
    """The lock is an flock: a lock file whose process died (kill -9) is no lock."""
    out = tmp_path / "out"
    (tmp_path / ".out.lock").write_text("999999999\n")
    assert _run(scenario, out).status == "complete"
    _same_results(out, reference)
    assert not (tmp_path / ".out.lock").exists()
