"""``[motion] model = "imm"`` in configuration files: reading the interacting models,
writing them back, the key each bad value is reported under, and a run on a loaded file."""

from __future__ import annotations

import copy
import dataclasses
import tomllib
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from support import SENSOR, make_scans

from mapassoc.data.config import (
    MOTION_MODELS,
    Config,
    config_to_toml,
    load_config,
    parse_config,
    write_config,
)
from mapassoc.errors import ConfigError
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.models.interacting import InteractingModels
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import ConstantVelocity

IMM_TOML = f"""
[motion]
model = "imm"
switch_probability = 0.05
initial_probabilities = [0.25, 0.75]

[[motion.models]]
model = "constant_velocity"
ndim = 2
noise_intensity = 1.0

[[motion.models]]
model = "constant_velocity"
ndim = 2
noise_intensity = 100.0

[[sensors]]
name = "{SENSOR}"
measurement = "position"
noise_std = 1.0
detection_probability = 0.9
false_alarms_per_scan = 1e-6
region = [[-100.0, 100.0], [-100.0, 100.0]]

[birth]
rate = 0.1
initial_count = 2.0
velocity_std = 5.0

[estimator.windows]
window_length = 3
"""


def _document() -> dict[str, object]:
    return tomllib.loads(IMM_TOML)


def _parse(document: dict[str, object]) -> Config:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # no [estimator.<other>] tables
        return parse_config(document)


def _imm(config: Config) -> InteractingModels:
    assert isinstance(config.motion, InteractingModels)
    return config.motion


def test_the_issue_example_loads_into_interacting_models() -> None:
    motion = _imm(_parse(_document()))
    assert [type(model) for model in motion.models] == [ConstantVelocity, ConstantVelocity]
    assert [model.noise_intensity for model in motion.models] == [1.0, 100.0]
    assert [model.ndim for model in motion.models] == [2, 2]
    assert motion.switching.n_models == 2
    assert motion.switching.switch_probability == 0.05 and motion.switching.matrix is None
    assert motion.initial_probabilities.tolist() == [0.25, 0.75]


def test_initial_probabilities_default_to_uniform_and_a_matrix_is_read() -> None:
    document = _document()
    motion_table = document["motion"]
    assert isinstance(motion_table, dict)
    del motion_table["initial_probabilities"], motion_table["switch_probability"]
    motion_table["matrix"] = [[0.9, 0.1], [0.2, 0.8]]
    motion = _imm(_parse(document))
    assert motion.initial_probabilities.tolist() == [0.5, 0.5]
    assert motion.switching.switch_probability is None
    assert motion.switching.matrix is not None
    assert motion.switching.matrix.tolist() == [[0.9, 0.1], [0.2, 0.8]]
    # the law is the file's per unit of time
    assert np.allclose(motion.switching.at(1.0), [[0.9, 0.1], [0.2, 0.8]])


def test_a_position_sensor_measures_the_common_state() -> None:
    config = _parse(_document())
    measurement = config.sensors[SENSOR].measurement
    assert isinstance(measurement, LinearMeasurement)
    one_model = ConstantVelocity(ndim=2, noise_intensity=1.0)
    single = LinearMeasurement.position(one_model, noise_std=1.0)
    assert np.array_equal(measurement.H, single.H)
    assert np.array_equal(measurement.noise_covariance, np.eye(2))


def _assert_same_imm(got: InteractingModels, want: InteractingModels) -> None:
    assert [type(m) for m in got.models] == [type(m) for m in want.models]
    assert [repr(m) for m in got.models] == [repr(m) for m in want.models]
    assert got.switching.switch_probability == want.switching.switch_probability
    if want.switching.matrix is None:
        assert got.switching.matrix is None
    else:
        assert got.switching.matrix is not None
        assert np.array_equal(got.switching.matrix, want.switching.matrix)
    assert np.array_equal(got.initial_probabilities, want.initial_probabilities)


@pytest.mark.parametrize(
    "law",
    [{"switch_probability": 0.05}, {"matrix": [[0.9, 0.1], [1 / 3, 2 / 3]]}],
    ids=["switch_probability", "matrix"],
)
def test_round_trip_read_write_read(law: dict[str, object]) -> None:
    document = _document()
    motion_table = document["motion"]
    assert isinstance(motion_table, dict)
    del motion_table["switch_probability"]
    motion_table.update(law)
    config = _parse(document)
    text = config_to_toml(config)
    assert '[motion]\nmodel = "imm"\n' in text and text.count("[[motion.models]]") == 2
    again = _parse(tomllib.loads(text))
    _assert_same_imm(_imm(again), _imm(config))
    assert config_to_toml(again) == text  # a fixed point


def test_write_config_and_load_config_round_trip(tmp_path: Path) -> None:
    config = _parse(_document())
    path = tmp_path / "imm.toml"
    write_config(path, config)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # every section is written
        loaded = load_config(path)
    _assert_same_imm(_imm(loaded), _imm(config))


def _set(path: tuple[str, ...], value: object) -> Callable[[dict], None]:
    def mutate(data: dict) -> None:
        table = data
        for part in path[:-1]:
            table = table[int(part)] if isinstance(table, list) else table[part]
        table[path[-1]] = value

    return mutate


def _delete(*path: str) -> Callable[[dict], None]:
    def mutate(data: dict) -> None:
        table = data
        for part in path[:-1]:
            table = table[part]
        del table[path[-1]]

    return mutate


