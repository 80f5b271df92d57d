"""Worker processes record a Ctrl-C however early it reaches them."""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import signal
import time
from typing import Any

import pytest

from mapassoc.apps.workers import run_on_pool


@pytest.mark.slow
def test_a_signal_while_the_workers_start_breaks_no_worker(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """In a terminal a Ctrl-C reaches every process of the group, workers that are still
    importing included: each records it (its task polls it) instead of dying with a
    traceback, which would break the pool."""
    submit = concurrent.futures.ProcessPoolExecutor.submit
    signalled: list[int] = []

    def submit_then_signal(self: Any, *args: Any, **kwargs: Any) -> Any:
        future = submit(self, *args, **kwargs)  # starts a worker process
        for child in multiprocessing.active_children():  # at once: it is still starting
            os.kill(child.pid, signal.SIGINT)
            signalled.append(child.pid)
        return future

    monkeypatch.setattr(concurrent.futures.ProcessPoolExecutor, "submit", submit_then_signal)
    outcomes: dict[int, BaseException | None] = {}
    run_on_pool(
        2,
        [(time.sleep, (0.2,), {}), (time.sleep, (0.2,), {})],
        on_done=lambda index, future: outcomes.__setitem__(index, future.exception()),
        stop=lambda: False,
    )
    assert signalled
    assert outcomes == {0: None, 1: None}
