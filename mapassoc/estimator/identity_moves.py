"""Identity moves over the whole recording: switch, split and merge, each on its exact ΔJ.

The refinement's window re-solves change a track set inside one window at a time, and its
fragment links join an end to a start at most ``link_gap`` scans later.  Where targets
travel close together for longer than a window, or where the per-tree cap cut the
alternatives a re-solve needed, what is left wrong is who each target is: two tracks that
exchanged their continuations, a track that jumped from one target to another, two pieces
of one target far apart.  These moves change exactly that, over the whole recording, and
each is accepted only where the recording objective J (:mod:`mapassoc.estimator.objective`)
rises, computed from the changed tracks' whole filter runs, so J never decreases.

The move family is the one of Oh, Russell and Sastry ("Markov Chain Monte Carlo Data
Association for Multi-Target Tracking", IEEE TAC 2009) and of the batch trajectory-PMBM
of Xia, García-Fernández, Meyer and Svensson (IEEE TAES 2024): *switch*, *split* and
*merge*.  mapassoc makes them greedy and exact instead of sampled: a move is proposed
where it can pay and applied where its exact ΔJ is positive.

* **switch** (:func:`switch_tracks`): two tracks both detected at scan ``m`` exchange
  everything after ``m``.  Proposed where their detections at ``m`` are close (a close
  approach, :data:`SWITCH_DETECTION_DISTANCE`); its ΔJ is proposed by
  re-filtering each tail from the other head's state (converging to the tail's own run,
  :meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging_many`).
* **split** (:func:`split_tracks`): a track is cut before a detection whose term is
  negative (the detection costs the track more than it pays: a jump of the innovation).
  The head's value is read off the track's own run, the tail's is a new track's.
* **extend** (:func:`extend_tracks`): a track takes a detection no track uses, at most
  ``gap`` scans after its end or before its start (a missed end or start taken back).
  Only detections in the track's gate are scored (the trees' gate, through
  :meth:`~mapassoc.estimator.objective.RecordingObjective.continue_each` after the end;
  one filter step from the new first detection before the start).
* **merge** (:func:`merge_tracks`): fragment linking
  (:func:`~mapassoc.estimator.linking.link_fragments`) over any gap, with the missed
  detections' terms between.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mapassoc.errors import check_stop
from mapassoc.estimator.boundaries import REFINEMENT_PHASE, rises
from mapassoc.estimator.linking import link_fragments
from mapassoc.estimator.objective import RecordingObjective, TrackPath

__all__ = [
    "SWITCH_DETECTION_DISTANCE",
    "EXTEND_SCANS",
    "close_approaches",
    "IdentityMoveCounts",
    "switch_tracks",
    "split_tracks",
    "extend_tracks",
    "merge_tracks",
    "identity_moves",
]

SWITCH_DETECTION_DISTANCE = 25.0
"""Largest squared Mahalanobis distance of two tracks' detections at a common scan (their
measurement residual under twice the sensor's noise covariance, the law of the difference
of two detections of one point) at which a switch after that scan is proposed: about 7
noise standard deviations, where the two tracks' gates overlap.  The detections, not the
filtered states, are compared: where two targets cross, their positions meet while their
velocities differ.  A proposal rule only: it bounds the work, never J."""

EXTEND_SCANS = 2
"""Most scans between a track's end (or start) and a free detection an extension gives
it: a start or an end the forward pass missed is a scan or two away; detections further
off are the merges' and the window re-solves' (before a start the gate of a new track is
wide, so every scan further back adds many candidates, each a filter run)."""

MAX_ROUNDS = 100
"""Most rounds of one move kind in one call: a deterministic work budget (each accepted
move raises J, so the rounds end anyway; the budget bounds a pathological recording)."""


@dataclass(frozen=True)
class IdentityMoveCounts:
    """Moves made by :func:`identity_moves`.

    Attributes
    ----------
    switches, splits, extensions, merges : int
    """

    switches: int = 0
    splits: int = 0
    extensions: int = 0
    merges: int = 0

    @property
    def total(self) -> int:
        """All moves made."""
        return self.switches + self.splits + self.extensions + self.merges


def identity_moves(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    *,
    next_id: int,
    refilter_detections: int,
    extend_gap: int = EXTEND_SCANS,
    stop: Callable[[], bool] | None = None,
) -> tuple[IdentityMoveCounts, int]:
    """Switches, splits, extensions (within ``extend_gap`` scans), then merges over any
    gap, each where the exact J rises.

    ``tracks`` (id -> path) and ``values`` (id -> v) are updated in place; returns the
    counts and the next free track id (splits make new tracks).  ``stop`` is polled
    before every round.
    """
    switches = switch_tracks(
        objective, tracks, values, refilter_detections=refilter_detections, stop=stop
    )
    splits, next_id = split_tracks(objective, tracks, values, next_id=next_id, stop=stop)
    extensions = extend_tracks(objective, tracks, values, gap=extend_gap, stop=stop)
    merges = merge_tracks(
        objective, tracks, values, refilter_detections=refilter_detections, stop=stop
    )
    counts = IdentityMoveCounts(
        switches=switches, splits=splits, extensions=extensions, merges=merges
    )
    return counts, next_id


# -- switch ------------------------------------------------------------------------------
def switch_tracks(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    *,
    refilter_detections: int,
    stop: Callable[[], bool] | None = None,
) -> int:
    """Exchange the tails of two tracks after a common scan where J rises; the number made.

    Each round proposes every close approach (module docstring), applies the proposals
    that share no track in decreasing order of proposed gain, each only where the exact
    values of the two new tracks beat the old ones, and repeats until a round applies
    none (or :data:`MAX_ROUNDS`).  The tracks keep their ids with their heads.
    """
    made = 0
    for _ in range(MAX_ROUNDS):
        check_stop(stop, REFINEMENT_PHASE)
        proposals = _switch_proposals(objective, tracks, values, refilter_detections)
        applied = _apply_switches(objective, tracks, values, proposals)
        made += applied
        if applied == 0:
            break
    return made


def _switch_proposals(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    refilter: int,
) -> list[tuple[float, int, int, int, int]]:
    """(proposed gain, track a, track b, a's index of the cut, b's) of each close
    approach whose proposed switch rises, the largest gain first.

    Both continuations of every approach (a's head with b's tail, b's head with a's) are
    re-filtered in one batch
    (:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging_many`).
    """
    approaches = close_approaches(objective, tracks)
    runs = {
        tid: objective.trajectory(tracks[tid]) for tid in {t for a in approaches for t in a[:2]}
    }
    requests = []
    for a, b, i, j in approaches:
        requests.append((runs[a].state(i), runs[b], j + 1))
        requests.append((runs[b].state(j), runs[a], i + 1))
    continued = objective.continue_converging_many(requests, max_detections=refilter)
    proposals = []
    for n, (a, b, i, j) in enumerate(approaches):
        gain = float(continued[2 * n][0] + continued[2 * n + 1][0]) - (values[a] + values[b])
        if rises(0.0, gain):
            proposals.append((gain, a, b, i, j))
    return sorted(proposals, reverse=True)


def close_approaches(
    objective: RecordingObjective, tracks: dict[int, TrackPath]
) -> list[tuple[int, int, int, int]]:
    """``(a, b, i, j)``: tracks ``a < b`` whose detections ``i`` and ``j`` are at one
    scan, each followed by more detections, and close (:data:`SWITCH_DETECTION_DISTANCE`).

    Scan by scan, the detections of the tracks detected there are compared all at once
    (the squared Mahalanobis distance of their residual under twice the sensor's noise
    covariance), so the cost grows with the tracks per scan, not with the pairs of tracks.
    """
    at_scan: dict[int, list[tuple[int, int, int]]] = {}
    for tid in sorted(tracks):
        for i, (m, d) in enumerate(tracks[tid][:-1]):
            at_scan.setdefault(m, []).append((tid, i, d))
    found = []
    for m, entries in sorted(at_scan.items()):
        if len(entries) < 2:
            continue
        measurement = objective.config.sensors[objective.scans[m].sensor].measurement
        z = objective.scans[m].detections[[d for _, _, d in entries]]
        diff = measurement.residual(z[:, None, :], z[None, :, :])
        inverse = np.linalg.inv(2.0 * measurement.noise_covariance)
        d2 = np.einsum("abi,ij,abj->ab", diff, inverse, diff)
        for p, q in zip(*np.nonzero(np.triu(d2 <= SWITCH_DETECTION_DISTANCE, k=1)), strict=True):
            (a, i, _), (b, j, _) = entries[p], entries[q]
            found.append((a, b, i, j))
    return found


def _apply_switches(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    proposals: list[tuple[float, int, int, int, int]],
) -> int:
    """Apply the proposals that share no track where the exact J rises."""
    used: set[int] = set()
    applied = 0
    for _gain, a, b, i, j in proposals:
        if a in used or b in used:
            continue  # the other's paths changed: proposed again next round
        path_a, path_b = tracks[a], tracks[b]
        new_a = path_a[: i + 1] + path_b[j + 1 :]
        new_b = path_b[: j + 1] + path_a[i + 1 :]
        value_a, value_b = objective.track_value(new_a), objective.track_value(new_b)
        if not rises(values[a] + values[b], value_a + value_b):
            continue
        used.update((a, b))
        tracks[a], tracks[b] = new_a, new_b
        values[a], values[b] = value_a, value_b
        applied += 1
    return applied


# -- split -------------------------------------------------------------------------------
def split_tracks(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    *,
    next_id: int,
    stop: Callable[[], bool] | None = None,
) -> tuple[int, int]:
    """Cut tracks before a detection whose term is negative, where J rises.

    Per track, every such cut is scored exactly (the head's value from the track's own
    run, the tail's from its own filter run) and the best rising one is made; the pieces
    are tried again until none rises (or :data:`MAX_ROUNDS`).  The head keeps the id,
    the tail gets ``next_id`` on.  Returns the number of cuts and the next free id.
    """
    made = 0
    pending = sorted(tracks)
    for _ in range(MAX_ROUNDS):
        if not pending:
            break
        check_stop(stop, REFINEMENT_PHASE)
        again: list[int] = []
        for tid in pending:
            cut = _best_split(objective, tracks[tid], values[tid])
            if cut is None:
                continue
            k, head, tail = cut
            path = tracks[tid]
            tracks[tid], values[tid] = path[:k], head
            tracks[next_id], values[next_id] = path[k:], tail
            again.extend((tid, next_id))
            next_id += 1
            made += 1
        pending = again
    return made, next_id


def _best_split(
    objective: RecordingObjective, path: TrackPath, value: float
) -> tuple[int, float, float] | None:
    """``(k, v(head), v(tail))`` of the best cut before detection ``k`` that raises J,
    among the detections whose term is negative; None if no such cut rises."""
    run = objective.trajectory(path)
    tails = objective.terms.tails
    steps = np.diff(run.values)  # the term of each detection after the first
    best: tuple[int, float, float] | None = None
    for k in np.flatnonzero(steps < 0.0) + 1:
        head = float(run.values[k - 1] + tails[path[k - 1][0]])
        tail = objective.track_value(path[k:])
        if rises(value if best is None else best[1] + best[2], head + tail):
            best = (int(k), head, tail)
    return best


# -- extend ------------------------------------------------------------------------------
def extend_tracks(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    *,
    gap: int,
    stop: Callable[[], bool] | None = None,
) -> int:
    """Give tracks free detections at most ``gap`` scans after their end or before their
    start, where J rises; the number of detections taken.

    Each round scores every track's best extension by one free detection, applies them
    in decreasing order of gain (a detection to one track), each on the exact value of
    the extended track, and repeats until a round applies none (or :data:`MAX_ROUNDS`).
    """
    made = 0
    for _ in range(MAX_ROUNDS if gap > 0 else 0):
        check_stop(stop, REFINEMENT_PHASE)
        free = _free_detections(objective, tracks)
        proposals = []
        for tid in sorted(tracks):
            best = _best_extension(objective, tracks[tid], values[tid], free, gap)
            if best is not None:
                proposals.append((best[0], tid, best[1]))
        applied = 0
        taken: set[tuple[int, int]] = set()
        for _gain, tid, path in sorted(proposals, reverse=True):
            added = set(path) - set(tracks[tid])
            value = objective.track_value(path)
            if added & taken or not rises(values[tid], value):
                continue
            taken |= added
            tracks[tid], values[tid] = path, value
            applied += 1
        made += applied
        if applied == 0:
            break
    return made


def _free_detections(
    objective: RecordingObjective, tracks: dict[int, TrackPath]
) -> dict[int, list[int]]:
    """Per scan, the detections (indices in the scan) no track uses."""
    used = {d for path in tracks.values() for d in path}
    return {
        m: [j for j in range(scan.size) if (m, j) not in used]
        for m, scan in enumerate(objective.scans)
    }


def _best_extension(
    objective: RecordingObjective,
    path: TrackPath,
    value: float,
    free: dict[int, list[int]],
    gap: int,
) -> tuple[float, TrackPath] | None:
    """``(gain, extended path)`` of the track's best extension by one free detection
    within ``gap`` scans of its end or its start; None if none raises J."""
    M = len(objective.scans)
    last, first = path[-1][0], path[0][0]
    after = [(m, j) for m in range(last + 1, min(M, last + gap + 1)) for j in free[m]]
    candidates: list[tuple[float, TrackPath]] = []
    if after:
        run = objective.trajectory(path)
        found = objective.continue_each(run.state(len(path) - 1), after)
        for detection, (ok, state) in zip(after, found, strict=True):
            if ok.size:
                extended = float(state.value[0] + objective.terms.tails[detection[0]])
                candidates.append((extended - value, (*path, detection)))
    for m in range(max(0, first - gap), first):
        if not free[m]:
            continue
        # Every free detection of the scan as a new track's first, continued by this
        # track's first detection in one batch: only those whose gate it falls in count.
        reach = objective.continue_paths(objective.start_paths(m, free[m]), path[:1])
        for k in np.flatnonzero(np.isfinite(reach.value)):
            longer = ((m, free[m][k]), *path)
            candidates.append((objective.track_value(longer) - value, longer))
    rising = [c for c in candidates if rises(0.0, c[0])]
    return max(rising, key=lambda c: c[0]) if rising else None


# -- merge -------------------------------------------------------------------------------
def merge_tracks(
    objective: RecordingObjective,
    tracks: dict[int, TrackPath],
    values: dict[int, float],
    *,
    refilter_detections: int,
    stop: Callable[[], bool] | None = None,
) -> int:
    """Join tracks that end to tracks that start any number of scans later, where J
    rises (:func:`~mapassoc.estimator.linking.link_fragments` with the whole recording
    as the gap); the number of joins made."""
    return link_fragments(
        objective,
        tracks,
        values,
        link_gap=len(objective.scans),
        refilter_detections=refilter_detections,
        stop=stop,
    )
