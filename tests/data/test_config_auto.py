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


IMM_MOTION = """[motion]
model = "imm"
switch_probability = 0.05

[[motion.models]]
model = "constant_velocity"
ndim = 2
noise_intensity = 0.5

[[motion.models]]
model = "{model}"
ndim = 2
noise_intensity = {q}{extra}
"""


def _imm_text(q: str = "100.0", extra: str = "", model: str = "constant_velocity") -> str:
    motion = IMM_MOTION.format(model=model, q=q, extra=extra)
    return _text().replace('[motion]\nmodel = "constant_velocity"\nndim = 2\n'
                           "noise_intensity = 0.5\n", motion)  # fmt: skip


def test_an_imm_components_auto_noise_intensity_is_listed_with_its_start(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from mapassoc.data.config import NOISE_PLACEHOLDER
    from mapassoc.models.motion import ConstantVelocity

    for extra, start in (("", None), ("\nnoise_intensity_start = 20.0", 20.0)):
        config = _load(tmp_path, _imm_text('"auto"', extra))
        assert config.auto == AutoParameters(model_noise_intensity=((1, start),))
        assert config.auto.pending and config.auto.model_noise_starts() == {1: start}
        assert config.auto.names() == ["motion.models[1].noise_intensity"]
        assert not config.auto.noise_intensity and config.auto.noise_intensity_start is None
        quiet, agile = config.motion.models  # type: ignore[attr-defined]
        assert repr(quiet) == repr(ConstantVelocity(ndim=2, noise_intensity=0.5))  # untouched
        assert repr(agile) == repr(ConstantVelocity(ndim=2, noise_intensity=NOISE_PLACEHOLDER))
    given = _load(tmp_path, _imm_text())
    assert not given.auto.pending and given.auto.model_noise_starts() == {}
    assert given.motion.models[1].noise_intensity == 100.0  # type: ignore[attr-defined]


def test_an_imm_components_auto_noise_intensity_round_trips_through_toml(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import tomllib

    for extra in ("", "\nnoise_intensity_start = 20.0"):
        config = _load(tmp_path, _imm_text('"auto"', extra))
        text = config_to_toml(config)
        second = text.split("[[motion.models]]")[2].split("\n[")[0]
        assert 'noise_intensity = "auto"' in second and text.count('"auto"') == 1
        assert ("noise_intensity_start = 20.0" in second) == bool(extra)
        again = parse_config(tomllib.loads(text))
        assert again.auto == config.auto
        assert repr(again.motion) == repr(config.motion)
        assert config_to_toml(again) == text  # a fixed point


@pytest.mark.parametrize(
    ("text", "key", "message"),
    [
        (_imm_text('"auto"', model="singer").replace(
            'model = "singer"\nndim = 2\n', 'model = "singer"\nndim = 2\n'
            "time_constant = 10.0\nacceleration_std = 1.0\n"),
         "motion.models[1].noise_intensity",
         "\"auto\" needs model = one of ['constant_velocity', 'constant_acceleration', "
         "'random_walk'], got 'singer'"),
        (_imm_text(extra="\nnoise_intensity_start = 20.0"),
         "motion.models[1].noise_intensity_start", 'only goes with noise_intensity = "auto"'),
        (_imm_text('"auto"', "\nnoise_intensity_start = 0.0"),
         "motion.models[1].noise_intensity_start", "got 0.0"),
        (_imm_text('"auto"', "\nnoise_intensity_start = -1.0"),
         "motion.models[1].noise_intensity_start", "got -1.0"),
        (_imm_text().replace('switch_probability = 0.05', 'switch_probability = 0.05\n'
                             'noise_intensity = "auto"'),
         "motion.noise_intensity", "allowed keys for imm"),
        (_imm_text().replace('switch_probability = 0.05', 'switch_probability = 0.05\n'
                             "noise_intensity_start = 1.0"),
         "motion.noise_intensity_start", "allowed keys for imm"),
    ],
)  # fmt: skip
def test_bad_imm_auto_noise_names_its_key(tmp_path, text: str, key: str, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError) as info:
        _load(tmp_path, text)
    assert info.value.key == key
    assert message in str(info.value)


def test_auto_components_must_be_components_of_an_imm_set(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import dataclasses

    single = _load(tmp_path, _text())
    with pytest.raises(InputError, match=r"auto.model_noise_intensity names components \[0\]"):
        dataclasses.replace(single, auto=AutoParameters(model_noise_intensity=((0, None),)))
    imm = _load(tmp_path, _imm_text())
    for bad in (((2, None),), ((1, None), (0, None)), ((1, None), (1, None)), ((True, None),)):
        with pytest.raises(InputError, match="distinct components 0..1 in increasing order"):
            dataclasses.replace(imm, auto=AutoParameters(model_noise_intensity=bad))  # type: ignore[arg-type]
    with pytest.raises(InputError, match="start of component 1 must be positive"):
        dataclasses.replace(imm, auto=AutoParameters(model_noise_intensity=((1, 0.0),)))
    both = AutoParameters(model_noise_intensity=((0, None), (1, 3.0)))
    assert dataclasses.replace(imm, auto=both).auto.names() == [
        "motion.models[0].noise_intensity", "motion.models[1].noise_intensity"]
    whole = dataclasses.replace(imm, auto=AutoParameters(noise_intensity=True))
    with pytest.raises(ConfigError) as info:  # the writer has nowhere to write it
        config_to_toml(whole)
    assert info.value.key == "motion.noise_intensity"
    assert "no noise_intensity of its own" in str(info.value)


def test_nothing_runs_on_an_imm_components_placeholder(tmp_path) -> None:  # type: ignore[no-untyped-def]
    config = _load(tmp_path, _imm_text('"auto"'))
    with pytest.raises(InputError, match=r"motion.models\[1\].noise_intensity = \"auto\"; "
                       "estimate them from the recording first"):  # fmt: skip
        WindowEstimator(config=config)
