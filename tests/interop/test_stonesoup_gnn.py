"""Stone Soup's GNN baseline: it runs on our scans, and its tracks convert faithfully."""

from __future__ import annotations

import numpy as np
import pytest

from mapassoc.errors import InputError
from mapassoc.evaluation.scenarios import build_scenario, generic_config, truncate_scenario
from mapassoc.filtering.kalman import FilterStep, filter_sequence

pytest.importorskip("stonesoup")

from mapassoc.interop.stonesoup_gnn import StoneSoupGNN, stonesoup_gnn_tracks  # noqa: E402


@pytest.fixture(scope="module")
def crossing():  # type: ignore[no-untyped-def]
    scenario = truncate_scenario(build_scenario("crossing", 0), 25)
    config = generic_config(scenario)
    return scenario, config, stonesoup_gnn_tracks(scenario.scans, config)


def test_tracks_use_real_detections_of_their_own_scans_and_follow_targets(crossing) -> None:  # type: ignore[no-untyped-def]
    scenario, _, tracks = crossing
    rows_at = {scan.time: set(scan.rows.tolist()) for scan in scenario.scans}
    used = tracks.detection_rows >= 0
    assert used.any()
    for time, row in zip(tracks.times[used], tracks.detection_rows[used], strict=True):
        assert int(row) in rows_at[float(time)]
    # Each detection belongs to one track at most (a one-to-one assignment per scan).
    assert len(set(tracks.detection_rows[used].tolist())) == int(np.count_nonzero(used))
    # Every track ends at a detection (trailing predictions are left out), and its
    # detections are mostly one target's (crossing is an easy family for a GNN).
    origin = dict(zip(scenario.origins.rows.tolist(), scenario.origins.target_ids.tolist(),
                      strict=True))  # fmt: skip
    for tid in np.unique(tracks.track_ids):
        mine = tracks.track_ids == tid
        assert tracks.detection_rows[mine][np.argmax(tracks.times[mine])] >= 0
        owners = [origin[int(r)] for r in tracks.detection_rows[mine] if r >= 0]
        if len(owners) >= 5:
            assert max(owners.count(o) for o in set(owners)) >= 0.8 * len(owners)
    targets = len(np.unique(scenario.truth.target_ids))
    assert targets <= len(np.unique(tracks.track_ids)) <= 3 * targets


def test_a_tracks_states_are_our_kalman_filter_on_its_detections(crossing) -> None:  # type: ignore[no-untyped-def]
    """Same constant-velocity Q, same updates: started from Stone Soup's first state, our
    filter over the track's detections and misses gives its states, in our state order."""
    scenario, config, tracks = crossing
    sensor = config.sensors["pos"]
    by_row = {int(r): scan.detections[j] for scan in scenario.scans
              for j, r in enumerate(scan.rows)}  # fmt: skip
    checked = 0
    for tid in np.unique(tracks.track_ids):
        mine = np.flatnonzero(tracks.track_ids == tid)
        mine = mine[np.argsort(tracks.times[mine])]
        if mine.size < 4:
            continue
        first = mine[0]
        steps = [FilterStep(time=float(tracks.times[first]))]
        for i in mine[1:]:
            row = int(tracks.detection_rows[i])
            z = by_row[row] if row >= 0 else None
            steps.append(FilterStep(time=float(tracks.times[i]),
                                    measurement=sensor.measurement if z is not None else None,
                                    z=z))  # fmt: skip
        P0 = np.diag(tracks.variances[first])
        ours = filter_sequence(config.motion, tracks.states[first], P0, steps, smooth=False)
        # The first state's covariance is diagonal in Stone Soup's initiator (positions
        # from R, velocities from the prior), so its diagonal is all of it.
        assert np.allclose(ours.x_filtered, tracks.states[mine], rtol=1e-6, atol=1e-6)
        assert np.allclose(np.diagonal(ours.P_filtered, axis1=1, axis2=2),
                           tracks.variances[mine], rtol=1e-6, atol=1e-6)  # fmt: skip
        checked += 1
    assert checked >= 2


def test_settings_are_checked_and_other_motion_models_refused() -> None:
    with pytest.raises(InputError, match="min_points"):
        StoneSoupGNN(min_points=0)
    with pytest.raises(InputError, match="gate"):
        StoneSoupGNN(gate=-1.0)
    turning = truncate_scenario(build_scenario("turning", 0), 5)
    with pytest.raises(InputError, match="constant_velocity"):
        stonesoup_gnn_tracks(turning.scans, turning.config)
