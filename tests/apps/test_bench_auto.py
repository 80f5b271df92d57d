"""``mapassoc bench --parameters auto``: the model's values estimated from the recording
first, the estimates beside the truth, and the "auto" run against the given-values run.

The runs are short (crossing, 30 scans, 3-scan windows: about 6 s for "auto"), so the
tolerances are generous: on 30 scans from the default starts the false-alarm rate and Pd
come close, the noise std within a factor of a few, and the process noise not at all
(the changelog measured the same from the default starts on 200 scans); the benchmark
prints those errors, which is what it is for.
"""

from __future__ import annotations

import dataclasses
import io
import json
import math

import pytest

from mapassoc.apps.bench import _bench_setup, bench_scenario, run_benchmark
from mapassoc.apps.bench_auto import (
    AUTO_GOSPA_GOAL,
    auto_fields,
    auto_summary_line,
    estimates_line,
    run_auto,
    summarize_auto,
)
from mapassoc.apps.cli import build_parser, main
from mapassoc.data.config import NOISE_PLACEHOLDER, check_config
from mapassoc.errors import InputError
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.models.interacting import InteractingModels

SCANS = 30
WINDOW = 3


@pytest.fixture(scope="module")
def both(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    """One seed of crossing run with the given values and with "auto": the result, what
    it printed and the JSON it wrote."""
    path = tmp_path_factory.mktemp("bench-auto") / "bench.json"
    out = io.StringIO()
    result = run_benchmark(
        families=["crossing"], seeds=1, window_length=WINDOW, config="scenario", scans=SCANS,
        json_path=path, gating=False, out=out, k_priors=["birth"],
        parameters=("given", "auto"),
    )  # fmt: skip
    return result, out.getvalue(), json.loads(path.read_text())


def test_the_auto_run_estimates_near_the_truth(both) -> None:  # type: ignore[no-untyped-def]
    result, _, _ = both
    given, auto = result.runs
    assert (given.parameters, auto.parameters) == ("given", "auto")
    assert given.estimates is None
    truth = build_scenario("crossing", 0).config
    values = {v.label: v for v in auto.estimates}
    assert list(values) == ["q", "pos rate", "pos Pd", "pos std", "births", "initial",
                            "survival"]  # fmt: skip
    assert values["survival"].truth == truth.birth.survival_probability
    assert 0.0 < values["survival"].estimate <= 1.0 and values["births"].estimate >= 0.0
    sensor = truth.sensors["pos"]
    assert values["pos rate"].truth == sensor.false_alarms_per_scan
    assert values["pos Pd"].truth == sensor.detection_probability
    assert values["q"].truth == truth.motion.noise_intensity  # type: ignore[attr-defined]
    assert values["pos std"].truth == pytest.approx(1.0)
    assert values["pos rate"].error <= 0.25
    assert values["pos Pd"].error <= 0.1 and values["pos Pd"].absolute
    assert values["pos std"].error <= 1.5  # within 2.5 times the truth
    assert values["q"].estimate > 0 and math.isfinite(values["q"].error)
    assert values["pos rate"].error == pytest.approx(
        abs(values["pos rate"].estimate - 10.0) / 10.0
    )
    # The estimation is in the run's time; the run itself is the estimation's last pass.
    assert auto.seconds > given.seconds
    assert math.isfinite(auto.gospa.total) and auto.tracks >= 1


def test_the_estimates_are_printed_under_the_run_and_summarised(both) -> None:  # type: ignore[no-untyped-def]
    result, text, _ = both
    auto = result.runs[1]
    lines = text.splitlines()
    assert "parameters given,auto" in lines[0]
    at = next(i for i, line in enumerate(lines) if line.startswith("crossing") and " auto " in line)
    assert lines[at + 1] == estimates_line(auto.estimates)
    for v in auto.estimates:
        assert f"{v.label} {v.estimate:.3g} (true {v.truth:.3g}" in lines[at + 1]
    assert "=> crossing (k_prior birth, parameters auto)" in text
    (summary,) = result.auto
    ratio = auto.gospa.total / result.runs[0].gospa.total
    assert summary.gospa_ratio_mean == pytest.approx(ratio)
    assert auto_summary_line(summary) in lines
    assert f"GOSPA {ratio:.3f}x the given values' run" in text
    assert f"goal <= {AUTO_GOSPA_GOAL:g}x" in text
    assert "goals of parameters auto (k_prior birth):" in text
    assert "estimates within 20% of the truth (Pd within 0.03)" in text
    # The goals of the first choice, as before: GOSPA against the oracle.
    assert "goals (k_prior birth):" in text


def test_the_json_holds_the_estimates_and_the_ratio(both) -> None:  # type: ignore[no-untyped-def]
    result, _, data = both
    assert data["settings"]["parameters"] == ["given", "auto"]
    assert [run["parameters"] for run in data["runs"]] == ["given", "auto"]
    assert data["runs"][0]["estimates"] is None
    estimates = data["runs"][1]["estimates"]
    assert [e["key"] for e in estimates] == [
        "motion.noise_intensity", "sensors.pos.false_alarms_per_scan",
        "sensors.pos.detection_probability", "sensors.pos.noise_std", "birth.rate",
        "birth.initial_count", "birth.survival_probability",
    ]  # fmt: skip
    assert estimates[1]["truth"] == 10.0 and estimates[1]["goal"] == 0.2
    assert [f["parameters"] for f in data["families"]] == ["given", "auto"]
    (auto,) = data["auto"]
    assert auto["gospa_ratio_mean"] == pytest.approx(result.auto[0].gospa_ratio_mean)
    assert auto["gospa_met"] == (auto["gospa_ratio_mean"] <= AUTO_GOSPA_GOAL)
    assert [e["label"] for e in auto["errors"]] == ["q", "pos rate", "pos Pd", "pos std",
                                                    "births", "initial", "survival"]  # fmt: skip


def test_the_auto_configuration_holds_placeholders_and_the_run_none() -> None:
    setup = _bench_setup("crossing", 0, WINDOW, 5.0, "scenario", 12, "birth", "configured", "auto")
    config = setup.config
    assert config.auto.pending and len(config.auto.names()) == 7
    sensor = config.sensors["pos"]
    # The reader's placeholders: nothing of the true values (rate 10, Pd 0.9, q 0.002).
    assert (sensor.false_alarms_per_scan, sensor.detection_probability) == (0.0, 1.0)
    assert config.motion.noise_intensity == NOISE_PLACEHOLDER  # type: ignore[attr-defined]
    assert config.estimator.count.k_prior == "birth"
    assert config.estimator.windows.window_length == WINDOW
    truth = setup.scenario.config
    ran = run_auto(config, setup.scenario.scans, truth)
    assert not ran.config.auto.pending
    check_config(ran.config)  # runnable: no "auto" left
    # The last pass is the run unless its noise update moved the levels (then run again).
    assert ran.reran == (ran.estimate.result is None)
    assert ran.result is (ran.estimate.result or ran.result)
    values = {v.label: v.estimate for v in ran.values}
    assert values["pos Pd"] == ran.config.sensors["pos"].detection_probability
    assert values["q"] == ran.config.motion.noise_intensity  # type: ignore[attr-defined]
    # A set's models are estimated under the set: each component "auto", no single q.
    setup = _bench_setup("crossing", 0, WINDOW, 5.0, "scenario", 12, "birth", "imm", "auto")
    config = setup.config
    assert isinstance(config.motion, InteractingModels)
    assert [f.label for f in auto_fields(config)][:2] == ["q0", "q1"]
    assert "motion.models[1].noise_intensity" in config.auto.names()
    assert not config.auto.noise_intensity
    imm = run_auto(config, setup.scenario.scans, truth)
    assert isinstance(imm.config.motion, InteractingModels) and not imm.config.auto.pending
    values = {v.label: v for v in imm.values}
    assert [m.noise_intensity for m in imm.config.motion.models] == [
        values["q0"].estimate, values["q1"].estimate]  # fmt: skip
    assert values["q0"].truth is None  # the scenario simulates one model, not a set
    assert all(m.noise_intensity != NOISE_PLACEHOLDER for m in imm.config.motion.models)


def test_the_fields_follow_the_models() -> None:
    turning = [f.label for f in auto_fields(build_scenario("turning", 0, scans=5).config)]
    # a coordinated turn: no one scale
    assert turning == ["pos rate", "pos Pd", "pos std", "births", "initial", "survival"]
    two = [f.label for f in auto_fields(build_scenario("two_sensors", 0, scans=5).config)]
    assert two == ["q", "pos rate", "pos Pd", "pos std", "radar rate", "radar Pd", "births",
                   "initial", "survival"]  # fmt: skip


def test_without_given_runs_the_ratio_is_not_run(both) -> None:  # type: ignore[no-untyped-def]
    result, _, _ = both
    auto = result.runs[1]
    (summary,) = summarize_auto([auto, dataclasses.replace(auto, seed=1)])
    assert summary.gospa_ratio_mean is None and summary.gospa_met is None
    assert summary.seeds == (0, 1)
    assert "not run (add given to parameters)" in auto_summary_line(summary)
    assert summarize_auto([result.runs[0]]) == []


def test_an_unknown_choice_is_refused_naming_parameters(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(InputError, match="parameters must be one of given, auto") as info:
        bench_scenario("crossing", 0, WINDOW, scans=5, parameters="estimated")
    assert info.value.key == "parameters"
    for bad, message in (
        (("given", "estimated"), "parameters\\[1\\] must be one of given, auto"),
        ("auto", "parameters must be a sequence"),
        ((), "parameters must name at least one"),
        (("auto", "auto"), "parameters must be distinct"),
    ):
        with pytest.raises(InputError, match=message):
            run_benchmark(families=["crossing"], seeds=1, scans=5, gating=False,
                          out=io.StringIO(), parameters=bad)  # type: ignore[arg-type]  # fmt: skip
    assert main(["bench", "--families", "crossing", "--parameters", "given,nope"]) == 2
    assert "parameters[1] must be one of given, auto" in capsys.readouterr().err
    # --families takes commas too (as the brief's and compare's spelling has it).
    assert main(["bench", "--families", "crossing,no-such-family"]) == 2
    assert "unknown scenario(s) 'no-such-family'" in capsys.readouterr().err


def test_the_command_line_option() -> None:
    assert build_parser().parse_args(["bench"]).parameters == ["given"]
    args = build_parser().parse_args(["bench", "--parameters", "given, auto"])
    assert args.parameters == ["given", "auto"]


def test_the_defaults_run_as_before() -> None:
    run = bench_scenario("crossing", 0, WINDOW, scans=5)
    assert run.parameters == "given" and run.estimates is None
