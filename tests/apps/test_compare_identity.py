"""``compare`` rows carry P-GOSPA (with its existence-mismatch part); the summary table
shows P-GOSPA and T-GOSPA's identity switches."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from mapassoc.apps.compare import compare, format_summary, summarize
from mapassoc.data.io import TrackTable, TruthTable
from mapassoc.data.outputs import TrackerOutput
from mapassoc.evaluation.scenarios import build_scenario, generic_config, truncate_scenario
from mapassoc.evaluation.scoring import score_tracks
from mapassoc.evaluation.tables import pgospa_tables
from mapassoc.trackers.registry import build_tracker

SCANS = 8


@pytest.fixture(scope="module")
def table() -> pd.DataFrame:
    return compare(["map", "gnn"], ["crossing"], [0], scans=SCANS, config="generic")


def test_rows_carry_pgospa_of_the_reported_existence(table: pd.DataFrame) -> None:
    rows = table.set_index("tracker")
    assert (table["status"] == "ok").all()
    scenario = truncate_scenario(build_scenario("crossing", 0), SCANS)
    config = generic_config(scenario)
    tracks = build_tracker("map", config=config, origins=scenario.origins).track(
        scenario.scans
    ).tracks
    assert tracks.existence is not None  # the MAP estimator reports existence
    series = pgospa_tables(scenario.truth, tracks, c=10.0)
    assert rows.loc["map", "pgospa"] == pytest.approx(series.mean_total, rel=1e-9)
    assert rows.loc["map", "pgospa_existence_mismatch"] == pytest.approx(
        float(np.mean(series.existence_mismatch)), rel=1e-9, abs=1e-12
    )
    # GNN reports no existence: its P-GOSPA is its GOSPA and nothing is mismatched.
    assert rows.loc["gnn", "pgospa"] == pytest.approx(rows.loc["gnn", "gospa"], rel=1e-12)
    assert rows.loc["gnn", "pgospa_existence_mismatch"] == 0.0


def test_the_summary_shows_pgospa_and_tgospa_switches(table: pd.DataFrame) -> None:
    summary = summarize(table)
    lines = format_summary(summary).splitlines()
    labels = lines[0].split()
    p_col, t_col = labels.index("P-GOSPA"), labels.index("T-IDsw")
    assert labels[p_col - 1] == "false^p" and labels[t_col - 1] == "T-GOSPA"
    for line, (_, row) in zip(lines[2:], summary.iterrows(), strict=True):
        cells = line.split()
        assert float(cells[p_col]) == pytest.approx(row["pgospa"], abs=0.005)
        assert float(cells[t_col]) == pytest.approx(row["tgospa_id_switches"], abs=0.05)


def test_score_tracks_pgospa_by_hand() -> None:
    # One target at the origin at times 0 and 1; track 2 at distance 3 with existence 0.5.
    truth = TruthTable(
        target_ids=np.array([0, 0]),
        times=np.array([0.0, 1.0]),
        states=np.zeros((2, 2)),
        state_names=("x", "y"),
    )
    tracks = TrackTable(
        track_ids=np.array([2, 2]),
        times=np.array([0.0, 1.0]),
        sensors=("pos", "pos"),
        states=np.array([[3.0, 0.0], [3.0, 0.0]]),
        variances=np.ones((2, 2)),
        detection_rows=np.array([-1, -1]),
        state_names=("x", "y"),
        existence=np.array([0.5, 0.5]),
    )
    scores = score_tracks(
        truth, TrackerOutput(tracks=tracks, seconds=0.0), c=10.0, clear_mot_scores=False
    )
    # Each time: 0.5 * 9 + 0.5 * 100 / 2 = 29.5; GOSPA 3.
    assert scores.pgospa == pytest.approx(math.sqrt(29.5))
    assert scores.pgospa_existence_mismatch == pytest.approx(25.0)
    assert scores.gospa == pytest.approx(3.0)
    assert scores.as_row()["pgospa"] == scores.pgospa
