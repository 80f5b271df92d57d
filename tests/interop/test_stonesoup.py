"""Stone Soup interoperability (:mod:`mapassoc.interop.stonesoup`).

Stone Soup simulates two crossing targets in clutter with its own simulators; the
detections are converted to our scans, tracked with :class:`MapTracker` under a Config of the
same models, converted back, and scored with Stone Soup's own GOSPA metric manager, which
must agree with :func:`evaluate_tables` time by time.  Round trips pin the conversions
(ours -> Stone Soup -> ours is the identity), and hand-worked cases pin the state and
measurement orders against Stone Soup's own model functions.
"""

from __future__ import annotations

import datetime as dt
import subprocess
import sys
from dataclasses import dataclass

import numpy as np
import pytest

stonesoup = pytest.importorskip("stonesoup")

from stonesoup.measures import Euclidean  # noqa: E402
from stonesoup.metricgenerator.manager import MultiManager, SimpleManager  # noqa: E402
from stonesoup.metricgenerator.ospametric import GOSPAMetric, OSPAMetric  # noqa: E402
from stonesoup.models.measurement.linear import LinearGaussian  # noqa: E402
from stonesoup.models.measurement.nonlinear import CartesianToBearingRange  # noqa: E402
from stonesoup.models.transition.linear import (  # noqa: E402
    CombinedLinearGaussianTransitionModel,
)
from stonesoup.models.transition.linear import (  # noqa: E402
    ConstantVelocity as StoneSoupConstantVelocity,
)
from stonesoup.simulator.simple import (  # noqa: E402
    MultiTargetGroundTruthSimulator,
    SimpleDetectionSimulator,
)
from stonesoup.types.detection import Clutter, Detection, TrueDetection  # noqa: E402
from stonesoup.types.groundtruth import GroundTruthPath, GroundTruthState  # noqa: E402
from stonesoup.types.state import GaussianState, StateVector  # noqa: E402
from stonesoup.types.track import Track  # noqa: E402

from mapassoc.data.config import Config  # noqa: E402
from mapassoc.data.io import TrackTable, TruthTable  # noqa: E402
from mapassoc.data.scans import Scan  # noqa: E402
from mapassoc.data.settings import BirthModel, EstimatorSettings  # noqa: E402
from mapassoc.errors import InputError  # noqa: E402
from mapassoc.evaluation.metrics import gospa_over_time  # noqa: E402
from mapassoc.evaluation.scenarios import build_scenario  # noqa: E402
from mapassoc.evaluation.tables import (  # noqa: E402
    evaluate_tables,
    position_names,
    track_points,
    truth_points,
)
from mapassoc.interop.stonesoup import (  # noqa: E402
    INSTALL_HINT,
    StoneSoupScans,
    origins_from_stonesoup,
    scans_from_stonesoup,
    scans_to_stonesoup,
    stonesoup_measurement_models,
    stonesoup_position_mapping,
    stonesoup_state_names,
    tracks_to_stonesoup,
    truth_from_stonesoup,
    truth_to_stonesoup,
)
from mapassoc.models.measurement import LinearMeasurement, RangeBearing  # noqa: E402
from mapassoc.models.motion import ConstantVelocity  # noqa: E402
from mapassoc.models.sensor import Region, Sensor  # noqa: E402
from mapassoc.trackers.map_estimator import MapTracker  # noqa: E402
from mapassoc.trackers.oracle import OracleTracker  # noqa: E402

START = dt.datetime(2024, 1, 1, 12, 0, 0)
NOISE_INTENSITY = 0.05
NOISE_STD = 1.0
DETECTION_PROBABILITY = 0.9
CLUTTER_RATE = 5.0
BOUNDS = [[-100.0, 100.0], [-100.0, 100.0]]
NUM_STEPS = 25
CUTOFF = 10.0
ORDER = 2.0
SENSOR = "radar"


# --------------------------------------------------------------------------- the simulation


@dataclass(frozen=True, eq=False)
class Simulation:
    """Stone Soup's simulation of two crossing targets and its conversion to our types."""

    pairs: list
    paths: set
    model: LinearGaussian
    config: Config
    imported: StoneSoupScans
    truth: TruthTable


