"""The hard scenario families, the scenario transformations and the generic configuration."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest

from mapassoc.data.scans import check_scan_order
from mapassoc.data.settings import BirthModel, EstimatorSettings
from mapassoc.errors import InputError
from mapassoc.evaluation.scenarios import (
    BURST_FALSE_ALARMS,
    BURST_SCAN,
    GENERIC_BIRTH_RATE,
    GENERIC_INITIAL_COUNT,
    PARALLEL_SPACING,
    add_false_alarms,
    build_scenario,
    burst,
    describe_scenario,
    generic_config,
    scenario_names,
    top_initial_speed,
    truncate_scenario,
)
from mapassoc.evaluation.simulate import Scenario

# name -> (targets, detection probability, false alarms per scan, region area)
HARD = {
    "parallel": (5, 0.9, 20.0, 15_000.0),
    "dense_pd08": (10, 0.8, 50.0, 10_000.0),
    "scale20": (20, 0.9, 40.0, 20_000.0),
    "scale50": (50, 0.9, 100.0, 50_000.0),
    "scale100": (100, 0.9, 200.0, 100_000.0),
    "burst": (10, 0.9, 20.0, 40_000.0),
}


@cache
def built(name: str, seed: int) -> Scenario:
    return build_scenario(name, seed)


def _assert_same(a: Scenario, b: Scenario) -> None:
    assert [(s.time, s.sensor) for s in a.scans] == [(s.time, s.sensor) for s in b.scans]
    for sa, sb in zip(a.scans, b.scans, strict=True):
        np.testing.assert_array_equal(sa.detections, sb.detections)
        np.testing.assert_array_equal(sa.rows, sb.rows)
    np.testing.assert_array_equal(a.truth.target_ids, b.truth.target_ids)
    np.testing.assert_array_equal(a.truth.times, b.truth.times)
    np.testing.assert_array_equal(a.truth.states, b.truth.states)
    np.testing.assert_array_equal(a.origins.rows, b.origins.rows)
    np.testing.assert_array_equal(a.origins.target_ids, b.origins.target_ids)


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


def _false_alarms_per_scan(scenario: Scenario) -> np.ndarray:
    origin = _origin_map(scenario)
    return np.array(
        [sum(origin[row] == -1 for row in scan.rows.tolist()) for scan in scenario.scans]
    )


def _assert_origins_consistent(scenario: Scenario) -> None:
    """Origins cover exactly the detection rows; target detections lie near their truth."""
    rows = np.concatenate([scan.rows for scan in scenario.scans])
    np.testing.assert_array_equal(np.sort(rows), scenario.origins.rows)
    truth = {
        (int(i), float(t)): state
        for i, t, state in zip(
            scenario.truth.target_ids, scenario.truth.times, scenario.truth.states, strict=True
        )
    }
    origin = _origin_map(scenario)
    for scan in scenario.scans:
        for row, z in zip(scan.rows.tolist(), scan.detections, strict=True):
            if origin[row] != -1:
                # Unit measurement noise: 6 standard deviations per component.
                assert np.all(np.abs(z - truth[(origin[row], scan.time)][:2]) < 6.0)


# --------------------------------------------------------------------------- the families


def test_hard_families_are_registered() -> None:
    names = scenario_names()
    assert set(HARD) <= set(names)
    assert names[:5] == ["crossing", "dense", "dense50", "turning", "two_sensors"]
    for name in HARD:
        assert describe_scenario(name) and "\n" not in describe_scenario(name)


@pytest.mark.parametrize("name", sorted(HARD))
def test_family_is_deterministic_and_seed_driven(name: str) -> None:
    a = built(name, 0)
    _assert_same(a, build_scenario(name, 0))
    other = built(name, 1)
    assert [s.size for s in a.scans] != [s.size for s in other.scans]
    assert not np.array_equal(a.truth.states, other.truth.states)
    # The geometry is fixed: same targets, born and dying at the same scans.
    for scenario in (a, other):
        check_scan_order(scenario.scans)
    assert _spans(a) == _spans(other)


@pytest.mark.parametrize("name", sorted(HARD))
def test_family_has_the_stated_targets_sensor_and_clutter(name: str) -> None:
    targets, pd, false_alarms, area = HARD[name]
    scans = 0
    counts = []
    for seed in (0, 1):
        scenario = built(name, seed)
        assert len(np.unique(scenario.truth.target_ids)) == targets
        sensor = scenario.config.sensors["pos"]
        assert sensor.detection_probability == pd
        assert sensor.false_alarms_per_scan == false_alarms
        assert sensor.region.volume == pytest.approx(area)
        per_scan = _false_alarms_per_scan(scenario)
        if name == "burst":
            per_scan = np.delete(per_scan, BURST_SCAN)
        counts.append(per_scan)
        scans += per_scan.size
    mean = float(np.mean(np.concatenate(counts)))
    # False alarms are Poisson(lambda) per scan, so the mean over S scans has standard
    # deviation sqrt(lambda / S); 4 of them make a false failure a 1-in-15,000 event.
    assert abs(mean - false_alarms) <= 4.0 * math.sqrt(false_alarms / scans)


def test_scale_family_has_a_fixed_density() -> None:
    for targets in (20, 50, 100):
        scenario = built(f"scale{targets}", 0)
        sensor = scenario.config.sensors["pos"]
        assert sensor.region.volume / targets == pytest.approx(1_000.0)
        assert sensor.false_alarms_per_scan / sensor.region.volume * 1_000.0 == pytest.approx(2.0)
        # Speed 1 at birth (the first truth record of each target is its initial state).
        truth = scenario.truth
        _, first = np.unique(truth.target_ids, return_index=True)
        np.testing.assert_allclose(np.hypot(*truth.states[first, 2:4].T), 1.0)


def test_scale_and_dense_families_have_births_and_deaths() -> None:
    for name in ("scale20", "scale50", "scale100", "dense_pd08"):
        truth = built(name, 0).truth
        last_time = truth.times.max()
        ids = np.unique(truth.target_ids)
        born_late = sum(truth.times[truth.target_ids == i].min() > 0 for i in ids)
        die_early = sum(truth.times[truth.target_ids == i].max() < last_time for i in ids)
        assert born_late >= 1 and die_early >= 1, name


def test_parallel_targets_are_abreast_2_5_apart() -> None:
    for seed in (0, 1):
        truth = built("parallel", seed).truth
        ids = np.unique(truth.target_ids)
        tracks = np.stack([truth.states[truth.target_ids == i] for i in ids])  # (5, T, 4)
        first = tracks[:, 0]
        # At the first scan (the targets' initial states): same x, same velocity (1, 0),
        # neighbours exactly PARALLEL_SPACING = 2.5 apart across track.
        np.testing.assert_allclose(np.diff(np.sort(first[:, 1])), PARALLEL_SPACING)
        np.testing.assert_allclose(first[:, 0], first[0, 0])
        np.testing.assert_allclose(first[:, 2:], [[1.0, 0.0]] * 5)
        # Over the run the formation keeps its order and its spacing: the neighbours'
        # across-track gap drifts by ~0.9 (std) at the end of the run, much less on average.
        gaps = np.diff(tracks[:, :, 1], axis=0)
        assert np.all(gaps > 0.0)
        assert abs(float(gaps.mean()) - PARALLEL_SPACING) < 0.5


def test_burst_scan_has_2000_more_detections_than_its_neighbours() -> None:
    for seed in (0, 1, 2):
        scenario = built("burst", seed)
        sizes = [scan.size for scan in scenario.scans]
        # Neighbours have ~20 false alarms + ~9 targets each (Poisson); the burst scan the
        # same plus exactly 2000, so the difference is 2000 +- the difference of two such
        # counts (std ~8): 4 std of slack below 2000.
        for neighbour in (BURST_SCAN - 1, BURST_SCAN + 1):
            assert sizes[BURST_SCAN] - sizes[neighbour] >= BURST_FALSE_ALARMS - 32
        assert sizes[BURST_SCAN] >= BURST_FALSE_ALARMS
        assert max(np.delete(sizes, BURST_SCAN)) < 100
        # Exactly 2000 more than the same realisation without the burst, all false alarms.
        quiet = burst(seed, extra_false_alarms=0)
        assert sizes[BURST_SCAN] == quiet.scans[BURST_SCAN].size + BURST_FALSE_ALARMS
        fa = _false_alarms_per_scan(scenario)
        assert fa[BURST_SCAN] == _false_alarms_per_scan(quiet)[BURST_SCAN] + BURST_FALSE_ALARMS
        _assert_origins_consistent(scenario)
        region = scenario.config.sensors["pos"].region
        assert np.all(region.contains(scenario.scans[BURST_SCAN].detections))


# --------------------------------------------------------------------------- transformations


def test_add_false_alarms_keeps_everything_else() -> None:
    base = built("parallel", 0)
    noisy = add_false_alarms(base, 3, 50, seed=7)
    assert noisy.truth is base.truth and noisy.config is base.config
    for index, (a, b) in enumerate(zip(base.scans, noisy.scans, strict=True)):
        assert (a.time, a.sensor) == (b.time, b.sensor)
        if index != 3:
            np.testing.assert_array_equal(a.detections, b.detections)
    assert noisy.scans[3].size == base.scans[3].size + 50
    # Rows are renumbered as the detections file numbers them: consecutive from line 2.
    rows = np.concatenate([scan.rows for scan in noisy.scans])
    np.testing.assert_array_equal(rows, np.arange(2, 2 + rows.size))
    _assert_origins_consistent(noisy)

    # Every target detection keeps its origin.
    def detections_of(scenario: Scenario) -> set[tuple[float, float, int]]:
        origin = _origin_map(scenario)
        return {
            (float(z[0]), float(z[1]), origin[row])
            for scan in scenario.scans
            for row, z in zip(scan.rows.tolist(), scan.detections, strict=True)
            if origin[row] != -1
        }

    assert detections_of(noisy) == detections_of(base)
    _assert_same(noisy, add_false_alarms(base, 3, 50, seed=7))
    assert add_false_alarms(base, 3, 0, seed=7) is base


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"scan_index": 40, "count": 1, "seed": 0}, "scan_index"),
        ({"scan_index": -1, "count": 1, "seed": 0}, "scan_index"),
        ({"scan_index": 0, "count": -5, "seed": 0}, "count"),
        ({"scan_index": 0, "count": 1, "seed": -1}, "seed"),
    ],
)
def test_add_false_alarms_rejects_bad_arguments(kwargs: dict[str, int], message: str) -> None:
    with pytest.raises(InputError, match=message):
        add_false_alarms(built("parallel", 0), **kwargs)  # type: ignore[arg-type]


def test_truncate_scenario_keeps_the_start() -> None:
    full = built("burst", 0)
    short = truncate_scenario(full, 10)
    assert len(short.scans) == 10
    assert short.truth.times.max() == full.scans[9].time
    _assert_origins_consistent(short)
    assert truncate_scenario(full, 1000) is full
    with pytest.raises(InputError, match="n_scans"):
        truncate_scenario(full, 0)


# --------------------------------------------------------------------------- generic configuration


@pytest.mark.parametrize("name", ["crossing", "turning", "two_sensors", *sorted(HARD)])
def test_generic_config(name: str) -> None:
    scenario = built(name, 0)
    config = generic_config(scenario)
    assert config.motion is scenario.config.motion
    assert config.sensors == scenario.config.sensors
    most = max(scan.size for scan in scenario.scans)
    assert config.estimator.max_tracks == 2 * most
    assert config.estimator == EstimatorSettings(max_tracks=2 * most)
    assert config.birth == BirthModel(
        rate=GENERIC_BIRTH_RATE,
        initial_count=GENERIC_INITIAL_COUNT,
        velocity_std=top_initial_speed(scenario),
    )
    bench = generic_config(scenario, window_length=7, time_limit=0.5)
    assert (bench.estimator.window_length, bench.estimator.time_limit) == (7, 0.5)
    assert bench.estimator.max_tracks == 2 * most


def test_generic_config_reads_the_scenario() -> None:
    burst_config = generic_config(built("burst", 0))
    assert burst_config.estimator.max_tracks >= 2 * BURST_FALSE_ALARMS
    # A truncated scenario gets its own detection count (before the burst scan).
    short = truncate_scenario(built("burst", 0), BURST_SCAN)
    assert generic_config(short).estimator.max_tracks < 200
    assert top_initial_speed(built("parallel", 0)) == pytest.approx(1.0)
    assert top_initial_speed(built("scale50", 0)) == pytest.approx(1.0)
    crossing_speed = math.hypot(2.0, 0.6)
    assert top_initial_speed(built("crossing", 0)) == pytest.approx(crossing_speed)
