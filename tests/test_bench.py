"""``mapassoc bench``: a quick smoke run, the summaries, and the command-line options."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import pytest

from mapassoc.bench import (
    DEFAULT_FAMILIES,
    GOSPA_RATIO_GOAL,
    SPEED_GOALS,
    BenchmarkResult,
    GospaParts,
    RunResult,
    bench_scenario,
    run_benchmark,
    scale_growth,
    summarize_family,
)
from mapassoc.cli import _BENCH_FAMILIES, build_parser, main
from mapassoc.errors import InputError
from mapassoc.scenarios import build_scenario, scenario_names, truncate_scenario

# A few scans of the crossing scenario: enough for several 3-scan windows, fast.
SCANS = 8
WINDOW = 3


def _run(family: str, seed: int, *, seconds_per_scan: float, ratio: float, statuses) -> RunResult:
    """A synthetic run (no estimator) for the summary functions."""
    parts = GospaParts(total=ratio, localisation=1.0, missed=0.0, false=0.0)
    return RunResult(
        family=family,
        seed=seed,
        config="generic",
        targets=int(family.removeprefix("scale")) if family.startswith("scale") else 4,
        scans=30,
        detections_per_scan=10.0,
        max_detections=12,
        window_length=5,
        time_limit=2.0,
        max_tracks=24,
        seconds=30 * seconds_per_scan,
        scans_per_second=1.0 / seconds_per_scan,
        seconds_per_scan=seconds_per_scan,
        window_p50_ms=1.0,
        window_p95_ms=2.0,
        window_max_ms=3000.0 if "time_limit" in dict(statuses) else 3.0,
        windows=sum(count for _, count in statuses),
        windows_over_limit=1 if "time_limit" in dict(statuses) else 0,
        hypotheses_mean=10.0,
        hypotheses_max=20,
        largest_cluster=5,
        status_counts=tuple(statuses),
        min_captured_mass=0.9,
        tracks=4,
        gospa=parts,
        oracle_gospa=GospaParts(total=1.0, localisation=1.0, missed=0.0, false=0.0),
        gospa_ratio=ratio,
    )


# --------------------------------------------------------------------------- smoke run


@pytest.fixture(scope="module")
def smoke(tmp_path_factory: pytest.TempPathFactory) -> tuple[BenchmarkResult, str, dict]:
    path = tmp_path_factory.mktemp("bench") / "bench.json"
    out = io.StringIO()
    result = run_benchmark(
        families=["crossing"],
        seeds=1,
        window_length=WINDOW,
        time_limit=5.0,
        scans=SCANS,
        json_path=path,
        gating=False,
        out=out,
    )
    return result, out.getvalue(), json.loads(path.read_text())


def test_smoke_run_measures_the_crossing_scenario(smoke) -> None:
    result, _, _ = smoke
    (run,) = result.runs
    assert (run.family, run.seed, run.config, run.scans) == ("crossing", 0, "generic", SCANS)
    assert run.window_length == WINDOW and run.time_limit == 5.0
    assert run.windows >= 1
    # Statuses are counted as the pipeline names them; every window is counted once.
    assert sum(count for _, count in run.status_counts) == run.windows
    assert all(isinstance(status, str) and status for status, _ in run.status_counts)
    assert 0.0 <= run.min_captured_mass <= 1.0
    assert 0 <= run.windows_over_limit <= run.windows
    assert run.window_p50_ms <= run.window_p95_ms <= run.window_max_ms
    assert run.scans_per_second > 0 and run.seconds_per_scan > 0
    assert run.oracle_gospa.total >= 0 and run.gospa.total >= 0
    assert run.gospa_ratio == pytest.approx(run.gospa.total / run.oracle_gospa.total)
    # The generic configuration: Kmax twice the most detections of the scans run.
    scenario = truncate_scenario(build_scenario("crossing", 0), SCANS)
    assert run.max_tracks == 2 * max(scan.size for scan in scenario.scans) == 2 * run.max_detections
    (family,) = result.families
    assert family.family == "crossing" and family.seeds == (0,)
    assert family.speed_goal == SPEED_GOALS["crossing"]
    assert family.gospa_ratio_mean == pytest.approx(run.gospa_ratio)
    assert result.growth is None and math.isnan(result.gating_pairs_per_second)


def test_smoke_run_prints_lines_and_goals(smoke) -> None:
    _, text, _ = smoke
    lines = text.splitlines()
    assert lines[0].startswith("window length 3, time limit 5 s, generic configuration")
    assert any(line.startswith("crossing      0") for line in lines)
    assert any("=> crossing, 1 seed(s)" in line for line in lines)
    assert "goal >= 150" in text and f"goal <= {GOSPA_RATIO_GOAL:g}x" in text
    assert "every window within its time limit" in text
    assert "goals:" in lines


def test_smoke_run_writes_json(smoke) -> None:
    result, _, data = smoke
    assert data["settings"]["families"] == ["crossing"]
    assert data["settings"]["scans"] == SCANS
    (run,) = data["runs"]
    assert sum(run["status_counts"].values()) == result.runs[0].windows
    assert run["gospa"]["total"] == pytest.approx(result.runs[0].gospa.total)
    assert data["families"][0]["speed_met"] in (True, False)
    assert data["gating_pairs_per_second"] is None  # not measured: NaN written as null


def test_scenario_configuration_keeps_the_scenarios_kmax() -> None:
    run = bench_scenario("crossing", 1, 2, time_limit=5.0, config="scenario", scans=4)
    assert run.config == "scenario" and run.window_length == 2 and run.scans == 4
    assert run.max_tracks == build_scenario("crossing", 1).config.estimator.max_tracks


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"families": ["nope"]}, "nope"),
        ({"families": []}, "families"),
        ({"seeds": 0}, "seeds"),
        ({"window_length": 0}, "window_length"),
        ({"time_limit": 0.0}, "time_limit"),
        ({"time_limit": math.inf}, "time_limit"),
        ({"config": "tuned"}, "config"),
        ({"scans": 0}, "scans"),
    ],
)
def test_run_benchmark_checks_arguments_before_running(kwargs, message: str) -> None:
    out = io.StringIO()
    with pytest.raises(InputError, match=message):
        run_benchmark(**{"families": ["crossing"], **kwargs}, out=out)
    assert out.getvalue() == ""


# --------------------------------------------------------------------------- summaries


def test_family_summary_counts_any_status_and_spreads_the_ratio() -> None:
    runs = [
        _run("parallel", 0, seconds_per_scan=0.1, ratio=1.1, statuses=[("exact", 20)]),
        _run(
            "parallel",
            1,
            seconds_per_scan=0.05,
            ratio=1.5,
            statuses=[("exact", 18), ("bounded", 1), ("time_limit", 1)],
        ),
    ]
    summary = summarize_family(runs)
    assert summary.seeds == (0, 1)
    assert dict(summary.status_counts) == {"exact": 38, "bounded": 1, "time_limit": 1}
    assert summary.status_counts[0] == ("exact", 38)
    assert summary.gospa_ratio_mean == pytest.approx(1.3)
    assert (summary.gospa_ratio_min, summary.gospa_ratio_max) == (1.1, 1.5)
    assert summary.scans_per_second == pytest.approx(15.0)
    assert summary.windows == 40 and summary.windows_over_limit == 1
    assert summary.speed_goal == 20.0 and summary.speed_met is False
    assert summary.gospa_met is False and summary.time_limit_met is False
    with pytest.raises(InputError, match="one family"):
        summarize_family([runs[0], _run("burst", 0, seconds_per_scan=1, ratio=1, statuses=[])])
    with pytest.raises(InputError, match="at least one"):
        summarize_family([])


def test_scale_growth_exponent() -> None:
    def family(targets: int, seconds: float):
        name = f"scale{targets}"
        return summarize_family(
            [_run(name, 0, seconds_per_scan=seconds, ratio=1.0, statuses=[("exact", 1)])]
        )

    linear = scale_growth([family(20, 0.2), family(50, 0.5), family(100, 1.0)])
    assert linear is not None
    assert linear.families == ("scale20", "scale50", "scale100")
    assert linear.exponent == pytest.approx(1.0)
    quadratic = scale_growth([family(20, 0.04), family(100, 1.0)])
    assert quadratic is not None and quadratic.exponent == pytest.approx(2.0)
    assert not quadratic.linear_or_better
    assert scale_growth([family(20, 0.2)]) is None


# --------------------------------------------------------------------------- command line


def test_bench_defaults() -> None:
    args = build_parser().parse_args(["bench"])
    assert args.families == list(DEFAULT_FAMILIES) == list(_BENCH_FAMILIES)
    assert set(DEFAULT_FAMILIES) <= set(scenario_names())
    assert (args.seeds, args.window_length, args.time_limit) == (5, 5, 2.0)
    assert (args.config, args.scans, args.json) == ("generic", None, None)


def test_bench_options_parse() -> None:
    args = build_parser().parse_args(
        [
            "bench",
            "--families",
            "parallel",
            "scale20",
            "--seeds",
            "3",
            "--window-length",
            "7",
            "--time-limit",
            "0.5",
            "--config",
            "scenario",
            "--scans",
            "12",
            "--json",
            "out.json",
        ]
    )
    assert args.families == ["parallel", "scale20"]
    assert (args.seeds, args.window_length, args.time_limit) == (3, 7, 0.5)
    assert (args.config, args.scans, args.json) == ("scenario", 12, "out.json")
    # The former option name still selects families.
    assert build_parser().parse_args(["bench", "--scenarios", "dense"]).families == ["dense"]


@pytest.mark.parametrize(
    "argv",
    [
        ["bench", "--config", "tuned"],
        ["bench", "--seeds", "two"],
        ["bench", "--seed", "3"],  # no abbreviation of --seeds: the old option is gone
    ],
)
def test_bench_rejects_bad_options(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(argv)
    assert exc.value.code == 2
    capsys.readouterr()


def test_bench_command_reports_bad_values(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "--families", "crossing", "no-such-family"]) == 2
    assert "no-such-family" in capsys.readouterr().err
    assert main(["bench", "--seeds", "0"]) == 2
    assert "seeds" in capsys.readouterr().err


def test_bench_command_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bench.json"
    argv = ["bench", "--families", "crossing", "--seeds", "1", "--scans", "5"]
    assert main([*argv, "--window-length", "2", "--json", str(path)]) == 0
    out = capsys.readouterr().out
    assert "=> crossing" in out and "pairs/s" in out
    data = json.loads(path.read_text())
    assert data["runs"][0]["scans"] == 5 and data["runs"][0]["window_length"] == 2
