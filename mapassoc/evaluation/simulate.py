"""Seeded, reproducible simulation of targets, detections and false alarms.

The generative model is the one the estimator assumes (Afzal's survey, sections 4 and 5.1):

* **Motion** (Afzal's survey, section 4, "Motion Modeling"): between consecutive scan times a
  target's true state follows ``x_k = f(x_{k-1}, dt) + q``, ``q ~ N(0, Q(dt))``, with the
  configuration's motion model.  A target exists from ``birth_time`` to ``death_time``
  (inclusive); its state at ``birth_time`` is :attr:`TargetSpec.initial_state`.
* **Detection** (Afzal's survey, eqs. 9-11): at each scan of sensor s, each alive target is
  detected with probability ``Pd_s``; a detection is ``z = h(x) + v``, ``v ~ N(0, R)``,
  with angular components (the bearing of a range-bearing sensor) wrapped to (-pi, pi].
  A detection whose value falls outside the sensor's region is dropped: the sensor only
  reports inside its surveillance region, so the target counts as missed in that scan.
* **False alarms** (Afzal's survey, eqs. 12-13): ``Poisson(lambda_bar_s)`` per scan, uniform over
  the sensor's region.
* **Shuffle** (Afzal's survey, eq. 14, ``Z_k = Pi(O_k, C_k)``): target detections and false alarms
  are put in a random order within the scan.

Randomness comes only from ``numpy.random.Generator`` objects derived from the ``seed``
argument (no global RNG): ``SeedSequence(seed)`` spawns one stream per target for its
motion and one stream for all sensing (detection draws, measurement noise, false alarms,
shuffles).  So a target's true trajectory does not change when other targets are added,
and the same seed reproduces the same scenario bit for bit.

Target ids are ``1, 2, ..., len(targets)`` in the order of the ``targets`` list; ``-1``
marks a false alarm in :class:`~mapassoc.data.io.Origins`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config, write_config
from mapassoc.data.io import (
    Origins,
    TruthTable,
    number_rows,
)
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError, NotPositiveDefiniteError
from mapassoc.models.sensor import Sensor
from mapassoc.validation import check_finite_array, check_positive

__all__ = [
    "TargetSpec",
    "Scenario",
    "simulate",
    "write_scenario",
    "scan_plan_regular",
    "gaussian_factor",
    "SCENARIO_FILES",
]

#: File names written by :func:`write_scenario`, keyed by the keys of its result.
SCENARIO_FILES = {
    "detections": "detections.csv",
    "truth": "truth.csv",
    "origins": "origins.csv",
    "config": "config.toml",
}

# Eigenvalues of a covariance above -_ROUNDOFF * max(1, largest |eigenvalue|) count as
# round-off of a positive-semidefinite matrix and are set to zero; anything more negative
# is a genuinely indefinite matrix and raises.
_ROUNDOFF = 1e-10


@dataclass(frozen=True, eq=False)
class TargetSpec:
    """One simulated target.

    Parameters
    ----------
    initial_state : ndarray, shape (n,)
        True state at ``birth_time``, in the motion model's state space (for example
        ``(x, y, vx, vy)`` for 2-D constant velocity, ``(x, y, speed, heading, turn_rate)``
        for coordinated turn).
    birth_time : float
        First time at which the target exists.
    death_time : float
        Last time at which the target exists (``>= birth_time``; ``inf`` is allowed and
        means "until the end of the scan plan").
    """

    initial_state: FloatArray
    birth_time: float
    death_time: float

    def __post_init__(self) -> None:
        state = check_finite_array("initial_state", self.initial_state)
        if state.ndim != 1 or state.size == 0:
            raise InputError(
                f"initial_state must be a 1-D state vector (n,), got shape {state.shape}"
            )
        birth = float(self.birth_time)
        death = float(self.death_time)
        if not math.isfinite(birth):
            raise InputError(f"birth_time must be finite, got {self.birth_time!r}")
        if math.isnan(death) or death < birth:
            raise InputError(f"death_time must be >= birth_time ({birth}), got {self.death_time!r}")
        state.setflags(write=False)
        object.__setattr__(self, "initial_state", state)
        object.__setattr__(self, "birth_time", birth)
        object.__setattr__(self, "death_time", death)

    def alive_at(self, time: float) -> bool:
        """Whether the target exists at ``time`` (inclusive span)."""
        return self.birth_time <= time <= self.death_time


@dataclass(frozen=True, eq=False)
class Scenario:
    """A simulated run: configuration, detections and ground truth.

    Parameters
    ----------
    name : str
        Scenario name.
    config : Config
        Motion model, sensors, birth model and estimator settings matching the simulation.
    scans : list of Scan
        Scans sorted by (time, sensor), rows numbered as the detections file numbers them
        (:func:`mapassoc.data.io.number_rows`).
    truth : TruthTable
        One row per (target, distinct scan time) at which the target is alive, sorted by
        (time, target id).
    origins : Origins
        For every detection row, the id of the target that produced it or ``-1`` for a
        false alarm; sorted by row.
    """

    name: str
    config: Config
    scans: list[Scan]
    truth: TruthTable
    origins: Origins

    @property
    def detection_count(self) -> int:
        """Total number of detections over all scans."""
        return sum(scan.size for scan in self.scans)


def gaussian_factor(covariance: ArrayLike, name: str = "covariance") -> FloatArray:
    """A matrix ``A`` with ``A A^T = covariance``, for sampling ``A @ N(0, I)``.

    Computed by ``numpy.linalg.eigh`` so that singular positive-semidefinite matrices
    (the process noise of the coordinated-turn model has no position component) are
    sampled exactly in their range.  Negative eigenvalues no larger in magnitude than
    ``1e-10 * max(1, largest |eigenvalue|)`` are round-off of a semidefinite matrix and are
    set to zero; any more negative eigenvalue raises.  No jitter is added.

    Parameters
    ----------
    covariance : array_like, shape (n, n)
        Symmetric positive-semidefinite matrix.
    name : str
        Name used in error messages.

    Returns
    -------
    ndarray, shape (n, n)

    Raises
    ------
    NotPositiveDefiniteError
        Not symmetric, or an eigenvalue is negative beyond round-off.
    """
    C = check_finite_array(name, covariance)
    if C.ndim != 2 or C.shape[0] != C.shape[1]:
        raise InputError(f"{name} must be a square (n, n) matrix, got shape {C.shape}")
    scale = max(1.0, float(np.max(np.abs(C)))) if C.size else 1.0
    if not np.allclose(C, C.T, rtol=1e-9, atol=1e-12 * scale):
        raise NotPositiveDefiniteError(f"{name} must be symmetric, got {C.tolist()!r}")
    eigenvalues, eigenvectors = np.linalg.eigh(C)
    tolerance = _ROUNDOFF * max(1.0, float(np.max(np.abs(eigenvalues))))
    if eigenvalues.size and eigenvalues.min() < -tolerance:
        raise NotPositiveDefiniteError(
            f"{name} must be positive-semidefinite, got eigenvalues {eigenvalues.tolist()!r}"
        )
    roots = np.sqrt(np.where(eigenvalues < 0.0, 0.0, eigenvalues))
    return eigenvectors * roots[None, :]


def _check_seed(seed: object) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def _check_plan(
    scan_plan: Sequence[tuple[float, str]], sensor_names: Sequence[str]
) -> list[tuple[float, str]]:
    """Validate the plan and return it sorted by (time, sensor)."""
    if len(scan_plan) == 0:
        raise InputError("scan_plan must contain at least one (time, sensor_name) pair")
    plan: list[tuple[float, str]] = []
    for i, entry in enumerate(scan_plan):
        if not (isinstance(entry, (tuple, list)) and len(entry) == 2):
            raise InputError(f"scan_plan[{i}] must be a (time, sensor_name) pair, got {entry!r}")
        time, sensor = entry
        if isinstance(time, bool) or not isinstance(time, (int, float, np.integer, np.floating)):
            raise InputError(f"scan_plan[{i}] time must be a number, got {time!r}")
        t = float(time)
        if not math.isfinite(t):
            raise InputError(f"scan_plan[{i}] time must be finite, got {time!r}")
        if sensor not in sensor_names:
            raise InputError(
                f"scan_plan[{i}] names sensor {sensor!r}, which is not in the configuration "
                f"(sensors: {sorted(sensor_names)})"
            )
        if plan and t < plan[-1][0]:
            raise InputError(
                f"scan_plan must be sorted by time: entry {i} at time {t} follows time "
                f"{plan[-1][0]}"
            )
        plan.append((t, str(sensor)))
    ordered = sorted(plan)
    for previous, current in zip(ordered, ordered[1:], strict=False):
        if previous == current:
            raise InputError(
                f"scan_plan has sensor {current[1]!r} twice at time {current[0]}; one scan "
                f"per (time, sensor) is allowed"
            )
    return ordered


def _simulate_truth(
    config: Config,
    targets: Sequence[TargetSpec],
    times: FloatArray,
    streams: Sequence[np.random.Generator],
) -> list[dict[float, FloatArray]]:
    """True state of each target at each distinct scan time at which it is alive.

    ``times`` is sorted; each target visits only the times of its own life (found by
    bisection), so the work is linear in the number of (target, time) records.
    """
    motion = config.motion
    factors: dict[float, FloatArray] = {}
    # A linear model's transition is x -> F(dt) x with F its (constant) Jacobian.
    matrices: dict[float, FloatArray] = {}
    trajectories: list[dict[float, FloatArray]] = []
    for target, rng in zip(targets, streams, strict=True):
        state = np.array(target.initial_state, dtype=float)
        previous_time = target.birth_time
        trajectory: dict[float, FloatArray] = {}
        first = int(np.searchsorted(times, target.birth_time, side="left"))
        stop = int(np.searchsorted(times, target.death_time, side="right"))
        for time in times[first:stop]:
            dt = float(time) - previous_time
            if dt > 0.0:
                if dt not in factors:
                    factors[dt] = gaussian_factor(
                        motion.process_noise(dt), f"process noise Q(dt={dt})"
                    )
                noise = factors[dt] @ rng.standard_normal(motion.state_dim)
                if motion.is_linear:
                    if dt not in matrices:
                        matrices[dt] = motion.jacobian(state, dt)
                    state = matrices[dt] @ state + noise
                else:
                    state = motion.transition(state, dt) + noise
            trajectory[float(time)] = state.copy()
            previous_time = float(time)
        trajectories.append(trajectory)
    return trajectories


def _alive_by_time(trajectories: Sequence[dict[float, FloatArray]]) -> dict[float, list[int]]:
    """Indices of the targets alive at each time, ascending (one pass over the records)."""
    alive: dict[float, list[int]] = {}
    for k, trajectory in enumerate(trajectories):
        for time in trajectory:
            alive.setdefault(time, []).append(k)
    return alive


def _check_targets(config: Config, targets: Sequence[TargetSpec]) -> None:
    """Every target a :class:`TargetSpec` whose state fits the motion model."""
    n = config.motion.state_dim
    for i, target in enumerate(targets):
        if not isinstance(target, TargetSpec):
            raise InputError(f"targets[{i}] must be a TargetSpec, got {target!r}")
        if target.initial_state.shape != (n,):
            raise InputError(
                f"targets[{i}].initial_state must have shape ({n},) for the "
                f"{type(config.motion).__name__} state {config.motion.state_names}, got "
                f"shape {target.initial_state.shape}"
            )


@dataclass(frozen=True, eq=False)
class _SimulatedTruth:
    """The true trajectories at the distinct scan times.

    Attributes
    ----------
    times : ndarray, shape (N,)
        Distinct scan times, sorted.
    trajectories : list of dict of float to ndarray
        State of target ``k`` at each time it is alive.
    alive_at : dict of float to list of int
        Indices of the targets alive at each time, ascending.
    target_ids : ndarray of int, shape (len(targets),)
        ``1, 2, ...``: the id of each target.
    """

    times: FloatArray
    trajectories: list[dict[float, FloatArray]]
    alive_at: dict[float, list[int]]
    target_ids: NDArray[np.int64]


def _noise_factors(config: Config) -> dict[str, FloatArray]:
    """A square root of every sensor's measurement noise covariance R, by sensor name."""
    return {
        sensor_name: gaussian_factor(
            sensor.measurement.noise_covariance, f"sensor '{sensor_name}' measurement noise R"
        )
        for sensor_name, sensor in config.sensors.items()
    }


