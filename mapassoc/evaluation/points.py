"""Point sets over a run (:class:`TimedPoints`) and the checks the metrics share.

The per-time metrics (:mod:`mapassoc.evaluation.metrics`), the trajectory metrics
(:mod:`mapassoc.evaluation.tgospa`), CLEAR MOT (:mod:`mapassoc.evaluation.clear_mot`) and
the scoring of tracker outputs all take their runs as :class:`TimedPoints`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.errors import InputError
from mapassoc.validation import check_positive

__all__ = [
    "COST_POWER_RANGE",
    "TimedPoints",
    "check_cost_powers",
    "check_order",
    "check_runs",
    "float_array",
    "int_array",
    "readonly",
]


def readonly(array: NDArray) -> NDArray:
    """``array`` made read-only (in place) and returned."""
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class TimedPoints:
    """Point sets over a run: one row per (time, object).

    Parameters
    ----------
    times : ndarray, shape (N,)
        Time of each row.  Rows of one time must be contiguous (grouped by time); the groups
        need not be sorted.  Times are compared exactly (see the module docstring).
    ids : ndarray of int, shape (N,)
        Object (target or track) identifier of each row; unique within a time.  The metrics
        here are per-time set metrics and do not use identities beyond this check.
    positions : ndarray, shape (N, d)
        Position of each row, ``d >= 1``.  An empty run has shape ``(0, d)``.
    """

    times: NDArray[np.float64]
    ids: NDArray[np.int64]
    positions: NDArray[np.float64]

    def __post_init__(self) -> None:
        times = float_array("times", self.times)
        if times.ndim != 1:
            raise InputError(f"times must have shape (N,), got shape {times.shape}")
        num_rows = times.shape[0]
        ids = int_array("ids", self.ids)
        if ids.shape != (num_rows,):
            raise InputError(
                f"ids must have shape ({num_rows},) to match times, got shape {ids.shape}"
            )
        positions = float_array("positions", self.positions)
        if positions.ndim != 2 or positions.shape[0] != num_rows or positions.shape[1] < 1:
            raise InputError(
                f"positions must have shape ({num_rows}, d) with d >= 1 to match times, "
                f"got shape {positions.shape}"
            )
        if num_rows > 1:
            starts = np.flatnonzero(times[1:] != times[:-1]) + 1
            block_times = times[np.concatenate(([0], starts))]
            unique_block_times, counts = np.unique(block_times, return_counts=True)
            if np.any(counts > 1):
                split = unique_block_times[counts > 1].tolist()
                raise InputError(
                    f"rows must be grouped by time (each time one contiguous block), but times "
                    f"{split[:5]} appear in more than one block"
                )
            order = np.lexsort((ids, times))
            same = (times[order][1:] == times[order][:-1]) & (ids[order][1:] == ids[order][:-1])
            if np.any(same):
                first = order[1:][same][0]
                raise InputError(
                    f"ids must be unique within a time, but id {int(ids[first])} appears more "
                    f"than once at time {float(times[first])!r}"
                )
        object.__setattr__(self, "times", readonly(times))
        object.__setattr__(self, "ids", readonly(ids))
        object.__setattr__(self, "positions", readonly(positions))

    @classmethod
    def empty(cls, dim: int) -> TimedPoints:
        """Return a run without rows whose positions have dimension ``dim``."""
        if isinstance(dim, bool) or not isinstance(dim, int | np.integer) or dim < 1:
            raise InputError(f"dim must be an integer >= 1, got {dim!r}")
        return cls(
            times=np.zeros(0), ids=np.zeros(0, dtype=np.int64), positions=np.zeros((0, int(dim)))
        )

    @classmethod
    def from_unsorted(
        cls, *, times: ArrayLike, ids: ArrayLike, positions: ArrayLike
    ) -> TimedPoints:
        """Build from rows in any order by sorting them stably by time.

        Parameters
        ----------
        times : array_like, shape (N,)
        ids : array_like of int, shape (N,)
        positions : array_like, shape (N, d)
        """
        times_arr = float_array("times", times)
        if times_arr.ndim != 1:
            raise InputError(f"times must have shape (N,), got shape {times_arr.shape}")
        ids_arr = int_array("ids", ids)
        positions_arr = float_array("positions", positions)
        if ids_arr.shape != times_arr.shape or positions_arr.shape[:1] != times_arr.shape:
            raise InputError(
                f"times, ids and positions must have the same number of rows, got shapes "
                f"{times_arr.shape}, {ids_arr.shape} and {positions_arr.shape}"
            )
        order = np.argsort(times_arr, kind="stable")
        return cls(times=times_arr[order], ids=ids_arr[order], positions=positions_arr[order])

    @property
    def dim(self) -> int:
        """Position dimension d."""
        return int(self.positions.shape[1])

    @property
    def distinct_times(self) -> NDArray[np.float64]:
        """Sorted distinct times, shape (T,)."""
        return np.unique(self.times)

    def positions_at(self, time: float) -> NDArray[np.float64]:
        """Positions of the rows whose time equals ``time`` exactly, shape (k, d)."""
        return self.positions[self.times == time]

    def __repr__(self) -> str:
        return (
            f"TimedPoints(rows={self.times.shape[0]}, times={self.distinct_times.shape[0]}, "
            f"dim={self.dim})"
        )


def float_array(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """``value`` as a float array, refusing what is not numeric (the message names
    ``name``)."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a numeric array, got {value!r}") from None
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0].tolist()
        raise InputError(
            f"{name} must contain only finite values, got {arr[tuple(bad)]!r} at index {bad}"
        )
    return arr


