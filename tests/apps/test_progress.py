"""Progress: tqdm on a terminal, a log line at most every log_seconds elsewhere."""

from __future__ import annotations

import io

import pytest

from mapassoc.apps.progress import Progress


def test_log_lines_are_throttled_and_say_rate_and_time_left(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    clock = iter([0.0, 1.0, 5.0, 31.0, 40.0])
    monkeypatch.setattr("mapassoc.apps.progress.time.monotonic", lambda: next(clock))
    stream = io.StringIO()
    progress = Progress(stream, label="run", unit="scans", log_seconds=30.0)  # t = 0
    progress(10, 100)  # t = 1: too soon
    progress(20, 100)  # t = 5: too soon
    progress(62, 100)  # t = 31: 62 scans in 31 s -> 2 scans/s, 38 left -> 19 s
    progress(100, 100)  # t = 40: the end is always logged
    lines = stream.getvalue().splitlines()
    assert lines == [
        "mapassoc: run 62/100 scans (62%), 2 scans/s, about 0:00:19 left",
        "mapassoc: run 100/100 scans (100%), 2.5 scans/s, 0:00:40 in all",
    ]


def test_a_resumed_run_leaves_earlier_scans_out_of_the_rate() -> None:
    progress = Progress(io.StringIO(), label="run", unit="scans", initial=50)
    assert progress.line(60, 100, 5.0) == (
        "mapassoc: run 60/100 scans (60%), 2 scans/s, about 0:00:20 left"
    )


def test_a_terminal_gets_a_tqdm_bar() -> None:
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    stream = Terminal()
    progress = Progress(stream, label="run", unit="scans")
    for done in (10, 50, 100):
        progress(done, 100)
    text = stream.getvalue()
    assert "mapassoc run" in text and "100/100" in text and "scan/s" in text


def test_disabled_writes_nothing() -> None:
    stream = io.StringIO()
    progress = Progress(stream, label="run", unit="scans", enabled=False)
    progress(100, 100)
    assert stream.getvalue() == ""
