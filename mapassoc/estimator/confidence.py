"""How sure a (refined) track set is: existence and association probabilities.

The confidence pass: one sweep over the recording in windows of ``window_length``
scans, each window's program built as the refinement's re-solves build theirs
(:class:`~mapassoc.estimator.boundaries.WindowBoundaries`: the tracks outside it fixed,
the tracks crossing it carried in and anchored after it), its marginals computed by the
window solver (:meth:`~mapassoc.estimator.cluster_solving.ClusterSolver.marginals`, K
free) with the weights ``exp(J)`` (endings summed).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray
from mapassoc.errors import check_stop
from mapassoc.estimator.boundaries import Carried, WindowBoundaries
from mapassoc.estimator.cluster_solving import ClusterSolver, ClusterStatus, WindowMarginals
from mapassoc.estimator.hypotheses import HypothesisGenerator, WindowHypotheses
from mapassoc.estimator.objective import TrackPath
from mapassoc.formulations.packing import gather_rows

__all__ = [
    "ASSOCIATION_FLOOR",
    "CONFIDENCE_PHASE",
    "ConfidencePass",
    "TrackConfidence",
]

CONFIDENCE_PHASE = "the confidence pass"
"""The phase a stop during the confidence pass names (in its StopRequested)."""

MARGINALS_WORK = 50_000
"""Transitions of the exact forward-backward search per cluster of the confidence pass;
past them, or on course for more than ``WORK_PROJECTION`` times them, the cluster's
marginals come from the beam of :data:`MARGINALS_BEAM` frontiers (the projection spares
the searches that would fail anyway, every search that finishes still finishing)."""

MARGINALS_BEAM = 32
"""Frontiers of the beam of a cluster past :data:`MARGINALS_WORK`."""


def _probability(total: float) -> float:
    """A sum of the probabilities of exclusive events, rounded into [0, 1] (more than
    1e-9 out is a fault, not rounding, and raises)."""
    if not -1e-9 <= total <= 1.0 + 1e-9:
        raise RuntimeError(f"a sum of exclusive probabilities came out {total!r}")
    return min(1.0, max(0.0, total))


@dataclass(frozen=True, eq=False)
class TrackConfidence:
    """How sure the refined track set is of each track and detection (:meth:`ConfidencePass.run`).

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


class ConfidencePass:
    """Existence and association probabilities of a track set (module docstring).

    Parameters
    ----------
    boundaries : WindowBoundaries
        Builds each window's trees and program.
    generator : HypothesisGenerator
        Grows and prunes the windows' trees.
    solver : ClusterSolver
        The window solver whose marginals are taken.
    window_length : int
    values : callable
        Every track's exact value (track id -> path, to track id -> value).
    """

    def __init__(
        self,
        *,
        boundaries: WindowBoundaries,
        generator: HypothesisGenerator,
        solver: ClusterSolver,
        window_length: int,
        values: Callable[[Mapping[int, TrackPath]], dict[int, float]],
    ) -> None:
        self.boundaries = boundaries
        self.generator = generator
        self.solver = solver
        self.window_length = int(window_length)
        self.values = values

    def run(
        self, tracks: Mapping[int, TrackPath], *, stop: Callable[[], bool] | None = None
    ) -> TrackConfidence:
        """Existence and association probabilities of a (refined) track set.

        One pass over the recording in windows of ``window_length`` scans: each window's
        program is built as in
        :meth:`~mapassoc.estimator.refinement.Refiner.resolve_window` (the tracks outside
        it fixed, the tracks crossing it carried in and anchored after it), and the
        posterior marginal of every hypothesis and join is computed by the window
        solver (:meth:`~mapassoc.estimator.cluster_solving.ClusterSolver.marginals`) with the
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
        scans = self.boundaries.scans
        current = {int(tid): tuple(path) for tid, path in tracks.items() if path}
        values = self.values(current)
        track_of = {p: tid for tid, path in current.items() for p in path}
        existence: dict[int, float] = {}
        associations: dict[int, dict[int, float]] = {tid: {} for tid in current}
        exact = True
        windows = 0
        M = len(scans)
        for a in range(0, M, self.window_length):
            check_stop(stop, CONFIDENCE_PHASE)
            b = min(a + self.window_length, M)
            windows += 1
            window_exact = self._window(current, values, track_of, a, b, existence, associations)
            exact = exact and window_exact
        for tid in current:
            existence.setdefault(tid, math.nan)  # its first detection's tree was pruned
            own = {int(scans[m].rows[j]) for m, j in current[tid]}
            associations[tid] = {
                row: _probability(p)
                for row, p in sorted(associations[tid].items())
                if p >= ASSOCIATION_FLOOR or row in own
            }
        return TrackConfidence(existence, associations, exact, windows)

    def _window(
        self,
        current: Mapping[int, TrackPath],
        values: Mapping[int, float],
        track_of: Mapping[tuple[int, int], int],
        a: int,
        b: int,
        existence: dict[int, float],
        associations: dict[int, dict[int, float]],
    ) -> bool:
        """One window's probabilities added to ``existence`` and ``associations``;
        whether its marginals were exact (False, and nothing added, where a cluster's
        beam found no feasible set)."""
        hyps, carried, anchors, _ = self.boundaries.hypotheses(
            current, values, a, b, self.generator
        )
        problem, joins = self.boundaries.program(
            hyps, carried, anchors, a, prune_log_ratio=self.generator.prune_log_ratio, masses=True
        )
        if problem.num_hypotheses == 0:
            return True
        found = self.solver.marginals(problem, work_limit=MARGINALS_WORK, beam_width=MARGINALS_BEAM)
        probabilities = found.probabilities
        if not np.all(np.isfinite(probabilities)):
            # A cluster whose beam kept no feasible set, even widened: this window's
            # probabilities are unknown (its tracks' existence stays nan, as for a
            # pruned first tree) rather than a stopped run.
            return False
        base = np.r_[np.arange(hyps.count), np.array([h for h, _ in joins], dtype=np.int64)]
        owner = _tree_owners(hyps, carried, track_of, a)
        uses = _Uses.of(hyps, base)
        _add_associations(associations, uses, hyps, base, owner, probabilities)
        det = hyps.detections
        window_index = {
            (a + int(det.scan_position[d]), int(det.index_in_scan[d])): d for d in range(det.count)
        }
        for tid in sorted(current):
            if a <= current[tid][0][0] < b:
                mine = np.array(
                    [window_index[p] for p in current[tid] if p in window_index], dtype=np.int64
                )
                existence[tid] = self._existence(found, uses, mine)
        return found.status is ClusterStatus.EXACT

    def _existence(self, found: WindowMarginals, uses: _Uses, mine: NDArray[np.int64]) -> float:
        """The probability that some track uses one of the detections ``mine``."""
        value = ClusterSolver.any_of(found, uses.using(mine), work_limit=MARGINALS_WORK)
        if math.isnan(value):
            # A cluster had only the beam's marginals: the largest probability that one
            # of the detections is used, a lower bound of the union.
            value = _probability(uses.largest_use(mine, found.probabilities))
        return value


def _tree_owners(
    hyps: WindowHypotheses,
    carried: Sequence[Carried],
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
