"""The realistic scenario families: converging, meeting, parallel_pd08, dense_radar, staggered."""

from __future__ import annotations

import itertools
import math
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from mapassoc.data.config import load_config
from mapassoc.data.scans import check_scan_order
from mapassoc.data.settings import BirthModel, EstimatorSettings
from mapassoc.evaluation.manoeuvres import MANOEUVRE_FAMILIES
from mapassoc.evaluation.scenarios import (
    CONVERGING_SPACING,
    CONVERGING_TIME,
    GENERIC_BIRTH_RATE,
    GENERIC_INITIAL_COUNT,
    MEETING_TIME,
    build_scenario,
    describe_scenario,
    generic_config,
    lengthenable_scenarios,
    native_scan_count,
    scenario_names,
    top_initial_speed,
)
from mapassoc.evaluation.simulate import Scenario, write_scenario

# name -> (targets, detection probability, false alarms per scan, region area, scans)
REALISTIC = {
    "converging": (6, 0.7, 30.0, 160_000.0, 80),
    "meeting": (4, 0.9, 10.0, 10_000.0, 60),
    "parallel_pd08": (5, 0.8, 20.0, 15_000.0, 40),
    "dense_radar": (10, 0.8, 50.0, 10_000.0, 100),
    "staggered": (8, 0.9, 10.0, 40_000.0, 80),
}
SEEDS = (0, 1, 2, 3, 4)


@cache
def built(name: str, seed: int) -> Scenario:
    return build_scenario(name, seed)


def _origin_map(scenario: Scenario) -> dict[int, int]:
    o = scenario.origins
    return dict(zip(o.rows.tolist(), o.target_ids.tolist(), strict=True))


def _spans(scenario: Scenario) -> dict[int, tuple[float, float]]:
    """First and last truth time of every target."""
    t = scenario.truth
    return {
        int(i): (float(t.times[t.target_ids == i].min()), float(t.times[t.target_ids == i].max()))
        for i in np.unique(t.target_ids)
    }


def _positions(scenario: Scenario, time: float) -> dict[int, np.ndarray]:
    """True position of every target alive at ``time``."""
    t = scenario.truth
    at = t.times == time
    return {int(i): s[:2] for i, s in zip(t.target_ids[at], t.states[at], strict=True)}


def _distances(scenario: Scenario, time: float) -> np.ndarray:
    """Pairwise distances of the targets alive at ``time`` (ids in order), inf diagonal."""
    where = _positions(scenario, time)
    points = np.array([where[i] for i in sorted(where)])
    gaps = np.linalg.norm(points[:, None] - points[None], axis=-1)
    np.fill_diagonal(gaps, np.inf)
    return gaps


def _closest_approach(scenario: Scenario, a: int, b: int) -> float:
    """Smallest distance between targets ``a`` and ``b`` over the scans both are alive."""
    t = scenario.truth
    common = np.intersect1d(t.times[t.target_ids == a], t.times[t.target_ids == b])
    return min(
        float(np.linalg.norm(_positions(scenario, time)[a] - _positions(scenario, time)[b]))
        for time in common
    )


def _first_states(scenario: Scenario) -> np.ndarray:
    """Each target's state at its first truth record (its initial state), in id order."""
    t = scenario.truth
    order = np.lexsort((t.times, t.target_ids))
    ids = t.target_ids[order]
    return t.states[order[np.concatenate([[True], ids[1:] != ids[:-1]])]]


# --------------------------------------------------------------------------- all five


def test_realistic_families_are_registered_after_the_others() -> None:
    names = scenario_names()
    # The manoeuvring families (metres and seconds) are registered after these.
    manoeuvring = len(MANOEUVRE_FAMILIES)
    assert names[-manoeuvring:] == list(MANOEUVRE_FAMILIES)
    assert names[-len(REALISTIC) - manoeuvring : -manoeuvring] == list(REALISTIC)
    assert set(REALISTIC) <= set(lengthenable_scenarios())
    for name in REALISTIC:
        description = describe_scenario(name)
        assert description and "\n" not in description
        assert native_scan_count(name) == REALISTIC[name][4]


