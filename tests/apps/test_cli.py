"""The command line: simulate -> run -> evaluate through ``main``, and its error reporting."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from mapassoc.apps.cli import main
from mapassoc.data.io import read_tracks


@pytest.fixture(scope="module")
def scenario_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scenario")
    assert main(["simulate", "turning", "--out", str(out), "--seed", "3"]) == 0
    return out


def test_simulate_writes_the_scenario_folder(scenario_dir: Path) -> None:
    """The files read back as the scenario the library builds for the same name and seed."""
    import numpy as np

    from mapassoc.data.config import load_config
    from mapassoc.data.io import read_detections, read_origins, read_truth
    from mapassoc.evaluation.scenarios import build_scenario

    scenario = build_scenario("turning", 3)
    config = load_config(scenario_dir / "config.toml")
    assert config.birth == scenario.config.birth
    assert config.estimator == scenario.config.estimator
    assert repr(config.motion) == repr(scenario.config.motion)
    scans = read_detections(scenario_dir / "detections.csv", config.sensors)
    assert [s.time for s in scans] == [s.time for s in scenario.scans]
    for read, built in zip(scans, scenario.scans, strict=True):
        np.testing.assert_array_equal(read.rows, built.rows)
        np.testing.assert_allclose(read.detections, built.detections, rtol=1e-12)
    truth = read_truth(scenario_dir / "truth.csv")
    np.testing.assert_array_equal(truth.target_ids, scenario.truth.target_ids)
    np.testing.assert_allclose(truth.states, scenario.truth.states, rtol=1e-12)
    origins = read_origins(scenario_dir / "origins.csv")
    np.testing.assert_array_equal(origins.target_ids, scenario.origins.target_ids)


def test_run_then_evaluate(
    scenario_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    code = main(
        [
            "run",
            str(scenario_dir / "config.toml"),
            str(scenario_dir / "detections.csv"),
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    assert code == 0
    tracks = read_tracks(out / "tracks.csv")
    assert tracks.track_ids.size > 0
    windows = [json.loads(line) for line in (out / "windows.jsonl").read_text().splitlines()]
    assert windows, "no window lines"
    for w in windows:
        assert sum(w["p_k"]) == pytest.approx(1.0, abs=1e-9)
        assert 0 <= w["marginal_k"] < len(w["p_k"]) and 0 <= w["joint_map_k"] < len(w["p_k"])
        assert w["status"] in ("exact", "capped", "bounded", "time_limit")
        assert w["nodes_generated"] >= w["hypotheses_kept"] - w["carried_tracks"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scans"] == windows[-1]["last_scan"] + 1
    capsys.readouterr()
    metrics = tmp_path / "metrics.json"
    assert (
        main(
            [
                "evaluate",
                str(out / "tracks.csv"),
                str(scenario_dir / "truth.csv"),
                "--json",
                str(metrics),
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "GOSPA" in printed or "gospa" in printed
    data = json.loads(metrics.read_text())
    # Three targets that the estimator tracks well: GOSPA well below the cut-off scale.
    assert data["gospa"]["mean_total"] < 3.0
    # T-GOSPA of the trajectories, switching cost defaulting to the cut-off, and fragments.
    assert "T-GOSPA (c=10, p=2, gamma=10)" in printed and "identity switches" in printed
    assert data["tgospa"]["gamma"] == 10.0 and data["tgospa"]["method"] == "milp"
    parts = ("localisation", "missed", "false", "switching")
    assert data["tgospa"]["total"] ** 2 == pytest.approx(sum(data["tgospa"][k] for k in parts))
    assert data["fragmentation"]["fragments_per_target"] >= 1.0
    assert main(["evaluate", str(out / "tracks.csv"), str(scenario_dir / "truth.csv"),
                 "--switch-cost", "3", "--tgospa-method", "lp"]) == 0
    assert "gamma=3, LP lower bound" in capsys.readouterr().out


def test_run_is_byte_identical_without_timings(scenario_dir: Path, tmp_path: Path) -> None:
    outs = []
    for name in ("a", "b"):
        out = tmp_path / name
        assert (
            main(
                [
                    "run",
                    str(scenario_dir / "config.toml"),
                    str(scenario_dir / "detections.csv"),
                    "--out",
                    str(out),
                    "--no-progress",
                    "--no-timings",
                ]
            )
            == 0
        )
        outs.append(out)
    for name in ("tracks.csv", "associations.csv", "windows.jsonl", "summary.json"):
        assert (outs[0] / name).read_bytes() == (outs[1] / name).read_bytes(), name


def test_run_writes_the_refinement_the_existence_and_the_associations(
    scenario_dir: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    args = ["run", str(scenario_dir / "config.toml"), str(scenario_dir / "detections.csv")]
    assert main([*args, "--out", str(out), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    refinement = summary["refinement"]
    history = [refinement["objective_forward"], *refinement["objective_after_pass"]]
    assert all(b >= a for a, b in zip(history, history[1:], strict=False))
    assert refinement["objective"] == history[-1]
    tracks = read_tracks(out / "tracks.csv")
    assert tracks.existence is not None
    assert np.all((tracks.existence >= 0) & (tracks.existence <= 1))
    with (out / "associations.csv").open() as handle:
        pairs = {
            (int(r["detection_id"]), int(r["track_id"])): float(r["probability"])
            for r in csv.DictReader(handle)
        }
    assert all(0.0 <= p <= 1.0 for p in pairs.values())
    used = tracks.detection_rows >= 0
    for row, track in zip(tracks.detection_rows[used], tracks.track_ids[used], strict=True):
        assert (int(row), int(track)) in pairs  # every track's own detections are listed
    # Per detection the probabilities over tracks are of exclusive events.
    per_detection: dict[int, float] = {}
    for (row, _), p in pairs.items():
        per_detection[row] = per_detection.get(row, 0.0) + p
    assert max(per_detection.values()) <= 1.0 + 1e-9


def test_bad_input_exits_2_with_a_message(
    scenario_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.toml"
    text = (scenario_dir / "config.toml").read_text()
    bad.write_text(text.replace("detection_probability = 0.9", "detection_probability = 1.5"))
    assert "detection_probability = 1.5" in bad.read_text()
    code = main(
        ["run", str(bad), str(scenario_dir / "detections.csv"), "--out", str(tmp_path / "o")]
    )
    assert code == 2
    err = capsys.readouterr().err
    assert "detection_probability" in err and "1.5" in err
    code = main(["evaluate", str(tmp_path / "missing.csv"), str(scenario_dir / "truth.csv")])
    assert code == 2
    assert "missing.csv" in capsys.readouterr().err
    assert main(["simulate", "no-such-scenario", "--out", str(tmp_path / "x")]) == 2
    assert "no-such-scenario" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["simulate", "run", "evaluate", "demo", "bench", "scenarios"])
def test_every_command_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    assert command in capsys.readouterr().out


def test_scenarios_lists_the_default(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    assert "crossing" in out and "(default)" in out


# ------------------------------------------------------------ single files on a full disk


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 10-scan scenario (``scenario/``) and its run (``run/``)."""
    root = tmp_path_factory.mktemp("tiny")
    assert main(["simulate", "crossing", "--out", str(root / "scenario"), "--scans", "10"]) == 0
    assert main(["run", str(root / "scenario" / "config.toml"),
                 str(root / "scenario" / "detections.csv"), "--out", str(root / "run"),
                 "--no-progress"]) == 0  # fmt: skip
    return root


