"""The benchmark's identity columns: P-GOSPA, T-GOSPA beside the oracle's and their ratio,
fragments, track ids per target and switches, in the record, the JSON, the aligned line and
the family summary."""

from __future__ import annotations

import json
from dataclasses import asdict, replace

import pytest

from mapassoc.apps.bench import (
    GOSPA_CUTOFF,
    BenchmarkResult,
    GospaParts,
    RunResult,
    _family_line,
    _header,
    _run_line,
    bench_scenario,
    summarize_family,
)
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.scenarios import build_scenario, generic_config, truncate_scenario
from mapassoc.evaluation.tables import pgospa_tables

SCANS = 8
WINDOW = 3


@pytest.fixture(scope="module")
def run() -> RunResult:
    return bench_scenario("crossing", 0, WINDOW, time_limit=5.0, scans=SCANS)


def test_the_ratios_and_pgospa_are_those_of_the_run(run: RunResult) -> None:
    assert run.tgospa is not None and run.oracle_tgospa is not None
    assert run.tgospa_ratio == pytest.approx(run.tgospa / run.oracle_tgospa, rel=1e-12)
    assert run.ids_per_target == pytest.approx(run.tracks / run.targets)
    # P-GOSPA of the same estimate, with the existence column the estimator writes.
    scenario = truncate_scenario(build_scenario("crossing", 0), SCANS)
    config = generic_config(scenario, window_length=WINDOW, time_limit=5.0)
    config = replace(config, estimator=replace(config.estimator, k_prior="birth"))
    tracks = WindowEstimator(config=config).run(scenario.scans).tracks
    assert tracks.existence is not None
    expected = pgospa_tables(scenario.truth, tracks, c=GOSPA_CUTOFF).mean_total
    assert run.pgospa == pytest.approx(expected, rel=1e-9)


def test_the_json_holds_the_new_fields(run: RunResult) -> None:
    row = json.loads(json.dumps(asdict(run), allow_nan=False))
    assert row["tgospa_ratio"] == pytest.approx(run.tgospa_ratio)
    assert row["pgospa"] == pytest.approx(run.pgospa)
    summary = summarize_family([run])
    data = BenchmarkResult(
        settings={}, runs=(run,), families=(summary,), growth=None, gating_pairs_per_second=1.0
    ).to_json()
    family = data["families"][0]  # type: ignore[index]
    assert family["tgospa_ratio_mean"] == pytest.approx(run.tgospa_ratio)
    assert family["pgospa_ratio_mean"] == pytest.approx(run.pgospa / run.oracle_gospa.total)
    assert family["id_switches_mean"] == run.tgospa_id_switches


@pytest.mark.parametrize("width", [10, 16])
def test_header_and_line_align(run: RunResult, width: int) -> None:
    header, line = _header(width), _run_line(run, width)
    # Both end in their status: the columns before it take the same room.
    assert header.index("  status") == len(line) - len(line.split("  ")[-1]) - 2
    values = line[width + 1 :]
    labels = header[width + 1 :]
    # Every right-aligned cell ends where its label ends.
    for name in ("tgts", "oracle", "ratio", "P-GOSPA", "T-GOSPA", "T-ratio", "frag", "ids/tg",
                 "IDsw", "Brier", "K hit"):
        end = labels.index(f" {name} ") + 1 + len(name) if f" {name} " in labels else None
        assert end is not None, name
        assert values[end - 1] != " " and values[end] == " ", name
    assert f"{run.tgospa_ratio:.2f}" in line and f"{run.pgospa:.2f}" in line


def test_a_run_without_identity_prints_dashes_and_the_summary_omits_it(run: RunResult) -> None:
    bare = replace(run, tgospa=None, oracle_tgospa=None, tgospa_ratio=None, pgospa=None,
                   fragments_per_target=None, tgospa_id_switches=None)
    line = _run_line(bare)
    assert len(line.split("  ")[0]) == len(_run_line(run).split("  ")[0])
    summary = summarize_family([bare])
    assert summary.tgospa_ratio_mean is None and summary.pgospa_ratio_mean is None
    assert "identity" not in _family_line(summary, 5.0)


def test_the_family_summary_means_the_identity_columns(run: RunResult) -> None:
    oracle = GospaParts(total=2.0, localisation=0.0, missed=0.0, false=0.0)
    runs = [
        replace(run, seed=0, fragments_per_target=1.0, tgospa_id_switches=0, tgospa_ratio=1.5,
                pgospa=3.0, oracle_gospa=oracle),
        replace(run, seed=1, fragments_per_target=2.0, tgospa_id_switches=3, tgospa_ratio=2.5,
                pgospa=5.0, oracle_gospa=oracle),
    ]
    summary = summarize_family(runs)
    assert summary.fragments_per_target_mean == pytest.approx(1.5)
    assert summary.id_switches_mean == pytest.approx(1.5)
    assert summary.tgospa_ratio_mean == pytest.approx(2.0)
    # (3 / 2 + 5 / 2) / 2.
    assert summary.pgospa_ratio_mean == pytest.approx(2.0)
    text = _family_line(summary, 5.0)
    assert "identity: frag 1.50, IDsw 1.5, T-GOSPA 2.00x oracle, P-GOSPA 2.00x oracle GOSPA" in text
