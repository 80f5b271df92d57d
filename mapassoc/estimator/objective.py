"""The whole recording's objective: J(omega) = log p(omega | Z) + const for a track set.

A sliding window scores its hypotheses with the terms of Perry's MAP formulation under
mapassoc's birth model (``docs/model.md``, sections 2-3).  Over a whole recording the
same terms add up, track by track, to the log-posterior of a track set ``omega`` against
the empty one (every detection a false alarm, no target ever detected):

    J(omega) = log p(omega | Z) - log p(empty | Z) = sum_{tau in omega} v(tau),

because under the birth model the targets never detected form a Poisson process whose
law does not depend on ``omega`` (its factor cancels in the ratio; ``docs/model.md``,
eq. (B), with the window replaced by the recording), and the false-alarm factor of
Perry's eq. (10) becomes ``lambda^{-T_m}`` per scan once the shuffle of the scan is
accounted for (eq. (★) there), which each track takes as its ``- log lambda`` per
detection.  A track ``tau`` with detections at scans ``f = m_1 < m_2 < ... < m_L`` has

    v(tau) = log u_f + log Pd_f - log lambda_bar_f                    (first detection)
           + sum_{m = f+1}^{m_L} [ dt_m log Ps + c_m ]                  (every later scan)
           + tail(m_L),

with ``c_m = log Pd_m + log N(nu_m; 0, S_m) - log lambda_m`` where it is detected
(Kalman innovation of its own filter; ``-inf`` outside the gate, which the window model
never associates), ``c_m = log(1 - Pd_m P_G)`` where it is missed, ``u_f`` the
undetected-target mean of :mod:`mapassoc.models.population` from the recording's first
scan, and::

    tail(m) = max( log(1 - Ps^{t_{m+1} - t_m}),
                   (t_{m+1} - t_m) log Ps + log(1 - Pd_{m+1} P_G) + tail(m + 1) ),
    tail(last scan) = 0,

the best of the track's endings after its last detection (it ends in the gap after scan
``m``, or is missed at scan ``m + 1`` and ends later, or lives to the recording's end).
The death time is thus part of ``omega`` and maximised over, as the windows' "ended"
and "missed to the end" hypotheses are.  These are exactly the terms the hypothesis
trees use (:mod:`mapassoc.estimator.hypotheses`), taken from the same table of terms
(:class:`~mapassoc.estimator.terms.ScanTerms`) and computed with the same filter steps:
every prediction, innovation (the one ``S``), gate, log-likelihood and update here and in
the trees is a call of the batched interface :mod:`mapassoc.filtering.batch`, so a
recording no longer than one window gets J equal to its window's best objective by
construction (the same states, bit for bit on the numpy backend).

J is defined under the birth model (the default ``k_prior``); a named prior on K
reweights each window's count of targets and has no whole-recording counterpart.

Code that scores a track set found in any way (the forward pass, a refinement, another
tracker's hard associations) calls :meth:`RecordingObjective.value`;
:mod:`mapassoc.estimator.refinement` uses the batched continuation
(:meth:`RecordingObjective.continue_paths`) to score joins exactly.  Runs whose every
step is linear (a track's tail in :meth:`RecordingObjective.trajectory`, the joins of
:meth:`RecordingObjective.continue_converging_many`) go to the re-filtering engine
:mod:`mapassoc.estimator.refiltering`, whose backend (compiled kernels or numpy) is
chosen in :func:`mapassoc.filtering.compiled.filter_backend`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.data.config import Config, check_config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.converging import converge_in_lockstep
from mapassoc.estimator.refiltering import ConvergeRequest, Refiltering
from mapassoc.estimator.terms import ScanTerms, detection_term
from mapassoc.estimator.track_paths import CONVERGED, PathState, TrackPath, Trajectory
from mapassoc.filtering.batch import KalmanFilter
from mapassoc.models.birth import (
    birth_states,
    convert_initiated_many,
    initiation_measurement,
    initiation_model,
    needs_conversion,
)
from mapassoc.models.interacting import filter_state_dim

__all__ = [
    "TrackPath",
    "PathState",
    "Trajectory",
    "TRAJECTORY_CACHE",
    "CONVERGED",
    "RecordingObjective",
    "paths_from_rows",
    "rows_from_paths",
]

TRAJECTORY_CACHE = 20_000
"""Most track runs :meth:`RecordingObjective.trajectory` keeps."""


class RecordingObjective:
    """J(omega) of track sets over one recording (module docstring).

    Parameters
    ----------
    config : Config
        Motion model, sensors, birth model and the estimator's ``gate_probability``:
        the model the windows use.
    scans : sequence of Scan
        The whole recording, sorted by (time, sensor).

    Attributes
    ----------
    terms : ScanTerms
        The per-scan terms of the model (:mod:`mapassoc.estimator.terms`): the first
        detection, miss, survival and end terms, the tails and their masses, ``log Pd``,
        ``log lambda`` and the gates.
    undetected_after : tuple of UndetectedTargets, length M
        The targets never detected, just after each scan (where a window starting at
        the next scan continues from).
    """

    def __init__(self, *, config: Config, scans: Sequence[Scan]) -> None:
        self.config = check_config(config)
        self.scans = tuple(scans)
        if not self.scans:
            raise InputError("a recording objective needs at least one scan")
        birth = config.birth
        self.motion = config.motion
        self.birth = birth
        self.gate_probability = float(config.estimator.pruning.gate_probability)
        self._init_model = initiation_model(self.motion)
        self._converts = needs_conversion(self.motion)
        self._sensors = [config.sensors[s.sensor] for s in self.scans]
        self.terms = ScanTerms.of_recording(config, self.scans)
        self.times = self.terms.times
        self._trajectories: dict[TrackPath, Trajectory] = {}
        self.kalman = KalmanFilter(motion=self.motion)
        self.refiltering = Refiltering(
            scans=self.scans,
            measurements=[sensor.measurement for sensor in self._sensors],
            motion=self.motion,
            terms=self.terms,
            kalman=self.kalman,
        )
        self._row_of = {
            int(row): (m, j) for m, scan in enumerate(self.scans) for j, row in enumerate(scan.rows)
        }

    # -- the pieces --------------------------------------------------------------------
    def misses_between(self, first: int, last: int) -> float:
        """Sum of ``dt log Ps + log(1 - Pd P_G)`` over scans ``first..last`` (0 if empty)."""
        return self.terms.misses_between(first, last)

    def start_path(self, path: TrackPath) -> PathState:
        """The state of a track at its first detection, valued by the first-detection term."""
        m, j = path[0]
        return self.start_paths(m, [j])

    def start_paths(self, m: int, detections: Sequence[int]) -> PathState:
        """A batch of new tracks, one per detection of scan ``m`` (indices in the scan),
        each at its first detection and valued by the first-detection term."""
        scan = self.scans[m]
        z = scan.detections[np.asarray(detections, dtype=np.int64)].reshape(len(detections), -1)
        x, P = birth_states(self.motion, self._sensors[m].measurement, z, self.birth)
        return PathState(
            scan=m,
            means=x,
            covariances=P,
            initiated=not self._converts,
            first_time=np.full(len(detections), scan.time),
            value=np.full(len(detections), self.terms.birth[m]),
        )

    def continue_paths(self, start: PathState, path: Iterable[tuple[int, int]]) -> PathState:
        """Advance a batch of tracks through ``path``: the same detections for each.

        Every scan after ``start.scan`` up to the last scan of ``path`` is a step: the
        survival term and a miss, or the continuation by the path's detection at that
        scan (Kalman/EKF prediction and update, as the hypothesis trees do).

        Parameters
        ----------
        start : PathState
            States at scan ``start.scan``; ``path`` must start after it.
        path : iterable of (int, int)
            ``(scan, index in scan)`` in increasing scan order.

        Returns
        -------
        PathState
            At the last scan of ``path`` (``start`` itself when ``path`` is empty).
        """
        state = start
        for m, j in path:
            if m <= state.scan:
                raise InputError(
                    f"path detection at scan {m} is not after the track's state at scan "
                    f"{state.scan}"
                )
            if m > state.scan + 1:
                state = self.advance_missed(state, m - 1)
            state = self.detect(state, m, j)
        return state

    def continue_each(
        self, start: PathState, detections: Sequence[tuple[int, int]]
    ) -> list[tuple[IntArray, PathState]]:
        """Each detection ``(m, j)`` (after ``start.scan``) tried as the next one of every
        track of ``start``.

        Returns, per detection, the tracks (positions in ``start``) whose gate it falls
        in and their states after it: what ``continue_paths(start, [(m, j)])`` gives,
        restricted to its finite values.  For tracks in the motion model's space the
        prediction to each scan and the innovation are computed once for all the
        detections of that scan, the gate is the trees' (:meth:`Innovation.gate
        <mapassoc.filtering.batch.Innovation.gate>`), and only the pairs inside it are
        updated (refinement tries the first detection of every anchor after every leaf
        of a window this way).
        """
        by_scan: dict[int, list[int]] = {}
        for i, (m, _) in enumerate(detections):
            if m <= start.scan:
                raise InputError(
                    f"path detection at scan {m} is not after the track's state at scan "
                    f"{start.scan}"
                )
            by_scan.setdefault(int(m), []).append(i)
        found: dict[int, tuple[IntArray, PathState]] = {}
        for m, indices in by_scan.items():
            # An uninitiated batch converts at scan m together when every track's first
            # detection is earlier (the trees' rule); otherwise track by track.
            if start.initiated or bool(np.all(self.scans[m].time > start.first_time)):
                found.update(self._continue_at(start, m, [(i, detections[i][1]) for i in indices]))
                continue
            for i in indices:
                state = self.continue_paths(start, (detections[i],))
                ok = np.flatnonzero(np.isfinite(state.value))
                found[i] = (ok, state.take(ok))
        return [found[i] for i in range(len(detections))]

    def _continue_at(
        self, start: PathState, m: int, requested: Sequence[tuple[int, int]]
    ) -> dict[int, tuple[IntArray, PathState]]:
        """:meth:`continue_each` of the detections ``requested`` (``(key, index in scan
        m)``) at one scan, for initiated tracks or uninitiated ones that all convert at
        scan ``m``: one prediction and one innovation for all of them, the gate of every
        (track, detection) pair (the trees' gate), one update per pair inside it (and
        the conversion).  Keyed by ``key``."""
        missed = self.advance_missed(start, m - 1)
        x, P = self._predict(missed, m)
        measurement = self._sensors[m].measurement
        if not start.initiated:
            measurement = initiation_measurement(self.motion, measurement)
        innovation = self.kalman.innovation(measurement, x, P)
        measured = self.scans[m].detections[[j for _, j in requested]]
        pairs = innovation.gate(measured, float(self.terms.thresholds[m]))
        xu, Pu = self.kalman.update(x, P, innovation, pairs.row, pairs.nu)
        if not start.initiated:  # every track converts here (continue_each)
            xu, Pu = convert_initiated_many(self.motion, xu, Pu, self.birth)
        value = (
            missed.value[pairs.row]
            + self.terms.survival[m]
            + self._detection_term(m, pairs.d2, pairs.loglik)
        )
        finite = np.isfinite(value)
        found: dict[int, tuple[IntArray, PathState]] = {}
        for col, (key, _) in enumerate(requested):
            mine = np.flatnonzero((pairs.detection == col) & finite)
            rows = pairs.row[mine]
            state = PathState(
                scan=m,
                means=xu[mine],
                covariances=Pu[mine],
                initiated=True,
                first_time=start.first_time[rows],
                value=value[mine],
            )
            found[key] = (rows, state)
        return found

    def advance_missed(self, state: PathState, until: int) -> PathState:
        """Misses at scans ``state.scan + 1 .. until``; states predicted to ``until``."""
        if until <= state.scan:
            return state
        x, P = self._predict(state, until)
        return PathState(
            scan=until,
            means=x,
            covariances=P,
            initiated=state.initiated,
            first_time=state.first_time,
            value=state.value + self.misses_between(state.scan + 1, until),
        )

    def _predict(self, state: PathState, to_scan: int) -> tuple[FloatArray, FloatArray]:
        """Predict the states from scan ``state.scan`` to ``to_scan`` (skipping dt = 0).

        The hypothesis trees predict scan by scan; prediction over several steps at once
        is the same for a linear model only, so the steps are taken one by one.
        """
        model = self.motion if state.initiated else self._init_model
        x, P = state.means, state.covariances
        for m in range(state.scan + 1, to_scan + 1):
            dt = float(self.times[m] - self.times[m - 1])
            if dt > 0:
                x, P, _ = self.kalman.predict(model, x, P, dt)
        return x, P

    def _detection_term(self, m: int | IntArray, d2: FloatArray, loglik: FloatArray) -> FloatArray:
        """``c_m`` of a detection at scan ``m`` (per track, or per track's own scan):
        ``log Pd + log N(nu; 0, S) - log lambda`` inside the gate, ``-inf`` outside."""
        term = detection_term(self.terms.log_pd[m], loglik, self.terms.log_clutter[m])
        return np.where(d2 <= self.terms.thresholds[m], term, -math.inf)

    def detect(self, state: PathState, m: int, j: int | IntArray) -> PathState:
        """The step to scan ``m`` = ``state.scan + 1`` continued by its detection ``j``
        (one index in the scan for the whole batch, or one per track, shape (B,))."""
        sensor = self._sensors[m]
        scan = self.scans[m]
        initiated = state.initiated
        measurement = (
            sensor.measurement
            if initiated
            else initiation_measurement(self.motion, sensor.measurement)
        )
        x, P = self._predict(state, m)
        innovation = self.kalman.innovation(measurement, x, P)
        nu = innovation.residuals(scan.detections[j])
        d2, loglik = innovation.scores(nu)
        xu, Pu = self.kalman.update(x, P, innovation, np.arange(len(x)), nu)
        value = state.value + self.terms.survival[m] + self._detection_term(m, d2, loglik)
        if not initiated:
            # A coordinated-turn track converts at its first detection later than its
            # first one, as in the hypothesis trees; batches share the first time only
            # when they share the path, so the flag is checked per track.
            convert = scan.time > state.first_time
            if np.any(convert) and not np.all(convert):
                raise InputError("a batch of tracks must convert to the turn state together")
            if np.all(convert):
                xu, Pu = convert_initiated_many(self.motion, xu, Pu, self.birth)
                initiated = True
        return PathState(
            scan=m,
            means=xu,
            covariances=Pu,
            initiated=initiated,
            first_time=state.first_time,
            value=value,
        )

    # -- whole tracks --------------------------------------------------------------------
    def track_value(self, path: TrackPath) -> float:
        """``v(tau)``: the track's terms from its first detection to its best ending."""
        return self.trajectory(path).value

    def trajectory(self, path: TrackPath) -> Trajectory:
        """The track's filter run: its state and value after each of its detections.

        Kept in a cache of the most recent :data:`TRAJECTORY_CACHE` paths (refinement
        asks again and again for the tracks it has not changed).
        """
        path = tuple(path)
        cached = self._trajectories.pop(path, None)
        if cached is None:
            if not path:
                raise InputError("a track needs at least one detection")
            state = self.start_path(path)
            means, covariances = [state.means[0]], [state.covariances[0]]
            initiated, values = [state.initiated], [float(state.value[0])]
            # Detections from which every step is linear: the backend's run takes over
            # there once the state is in the motion model's space.
            linear_from = self.refiltering.linear_suffix(path)
            for k in range(1, len(path)):
                if k >= linear_from and self._in_motion_space(state):
                    # The rest of the run in one call (the same steps).
                    rest = self.refiltering.filter_path(state, path[k:])
                    means.extend(rest[0])
                    covariances.extend(rest[1])
                    values.extend(rest[2].tolist())
                    initiated.extend([True] * (len(path) - k))
                    break
                state = self.continue_paths(state, (path[k],))
                means.append(state.means[0])
                covariances.append(state.covariances[0])
                initiated.append(state.initiated)
                values.append(float(state.value[0]))
            cached = Trajectory(
                path=path,
                means=tuple(means),
                covariances=tuple(covariances),
                initiated=np.array(initiated, dtype=bool),
                first_time=float(state.first_time[0]),
                values=np.array(values),
                value=float(values[-1] + self.terms.tails[path[-1][0]]),
            )
            if len(self._trajectories) >= TRAJECTORY_CACHE:
                del self._trajectories[next(iter(self._trajectories))]
        self._trajectories[path] = cached
        return cached

    def continue_converging(
        self,
        start: PathState,
        reference: Trajectory,
        first: int,
        *,
        max_detections: int | None = None,
    ) -> FloatArray:
        """Values of a batch of tracks continued through ``reference.path[first:]``.

        Each track of ``start`` is advanced detection by detection through the
        reference's detections from index ``first`` on, exactly as
        :meth:`continue_paths` does, until its filtered state equals the reference's own
        state after the same detection (every entry of the mean and the covariance
        within :data:`CONVERGED` relative to ``1 + |entry|``).  From there on the two
        filters see the same detections from the same state, so the remaining terms
        are the reference's own: their sum is taken from the reference instead of
        being computed again.  The Kalman filter forgets where it started
        geometrically fast, so a join of a long track costs a few steps rather than
        its whole length; the error is that of two states equal to about 1e-9, far
        below the acceptance threshold of a refinement move.

        Parameters
        ----------
        start : PathState
            States before ``reference.path[first]`` (at an earlier scan).
        reference : Trajectory
            A track whose detections from ``first`` on are the ones to continue with.
        first : int
            Index into ``reference.path``.
        max_detections : int, optional
            Re-filter at most this many detections; past them the reference's own terms
            are taken whether or not the states agree (an approximation: the Kalman
            filter's memory of its start decays geometrically, but is not gone).  The
            refinement proposes moves with it and accepts them on exact values.

        Returns
        -------
        ndarray, shape (B,)
            Each track's value so far plus the terms of the reference's detections from
            ``first`` on and its best ending (``-inf`` where a detection is out of gate).
        """
        return converge_in_lockstep(self, [(start, reference, first)], max_detections)[0]

    def continue_converging_many(
        self,
        requests: Sequence[ConvergeRequest],
        *,
        max_detections: int | None = None,
    ) -> list[FloatArray]:
        """:meth:`continue_converging` of several ``(start, reference, first)`` at once.

        Returns what ``continue_converging(start, reference, first, max_detections=...)``
        returns for each request, up to rounding (the same filter steps taken in one
        batch: each track at its own scan, with its own detections).  Batching pays where
        each request holds a few tracks: refinement scores the joins to every anchor of a
        window this way, one Kalman step for all of them rather than one per anchor.
        Requests that a batch cannot take (a nonlinear motion or measurement model, a
        state not yet in the motion model's space) are continued one by one.
        """
        out: list[FloatArray] = [np.full(len(start), -math.inf) for start, _, _ in requests]
        batchable: list[int] = []
        others: list[int] = []
        for i, (start, reference, first) in enumerate(requests):
            if len(start) == 0:
                continue
            (batchable if self._batchable(start, reference, first) else others).append(i)
        if others:
            rest = converge_in_lockstep(self, [requests[i] for i in others], max_detections)
            for i, values in zip(others, rest, strict=True):
                out[i] = values
        if batchable:
            chosen = [requests[i] for i in batchable]
            for i, values in zip(
                batchable, self.refiltering.converge(chosen, max_detections), strict=True
            ):
                out[i] = values
        return out

    def _batchable(self, start: PathState, reference: Trajectory, first: int) -> bool:
        """Whether a request's steps are all linear Kalman steps in one state space."""
        if first >= len(reference.path) or not bool(np.all(reference.initiated[first:])):
            return False
        rest = reference.path[first:]
        return self._in_motion_space(start) and self.refiltering.converges(rest)

    def _in_motion_space(self, state: PathState) -> bool:
        """Whether ``state`` is an initiated track in the motion model's state space."""
        return state.initiated and state.means.shape[1] == filter_state_dim(self.motion)

    def value(self, tracks: Mapping[int, TrackPath] | Iterable[TrackPath]) -> float:
        """J(omega) = sum of the tracks' values (0 for no track; ``-inf`` if impossible)."""
        paths = tracks.values() if isinstance(tracks, Mapping) else tracks
        return float(sum(self.track_value(p) for p in paths))

    # -- detection ids -------------------------------------------------------------------
    def path_of_rows(self, rows: Sequence[int]) -> TrackPath:
        """The path of a track given its detection ids (any order)."""
        try:
            pairs = sorted(self._row_of[int(r)] for r in rows)
        except KeyError as exc:
            raise InputError(f"detection id {exc.args[0]} is not in the recording") from None
        scans_used = [m for m, _ in pairs]
        if len(set(scans_used)) != len(scans_used):
            raise InputError(f"a track uses two detections of one scan (ids {list(rows)})")
        return tuple(pairs)


def paths_from_rows(
    objective: RecordingObjective, track_rows: Mapping[int, Sequence[int]]
) -> dict[int, TrackPath]:
    """Track id -> path, from track id -> detection ids (``EstimateResult.track_rows``)."""
    return {tid: objective.path_of_rows(rows) for tid, rows in track_rows.items() if len(rows)}


def rows_from_paths(
    scans: Sequence[Scan], tracks: Mapping[int, TrackPath]
) -> dict[int, tuple[int, ...]]:
    """Track id -> detection ids in scan order, from track id -> path."""
    return {
        tid: tuple(int(scans[m].rows[j]) for m, j in path) for tid, path in sorted(tracks.items())
    }