def our_config() -> Config:
    """Models of the simulation: CV q = 0.05, position noise 1, Pd 0.9, 5 false alarms."""
    motion = ConstantVelocity(ndim=2, noise_intensity=NOISE_INTENSITY)
    sensor = Sensor(
        name=SENSOR,
        measurement=LinearMeasurement.position(motion, noise_std=NOISE_STD),
        detection_probability=DETECTION_PROBABILITY,
        false_alarms_per_scan=CLUTTER_RATE,
        region=Region.from_bounds(BOUNDS),
    )
    return Config(
        motion=motion,
        sensors={SENSOR: sensor},
        birth=BirthModel(
            rate=0.01, initial_count=2.0, velocity_std=5.0, survival_probability=0.999
        ),
        estimator=EstimatorSettings(window_length=5, max_tracks=10),
    )


def simulate(seed: int) -> Simulation:
    """Two targets from (-36, -30) and (36, -30) meeting near (0, 0) at t = 12 s."""
    transition = CombinedLinearGaussianTransitionModel(
        [StoneSoupConstantVelocity(NOISE_INTENSITY), StoneSoupConstantVelocity(NOISE_INTENSITY)],
        seed=seed,
    )
    model = LinearGaussian(
        ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * NOISE_STD**2, seed=seed + 1
    )
    truth_sim = MultiTargetGroundTruthSimulator(
        transition_model=transition,
        initial_state=GaussianState(StateVector([0.0, 0.0, 0.0, 0.0]), np.eye(4), timestamp=START),
        birth_rate=0.0,
        death_probability=0.0,
        preexisting_states=[
            StateVector([-36.0, 3.0, -30.0, 2.5]),
            StateVector([36.0, -3.0, -30.0, 2.5]),
        ],
        number_steps=NUM_STEPS,
        timestep=dt.timedelta(seconds=1),
        seed=seed + 2,
    )
    detection_sim = SimpleDetectionSimulator(
        groundtruth=truth_sim,
        measurement_model=model,
        meas_range=np.array(BOUNDS),
        detection_probability=DETECTION_PROBABILITY,
        clutter_rate=CLUTTER_RATE,
        seed=seed + 3,
    )
    pairs = []
    paths: set = set()
    for when, detections in detection_sim:
        pairs.append((when, set(detections)))
        paths |= set(truth_sim.groundtruth_paths)
    config = our_config()
    imported = scans_from_stonesoup(pairs, sensor_of={model: SENSOR}, config=config)
    truth = truth_from_stonesoup(
        paths, epoch=imported.epoch, state_names=config.motion.state_names
    )
    return Simulation(pairs, paths, model, config, imported, truth)


@pytest.fixture(scope="module")
def simulation() -> Simulation:
    return simulate(seed=0)


@pytest.fixture(scope="module")
def map_tracks(simulation: Simulation) -> TrackTable:
    return MapTracker(config=simulation.config).track(simulation.imported.scans).tracks


def stonesoup_gospa(paths: set, tracks: set, state_names: tuple[str, ...]) -> list:
    """Stone Soup's per-time GOSPA metrics (alpha = 2) on positions, through its manager."""
    mapping = stonesoup_position_mapping(state_names)
    generator = GOSPAMetric(c=CUTOFF, p=ORDER, measure=Euclidean(mapping=mapping))
    manager = MultiManager([generator])
    manager.add_data({"groundtruth_paths": paths, "tracks": tracks})
    metric = manager.generate_metrics()["gospa_generator"]["GOSPA Metrics"]
    return sorted(metric.value, key=lambda m: m.timestamp)


# --------------------------------------------------------------------------- import


def test_imported_scans_follow_our_conventions(simulation: Simulation) -> None:
    imported = simulation.imported
    scans = imported.scans
    assert imported.epoch == START
    assert [scan.time for scan in scans] == [float(k) for k in range(NUM_STEPS)]
    assert all(scan.sensor == SENSOR for scan in scans)
    rows = np.concatenate([scan.rows for scan in scans])
    total = sum(len(detections) for _, detections in simulation.pairs)
    np.testing.assert_array_equal(rows, np.arange(2, 2 + total))
    for scan in scans:  # numbered in lexicographic order of the measurement vectors
        keys = [tuple(z) for z in scan.detections.tolist()]
        assert keys == sorted(keys)
    # Every Stone Soup detection comes back once, traced by its row, with its vector.
    originals = {id(d) for _, detections in simulation.pairs for d in detections}
    assert {id(d) for d in imported.detections.values()} == originals
    for scan in scans:
        for z, row in zip(scan.detections, scan.rows.tolist(), strict=True):
            detection = imported.detections[row]
            np.testing.assert_array_equal(np.asarray(detection.state_vector, float).ravel(), z)
            assert detection.timestamp == START + dt.timedelta(seconds=scan.time)


