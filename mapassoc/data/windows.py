"""The sliding window over a recording's scans, shared by every windowed method.

A window starts at the first scan not yet committed, holds ``length`` scans (fewer at
the recording's end) and commits its oldest ``stride`` of them, or all of them when it
reaches the last scan: so the windows' committed scans cover the recording exactly once,
in order.  The MAP estimator's forward pass (:meth:`mapassoc.estimator.pipeline.
WindowEstimator.step`) and the network-flow tracker (:mod:`mapassoc.trackers.flow`)
slide the same way, through :func:`window_span`.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from mapassoc.validation import check_integer

__all__ = ["WindowSpan", "window_span", "window_spans"]


@dataclass(frozen=True)
class WindowSpan:
    """Scans ``start..end-1`` of a window, of which ``start..start+commit-1`` are committed."""

    start: int
    end: int
    commit: int

    @property
    def next_start(self) -> int:
        """The first scan of the next window (``end`` of the recording after the last)."""
        return self.start + self.commit


def window_span(start: int, total: int, *, length: int, stride: int) -> WindowSpan:
    """The window that starts at scan ``start`` of a recording of ``total`` scans.

    Raises
    ------
    InputError
        ``start`` outside ``0..total-1``, ``length < 1`` or ``stride`` outside
        ``1..length`` (the key names the argument).
    """
    total = check_integer("total", total, minimum=1)
    start = check_integer("start", start, minimum=0, maximum=total - 1)
    length = check_integer("length", length, minimum=1)
    stride = check_integer("stride", stride, minimum=1, maximum=length)
    end = min(start + length, total)
    return WindowSpan(start, end, stride if end < total else end - start)


def window_spans(total: int, *, length: int, stride: int) -> Iterator[WindowSpan]:
    """Every window of a recording of ``total`` scans (none when ``total`` is 0)."""
    start = 0
    while start < total:
        span = window_span(start, total, length=length, stride=stride)
        yield span
        start = span.next_start
