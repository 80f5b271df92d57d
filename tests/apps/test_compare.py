"""Tests of mapassoc.apps.compare (compare, summarize, format_summary), the
``mapassoc compare`` command and its figure."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from mapassoc.apps.cli import main
from mapassoc.apps.compare import COMPARE_COLUMNS, compare, format_summary, summarize
from mapassoc.errors import InputError
from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario
from mapassoc.evaluation.scoring import TrackingScores, score_tracks
from mapassoc.trackers.oracle import OracleTracker

# The scores' own "seconds" (the tracker's timing) gives way to the row's measured one.
SCORE_COLUMNS = tuple(f.name for f in dataclasses.fields(TrackingScores) if f.name != "seconds")
# Columns that differ between two runs of the same comparison: wall times.
TIMING_COLUMNS = ("seconds", "scans_per_second")


@pytest.fixture(scope="module")
def two_seeds() -> pd.DataFrame:
    return compare(["gnn", "oracle"], ["crossing"], [0, 1], scans=15)


def test_one_row_per_run_with_the_documented_columns() -> None:
    table = compare(["gnn", "oracle"], ["crossing"], [0], scans=15)
    assert tuple(table.columns) == COMPARE_COLUMNS + SCORE_COLUMNS
    assert table[["scenario", "seed", "tracker"]].values.tolist() == [
        ["crossing", 0, "gnn"],
        ["crossing", 0, "oracle"],
    ]
    assert (table["status"] == "ok").all()
    assert (table["c"] == 10.0).all() and (table["motp_threshold"] == 10.0).all()
    assert (table["seconds"] > 0).all()
    assert np.allclose(table["scans_per_second"], 15 / table["seconds"])
    by_tracker = table.set_index("tracker")
    # The oracle smooths on the true associations: the lowest GOSPA and OSPA(2).
    assert by_tracker.loc["oracle", "gospa"] < by_tracker.loc["gnn", "gospa"]
    assert by_tracker.loc["oracle", "ospa2"] < by_tracker.loc["gnn", "ospa2"]
    # The oracle row is score_tracks of the oracle on the same truncated realisation.
    scenario = truncate_scenario(build_scenario("crossing", 0), 15)
    output = OracleTracker(config=scenario.config, origins=scenario.origins).track(scenario.scans)
    expected = score_tracks(scenario.truth, output, c=10.0).as_row()
    for column, value in expected.items():
        if column in TIMING_COLUMNS:
            continue
        got = by_tracker.loc["oracle", column]
        if value is None:
            assert got is None or pd.isna(got), column
        else:
            assert got == pytest.approx(value, rel=1e-12), column


def test_summarize_averages_over_seeds(two_seeds: pd.DataFrame) -> None:
    assert len(two_seeds) == 4 and sorted(set(two_seeds["seed"])) == [0, 1]
    summary = summarize(two_seeds)
    assert summary[["scenario", "tracker"]].values.tolist() == [
        ["crossing", "gnn"],
        ["crossing", "oracle"],
    ]
    assert (summary["runs"] == 2).all() and (summary["failed"] == 0).all()
    for tracker in ("gnn", "oracle"):
        rows = two_seeds[two_seeds["tracker"] == tracker]
        assert rows["gospa"].iloc[0] != rows["gospa"].iloc[1]  # the seeds differ
        got = summary.set_index("tracker").loc[tracker]
        for column in ("gospa", "ospa2", "mota", "id_switches", "seconds", "num_tracks"):
            hand = (float(rows[column].iloc[0]) + float(rows[column].iloc[1])) / 2.0
            assert got[column] == pytest.approx(hand, rel=1e-12), column
    assert "seed" not in summary.columns and "status" not in summary.columns


def test_summarize_leaves_failed_runs_out_of_the_means() -> None:
    table = pd.DataFrame(
        [
            {"scenario": "a", "seed": 0, "tracker": "x", "status": "ok", "gospa": 1.0},
            {"scenario": "a", "seed": 1, "tracker": "x", "status": "ok", "gospa": 3.0},
            {"scenario": "a", "seed": 2, "tracker": "x", "status": "ok", "gospa": 8.0},
            {"scenario": "a", "seed": 3, "tracker": "x", "status": "InputError: no",
             "gospa": math.nan},
            {"scenario": "a", "seed": 0, "tracker": "y", "status": "InputError: no",
             "gospa": math.nan},
        ]
    )
    summary = summarize(table).set_index("tracker")
    assert summary.loc["x", "gospa"] == 4.0  # the mean (the median would be 3)
    assert (summary.loc["x", "runs"], summary.loc["x", "failed"]) == (3, 1)
    assert (summary.loc["y", "runs"], summary.loc["y", "failed"]) == (0, 1)
    assert math.isnan(summary.loc["y", "gospa"])
    with pytest.raises(InputError, match="status"):
        summarize(table.drop(columns="status"))


def test_format_summary_shows_the_means(two_seeds: pd.DataFrame) -> None:
    summary = summarize(two_seeds)
    text = format_summary(summary)
    lines = text.splitlines()
    assert lines[0].split() == [
        "scenario", "tracker", "runs", "GOSPA", "loc^p", "miss^p", "false^p", "P-GOSPA",
        "OSPA2", "T-GOSPA", "T-IDsw", "frag", "MOTA", "IDsw", "Brier", "seconds",
    ]
    assert set(lines[1]) == {"-"}
    for line, (_, row) in zip(lines[2:], summary.iterrows(), strict=True):
        cells = line.split()
        assert cells[:3] == [row["scenario"], row["tracker"], "2"]
        assert float(cells[3]) == pytest.approx(row["gospa"], abs=0.005)
        assert float(cells[7]) == pytest.approx(row["pgospa"], abs=0.005)
        assert float(cells[8]) == pytest.approx(row["ospa2"], abs=0.005)
        assert float(cells[9]) == pytest.approx(row["tgospa"], abs=0.005)
        assert float(cells[10]) == pytest.approx(row["tgospa_id_switches"], abs=0.05)
        assert float(cells[11]) == pytest.approx(row["fragments_per_target"], abs=0.005)
        assert cells[14] == "-"  # neither tracker reports p(K | Z)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"trackers": ["gnn", "nosuch"]}, r"unknown trackers \['nosuch'\]"),
        ({"scenarios": ["crossing", "atlantis"]}, r"unknown scenarios \['atlantis'\]"),
        ({"trackers": "gnn"}, "sequence of names"),
        ({"trackers": []}, "trackers is empty"),
        ({"trackers": ["gnn", "gnn"]}, "twice"),
        ({"seeds": [-1]}, "seeds"),
        ({"seeds": [True]}, "seeds"),
        ({"seeds": []}, "seeds is empty"),
        ({"c": 0.0}, "c must be"),
        ({"config": "tuned"}, "config"),
        ({"scans": 0}, "scans"),
        ({"window_length": 0}, "window_length"),
        ({"time_limit": 0.0}, "time_limit"),
        ({"time_limit": float("inf")}, "time_limit"),
        ({"ospa2_window": 0}, "ospa2_window"),
    ],
)
def test_bad_arguments_raise_before_running(kwargs: dict, message: str) -> None:
    arguments = {"trackers": ["gnn"], "scenarios": ["crossing"], "seeds": [0], **kwargs}
    trackers = arguments.pop("trackers")
    scenarios = arguments.pop("scenarios")
    seeds = arguments.pop("seeds")
    with pytest.raises(InputError, match=message):
        compare(trackers, scenarios, seeds, **arguments)


def test_windowed_ospa2_option() -> None:
    table = compare(["oracle"], ["crossing"], [0], scans=15, ospa2_window=3)
    scenario = truncate_scenario(build_scenario("crossing", 0), 15)
    output = OracleTracker(config=scenario.config, origins=scenario.origins).track(scenario.scans)
    expected = score_tracks(scenario.truth, output, c=10.0, ospa2_window=3)
    assert table["ospa2_window"].tolist() == [3]
    assert table["ospa2"].iloc[0] == pytest.approx(expected.ospa2, rel=1e-12)
    whole = score_tracks(scenario.truth, output, c=10.0)
    assert expected.ospa2 != pytest.approx(whole.ospa2)  # the option changes the score


def test_time_limit_reaches_every_tracker(monkeypatch: pytest.MonkeyPatch) -> None:
    from mapassoc.apps import compare as module

    seen: list[float] = []
    real = module.build_tracker

    def spy(name: str, *, config: object, origins: object) -> object:
        seen.append(config.estimator.time_limit)  # type: ignore[attr-defined]
        return real(name, config=config, origins=origins)  # type: ignore[arg-type]

    monkeypatch.setattr(module, "build_tracker", spy)
    compare(["oracle", "gnn"], ["crossing"], [0], scans=5, time_limit=600.0)
    assert seen == [600.0, 600.0]


def test_seeds_may_be_any_iterable_of_integers() -> None:
    table = compare(["oracle"], ["crossing"], np.array([0, 1]), scans=5)
    assert table["seed"].tolist() == [0, 1]
    again = compare(["oracle"], ["crossing"], (s for s in (0, 1)), scans=5)
    assert again["gospa"].tolist() == table["gospa"].tolist()


def test_draw_comparison_bars_are_the_summary(two_seeds: pd.DataFrame) -> None:
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    from mapassoc.apps.plotting import draw_comparison

    summary = summarize(two_seeds)
    fig = Figure()
    axes = [fig.add_subplot(2, 3, i + 1) for i in range(5)]
    draw_comparison(axes, summary)
    columns = ("gospa", "ospa2", "tgospa", "fragments_per_target", "seconds")
    for ax, column in zip(axes, columns, strict=True):
        heights = [patch.get_height() for patch in ax.patches]
        np.testing.assert_allclose(heights, summary[column].to_numpy(dtype=float))
    # The identity panels are not the same numbers as the others (a mix-up would pass a
    # check of one column only), and a summary row per tracker is one bar per panel.
    assert not np.allclose(summary["tgospa"], summary["gospa"])
    assert len(axes[3].patches) == len(summary)
    with pytest.raises(InputError, match="axes: got 4 Axes, expected 5"):
        draw_comparison(axes[:4], summary)


def test_cli_writes_consistent_tables_and_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("matplotlib")
    out = tmp_path / "cmp"
    status = main(
        ["compare", "--trackers", "gnn,oracle", "--scenarios", "crossing", "--scans", "15",
         "--out", str(out)]
    )
    assert status == 0
    printed = capsys.readouterr()
    table = pd.read_csv(out / "compare.csv")
    summary = pd.read_csv(out / "compare_summary.csv")
    assert tuple(table.columns) == COMPARE_COLUMNS + SCORE_COLUMNS
    assert table["tracker"].tolist() == ["gnn", "oracle"] and (table["seed"] == 0).all()
    # The same comparison in-process gives the same scores (the runs are deterministic).
    direct = compare(["gnn", "oracle"], ["crossing"], [0], scans=15)
    for column in ("gospa", "ospa", "ospa2", "mota", "motp", "id_switches", "num_tracks"):
        np.testing.assert_allclose(table[column], direct[column].astype(float), rtol=1e-9)
    # The summary file is the summary of the table file (one seed: the rows themselves).
    assert summary["tracker"].tolist() == ["gnn", "oracle"] and (summary["runs"] == 1).all()
    for column in ("gospa", "ospa2", "mota", "seconds"):
        np.testing.assert_allclose(summary[column], table[column], rtol=1e-12)
    # What it printed is format_summary of that summary, then the files written.
    assert format_summary(summarize(direct)).splitlines()[0] in printed.out
    for _, row in summary.iterrows():
        assert f"{row['gospa']:7.2f}" in printed.out
    assert "compare.png" in printed.out.splitlines()[-1]
    assert "crossing seed 0 gnn" in printed.err
    png = (out / "compare.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    from matplotlib.image import imread

    assert imread(out / "compare.png").shape[:2] == (800, 1200)  # 12 x 8 in at 100 dpi


def test_cli_reports_unknown_names(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status = main(
        ["compare", "--trackers", "gnn,nosuch", "--scenarios", "crossing", "--out",
         str(tmp_path / "x"), "--no-plot"]
    )
    assert status == 2
    assert "nosuch" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


# ------------------------------------------------------------ the compare folder's rule

QUICK = ["compare", "--trackers", "oracle", "--scenarios", "crossing", "--scans", "5",
         "--no-plot"]  # fmt: skip


@pytest.mark.parametrize("options", [[], ["--overwrite"]])
def test_cli_never_writes_into_a_users_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: list[str]
) -> None:
    """`compare --out c`, c holding a compare.csv of the user's: refused, with or without
    --overwrite, before anything runs; the folder stays byte for byte."""
    out = tmp_path / "c"
    out.mkdir()
    (out / "compare.csv").write_text("my,own\n1,2\n")
    (out / "notes.txt").write_text("keep")
    assert main([*QUICK, "--out", str(out), *options]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and str(out) in captured.err
    assert "crossing seed 0" not in captured.err  # nothing ran
    assert (out / "compare.csv").read_text() == "my,own\n1,2\n"
    assert sorted(p.name for p in out.iterdir()) == ["compare.csv", "notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c"]


def test_cli_replaces_its_own_comparison_only_with_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "c"
    assert main([*QUICK, "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "compare.csv", "compare_summary.csv", "manifest.json"]  # fmt: skip
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["format"] == "mapassoc-compare/1" and manifest["status"] == "complete"
    header = (out / "compare.csv").read_text().splitlines()[0]
    capsys.readouterr()
    assert main([*QUICK, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds a complete comparison" in err
    assert "--overwrite" in err and "--resume" not in err
    (out / "compare.csv").write_bytes(b"changed by hand")
    assert main([*QUICK, "--out", str(out), "--overwrite"]) == 0
    assert (out / "compare.csv").read_text().splitlines()[0] == header
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c"]  # no .partial, no lock


def test_cli_overwrites_a_comparison_written_before_folders_had_a_manifest(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "c"
    assert main([*QUICK, "--out", str(out)]) == 0
    (out / "manifest.json").unlink()  # what the version before wrote
    assert main([*QUICK, "--out", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert main([*QUICK, "--out", str(out), "--overwrite"]) == 0
    assert (out / "manifest.json").exists()


def test_cli_documents_overwrite(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    assert "--overwrite" in capsys.readouterr().out
