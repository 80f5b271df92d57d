"""Named built-in scenarios for demonstrations, tests and benchmarks.

Each scenario fixes a geometry (targets, sensors, scan times) and takes the seed of the
random realisation (process noise, detections, false alarms): ``build_scenario(name, seed)``.
The geometry does not depend on the seed; the layouts of ``"dense"`` and ``"dense50"`` are
drawn once from a fixed layout seed.

Every scenario's configuration matches its simulation: the same motion model and noise,
the simulated sensors, a :class:`~mapassoc.settings.BirthModel` derived from the targets
(:func:`birth_model_for`) and default :class:`~mapassoc.settings.EstimatorSettings` except
``max_tracks`` (:func:`max_tracks_for`).

Speeds are 1-3 length units per unit time with position noise of standard deviation 1 and
scans one time unit apart, so every target is trackable on its own; the difficulty comes
from crossings, false alarms and missed detections.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from mapassoc.config import Config
from mapassoc.errors import InputError
from mapassoc.measurement import LinearMeasurement, RangeBearing
from mapassoc.motion import ConstantVelocity, CoordinatedTurn, MotionModel
from mapassoc.sensor import Region, Sensor
from mapassoc.settings import BirthModel, EstimatorSettings
from mapassoc.simulate import Scenario, TargetSpec, scan_plan_regular, simulate

__all__ = [
    "SCENARIOS",
    "DEFAULT_SCENARIO",
    "build_scenario",
    "scenario_names",
    "describe_scenario",
    "birth_model_for",
    "max_tracks_for",
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
# Fixed seed of the random layouts of "dense" and "dense50" (geometry, not noise).
_LAYOUT_SEED = 20240601


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
    if isinstance(motion, CoordinatedTurn):
        return abs(float(state[2]))
    velocity = [state[i] for i in getattr(motion, "velocity_indices", ())]
    return float(np.hypot(*velocity)) if len(velocity) == 2 else float(np.linalg.norm(velocity))


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
    top_turn = (
        max(abs(float(t.initial_state[4])) for t in seen)
        if isinstance(motion, CoordinatedTurn)
        else 0.0
    )
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
    motion: MotionModel, half_width: float, false_alarms: float, *, name: str = "pos"
) -> Sensor:
    return Sensor(
        name=name,
        measurement=LinearMeasurement.position(motion, noise_std=1.0),
        detection_probability=0.9,
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
    rng: np.random.Generator, half_width: float, n_pairs: int, n_singles: int, n_scans: int
) -> list[TargetSpec]:
    """Crossing pairs plus independent targets, all inside 90% of the region over their life.

    A pair's two noise-free paths meet at the same point at the same time (a crossing in
    time, not only in space), with headings 30 to 150 degrees apart.  Speeds are uniform in
    [1, 3] per unit time, headings uniform.
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
            speed = rng.uniform(1.0, 3.0)
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
        speed = rng.uniform(1.0, 3.0)
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


# --------------------------------------------------------------------------- registry

SCENARIOS: dict[str, Callable[[int], Scenario]] = {
    "crossing": crossing,
    "dense": dense,
    "dense50": dense50,
    "turning": turning,
    "two_sensors": two_sensors,
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
