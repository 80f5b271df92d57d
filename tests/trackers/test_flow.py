"""The min-cost network-flow tracker: hand-worked tracks, brute force over track sets under
its own pairwise costs, the chosen number of tracks, stitching across windows, and an
end-to-end run on the crossing scenario."""

from __future__ import annotations

import collections
import math

import numpy as np
import pytest
from support import make_config, make_scans

from mapassoc.errors import InputError
from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario
from mapassoc.evaluation.scoring import score_tracks
from mapassoc.filtering import track_filter as tf
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.population import recording_start, window_population
from mapassoc.trackers.flow import FlowTracker, FlowWindowReport
from mapassoc.trackers.oracle import OracleTracker


def _config(**changes):
    settings = {
        "motion": ConstantVelocity(ndim=2, noise_intensity=0.01),
        "noise_std": 0.5,
        "detection_probability": 0.9,
        "false_alarms_per_scan": 2.0,
        "region": [[-50.0, 50.0], [-50.0, 50.0]],
        "initial_count": 2.0,
        "rate": 0.01,
        "velocity_std": 2.0,
        "survival_probability": 0.99,
        "max_tracks": 5,
        "window_length": 3,
        "stride": 1,
        "gate_probability": 0.999,
    }
    settings.update(changes)
    return make_config(**settings)


# ------------------------------------------------------------------ hand-worked case


def two_tracks_with_clutter(n_scans: int = 8):
    """Target A from (-20, 10) at +1 in x per scan (missed at scan 4), target B from
    (20, -10) at (-1, +0.5); two false alarms per scan at least 15 from either.

    Returns the scans and the true (scan -> detection index) of A and B."""
    rng = np.random.default_rng(0)
    dets, truth_a, truth_b = [], {}, {}
    for k in range(n_scans):
        a = np.array([-20.0 + k, 10.0]) + rng.normal(0.0, 0.5, 2)
        b = np.array([20.0 - k, -10.0 + 0.5 * k]) + rng.normal(0.0, 0.5, 2)
        clutter = []
        while len(clutter) < 2:
            z = rng.uniform(-50.0, 50.0, 2)
            if min(np.linalg.norm(z - a), np.linalg.norm(z - b)) > 15.0:
                clutter.append(z)
        points = [c.tolist() for c in clutter] + ([] if k == 4 else [a.tolist()]) + [b.tolist()]
        order = rng.permutation(len(points))
        dets.append([points[i] for i in order])
        where = {int(i): pos for pos, i in enumerate(order)}
        if k != 4:
            truth_a[k] = where[2]
        truth_b[k] = where[len(points) - 1]
    return make_scans([float(k) for k in range(n_scans)], dets, 2), truth_a, truth_b


def test_two_separated_tracks_among_clutter_are_found_with_their_detections() -> None:
    scans, truth_a, truth_b = two_tracks_with_clutter()
    out = FlowTracker(config=_config()).track(scans)
    # Exactly the two targets, each with all its detections (A across its missed scan 4,
    # a link over one skipped scan), and one id per target over six windows.
    assert sorted(out.associations.values(), key=lambda a: sorted(a.items())) == sorted(
        [truth_a, truth_b], key=lambda a: sorted(a.items())
    )
    assert set(out.associations) == {1, 2}
    reports = out.details
    assert all(isinstance(r, FlowWindowReport) for r in reports)
    assert [(r.first_scan, r.last_scan, r.committed_scans) for r in reports] == [
        (0, 2, 1), (1, 3, 1), (2, 4, 1), (3, 5, 1), (4, 6, 1), (5, 7, 3)
    ]
    # Two tracks in every window; from the second window on both are carried in.
    assert [r.chosen_tracks for r in reports] == [2] * 6
    assert [r.carried_tracks for r in reports] == [0] + [2] * 5
    assert not any(r.at_max_flow for r in reports)
    # The tracks are the shared smoother on those associations: one row per scan of each.
    rows = collections.Counter(out.tracks.track_ids.tolist())
    assert rows == {tid: max(a) - min(a) + 1 for tid, a in out.associations.items()}


