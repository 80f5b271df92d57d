"""Joins continued in lockstep: the refinement's converging continuations of many
requests, for motion models the compiled re-filtering cannot take.

:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging_many` hands
the linear requests to the compiled kernels (:mod:`mapassoc.estimator.refiltering`);
the others (a model set, an extended Kalman filter, a nonlinear sensor) would each be
continued on their own, one small batch per step, and the cost of a numpy call then
lies in its overhead, not its arithmetic.  Here every request takes its next step in
the same round, and the requests whose tracks are at the same scan and go to the same
next scan are stacked into one batch: one prediction, one innovation and one update
for all of them (each row with its own reference's detection).  A request's steps are
those of :meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging`
(the same filter calls on the same rows, so the same numbers); only the batching
differs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.errors import InputError
from mapassoc.estimator.terms import ScanTerms
from mapassoc.estimator.track_paths import CONVERGED, PathState, Trajectory
from mapassoc.filtering.scan_steps import states_agree

ConvergeRequest = tuple[PathState, Trajectory, int]
"""``(start, reference, first)``: tracks at ``start`` continued through
``reference.path[first:]``."""


class RecordingObjective(Protocol):
    """What the lockstep reads of :class:`~mapassoc.estimator.objective.RecordingObjective`
    (a protocol, so that this module does not import the objective that calls it)."""

    times: FloatArray
    terms: ScanTerms

    def advance_missed(self, state: PathState, until: int) -> PathState: ...

    def detect(self, state: PathState, m: int, j: int | IntArray) -> PathState: ...

__all__ = ["ConvergeRequest", "converge_in_lockstep"]


@dataclass
class _Walk:
    """One request on its way: its live tracks, their positions in the request's start,
    the reference, the index of the reference's next detection, and where it stops."""

    state: PathState
    rows: IntArray
    reference: Trajectory
    k: int
    stop: int
    last: int


def converge_in_lockstep(
    objective: RecordingObjective,
    requests: Sequence[ConvergeRequest],
    max_detections: int | None,
) -> list[FloatArray]:
    """:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging` of
    every request (module docstring).

    Parameters
    ----------
    objective : RecordingObjective
    requests : sequence of (PathState, Trajectory, int)
        ``(start, reference, first)``, as for ``continue_converging``.
    max_detections : int, optional
        As for ``continue_converging``.

    Returns
    -------
    list of ndarray, one of shape (B_c,) per request
    """
    out = [np.full(len(start), -math.inf) for start, _, _ in requests]
    walks: dict[int, _Walk] = {}
    for c, (start, reference, first) in enumerate(requests):
        last = len(reference.path) - 1
        stop = last if max_detections is None else min(last, first + max_detections - 1)
        if first > last:  # nothing to continue with: the start's values and the tail
            out[c] = np.array(start.value, dtype=np.float64)
        elif len(start):
            if reference.path[first][0] <= start.scan:
                raise InputError(
                    f"path detection at scan {reference.path[first][0]} is not after the "
                    f"track's state at scan {start.scan}"
                )
            walks[c] = _Walk(start, np.arange(len(start)), reference, first, stop, last)
    scan = min((walk.state.scan for walk in walks.values()), default=0)
    while walks:
        live = [c for c, walk in walks.items() if walk.state.scan == scan]
        if not live:  # the next start
            scan = min(walk.state.scan for walk in walks.values())
            continue
        m = scan + 1
        groups: dict[tuple[bool, bool, bool], list[int]] = {}
        for c in live:
            groups.setdefault(_batch_key(objective, walks[c], m), []).append(c)
        for (detected, _, _), members in groups.items():
            states = _step(objective, walks, members, m, detected=detected)
            for c, state in zip(members, states, strict=True):
                if not detected:
                    walks[c].state = state
                elif not _settle(walks[c], state, out[c]):
                    del walks[c]
        scan = m
    tails = [objective.terms.tails[reference.path[-1][0]] for _, reference, _ in requests]
    return [values + tail for values, tail in zip(out, tails, strict=True)]


def _batch_key(objective: RecordingObjective, walk: _Walk, m: int) -> tuple[bool, bool, bool]:
    """Tracks at one scan step to the next, scan ``m``, together when they are alike:
    detected there by their references or missed, initiated or not, and (detected and
    not initiated) all converting there or not (a request whose tracks would not convert
    together is refused by the step, as one track at a time refuses it)."""
    state = walk.state
    detected = walk.reference.path[walk.k][0] == m
    converts = (
        detected and not state.initiated and bool(np.all(objective.times[m] > state.first_time))
    )
    return detected, state.initiated, converts


def _step(
    objective: RecordingObjective,
    walks: dict[int, _Walk],
    members: list[int],
    m: int,
    *,
    detected: bool,
) -> list[PathState]:
    """The step to scan ``m`` of the requests ``members`` (all at scan ``m - 1``) as one
    batch, cut back into one state per request: the update by each request's reference
    detection there (``detected``), or a miss."""
    states = [walks[c].state for c in members]
    sizes = [len(s) for s in states]
    batch = PathState(
        scan=states[0].scan,
        means=np.concatenate([s.means for s in states]),
        covariances=np.concatenate([s.covariances for s in states]),
        initiated=states[0].initiated,
        first_time=np.concatenate([s.first_time for s in states]),
        value=np.concatenate([s.value for s in states]),
    )
    if detected:
        detections = np.repeat(
            np.array([walks[c].reference.path[walks[c].k][1] for c in members], dtype=np.int64),
            sizes,
        )
        batch = objective.detect(batch, m, detections)
    else:
        batch = objective.advance_missed(batch, m)
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    return [batch.take(np.arange(offsets[i], offsets[i + 1])) for i in range(len(members))]


def _settle(walk: _Walk, state: PathState, out: FloatArray) -> bool:
    """The bookkeeping of ``continue_converging`` after the step to detection
    ``walk.k``: tracks out of gate leave, converged tracks (and every track at the cap)
    take the reference's remaining terms; whether the request goes on."""
    reference, k, last = walk.reference, walk.k, walk.last
    finite = np.flatnonzero(np.isfinite(state.value))
    state, rows = state.take(finite), walk.rows[finite]
    if len(state) == 0:
        return False
    rest = reference.values[last] - reference.values[k]
    if k == walk.stop < last:  # cut short: the reference's terms from here on
        out[rows] = state.value + rest
        return False
    if k == last:
        out[rows] = state.value
        return False
    if state.initiated == bool(reference.initiated[k]):
        mean, cov = reference.means[k], reference.covariances[k]
        if state.means.shape[1:] == mean.shape:
            same = states_agree(state.means, state.covariances, mean, cov, CONVERGED)
            if np.any(same):
                out[rows[same]] = state.value[same] + rest
                keep = np.flatnonzero(~same)
                state, rows = state.take(keep), rows[keep]
                if len(state) == 0:
                    return False
    walk.state, walk.rows, walk.k = state, rows, k + 1
    return True