def _observe(
    sensor: Sensor,
    noise_factor: FloatArray,
    truth: _SimulatedTruth,
    time: float,
    rng: np.random.Generator,
) -> tuple[FloatArray, NDArray[np.int64]]:
    """One scan of ``sensor`` at ``time``: its shuffled detections and their origins.

    Returns
    -------
    detections : ndarray, shape (m, dz)
    origins : ndarray of int, shape (m,)
        Target id of each detection, -1 for a false alarm.
    """
    model = sensor.measurement
    dz = model.measurement_dim
    alive = truth.alive_at.get(time, [])
    # Draw order is fixed (detection flags, noise, clutter count, clutter, shuffle) so
    # that the stream, and hence the scenario, depends only on the seed.
    detected = rng.random(len(alive)) < sensor.detection_probability
    noise = rng.standard_normal((len(alive), dz)) @ noise_factor.T
    if alive:
        states = np.stack([truth.trajectories[k][time] for k in alive])
        values = model.predict(states) + noise
        # The residual against zero is the identity on linear components and wraps
        # angular ones (bearing) to (-pi, pi].
        values = model.residual(values, np.zeros_like(values))
    else:
        values = np.empty((0, dz))
    keep = detected & sensor.region.contains(values)
    clutter_count = int(rng.poisson(sensor.false_alarms_per_scan))
    clutter = sensor.region.sample(rng, clutter_count)
    detections = np.concatenate([values[keep], clutter.reshape(-1, dz)])
    origin = np.concatenate(
        [
            truth.target_ids[np.asarray(alive, dtype=np.int64)[keep]],
            -np.ones(clutter_count, np.int64),
        ]
    )
    order = rng.permutation(detections.shape[0])
    m = detections.shape[0]
    return detections[order].reshape(m, dz), origin[order].astype(np.int64)


