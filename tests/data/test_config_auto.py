"""`"auto"` sensor parameters in the configuration: read, written, refused where unsafe."""

from __future__ import annotations

import pytest
from support import MINIMAL_CONFIG_TOML

from mapassoc.data.config import AutoParameters, config_to_toml, load_config, parse_config
from mapassoc.errors import ConfigError, InputError
from mapassoc.estimator.pipeline import WindowEstimator

BASE = (
    MINIMAL_CONFIG_TOML.replace("detection_probability = 0.9", "detection_probability = {pd}")
    .replace("false_alarms_per_scan = 10.0", "false_alarms_per_scan = {rate}")
    + "{extra}\n[birth]\n[estimator]\n"
)


def _text(pd: str = "0.9", rate: str = "10.0", extra: str = "") -> str:
    return BASE.format(pd=pd, rate=rate, extra=extra)


def _load(tmp_path, text: str):  # type: ignore[no-untyped-def]
    path = tmp_path / "config.toml"
    path.write_text(text)
    return load_config(path)


def test_auto_parameters_are_listed_with_their_start(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = _load(tmp_path, _text('"auto"', '"auto"', "detection_probability_start = 0.85"))
    assert config.auto == AutoParameters(("radar",), (("radar", 0.85),))
    assert config.auto.pending and config.auto.pd_starts() == {"radar": 0.85}
    only_rate = _load(tmp_path, _text(rate='"auto"'))
    assert only_rate.auto == AutoParameters(("radar",), ())
    assert only_rate.sensors["radar"].detection_probability == 0.9
    assert not _load(tmp_path, _text()).auto.pending


def test_auto_round_trips_through_toml(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import tomllib

    for extra in ("", "detection_probability_start = 0.85"):
        config = _load(tmp_path, _text('"auto"', '"auto"', extra))
        text = config_to_toml(config)
        again = parse_config(tomllib.loads(text))
        assert again.auto == config.auto
        assert 'false_alarms_per_scan = "auto"' in text
        assert 'detection_probability = "auto"' in text


@pytest.mark.parametrize(
    ("pd", "rate", "extra", "key", "message"),
    [
        ('"Auto"', "10.0", "", "sensors[0].detection_probability", 'or "auto"'),
        ("0.9", '"estimate"', "", "sensors[0].false_alarms_per_scan", 'or "auto"'),
        ("0.9", "10.0", "detection_probability_start = 0.8",
         "sensors[0].detection_probability_start", 'only goes with detection_probability = "auto"'),
        ('"auto"', "10.0", "detection_probability_start = 0.0",
         "sensors[0].detection_probability_start", "(0, 1]"),
        ('"auto"', "10.0", "detection_probability_start = 1.5",
         "sensors[0].detection_probability_start", ""),
    ],
)  # fmt: skip
def test_bad_auto_values_name_their_key(
    tmp_path, pd: str, rate: str, extra: str, key: str, message: str  # type: ignore[no-untyped-def]
) -> None:
    with pytest.raises(ConfigError) as info:
        _load(tmp_path, _text(pd, rate, extra))
    assert info.value.key == key
    assert message in str(info.value)


def test_nothing_runs_on_the_placeholders(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = _load(tmp_path, _text('"auto"', '"auto"'))
    with pytest.raises(InputError, match=r"false_alarms_per_scan, .*detection_probability = "
                       r"\"auto\"; estimate them from the recording first"):  # fmt: skip
        WindowEstimator(config=config)
    from mapassoc.trackers.registry import build_tracker

    with pytest.raises(InputError, match="estimate them from the recording first"):
        build_tracker("gnn", config=config, origins=None)
