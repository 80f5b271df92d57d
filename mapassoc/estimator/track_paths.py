"""A track's path through a recording and the filtered states along it.

The types the recording objective (:mod:`mapassoc.estimator.objective`), its batched
re-filtering engine (:mod:`mapassoc.estimator.refiltering`) and the refinement pass
between them: a track's detections (:data:`TrackPath`), a batch of tracks' states at
one scan with their values so far (:class:`PathState`), and one track's whole filter run
(:class:`Trajectory`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray, IntArray

__all__ = ["TrackPath", "PathState", "Trajectory", "CONVERGED"]

TrackPath = tuple[tuple[int, int], ...]
"""A track's detections as ``((scan index, index in that scan), ...)`` in increasing scan
order, at most one per scan."""

CONVERGED = 1e-9
"""Relative agreement of two filtered states taken as equal by
:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging`."""


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One track's filter run (:meth:`~mapassoc.estimator.objective.RecordingObjective.trajectory`).

    Attributes
    ----------
    path : TrackPath
    means, covariances : tuple of ndarray
        Filtered state after each detection (its dimension may change once for a
        coordinated-turn track, at its conversion).
    initiated : ndarray of bool, shape (L,)
    first_time : float
    values : ndarray, shape (L,)
        Sum of the track's terms up to and including each detection.
    value : float
        ``v(tau)``: ``values[-1]`` plus the best ending after the last detection.
    """

    path: TrackPath
    means: tuple[FloatArray, ...]
    covariances: tuple[FloatArray, ...]
    initiated: NDArray[np.bool_]
    first_time: float
    values: FloatArray
    value: float

    def state(self, k: int) -> PathState:
        """The state after detection ``k`` as a batch of one."""
        return PathState(
            scan=self.path[k][0],
            means=self.means[k][None, :],
            covariances=self.covariances[k][None, :, :],
            initiated=bool(self.initiated[k]),
            first_time=np.array([self.first_time]),
            value=np.array([self.values[k]]),
        )


@dataclass(frozen=True, eq=False)
class PathState:
    """Filtered states of a batch of tracks at one scan, and their values so far.

    Attributes
    ----------
    scan : int
        Index of the scan (in the recording) the states are at.
    means : ndarray, shape (B, n)
    covariances : ndarray, shape (B, n, n)
    initiated : bool
        Whether the states are in the motion model's own space (False only for a
        coordinated-turn track before its conversion); one value for the batch.
    first_time : ndarray, shape (B,)
        Time of each track's first detection.
    value : ndarray, shape (B,)
        Sum of the track's terms up to and including this scan (``-inf``: impossible).
    """

    scan: int
    means: FloatArray
    covariances: FloatArray
    initiated: bool
    first_time: FloatArray
    value: FloatArray

    def __len__(self) -> int:
        return int(self.value.shape[0])

    def take(self, index: IntArray) -> PathState:
        """The tracks at ``index``."""
        return PathState(
            scan=self.scan,
            means=self.means[index],
            covariances=self.covariances[index],
            initiated=self.initiated,
            first_time=self.first_time[index],
            value=self.value[index],
        )
