"""One long recording in parallel: overlapping time segments, solved apart, stitched.

The sliding-window estimator is sequential: each window starts from the tracks the
previous one committed.  To use several cores on one recording, cut it into ``K``
segments of consecutive scans that overlap by ``overlap`` scans (at least a window),
run the estimator on each segment independently (:func:`solve_segment`, any executor),
and stitch the results (:func:`stitch_segments`):

* Segment ``i`` *owns* the scans from ``cut[i]`` to ``cut[i + 1]``, the cuts lying in the
  middle of each overlap: every segment decides the scans where it has at least
  ``overlap // 2`` scans of context on both sides (its first ``overlap // 2`` scans
  warm it up: tracks already present at a segment's start are born there, and the
  end of a segment commits with less look-ahead).
* Each track keeps, of each segment, the detections of the scans that segment owns.
* A track of segment ``i - 1`` and a track of segment ``i`` are the same target when
  they share detections in the overlap: the pairs are matched one to one, maximising
  the number of shared detections (an assignment problem; pairs sharing none are never
  matched).  Matched pieces chain into one track; the others start or end at the cut.
* The stitched tracks are RTS-smoothed over all their detections, as in a sequential
  run; window reports are those of the windows each segment owns.

A detection is used by at most one stitched track (the owned ranges are disjoint), so
the result is a feasible track set.  It is not the sequential run's: a segment starts
without the tracks the sequential run would carry into it, and the two may commit
differently near the cuts.  ``mapassoc bench-reprocess`` measures both the speed-up and
the accuracy against the sequential run.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from mapassoc.data.config import Config, check_config
from mapassoc.data.scans import Scan, check_scans
from mapassoc.errors import InputError
from mapassoc.estimator.pipeline import EstimateResult, WindowEstimator, WindowReport, WindowTally
from mapassoc.estimator.refinement import refine_track_rows
from mapassoc.filtering.smoothing import smooth_tracks
from mapassoc.validation import check_instance

__all__ = [
    "Segment",
    "SegmentResult",
    "plan_segments",
    "solve_segment",
    "stitch_segments",
    "run_segmented",
]


@dataclass(frozen=True)
class Segment:
    """The scans one segment runs over and the scans it owns (half-open index ranges).

    Attributes
    ----------
    index : int
    first, stop : int
        The segment runs over ``scans[first:stop]``.
    own_first, own_stop : int
        It decides ``scans[own_first:own_stop]`` (``first <= own_first < own_stop <= stop``).
    """

    index: int
    first: int
    stop: int
    own_first: int
    own_stop: int


@dataclass(frozen=True)
class SegmentResult:
    """What one segment's run leaves for the stitching (small: it crosses processes).

    Attributes
    ----------
    segment : Segment
    track_rows : dict of int to tuple of int
        Detection ids of each of the segment's tracks, in scan order.
    windows : tuple of WindowReport
        The segment's windows (scan indices relative to ``segment.first``).
    seconds : float
        Wall time of the segment's run.
    """

    segment: Segment
    track_rows: dict[int, tuple[int, ...]]
    windows: tuple[WindowReport, ...]
    seconds: float


def plan_segments(total_scans: int, *, segments: int, overlap: int) -> list[Segment]:
    """Cut ``total_scans`` scans into ``segments`` overlapping segments of equal share.

    Parameters
    ----------
    total_scans : int
        Scans of the recording, >= 1.
    segments : int
        Number of segments, >= 1 (1: the whole recording, no stitching).
    overlap : int
        Scans two neighbouring segments share, >= 2; every owned share must hold at least
        ``overlap`` scans.

    Raises
    ------
    InputError
        A bad number, or segments too short for the overlap.
    """
    for name, value, least in (
        ("total_scans", total_scans, 1),
        ("segments", segments, 1),
        ("overlap", overlap, 2),
    ):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < least:
            raise InputError(f"{name} must be an integer >= {least}, got {value!r}")
    if segments == 1:
        return [Segment(0, 0, total_scans, 0, total_scans)]
    share = total_scans / segments
    if share < overlap:
        raise InputError(
            f"{segments} segments of {total_scans} scans own {share:.1f} scans each, fewer "
            f"than the overlap of {overlap}; use at most {max(1, total_scans // overlap)} "
            "segments or a smaller overlap"
        )
    bounds = [round(i * share) for i in range(segments + 1)]
    half = overlap // 2
    cuts = [0, *(b - half for b in bounds[1:-1]), total_scans]
    plan = []
    for i in range(segments):
        first = max(0, bounds[i] - overlap) if i > 0 else 0
        stop = bounds[i + 1] if i < segments - 1 else total_scans
        plan.append(Segment(i, first, stop, cuts[i], cuts[i + 1]))
    return plan


def solve_segment(
    config: Config,
    scans: Sequence[Scan],
    segment: Segment,
    *,
    stop: Callable[[], bool] | None = None,
) -> SegmentResult | None:
    """Run the estimator over ``scans[segment.first:segment.stop]`` (picklable arguments).

    Parameters
    ----------
    config : Config
    scans : sequence of Scan
        The segment's scans only (``scans[segment.first:segment.stop]``), so that a process
        pool ships no more than it needs.
    segment : Segment
    stop : callable, optional
        Polled at every window boundary; True abandons the segment.

    Returns
    -------
    SegmentResult, or None when ``stop`` abandoned the segment.
    """
    if len(scans) != segment.stop - segment.first:
        raise InputError(
            f"segment {segment.index} runs over {segment.stop - segment.first} scans, got "
            f"{len(scans)}"
        )
    started = time.perf_counter()
    estimator = WindowEstimator(config=config)
    state = estimator.start(scans)
    reports = []
    while not state.done:
        if stop is not None and stop():
            return None
        reports.append(estimator.step(scans, state))
    result = estimator.finish(scans, state, windows=reports, refine=False)
    return SegmentResult(
        segment=segment,
        track_rows=dict(result.track_rows),
        windows=result.windows,
        seconds=time.perf_counter() - started,
    )


def _match(
    earlier: dict[int, set[int]], later: dict[int, set[int]]
) -> list[tuple[int, int]]:
    """One-to-one pairs (earlier id, later id) maximising shared detections (> 0 each)."""
    a_ids, b_ids = sorted(earlier), sorted(later)
    if not a_ids or not b_ids:
        return []
    shared = np.array(
        [[len(earlier[a] & later[b]) for b in b_ids] for a in a_ids], dtype=float
    )
    rows, cols = linear_sum_assignment(shared, maximize=True)
    return [(a_ids[r], b_ids[c]) for r, c in zip(rows, cols, strict=True) if shared[r, c] > 0]


def _checked_results(
    scans: Sequence[Scan], results: Sequence[SegmentResult]
) -> list[SegmentResult]:
    """``results`` in segment order, refused unless they are every segment of one plan
    covering ``scans``."""
    ordered = sorted(results, key=lambda r: r.segment.index)
    if not ordered or [r.segment.index for r in ordered] != list(range(len(ordered))):
        raise InputError("results must hold every segment of one plan, from index 0")
    if ordered[0].segment.own_first != 0 or ordered[-1].segment.own_stop != len(scans):
        raise InputError(f"the segments do not cover the {len(scans)} scans")
    return ordered


@dataclass(frozen=True)
class _Places:
    """Where every detection id of the recording is: (scan index, index in the scan)."""

    scan_of: dict[int, tuple[int, int]]

    @classmethod
    def of(cls, scans: Sequence[Scan]) -> _Places:
        return cls(
            {int(row): (k, j) for k, scan in enumerate(scans) for j, row in enumerate(scan.rows)}
        )

    def where(self, row: int) -> tuple[int, int]:
        """(scan index, index in the scan) of detection id ``row``."""
        try:
            return self.scan_of[row]
        except KeyError:
            raise InputError(f"detection id {row} of a segment is in no scan") from None


class _Chains:
    """Chains of (segment index, track id) pieces: a union-find keyed by the pair."""

    def __init__(self, results: Sequence[SegmentResult]) -> None:
        self._parent: dict[tuple[int, int], tuple[int, int]] = {}
        for result in results:
            for tid in result.track_rows:
                self._parent[(result.segment.index, tid)] = (result.segment.index, tid)

    def find(self, node: tuple[int, int]) -> tuple[int, int]:
        """The representative of the chain holding ``node``."""
        parent = self._parent
        while parent[node] != node:
            parent[node] = parent[parent[node]]
            node = parent[node]
        return node

    def join(self, earlier: tuple[int, int], later: tuple[int, int]) -> None:
        """Put ``later``'s chain after ``earlier``'s (one chain, represented by earlier's)."""
        root = self.find(earlier)
        self._parent[self.find(later)] = root


def _link_overlaps(results: Sequence[SegmentResult], places: _Places) -> _Chains:
    """Chain the tracks of neighbouring segments that share detections in their overlap
    (matched one to one by :func:`_match`)."""
    chains = _Chains(results)
    for before, after in zip(results, results[1:], strict=False):
        lo, hi = after.segment.first, before.segment.stop  # the overlap's scans

        def in_overlap(rows: tuple[int, ...], lo: int = lo, hi: int = hi) -> set[int]:
            return {r for r in rows if lo <= places.where(r)[0] < hi}

        earlier = {t: in_overlap(rows) for t, rows in before.track_rows.items()}
        later = {t: in_overlap(rows) for t, rows in after.track_rows.items()}
        for a, b in _match(earlier, later):
            chains.join((before.segment.index, a), (after.segment.index, b))
    return chains


def _stitched_associations(
    results: Sequence[SegmentResult], places: _Places, chains: _Chains
) -> dict[int, dict[int, int]]:
    """Track id -> {scan index: index in the scan} of the stitched tracks: each chain keeps,
    of each segment, the detections of the scans that segment owns; tracks are numbered
    1, 2, ... in order of their first detection."""
    pieces: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for result in results:
        seg = result.segment
        for tid, rows in result.track_rows.items():
            owned = [
                places.where(r) for r in rows if seg.own_first <= places.where(r)[0] < seg.own_stop
            ]
            if owned:
                pieces.setdefault(chains.find((seg.index, tid)), []).extend(owned)
    ordered = sorted(pieces.values(), key=lambda p: min(p))
    return {tid: dict(sorted(p)) for tid, p in enumerate(ordered, start=1)}


def _owned_windows(results: Sequence[SegmentResult]) -> tuple[list[WindowReport], WindowTally]:
    """The windows each segment owns (those starting in its owned scans), renumbered and
    moved to the recording's scan indices, and their tally (``seconds``: the sum of the
    segments' wall times)."""
    windows: list[WindowReport] = []
    tally = WindowTally()
    for result in results:
        seg = result.segment
        for report in result.windows:
            first = report.first_scan + seg.first
            if not seg.own_first <= first < seg.own_stop:
                continue
            owned_commit = min(report.committed_scans, seg.own_stop - first)
            moved = dataclasses.replace(
                report,
                window=len(windows),
                first_scan=first,
                last_scan=report.last_scan + seg.first,
                committed_scans=owned_commit,
            )
            windows.append(moved)
            tally.add(moved)
    tally.seconds = math.fsum(r.seconds for r in results)
    return windows, tally


def stitch_segments(
    scans: Sequence[Scan],
    results: Sequence[SegmentResult],
    config: Config,
    *,
    stop: Callable[[], bool] | None = None,
) -> EstimateResult:
    """Join segment runs into one result (module docstring).

    Parameters
    ----------
    scans : sequence of Scan
        The whole recording.
    results : sequence of SegmentResult
        One per segment of a plan over ``len(scans)`` scans, in segment order.
    config : Config
    stop : callable, optional
        Polled between the units of the stitched set's refinement
        (:func:`~mapassoc.estimator.refinement.refine_track_rows`), which raises
        StopRequested when it returns True.

    Returns
    -------
    EstimateResult
        Tracks numbered 1, 2, ... in order of their first detection; the windows each
        segment owns, renumbered; ``seconds`` the sum of the segments' wall times.
    """
    results = _checked_results(scans, results)
    places = _Places.of(scans)
    chains = _link_overlaps(results, places)
    associations = _stitched_associations(results, places, chains)
    track_rows = {
        tid: tuple(int(scans[k].rows[j]) for k, j in sorted(a.items()))
        for tid, a in associations.items()
    }
    refined = None
    if config.estimator.refinement.passes > 0 and track_rows:
        refined = refine_track_rows(config, scans, track_rows, stop=stop)
        track_rows = refined.track_rows
        associations = {
            tid: dict(places.where(r) for r in rows) for tid, rows in track_rows.items()
        }
    tracks = smooth_tracks(scans, associations, config)
    if refined is not None and refined.confidence is not None:
        tracks = tracks.with_existence(refined.confidence.existence)
    windows, tally = _owned_windows(results)
    return EstimateResult(
        tracks=tracks,
        windows=tuple(windows),
        track_rows=track_rows,
        seconds=tally.seconds,
        num_scans=len(scans),
        tally=tally,
        refinement=None if refined is None else refined.report,
        confidence=None if refined is None else refined.confidence,
        dropped=() if refined is None else refined.dropped,
    )


def run_segmented(
    config: Config,
    scans: Sequence[Scan],
    *,
    segments: int,
    overlap: int | None = None,
    executor: concurrent.futures.Executor | None = None,
) -> EstimateResult:
    """Estimate tracks over ``scans`` in ``segments`` overlapping segments, then stitch.

    Parameters
    ----------
    config : Config
    scans : sequence of Scan
        Sorted by (time, sensor).
    segments : int
        Number of segments (>= 1); with ``executor`` a process pool, as many as its
        workers use every core.
    overlap : int, optional
        Scans shared by neighbouring segments, at least the window length (default four
        windows: two of warm-up and two of look-ahead around each cut).
    executor : concurrent.futures.Executor, optional
        Where the segments run (for example a ``ProcessPoolExecutor``); default: here,
        one after the other.

    Raises
    ------
    InputError
        ``config`` not a :class:`Config` (a path is loaded with ``load_config`` first),
        ``scans`` not a run of scans (:func:`mapassoc.data.scans.check_scans`), or a bad
        ``segments``, ``overlap`` or ``executor``.
    """
    config = check_config(config)
    scans = check_scans(scans, config.sensors)
    if executor is not None:
        check_instance("executor", executor, concurrent.futures.Executor)
    window = config.estimator.windows.window_length
    if overlap is None:
        overlap = 4 * window
    if isinstance(overlap, bool) or not isinstance(overlap, int) or overlap < window:
        raise InputError(
            f"overlap must be an integer >= the window length {window}, got {overlap!r}"
        )
    plan = plan_segments(len(scans), segments=segments, overlap=max(overlap, 2))
    WindowEstimator(config=config).start(scans)  # every check of the whole run, up front
    if executor is None:
        solved = [solve_segment(config, scans[s.first : s.stop], s) for s in plan]
    else:
        futures = [
            executor.submit(solve_segment, config, scans[s.first : s.stop], s) for s in plan
        ]
        solved = [future.result() for future in futures]
    return stitch_segments(scans, [r for r in solved if r is not None], config)
