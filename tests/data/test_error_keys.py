"""Tests of ``InputError.key``: the settings dataclasses name the offending field.

:mod:`mapassoc.data.config` reports ``<section>.<key>`` from it, so every validated field of
:class:`BirthModel` and of each record :class:`EstimatorSettings` composes must set it (and
an old flat key of ``EstimatorSettings`` is reported under the name it was given as).
"""

from __future__ import annotations

import copy
import dataclasses
import tomllib

import pytest
from support import MINIMAL_CONFIG_TOML

from mapassoc.data.config import parse_config
from mapassoc.data.settings import (
    FLAT_KEYS,
    BirthModel,
    CountSettings,
    EstimatorSettings,
    ParameterSettings,
    PruningSettings,
    RefinementSettings,
    SearchSettings,
    WindowSettings,
)
from mapassoc.errors import ConfigError, InputError
from mapassoc.estimator.posterior import CountPrior

# One bad value per validated field, typed as the TOML reader hands it over (so the
# same table drives the constructor and the config reader), plus the other fields it
# needs to be checked at all.
BAD_BIRTH: dict[str, tuple[object, dict[str, object]]] = {
    "rate": (-0.1, {}),
    "initial_count": (-1.0, {}),
    "velocity_std": (0.0, {}),
    "acceleration_std": (-1.0, {}),
    "speed_std": (0.0, {}),
    "turn_rate_std": (float("inf"), {}),
    "survival_probability": (0.0, {}),
}

BAD_WINDOWS: dict[str, tuple[object, dict[str, object]]] = {
    "window_length": (0, {}),
    "stride": (6, {"window_length": 5}),
    "time_limit": (0.0, {}),
}
BAD_PRUNING: dict[str, tuple[object, dict[str, object]]] = {
    "gate_probability": (1.5, {}),
    "max_hypotheses_per_tree": (0, {}),
    "prune_log_ratio": (-1.0, {}),
    "sibling_prune_log_ratio": (-1.0, {}),
}
BAD_SEARCH: dict[str, tuple[object, dict[str, object]]] = {
    "solver": ("", {}),
    "exact_work_limit": (0, {}),
    "beam_width": (0, {}),
    "bound_prune_log_ratio": (-1.0, {}),
    "program_time_limit": (0.0, {}),
    "beam_entry_margin": (0.0, {}),
    "mass_bound_multiplier_limit": (-1.0, {}),
    "mass_bound_multipliers": (0, {}),
}
BAD_COUNT: dict[str, tuple[object, dict[str, object]]] = {
    "max_tracks": (-1, {}),
    "k_prior": ("flat", {}),
    "k_prior_mean": (0.0, {}),
    "k_prior_weights": ((1.0,), {"k_prior": "weights", "max_tracks": 2}),
    "k_estimate": ("mode", {}),
}
BAD_REFINEMENT: dict[str, tuple[object, dict[str, object]]] = {
    "passes": (-1, {}),
    "window_length": (0, {}),
    "long_window_length": (0, {}),
    "stride": (0, {}),
    "scan_windows": (1, {}),
    "link_gap": (-1, {}),
    "refilter_detections": (0, {}),
    "prune_log_ratio": (-1.0, {}),
    "long_prune_log_ratio": (-1.0, {}),
    "identity_moves": (1, {}),
    "group_moves": (1, {}),
    "min_existence": (1.5, {}),
}
BAD_PARAMETERS: dict[str, tuple[object, dict[str, object]]] = {
    "rate_tolerance": (0.0, {}),
    "pd_tolerance": (-1.0, {}),
    "max_passes": (0, {}),
    "sample_scans": (0, {}),
    "sample_blocks_count": (0, {}),
    "soft_counts": (1, {}),
}
# The old flat keys of EstimatorSettings (FLAT_KEYS): an error names the key as given.
BAD_FLAT: dict[str, tuple[object, dict[str, object]]] = {
    "window_length": (0, {}),
    "stride": (6, {"window_length": 5}),
    "max_tracks": (-1, {}),
    "gate_probability": (1.5, {}),
    "max_hypotheses_per_tree": (0, {}),
    "prune_log_ratio": (-1.0, {}),
    "sibling_prune_log_ratio": (-1.0, {}),
    "k_prior": ("flat", {}),
    "k_prior_mean": (0.0, {}),
    "k_prior_weights": ((1.0,), {"k_prior": "weights", "max_tracks": 2}),
    "k_estimate": ("mode", {}),
    "solver": ("", {}),
    "time_limit": (0.0, {}),
    "exact_work_limit": (0, {}),
    "beam_width": (0, {}),
    "refine_passes": (-1, {}),
    "refine_link_gap": (-1, {}),
    "refine_prune_log_ratio": (-1.0, {}),
    "min_existence": (1.5, {}),
}

