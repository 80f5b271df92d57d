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
(:class:`~mapassoc.estimator.terms.ScanTerms`) and computed with the same filter, so a
recording no longer than one window gets J equal to its window's best objective.

J is defined under the birth model (the default ``k_prior``); a named prior on K
reweights each window's count of targets and has no whole-recording counterpart.

Code that scores a track set found in any way (the forward pass, a refinement, another
tracker's hard associations) calls :meth:`RecordingObjective.value`;
:mod:`mapassoc.estimator.refinement` uses the batched continuation
(:meth:`RecordingObjective.continue_paths`) to score joins exactly.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import BoolArray, FloatArray, IntArray
from mapassoc.data.config import Config, check_config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.terms import ScanTerms, detection_term
from mapassoc.filtering.compiled import ScanModel, kalman_kernels
from mapassoc.filtering.kalman import (
    innovation_covariance,
    pairwise_gate_and_loglik,
    predict_motion,
    predicted_covariance,
    update,
)
from mapassoc.models.birth import (
    birth_states,
    convert_initiated,
    initiation_measurement,
    initiation_model,
    needs_conversion,
)
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import MotionModel

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

_LOG_2PI = math.log(2.0 * math.pi)

TrackPath = tuple[tuple[int, int], ...]
"""A track's detections as ``((scan index, index in that scan), ...)`` in increasing scan
order, at most one per scan."""


TRAJECTORY_CACHE = 20_000
"""Most track runs :meth:`RecordingObjective.trajectory` keeps."""

_GATE_BLOCK = 1 << 18
"""Most (track, detection) pairs :func:`_squared_distances` computes in one block."""

CONVERGED = 1e-9
"""Relative agreement of two filtered states taken as equal by
:meth:`RecordingObjective.continue_converging`."""


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One track's filter run (:meth:`RecordingObjective.trajectory`).

    Attributes
    ----------
    path : TrackPath
    means, covariances : tuple of ndarray
        Filtered state after each detection (its dimension may change once for a
        coordinated-turn track, at its conversion).
    initiated : ndarray of bool, shape (L,)
    first_time : float
    values : ndarray, shape (L,)
        Sum of the track's terms up to and including each detection.
    value : float
        ``v(tau)``: ``values[-1]`` plus the best ending after the last detection.
    """

    path: TrackPath
    means: tuple[FloatArray, ...]
    covariances: tuple[FloatArray, ...]
    initiated: NDArray[np.bool_]
    first_time: float
    values: FloatArray
    value: float

    def state(self, k: int) -> PathState:
        """The state after detection ``k`` as a batch of one."""
        return PathState(
            scan=self.path[k][0],
            means=self.means[k][None, :],
            covariances=self.covariances[k][None, :, :],
            initiated=bool(self.initiated[k]),
            first_time=np.array([self.first_time]),
            value=np.array([self.values[k]]),
        )


@dataclass(frozen=True, eq=False)
class PathState:
    """Filtered states of a batch of tracks at one scan, and their values so far.

    Attributes
    ----------
    scan : int
        Index of the scan (in the recording) the states are at.
    means : ndarray, shape (B, n)
    covariances : ndarray, shape (B, n, n)
    initiated : bool
        Whether the states are in the motion model's own space (False only for a
        coordinated-turn track before its conversion); one value for the batch.
    first_time : ndarray, shape (B,)
        Time of each track's first detection.
    value : ndarray, shape (B,)
        Sum of the track's terms up to and including this scan (``-inf``: impossible).
    """

    scan: int
    means: FloatArray
    covariances: FloatArray
    initiated: bool
    first_time: FloatArray
    value: FloatArray

    def __len__(self) -> int:
        return int(self.value.shape[0])

    def take(self, index: IntArray) -> PathState:
        """The tracks at ``index``."""
        return PathState(
            scan=self.scan,
            means=self.means[index],
            covariances=self.covariances[index],
            initiated=self.initiated,
            first_time=self.first_time[index],
            value=self.value[index],
        )


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
        self._measurement_dim = max(
            sensor.measurement.measurement_dim for sensor in config.sensors.values()
        )
        self.terms = ScanTerms.of_recording(config, self.scans)
        self.times = self.terms.times
        self._trajectories: dict[TrackPath, Trajectory] = {}
        self._motion_cache: dict[tuple[int, float], tuple[FloatArray, FloatArray]] = {}
        self._scan_model_cache: ScanModel | None = None
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
        scan = self.scans[m]
        z = scan.detections[j][None, :]
        x, P = birth_states(self.motion, self._sensors[m].measurement, z, self.birth)
        return PathState(
            scan=m,
            means=x,
            covariances=P,
            initiated=not self._converts,
            first_time=np.array([scan.time]),
            value=np.array([self.terms.birth[m]]),
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
            state = self._detect(state, m, j)
        return state

    def continue_each(
        self, start: PathState, detections: Sequence[tuple[int, int]]
    ) -> list[tuple[IntArray, PathState]]:
        """Each detection ``(m, j)`` (after ``start.scan``) tried as the next one of every
        track of ``start``.

        Returns, per detection, the tracks (positions in ``start``) whose gate it falls
        in and their states after it: what ``continue_paths(start, [(m, j)])`` gives,
        restricted to its finite values.  With linear models the prediction to each scan
        and the innovation covariances are computed once for all the detections of that
        scan, and only the tracks in a detection's gate are updated (refinement tries the
        first detection of every anchor after every leaf of a window this way).
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
            measurement = self._sensors[m].measurement
            if not (
                start.initiated
                and self.motion.is_linear
                and isinstance(measurement, LinearMeasurement)
            ):
                for i in indices:
                    state = self.continue_paths(start, (detections[i],))
                    ok = np.flatnonzero(np.isfinite(state.value))
                    found[i] = (ok, state.take(ok))
                continue
            missed = self.advance_missed(start, m - 1)
            x, P = self._predict(missed, m)
            H, R = measurement.H, measurement.noise_covariance
            S_inv, _ = _inverse_and_logdet(innovation_covariance(H, P, R))
            predicted = x @ H.T
            # A slightly wider gate first; the exact one is applied by the update.
            wide = self.terms.thresholds[m] * (1.0 + 1e-9)
            measured = self.scans[m].detections[[detections[i][1] for i in indices]]
            inside = _squared_distances(predicted, S_inv, measured) <= wide
            gated = [np.flatnonzero(inside[:, col]) for col in range(len(indices))]
            # One Kalman update for every (track, detection) pair in a gate.
            rows_all = np.concatenate(gated)
            cols_all = np.repeat(np.arange(len(indices)), [g.size for g in gated])
            if rows_all.size:
                d2, loglik, xu, Pu = self._linear_step(
                    x[rows_all], P[rows_all], measured[cols_all], H, R
                )
                value_all = (
                    missed.value[rows_all]
                    + self.terms.survival[m]
                    + self._detection_term(m, d2, loglik)
                )
            bounds = np.concatenate([[0], np.cumsum([g.size for g in gated])])
            for col, i in enumerate(indices):
                rows = gated[col]
                if rows.size:
                    part = slice(int(bounds[col]), int(bounds[col + 1]))
                    ok = np.flatnonzero(np.isfinite(value_all[part]))
                    rows = rows[ok]
                    state = PathState(
                        scan=m,
                        means=xu[part][ok],
                        covariances=Pu[part][ok],
                        initiated=True,
                        first_time=start.first_time[rows],
                        value=value_all[part][ok],
                    )
                else:
                    state = start.take(rows)
                found[i] = (rows, state)
        return [found[i] for i in range(len(detections))]

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
            if dt <= 0:
                continue
            matrices = self._linear_motion(model, dt)
            if matrices is None:
                x, P, _ = predict_motion(model, x, P, dt)
            else:
                F, Q = matrices
                x = x @ F.T
                P = predicted_covariance(F, P, Q)
        return x, P

    def _linear_motion(self, model: MotionModel, dt: float) -> tuple[FloatArray, FloatArray] | None:
        """``(F, Q)`` of a linear motion model over ``dt`` (cached), None for a nonlinear one."""
        if not model.is_linear:
            return None
        key = (id(model), dt)
        cached = self._motion_cache.get(key)
        if cached is None:
            # A linear model's Jacobian is F(dt), wherever it is taken.
            F = np.asarray(model.jacobian(np.zeros(model.state_dim), dt), dtype=np.float64)
            cached = (F, np.asarray(model.process_noise(dt), dtype=np.float64))
            self._motion_cache[key] = cached
        return cached

    def _linear_step(
        self, x: FloatArray, P: FloatArray, z: FloatArray, H: FloatArray, R: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Kalman update of a batch by one detection through a linear measurement.

        The same algebra as :func:`~mapassoc.filtering.kalman.update` (gain through
        ``S^-1``, Joseph-form covariance) with a batched inverse of the small S instead of
        Cholesky solves: for one track at a time, numpy's per-call overhead is the cost.

        Returns
        -------
        d2, loglik : ndarray, shape (B,)
            Squared Mahalanobis distance and ``log N(nu; 0, S)``.
        x_post, P_post
        """
        HP = H @ P  # (B, d, n)
        S = innovation_covariance(H, P, R)
        nu = z - x @ H.T
        S_inv, logdet = _inverse_and_logdet(S)
        y = np.einsum("bij,bj->bi", S_inv, nu)
        d2 = np.einsum("bi,bi->b", nu, y)
        loglik = -0.5 * (nu.shape[-1] * _LOG_2PI + logdet + d2)
        K = np.swapaxes(HP, -1, -2) @ S_inv  # (B, n, d)
        x_post = x + np.einsum("bij,bj->bi", K, nu)
        A = np.eye(P.shape[-1]) - K @ H
        P_post = A @ P @ np.swapaxes(A, -1, -2) + K @ R @ np.swapaxes(K, -1, -2)
        return d2, loglik, x_post, 0.5 * (P_post + np.swapaxes(P_post, -1, -2))

    def _detection_term(
        self, m: int | IntArray, d2: FloatArray, loglik: FloatArray
    ) -> FloatArray:
        """``c_m`` of a detection at scan ``m`` (per track, or per track's own scan):
        ``log Pd + log N(nu; 0, S) - log lambda`` inside the gate, ``-inf`` outside."""
        term = detection_term(self.terms.log_pd[m], loglik, self.terms.log_clutter[m])
        return np.where(d2 <= self.terms.thresholds[m], term, -math.inf)

    def _detect(self, state: PathState, m: int, j: int) -> PathState:
        """The step to scan ``m`` = ``state.scan + 1`` continued by its detection ``j``."""
        sensor = self._sensors[m]
        scan = self.scans[m]
        initiated = state.initiated
        measurement = (
            sensor.measurement
            if initiated
            else initiation_measurement(self.motion, sensor.measurement)
        )
        x, P = self._predict(state, m)
        z = scan.detections[j]
        R = sensor.measurement.noise_covariance
        if isinstance(measurement, LinearMeasurement):
            d2, loglik, xu, Pu = self._linear_step(x, P, z, measurement.H, R)
        else:
            H = measurement.jacobian(x)
            z_hat = measurement.predict(x)
            S = innovation_covariance(H, P, R)
            nu = measurement.residual(z[None, None, :], z_hat[:, None, :])
            d2, loglik = pairwise_gate_and_loglik(nu, S)
            d2, loglik, nu = d2[:, 0], loglik[:, 0], nu[:, 0]
            xu, Pu = update(x, P, nu, S, H, R)
        value = state.value + self.terms.survival[m] + self._detection_term(m, d2, loglik)
        if not initiated:
            # A coordinated-turn track converts at its first detection later than its
            # first one, as in the hypothesis trees; batches share the first time only
            # when they share the path, so the flag is checked per track.
            convert = scan.time > state.first_time
            if np.any(convert) and not np.all(convert):
                raise InputError("a batch of tracks must convert to the turn state together")
            if np.all(convert):
                converted = [
                    convert_initiated(self.motion, xu[b], Pu[b], self.birth) for b in range(len(xu))
                ]
                xu = np.array([c[0] for c in converted]).reshape(len(xu), -1)
                n = xu.shape[1]
                Pu = np.array([c[1] for c in converted]).reshape(len(xu), n, n)
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
            kernels = kalman_kernels()
            # Detections from which every step is linear: the kernel takes over there
            # once the state is in the motion model's space.
            linear_from = self._linear_suffix(path) if kernels is not None else len(path)
            for k in range(1, len(path)):
                if kernels is not None and k >= linear_from and self._in_motion_space(state):
                    # The rest of the run in the compiled kernel (the same steps).
                    rest = self._filter_compiled(kernels, state, path[k:])
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
        B = len(start)
        out = np.full(B, -math.inf)
        rows = np.arange(B)
        state = start
        last = len(reference.path) - 1
        stop = last if max_detections is None else min(last, first + max_detections - 1)
        for k in range(first, stop + 1):
            state = self.continue_paths(state, reference.path[k : k + 1])
            finite = np.flatnonzero(np.isfinite(state.value))
            if finite.size < len(state):
                state, rows = state.take(finite), rows[finite]
            if len(state) == 0:
                return out
            if k == stop < last:  # cut short: the reference's terms from here on
                out[rows] = state.value + (reference.values[last] - reference.values[k])
                return out + self.terms.tails[reference.path[last][0]]
            if k < last and state.initiated == bool(reference.initiated[k]):
                mean, cov = reference.means[k], reference.covariances[k]
                if state.means.shape[1:] == mean.shape:
                    same = np.all(
                        np.abs(state.means - mean) <= CONVERGED * (1.0 + np.abs(mean)), axis=1
                    ) & np.all(
                        np.abs(state.covariances - cov) <= CONVERGED * (1.0 + np.abs(cov)),
                        axis=(1, 2),
                    )
                    if np.any(same):
                        rest = reference.values[last] - reference.values[k]
                        out[rows[same]] = state.value[same] + rest
                        keep = np.flatnonzero(~same)
                        state, rows = state.take(keep), rows[keep]
                        if len(state) == 0:
                            break
        if len(state):
            out[rows] = state.value
        return out + self.terms.tails[reference.path[last][0]]

    def continue_converging_many(
        self,
        requests: Sequence[tuple[PathState, Trajectory, int]],
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
        for i, (start, reference, first) in enumerate(requests):
            if len(start) == 0:
                continue
            if self._batchable(start, reference, first):
                batchable.append(i)
            else:
                out[i] = self.continue_converging(
                    start, reference, first, max_detections=max_detections
                )
        if batchable:
            self._converge_batch(requests, batchable, out, max_detections)
        return out

    def _batchable(self, start: PathState, reference: Trajectory, first: int) -> bool:
        """Whether a request's steps are all linear Kalman steps in one state space."""
        if first >= len(reference.path) or not bool(np.all(reference.initiated[first:])):
            return False
        return self._in_motion_space(start) and self._linear_suffix(reference.path[first:]) == 0

    def _in_motion_space(self, state: PathState) -> bool:
        """Whether ``state`` is an initiated track in the motion model's state space."""
        return state.initiated and state.means.shape[1] == self.motion.state_dim

    def _linear_suffix(self, path: TrackPath) -> int:
        """The first index of ``path`` from which every step is a linear Kalman step (a
        linear motion model and linear measurements at the path's scans); ``len(path)``
        where the motion model is not linear."""
        if not self.motion.is_linear:
            return len(path)
        k = len(path)
        while k > 0 and isinstance(self._sensors[path[k - 1][0]].measurement, LinearMeasurement):
            k -= 1
        return k

    def _filter_compiled(
        self, kernels: ModuleType, state: PathState, path: TrackPath
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """One track's run from ``state`` through ``path`` in the compiled kernel
        (``filter_along_path``): its means, covariances and values after each detection."""
        detections = np.zeros((len(path), self._measurement_dim))
        for i, (m, j) in enumerate(path):
            z = self.scans[m].detections[j]
            detections[i, : z.shape[0]] = z
        means, covariances, values, positive = kernels.filter_along_path(
            np.array(state.means[0], dtype=np.float64),
            np.array(state.covariances[0], dtype=np.float64),
            float(state.value[0]),
            int(state.scan),
            np.array([m for m, _ in path], dtype=np.int64),
            detections,
            self._scan_model(),
        )
        if not positive:
            raise InputError("innovation covariance S is not positive-definite")
        return means, covariances, values

    def _converge_batch(
        self,
        requests: Sequence[tuple[PathState, Trajectory, int]],
        chosen: Sequence[int],
        out: list[FloatArray],
        max_detections: int | None,
    ) -> None:
        """The batched body of :meth:`continue_converging_many` (linear steps only).

        What each step reads of a track's reference (its detection, scan, sensor, the
        reference's state and value there) is gathered once per request into arrays
        indexed by (request, step), so a step is array indexing whatever the number of
        tracks.  The tracks of every request are stacked into flat arrays, continued in
        the compiled kernel or, without it, by :meth:`_converge_numpy`, and the flat
        result is cut back into one array per request.
        """
        for i in chosen:  # a path must be after its start
            start, reference, first = requests[i]
            if reference.path[first][0] <= start.scan:
                raise InputError(
                    f"path detection at scan {reference.path[first][0]} is not after the "
                    f"track's state at scan {start.scan}"
                )
        table = _ReferenceSteps.gather(self, [requests[i] for i in chosen], max_detections)
        starts = [requests[i][0] for i in chosen]
        sizes = np.array([len(start) for start in starts], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)])
        request = np.repeat(np.arange(len(chosen)), sizes)
        x = np.concatenate([start.means for start in starts])
        P = np.concatenate([start.covariances for start in starts])
        value = np.concatenate([start.value for start in starts])
        scan = np.repeat(np.array([start.scan for start in starts], dtype=np.int64), sizes)
        kernels = kalman_kernels()
        if kernels is not None:
            flat = self._converge_compiled(kernels, table, x, P, value, scan, request)
        else:
            flat = self._converge_numpy(table, x, P, value, scan, request)
        for c, i in enumerate(chosen):
            out[i] = flat[offsets[c] : offsets[c + 1]]

    def _converge_numpy(
        self,
        table: _ReferenceSteps,
        x: FloatArray,
        P: FloatArray,
        value: FloatArray,
        scan: IntArray,
        request: IntArray,
    ) -> FloatArray:
        """The batched continuation's loop in numpy, one reference detection per round
        for every track still going (the same steps as :meth:`_converge_compiled`).

        Each round predicts every track to its reference's next detection
        (:meth:`_predict_batch`), updates it by that detection (:meth:`_update_batch`),
        adds the survival and detection terms, and lets the tracks that leave
        (:meth:`_ReferenceSteps.leaving`) take their final value.  The arguments are
        changed in place.
        """
        track = np.arange(value.size)  # position in the flat output
        flat = np.full(value.size, -math.inf)
        step = np.zeros(track.size, dtype=np.int64)  # detections of the reference taken
        while track.size:
            target = table.scan[request, step]
            self._predict_batch(x, P, value, scan, target)
            d2, loglik = self._update_batch(table, x, P, request, step, target)
            value += self.terms.survival[target] + self._detection_term(target, d2, loglik)
            leave, result = table.leaving(x, P, value, request, step)
            flat[track[leave]] = result[leave]
            keep = np.flatnonzero(~leave)
            track, request, x, P, value = track[keep], request[keep], x[keep], P[keep], value[keep]
            scan, step = scan[keep], step[keep] + 1
        return flat

    def _predict_batch(
        self, x: FloatArray, P: FloatArray, value: FloatArray, scan: IntArray, target: IntArray
    ) -> None:
        """Predict each track scan by scan (as the trees do), from its own ``scan`` to its
        ``target`` scan, adding the survival and miss terms of the scans it passes; in
        place."""
        while True:
            moving = np.flatnonzero(scan < target)
            if moving.size == 0:
                break
            nxt = scan[moving] + 1
            dts = self.times[nxt] - self.times[nxt - 1]
            for dt in np.unique(dts[dts > 0]).tolist():
                rows = moving[dts == dt]
                F, Q = self._linear_motion(self.motion, float(dt))  # type: ignore[misc]
                x[rows] = x[rows] @ F.T
                P[rows] = predicted_covariance(F, P[rows], Q)
            missed = nxt < target[moving]
            value[moving[missed]] += self.terms.survival[nxt[missed]] + self.terms.miss[nxt[missed]]
            scan[moving] = nxt

    def _update_batch(
        self,
        table: _ReferenceSteps,
        x: FloatArray,
        P: FloatArray,
        request: IntArray,
        step: IntArray,
        target: IntArray,
    ) -> tuple[FloatArray, FloatArray]:
        """Update each track by its reference's detection at ``step``, one sensor at a
        time, in place; the squared Mahalanobis distances and log-likelihoods."""
        d2 = np.empty(request.size)
        loglik = np.empty(request.size)
        sensor_of = table.sensor[request, step]
        for sensor in np.unique(sensor_of).tolist():
            rows = np.flatnonzero(sensor_of == sensor)
            measurement = self._sensors[int(target[rows[0]])].measurement
            H, R = measurement.H, measurement.noise_covariance  # type: ignore[attr-defined]
            z = table.detection[request[rows], step[rows], : H.shape[0]]
            d2[rows], loglik[rows], x[rows], P[rows] = self._linear_step(x[rows], P[rows], z, H, R)
        return d2, loglik

    def _converge_compiled(
        self,
        kernels: ModuleType,
        table: _ReferenceSteps,
        x: FloatArray,
        P: FloatArray,
        value: FloatArray,
        scan: IntArray,
        request: IntArray,
    ) -> FloatArray:
        """The batched continuation's loop in the compiled kernel
        (``continue_along_references``), track by track; the same steps as
        :meth:`_converge_numpy`."""
        flat, positive = kernels.continue_along_references(
            np.ascontiguousarray(x, dtype=np.float64),
            np.ascontiguousarray(P, dtype=np.float64),
            np.ascontiguousarray(value, dtype=np.float64),
            scan.astype(np.int64),
            request.astype(np.int64),
            table.steps,
            table.scan,
            table.detection,
            table.rest,
            table.mean,
            table.covariance,
            table.tail,
            self._scan_model(),
            CONVERGED,
        )
        if not positive:
            raise InputError("innovation covariance S is not positive-definite")
        return np.asarray(flat, dtype=np.float64)

    def _scan_model(self) -> ScanModel:
        """What the compiled kernels read of the recording per scan
        (:data:`~mapassoc.filtering.compiled.ScanModel`): whether the step from
        scan ``m - 1`` has a positive time step, the motion model's ``F`` and ``Q`` over
        it, the scan's linear measurement ``H``, ``R`` (zero-padded to the largest
        measurement dimension) with its dimension (zeros where a step does not move or
        a measurement is not linear), and the per-scan terms and gates.  Built once."""
        if self._scan_model_cache is None:
            M, n, dz = len(self.scans), self.motion.state_dim, self._measurement_dim
            moves = np.zeros(M, dtype=bool)
            F, Q = np.zeros((M, n, n)), np.zeros((M, n, n))
            H, R = np.zeros((M, dz, n)), np.zeros((M, dz, dz))
            dims = np.zeros(M, dtype=np.int64)
            for m in range(M):
                dt = float(self.times[m] - self.times[m - 1]) if m else 0.0
                matrices = self._linear_motion(self.motion, dt) if dt > 0 else None
                if matrices is not None:
                    moves[m] = True
                    F[m], Q[m] = matrices
                measurement = self._sensors[m].measurement
                if isinstance(measurement, LinearMeasurement):
                    d = measurement.H.shape[0]
                    dims[m] = d
                    H[m, :d] = measurement.H
                    R[m, :d, :d] = measurement.noise_covariance
            self._scan_model_cache = (
                moves,
                F,
                Q,
                H,
                R,
                dims,
                np.ascontiguousarray(self.terms.survival, dtype=np.float64),
                np.ascontiguousarray(self.terms.miss, dtype=np.float64),
                np.ascontiguousarray(self.terms.log_pd, dtype=np.float64),
                np.ascontiguousarray(self.terms.log_clutter, dtype=np.float64),
                np.ascontiguousarray(self.terms.thresholds, dtype=np.float64),
            )
        return self._scan_model_cache

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


@dataclass(frozen=True, eq=False)
class _ReferenceSteps:
    """What the batched continuation reads of each request's reference, per step.

    Row ``c`` is request ``c``; column ``s`` its reference's detection ``first + s``, for
    ``s < steps[c]`` (up to the reference's last detection or the cap).

    Attributes
    ----------
    steps : ndarray of int, shape (C,)
    scan, sensor : ndarray of int, shape (C, W)
        The detection's scan and its sensor's code.
    detection : ndarray, shape (C, W, dz)
        The measurement (zero-padded to the largest sensor dimension).
    rest : ndarray, shape (C, W)
        The reference's value after its last detection minus its value at this one.
    mean, covariance : ndarray, shapes (C, W, n) and (C, W, n, n)
        The reference's filtered state at this detection.
    tail : ndarray, shape (C,)
        The best ending after the reference's last detection.
    """

    steps: IntArray
    scan: IntArray
    sensor: IntArray
    detection: FloatArray
    rest: FloatArray
    mean: FloatArray
    covariance: FloatArray
    tail: FloatArray

    @classmethod
    def gather(
        cls,
        objective: RecordingObjective,
        requests: Sequence[tuple[PathState, Trajectory, int]],
        max_detections: int | None,
    ) -> _ReferenceSteps:
        C = len(requests)
        lasts = [len(reference.path) - 1 for _, reference, _ in requests]
        stops = [
            last if max_detections is None else min(last, first + max_detections - 1)
            for (_, _, first), last in zip(requests, lasts, strict=True)
        ]
        steps = np.array(
            [stop - first + 1 for (_, _, first), stop in zip(requests, stops, strict=True)],
            dtype=np.int64,
        )
        W = int(steps.max(initial=1))
        n = requests[0][0].means.shape[1]
        dz = objective._measurement_dim
        codes: dict[str, int] = {}
        scan = np.zeros((C, W), dtype=np.int64)
        sensor = np.zeros((C, W), dtype=np.int64)
        detection = np.zeros((C, W, dz))
        rest = np.zeros((C, W))
        mean = np.zeros((C, W, n))
        covariance = np.zeros((C, W, n, n))
        tail = np.zeros(C)
        for c, (_, reference, first) in enumerate(requests):
            tail[c] = objective.terms.tails[reference.path[-1][0]]
            for s in range(int(steps[c])):
                m, j = reference.path[first + s]
                z = objective.scans[m].detections[j]
                scan[c, s] = m
                sensor[c, s] = codes.setdefault(objective.scans[m].sensor, len(codes))
                detection[c, s, : z.shape[0]] = z
                rest[c, s] = reference.values[-1] - reference.values[first + s]
                mean[c, s] = reference.means[first + s]
                covariance[c, s] = reference.covariances[first + s]
        return cls(steps, scan, sensor, detection, rest, mean, covariance, tail)

    def leaving(
        self,
        x: FloatArray,
        P: FloatArray,
        value: FloatArray,
        request: IntArray,
        step: IntArray,
    ) -> tuple[BoolArray, FloatArray]:
        """Which tracks leave after ``step`` (out of gate, at their reference's end or cut
        short, or converged to the reference's state) and the value each leaves with (its
        value plus the reference's rest and tail; ``-inf`` out of gate)."""
        done = ~np.isfinite(value)
        ended = step == self.steps[request] - 1
        result = np.where(done, -math.inf, value + self.rest[request, step] + self.tail[request])
        same = np.zeros(value.size, dtype=bool)
        check = np.flatnonzero(~done & ~ended)
        if check.size:
            mean = self.mean[request[check], step[check]]
            cov = self.covariance[request[check], step[check]]
            same[check] = np.all(
                np.abs(x[check] - mean) <= CONVERGED * (1.0 + np.abs(mean)), axis=1
            ) & np.all(np.abs(P[check] - cov) <= CONVERGED * (1.0 + np.abs(cov)), axis=(1, 2))
        return done | ended | same, result


def _squared_distances(
    predicted: FloatArray, inverse: FloatArray, measured: FloatArray
) -> FloatArray:
    """Squared Mahalanobis distance of every detection from every track's prediction.

    Parameters
    ----------
    predicted : ndarray, shape (B, d)
        Predicted measurements.
    inverse : ndarray, shape (B, d, d)
        Inverse innovation covariances (symmetric).
    measured : ndarray, shape (A, d)

    Returns
    -------
    ndarray, shape (B, A)
        ``nu^T S^-1 nu`` with ``nu = measured[a] - predicted[b]``, summed term by term
        over the d (d + 1) / 2 entries of ``S^-1`` in blocks of detections (a dense
        ``einsum`` per detection costs far more for d = 2).
    """
    B, d = predicted.shape
    out = np.empty((B, measured.shape[0]))
    block = max(1, _GATE_BLOCK // max(B, 1))
    for a0 in range(0, measured.shape[0], block):
        nu = measured[None, a0 : a0 + block, :] - predicted[:, None, :]  # (B, a, d)
        total = np.zeros(nu.shape[:2])
        for i in range(d):
            total += inverse[:, i, i, None] * nu[:, :, i] ** 2
            for j in range(i + 1, d):
                total += 2.0 * inverse[:, i, j, None] * nu[:, :, i] * nu[:, :, j]
        out[:, a0 : a0 + block] = total
    return out


def _inverse_and_logdet(S: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``S^-1`` and ``log det S`` of a batch of symmetric matrices, shape (B, d, d).

    Closed forms for d = 1 and 2 (the usual radar and position measurements: numpy's
    batched ``inv`` and ``slogdet`` cost far more than their arithmetic on small
    batches), numpy's otherwise.

    Raises
    ------
    InputError
        Where an ``S`` is not positive-definite.
    """
    d = S.shape[-1]
    if d == 1:
        det = S[:, 0, 0]
        positive = det > 0
        inverse = (1.0 / np.where(positive, det, 1.0))[:, None, None]
    elif d == 2:
        a, b, c = S[:, 0, 0], S[:, 0, 1], S[:, 1, 1]
        det = a * c - b * b
        positive = (a > 0) & (det > 0)
        scale = 1.0 / np.where(positive, det, 1.0)
        inverse = np.empty_like(S)
        inverse[:, 0, 0] = c * scale
        inverse[:, 1, 1] = a * scale
        inverse[:, 0, 1] = inverse[:, 1, 0] = -b * scale
    else:
        sign, logdet = np.linalg.slogdet(S)
        if np.any(sign <= 0):
            raise InputError("innovation covariance S is not positive-definite")
        return np.asarray(np.linalg.inv(S), dtype=np.float64), logdet
    if not np.all(positive):
        raise InputError("innovation covariance S is not positive-definite")
    return inverse, np.log(det)


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
