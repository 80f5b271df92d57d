"""Refinement of a whole recording's track set: revise past decisions where J rises.

The forward pass (:class:`~mapassoc.estimator.pipeline.WindowEstimator`) decides like an
online tracker: each window commits its oldest scans for good.  Offline, every
decision can be revisited.  This module climbs the recording objective
J(omega) = log p(omega | Z) + const of :mod:`mapassoc.estimator.objective` from the
forward pass's track set with two exact moves, each accepted only when J rises:

**Window re-solve with both boundaries** (:meth:`Refiner.resolve_window`).  The
associations of the scans ``a..b-1`` are freed.  A track with detections before ``a``
enters the window as a carried track (its filtered state at scan ``a - 1``, its misses
up to there scored, and ending before the window still open: it may have ended at any
gap since its last detection).  A track with detections after ``b - 1``, or starting
within ``lookahead`` scans after it, becomes an **anchor**: a track piece that a window
hypothesis alive at the window's last scan may join.  The join's score is the exact
change of J: the anchor's detections re-filtered from the joining hypothesis' state
(:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_paths`, batched over
every joining hypothesis), minus the anchor's value as a track of its own, whose
first-detection term the join replaces.  A hypothesis that joins nothing and is alive at
the window's end gets its best ending (``tail``).  The window's hypothesis trees are
grown as in the forward pass (carried and new trees, the same scoring and gating), but
pruned at the refinement's own, wider ``prune_log_ratio``
(``RefinementSettings.prune_log_ratio``: a re-solve that keeps only what the
forward pass kept can mostly confirm it; the new trees' bound pruning allows for the most
a join can add; the long windows at ``long_prune_log_ratio``), and one
packing problem (detections at most once, carried tracks exactly once, anchors at most
once; built by :func:`~mapassoc.estimator.window_program.packing_problem`, the forward
pass's builder) is solved for its best set with K free by the forward pass's window
solver (:meth:`~mapassoc.estimator.cluster_solving.ClusterSolver.best_set`), with its
deadline (``SearchSettings.program_time_limit``) and statuses (``exact``, ``bounded``,
``time_limit``, counted in :class:`RefinementReport`).  Because every selected item's
score is its exact change of J, the program's optimum is the best J over the window's
kept hypotheses; the new track set is valued again track by track and replaces the old
one only when J rises.
This also lets a track that started late pick up the detections it was missed at.

**Dropping** a track whose value is negative (J rises by minus its value: its detections
are likelier false alarms, which windows shorter than the track cannot see whole).

**Fragment linking** (:mod:`mapassoc.estimator.linking`).  A track that ends and one that
starts within ``link_gap`` scans after it are candidates for a join; the exact change of
J of each join comes from re-filtering the later track from the earlier one's state.
The best set of joins (each end to at most one start) is an assignment
(:func:`scipy.optimize.linear_sum_assignment`); joins that share no track are applied
where J rises, and linking repeats until none does.

Sweeps go over the recording's windows of ``window_length`` scans (every ``stride``
scans), then over windows twice as long, then over single scans, forward, then all three
backward, re-solving only windows near a change, until a sweep of each length changes
nothing or ``passes`` sweeps are done. The long windows start the targets that no short
window found worth a track; the single-scan windows, run at the scans where the per-tree
cap cut a longer window's trees, are exact coordinate-ascent steps whose trees the cap
never cuts, which closely spaced targets need. Every move is accepted only when the exact
J of the changed tracks rises, so J never decreases; with each re-solve's deadline
(``SearchSettings.program_time_limit``) and the pass budget the work is bounded, and with
every re-solve's status ``exact`` the result is a function of the input alone.

The confidence pass (:mod:`mapassoc.estimator.confidence`) takes the same windows'
marginals from the same window solver.

Proposals re-filter at most ``refilter_detections`` of an anchor's detections (the
acceptance re-filters all of them), and the joins to one anchor are pruned like the
nodes of one tree (the refinement's ``prune_log_ratio`` below the best after the
anchor's first detection): the window's program is exact over the hypotheses and joins it keeps.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from mapassoc.data.config import Config, check_config
from mapassoc.data.scans import Scan
from mapassoc.data.settings import RefinementSettings
from mapassoc.errors import InputError, check_stop
from mapassoc.estimator.boundaries import REFINEMENT_PHASE, WindowBoundaries, rises
from mapassoc.estimator.cluster_solving import CLUSTER_STATUSES, ClusterSolver, ClusterStatus
from mapassoc.estimator.confidence import (
    ASSOCIATION_FLOOR,
    CONFIDENCE_PHASE,
    ConfidencePass,
    TrackConfidence,
)
from mapassoc.estimator.group_moves import regroup_tracks
from mapassoc.estimator.hypotheses import HypothesisGenerator
from mapassoc.estimator.identity_moves import identity_moves
from mapassoc.estimator.linking import link_fragments
from mapassoc.estimator.objective import RecordingObjective, TrackPath, rows_from_paths

__all__ = [
    "RefinementSettings",
    "RefinementReport",
    "TrackConfidence",
    "ASSOCIATION_FLOOR",
    "Refiner",
    "RefinedTracks",
    "refine_track_rows",
    "track_confidence",
    "REFINEMENT_PHASE",
    "CONFIDENCE_PHASE",
]


def _no_statuses() -> dict[str, int]:
    return {status.value: 0 for status in CLUSTER_STATUSES}


@dataclass
class RefinementReport:
    """What the refinement did (``summary.json``'s ``refinement``).

    Attributes
    ----------
    objective_forward : float
        J of the forward pass's track set.
    objective_after_pass : list of float
        J after each sweep (window re-solves, then fragment linking; with
        ``identity_moves``, the moves after each round of sweeps of every window length,
        where the sweeps have converged and at the last pass); non-decreasing.
    windows_solved, windows_improved : int
    windows_time_limited : int
        Re-solves whose window solve the deadline cut short (status ``time_limit``; its
        incumbent was used only where it raised J).
    status_counts : dict of str to int
        Re-solves per status of their window solve (``exact``, ``bounded``,
        ``time_limit``), as the forward pass counts its windows.
    links : int
        Fragment joins made.
    switches, splits, extensions, merges : int
        Identity moves made (:mod:`mapassoc.estimator.identity_moves`; 0 unless
        ``identity_moves`` is set): tail exchanges, cuts, free detections taken after a
        track's end or before its start, and joins over any gap.
    regroups : int
        Group re-solves made (:mod:`mapassoc.estimator.group_moves`; 0 when
        ``group_moves`` is off): closely spaced tracks re-tracked together.
    stopped : str
        Why the sweeps ended: ``"converged"`` (a sweep of every window length changed
        nothing: no move the refinement makes raises J) or ``"pass_limit"`` (``passes``
        sweeps were made and the last one still changed the set).
    dropped : int
        Tracks removed because their value was negative (their detections are likelier
        false alarms).
    seconds : float
    """

    objective_forward: float = 0.0
    objective_after_pass: list[float] = field(default_factory=list)
    windows_solved: int = 0
    windows_improved: int = 0
    windows_time_limited: int = 0
    status_counts: dict[str, int] = field(default_factory=_no_statuses)
    links: int = 0
    switches: int = 0
    splits: int = 0
    extensions: int = 0
    merges: int = 0
    regroups: int = 0
    dropped: int = 0
    stopped: str = "converged"
    seconds: float = 0.0

    @property
    def objective(self) -> float:
        """J of the refined track set."""
        if self.objective_after_pass:
            return self.objective_after_pass[-1]
        return self.objective_forward

    def to_json(self, *, timings: bool = True) -> dict[str, object]:
        out: dict[str, object] = {
            "objective_forward": self.objective_forward,
            "objective_after_pass": list(self.objective_after_pass),
            "objective": self.objective,
            "passes": len(self.objective_after_pass),
            "windows_solved": self.windows_solved,
            "windows_improved": self.windows_improved,
            "windows_time_limited": self.windows_time_limited,
            "window_statuses": dict(self.status_counts),
            "links": self.links,
            "switches": self.switches,
            "splits": self.splits,
            "extensions": self.extensions,
            "merges": self.merges,
            "regroups": self.regroups,
            "tracks_dropped": self.dropped,
            "stopped": self.stopped,
        }
        if timings:
            out["seconds"] = self.seconds
        return out


class Refiner:
    """Climbs J(omega) of a whole recording from a given track set (module docstring).

    Parameters
    ----------
    config : Config
        The model and the estimator settings the forward pass used.
    scans : sequence of Scan
        The whole recording.
    settings : RefinementSettings
    objective : RecordingObjective, optional
        Built from ``config`` and ``scans`` when not given.

    Raises
    ------
    InputError
        The configuration's ``solver`` names no integer-program backend.
    """

    def __init__(
        self,
        *,
        config: Config,
        scans: Sequence[Scan],
        settings: RefinementSettings,
        objective: RecordingObjective | None = None,
    ) -> None:
        self.config = check_config(config)
        self.scans = tuple(scans)
        self.settings = settings
        est = config.estimator
        self.window_length = settings.window_length or est.window_length
        self.long_window_length = (
            2 * self.window_length
            if settings.long_window_length is None
            else settings.long_window_length
        )
        self.stride = settings.stride or max(1, (self.window_length + 1) // 2)
        self.objective = objective or RecordingObjective(config=config, scans=self.scans)
        self.generator, self.long_generator = self._generators()
        self.window_solver = ClusterSolver.from_settings(est.search)
        self.time_limit = est.search.program_time_limit  # each re-solve's window solve
        self._capped_scans: set[int] = set()  # scans of re-solves whose trees the cap cut
        gain_bounds = np.array(
            [
                max(0.0, self.generator.continuation_gain_bound(config.sensors[s.sensor]))
                for s in self.scans
            ]
        )
        self.boundaries = WindowBoundaries(
            objective=self.objective,
            scans=self.scans,
            refilter_detections=settings.refilter_detections,
            gain_bounds=gain_bounds,
        )

    def _generators(self) -> tuple[HypothesisGenerator, HypothesisGenerator]:
        """The trees' generators of the short and of the long windows (their widths)."""
        config, settings = self.config, self.settings
        est = config.estimator
        long_ratio = (
            settings.prune_log_ratio
            if settings.long_prune_log_ratio is None
            else settings.long_prune_log_ratio
        )
        short, long = (
            HypothesisGenerator(
                motion=config.motion,
                sensors=config.sensors,
                birth=config.birth,
                gate_probability=est.gate_probability,
                max_hypotheses_per_tree=est.max_hypotheses_per_tree,
                prune_log_ratio=ratio,
            )
            for ratio in (settings.prune_log_ratio, long_ratio)
        )
        return short, long

    # -- the whole refinement ------------------------------------------------------------
    def refine(
        self,
        tracks: Mapping[int, TrackPath],
        *,
        next_id: int | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> tuple[dict[int, TrackPath], RefinementReport]:
        """Refine ``tracks`` (track id -> path) and return the new set and a report.

        Track ids are kept where a track keeps its first detection before a re-solved
        window; new pieces get ids from ``next_id`` on (default: one past the largest).
        ``stop`` is polled before every re-solve and every linking round; when it returns
        True the refinement raises :class:`~mapassoc.errors.StopRequested`
        (:data:`REFINEMENT_PHASE`), leaving ``tracks`` as they were.
        """
        t0 = time.perf_counter()
        current = {int(tid): tuple(path) for tid, path in tracks.items() if path}
        values = self._exact_values(current)
        self._next_id = next_id if next_id is not None else max(current, default=0) + 1
        self._capped_scans.clear()
        report = RefinementReport(objective_forward=float(sum(values.values())))
        lengths = [self.window_length]
        if self.long_window_length > self.window_length:
            lengths.append(self.long_window_length)
        if self.settings.scan_windows and self.window_length > 1:
            lengths.append(1)
        lengths = list(dict.fromkeys(min(n, len(self.scans)) for n in lengths))
        starts = {n: self.window_starts(n) for n in lengths}
        dirty = {n: set(starts[n]) for n in lengths}
        unchanged = 0
        report.stopped = "pass_limit" if self.settings.passes > 0 else "converged"
        for sweep in range(self.settings.passes):
            N = lengths[sweep % len(lengths)]
            order = starts[N] if (sweep // len(lengths)) % 2 == 0 else starts[N][::-1]
            changed = self._sweep(current, values, N, order, starts, dirty, report, stop)
            unchanged = 0 if changed else unchanged + 1
            last = sweep == self.settings.passes - 1
            round_done = (sweep + 1) % len(lengths) == 0  # a sweep of every window length
            if (unchanged >= len(lengths) or round_done or last) and self._identity_moves(
                current, values, report, stop
            ):
                unchanged = 0  # the moves changed the set: every window may pay again
                dirty = {n: set(starts[n]) for n in lengths}
            values = self._exact_values(current)
            report.objective_after_pass.append(float(sum(values.values())))
            if unchanged >= len(lengths):
                report.stopped = "converged"
                break  # a sweep of every window length changed nothing
        tracks_out = dict(sorted(current.items()))
        report.seconds = time.perf_counter() - t0
        return tracks_out, report

    def _sweep(
        self,
        current: dict[int, TrackPath],
        values: dict[int, float],
        N: int,
        order: Sequence[int],
        starts: Mapping[int, Sequence[int]],
        dirty: dict[int, set[int]],
        report: RefinementReport,
        stop: Callable[[], bool] | None,
    ) -> bool:
        """One sweep of the windows of ``N`` scans that are ``dirty`` (near a change), in
        ``order``, then fragment linking and dropping; whether anything changed."""
        if N == 1 < min(self.window_length, len(self.scans)):
            # Single scans only where a longer window's trees were cut by the cap:
            # elsewhere those windows' programs held every one-scan change already.
            dirty[N] &= self._capped_scans
        changed = False
        for a in order:
            if a not in dirty[N]:
                continue
            check_stop(stop, REFINEMENT_PHASE)
            dirty[N].discard(a)
            report.windows_solved += 1
            improved, status = self.resolve_window(current, values, a, a + N)
            report.status_counts[status.value] += 1
            report.windows_time_limited += int(status is ClusterStatus.TIME_LIMIT)
            if improved:
                report.windows_improved += 1
                changed = True
                for n in dirty:  # windows of every length near the change
                    low, high = a - 2 * n, a + N + n
                    dirty[n].update(s for s in starts[n] if low <= s <= high)
                dirty[N].discard(a)
        if self.settings.link_gap > 0:
            links = self.link_fragments(current, values, stop=stop)
            report.links += links
            changed = changed or links > 0
        # A track worth less than its detections as false alarms (v < 0, which
        # windows shorter than the track cannot see whole) goes: J rises by -v.
        dropped = [tid for tid, value in values.items() if rises(value, 0.0)]
        for tid in dropped:
            del current[tid]
            del values[tid]
        report.dropped += len(dropped)
        return changed or bool(dropped)

    def _identity_moves(
        self,
        current: dict[int, TrackPath],
        values: dict[int, float],
        report: RefinementReport,
        stop: Callable[[], bool] | None,
    ) -> bool:
        """The identity moves over the whole recording (when ``identity_moves`` is set),
        then the group re-solves (when ``group_moves`` is); whether any was made."""
        made = 0
        if self.settings.identity_moves:
            counts, self._next_id = identity_moves(
                self.objective,
                current,
                values,
                next_id=self._next_id,
                refilter_detections=self.settings.refilter_detections,
                stop=stop,
            )
            report.switches += counts.switches
            report.splits += counts.splits
            report.extensions += counts.extensions
            report.merges += counts.merges
            made += counts.total
        if self.settings.group_moves:
            regroups = regroup_tracks(self.objective, current, values, stop=stop)
            report.regroups += regroups
            made += regroups
        return made > 0

    def window_starts(self, length: int | None = None) -> list[int]:
        """First scans of the re-solved windows of ``length`` scans (default
        ``window_length``): every ``(length + 1) // 2`` scans (``stride`` for the default
        length), the last window ending at the recording's last scan."""
        M = len(self.scans)
        N = min(length or self.window_length, M)
        step = self.stride if N == min(self.window_length, M) else max(1, (N + 1) // 2)
        starts = list(range(0, M - N + 1, step))
        if starts[-1] != M - N:
            starts.append(M - N)
        return starts

    def _exact_values(self, tracks: Mapping[int, TrackPath]) -> dict[int, float]:
        """Every track's value from its whole filter run (no convergence shortcut)."""
        return {tid: self.objective.track_value(path) for tid, path in tracks.items()}

    # -- window re-solve -------------------------------------------------------------------
    def resolve_window(
        self, tracks: dict[int, TrackPath], values: dict[int, float], a: int, b: int
    ) -> tuple[bool, ClusterStatus]:
        """Re-solve scans ``a..b-1`` with both boundaries; update ``tracks`` in place.

        Returns
        -------
        improved : bool
            Whether J rose (and ``tracks``, ``values`` were changed).
        status : ClusterStatus
            The window solve's status (``time_limit`` when the deadline cut it short).
        """
        obj = self.objective
        if not 0 <= a < b <= len(self.scans):
            raise InputError(f"window {a}..{b - 1} is not within the recording's scans")
        generator = self.long_generator if b - a > self.window_length else self.generator
        hyps, carried, anchors, touched = self.boundaries.hypotheses(
            tracks, values, a, b, generator
        )
        if hyps.nodes_capped > 0:
            self._capped_scans.update(range(a, b))
        problem, joins = self.boundaries.program(
            hyps, carried, anchors, a, prune_log_ratio=generator.prune_log_ratio
        )
        if problem.num_hypotheses == 0:
            return False, ClusterStatus.EXACT
        solved = self.window_solver.best_set(problem, time.perf_counter() + self.time_limit)
        if solved.selection is None:
            return False, solved.status
        pieces = self.boundaries.decode(hyps, solved.selection, joins, carried, anchors, a)
        if {path for _, path in pieces} == {tracks[tid] for tid in touched}:
            return False, solved.status  # the window's best set is the current one
        # Accepted on exact values: every changed track's whole filter run.
        new_values = [obj.track_value(path) for _, path in pieces]
        old = sum(values[tid] for tid in touched)
        if not rises(old, float(sum(new_values))):
            return False, solved.status
        for tid in touched:
            del tracks[tid]
            del values[tid]
        for (kept_id, path), value in zip(pieces, new_values, strict=True):
            if kept_id is None:
                new_id = self._next_id
                self._next_id += 1
            else:
                new_id = kept_id
            tracks[new_id] = path
            values[new_id] = value
        return True, solved.status

    # -- fragment linking and confidence ---------------------------------------------------
    def link_fragments(
        self,
        tracks: dict[int, TrackPath],
        values: dict[int, float],
        *,
        stop: Callable[[], bool] | None = None,
    ) -> int:
        """Join tracks that end to tracks that start within ``link_gap`` scans where J
        rises (:func:`~mapassoc.estimator.linking.link_fragments`); returns the joins
        made, ``tracks`` and ``values`` updated in place."""
        return link_fragments(
            self.objective,
            tracks,
            values,
            link_gap=self.settings.link_gap,
            refilter_detections=self.settings.refilter_detections,
            stop=stop,
        )

    def confidence(
        self, tracks: Mapping[int, TrackPath], *, stop: Callable[[], bool] | None = None
    ) -> TrackConfidence:
        """Existence and association probabilities of a (refined) track set, in windows
        of ``window_length`` scans (:meth:`~mapassoc.estimator.confidence.ConfidencePass.run`).
        ``stop`` is polled before every window (:data:`CONFIDENCE_PHASE`)."""
        return ConfidencePass(
            boundaries=self.boundaries,
            generator=self.generator,
            solver=self.window_solver,
            window_length=self.window_length,
            values=self._exact_values,
        ).run(tracks, stop=stop)


@dataclass(frozen=True, eq=False)
class RefinedTracks:
    """What :func:`refine_track_rows` returns.

    Attributes
    ----------
    track_rows : dict of int to tuple of int
        The refined tracks' detection ids in scan order, by track id (those below
        ``min_existence`` left out).
    report : RefinementReport
    confidence : TrackConfidence or None
        Existence and association probabilities of the refined set (before the
        ``min_existence`` cut); None when not asked for.
    dropped : tuple of int
        Ids of the tracks left out for an existence below ``min_existence``.
    """

    track_rows: dict[int, tuple[int, ...]]
    report: RefinementReport
    confidence: TrackConfidence | None
    dropped: tuple[int, ...] = ()


def refine_track_rows(
    config: Config,
    scans: Sequence[Scan],
    track_rows: Mapping[int, Sequence[int]],
    *,
    settings: RefinementSettings | None = None,
    confidence: bool = True,
    min_existence: float | None = None,
    stop: Callable[[], bool] | None = None,
) -> RefinedTracks:
    """Refine a track set given as track id -> detection ids (what the estimator keeps).

    Parameters
    ----------
    config : Config
    scans : sequence of Scan
        The whole recording.
    track_rows : mapping of int to sequence of int
        Detection ids of every track.
    settings : RefinementSettings, optional
        Default: the configuration's (``config.estimator.refinement``).
    confidence : bool
        Whether to compute the refined set's existence and association probabilities
        (:meth:`Refiner.confidence`).
    min_existence : float, optional
        Leave out the tracks whose existence probability is below this (needs
        ``confidence``); default: ``config.estimator.refinement.min_existence``.
    stop : callable, optional
        Polled between the units of the refinement and of the confidence pass
        (:meth:`Refiner.refine`, :meth:`Refiner.confidence`).

    Returns
    -------
    RefinedTracks

    Raises
    ------
    StopRequested
        ``stop`` returned True (nothing is returned: the caller starts again from
        ``track_rows``, which gives the same result, the refinement being deterministic).
    """
    if settings is None:
        settings = config.estimator.refinement
    if min_existence is None:
        min_existence = config.estimator.refinement.min_existence
    objective = RecordingObjective(config=config, scans=scans)
    paths = {tid: objective.path_of_rows(rows) for tid, rows in track_rows.items() if len(rows)}
    refiner = Refiner(config=config, scans=scans, settings=settings, objective=objective)
    refined, report = refiner.refine(paths, stop=stop)
    sure = refiner.confidence(refined, stop=stop) if confidence else None
    dropped: tuple[int, ...] = ()
    if sure is not None and min_existence > 0:
        dropped = tuple(tid for tid in refined if sure.existence.get(tid, math.nan) < min_existence)
        refined = {tid: path for tid, path in refined.items() if tid not in dropped}
    return RefinedTracks(rows_from_paths(scans, refined), report, sure, dropped)


def track_confidence(
    config: Config,
    scans: Sequence[Scan],
    track_rows: Mapping[int, Sequence[int]],
    *,
    stop: Callable[[], bool] | None = None,
) -> TrackConfidence:
    """The confidence pass over a track set as it is, without refining it first.

    The passes of the EM of ``"auto"`` parameters count soft associations from the
    forward pass's tracks (:func:`mapassoc.estimator.parameters.association_counts`):
    they need the pass's probabilities, not the refinement, which would cost one to
    three times the pass again, so only the pass runs (with the configuration's
    refinement settings, as :func:`refine_track_rows` runs it).

    Parameters
    ----------
    config : Config
    scans : sequence of Scan
        The recording the tracks are of.
    track_rows : mapping of int to sequence of int
        Detection ids of every track, by track id.
    stop : callable, optional
        Polled before every window (:meth:`Refiner.confidence`).

    Returns
    -------
    TrackConfidence
    """
    objective = RecordingObjective(config=config, scans=scans)
    paths = {tid: objective.path_of_rows(rows) for tid, rows in track_rows.items() if len(rows)}
    refiner = Refiner(
        config=config, scans=scans, settings=config.estimator.refinement, objective=objective
    )
    return refiner.confidence(paths, stop=stop)
