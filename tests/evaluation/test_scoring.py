"""Tests of mapassoc.evaluation.scoring: every metric of a tracker run as TrackingScores."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mapassoc.data.io import TrackTable, TruthTable
from mapassoc.errors import InputError
from mapassoc.evaluation.calibration import count_series_scores
from mapassoc.evaluation.metrics import gospa_over_time
from mapassoc.evaluation.ospa import ospa2, ospa2_over_time, ospa_over_time
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.evaluation.scoring import TrackingScores, score_tracks
from mapassoc.evaluation.tables import position_names, track_points, truth_points
from mapassoc.evaluation.tgospa import fragmentation_of, tgospa
from mapassoc.trackers.base import CountSeries, TrackerOutput
from mapassoc.trackers.oracle import OracleTracker

pytest.importorskip("motmetrics")

from mapassoc.evaluation.clear_mot import clear_mot  # noqa: E402


@pytest.fixture(scope="module")
def crossing() -> tuple[TruthTable, TrackerOutput]:
    scenario = build_scenario("crossing", 0)
    output = OracleTracker(config=scenario.config, origins=scenario.origins).track(scenario.scans)
    return scenario.truth, output


def truth_as_tracks(truth: TruthTable) -> TrackerOutput:
    """The truth written as a track table (ids kept, zero variances)."""
    n = truth.times.shape[0]
    tracks = TrackTable(
        track_ids=truth.target_ids,
        times=truth.times,
        sensors=("radar",) * n,
        states=truth.states,
        variances=np.zeros_like(truth.states),
        detection_rows=np.full(n, -1, dtype=np.int64),
        state_names=truth.state_names,
    )
    return TrackerOutput(tracks=tracks, seconds=0.25)


def test_oracle_scores_equal_the_metrics_computed_directly(
    crossing: tuple[TruthTable, TrackerOutput],
) -> None:
    truth, output = crossing
    scores = score_tracks(truth, output, c=10.0, p=2.0)
    names = position_names(truth, output.tracks)
    assert names == ("x", "y")
    truth_run = truth_points(truth, names)
    track_run = track_points(output.tracks, names)
    gospa = gospa_over_time(truth_run, track_run, c=10.0, p=2.0)
    assert scores.gospa == pytest.approx(gospa.mean_total, rel=1e-12)
    assert scores.gospa_localisation == pytest.approx(gospa.mean_localisation, rel=1e-12)
    # The oracle covers every target at every scan of this run: localisation only.
    assert scores.gospa_missed == 0.0 and scores.gospa_false == 0.0
    assert scores.gospa > 0.0
    assert scores.gospa**2 <= scores.gospa_localisation + 1e-12  # mean of roots <= root of mean
    assert scores.ospa == pytest.approx(
        ospa_over_time(truth_run, track_run, c=10.0).mean_total, rel=1e-12
    )
    assert scores.ospa2 == pytest.approx(ospa2(truth_run, track_run, c=10.0).total, rel=1e-12)
    assert scores.ospa2_window is None
    mot = clear_mot(truth_run, track_run, threshold=10.0)
    assert (scores.mota, scores.motp) == (mot.mota, mot.motp)
    assert scores.mota == 1.0 and scores.id_switches == 0 and scores.fragmentations == 0
    assert scores.mostly_tracked == np.unique(truth.target_ids).size
    assert scores.motp_threshold == 10.0
    assert scores.num_tracks == np.unique(output.tracks.track_ids).size
    assert scores.seconds == output.seconds
    assert (scores.k_brier, scores.k_ece, scores.k_hit_rate) == (None, None, None)


def test_truth_scored_against_itself_is_perfect(
    crossing: tuple[TruthTable, TrackerOutput],
) -> None:
    truth, _ = crossing
    scores = score_tracks(truth, truth_as_tracks(truth), c=10.0)
    for field in ("gospa", "gospa_localisation", "gospa_missed", "gospa_false", "ospa", "ospa2"):
        assert getattr(scores, field) == 0.0, field
    assert scores.mota == 1.0 and scores.motp == 0.0
    assert (scores.id_switches, scores.fragmentations, scores.mostly_lost) == (0, 0, 0)
    assert scores.mostly_tracked == scores.num_tracks == np.unique(truth.target_ids).size
    windowed = score_tracks(truth, truth_as_tracks(truth), c=10.0, ospa2_window=5)
    assert windowed.ospa2 == 0.0 and windowed.ospa2_window == 5


def test_no_tracks_is_all_missed(crossing: tuple[TruthTable, TrackerOutput]) -> None:
    truth, output = crossing
    tracks = output.tracks
    keep = np.zeros(tracks.track_ids.shape[0], dtype=bool)
    empty_tracks = TrackTable(
        track_ids=tracks.track_ids[keep], times=tracks.times[keep], sensors=(),
        states=tracks.states[keep], variances=tracks.variances[keep],
        detection_rows=tracks.detection_rows[keep], state_names=tracks.state_names,
    )
    scores = score_tracks(truth, TrackerOutput(tracks=empty_tracks, seconds=0.0), c=10.0)
    # n_t targets at time t, all missed: GOSPA_t = sqrt(n_t c^2 / 2); OSPA = OSPA(2) = c.
    n_t = np.unique(truth.times, return_counts=True)[1]
    assert n_t.min() < n_t.max()  # targets come and go in this scenario
    assert scores.gospa == pytest.approx(float(np.mean(np.sqrt(n_t * 100.0 / 2.0))))
    assert scores.gospa_missed == pytest.approx(float(np.mean(n_t * 50.0)))
    assert scores.ospa == pytest.approx(10.0) and scores.ospa2 == pytest.approx(10.0)
    assert scores.mota == 0.0 and math.isnan(scores.motp)
    assert scores.mostly_lost == np.unique(truth.target_ids).size and scores.num_tracks == 0


def test_options_window_threshold_counts_and_no_clear_mot(
    crossing: tuple[TruthTable, TrackerOutput],
) -> None:
    truth, output = crossing
    names = position_names(truth, output.tracks)
    truth_run = truth_points(truth, names)
    track_run = track_points(output.tracks, names)
    counts = CountSeries(
        start_times=np.array([0.0, 10.0]),
        end_times=np.array([4.0, 14.0]),
        probabilities=np.array([[0.1, 0.2, 0.7], [0.0, 0.5, 0.5]]),
    )
    with_counts = dataclasses.replace(output, counts=counts)
    scores = score_tracks(
        truth, with_counts, c=5.0, p=1.0, motp_threshold=2.0, ospa2_window=7, num_bins=4
    )
    assert scores.ospa2 == pytest.approx(
        ospa2_over_time(truth_run, track_run, c=5.0, p=1.0, window_length=7).mean_total
    )
    assert scores.ospa2_window == 7
    assert scores.gospa == pytest.approx(gospa_over_time(truth_run, track_run, c=5.0, p=1.0)
                                         .mean_total)
    mot = clear_mot(truth_run, track_run, threshold=2.0)
    assert scores.motp_threshold == 2.0 and scores.mota == mot.mota
    expected = count_series_scores(truth, counts, num_bins=4)
    assert (scores.k_brier, scores.k_ece, scores.k_hit_rate) == (
        expected.brier, expected.ece, expected.hit_rate
    )
    without = score_tracks(truth, output, c=5.0, clear_mot_scores=False)
    assert all(
        getattr(without, f) is None
        for f in ("mota", "motp", "id_switches", "fragmentations", "mostly_tracked",
                  "mostly_lost", "motp_threshold")
    )


def test_as_row_is_flat_and_in_declaration_order(
    crossing: tuple[TruthTable, TrackerOutput],
) -> None:
    truth, output = crossing
    row = score_tracks(truth, output, c=10.0).as_row()
    assert list(row) == [f.name for f in dataclasses.fields(TrackingScores)]
    assert all(v is None or isinstance(v, (int, float)) for v in row.values())
    assert not any(isinstance(v, float) and math.isnan(v) for v in row.values())


def test_bad_arguments(crossing: tuple[TruthTable, TrackerOutput]) -> None:
    truth, output = crossing
    with pytest.raises(InputError, match="truth must be a TruthTable"):
        score_tracks(output, output, c=10.0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="output must be a TrackerOutput"):
        score_tracks(truth, output.tracks, c=10.0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="c"):
        score_tracks(truth, output, c=0.0)
    with pytest.raises(InputError, match="motp_threshold"):
        score_tracks(truth, output, c=10.0, motp_threshold=-1.0)
    with pytest.raises(InputError, match="clear_mot_scores"):
        score_tracks(truth, output, c=10.0, clear_mot_scores=1)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="window_length"):
        score_tracks(truth, output, c=10.0, ospa2_window=0)
    empty = TruthTable(
        target_ids=np.zeros(0, dtype=np.int64), times=np.zeros(0), states=np.zeros((0, 2)),
        state_names=("x", "y"),
    )
    with pytest.raises(InputError, match="truth has no records"):
        score_tracks(empty, output, c=10.0)


def test_tgospa_columns(crossing: tuple[TruthTable, TrackerOutput]) -> None:
    truth, output = crossing
    scores = score_tracks(truth, output, c=10.0, p=2.0, switch_cost=4.0)
    names = position_names(truth, output.tracks)
    direct = tgospa(
        truth_points(truth, names), track_points(output.tracks, names), c=10.0, gamma=4.0
    )
    assert scores.tgospa == pytest.approx(direct.total, rel=1e-12) and scores.tgospa > 0.0
    assert scores.tgospa_switching == pytest.approx(direct.switching)
    assert scores.tgospa_gamma == 4.0
    assert scores.fragments_per_target == fragmentation_of(direct).fragments_per_target
    assert scores.tgospa_id_switches == fragmentation_of(direct).num_id_switches
    assert score_tracks(truth, output, c=10.0).tgospa_gamma == 10.0  # gamma defaults to c
    perfect = score_tracks(truth, truth_as_tracks(truth), c=10.0)
    assert perfect.tgospa == 0.0 and perfect.tgospa_switching == 0.0
    assert perfect.fragments_per_target == 1.0 and perfect.tgospa_id_switches == 0
    with pytest.raises(InputError, match="^switch_cost "):
        score_tracks(truth, output, c=10.0, switch_cost=-1.0)
    with pytest.raises(InputError, match="^tgospa_method "):
        score_tracks(truth, output, c=10.0, tgospa_method="exact")