def test_stitched_windows_agree_with_one_window_over_the_whole_recording() -> None:
    scans, _, _ = two_tracks_with_clutter()
    sliding = FlowTracker(config=_config()).track(scans)
    whole = FlowTracker(config=_config(), window_length=len(scans), stride=len(scans)).track(
        scans
    )
    assert len(whole.details) == 1
    assert sliding.associations == whole.associations
    # Stride 2 commits two scans per window: the same tracks and ids.
    assert FlowTracker(config=_config(), stride=2).track(scans).associations == (
        sliding.associations
    )


def test_a_carried_track_keeps_its_id_when_it_ends_and_a_new_one_starts() -> None:
    # Target A lives on scans 0-3 only; B appears at scan 3.  A's id (1) is fixed when
    # scan 0 is committed and kept to its end; B gets the next id.
    scans, truth_a, truth_b = two_tracks_with_clutter()
    cut = [scans[k] for k in range(8)]
    dets = []
    for k, scan in enumerate(cut):
        keep = [j for j in range(scan.size)
                if not (k > 3 and truth_a.get(k) == j) and not (k < 3 and truth_b[k] == j)]
        dets.append([scan.detections[j].tolist() for j in keep])
    scans2 = make_scans([float(k) for k in range(8)], dets, 2)
    out = FlowTracker(config=_config()).track(scans2)
    lengths = {tid: (min(a), max(a)) for tid, a in out.associations.items()}
    assert lengths == {1: (0, 3), 2: (3, 7)}


# ------------------------------------------------------------------ brute force


def own_costs(config, scans, max_gap):
    """The tracker's documented edge costs, rebuilt from the library's primitives, for a
    single window holding every scan (no carried track)."""
    sensor = next(iter(config.sensors.values()))
    V = sensor.region.volume
    pd, pg = sensor.detection_probability, config.estimator.gate_probability
    log_ps = math.log(config.birth.survival_probability)
    log_miss = math.log(1.0 - pd * pg)
    times = [s.time for s in scans]
    u = window_population(
        scans, [pd] * len(scans), config.birth, recording_start(config.birth, times[0])
    ).first_detection_means
    n = len(scans)

    def tail(j: int) -> float:
        # Every ending after scan j: missed at scans j+1..m, then ended before scan m+1
        # (m < n - 1), or missed at every later scan.
        best = -math.inf
        score = 0.0
        for m in range(j, n):
            if m < n - 1:
                dt = times[m + 1] - times[m]
                best = max(best, score + math.log(1.0 - math.exp(dt * log_ps)))
                score += dt * log_ps + log_miss
        return max(best, score)

    items = [(k, j) for k, s in enumerate(scans) for j in range(s.size)]
    entry = {it: -(math.log(u[it[0]]) - math.log(V)) for it in items}
    obs = -(math.log(pd) - math.log(sensor.false_alarms_per_scan / V))
    exits = {it: -tail(it[0]) for it in items}
    links = {}
    for k, j in items:
        born = tf.start_track(config, scans[k], j)
        for q in range(k + 1, min(k + 1 + max_gap, n - 1) + 1):
            inn = tf.innovations(config, tf.predict_track(config, born, times[q]), scans[q])
            for b in range(scans[q].size):
                base = (times[q] - times[k]) * log_ps + (q - k - 1) * log_miss
                links[((k, j), (q, b))] = -(base + float(inn.log_likelihood[b]))
    return items, entry, obs, exits, links