@pytest.mark.parametrize("name", list(REALISTIC))
def test_family_is_deterministic_and_seed_driven(name: str) -> None:
    a = built(name, 0)
    again = build_scenario(name, 0)
    for sa, sb in zip(a.scans, again.scans, strict=True):
        np.testing.assert_array_equal(sa.detections, sb.detections)
    np.testing.assert_array_equal(a.truth.states, again.truth.states)
    other = built(name, 1)
    assert [s.size for s in a.scans] != [s.size for s in other.scans]
    assert not np.array_equal(a.truth.states, other.truth.states)
    # The geometry is fixed: same targets, born and dying at the same scans, and the
    # same configuration.
    for scenario in (a, other):
        check_scan_order(scenario.scans)
    assert _spans(a) == _spans(other)
    assert (a.config.birth, a.config.estimator) == (other.config.birth, other.config.estimator)


@pytest.mark.parametrize("name", list(REALISTIC))
def test_family_has_the_stated_targets_sensor_and_clutter(name: str) -> None:
    targets, pd, false_alarms, area, scans = REALISTIC[name]
    fa_counts, detected, present = [], 0, 0
    for seed in (0, 1):
        scenario = built(name, seed)
        assert len(scenario.scans) == scans
        assert len(np.unique(scenario.truth.target_ids)) == targets
        assert list(scenario.config.sensors) == ["pos"]
        sensor = scenario.config.sensors["pos"]
        assert sensor.detection_probability == pd
        assert sensor.false_alarms_per_scan == false_alarms
        assert sensor.region.volume == pytest.approx(area)
        origin = np.array([_origin_map(scenario)[r] for s in scenario.scans for r in s.rows])
        sizes = [s.size for s in scenario.scans]
        fa_counts.extend(
            int(np.sum(part == -1)) for part in np.split(origin, np.cumsum(sizes)[:-1])
        )
        detected += int(np.sum(origin != -1))
        present += scenario.truth.size
        assert np.all(sensor.region.contains(scenario.truth.states[:, :2]))
    # Poisson false alarms: the mean over S scans has std sqrt(lambda / S); 4 of them.
    assert abs(np.mean(fa_counts) - false_alarms) <= 4.0 * math.sqrt(false_alarms / len(fa_counts))
    # Binomial detections of the targets present (every truth record is inside the region).
    assert abs(detected / present - pd) <= 4.0 * math.sqrt(pd * (1 - pd) / present)


@pytest.mark.parametrize("name", list(REALISTIC))
def test_configuration_states_the_true_model(name: str, tmp_path: Path) -> None:
    scenario = built(name, 0)
    truth, config = scenario.truth, scenario.config
    spans = _spans(scenario)
    first, last = scenario.scans[0].time, scenario.scans[-1].time
    present = sum(1 for born, _ in spans.values() if born <= first)
    births = len(spans) - present
    assert config.birth.initial_count == present
    assert config.birth.rate == pytest.approx(max(0.01, births / len(scenario.scans)))
    top = float(np.max(np.hypot(*_first_states(scenario)[:, 2:4].T)))
    assert config.birth.velocity_std == pytest.approx(max(1.0, 1.5 * top))
    assert 0.9 < config.birth.survival_probability < 1.0
    _, alive = np.unique(truth.times, return_counts=True)
    assert config.estimator == EstimatorSettings(max_tracks=max(8, math.ceil(2.5 * alive.max())))
    # Exponential survival at the observed death rate (at least one death counted).
    deaths = sum(1 for _, died in spans.values() if died < last)
    alive_time = sum(died - born for born, died in spans.values())
    hazard = max(deaths, 1) / alive_time
    assert config.birth.survival_probability == pytest.approx(math.exp(-hazard))
    # What `mapassoc simulate` writes is that configuration, with the simulated sensor
    # and motion model.
    written = load_config(write_scenario(scenario, tmp_path)["config"])
    assert (written.birth, written.estimator) == (config.birth, config.estimator)
    assert written.motion.noise_intensity == config.motion.noise_intensity  # type: ignore[attr-defined]
    sensor, true_sensor = written.sensors["pos"], config.sensors["pos"]
    assert sensor.detection_probability == true_sensor.detection_probability
    assert sensor.false_alarms_per_scan == true_sensor.false_alarms_per_scan
    np.testing.assert_array_equal(sensor.region.lower, true_sensor.region.lower)
    np.testing.assert_array_equal(sensor.region.upper, true_sensor.region.upper)


