"""The estimator's settings as one record per component: every field reachable from TOML
and written back, the old flat keys loading (with one deprecation warning naming the keys
that replace them) to the same configuration."""

from __future__ import annotations

import copy
import dataclasses
import math
import tomllib
import warnings
from pathlib import Path
from typing import Any

import pytest
from support import MINIMAL_CONFIG_TOML

from mapassoc.data.config import config_to_toml, load_config, parse_config
from mapassoc.data.settings import (
    COMPONENTS,
    FLAT_KEYS,
    CountSettings,
    EstimatorSettings,
    ParameterSettings,
    PruningSettings,
    RefinementSettings,
    SearchSettings,
    WindowSettings,
)
from mapassoc.errors import ConfigError, InputError

# A value other than the default for every field of every record (a consistent set).
NON_DEFAULT: dict[str, dict[str, Any]] = {
    "windows": {"window_length": 7, "stride": 2, "time_limit": 3.5},
    "pruning": {
        "gate_probability": 0.99,
        "max_hypotheses_per_tree": 32,
        "prune_log_ratio": 7.5,
        "sibling_prune_log_ratio": math.inf,
    },
    "search": {
        "solver": "cvxpy-highs",
        "exact_work_limit": 1000,
        "beam_width": 50,
        "bound_prune_log_ratio": 11.0,
        "program_time_limit": 0.25,
        "beam_entry_margin": 30.0,
        "mass_bound_multiplier_limit": 12.0,
        "mass_bound_multipliers": 7,
    },
    "count": {
        "max_tracks": 3,
        "k_prior": "weights",
        "k_prior_mean": 2.5,
        "k_prior_weights": [1.0, 2.0, 0.5, 0.25],
        "k_estimate": "median",
    },
    "refinement": {
        "passes": 2,
        "window_length": 4,
        "long_window_length": 12,
        "stride": 3,
        "scan_windows": False,
        "link_gap": 4,
        "refilter_detections": 7,
        "prune_log_ratio": 20.0,
        "long_prune_log_ratio": 6.0,
        "identity_moves": False,
        "group_moves": False,
        "min_existence": 0.3,
    },
    "parameters": {
        "rate_tolerance": 0.05,
        "pd_tolerance": 0.01,
        "max_passes": 5,
        "sample_scans": 300,
        "sample_blocks_count": 3,
        "soft_counts": False,
    },
}


def document(estimator: dict[str, Any] | None) -> dict[str, Any]:
    data = copy.deepcopy(tomllib.loads(MINIMAL_CONFIG_TOML))
    data["birth"] = {"rate": 0.2}
    if estimator is not None:
        data["estimator"] = estimator
    return data


def test_the_table_sets_every_field_of_every_record() -> None:
    for name, cls in COMPONENTS.items():
        assert set(NON_DEFAULT[name]) == {f.name for f in dataclasses.fields(cls)}, name
        default = getattr(EstimatorSettings(), name)
        for field, value in NON_DEFAULT[name].items():
            assert getattr(default, field) != value, f"{name}.{field} is its default"


def test_every_field_is_read_from_toml_and_written_back() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new layout warns of nothing
        config = parse_config(document(copy.deepcopy(NON_DEFAULT)))
    for name, values in NON_DEFAULT.items():
        record = getattr(config.estimator, name)
        for field, value in values.items():
            got = getattr(record, field)
            assert (list(got) if isinstance(got, tuple) else got) == value, (name, field)
    text = config_to_toml(config)
    for name in COMPONENTS:
        assert f"\n[estimator.{name}]\n" in text
    assert "scan_windows = false\n" in text and "long_window_length = 12\n" in text
    again = parse_config(tomllib.loads(text))
    assert again.estimator == config.estimator
    assert config_to_toml(again) == text  # parse -> write -> parse is a fixed point


def test_records_missing_from_the_file_take_the_estimators_defaults() -> None:
    config = parse_config(document({"windows": {"window_length": 4}}))
    assert config.estimator == EstimatorSettings(windows=WindowSettings(window_length=4))
    # the refinement's long windows at the forward pass's width, as before the records
    assert config.estimator.refinement.long_prune_log_ratio == 9.0
    assert RefinementSettings().long_prune_log_ratio is None  # the record's own default


def test_an_unknown_key_in_a_table_names_the_table_and_its_keys() -> None:
    with pytest.raises(ConfigError) as info:
        parse_config(document({"windows": {"length": 4}}))
    assert info.value.key == "estimator.windows.length"
    assert "window_length, stride, time_limit" in str(info.value)
    with pytest.raises(ConfigError) as info:
        parse_config(document({"windowz": {}}))
    assert info.value.key == "estimator.windowz"


