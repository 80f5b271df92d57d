"""`"auto"` keys of the birth model in the configuration: read, written, refused where unsafe."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
from support import MINIMAL_CONFIG_TOML

from mapassoc.data.config import (
    BIRTH_PLACEHOLDERS,
    config_to_toml,
    load_config,
    parse_config,
)
from mapassoc.data.scans import Scan
from mapassoc.errors import ConfigError, InputError
from mapassoc.estimator.birth_estimation import BirthLevels, with_birth_levels
from mapassoc.estimator.pipeline import WindowEstimator


def _load(tmp_path, birth: str):  # type: ignore[no-untyped-def]
    path = tmp_path / "config.toml"
    path.write_text(MINIMAL_CONFIG_TOML + "\n[birth]\n" + birth + "\n[estimator]\n")
    return load_config(path)


ALL_AUTO = (
    'rate = "auto"\ninitial_count = "auto"\nsurvival_probability = "auto"\n'
    'velocity_std = "auto"\n'
)


def test_auto_birth_keys_are_listed_with_their_starts(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = _load(tmp_path, ALL_AUTO + "rate_start = 0.2\nsurvival_probability_start = 0.95")
    assert config.auto.birth_starts() == {
        "rate": 0.2, "initial_count": None, "survival_probability": 0.95, "velocity_std": None
    }  # fmt: skip
    assert config.auto.pending
    assert config.auto.names() == ["birth.rate", "birth.initial_count",
                                   "birth.survival_probability", "birth.velocity_std"]  # fmt: skip
    for key, value in BIRTH_PLACEHOLDERS.items():
        assert getattr(config.birth, key) == value
    one = _load(tmp_path, 'rate = "auto"\ninitial_count = 4.0\nvelocity_std = 3.0')
    assert one.auto.birth_starts() == {"rate": None}
    assert one.birth.initial_count == 4.0 and one.birth.velocity_std == 3.0
    assert not _load(tmp_path, "rate = 0.2").auto.pending


def test_auto_birth_keys_round_trip_through_toml(tmp_path) -> None:  # type: ignore[no-untyped-def]
    for extra in ("", "rate_start = 0.2\nvelocity_std_start = 5.0"):
        config = _load(tmp_path, ALL_AUTO + extra)
        text = config_to_toml(config)
        assert 'rate = "auto"' in text and 'velocity_std = "auto"' in text
        assert ("rate_start = 0.2" in text) == bool(extra)
        assert parse_config(tomllib.loads(text)).auto == config.auto


@pytest.mark.parametrize(
    ("birth", "key", "message"),
    [
        ("rate = 0.2\nrate_start = 0.3", "birth.rate_start", 'only goes with rate = "auto"'),
        ("velocity_std_start = 3.0", "birth.velocity_std_start",
         'only goes with velocity_std = "auto"'),
        ('rate = "auto"\nrate_start = -1.0', "birth.rate_start", ""),
        ('survival_probability = "auto"\nsurvival_probability_start = 1.5',
         "birth.survival_probability_start", ""),
        ('speed_std = "auto"', "birth.speed_std", '"auto" is only for [birth] rate'),
        ('rate = "Auto"', "birth.rate", ""),
        ("rate_typo = 1.0", "birth.rate_typo", "unknown key"),
    ],
)  # fmt: skip
def test_bad_auto_birth_values_name_their_key(tmp_path, birth: str, key: str, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError) as info:
        _load(tmp_path, birth)
    assert info.value.key == key
    assert message in str(info.value)


def test_velocity_std_auto_needs_velocity_components(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "config.toml"
    path.write_text(
        MINIMAL_CONFIG_TOML.replace('model = "constant_velocity"', 'model = "random_walk"')
        + '\n[birth]\nvelocity_std = "auto"\n[estimator]\n'
    )
    with pytest.raises(ConfigError) as info:
        load_config(path)
    assert info.value.key == "birth.velocity_std"
    assert "velocity components" in str(info.value)


def test_nothing_runs_on_the_birth_placeholders(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = _load(tmp_path, 'rate = "auto"\nsurvival_probability = "auto"')
    with pytest.raises(InputError, match=r"birth.rate, birth.survival_probability = \"auto\"; "
                       "estimate them from the recording first"):  # fmt: skip
        WindowEstimator(config=config)


def test_a_configuration_with_the_estimates_is_written_loads_and_runs(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = _load(tmp_path, ALL_AUTO)
    values = {"rate": 0.05, "initial_count": 2.0, "survival_probability": 0.97,
              "velocity_std": 1.5}  # fmt: skip
    filled = with_birth_levels(config, BirthLevels(values))
    assert not filled.auto.pending
    text = config_to_toml(filled)
    assert '"auto"' not in text
    again = parse_config(tomllib.loads(text))
    assert {key: getattr(again.birth, key) for key in values} == values
    scans = [Scan(float(t), "radar", np.array([[1.0 * t, 0.0]]), np.array([t])) for t in range(6)]
    result = WindowEstimator(config=again).run(scans)
    assert sorted(len(rows) for rows in result.track_rows.values()) == [6]
