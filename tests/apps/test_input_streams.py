"""Inputs are read once: named pipes work like files, and a stop is honoured while waiting."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from mapassoc.apps.cli import main
from mapassoc.apps.runs import InputWaitInterrupted, RunOptions, read_input, run_files
from mapassoc.apps.stopping import StopFlag

pytestmark = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes need POSIX")


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scen") / "crossing"
    assert main(["simulate", "crossing", "--out", str(out), "--seed", "3", "--scans", "20"]) == 0
    return out


def _feed(pipe: Path, data: bytes, delay: float = 0.2) -> threading.Thread:
    """Write ``data`` into the named pipe ``pipe`` once a reader has it open."""

    def write() -> None:
        time.sleep(delay)
        with open(pipe, "wb") as handle:  # blocks until the reader opens it
            handle.write(data)

    thread = threading.Thread(target=write, daemon=True)
    thread.start()
    return thread


def test_read_input_hashes_the_bytes_it_returns(tmp_path: Path) -> None:
    import hashlib

    path = tmp_path / "a.csv"
    path.write_bytes(b"time,x\n1,2\n")
    data, identity = read_input(path)
    assert data == b"time,x\n1,2\n"
    assert identity == {"path": str(path), "bytes": 11,
                        "sha256": hashlib.sha256(data).hexdigest()}


def test_named_pipes_give_the_same_run_as_files(scenario: Path, tmp_path: Path) -> None:
    """Config and detections from named pipes (each can be read only once, as a process
    substitution <(...) can): the same tracks and the same input hashes as the files."""
    reference = tmp_path / "ref"
    run_files(
        scenario / "config.toml",
        scenario / "detections.csv",
        reference,
        RunOptions(timings=False, progress=False),
    )
    config_pipe, detections_pipe = tmp_path / "config.toml", tmp_path / "detections.csv"
    os.mkfifo(config_pipe)
    os.mkfifo(detections_pipe)
    feeders = [
        _feed(config_pipe, (scenario / "config.toml").read_bytes()),
        _feed(detections_pipe, (scenario / "detections.csv").read_bytes(), delay=0.5),
    ]
    out = tmp_path / "out"
    run_files(config_pipe, detections_pipe, out, RunOptions(timings=False, progress=False))
    for thread in feeders:
        thread.join(5)
    for name in ("tracks.csv", "windows.jsonl"):
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name
    import json

    hashes = [json.loads((folder / "manifest.json").read_text())["inputs"]
              for folder in (out, reference)]
    for kind in ("config", "detections"):
        assert hashes[0][kind]["sha256"] == hashes[1][kind]["sha256"]


def test_a_stop_is_honoured_while_waiting_for_input(scenario: Path, tmp_path: Path) -> None:
    pipe = tmp_path / "detections.csv"
    os.mkfifo(pipe)  # no writer ever opens it
    flag = StopFlag()
    raised: list[BaseException] = []

    def run() -> None:
        try:
            run_files(
                scenario / "config.toml",
                pipe,
                tmp_path / "out",
                RunOptions(progress=False),
                stop=flag,
            )  # fmt: skip
        except BaseException as exc:  # noqa: BLE001 - handed to the test below
            raised.append(exc)

    runner = threading.Thread(target=run, daemon=True)
    runner.start()
    time.sleep(0.3)
    assert runner.is_alive()  # waiting on the pipe
    flag.set()
    runner.join(60)  # a liveness bound, not a speed test: without the fix it never ends
    assert not runner.is_alive(), "the stop request was not honoured while waiting"
    assert len(raised) == 1 and isinstance(raised[0], InputWaitInterrupted)
    assert "waiting for input" in str(raised[0]) and "detections.csv" in str(raised[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["detections.csv"]


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_the_command_line_stops_while_waiting_on_a_pipe(
    scenario: Path, tmp_path: Path, signum: signal.Signals
) -> None:
    """Once, a blocked read of a named pipe ignored SIGTERM for good and a second Ctrl-C
    gave a traceback; now either signal ends the command at once with one line, 130."""
    pipe = tmp_path / "detections.csv"
    os.mkfifo(pipe)
    child = subprocess.Popen(
        [sys.executable, "-m", "mapassoc.apps.cli", "run", str(scenario / "config.toml"),
         str(pipe), "--out", str(tmp_path / "out"), "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    time.sleep(2.0)  # well into the wait on the pipe
    assert child.poll() is None
    child.send_signal(signum)
    try:
        out, err = child.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        child.kill()
        raise AssertionError("the run did not stop while waiting on a named pipe") from None
    assert child.returncode == 130, err
    assert err.strip().splitlines() == [
        f"mapassoc: stopped while waiting for input {pipe}; nothing was written"
    ]
    assert "Traceback" not in err and out == ""
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.partial").exists()


def test_a_run_with_stderr_closed_completes(scenario: Path, tmp_path: Path) -> None:
    """With stderr closed (2>&-) Python has no sys.stderr; progress on, the run once
    failed with "'NoneType' object has no attribute 'write'" in its manifest."""
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-m", "mapassoc.apps.cli", "run", str(scenario / "config.toml"),
         str(scenario / "detections.csv"), "--out", str(out)],
        stdout=subprocess.PIPE, text=True, timeout=300, preexec_fn=lambda: os.close(2),
    )
    assert done.returncode == 0
    assert "tracks over 20 scans" in done.stdout
    import json

    assert json.loads((out / "manifest.json").read_text())["status"] == "complete"



@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Six scans, and a run of them (``tiny/ref``)."""
    out = tmp_path_factory.mktemp("tiny") / "crossing"
    assert main(["simulate", "crossing", "--out", str(out), "--seed", "3", "--scans", "6"]) == 0
    run_files(out / "config.toml", out / "detections.csv", out / "ref",
              RunOptions(timings=False, progress=False))  # fmt: skip
    return out


