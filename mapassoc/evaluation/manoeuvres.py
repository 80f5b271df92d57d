"""Bench families of targets that manoeuvre: straight legs, coordinated turns, speed changes.

The built-in scenarios of :mod:`mapassoc.evaluation.scenarios` move their targets by the
estimator's own motion model.  The families here do not: each target flies a *flight
plan*, a sequence of legs of constant turn rate and constant along-track acceleration
(a straight leg, a coordinated turn, or a speed change), integrated exactly, so that a
constant-velocity (or any single-model) estimator meets the mismatch users' data brings:
long straight stretches where a small process noise is right, and turns where it is
badly wrong.  Units are physical: metres and seconds.

Families (:data:`MANOEUVRE_FAMILIES`):

* ``"aircraft"``: independent aircraft-like targets, 60-240 m/s, coordinated turns of
  1-5 deg/s through 30-120 deg between straight legs, speed changes of up to 2 m/s^2;
  4 s scans, position noise 50 m, Pd 0.85, 40 false alarms per scan over 60 km x 60 km.
* ``"ships"``: ship-like slow turners, 3-12 m/s, turns of 0.3-1.5 deg/s; 4 s scans,
  30 m noise, Pd 0.8, 30 false alarms per scan over 10 km x 10 km.
* ``"crossing_turns"``: pairs of aircraft whose paths cross in the middle of one's turn
  (the other crossing it at 30-150 deg); 5 s scans, 40 m noise, Pd 0.9, 30 false alarms.
* ``"converging_turns"``: pairs of aircraft from different directions that turn onto one
  common track and fly on abreast 3-6 noise standard deviations apart (a merge onto a
  parallel approach); 5 s scans, 60 m noise, Pd 0.8, 50 false alarms.

Each family is a steady birth-death traffic: flights (or pairs) appear as a renewal
process whose gaps are uniform between half and one and a half of the mean gap, each
lives a whole number of scans, and the traffic starts in its steady state (flights born
before the first scan are seen from it).  Unlike the built-in scenarios, whose geometry
is fixed and whose seed draws the noise, the seed here draws the traffic too (flight
plans, times) as well as the detections: a manoeuvre family's point is the variety of
its turns, and every seed is a new traffic sample.  A recording of any length is the
same process run longer (:meth:`ManoeuvreFamily.build`).

The configuration's motion model is 2-D constant velocity whose noise intensity is
*moment-matched to the truth*: ``q = mean |v_k - v_{k-1}|^2 / (2 T)`` over the truth's
consecutive scans (the velocity of the white-noise-acceleration model changes over a
scan by ``q T`` per axis in variance: Bar-Shalom, Li and Kirubarajan, *Estimation with
Applications to Tracking and Navigation*, 2001, section 6.2.2).  That is the process
noise a fit of a single constant-velocity model to the truth would give, the baseline a
multiple-model estimator must beat.  The birth model follows the rules of
:func:`mapassoc.evaluation.scenarios.birth_model_for`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config
from mapassoc.data.settings import CountSettings, EstimatorSettings
from mapassoc.errors import InputError
from mapassoc.evaluation.simulate import (
    Scenario,
    _alive_by_time,
    _observe_plan,
    _SimulatedTruth,
    _truth_table,
    scan_plan_regular,
)
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.population import BirthModel
from mapassoc.models.sensor import Region, Sensor
from mapassoc.validation import check_integer

__all__ = [
    "Leg",
    "Flight",
    "ManoeuvreFamily",
    "MANOEUVRE_FAMILIES",
    "flight_states",
    "matched_noise_intensity",
]

_SENSOR = "pos"
_MAX_DRAWS = 2_000
_DEG = math.pi / 180.0
_INSIDE = 0.95
"""Every true position stays inside this share of the region's half width."""


@dataclass(frozen=True)
class Leg:
    """One leg of a flight plan: constant turn rate and along-track acceleration.

    Parameters
    ----------
    duration : float
        Seconds, > 0.
    turn_rate : float
        rad/s (positive: counter-clockwise); 0 for a straight leg or a speed change.
    acceleration : float
        Along-track acceleration, m/s^2; 0 for a straight leg or a coordinated turn.
    """

    duration: float
    turn_rate: float = 0.0
    acceleration: float = 0.0