def int_array(name: str, value: ArrayLike) -> NDArray[np.int64]:
    """``value`` as an int64 array, refusing what is not integer (the message names
    ``name``)."""
    arr = np.array(value)
    if arr.size == 0:
        return arr.astype(np.int64)
    if arr.dtype.kind not in "iu":
        raise InputError(f"{name} must be an integer array, got dtype {arr.dtype} ({value!r})")
    return arr.astype(np.int64)


def check_order(p: object) -> float:
    """The GOSPA/OSPA order ``p`` as a float, refusing values below 1 (the metrics are
    metrics only for p >= 1)."""
    order = check_positive("p", p)
    if order < 1.0:
        raise InputError(f"p must be >= 1 (GOSPA is a metric only for p >= 1), got {p!r}")
    return order


COST_POWER_RANGE = (1e-200, 1e200)
"""The range a cut-off or switching cost raised to the order, ``c^p``, must lie in: the
metrics add such costs over every target, track and time (up to 1e108 terms then stay
finite) and divide by them, so a ``c^p`` that overflows (``c = 1e300``, or ``p = 2000``
with ``c = 10``) or underflows would give inf, NaN or a division by zero."""


def check_cost_powers(p: float, **costs: float) -> None:
    """Each ``cost ** p`` within :data:`COST_POWER_RANGE` (``p`` and the costs checked
    already: ``p >= 1``, costs > 0); ``costs`` by argument name (``c=10.0``).

    Raises
    ------
    InputError
        Naming the argument, its value, ``p`` and what to do.
    """
    low, high = COST_POWER_RANGE
    for name, cost in costs.items():
        try:
            power = cost**p
        except OverflowError:
            power = math.inf
        if not low <= power <= high:
            what = "overflows" if power > high else "underflows"
            raise InputError(
                f"{name}^p = {cost!r}^{p!r} {what}: the metrics add and divide such costs and "
                f"need them between {low:g} and {high:g}; choose a {name} or an order p "
                "nearer 1"
            )


def check_runs(truth: TimedPoints, estimates: TimedPoints) -> None:
    """Refuse a truth and an estimate that are not both ``TimedPoints`` of the same position
    dimension."""
    for name, run in (("truth", truth), ("estimates", estimates)):
        if not isinstance(run, TimedPoints):
            raise InputError(f"{name} must be a TimedPoints, got {type(run).__name__}")
    if truth.dim != estimates.dim:
        raise InputError(
            f"truth and estimates must have the same position dimension, got truth "
            f"{truth.dim} and estimates {estimates.dim}"
        )
    if truth.times.shape[0] == 0 and estimates.times.shape[0] == 0:
        raise InputError("truth and estimates both have no rows: there is no time to evaluate at")