RECORDS: dict[str, tuple[type, dict[str, tuple[object, dict[str, object]]]]] = {
    "birth": (BirthModel, BAD_BIRTH),
    "estimator.windows": (WindowSettings, BAD_WINDOWS),
    "estimator.pruning": (PruningSettings, BAD_PRUNING),
    "estimator.search": (SearchSettings, BAD_SEARCH),
    "estimator.count": (CountSettings, BAD_COUNT),
    "estimator.refinement": (RefinementSettings, BAD_REFINEMENT),
    "estimator.parameters": (ParameterSettings, BAD_PARAMETERS),
}

CASES = [
    (section, cls, name, bad, extra)
    for section, (cls, table) in RECORDS.items()
    for name, (bad, extra) in table.items()
]
FLAT_CASES = [(name, bad, extra) for name, (bad, extra) in BAD_FLAT.items()]


def _validated_fields(cls: type) -> set[str]:
    """Every field of ``cls``: each has a validation rule (the table must cover it)."""
    return {field.name for field in dataclasses.fields(cls)}


@pytest.mark.parametrize(("cls", "table"), list(RECORDS.values()), ids=list(RECORDS))
def test_table_covers_every_validated_field(
    cls: type, table: dict[str, tuple[object, dict[str, object]]]
) -> None:
    assert set(table) == _validated_fields(cls), (
        f"{cls.__name__}: give every validated field a bad value in this table"
    )
    cls()  # the defaults are valid


def test_the_flat_table_covers_every_old_key() -> None:
    assert set(BAD_FLAT) == set(FLAT_KEYS)


@pytest.mark.parametrize(
    ("section", "cls", "name", "bad", "extra"), CASES, ids=[f"{c[0]}.{c[2]}" for c in CASES]
)
def test_settings_error_names_the_field(
    section: str, cls: type, name: str, bad: object, extra: dict[str, object]
) -> None:
    with pytest.raises(InputError) as info:
        cls(**extra, **{name: bad})
    assert info.value.key == name
    assert name in str(info.value)


def _document(section: str, table: dict[str, object]) -> dict[str, object]:
    data = copy.deepcopy(tomllib.loads(MINIMAL_CONFIG_TOML))
    table = {k: list(v) if isinstance(v, tuple) else v for k, v in table.items()}
    if section.startswith("estimator."):
        data["estimator"] = {section.split(".", 1)[1]: table}
    else:
        data[section] = table
    return data


@pytest.mark.parametrize(
    ("section", "cls", "name", "bad", "extra"), CASES, ids=[f"{c[0]}.{c[2]}" for c in CASES]
)
def test_config_reports_section_and_field(
    section: str, cls: type, name: str, bad: object, extra: dict[str, object]
) -> None:
    with pytest.raises(InputError) as direct:
        cls(**extra, **{name: bad})
    with pytest.raises(ConfigError) as info:
        parse_config(_document(section, {**extra, name: bad}), source="bad.toml")
    assert info.value.key == f"{section}.{name}"
    assert str(info.value) == f"bad.toml: config key '{section}.{name}': {direct.value}"


@pytest.mark.parametrize(("name", "bad", "extra"), FLAT_CASES, ids=[c[0] for c in FLAT_CASES])
def test_an_old_flat_key_error_names_the_key_as_given(
    name: str, bad: object, extra: dict[str, object]
) -> None:
    with pytest.raises(InputError) as direct:
        EstimatorSettings(**extra, **{name: bad})
    assert direct.value.key == name
    with pytest.raises(ConfigError) as info:  # refused before the deprecation is told
        parse_config(_document("estimator", {**extra, name: bad}), source="bad.toml")
    assert info.value.key == f"estimator.{name}"
    assert str(info.value) == f"bad.toml: config key 'estimator.{name}': {direct.value}"


def test_weight_entry_error_names_the_entry() -> None:
    with pytest.raises(InputError) as info:
        EstimatorSettings(max_tracks=2, k_prior="weights", k_prior_weights=(1.0, -1.0, 0.0))
    assert info.value.key == "k_prior_weights[1]"
    with pytest.raises(InputError) as info:
        EstimatorSettings(max_tracks=1, k_prior="weights", k_prior_weights=(0.0, 0.0))
    assert info.value.key == "k_prior_weights"
    assert str(info.value) == "k_prior_weights must have at least one positive entry"


def test_count_prior_names_the_settings_field() -> None:
    with pytest.raises(InputError) as info:
        CountPrior(kmax=-1)
    assert info.value.key == "max_tracks"


def test_key_defaults_to_none_and_message_is_unchanged() -> None:
    error = InputError("x must be positive, got -1")
    assert error.key is None
    assert str(error) == "x must be positive, got -1"
    assert error.args == ("x must be positive, got -1",)
    keyed = InputError("rate must be positive, got -1", key="rate")
    assert (keyed.key, str(keyed)) == ("rate", "rate must be positive, got -1")
    with pytest.raises(TypeError):
        InputError("message", "rate")  # type: ignore[misc]
