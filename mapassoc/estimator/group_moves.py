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

from mapassoc.accelerate import compiled_module
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


_Chain = tuple[tuple[int, int], "_Chain"] | None
"""A head's detections since the start scan, newest first: ``((scan, j), older)``, shared
between a hypothesis and its children (a child adds one cell instead of copying paths)."""


@dataclass(eq=False)
class _Beam:
    """The joint hypotheses after one scan: B hypotheses of K heads each, over U distinct
    head histories.

    A head's state depends only on its detections, and hypotheses share most heads'
    histories (a child changes some heads of its parent; siblings share the rest), so the
    heads are stored once per distinct history (a *row*) and ``slot`` (B, K) names each
    hypothesis head's row: the Kalman steps run once per row, not per hypothesis head.
    Per row: ``states`` (U rows) predicted to the scan with their running value,
    ``last_value``/``last_scan`` (U,) its value at, and scan of, its last detection,
    ``chains`` its detections since the start (:data:`_Chain`), ``recent`` (U,
    :data:`MERGE_SCANS` - 1) its detections (indices in their scans, -1 none) at the
    scans before, newest first.  ``score`` (B,) the hypotheses' J.
    """

    states: PathState
    slot: IntArray
    last_value: FloatArray
    last_scan: IntArray
    chains: list[_Chain]
    recent: IntArray
    score: FloatArray


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
    best = beam.slot[int(np.argmax(beam.score))]
    return [_unrolled(beam.chains[row]) for row in best.tolist()]


def _unrolled(chain: _Chain) -> list[tuple[int, int]]:
    """A chain's detections in scan order."""
    out = []
    while chain is not None:
        out.append(chain[0])
        chain = chain[1]
    return out[::-1]


def _start(objective: RecordingObjective, runs: Sequence[Trajectory], a: int) -> _Beam:
    """One hypothesis: the heads as they are, predicted to scan ``a``."""
    states = [run.state(len(run.path) - 1) for run in runs]
    moved = [objective.advance_missed(s, a) for s in states]
    tails = objective.terms.tails
    last_value = np.array([run.values[-1] for run in runs])
    last_scan = np.array([run.path[-1][0] for run in runs], dtype=np.int64)
    return _Beam(
        states=PathState(
            scan=a,
            means=np.concatenate([s.means for s in moved]),
            covariances=np.concatenate([s.covariances for s in moved]),
            initiated=True,
            first_time=np.concatenate([s.first_time for s in moved]),
            value=np.concatenate([s.value for s in moved]),
        ),
        slot=np.arange(len(runs), dtype=np.int64)[None, :],
        last_value=last_value,
        last_scan=last_scan,
        chains=[None for _ in runs],
        recent=np.full((len(runs), MERGE_SCANS - 1), -1, dtype=np.int64),
        score=np.array([(last_value + tails[last_scan]).sum()]),
    )


def _advance(objective: RecordingObjective, beam: _Beam, m: int, offered: IntArray) -> _Beam:
    """The beam after scan ``m``: every hypothesis's heads missed or detected by one of
    ``offered`` each, the best children kept (module docstring)."""
    U = len(beam.states)
    tails = objective.terms.tails
    missed = objective.advance_missed(beam.states, m)
    found = objective.continue_each(beam.states, [(m, int(j)) for j in offered])
    base = beam.last_value + tails[beam.last_scan]
    gain = np.full((U, offered.size), -np.inf)
    where = np.full((U, offered.size), -1, dtype=np.int64)  # row in found[d][1]
    for d, (rows, state) in enumerate(found):
        gain[rows, d] = state.value + tails[m] - base[rows]
        where[rows, d] = np.arange(rows.size)
    history = _history(beam.recent)[beam.slot]
    parents, choices, scores = _children(beam.score, gain[beam.slot], history)
    rows, picks, slot = _child_rows(beam.slot[parents], choices, offered.size)
    sources = [missed] + [state for _, state in found]
    offsets = np.cumsum([0] + [len(state) for state in sources])
    detected = picks >= 0
    index = rows.copy()
    index[detected] = offsets[picks[detected] + 1] + where[rows[detected], picks[detected]]
    value = np.concatenate([state.value for state in sources])[index]
    return _Beam(
        states=PathState(
            scan=m,
            means=np.concatenate([state.means for state in sources])[index],
            covariances=np.concatenate([state.covariances for state in sources])[index],
            initiated=True,
            first_time=missed.first_time[rows],
            value=value,
        ),
        slot=slot,
        last_value=np.where(detected, value, beam.last_value[rows]),
        last_scan=np.where(detected, m, beam.last_scan[rows]).astype(np.int64),
        chains=[
            beam.chains[r] if d < 0 else ((m, int(offered[d])), beam.chains[r])
            for r, d in zip(rows.tolist(), picks.tolist(), strict=True)
        ],
        recent=_recent(beam.recent[rows], picks, offered),
        score=scores,
    )


