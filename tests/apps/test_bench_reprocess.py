"""bench-reprocess on tiny sizes: every measurement runs and the checks it prints hold."""

from __future__ import annotations

import pytest

from mapassoc.apps.bench_reprocess import run_child, run_reprocess_benchmark
from mapassoc.errors import InputError

pytestmark = pytest.mark.slow


def test_tiny_reprocess_benchmark(capsys: pytest.CaptureFixture[str]) -> None:
    results = run_reprocess_benchmark(
        recordings=2, scans=40, long_scans=80, segment_families=("crossing",),
        segment_scans=100, jobs=2,
    )  # fmt: skip
    batch = results["batch"]
    assert isinstance(batch, dict) and batch["same_files"] is True
    long = results["long"]
    assert isinstance(long, dict) and long["max_rss_mb"] > 10 and long["seconds"] > 0
    segments = results["segments"]
    assert isinstance(segments, dict)
    crossing = segments["crossing"]
    assert crossing["tracks"]["segments"] >= 1
    assert crossing["gospa"]["segments"] == pytest.approx(crossing["gospa"]["sequential"], rel=0.1)
    printed = capsys.readouterr().out
    assert "scans/s" in printed and "peak memory" in printed and "same tracks" in printed
    startup = results["startup"]
    assert isinstance(startup, dict)
    assert 0 < startup["--help median"] <= startup["--help max"]
    assert "mapassoc --help" in printed and "goal < 0.5 s" in printed


def test_a_failing_child_names_its_command() -> None:
    with pytest.raises(InputError, match="`mapassoc simulate no-such --out .*` failed: .*no-such"):
        run_child(["simulate", "no-such", "--out", "/tmp/never-written"])