@dataclass(frozen=True)
class Flight:
    """A target's flight plan: where and how it starts, its legs, its life.

    After its last leg the target flies straight at its final speed.

    Parameters
    ----------
    position : tuple of float
        ``(x, y)`` at ``birth_time``, metres.
    speed, heading : float
        At ``birth_time``: m/s (> 0) and rad from the x axis.
    legs : tuple of Leg
    birth_time, death_time : float
        Seconds; the target exists on ``[birth_time, death_time]``.
    """

    position: tuple[float, float]
    speed: float
    heading: float
    legs: tuple[Leg, ...]
    birth_time: float
    death_time: float


def _leg_end(
    p: complex, v: float, h: float, leg: Leg, t: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Position (complex), speed and heading ``t`` seconds into a leg, exactly.

    With speed ``v + a t`` and heading ``h + w t`` the velocity is
    ``(v + a t) exp(i (h + w t))``; its integral is, for ``w != 0``,
    ``exp(i h) [(v + a s) exp(i w s) / (i w) + a exp(i w s) / w^2]`` from 0 to t.
    """
    a, w = leg.acceleration, leg.turn_rate
    if w == 0.0:
        position = p + np.exp(1j * h) * (v * t + 0.5 * a * t * t)
        return position, v + a * t, np.full_like(t, h)
    rot = np.exp(1j * w * t)
    integral = (v + a * t) * rot / (1j * w) + a * rot / w**2 - (v / (1j * w) + a / w**2)
    return p + np.exp(1j * h) * integral, v + a * t, h + w * t


def flight_states(flight: Flight, times: FloatArray) -> FloatArray:
    """True constant-velocity states ``(x, y, vx, vy)`` of a flight at ``times``.

    Parameters
    ----------
    flight : Flight
    times : ndarray, shape (T,)
        Seconds, each at or after ``flight.birth_time``.

    Returns
    -------
    ndarray, shape (T, 4)
    """
    t = np.asarray(times, dtype=float) - flight.birth_time
    # Scan times k T computed from a birth time on the scan grid may fall a rounding
    # error before it.
    t = np.where((t < 0) & (t > -1e-6 * max(1.0, abs(flight.birth_time))), 0.0, t)
    if np.any(t < 0):
        raise InputError(f"times must be >= the flight's birth_time {flight.birth_time}")
    position = np.zeros(t.shape, dtype=complex)
    speed = np.zeros(t.shape)
    heading = np.zeros(t.shape)
    p, v, h, start = complex(*flight.position), flight.speed, flight.heading, 0.0
    for leg in (*flight.legs, Leg(duration=math.inf)):
        inside = (t >= start) & (t < start + leg.duration)
        position[inside], speed[inside], heading[inside] = _leg_end(p, v, h, leg, t[inside] - start)
        if not math.isfinite(leg.duration):
            break
        end = np.array([leg.duration])
        pe, ve, he = _leg_end(p, v, h, leg, end)
        p, v, h, start = complex(pe[0]), float(ve[0]), float(he[0]), start + leg.duration
    velocity = speed * np.exp(1j * heading)
    return np.stack([position.real, position.imag, velocity.real, velocity.imag], axis=-1)


def matched_noise_intensity(states: Sequence[FloatArray], interval: float) -> float:
    """Constant-velocity noise intensity moment-matched to true velocity increments.

    ``q = mean over consecutive scans of |v_k - v_{k-1}|^2 / (2 T)`` (module docstring).

    Parameters
    ----------
    states : sequence of ndarray, shape (T_i, 4)
        Each target's states at consecutive scans ``interval`` apart.
    interval : float
        Scan interval T, seconds.

    Returns
    -------
    float
        At least ``1e-6`` (a recording of straight flights still needs a positive q).
    """
    increments = [np.diff(s[:, 2:4], axis=0) for s in states if len(s) > 1]
    if not increments:
        return 1e-6
    squared = np.concatenate([np.sum(d * d, axis=1) for d in increments])
    return max(1e-6, float(np.mean(squared)) / (2.0 * interval))


@dataclass(frozen=True)
class ManoeuvreFamily:
    """A family of manoeuvring traffic: its sensor, its targets' flight plans, its length.

    Parameters
    ----------
    name, description : str
    interval : float
        Seconds between scans.
    noise_std : float
        Position noise standard deviation per axis, metres.
    detection_probability, false_alarms_per_scan : float
    half_width : float
        The region is ``[-half_width, half_width]^2``, metres.
    native_scans : int
        Scans of ``build(seed)``.
    mean_alive : float
        Targets alive at a time, on average.
    lives : tuple of int
        Fewest and most scans a flight lives.
    speeds : tuple of float
        Lowest and highest speed, m/s.
    turn_rates : tuple of float
        Lowest and highest absolute turn rate, deg/s.
    turn_angles : tuple of float
        Smallest and largest heading change of a turn, deg.
    legs : tuple of float
        Shortest and longest straight leg, seconds.
    speed_change : float
        Probability that a straight leg is followed by a speed change.
    max_acceleration : float
        Largest along-track acceleration of a speed change, m/s^2.
    kind : {"single", "crossing", "converging"}
        Independent flights, or pairs whose paths cross in a turn, or pairs that turn onto
        one track and fly abreast.
    """

    name: str
    description: str
    interval: float
    noise_std: float
    detection_probability: float
    false_alarms_per_scan: float
    half_width: float
    native_scans: int
    mean_alive: float
    lives: tuple[int, int]
    speeds: tuple[float, float]
    turn_rates: tuple[float, float]
    turn_angles: tuple[float, float]
    legs: tuple[float, float]
    speed_change: float
    max_acceleration: float
    kind: str

    def __post_init__(self) -> None:
        if self.kind not in ("single", "crossing", "converging"):
            raise InputError(
                f"kind must be 'single', 'crossing' or 'converging', got {self.kind!r}"
            )

    @property
    def scan_period(self) -> float:
        """Seconds between consecutive scans."""
        return self.interval

    def build(self, seed: int, scans: int | None = None) -> Scenario:
        """The family's recording of ``scans`` scans (default :attr:`native_scans`).

        Raises
        ------
        InputError
            A bad seed or number of scans.
        """
        seed = check_integer("seed", seed, minimum=0)
        count = self.native_scans if scans is None else check_integer("scans", scans, minimum=1)
        layout_seed, sensing_seed = np.random.SeedSequence([seed, _family_key(self.name)]).spawn(2)
        rng = np.random.default_rng(layout_seed)
        last = (count - 1) * self.interval
        flights = _traffic(self, rng, last)
        return _observe(self, flights, count, np.random.default_rng(sensing_seed))


def _family_key(name: str) -> int:
    """A fixed integer per family name, so that families with one seed differ."""
    return int.from_bytes(name.encode("utf-8")[:8].ljust(8, b"\0"), "little")


# --------------------------------------------------------------------------- flight plans


def _turn(rng: np.random.Generator, family: ManoeuvreFamily, sign: float | None = None) -> Leg:
    rate = rng.uniform(*family.turn_rates) * _DEG
    angle = rng.uniform(*family.turn_angles) * _DEG
    side = sign if sign is not None else float(rng.choice([-1.0, 1.0]))
    return Leg(duration=angle / rate, turn_rate=side * rate)


def _speed_change(rng: np.random.Generator, family: ManoeuvreFamily, speed: float) -> Leg | None:
    """A speed change to a new speed in the family's range, or None when too small."""
    target = rng.uniform(*family.speeds)
    change = target - speed
    if abs(change) < 0.1 * speed:
        return None
    acceleration = math.copysign(rng.uniform(0.3, 1.0) * family.max_acceleration, change)
    return Leg(duration=change / acceleration, acceleration=acceleration)


def _plan_legs(
    rng: np.random.Generator, family: ManoeuvreFamily, speed: float, span: float
) -> tuple[Leg, ...]:
    """Straight legs alternating with turns (and now and then a speed change) for ``span`` s.

    The first leg is a straight leg cut at a uniform point, so that a flight seen from
    the first scan may be anywhere in its plan.
    """
    legs: list[Leg] = []
    elapsed = 0.0
    first = rng.uniform(*family.legs) * rng.uniform(0.0, 1.0)
    legs.append(Leg(duration=max(first, family.interval)))
    elapsed += legs[-1].duration
    while elapsed < span:
        if rng.random() < family.speed_change:
            change = _speed_change(rng, family, speed)
            if change is not None:
                legs.append(change)
                speed += change.acceleration * change.duration
                elapsed += change.duration
        legs.append(_turn(rng, family))
        legs.append(Leg(duration=rng.uniform(*family.legs)))
        elapsed += legs[-2].duration + legs[-1].duration
    return tuple(legs)


def _scan_times(family: ManoeuvreFamily, flight: Flight, last: float) -> FloatArray:
    """The scan times at which ``flight`` is alive (scans at ``0, T, 2T, ...`` to ``last``)."""
    first = max(0, math.ceil(flight.birth_time / family.interval - 1e-9))
    final = min(math.floor(last / family.interval + 1e-9),
                math.floor(flight.death_time / family.interval + 1e-9))  # fmt: skip
    return np.asarray(np.arange(first, final + 1) * family.interval, dtype=np.float64)


def _placed(family: ManoeuvreFamily, flight: Flight, offset: complex) -> Flight:
    return Flight(
        position=(flight.position[0] + offset.real, flight.position[1] + offset.imag),
        speed=flight.speed,
        heading=flight.heading,
        legs=flight.legs,
        birth_time=flight.birth_time,
        death_time=flight.death_time,
    )


def _fits(family: ManoeuvreFamily, flights: Sequence[Flight], last: float) -> bool:
    limit = _INSIDE * family.half_width
    for flight in flights:
        times = _scan_times(family, flight, last)
        if times.size and np.any(np.abs(flight_states(flight, times)[:, :2]) > limit):
            return False
    return True


def _centred(
    family: ManoeuvreFamily, rng: np.random.Generator, flights: list[Flight], last: float
) -> list[Flight] | None:
    """The flights moved together so that their seen positions' box sits at a random
    point inside the region, or None when the box does not fit."""
    points = [
        flight_states(f, _scan_times(family, f, last))[:, :2]
        for f in flights
        if _scan_times(family, f, last).size
    ]
    if not points:
        return flights
    allp = np.concatenate(points)
    low, high = allp.min(axis=0), allp.max(axis=0)
    room = _INSIDE * family.half_width - 0.5 * (high - low)
    if np.any(room <= 0):
        return None
    centre = rng.uniform(-room, room)
    shift = centre - 0.5 * (low + high)
    moved = [_placed(family, f, complex(shift[0], shift[1])) for f in flights]
    return moved if _fits(family, moved, last) else None


def _single(
    family: ManoeuvreFamily, rng: np.random.Generator, birth: float, life: float, last: float
) -> list[Flight]:
    speed = rng.uniform(*family.speeds)
    heading = rng.uniform(-math.pi, math.pi)
    legs = _plan_legs(rng, family, speed, life)
    return [Flight((0.0, 0.0), speed, heading, legs, birth, birth + life)]


def _state_at(flight: Flight, time: float) -> tuple[complex, complex]:
    """Position and velocity (complex) of a flight at one time."""
    s = flight_states(flight, np.array([time]))[0]
    return complex(s[0], s[1]), complex(s[2], s[3])


def _moved_to(flight: Flight, time: float, point: complex, heading: float) -> Flight:
    """The flight turned and moved rigidly so that at ``time`` it is at ``point`` heading
    ``heading``."""
    where, velocity = _state_at(flight, time)
    turn = heading - math.atan2(velocity.imag, velocity.real)
    start = complex(*flight.position)
    new_start = point + (start - where) * complex(math.cos(turn), math.sin(turn))
    return Flight(
        position=(new_start.real, new_start.imag),
        speed=flight.speed,
        heading=flight.heading + turn,
        legs=flight.legs,
        birth_time=flight.birth_time,
        death_time=flight.death_time,
    )


def _crossing(
    family: ManoeuvreFamily, rng: np.random.Generator, birth: float, life: float, last: float
) -> list[Flight]:
    """Two flights whose paths cross in the middle of the first one's turn."""
    first = _single(family, rng, birth, life, last)[0]
    starts = np.cumsum([0.0] + [leg.duration for leg in first.legs])
    turns = [
        birth + starts[i] + 0.5 * leg.duration
        for i, leg in enumerate(first.legs)
        if leg.turn_rate != 0.0 and birth + 0.2 * life < birth + starts[i] < birth + 0.7 * life
    ]
    meet = turns[0] if turns else birth + 0.5 * life
    meet = round(meet / family.interval) * family.interval  # at a scan: seen at one point
    second_birth = min(birth + rng.uniform(0.0, 0.2) * life, meet)
    other = _single(family, rng, second_birth, life, last)[0]
    where, velocity = _state_at(first, meet)
    angle = math.atan2(velocity.imag, velocity.real)
    crossing = float(rng.choice([-1.0, 1.0])) * rng.uniform(30.0, 150.0) * _DEG
    return [first, _moved_to(other, meet, where, angle + crossing)]


def _converging(
    family: ManoeuvreFamily, rng: np.random.Generator, birth: float, life: float, last: float
) -> list[Flight]:
    """Two flights from different directions that turn onto one track and fly abreast.

    Both fly straight, turn (opposite senses) and end on the same heading at the same
    speed, ``3-6`` noise standard deviations apart across the track, for the last 40-60%
    of the life.
    """
    speed = rng.uniform(*family.speeds)
    merge = birth + rng.uniform(0.4, 0.6) * life
    final = rng.uniform(-math.pi, math.pi)
    separation = rng.uniform(3.0, 6.0) * family.noise_std
    flights = []
    for side in (1.0, -1.0):
        turn = _turn(rng, family, sign=side)
        straight = merge - birth - turn.duration
        if straight <= family.interval:
            straight = family.interval
        legs = (Leg(duration=straight), turn)
        flight = Flight((0.0, 0.0), speed, final - turn.turn_rate * turn.duration, legs,
                        merge - straight - turn.duration, birth + life)  # fmt: skip
        offset = side * 0.5 * separation * complex(-math.sin(final), math.cos(final))
        flights.append(_moved_to(flight, merge, offset, final))
    return flights


_MAKERS = {"single": _single, "crossing": _crossing, "converging": _converging}


def _traffic(family: ManoeuvreFamily, rng: np.random.Generator, last: float) -> list[Flight]:
    """The steady birth-death traffic seen between 0 and ``last`` (module docstring)."""
    members = 1 if family.kind == "single" else 2
    mean_life = 0.5 * (family.lives[0] + family.lives[1]) * family.interval
    gap = mean_life * members / family.mean_alive
    clock = -family.lives[1] * family.interval + rng.uniform(0.0, gap)
    flights: list[Flight] = []
    while clock <= last:
        birth = math.floor(clock / family.interval) * family.interval
        for _ in range(_MAX_DRAWS):
            life = float(rng.integers(family.lives[0], family.lives[1] + 1)) * family.interval
            drawn = _MAKERS[family.kind](family, rng, birth, life, last)
            placed = _centred(family, rng, drawn, last)
            if placed is not None:
                flights.extend(f for f in placed if _scan_times(family, f, last).size)
                break
        else:
            raise InputError(f"cannot place a {family.name} flight inside the region")
        clock += rng.uniform(0.5 * gap, 1.5 * gap)
    return flights


# --------------------------------------------------------------------------- sensing


def _config(family: ManoeuvreFamily, flights: Sequence[Flight], states: Sequence[FloatArray],
            count: int) -> Config:  # fmt: skip
    """The family's configuration: matched constant velocity, its radar, its birth model."""
    motion = ConstantVelocity(
        ndim=2, noise_intensity=matched_noise_intensity(states, family.interval)
    )
    sensor = Sensor(
        name=_SENSOR,
        measurement=LinearMeasurement.position(motion, noise_std=family.noise_std),
        detection_probability=family.detection_probability,
        false_alarms_per_scan=family.false_alarms_per_scan,
        region=Region.from_bounds([[-family.half_width, family.half_width]] * 2),
    )
    last = (count - 1) * family.interval
    present = sum(1 for f in flights if f.birth_time <= 0.0)
    deaths = sum(1 for f in flights if f.death_time < last)
    alive_time = sum(min(f.death_time, last) - max(f.birth_time, 0.0) for f in flights)
    top = max((float(np.max(np.hypot(s[:, 2], s[:, 3]))) for s in states), default=1.0)
    scan_index = [np.rint(_scan_times(family, f, last) / family.interval).astype(np.int64)
                  for f in flights]  # fmt: skip
    most = int(np.max(np.bincount(np.concatenate(scan_index)))) if flights else 0
    birth = BirthModel(
        rate=max(0.01, (len(flights) - present) / count),
        initial_count=float(present),
        velocity_std=max(1.0, 1.5 * top),
        speed_std=max(1.0, 1.5 * top),
        turn_rate_std=max(0.02, 2.0 * family.turn_rates[1] * _DEG),
        survival_probability=math.exp(-max(deaths, 1) / max(alive_time, 1.0)),
    )
    estimator = EstimatorSettings(count=CountSettings(max_tracks=max(8, math.ceil(2.5 * most))))
    return Config(motion=motion, sensors={_SENSOR: sensor}, birth=birth, estimator=estimator)


def _observe(
    family: ManoeuvreFamily, flights: Sequence[Flight], count: int, rng: np.random.Generator
) -> Scenario:
    """Detections of the flights by the family's radar over ``count`` scans."""
    last = (count - 1) * family.interval
    plan = scan_plan_regular([_SENSOR], 0.0, family.interval, count)
    times = np.array([t for t, _ in plan])
    per_flight = [_scan_times(family, f, last) for f in flights]
    states = [flight_states(f, t) for f, t in zip(flights, per_flight, strict=True)]
    config = _config(family, flights, states, count)
    trajectories = [
        {float(times[int(round(t / family.interval))]): s for t, s in zip(ts, ss, strict=True)}
        for ts, ss in zip(per_flight, states, strict=True)
    ]
    truth = _SimulatedTruth(
        times=times,
        trajectories=trajectories,
        alive_at=_alive_by_time(trajectories),
        target_ids=np.arange(1, len(flights) + 1, dtype=np.int64),
    )
    scans, origins = _observe_plan(config, plan, truth, rng)
    return Scenario(
        name=family.name,
        config=config,
        scans=scans,
        truth=_truth_table(config, truth),
        origins=origins,
    )


# --------------------------------------------------------------------------- families

MANOEUVRE_FAMILIES: dict[str, ManoeuvreFamily] = {
    family.name: family
    for family in (
        ManoeuvreFamily(
            name="aircraft",
            description=(
                "aircraft-like targets at 60-240 m/s: straight legs, coordinated turns of "
                "1-5 deg/s through 30-120 deg, speed changes; 4 s scans, 50 m noise, Pd 0.85, "
                "40 false alarms/scan over 60 km x 60 km, 60 scans"
            ),
            interval=4.0, noise_std=50.0, detection_probability=0.85,
            false_alarms_per_scan=40.0, half_width=30_000.0, native_scans=60,
            mean_alive=8.0, lives=(30, 60), speeds=(60.0, 240.0), turn_rates=(1.0, 5.0),
            turn_angles=(30.0, 120.0), legs=(20.0, 80.0), speed_change=0.3,
            max_acceleration=2.0, kind="single",
        ),
        ManoeuvreFamily(
            name="ships",
            description=(
                "ship-like slow turners at 3-12 m/s, turns of 0.3-1.5 deg/s through 20-90 "
                "deg; 4 s scans, 30 m noise, Pd 0.8, 30 false alarms/scan over 10 km x 10 km, "
                "100 scans"
            ),
            interval=4.0, noise_std=30.0, detection_probability=0.8,
            false_alarms_per_scan=30.0, half_width=5_000.0, native_scans=100,
            mean_alive=8.0, lives=(50, 100), speeds=(3.0, 12.0), turn_rates=(0.3, 1.5),
            turn_angles=(20.0, 90.0), legs=(40.0, 160.0), speed_change=0.3,
            max_acceleration=0.1, kind="single",
        ),
        ManoeuvreFamily(
            name="crossing_turns",
            description=(
                "pairs of aircraft (60-240 m/s, turns of 1-5 deg/s) whose paths cross in the "
                "middle of one's turn at 30-150 deg; 5 s scans, 40 m noise, Pd 0.9, 30 false "
                "alarms/scan over 50 km x 50 km, 50 scans"
            ),
            interval=5.0, noise_std=40.0, detection_probability=0.9,
            false_alarms_per_scan=30.0, half_width=25_000.0, native_scans=50,
            mean_alive=6.0, lives=(30, 50), speeds=(60.0, 240.0), turn_rates=(1.0, 5.0),
            turn_angles=(30.0, 120.0), legs=(20.0, 80.0), speed_change=0.2,
            max_acceleration=2.0, kind="crossing",
        ),
        ManoeuvreFamily(
            name="converging_turns",
            description=(
                "pairs of aircraft (60-240 m/s) from different directions turning at 1-5 "
                "deg/s onto one track, then abreast 3-6 noise std apart; 5 s scans, 60 m "
                "noise, Pd 0.8, 50 false alarms/scan over 50 km x 50 km, 50 scans"
            ),
            interval=5.0, noise_std=60.0, detection_probability=0.8,
            false_alarms_per_scan=50.0, half_width=25_000.0, native_scans=50,
            mean_alive=6.0, lives=(30, 50), speeds=(60.0, 240.0), turn_rates=(1.0, 5.0),
            turn_angles=(30.0, 120.0), legs=(20.0, 80.0), speed_change=0.0,
            max_acceleration=2.0, kind="converging",
        ),
    )
}  # fmt: skip
"""The manoeuvring families by name (module docstring)."""
