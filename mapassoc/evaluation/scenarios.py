"""Named built-in scenarios for demonstrations, tests and benchmarks.

Each scenario fixes a geometry (targets, sensors, scan times) and takes the seed of the
random realisation (process noise, detections, false alarms): ``build_scenario(name, seed)``.
The geometry does not depend on the seed; the random layouts (``"dense"``, ``"dense50"``,
``"dense_pd08"``, the ``"scale*"`` family and ``"burst"``) are drawn once from fixed layout
seeds.

The hard families stress one difficulty each: ``"parallel"`` (a close formation, targets
2.5 noise standard deviations apart), ``"dense_pd08"`` (missed detections in heavy
clutter), ``"scale20"`` / ``"scale50"`` / ``"scale100"`` (size at a fixed density) and
``"burst"`` (one scan flooded by 2,000 extra false alarms).  The realistic families combine
them as users' data does: ``"converging"`` (six targets closing to 1.5 apart, Pd 0.7),
``"meeting"`` (four targets through one point), ``"parallel_pd08"`` (the ``"parallel"``
lanes at Pd 0.8), ``"dense_radar"`` (10 targets, Pd 0.8, 50 false alarms over a 1 km
square at 10 m noise, 100 scans) and ``"staggered"`` (births and deaths all through,
crossings).  The manoeuvring families ``"aircraft"``, ``"ships"``, ``"crossing_turns"``
and ``"converging_turns"`` (:mod:`mapassoc.evaluation.manoeuvres`) fly flight plans of
straight legs, coordinated turns and speed changes, in metres and seconds, and draw their
traffic from the seed.  :func:`generic_config` gives the configuration the benchmark runs them with,
the same recipe for every family.

Every scenario's configuration matches its simulation: the same motion model and noise,
the simulated sensors, a :class:`~mapassoc.models.population.BirthModel` derived from the targets
(:func:`birth_model_for`) and default :class:`~mapassoc.data.settings.EstimatorSettings` except
``max_tracks`` (:func:`max_tracks_for`).  The one exception is ``"burst"``, whose
configuration keeps the normal false-alarm rate: the burst is what it should survive.

Any length: ``build_scenario(name, seed, scans=N)`` gives N scans.  Fewer than the native
length are the start of the native run; more are a lengthened run of the same models,
sensors and clutter whose targets are a stationary birth-death population with the
native character (section "long recordings" below), built in time linear in N.
:func:`scenario_scan_period` and :func:`scans_for_duration` turn a duration into N.

Speeds are 0.7-3 length units per unit time (about 1 in the hard families) with position
noise of standard deviation 1 (think 10 m) and scans one time unit apart, so every target
is trackable on its own; the difficulty comes from crossings, close formations, false
alarms and missed detections.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config
from mapassoc.data.io import Origins, TruthTable, number_rows
from mapassoc.data.scans import Scan
from mapassoc.data.settings import CountSettings, EstimatorSettings
from mapassoc.errors import InputError
from mapassoc.evaluation.manoeuvres import MANOEUVRE_FAMILIES
from mapassoc.evaluation.simulate import Scenario, TargetSpec, scan_plan_regular, simulate
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity, CoordinatedTurn, MotionModel
from mapassoc.models.population import BirthModel
from mapassoc.models.sensor import Region, Sensor
from mapassoc.validation import check_integer

__all__ = [
    "SCENARIOS",
    "DEFAULT_SCENARIO",
    "build_scenario",
    "scenario_names",
    "describe_scenario",
    "birth_model_for",
    "max_tracks_for",
    "generic_config",
    "length_unit",
    "top_initial_speed",
    "add_false_alarms",
    "truncate_scenario",
    "lengthenable_scenarios",
    "native_scan_count",
    "scenario_scan_period",
    "scans_for_duration",
    "PARALLEL_SPACING",
    "CONVERGING_SPACING",
    "CONVERGING_TIME",
    "MEETING_TIME",
    "SCALE_AREA_PER_TARGET",
    "SCALE_FALSE_ALARMS_PER_AREA",
    "BURST_SCAN",
    "BURST_FALSE_ALARMS",
    "GENERIC_BIRTH_RATE",
    "GENERIC_INITIAL_COUNT",
]

Plan = list[tuple[float, str]]

DEFAULT_SCENARIO = "crossing"
"""The scenario that ``mapassoc demo`` and ``mapassoc simulate`` use when none is named."""

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
# Acceleration noise intensity of "meeting", as low as the formation's so that every
# realisation has the designed encounter: a target drifts by sqrt(q t^3 / 3) ~ 0.42 units
# (std per axis) from its noise-free path over the 30 scans to the meeting.
_ENCOUNTER_NOISE = _FORMATION_NOISE
# The same for "converging", half as much: two targets' relative drift is 0.65 (std per
# axis) at the closest time t = 40 and 1.8 at the last scan, against designed distances
# of 1.5 and 7.4 between neighbours.
_CONVERGING_NOISE = 1e-5
#: Distance of each "converging" target from its neighbours on the ring at their closest
#: (noise std units): the six targets sit on a regular hexagon of this radius.
CONVERGING_SPACING = 1.5
#: Time at which the "converging" targets are closest (the middle of the 80 scans).
CONVERGING_TIME = 40.0
# Rate (rad per unit time) at which the "converging" group turns in its own frame: every
# pairwise distance is its closest value times sqrt(1 + (0.12 (t - 40))^2), so neighbours
# are within 2 of each other for 15 scans, within 3 for 29, and 7.4 apart at the ends.
_CONVERGING_TWIST = 0.12
#: Time at which the four "meeting" targets pass the same point (the middle of 60 scans).
MEETING_TIME = 30.0
# Acceleration noise intensity of "dense_radar" (0.01 m^2/s^3 at 10 m per unit): over its
# 100 scans a velocity component wanders by sqrt(q t) ~ 0.1 (1 m/s) and a position by
# sqrt(q t^3 / 3) ~ 5.8 (std), so the noise-free paths keep a 12.5-unit margin.
_RADAR_NOISE = 1e-4
# Time between two scans of one sensor in every built-in scenario.
_INTERVAL = 1.0
# Fixed seed of the layouts of lengthened scenarios (``build_scenario(..., scans=N)``).
_LONG_LAYOUT_SEED = 20250101
# Rejection sampling of a lengthened layout gives up after this many draws per target.
_MAX_DRAWS = 10_000

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


def _alive_counts(targets: Sequence[TargetSpec], times: FloatArray) -> NDArray[np.int64]:
    """Number of targets alive at each of ``times`` (inclusive spans), without a loop."""
    births = np.sort(np.array([t.birth_time for t in targets], dtype=float))
    deaths = np.sort(np.array([t.death_time for t in targets], dtype=float))
    born = np.searchsorted(births, times, side="right")
    dead = np.searchsorted(deaths, times, side="left")
    return (born - dead).astype(np.int64)


def max_tracks_for(targets: Sequence[TargetSpec], plan: Plan) -> int:
    """``max(8, ceil(2.5 * most targets alive at one scan time))``."""
    if not plan:
        raise InputError("plan must contain at least one scan")
    most = int(np.max(_alive_counts(targets, np.array([time for time, _ in plan]))))
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
        estimator=EstimatorSettings(count=CountSettings(max_tracks=max_tracks_for(targets, plan))),
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
    margin: float = 0.9,
) -> list[TargetSpec]:
    """Crossing pairs plus independent targets, all inside 90% of the region over their life.

    A pair's two noise-free paths meet at the same point at the same time (a crossing in
    time, not only in space), with headings 30 to 150 degrees apart.  Speeds are uniform in
    ``speeds`` (default [1, 3]) per unit time, headings uniform.  ``margin`` is the share
    of the half width the noise-free paths stay inside (default 0.9).
    """
    limit = margin * half_width
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


# --------------------------------------------------------------------------- geometries


@dataclass(frozen=True, eq=False)
class _Geometry:
    """What a scenario fixes besides the seed: models, sensors, targets, scan plan.

    ``kind``, ``half_width``, ``pair_share`` and ``long_seed`` describe how
    :func:`_long_targets` lengthens it: a stationary birth-death population of the
    same kind of targets (``"straight"``: constant-velocity singles and crossing pairs;
    ``"turning"``: coordinated-turn singles; ``"formation"``: successive formations
    abreast; ``"episodes"``: the native targets again and again, one native run after
    another, each turned and moved at random) inside 90% of the
    ``[-half_width, half_width]^2`` square.
    """

    motion: MotionModel
    sensors: tuple[Sensor, ...]
    targets: tuple[TargetSpec, ...]
    scans_per_sensor: int
    offsets: tuple[float, ...] | None
    kind: str
    half_width: float
    pair_share: float
    long_seed: int

    @property
    def sensor_names(self) -> list[str]:
        return [sensor.name for sensor in self.sensors]

    def plan(self, scans_per_sensor: int) -> Plan:
        offsets = None if self.offsets is None else list(self.offsets)
        return scan_plan_regular(self.sensor_names, 0.0, _INTERVAL, scans_per_sensor, offsets)

    @property
    def scan_period(self) -> float:
        """Time between consecutive scans of the recording (the sensors interleave evenly)."""
        return _INTERVAL / len(self.sensors)


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


def _crossing_geometry() -> _Geometry:
    motion = ConstantVelocity(ndim=2, noise_intensity=_CV_NOISE)
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, 100.0, 10.0),),
        targets=tuple(_crossing_targets()),
        scans_per_sensor=60,
        offsets=None,
        kind="straight",
        half_width=100.0,
        pair_share=1.0,
        long_seed=_LONG_LAYOUT_SEED,
    )


def _dense_geometry() -> _Geometry:
    motion = ConstantVelocity(ndim=2, noise_intensity=_CV_NOISE)
    n_scans = 60
    layout = np.random.default_rng(_LAYOUT_SEED)
    targets = _random_layout(layout, 200.0, n_pairs=2, n_singles=6, n_scans=n_scans)
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, 200.0, 50.0),),
        targets=tuple(targets),
        scans_per_sensor=n_scans,
        offsets=None,
        kind="straight",
        half_width=200.0,
        pair_share=0.4,
        long_seed=_LONG_LAYOUT_SEED + 1,
    )


def _dense50_geometry() -> _Geometry:
    motion = ConstantVelocity(ndim=2, noise_intensity=_CV_NOISE)
    n_scans = 40
    half_width = 200.0 * math.sqrt(5.0)
    layout = np.random.default_rng(_LAYOUT_SEED + 50)
    targets = _random_layout(layout, half_width, n_pairs=10, n_singles=30, n_scans=n_scans)
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, half_width, 250.0),),
        targets=tuple(targets),
        scans_per_sensor=n_scans,
        offsets=None,
        kind="straight",
        half_width=half_width,
        pair_share=0.4,
        long_seed=_LONG_LAYOUT_SEED + 2,
    )


def _turning_geometry() -> _Geometry:
    motion = CoordinatedTurn(
        speed_noise_intensity=_CT_SPEED_NOISE, turn_rate_noise_intensity=_CT_TURN_NOISE
    )
    targets = [
        _turning((-70.0, -60.0), 2.0, 0.0, 0.05, 0.0, 59.0),
        _turning((60.0, -70.0), 2.5, math.pi / 2, 0.03, 5.0, 59.0),
        _turning((-40.0, 70.0), 2.0, 0.0, -0.04, 10.0, 50.0),
    ]
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, 100.0, 10.0),),
        targets=tuple(targets),
        scans_per_sensor=60,
        offsets=None,
        kind="turning",
        half_width=100.0,
        pair_share=0.0,
        long_seed=_LONG_LAYOUT_SEED + 3,
    )


def _two_sensors_geometry() -> _Geometry:
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
    return _Geometry(
        motion=motion,
        sensors=(position, radar),
        targets=tuple(_crossing_targets()),
        scans_per_sensor=60,
        offsets=(0.0, 0.5),
        kind="straight",
        half_width=100.0,
        pair_share=1.0,
        # The same lengthened targets as "crossing": the two scenarios stay comparable.
        long_seed=_LONG_LAYOUT_SEED,
    )


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


def _parallel_geometry() -> _Geometry:
    motion = ConstantVelocity(ndim=2, noise_intensity=_FORMATION_NOISE)
    half_width = _square_half_width(15_000.0)
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, half_width, 20.0),),
        targets=tuple(_parallel_targets()),
        scans_per_sensor=40,
        offsets=None,
        kind="formation",
        half_width=half_width,
        pair_share=0.0,
        long_seed=_LONG_LAYOUT_SEED + 5,
    )


def _dense_pd08_geometry() -> _Geometry:
    motion = ConstantVelocity(ndim=2, noise_intensity=_SLOW_CV_NOISE)
    n_scans = 40
    half_width = _square_half_width(10_000.0)
    layout = np.random.default_rng(_LAYOUT_SEED + 108)
    targets = _random_layout(
        layout, half_width, n_pairs=2, n_singles=6, n_scans=n_scans, speeds=(0.8, 1.2)
    )
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, half_width, 50.0, detection_probability=0.8),),
        targets=tuple(targets),
        scans_per_sensor=n_scans,
        offsets=None,
        kind="straight",
        half_width=half_width,
        pair_share=0.4,
        long_seed=_LONG_LAYOUT_SEED + 6,
    )


def _scale_geometry(targets_count: int) -> _Geometry:
    motion = ConstantVelocity(ndim=2, noise_intensity=_SLOW_CV_NOISE)
    n_scans = 30
    area = targets_count * SCALE_AREA_PER_TARGET
    half_width = _square_half_width(area)
    layout = np.random.default_rng(_LAYOUT_SEED + 1000 + targets_count)
    targets = _random_layout(
        layout, half_width, n_pairs=0, n_singles=targets_count, n_scans=n_scans, speeds=(1.0, 1.0)
    )
    false_alarms = SCALE_FALSE_ALARMS_PER_AREA * targets_count
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, half_width, false_alarms),),
        targets=tuple(targets),
        scans_per_sensor=n_scans,
        offsets=None,
        kind="straight",
        half_width=half_width,
        pair_share=0.0,
        long_seed=_LONG_LAYOUT_SEED + 1000 + targets_count,
    )


def _burst_geometry() -> _Geometry:
    motion = ConstantVelocity(ndim=2, noise_intensity=_SLOW_CV_NOISE)
    n_scans = 40
    half_width = 100.0
    layout = np.random.default_rng(_LAYOUT_SEED + 2000)
    targets = _random_layout(
        layout, half_width, n_pairs=2, n_singles=6, n_scans=n_scans, speeds=(1.0, 2.0)
    )
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, half_width, 20.0),),
        targets=tuple(targets),
        scans_per_sensor=n_scans,
        offsets=None,
        kind="straight",
        half_width=half_width,
        pair_share=0.4,
        long_seed=_LONG_LAYOUT_SEED + 2000,
    )


# --------------------------------------------------------------------------- realistic families
#
# Each combines difficulties the way recorded data does (the brief behind them: as hard as
# real users' data).  Same units as above; "dense_radar" reads them as 10 m and 1 s.


def _converging_targets() -> list[TargetSpec]:
    """Six targets that converge, fly as a tight group and separate, all alive throughout.

    At ``CONVERGING_TIME`` (t = 40) their noise-free positions are the corners of a
    regular hexagon of radius ``CONVERGING_SPACING`` (1.5) around the origin, so each is
    1.5 from its two neighbours (2.6 and 3.0 from the others).  Their velocities are
    ``(1, 0)`` plus the group turning at ``_CONVERGING_TWIST`` (0.12 rad per unit time)
    about its centre, perpendicular to every pairwise offset: the noise-free paths are
    straight, never cross, and every pairwise distance is its value at t = 40 times
    ``sqrt(1 + (0.12 (t - 40))^2)``: neighbours within 2 of each other from t = 33 to 47,
    within 3 from t = 26 to 54, and 7.4 apart at the first and last scans.  Speeds 0.82 to
    1.18, headings within 10 degrees of +x.
    """
    targets = []
    for k in range(6):
        angle = math.pi / 6.0 + k * math.pi / 3.0
        ox, oy = CONVERGING_SPACING * math.cos(angle), CONVERGING_SPACING * math.sin(angle)
        velocity = (1.0 - _CONVERGING_TWIST * oy, _CONVERGING_TWIST * ox)
        targets.append(_through((ox, oy), CONVERGING_TIME, velocity, 0.0, math.inf))
    return targets


def _converging_geometry() -> _Geometry:
    """Six targets closely spaced for a while (Xia, Garcia-Fernandez and Svensson, IEEE
    TAES 2024, batch TPMBM by MCMC: Pd 0.7, 30 false alarms per scan over 400 x 400)."""
    motion = ConstantVelocity(ndim=2, noise_intensity=_CONVERGING_NOISE)
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, 200.0, 30.0, detection_probability=0.7),),
        targets=tuple(_converging_targets()),
        scans_per_sensor=80,
        offsets=None,
        # Lengthened as one converging group after another (turned and moved at random):
        # a stationary population of independent targets would lose the group.
        kind="episodes",
        half_width=200.0,
        pair_share=0.0,
        long_seed=_LONG_LAYOUT_SEED + 7,
    )


def _meeting_targets() -> list[TargetSpec]:
    """Four targets at speed 1 through the origin at ``MEETING_TIME`` (t = 30).

    Two come from the west with headings +15 and -15 degrees, two from the east with
    headings 165 and 195 degrees: each side's pair closes at 0.52 per unit time (within 3
    of each other from t = 25 to 35), the opposite ones pass head-on at about 2 per unit
    time.  All alive from t = 0 (30 units from the origin) to the end (29 units out).
    """
    headings = [math.radians(d) for d in (15.0, -15.0, 165.0, 195.0)]
    return [
        _through((0.0, 0.0), MEETING_TIME, (math.cos(h), math.sin(h)), 0.0, math.inf)
        for h in headings
    ]


def _meeting_geometry() -> _Geometry:
    motion = ConstantVelocity(ndim=2, noise_intensity=_ENCOUNTER_NOISE)
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, 50.0, 10.0),),
        targets=tuple(_meeting_targets()),
        scans_per_sensor=60,
        offsets=None,
        # Lengthened as one meeting after another (turned and moved at random), as for
        # "converging": independent crossing pairs would not meet four at a time.
        kind="episodes",
        half_width=50.0,
        pair_share=0.0,
        long_seed=_LONG_LAYOUT_SEED + 8,
    )


def _parallel_pd08_geometry() -> _Geometry:
    """The ``"parallel"`` formation and clutter with Pd 0.8 instead of 0.9."""
    base = _parallel_geometry()
    motion = base.motion
    half_width = base.half_width
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, half_width, 20.0, detection_probability=0.8),),
        targets=base.targets,
        scans_per_sensor=base.scans_per_sensor,
        offsets=None,
        # Lengthened as "parallel" (one formation after another), with the same targets.
        kind="formation",
        half_width=half_width,
        pair_share=0.0,
        long_seed=base.long_seed,
    )


def _dense_radar_geometry() -> _Geometry:
    """10 targets (3 crossing pairs) in a 100 x 100 region (1 km at 10 m), 100 scans.

    Speeds uniform in [0.7, 1] (7-10 m/s at one scan per second), so the birth model's
    velocity standard deviation, 1.5 times the top speed, is 1.47 (15 m/s).  The
    noise-free paths stay inside 75% of the half width: 100 scans of process noise move a
    target further than the 40 of "dense_pd08".
    """
    motion = ConstantVelocity(ndim=2, noise_intensity=_RADAR_NOISE)
    n_scans = 100
    half_width = 50.0
    layout = np.random.default_rng(_LAYOUT_SEED + 3000)
    targets = _random_layout(
        layout,
        half_width,
        n_pairs=3,
        n_singles=4,
        n_scans=n_scans,
        speeds=(0.7, 1.0),
        margin=0.75,
    )
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, half_width, 50.0, detection_probability=0.8),),
        targets=tuple(targets),
        scans_per_sensor=n_scans,
        offsets=None,
        # Lengthened like "dense": independent targets and crossing pairs, births and
        # deaths all through, which is what this family is.
        kind="straight",
        half_width=half_width,
        pair_share=0.6,
        long_seed=_LONG_LAYOUT_SEED + 3000,
    )


def _staggered_targets() -> list[TargetSpec]:
    """Eight targets born and dying all through 80 scans; three crossing pairs.

    Births at t = 0, 0, 6, 22, 30, 35, 48, 52; deaths after t = 40, 50, 62, 68 and 75, three
    alive to the end; 2 to 6 alive at a time.  Pairs (1, 2), (4, 5) and (6, 7) meet at one
    point at t = 20, 45 and 65 (headings 37, 90 and 91 degrees apart); 3 and 8 are alone.
    Speeds 1.3 to 1.6, every noise-free path inside +-70.
    """
    inf = math.inf
    return [
        _through((-30.0, 20.0), 20.0, (1.5, 0.5), 0.0, 40.0),
        _through((-30.0, 20.0), 20.0, (1.2, -0.9), 6.0, 62.0),
        _through((40.0, 50.0), 25.0, (-1.0, -1.2), 0.0, 50.0),
        _through((25.0, -30.0), 45.0, (0.0, 1.6), 22.0, inf),
        _through((25.0, -30.0), 45.0, (-1.4, 0.6), 30.0, 68.0),
        _through((-20.0, -50.0), 65.0, (1.3, 0.4), 48.0, inf),
        _through((-20.0, -50.0), 65.0, (-0.8, 1.0), 52.0, inf),
        _through((-50.0, 40.0), 55.0, (0.9, -1.1), 35.0, 75.0),
    ]


def _staggered_geometry() -> _Geometry:
    motion = ConstantVelocity(ndim=2, noise_intensity=_SLOW_CV_NOISE)
    return _Geometry(
        motion=motion,
        sensors=(_position_sensor(motion, 100.0, 10.0),),
        targets=tuple(_staggered_targets()),
        scans_per_sensor=80,
        offsets=None,
        # Lengthened like "crossing": a stationary birth-death population with the native
        # share of crossing pairs, which keeps births and deaths all through the run.
        kind="straight",
        half_width=100.0,
        pair_share=0.75,
        long_seed=_LONG_LAYOUT_SEED + 4000,
    )


def _native(name: str, geometry: _Geometry, seed: int) -> Scenario:
    plan = geometry.plan(geometry.scans_per_sensor)
    return _scenario(name, geometry.motion, geometry.sensors, geometry.targets, plan, seed)


# --------------------------------------------------------------------------- scenarios


def crossing(seed: int) -> Scenario:
    """4 CV targets in two simultaneously crossing pairs, 10 false alarms/scan, 60 scans."""
    return _native("crossing", _crossing_geometry(), seed)


def dense(seed: int) -> Scenario:
    """10 CV targets (2 crossing pairs) in a 400 x 400 region, 50 false alarms/scan."""
    return _native("dense", _dense_geometry(), seed)


def dense50(seed: int) -> Scenario:
    """50 CV targets (10 crossing pairs), 5x the area of "dense", 250 false alarms/scan."""
    return _native("dense50", _dense50_geometry(), seed)


def turning(seed: int) -> Scenario:
    """3 coordinated-turn targets turning at 0.03-0.05 rad/scan, 10 false alarms/scan."""
    return _native("turning", _turning_geometry(), seed)


def two_sensors(seed: int) -> Scenario:
    """The crossing targets seen by a position sensor and a range-bearing radar, interleaved."""
    return _native("two_sensors", _two_sensors_geometry(), seed)


def parallel(seed: int) -> Scenario:
    """5 CV targets abreast 2.5 apart at speed 1, 20 false alarms/scan over 15,000, 40 scans.

    The formation flies nearly straight: the acceleration noise intensity is
    ``2e-5`` (instead of the ``0.002`` of the other Cartesian scenarios), so the
    across-track distance between two neighbours drifts by about 0.9 units (standard
    deviation) over the 40 scans and the formation keeps its order.
    """
    return _native("parallel", _parallel_geometry(), seed)


def dense_pd08(seed: int) -> Scenario:
    """10 CV targets (2 crossing pairs), Pd 0.8, 50 false alarms/scan over 100 x 100.

    Speeds uniform in [0.8, 1.2] per scan, births and deaths, 40 scans.
    """
    return _native("dense_pd08", _dense_pd08_geometry(), seed)


def _scale(targets_count: int, seed: int) -> Scenario:
    """``targets_count`` CV targets at the fixed density of the ``scale*`` family.

    One target per ``SCALE_AREA_PER_TARGET`` units^2 and ``SCALE_FALSE_ALARMS_PER_AREA``
    false alarms per that area per scan, Pd 0.9, speed 1, uniform headings, births in the
    first third and some deaths (:func:`_random_life`), 30 scans.
    """
    return _native(f"scale{targets_count}", _scale_geometry(targets_count), seed)


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
    base = _native("burst", _burst_geometry(), seed)
    return add_false_alarms(base, BURST_SCAN, extra_false_alarms, seed=seed)


def converging(seed: int) -> Scenario:
    """6 CV targets converging to 1.5 apart at t = 40 and separating; Pd 0.7, 80 scans.

    30 false alarms per scan over 400 x 400 (the closely spaced case of Xia,
    Garcia-Fernandez and Svensson, IEEE TAES 2024); the geometry is
    :func:`_converging_targets`, with acceleration noise ``1e-5`` (half that of
    ``"parallel"``) so that the group forms and separates in every realisation.
    """
    return _native("converging", _converging_geometry(), seed)


def meeting(seed: int) -> Scenario:
    """4 CV targets at speed 1 through one point at t = 30; Pd 0.9, 60 scans.

    10 false alarms per scan over 100 x 100; two pairs 30 degrees apart from opposite
    sides (:func:`_meeting_targets`), acceleration noise ``2e-5``.
    """
    return _native("meeting", _meeting_geometry(), seed)


def parallel_pd08(seed: int) -> Scenario:
    """The ``"parallel"`` formation (5 abreast 2.5 apart, 20 false alarms/scan) at Pd 0.8."""
    return _native("parallel_pd08", _parallel_pd08_geometry(), seed)


def dense_radar(seed: int) -> Scenario:
    """10 CV targets (3 crossing pairs), Pd 0.8, 50 false alarms/scan, 100 scans.

    Read as a radar: 1 km x 1 km region (100 x 100 units of the 10 m position noise),
    one scan per second, speeds 7-10 m/s, birth velocity standard deviation 14.7 m/s,
    3 targets at the start, 7 born in the first third, 5 dying before the end
    (:func:`_dense_radar_geometry`).
    """
    return _native("dense_radar", _dense_radar_geometry(), seed)


def staggered(seed: int) -> Scenario:
    """8 CV targets born and dying all through 80 scans, 3 crossing pairs; Pd 0.9.

    10 false alarms per scan over 200 x 200 (:func:`_staggered_targets`).
    """
    return _native("staggered", _staggered_geometry(), seed)


# --------------------------------------------------------------------------- long recordings
#
# A lengthened scenario (``build_scenario(name, seed, scans=N)`` with N above the native
# length) is not the native geometry run for longer: the native targets would leave the
# region.  It is a stationary birth-death population with the native character:
#
# * the same motion model, sensors, clutter and scan plan (period and interleaving);
# * about as many targets alive at a time as the native run has on average
#   (``_mean_alive``), each living a uniform whole number of scans between half and all of
#   the native run (the ``_random_life`` convention), so process noise moves them no
#   further than in the native run;
# * births at rate ``steady / mean life`` per unit time, as a renewal process whose gaps
#   are uniform between half and one and a half of the mean gap (more regular than a
#   Poisson process: 10,000 scans of "crossing" keep 1 to 7 targets alive, 3.4 on
#   average like the native run, where Poisson births spread them over 0 to 10),
#   started one longest life before the first scan so that the run starts in the steady
#   state (the targets born before 0 and alive at 0 are the initial population);
# * the same kind of targets: straight constant-velocity targets with the native speeds,
#   the native share of them born in crossing pairs (both paths through one point at one
#   time); coordinated-turn targets with the native speeds and turn rates; or, for the
#   formation, one formation of five abreast after another, each for the native length;
#   or, for the encounters ("converging", "meeting"), the native targets again, one native
#   run after another, each turned about the origin and moved at random;
# * every noise-free path inside 90% of the region (drawn again until it is).
#
# The layout is drawn from a fixed seed per scenario, in time order, so the targets of a
# shorter long run are the targets of a longer one that are born before its end.


def _mean_alive(targets: Sequence[TargetSpec], plan: Plan) -> float:
    """Mean over the plan's scans of the number of targets alive."""
    times = np.array([time for time, _ in plan])
    return float(np.mean(_alive_counts(targets, times)))


