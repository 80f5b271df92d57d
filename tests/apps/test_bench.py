"""``mapassoc bench``: a smoke run, the scores of p(K | Z), the summaries, the options."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from mapassoc.apps.bench import (
    BENCH_K_PRIORS,
    DEFAULT_FAMILIES,
    DEFAULT_K_PRIORS,
    GOSPA_RATIO_GOAL,
    SPEED_GOALS,
    BenchmarkResult,
    GospaParts,
    RunResult,
    _comparison_text,
    bench_scenario,
    run_benchmark,
    scale_growth,
    summarize_family,
)
from mapassoc.apps.cli import build_parser, main
from mapassoc.data.io import TruthTable
from mapassoc.errors import InputError
from mapassoc.evaluation.calibration import count_scores, window_target_counts
from mapassoc.evaluation.scenarios import build_scenario, scenario_names, truncate_scenario

# A few scans of the crossing scenario: enough for several 3-scan windows, fast.
SCANS = 8
WINDOW = 3
PRIORS = ("birth", "uniform")


def _run(
    family: str,
    seed: int,
    *,
    seconds_per_scan: float,
    ratio: float,
    statuses,
    k_prior: str = "birth",
    brier: float = 0.5,
    hit_rate: float = 0.5,
) -> RunResult:
    """A synthetic run (no estimator) for the summary functions."""
    parts = GospaParts(total=ratio, localisation=1.0, missed=0.0, false=0.0)
    return RunResult(
        family=family,
        seed=seed,
        config="generic",
        k_prior=k_prior,
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
        k_brier=brier,
        k_hit_rate=hit_rate,
        k_mean_p_true=0.5,
    )


# --------------------------------------------------------------------------- p(K | Z) scores


def _truth(records: list[tuple[int, float]]) -> TruthTable:
    ids, times = zip(*records, strict=True)
    return TruthTable(
        target_ids=np.array(ids),
        times=np.array(times, dtype=float),
        states=np.zeros((len(records), 1)),
        state_names=("x",),
    )


def _window(start: float, end: float) -> SimpleNamespace:
    return SimpleNamespace(start_time=start, end_time=end)


def _counted(probabilities: list[float], marginal_k: int) -> SimpleNamespace:
    return SimpleNamespace(p_k=np.array(probabilities), marginal_k=marginal_k)


def test_window_target_counts_counts_distinct_targets_alive_in_the_window() -> None:
    # Target 0 alive at t = 0, 1, 2; target 1 at t = 2, 3; target 5 at t = 4 only.
    truth = _truth([(0, 0.0), (0, 1.0), (0, 2.0), (1, 2.0), (1, 3.0), (5, 4.0)])
    windows = [
        _window(0.0, 1.0),  # target 0 (two records, counted once)
        _window(1.0, 2.0),  # 0 and 1 (1 enters at the end time: both ends count)
        _window(2.0, 3.0),  # 0 (at the start time) and 1
        _window(3.0, 4.0),  # 1 and 5
        _window(4.5, 6.0),  # nobody
        _window(0.0, 4.0),  # all three
        _window(2.0, 2.0),  # one instant: 0 and 1
    ]
    counts = window_target_counts(truth, windows)
    assert counts.dtype == np.int64
    assert counts.tolist() == [1, 2, 2, 2, 0, 3, 2]
    assert window_target_counts(truth, []).tolist() == []


def test_window_target_counts_checks_its_arguments() -> None:
    truth = _truth([(0, 0.0)])
    with pytest.raises(InputError, match="truth must be a TruthTable"):
        window_target_counts([(0, 0.0)], [_window(0.0, 1.0)])  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"windows\[1\] must have finite start_time <= end_time"):
        window_target_counts(truth, [_window(0.0, 1.0), _window(2.0, 1.0)])
    with pytest.raises(InputError, match=r"windows\[0\]"):
        window_target_counts(truth, [_window(math.nan, 1.0)])


def test_count_scores_golden_values() -> None:
    windows = [
        # True K 1: Brier (0.2 - 0)^2 + (0.8 - 1)^2 = 0.08; p(true) 0.8; marginal right.
        _counted([0.2, 0.8], 1),
        # True K 2, past the vector's end (implicit 0): 0.5^2 + 0.5^2 + (0 - 1)^2 = 1.5;
        # p(true) 0; marginal wrong.
        _counted([0.5, 0.5], 0),
        # True K 0: (0.1 - 1)^2 + 0.6^2 + 0.3^2 = 0.81 + 0.36 + 0.09 = 1.26; p(true) 0.1.
        _counted([0.1, 0.6, 0.3], 1),
    ]
    scores = count_scores(windows, [1, 2, 0])
    assert scores.brier == pytest.approx((0.08 + 1.5 + 1.26) / 3)
    assert scores.hit_rate == pytest.approx(1 / 3)
    assert scores.mean_p_true == pytest.approx((0.8 + 0.0 + 0.1) / 3)
    # The ends of the range: certain and right, certain and wrong (also past the end).
    certain = count_scores([_counted([0.0, 0.0, 1.0], 2)], np.array([2]))
    assert (certain.brier, certain.hit_rate, certain.mean_p_true) == (0.0, 1.0, 1.0)
    assert count_scores([_counted([0.0, 1.0], 1)], [0]).brier == pytest.approx(2.0)
    assert count_scores([_counted([1.0], 0)], [3]).brier == pytest.approx(2.0)
    # Uniform over 0..3 with the true K inside: 1 - 1/4.
    assert count_scores([_counted([0.25] * 4, 0)], [3]).brier == pytest.approx(0.75)


@pytest.mark.parametrize(
    ("windows", "counts", "message"),
    [
        ([], [], "at least one window"),
        ([_counted([1.0], 0)], [0, 1], "one integer >= 0 per window"),
        ([_counted([1.0], 0)], [-1], "one integer >= 0 per window"),
        ([_counted([1.0], 0)], [0.5], "one integer >= 0 per window"),
        ([_counted([[1.0]], 0)], [0], r"windows\[0\].p_k"),
        ([_counted([1.5, -0.5], 0)], [0], r"windows\[0\].p_k"),
        ([_counted([math.nan], 0)], [0], r"windows\[0\].p_k"),
    ],
)
def test_count_scores_checks_its_arguments(windows, counts, message: str) -> None:
    with pytest.raises(InputError, match=message):
        count_scores(windows, counts)


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
        k_priors=PRIORS,
    )
    return result, out.getvalue(), json.loads(path.read_text())


def test_smoke_run_measures_the_crossing_scenario(smoke) -> None:
    result, _, _ = smoke
    assert [run.k_prior for run in result.runs] == list(PRIORS)
    run = result.runs[0]
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
    # The forward pass is a part of the run: its own throughput is at least the run's.
    assert run.forward_scans_per_second is not None
    assert run.forward_scans_per_second >= run.scans_per_second
    assert run.oracle_gospa.total >= 0 and run.gospa.total >= 0
    assert run.gospa_ratio == pytest.approx(run.gospa.total / run.oracle_gospa.total)
    # The generic configuration: Kmax twice the most detections of the scans run.
    scenario = truncate_scenario(build_scenario("crossing", 0), SCANS)
    assert run.max_tracks == 2 * max(scan.size for scan in scenario.scans) == 2 * run.max_detections
    for r in result.runs:
        assert 0.0 <= r.k_brier <= 2.0
        assert 0.0 <= r.k_hit_rate <= 1.0 and 0.0 <= r.k_mean_p_true <= 1.0
    # One summary per prior, in the order of k_priors.
    assert [(f.family, f.k_prior) for f in result.families] == [("crossing", p) for p in PRIORS]
    for family, r in zip(result.families, result.runs, strict=True):
        assert family.seeds == (0,)
        assert family.speed_goal == SPEED_GOALS["crossing"]
        assert family.gospa_ratio_mean == pytest.approx(r.gospa_ratio)
        assert family.k_brier_mean == pytest.approx(r.k_brier)
        assert family.k_hit_rate_mean == pytest.approx(r.k_hit_rate)
    assert result.growth is None and math.isnan(result.gating_pairs_per_second)


def test_smoke_run_prints_lines_and_goals(smoke) -> None:
    result, text, _ = smoke
    lines = text.splitlines()
    assert lines[0].startswith("window length 3, time limit 5 s, generic configuration")
    assert "k_priors birth,uniform" in lines[0]
    assert "Brier" in lines[1] and "k_prior" in lines[1]
    for run in result.runs:
        (line,) = [line for line in lines if line.startswith(f"crossing      0 {run.k_prior} ")]
        assert f" {run.k_brier:5.3f} " in line
    for prior in PRIORS:
        assert any(f"=> crossing (k_prior {prior}), 1 seed(s)" in line for line in lines)
    assert "goal >= 150" in text and f"goal <= {GOSPA_RATIO_GOAL:g}x" in text
    assert "every window within its time limit" in text
    # The goals judge the first prior only: the speed goal is listed once.
    assert "goals (k_prior birth):" in lines
    assert text.count("crossing >= 150 scans/s") == 1
    # The comparison block comes last: per family and prior, then the better prior.
    start = lines.index(next(line for line in lines if line.startswith("k_prior comparison")))
    block = lines[start:]
    assert block[1].split() == ["family", *PRIORS]
    assert block[2].split()[0] == "crossing" and block[3].split()[0] == "mean"
    assert block[4].startswith("  lower mean GOSPA ratio over families: ")
    assert "lower mean Brier: " in block[4]


def test_smoke_run_writes_json(smoke) -> None:
    result, _, data = smoke
    assert data["settings"]["families"] == ["crossing"]
    assert data["settings"]["scans"] == SCANS
    assert data["settings"]["k_priors"] == list(PRIORS)
    assert [run["k_prior"] for run in data["runs"]] == list(PRIORS)
    for run, measured in zip(data["runs"], result.runs, strict=True):
        assert sum(run["status_counts"].values()) == measured.windows
        assert run["gospa"]["total"] == pytest.approx(measured.gospa.total)
        assert run["k_brier"] == pytest.approx(measured.k_brier)
        assert run["k_hit_rate"] == pytest.approx(measured.k_hit_rate)
        assert run["k_mean_p_true"] == pytest.approx(measured.k_mean_p_true)
    assert [family["k_prior"] for family in data["families"]] == list(PRIORS)
    assert all("k_brier_mean" in family for family in data["families"])
    assert data["families"][0]["speed_met"] in (True, False)
    assert data["gating_pairs_per_second"] is None  # not measured: NaN written as null


def test_bench_scenario_runs_the_prior_it_is_given() -> None:
    runs = {
        prior: bench_scenario("crossing", 0, WINDOW, time_limit=5.0, scans=SCANS, k_prior=prior)
        for prior in PRIORS
    }
    assert {prior: run.k_prior for prior, run in runs.items()} == {p: p for p in PRIORS}
    for run in runs.values():
        assert 0.0 <= run.k_brier <= 2.0
        assert 0.0 <= run.k_hit_rate <= 1.0 and 0.0 <= run.k_mean_p_true <= 1.0
    # The same windows, another prior: p(K | Z) differs.
    assert runs["birth"].windows == runs["uniform"].windows
    assert runs["birth"].k_brier != runs["uniform"].k_brier
    # The scores are those of the helpers on the estimator's own windows.
    scenario = truncate_scenario(build_scenario("crossing", 0), SCANS)
    assert runs["birth"].targets == len(np.unique(scenario.truth.target_ids))


@pytest.mark.parametrize(
    ("k_prior", "message"),
    [
        ("weights", "k_prior cannot be 'weights'.*k_prior_weights"),
        ("nope", "k_prior must be one of"),
    ],
)
def test_bench_scenario_checks_the_prior(k_prior: str, message: str) -> None:
    with pytest.raises(InputError, match=message):
        bench_scenario("crossing", 0, WINDOW, scans=SCANS, k_prior=k_prior)


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
        ({"k_priors": ("birth", "nope")}, r"k_priors\[1\] must be one of birth, uniform, poisson"),
        ({"k_priors": ("weights",)}, r"k_priors\[0\] cannot be 'weights'"),
        ({"k_priors": ()}, "k_priors must name at least one prior"),
        ({"k_priors": ("uniform", "uniform")}, "k_priors must be distinct"),
        ({"k_priors": "birth"}, "k_priors must be a sequence of prior names"),
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
        _run(
            "parallel",
            0,
            seconds_per_scan=0.1,
            ratio=1.1,
            statuses=[("exact", 20)],
            k_prior="uniform",
            brier=0.2,
            hit_rate=0.9,
        ),
        _run(
            "parallel",
            1,
            seconds_per_scan=0.05,
            ratio=1.5,
            statuses=[("exact", 18), ("bounded", 1), ("time_limit", 1)],
            k_prior="uniform",
            brier=0.6,
            hit_rate=0.5,
        ),
    ]
    summary = summarize_family(runs)
    assert summary.seeds == (0, 1) and summary.k_prior == "uniform"
    assert summary.k_brier_mean == pytest.approx(0.4)
    assert summary.k_hit_rate_mean == pytest.approx(0.7)
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
    birth = _run("parallel", 2, seconds_per_scan=1, ratio=1, statuses=[], k_prior="birth")
    with pytest.raises(InputError, match="one k_prior, got \\['birth', 'uniform'\\]"):
        summarize_family([runs[0], birth])


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
    uniform = summarize_family(
        [_run("scale50", 0, seconds_per_scan=0.5, ratio=1.0, statuses=[], k_prior="uniform")]
    )
    with pytest.raises(InputError, match="one k_prior"):
        scale_growth([family(20, 0.2), uniform])


def test_comparison_names_the_prior_with_the_lower_means() -> None:
    def summary(family: str, prior: str, ratio: float, brier: float):
        return summarize_family(
            [
                _run(
                    family,
                    0,
                    seconds_per_scan=0.1,
                    ratio=ratio,
                    statuses=[("exact", 1)],
                    k_prior=prior,
                    brier=brier,
                )
            ]
        )

    summaries = [
        summary("crossing", "birth", 1.0, 0.5),
        summary("crossing", "uniform", 1.2, 0.1),
        summary("dense", "birth", 1.4, 0.3),
        summary("dense", "uniform", 1.4, 0.5),
    ]
    lines = _comparison_text(summaries, ["birth", "uniform"]).splitlines()
    assert lines[1].split() == ["family", "birth", "uniform"]
    assert lines[2].split() == ["crossing", "1.00", "/", "0.500", "1.20", "/", "0.100"]
    assert lines[3].split() == ["dense", "1.40", "/", "0.300", "1.40", "/", "0.500"]
    # Means over families: ratio 1.20 vs 1.30, Brier 0.400 vs 0.300.
    assert lines[4].split() == ["mean", "1.20", "/", "0.400", "1.30", "/", "0.300"]
    assert lines[5] == (
        "  lower mean GOSPA ratio over families: birth (birth 1.20, uniform 1.30); "
        "lower mean Brier: uniform (birth 0.400, uniform 0.300)"
    )
    alone = _comparison_text(summaries[:1], ["birth"]).splitlines()
    assert "(one prior only)" in alone[-1]


# --------------------------------------------------------------------------- command line


def test_bench_defaults() -> None:
    args = build_parser().parse_args(["bench"])
    assert args.families == list(DEFAULT_FAMILIES)
    assert set(DEFAULT_FAMILIES) <= set(scenario_names())
    assert (args.seeds, args.window_length, args.time_limit) == (5, 5, 2.0)
    assert (args.config, args.scans, args.json) == ("generic", None, None)
    assert args.k_priors == list(DEFAULT_K_PRIORS)
    assert set(DEFAULT_K_PRIORS) <= set(BENCH_K_PRIORS)


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
            "--k-priors",
            "uniform, poisson",
        ]
    )
    assert args.k_priors == ["uniform", "poisson"]
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
    assert main(["bench", "--families", "crossing", "--k-priors", "birth,weights"]) == 2
    assert "k_priors[1] cannot be 'weights'" in capsys.readouterr().err
    assert main(["bench", "--families", "crossing", "--k-priors", "birth,"]) == 2
    assert "k_priors[1] must be one of" in capsys.readouterr().err


def test_bench_command_runs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bench.json"
    argv = ["bench", "--families", "crossing", "--seeds", "1", "--scans", "5"]
    assert main([*argv, "--window-length", "2", "--json", str(path), "--k-priors", "uniform"]) == 0
    out = capsys.readouterr().out
    assert "=> crossing (k_prior uniform)" in out and "pairs/s" in out
    assert "k_prior birth" not in out
    data = json.loads(path.read_text())
    assert data["runs"][0]["scans"] == 5 and data["runs"][0]["window_length"] == 2
    assert data["settings"]["k_priors"] == ["uniform"] and data["runs"][0]["k_prior"] == "uniform"


def test_bench_motion_imm_runs_the_configured_model_at_two_noise_levels() -> None:
    from mapassoc.apps.bench import _bench_setup
    from mapassoc.models.interacting import NOISE_LEVELS, InteractingModels

    plain = _bench_setup("crossing", 0, WINDOW, 5.0, "generic", SCANS, "birth")
    imm = _bench_setup("crossing", 0, WINDOW, 5.0, "generic", SCANS, "birth", "imm")
    assert isinstance(imm.config.motion, InteractingModels)
    q = plain.config.motion.noise_intensity
    assert [m.noise_intensity for m in imm.config.motion.models] == [f * q for f in NOISE_LEVELS]
    assert repr(imm.config.sensors) == repr(plain.config.sensors)
    assert imm.config.birth == plain.config.birth
    run = bench_scenario("crossing", 0, WINDOW, time_limit=5.0, scans=SCANS, motion="imm")
    assert run.tracks >= 1 and math.isfinite(run.gospa.total)
    with pytest.raises(InputError, match="motion must be one of configured, imm"):
        bench_scenario("crossing", 0, WINDOW, scans=SCANS, motion="cv")
