"""Stop requests: a flag set by SIGINT / SIGTERM (or by hand), read between units of work.

The command line and the batch install the handlers around a run
(:func:`stop_on_signals`); the worker processes (:mod:`mapassoc.apps.workers`) keep their
own flag; a run (:func:`mapassoc.apps.runs.run_files`) takes any ``stop`` callable and
hands the same one to every phase: the forward pass polls it between windows, the
parameter estimation between its windows, the whole recording's refinement between its
re-solves and linking rounds, the confidence pass between its windows
(:class:`mapassoc.errors.StopRequested`).  Before any of that, the ``mapassoc`` script
(:mod:`mapassoc.apps.launch`) catches both signals while the command line is imported,
and turns SIGTERM into a KeyboardInterrupt (what a Ctrl-C is) outside a run, so that a
signal at any moment ends the command with one line and :data:`EXIT_INTERRUPTED`.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType

__all__ = ["EXIT_INTERRUPTED", "StopFlag", "stop_on_signals", "sigterm_interrupts"]

EXIT_INTERRUPTED = 130
"""Exit status of a command stopped by SIGINT or SIGTERM (128 + SIGINT, the shell's
convention)."""


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

    The first signal asks the run to stop after the current unit of work (a window, a
    move of the refinement; and says so at once when ``notice`` and stderr is a
    terminal: a log gets only the final line); a second SIGINT raises KeyboardInterrupt
    at once.  Outside the main thread (signal handlers
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
                f"mapassoc: {name}: stopping after the current window or move "
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


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


@contextlib.contextmanager
def sigterm_interrupts() -> Iterator[None]:
    """Make SIGTERM raise KeyboardInterrupt while the block runs, as SIGINT does.

    What a command does outside :func:`stop_on_signals` (which takes both signals over
    for a run): the command line reports a KeyboardInterrupt in one line with
    :data:`EXIT_INTERRUPTED`, where the default action of SIGTERM would end the process
    without a word.  Outside the main thread the block runs unchanged.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