def _straight_fits(spec: TargetSpec, limit: float) -> bool:
    start = spec.initial_state[:2]
    end = start + spec.initial_state[2:] * (spec.death_time - spec.birth_time)
    return _inside(start, limit) and _inside(end, limit)


def _turning_fits(motion: MotionModel, spec: TargetSpec, limit: float) -> bool:
    if not _inside(spec.initial_state[:2], limit):
        return False
    span = spec.death_time - spec.birth_time
    steps = np.linspace(0.0, span, 9)[1:]
    ends = [motion.transition(spec.initial_state, float(dt))[:2] for dt in steps if dt > 0]
    return all(_inside(end, limit) for end in ends)


class _Lives:
    """Uniform whole-scan lives between ``low`` and ``high`` time units."""

    def __init__(self, native_scans: int) -> None:
        self.low = native_scans // 2
        self.high = native_scans - 1

    @property
    def mean(self) -> float:
        return 0.5 * (self.low + self.high)

    def draw(self, rng: np.random.Generator) -> int:
        return int(rng.integers(self.low, self.high + 1))


@dataclass(frozen=True)
class _Ranges:
    """The native targets' initial speeds and absolute turn rates: (lowest, highest)."""

    speeds: tuple[float, float]
    turn_rates: tuple[float, float]

    @classmethod
    def of(cls, geometry: _Geometry) -> _Ranges:
        motion = geometry.motion
        speeds = [motion.speed(t.initial_state) for t in geometry.targets]
        rates = [abs(motion.turn_rate(t.initial_state)) for t in geometry.targets]
        return cls(speeds=(min(speeds), max(speeds)), turn_rates=(min(rates), max(rates)))


