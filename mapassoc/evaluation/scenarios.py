"""Named built-in scenarios for demonstrations, tests and benchmarks.

Each scenario fixes a geometry (targets, sensors, scan times) and takes the seed of the
random realisation (process noise, detections, false alarms): ``build_scenario(name, seed)``.
The geometry does not depend on the seed; the random layouts (``"dense"``, ``"dense50"``,
``"dense_pd08"``, the ``"scale*"`` family and ``"burst"``) are drawn once from fixed layout
seeds.

The hard families stress one difficulty each: ``"parallel"`` (a close formation, targets
2.5 noise standard deviations apart), ``"dense_pd08"`` (missed detections in heavy
clutter), ``"scale20"`` / ``"scale50"`` / ``"scale100"`` (size at a fixed density) and
``"burst"`` (one scan flooded by 2,000 extra false alarms).  :func:`generic_config` gives
the configuration the benchmark runs them with, the same recipe for every family.

Every scenario's configuration matches its simulation: the same motion model and noise,
the simulated sensors, a :class:`~mapassoc.data.settings.BirthModel` derived from the targets
(:func:`birth_model_for`) and default :class:`~mapassoc.data.settings.EstimatorSettings` except
``max_tracks`` (:func:`max_tracks_for`).  The one exception is ``"burst"``, whose
configuration keeps the normal false-alarm rate: the burst is what it should survive.

Speeds are 1-3 length units per unit time (about 1 in the hard families) with position
noise of standard deviation 1 (think 10 m) and scans one time unit apart, so every target
is trackable on its own; the difficulty comes from crossings, close formations, false
alarms and missed detections.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from mapassoc.data.config import Config
from mapassoc.data.io import Origins, TruthTable, number_rows
from mapassoc.data.scans import Scan
from mapassoc.data.settings import BirthModel, EstimatorSettings
from mapassoc.errors import InputError
from mapassoc.evaluation.simulate import Scenario, TargetSpec, scan_plan_regular, simulate
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity, CoordinatedTurn, MotionModel
from mapassoc.models.sensor import Region, Sensor

__all__ = [
    "SCENARIOS",
    "DEFAULT_SCENARIO",
    "build_scenario",
    "scenario_names",
    "describe_scenario",
    "birth_model_for",
    "max_tracks_for",
    "generic_config",
    "top_initial_speed",
    "add_false_alarms",
    "truncate_scenario",
    "PARALLEL_SPACING",
    "SCALE_AREA_PER_TARGET",
    "SCALE_FALSE_ALARMS_PER_AREA",
    "BURST_SCAN",
    "BURST_FALSE_ALARMS",
    "GENERIC_BIRTH_RATE",
    "GENERIC_INITIAL_COUNT",
]

FloatArray = NDArray[np.float64]
Plan = list[tuple[float, str]]

DEFAULT_SCENARIO = "crossing"

# Nearly-constant-velocity acceleration noise intensity of the Cartesian scenarios
# (length^2 / time^3): the velocity wanders by about 0.045 per unit time, so over a
# 60-scan run a target keeps its heading to within a few degrees.
_CV_NOISE = 0.002
# Coordinated-turn noise: along-track acceleration and turn-rate derivative intensities.
_CT_SPEED_NOISE = 0.001
_CT_TURN_NOISE = 1e-6
# Fixed seed of the random layouts of "dense" and "dense50" (geometry, not noise); the
# other random layouts use fixed offsets from it.
_LAYOUT_SEED = 20240601
# Acceleration noise intensity of the "parallel" formation: neighbours' across-track
# distance drifts by sqrt(2 q t^3 / 3) ~ 0.9 units over 40 scans, so they stay abreast.
_FORMATION_NOISE = 2e-5
# Acceleration noise intensity of "dense_pd08", the "scale*" family and "burst", whose
# targets move at about 1 unit per scan: each velocity component wanders by about
# sqrt(q t) ~ 0.14 over 40 scans, so speeds stay near 1 (with 0.002 they would wander by
# 0.28, a quarter of the speed).
_SLOW_CV_NOISE = 5e-4

#: Across-track distance of neighbouring targets in ``"parallel"`` (noise std units).
PARALLEL_SPACING = 2.5
#: Region area per target of the ``"scale*"`` family (units^2; 1,000 = 0.1 km^2 at 10 m).
SCALE_AREA_PER_TARGET = 1_000.0
#: False alarms per scan per ``SCALE_AREA_PER_TARGET`` of region in the ``"scale*"`` family.
SCALE_FALSE_ALARMS_PER_AREA = 2.0
#: Index of the scan of ``"burst"`` that gets the extra false alarms (the middle of 40).
BURST_SCAN = 20
#: Extra false alarms in that scan.
BURST_FALSE_ALARMS = 2000
#: Birth rate (new targets per scan) of :func:`generic_config`.
GENERIC_BIRTH_RATE = 0.05
#: Expected targets present at the start in :func:`generic_config`.
GENERIC_INITIAL_COUNT = 5.0


# --------------------------------------------------------------------------- helpers


def _through(
    point: tuple[float, float],
    at_time: float,
    velocity: tuple[float, float],
    birth_time: float,
    death_time: float,
) -> TargetSpec:
    """A constant-velocity target whose noise-free path passes ``point`` at ``at_time``."""
    v = np.asarray(velocity, dtype=float)
    start = np.asarray(point, dtype=float) - v * (at_time - birth_time)
    return TargetSpec(
        initial_state=np.concatenate([start, v]), birth_time=birth_time, death_time=death_time
    )


def _turning(
    start: tuple[float, float],
    speed: float,
    heading: float,
    turn_rate: float,
    birth_time: float,
    death_time: float,
) -> TargetSpec:
    """A coordinated-turn target state ``(x, y, speed, heading, turn_rate)`` at birth."""
    return TargetSpec(
        initial_state=np.array([start[0], start[1], speed, heading, turn_rate]),
        birth_time=birth_time,
        death_time=death_time,
    )


def _speed(motion: MotionModel, state: FloatArray) -> float:
    return motion.speed(state)


def birth_model_for(motion: MotionModel, targets: Sequence[TargetSpec], plan: Plan) -> BirthModel:
    """A birth model consistent with the simulated targets.

    * ``initial_count``: targets alive at the first scan (the initial population);
    * ``rate``: targets born after the first scan, per scan of the plan, at least 0.01.
    * ``velocity_std`` and ``speed_std``: 1.5 times the largest initial speed, at least 1,
      so that the birth prior covers every true velocity component, including the drift
      of the speeds under process noise, within one standard deviation.
    * ``turn_rate_std``: twice the largest initial turn rate, at least 0.02 rad per unit time.
    * ``survival_probability``: ``exp(-deaths / alive time)`` per unit time, the
      exponential survival whose hazard is the observed death rate; a target dies when
      its ``death_time`` is before the last scan.  At least one death is counted so that
      track ends stay possible.

    Parameters
    ----------
    motion : MotionModel
    targets : sequence of TargetSpec
    plan : list of (float, str)
        The scan plan, sorted by time.
    """
    if not plan:
        raise InputError("plan must contain at least one scan")
    first, last = plan[0][0], plan[-1][0]
    seen = [t for t in targets if t.birth_time <= last and t.death_time >= first]
    if not seen:
        raise InputError("no target is alive during the scan plan")
    present = sum(1 for t in seen if t.birth_time <= first)
    births = len(seen) - present
    deaths = sum(1 for t in seen if t.death_time < last)
    alive_time = sum(min(t.death_time, last) - max(t.birth_time, first) for t in seen)
    hazard = max(deaths, 1) / max(alive_time, 1.0)
    top_speed = max(_speed(motion, t.initial_state) for t in seen)
    top_turn = max(abs(motion.turn_rate(t.initial_state)) for t in seen)
    return BirthModel(
        rate=max(0.01, births / len(plan)),
        initial_count=float(present),
        velocity_std=max(1.0, 1.5 * top_speed),
        speed_std=max(1.0, 1.5 * top_speed),
        turn_rate_std=max(0.02, 2.0 * top_turn),
        survival_probability=math.exp(-hazard),
    )


def max_tracks_for(targets: Sequence[TargetSpec], plan: Plan) -> int:
    """``max(8, ceil(2.5 * most targets alive at one scan time))``."""
    most = max(sum(1 for t in targets if t.alive_at(time)) for time, _ in plan)
    return max(8, math.ceil(2.5 * most))


def _scenario(
    name: str,
    motion: MotionModel,
    sensors: Sequence[Sensor],
    targets: Sequence[TargetSpec],
    plan: Plan,
    seed: int,
) -> Scenario:
    config = Config(
        motion=motion,
        sensors={sensor.name: sensor for sensor in sensors},
        birth=birth_model_for(motion, targets, plan),
        estimator=EstimatorSettings(max_tracks=max_tracks_for(targets, plan)),
    )
    return simulate(config, targets, plan, seed=seed, name=name)


def _position_sensor(
    motion: MotionModel,
    half_width: float,
    false_alarms: float,
    *,
    name: str = "pos",
    detection_probability: float = 0.9,
) -> Sensor:
    return Sensor(
        name=name,
        measurement=LinearMeasurement.position(motion, noise_std=1.0),
        detection_probability=detection_probability,
        false_alarms_per_scan=false_alarms,
        region=Region.from_bounds([[-half_width, half_width], [-half_width, half_width]]),
    )


def _random_life(
    rng: np.random.Generator, n_scans: int, must_cover: float | None
) -> tuple[int, int]:
    """Birth and death scan of a random target; the span covers ``must_cover`` if given."""
    last = n_scans - 1
    min_life = n_scans // 2
    latest_birth = n_scans // 3 if must_cover is None else min(n_scans // 3, int(must_cover) - 5)
    birth = 0 if rng.random() < 0.6 or latest_birth < 1 else int(rng.integers(1, latest_birth + 1))
    earliest_death = (
        birth + min_life if must_cover is None else max(birth + min_life, int(must_cover) + 5)
    )
    if rng.random() < 0.7 or earliest_death > last - 1:
        return birth, last
    return birth, int(rng.integers(earliest_death, last))


def _inside(point: FloatArray, limit: float) -> bool:
    return bool(np.all(np.abs(point) <= limit))


def _random_layout(
    rng: np.random.Generator,
    half_width: float,
    n_pairs: int,
    n_singles: int,
    n_scans: int,
    speeds: tuple[float, float] = (1.0, 3.0),
) -> list[TargetSpec]:
    """Crossing pairs plus independent targets, all inside 90% of the region over their life.

    A pair's two noise-free paths meet at the same point at the same time (a crossing in
    time, not only in space), with headings 30 to 150 degrees apart.  Speeds are uniform in
    ``speeds`` (default [1, 3]) per unit time, headings uniform.
    """
    limit = 0.9 * half_width
    targets: list[TargetSpec] = []

    def fits(spec: TargetSpec) -> bool:
        start = spec.initial_state[:2]
        end = start + spec.initial_state[2:] * (spec.death_time - spec.birth_time)
        return _inside(start, limit) and _inside(end, limit)

    while len(targets) < 2 * n_pairs:
        meet = rng.uniform(-0.6 * half_width, 0.6 * half_width, size=2)
        meet_time = float(rng.integers(n_scans // 3, 2 * n_scans // 3 + 1))
        heading = rng.uniform(-math.pi, math.pi)
        headings = (
            heading,
            heading + rng.choice([-1.0, 1.0]) * rng.uniform(math.pi / 6, 5 * math.pi / 6),
        )
        pair = []
        for h in headings:
            speed = rng.uniform(*speeds)
            birth, death = _random_life(rng, n_scans, meet_time)
            velocity = (speed * math.cos(h), speed * math.sin(h))
            pair.append(_through((meet[0], meet[1]), meet_time, velocity, birth, death))
        if all(fits(spec) for spec in pair):
            targets.extend(pair)
    singles = 0
    while singles < n_singles:
        birth, death = _random_life(rng, n_scans, None)
        middle_time = 0.5 * (birth + death)
        middle = rng.uniform(-0.7 * half_width, 0.7 * half_width, size=2)
        speed = rng.uniform(*speeds)
        h = rng.uniform(-math.pi, math.pi)
        velocity = (speed * math.cos(h), speed * math.sin(h))
        spec = _through((middle[0], middle[1]), middle_time, velocity, birth, death)
        if fits(spec):
            targets.append(spec)
            singles += 1
    return targets


# --------------------------------------------------------------------------- scenarios


def _crossing_targets() -> list[TargetSpec]:
    """Two pairs; each pair meets at one point at t = 30 (the pairs 28 units apart).

    Births at t = 0, 6, 3 and 12; target 4 dies at t = 45, the others live to the end.
    """
    return [
        _through((-10.0, 10.0), 30.0, (2.0, 0.6), 0.0, math.inf),
        _through((-10.0, 10.0), 30.0, (2.0, -0.6), 6.0, math.inf),
        _through((10.0, -10.0), 30.0, (-0.6, 2.0), 3.0, math.inf),
        _through((10.0, -10.0), 30.0, (0.6, 2.0), 12.0, 45.0),
    ]


def crossing(seed: int) -> Scenario:
    """4 CV targets in two simultaneously crossing pairs, 10 false alarms/scan, 60 scans."""
    motion = ConstantVelocity(ndim=2, noise_intensity=_CV_NOISE)
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 60)
    sensor = _position_sensor(motion, 100.0, 10.0)
    return _scenario("crossing", motion, [sensor], _crossing_targets(), plan, seed)


def dense(seed: int) -> Scenario:
    """10 CV targets (2 crossing pairs) in a 400 x 400 region, 50 false alarms/scan."""
    motion = ConstantVelocity(ndim=2, noise_intensity=_CV_NOISE)
    n_scans = 60
    layout = np.random.default_rng(_LAYOUT_SEED)
    targets = _random_layout(layout, 200.0, n_pairs=2, n_singles=6, n_scans=n_scans)
    plan = scan_plan_regular(["pos"], 0.0, 1.0, n_scans)
    sensor = _position_sensor(motion, 200.0, 50.0)
    return _scenario("dense", motion, [sensor], targets, plan, seed)


def dense50(seed: int) -> Scenario:
    """50 CV targets (10 crossing pairs), 5x the area of "dense", 250 false alarms/scan."""
    motion = ConstantVelocity(ndim=2, noise_intensity=_CV_NOISE)
    n_scans = 40
    half_width = 200.0 * math.sqrt(5.0)
    layout = np.random.default_rng(_LAYOUT_SEED + 50)
    targets = _random_layout(layout, half_width, n_pairs=10, n_singles=30, n_scans=n_scans)
    plan = scan_plan_regular(["pos"], 0.0, 1.0, n_scans)
    sensor = _position_sensor(motion, half_width, 250.0)
    return _scenario("dense50", motion, [sensor], targets, plan, seed)


def turning(seed: int) -> Scenario:
    """3 coordinated-turn targets turning at 0.03-0.05 rad/scan, 10 false alarms/scan."""
    motion = CoordinatedTurn(
        speed_noise_intensity=_CT_SPEED_NOISE, turn_rate_noise_intensity=_CT_TURN_NOISE
    )
    targets = [
        _turning((-70.0, -60.0), 2.0, 0.0, 0.05, 0.0, 59.0),
        _turning((60.0, -70.0), 2.5, math.pi / 2, 0.03, 5.0, 59.0),
        _turning((-40.0, 70.0), 2.0, 0.0, -0.04, 10.0, 50.0),
    ]
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 60)
    sensor = _position_sensor(motion, 100.0, 10.0)
    return _scenario("turning", motion, [sensor], targets, plan, seed)


def two_sensors(seed: int) -> Scenario:
    """The crossing targets seen by a position sensor and a range-bearing radar, interleaved."""
    motion = ConstantVelocity(ndim=2, noise_intensity=_CV_NOISE)
    position = _position_sensor(motion, 100.0, 10.0)
    # The radar sits 60 units below the region; the (range, bearing) box covers the
    # whole 200 x 200 region: ranges 60..279, bearings 0.54..2.60 rad.
    radar = Sensor(
        name="radar",
        measurement=RangeBearing(
            sensor_position=[0.0, -160.0],
            range_std=1.0,
            bearing_std=0.005,
            position_indices=(0, 1),
        ),
        detection_probability=0.9,
        false_alarms_per_scan=10.0,
        region=Region.from_bounds([[50.0, 290.0], [0.5, 2.65]]),
    )
    plan = scan_plan_regular(["pos", "radar"], 0.0, 1.0, 60, offsets=[0.0, 0.5])
    return _scenario("two_sensors", motion, [position, radar], _crossing_targets(), plan, seed)


# --------------------------------------------------------------------------- hard families
#
# Length unit: the position noise standard deviation (think 10 m); time unit: one scan.
# Geometries are fixed (deterministic or drawn from fixed layout seeds); the ``seed``
# argument drives process noise, detections and false alarms as in the scenarios above.


def _square_half_width(area: float) -> float:
    """Half the side of a square region of the given area."""
    return 0.5 * math.sqrt(area)


def _parallel_targets() -> list[TargetSpec]:
    """5 targets abreast, ``PARALLEL_SPACING`` apart across track, all moving +x at speed 1."""
    offsets = (np.arange(5) - 2.0) * PARALLEL_SPACING
    return [
        TargetSpec(
            initial_state=np.array([-20.0, float(y), 1.0, 0.0]),
            birth_time=0.0,
            death_time=math.inf,
        )
        for y in offsets
    ]


def parallel(seed: int) -> Scenario:
    """5 CV targets abreast 2.5 apart at speed 1, 20 false alarms/scan over 15,000, 40 scans.

    The formation flies nearly straight: the acceleration noise intensity is
    ``2e-5`` (instead of the ``0.002`` of the other Cartesian scenarios), so the
    across-track distance between two neighbours drifts by about 0.9 units (standard
    deviation) over the 40 scans and the formation keeps its order.
    """
    motion = ConstantVelocity(ndim=2, noise_intensity=_FORMATION_NOISE)
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 40)
    sensor = _position_sensor(motion, _square_half_width(15_000.0), 20.0)
    return _scenario("parallel", motion, [sensor], _parallel_targets(), plan, seed)


def dense_pd08(seed: int) -> Scenario:
    """10 CV targets (2 crossing pairs), Pd 0.8, 50 false alarms/scan over 100 x 100.

    Speeds uniform in [0.8, 1.2] per scan, births and deaths, 40 scans.
    """
    motion = ConstantVelocity(ndim=2, noise_intensity=_SLOW_CV_NOISE)
    n_scans = 40
    half_width = _square_half_width(10_000.0)
    layout = np.random.default_rng(_LAYOUT_SEED + 108)
    targets = _random_layout(
        layout, half_width, n_pairs=2, n_singles=6, n_scans=n_scans, speeds=(0.8, 1.2)
    )
    plan = scan_plan_regular(["pos"], 0.0, 1.0, n_scans)
    sensor = _position_sensor(motion, half_width, 50.0, detection_probability=0.8)
    return _scenario("dense_pd08", motion, [sensor], targets, plan, seed)


def _scale(targets_count: int, seed: int) -> Scenario:
    """``targets_count`` CV targets at the fixed density of the ``scale*`` family.

    One target per ``SCALE_AREA_PER_TARGET`` units^2 and ``SCALE_FALSE_ALARMS_PER_AREA``
    false alarms per that area per scan, Pd 0.9, speed 1, uniform headings, births in the
    first third and some deaths (:func:`_random_life`), 30 scans.
    """
    name = f"scale{targets_count}"
    motion = ConstantVelocity(ndim=2, noise_intensity=_SLOW_CV_NOISE)
    n_scans = 30
    area = targets_count * SCALE_AREA_PER_TARGET
    half_width = _square_half_width(area)
    layout = np.random.default_rng(_LAYOUT_SEED + 1000 + targets_count)
    targets = _random_layout(
        layout, half_width, n_pairs=0, n_singles=targets_count, n_scans=n_scans, speeds=(1.0, 1.0)
    )
    plan = scan_plan_regular(["pos"], 0.0, 1.0, n_scans)
    false_alarms = SCALE_FALSE_ALARMS_PER_AREA * targets_count
    sensor = _position_sensor(motion, half_width, false_alarms)
    return _scenario(name, motion, [sensor], targets, plan, seed)


def scale20(seed: int) -> Scenario:
    """20 CV targets over 20,000 units^2, 40 false alarms/scan, 30 scans (``scale`` family)."""
    return _scale(20, seed)


def scale50(seed: int) -> Scenario:
    """50 CV targets over 50,000 units^2, 100 false alarms/scan, 30 scans (``scale`` family)."""
    return _scale(50, seed)


def scale100(seed: int) -> Scenario:
    """100 CV targets over 100,000 units^2, 200 false alarms/scan, 30 scans (``scale`` family)."""
    return _scale(100, seed)


def burst(seed: int, extra_false_alarms: int = BURST_FALSE_ALARMS) -> Scenario:
    """10 CV targets, 20 false alarms/scan, and one scan with a burst of extra false alarms.

    The geometry: 2 crossing pairs and 6 independent targets at speed 1-2 in a 200 x 200
    region, Pd 0.9, 40 scans.  Scan ``BURST_SCAN`` (the middle one) gets
    ``extra_false_alarms`` more false alarms uniform over the region
    (:func:`add_false_alarms`, drawn from ``seed``); the configuration keeps 20 false
    alarms per scan, as an estimator configured for the normal clutter would.

    Parameters
    ----------
    seed : int
        Seed of the realisation.
    extra_false_alarms : int
        Size of the burst (default ``BURST_FALSE_ALARMS`` = 2000; 0 gives the scenario
        without the burst, every other draw unchanged).
    """
    motion = ConstantVelocity(ndim=2, noise_intensity=_SLOW_CV_NOISE)
    n_scans = 40
    half_width = 100.0
    layout = np.random.default_rng(_LAYOUT_SEED + 2000)
    targets = _random_layout(
        layout, half_width, n_pairs=2, n_singles=6, n_scans=n_scans, speeds=(1.0, 2.0)
    )
    plan = scan_plan_regular(["pos"], 0.0, 1.0, n_scans)
    sensor = _position_sensor(motion, half_width, 20.0)
    base = _scenario("burst", motion, [sensor], targets, plan, seed)
    return add_false_alarms(base, BURST_SCAN, extra_false_alarms, seed=seed)


# --------------------------------------------------------------------------- transformations


def _check_count(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _origin_of_rows(origins: Origins, rows: NDArray[np.int64]) -> NDArray[np.int64]:
    """Target id (or -1) of each detection row, looked up in ``origins``."""
    order = np.argsort(origins.rows, kind="stable")
    sorted_rows = origins.rows[order]
    where = np.searchsorted(sorted_rows, rows)
    found = where < sorted_rows.shape[0]
    found[found] = sorted_rows[where[found]] == rows[found]
    if not np.all(found):
        missing = rows[~found].tolist()
        raise InputError(f"scenario origins have no entry for detection rows {missing[:5]!r}")
    return origins.target_ids[order][where].astype(np.int64)


def add_false_alarms(scenario: Scenario, scan_index: int, count: int, *, seed: int) -> Scenario:
    """A copy of ``scenario`` with ``count`` extra false alarms in one scan.

    The extra false alarms are uniform over the region of the scan's sensor and shuffled
    into the scan with its detections; every scan's rows are renumbered as the
    detections file numbers them (:func:`~mapassoc.data.io.number_rows`) and the origins
    follow their detections (the new ones are ``-1``).  The truth and the configuration
    are unchanged.  ``count == 0`` returns the scenario as is.

    Parameters
    ----------
    scenario : Scenario
    scan_index : int
        Index of the scan in ``scenario.scans`` (0-based).
    count : int
        Number of false alarms to add, >= 0.
    seed : int
        Non-negative seed of the positions and the shuffle
        (``numpy.random.default_rng(seed)``).

    Returns
    -------
    Scenario

    Raises
    ------
    InputError
        ``scan_index`` out of range, a negative ``count`` or a bad ``seed``.
    """
    if not isinstance(scenario, Scenario):
        raise InputError(f"scenario must be a Scenario, got {scenario!r}")
    n_scans = len(scenario.scans)
    index = _check_count("scan_index", scan_index, 0)
    if index >= n_scans:
        raise InputError(
            f"scan_index must be < the number of scans ({n_scans}) of scenario "
            f"{scenario.name!r}, got {scan_index!r}"
        )
    extra = _check_count("count", count, 0)
    rng = np.random.default_rng(_check_count("seed", seed, 0))
    if extra == 0:
        return scenario
    target = scenario.scans[index]
    region = scenario.config.sensors[target.sensor].region
    clutter = region.sample(rng, extra).reshape(extra, -1)
    detections = np.concatenate([target.detections, clutter])
    origin = np.concatenate(
        [_origin_of_rows(scenario.origins, target.rows), -np.ones(extra, np.int64)]
    )
    order = rng.permutation(detections.shape[0])
    raw = list(scenario.scans)
    raw[index] = Scan(
        time=target.time,
        sensor=target.sensor,
        detections=detections[order],
        rows=np.arange(detections.shape[0], dtype=np.int64),
    )
    per_scan = [_origin_of_rows(scenario.origins, scan.rows) for scan in scenario.scans]
    per_scan[index] = origin[order]
    scans = number_rows(raw)
    rows = np.concatenate([scan.rows for scan in scans])
    ids = np.concatenate(per_scan)
    by_row = np.argsort(rows, kind="stable")
    return Scenario(
        name=scenario.name,
        config=scenario.config,
        scans=scans,
        truth=scenario.truth,
        origins=Origins(rows=rows[by_row], target_ids=ids[by_row]),
    )


def truncate_scenario(scenario: Scenario, n_scans: int) -> Scenario:
    """The first ``n_scans`` scans of a scenario, with their truth and origins.

    Truth records after the last kept scan time are dropped, and so are the origins of
    the dropped detections; rows keep their numbers (the kept scans are the start of the
    detections file).  ``n_scans`` at least the number of scans returns the scenario as is.

    Parameters
    ----------
    scenario : Scenario
    n_scans : int
        Scans to keep, >= 1.

    Raises
    ------
    InputError
        ``n_scans`` not an integer >= 1.
    """
    if not isinstance(scenario, Scenario):
        raise InputError(f"scenario must be a Scenario, got {scenario!r}")
    keep = _check_count("n_scans", n_scans, 1)
    if keep >= len(scenario.scans):
        return scenario
    scans = list(scenario.scans[:keep])
    last_time = scans[-1].time
    truth = scenario.truth
    alive = truth.times <= last_time
    kept_rows = np.concatenate([scan.rows for scan in scans])
    in_kept = np.isin(scenario.origins.rows, kept_rows)
    return Scenario(
        name=scenario.name,
        config=scenario.config,
        scans=scans,
        truth=TruthTable(
            target_ids=truth.target_ids[alive],
            times=truth.times[alive],
            states=truth.states[alive],
            state_names=truth.state_names,
        ),
        origins=Origins(
            rows=scenario.origins.rows[in_kept], target_ids=scenario.origins.target_ids[in_kept]
        ),
    )


# --------------------------------------------------------------------------- generic configuration


def top_initial_speed(scenario: Scenario) -> float:
    """Largest speed of any target at its first truth record.

    The first record is the target's initial state when it is born at a scan time (as in
    every built-in scenario).

    Raises
    ------
    InputError
        The scenario has no target.
    """
    truth = scenario.truth
    if truth.size == 0:
        raise InputError(f"scenario {scenario.name!r} has no target (empty truth)")
    order = np.lexsort((truth.times, truth.target_ids))
    ids = truth.target_ids[order]
    first = order[np.concatenate([[True], ids[1:] != ids[:-1]])]
    motion = scenario.config.motion
    return max(_speed(motion, truth.states[i]) for i in first)


def generic_config(
    scenario: Scenario,
    *,
    window_length: int | None = None,
    time_limit: float | None = None,
) -> Config:
    """The one configuration the benchmark uses for every family, not tuned per family.

    Keeps the scenario's motion model and sensors (what a user knows about the platform
    and the radar) and replaces what would otherwise be fitted to the simulated truth:

    * ``BirthModel(rate=0.05, initial_count=5.0, velocity_std=v)`` with ``v`` the top
      initial target speed (:func:`top_initial_speed`), every other field default;
    * ``EstimatorSettings(max_tracks=2 * m)`` with ``m`` the most detections in any scan
      of ``scenario`` (so a truncated scenario gets its own ``m``), every other setting
      default except ``window_length`` and ``time_limit`` when given.

    Parameters
    ----------
    scenario : Scenario
    window_length : int, optional
        Scans per window (default: the :class:`~mapassoc.data.settings.EstimatorSettings`
        default).
    time_limit : float, optional
        Seconds per solve (default: the settings default).

    Returns
    -------
    Config

    Raises
    ------
    InputError
        The scenario has no target or no scan, or a bad ``window_length`` or
        ``time_limit``.
    """
    if not isinstance(scenario, Scenario):
        raise InputError(f"scenario must be a Scenario, got {scenario!r}")
    if not scenario.scans:
        raise InputError(f"scenario {scenario.name!r} has no scan")
    most = max(scan.size for scan in scenario.scans)
    overrides: dict[str, object] = {}
    if window_length is not None:
        overrides["window_length"] = window_length
    if time_limit is not None:
        overrides["time_limit"] = time_limit
    return Config(
        motion=scenario.config.motion,
        sensors=dict(scenario.config.sensors),
        birth=BirthModel(
            rate=GENERIC_BIRTH_RATE,
            initial_count=GENERIC_INITIAL_COUNT,
            velocity_std=top_initial_speed(scenario),
        ),
        estimator=EstimatorSettings(max_tracks=2 * most, **overrides),  # type: ignore[arg-type]
    )


# --------------------------------------------------------------------------- registry

SCENARIOS: dict[str, Callable[[int], Scenario]] = {
    "crossing": crossing,
    "dense": dense,
    "dense50": dense50,
    "turning": turning,
    "two_sensors": two_sensors,
    "parallel": parallel,
    "dense_pd08": dense_pd08,
    "scale20": scale20,
    "scale50": scale50,
    "scale100": scale100,
    "burst": burst,
}

_DESCRIPTIONS: dict[str, str] = {
    "crossing": (
        "4 constant-velocity targets in two pairs crossing near the centre at t=30, staggered "
        "births, one death; Pd 0.9, 10 false alarms/scan, 60 scans (the default demo)"
    ),
    "dense": (
        "10 constant-velocity targets in a 400x400 region, 2 crossing pairs, births and "
        "deaths; Pd 0.9, 50 false alarms/scan, 60 scans"
    ),
    "dense50": (
        "50 constant-velocity targets at the density of 'dense' (5x the area), 10 crossing "
        "pairs; Pd 0.9, 250 false alarms/scan, 40 scans"
    ),
    "turning": (
        "3 coordinated-turn targets turning at 0.03-0.05 rad per scan, position sensor; "
        "Pd 0.9, 10 false alarms/scan, 60 scans"
    ),
    "two_sensors": (
        "the 4 crossing targets seen by a position sensor and a range-bearing radar below "
        "the region, scans interleaved by half an interval; Pd 0.9, 10 false alarms/scan each"
    ),
    "parallel": (
        "5 constant-velocity targets abreast, 2.5 apart, speed 1, nearly straight; Pd 0.9, "
        "20 false alarms/scan over 15,000 units^2, 40 scans"
    ),
    "dense_pd08": (
        "10 constant-velocity targets (2 crossing pairs) at speed ~1 in a 100x100 region, "
        "births and deaths; Pd 0.8, 50 false alarms/scan, 40 scans"
    ),
    "scale20": (
        "20 constant-velocity targets at speed 1, random headings, births and deaths, one "
        "per 1,000 units^2; Pd 0.9, 40 false alarms/scan (2 per 1,000 units^2), 30 scans"
    ),
    "scale50": (
        "50 targets at the density of 'scale20' (50,000 units^2); Pd 0.9, 100 false "
        "alarms/scan, 30 scans"
    ),
    "scale100": (
        "100 targets at the density of 'scale20' (100,000 units^2); Pd 0.9, 200 false "
        "alarms/scan, 30 scans"
    ),
    "burst": (
        "10 constant-velocity targets (2 crossing pairs) in a 200x200 region; Pd 0.9, 20 "
        "false alarms/scan and 2,000 extra in scan 20 of 40"
    ),
}


def scenario_names() -> list[str]:
    """Names of the built-in scenarios, the default (``"crossing"``) first."""
    return list(SCENARIOS)


def _check_name(name: str) -> str:
    if name not in SCENARIOS:
        raise InputError(
            f"unknown scenario {name!r}; expected one of {', '.join(scenario_names())}"
        )
    return name


def describe_scenario(name: str) -> str:
    """One-line description of a built-in scenario."""
    return _DESCRIPTIONS[_check_name(name)]


def build_scenario(name: str = DEFAULT_SCENARIO, seed: int = 0) -> Scenario:
    """Build the named scenario with the given random seed.

    Parameters
    ----------
    name : str
        One of :func:`scenario_names`.
    seed : int
        Non-negative seed of the noise realisation (the geometry is fixed).

    Raises
    ------
    InputError
        Unknown name or bad seed.
    """
    return SCENARIOS[_check_name(name)](seed)
