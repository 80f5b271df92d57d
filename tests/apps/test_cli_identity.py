"""``mapassoc evaluate`` reports P-GOSPA beside GOSPA and writes it as ``"pgospa"``; its
help names the T-GOSPA settings of Xia et al."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mapassoc.apps.cli import build_parser, main
from mapassoc.data.formats import write_tracks_file, write_truth_file
from mapassoc.data.io import TrackTable, TruthTable

NAMES = ("x", "y")


def write_files(folder: Path, existence: list[float] | None) -> tuple[Path, Path]:
    """One target at the origin at times 0 and 1; track 3 at distance 3 at time 0, and
    track 4 at distance 20 (a false track, the target missed) at time 1."""
    truth = TruthTable(
        target_ids=np.array([0, 0]),
        times=np.array([0.0, 1.0]),
        states=np.zeros((2, 2)),
        state_names=NAMES,
    )
    tracks = TrackTable(
        track_ids=np.array([3, 4]),
        times=np.array([0.0, 1.0]),
        sensors=("pos", "pos"),
        states=np.array([[3.0, 0.0], [20.0, 0.0]]),
        variances=np.ones((2, 2)),
        detection_rows=np.array([-1, -1]),
        state_names=NAMES,
        existence=None if existence is None else np.array(existence),
    )
    truth_path, tracks_path = folder / "truth.csv", folder / "tracks.csv"
    write_truth_file(truth_path, truth)
    write_tracks_file(tracks_path, tracks)
    return tracks_path, truth_path


def evaluate_json(
    tmp_path: Path, existence: list[float] | None, *extra: str
) -> tuple[str, dict[str, object]]:
    tracks, truth = write_files(tmp_path, existence)
    out = tmp_path / "metrics.json"
    assert main(["evaluate", str(tracks), str(truth), "--json", str(out), *extra]) == 0
    return out.name, json.loads(out.read_text())


def test_evaluate_prints_and_writes_pgospa(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, data = evaluate_json(tmp_path, [0.5, 0.2])
    printed = capsys.readouterr().out
    lines = printed.splitlines()
    # P-GOSPA follows GOSPA's parts, before the counts.
    first = next(i for i, line in enumerate(lines) if line.startswith("P-GOSPA mean"))
    assert lines[first - 1].lstrip().startswith("false part of GOSPA^2")
    assert "existence mismatch part of P-GOSPA^2, mean" in printed
    pg = data["pgospa"]
    assert isinstance(pg, dict)
    # Time 0: 0.5 * 9 + 0.5 * 50 = 29.5.  Time 1: a miss (50) and 0.2 * 50 = 10, so 60.
    assert pg["mean_total"] == pytest.approx((math.sqrt(29.5) + math.sqrt(60.0)) / 2)
    assert pg["mean_localisation"] == pytest.approx(4.5 / 2)
    assert pg["mean_existence_mismatch"] == pytest.approx(25.0 / 2)
    assert pg["mean_missed"] == pytest.approx(50.0 / 2)
    assert pg["mean_false"] == pytest.approx(10.0 / 2)
    assert (pg["c"], pg["p"], pg["alpha"], pg["num_times"]) == (10.0, 2.0, 2.0, 2)
    # GOSPA ignores the existence: (3 + 10) / 2.
    gospa = data["gospa"]
    assert isinstance(gospa, dict) and gospa["mean_total"] == pytest.approx(6.5)
    assert f"{pg['mean_total']:.4f}" in printed


def test_without_an_existence_column_pgospa_equals_gospa(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _, data = evaluate_json(tmp_path, None, "--cutoff", "10", "--order", "1")
    pg, gospa = data["pgospa"], data["gospa"]
    assert isinstance(pg, dict) and isinstance(gospa, dict)
    assert pg["mean_total"] == pytest.approx(gospa["mean_total"])
    assert pg["mean_existence_mismatch"] == 0.0
    assert pg["p"] == 1.0
    # The other keys are still there.
    assert {"gospa", "tgospa", "fragmentation", "position_rmse"} <= set(data)


def test_disjoint_times_are_warned_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tracks, truth = write_files(tmp_path, [1.0, 1.0])
    other = tmp_path / "other.csv"
    text = truth.read_text().replace("\n0,0.0,", "\n0,7.0,").replace("\n0,1.0,", "\n0,8.0,")
    other.write_text(text)
    assert main(["evaluate", str(tracks), str(other)]) == 0
    assert capsys.readouterr().err.count("share no time") == 1


def test_the_help_names_xia_et_al_settings() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.choices and "evaluate" in a.choices)
    text = sub.choices["evaluate"].format_help()  # type: ignore[index]
    assert "--cutoff 10 --order 1 --switch-cost 2" in " ".join(text.split())
    assert "P-GOSPA" in text