def _observe_plan(
    config: Config,
    plan: Sequence[tuple[float, str]],
    truth: _SimulatedTruth,
    rng: np.random.Generator,
) -> tuple[list[Scan], Origins]:
    """The scans of the plan, in its order, with file row numbers, and their origins."""
    noise_factors = _noise_factors(config)
    raw_scans: list[Scan] = []
    scan_origins: list[NDArray[np.int64]] = []
    next_placeholder = 0
    for time, sensor_name in plan:
        detections, origin = _observe(
            config.sensors[sensor_name], noise_factors[sensor_name], truth, time, rng
        )
        m = detections.shape[0]
        raw_scans.append(
            Scan(
                time=time,
                sensor=sensor_name,
                detections=detections,
                rows=np.arange(next_placeholder, next_placeholder + m, dtype=np.int64),
            )
        )
        scan_origins.append(origin)
        next_placeholder += m
    scans = number_rows(raw_scans)
    rows = np.concatenate([s.rows for s in scans]) if scans else np.empty(0, np.int64)
    origin_ids = np.concatenate(scan_origins) if scan_origins else np.empty(0, np.int64)
    by_row = np.argsort(rows, kind="stable")
    origins = Origins(rows=rows[by_row].astype(np.int64), target_ids=origin_ids[by_row])
    return list(scans), origins


