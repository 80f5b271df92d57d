"""Builders shared by several test modules (plain functions and constants, no fixtures).

Test modules import from here (``from support import make_config``), never from each
other; ``tests/test_architecture.py`` checks that.  ``tests/`` is on ``sys.path`` because
pytest's default ``prepend`` import mode inserts the directory of ``tests/conftest.py``.

* :data:`NO_TIME_LIMIT`, the time limit of tests that compare numbers (no window reaches it);
* one-sensor windows: :data:`SENSOR`, :func:`make_config`, :func:`make_scans`,
  :func:`random_window` (used by ``estimator/`` and ``formulations/`` tests);
* brute-force enumeration of track partitions: :func:`partitions`;
* random packing problems and their brute-force per-k tables: :func:`random_problem`,
  :func:`brute_force_tables` (used by ``formulations/`` and ``solvers/`` tests);
* a full disk, as writes see it: :func:`file_size_limit` (used by ``apps/`` tests).
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import math
import resource
import signal
import sys
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from mapassoc.data.config import Config
from mapassoc.data.scans import Scan
from mapassoc.data.settings import BirthModel, EstimatorSettings
from mapassoc.estimator.hypotheses import CarriedTrack
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.formulations.packing import PackingProblem
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import ConstantVelocity, MotionModel
from mapassoc.models.sensor import Region, Sensor

NO_TIME_LIMIT = 600.0
"""``EstimatorSettings.time_limit`` for tests that compare numbers: no window of the
test suite comes near it, so the deterministic work limits alone bound every window and
the results are a function of the input (the clock guard of ``conftest.py`` checks it)."""

SENSOR = "s"
"""The name of the one sensor of :func:`make_config` and :func:`make_scans`."""
MAX_ENUMERATED_HYPOTHESES = 40  # EnumerationSolver's default max_variables

# ------------------------------------------------------------------ one-sensor windows


MINIMAL_CONFIG_TOML = """
[motion]
model = "constant_velocity"
ndim = 2
noise_intensity = 0.5

