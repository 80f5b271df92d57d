"""The manoeuvring bench families: exact flight plans, and the properties each family states."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mapassoc.errors import InputError
from mapassoc.evaluation.manoeuvres import (
    MANOEUVRE_FAMILIES,
    Flight,
    Leg,
    flight_states,
    matched_noise_intensity,
)
from mapassoc.evaluation.scenarios import (
    build_scenario,
    native_scan_count,
    scenario_names,
    scenario_scan_period,
)
from mapassoc.evaluation.simulate import Scenario
from mapassoc.filtering.imm import IMMState, SwitchingLaw, imm_filter, imm_predict
from mapassoc.filtering.kalman import FilterStep, gate_threshold, innovation
from mapassoc.models.motion import ConstantVelocity

FAMILIES = sorted(MANOEUVRE_FAMILIES)


def _numerical(flight: Flight, end: float, step: float = 1e-3) -> np.ndarray:
    """Position at ``end`` by integrating speed and heading leg by leg (midpoint rule)."""
    t = np.arange(0.0, end, step) + 0.5 * step
    speed = np.full_like(t, flight.speed)
    heading = np.full_like(t, flight.heading)
    start, v, h = 0.0, flight.speed, flight.heading
    for leg in flight.legs:
        inside = (t >= start) & (t < start + leg.duration)
        speed[inside] = v + leg.acceleration * (t[inside] - start)
        heading[inside] = h + leg.turn_rate * (t[inside] - start)
        v += leg.acceleration * leg.duration
        h += leg.turn_rate * leg.duration
        start += leg.duration
    after = t >= start
    speed[after], heading[after] = v, h
    return np.array(flight.position) + step * np.array(
        [np.sum(speed * np.cos(heading)), np.sum(speed * np.sin(heading))]
    )


def test_flight_states_are_the_exact_integral_of_the_plan() -> None:
    legs = (
        Leg(duration=10.0),
        Leg(duration=30.0, turn_rate=3.0 * math.pi / 180.0),
        Leg(duration=8.0, acceleration=-2.0),
        Leg(duration=20.0, turn_rate=-2.0 * math.pi / 180.0, acceleration=0.5),
    )
    flight = Flight((100.0, -50.0), 150.0, 0.3, legs, 0.0, 200.0)
    times = np.array([0.0, 5.0, 10.0, 25.0, 40.0, 44.0, 48.0, 60.0, 68.0, 90.0])
    states = flight_states(flight, times)
    for time, state in zip(times[1:], states[1:], strict=True):
        assert np.allclose(state[:2], _numerical(flight, float(time)), atol=1e-3)
    # Speeds and headings leg by leg: 150 straight, 150 turning 3 deg/s, 150 - 2 t, ...
    speed = np.hypot(states[:, 2], states[:, 3])
    assert np.allclose(speed[:7], [150, 150, 150, 150, 150, 142, 134])
    assert speed[8] == pytest.approx(134 + 0.5 * 20)
    heading = np.arctan2(states[:, 3], states[:, 2])
    assert heading[4] - heading[2] == pytest.approx(math.radians(90.0))
    assert np.allclose(flight_states(flight, np.array([0.0]))[0], [100, -50,
                       150 * math.cos(0.3), 150 * math.sin(0.3)])  # fmt: skip
    with pytest.raises(InputError, match="birth_time"):
        flight_states(flight, np.array([-1.0]))


def test_matched_noise_intensity_by_hand() -> None:
    # Velocity increments (1, 0) and (0, 1) over T = 2: mean |dv|^2 = 1, q = 1 / (2 T).
    states = [np.array([[0, 0, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1.0]])]
    assert matched_noise_intensity(states, 2.0) == pytest.approx(0.25)
    assert matched_noise_intensity([np.zeros((1, 4))], 2.0) == 1e-6


@pytest.fixture(scope="module", params=FAMILIES)
def built(request: pytest.FixtureRequest) -> tuple[str, list[Scenario]]:
    return request.param, [build_scenario(request.param, seed) for seed in range(3)]


def _tracks(scenario: Scenario) -> list[np.ndarray]:
    truth = scenario.truth
    return [truth.states[truth.target_ids == i] for i in np.unique(truth.target_ids)]


def test_speeds_and_turn_rates_are_in_the_familys_ranges(
    built: tuple[str, list[Scenario]],
) -> None:
    name, scenarios = built
    family = MANOEUVRE_FAMILIES[name]
    rates = []
    for scenario in scenarios:
        for states in _tracks(scenario):
            speed = np.hypot(states[:, 2], states[:, 3])
            assert np.all(speed >= family.speeds[0] - 1e-9)
            assert np.all(speed <= family.speeds[1] + 1e-9)
            heading = np.unwrap(np.arctan2(states[:, 3], states[:, 2]))
            rates.extend(np.degrees(np.abs(np.diff(heading))) / family.interval)
    rates_ = np.array(rates)
    # A heading change over a scan is a share of one turn at most: never above the top rate.
    assert rates_.max() <= family.turn_rates[1] + 1e-6
    # Targets turn for a good share of the scans, and some at the top of the range.
    turning = rates_ > 0.05
    assert 0.1 < np.mean(turning) < 0.7
    assert rates_.max() > 0.8 * family.turn_rates[1]


def test_detection_probability_and_clutter_are_realised(
    built: tuple[str, list[Scenario]],
) -> None:
    name, scenarios = built
    family = MANOEUVRE_FAMILIES[name]
    detected = records = false_alarms = scans = 0
    for scenario in scenarios:
        records += scenario.truth.size
        detected += int(np.count_nonzero(scenario.origins.target_ids >= 0))
        false_alarms += int(np.count_nonzero(scenario.origins.target_ids < 0))
        scans += len(scenario.scans)
        assert scenario.config.sensors["pos"].region.contains(scenario.truth.states[:, :2]).all()
    pd = family.detection_probability
    assert abs(detected / records - pd) < 4 * math.sqrt(pd * (1 - pd) / records)
    rate = family.false_alarms_per_scan
    assert abs(false_alarms / scans - rate) < 4 * math.sqrt(rate / scans)


def test_the_configuration_matches_the_truth(built: tuple[str, list[Scenario]]) -> None:
    name, scenarios = built
    family = MANOEUVRE_FAMILIES[name]
    for scenario in scenarios:
        config = scenario.config
        q = matched_noise_intensity(_tracks(scenario), family.interval)
        assert config.motion.noise_intensity == pytest.approx(q)
        sensor = config.sensors["pos"]
        assert np.allclose(sensor.measurement.R, family.noise_std**2 * np.eye(2))
        velocities = scenario.truth.states[:, 2:4]
        assert config.birth.velocity_std >= np.max(np.hypot(velocities[:, 0], velocities[:, 1]))
        assert np.allclose(np.diff([s.time for s in scenario.scans]), family.interval)


def test_pairs_cross_or_converge_as_the_family_says(built: tuple[str, list[Scenario]]) -> None:
    """Crossing pairs come within 2 noise std of each other; converging pairs end abreast,
    3-6 noise std apart with one velocity."""
    name, scenarios = built
    family = MANOEUVRE_FAMILIES[name]
    if family.kind == "single":
        pytest.skip("independent flights")
    close = abreast = 0
    for scenario in scenarios:
        truth = scenario.truth
        ids = np.unique(truth.target_ids)
        for a in ids:
            for b in ids[ids > a]:
                ta, tb = truth.times[truth.target_ids == a], truth.times[truth.target_ids == b]
                common, ia, ib = np.intersect1d(ta, tb, return_indices=True)
                if common.size < 2:
                    continue
                sa = truth.states[truth.target_ids == a][ia]
                sb = truth.states[truth.target_ids == b][ib]
                gap = np.hypot(*(sa[:, :2] - sb[:, :2]).T)
                close += bool(gap.min() < 2 * family.noise_std)
                same = np.hypot(*(sa[-1, 2:] - sb[-1, 2:])) < 1e-6
                abreast += bool(same and 2.9 * family.noise_std < gap[-1] < 6.1 * family.noise_std)
    if family.kind == "crossing":
        assert close >= 3
    else:
        assert abreast >= 3


def test_seeds_draw_new_traffic_and_repeat_exactly() -> None:
    one = build_scenario("aircraft", 1)
    again = build_scenario("aircraft", 1)
    other = build_scenario("aircraft", 2)
    assert np.array_equal(one.truth.states, again.truth.states)
    assert all(np.array_equal(a.detections, b.detections)
               for a, b in zip(one.scans, again.scans, strict=True))  # fmt: skip
    assert one.truth.size != other.truth.size or not np.allclose(one.truth.states,
                                                                 other.truth.states)  # fmt: skip


def test_families_are_registered_with_their_length_and_period() -> None:
    for name, family in MANOEUVRE_FAMILIES.items():
        assert name in scenario_names()
        assert native_scan_count(name) == family.native_scans
        assert scenario_scan_period(name) == family.interval
    longer = build_scenario("crossing_turns", 0, scans=80)
    assert len(longer.scans) == 80
    alive = np.unique(longer.truth.times, return_counts=True)[1]
    assert alive[-20:].mean() > 0.5 * MANOEUVRE_FAMILIES["crossing_turns"].mean_alive
    shorter = build_scenario("crossing_turns", 0, scans=10)
    native = build_scenario("crossing_turns", 0)
    assert all(np.array_equal(a.detections, b.detections)
               for a, b in zip(shorter.scans, native.scans[:10], strict=True))  # fmt: skip


def _outside_gate(scenario: Scenario, models: tuple, law: SwitchingLaw) -> tuple[int, int]:  # type: ignore[type-arg]
    """True detections (from each target's third on) outside the 0.999 gate of every
    model of an IMM run on the true associations, and their number."""
    meas = scenario.config.sensors["pos"].measurement
    threshold = gate_threshold(0.999, 2)
    where = {int(r): (scan.time, scan.detections[j]) for scan in scenario.scans
             for j, r in enumerate(scan.rows)}  # fmt: skip
    outside = total = 0
    for target in np.unique(scenario.origins.target_ids[scenario.origins.target_ids >= 0]):
        rows = scenario.origins.rows[scenario.origins.target_ids == target]
        detections = sorted((where[int(r)] for r in rows), key=lambda d: d[0])
        if len(detections) < 3:
            continue
        x0 = np.array([*detections[0][1], 0.0, 0.0])
        v2 = scenario.config.birth.velocity_std ** 2
        P0 = np.diag([meas.R[0, 0], meas.R[1, 1], v2, v2])
        steps = [FilterStep(time=t, measurement=meas, z=z) for t, z in detections]
        run = imm_filter(models, law, x0, P0, steps)
        for k in range(2, len(detections)):
            dt = detections[k][0] - detections[k - 1][0]
            previous = IMMState(run.log_filtered[k - 1], run.x_filtered[k - 1],
                                run.P_filtered[k - 1])  # fmt: skip
            prediction = imm_predict(previous, models, law.at(dt), dt)
            nu, S, _ = innovation(meas, prediction.means, prediction.covariances, detections[k][1])
            d2 = np.einsum("ji,ji->j", nu, np.linalg.solve(S, nu[..., None])[..., 0])
            outside += bool(np.all(d2 > threshold))
            total += 1
    return outside, total


def test_aircraft_turns_break_the_constant_velocity_gate_and_not_an_imms() -> None:
    """What the family is for: with the matched q, the constant-velocity filter on the
    true associations gates out several per cent of the true detections (1 in 1,000
    expected of a right model), an IMM of q / 20 and 5 q a few in 1,000."""
    scenario = build_scenario("aircraft", 0)
    q = scenario.config.motion.noise_intensity
    single = SwitchingLaw(n_models=1, switch_probability=0.0)
    out_cv, total = _outside_gate(scenario, (scenario.config.motion,), single)
    pair = (ConstantVelocity(ndim=2, noise_intensity=q / 20), ConstantVelocity(ndim=2,
            noise_intensity=5 * q))  # fmt: skip
    out_imm, _ = _outside_gate(scenario, pair, SwitchingLaw(n_models=2, switch_probability=0.05))
    assert out_cv > 0.02 * total
    assert out_imm < 0.005 * total
