"""Kill ``mapassoc run`` at random moments (SIGKILL and SIGINT), resume until done.

Nothing may be lost or duplicated: the final files equal, byte for byte, those of a run
that was never interrupted (timings off).
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mapassoc.apps.cli import main
from mapassoc.apps.run_folders import read_manifest

pytestmark = pytest.mark.slow


def _command(scenario: Path, out: Path) -> list[str]:
    return [
        sys.executable, "-m", "mapassoc.apps.cli", "run",
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