def _child_rows(
    parent_rows: IntArray, choices: IntArray, D: int
) -> tuple[IntArray, IntArray, IntArray]:
    """The distinct (parent row, choice) pairs of the children's heads: their parent rows
    (U',), their detections (U',; -1 a miss) and each child head's pair (C, K)."""
    keys = parent_rows * (D + 1) + choices + 1
    unique, inverse = np.unique(keys.reshape(-1), return_inverse=True)
    return unique // (D + 1), unique % (D + 1) - 1, inverse.reshape(keys.shape).astype(np.int64)


def _history(recent: IntArray) -> IntArray:
    """(U,) ids of the rows of ``recent`` (U, :data:`MERGE_SCANS` - 1): equal ids, equal
    detections at the last scans (the merging key's part of the past)."""
    U, S = recent.shape
    if S == 0:
        return np.zeros(U, dtype=np.int64)
    _, ids = np.unique(recent, axis=0, return_inverse=True)
    return ids.reshape(U).astype(np.int64)


def _recent(parents: IntArray, picks: IntArray, offered: IntArray) -> IntArray:
    """The new rows' ``recent`` (U', S): the detection just chosen (``picks`` (U',) into
    ``offered``, -1 a miss), then the parent row's (``parents`` (U', S)) without the
    oldest."""
    chosen = np.full(picks.shape, -1, dtype=np.int64)
    chosen[picks >= 0] = offered[picks[picks >= 0]]
    return np.concatenate([chosen[:, None], parents], axis=1)[:, : parents.shape[1]]


def _children(
    score: FloatArray, gain: FloatArray, history: IntArray
) -> tuple[IntArray, IntArray, FloatArray]:
    """The kept children's parents (C,), choices (C, K) and scores (C,): the compiled
    search (:mod:`mapassoc.estimator.compiled_beam`) where numba loads, else its twin
    :func:`_best_children`."""
    kernels = compiled_module("mapassoc.estimator.compiled_beam")
    if kernels is not None:
        return kernels.best_children(
            score, np.ascontiguousarray(gain), history, GROUP_BEAM, GROUP_BRANCH
        )
    children = _best_children(score, gain, history)
    K = gain.shape[1]
    return (
        np.array([b for _, b, _ in children], dtype=np.int64),
        np.array([c for _, _, c in children], dtype=np.int64).reshape(-1, K),
        np.array([total for total, _, _ in children]),
    )


def _best_children(
    score: FloatArray, gain: FloatArray, history: IntArray
) -> list[tuple[float, int, tuple[int, ...]]]:
    """The :data:`GROUP_BEAM` best children ``(score, parent, choice)`` over all parents.

    ``score`` (B,) the parents' scores, ``gain`` (B, K, D) each head's gain from each
    offered detection (``-inf`` outside its gate; a miss gains 0), ``history`` (B, K) an
    id of each parent head's recent detections; ``choice[i]`` is head ``i``'s detection
    (-1 missed), no detection twice.  A best-first search over partial assignments in
    order of their score plus every undecided head's largest gain (an upper bound), so
    children come out best first; a child whose history and choice per head an earlier
    one had is merged into it, and a parent stops at :data:`GROUP_BRANCH` children.
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
    pasts = [tuple(row) for row in history.tolist()]
    while heap and len(out) < GROUP_BEAM:
        _, b, i, total, used, choice = heapq.heappop(heap)
        if per_parent[b] >= GROUP_BRANCH:
            continue
        if i == K:
            merged = (pasts[b], choice)
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
