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


def _noise_text(q: str = "0.5", std: str = "1.0", motion_extra: str = "",
                sensor_extra: str = "") -> str:  # fmt: skip
    text = _text().replace("noise_intensity = 0.5", f"noise_intensity = {q}{motion_extra}")
    return text.replace("noise_std = 1.0", f"noise_std = {std}{sensor_extra}")


def test_auto_noise_levels_are_listed_with_their_start(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = _load(tmp_path, _noise_text('"auto"', '"auto"'))
    assert config.auto.noise_intensity and config.auto.noise_intensity_start is None
    assert config.auto.noise_std_starts() == {"radar": None}
    assert config.auto.pending
    assert config.auto.names() == ["motion.noise_intensity", "sensor 'radar' noise_std"]
    started = _load(tmp_path, _noise_text('"auto"', '"auto"', "\nnoise_intensity_start = 2.0",
                                          "\nnoise_std_start = [1.5, 2.5]"))  # fmt: skip
    assert started.auto.noise_intensity_start == 2.0
    assert started.auto.noise_std_starts() == {"radar": (1.5, 2.5)}
    pooled = _load(tmp_path, _noise_text(std='"auto"', sensor_extra="\nnoise_std_start = 3.0"))
    assert pooled.auto.noise_std_starts() == {"radar": (3.0,)}
    assert not pooled.auto.noise_intensity and pooled.motion.noise_intensity == 0.5


def test_auto_noise_levels_round_trip_through_toml(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import tomllib

    for motion_extra, sensor_extra in (("", ""), ("\nnoise_intensity_start = 2.0",
                                                  "\nnoise_std_start = [1.5, 2.5]"),
                                       ("", "\nnoise_std_start = 3.0")):  # fmt: skip
        config = _load(tmp_path, _noise_text('"auto"', '"auto"', motion_extra, sensor_extra))
        text = config_to_toml(config)
        assert 'noise_intensity = "auto"' in text and 'noise_std = "auto"' in text
        assert parse_config(tomllib.loads(text)).auto == config.auto


@pytest.mark.parametrize(
    ("text", "key", "message"),
    [
        (_noise_text(motion_extra="\nnoise_intensity_start = 2.0"),
         "motion.noise_intensity_start", 'only goes with noise_intensity = "auto"'),
        (_noise_text('"auto"', motion_extra="\nnoise_intensity_start = -1.0"),
         "motion.noise_intensity_start", ""),
        (_noise_text(sensor_extra="\nnoise_std_start = 2.0"),
         "sensors[0].noise_std_start", 'only goes with noise_std = "auto"'),
        (_noise_text(std='"auto"', sensor_extra="\nnoise_std_start = [1.0, 2.0, 3.0]"),
         "sensors[0].noise_std_start", "one standard deviation per position component (2)"),
        (_noise_text().replace(
            'model = "constant_velocity"\nndim = 2\nnoise_intensity = 0.5',
            'model = "coordinated_turn"\nspeed_noise_intensity = "auto"\n'
            "turn_rate_noise_intensity = 0.01"),
         "motion.speed_noise_intensity", '"auto" is only for [motion] noise_intensity'),
    ],
)  # fmt: skip
def test_bad_auto_noise_values_name_their_key(tmp_path, text: str, key: str, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError) as info:
        _load(tmp_path, text)
    assert info.value.key == key
    assert message in str(info.value)


def test_a_range_bearing_std_cannot_be_auto(tmp_path) -> None:  # type: ignore[no-untyped-def]
    text = _text().replace(
        'measurement = "position"\nnoise_std = 1.0',
        'measurement = "range_bearing"\nposition = [0.0, 0.0]\nrange_std = "auto"\n'
        "bearing_std = 0.01",
    ).replace("region = [[-100.0, 100.0], [-100.0, 100.0]]", "region = [[0.0, 100.0], [-3.2, 3.2]]")
    with pytest.raises(ConfigError) as info:
        _load(tmp_path, text)
    assert info.value.key == "sensors[0].range_std"
    assert '"auto" is only for noise_std of a position sensor' in str(info.value)


def test_nothing_runs_on_the_noise_placeholders(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = _load(tmp_path, _noise_text('"auto"', '"auto"'))
    with pytest.raises(InputError, match=r"motion.noise_intensity, sensor 'radar' noise_std = "
                       r"\"auto\"; estimate them from the recording first"):  # fmt: skip
        WindowEstimator(config=config)