@pytest.mark.parametrize("name", list(REALISTIC))
def test_generic_config(name: str) -> None:
    scenario = built(name, 0)
    config = generic_config(scenario)
    assert config.motion is scenario.config.motion
    assert config.sensors == scenario.config.sensors
    most = max(scan.size for scan in scenario.scans)
    assert config.estimator == EstimatorSettings(max_tracks=2 * most)
    assert config.birth == BirthModel(
        rate=GENERIC_BIRTH_RATE,
        initial_count=GENERIC_INITIAL_COUNT,
        velocity_std=top_initial_speed(scenario),
    )


# --------------------------------------------------------------------------- each family


def test_converging_targets_close_to_1_5_apart_then_separate() -> None:
    assert (CONVERGING_SPACING, CONVERGING_TIME) == (1.5, 40.0)
    spans = _spans(built("converging", 0))
    assert set(spans.values()) == {(0.0, 79.0)}
    ring_means = []
    for seed in SEEDS:
        scenario = built("converging", seed)
        # At t = 40 the six sit on a hexagon of radius 1.5 (ids in ring order), moved
        # by process noise: neighbours 1.5 apart on average, nobody further than 3 from
        # its nearest neighbour.
        gaps = _distances(scenario, CONVERGING_TIME)
        ring = [gaps[k, (k + 1) % 6] for k in range(6)]
        ring_means.append(np.mean(ring))
        assert np.max(np.min(gaps, axis=1)) < 3.0
        assert np.max(ring) < 3.5
        # Closely spaced for a while: neighbours within 3 on average from t = 33 to 47.
        for time in (33.0, 47.0):
            gaps = _distances(scenario, time)
            assert np.mean([gaps[k, (k + 1) % 6] for k in range(6)]) < 3.0
        # Separated at the ends (7.4 apart by design): every pair at least 4 apart.
        assert np.min(_distances(scenario, 0.0)) > 7.0
        assert np.min(_distances(scenario, 79.0)) > 4.0
    assert abs(np.mean(ring_means) - CONVERGING_SPACING) < 0.3
    # Headings within 10 degrees of +x, speeds near 1.
    initial = _first_states(built("converging", 0))
    assert np.all(np.abs(np.degrees(np.arctan2(initial[:, 3], initial[:, 2]))) < 10.0)
    assert np.all(np.abs(np.hypot(initial[:, 2], initial[:, 3]) - 1.0) < 0.2)


def test_meeting_targets_pass_one_point_together() -> None:
    assert MEETING_TIME == 30.0
    for seed in SEEDS:
        scenario = built("meeting", seed)
        # All four within 2 of the origin, and of each other, at t = 30.
        where = _positions(scenario, MEETING_TIME)
        assert sorted(where) == [1, 2, 3, 4]
        assert max(np.linalg.norm(p) for p in where.values()) < 2.0
        assert np.max(_distances(scenario, MEETING_TIME)[~np.eye(4, dtype=bool)]) < 2.0
        # Apart at both ends (the closest, a same-side pair 30 degrees apart: 15.5 and 15
        # by design, moved by process noise).
        assert np.min(_distances(scenario, 0.0)) > 12.0
        assert np.min(_distances(scenario, 59.0)) > 8.0
    initial = _first_states(built("meeting", 0))
    headings = np.degrees(np.arctan2(initial[:, 3], initial[:, 2])) % 360.0
    np.testing.assert_allclose(headings, [15.0, 345.0, 165.0, 195.0])
    np.testing.assert_allclose(np.hypot(initial[:, 2], initial[:, 3]), 1.0)


def test_parallel_pd08_is_parallel_with_fewer_detections() -> None:
    for seed in (0, 1):
        lanes = built("parallel", seed)
        harder = built("parallel_pd08", seed)
        # The same targets and process noise draws: identical truth.
        np.testing.assert_array_equal(lanes.truth.states, harder.truth.states)
        assert lanes.config.motion.noise_intensity == harder.config.motion.noise_intensity  # type: ignore[attr-defined]
        assert lanes.config.birth == harder.config.birth
        a, b = lanes.config.sensors["pos"], harder.config.sensors["pos"]
        assert (a.false_alarms_per_scan, a.region.volume) == (
            b.false_alarms_per_scan,
            b.region.volume,
        )
        assert (a.detection_probability, b.detection_probability) == (0.9, 0.8)
    lengthened = build_scenario("parallel_pd08", 0, scans=130)
    np.testing.assert_array_equal(
        lengthened.truth.states, build_scenario("parallel", 0, scans=130).truth.states
    )


