"""Group re-solves: closely spaced tracks re-tracked together from a scan to their ends.

Where several targets travel closely spaced for longer than a window (the ``converging``
family: six targets 1.5 noise stds apart for 40 scans, Pd 0.7), the window re-solves and
the pairwise identity moves (:mod:`mapassoc.estimator.identity_moves`) stop at a set in
which fewer tracks than targets share the group's detections, hopping between targets.
The truth scores more J there, but no change of one window or of two tracks leads to it:
each step towards it first costs J.

This move re-tracks a whole group at once.  A *group* is a connected component of the
tracks' close approaches (:func:`~mapassoc.estimator.identity_moves.close_approaches`).
From a start scan ``a``, every track of the group with a detection at or before ``a``
keeps that head; every detection of the group after ``a`` and every free detection is
offered again, and a beam search over joint assignments (the heads to the detections of
each scan, each head detected once or missed, each detection used once) keeps the
:data:`GROUP_BEAM` best joint hypotheses scan by scan to the group's last scan.  A
hypothesis's score is its tracks' exact J (each head valued as if it ended after its last
detection, :attr:`~mapassoc.estimator.track_paths.Trajectory.value`), so the score of the
final best hypothesis is the group's J in the new set; the move is applied only where the
exact J of the new tracks, computed afresh, rises.

Two choices keep the beam from collapsing onto one early decision, both found by
measuring on ``converging`` (a plain beam of 512 hypotheses lost the truth's assignment
at a scan where it trailed the best by 11 nats, and recovered only 1473 of the truth's
1505 nats):

* *state merging*: of the hypotheses that agree on every head's detections over the last
  :data:`MERGE_SCANS` scans, only the best is kept (their heads' states, and so their
  futures, are nearly the same; the Kalman filter forgets the older choices), so the beam
  holds different recent alternatives rather than copies differing in the past;
* *a cap per parent* (:data:`GROUP_BRANCH`): one strong hypothesis cannot fill the beam
  with its own children.

It is the multiple-hypothesis idea (Reid, "An Algorithm for Tracking Multiple Targets",
IEEE TAC 1979; its N-scan merging) applied as a move of a MAP search: exact in its score,
greedy in its acceptance, heuristic only in which joint hypotheses it keeps.  Tracks of
the group that start after ``a`` are first dissolved into the offered detections (they
are often the fragments of the heads' targets); where that does not pay, the move is
tried again with them kept as they are.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.errors import check_stop
from mapassoc.estimator.boundaries import REFINEMENT_PHASE, rises
from mapassoc.estimator.identity_moves import close_approaches
from mapassoc.estimator.objective import RecordingObjective, TrackPath
from mapassoc.estimator.track_paths import PathState, Trajectory

__all__ = [
    "GROUP_BEAM",
    "GROUP_BRANCH",
    "MERGE_SCANS",
    "START_STEP",
    "TrackGroup",
    "close_groups",
    "regroup_tracks",
]

GROUP_BEAM = 256
"""Joint hypotheses the beam keeps after each scan."""

GROUP_BRANCH = 8
"""Most children of one joint hypothesis among those kept at a scan."""

MERGE_SCANS = 2
"""Hypotheses agreeing on the last this many scans' assignments are merged (the best
kept); 1 merged too much on ``converging`` (the beam lost the heads' separation), 3 and
more too little."""

START_STEP = 10
"""Scans between the start scans tried for one group, from its first close approach."""


@dataclass(frozen=True)
class TrackGroup:
    """Tracks connected by close approaches, and the scans of their first and last one.

    Attributes
    ----------
    tracks : tuple of int
    first, last : int
    """

    tracks: tuple[int, ...]
    first: int
    last: int


def close_groups(objective: RecordingObjective, tracks: dict[int, TrackPath]) -> list[TrackGroup]:
    """The connected components of the close-approach graph of ``tracks`` (two tracks or
    more), in order of their first close approach (a union-find over the approaches)."""
    parent: dict[int, int] = {}

    def root(t: int) -> int:
        while parent.setdefault(t, t) != t:
            parent[t] = parent[parent[t]]
            t = parent[t]
        return t

    scans: list[tuple[int, int]] = []
    for a, b, i, _ in close_approaches(objective, tracks):
        parent[root(a)] = root(b)
        scans.append((a, tracks[a][i][0]))
    members: dict[int, list[int]] = {}
    for t in parent:
        members.setdefault(root(t), []).append(t)
    spans: dict[int, list[int]] = {}
    for t, scan in scans:
        spans.setdefault(root(t), []).append(scan)
    groups = [
        TrackGroup(tracks=tuple(sorted(ts)), first=min(spans[r]), last=max(spans[r]))
        for r, ts in members.items()
    ]
    return sorted(groups, key=lambda g: (g.first, g.tracks))


def regroup_tracks(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    *,
    stop: Callable[[], bool] | None = None,
) -> int:
    """Group re-solves (module docstring) wherever the exact J rises; the number made.

    ``tracks`` (id -> path) and ``values`` (id -> v) are updated in place; the heads keep
    their ids, dissolved tracks disappear.  Each group is tried from its first close
    approach every :data:`START_STEP` scans up to its last, first dissolving the tracks
    that start after the start scan, then keeping them.
    """
    made = 0
    for group in close_groups(objective, tracks):
        for a in range(group.first, max(group.first, group.last - START_STEP // 2) + 1, START_STEP):
            tried: list[list[int]] = []
            for dissolve in (True, False):
                check_stop(stop, REFINEMENT_PHASE)
                members = [
                    t for t in group.tracks if t in tracks and (dissolve or tracks[t][0][0] <= a)
                ]
                if members in tried:
                    continue  # no track starts after ``a``: the same re-solve again
                tried.append(members)
                if _try_group(objective, tracks, values, members, a):
                    made += 1
                    break
    return made


def _try_group(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    members: Sequence[int],
    a: int,
) -> bool:
    """One group re-solve from scan ``a``, applied where the exact J rises."""
    heads = [t for t in members if tracks[t][0][0] <= a]
    if len(heads) < 2:
        return False
    prefixes = [tuple(x for x in tracks[t] if x[0] <= a) for t in heads]
    runs = [objective.trajectory(p) for p in prefixes]
    if not all(bool(run.initiated[-1]) for run in runs):
        return False  # a head not yet in the motion model's space: batches need one space
    end = max(tracks[t][-1][0] for t in members)
    offered = _offered(objective, tracks, members, a, end)
    added = _beam(objective, runs, a, end, offered)
    new = {t: prefixes[i] + tuple(added[i]) for i, t in enumerate(heads)}
    new_values = {t: objective.track_value(p) for t, p in new.items()}
    old = sum(values[t] for t in members)
    if not rises(old, sum(new_values.values())):
        return False
    for t in members:
        del tracks[t]
        del values[t]
    tracks.update(new)
    values.update(new_values)
    return True


def _offered(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    members: Sequence[int],
    a: int,
    end: int,
) -> dict[int, IntArray]:
    """Per scan ``a + 1 .. end``: the detections (indices in the scan) no track outside
    ``members`` uses."""
    outside: dict[int, set[int]] = {}
    chosen = set(members)
    for tid, path in tracks.items():
        if tid not in chosen:
            for m, j in path:
                if a < m <= end:
                    outside.setdefault(m, set()).add(j)
    offered = {}
    for m in range(a + 1, end + 1):
        taken = outside.get(m, set())
        free = [j for j in range(len(objective.scans[m].rows)) if j not in taken]
        offered[m] = np.asarray(free, dtype=np.int64)
    return offered


@dataclass(eq=False)
class _Beam:
    """The joint hypotheses after one scan: B hypotheses of K heads each.

    ``states`` (B*K rows) are the heads predicted to the scan with their running value;
    ``last_value``/``last_scan`` (B, K) each head's value at, and scan of, its last
    detection; ``score`` (B,) the hypotheses' J; ``added`` each hypothesis's detections
    per head since the start.
    """

    states: PathState
    last_value: FloatArray
    last_scan: IntArray
    score: FloatArray
    added: list[list[list[tuple[int, int]]]]


def _beam(
    objective: RecordingObjective,
    runs: Sequence[Trajectory],
    a: int,
    end: int,
    offered: dict[int, IntArray],
) -> list[list[tuple[int, int]]]:
    """The best joint hypothesis's detections per head after scan ``a`` up to ``end``
    (``runs``: the heads' trajectories up to ``a``)."""
    beam = _start(objective, runs, a)
    for m in range(a + 1, end + 1):
        beam = _advance(objective, beam, m, offered[m])
    return beam.added[int(np.argmax(beam.score))]


def _start(objective: RecordingObjective, runs: Sequence[Trajectory], a: int) -> _Beam:
    """One hypothesis: the heads as they are, predicted to scan ``a``."""
    states = [run.state(len(run.path) - 1) for run in runs]
    moved = [objective.advance_missed(s, a) for s in states]
    tails = objective.terms.tails
    last_value = np.array([[run.values[-1] for run in runs]])
    last_scan = np.array([[run.path[-1][0] for run in runs]], dtype=np.int64)
    return _Beam(
        states=PathState(
            scan=a,
            means=np.concatenate([s.means for s in moved]),
            covariances=np.concatenate([s.covariances for s in moved]),
            initiated=True,
            first_time=np.concatenate([s.first_time for s in moved]),
            value=np.concatenate([s.value for s in moved]),
        ),
        last_value=last_value,
        last_scan=last_scan,
        score=(last_value + tails[last_scan]).sum(axis=1),
        added=[[[] for _ in runs]],
    )


def _advance(objective: RecordingObjective, beam: _Beam, m: int, offered: IntArray) -> _Beam:
    """The beam after scan ``m``: every hypothesis's heads missed or detected by one of
    ``offered`` each, the best children kept (module docstring)."""
    B, K = beam.last_value.shape
    tails = objective.terms.tails
    missed = objective.advance_missed(beam.states, m)
    gain = np.full((B * K, offered.size), -np.inf)
    detected: dict[tuple[int, int], int] = {}
    found = objective.continue_each(beam.states, [(m, int(j)) for j in offered])
    flat_last = (beam.last_value + tails[beam.last_scan]).reshape(-1)
    for d, (rows, state) in enumerate(found):
        gain[rows, d] = state.value + tails[m] - flat_last[rows]
        for n, row in enumerate(rows.tolist()):
            detected[(row, d)] = n

    def recent(b: int, choice: tuple[int, ...]) -> tuple[object, ...]:
        return tuple((_since(beam.added[b][i], m - MERGE_SCANS), choice[i]) for i in range(K))

    children = _best_children(beam.score, gain.reshape(B, K, -1), recent)
    return _children_beam(beam, children, missed, found, detected, m, offered)


def _since(path: list[tuple[int, int]], scan: int) -> tuple[tuple[int, int], ...]:
    """The detections of ``path`` (in scan order) after ``scan``, read from its end: the
    merging key looks at the last scans only, and a path grows over the whole span."""
    first = len(path)
    while first > 0 and path[first - 1][0] > scan:
        first -= 1
    return tuple(path[first:])


def _children_beam(
    beam: _Beam,
    children: list[tuple[float, int, tuple[int, ...]]],
    missed: PathState,
    found: list[tuple[IntArray, PathState]],
    detected: dict[tuple[int, int], int],
    m: int,
    offered: IntArray,
) -> _Beam:
    """The kept children as the next beam."""
    K = beam.last_value.shape[1]
    pick_state, pick_row = [], []  # per child head: which state array (-1 missed) and row
    last_value = np.empty((len(children), K))
    last_scan = np.empty((len(children), K), dtype=np.int64)
    added = []
    for c, (_, b, choice) in enumerate(children):
        paths = [list(p) for p in beam.added[b]]
        for i, d in enumerate(choice):
            row = b * K + i
            if d < 0:
                pick_state.append(-1)
                pick_row.append(row)
                last_value[c, i], last_scan[c, i] = beam.last_value[b, i], beam.last_scan[b, i]
                continue
            n = detected[(row, d)]
            pick_state.append(d)
            pick_row.append(n)
            last_value[c, i], last_scan[c, i] = found[d][1].value[n], m
            paths[i].append((m, int(offered[d])))
        added.append(paths)
    sources = [missed] + [state for _, state in found]
    means = np.stack([sources[s + 1].means[r] for s, r in zip(pick_state, pick_row, strict=True)])
    covs = np.stack(
        [sources[s + 1].covariances[r] for s, r in zip(pick_state, pick_row, strict=True)]
    )
    value = np.array([sources[s + 1].value[r] for s, r in zip(pick_state, pick_row, strict=True)])
    first_time = np.tile(missed.first_time[:K], len(children))
    return _Beam(
        states=PathState(
            scan=m,
            means=means,
            covariances=covs,
            initiated=True,
            first_time=first_time,
            value=value,
        ),  # fmt: skip
        last_value=last_value,
        last_scan=last_scan,
        score=np.array([score for score, _, _ in children]),
        added=added,
    )


def _best_children(
    score: FloatArray, gain: FloatArray, key: Callable[[int, tuple[int, ...]], object]
) -> list[tuple[float, int, tuple[int, ...]]]:
    """The :data:`GROUP_BEAM` best children ``(score, parent, choice)`` over all parents.

    ``score`` (B,) the parents' scores, ``gain`` (B, K, D) each head's gain from each
    offered detection (``-inf`` outside its gate; a miss gains 0); ``choice[i]`` is head
    ``i``'s detection (-1 missed), no detection twice.  A best-first search over partial
    assignments in order of their score plus every undecided head's largest gain (an
    upper bound), so children come out best first; a child whose ``key`` an earlier one
    had is merged into it, and a parent stops at :data:`GROUP_BRANCH` children.
    """
    B, K, _ = gain.shape
    options, rest = _head_options(gain)
    heap: list[tuple[float, int, int, float, int, tuple[int, ...]]] = [
        (-(float(score[b]) + rest[b, 0]), b, 0, float(score[b]), 0, ()) for b in range(B)
    ]
    heapq.heapify(heap)
    out: list[tuple[float, int, tuple[int, ...]]] = []
    seen: set[object] = set()
    per_parent = np.zeros(B, dtype=np.int64)
    while heap and len(out) < GROUP_BEAM:
        _, b, i, total, used, choice = heapq.heappop(heap)
        if per_parent[b] >= GROUP_BRANCH:
            continue
        if i == K:
            merged = key(b, choice)
            if merged not in seen:
                seen.add(merged)
                out.append((total, b, choice))
                per_parent[b] += 1
            continue
        bound = rest[b, i + 1]
        heapq.heappush(heap, (-(total + bound), b, i + 1, total, used, (*choice, -1)))
        for g, d in options[b][i]:
            if not (used >> d) & 1:
                t = total + g
                heapq.heappush(heap, (-(t + bound), b, i + 1, t, used | (1 << d), (*choice, d)))
    return out


def _head_options(gain: FloatArray) -> tuple[list[list[list[tuple[float, int]]]], FloatArray]:
    """Per parent and head, its finite ``(gain, detection)`` best first; and per parent
    ``rest[b, i]``, the sum of the positive largest gains of heads ``i..K-1``."""
    B, K, _ = gain.shape
    options = []
    rest = np.zeros((B, K + 1))
    for b in range(B):
        heads = []
        for i in range(K):
            finite = np.flatnonzero(np.isfinite(gain[b, i]))
            order = finite[np.argsort(-gain[b, i, finite], kind="stable")]
            heads.append([(float(gain[b, i, d]), int(d)) for d in order])
        options.append(heads)
        for i in range(K - 1, -1, -1):
            top = heads[i][0][0] if heads[i] else 0.0
            rest[b, i] = rest[b, i + 1] + max(0.0, top)
    return options, rest
