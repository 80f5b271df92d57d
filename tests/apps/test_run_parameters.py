"""`"auto"` sensor parameters through the command line: run, resume, estimate-parameters."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mapassoc.apps import runs
from mapassoc.apps.cli import main
from mapassoc.apps.runs import RunInterrupted, RunOptions, run_files

pytestmark = pytest.mark.slow


def _auto(folder: Path, *, rate: bool = True, pd: bool = True) -> Path:
    """The folder's config.toml with the sensor parameters "auto" and no clock limit."""
    text = (folder / "config.toml").read_text()
    lines = []
    for line in text.splitlines():
        if rate and line.startswith("false_alarms_per_scan ="):
            line = 'false_alarms_per_scan = "auto"'
        if pd and line.startswith("detection_probability ="):
            line = 'detection_probability = "auto"'
        if line.startswith("time_limit ="):
            line = "time_limit = 600.0"
        lines.append(line)
    out = folder / "auto.toml"
    out.write_text("\n".join(lines) + "\n")
    return out


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scen") / "crossing"
    assert main(["simulate", "crossing", "--out", str(out), "--seed", "1"]) == 0
    return out


def test_an_auto_run_records_its_estimates(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = _auto(scenario)
    out = tmp_path / "run"
    assert main(["run", str(config), str(scenario / "detections.csv"), "--out", str(out),
                 "--no-timings"]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "mapassoc: parameters pass 1: pos: false_alarms_per_scan" in err
    summary = json.loads((out / "summary.json").read_text())
    manifest = json.loads((out / "manifest.json").read_text())
    parameters = summary["parameters"]
    assert manifest["parameters"] == parameters
    found = parameters["sensors"]["pos"]
    assert found["false_alarms_per_scan"] == pytest.approx(10.0, rel=0.15)
    assert found["detection_probability"] == pytest.approx(0.9, abs=0.05)
    assert 1 <= len(parameters["passes"]) <= 3
    assert all("seconds" not in p for p in parameters["passes"])  # --no-timings
    # The run used exactly the values it reports: a run given them as numbers is the same.
    text = (scenario / "config.toml").read_text().splitlines()
    fixed = []
    for line in text:
        if line.startswith("false_alarms_per_scan ="):
            line = f"false_alarms_per_scan = {found['false_alarms_per_scan']!r}"
        if line.startswith("detection_probability ="):
            line = f"detection_probability = {found['detection_probability']!r}"
        if line.startswith("time_limit ="):
            line = "time_limit = 600.0"
        fixed.append(line)
    numbers = tmp_path / "numbers.toml"
    numbers.write_text("\n".join(fixed) + "\n")
    again = tmp_path / "again"
    assert main(["run", str(numbers), str(scenario / "detections.csv"), "--out", str(again),
                 "--no-timings", "--no-progress"]) == 0  # fmt: skip
    for name in ("tracks.csv", "windows.jsonl"):
        assert (again / name).read_bytes() == (out / name).read_bytes(), name


def test_a_resumed_auto_run_keeps_its_estimates(
    scenario: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A recording longer than the estimation's sample runs after the estimate with
    checkpoints; stopped and resumed, it gives the uninterrupted run's files and does not
    estimate again."""
    from mapassoc.estimator import parameters

    real = parameters.estimate_parameters
    calls: list[int] = []

    def on_a_sample(*args: object, **kwargs: object) -> object:
        result = real(*args, sample_scans=30, sample_blocks_count=2, **kwargs)  # type: ignore[arg-type]
        calls.append(1)
        return result

    monkeypatch.setattr(parameters, "estimate_parameters", on_a_sample)
    config = _auto(scenario)
    detections = scenario / "detections.csv"
    whole = tmp_path / "whole"
    run_files(config, detections, whole, RunOptions(timings=False, progress=False))
    assert calls == [1]
    out = tmp_path / "out"
    polls: list[int] = []

    def stop_after_ten() -> bool:  # ten windows of the run itself, after the estimate
        if len(calls) == 2:
            polls.append(1)
        return len(polls) > 10

    with pytest.raises(RunInterrupted):
        run_files(
            config,
            detections,
            out,
            RunOptions(timings=False, progress=False, checkpoint_seconds=0.0),
            stop=stop_after_ten,
        )  # fmt: skip
    assert len(calls) == 2
    run_files(config, detections, out, RunOptions(timings=False, progress=False, resume=True))
    assert len(calls) == 2  # the resumed session kept the manifest's estimates
    for name in ("tracks.csv", "windows.jsonl", "summary.json"):
        assert (out / name).read_bytes() == (whole / name).read_bytes(), name


def test_estimate_parameters_prints_writes_and_warns(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = (scenario / "config.toml").read_text()
    wrong = tmp_path / "wrong.toml"
    lines = [
        "false_alarms_per_scan = 40.0" if line.startswith("false_alarms_per_scan =") else line
        for line in text.splitlines()
    ]
    wrong.write_text("\n".join(lines) + "\n")
    written = tmp_path / "estimated.toml"
    assert main(["estimate-parameters", str(wrong), str(scenario / "detections.csv"),
                 "--write", str(written), "--no-progress"]) == 0  # fmt: skip
    captured = capsys.readouterr()
    assert "pos" in captured.out and "40" in captured.out
    assert "configured false_alarms_per_scan = 40, the recording says" in captured.err
    from mapassoc.data.config import load_config

    estimated = load_config(written).sensors["pos"]
    assert estimated.false_alarms_per_scan == pytest.approx(10.0, rel=0.15)
    assert not load_config(written).auto.pending
    # Never overwrites.
    assert main(["estimate-parameters", str(wrong), str(scenario / "detections.csv"),
                 "--write", str(written), "--no-progress"]) == 2  # fmt: skip
    assert "exists already" in capsys.readouterr().err


def test_a_stop_while_estimating_writes_nothing(scenario: Path, tmp_path: Path) -> None:
    config = _auto(scenario)
    out = tmp_path / "out"
    with pytest.raises(runs.StoppedBeforeRun, match="while estimating the sensor parameters"):
        run_files(
            config,
            scenario / "detections.csv",
            out,
            RunOptions(progress=False),
            stop=lambda: True,
        )  # fmt: skip
    assert not out.exists() and not out.with_name("out.partial").exists()


def test_a_batch_estimates_each_recording_s_parameters(scenario: Path, tmp_path: Path) -> None:
    import shutil

    source = tmp_path / "recs"
    (source / "one").mkdir(parents=True)
    shutil.copy(scenario / "detections.csv", source / "one" / "detections.csv")
    shutil.copy(_auto(scenario), source / "one" / "config.toml")
    out = tmp_path / "batch"
    assert main(["batch", str(source), "--out", str(out), "--jobs", "1", "--no-timings",
                 "--no-progress"]) == 0  # fmt: skip
    summary = json.loads((out / "one" / "summary.json").read_text())
    found = summary["parameters"]["sensors"]["pos"]
    assert found["rate_estimated"] and found["pd_estimated"]
    single = tmp_path / "single"
    run_files(
        source / "one" / "config.toml",
        source / "one" / "detections.csv",
        single,
        RunOptions(timings=False, progress=False),
    )  # fmt: skip
    assert (single / "tracks.csv").read_bytes() == (out / "one" / "tracks.csv").read_bytes()


def _auto_noise(folder: Path, tmp_path: Path) -> Path:
    """The folder's config.toml with both noise levels "auto" (starts 4 q and 2 std)."""
    lines = []
    for line in (folder / "config.toml").read_text().splitlines():
        if line.startswith("noise_intensity ="):
            start = 4 * float(line.split("=")[1])
            line = f'noise_intensity = "auto"\nnoise_intensity_start = {start!r}'
        if line.startswith("noise_std ="):
            line = 'noise_std = "auto"\nnoise_std_start = 2.0'
        if line.startswith("time_limit ="):
            line = "time_limit = 600.0"
        lines.append(line)
    out = tmp_path / "noise.toml"
    out.write_text("\n".join(lines) + "\n")
    return out


def test_auto_noise_levels_are_printed_written_and_recorded(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from mapassoc.data.config import load_config

    config = _auto_noise(scenario, tmp_path)
    written = tmp_path / "estimated.toml"
    assert main(["estimate-parameters", str(config), str(scenario / "detections.csv"),
                 "--write", str(written), "--no-progress"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "motion.noise_intensity" in out and "sensor 'pos' noise_std" in out
    estimated = load_config(written)
    assert not estimated.auto.pending
    assert estimated.sensors["pos"].measurement.noise_covariance[0, 0] == pytest.approx(
        1.0, rel=0.4
    )  # a std within 20%
    run = tmp_path / "run"
    assert main(["run", str(config), str(scenario / "detections.csv"), "--out", str(run),
                 "--no-timings", "--no-progress"]) == 0  # fmt: skip
    noise = json.loads((run / "summary.json").read_text())["parameters"]["noise"]
    assert set(noise) == {"noise_intensity", "noise_std"}
    assert noise["noise_std"]["pos"][0] == pytest.approx(1.0, rel=0.2)


def _auto_birth(folder: Path, tmp_path: Path) -> Path:
    """The folder's config.toml with [birth] rate and survival_probability "auto"."""
    lines = []
    for line in (folder / "config.toml").read_text().splitlines():
        if line.startswith(("rate =", "survival_probability =")):
            line = line.split(" =")[0] + ' = "auto"'
        if line.startswith("time_limit ="):
            line = "time_limit = 600.0"
        lines.append(line)
    out = tmp_path / "birth.toml"
    out.write_text("\n".join(lines) + "\n")
    return out


def test_auto_birth_keys_are_printed_written_and_recorded(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from mapassoc.data.config import load_config

    config = _auto_birth(scenario, tmp_path)
    truth = load_config(scenario / "config.toml").birth
    written = tmp_path / "estimated.toml"
    assert main(["estimate-parameters", str(config), str(scenario / "detections.csv"),
                 "--write", str(written), "--no-progress"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "birth.rate" in out and "birth.survival_probability" in out
    estimated = load_config(written)
    assert not estimated.auto.pending
    assert estimated.birth.rate == pytest.approx(truth.rate, rel=0.3)
    run = tmp_path / "run"
    assert main(["run", str(config), str(scenario / "detections.csv"), "--out", str(run),
                 "--no-timings"]) == 0  # fmt: skip
    assert "birth rate" in capsys.readouterr().err  # the pass's line
    birth = json.loads((run / "summary.json").read_text())["parameters"]["birth"]
    assert set(birth) == {"rate", "survival_probability"}
    assert birth["survival_probability"] == pytest.approx(truth.survival_probability, abs=0.01)