def _draw_single(
    rng: np.random.Generator, geometry: _Geometry, ranges: _Ranges, birth: float, lives: _Lives
) -> TargetSpec:
    half_width = geometry.half_width
    for _ in range(_MAX_DRAWS):
        life = lives.draw(rng)
        speed = rng.uniform(*ranges.speeds)
        heading = rng.uniform(-math.pi, math.pi)
        if geometry.kind == "turning":
            rate = rng.uniform(*ranges.turn_rates) * rng.choice([-1.0, 1.0])
            start = rng.uniform(-0.7 * half_width, 0.7 * half_width, size=2)
            spec = _turning((start[0], start[1]), speed, heading, rate, birth, birth + life)
            if _turning_fits(geometry.motion, spec, 0.9 * half_width):
                return spec
            continue
        middle = rng.uniform(-0.7 * half_width, 0.7 * half_width, size=2)
        velocity = (speed * math.cos(heading), speed * math.sin(heading))
        spec = _through((middle[0], middle[1]), birth + 0.5 * life, velocity, birth, birth + life)
        if _straight_fits(spec, 0.9 * half_width):
            return spec
    raise InputError(f"cannot place a target inside the region after {_MAX_DRAWS} draws")


def _draw_pair(
    rng: np.random.Generator, geometry: _Geometry, ranges: _Ranges, birth: float, lives: _Lives
) -> list[TargetSpec]:
    """Two straight targets whose noise-free paths meet at one point at one time."""
    half_width = geometry.half_width
    for _ in range(_MAX_DRAWS):
        lifespans = [lives.draw(rng) for _ in range(2)]
        delays = [0, int(rng.integers(0, lives.low // 3 + 1))]
        starts = [birth + d for d in delays]
        ends = [s + life for s, life in zip(starts, lifespans, strict=True)]
        earliest, latest = max(starts) + 5, min(ends) - 5
        if latest < earliest:
            continue
        meet_time = float(rng.integers(int(earliest), int(latest) + 1))
        meet = rng.uniform(-0.6 * half_width, 0.6 * half_width, size=2)
        heading = rng.uniform(-math.pi, math.pi)
        turn = rng.choice([-1.0, 1.0]) * rng.uniform(math.pi / 6, 5 * math.pi / 6)
        pair = []
        for h, start, end in zip((heading, heading + turn), starts, ends, strict=True):
            speed = rng.uniform(*ranges.speeds)
            velocity = (speed * math.cos(h), speed * math.sin(h))
            pair.append(_through((meet[0], meet[1]), meet_time, velocity, start, end))
        if all(_straight_fits(spec, 0.9 * half_width) for spec in pair):
            return pair
    raise InputError(f"cannot place a crossing pair inside the region after {_MAX_DRAWS} draws")


def _draw_formation(
    rng: np.random.Generator, geometry: _Geometry, birth: float, life: int
) -> list[TargetSpec]:
    """The native formation (offsets across track, speed) on a random straight path."""
    natives = geometry.targets
    speed = geometry.motion.speed(natives[0].initial_state)
    centre = natives[len(natives) // 2].initial_state[1]
    across = np.array([t.initial_state[1] for t in natives]) - centre
    half_width = geometry.half_width
    for _ in range(_MAX_DRAWS):
        heading = rng.uniform(-math.pi, math.pi)
        middle = rng.uniform(-0.3 * half_width, 0.3 * half_width, size=2)
        direction = np.array([math.cos(heading), math.sin(heading)])
        normal = np.array([-direction[1], direction[0]])
        velocity = (speed * direction[0], speed * direction[1])
        members = []
        for offset in across:
            point = middle + offset * normal
            members.append(
                _through((point[0], point[1]), birth + 0.5 * life, velocity, birth, birth + life)
            )
        if all(_straight_fits(spec, 0.9 * half_width) for spec in members):
            return members
    raise InputError(f"cannot place a formation inside the region after {_MAX_DRAWS} draws")


def _draw_episode(rng: np.random.Generator, geometry: _Geometry, start: float) -> list[TargetSpec]:
    """The native targets turned about the origin and moved, their times shifted by ``start``.

    For 2-D constant-velocity targets ``(x, y, vx, vy)``; a native target alive to the end
    dies at the native last scan (``scans_per_sensor - 1`` after ``start``).
    """
    last = float(geometry.scans_per_sensor - 1)
    half_width = geometry.half_width
    for _ in range(_MAX_DRAWS):
        angle = rng.uniform(-math.pi, math.pi)
        rotation = np.array(
            [[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]]
        )
        shift = rng.uniform(-0.3 * half_width, 0.3 * half_width, size=2)
        members = []
        for spec in geometry.targets:
            state = spec.initial_state
            members.append(
                TargetSpec(
                    initial_state=np.concatenate(
                        [rotation @ state[:2] + shift, rotation @ state[2:4]]
                    ),
                    birth_time=start + spec.birth_time,
                    death_time=start + min(spec.death_time, last),
                )
            )
        if all(_straight_fits(spec, 0.9 * half_width) for spec in members):
            return members
    raise InputError(f"cannot place an episode inside the region after {_MAX_DRAWS} draws")


def _at_time_zero(motion: MotionModel, spec: TargetSpec) -> TargetSpec | None:
    """A burn-in target seen from time 0: moved there noise-free, or None if dead by then."""
    if spec.birth_time >= 0.0:
        return spec
    if spec.death_time < 0.0:
        return None
    state = motion.transition(spec.initial_state, -spec.birth_time)
    return TargetSpec(initial_state=state, birth_time=0.0, death_time=spec.death_time)


def _long_targets(geometry: _Geometry, last_time: float) -> list[TargetSpec]:
    """The stationary birth-death population of a lengthened scenario (see above)."""
    rng = np.random.default_rng(geometry.long_seed)
    lives = _Lives(geometry.scans_per_sensor)
    drawn: list[TargetSpec] = []
    if geometry.kind == "formation":
        life = geometry.scans_per_sensor - 1
        birth = 0.0
        while birth <= last_time:
            drawn.extend(_draw_formation(rng, geometry, birth, life))
            birth += life + _INTERVAL
        return drawn
    if geometry.kind == "episodes":
        start = 0.0
        while start <= last_time:
            drawn.extend(_draw_episode(rng, geometry, start))
            start += float(geometry.scans_per_sensor) * _INTERVAL
        return [spec for spec in drawn if spec.birth_time <= last_time]
    native_plan = geometry.plan(geometry.scans_per_sensor)
    steady = _mean_alive(geometry.targets, native_plan)
    share = geometry.pair_share
    pair_probability = share / (2.0 - share)  # so that `share` of the targets are in pairs
    event_rate = steady / lives.mean / (1.0 + pair_probability)  # birth events per unit time
    ranges = _Ranges.of(geometry)
    gap = 1.0 / event_rate
    clock = -float(lives.high) + rng.uniform(0.0, gap)
    while clock <= last_time:
        birth = float(math.floor(clock))  # births at whole times, as in the native runs
        if rng.random() < pair_probability:
            drawn.extend(_draw_pair(rng, geometry, ranges, birth, lives))
        else:
            drawn.append(_draw_single(rng, geometry, ranges, birth, lives))
        clock += rng.uniform(0.5 * gap, 1.5 * gap)
    kept = [_at_time_zero(geometry.motion, spec) for spec in drawn]
    return [spec for spec in kept if spec is not None and spec.birth_time <= last_time]


def _lengthened(name: str, geometry: _Geometry, scans: int, seed: int) -> Scenario:
    per_sensor = -(-scans // len(geometry.sensors))
    plan = geometry.plan(per_sensor)[:scans]
    targets = _long_targets(geometry, plan[-1][0])
    return _scenario(name, geometry.motion, geometry.sensors, targets, plan, seed)


def _lengthened_burst(name: str, geometry: _Geometry, scans: int, seed: int) -> Scenario:
    """Long "burst": a burst of ``BURST_FALSE_ALARMS`` in scan 20 of every 40."""
    base = _lengthened(name, geometry, scans, seed)
    period = geometry.scans_per_sensor
    counts = {index: BURST_FALSE_ALARMS for index in range(BURST_SCAN, scans, period)}
    return _add_false_alarms_at(base, counts, seed=seed)


# --------------------------------------------------------------------------- transformations


def _origins_by_scan(origins: Origins, scans: Sequence[Scan]) -> list[NDArray[np.int64]]:
    """Target id (or -1) of each detection row of each scan, looked up in ``origins``.

    One sort of the origins and one lookup of all rows: linear-logarithmic in the rows.
    """
    order = np.argsort(origins.rows, kind="stable")
    sorted_rows = origins.rows[order]
    sizes = [scan.size for scan in scans]
    rows = (
        np.concatenate([scan.rows for scan in scans]) if scans else np.empty(0, dtype=np.int64)
    )
    where = np.searchsorted(sorted_rows, rows)
    found = where < sorted_rows.shape[0]
    found[found] = sorted_rows[where[found]] == rows[found]
    if not np.all(found):
        missing = rows[~found].tolist()
        raise InputError(f"scenario origins have no entry for detection rows {missing[:5]!r}")
    ids = origins.target_ids[order][where].astype(np.int64)
    return list(np.split(ids, np.cumsum(sizes)[:-1])) if scans else []


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
    index = check_integer("scan_index", scan_index, minimum=0)
    if index >= n_scans:
        raise InputError(
            f"scan_index must be < the number of scans ({n_scans}) of scenario "
            f"{scenario.name!r}, got {scan_index!r}"
        )
    extra = check_integer("count", count, minimum=0)
    seed = check_integer("seed", seed, minimum=0)
    return _add_false_alarms_at(scenario, {index: extra}, seed=seed)


def _add_false_alarms_at(
    scenario: Scenario, counts: Mapping[int, int], *, seed: int
) -> Scenario:
    """:func:`add_false_alarms` for several scans at once (``counts``: scan index -> count).

    The scans are visited in index order with one generator, so one entry gives exactly
    :func:`add_false_alarms`; one pass over the scans whatever the number of entries.
    """
    rng = np.random.default_rng(seed)
    todo = {index: extra for index, extra in sorted(counts.items()) if extra > 0}
    if not todo:
        return scenario
    raw = list(scenario.scans)
    per_scan = _origins_by_scan(scenario.origins, scenario.scans)
    for index, extra in todo.items():
        target = scenario.scans[index]
        region = scenario.config.sensors[target.sensor].region
        clutter = region.sample(rng, extra).reshape(extra, -1)
        detections = np.concatenate([target.detections, clutter])
        origin = np.concatenate([per_scan[index], -np.ones(extra, np.int64)])
        order = rng.permutation(detections.shape[0])
        raw[index] = Scan(
            time=target.time,
            sensor=target.sensor,
            detections=detections[order],
            rows=np.arange(detections.shape[0], dtype=np.int64),
        )
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
    keep = check_integer("n_scans", n_scans, minimum=1)
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


def length_unit(config: Config) -> float:
    """The largest position-noise standard deviation of the configuration's linear
    sensors (1 if none): the unit the benchmarks' GOSPA cut-offs are given in.

    The native families measure lengths in that unit (a noise std of 1), the manoeuvring
    ones in metres (30-60 m), so a cut-off of ``10`` means ten noise standard deviations
    in both.
    """
    stds = [
        float(np.sqrt(np.max(np.diag(sensor.measurement.noise_covariance))))
        for sensor in config.sensors.values()
        if isinstance(sensor.measurement, LinearMeasurement)
    ]
    return max(stds) if stds else 1.0


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
    * ``count.max_tracks = 2 * m`` with ``m`` the most detections in any scan
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
    estimator = EstimatorSettings(count=CountSettings(max_tracks=2 * most))
    if window_length is not None:
        estimator = estimator.with_window_length(window_length)
    if time_limit is not None:
        estimator = estimator.with_time_limit(time_limit)
    return Config(
        motion=scenario.config.motion,
        sensors=dict(scenario.config.sensors),
        birth=BirthModel(
            rate=GENERIC_BIRTH_RATE,
            initial_count=GENERIC_INITIAL_COUNT,
            velocity_std=top_initial_speed(scenario),
        ),
        estimator=estimator,
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
    "converging": converging,
    "meeting": meeting,
    "parallel_pd08": parallel_pd08,
    "dense_radar": dense_radar,
    "staggered": staggered,
    # Manoeuvring traffic in metres and seconds (mapassoc.evaluation.manoeuvres).
    **{name: family.build for name, family in MANOEUVRE_FAMILIES.items()},
}
"""The built-in scenarios by name: ``SCENARIOS[name](seed)`` builds one."""

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
    "converging": (
        "6 constant-velocity targets converging to 1.5 apart (a hexagon) at t=40 and "
        "separating; Pd 0.7, 30 false alarms/scan over 400x400, 80 scans"
    ),
    "meeting": (
        "4 constant-velocity targets at speed 1 through one point at t=30, two from each "
        "side 30 degrees apart; Pd 0.9, 10 false alarms/scan over 100x100, 60 scans"
    ),
    "parallel_pd08": (
        "the 'parallel' formation (5 abreast, 2.5 apart, 20 false alarms/scan over 15,000 "
        "units^2, 40 scans) at Pd 0.8"
    ),
    "dense_radar": (
        "10 constant-velocity targets (3 crossing pairs) at speed 0.7-1 in a 100x100 region "
        "(1 km at 10 m), births and deaths; Pd 0.8, 50 false alarms/scan, 100 scans"
    ),
    "staggered": (
        "8 constant-velocity targets born and dying all through the run, 3 crossing pairs; "
        "Pd 0.9, 10 false alarms/scan over 200x200, 80 scans"
    ),
    **{name: family.description for name, family in MANOEUVRE_FAMILIES.items()},
}


def scenario_names() -> list[str]:
    """Names of the built-in scenarios, the default (``"crossing"``) first."""
    return list(SCENARIOS)


def _check_name(name: str) -> str:
    if not isinstance(name, str) or name not in SCENARIOS:
        raise InputError(
            f"unknown scenario name {name!r}; expected one of {', '.join(scenario_names())}"
        )
    return name


def describe_scenario(name: str) -> str:
    """One-line description of a built-in scenario."""
    return _DESCRIPTIONS[_check_name(name)]


_GEOMETRIES: dict[str, Callable[[], _Geometry]] = {
    "crossing": _crossing_geometry,
    "dense": _dense_geometry,
    "dense50": _dense50_geometry,
    "turning": _turning_geometry,
    "two_sensors": _two_sensors_geometry,
    "parallel": _parallel_geometry,
    "dense_pd08": _dense_pd08_geometry,
    "scale20": lambda: _scale_geometry(20),
    "scale50": lambda: _scale_geometry(50),
    "scale100": lambda: _scale_geometry(100),
    "burst": _burst_geometry,
    "converging": _converging_geometry,
    "meeting": _meeting_geometry,
    "parallel_pd08": _parallel_pd08_geometry,
    "dense_radar": _dense_radar_geometry,
    "staggered": _staggered_geometry,
}
"""The fixed geometry of each built-in scenario (what a lengthened run keeps)."""

_LENGTHEN: dict[str, Callable[[str, _Geometry, int, int], Scenario]] = {
    name: _lengthened for name in _GEOMETRIES
}
_LENGTHEN["burst"] = _lengthened_burst


def lengthenable_scenarios() -> list[str]:
    """Names of the scenarios that ``build_scenario(..., scans=N)`` can make longer."""
    return [
        name
        for name in SCENARIOS
        if name in MANOEUVRE_FAMILIES or (name in _LENGTHEN and name in _GEOMETRIES)
    ]


def _geometry(name: str, purpose: str) -> _Geometry:
    if name not in _GEOMETRIES:
        raise InputError(
            f"scenario {name!r} has no fixed geometry, so {purpose} is not known; scenarios "
            f"with one: {', '.join(lengthenable_scenarios())}"
        )
    return _GEOMETRIES[name]()


def native_scan_count(name: str) -> int:
    """Number of scans of ``build_scenario(name, seed)`` (every sensor's scans together).

    Raises
    ------
    InputError
        Unknown name.
    """
    _check_name(name)
    if name in MANOEUVRE_FAMILIES:
        return MANOEUVRE_FAMILIES[name].native_scans
    if name in _GEOMETRIES:
        geometry = _GEOMETRIES[name]()
        return geometry.scans_per_sensor * len(geometry.sensors)
    return len(SCENARIOS[name](0).scans)


def scenario_scan_period(name: str) -> float:
    """Time between consecutive scans of the named scenario, in its time unit.

    Every built-in scenario scans at a fixed period: one time unit, or half a unit for
    ``"two_sensors"``, whose two sensors each scan once per unit, interleaved.  The time
    unit is what the files call time; the command line treats it as a second.

    Raises
    ------
    InputError
        Unknown name, or a scenario without a fixed geometry.
    """
    if _check_name(name) in MANOEUVRE_FAMILIES:
        return MANOEUVRE_FAMILIES[name].scan_period
    return _geometry(name, "its scan period").scan_period


def scans_for_duration(name: str, duration: float) -> int:
    """The number of scans that makes the named scenario last ``duration`` time units.

    A recording of ``N`` scans at period ``P`` (:func:`scenario_scan_period`) lasts
    ``N * P`` (each scan stands for one period), so this is ``ceil(duration / P)``, at
    least 1; pass it to ``build_scenario(name, seed, scans=...)``.

    Parameters
    ----------
    name : str
    duration : float
        Length of the recording, > 0 and finite (time units; seconds on the command line).

    Raises
    ------
    InputError
        Unknown name, or ``duration`` not a positive finite number.
    """
    period = scenario_scan_period(name)
    if (
        isinstance(duration, bool)
        or not isinstance(duration, (int, float, np.integer, np.floating))
        or not math.isfinite(duration)
        or duration <= 0
    ):
        raise InputError(f"duration must be a positive finite number, got {duration!r}")
    # The tolerance keeps 60.000000000001 / 1.0 from turning into 61 scans.
    return max(1, math.ceil(float(duration) / period - 1e-9))


def build_scenario(
    name: str = DEFAULT_SCENARIO, seed: int = 0, *, scans: int | None = None
) -> Scenario:
    """Build the named scenario with the given random seed, optionally of a given length.

    Without ``scans`` (or with ``scans`` equal to :func:`native_scan_count`) the result is
    the scenario's fixed geometry, bit for bit the same for a given seed.  Fewer scans
    give its first ``scans`` scans (:func:`truncate_scenario`).  More scans give a
    lengthened run with the same models, sensors, clutter and scan period, in which a
    stationary birth-death population with the native character replaces the native
    targets (which would leave the region): about the native average number of targets
    alive at any time, each alive for half to all of the native run, the native speeds
    (and turn rates), the native share of crossing pairs, for ``"parallel"`` and
    ``"parallel_pd08"`` one formation after another, for ``"converging"`` and
    ``"meeting"`` one native run after another (turned and moved at random), for
    ``"burst"`` a burst in scan 20 of every 40.  Its layout
    is fixed (drawn from a fixed seed, in time order), its configuration is derived from
    its targets as for every scenario (:func:`birth_model_for`, :func:`max_tracks_for`),
    and building it is linear in the number of scans (10,000 scans of ``"crossing"``, about
    130,000 detections, take a few seconds).

    Parameters
    ----------
    name : str
        One of :func:`scenario_names`.
    seed : int
        Non-negative seed of the noise realisation (the geometry is fixed).
    scans : int, optional
        Number of scans of the result, >= 1 (every sensor's scans together:
        ``"two_sensors"`` alternates its two sensors).  Lengthening past the native length
        is possible for :func:`lengthenable_scenarios` (every built-in scenario);
        :func:`scans_for_duration` converts a duration.

    Raises
    ------
    InputError
        Unknown name, bad seed, ``scans`` not an integer >= 1, or a scenario that cannot
        be lengthened to ``scans``.
    """
    _check_name(name)
    if scans is None:
        return SCENARIOS[name](seed)
    count = check_integer("scans", scans, minimum=1)
    native = native_scan_count(name)
    if count <= native:
        return truncate_scenario(SCENARIOS[name](seed), count)
    if name not in lengthenable_scenarios():
        raise InputError(
            f"scenario {name!r} cannot be lengthened beyond its {native} scans (scans="
            f"{scans!r}); scenarios that can: {', '.join(lengthenable_scenarios())}"
        )
    seed = check_integer("seed", seed, minimum=0)
    _check_simulated_size(name, count)
    if name in MANOEUVRE_FAMILIES:  # the same traffic process, run longer
        return MANOEUVRE_FAMILIES[name].build(seed, count)
    return _LENGTHEN[name](name, _GEOMETRIES[name](), count, seed)


MAX_SIMULATED_DETECTIONS = 20_000_000
"""The most detections :func:`build_scenario` simulates in one recording.

A lengthened scenario is built in memory (about 100 bytes a detection in its scans,
truth and origins, before any file is written), so 20 million detections take a couple
of GB; longer recordings are better simulated as several, and an absurd ``--scans``
(a typing slip of a few zeros) is refused at once instead of filling the memory."""


def _check_simulated_size(name: str, scans: int) -> None:
    """Raise InputError when ``scans`` of ``name`` would exceed the detections limit.

    The expected count is the native scenario's detections per scan (targets and clutter
    of seed 0) times ``scans``: a lengthened run keeps the native density.
    """
    native = SCENARIOS[name](0)
    per_scan = sum(len(scan.detections) for scan in native.scans) / len(native.scans)
    expected = per_scan * scans
    if expected > MAX_SIMULATED_DETECTIONS:
        asked = f"{scans:,}" if scans < 10**15 else f"{float(scans):.3g}"
        raise InputError(
            f"scans={asked} of scenario {name!r} would simulate about {expected:.3g} "
            f"detections ({per_scan:.3g} per scan), over the limit of "
            f"{MAX_SIMULATED_DETECTIONS:,} one recording is built with in memory; simulate "
            f"at most {int(MAX_SIMULATED_DETECTIONS // per_scan):,} scans, or several "
            "recordings",
            key="scans",
        )
