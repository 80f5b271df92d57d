"""Stop requests: a flag set by SIGINT / SIGTERM (or by hand), read at window boundaries.

The command line and the batch install the handlers around a run
(:func:`stop_on_signals`); the worker processes (:mod:`mapassoc.apps.workers`) keep their
own flag; a run (:func:`mapassoc.apps.runs.run_files`) takes any ``stop`` callable.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType

__all__ = ["StopFlag", "stop_on_signals"]


class StopFlag:
    """A stop request, set by a signal handler (or by hand) and read at window boundaries."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self.signal_name: str | None = None

    def set(self, signal_name: str = "request") -> None:
        self.signal_name = signal_name
        self._event.set()

    def __call__(self) -> bool:
        return self._event.is_set()


@contextlib.contextmanager
def stop_on_signals(flag: StopFlag, *, notice: bool = True) -> Iterator[StopFlag]:
    """Turn SIGINT and SIGTERM into ``flag.set()`` while the block runs.

    The first signal asks the run to stop after the current window (and says so at once
    when ``notice`` and stderr is a terminal: a log gets only the final line); a second
    SIGINT raises KeyboardInterrupt at once.  Outside the main thread (signal handlers
    cannot be installed there) the block runs unchanged.
    """
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        name = signal.Signals(signum).name
        if flag() and signum == signal.SIGINT:
            raise KeyboardInterrupt
        flag.set(name)
        if notice and sys.stderr.isatty():
            print(
                f"mapassoc: {name}: stopping after the current window "
                "(Ctrl-C again to stop at once)",
                file=sys.stderr,
                flush=True,
            )

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield flag
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
