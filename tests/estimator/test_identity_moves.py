"""The identity moves (switch, split, merge over any gap) against J computed from scratch.

* On random tiny recordings from random feasible track sets, every move the functions
  make leaves each track's value equal to a fresh objective's value of its path, J never
  lower, the set feasible.
* Hand-made mistakes are undone: two true tracks whose tails were exchanged at a close
  approach are switched back; a true track broken in two across a gap longer than
  ``link_gap`` is merged where J rises, while fragment linking leaves it broken.
* A split is made exactly where a cut (scored from scratch) raises J, and leaves no
  such cut.
* On recordings small enough to enumerate every track set, refinement with the moves
  reaches the global MAP at least as often as without, and is never below it on a seed
  where the refinement without them is at it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from support import all_track_sets, feasible_track_set, single_detection_tracks, tiny_recording

from mapassoc.estimator import identity_moves as moves
from mapassoc.estimator.linking import link_fragments
from mapassoc.estimator.objective import RecordingObjective, TrackPath
from mapassoc.estimator.refinement import RefinementSettings, Refiner
from mapassoc.evaluation.scenarios import build_scenario


def _random_tracks(scans, rng: np.random.Generator) -> dict[int, TrackPath]:
    """A random feasible track set: each detection starts a track or continues one."""
    tracks: dict[int, list[tuple[int, int]]] = {}
    for m, scan in enumerate(scans):
        free = [tid for tid, path in tracks.items() if path[-1][0] < m]
        for j in range(scan.size):
            if free and rng.random() < 0.7:
                tracks[free.pop(int(rng.integers(len(free))))].append((m, j))
            else:
                tracks[len(tracks) + 1] = [(m, j)]
    return {tid: tuple(path) for tid, path in tracks.items()}


@pytest.mark.parametrize("seed", range(12))
def test_every_move_leaves_values_equal_to_j_from_scratch(seed: int) -> None:
    config, scans = tiny_recording(seed, num_scans=6, most=3)
    objective = RecordingObjective(config=config, scans=scans)
    tracks = _random_tracks(scans, np.random.default_rng(seed))
    values = {tid: objective.track_value(path) for tid, path in tracks.items()}
    before = sum(values.values())
    counts, next_id = moves.identity_moves(
        objective, tracks, values, next_id=max(tracks) + 1, refilter_detections=2
    )
    fresh = RecordingObjective(config=config, scans=scans)
    assert feasible_track_set(tracks)
    assert set(values) == set(tracks) and next_id > max(tracks)
    for tid, path in tracks.items():
        assert values[tid] == pytest.approx(fresh.track_value(path), abs=1e-9)
    after = fresh.value(list(tracks.values()))
    assert after >= before - 1e-9
    if counts.total == 0:
        assert after == pytest.approx(before, abs=1e-9)


def _truth_paths(scenario) -> tuple[RecordingObjective, dict[int, TrackPath]]:
    objective = RecordingObjective(config=scenario.config, scans=scenario.scans)
    rows: dict[int, list[int]] = {}
    origins = scenario.origins
    for row, target in zip(origins.rows.tolist(), origins.target_ids.tolist(), strict=True):
        if target >= 0:
            rows.setdefault(int(target), []).append(int(row))
    paths = {tid: objective.path_of_rows(r) for tid, r in rows.items()}
    return objective, paths


def test_a_switch_undoes_tails_exchanged_at_a_close_approach() -> None:
    scenario = build_scenario("crossing", seed=1)
    objective, truth = _truth_paths(scenario)
    truth = {t: p for t, p in truth.items() if math.isfinite(objective.track_value(p))}
    pairs = moves.close_approaches(objective, truth)
    assert pairs, "the crossing pairs come close"
    a, b, i, j = pairs[len(pairs) // 2]
    swapped = dict(truth)
    swapped[a] = truth[a][: i + 1] + truth[b][j + 1 :]
    swapped[b] = truth[b][: j + 1] + truth[a][i + 1 :]
    values = {tid: objective.track_value(path) for tid, path in swapped.items()}
    true_pair = objective.track_value(truth[a]) + objective.track_value(truth[b])
    assert values[a] + values[b] < true_pair  # a real mistake
    made = moves.switch_tracks(objective, swapped, values, refilter_detections=15)
    assert made >= 1
    assert swapped[a] == truth[a] and swapped[b] == truth[b]


def _rising_cuts(objective: RecordingObjective, path: TrackPath, value: float) -> list[int]:
    """Cuts before a detection whose term is negative that raise J, from scratch."""
    run = objective.trajectory(path)
    cuts = []
    for k in range(1, len(path)):
        if run.values[k] - run.values[k - 1] < 0.0:
            pieces = objective.track_value(path[:k]) + objective.track_value(path[k:])
            if pieces > value + 1e-6:
                cuts.append(k)
    return cuts


def test_a_split_cuts_where_j_rises_and_leaves_no_rising_cut() -> None:
    """From random track sets of random recordings: where a cut before a negative-term
    detection raises J (scored here from scratch, the head as a track of its own), the
    split makes one, and afterwards no track has such a cut left."""
    cut_somewhere = 0
    for seed in range(30):
        config, scans = tiny_recording(200 + seed, num_scans=6, most=3)
        objective = RecordingObjective(config=config, scans=scans)
        tracks = _random_tracks(scans, np.random.default_rng(seed))
        values = {tid: objective.track_value(path) for tid, path in tracks.items()}
        expected = any(_rising_cuts(objective, tracks[t], values[t]) for t in tracks)
        before = sum(values.values())
        made, _ = moves.split_tracks(objective, tracks, values, next_id=1000)
        assert (made > 0) == expected
        assert sum(values.values()) >= before - 1e-9
        for tid, path in tracks.items():
            assert values[tid] == pytest.approx(objective.track_value(path), abs=1e-9)
            assert not _rising_cuts(objective, path, values[tid])
        cut_somewhere += made > 0
    assert cut_somewhere >= 3


def test_merge_joins_across_a_gap_longer_than_the_link_gap_where_j_rises() -> None:
    scenario = build_scenario("crossing", seed=1)
    objective, truth = _truth_paths(scenario)
    tid = max(truth, key=lambda t: len(truth[t]))
    path = truth[tid]
    gap = 3
    k = len(path) // 3
    head, tail = path[:k], path[k + gap :]
    link_gap = tail[0][0] - head[-1][0] - 1  # one scan short of the join
    joined = objective.track_value(head + tail)
    apart = objective.track_value(head) + objective.track_value(tail)
    assert joined > apart  # the precondition: the join pays under the model
    tracks = {1: head, 2: tail}
    values = {1: objective.track_value(head), 2: objective.track_value(tail)}
    linked = link_fragments(
        objective, dict(tracks), dict(values), link_gap=link_gap, refilter_detections=15
    )
    assert linked == 0
    made = moves.merge_tracks(objective, tracks, values, refilter_detections=15)
    assert made == 1 and list(tracks.values()) == [head + tail]
    assert sum(values.values()) == pytest.approx(joined, abs=1e-9)


def _map_and_refined(seed: int, identity: bool) -> tuple[float, float]:
    config, scans = tiny_recording(100 + seed, num_scans=5, most=2)
    objective = RecordingObjective(config=config, scans=scans)
    best = max(objective.value(tracks) for tracks in all_track_sets(scans))
    singles = single_detection_tracks(scans)
    settings = RefinementSettings(
        passes=4, window_length=2, long_window_length=2, link_gap=1, identity_moves=identity
    )
    refiner = Refiner(config=config, scans=scans, settings=settings, objective=objective)
    refined, report = refiner.refine(singles)
    assert feasible_track_set(refined)
    assert report.objective == pytest.approx(objective.value(list(refined.values())), abs=1e-9)
    return best, report.objective


def test_the_moves_reach_the_global_map_at_least_as_often_on_enumerable_recordings() -> None:
    without = with_moves = 0
    for seed in range(20):
        best, plain = _map_and_refined(seed, identity=False)
        _, moved = _map_and_refined(seed, identity=True)
        assert moved <= best + 1e-9 and plain <= best + 1e-9
        without += math.isclose(plain, best, abs_tol=1e-9)
        with_moves += math.isclose(moved, best, abs_tol=1e-9)
    assert with_moves >= without


def test_the_report_says_why_the_sweeps_stopped() -> None:
    config, scans = tiny_recording(3, num_scans=5, most=2)
    singles = single_detection_tracks(scans)
    settings = RefinementSettings(passes=1, window_length=2, identity_moves=True)
    _, one = Refiner(config=config, scans=scans, settings=settings).refine(singles)
    many = dataclasses.replace(settings, passes=50)
    _, converged = Refiner(config=config, scans=scans, settings=many).refine(singles)
    assert converged.stopped == "converged" and len(converged.objective_after_pass) < 50
    assert one.stopped in ("pass_limit", "converged")
    assert one.to_json()["stopped"] == one.stopped
    assert converged.objective >= one.objective - 1e-9


@pytest.mark.parametrize("seed", range(6))
def test_close_approaches_are_every_close_pair_of_detections_at_a_common_scan(seed: int) -> None:
    """The scan-by-scan search against a loop over every pair of tracks and scans."""
    config, scans = tiny_recording(300 + seed, num_scans=6, most=3)
    objective = RecordingObjective(config=config, scans=scans)
    tracks = _random_tracks(scans, np.random.default_rng(seed))
    expected = set()
    for a in tracks:
        for b in tracks:
            if a >= b:
                continue
            for i, (m, c) in enumerate(tracks[a][:-1]):
                for j, (n, d) in enumerate(tracks[b][:-1]):
                    if m != n:
                        continue
                    measurement = config.sensors[scans[m].sensor].measurement
                    diff = scans[m].detections[c] - scans[m].detections[d]
                    R2 = 2.0 * measurement.noise_covariance
                    if diff @ np.linalg.solve(R2, diff) <= moves.SWITCH_DETECTION_DISTANCE:
                        expected.add((a, b, i, j))
    assert set(moves.close_approaches(objective, tracks)) == expected


def _rising_extensions(objective: RecordingObjective, tracks: dict[int, TrackPath], gap: int):
    """(track, detection) of every free detection within ``gap`` scans of a track's end
    or start whose addition raises J, each scored from scratch (the whole filter run)."""
    used = {d for path in tracks.values() for d in path}
    found = []
    for tid, path in tracks.items():
        value = objective.track_value(path)
        first, last = path[0][0], path[-1][0]
        for m, scan in enumerate(objective.scans):
            if not (last < m <= last + gap or first - gap <= m < first):
                continue
            for j in range(scan.size):
                if (m, j) in used:
                    continue
                longer = (*path, (m, j)) if m > last else ((m, j), *path)
                if objective.track_value(longer) > value + 1e-6:
                    found.append((tid, (m, j)))
    return found


@pytest.mark.parametrize("seed", range(10))
def test_extend_takes_every_free_detection_that_pays_near_an_end_or_a_start(seed: int) -> None:
    config, scans = tiny_recording(400 + seed, num_scans=6, most=3)
    objective = RecordingObjective(config=config, scans=scans)
    rng = np.random.default_rng(seed)
    tracks = _random_tracks(scans, rng)
    # Free some detections: drop each track's first or last detection half of the time.
    for tid, path in list(tracks.items()):
        if len(path) > 1 and rng.random() < 0.5:
            tracks[tid] = path[1:] if rng.random() < 0.5 else path[:-1]
    values = {tid: objective.track_value(path) for tid, path in tracks.items()}
    before = sum(values.values())
    expected = bool(_rising_extensions(objective, tracks, moves.EXTEND_SCANS))
    made = moves.extend_tracks(objective, tracks, values, gap=moves.EXTEND_SCANS)
    assert (made > 0) == expected
    assert feasible_track_set(tracks) and sum(values.values()) >= before - 1e-9
    for tid, path in tracks.items():
        assert values[tid] == pytest.approx(objective.track_value(path), abs=1e-9)
    assert not _rising_extensions(objective, tracks, moves.EXTEND_SCANS)


def test_extend_takes_back_a_true_tracks_missed_first_and_last_detections() -> None:
    scenario = build_scenario("crossing", seed=1)
    objective, truth = _truth_paths(scenario)
    tid = max(truth, key=lambda t: objective.track_value(truth[t]))
    path = truth[tid]
    cut = path[1:-1]
    assert objective.track_value(path) > objective.track_value(cut)  # the ends pay
    tracks, values = {tid: cut}, {tid: objective.track_value(cut)}
    made = moves.extend_tracks(objective, tracks, values, gap=moves.EXTEND_SCANS)
    assert made >= 2 and values[tid] >= objective.track_value(path) - 1e-9
    assert set(path) <= set(tracks[tid])
