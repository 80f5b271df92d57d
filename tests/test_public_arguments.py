"""Every public function and class of ``mapassoc`` given None, a string or an integer
where another type belongs: it accepts the value (where it is one of the documented
kinds) or raises one :class:`~mapassoc.errors.MapassocError` whose message names the
argument; never a raw TypeError, AttributeError or ValueError from deep inside.

The valid call of each name is listed below (:data:`VALID`); each case replaces one
argument of it.  :func:`test_every_public_callable_is_swept` keeps the list complete.
"""

from __future__ import annotations

import dataclasses
import inspect
import tomllib
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

import mapassoc as ma
from mapassoc.apps.runs import RunOptions
from mapassoc.data.config import config_to_toml, write_config
from mapassoc.data.io import write_truth
from mapassoc.errors import MapassocError
from mapassoc.evaluation.scenarios import truncate_scenario

SCENARIO = truncate_scenario(ma.build_scenario("crossing", 0), 6)
CONFIG = SCENARIO.config
SENSORS = CONFIG.sensors
SENSOR = next(iter(SENSORS.values()))
MOTION = CONFIG.motion
TRACKS = ma.oracle_tracks(SCENARIO.scans, SCENARIO.origins, CONFIG)
POSITION = ma.LinearMeasurement.position(MOTION, noise_std=1.0)
QUIET = RunOptions(progress=False)
COMPONENTS = SENSOR.measurement.component_names
FRAME = pd.DataFrame({"time": [0.0], "sensor": [SENSOR.name], **{n: [0.0] for n in COMPONENTS}})
WINDOW = ma.WindowEstimator(config=CONFIG).solve_window(SCENARIO.scans[:5])

Call = tuple[tuple[Any, ...], dict[str, Any]]


def _is(value: object, placeholder: str) -> bool:
    return isinstance(value, str) and value == placeholder


def _estimator(method: str) -> Callable[..., object]:
    def call(*args: object, **kwargs: object) -> object:
        estimator = ma.WindowEstimator(config=CONFIG)
        if method == "step":  # a fresh state for each call: step advances it
            scans, state = args
            args = (scans, estimator.start(SCENARIO.scans) if _is(state, "<state>") else state)
        return getattr(estimator, method)(*args, **kwargs)

    return call


def _named(name: str) -> Callable[..., object]:
    if name.startswith("WindowEstimator."):
        return _estimator(name.split(".")[1])
    owner, _, attribute = name.partition(".")
    target = getattr(ma, owner)
    return getattr(target, attribute) if attribute else target


# One valid call per public name; files are those of the ``files`` fixture (the test
# runs in its folder).
VALID: dict[str, Call] = {
    "BirthModel": ((), {"rate": 0.1}),
    "EstimatorSettings": ((), {"window_length": 5, "k_prior_mean": 5.0, "solver": "highs"}),
    "ConstantVelocity": ((), {"noise_intensity": 1.0}),
    "ConstantAcceleration": ((), {"noise_intensity": 1.0}),
    "RandomWalk": ((), {"noise_intensity": 1.0}),
    "CoordinatedTurn": ((), {"speed_noise_intensity": 1.0, "turn_rate_noise_intensity": 0.1}),
    "Singer": ((), {"time_constant": 1.0, "acceleration_std": 1.0}),
    "LinearMeasurement": ((), {"H": POSITION.H, "R": POSITION.R, "component_names": ("x", "y")}),
    "LinearMeasurement.position": ((MOTION,), {"noise_std": 1.0}),
    "RangeBearing": ((), {"sensor_position": [0.0, 0.0], "range_std": 1.0, "bearing_std": 0.1}),
    "Sensor": ((), {"name": "s", "measurement": SENSOR.measurement, "detection_probability": 0.9,
                    "false_alarms_per_scan": 1.0, "region": SENSOR.region}),
    "Region": ((np.zeros(2), np.ones(2)), {}),
    "Region.from_bounds": (([[0, 1], [0, 1]],), {}),
    "Config": ((), {"motion": MOTION, "sensors": SENSORS, "birth": CONFIG.birth,
                    "estimator": CONFIG.estimator}),
    "load_config": (("c.toml",), {"solver_names": ["highs"]}),
    "parse_config": ((tomllib.loads(config_to_toml(CONFIG)),), {}),
    "Scan": ((1.0, "s", np.zeros((0, 2)), np.zeros(0, dtype=np.int64)), {}),
    "read_detections": (("d.csv", SENSORS), {}),
    "read_detections_file": (("d.csv", SENSORS), {}),
    "write_detections": (("w.csv", SCENARIO.scans, SENSORS), {}),
    "write_detections_file": (("w.csv", SCENARIO.scans, SENSORS), {}),
    "read_truth": (("truth.csv",), {}),
    "read_truth_file": (("truth.csv",), {}),
    "read_tracks": (("t.csv",), {}),
    "read_tracks_file": (("t.csv",), {}),
    "write_tracks": (("w.csv", TRACKS), {}),
    "write_tracks_file": (("w.csv", TRACKS), {}),
    "TruthTable": ((), {f.name: getattr(SCENARIO.truth, f.name)
                        for f in dataclasses.fields(SCENARIO.truth)}),
    "TrackTable": ((), {f.name: getattr(TRACKS, f.name) for f in dataclasses.fields(TRACKS)}),
    "scans_from_frame": ((FRAME, SENSORS), {}),
    "scans_from_arrays": (([0.0], [[0.0, 0.0]], SENSORS), {}),
    "WindowEstimator": ((), {"config": CONFIG}),
    "WindowEstimator.run": ((SCENARIO.scans,), {}),
    "WindowEstimator.start": ((SCENARIO.scans,), {}),
    "WindowEstimator.solve_window": ((SCENARIO.scans[:5],), {}),
    "WindowEstimator.step": ((SCENARIO.scans, "<state>"), {}),
    "RunState": ((6,), {}),
    "run_segmented": ((CONFIG, SCENARIO.scans), {"segments": 1}),
    "CountPrior": ((), {}),
    "k_posterior": ((WINDOW.table.best, WINDOW.table.log_mass),
                    {"prior": WINDOW.posterior.count_prior, "population": WINDOW.population}),
    "UndetectedTargets": ((1.0, 0.0), {}),
    "build_scenario": (("crossing", 0), {"scans": 3}),
    "scenario_names": ((), {}),
    "generic_config": ((SCENARIO,), {}),
    "evaluate_tables": ((SCENARIO.truth, TRACKS), {"c": 10.0}),
    "gospa": (([[0.0, 0.0]], [[1.0, 1.0]]), {"c": 10.0}),
    "oracle_tracks": ((SCENARIO.scans, SCENARIO.origins, CONFIG), {}),
    "n_object_posterior": (([[0.0, 0.0, 0.0, 0.0]], [np.eye(4)], [[0.0, 0.0]], POSITION, 0.9,
                            0.01), {}),
    "single_object_sequences": (([0.0, 0.0, 0.0, 0.0], np.eye(4), [[[0.0, 0.0]]], MOTION,
                                 POSITION, 0.9, 0.01), {}),
    "run_files": (("c.toml", "d.csv", "out"), {"options": QUIET}),
    "find_recordings": (("recordings",), {}),
    "run_batch": (("<recordings>", "batch"), {"shared_config": "c.toml", "options": QUIET,
                                              "jobs": 1, "progress": False}),
}  # fmt: skip

