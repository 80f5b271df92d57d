"""The Python entry points check their arguments as the command line does (issue 19).

``WindowEstimator(config="x.toml")``, ``run("file.csv")``, ``run(DataFrame)`` raised raw
AttributeErrors, and ``solve_window`` accepted scans in reverse time order or the same
scan three times.  One check (:func:`mapassoc.data.scans.check_scans`) now serves
``start``, ``run``, ``solve_window`` and every tracker's ``track``; each failure is one
InputError saying what to pass.  The time-step warning of ``start`` is tested here too.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import mapassoc as ma
from mapassoc.apps.cli import main
from mapassoc.data.config import write_config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.pipeline import WindowEstimator, time_scale_warning
from mapassoc.evaluation.scenarios import (
    build_scenario,
    generic_config,
    scenario_names,
    truncate_scenario,
)
from mapassoc.trackers.registry import TRACKERS, build_tracker

SCENARIO = truncate_scenario(build_scenario("crossing", 0), 6)


def _entry_points() -> dict[str, Callable[[object], object]]:
    """Every public function that takes a run's scans, by name."""
    estimator = WindowEstimator(config=SCENARIO.config)
    points: dict[str, Callable[[object], object]] = {
        "WindowEstimator.run": estimator.run,
        "WindowEstimator.start": estimator.start,
        "WindowEstimator.solve_window": estimator.solve_window,
    }
    for name, spec in TRACKERS.items():
        tracker = build_tracker(
            name, config=SCENARIO.config, origins=SCENARIO.origins if spec.needs_truth else None
        )
        points[f"{name}.track"] = tracker.track
    return points


ENTRY_POINTS = _entry_points()

BAD_SCANS = [
    # (what is passed, a phrase of the message: what to do instead)
    ("scen/detections.csv", "read_detections_file(path, config.sensors)"),
    (Path("scen/detections.csv"), "read_detections_file(path, config.sensors)"),
    (pd.DataFrame({"time": [0.0], "sensor": ["pos"], "x": [1.0], "y": [2.0]}),
     "scans_from_frame(frame, config.sensors)"),
    (np.zeros((4, 3)), "scans_from_arrays(times, measurements, config.sensors)"),
    (SCENARIO.scans[0], "pass [scan]"),
    ([SCENARIO.scans[0], "x"], "scans[1] must be a mapassoc.Scan"),
    (None, "must be a sequence of mapassoc.Scan"),
    (SCENARIO.scans[:5][::-1], "sorted by (time, sensor)"),
    ([SCENARIO.scans[0]] * 3, "sorted by (time, sensor) without repeats"),
    ([], "is empty"),
]  # fmt: skip
BAD_IDS = ["str", "path", "frame", "array", "one_scan", "not_scan", "none", "reversed",
           "thrice", "empty"]  # fmt: skip


@pytest.mark.parametrize("entry", sorted(ENTRY_POINTS))
@pytest.mark.parametrize(("scans", "phrase"), BAD_SCANS, ids=BAD_IDS)
def test_every_entry_point_refuses_what_is_not_a_run_of_scans(
    entry: str, scans: object, phrase: str
) -> None:
    with pytest.raises(InputError) as info:
        ENTRY_POINTS[entry](scans)
    message = str(info.value)
    assert phrase in message and "\n" not in message, message


def test_solve_window_and_run_refuse_the_same_scans_with_the_same_message() -> None:
    estimator = WindowEstimator(config=SCENARIO.config)
    for scans, _ in BAD_SCANS:
        messages = []
        for call in (estimator.run, estimator.solve_window):
            with pytest.raises(InputError) as info:
                call(scans)  # type: ignore[arg-type]
            messages.append(str(info.value).replace("solve", "estimate"))
        assert messages[0] == messages[1]
    # A proper window still solves: the first window of run() (the docstring's promise).
    window = estimator.solve_window(SCENARIO.scans[:5])
    first = estimator.run(SCENARIO.scans).windows[0]
    np.testing.assert_array_equal(
        window.posterior.probabilities[: len(first.p_k)], first.p_k
    )


