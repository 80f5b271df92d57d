"""Settings as a run folder's manifest records them: valid JSON, read back equal."""

from __future__ import annotations

import json
import math

import pytest

from mapassoc.data.settings import (
    BirthModel,
    EstimatorSettings,
    settings_from_json,
    settings_to_json,
)
from mapassoc.errors import InputError


@pytest.mark.parametrize(
    "settings",
    [
        EstimatorSettings(),
        EstimatorSettings(
            prune_log_ratio=math.inf,
            sibling_prune_log_ratio=math.inf,
            refine_prune_log_ratio=math.inf,
            k_prior="weights",
            k_prior_weights=(1.0, 2.5, 0.0),
            max_tracks=2,
        ),
        BirthModel(rate=0.2, survival_probability=1.0),
    ],
)
def test_settings_round_trip_through_strict_json(
    settings: EstimatorSettings | BirthModel,
) -> None:
    text = json.dumps(settings_to_json(settings), allow_nan=False)
    assert settings_from_json(type(settings), json.loads(text)) == settings


def test_infinite_widths_are_written_as_inf() -> None:
    record = settings_to_json(EstimatorSettings(prune_log_ratio=math.inf))
    assert record["pruning"]["prune_log_ratio"] == "inf"  # type: ignore[index]
    assert record["pruning"]["sibling_prune_log_ratio"] is None  # type: ignore[index]
    assert record["search"]["solver"] == "highs"  # type: ignore[index]


def test_a_record_of_the_old_flat_keys_reads_as_the_same_settings() -> None:
    """Run folders written before the records hold the flat form; it reads back equal."""
    flat = {"prune_log_ratio": "inf", "time_limit": 600.0, "k_prior": "uniform"}
    assert settings_from_json(EstimatorSettings, flat) == EstimatorSettings(
        prune_log_ratio=math.inf, time_limit=600.0, k_prior="uniform"
    )


def test_a_bad_record_names_the_field() -> None:
    with pytest.raises(InputError, match="prune_log_ratio: .*'lots'"):
        settings_from_json(EstimatorSettings, {"prune_log_ratio": "lots"})
    with pytest.raises(InputError, match="no fields \\['colour'\\]"):
        settings_from_json(EstimatorSettings, {"colour": 1})
    with pytest.raises(InputError, match="windows: expected an object"):
        settings_from_json(EstimatorSettings, {"windows": 5})