[[sensors]]
name = "radar"
measurement = "position"
noise_std = 1.0
detection_probability = 0.9
false_alarms_per_scan = 10.0
region = [[-100.0, 100.0], [-100.0, 100.0]]
"""
"""The smallest configuration file: a constant-velocity model and one position sensor
"radar" (no [birth] or [estimator] section)."""


def make_config(
    *,
    motion: MotionModel,
    noise_std: float,
    detection_probability: float,
    false_alarms_per_scan: float,
    region: list[list[float]],
    rate: float = 0.1,
    initial_count: float = 0.0,
    velocity_std: float = 1.0,
    survival_probability: float = 0.95,
    max_tracks: int = 5,
    window_length: int = 3,
    stride: int = 1,
    gate_probability: float = 1.0,
    prune_log_ratio: float = math.inf,
    max_hypotheses_per_tree: int = 10**6,
    solver: str = "highs",
) -> Config:
    """A one-sensor configuration (sensor ``"s"`` with a position measurement).

    The defaults switch every pruning off (no gate, infinite score ratio, no cap), so
    that the window's hypotheses are all the model allows.
    """
    sensor = Sensor(
        name=SENSOR,
        measurement=LinearMeasurement.position(motion, noise_std=noise_std),
        detection_probability=detection_probability,
        false_alarms_per_scan=false_alarms_per_scan,
        region=Region.from_bounds(region),
    )
    return Config(
        motion=motion,
        sensors={SENSOR: sensor},
        birth=BirthModel(
            rate=rate,
            initial_count=initial_count,
            velocity_std=velocity_std,
            survival_probability=survival_probability,
        ),
        estimator=EstimatorSettings(
            window_length=window_length,
            stride=stride,
            max_tracks=max_tracks,
            gate_probability=gate_probability,
            prune_log_ratio=prune_log_ratio,
            max_hypotheses_per_tree=max_hypotheses_per_tree,
            solver=solver,
        ),
    )


def make_scans(times: list[float], detections: list[list[list[float]]], dz: int) -> list[Scan]:
    """Scans of sensor ``"s"`` with rows numbered 2, 3, ... in scan order."""
    scans = []
    row = 2
    for time, dets in zip(times, detections, strict=True):
        z = np.asarray(dets, dtype=float).reshape(len(dets), dz)
        scans.append(Scan(time, SENSOR, z, np.arange(row, row + len(dets), dtype=np.int64)))
        row += len(dets)
    return scans


def random_spd(rng: np.random.Generator, n: int) -> np.ndarray:
    """A random symmetric positive-definite matrix, shape (n, n)."""
    a = rng.normal(0.0, 0.5, size=(n, n))
    return a @ a.T + np.diag(rng.uniform(0.2, 2.0, size=n))


@dataclass(frozen=True, eq=False)
class RandomWindow:
    """A window of :func:`random_window`: its estimator, scans and carried tracks."""

    estimator: WindowEstimator
    scans: list[Scan]
    carried: list[CarriedTrack]


def random_window(seed: int) -> RandomWindow:
    """A random small window whose unmerged program has at most 40 hypotheses.

    1-3 scans at irregular times, 0-3 detections per scan, 0-2 carried tracks, random Pd,
    clutter, birth rate and survival (sometimes exactly 1: no deaths), 1-D or 2-D constant
    velocity.  Draws again (same generator) until the window fits the enumerator.
    """
    rng = np.random.default_rng(seed)
    while True:
        ndim = int(rng.choice([1, 1, 2]))
        motion = ConstantVelocity(ndim=ndim, noise_intensity=float(rng.uniform(0.1, 1.0)))
        num_scans = int(rng.integers(1, 4))
        counts = [int(rng.integers(0, 4)) for _ in range(num_scans)]
        num_carried = int(rng.integers(0, 3))
        times = np.cumsum(np.r_[0.0, rng.uniform(0.5, 2.0, size=num_scans - 1)]).tolist()
        detections = [rng.uniform(-6.0, 6.0, size=(c, ndim)).tolist() for c in counts]
        survival = 1.0 if rng.random() < 0.2 else float(rng.uniform(0.5, 0.99))
        config = make_config(
            motion=motion,
            noise_std=float(rng.uniform(0.3, 1.5)),
            detection_probability=float(rng.uniform(0.4, 0.95)),
            false_alarms_per_scan=float(rng.uniform(0.2, 3.0)),
            region=[[-8.0, 8.0]] * ndim,
            rate=float(rng.uniform(0.05, 1.0)),
            velocity_std=float(rng.uniform(0.3, 2.0)),
            survival_probability=survival,
            max_tracks=sum(counts) + num_carried + 1,  # the top K is always infeasible
        )
        carried = []
        for i in range(num_carried):
            n = motion.state_dim
            mean = np.r_[rng.uniform(-6.0, 6.0, size=ndim), rng.uniform(-1.0, 1.0, size=ndim)]
            time = -float(rng.uniform(0.3, 1.5))
            carried.append(
                CarriedTrack(
                    track_id=10 + i,
                    mean=mean,
                    covariance=random_spd(rng, n),
                    time=time,
                    initiated=True,
                    num_detections=2,
                    first_detection_time=time - 1.0,
                )
            )
        estimator = WindowEstimator(config=config)
        scans = make_scans(times, detections, ndim)
        hypotheses = estimator.generator.generate(scans, carried)
        if hypotheses.count <= MAX_ENUMERATED_HYPOTHESES:
            return RandomWindow(estimator, scans, carried)


# ------------------------------------------------------------------------- partitions


def partitions(scan_of: list[int]) -> Iterator[list[tuple[int, ...]]]:
    """Every partition of the detections into tracks and false alarms.

    Detections are indexed in scan order; a track is a tuple of detections of strictly
    increasing scans (at most one detection per scan).  Each partition appears once:
    a detection is a false alarm, starts a track, or extends a track whose last
    detection is in an earlier scan.
    """
    tracks: list[list[int]] = []

    def place(d: int) -> Iterator[list[tuple[int, ...]]]:
        if d == len(scan_of):
            yield [tuple(t) for t in tracks]
            return
        yield from place(d + 1)  # false alarm
        tracks.append([d])  # new track
        yield from place(d + 1)
        tracks.pop()
        for t in tracks:
            if scan_of[t[-1]] < scan_of[d]:
                t.append(d)
                yield from place(d + 1)
                t.pop()

    yield from place(0)


# ------------------------------------------------------------------- packing problems


def random_problem(rng: np.random.Generator, H: int, D: int, G: int) -> PackingProblem:
    """H hypotheses over D detections and G exactly-one groups (each group keeps a free member)."""
    lists = []
    group_of = rng.integers(-1, G, size=H) if G else np.full(H, -1)
    for g in range(G):  # every group gets a member that uses no detection
        group_of[g % H] = g
    for h in range(H):
        k = 0 if (G and h < G) else int(rng.integers(1, min(3, D) + 1))
        dets = sorted(rng.choice(D, size=k, replace=False).tolist()) if k else []
        res = dets + ([D + int(group_of[h])] if group_of[h] >= 0 else [])
        lists.append(res)
    indptr = np.concatenate([[0], np.cumsum([len(r) for r in lists])])
    indices = np.concatenate([np.asarray(r, dtype=np.int64) for r in lists])
    exactly_one = np.r_[np.zeros(D, bool), np.ones(G, bool)]
    counts = rng.random(H) < 0.9
    scores = rng.normal(0.0, 3.0, size=H)
    return PackingProblem(scores, indptr, indices, exactly_one, counts)


def brute_force_tables(problem: PackingProblem, kmax: int) -> tuple[np.ndarray, np.ndarray]:
    """best[k] and log-mass[k] for k = 0..kmax, by enumerating every subset of hypotheses.

    k counts the selected hypotheses whose ``counts`` flag is set; an infeasible k is -inf.
    """
    best = np.full(kmax + 1, -math.inf)
    terms: list[list[float]] = [[] for _ in range(kmax + 1)]
    H = problem.num_hypotheses
    for r in range(H + 1):
        for sel in itertools.combinations(range(H), r):
            if not problem.is_feasible(np.array(sel, dtype=np.int64)):
                continue
            k = int(np.count_nonzero(problem.counts[list(sel)]))
            if k > kmax:
                continue
            v = problem.value(np.array(sel, dtype=np.int64))
            best[k] = max(best[k], v)
            terms[k].append(v)
    mass = np.array([np.logaddexp.reduce(t) if t else -math.inf for t in terms])
    return best, mass


def banded_problem(rng: np.random.Generator, H: int, D: int, band: int) -> PackingProblem:
    """Hypotheses like a window's: each uses 1-3 detections close together (within
    ``band`` of each other, as a track's detections are close in time) and belongs to a
    tree (one per three detection positions) whose exactly-once resource it uses; each
    tree also has a member with no detection, so every exactly-once row can be met."""
    trees = (D - band) // 3 + 1
    lists = [[D + t] for t in range(trees)]  # the trees' detection-free members
    for _ in range(H - trees):
        start = int(rng.integers(0, D - band))
        chosen = rng.choice(np.arange(start, start + band), size=int(rng.integers(1, 4)))
        lists.append(sorted(set(chosen.tolist())) + [D + start // 3])
    indptr = np.concatenate([[0], np.cumsum([len(r) for r in lists])])
    indices = np.concatenate([np.asarray(r, dtype=np.int64) for r in lists])
    exactly_one = np.r_[np.zeros(D, dtype=bool), np.ones(trees, dtype=bool)]
    return PackingProblem(
        rng.normal(0.0, 3.0, size=H), indptr, indices, exactly_one, rng.random(H) < 0.9
    )


# ------------------------------------------------------------------ a full disk


@contextlib.contextmanager
def file_size_limit(size: int) -> Iterator[None]:
    """Inside the block, a write past ``size`` bytes of any file fails (``EFBIG``) after
    writing what fits, as a write to a full disk does, whatever code makes it."""
    previous = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (size, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, previous)


def polling_unit(units: tuple[str, ...], depth: int = 3) -> str:
    """The innermost function of ``units`` on the call stack above a ``stop`` callable's
    ``__call__`` (``depth`` frames up: this function, the caller's helper, the poll), or
    ``"other"``: which phase's unit of work polled the run's stop."""
    frame = sys._getframe(depth)
    while frame is not None:
        if frame.f_code.co_name in units:
            return frame.f_code.co_name
        frame = frame.f_back  # type: ignore[assignment]
    return "other"


TINY_NOISE_INTENSITY = 0.4


def tiny_recording(seed: int, num_scans: int = 3, most: int = 2) -> tuple[Config, list[Scan]]:
    """A random 1-D or 2-D recording of ``num_scans`` scans with 0..``most`` detections each."""
    rng = np.random.default_rng(seed)
    ndim = int(rng.choice([1, 2]))
    motion = ConstantVelocity(ndim=ndim, noise_intensity=TINY_NOISE_INTENSITY)
    times = np.cumsum(np.r_[0.0, rng.uniform(0.5, 1.5, size=num_scans - 1)]).tolist()
    counts = [int(rng.integers(0, most + 1)) for _ in range(num_scans)]
    # Targets that move a little plus clutter, so that some track sets score well.
    start = rng.uniform(-3.0, 3.0, size=ndim)
    detections = []
    for t, c in zip(times, counts, strict=True):
        points = [start + 0.5 * t + rng.normal(0, 0.4, size=ndim) for _ in range(c)]
        if c and rng.random() < 0.5:
            points[-1] = rng.uniform(-6.0, 6.0, size=ndim)
        detections.append([p.tolist() for p in points])
    config = make_config(
        motion=motion,
        noise_std=float(rng.uniform(0.3, 0.8)),
        detection_probability=float(rng.uniform(0.5, 0.95)),
        false_alarms_per_scan=float(rng.uniform(0.3, 2.0)),
        region=[[-8.0, 8.0]] * ndim,
        rate=float(rng.uniform(0.1, 0.8)),
        initial_count=float(rng.uniform(0.0, 2.0)),
        velocity_std=float(rng.uniform(0.5, 1.5)),
        survival_probability=float(rng.uniform(0.6, 0.99)),
        window_length=num_scans,
    )
    config = dataclasses.replace(
        config, estimator=dataclasses.replace(config.estimator, time_limit=NO_TIME_LIMIT)
    )
    return config, make_scans(times, detections, ndim)


def all_track_sets(scans: list[Scan]) -> Iterator[list[tuple[tuple[int, int], ...]]]:
    """Every track set of a recording, as lists of ((scan, index), ...) paths."""
    where = [(k, i) for k, scan in enumerate(scans) for i in range(scan.size)]
    for partition in partitions([k for k, _ in where]):
        yield [tuple(where[d] for d in track) for track in partition]


def feasible_track_set(tracks: dict[int, tuple[tuple[int, int], ...]]) -> bool:
    """Whether every track is in scan order with at most one detection per scan and no
    detection is used twice."""
    used = [d for path in tracks.values() for d in path]
    ordered = all(
        list(path) == sorted(path) and len({m for m, _ in path}) == len(path)
        for path in tracks.values()
    )
    return ordered and len(used) == len(set(used))


def single_detection_tracks(scans: list[Scan]) -> dict[int, tuple[tuple[int, int], ...]]:
    """A poor starting set: every detection its own track (ids from 1)."""
    where = [(m, j) for m, scan in enumerate(scans) for j in range(scan.size)]
    return {i + 1: (d,) for i, d in enumerate(where)}


def fresh_hypothesis_paths(hypotheses) -> Iterator[tuple[list[int], tuple[tuple[int, int], ...]]]:
    """Each hypothesis of a window's trees that is not a carried tree's: its nodes with a
    detection, root first, and its path of ``(scan, index in scan)``."""
    nodes, window = hypotheses.nodes, hypotheses.detections
    for h in range(hypotheses.count):
        if hypotheses.tree_track_ids[hypotheses.tree[h]] >= 0:
            continue  # carried trees have no prior here (the window starts the recording)
        along = [v for v in nodes.path(int(hypotheses.leaf[h])) if nodes.detection[v] >= 0]
        path = tuple(
            (int(window.scan_position[d]), int(window.index_in_scan[d]))
            for d in nodes.detection[along]
        )
        yield along, path
