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
integer program (detections at most once, carried tracks exactly once, anchors at most
once) picks the best set.  Because every selected item's score is its exact change of
J, the program's optimum is the best J over the window's kept hypotheses; the new
track set is valued again track by track and replaces the old one only when J rises.
This also lets a track that started late pick up the detections it was missed at.

**Dropping** a track whose value is negative (J rises by minus its value: its detections
are likelier false alarms, which windows shorter than the track cannot see whole).

**Fragment linking** (:meth:`Refiner.link_fragments`).  A track that ends and one that
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
J of the changed tracks rises, so J never decreases; with the integer program's time limit
(``SearchSettings.program_time_limit``) and the pass budget the work is bounded, and without a
time limit reached the result is a function of the input alone.

Proposals re-filter at most ``refilter_detections`` of an anchor's detections (the
acceptance re-filters all of them), and the joins to one anchor are pruned like the
nodes of one tree (the refinement's ``prune_log_ratio`` below the best after the
anchor's first detection): the window's program is exact over the hypotheses and joins it keeps.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config, check_config
from mapassoc.data.scans import Scan
from mapassoc.data.settings import RefinementSettings
from mapassoc.errors import InputError, check_stop
from mapassoc.estimator.cluster_solving import (
    WORK_PROJECTION,
    best_set_by_fixing,
    default_lp_solver,
)
from mapassoc.estimator.hypotheses import CarriedTrack, HypothesisGenerator, WindowHypotheses
from mapassoc.estimator.objective import (
    PathState,
    RecordingObjective,
    TrackPath,
    Trajectory,
    rows_from_paths,
)
from mapassoc.formulations.clusters import cluster_hypotheses
from mapassoc.formulations.frontier import SearchLimitExceeded, frontier_search
from mapassoc.formulations.marginals import (
    ENUMERATION_MAX_HYPOTHESES,
    enumerated_marginals,
    frontier_marginals,
)
from mapassoc.formulations.packing import PackingProblem, gather_rows
from mapassoc.solvers import get_integer_solver

__all__ = [
    "RefinementSettings",
    "RefinementReport",
    "TrackConfidence",
    "ASSOCIATION_FLOOR",
    "Refiner",
    "RefinedTracks",
    "refine_track_rows",
    "REFINEMENT_PHASE",
    "CONFIDENCE_PHASE",
]

_IMPROVEMENT = 1e-6
"""A move is accepted when J rises by more than this many nats plus 1e-9 of ``|J of the
changed tracks|``: below it, the change is rounding (and the 1e-9 agreement at which
:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging` stops
re-filtering)."""


_MARGINALS_WORK = 50_000
"""Transitions of the exact forward-backward search per cluster of the confidence pass;
past them, or on course for more than ``WORK_PROJECTION`` times them, the cluster's
marginals come from the beam of :data:`_MARGINALS_BEAM` frontiers.  (The projection
spares the searches that would fail anyway: 1.15 s -> 0.14 s of failed searches on
dense_pd08, 0.95 -> 0.12 s on parallel, with every search that finished before still
finishing.)"""

_MARGINALS_BEAM = 32

_BEAM_MARGIN = 40.0
"""Per-frontier entries more than this many nats below a frontier's best are dropped by the
beam that computes a cluster's marginals past ``exact_work_limit``."""

_SMALL_CLUSTER = 12
"""Clusters of at most this many hypotheses are searched exactly by the frontier search;
larger ones go to the integer program together."""


def _uncounted(problem: PackingProblem) -> PackingProblem:
    """``problem`` with no hypothesis counted: its per-k tables have one entry, k = 0,
    the best set and the mass over every size (the re-solve's program has no
    cardinality row)."""
    return PackingProblem.derived(
        scores=problem.scores,
        resource_indptr=problem.resource_indptr,
        resource_indices=problem.resource_indices,
        exactly_one=problem.exactly_one,
        counts=np.zeros(problem.num_hypotheses, dtype=bool),
        log_weights=problem.weights,
    )


def _probability(total: float) -> float:
    """A sum of the probabilities of exclusive events, rounded into [0, 1].

    The hypotheses of one tree are exclusive, so the sum is at most 1 but for rounding
    (a few ulps); more than 1e-9 over is a fault, not rounding, and raises.
    """
    if not -1e-9 <= total <= 1.0 + 1e-9:
        raise RuntimeError(f"a sum of exclusive probabilities came out {total!r}")
    return min(1.0, max(0.0, total))


def _rises(old: float, new: float) -> bool:
    """Whether ``new`` beats ``old`` by more than rounding (:data:`_IMPROVEMENT`)."""
    return new > old + _IMPROVEMENT + 1e-9 * abs(old)


REFINEMENT_PHASE = "the refinement of the whole recording"
"""The phase a stop during :meth:`Refiner.refine` names (in its StopRequested)."""
CONFIDENCE_PHASE = "the confidence pass"
"""The phase a stop during :meth:`Refiner.confidence` names."""


@dataclass
class RefinementReport:
    """What the refinement did (``summary.json``'s ``refinement``).

    Attributes
    ----------
    objective_forward : float
        J of the forward pass's track set.
    objective_after_pass : list of float
        J after each sweep (window re-solves, then fragment linking); non-decreasing.
    windows_solved, windows_improved : int
    windows_time_limited : int
        Re-solves whose integer program stopped at the time limit (its incumbent was
        used only where it raised J).
    links : int
        Fragment joins made.
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
    links: int = 0
    dropped: int = 0
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
            "links": self.links,
            "tracks_dropped": self.dropped,
        }
        if timings:
            out["seconds"] = self.seconds
        return out


@dataclass(frozen=True, eq=False)
class TrackConfidence:
    """How sure the refined track set is of each track and detection (:meth:`Refiner.confidence`).

    Every probability is a posterior marginal of one window of ``window_length`` scans,
    the track set outside it held at the refined one: the sum, over every track set of
    the window's kept hypotheses (joins to the tracks after it included), of
    ``exp(J)``, normalised.

    Attributes
    ----------
    existence : dict of int to float
        Per track: the probability that a target's first detection is the track's first
        detection (the new track tree rooted there is in the set), in the window that
        holds it.
    associations : dict of int to dict of int to float
        Per track: detection id -> the probability that the detection belongs to the
        track (the track's tree in the window of the detection uses it), for its own
        detections and for every other detection the track could take with probability
        at least :data:`ASSOCIATION_FLOOR`.
    exact : bool
        Whether every window's marginals were exact over its kept hypotheses (False when
        a cluster needed the beam search: its probabilities are then among the sets the
        beam kept).
    windows : int
    """

    existence: dict[int, float]
    associations: dict[int, dict[int, float]]
    exact: bool
    windows: int


ASSOCIATION_FLOOR = 1e-4
"""Association probabilities below this are left out of :attr:`TrackConfidence.associations`."""


@dataclass(frozen=True, eq=False)
class _Carried:
    """A track entering a re-solved window: its detections before it and its state."""

    track_id: int
    prefix: TrackPath
    reference: Trajectory
    """The track's current filter run (its first ``len(prefix)`` detections are the prefix)."""
    state: CarriedTrack
    value_alive: float
    """The prefix's terms with the track alive at scan ``a - 1`` (misses included)."""
    value_ended: float
    """The best value of the prefix ending at a gap before scan ``a - 1``'s (``-inf`` if none)."""
    mass_ended: float
    """The log of the summed probability of those endings."""


@dataclass(frozen=True, eq=False)
class _Anchor:
    """A track piece after a re-solved window that a window hypothesis may join."""

    origin: int
    path: TrackPath
    whole: bool
    """Whether the piece is the whole track (else the suffix of a track crossing the window)."""
    value: float
    """Its value as a track of its own."""
    reference: Trajectory
    """The current filter run of the track it belongs to."""
    offset: int
    """Index of the piece's first detection in ``reference.path``."""


@dataclass(frozen=True, eq=False)
class _Uses:
    """Which window detections the program's hypotheses use, as index arrays both ways
    (one entry per detection of each hypothesis, never a hypotheses x detections array:
    a scan of many thousand detections costs what the window keeps).

    ``detections[ptr[i]:ptr[i + 1]]`` are program hypothesis i's detections and
    ``users[user_ptr[d]:user_ptr[d + 1]]`` the program hypotheses using detection d, in
    increasing order.
    """

    ptr: NDArray[np.int64]
    detections: NDArray[np.int64]
    user_ptr: NDArray[np.int64]
    users: NDArray[np.int64]

    @classmethod
    def of(cls, hyps: WindowHypotheses, base: NDArray[np.int64]) -> _Uses:
        """The uses of program hypotheses ``base`` (window hypothesis of each)."""
        ptr, detections = gather_rows(hyps.detection_indptr, hyps.detection_indices, base)
        holder = np.repeat(np.arange(base.size, dtype=np.int64), np.diff(ptr))
        order = np.argsort(detections, kind="stable")
        per_detection = np.bincount(detections, minlength=hyps.detections.count)
        user_ptr = np.concatenate([[0], np.cumsum(per_detection)]).astype(np.int64)
        return cls(ptr, detections, user_ptr, holder[order])

    def holders(self) -> NDArray[np.int64]:
        """The program hypothesis of each entry of ``detections``."""
        return np.repeat(np.arange(self.ptr.size - 1, dtype=np.int64), np.diff(self.ptr))

    def using(self, detections: NDArray[np.int64]) -> NDArray[np.int64]:
        """The program hypotheses that use at least one of ``detections``, sorted."""
        _, found = gather_rows(self.user_ptr, self.users, detections)
        return np.unique(found)

    def largest_use(self, detections: NDArray[np.int64], probabilities: FloatArray) -> float:
        """The largest, over ``detections``, probability that a hypothesis uses it.

        Each sum runs over a column of every hypothesis' probability of using the
        detection (zeros included: linear in what the window keeps), as numpy sums a
        column, so the float is the same however the uses are stored.
        """
        sums = np.zeros(detections.size)
        column = np.zeros(probabilities.shape[0])
        for k, d in enumerate(detections.tolist()):
            users = self.users[self.user_ptr[d] : self.user_ptr[d + 1]]
            column[users] = probabilities[users]
            sums[k] = column.sum()
            column[users] = 0.0
        return float(np.max(sums, initial=0.0))


@dataclass(frozen=True, eq=False)
class _Clusters:
    """A window's clusters for :meth:`Refiner._any_of`: the problem with no hypothesis
    counted, each cluster's members and log-mass, and the cluster of every hypothesis."""

    uncounted: PackingProblem
    clusters: Sequence[tuple[NDArray[np.int64], float]]
    cluster_of: NDArray[np.int64]

    @classmethod
    def of(
        cls, problem: PackingProblem, clusters: Sequence[tuple[NDArray[np.int64], float]]
    ) -> _Clusters:
        cluster_of = np.full(problem.num_hypotheses, -1, dtype=np.int64)
        for c, (members, _) in enumerate(clusters):
            cluster_of[members] = c
        return cls(_uncounted(problem), clusters, cluster_of)


def _add_associations(
    associations: dict[int, dict[int, float]],
    uses: _Uses,
    hyps: WindowHypotheses,
    base: NDArray[np.int64],
    owner: Mapping[int, int],
    probabilities: FloatArray,
) -> None:
    """Add each program hypothesis' probability to the association of its tree's track
    (``owner``: tree -> track id) with every detection it uses (by detection id).

    Each (track, detection) sum runs over the hypotheses in program order, so it is the
    same float as adding them one by one.
    """
    if not owner or base.size == 0:
        return
    trees = np.asarray(hyps.tree, dtype=np.int64)
    # A carried track's tree may have no hypothesis left in the program (pruned), so the
    # owners' tree numbers can lie past the largest tree with one.
    has_owner = np.zeros(max(int(trees.max()), max(owner)) + 1, dtype=bool)
    track = np.zeros(has_owner.size, dtype=np.int64)
    for tree, tid in owner.items():
        has_owner[tree] = True
        track[tree] = tid
    program_trees = trees[base]
    holders = uses.holders()
    keep = has_owner[program_trees[holders]] & ~(probabilities[holders] <= 0.0)
    held = holders[keep]
    tids = track[program_trees[held]]
    rows = np.asarray(hyps.detections.rows, dtype=np.int64)[uses.detections[keep]]
    pairs, inverse = np.unique(np.stack([tids, rows]), axis=1, return_inverse=True)
    sums = np.bincount(inverse.reshape(-1), weights=probabilities[held], minlength=pairs.shape[1])
    for (tid, row), total in zip(pairs.T.tolist(), sums.tolist(), strict=True):
        into = associations[tid]
        into[row] = into.get(row, 0.0) + total


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
        self.generator, self.long_generator = (
            HypothesisGenerator(
                motion=config.motion,
                sensors=config.sensors,
                birth=config.birth,
                gate_probability=est.gate_probability,
                max_hypotheses_per_tree=est.max_hypotheses_per_tree,
                prune_log_ratio=ratio,
            )
            for ratio in (
                settings.prune_log_ratio,
                settings.prune_log_ratio
                if settings.long_prune_log_ratio is None
                else settings.long_prune_log_ratio,
            )
        )
        try:
            self.solver = get_integer_solver(est.solver)
        except ValueError as exc:
            raise InputError(f"estimator solver: {exc}", key="solver") from None
        self.lp_solver = default_lp_solver(self.solver)
        self.time_limit = est.search.program_time_limit  # each integer program's
        self._refilter = settings.refilter_detections
        self._capped_scans: set[int] = set()  # scans of re-solves whose trees the cap cut
        self.exact_work_limit = est.exact_work_limit
        self.beam_width = est.beam_width
        self._gain_bounds = np.array(
            [
                max(0.0, self.generator.continuation_gain_bound(config.sensors[s.sensor]))
                for s in self.scans
            ]
        )

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
        for sweep in range(self.settings.passes):
            N = lengths[sweep % len(lengths)]
            order = starts[N] if (sweep // len(lengths)) % 2 == 0 else starts[N][::-1]
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
                improved, limited = self.resolve_window(current, values, a, a + N)
                report.windows_time_limited += int(limited)
                if improved:
                    report.windows_improved += 1
                    changed = True
                    for n in lengths:  # windows of every length near the change
                        low, high = a - 2 * n, a + N + n
                        dirty[n].update(s for s in starts[n] if low <= s <= high)
                    dirty[N].discard(a)
            if self.settings.link_gap > 0:
                links = self.link_fragments(current, values, stop=stop)
                report.links += links
                changed = changed or links > 0
            # A track worth less than its detections as false alarms (v < 0, which
            # windows shorter than the track cannot see whole) goes: J rises by -v.
            dropped = [tid for tid, value in values.items() if _rises(value, 0.0)]
            for tid in dropped:
                del current[tid]
                del values[tid]
            report.dropped += len(dropped)
            changed = changed or bool(dropped)
            values = self._exact_values(current)
            report.objective_after_pass.append(float(sum(values.values())))
            unchanged = 0 if changed else unchanged + 1
            if unchanged >= len(lengths):
                break  # a sweep of every window length changed nothing
        tracks_out = dict(sorted(current.items()))
        report.seconds = time.perf_counter() - t0
        return tracks_out, report

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
    ) -> tuple[bool, bool]:
        """Re-solve scans ``a..b-1`` with both boundaries; update ``tracks`` in place.

        Returns
        -------
        improved : bool
            Whether J rose (and ``tracks``, ``values`` were changed).
        time_limited : bool
            Whether the integer program stopped at the time limit.
        """
        obj = self.objective
        if not 0 <= a < b <= len(self.scans):
            raise InputError(f"window {a}..{b - 1} is not within the recording's scans")
        generator = self.long_generator if b - a > self.window_length else self.generator
        hyps, carried, anchors, touched = self._window_hypotheses(
            tracks, values, a, b, generator
        )
        if hyps.nodes_capped > 0:
            self._capped_scans.update(range(a, b))
        problem, joins = self._program(
            hyps, carried, anchors, a, prune_log_ratio=generator.prune_log_ratio
        )
        if problem.num_hypotheses == 0:
            return False, False
        selection, limited = self._best_set(problem)
        if selection is None:
            return False, limited
        pieces = self._decode(hyps, selection, joins, carried, anchors, a)
        if {path for _, path in pieces} == {tracks[tid] for tid in touched}:
            return False, limited  # the window's best set is the current one
        # Accepted on exact values: every changed track's whole filter run.
        new_values = [obj.track_value(path) for _, path in pieces]
        old = sum(values[tid] for tid in touched)
        if not _rises(old, float(sum(new_values))):
            return False, limited
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
        return True, limited

    def _best_set(self, problem: PackingProblem) -> tuple[NDArray[np.int64] | None, bool]:
        """The best feasible set of the re-solve's program, and whether a solve was cut
        short by the time limit (None: no feasible set was found).

        The program has no cardinality row, so it splits into independent clusters; each
        of at most :data:`_SMALL_CLUSTER` hypotheses is searched exactly by the frontier
        search with every hypothesis uncounted (one table entry: the best set over all
        sizes), the larger ones by one integer program.
        """
        uncounted = _uncounted(problem)
        chosen: list[NDArray[np.int64]] = []
        large: list[NDArray[np.int64]] = []
        clusters = cluster_hypotheses(uncounted)
        lone = np.array([int(m[0]) for m in clusters if len(m) == 1], dtype=np.int64)
        if lone.size:
            # A hypothesis sharing no resource with another is taken when it must be (it
            # alone holds an exactly-once resource) or when it adds to J (score > 0, as
            # the frontier search breaks the tie at 0 towards the empty set).
            required = problem.uses_any(problem.exactly_one)
            chosen.append(lone[required[lone] | (problem.scores[lone] > 0)])
        for members in clusters:
            if len(members) == 1:
                continue
            if len(members) > _SMALL_CLUSTER:
                large.append(members)
                continue
            try:
                found = frontier_search(
                    uncounted.subproblem(members), 0, work_limit=self.exact_work_limit
                )
            except SearchLimitExceeded:
                large.append(members)
                continue
            best = found.best_sets[0]
            if best is None:
                return None, False
            chosen.append(members[np.asarray(best, dtype=np.int64)])
        limited = False
        if large:
            # One program for every large cluster: a solver call costs about a
            # millisecond whatever its size.
            members = np.concatenate(large)
            selection, optimal = best_set_by_fixing(
                problem.subproblem(members),
                solver=self.solver,
                lp_solver=self.lp_solver,
                time_limit=self.time_limit,
            )
            limited = not optimal
            if selection is None:
                return None, limited
            chosen.append(members[selection])
        if not chosen:
            return np.zeros(0, dtype=np.int64), limited
        return np.sort(np.concatenate(chosen)), limited

    def _split(
        self, tracks: Mapping[int, TrackPath], values: Mapping[int, float], a: int, b: int
    ) -> tuple[list[_Carried], list[_Anchor], list[int]]:
        """The carried tracks, the anchors and the ids of every track the window touches."""
        obj = self.objective
        carried: list[_Carried] = []
        anchors: list[_Anchor] = []
        touched: list[int] = []
        for tid in sorted(tracks):
            path = tracks[tid]
            first, last = path[0][0], path[-1][0]
            # Tracks within a window's length of it may be carried in or joined.
            reach = b - a
            if last < a - reach or first > b - 1 + reach:
                continue
            prefix = tuple(p for p in path if p[0] < a)
            middle = [p for p in path if a <= p[0] < b]
            suffix = tuple(p for p in path if p[0] >= b)
            reference = obj.trajectory(path)
            if not prefix and not middle:
                anchors.append(_Anchor(tid, suffix, True, values[tid], reference, 0))
                touched.append(tid)
                continue
            if prefix:
                entering = self._carried(tid, prefix, reference, a)
                if entering is None:
                    if middle or suffix:  # the track as it is would be impossible
                        raise InputError(
                            f"track {tid} cannot be alive at scan {a - 1} between its "
                            "detections (a miss there has probability 0)"
                        )
                    continue  # ended before the window, and nothing in it can change that
                carried.append(entering)
            touched.append(tid)
            if suffix:
                offset = len(path) - len(suffix)
                anchors.append(_Anchor(tid, suffix, False, math.nan, reference, offset))
        # An anchor's value alone: its first detection started anew, every anchor's
        # re-filter in one batch.
        alone = [i for i, anchor in enumerate(anchors) if not anchor.whole]
        alone_values = obj.continue_converging_many(
            [
                (obj.start_path(anchors[i].path), anchors[i].reference, anchors[i].offset + 1)
                for i in alone
            ],
            max_detections=self._refilter,
        )
        for i, value in zip(alone, alone_values, strict=True):
            anchors[i] = replace(anchors[i], value=float(value[0]))
        return carried, anchors, touched

    def _carried(
        self, tid: int, prefix: TrackPath, reference: Trajectory, a: int
    ) -> _Carried | None:
        """The prefix's state at scan ``a - 1``, or None when it cannot be alive there."""
        obj = self.objective
        at_last = reference.state(len(prefix) - 1)
        alive = obj.advance_missed(at_last, a - 1)
        value_alive = float(alive.value[0])
        if not math.isfinite(value_alive):
            return None
        # End in the gap after a scan g < a - 1.
        ended, mass_ended = obj.terms.endings_before(float(at_last.value[0]), at_last.scan, a - 1)
        state = CarriedTrack(
            track_id=tid,
            mean=alive.means[0].copy(),
            covariance=alive.covariances[0].copy(),
            time=float(obj.times[a - 1]),
            initiated=alive.initiated,
            num_detections=len(prefix),
            first_detection_time=float(at_last.first_time[0]),
        )
        return _Carried(tid, prefix, reference, state, value_alive, ended, mass_ended)

    def _program(
        self,
        hyps: WindowHypotheses,
        carried: Sequence[_Carried],
        anchors: Sequence[_Anchor],
        a: int,
        *,
        prune_log_ratio: float,
        masses: bool = False,
    ) -> tuple[PackingProblem, list[tuple[int, int]]]:
        """The packing problem of the re-solve; ``joins[i]`` = (hypothesis, anchor) of the
        program's hypothesis ``H + i``.

        With ``masses`` the problem's log-weights are for sums over track sets (the
        endings summed rather than maximised) and joins no better than their hypothesis
        alone are kept (they are never in a best set, but they carry probability).
        """
        obj = self.objective
        nodes = hyps.nodes
        H = hyps.count
        D = hyps.detections.count
        C = len(carried)
        N = len(hyps.scans)
        leaves = hyps.leaf
        alive = nodes.alive[leaves]
        layer = nodes.layer[leaves]
        scores = hyps.scores.astype(float).copy()
        tails = np.where(alive, obj.terms.tails[a + np.maximum(layer, 0)], 0.0)
        plain = scores + tails
        weights = scores + np.where(alive, obj.terms.tail_masses[a + np.maximum(layer, 0)], 0.0)
        is_carried = hyps.tree < C
        for h in np.flatnonzero(is_carried & ~hyps.counts_toward_k).tolist():
            c = carried[int(hyps.tree[h])]
            plain[h] = max(scores[h], c.value_ended - c.value_alive)
            weights[h] = float(np.logaddexp(scores[h], c.mass_ended - c.value_alive))
        base_ptr, base = gather_rows(
            hyps.detection_indptr,
            hyps.detection_indices,
            np.arange(H),
            np.where(is_carried, D + hyps.tree, -1),
        )
        join_h: list[NDArray[np.int64]] = []
        join_anchor: list[NDArray[np.int64]] = []
        join_score: list[NDArray[np.float64]] = []
        ends = np.flatnonzero(alive & (layer == N - 1))
        gains = self._join_gains(hyps, ends, scores[ends], anchors, a + N - 1, prune_log_ratio)
        for i, anchor in enumerate(anchors):
            if ends.size == 0:
                break
            gain = gains[i]
            # An anchor that cannot stand alone (its own filter gates out one of its
            # detections: value -inf) must be joined; its resource is then exactly-once
            # and its joins are scored without the baseline.
            baseline = anchor.value if math.isfinite(anchor.value) else 0.0
            joined = scores[ends] + gain - baseline
            # A join no better than its hypothesis left alone is dominated: it uses more.
            if masses:
                better = np.flatnonzero(np.isfinite(joined))
            else:
                better = np.flatnonzero(np.isfinite(joined) & (joined > plain[ends]))
            join_h.append(ends[better])
            join_anchor.append(np.full(better.size, i, dtype=np.int64))
            join_score.append(joined[better])
        joined_h = np.concatenate(join_h) if join_h else np.zeros(0, dtype=np.int64)
        anchor_of = np.concatenate(join_anchor) if join_anchor else np.zeros(0, dtype=np.int64)
        join_scores = np.concatenate(join_score) if join_score else np.zeros(0)
        joins = list(zip(joined_h.tolist(), anchor_of.tolist(), strict=True))
        # a join uses its hypothesis's resources and its anchor's
        join_ptr, join_indices = gather_rows(base_ptr, base, joined_h, D + C + anchor_of)
        indptr = np.concatenate([base_ptr, base_ptr[-1] + join_ptr[1:]])
        indices = np.concatenate([base, join_indices])
        all_scores = np.concatenate([plain, join_scores])
        # A join's score holds no ending of its own: the anchor's ending is in both its
        # terms and the baseline, and cancels.  Its weight is its score.
        problem = PackingProblem(
            scores=all_scores,
            log_weights=np.concatenate([weights, join_scores]) if masses else None,
            resource_indptr=indptr,
            resource_indices=indices,
            exactly_one=np.r_[
                np.zeros(D, bool),
                np.ones(C, bool),
                [not math.isfinite(anchor.value) for anchor in anchors],
            ],
            counts=np.ones(all_scores.shape[0], dtype=bool),
        )
        return problem, joins

    def _join_gains(
        self,
        hyps: WindowHypotheses,
        ends: NDArray[np.int64],
        end_scores: FloatArray,
        anchors: Sequence[_Anchor],
        last_scan: int,
        prune_log_ratio: float,
    ) -> list[FloatArray]:
        """Per anchor, its terms and best ending after each leaf in ``ends`` (alive at
        the window's last scan, ``last_scan`` of the recording), re-filtered from the
        leaf's state.

        The joins to one anchor compete for it as the nodes of one tree compete for its
        place, and they are pruned the same way (``prune_log_ratio``, the window's
        generator's): after the anchor's
        first detection, a join whose score so far (its hypothesis' score, ``end_scores``,
        plus the join's first terms) is more than ``prune_log_ratio`` below the anchor's
        best join is not followed further (``-inf``).  The joins followed are scored
        exactly, every anchor's in one batch
        (:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging_many`).
        """
        obj = self.objective
        gains = [np.full(len(ends), -math.inf) for _ in anchors]
        if ends.size == 0 or not anchors:
            return gains
        nodes = hyps.nodes
        leaves = hyps.leaf[ends]
        firsts: list[list[tuple[NDArray[np.int64], PathState]]] = [[] for _ in anchors]
        targets = [anchor.path[0] for anchor in anchors]
        for initiated in (True, False):
            group = np.flatnonzero(nodes.initiated[leaves] == initiated)
            if group.size == 0:
                continue
            # Uninitiated states convert per track at their next later detection; they
            # are advanced one by one so that a batch never mixes conversion times.
            batches = [group] if initiated else [group[k : k + 1] for k in range(group.size)]
            for batch in batches:
                v = leaves[batch]
                d = int(nodes.state_dims[v[0]])
                start = PathState(
                    scan=last_scan,
                    means=nodes.means[v, :d],
                    covariances=nodes.covariances[v, :d, :d],
                    initiated=initiated,
                    first_time=nodes.first_time[v],
                    value=np.zeros(len(v)),
                )
                for i, (rows, state) in enumerate(obj.continue_each(start, targets)):
                    if rows.size:
                        firsts[i].append((batch[rows], state))
        pending: list[tuple[int, NDArray[np.int64], PathState]] = []
        for i, reached in enumerate(firsts):
            if not reached:
                continue
            so_far = np.concatenate([end_scores[b] + s.value for b, s in reached])
            floor = float(np.max(so_far)) - prune_log_ratio
            for batch, first in reached:
                keep = np.flatnonzero(end_scores[batch] + first.value >= floor)
                if keep.size:
                    pending.append((i, batch[keep], first.take(keep)))
        values = obj.continue_converging_many(
            [(state, anchors[i].reference, anchors[i].offset + 1) for i, _, state in pending],
            max_detections=self._refilter,
        )
        for (i, batch, _), value in zip(pending, values, strict=True):
            gains[i][batch] = value
        return gains

    def _decode(
        self,
        hyps: WindowHypotheses,
        selection: NDArray[np.int64],
        joins: Sequence[tuple[int, int]],
        carried: Sequence[_Carried],
        anchors: Sequence[_Anchor],
        a: int,
    ) -> list[tuple[int | None, TrackPath]]:
        """The tracks of a selected set: (track id, or None for a new id; path).

        A carried track keeps its id; a new tree that joins an anchor takes the id of the
        anchor's track unless a carried piece of that track kept it; an anchor left alone
        keeps its track's id under the same condition.
        """
        H = hyps.count
        C = len(carried)
        det = hyps.detections
        chosen: list[tuple[int, int | None]] = [
            (s, None) if s < H else joins[s - H] for s in selection.tolist()
        ]
        kept_ids = {carried[int(hyps.tree[h])].track_id for h, _ in chosen if hyps.tree[h] < C}
        pieces: list[tuple[int | None, TrackPath]] = []
        joined: set[int] = set()
        for h, anchor_index in chosen:
            dets = hyps.detections_of(h)
            path: TrackPath = tuple(
                (a + int(det.scan_position[d]), int(det.index_in_scan[d])) for d in dets
            )
            tree = int(hyps.tree[h])
            tid: int | None = None
            if tree < C:
                tid = carried[tree].track_id
                path = carried[tree].prefix + path
            if anchor_index is not None:
                anchor = anchors[anchor_index]
                joined.add(anchor_index)
                path = path + anchor.path
                if tid is None and anchor.origin not in kept_ids:
                    tid = anchor.origin
                    kept_ids.add(tid)
            if path:
                pieces.append((tid, path))
        for i, anchor in enumerate(anchors):
            if i in joined:
                continue
            tid = None if anchor.origin in kept_ids else anchor.origin
            if tid is not None:
                kept_ids.add(tid)
            pieces.append((tid, anchor.path))
        return pieces

    # -- how sure ------------------------------------------------------------------------
    def confidence(
        self, tracks: Mapping[int, TrackPath], *, stop: Callable[[], bool] | None = None
    ) -> TrackConfidence:
        """Existence and association probabilities of a (refined) track set.

        One pass over the recording in windows of ``window_length`` scans: each window's
        program is built as in :meth:`resolve_window` (the tracks outside it fixed, the
        tracks crossing it carried in and anchored after it), and the posterior marginal
        of every hypothesis and join is computed by the frontier search run forward and
        backward (:func:`mapassoc.formulations.marginals.frontier_marginals`; a cluster of
        at most twelve hypotheses lists its subsets instead,
        :func:`~mapassoc.formulations.marginals.enumerated_marginals`) with the
        weights ``exp(J)`` (endings summed).  A track's existence is the probability that
        its detections in the window of its first detection are not all false alarms: that
        some track uses at least one of them (one minus the mass of the sets that use none,
        over the total).  A fragment of a target's track that the MAP set keeps apart
        thus keeps its existence, and a track of false alarms gets the probability that
        they are something else.  A detection's association to a track is the
        probability that the track's tree (carried, or new at one of the track's
        detections) uses it.  ``stop`` is polled before every window; when it returns
        True this raises :class:`~mapassoc.errors.StopRequested` (:data:`CONFIDENCE_PHASE`).
        """
        current = {int(tid): tuple(path) for tid, path in tracks.items() if path}
        values = self._exact_values(current)
        track_of = {p: tid for tid, path in current.items() for p in path}
        existence: dict[int, float] = {}
        associations: dict[int, dict[int, float]] = {tid: {} for tid in current}
        exact = True
        windows = 0
        M = len(self.scans)
        for a in range(0, M, self.window_length):
            check_stop(stop, CONFIDENCE_PHASE)
            b = min(a + self.window_length, M)
            windows += 1
            hyps, carried, anchors, _ = self._window_hypotheses(
                current, values, a, b, self.generator
            )
            problem, joins = self._program(
                hyps,
                carried,
                anchors,
                a,
                prune_log_ratio=self.generator.prune_log_ratio,
                masses=True,
            )
            if problem.num_hypotheses == 0:
                continue
            probabilities, window_exact, clusters = self._marginals(problem)
            exact = exact and window_exact
            base = np.r_[np.arange(hyps.count), np.array([h for h, _ in joins], dtype=np.int64)]
            owner = self._tree_owners(hyps, carried, track_of, a)
            uses = _Uses.of(hyps, base)
            _add_associations(associations, uses, hyps, base, owner, probabilities)
            det = hyps.detections
            window_index = {
                (a + int(det.scan_position[d]), int(det.index_in_scan[d])): d
                for d in range(det.count)
            }
            weighed = _Clusters.of(problem, clusters)
            for tid in sorted(current):
                if not a <= current[tid][0][0] < b:
                    continue
                mine = np.array(
                    [window_index[p] for p in current[tid] if p in window_index], dtype=np.int64
                )
                value = self._any_of(weighed, uses.using(mine))
                if math.isnan(value):
                    # A cluster had only the beam's marginals: the largest probability
                    # that one of the detections is used, a lower bound of the union.
                    value = _probability(uses.largest_use(mine, probabilities))
                existence[tid] = value
        for tid in current:
            existence.setdefault(tid, math.nan)  # its first detection's tree was pruned
            own = {int(self.scans[m].rows[j]) for m, j in current[tid]}
            associations[tid] = {
                row: _probability(p)
                for row, p in sorted(associations[tid].items())
                if p >= ASSOCIATION_FLOOR or row in own
            }
        return TrackConfidence(existence, associations, exact, windows)

    def _window_hypotheses(
        self,
        tracks: Mapping[int, TrackPath],
        values: Mapping[int, float],
        a: int,
        b: int,
        generator: HypothesisGenerator,
    ) -> tuple[WindowHypotheses, list[_Carried], list[_Anchor], list[int]]:
        """The hypothesis trees of scans ``a..b-1`` with both boundaries (module docstring),
        grown and pruned by ``generator``."""
        obj = self.objective
        carried, anchors, touched = self._split(tracks, values, a, b)
        window_scans = self.scans[a:b]
        carried_states = [c.state for c in carried]
        undetected = obj.terms.undetected_after[a - 1] if a > 0 else None
        population = generator.population(window_scans, carried_states, undetected)
        end_gain = 0.0
        for anchor in anchors:
            first = anchor.path[0][0]
            end_gain = max(end_gain, self._gain_bounds[first] - obj.terms.birth[first])
        hyps = generator.generate(
            window_scans, carried_states, population=population, end_gain=end_gain
        )
        return hyps, carried, anchors, touched

    def _tree_owners(
        self,
        hyps: WindowHypotheses,
        carried: Sequence[_Carried],
        track_of: Mapping[tuple[int, int], int],
        a: int,
    ) -> dict[int, int]:
        """Window tree -> the track it stands for: a carried tree's track, and a new tree
        rooted at one of a track's detections (the same target, maybe started at another
        of its detections)."""
        owner = {t: c.track_id for t, c in enumerate(carried)}
        nodes = hyps.nodes
        det = hyps.detections
        for v in np.flatnonzero((nodes.parent < 0) & (nodes.tree >= len(carried))).tolist():
            d = int(nodes.detection[v])
            if d < 0:
                continue
            tid = track_of.get((a + int(det.scan_position[d]), int(det.index_in_scan[d])))
            if tid is not None:
                owner[int(nodes.tree[v])] = tid
        return owner

    def _marginals(
        self, problem: PackingProblem
    ) -> tuple[FloatArray, bool, list[tuple[NDArray[np.int64], float]]]:
        """P(h in the set) of every hypothesis under the weights exp(log_weights), whether
        they are exact (clusters past :data:`_MARGINALS_WORK` use the beam), and each
        cluster's members with its log-mass (``nan`` where the beam gave only a part)."""
        uncounted = _uncounted(problem)
        out = np.zeros(problem.num_hypotheses)
        exact = True
        seed = np.zeros(1)
        clusters: list[tuple[NDArray[np.int64], float]] = []
        required = uncounted.uses_any(uncounted.exactly_one)
        for members in cluster_hypotheses(uncounted):
            if len(members) == 1:
                # A lone hypothesis: the sets are {h} and, unless it alone holds an
                # exactly-once resource, {}; in closed form.
                h = int(members[0])
                weight = float(uncounted.weights[h])
                total = weight if required[h] else float(np.logaddexp(0.0, weight))
                out[h] = math.exp(weight - total)
                clusters.append((members, total))
                continue
            sub = uncounted.subproblem(members)
            try:
                if len(members) <= ENUMERATION_MAX_HYPOTHESES:
                    found = enumerated_marginals(sub, seed)  # every subset listed
                else:
                    found = frontier_marginals(
                        sub, seed, work_limit=_MARGINALS_WORK, work_projection=WORK_PROJECTION
                    )
            except SearchLimitExceeded:
                found = frontier_marginals(
                    sub, seed, max_frontiers=_MARGINALS_BEAM, entry_margin=_BEAM_MARGIN
                )
            exact = exact and found.exact
            out[members] = np.exp(found.log_containing[0] - found.log_total[0])
            clusters.append((members, float(found.log_total[0]) if found.exact else math.nan))
        return out, exact, clusters

    def _any_of(self, weighed: _Clusters, chosen: NDArray[np.int64]) -> float:
        """P(at least one of the hypotheses ``chosen`` is in the set): one minus the mass
        of the sets without any of them over the total, cluster by cluster (only the
        clusters holding one of them)."""
        if chosen.size == 0:
            return 0.0
        log_none = 0.0
        for c in np.unique(weighed.cluster_of[chosen]).tolist():
            members, log_total = weighed.clusters[c]
            if math.isnan(log_total):
                return math.nan  # the beam's part of the mass: no ratio to take
            rest = members[~np.isin(members, chosen)]
            if rest.size == 0:
                log_none += -log_total  # only the empty set is left: weight 1
                continue
            sub = weighed.uncounted.subproblem(rest)
            try:
                found = frontier_search(sub, 0, work_limit=_MARGINALS_WORK)
            except SearchLimitExceeded:
                return math.nan  # (its order differs from the whole cluster's)
            log_none += float(found.log_mass[0]) - log_total
        return _probability(-math.expm1(min(0.0, log_none)))

    # -- fragment linking -------------------------------------------------------------------
    def link_fragments(
        self,
        tracks: dict[int, TrackPath],
        values: dict[int, float],
        *,
        stop: Callable[[], bool] | None = None,
    ) -> int:
        """Join tracks that end to tracks that start within ``link_gap`` scans where J rises.

        Returns the number of joins made; ``tracks`` and ``values`` are updated in place.
        ``stop`` is polled before every round (as in :meth:`refine`).
        """
        obj = self.objective
        gap = self.settings.link_gap
        made = 0
        while True:
            check_stop(stop, REFINEMENT_PHASE)
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
                end = obj.trajectory(path1).state(len(path1) - 1)
                for t2 in later:
                    reference = obj.trajectory(tracks[t2])
                    joined = float(
                        obj.continue_converging(end, reference, 0, max_detections=self._refilter)[0]
                    )
                    if _rises(values[t1] + values[t2], joined):
                        pairs.append((t1, t2, joined - values[t1] - values[t2]))
            if not pairs:
                return made
            ends = sorted({p[0] for p in pairs})
            starts = sorted({p[1] for p in pairs})
            gain = np.full((len(ends), len(starts)), -1e300)
            for t1, t2, delta in pairs:
                gain[ends.index(t1), starts.index(t2)] = delta
            rows, cols = linear_sum_assignment(gain, maximize=True)
            chosen = sorted(
                ((float(gain[r, c]), ends[r], starts[c]) for r, c in zip(rows, cols, strict=True)
                 if gain[r, c] > 0),
                reverse=True,
            )
            used: set[int] = set()
            joined_now = 0
            for _delta, t1, t2 in chosen:
                if t1 in used or t2 in used:
                    continue  # a chain: its joins are not independent; the next round
                used.update((t1, t2))
                path = tracks[t1] + tracks[t2]
                value = obj.track_value(path)  # accepted on the exact value
                if not _rises(values[t1] + values[t2], value):
                    continue
                del tracks[t2]
                del values[t2]
                tracks[t1] = path
                values[t1] = value
                joined_now += 1
            made += joined_now
            if joined_now == 0:
                return made


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
        dropped = tuple(
            tid for tid in refined if sure.existence.get(tid, math.nan) < min_existence
        )
        refined = {tid: path for tid, path in refined.items() if tid not in dropped}
    return RefinedTracks(rows_from_paths(scans, refined), report, sure, dropped)
