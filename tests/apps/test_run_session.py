"""The steps of a run session (:class:`mapassoc.apps.runs.RunSession`), one at a time."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from mapassoc.apps import runs
from mapassoc.apps.cli import main
from mapassoc.apps.runs import RunOptions, RunSession


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short crossing recording, with ``auto.toml``: its configuration with both
    sensor parameters "auto"."""
    out = tmp_path_factory.mktemp("scen") / "crossing"
    assert main(["simulate", "crossing", "--out", str(out), "--seed", "3", "--scans", "12"]) == 0
    lines = [
        'false_alarms_per_scan = "auto"' if line.startswith("false_alarms_per_scan =")
        else 'detection_probability = "auto"' if line.startswith("detection_probability =")
        else line
        for line in (out / "config.toml").read_text().splitlines()
    ]  # fmt: skip
    (out / "auto.toml").write_text("\n".join(lines) + "\n")
    return out


def _opened(
    scenario: Path, out: Path, config: str = "config.toml", **options: object
) -> RunSession:
    session = RunSession(RunOptions(progress=False, **options))  # type: ignore[arg-type]
    session.open(scenario / config, scenario / "detections.csv", out)
    return session


def test_open_reads_the_inputs_and_writes_nothing(scenario: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    session = _opened(scenario, out)
    inputs = session.inputs
    detections = (scenario / "detections.csv").read_bytes()
    assert inputs.identities["detections"]["bytes"] == len(detections)
    assert inputs.settings["segments"] == 1 and inputs.settings["timings"] is True
    with pytest.raises(dataclasses.FrozenInstanceError):
        inputs.config = None  # type: ignore[misc]
    assert session.resume() is None  # not asked to resume: run from the start
    assert not out.exists() and not out.with_name("out.partial").exists()
    scans = session.read_scans()
    assert len(scans) == 12 and sum(scan.size for scan in scans) == len(detections.splitlines()) - 1


def test_a_resumed_session_keeps_its_estimates_without_estimating(
    scenario: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The estimation step takes a resumed run's recorded estimates as they are."""

    def refuse(*args: object, **kwargs: object) -> object:
        raise AssertionError("a resumed run must not estimate again")

    monkeypatch.setattr(runs, "estimate_with_progress", refuse)
    session = _opened(scenario, tmp_path / "out", "auto.toml")
    assert session.inputs.config.auto.pending
    session.read_scans()
    recorded = {"sensors": {"pos": {"false_alarms_per_scan": 7.5, "detection_probability": 0.75}}}
    session.point = runs._ResumePoint(checkpoint={}, manifest={"parameters": recorded})
    model = session.estimate_parameters()
    assert model.parameters is recorded and model.precomputed is None
    sensor = model.config.sensors["pos"]
    assert (sensor.false_alarms_per_scan, sensor.detection_probability) == (7.5, 0.75)
    assert not model.config.auto.pending


def test_a_configuration_without_auto_values_is_run_as_loaded(
    scenario: Path, tmp_path: Path
) -> None:
    session = _opened(scenario, tmp_path / "out")
    session.read_scans()
    model = session.estimate_parameters()
    assert model.config is session.inputs.config and model.parameters is None