def test_dense_radar_reads_as_a_1_km_radar_with_births_deaths_and_crossings() -> None:
    scenario = built("dense_radar", 0)
    sensor = scenario.config.sensors["pos"]
    np.testing.assert_allclose(sensor.region.lower, [-50.0, -50.0])  # 1 km at 10 m a unit
    np.testing.assert_allclose(sensor.region.upper, [50.0, 50.0])
    # Velocity prior 15 m/s: 1.5 times the top speed (0.98), speeds 0.7-1 at birth.
    assert 1.4 < scenario.config.birth.velocity_std <= 1.5
    speeds = np.hypot(*_first_states(scenario)[:, 2:4].T)
    assert np.all((speeds >= 0.7) & (speeds <= 1.0))
    spans = _spans(scenario)
    assert sum(1 for born, _ in spans.values() if born > 0) >= 5
    assert sum(1 for _, died in spans.values() if died < 99) >= 3
    for seed in (0, 1, 2):
        s = built("dense_radar", seed)
        # The 3 crossing pairs (and chance encounters): at least 3 pairs within 1.5.
        close = sum(
            1
            for a, b in itertools.combinations(sorted(spans), 2)
            if max(spans[a][0], spans[b][0]) <= min(spans[a][1], spans[b][1])
            and _closest_approach(s, a, b) < 1.5
        )
        assert close >= 3, seed


def test_staggered_lives_and_crossings() -> None:
    scenario = built("staggered", 0)
    spans = _spans(scenario)
    assert [spans[i][0] for i in range(1, 9)] == [0, 6, 0, 22, 30, 48, 52, 35]
    assert [spans[i][1] for i in range(1, 9)] == [40, 62, 50, 79, 68, 79, 79, 75]
    _, alive = np.unique(scenario.truth.times, return_counts=True)
    assert alive.min() == 2 and alive.max() == 6
    for seed in SEEDS:
        s = built("staggered", seed)
        # The crossing pairs (ids 1-2, 4-5, 6-7: partners born a few scans apart) meet.
        for a, b in ((1, 2), (4, 5), (6, 7)):
            assert _closest_approach(s, a, b) < 4.0, (seed, a, b)
        # The lone targets 3 and 8 stay clear of the others.
        for lone in (3, 8):
            for other in spans:
                overlap = max(spans[lone][0], spans[other][0]) <= min(
                    spans[lone][1], spans[other][1]
                )
                if other != lone and overlap:
                    assert _closest_approach(s, lone, other) > 10.0


# --------------------------------------------------------------------------- lengthened


def test_lengthened_encounters_repeat_the_native_run() -> None:
    converging = build_scenario("converging", 0, scans=240)
    times, alive = np.unique(converging.truth.times, return_counts=True)
    assert np.all(alive == 6) and times[-1] == 239.0
    # Every 80 scans a new group of six, closely spaced at its own t = 40.
    assert len(np.unique(converging.truth.target_ids)) == 18
    for start in (0.0, 80.0, 160.0):
        assert np.max(np.min(_distances(converging, start + CONVERGING_TIME), axis=1)) < 3.0
        assert np.min(_distances(converging, start)) > 4.0
    meeting = build_scenario("meeting", 1, scans=180)
    _, alive = np.unique(meeting.truth.times, return_counts=True)
    assert np.all(alive == 4)
    for start in (0.0, 60.0, 120.0):
        gaps = _distances(meeting, start + MEETING_TIME)
        assert np.max(gaps[~np.eye(4, dtype=bool)]) < 2.5
    region = meeting.config.sensors["pos"].region
    assert np.all(region.contains(meeting.truth.states[:, :2]))


@pytest.mark.parametrize("name", ["dense_radar", "staggered"])
def test_lengthened_populations_keep_births_and_deaths(name: str) -> None:
    native = native_scan_count(name)
    scenario = build_scenario(name, 0, scans=4 * native)
    spans = _spans(scenario)
    end = scenario.scans[-1].time
    assert sum(1 for born, _ in spans.values() if born > 0.75 * end) >= 2
    assert sum(1 for _, died in spans.values() if died < 0.25 * end) >= 2
    region = scenario.config.sensors["pos"].region
    assert region.contains(scenario.truth.states[:, :2]).mean() > 0.99