NOT_CALLED = {
    # result records the package builds (never given by a user), and the errors
    "WindowSolution", "WindowReport", "EstimateResult", "KPosterior",
    "InputError", "ConfigError", "DataFileError", "OutputError",
}  # fmt: skip
SKIPPED = {
    # a worker pool of 5 processes, or a 30 s wait for a Dask scheduler, for one case
    ("run_batch", "jobs"), ("run_batch", "scheduler"),
}  # fmt: skip
BAD_VALUES = (None, "x", 5)


def _parameters(name: str) -> list[inspect.Parameter]:
    """The parameters of the public name (a method's without ``self``)."""
    if name.startswith("WindowEstimator."):
        method = getattr(ma.WindowEstimator, name.split(".")[1])
        return list(inspect.signature(method).parameters.values())[1:]
    return list(inspect.signature(_named(name)).parameters.values())


def _cases() -> Iterator[tuple[str, str, object]]:
    for name, (args, kwargs) in VALID.items():
        for i, parameter in enumerate(_parameters(name)):
            slot = parameter.name
            if (name, slot) in SKIPPED:
                continue
            if i >= len(args) and slot not in kwargs and parameter.default is parameter.empty:
                continue
            for bad in BAD_VALUES:
                yield name, slot, bad


def _with(name: str, slot: str, bad: object) -> Call:
    """The valid call of ``name`` with the argument ``slot`` replaced by ``bad``."""
    args, kwargs = VALID[name]
    position = [p.name for p in _parameters(name)].index(slot)
    if position < len(args):
        return (*args[:position], bad, *args[position + 1 :]), kwargs
    return args, {**kwargs, slot: bad}


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("public_arguments")
    ma.write_detections(folder / "d.csv", SCENARIO.scans, SENSORS)
    ma.write_tracks(folder / "t.csv", TRACKS)
    write_truth(folder / "truth.csv", SCENARIO.truth)
    write_config(folder / "c.toml", CONFIG)
    (folder / "recordings").mkdir()
    ma.write_detections(folder / "recordings" / "a.csv", SCENARIO.scans, SENSORS)
    return folder


def _call(name: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> object:
    args = tuple(ma.find_recordings("recordings") if _is(a, "<recordings>") else a for a in args)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return _named(name)(*args, **kwargs)


@pytest.mark.parametrize("name", sorted(VALID))
def test_the_valid_calls_are_valid(name: str, files: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(files)
    _call(name, *VALID[name])


@pytest.mark.parametrize(("name", "slot", "bad"), list(_cases()))
def test_none_text_or_an_integer_is_accepted_or_refused_naming_the_argument(
    name: str, slot: str, bad: object, files: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(files)
    args, kwargs = _with(name, slot, bad)
    try:
        _call(name, args, kwargs)
    except MapassocError as error:
        message = str(error)
        assert "\n" not in message
        if not isinstance(error, ma.ConfigError | ma.DataFileError | ma.OutputError):
            # A settings class names the configuration key of the field (InputError.key).
            named = [slot, slot.replace("_", " "), getattr(error, "key", None) or slot]
            assert any(word in message for word in named), message
    # Any other exception fails the test: it is a raw error from inside.


def test_every_public_callable_is_swept() -> None:
    names = {n for n in ma.__all__ if callable(getattr(ma, n))}
    swept = {n.split(".")[0] for n in VALID}
    assert names - swept - NOT_CALLED == set()
