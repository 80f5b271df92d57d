"""Infinite settings and log-likelihoods in a run's JSON files (manifest, summary,
windows.jsonl): written as the strings "inf" / "-inf", compared on resume, read back."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mapassoc.apps.cli import main
from mapassoc.apps.runs import RunInterrupted, RunOptions, run_files
from mapassoc.data.config import load_config
from mapassoc.data.settings import EstimatorSettings, settings_from_json

RESULT_FILES = ("tracks.csv", "windows.jsonl", "summary.json")


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scen") / "crossing"
    assert main(["simulate", "crossing", "--out", str(out), "--seed", "1", "--scans", "8"]) == 0
    return out


def _edit(scenario: Path, target: Path, replace: dict[str, str]) -> Path:
    """The scenario's config.toml with the lines replaced whose ``[table] key =`` start is
    a key of ``replace`` (``"[estimator.windows] time_limit ="``; a key without a table
    matches in every table), and no clock limit."""
    replace = {
        "[estimator.windows] time_limit =": "time_limit = 600.0",
        "[estimator.search] program_time_limit =": "program_time_limit = 600.0",
        **replace,
    }
    lines = []
    table = ""
    for line in (scenario / "config.toml").read_text().splitlines():
        if line.startswith("["):
            table = line
        for start, new in replace.items():
            if line.startswith(start) or f"{table} {line}".startswith(start):
                line = new
        lines.append(line)
    target.write_text("\n".join(lines) + "\n")
    return target


INFINITE = {
    "[estimator.pruning] prune_log_ratio =": "prune_log_ratio = inf\n"
    "sibling_prune_log_ratio = inf",
    "[estimator.refinement] prune_log_ratio =": "prune_log_ratio = inf",
    "[estimator.refinement] passes =": "passes = 1",
}


def _options(**changes: object) -> RunOptions:
    return RunOptions(timings=False, progress=False, **changes)  # type: ignore[arg-type]


def _strict_json(path: Path) -> list[object]:
    """Every JSON document of ``path`` (one, or one per line), refusing NaN and Infinity."""

    def refuse(name: str) -> object:
        raise AssertionError(f"{path.name} holds the non-JSON constant {name}")

    text = path.read_text()
    docs = text.splitlines() if path.suffix == ".jsonl" else [text]
    return [json.loads(doc, parse_constant=refuse) for doc in docs]


def test_inf_prune_widths_are_written_and_resumed(scenario: Path, tmp_path: Path) -> None:
    """prune_log_ratio = inf ("inf disables") runs, its manifest says "inf" and reads back
    to the same settings, a stopped run resumes over it and a complete one is skipped."""
    config = _edit(scenario, tmp_path / "inf.toml", INFINITE)
    detections = scenario / "detections.csv"
    reference = tmp_path / "ref"
    run_files(config, detections, reference, _options())
    for name in ("manifest.json", "summary.json", "windows.jsonl"):
        _strict_json(reference / name)
    manifest = json.loads((reference / "manifest.json").read_text())
    recorded = manifest["settings"]["estimator"]
    for record, key in (("pruning", "prune_log_ratio"), ("pruning", "sibling_prune_log_ratio"),
                        ("refinement", "prune_log_ratio")):  # fmt: skip
        assert recorded[record][key] == "inf", key
    assert settings_from_json(EstimatorSettings, recorded) == load_config(config).estimator

    out = tmp_path / "out"
    polls = iter(range(10**6))
    with pytest.raises(RunInterrupted):
        run_files(config, detections, out, _options(checkpoint_seconds=0.0),
                  stop=lambda: next(polls) >= 2)  # fmt: skip
    assert run_files(config, detections, out, _options(resume=True)).status == "complete"
    for name in RESULT_FILES:
        assert (out / name).read_bytes() == (reference / name).read_bytes(), name
    assert run_files(config, detections, out, _options(resume=True)).status == "skipped"


def test_a_minus_inf_pass_objective_is_written(scenario: Path, tmp_path: Path) -> None:
    """A kept Pd of 1 with missed scans makes an estimation pass's objective -inf: the
    summary and the manifest say "-inf" instead of failing to be written."""
    config = _edit(scenario, tmp_path / "pd1.toml", {
        "detection_probability =": "detection_probability = 1.0",
        "false_alarms_per_scan =": 'false_alarms_per_scan = "auto"',
        "[estimator.refinement] passes =": "passes = 0",
    })  # fmt: skip
    out = tmp_path / "out"
    run_files(config, scenario / "detections.csv", out, _options())
    (summary,) = _strict_json(out / "summary.json")
    (manifest,) = _strict_json(out / "manifest.json")
    assert isinstance(summary, dict) and isinstance(manifest, dict)
    objectives = [p["objective"] for p in summary["parameters"]["passes"]]
    assert "-inf" in objectives
    assert manifest["parameters"] == summary["parameters"]
