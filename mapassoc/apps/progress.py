"""Progress of long runs: a tqdm bar on a terminal, a periodic log line elsewhere.

A run reports ``(done, total)`` after every window (scans) or every recording (a
batch).  On a terminal the bar shows the rate and the time left (tqdm computes both);
when standard error is not a terminal (a log file, a batch system, CI) a line such as ::

    mapassoc: run 1200/2100 scans (57%), 35.2 scans/s, about 0:00:25 left

is written at most every ``log_seconds`` and once at the end, so logs stay short and
still show that the run is alive.
"""

from __future__ import annotations

import datetime
import time
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from tqdm import tqdm

__all__ = ["Progress"]


def _clock(seconds: float) -> str:
    return str(datetime.timedelta(seconds=round(seconds)))


class Progress:
    """Callable ``progress(done, total)`` for :meth:`WindowEstimator.run` and batches.

    Parameters
    ----------
    stream : text stream or None
        Where to write (standard error); None (a process started with stderr closed,
        where ``sys.stderr`` is None) writes nothing.
    label : str
        What is running (``"run"``, ``"batch"``); starts the log lines.
    unit : str
        What is counted (``"scans"``, ``"recordings"``).
    enabled : bool
        False: write nothing.
    log_seconds : float
        Least interval between two log lines when ``stream`` is not a terminal.
    initial : int
        Units done before this session (a resumed run), left out of the rate.
    """

    def __init__(
        self,
        stream: TextIO | None,
        *,
        label: str,
        unit: str,
        enabled: bool = True,
        log_seconds: float = 30.0,
        initial: int = 0,
    ) -> None:
        if not log_seconds > 0:
            raise ValueError(f"log_seconds must be > 0, got {log_seconds!r}")
        self.stream = stream
        self.label = label
        self.unit = unit
        # No stream (sys.stderr is None when the process started with stderr closed):
        # nothing to show progress on.
        self.enabled = enabled and stream is not None
        self.log_seconds = float(log_seconds)
        self.initial = int(initial)
        self._terminal = enabled and bool(getattr(stream, "isatty", lambda: False)())
        self._bar: tqdm | None = None
        self._started = time.monotonic()
        self._last_log = self._started

    def __call__(self, done: int, total: int) -> None:
        if not self.enabled:
            return
        if self._terminal:
            if self._bar is None:
                from tqdm import tqdm  # imported when a bar is first drawn, not at start-up

                self._bar = tqdm(
                    total=total,
                    initial=self.initial,
                    unit=self.unit.rstrip("s") or self.unit,
                    desc=f"mapassoc {self.label}",
                    file=self.stream,
                    dynamic_ncols=True,
                )
            self._bar.update(done - self._bar.n)
            if done >= total:
                self.close()
            return
        now = time.monotonic()
        if done < total and now - self._last_log < self.log_seconds:
            return
        self._last_log = now
        stream = self.stream
        assert stream is not None  # enabled is False when there is no stream (see __init__)
        stream.write(self.line(done, total, now - self._started) + "\n")
        stream.flush()

    def line(self, done: int, total: int, elapsed: float) -> str:
        """The log line for ``done`` of ``total`` after ``elapsed`` seconds."""
        share = f" ({100 * done / total:.0f}%)" if total else ""
        text = f"mapassoc: {self.label} {done}/{total} {self.unit}{share}"
        counted = done - self.initial
        if elapsed > 0 and counted > 0:
            rate = counted / elapsed
            text += f", {rate:.3g} {self.unit}/s"
            if done < total:
                text += f", about {_clock((total - done) / rate)} left"
            else:
                text += f", {_clock(elapsed)} in all"
        return text

    def close(self) -> None:
        """End the bar (a no-op for log lines)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