def test_evaluate_json_on_a_full_disk_keeps_the_old_file_or_none(
    tiny_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A disk that fills while `evaluate --json` writes used to leave a cut file (or an
    empty one) in place of the previous one."""
    from support import file_size_limit

    args = ["evaluate", str(tiny_run / "run" / "tracks.csv"),
            str(tiny_run / "scenario" / "truth.csv")]  # fmt: skip
    old = tmp_path / "old.json"
    old.write_text('{"previous": true}\n')
    for path in (old, tmp_path / "new.json"):
        with file_size_limit(64):
            code = main([*args, "--json", str(path)])
        assert code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{path}: cannot write: File too large" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.json"]
    assert old.read_text() == '{"previous": true}\n'
    assert main([*args, "--json", str(old)]) == 0
    assert "gospa" in json.loads(old.read_text())


def test_estimate_parameters_write_on_a_full_disk_leaves_no_file(
    tiny_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from support import file_size_limit

    written = tmp_path / "estimated.toml"
    args = ["estimate-parameters", str(tiny_run / "scenario" / "config.toml"),
            str(tiny_run / "scenario" / "detections.csv"), "--write", str(written),
            "--no-progress"]  # fmt: skip
    with file_size_limit(64):
        code = main(args)
    assert code == 2
    err = capsys.readouterr().err
    assert f"{written}: cannot write: File too large" in err
    assert list(tmp_path.iterdir()) == []
    assert main(args) == 0
    assert "[motion]" in written.read_text()


def test_simulate_overwrite_never_replaces_a_users_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`simulate … --out d --overwrite`, d a folder of the user's with a config.toml of
    their own beside other files: refused, every file as it was."""
    out = tmp_path / "d"
    out.mkdir()
    (out / "config.toml").write_text("# mine\n")
    (out / "notes.txt").write_text("keep")
    args = ["simulate", "crossing", "--out", str(out), "--scans", "5"]
    for options in ([], ["--overwrite"]):
        assert main([*args, *options]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and str(out) in err and "notes.txt" in err
    assert (out / "config.toml").read_text() == "# mine\n"
    assert sorted(p.name for p in out.iterdir()) == ["config.toml", "notes.txt"]
    # A folder simulate wrote is replaced with --overwrite only.
    (out / "notes.txt").unlink()
    (out / "config.toml").unlink()
    assert main(args) == 0
    assert main(args) == 2 and "pass --overwrite" in capsys.readouterr().err
    assert main([*args, "--overwrite", "--seed", "1"]) == 0
