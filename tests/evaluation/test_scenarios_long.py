"""Scenarios of any length: ``build_scenario(name, seed, scans=N)`` and the duration helpers."""

from __future__ import annotations

import numpy as np
import pytest

from mapassoc.errors import InputError
from mapassoc.evaluation import scenarios
from mapassoc.evaluation.scenarios import (
    build_scenario,
    lengthenable_scenarios,
    native_scan_count,
    scan_plan_regular,
    scans_for_duration,
    scenario_names,
    scenario_scan_period,
    truncate_scenario,
)
from mapassoc.evaluation.simulate import Scenario

REQUIRED = ("crossing", "dense", "two_sensors")


def alive_per_time(scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """Distinct truth times and the number of targets alive at each."""
    return np.unique(scenario.truth.times, return_counts=True)


def native_mean_alive(name: str) -> float:
    return float(np.mean(alive_per_time(build_scenario(name, 0))[1]))


def test_native_scan_count_is_the_length_of_the_native_scenario() -> None:
    for name in scenario_names():
        assert native_scan_count(name) == len(build_scenario(name, 0).scans), name
    assert native_scan_count("crossing") == 60
    assert native_scan_count("two_sensors") == 120  # 60 scans of each sensor


@pytest.mark.parametrize("name", ["crossing", "two_sensors", "burst"])
def test_scans_equal_to_the_native_length_give_the_native_scenario(name: str) -> None:
    native = build_scenario(name, 1)
    same = build_scenario(name, 1, scans=native_scan_count(name))
    assert len(same.scans) == len(native.scans)
    for a, b in zip(native.scans, same.scans, strict=True):
        assert (a.time, a.sensor) == (b.time, b.sensor)
        assert np.array_equal(a.detections, b.detections) and np.array_equal(a.rows, b.rows)
    assert np.array_equal(native.truth.states, same.truth.states)
    assert np.array_equal(native.origins.target_ids, same.origins.target_ids)


def test_fewer_scans_are_the_start_of_the_native_scenario() -> None:
    short = build_scenario("dense", 0, scans=17)
    expected = truncate_scenario(build_scenario("dense", 0), 17)
    assert len(short.scans) == 17
    assert [s.time for s in short.scans] == [s.time for s in expected.scans]
    assert all(
        np.array_equal(a.detections, b.detections)
        for a, b in zip(short.scans, expected.scans, strict=True)
    )
    assert np.array_equal(short.truth.states, expected.truth.states)


@pytest.mark.parametrize("bad", [0, -3, 2.5, True, "100"])
def test_scans_must_be_an_integer_of_at_least_one(bad: object) -> None:
    with pytest.raises(InputError, match=rf"scans must be an integer >= 1, got {bad!r}"):
        build_scenario("crossing", 0, scans=bad)  # type: ignore[arg-type]


def test_every_built_in_scenario_can_be_lengthened() -> None:
    assert set(REQUIRED) <= set(lengthenable_scenarios())
    assert lengthenable_scenarios() == scenario_names()
    for name in scenario_names():
        scenario = build_scenario(name, 0, scans=native_scan_count(name) + 7)
        assert len(scenario.scans) == native_scan_count(name) + 7, name
        assert scenario.name == name


def test_a_scenario_without_a_geometry_names_itself_and_the_ones_that_can(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setitem(
        scenarios.SCENARIOS,
        "mine",
        lambda seed: truncate_scenario(build_scenario("crossing", seed), 10),
    )
    assert len(build_scenario("mine", 0, scans=4).scans) == 4  # shorter still works
    message = (
        r"scenario 'mine' cannot be lengthened beyond its 10 scans \(scans=11\); "
        r"scenarios that can: crossing, dense"
    )
    with pytest.raises(InputError, match=message):
        build_scenario("mine", 0, scans=11)
    with pytest.raises(InputError, match=r"scenario 'mine' has no fixed geometry"):
        scenario_scan_period("mine")


@pytest.mark.parametrize("name", REQUIRED)
def test_a_long_run_keeps_a_steady_population_inside_the_region(name: str) -> None:
    scans = 3000
    scenario = build_scenario(name, 0, scans=scans)
    assert len(scenario.scans) == scans
    times, alive = alive_per_time(scenario)
    # Someone is alive throughout: no stretch of more than 5 time units without a target.
    assert times[0] == 0.0 and np.max(np.diff(times)) <= 5.0
    assert times[-1] >= scenario.scans[-1].time - 5.0
    # The average number alive stays near the native average in every sixth of the run.
    target = native_mean_alive(name)
    for part in np.array_split(alive, 6):
        assert 0.7 * target <= part.mean() <= 1.4 * target, (name, part.mean(), target)
    # Births and deaths all through the run, not only at its ends.
    ids = scenario.truth.target_ids
    first = {i: t for t, i in zip(scenario.truth.times[::-1], ids[::-1], strict=True)}
    last = {i: t for t, i in zip(scenario.truth.times, ids, strict=True)}
    end = scenario.scans[-1].time
    assert sum(1 for t in first.values() if 0.75 * end < t) >= 5
    assert sum(1 for t in last.values() if t < 0.25 * end) >= 5
    # Targets stay in the position sensor's region (noise may take a few records out).
    region = scenario.config.sensors["pos"].region
    inside = region.contains(scenario.truth.states[:, :2])
    assert inside.mean() > 0.995


def test_long_crossing_targets_still_cross_in_pairs() -> None:
    scenario = build_scenario("crossing", 0, scans=2000)
    truth = scenario.truth
    close: set[int] = set()
    _, starts = np.unique(truth.times, return_index=True)  # truth is sorted by time
    for at in np.split(np.arange(truth.size), starts[1:]):
        if len(at) < 2:
            continue
        positions = truth.states[at, :2]
        gaps = np.linalg.norm(positions[:, None] - positions[None], axis=-1)
        np.fill_diagonal(gaps, np.inf)
        close.update(truth.target_ids[at][np.min(gaps, axis=1) < 5.0].tolist())
    ids = np.unique(truth.target_ids)
    # Every target is born in a crossing pair; those cut by the ends of the run may miss
    # their crossing, and a few meet their partner more than 5 units apart after drift.
    assert len(close) >= 0.8 * len(ids)


def test_two_sensors_long_run_alternates_its_sensors_half_a_unit_apart() -> None:
    scenario = build_scenario("two_sensors", 2, scans=301)
    assert len(scenario.scans) == 301
    assert [s.sensor for s in scenario.scans[:4]] == ["pos", "radar", "pos", "radar"]
    assert np.allclose(np.diff([s.time for s in scenario.scans]), 0.5)
    assert scenario.scans[-1].sensor == "pos" and scenario.scans[-1].time == 150.0
    assert sum(s.size for s in scenario.scans if s.sensor == "radar") > 0


def test_long_parallel_keeps_five_abreast_and_long_burst_bursts_every_40_scans() -> None:
    parallel = build_scenario("parallel", 0, scans=400)
    _, alive = alive_per_time(parallel)
    assert np.all(alive == 5)
    burst = build_scenario("burst", 0, scans=130)
    big = [i for i, scan in enumerate(burst.scans) if scan.size > 1000]
    assert big == [20, 60, 100]


def test_a_longer_run_extends_a_shorter_one_and_the_layout_does_not_depend_on_the_seed() -> None:
    short = build_scenario("crossing", 3, scans=300)
    long = build_scenario("crossing", 3, scans=700)
    keep = long.truth.times <= short.scans[-1].time
    assert np.array_equal(short.truth.target_ids, long.truth.target_ids[keep])
    assert np.array_equal(short.truth.states, long.truth.states[keep])
    other = build_scenario("crossing", 4, scans=300)
    assert np.array_equal(short.truth.target_ids, other.truth.target_ids)
    assert np.array_equal(short.truth.times, other.truth.times)
    assert not np.array_equal(short.truth.states, other.truth.states)


def test_scan_periods_match_the_native_scan_times() -> None:
    for name in scenario_names():
        times = [scan.time for scan in build_scenario(name, 0).scans]
        assert np.allclose(np.diff(times), scenario_scan_period(name)), name
    assert scenario_scan_period("crossing") == 1.0
    assert scenario_scan_period("two_sensors") == 0.5


def test_scans_for_duration() -> None:
    assert scans_for_duration("crossing", 60) == 60
    assert scans_for_duration("crossing", 60.000000001) == 60
    assert scans_for_duration("crossing", 60.5) == 61
    assert scans_for_duration("crossing", 0.2) == 1
    assert scans_for_duration("two_sensors", 60.0) == 120
    scenario = build_scenario("two_sensors", 0, scans=scans_for_duration("two_sensors", 100))
    assert len(scenario.scans) * scenario_scan_period("two_sensors") == 100.0


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), "10", True])
def test_scans_for_duration_rejects_a_bad_duration(bad: object) -> None:
    with pytest.raises(InputError, match=r"duration must be a positive finite number, got"):
        scans_for_duration("crossing", bad)  # type: ignore[arg-type]


def test_max_tracks_for_counts_the_most_targets_alive_at_one_time() -> None:
    native = build_scenario("crossing", 0)
    assert native.config.estimator.max_tracks == 10  # 4 alive at once: ceil(2.5 * 4)
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 3)
    with pytest.raises(InputError, match="plan must contain at least one scan"):
        scenarios.max_tracks_for([], [])
    assert scenarios.max_tracks_for([], plan) == 8


def test_a_10000_scan_recording_builds() -> None:
    """(How fast is measured by `mapassoc bench-reprocess`, not asserted here: a timed
    test depends on the machine.)"""
    scenario = build_scenario("crossing", 0, scans=10_000)
    assert len(scenario.scans) == 10_000
    assert scenario.detection_count > 60_000
    _, alive = alive_per_time(scenario)
    assert 2.5 <= alive[-2000:].mean() <= 4.5