def _truth_table(config: Config, truth: _SimulatedTruth) -> TruthTable:
    """The true states at every scan time, by time, then by target."""
    truth_ids: list[int] = []
    truth_times: list[float] = []
    truth_states: list[FloatArray] = []
    for time in truth.times:
        for k in truth.alive_at.get(float(time), []):
            truth_ids.append(int(truth.target_ids[k]))
            truth_times.append(float(time))
            truth_states.append(truth.trajectories[k][float(time)])
    return TruthTable(
        target_ids=np.array(truth_ids, dtype=np.int64),
        times=np.array(truth_times, dtype=float),
        states=np.array(truth_states, dtype=float).reshape(len(truth_ids), config.motion.state_dim),
        state_names=tuple(config.motion.state_names),
    )


def simulate(
    config: Config,
    targets: Sequence[TargetSpec],
    scan_plan: Sequence[tuple[float, str]],
    *,
    seed: int,
    name: str = "simulated",
) -> Scenario:
    """Simulate detections of ``targets`` by the sensors of ``config``.

    Parameters
    ----------
    config : Config
        Motion model used to propagate the true states and sensors that observe them.
    targets : sequence of TargetSpec
        Target ``i`` (0-based) gets the id ``i + 1``.
    scan_plan : sequence of (float, str)
        ``(time, sensor_name)`` pairs sorted by time; several sensors may share a time
        (the scans are then ordered by sensor name), one sensor may not scan twice at
        the same time.
    seed : int
        Non-negative seed of every random draw.
    name : str
        Name stored in the returned scenario.

    Returns
    -------
    Scenario
        Scans with file row numbers, truth at every scan time and the origin of every
        detection.

    Raises
    ------
    InputError
        A target state of the wrong length, an unknown sensor in the plan, an unsorted
        plan, or a bad seed.
    """
    seed = _check_seed(seed)
    if not isinstance(name, str) or not name:
        raise InputError(f"name must be a non-empty string, got {name!r}")
    _check_targets(config, targets)
    plan = _check_plan(scan_plan, list(config.sensors))

    motion_seeds, sensing_seed = np.random.SeedSequence(seed).spawn(2)
    motion_streams = [np.random.default_rng(s) for s in motion_seeds.spawn(len(targets))]
    rng = np.random.default_rng(sensing_seed)

    times = np.unique(np.array([t for t, _ in plan]))
    trajectories = _simulate_truth(config, targets, times, motion_streams)
    truth = _SimulatedTruth(
        times=times,
        trajectories=trajectories,
        alive_at=_alive_by_time(trajectories),
        target_ids=np.arange(1, len(targets) + 1, dtype=np.int64),
    )
    scans, origins = _observe_plan(config, plan, truth, rng)
    return Scenario(
        name=name, config=config, scans=scans, truth=_truth_table(config, truth), origins=origins
    )