def test_truth_and_origins_match_stonesoup_labels(simulation: Simulation) -> None:
    truth = simulation.truth
    assert truth.state_names == ("x", "y", "vx", "vy")
    assert sorted(set(truth.target_ids.tolist())) == [0, 1]
    first = truth.states[truth.times == 0.0]
    # Stone Soup states are (x, vx, y, vy); ours (x, y, vx, vy); paths numbered by first
    # timestamp then uuid, so compare as a set.
    expected = [(-36.0, -30.0, 3.0, 2.5), (36.0, -30.0, -3.0, 2.5)]
    assert sorted(map(tuple, first.tolist())) == expected
    origins = origins_from_stonesoup(simulation.imported.detections, simulation.paths)
    labels = dict(zip(origins.rows.tolist(), origins.target_ids.tolist(), strict=True))
    for row, detection in simulation.imported.detections.items():
        if isinstance(detection, Clutter):
            assert labels[row] == -1
        else:
            assert isinstance(detection, TrueDetection)
            path = detection.groundtruth_path
            state = next(s for s in path if s.timestamp == detection.timestamp)
            position = np.asarray(state.state_vector, float).ravel()[[0, 2]]
            target = truth.target_ids[
                (truth.times == (detection.timestamp - START).total_seconds())
                & np.all(truth.states[:, :2] == position, axis=1)
            ]
            assert labels[row] == int(target[0])


# --------------------------------------------------------------------------- tracking and GOSPA


def test_stonesoup_gospa_of_our_tracks_equals_ours_time_by_time(
    simulation: Simulation, map_tracks: TrackTable
) -> None:
    tracks = tracks_to_stonesoup(map_tracks, epoch=simulation.imported.epoch)
    metrics = stonesoup_gospa(simulation.paths, tracks, simulation.config.motion.state_names)
    names = position_names(simulation.truth, map_tracks)
    series = gospa_over_time(
        truth_points(simulation.truth, names), track_points(map_tracks, names), c=CUTOFF, p=ORDER
    )
    stamps = [START + dt.timedelta(seconds=t) for t in series.times.tolist()]
    assert [m.timestamp for m in metrics] == stamps
    for key, ours in (
        ("distance", series.total),
        ("localisation", series.localisation),
        ("missed", series.missed),
        ("false", series.false),
    ):
        np.testing.assert_allclose([m.value[key] for m in metrics], ours, rtol=1e-12, atol=1e-12)
    summary = evaluate_tables(simulation.truth, map_tracks, c=CUTOFF, p=ORDER).gospa
    mean = float(np.mean([m.value["distance"] for m in metrics]))
    assert mean == pytest.approx(summary.mean_total, rel=1e-12)


def test_map_tracker_on_stonesoup_data_is_close_to_the_oracle(
    simulation: Simulation, map_tracks: TrackTable
) -> None:
    origins = origins_from_stonesoup(simulation.imported.detections, simulation.paths)
    oracle = OracleTracker(config=simulation.config, origins=origins).track(
        simulation.imported.scans
    )
    ours = evaluate_tables(simulation.truth, map_tracks, c=CUTOFF, p=ORDER).gospa
    best = evaluate_tables(simulation.truth, oracle.tracks, c=CUTOFF, p=ORDER).gospa
    assert ours.mean_num_false <= 0.1
    assert ours.mean_num_missed <= 0.2
    assert ours.mean_total <= 1.05 * best.mean_total  # equal on seeds 0-4