def _same_run(out: Path, reference: Path) -> None:
    for name in ("tracks.csv", "windows.jsonl"):
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name


@pytest.mark.slow  # a child process: its start-up and imports
def test_stdin_without_a_suffix_is_read_as_the_file(tiny: Path, tmp_path: Path) -> None:
    """`run CONFIG /dev/stdin` fed by a pipe (as `zcat d.csv.gz | mapassoc run c.toml
    /dev/stdin` is) was refused for having "no file suffix"; its content says CSV."""
    out = tmp_path / "out"
    done = subprocess.run(
        [sys.executable, "-m", "mapassoc.apps.cli", "run", str(tiny / "config.toml"),
         "/dev/stdin", "--out", str(out), "--no-progress", "--no-timings"],
        input=(tiny / "detections.csv").read_bytes(), capture_output=True, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    _same_run(out, tiny / "ref")


def test_a_pipe_without_a_suffix_is_run_like_the_file(tiny: Path, tmp_path: Path) -> None:
    """A named pipe called `detections`, as <(zcat detections.csv.gz) is /dev/fd/63."""
    pipe = tmp_path / "detections"
    os.mkfifo(pipe)
    feeder = _feed(pipe, (tiny / "detections.csv").read_bytes())
    run_files(tiny / "config.toml", pipe, tmp_path / "out",
              RunOptions(timings=False, progress=False))  # fmt: skip
    feeder.join(5)
    _same_run(tmp_path / "out", tiny / "ref")


@pytest.mark.parametrize("data_format", ["csv", "parquet"])
@pytest.mark.parametrize("named", [False, True])
def test_a_pipe_is_read_in_its_sniffed_or_named_format(
    tiny: Path, tmp_path: Path, data_format: str, named: bool
) -> None:
    """Without a suffix the format is the one named (--format), else that of the bytes
    (Parquet's PAR1, else CSV); the pipe is read once."""
    if data_format == "parquet":
        pytest.importorskip("pyarrow")
    from mapassoc.data.config import load_config
    from mapassoc.data.formats import read_detections_file, write_detections_file

    sensors = load_config(tiny / "config.toml").sensors
    scans = read_detections_file(tiny / "detections.csv", sensors)
    source = tmp_path / f"detections.{data_format}"
    write_detections_file(source, scans, sensors)
    pipe = tmp_path / "detections"
    os.mkfifo(pipe)
    feeder = _feed(pipe, source.read_bytes(), delay=0.05)
    got = read_detections_file(pipe, sensors, format_name=data_format if named else None)
    feeder.join(5)
    assert [s.time for s in got] == [s.time for s in scans]
    for mine, theirs in zip(got, scans, strict=True):
        assert mine.detections.tolist() == theirs.detections.tolist()
        assert mine.rows.tolist() == theirs.rows.tolist()