# One non-default value per old flat key, and the same configuration in the new layout.
FLAT_VALUES: dict[str, Any] = {
    "window_length": 7,
    "stride": 2,
    "max_tracks": 3,
    "gate_probability": 0.99,
    "max_hypotheses_per_tree": 32,
    "prune_log_ratio": 7.5,
    "sibling_prune_log_ratio": math.inf,
    "k_prior": "poisson",
    "k_prior_mean": 2.5,
    "k_prior_weights": [1.0, 2.0],
    "k_estimate": "joint",
    "solver": "cvxpy-highs",
    "time_limit": 600.0,
    "exact_work_limit": 1000,
    "beam_width": 50,
    "refine_passes": 2,
    "refine_link_gap": 4,
    "refine_prune_log_ratio": 20.0,
    "min_existence": 0.3,
}


@pytest.mark.parametrize("name", list(FLAT_KEYS))
def test_each_old_key_warns_naming_its_new_keys_and_gives_the_same_config(
    name: str, tmp_path: Path
) -> None:
    value = FLAT_VALUES[name]
    old = tmp_path / "old.toml"
    old.write_text(config_to_toml(parse_config(document(None))).split("[estimator.")[0]
                   + f"[estimator]\n{name} = {_toml(value)}\n")  # fmt: skip
    with pytest.warns(DeprecationWarning) as caught:
        config = load_config(old)
    messages = [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]
    assert len(messages) == 1
    for record, field in FLAT_KEYS[name]:
        assert f"{name} -> " in messages[0] and f"estimator.{record}.{field}" in messages[0]
    assert str(old) in messages[0] and "mapassoc migrate-config" in messages[0]
    new: dict[str, dict[str, Any]] = {}
    for record, field in FLAT_KEYS[name]:
        new.setdefault(record, {})[field] = value
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        expected = parse_config(document(new))
    assert config.estimator == expected.estimator
    assert getattr(config.estimator, name) == _python(value)  # the read-only alias
    assert config.estimator == EstimatorSettings(**{name: _python(value)})


def _toml(value: object) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list):
        return "[" + ", ".join(repr(v) for v in value) + "]"
    return "inf" if value == math.inf else repr(value)


def _python(value: object) -> object:
    return tuple(value) if isinstance(value, list) else value


def test_the_old_keys_that_set_several_things_set_each() -> None:
    settings = EstimatorSettings(time_limit=600.0, prune_log_ratio=5.0)
    assert settings.windows.time_limit == settings.search.program_time_limit == 600.0
    assert settings.pruning.prune_log_ratio == 5.0
    assert settings.search.bound_prune_log_ratio == 5.0
    assert settings.refinement.long_prune_log_ratio == 5.0
    assert settings.refinement.prune_log_ratio == 18.0  # refine_prune_log_ratio's own
    replaced = dataclasses.replace(settings, refine_passes=0)  # the aliases replace too
    assert replaced.refinement.passes == 0 and replaced.windows == settings.windows


def test_a_setting_given_by_its_old_key_and_its_new_one_is_refused() -> None:
    with pytest.raises(ConfigError) as info, warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        parse_config(document({"time_limit": 5.0, "search": {"program_time_limit": 1.0}}))
    assert info.value.key == "estimator.time_limit"
    assert "keep estimator.search.program_time_limit" in str(info.value)


def test_an_unknown_solver_is_named_by_the_key_it_was_given_as() -> None:
    with pytest.raises(ConfigError) as info:
        parse_config(document({"search": {"solver": "gurobi"}}), solver_names=["highs"])
    assert info.value.key == "estimator.search.solver"
    with pytest.raises(ConfigError) as info, warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        parse_config(document({"solver": "gurobi"}), solver_names=["highs"])
    assert info.value.key == "estimator.solver"


def test_records_are_checked_where_they_are_composed() -> None:
    with pytest.raises(InputError, match="windows must be a WindowSettings"):
        EstimatorSettings(windows=PruningSettings())  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"no settings \['colour'\]; its records are"):
        EstimatorSettings(colour=1)
    composed = EstimatorSettings(
        windows=WindowSettings(),
        pruning=PruningSettings(),
        search=SearchSettings(),
        count=CountSettings(),
        refinement=RefinementSettings(long_prune_log_ratio=9.0),
        parameters=ParameterSettings(),
    )
    assert composed == EstimatorSettings()