def test_ospa_through_simple_manager_relates_to_gospa_at_equal_cardinality(
    simulation: Simulation, map_tracks: TrackTable
) -> None:
    """At a time with n truths and n tracks, OSPA^p * n = GOSPA^p (alpha = 2)."""
    tracks = tracks_to_stonesoup(map_tracks, epoch=simulation.imported.epoch)
    mapping = stonesoup_position_mapping(simulation.config.motion.state_names)
    manager = SimpleManager(
        [
            GOSPAMetric(c=CUTOFF, p=ORDER, measure=Euclidean(mapping=mapping)),
            OSPAMetric(c=CUTOFF, p=ORDER, measure=Euclidean(mapping=mapping)),
        ]
    )
    manager.add_data(groundtruth_paths=simulation.paths, tracks=tracks)
    metrics = manager.generate_metrics()
    gospa = {m.timestamp: m.value for m in metrics["GOSPA Metrics"].value}
    ospa = {m.timestamp: m.value for m in metrics["OSPA distances"].value}
    names = position_names(simulation.truth, map_tracks)
    truths = truth_points(simulation.truth, names)
    estimates = track_points(map_tracks, names)
    compared = 0
    for t in truths.distinct_times.tolist():
        n = truths.positions_at(t).shape[0]
        if estimates.positions_at(t).shape[0] == n:
            stamp = START + dt.timedelta(seconds=t)
            assert ospa[stamp] ** ORDER * n == pytest.approx(gospa[stamp]["distance"] ** ORDER)
            compared += 1
    assert compared >= NUM_STEPS - 3


# --------------------------------------------------------------------------- round trips


def test_scans_round_trip_through_stonesoup_is_the_identity() -> None:
    scenario = build_scenario("crossing", seed=0)
    scans = scenario.scans[:12]
    models = stonesoup_measurement_models(scenario.config)
    pairs = scans_to_stonesoup(
        scans, config=scenario.config, epoch=START, measurement_models=models
    )
    assert len(pairs) == len(scans)
    back = scans_from_stonesoup(
        pairs, sensor_of={models["pos"]: "pos"}, row_key="row", config=scenario.config
    )
    assert back.epoch == START
    assert_same_scans(back.scans, scans)
    # Without row_key, rows are renumbered in lexicographic order within each scan: the same
    # multiset per scan, and the numbering is a fixed point of the round trip.
    renumbered = scans_from_stonesoup(pairs, sensor_of="pos").scans
    for a, b in zip(renumbered, scans, strict=True):
        assert sorted(map(tuple, a.detections.tolist())) == sorted(
            map(tuple, b.detections.tolist())
        )
    again = scans_from_stonesoup(
        scans_to_stonesoup(renumbered, config=scenario.config, epoch=START), sensor_of="pos"
    )
    assert_same_scans(again.scans, renumbered)


def test_two_sensor_round_trip_swaps_range_and_bearing_exactly() -> None:
    scenario = build_scenario("two_sensors", seed=0)
    scans = scenario.scans[:10]
    assert all(scan.size > 0 for scan in scans)  # asynchronous sensors, no empty scan
    epoch = dt.datetime(2024, 5, 1, tzinfo=dt.UTC)
    models = stonesoup_measurement_models(scenario.config)
    radar = models["radar"]
    assert isinstance(radar, CartesianToBearingRange)
    pairs = scans_to_stonesoup(
        scans, config=scenario.config, epoch=epoch, measurement_models=models
    )
    radar_scan = next(s for s in scans if s.sensor == "radar")
    radar_set = pairs[scans.index(radar_scan)][1]
    by_row = {d.metadata["row"]: d for d in radar_set}
    for z, row in zip(radar_scan.detections, radar_scan.rows.tolist(), strict=True):
        np.testing.assert_array_equal(np.asarray(by_row[row].state_vector, float).ravel(), z[::-1])
    back = scans_from_stonesoup(
        pairs,
        sensor_of={model: name for name, model in models.items()},
        empty_scans=False,
        row_key="row",
        config=scenario.config,
        epoch=epoch,
    )
    assert_same_scans(back.scans, scans)
    # With empty_scans (the default) every sensor scans at every time.
    filled = scans_from_stonesoup(
        pairs, sensor_of={model: name for name, model in models.items()}, config=scenario.config
    )
    assert len(filled.scans) == 2 * len(scans)
    assert sum(scan.size == 0 for scan in filled.scans) == len(scans)


