"""The ``mapassoc`` script: a stop request is answered in one line from its first line of code.

The command line imports numpy and the run machinery (a few tenths of a second, seconds
on a loaded machine) before a run installs its handlers
(:func:`mapassoc.apps.stopping.stop_on_signals`); a Ctrl-C in that time would print a
``KeyboardInterrupt`` traceback, and a SIGTERM would end the process without a word.
:func:`main` imports nothing heavy itself: it catches both signals while the command
line is imported (a signal then ends the command at once: one line, status 130, nothing
written), and makes SIGTERM act as a Ctrl-C for the rest of the command.  What comes
before any of mapassoc's code (the interpreter's own start, with its ``site`` imports)
is beyond its reach.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from mapassoc.apps.stopping import EXIT_INTERRUPTED, StopFlag, sigterm_interrupts, stop_on_signals

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``mapassoc`` command (:func:`mapassoc.apps.cli.main`); its exit status."""
    if sys.stderr is None:  # started with stderr closed (2>&-): messages go nowhere
        sys.stderr = open(os.devnull, "w", encoding="utf-8")  # noqa: SIM115
    try:
        with sigterm_interrupts():
            early = StopFlag()
            with stop_on_signals(early, notice=False):
                from mapassoc.apps import cli
            if early():
                print(
                    f"mapassoc: {early.signal_name}: stopped before the command started; "
                    "nothing was written",
                    file=sys.stderr,
                )
                return EXIT_INTERRUPTED
            return cli.main(argv)
    except KeyboardInterrupt:  # a second Ctrl-C while importing, or between two handlers
        print("mapassoc: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
