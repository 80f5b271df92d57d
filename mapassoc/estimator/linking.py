"""Fragment linking: join tracks that end to tracks that start soon after, where J rises.

A track that ends and one that starts within ``link_gap`` scans after it are candidates
for a join; the exact change of J of each join comes from re-filtering the later track
from the earlier one's state
(:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging`).  The best
set of joins (each end to at most one start) is an assignment
(:func:`scipy.optimize.linear_sum_assignment`); joins that share no track are applied
where the exact J of the joined track rises, and linking repeats until none does.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import linear_sum_assignment

from mapassoc.errors import check_stop
from mapassoc.estimator.boundaries import REFINEMENT_PHASE, rises
from mapassoc.estimator.objective import RecordingObjective, TrackPath

__all__ = ["link_fragments"]


def link_fragments(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    *,
    link_gap: int,
    refilter_detections: int,
    stop: Callable[[], bool] | None = None,
) -> int:
    """Join tracks that end to tracks that start within ``link_gap`` scans where J rises.

    Returns the number of joins made; ``tracks`` and ``values`` are updated in place.
    ``stop`` is polled before every round; when it returns True this raises
    :class:`~mapassoc.errors.StopRequested` (:data:`REFINEMENT_PHASE`).
    """
    made = 0
    while True:
        check_stop(stop, REFINEMENT_PHASE)
        pairs = _candidates(objective, tracks, values, link_gap, refilter_detections)
        if not pairs:
            return made
        joined_now = _apply(objective, tracks, values, _assigned(pairs))
        made += joined_now
        if joined_now == 0:
            return made


def _candidates(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    gap: int,
    refilter: int,
) -> list[tuple[int, int, float]]:
    """(earlier track, later track, proposed change of J) of every join that rises."""
    ids = sorted(tracks)
    by_first: dict[int, list[int]] = {}
    for tid in ids:
        by_first.setdefault(tracks[tid][0][0], []).append(tid)
    pairs: list[tuple[int, int, float]] = []
    for t1 in ids:
        last = tracks[t1][-1][0]
        later = [t2 for m in range(last + 1, last + gap + 1) for t2 in by_first.get(m, [])]
        if not later:
            continue
        path1 = tracks[t1]
        end = objective.trajectory(path1).state(len(path1) - 1)
        for t2 in later:
            reference = objective.trajectory(tracks[t2])
            joined = float(
                objective.continue_converging(end, reference, 0, max_detections=refilter)[0]
            )
            if rises(values[t1] + values[t2], joined):
                pairs.append((t1, t2, joined - values[t1] - values[t2]))
    return pairs


def _assigned(pairs: list[tuple[int, int, float]]) -> list[tuple[float, int, int]]:
    """The best assignment of ends to starts among ``pairs``: (gain, end, start), the
    largest gain first."""
    ends = sorted({p[0] for p in pairs})
    starts = sorted({p[1] for p in pairs})
    gain = np.full((len(ends), len(starts)), -1e300)
    for t1, t2, delta in pairs:
        gain[ends.index(t1), starts.index(t2)] = delta
    rows, cols = linear_sum_assignment(gain, maximize=True)
    return sorted(
        (
            (float(gain[r, c]), ends[r], starts[c])
            for r, c in zip(rows, cols, strict=True)
            if gain[r, c] > 0
        ),
        reverse=True,
    )


def _apply(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    chosen: list[tuple[float, int, int]],
) -> int:
    """Apply the joins of ``chosen`` that share no track and raise the exact J."""
    used: set[int] = set()
    joined_now = 0
    for _delta, t1, t2 in chosen:
        if t1 in used or t2 in used:
            continue  # a chain: its joins are not independent; the next round
        used.update((t1, t2))
        path = tracks[t1] + tracks[t2]
        value = objective.track_value(path)  # accepted on the exact value
        if not rises(values[t1] + values[t2], value):
            continue
        del tracks[t2]
        del values[t2]
        tracks[t1] = path
        values[t1] = value
        joined_now += 1
    return joined_now