def test_truth_round_trip_through_stonesoup_is_the_identity() -> None:
    truth = build_scenario("crossing", seed=1).truth
    paths = truth_to_stonesoup(truth, epoch=START)
    assert {p.id for p in paths} == {str(i) for i in set(truth.target_ids.tolist())}
    back = truth_from_stonesoup(paths, epoch=START, state_names=truth.state_names)
    order = np.lexsort((truth.times, truth.target_ids))
    np.testing.assert_array_equal(back.target_ids, truth.target_ids[order])
    np.testing.assert_array_equal(back.times, truth.times[order])
    np.testing.assert_array_equal(back.states, truth.states[order])
    assert back.state_names == truth.state_names


def assert_same_scans(got: list[Scan], expected: list[Scan]) -> None:
    assert len(got) == len(expected)
    for a, b in zip(got, expected, strict=True):
        assert (a.time, a.sensor) == (b.time, b.sensor)
        np.testing.assert_array_equal(a.detections, b.detections)
        np.testing.assert_array_equal(a.rows, b.rows)
        assert a.detections.shape == b.detections.shape


# --------------------------------------------------------------------------- hand-worked orders


def test_state_orders() -> None:
    assert stonesoup_state_names(("x", "y", "vx", "vy")) == ("x", "vx", "y", "vy")
    assert stonesoup_state_names(("x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az")) == (
        "x", "vx", "ax", "y", "vy", "ay", "z", "vz", "az",
    )
    turn = ("x", "y", "speed", "heading", "turn_rate")
    assert stonesoup_state_names(turn) == turn
    assert stonesoup_position_mapping(("x", "y", "vx", "vy")) == (0, 2)
    assert stonesoup_position_mapping(turn) == (0, 1)
    assert stonesoup_position_mapping(("x",)) == (0,)


def test_tracks_to_stonesoup_by_hand() -> None:
    epoch = dt.datetime(2024, 1, 1)
    tracks = TrackTable(
        track_ids=np.array([7, 7, 7, 3]),
        times=np.array([0.5, 0.0, 0.5, 0.0]),
        sensors=("a", "a", "b", "a"),
        states=np.array(
            [[1.0, 2.0, 3.0, 4.0], [0.0, 0.0, 1.0, 1.0], [1.5, 2.5, 3.5, 4.5], [9.0, 8.0, 7.0, 6.0]]
        ),
        variances=np.array(
            [[0.1, 0.2, 0.3, 0.4], [1.0, 1.0, 1.0, 1.0], [0.5, 0.6, 0.7, 0.8], [2.0, 3.0, 4.0, 5.0]]
        ),
        detection_rows=np.array([2, -1, 5, 3]),
        state_names=("x", "y", "vx", "vy"),
    )
    out = {track.id: track for track in tracks_to_stonesoup(tracks, epoch=epoch)}
    assert set(out) == {"3", "7"}
    assert all(isinstance(t, Track) for t in out.values())
    seven = out["7"]
    assert [s.timestamp for s in seven.states] == [
        epoch,
        epoch + dt.timedelta(seconds=0.5),
        epoch + dt.timedelta(seconds=0.5),
    ]
    np.testing.assert_array_equal(np.asarray(seven.states[1].state_vector).ravel(), [1, 3, 2, 4])
    np.testing.assert_array_equal(np.diag(seven.states[1].covar), [0.1, 0.3, 0.2, 0.4])
    assert np.count_nonzero(seven.states[1].covar - np.diag(np.diag(seven.states[1].covar))) == 0
    # Two rows at one time: table order kept, so the last (sensor "b") is what metrics use.
    last = list(seven.last_timestamp_generator())
    np.testing.assert_array_equal(np.asarray(last[-1].state_vector).ravel(), [1.5, 3.5, 2.5, 4.5])


