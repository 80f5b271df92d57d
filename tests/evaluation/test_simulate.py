"""Tests of the simulator, the built-in scenarios and the oracle tracker."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2, kstest

from mapassoc.data.config import Config, config_to_toml, load_config
from mapassoc.data.io import Origins, read_detections, read_origins, read_truth
from mapassoc.data.scans import Scan, check_scan_order
from mapassoc.data.settings import BirthModel, EstimatorSettings
from mapassoc.errors import InputError, NotPositiveDefiniteError
from mapassoc.evaluation.manoeuvres import MANOEUVRE_FAMILIES
from mapassoc.evaluation.oracle import oracle_tracks, true_associations
from mapassoc.evaluation.scenarios import (
    DEFAULT_SCENARIO,
    build_scenario,
    describe_scenario,
    scenario_names,
)
from mapassoc.evaluation.simulate import (
    Scenario,
    TargetSpec,
    gaussian_factor,
    scan_plan_regular,
    simulate,
    write_scenario,
)
from mapassoc.models.measurement import LinearMeasurement, RangeBearing
from mapassoc.models.motion import ConstantVelocity, CoordinatedTurn, MotionModel, RandomWalk
from mapassoc.models.sensor import Region, Sensor

# --------------------------------------------------------------------------- helpers


def _position_sensor(
    motion: MotionModel,
    *,
    name: str = "pos",
    pd: float = 0.9,
    false_alarms: float = 0.0,
    half_width: float = 100.0,
    std: float = 1.0,
) -> Sensor:
    dim = len(motion.position_indices)
    return Sensor(
        name=name,
        measurement=LinearMeasurement.position(motion, noise_std=std),
        detection_probability=pd,
        false_alarms_per_scan=false_alarms,
        region=Region.from_bounds([[-half_width, half_width]] * dim),
    )


def _config(motion: MotionModel, sensors: list[Sensor], birth: BirthModel | None = None) -> Config:
    return Config(
        motion=motion,
        sensors={s.name: s for s in sensors},
        birth=birth or BirthModel(),
        estimator=EstimatorSettings(),
    )


def _cv_target(x: float, y: float, vx: float, vy: float, birth=0.0, death=math.inf) -> TargetSpec:
    return TargetSpec(initial_state=np.array([x, y, vx, vy]), birth_time=birth, death_time=death)


def _truth_lookup(scenario: Scenario) -> dict[tuple[int, float], np.ndarray]:
    t = scenario.truth
    return {
        (int(i), float(time)): state
        for i, time, state in zip(t.target_ids, t.times, t.states, strict=True)
    }


def _origin_map(scenario: Scenario) -> dict[int, int]:
    o = scenario.origins
    return dict(zip(o.rows.tolist(), o.target_ids.tolist(), strict=True))


def _assert_same_scenario(a: Scenario, b: Scenario) -> None:
    assert len(a.scans) == len(b.scans)
    for sa, sb in zip(a.scans, b.scans, strict=True):
        assert (sa.time, sa.sensor) == (sb.time, sb.sensor)
        np.testing.assert_array_equal(sa.detections, sb.detections)
        np.testing.assert_array_equal(sa.rows, sb.rows)
    np.testing.assert_array_equal(a.truth.target_ids, b.truth.target_ids)
    np.testing.assert_array_equal(a.truth.times, b.truth.times)
    np.testing.assert_array_equal(a.truth.states, b.truth.states)
    assert a.truth.state_names == b.truth.state_names
    np.testing.assert_array_equal(a.origins.rows, b.origins.rows)
    np.testing.assert_array_equal(a.origins.target_ids, b.origins.target_ids)


def _position_rmse(scenario: Scenario, tracks) -> float:
    truth = _truth_lookup(scenario)
    errors = [
        np.sum((state[:2] - truth[(int(i), float(t))][:2]) ** 2)
        for i, t, state in zip(tracks.track_ids, tracks.times, tracks.states, strict=True)
    ]
    return float(np.sqrt(np.mean(errors)))


@pytest.fixture(scope="module")
def long_run() -> Scenario:
    """5 nearly static targets near the centre, Pd 0.7, 3 false alarms/scan, 2000 scans."""
    motion = RandomWalk(ndim=2, noise_intensity=1e-4)
    sensor = _position_sensor(motion, pd=0.7, false_alarms=3.0)
    targets = [
        TargetSpec(initial_state=np.array([x, y]), birth_time=0.0, death_time=math.inf)
        for x, y in [(-20.0, 0.0), (20.0, 0.0), (0.0, 20.0), (0.0, -20.0), (0.0, 0.0)]
    ]
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 2000)
    return simulate(_config(motion, [sensor]), targets, plan, seed=11)


# --------------------------------------------------------------------------- determinism


def test_same_seed_reproduces_and_different_seed_differs() -> None:
    a = build_scenario("crossing", seed=3)
    b = build_scenario("crossing", seed=3)
    _assert_same_scenario(a, b)
    c = build_scenario("crossing", seed=4)
    assert not np.array_equal(a.truth.states, c.truth.states)
    assert [s.size for s in a.scans] != [s.size for s in c.scans]


def test_target_truth_does_not_depend_on_other_targets() -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=0.01)
    config = _config(motion, [_position_sensor(motion, false_alarms=2.0)])
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 20)
    first = _cv_target(-10.0, 0.0, 1.0, 0.0)
    alone = simulate(config, [first], plan, seed=5)
    together = simulate(config, [first, _cv_target(10.0, 0.0, -1.0, 0.0)], plan, seed=5)
    mask = together.truth.target_ids == 1
    np.testing.assert_array_equal(alone.truth.states, together.truth.states[mask])


# --------------------------------------------------------------------------- detections


def test_every_target_detection_matches_its_origin() -> None:
    scenario = build_scenario("two_sensors", seed=2)
    truth = _truth_lookup(scenario)
    origin = _origin_map(scenario)
    all_rows = np.concatenate([s.rows for s in scenario.scans])
    np.testing.assert_array_equal(np.sort(all_rows), scenario.origins.rows)
    threshold = chi2.ppf(1.0 - 1e-9, 2)
    checked = 0
    for scan in scenario.scans:
        model = scenario.config.sensors[scan.sensor].measurement
        R_inv = np.linalg.inv(model.noise_covariance)
        for z, row in zip(scan.detections, scan.rows, strict=True):
            target = origin[int(row)]
            if target < 0:
                continue
            nu = model.residual(z, model.predict(truth[(target, scan.time)]))
            assert nu @ R_inv @ nu < threshold
            checked += 1
    assert checked > 300


def test_detection_rate_and_false_alarm_counts(long_run: Scenario) -> None:
    ids = long_run.origins.target_ids
    n_scans, n_targets, pd, lam = 2000, 5, 0.7, 3.0
    detected = int(np.sum(ids > 0))
    expected = n_targets * n_scans * pd
    assert abs(detected - expected) < 4.0 * math.sqrt(n_targets * n_scans * pd * (1 - pd))
    per_target = np.bincount(ids[ids > 0], minlength=n_targets + 1)[1:]
    assert np.all(np.abs(per_target - n_scans * pd) < 4.0 * math.sqrt(n_scans * pd * (1 - pd)))
    origin = _origin_map(long_run)
    clutter_counts = np.array(
        [sum(origin[int(r)] < 0 for r in scan.rows) for scan in long_run.scans]
    )
    assert abs(clutter_counts.mean() - lam) < 4.0 * math.sqrt(lam / n_scans)
    # Poisson: variance equals the mean (std of the sample variance ~ sqrt((lam + 2 lam^2)/n)).
    assert abs(clutter_counts.var(ddof=1) - lam) < 4.0 * math.sqrt((lam + 2 * lam**2) / n_scans)


def test_measurement_noise_and_clutter_distribution(long_run: Scenario) -> None:
    truth = _truth_lookup(long_run)
    origin = _origin_map(long_run)
    residuals, clutter = [], []
    for scan in long_run.scans:
        for z, row in zip(scan.detections, scan.rows, strict=True):
            target = origin[int(row)]
            if target < 0:
                clutter.append(z)
            else:
                residuals.append(z - truth[(target, scan.time)])
    residuals = np.array(residuals)
    np.testing.assert_allclose(residuals.mean(axis=0), 0.0, atol=4.0 / math.sqrt(len(residuals)))
    np.testing.assert_allclose(np.cov(residuals.T), np.eye(2), atol=0.05)
    clutter = np.array(clutter)
    for axis in range(2):
        assert kstest(clutter[:, axis], "uniform", args=(-100.0, 200.0)).pvalue > 1e-4


def test_detections_are_shuffled_within_scans(long_run: Scenario) -> None:
    origin = _origin_map(long_run)
    positions = {
        index
        for scan in long_run.scans[:200]
        for index, row in enumerate(scan.rows)
        if origin[int(row)] == 1
    }
    assert len(positions) > 3


def test_detections_stay_inside_the_region_and_targets_outside_are_missed() -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=1e-4)
    sensor = _position_sensor(motion, pd=1.0, false_alarms=5.0, half_width=50.0)
    leaving = _cv_target(0.0, 0.0, 5.0, 0.0)  # crosses x = 50 at t = 10, at 100 by t = 20
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 30)
    scenario = simulate(_config(motion, [sensor]), [leaving], plan, seed=1)
    for scan in scenario.scans:
        assert np.all(sensor.region.contains(scan.detections))
    origin = _origin_map(scenario)
    detected_times = [
        scan.time for scan in scenario.scans for r in scan.rows if origin[int(r)] == 1
    ]
    assert min(detected_times) == 0.0
    assert max(detected_times) < 15.0
    assert len(detected_times) >= 9


def test_bearing_is_wrapped_across_the_cut() -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=1e-4)
    radar = Sensor(
        name="radar",
        measurement=RangeBearing(sensor_position=[50.0, 0.0], range_std=1.0, bearing_std=0.05),
        detection_probability=1.0,
        false_alarms_per_scan=0.0,
        region=Region.from_bounds([[0.0, 300.0], [-math.pi, math.pi]]),
    )
    plan = scan_plan_regular(["radar"], 0.0, 1.0, 200)
    scenario = simulate(_config(motion, [radar]), [_cv_target(-50.0, 0.0, 0.0, 0.0)], plan, seed=0)
    bearings = np.concatenate([s.detections[:, 1] for s in scenario.scans])
    assert len(bearings) == 200
    assert np.all((bearings > -math.pi) & (bearings <= math.pi))
    assert np.any(bearings > 3.0) and np.any(bearings < -3.0)


# --------------------------------------------------------------------------- motion noise


def test_process_noise_increments_have_covariance_q() -> None:
    q, dt = 0.5, 0.5
    motion = ConstantVelocity(ndim=2, noise_intensity=q)
    sensor = _position_sensor(motion, pd=1.0, half_width=1e6)
    targets = [_cv_target(0.0, 0.0, 0.0, 0.0) for _ in range(5)]
    plan = scan_plan_regular(["pos"], 0.0, dt, 2000)
    scenario = simulate(_config(motion, [sensor]), targets, plan, seed=7)
    F = motion.transition_matrix(dt)
    increments = []
    for target in range(1, 6):
        states = scenario.truth.states[scenario.truth.target_ids == target]
        increments.append(states[1:] - states[:-1] @ F.T)
    sample = np.cov(np.concatenate(increments).T)
    Q = motion.process_noise(dt)
    scale = np.sqrt(np.outer(np.diag(Q), np.diag(Q)))
    assert np.all(np.abs(sample - Q) < 0.06 * scale)


def test_coordinated_turn_noise_is_sampled_in_the_range_of_singular_q() -> None:
    motion = CoordinatedTurn(speed_noise_intensity=0.01, turn_rate_noise_intensity=1e-4)
    sensor = _position_sensor(motion, pd=1.0, half_width=1e6)
    target = TargetSpec(
        initial_state=np.array([0.0, 0.0, 2.0, 0.3, 0.01]), birth_time=0.0, death_time=math.inf
    )
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 3000)
    scenario = simulate(_config(motion, [sensor]), [target], plan, seed=9)
    states = scenario.truth.states
    increments = states[1:] - motion.transition(states[:-1], 1.0)
    # Q has no position part: positions follow f exactly.
    np.testing.assert_allclose(increments[:, :2], 0.0, atol=1e-9)
    sample = np.cov(increments[:, 2:].T)
    Q = motion.process_noise(1.0)[2:, 2:]
    scale = np.sqrt(np.outer(np.diag(Q), np.diag(Q)))
    assert np.all(np.abs(sample - Q) < 0.1 * scale)


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.floats(-3.0, 3.0), min_size=9, max_size=9),
    st.integers(1, 3),
)
def test_gaussian_factor_reproduces_psd_matrices(entries: list[float], rank: int) -> None:
    B = np.array(entries).reshape(3, 3)[:, :rank]
    C = B @ B.T  # rank-deficient when rank < 3
    A = gaussian_factor(C)
    np.testing.assert_allclose(A @ A.T, C, atol=1e-9 * max(1.0, np.abs(C).max()))


def test_gaussian_factor_refuses_indefinite_and_asymmetric() -> None:
    with pytest.raises(NotPositiveDefiniteError, match="eigenvalues"):
        gaussian_factor(np.diag([1.0, -0.1]))
    with pytest.raises(NotPositiveDefiniteError, match="symmetric"):
        gaussian_factor(np.array([[1.0, 0.5], [0.0, 1.0]]))


# --------------------------------------------------------------------------- plan and truth


def test_scan_plan_regular_golden() -> None:
    assert scan_plan_regular(["b", "a"], 0.0, 1.0, 2, offsets=[0.0, 0.5]) == [
        (0.0, "b"),
        (0.5, "a"),
        (1.0, "b"),
        (1.5, "a"),
    ]
    assert scan_plan_regular(["b", "a"], 10.0, 2.0, 2) == [
        (10.0, "a"),
        (10.0, "b"),
        (12.0, "a"),
        (12.0, "b"),
    ]
    with pytest.raises(InputError, match="interval"):
        scan_plan_regular(["a"], 0.0, 0.0, 3)
    with pytest.raises(InputError, match="offsets"):
        scan_plan_regular(["a", "b"], 0.0, 1.0, 3, offsets=[0.0])


def test_shared_scan_times_give_one_truth_row_and_lives_are_respected() -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=0.01)
    sensors = [_position_sensor(motion, name=n, false_alarms=1.0) for n in ("a", "b")]
    targets = [_cv_target(0.0, 0.0, 1.0, 0.0, birth=2.0, death=6.0), _cv_target(5.0, 5.0, 0, 1)]
    plan = scan_plan_regular(["a", "b"], 0.0, 1.0, 10)
    scenario = simulate(_config(motion, sensors), targets, plan, seed=0)
    check_scan_order(scenario.scans)
    assert len(scenario.scans) == 20
    t = scenario.truth
    assert t.size == 5 + 10
    np.testing.assert_array_equal(t.times[t.target_ids == 1], [2.0, 3.0, 4.0, 5.0, 6.0])
    np.testing.assert_array_equal(t.states[(t.target_ids == 1)][0], [0.0, 0.0, 1.0, 0.0])
    origin = _origin_map(scenario)
    for scan in scenario.scans:
        for row in scan.rows:
            if origin[int(row)] == 1:
                assert 2.0 <= scan.time <= 6.0


def test_simulate_validates_its_arguments() -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=0.01)
    config = _config(motion, [_position_sensor(motion)])
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 3)
    good = [_cv_target(0.0, 0.0, 1.0, 0.0)]
    with pytest.raises(InputError, match=r"initial_state must have shape \(4,\)"):
        simulate(config, [TargetSpec(np.zeros(2), 0.0, 1.0)], plan, seed=0)
    with pytest.raises(InputError, match="sorted by time"):
        simulate(config, good, [(1.0, "pos"), (0.0, "pos")], seed=0)
    with pytest.raises(InputError, match="'radar'"):
        simulate(config, good, [(0.0, "radar")], seed=0)
    with pytest.raises(InputError, match="twice"):
        simulate(config, good, [(0.0, "pos"), (0.0, "pos")], seed=0)
    with pytest.raises(InputError, match="seed"):
        simulate(config, good, plan, seed=-1)
    with pytest.raises(InputError, match="death_time"):
        TargetSpec(np.zeros(4), 5.0, 4.0)


# --------------------------------------------------------------------------- files


def _assert_round_trip(scenario: Scenario, out_dir) -> None:
    paths = write_scenario(scenario, out_dir)
    assert sorted(p.name for p in paths.values()) == [
        "config.toml",
        "detections.csv",
        "origins.csv",
        "truth.csv",
    ]
    config = load_config(paths["config"])
    assert config_to_toml(config) == config_to_toml(scenario.config)
    scans = read_detections(paths["detections"], config.sensors)
    back = Scenario(
        name=scenario.name,
        config=config,
        scans=scans,
        truth=read_truth(paths["truth"]),
        origins=read_origins(paths["origins"]),
    )
    _assert_same_scenario(scenario, back)


def test_write_scenario_round_trips_two_sensors(tmp_path) -> None:
    _assert_round_trip(build_scenario("two_sensors", seed=1), tmp_path / "new" / "dir")


def test_write_scenario_round_trips_empty_scans_and_overwrites(tmp_path) -> None:
    motion = CoordinatedTurn(speed_noise_intensity=0.01, turn_rate_noise_intensity=1e-4)
    # Almost no clutter (a configuration file needs a rate > 0), so that scans are empty.
    sensor = _position_sensor(motion, pd=0.3, false_alarms=1e-9)
    target = TargetSpec(np.array([0.0, 0.0, 1.0, 0.0, 0.05]), 0.0, math.inf)
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 30)
    sparse = simulate(_config(motion, [sensor]), [target], plan, seed=4)
    assert any(scan.size == 0 for scan in sparse.scans)
    _assert_round_trip(build_scenario("crossing", seed=0), tmp_path)
    _assert_round_trip(sparse, tmp_path)  # same directory: every file overwritten


# --------------------------------------------------------------------------- scenarios


def test_scenario_registry() -> None:
    names = scenario_names()
    assert names[0] == DEFAULT_SCENARIO == "crossing"
    assert {"crossing", "dense", "dense50", "turning", "two_sensors"} <= set(names)
    for name in names:
        assert describe_scenario(name) and "\n" not in describe_scenario(name)
    with pytest.raises(InputError, match="crossing"):
        build_scenario("nope")


@pytest.mark.parametrize("name", scenario_names())
def test_every_named_scenario_builds_consistently(name: str) -> None:
    scenario = build_scenario(name, seed=0)
    assert scenario.name == name
    check_scan_order(scenario.scans)
    truth = scenario.truth
    ids = sorted(set(truth.target_ids.tolist()))
    assert ids == list(range(1, len(ids) + 1))
    most_alive = max(np.bincount(np.unique(truth.times, return_inverse=True)[1]))
    assert most_alive <= scenario.config.estimator.max_tracks <= max(8, 3 * most_alive)
    birth = scenario.config.birth
    assert birth.rate >= 0.01
    assert 0.9 < birth.survival_probability < 1.0
    if "speed" in truth.state_names:
        speeds = truth.states[:, truth.state_names.index("speed")]
    else:
        speeds = np.hypot(truth.states[:, 2], truth.states[:, 3])
    # Noise-std units per scan, or a manoeuvring family's own range in m/s.
    family = MANOEUVRE_FAMILIES.get(name)
    low, high = (0.5, 4.0) if family is None else family.speeds
    assert low < speeds.min() and speeds.max() < high
    assert birth.velocity_std >= speeds.max()
    for sensor in scenario.config.sensors.values():
        for scan in scenario.scans:
            if scan.sensor == sensor.name:
                assert np.all(sensor.region.contains(scan.detections))
    inside = scenario.config.sensors["pos"].region.contains(truth.states[:, :2])
    assert inside.all()


def test_births_and_deaths_happen_inside_the_crossing_run() -> None:
    scenario = build_scenario("crossing", seed=0)
    t = scenario.truth
    first = {i: t.times[t.target_ids == i].min() for i in range(1, 5)}
    last = {i: t.times[t.target_ids == i].max() for i in range(1, 5)}
    assert sorted(first.values()) == [0.0, 3.0, 6.0, 12.0]
    assert sorted(last.values()) == [45.0, 59.0, 59.0, 59.0]
    assert len(scenario.scans) == 60
    sensor = scenario.config.sensors["pos"]
    assert (sensor.detection_probability, sensor.false_alarms_per_scan) == (0.9, 10.0)


def test_dense50_has_the_density_of_dense() -> None:
    dense = build_scenario("dense", seed=0)
    dense50 = build_scenario("dense50", seed=0)
    small, large = dense.config.sensors["pos"], dense50.config.sensors["pos"]
    assert large.region.volume == pytest.approx(5.0 * small.region.volume)
    assert large.clutter_density == pytest.approx(small.clutter_density)
    n_small = len(set(dense.truth.target_ids.tolist()))
    n_large = len(set(dense50.truth.target_ids.tolist()))
    assert (n_small, n_large) == (10, 50)
    assert (small.false_alarms_per_scan, large.false_alarms_per_scan) == (50.0, 250.0)


# --------------------------------------------------------------------------- oracle


def _one_d_config(*names: str) -> Config:
    motion = RandomWalk(ndim=1, noise_intensity=1.0)
    sensors = [
        Sensor(
            name=n,
            measurement=LinearMeasurement.position(motion, noise_std=1.0),
            detection_probability=0.9,
            false_alarms_per_scan=1.0,
            region=Region.from_bounds([[-10.0, 10.0]]),
        )
        for n in names
    ]
    return _config(motion, sensors)


def _scan(time: float, sensor: str, values: list[float], rows: list[int]) -> Scan:
    return Scan(
        time=time,
        sensor=sensor,
        detections=np.array(values, dtype=float).reshape(-1, 1),
        rows=np.array(rows, dtype=np.int64),
    )


def test_oracle_golden_random_walk_chain_with_a_miss() -> None:
    # x0 -- x1 -- x2 with unit-variance steps, z0 = 0 on x0 and z2 = 4 on x2 (unit noise):
    # a Gaussian chain z0 - x0 - x1 - x2 - z2 of four unit links, so the smoothed means
    # interpolate linearly (1, 2, 3) and the variances are a (4 - a) / 4 = (3/4, 1, 3/4).
    config = _one_d_config("a")
    scans = [
        _scan(0.0, "a", [0.0, 7.0], [2, 3]),
        _scan(1.0, "a", [-5.0], [4]),
        _scan(2.0, "a", [4.0], [5]),
    ]
    origins = Origins(rows=np.array([2, 3, 4, 5]), target_ids=np.array([0, -1, -1, 0]))
    tracks = oracle_tracks(scans, origins, config)
    np.testing.assert_array_equal(tracks.track_ids, [0, 0, 0])
    np.testing.assert_allclose(tracks.states[:, 0], [1.0, 2.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(tracks.variances[:, 0], [0.75, 1.0, 0.75], atol=1e-12)
    np.testing.assert_array_equal(tracks.detection_rows, [2, -1, 5])


def test_true_associations_are_each_targets_scan_and_detection_indices() -> None:
    # Rows 2..6 over three scans: target 0 at (scan 0, index 0) and (scan 2, index 1),
    # target 7 at (scan 1, index 0) only, rows 3 and 5 false alarms.
    scans = [
        _scan(0.0, "a", [0.0, 7.0], [2, 3]),
        _scan(1.0, "a", [-5.0], [4]),
        _scan(2.0, "a", [9.0, 4.0], [5, 6]),
    ]
    origins = Origins(rows=np.array([2, 3, 4, 5, 6]), target_ids=np.array([0, -1, 7, -1, 0]))
    assert true_associations(scans, origins) == {0: {0: 0, 2: 1}, 7: {1: 0}}
    with pytest.raises(InputError, match="true_associations: origins"):
        true_associations(scans, "origins.csv")  # type: ignore[arg-type]


def test_oracle_golden_same_time_detections_skip_the_prediction() -> None:
    # Two sensors at t = 0 (no motion between): posterior of z = 0 and z = 2 with unit
    # noise is N(1, 1/2), at both rows.  Target 3 is detected once: its birth state.
    config = _one_d_config("a", "b")
    scans = [_scan(0.0, "a", [0.0, 9.0], [2, 3]), _scan(0.0, "b", [2.0], [4])]
    origins = Origins(rows=np.array([2, 3, 4]), target_ids=np.array([5, 3, 5]))
    tracks = oracle_tracks(scans, origins, config)
    np.testing.assert_array_equal(tracks.track_ids, [3, 5, 5])
    assert tracks.sensors == ("a", "a", "b")
    np.testing.assert_allclose(tracks.states[:, 0], [9.0, 1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(tracks.variances[:, 0], [1.0, 0.5, 0.5], atol=1e-12)
    np.testing.assert_array_equal(tracks.detection_rows, [3, 2, 4])


def test_oracle_beats_the_measurement_noise_on_clean_linear_data() -> None:
    motion = ConstantVelocity(ndim=2, noise_intensity=0.01)
    sensor = _position_sensor(motion, pd=1.0, false_alarms=0.0)
    targets = [
        _cv_target(-50.0, -50.0, 2.0, 1.0),
        _cv_target(50.0, -50.0, -1.0, 2.0, birth=5.0),
        _cv_target(0.0, 60.0, 0.5, -2.0, death=30.0),
    ]
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 40)
    scenario = simulate(_config(motion, [sensor]), targets, plan, seed=3)
    tracks = oracle_tracks(scenario.scans, scenario.origins, scenario.config)
    assert sorted(set(tracks.track_ids.tolist())) == [1, 2, 3]
    assert tracks.size == scenario.truth.size  # Pd = 1: every alive scan is a row
    assert np.all(tracks.detection_rows >= 2)
    origin = _origin_map(scenario)
    for i, row in zip(tracks.track_ids, tracks.detection_rows, strict=True):
        assert origin[int(row)] == i
    order = np.lexsort((tracks.track_ids, tracks.times))
    np.testing.assert_array_equal(order, np.arange(tracks.size))
    rmse = _position_rmse(scenario, tracks)
    raw = math.sqrt(2.0)  # RMS of the 2-D measurement error with unit std per axis
    assert rmse < 1.0 < raw


def test_oracle_on_two_sensors_rows_span_every_scan() -> None:
    scenario = build_scenario("two_sensors", seed=0)
    tracks = oracle_tracks(scenario.scans, scenario.origins, scenario.config)
    assert set(tracks.track_ids.tolist()) == set(scenario.truth.target_ids.tolist())
    scan_index = {(s.time, s.sensor): k for k, s in enumerate(scenario.scans)}
    origin = _origin_map(scenario)
    for target in set(tracks.track_ids.tolist()):
        mine = tracks.track_ids == target
        indices = sorted(
            scan_index[(t, s)]
            for t, s in zip(tracks.times[mine], np.array(tracks.sensors)[mine], strict=True)
        )
        assert indices == list(range(indices[0], indices[-1] + 1))
        used = sorted(r for r in tracks.detection_rows[mine].tolist() if r >= 0)
        assert used == sorted(r for r, o in origin.items() if o == target)
    assert _position_rmse(scenario, tracks) < 1.0


def test_oracle_coordinated_turn_smooths_through_the_conversion() -> None:
    motion = CoordinatedTurn(speed_noise_intensity=1e-3, turn_rate_noise_intensity=1e-6)
    sensor = _position_sensor(motion, pd=1.0, false_alarms=0.0, half_width=1000.0)
    rng = np.random.default_rng(0)
    targets = [
        TargetSpec(
            np.array(
                [
                    *rng.uniform(-500, 500, 2),
                    rng.uniform(1, 3),
                    rng.uniform(-3, 3),
                    rng.uniform(-0.05, 0.05),
                ]
            ),
            0.0,
            math.inf,
        )
        for _ in range(40)
    ]
    plan = scan_plan_regular(["pos"], 0.0, 1.0, 15)
    birth = BirthModel(velocity_std=3.0, speed_std=3.0, turn_rate_std=0.1)
    scenario = simulate(_config(motion, [sensor], birth), targets, plan, seed=1)
    tracks = oracle_tracks(scenario.scans, scenario.origins, scenario.config)
    assert tracks.state_names == motion.state_names
    assert _position_rmse(scenario, tracks) < 1.0
    truth = _truth_lookup(scenario)
    first = tracks.times == 0.0  # before the conversion: smoothed back through it
    true_first = np.array([truth[(int(i), 0.0)] for i in tracks.track_ids[first]])
    speed_error = np.abs(tracks.states[first, 2] - true_first[:, 2])
    assert np.mean(speed_error) < 0.2  # the filtered birth state had speed 0
    heading_error = np.abs(np.angle(np.exp(1j * (tracks.states[first, 3] - true_first[:, 3]))))
    assert np.mean(heading_error) < 0.2
    # Canonical turn states: speed >= 0, heading in (-pi, pi].
    assert np.all(tracks.states[:, 2] >= 0.0)
    assert np.all((tracks.states[:, 3] > -math.pi) & (tracks.states[:, 3] <= math.pi))
    detections = np.array(
        [
            scenario.scans[0].detections[list(scenario.scans[0].rows).index(r)]
            for r in tracks.detection_rows[first]
        ]
    )
    raw = np.sqrt(np.mean(np.sum((detections - true_first[:, :2]) ** 2, axis=1)))
    smoothed = np.sqrt(np.mean(np.sum((tracks.states[first, :2] - true_first[:, :2]) ** 2, axis=1)))
    assert smoothed < raw


def test_oracle_on_turning_scenario() -> None:
    scenario = build_scenario("turning", seed=0)
    tracks = oracle_tracks(scenario.scans, scenario.origins, scenario.config)
    assert set(tracks.track_ids.tolist()) == {1, 2, 3}
    assert _position_rmse(scenario, tracks) < 1.0
    assert np.all(np.isfinite(tracks.variances))


def test_oracle_coordinated_turn_single_detection_has_uninformative_heading() -> None:
    motion = CoordinatedTurn(speed_noise_intensity=1e-3, turn_rate_noise_intensity=1e-6)
    sensor = _position_sensor(motion)
    birth = BirthModel(speed_std=2.0, turn_rate_std=0.1)
    config = _config(motion, [sensor], birth)
    scans = [
        Scan(time=0.0, sensor="pos", detections=np.array([[3.0, 4.0]]), rows=np.array([2])),
    ]
    tracks = oracle_tracks(scans, Origins(rows=np.array([2]), target_ids=np.array([1])), config)
    np.testing.assert_allclose(tracks.states[0], [3.0, 4.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(tracks.variances[0], [1.0, 1.0, 4.0, math.pi**2 / 3, 0.01])


def test_oracle_validates_origins() -> None:
    config = _one_d_config("a")
    scans = [_scan(0.0, "a", [0.0, 1.0], [2, 3])]
    with pytest.raises(InputError, match="row 3"):
        oracle_tracks(scans, Origins(rows=np.array([2]), target_ids=np.array([1])), config)
    with pytest.raises(InputError, match="two detections"):
        oracle_tracks(scans, Origins(rows=np.array([2, 3]), target_ids=np.array([1, 1])), config)
    with pytest.raises(InputError, match=r"\[9\]"):
        oracle_tracks(
            scans, Origins(rows=np.array([2, 3, 9]), target_ids=np.array([1, -1, 1])), config
        )


@pytest.mark.parametrize("scans", [10**11, 10**300], ids=["1e11", "1e300"])
def test_an_absurd_length_is_refused_before_anything_is_built(scans: int) -> None:
    """`simulate crossing --scans 100000000000` once ran with memory growing for good."""
    import tracemalloc

    from mapassoc.evaluation.scenarios import MAX_SIMULATED_DETECTIONS

    tracemalloc.start()
    try:
        with pytest.raises(InputError, match=r"would simulate about .* detections") as info:
            build_scenario("crossing", 0, scans=scans)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert info.value.key == "scans"
    assert f"{MAX_SIMULATED_DETECTIONS:,}" in str(info.value)
    assert peak < 50e6  # the native scenario only
    # The limit it names is a length that is accepted.
    limit = int(str(info.value).split("at most ")[1].split(" scans")[0].replace(",", ""))
    from mapassoc.evaluation.scenarios import _check_simulated_size

    _check_simulated_size("crossing", limit)
    with pytest.raises(InputError):
        _check_simulated_size("crossing", limit + 2)