def best_track_set(items, entry, obs, exits, links):
    """Smallest-cost set of disjoint tracks (ties: fewer tracks), by enumeration."""
    following = collections.defaultdict(list)
    for (a, b), c in links.items():
        following[a].append((b, c))
    paths = []

    def extend(path, cost):
        paths.append((path, cost + exits[path[-1]]))
        for nxt, c in following[path[-1]]:
            extend(path + (nxt,), cost + c + obs)

    for it in items:
        extend((it,), entry[it] + obs)
    best = {"cost": 0.0, "set": ()}

    def grow(start, used, chosen, cost):
        if cost < best["cost"] - 1e-9 or (
            abs(cost - best["cost"]) <= 1e-9 and len(chosen) < len(best["set"])
        ):
            best["cost"], best["set"] = cost, tuple(chosen)
        for p in range(start, len(paths)):
            path, c = paths[p]
            if used.isdisjoint(path):
                grow(p + 1, used | set(path), chosen + [path], cost + c)

    grow(0, frozenset(), [], 0.0)
    return best["cost"], best["set"]


@pytest.mark.parametrize("solver", ["successive-shortest-paths", "networkx-flow"])
@pytest.mark.parametrize("seed", range(5))
def test_one_window_is_the_best_track_set_under_its_own_costs(seed: int, solver: str) -> None:
    # Dense clutter in a small region (no gate: every pair within max_gap is linked), so
    # that track sets genuinely compete; one target crosses the window.
    rng = np.random.default_rng(seed)
    config = _config(region=[[-6.0, 6.0], [-6.0, 6.0]], false_alarms_per_scan=1.5,
                     gate_probability=1.0, initial_count=1.0, rate=0.1,
                     survival_probability=0.9, noise_std=0.7)
    dets = []
    for k in range(3):
        points = [[-3.0 + 2.0 * k + rng.normal(0, 0.7), 1.0 + rng.normal(0, 0.7)]]
        points += rng.uniform(-6.0, 6.0, (int(rng.integers(1, 3)), 2)).tolist()
        dets.append(points)
    scans = make_scans([0.0, 1.0, 2.0], dets, 2)
    for max_gap in (0, 1):
        out = FlowTracker(
            config=config, max_gap=max_gap, window_length=3, stride=3, solver=solver
        ).track(scans)
        (report,) = out.details
        cost, track_set = best_track_set(*own_costs(config, scans, max_gap))
        assert report.chosen_tracks == len(track_set)
        assert float(np.min(report.track_costs)) == pytest.approx(cost, abs=1e-5)
        got = sorted(tuple(sorted(a.items())) for a in out.associations.values())
        assert got == sorted(tuple(path) for path in track_set)


def test_number_of_tracks_follows_the_clutter_free_targets() -> None:
    # Three targets at rest far apart, no clutter to speak of: three tracks; the same
    # scans with one target removed: two.
    config = _config(false_alarms_per_scan=1e-3)
    spots = [[-30.0, 0.0], [0.0, 30.0], [30.0, -30.0]]
    scans = make_scans([0.0, 1.0, 2.0, 3.0], [spots] * 4, 2)
    out = FlowTracker(config=config).track(scans)
    assert [r.chosen_tracks for r in out.details] == [3, 3]
    assert sorted(out.associations.values(), key=lambda a: a[0]) == [
        {k: j for k in range(4)} for j in range(3)
    ]
    scans = make_scans([0.0, 1.0, 2.0, 3.0], [spots[:2]] * 4, 2)
    assert [r.chosen_tracks for r in FlowTracker(config=config).track(scans).details] == [2, 2]
    # max_tracks caps K: the window reports that the cap bit.
    capped = FlowTracker(config=_config(false_alarms_per_scan=1e-3, max_tracks=2)).track(
        make_scans([0.0, 1.0, 2.0, 3.0], [spots] * 4, 2)
    )
    assert capped.details[0].chosen_tracks == 2 and capped.details[0].at_max_flow