def test_measurement_conversions_match_stonesoup_model_functions() -> None:
    """Our predict() and Stone Soup's function() agree once orders are converted."""
    motion = ConstantVelocity(ndim=2, noise_intensity=1.0)
    radar = RangeBearing(sensor_position=[10.0, -5.0], range_std=2.0, bearing_std=0.01)
    config = Config(
        motion=motion,
        sensors={
            "pos": Sensor(
                name="pos",
                measurement=LinearMeasurement.position(motion, noise_std=[1.0, 3.0]),
                detection_probability=0.9,
                false_alarms_per_scan=1.0,
                region=Region.from_bounds(BOUNDS),
            ),
            "radar": Sensor(
                name="radar",
                measurement=radar,
                detection_probability=0.9,
                false_alarms_per_scan=1.0,
                region=Region.from_bounds([[0.0, 300.0], [-np.pi, np.pi]]),
            ),
        },
        birth=BirthModel(),
        estimator=EstimatorSettings(),
    )
    models = stonesoup_measurement_models(config)
    assert models["pos"].mapping == (0, 2)
    np.testing.assert_array_equal(models["pos"].covar(), np.diag([1.0, 9.0]))
    assert tuple(models["radar"].mapping) == (0, 2)
    np.testing.assert_array_equal(models["radar"].covar(), np.diag([0.01**2, 4.0]))
    ours = np.array([-20.0, 35.0, 1.0, -2.0])  # (x, y, vx, vy)
    theirs = GaussianState(StateVector(ours[[0, 2, 1, 3]]), np.eye(4), timestamp=START)
    for name in ("pos", "radar"):
        z = models[name].function(theirs, noise=False)
        detection = Detection(z, timestamp=START, measurement_model=models[name])
        scans = scans_from_stonesoup(
            [(START, {detection})], sensor_of={models[name]: name}, config=config
        ).scans
        assert [(s.sensor, s.size) for s in scans] == [(name, 1)]
        scan = scans[0]
        np.testing.assert_allclose(
            scan.detections[0], config.sensors[name].measurement.predict(ours), rtol=1e-14
        )


def test_bare_detection_sets_take_the_time_of_their_detections() -> None:
    model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2))
    later = START + dt.timedelta(seconds=2.25)
    sets = [
        {Detection(StateVector([1.0, 2.0]), timestamp=later, measurement_model=model)},
        {
            Detection(StateVector([3.0, 4.0]), timestamp=START, measurement_model=model),
            Detection(StateVector([0.0, 9.0]), timestamp=START, measurement_model=model),
        },
    ]
    out = scans_from_stonesoup(sets, sensor_of="s")
    assert out.epoch == START
    assert [(s.time, s.size) for s in out.scans] == [(0.0, 2), (2.25, 1)]
    np.testing.assert_array_equal(out.scans[0].detections, [[0.0, 9.0], [3.0, 4.0]])
    np.testing.assert_array_equal(out.scans[0].rows, [2, 3])
    np.testing.assert_array_equal(out.scans[1].rows, [4])
    shifted = scans_from_stonesoup(sets, sensor_of="s", epoch=START - dt.timedelta(seconds=1))
    assert [s.time for s in shifted.scans] == [1.0, 3.25]


def test_paths_with_uuid_ids_are_numbered_by_first_time() -> None:
    early = GroundTruthPath(
        [GroundTruthState(StateVector([0.0, 1.0, 0.0, 1.0]), timestamp=START)], id="zzz"
    )
    late = GroundTruthPath(
        [
            GroundTruthState(
                StateVector([5.0, 0.0, 6.0, 0.0]), timestamp=START + dt.timedelta(seconds=1)
            )
        ],
        id="aaa",
    )
    truth = truth_from_stonesoup({late, early}, epoch=START, state_names=("x", "y", "vx", "vy"))
    np.testing.assert_array_equal(truth.target_ids, [0, 1])
    np.testing.assert_array_equal(truth.states, [[0.0, 0.0, 1.0, 1.0], [5.0, 6.0, 0.0, 0.0]])


# --------------------------------------------------------------------------- errors


