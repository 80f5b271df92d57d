"""What a tracking method returns: its tracks and, if it estimates it, p(K | Z) over time.

The records every tracker of :mod:`mapassoc.trackers` returns and
:mod:`mapassoc.evaluation` scores; they sit in the data layer so that scoring needs no
tracker (``mapassoc.trackers.base`` re-exports both).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.data.io import TrackTable
from mapassoc.errors import InputError

__all__ = ["CountSeries", "TrackerOutput"]


@dataclass(frozen=True, eq=False)
class CountSeries:
    """A distribution over the number of targets K for each of a series of time spans.

    Parameters
    ----------
    start_times, end_times : ndarray, shape (m,)
        Span of each distribution (for the window estimator: its window), start <= end.
    probabilities : ndarray, shape (m, L)
        ``probabilities[i, K]`` is p(K | Z) of span i for K < L (K >= L has probability
        0); every row is non-negative and sums to 1 within 1e-6.
    """

    start_times: FloatArray
    end_times: FloatArray
    probabilities: FloatArray

    def __post_init__(self) -> None:
        start = np.asarray(self.start_times, dtype=float)
        end = np.asarray(self.end_times, dtype=float)
        p = np.asarray(self.probabilities, dtype=float)
        if start.ndim != 1 or end.shape != start.shape:
            raise InputError(
                f"start_times and end_times must be 1-D of equal length, got shapes "
                f"{start.shape} and {end.shape}"
            )
        if p.ndim != 2 or p.shape[0] != start.shape[0] or p.shape[1] < 1:
            raise InputError(
                f"probabilities must have shape ({start.shape[0]}, L) with L >= 1, got {p.shape}"
            )
        if np.any(end < start) or not np.all(np.isfinite(start)):
            raise InputError("every span needs finite start_time <= end_time")
        if np.any(p < 0) or not np.allclose(p.sum(axis=1), 1.0, atol=1e-6):
            raise InputError("every row of probabilities must be non-negative and sum to 1")
        for a in (start, end, p):
            a.setflags(write=False)
        object.__setattr__(self, "start_times", start)
        object.__setattr__(self, "end_times", end)
        object.__setattr__(self, "probabilities", p)

    @classmethod
    def from_rows(
        cls, start_times: Sequence[float], end_times: Sequence[float], rows: Sequence[FloatArray]
    ) -> CountSeries:
        """Build from rows of different lengths (padded with zeros on the right)."""
        width = max((len(r) for r in rows), default=1)
        p = np.zeros((len(rows), width))
        for i, r in enumerate(rows):
            p[i, : len(r)] = r
        return cls(np.asarray(start_times, float), np.asarray(end_times, float), p)

    @property
    def size(self) -> int:
        """Number of spans m."""
        return int(self.start_times.shape[0])


@dataclass(frozen=True, eq=False)
class TrackerOutput:
    """What a tracker returns.

    Parameters
    ----------
    tracks : TrackTable
        Estimated tracks, one row per track per scan it covers.
    seconds : float
        Wall time of ``track`` (>= 0).
    associations : mapping of int to mapping of int to int, optional
        Track id -> {scan index -> detection index}: the hard associations behind
        ``tracks``; ``None`` for soft-association methods (JPDA).
    counts : CountSeries, optional
        p(K | Z) over time, for methods that estimate it.
    details : object, optional
        The method's own result (for the window estimator its
        :class:`~mapassoc.estimator.pipeline.EstimateResult`).
    """

    tracks: TrackTable
    seconds: float
    associations: Mapping[int, Mapping[int, int]] | None = None
    counts: CountSeries | None = None
    details: object = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.tracks, TrackTable):
            raise InputError(f"tracks must be a TrackTable, got {type(self.tracks).__name__}")
        if not (isinstance(self.seconds, (int, float)) and math.isfinite(self.seconds)
                and self.seconds >= 0):
            raise InputError(f"seconds must be a finite number >= 0, got {self.seconds!r}")