def test_track_costs_are_convex_and_infinite_below_the_carried_tracks() -> None:
    scans, _, _ = two_tracks_with_clutter()
    for report in FlowTracker(config=_config()).track(scans).details:
        costs = report.track_costs
        assert np.all(np.isinf(costs[: report.carried_tracks]))
        finite = costs[np.isfinite(costs)]
        assert np.all(np.diff(finite, n=2) >= -1e-6)
        assert int(np.argmin(costs)) == report.chosen_tracks


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"max_gap": -1}, "max_gap must be an integer >= 0"),
        ({"max_gap": 1.5}, "max_gap must be an integer >= 0"),
        ({"window_length": 0}, "window_length must be an integer >= 1"),
        ({"stride": 4}, r"stride must be an integer in 1..window_length \(3\)"),
        ({"stride": 0}, "stride must be an integer"),
        ({"solver": "highs"}, "solver must be one of successive-shortest-paths, networkx"),
    ],
)
def test_bad_options_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        FlowTracker(config=_config(), **kwargs)


def test_bad_config_is_refused() -> None:
    with pytest.raises(InputError, match="config must be a Config"):
        FlowTracker(config=None)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="false_alarms_per_scan = 0.0"):
        FlowTracker(config=_config(false_alarms_per_scan=0.0))


def test_both_flow_solvers_give_the_same_windows_on_a_cluttered_run() -> None:
    # dense seed 0, 12 scans: many components and carried tracks per window.
    s = truncate_scenario(build_scenario("dense", seed=0), 12)
    fast = FlowTracker(config=s.config).track(s.scans)
    simplex = FlowTracker(config=s.config, solver="networkx-flow").track(s.scans)
    assert fast.associations == simplex.associations
    assert len(fast.associations) >= 5
    for a, b in zip(fast.details, simplex.details, strict=True):
        assert a.chosen_tracks == b.chosen_tracks and a.components == b.components
        assert np.array_equal(np.isfinite(a.track_costs), np.isfinite(b.track_costs))
        finite = np.isfinite(a.track_costs)
        # The simplex works on costs rounded to 1e-6 (sum of capacities / scale bound).
        assert np.allclose(a.track_costs[finite], b.track_costs[finite], rtol=0, atol=1e-3)


# ------------------------------------------------------------------ end to end


def test_crossing_every_target_is_tracked_and_gospa_is_near_the_oracle() -> None:
    # crossing seed 0, all 60 scans (both crossings at t = 30, four births, a death at
    # t = 45).  Measured: GOSPA 0.895 against the oracle's 0.829 (c = 10, p = 2: 1.08x),
    # no missed or false part, four tracks, each target's track holding 28 of 29 to 55 of
    # 55 of its detections (>= 96%).  Bounds asserted: 1.2x the oracle, >= 90%.
    s = build_scenario("crossing", seed=0)
    out = FlowTracker(config=s.config).track(s.scans)
    origin = dict(zip(s.origins.rows.tolist(), s.origins.target_ids.tolist(), strict=True))
    per_target: dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    for tid, assoc in out.associations.items():
        for k, j in assoc.items():
            per_target[origin[int(s.scans[k].rows[j])]][tid] += 1
    detections = collections.Counter(t for t in origin.values() if t >= 0)
    assert len(detections) == 4
    false_alarms_used = sum(per_target[-1].values()) if -1 in per_target else 0
    assert false_alarms_used <= 2
    owners = set()
    for target, count in detections.items():
        (tid, hits), = per_target[target].most_common(1)
        assert hits >= 0.9 * count, (target, per_target[target], count)
        owners.add(tid)
    assert len(owners) == 4 == len(out.associations)
    scores = score_tracks(s.truth, out, c=10.0, clear_mot_scores=False)
    oracle = score_tracks(
        s.truth, OracleTracker(config=s.config, origins=s.origins).track(s.scans), c=10.0,
        clear_mot_scores=False,
    )
    assert scores.gospa <= 1.2 * oracle.gospa
    assert scores.gospa_missed == 0.0 and scores.gospa_false == 0.0


def test_detection_that_cannot_be_missed_is_refused_up_front() -> None:
    """Pd * P_G = 1 leaves a carried track no miss (log(1 - Pd P_G) = -inf): refused with
    the same message as GNN and JPDA, not a solver failure in some later window."""
    config = _config(detection_probability=1.0, gate_probability=1.0)
    with pytest.raises(InputError, match="Pd \\* P_G = 1"):
        FlowTracker(config=config)