def write_scenario(
    scenario: Scenario, out_dir: str | Path, *, data_format: str = "csv"
) -> dict[str, Path]:
    """Write a scenario's detections, truth, origins and configuration files.

    ``out_dir`` is created if needed; existing files of the same names are overwritten.

    Parameters
    ----------
    scenario : Scenario
    out_dir : str or Path
    data_format : str
        Format of the detections, truth and origins files, a name of
        :data:`~mapassoc.data.formats.FILE_FORMATS` (``"csv"`` or ``"parquet"``;
        Parquet needs the ``parquet`` extra).  Detection ids are the same in both: the
        CSV lines, which a Parquet file keeps in its ``detection_id`` column.

    Returns
    -------
    dict of str to Path
        Paths written, keyed ``"detections"``, ``"truth"``, ``"origins"`` and ``"config"``
        (file names in :data:`SCENARIO_FILES`, with the suffix of ``data_format``).
    """
    from mapassoc.data.formats import (
        file_name,
        format_names,
        write_detections_file,
        write_origins_file,
        write_truth_file,
    )

    if not isinstance(scenario, Scenario):
        raise InputError(f"scenario must be a Scenario, got {scenario!r}")
    if data_format not in format_names():
        raise InputError(
            f"data_format must be one of {', '.join(repr(n) for n in format_names())}, "
            f"got {data_format!r}"
        )
    directory = Path(out_dir)
    if directory.exists() and not directory.is_dir():
        raise InputError(f"out_dir must be a directory, got the existing file {str(directory)!r}")
    directory.mkdir(parents=True, exist_ok=True)
    paths = {key: directory / filename for key, filename in SCENARIO_FILES.items()}
    for key in ("detections", "truth", "origins"):
        paths[key] = directory / file_name(key, data_format)
    write_detections_file(paths["detections"], scenario.scans, scenario.config.sensors)
    write_truth_file(paths["truth"], scenario.truth)
    write_origins_file(paths["origins"], scenario.origins)
    write_config(paths["config"], scenario.config)
    return paths


def scan_plan_regular(
    sensors: Sequence[str],
    start: float,
    interval: float,
    count: int,
    offsets: Sequence[float] | None = None,
) -> list[tuple[float, str]]:
    """A plan in which every sensor scans ``count`` times at a regular interval.

    Sensor ``i`` scans at ``start + offsets[i] + k * interval`` for ``k = 0..count-1``.

    Parameters
    ----------
    sensors : sequence of str
        Distinct sensor names.
    start : float
        Time of the first scan (before offsets).
    interval : float
        Time between two scans of the same sensor, > 0.
    count : int
        Scans per sensor, >= 1.
    offsets : sequence of float, optional
        Per-sensor time offsets (default all 0; e.g. ``[0, interval / 2]`` interleaves two
        sensors).

    Returns
    -------
    list of (float, str)
        Sorted by (time, sensor name).
    """
    names = list(sensors)
    if not names or len(set(names)) != len(names) or not all(isinstance(s, str) for s in names):
        raise InputError(f"sensors must be a non-empty list of distinct names, got {sensors!r}")
    t0 = check_finite_array("start", start, shape=())
    step = check_positive("interval", interval)
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
        raise InputError(f"count must be an integer >= 1, got {count!r}")
    shifts = (
        np.zeros(len(names))
        if offsets is None
        else check_finite_array("offsets", offsets, shape=(len(names),))
    )
    plan = [
        (float(t0 + shift + k * step), name)
        for name, shift in zip(names, shifts, strict=True)
        for k in range(int(count))
    ]
    return sorted(plan)