@pytest.mark.parametrize(
    ("config", "phrase"),
    [
        ("x.toml", "config=mapassoc.load_config('x.toml')"),
        (Path("x.toml"), "config=mapassoc.load_config("),
        (None, "mapassoc.load_config(path)"),
        ({"motion": {}}, "mapassoc.parse_config(data)"),
    ],
)
def test_a_config_that_is_not_a_config_says_how_to_get_one(config: object, phrase: str) -> None:
    builders: list[Callable[[], object]] = [lambda: WindowEstimator(config=config)]  # type: ignore[arg-type]
    for name, spec in TRACKERS.items():
        origins = SCENARIO.origins if spec.needs_truth else None
        builders.append(lambda n=name, o=origins: build_tracker(n, config=config, origins=o))  # type: ignore[misc]
    for build in builders:
        with pytest.raises(InputError) as info:
            build()
        message = str(info.value)
        assert message.startswith("config must be a Config (mapassoc.Config), got ")
        assert phrase in message and "\n" not in message


# ------------------------------------------------------------------ time-step warning


def _timed(scenario: ma.evaluation.scenarios.Scenario, factor: float) -> list[Scan]:  # type: ignore[name-defined]
    return [Scan(s.time * factor, s.sensor, s.detections, s.rows) for s in scenario.scans]


def _unit_warnings(config: ma.Config, scans: list[Scan]) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        WindowEstimator(config=config).start(scans)
    return [str(w.message) for w in caught if "time units apart" in str(w.message)]


@pytest.mark.parametrize("name", scenario_names())
def test_no_built_in_scenario_warns_about_its_time_step(name: str) -> None:
    scenario = build_scenario(name, 0)
    for config in (scenario.config, generic_config(scenario)):
        assert _unit_warnings(config, list(scenario.scans)) == []
        assert time_scale_warning(config, scenario.scans) is None


@pytest.mark.parametrize("factor", [1e3, 1e9])
def test_times_in_milliseconds_or_nanoseconds_warn_naming_the_keys(factor: float) -> None:
    scenario = build_scenario("crossing", 0)
    messages = _unit_warnings(scenario.config, _timed(scenario, factor))
    assert len(messages) == 1
    message = messages[0]
    assert f"{factor:.6g} time units apart" in message
    assert f"velocity_std = {scenario.config.birth.velocity_std!r} per time unit" in message
    assert "time column" in message and "sensor 'pos'" in message and "\n" not in message