def _both(data: dict) -> None:
    data["motion"]["matrix"] = [[0.9, 0.1], [0.1, 0.9]]


def _nested(data: dict) -> None:
    data["motion"]["models"][1] = copy.deepcopy(data["motion"])


def _component(index: int, **values: object) -> Callable[[dict], None]:
    def mutate(data: dict) -> None:
        data["motion"]["models"][index].update(values)

    return mutate


def _swap(data: dict) -> None:
    del data["motion"]["switch_probability"]
    data["motion"]["matrix"] = [[0.9, 0.1], [0.1]]


def _no_generator(data: dict) -> None:
    del data["motion"]["switch_probability"]
    data["motion"]["matrix"] = [[0.0, 1.0], [1.0, 0.0]]  # a swap every unit: no generator


BAD = [
    (_delete("motion", "models"), "motion.models", "missing required key"),
    (_set(("motion", "models"), []), "motion.models", "non-empty array of tables"),
    (_set(("motion", "models"), 3), "motion.models", "got 3"),
    (_set(("motion", "models"), [1, 2]), "motion.models", "array of tables"),
    (_nested, "motion.models[1].model", "must be single models, got 'imm'"),
    (_component(0, model="bicycle"), "motion.models[0].model", "imm; got 'bicycle'"),
    (_component(0, speed=1.0), "motion.models[0].speed", "unknown key"),
    (_component(1, noise_intensity=-1.0), "motion.models[1].noise_intensity", "got -1.0"),
    (_component(1, ndim=4), "motion.models[1].ndim", "got 4"),
    (_both, "motion", "exactly one of switch_probability and matrix"),
    (_delete("motion", "switch_probability"), "motion", "got neither"),
    (_set(("motion", "switch_probability"), 0.6), "motion.switch_probability", "got 0.6"),
    (_set(("motion", "switch_probability"), "low"), "motion.switch_probability", "got 'low'"),
    (_swap, "motion.matrix", "square"),
    (_no_generator, "motion.matrix", "no continuous-time chain"),
    (_set(("motion", "initial_probabilities"), [1.0]), "motion.initial_probabilities",
     "2 probabilities"),
    (_set(("motion", "initial_probabilities"), 0.5), "motion.initial_probabilities",
     "must be an array"),
    (_component(1, ndim=3), "motion.models[1]", "one state space"),
    (_set(("motion", "noise_intensity"), 1.0), "motion.noise_intensity", "allowed keys for imm"),
]  # fmt: skip


@pytest.mark.parametrize(("mutate", "key", "fragment"), BAD)
def test_bad_imm_config_names_its_key(
    mutate: Callable[[dict], None], key: str, fragment: str
) -> None:
    data = _document()
    mutate(data)
    with pytest.raises(ConfigError) as info:
        parse_config(data, source="imm.toml")
    assert info.value.key == key
    message = str(info.value)
    assert message.startswith(f"imm.toml: config key '{key}': ")
    assert fragment in message


def test_the_allowed_model_names_include_imm() -> None:
    data = _document()
    data["motion"] = {"model": "bicycle"}
    with pytest.raises(ConfigError) as info:
        parse_config(data)
    assert info.value.key == "motion.model"
    assert "imm" in str(info.value) and "constant_velocity" in str(info.value)


def test_a_loaded_imm_config_runs_the_estimator() -> None:
    config = _parse(_document())
    times = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    # one target straight along x, one turning hard halfway (the agile model's case)
    first = [[-50.0 + 5.0 * t, 0.0] for t in times]
    second = [[20.0, 40.0 - 4.0 * t] if t < 3 else [20.0 + 6.0 * (t - 3), 28.0] for t in times]
    scans = make_scans(times, [[a, b] for a, b in zip(first, second, strict=True)], dz=2)
    result = WindowEstimator(config=config).run(scans)
    assert result.num_scans == len(times)
    # two tracks, each made of one target's detections (rows 2, 4, ... and 3, 5, ...)
    tracks = sorted(sorted(rows) for rows in result.track_rows.values())
    assert tracks == [list(range(2, 14, 2)), list(range(3, 14, 2))]


def test_the_configuration_names_include_imm() -> None:
    assert MOTION_MODELS[-1] == "imm" and "constant_velocity" in MOTION_MODELS


class _OwnVelocity(ConstantVelocity):
    """A constant-velocity model of its own class: not registered, so not writable."""


def test_the_writer_names_the_component_it_cannot_write() -> None:
    config = _parse(_document())
    motion = _imm(config)
    own = InteractingModels(
        models=[motion.models[0], _OwnVelocity(ndim=2, noise_intensity=3.0)],
        switching=motion.switching,
    )
    with pytest.raises(ConfigError) as info:
        config_to_toml(dataclasses.replace(config, motion=own))
    assert info.value.key == "motion.models[1]"
    assert "cannot write motion model" in str(info.value)


def test_a_matrix_for_another_number_of_models_names_the_matrix() -> None:
    data = _document()
    del data["motion"]["switch_probability"]  # type: ignore[attr-defined]
    data["motion"]["matrix"] = np.eye(3).tolist()  # type: ignore[index]
    with pytest.raises(ConfigError) as info:
        parse_config(data)
    assert info.value.key == "motion.matrix"
    assert "(2, 2) for n_models = 2" in str(info.value)
