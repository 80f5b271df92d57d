"""A re-solved window with both boundaries: its trees, its program, its decoded tracks.

What the refinement's re-solves and its confidence pass share
(:mod:`mapassoc.estimator.refinement` describes the move).  The associations of the
scans ``a..b-1`` are freed.  A track with detections before ``a`` enters the window as
a carried track (:class:`Carried`: its filtered state at scan ``a - 1``, its misses up to
there scored, and ending before the window still open).  A track with detections after
``b - 1``, or starting within a window's length after it, becomes an anchor
(:class:`Anchor`): a track piece that a window hypothesis alive at the window's last scan
may join, the join scored by its exact change of J.  The program is built by the one
window builder, :func:`~mapassoc.estimator.window_program.packing_problem`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.hypotheses import CarriedTrack, HypothesisGenerator, WindowHypotheses
from mapassoc.estimator.objective import (
    PathState,
    RecordingObjective,
    TrackPath,
    Trajectory,
)
from mapassoc.estimator.window_program import Joins, packing_problem
from mapassoc.formulations.packing import PackingProblem

__all__ = [
    "Anchor",
    "Carried",
    "WindowBoundaries",
    "IMPROVEMENT",
    "REFINEMENT_PHASE",
    "TREE_CACHE_NODES",
    "rises",
]

REFINEMENT_PHASE = "the refinement of the whole recording"
"""The phase a stop during the refinement names (in its StopRequested)."""

IMPROVEMENT = 1e-6
"""A move is accepted when J rises by more than this many nats plus 1e-9 of ``|J of the
changed tracks|``: below it, the change is rounding (and the 1e-9 agreement at which
:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging` stops
re-filtering)."""


TREE_CACHE_NODES = 1_000_000
"""Tree nodes :class:`WindowBoundaries` keeps of the windows it grew (the least recently
used windows' trees go first): a window re-solved with the same carried states and end
gain takes its trees from there (see :meth:`WindowBoundaries.hypotheses`).  About 200
bytes a node for a four-dimensional state."""


def rises(old: float, new: float) -> bool:
    """Whether ``new`` beats ``old`` by more than rounding (:data:`IMPROVEMENT`)."""
    return new > old + IMPROVEMENT + 1e-9 * abs(old)


@dataclass(frozen=True, eq=False)
class Carried:
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
class Anchor:
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



class WindowBoundaries:
    """Builds the re-solved windows of one recording (module docstring).

    Parameters
    ----------
    objective : RecordingObjective
    scans : sequence of Scan
        The whole recording.
    refilter_detections : int
        Detections of an anchor re-filtered when a join is proposed.
    gain_bounds : ndarray, shape (M,)
        Per scan, a bound on what continuing a track there can add (the new trees'
        bound pruning allows for the most a join can add).
    reuse_trees : bool
        Whether a window's trees are kept and given again while their inputs are
        unchanged (:meth:`hypotheses`; at most :data:`TREE_CACHE_NODES` nodes).  False
        grows them anew every time (the same trees, only slower: the tests compare).
    """

    def __init__(
        self,
        *,
        objective: RecordingObjective,
        scans: Sequence[Scan],
        refilter_detections: int,
        gain_bounds: FloatArray,
        reuse_trees: bool = True,
    ) -> None:
        self.objective = objective
        self.scans = tuple(scans)
        self._refilter = int(refilter_detections)
        self._gain_bounds = gain_bounds
        self.reuse_trees = bool(reuse_trees)
        # (a, b, generator) -> (the trees' inputs, the trees), oldest first.
        self._trees: dict[
            tuple[int, int, HypothesisGenerator], tuple[tuple[object, ...], WindowHypotheses]
        ] = {}
        self._nodes = 0  # tree nodes held in self._trees

    def hypotheses(
        self,
        tracks: Mapping[int, TrackPath],
        values: Mapping[int, float],
        a: int,
        b: int,
        generator: HypothesisGenerator,
    ) -> tuple[WindowHypotheses, list[Carried], list[Anchor], list[int]]:
        """The hypothesis trees of scans ``a..b-1`` with both boundaries (module docstring),
        grown and pruned by ``generator``.

        The trees depend on nothing else than the window, the generator, the carried
        tracks' states and the end gain (the bound of what a join after the window can
        add): with ``reuse_trees``, a window asked for again with those equal to the bit
        gets the trees it was given last time (the same object: the callers only read
        it), which sweeps over the same windows and the confidence pass after them do
        where a change elsewhere made a window dirty but left what enters it alone.  The
        anchors are made anew every time, the joins' scores with them.
        """
        obj = self.objective
        carried, anchors, touched = self.split(tracks, values, a, b)
        carried_states = [c.state for c in carried]
        end_gain = 0.0
        for anchor in anchors:
            first = anchor.path[0][0]
            end_gain = max(end_gain, self._gain_bounds[first] - obj.terms.birth[first])
        inputs = _tree_inputs(carried_states, end_gain)
        place = (a, b, generator)
        cached = self._trees.get(place) if self.reuse_trees else None
        if cached is not None and cached[0] == inputs:
            hyps = cached[1]
        else:
            window_scans = self.scans[a:b]
            undetected = obj.terms.undetected_after[a - 1] if a > 0 else None
            population = generator.population(window_scans, carried_states, undetected)
            hyps = generator.generate(
                window_scans, carried_states, population=population, end_gain=end_gain
            )
        if self.reuse_trees:
            self._remember(place, inputs, hyps)
        return hyps, carried, anchors, touched

    def _remember(
        self,
        place: tuple[int, int, HypothesisGenerator],
        inputs: tuple[object, ...],
        hyps: WindowHypotheses,
    ) -> None:
        """Keep a window's trees as its most recent, dropping the least recently used
        windows' trees past :data:`TREE_CACHE_NODES` nodes."""
        old = self._trees.pop(place, None)
        if old is not None:
            self._nodes -= old[1].nodes.score.size
        self._trees[place] = (inputs, hyps)
        self._nodes += hyps.nodes.score.size
        while self._nodes > TREE_CACHE_NODES and len(self._trees) > 1:
            _, dropped = self._trees.pop(next(iter(self._trees)))
            self._nodes -= dropped.nodes.score.size

    def split(
        self, tracks: Mapping[int, TrackPath], values: Mapping[int, float], a: int, b: int
    ) -> tuple[list[Carried], list[Anchor], list[int]]:
        """The carried tracks, the anchors and the ids of every track the window touches."""
        obj = self.objective
        carried: list[Carried] = []
        anchors: list[Anchor] = []
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
                anchors.append(Anchor(tid, suffix, True, values[tid], reference, 0))
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
                anchors.append(Anchor(tid, suffix, False, math.nan, reference, offset))
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
    ) -> Carried | None:
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
        return Carried(tid, prefix, reference, state, value_alive, ended, mass_ended)

    def program(
        self,
        hyps: WindowHypotheses,
        carried: Sequence[Carried],
        anchors: Sequence[Anchor],
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
        Every hypothesis counts (the program has no cardinality row: K is free).
        """
        scores, plain, weights = self._scores(hyps, carried, a)
        nodes = hyps.nodes
        N = len(hyps.scans)
        leaves = hyps.leaf
        ends = np.flatnonzero(nodes.alive[leaves] & (nodes.layer[leaves] == N - 1))
        gains = self._join_gains(hyps, ends, scores[ends], anchors, a + N - 1, prune_log_ratio)
        join_h: list[NDArray[np.int64]] = [np.zeros(0, dtype=np.int64)]
        join_anchor: list[NDArray[np.int64]] = [np.zeros(0, dtype=np.int64)]
        join_score: list[NDArray[np.float64]] = [np.zeros(0)]
        for i, anchor in enumerate(anchors):
            if ends.size == 0:
                break
            # An anchor that cannot stand alone (its own filter gates out one of its
            # detections: value -inf) must be joined; its resource is then exactly-once
            # and its joins are scored without the baseline.
            baseline = anchor.value if math.isfinite(anchor.value) else 0.0
            joined = scores[ends] + gains[i] - baseline
            # A join no better than its hypothesis left alone is dominated: it uses more.
            if masses:
                better = np.flatnonzero(np.isfinite(joined))
            else:
                better = np.flatnonzero(np.isfinite(joined) & (joined > plain[ends]))
            join_h.append(ends[better])
            join_anchor.append(np.full(better.size, i, dtype=np.int64))
            join_score.append(joined[better])
        # A join's score holds no ending of its own: the anchor's ending is in both its
        # terms and the baseline, and cancels.  Its weight is its score.
        joins = Joins(
            hypotheses=np.concatenate(join_h),
            anchors=np.concatenate(join_anchor),
            scores=np.concatenate(join_score),
            required=np.array([not math.isfinite(anchor.value) for anchor in anchors], bool),
        )
        problem = packing_problem(
            hyps,
            carried=len(carried),
            scores=plain,
            log_weights=weights if masses else None,
            counts=np.ones(hyps.count, dtype=bool),
            joins=joins,
        )
        return problem, list(zip(joins.hypotheses.tolist(), joins.anchors.tolist(), strict=True))

    def _scores(
        self, hyps: WindowHypotheses, carried: Sequence[Carried], a: int
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Each hypothesis' window score, its score with its best ending (``tail``) for
        the best set, and with its endings summed for the masses.  A carried track's
        "ended" hypothesis may also have ended at a gap before the window."""
        obj = self.objective
        nodes = hyps.nodes
        leaves = hyps.leaf
        alive = nodes.alive[leaves]
        layer = nodes.layer[leaves]
        scores = hyps.scores.astype(float).copy()
        at = a + np.maximum(layer, 0)
        plain = scores + np.where(alive, obj.terms.tails[at], 0.0)
        weights = scores + np.where(alive, obj.terms.tail_masses[at], 0.0)
        is_carried = hyps.tree < len(carried)
        for h in np.flatnonzero(is_carried & ~hyps.counts_toward_k).tolist():
            c = carried[int(hyps.tree[h])]
            plain[h] = max(scores[h], c.value_ended - c.value_alive)
            weights[h] = float(np.logaddexp(scores[h], c.mass_ended - c.value_alive))
        return scores, plain, weights

    def _join_gains(
        self,
        hyps: WindowHypotheses,
        ends: NDArray[np.int64],
        end_scores: FloatArray,
        anchors: Sequence[Anchor],
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
            # Uninitiated states convert at their next later detection: continue_each
            # takes them in one batch where all convert at the same scan.
            v = leaves[group]
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
                    firsts[i].append((group[rows], state))
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

    def decode(
        self,
        hyps: WindowHypotheses,
        selection: NDArray[np.int64],
        joins: Sequence[tuple[int, int]],
        carried: Sequence[Carried],
        anchors: Sequence[Anchor],
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



def _tree_inputs(carried: Sequence[CarriedTrack], end_gain: float) -> tuple[object, ...]:
    """Everything a window's trees depend on besides the window and the generator: the
    carried tracks' states, to the bit, and the end gain (the population follows from
    the carried tracks' times)."""
    states = tuple(
        (
            c.track_id, c.mean.tobytes(), c.covariance.tobytes(), c.time, c.initiated,
            c.num_detections, c.first_detection_time,
        )
        for c in carried
    )  # fmt: skip
    return (end_gain, states)