def test_bad_inputs_are_refused_with_the_culprit_named() -> None:
    model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2))
    other = LinearGaussian(ndim_state=4, mapping=(2, 0), noise_covar=np.eye(2))
    good = Detection(StateVector([1.0, 2.0]), timestamp=START, measurement_model=model)
    config = our_config()
    cases = [
        (lambda: scans_from_stonesoup([], sensor_of="s"), "detection_sets is empty"),
        (lambda: scans_from_stonesoup([set()], sensor_of="s"), "empty detection set"),
        (lambda: scans_from_stonesoup([(START, {good})], sensor_of=""), "sensor_of"),
        (
            lambda: scans_from_stonesoup([(START, {good})], sensor_of={other: "s"}),
            "no sensor for its measurement model",
        ),
        (
            lambda: scans_from_stonesoup(
                [(START + dt.timedelta(seconds=1), {good})], sensor_of="s"
            ),
            "has timestamp",
        ),
        (
            lambda: scans_from_stonesoup([(START, {good}), (START, [good])], sensor_of="s"),
            "more than once",
        ),
        (
            lambda: scans_from_stonesoup([(START, {good})], sensor_of="s", row_key="row"),
            "metadata has no 'row'",
        ),
        (
            lambda: scans_from_stonesoup(
                [(START, {Detection(StateVector([1.0, 2.0]), timestamp=START,
                                    measurement_model=other)})],
                sensor_of={other: SENSOR},
                config=config,
            ),
            "mapping",
        ),
        (
            lambda: scans_from_stonesoup(
                [(START, {good})], sensor_of="s", epoch=dt.datetime(2024, 1, 1, tzinfo=dt.UTC)
            ),
            "naive and timezone-aware",
        ),
        (
            lambda: scans_from_stonesoup(
                [(START, {Detection(StateVector([1.0, 2.0]), timestamp=START,
                                    measurement_model=CartesianToBearingRange(
                                        ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2),
                                        rotation_offset=StateVector([0.0, 0.0, 0.1])))})],
                sensor_of="s",
            ),
            "rotation_offset",
        ),
        (
            lambda: tracks_to_stonesoup(
                TrackTable(
                    track_ids=np.array([0, 0]),
                    times=np.array([0.0, 1e-7]),
                    sensors=("s", "s"),
                    states=np.zeros((2, 2)),
                    variances=np.zeros((2, 2)),
                    detection_rows=np.array([-1, -1]),
                    state_names=("x", "y"),
                ),
                epoch=START,
            ),
            "round to the same datetime",
        ),
        (lambda: tracks_to_stonesoup("tracks", epoch=START), "TrackTable"),
        (lambda: truth_to_stonesoup(build_scenario("crossing", 0).truth, epoch=0.0), "epoch"),
        (
            lambda: origins_from_stonesoup({2: good}, set()),
            "neither TrueDetection nor Clutter",
        ),
    ]
    for call, message in cases:
        with pytest.raises(InputError, match=message):
            call()


def test_without_stonesoup_the_module_imports_and_calls_name_the_extra() -> None:
    code = (
        "import sys; sys.modules['stonesoup'] = None\n"
        "import datetime\n"
        "import mapassoc.interop.stonesoup as m\n"
        "for call in (lambda: m.tracks_to_stonesoup(None, epoch=None),\n"
        "             lambda: m.scans_from_stonesoup([], sensor_of='s'),\n"
        "             lambda: m.stonesoup_measurement_models(None)):\n"
        "    try:\n"
        "        call()\n"
        "    except ImportError as exc:\n"
        "        assert str(exc) == m.INSTALL_HINT, exc\n"
        "    else:\n"
        "        raise AssertionError('no ImportError')\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    lazy = "import sys, mapassoc.interop.stonesoup; assert 'stonesoup' not in sys.modules"
    subprocess.run([sys.executable, "-c", lazy], check=True)
    assert "pip install 'mapassoc[stonesoup]'" in INSTALL_HINT



def test_detection_ids_from_zero_round_trip() -> None:
    """Ids are opaque (>= 0): scans numbered from 0 go to Stone Soup and back unchanged."""
    from mapassoc.data.scans import Scan

    scenario = build_scenario("crossing", seed=0)
    first = 0
    scans = []
    for scan in scenario.scans[:6]:
        ids = np.arange(first, first + scan.size)
        first += scan.size
        scans.append(Scan(scan.time, scan.sensor, scan.detections, ids))
    models = stonesoup_measurement_models(scenario.config)
    pairs = scans_to_stonesoup(
        scans, config=scenario.config, epoch=START, measurement_models=models
    )
    back = scans_from_stonesoup(
        pairs, sensor_of={models["pos"]: "pos"}, row_key="row", config=scenario.config
    )
    assert_same_scans(back.scans, scans)
    assert back.scans[0].rows.min() == 0