def test_the_warning_reaches_summary_json(tmp_path: Path) -> None:
    scenario = truncate_scenario(build_scenario("crossing", 0), 8)
    ma.write_detections_file(tmp_path / "detections.csv", _timed(scenario, 1e3),
                             scenario.config.sensors)  # fmt: skip
    write_config(tmp_path / "config.toml", scenario.config)
    out = tmp_path / "run"
    args = ["run", str(tmp_path / "config.toml"), str(tmp_path / "detections.csv")]
    assert main([*args, "--out", str(out), "--no-progress", "--no-timings"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert any("time units apart" in w for w in summary["warnings"])


# ------------------------------------------------------- wrong types at the boundaries


def _sensor() -> ma.Sensor:
    return next(iter(SCENARIO.config.sensors.values()))


def _sensor_with(**change: object) -> ma.Sensor:
    sensor = _sensor()
    arguments: dict[str, object] = {
        "name": "s",
        "measurement": sensor.measurement,
        "detection_probability": 0.9,
        "false_alarms_per_scan": 1.0,
        "region": sensor.region,
    }
    return ma.Sensor(**{**arguments, **change})  # type: ignore[arg-type]


def _tracks() -> ma.TrackTable:
    return ma.oracle_tracks(SCENARIO.scans, SCENARIO.origins, SCENARIO.config)


NO_ROWS = np.zeros(0, dtype=np.int64)

# (the call, the argument's name as the message gives it, the value's repr and type)
WRONG_TYPES: dict[str, tuple[Callable[[], object], str, str]] = {
    "scan_time_text": (lambda: Scan("12:00", "s", np.zeros((0, 2)), NO_ROWS),  # type: ignore[arg-type]
                       "scan time", "'12:00' (str)"),
    "scan_time_none": (lambda: Scan(None, "s", np.zeros((0, 2)), NO_ROWS),  # type: ignore[arg-type]
                       "scan time", "None (NoneType)"),
    "scan_detections_text": (lambda: Scan(1.0, "s", [["1", "2"]], np.zeros(1)),  # type: ignore[arg-type]
                             "scan detections", "[['1', '2']] (list)"),
    "scan_sensor_int": (lambda: Scan(1.0, 5, np.zeros((0, 2)), NO_ROWS),  # type: ignore[arg-type]
                        "scan sensor", "5 (int)"),
    "sensor_measurement_text": (lambda: _sensor_with(measurement="position"),
                                "sensor 's' measurement", "'position' (str)"),
    "sensor_measurement_none": (lambda: _sensor_with(measurement=None),
                                "sensor 's' measurement", "None (NoneType)"),
    "sensor_region_bounds": (lambda: _sensor_with(region=[[0, 1], [0, 1]]),
                             "sensor 's' region", "[[0, 1], [0, 1]] (list)"),
    "range_std_text": (lambda: ma.RangeBearing(sensor_position=[0, 0], range_std="1",  # type: ignore[arg-type]
                                               bearing_std=0.1),
                       "range_std", "'1' (str)"),
    "bearing_std_text": (lambda: ma.RangeBearing(sensor_position=[0, 0], range_std=1.0,
                                                 bearing_std="0.1"),  # type: ignore[arg-type]
                         "bearing_std", "'0.1' (str)"),
    "noise_std_text": (lambda: ma.LinearMeasurement.position(SCENARIO.config.motion,
                                                             noise_std="1"),
                       "noise_std", "'1' (str)"),
    "component_names_text": (lambda: ma.LinearMeasurement(H=np.eye(2), R=np.eye(2),
                                                           component_names="xy"),
                             "component_names", "'xy' (str)"),
    "load_config_none": (lambda: ma.load_config(None), "load_config: path",  # type: ignore[arg-type]
                         "None (NoneType)"),
    "load_config_int": (lambda: ma.load_config(5), "load_config: path", "5 (int)"),  # type: ignore[arg-type]
    "read_detections_file_none": (
        lambda: ma.read_detections_file(None, SCENARIO.config.sensors),  # type: ignore[arg-type]
        "read_detections_file: path", "None (NoneType)"),
    "read_detections_content_text": (
        lambda: ma.read_detections("d.csv", SCENARIO.config.sensors, content="time"),  # type: ignore[arg-type]
        "read_detections: content", "'time' (str)"),
    "read_tracks_none": (lambda: ma.read_tracks(None), "read_tracks: path",  # type: ignore[arg-type]
                         "None (NoneType)"),
    "read_truth_file_int": (lambda: ma.read_truth_file(5), "read_truth_file: path",  # type: ignore[arg-type]
                            "5 (int)"),
    "evaluate_tables_swapped": (lambda: ma.evaluate_tables(_tracks(), SCENARIO.truth, c=10.0),  # type: ignore[arg-type]
                                "truth", "(TrackTable); the two are swapped"),
    "evaluate_tables_tracks_none": (lambda: ma.evaluate_tables(SCENARIO.truth, None, c=10.0),  # type: ignore[arg-type]
                                    "tracks", "None (NoneType)"),
    "run_segmented_path": (lambda: ma.run_segmented("config.toml", SCENARIO.scans,  # type: ignore[arg-type]
                                                    segments=2),
                           "config", "'config.toml'"),
    "run_segmented_file_of_scans": (lambda: ma.run_segmented(SCENARIO.config, "d.csv",  # type: ignore[arg-type]
                                                             segments=2),
                                    "scans", "'d.csv'"),
    "run_files_config": (lambda: ma.run_files(SCENARIO.config, "d.csv", "out"),  # type: ignore[arg-type]
                         "run_files: config_path", "(Config); run_files reads a TOML file"),
    "run_files_out_none": (lambda: ma.run_files("c.toml", "d.csv", None),  # type: ignore[arg-type]
                           "run_files: out_dir", "None (NoneType)"),
    "run_files_stop_text": (lambda: ma.run_files("c.toml", "d.csv", "out", stop="now"),  # type: ignore[arg-type]
                            "run_files: stop", "'now' (str)"),
    "find_recordings_none": (lambda: ma.find_recordings(None), "find_recordings: source",  # type: ignore[arg-type]
                             "None (NoneType)"),
    "find_recordings_int": (lambda: ma.find_recordings(5), "find_recordings: source",  # type: ignore[arg-type]
                            "5 (int)"),
    "run_batch_folder": (lambda: ma.run_batch("recordings", "out"),  # type: ignore[arg-type]
                         "run_batch: recordings", "'recordings' (str); list the recordings"),
    "run_batch_out_none": (lambda: ma.run_batch([_recording()], None),  # type: ignore[arg-type]
                           "run_batch: out", "None (NoneType)"),
    "run_batch_progress_text": (lambda: ma.run_batch([_recording()], "out", progress="no"),  # type: ignore[arg-type]
                                "run_batch: progress", "'no' (str)"),
    "birth_rate_text": (lambda: ma.BirthModel(rate="0.1"), "birth rate", "'0.1' (str)"),  # type: ignore[arg-type]
    "birth_rate_bool": (lambda: ma.BirthModel(rate=True), "birth rate", "boolean True"),
    "k_prior_mean_text": (lambda: ma.EstimatorSettings(k_prior_mean="5"), "k_prior_mean",  # type: ignore[arg-type]
                          "'5' (str)"),
    "k_prior_weights_text": (lambda: ma.CountPrior(weights="1,2"), "k_prior_weights",  # type: ignore[arg-type]
                             "'1,2' (str)"),
    "region_bounds_text": (lambda: ma.Region.from_bounds("0,1"), "region bounds", "'0,1' (str)"),
    "run_progress_text": (lambda: WindowEstimator(config=SCENARIO.config).run(
        SCENARIO.scans, progress="yes"), "run: progress", "'yes' (str)"),  # type: ignore[arg-type]
    "solve_window_carried_none": (lambda: WindowEstimator(config=SCENARIO.config).solve_window(
        SCENARIO.scans[:5], None), "carried", "None (NoneType)"),  # type: ignore[arg-type]
    "step_state_text": (lambda: WindowEstimator(config=SCENARIO.config).step(
        SCENARIO.scans, "state"), "step: state", "'state' (str)"),  # type: ignore[arg-type]
    "run_state_total_text": (lambda: ma.RunState(total_scans="6"), "RunState total_scans",  # type: ignore[arg-type]
                             "'6' (str)"),
    "oracle_config_path": (lambda: ma.oracle_tracks(SCENARIO.scans, SCENARIO.origins, "c.toml"),  # type: ignore[arg-type]
                           "config", "'c.toml'"),
    "k_posterior_prior_none": (lambda: ma.k_posterior(np.zeros(1), np.zeros(1), prior=None,  # type: ignore[arg-type]
                                                      population=None),  # type: ignore[arg-type]
                               "k_posterior: prior", "None (NoneType)"),
}  # fmt: skip


def _recording() -> object:
    from mapassoc.apps.batch import Recording

    return Recording("a", Path("a.csv"), None)


@pytest.mark.parametrize("case", sorted(WRONG_TYPES))
def test_a_wrong_type_is_one_input_error_naming_the_argument_and_the_value(
    case: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each of these raised a raw TypeError, AttributeError or ValueError, or (a rate
    given as text) was accepted; nothing is read or written before the check."""
    monkeypatch.chdir(tmp_path)
    call, argument, value = WRONG_TYPES[case]
    with pytest.raises(InputError) as info:
        call()
    message = str(info.value)
    assert message.startswith(f"{argument} must be "), message
    assert value in message and "\n" not in message, message
    assert list(tmp_path.iterdir()) == []
