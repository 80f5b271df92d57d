"""The whole recording's objective J and its refinement, against independent references.

* J of every track set of tiny recordings equals a value written here from the
  generative model without the library's filter: each track's detections scored by
  their joint Gaussian law (the state-space model stacked over the track's scans, not
  the Kalman recursion), the birth, miss, survival and best-ending terms enumerated;
* J of a recording no longer than a window equals the window's best objective, by
  construction: along every kept hypothesis the trees' states are J's filter states bit
  for bit (numpy backend; to rounding with the compiled kernels) and the scores its values;
* refinement: never lowers J, returns feasible track sets, finds the global MAP when its
  window covers the recording, and leaves no single-window move that improves J.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from support import (
    NO_TIME_LIMIT,
    TINY_NOISE_INTENSITY,
    all_track_sets,
    brute_force_tables,
    feasible_track_set,
    fresh_hypothesis_paths,
    random_problem,
    single_detection_tracks,
    tiny_recording,
)

from mapassoc.errors import InputError
from mapassoc.estimator import refinement
from mapassoc.estimator.cluster_solving import ClusterStatus, uncounted
from mapassoc.estimator.objective import PathState, RecordingObjective, paths_from_rows
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.refinement import RefinementSettings, Refiner, refine_track_rows
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.filtering.compiled import COMPILED_SWITCH


def _joint_log_likelihood(config, scans, track) -> float:
    """log p(z_2..z_L | z_1) of a track's detections, stacked (no Kalman recursion).

    The state at the first detection is Gaussian: position = z_1 with covariance R
    (single-point initiation under a uniform position prior), velocity from the birth
    prior; later states follow x_k = F x_{k-1} + w_k with the constant-velocity F and
    Q of continuous white acceleration noise of intensity q, written out here.
    """
    sensor = config.sensors["s"]
    R = np.asarray(sensor.measurement.noise_covariance)
    d = R.shape[0]
    q = TINY_NOISE_INTENSITY
    first_scan, first_index = track[0]
    m0 = np.r_[scans[first_scan].detections[first_index], np.zeros(d)]
    P0 = np.zeros((2 * d, 2 * d))
    P0[:d, :d] = R
    P0[d:, d:] = config.birth.velocity_std**2 * np.eye(d)
    steps = range(first_scan, track[-1][0] + 1)
    means = {first_scan: m0}
    covs = {(first_scan, first_scan): P0}
    for k in steps:
        if k == first_scan:
            continue
        dt = scans[k].time - scans[k - 1].time
        F = np.block([[np.eye(d), dt * np.eye(d)], [np.zeros((d, d)), np.eye(d)]])
        eye = np.eye(d)
        Q = q * np.block([[dt**3 / 3 * eye, dt**2 / 2 * eye], [dt**2 / 2 * eye, dt * eye]])
        means[k] = F @ means[k - 1]
        for j in range(first_scan, k):
            covs[(k, j)] = F @ covs[(k - 1, j)]
            covs[(j, k)] = covs[(k, j)].T
        covs[(k, k)] = F @ covs[(k - 1, k - 1)] @ F.T + Q
    later = track[1:]
    if not later:
        return 0.0
    H = np.c_[np.eye(d), np.zeros((d, d))]
    mean = np.concatenate([H @ means[k] for k, _ in later])
    cov = np.block([[H @ covs[(k, j)] @ H.T for j, _ in later] for k, _ in later])
    cov += np.kron(np.eye(len(later)), R)
    z = np.concatenate([scans[k].detections[i] for k, i in later])
    sign, logdet = np.linalg.slogdet(2 * math.pi * cov)
    assert sign > 0
    r = z - mean
    return float(-0.5 * (logdet + r @ np.linalg.solve(cov, r)))


def _reference_value(config, scans, track) -> float:
    """A track's value from the generative model (module docstring), independently."""
    sensor = config.sensors["s"]
    birth = config.birth
    pd, ps = sensor.detection_probability, birth.survival_probability
    lam_bar = sensor.false_alarms_per_scan
    lam = lam_bar / sensor.region.volume
    times = [s.time for s in scans]
    # Expected number of targets alive and never detected, just before each scan.
    u = []
    remaining, previous = birth.initial_count, times[0]
    for t in times:
        u.append(remaining * ps ** (t - previous) + birth.rate)
        remaining, previous = u[-1] * (1 - pd), t
    first, last = track[0][0], track[-1][0]
    detected = {k for k, _ in track}
    value = math.log(u[first] * pd / lam_bar)
    for k in range(first + 1, last + 1):
        value += (times[k] - times[k - 1]) * math.log(ps)
        value += math.log(pd / lam) if k in detected else math.log(1 - pd)
    value += _joint_log_likelihood(config, scans, track)
    return value + max(_endings(config, scans, last))


def _endings(config, scans, last: int) -> list[float]:
    """Log-probability of each ending after a last detection at scan ``last``: dying in
    the gap after scan g >= last (missed at the scans between), or alive to the end."""
    pd = config.sensors["s"].detection_probability
    ps = config.birth.survival_probability
    times = [s.time for s in scans]
    endings = []
    running = 0.0
    for g in range(last, len(scans)):
        if g == len(scans) - 1:
            endings.append(running)
        else:
            endings.append(running + math.log(1 - ps ** (times[g + 1] - times[g])))
            running += (times[g + 1] - times[g]) * math.log(ps) + math.log(1 - pd)
    return endings


@pytest.mark.parametrize("seed", range(12))
def test_objective_equals_the_generative_model_on_every_track_set(seed: int) -> None:
    config, scans = tiny_recording(seed)
    objective = RecordingObjective(config=config, scans=scans)
    count = 0
    for tracks in all_track_sets(scans):
        expected = sum(_reference_value(config, scans, t) for t in tracks)
        assert objective.value(tracks) == pytest.approx(expected, abs=1e-9, rel=1e-12)
        count += 1
    assert count >= 1


def _forward_config(config):
    """``config`` for the forward pass alone (no refinement) and no clock limit."""
    return dataclasses.replace(
        config,
        estimator=dataclasses.replace(config.estimator, refine_passes=0, time_limit=NO_TIME_LIMIT),
    )


@pytest.mark.parametrize("name", ["crossing", "dense", "turning", "two_sensors"])
def test_objective_of_one_window_equals_its_best_objective(name: str) -> None:
    scenario = build_scenario(name, seed=1)
    config = _forward_config(scenario.config)
    scans = scenario.scans[: config.estimator.window_length]
    estimator = WindowEstimator(config=config)
    solution = estimator.solve_window(scans)
    _, tracks = estimator.k_estimator.choose(solution.posterior)
    result = estimator.run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    value = objective.value(paths_from_rows(objective, result.track_rows))
    assert value == pytest.approx(float(solution.table.best[tracks]), abs=1e-9)


@pytest.mark.parametrize("switch", ["0", "1"])
@pytest.mark.parametrize("name", ["crossing", "dense", "turning", "two_sensors"])
def test_the_trees_and_j_take_the_same_filter_steps(
    name: str, switch: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """J equals a window's objective by construction: along every kept hypothesis of a
    window that starts the recording, the tree's state after each of its detections is
    the state J's filter run reaches (the same predict, innovation, gate and update of
    mapassoc.filtering.batch), bit for bit on the numpy backend and to rounding on the
    compiled one, and the tree's score is the run's value (the same terms, summed in
    another order where a track is missed)."""
    if switch == "1":
        pytest.importorskip("numba")
    monkeypatch.setenv(COMPILED_SWITCH, switch)
    scenario = build_scenario(name, seed=1)
    config = _forward_config(scenario.config)
    scans = scenario.scans[: config.estimator.window_length]
    hypotheses = WindowEstimator(config=config).generator.generate(scans)
    objective = RecordingObjective(config=config, scans=scans)
    nodes = hypotheses.nodes
    checked = 0
    for along, path in fresh_hypothesis_paths(hypotheses):
        run = objective.trajectory(path)
        for k, v in enumerate(along):
            mean, covariance = nodes.state(v)
            if switch == "0":
                np.testing.assert_array_equal(mean, run.means[k])
                np.testing.assert_array_equal(covariance, run.covariances[k])
            else:
                np.testing.assert_allclose(mean, run.means[k], rtol=1e-9, atol=1e-9)
                np.testing.assert_allclose(covariance, run.covariances[k], rtol=1e-9, atol=1e-9)
            assert nodes.score[v] == pytest.approx(run.values[k], rel=1e-12, abs=1e-10)
        checked += 1
    assert checked >= 10


@pytest.mark.parametrize("seed", range(10))
def test_refinement_over_the_whole_recording_finds_the_global_map(seed: int) -> None:
    config, scans = tiny_recording(seed, num_scans=4, most=2)
    objective = RecordingObjective(config=config, scans=scans)
    best = max(objective.value(tracks) for tracks in all_track_sets(scans))
    # Start from a poor set: every detection its own track.
    singles = single_detection_tracks(scans)
    refiner = Refiner(
        config=config,
        scans=scans,
        settings=RefinementSettings(
            passes=2, window_length=len(scans), prune_log_ratio=math.inf
        ),  # nothing pruned: the window's program holds every track set
        objective=objective,
    )
    refined, report = refiner.refine(singles)
    assert feasible_track_set(refined)
    assert objective.value(refined) == pytest.approx(best, abs=1e-9)
    assert report.objective == pytest.approx(best, abs=1e-9)


@pytest.mark.parametrize("seed", range(16))
def test_a_resolve_programs_best_set_equals_enumeration(seed: int) -> None:
    """The window solver's best set with K free, as the refinement asks it (lone
    hypotheses in closed form, small clusters by the frontier search, large ones by the
    integer program) against every subset, sizes uncounted."""
    config, scans = tiny_recording(0)
    refiner = Refiner(config=config, scans=scans, settings=RefinementSettings())
    rng = np.random.default_rng(seed)
    H = int(rng.integers(1, 15))
    groups = min(H, int(rng.integers(0, 3)))  # every exactly-once resource has a member
    problem = random_problem(rng, H, int(rng.integers(H, 3 * H + 1)), groups)
    solved = refiner.window_solver.best_set(problem, math.inf)
    selection = solved.selection
    best, _ = brute_force_tables(uncounted(problem), 0)
    assert solved.status is ClusterStatus.EXACT
    if not math.isfinite(best[0]):
        assert selection is None
        return
    assert selection is not None and problem.is_feasible(selection)
    assert problem.value(selection) == pytest.approx(best[0], abs=1e-9)


@pytest.mark.parametrize("seed", range(12))
def test_a_windows_marginals_equal_enumeration(seed: int) -> None:
    """The window solver's marginals with K free, as the confidence pass asks them (lone
    hypotheses in closed form, the other clusters by the frontier search forward and
    backward) against a sum over every feasible set."""
    config, scans = tiny_recording(0)
    refiner = Refiner(config=config, scans=scans, settings=RefinementSettings())
    rng = np.random.default_rng(50 + seed)
    H = int(rng.integers(1, 11))
    groups = min(H, int(rng.integers(0, 3)))  # every exactly-once resource has a member
    problem = random_problem(rng, H, int(rng.integers(H, 3 * H + 1)), groups)
    found = refiner.window_solver.marginals(problem, work_limit=50_000, beam_width=32)
    probabilities, exact, clusters = found.probabilities, found.exact, found.clusters
    masses = []
    for r in range(H + 1):
        for chosen in itertools.combinations(range(H), r):
            selection = np.array(chosen, dtype=np.int64)
            if problem.is_feasible(selection):
                masses.append((set(chosen), float(np.sum(problem.weights[selection]))))
    total = np.logaddexp.reduce([m for _, m in masses])
    expected = [
        math.exp(np.logaddexp.reduce([m for c, m in masses if h in c] or [-math.inf]) - total)
        for h in range(H)
    ]
    assert exact
    assert probabilities == pytest.approx(expected, abs=1e-9)
    assert sum(t for _, t in clusters) == pytest.approx(total, abs=1e-9)


def test_single_scan_windows_go_where_the_cap_cut_a_longer_windows_trees() -> None:
    scenario = build_scenario("converging", seed=0)
    scans = scenario.scans[25:40]  # the six targets close together
    config = _forward_config(scenario.config)
    config = dataclasses.replace(
        config, estimator=dataclasses.replace(config.estimator, max_hypotheses_per_tree=8)
    )
    solved: list[tuple[int, int]] = []

    class Recording(Refiner):
        def resolve_window(self, tracks, values, a, b):  # type: ignore[no-untyped-def]
            solved.append((a, b))
            return super().resolve_window(tracks, values, a, b)

    forward = WindowEstimator(config=config).run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    paths = paths_from_rows(objective, forward.track_rows)
    refiner = Recording(config=config, scans=scans, settings=RefinementSettings(passes=3))
    refined, report = refiner.refine(paths)
    N = config.estimator.window_length
    assert {b - a for a, b in solved} == {N, 2 * N, 1}
    singles = {a for a, b in solved if b - a == 1}
    assert singles and singles <= refiner._capped_scans
    assert report.objective >= report.objective_forward - 1e-9
    solved.clear()
    Recording(
        config=config, scans=scans, settings=RefinementSettings(passes=3, scan_windows=False)
    ).refine(paths)
    assert {b - a for a, b in solved} == {N, 2 * N}
    # A recording of one scan: its one window is the short window, solved as always
    # (not held back as a single-scan window the cap never cut).
    solved.clear()
    Recording(config=config, scans=scans[:1], settings=RefinementSettings(passes=3)).refine(
        paths_from_rows(RecordingObjective(config=config, scans=scans[:1]), {})
    )
    assert solved == [(0, 1)]
    with pytest.raises(InputError) as error:
        RefinementSettings(scan_windows=1)  # type: ignore[arg-type]
    assert error.value.key == "scan_windows"


@pytest.mark.parametrize("seed", range(8))
def test_refinement_never_lowers_the_objective(seed: int) -> None:
    """Random short stretches of the built-in scenarios, forward pass then refinement."""
    rng = np.random.default_rng(100 + seed)
    name = ["crossing", "dense", "parallel", "dense_pd08"][seed % 4]
    scenario = build_scenario(name, seed=int(rng.integers(0, 5)))
    start = int(rng.integers(0, len(scenario.scans) - 16))
    scans = scenario.scans[start : start + 16]
    config = _forward_config(scenario.config)
    forward = WindowEstimator(config=config).run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    before = objective.value(paths_from_rows(objective, forward.track_rows))
    refined = refine_track_rows(
        config, scans, forward.track_rows, settings=RefinementSettings(passes=3), confidence=False
    )
    rows, report = refined.track_rows, refined.report
    after = objective.value(paths_from_rows(objective, rows))
    assert report.objective_forward == pytest.approx(before, abs=1e-9)
    assert after == pytest.approx(report.objective, abs=1e-9)
    assert after >= before - 1e-9
    history = [report.objective_forward, *report.objective_after_pass]
    assert all(b >= a - 1e-9 for a, b in zip(history, history[1:], strict=False))
    assert feasible_track_set(paths_from_rows(objective, rows))


def test_long_windows_are_pruned_at_their_own_width(monkeypatch: pytest.MonkeyPatch) -> None:
    scenario = build_scenario("crossing", seed=0)
    scans = scenario.scans[:24]
    config = _forward_config(scenario.config)
    own = Refiner(
        config=config,
        scans=scans,
        settings=RefinementSettings(prune_log_ratio=18.0, long_prune_log_ratio=3.0),
    )
    assert own.generator.prune_log_ratio == 18.0
    assert own.long_generator.prune_log_ratio == 3.0
    same = Refiner(config=config, scans=scans, settings=RefinementSettings(prune_log_ratio=7.0))
    assert same.long_generator.prune_log_ratio == 7.0
    with pytest.raises(InputError) as error:
        RefinementSettings(long_prune_log_ratio=-1.0)
    assert error.value.key == "long_prune_log_ratio"

    # The estimator's refinement: its own width for the short windows, the forward pass's
    # for the long ones.
    built: list[Refiner] = []

    class Recording(Refiner):
        def __init__(self, **kwargs: object) -> None:
            super().__init__(**kwargs)  # type: ignore[arg-type]
            built.append(self)

    monkeypatch.setattr(refinement, "Refiner", Recording)
    forward = WindowEstimator(config=config).run(scans)
    refine_track_rows(config, scans, forward.track_rows, confidence=False)
    est = config.estimator
    assert [r.generator.prune_log_ratio for r in built] == [est.refine_prune_log_ratio]
    assert [r.long_generator.prune_log_ratio for r in built] == [est.prune_log_ratio]
    assert est.prune_log_ratio < est.refine_prune_log_ratio


@pytest.mark.slow
def test_no_single_window_move_improves_a_converged_refinement() -> None:
    scenario = build_scenario("parallel", seed=0)
    scans = scenario.scans[:30]
    config = _forward_config(scenario.config)
    forward = WindowEstimator(config=config).run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    refiner = Refiner(
        config=config, scans=scans, settings=RefinementSettings(passes=20), objective=objective
    )
    refined, report = refiner.refine(paths_from_rows(objective, forward.track_rows))
    assert report.objective > report.objective_forward  # parallel lanes: it must improve
    values = {tid: objective.track_value(path) for tid, path in refined.items()}
    N = refiner.window_length
    for a in refiner.window_starts():
        improved, _ = refiner.resolve_window(refined, values, a, a + N)
        assert not improved, f"window {a}..{a + N - 1} still improves J"


def test_converging_continuation_agrees_with_the_whole_filter_run() -> None:
    scenario = build_scenario("crossing", seed=2)
    config, scans = scenario.config, scenario.scans
    result = WindowEstimator(config=_forward_config(config)).run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    paths = list(paths_from_rows(objective, result.track_rows).values())
    checked = 0
    for path in paths:
        for cut in range(1, len(path), 7):
            head, tail = path[:cut], path[cut:]
            # The tail started anew, then continued towards the whole track's run.
            reference = objective.trajectory(path)
            alone = objective.continue_converging(objective.start_path(tail), reference, cut + 1)
            assert float(alone[0]) == pytest.approx(objective.track_value(tail), abs=1e-6)
            # The head's state continued through the tail: the whole track again.
            state = objective.trajectory(head).state(len(head) - 1)
            whole = objective.continue_converging(state, reference, cut)
            assert float(whole[0]) == pytest.approx(objective.track_value(path), abs=1e-6)
            checked += 1
    assert checked > 10


@pytest.mark.parametrize("kalman_path", ["compiled", "numpy"])
@pytest.mark.parametrize("family", ["crossing", "dense", "two_sensors"])
def test_batched_continuation_equals_one_request_at_a_time(
    family: str, kalman_path: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """continue_converging_many gives what continue_converging gives per request, with
    and without a cap, for requests that start at different scans, continue different
    references (two sensors: different measurement models in one batch) and leave at
    different steps; on the numpy path and on the compiled kernels (numba), which also
    agree with each other."""
    if kalman_path == "compiled":
        pytest.importorskip("numba")
    monkeypatch.setenv(COMPILED_SWITCH, "1" if kalman_path == "compiled" else "0")
    scenario = build_scenario(family, seed=1)
    config, scans = scenario.config, scenario.scans[:25]
    result = WindowEstimator(config=_forward_config(config)).run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    paths = [p for p in paths_from_rows(objective, result.track_rows).values() if len(p) > 3]
    assert len(paths) >= 2
    requests = []
    for i, path in enumerate(paths):
        reference = objective.trajectory(path)
        other = objective.trajectory(paths[i - 1])
        for cut in (1, 2, len(path) // 2):
            # This track's own state and a fresh start at the same detection (one request
            # of two tracks), and another track's last state before it (mostly gated out).
            own, fresh = reference.state(cut - 1), objective.start_path(path[cut - 1 : cut])
            pair = PathState(
                scan=own.scan,
                means=np.concatenate([own.means, fresh.means]),
                covariances=np.concatenate([own.covariances, fresh.covariances]),
                initiated=True,
                first_time=np.concatenate([own.first_time, fresh.first_time]),
                value=np.concatenate([own.value, fresh.value]),
            )
            requests.append((pair, reference, cut))
            before = [k for k in range(len(other.path)) if other.path[k][0] < path[cut][0]]
            if before:
                requests.append((other.state(before[-1]), reference, cut))
    # continue_each: every detection of the next two scans tried after each request's
    # start, against continue_paths one detection at a time.
    tried = 0
    for start, _, _ in requests:
        targets = [
            (m, j)
            for m in (start.scan + 1, start.scan + 2)
            if m < len(scans)
            for j in range(scans[m].size)
        ]
        for (m, j), (rows, state) in zip(
            targets, objective.continue_each(start, targets), strict=True
        ):
            one = objective.continue_paths(start, ((m, j),))
            expected = np.flatnonzero(np.isfinite(one.value))
            np.testing.assert_array_equal(rows, expected)
            np.testing.assert_allclose(state.value, one.value[expected], rtol=1e-12, atol=1e-9)
            np.testing.assert_allclose(state.means, one.means[expected], rtol=1e-9, atol=1e-9)
            tried += int(rows.size > 0)
    assert tried > 0
    for cap in (None, 3):
        many = objective.continue_converging_many(requests, max_detections=cap)
        for (start, reference, first), got in zip(requests, many, strict=True):
            one = objective.continue_converging(start, reference, first, max_detections=cap)
            np.testing.assert_allclose(got, one, rtol=1e-9, atol=1e-9)
        if kalman_path == "compiled":
            monkeypatch.setenv(COMPILED_SWITCH, "0")
            plain = objective.continue_converging_many(requests, max_detections=cap)
            monkeypatch.setenv(COMPILED_SWITCH, "1")
            for got, expected in zip(many, plain, strict=True):
                np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9)
    assert any(np.isneginf(v).any() for v in many)  # some requests leave at the gate
    assert any(np.isfinite(v).any() for v in many)


def _reference_mass(config, scans, track) -> float:
    """A track's log-weight in sums over track sets: its endings summed, not maximised."""
    endings = _endings(config, scans, track[-1][0])
    best = _reference_value(config, scans, track)
    return best - max(endings) + float(np.logaddexp.reduce(endings))


@pytest.mark.parametrize("seed", range(8))
def test_existence_and_associations_equal_enumeration_over_every_track_set(seed: int) -> None:
    """With the confidence window covering the recording and nothing pruned, a track's
    existence (some track uses one of its detections) and its associations (the
    detection's track starts at one of its detections) are sums over every track set."""
    config, scans = tiny_recording(seed, num_scans=3, most=2)
    objective = RecordingObjective(config=config, scans=scans)
    sets = list(all_track_sets(scans))
    weights = np.array([sum(_reference_mass(config, scans, t) for t in s) for s in sets])
    probabilities = np.exp(weights - np.logaddexp.reduce(weights))
    # Any track set names the trees to ask about: the best one with a track.
    best = max((s for s in sets if s), key=objective.value)
    tracks = {i + 1: path for i, path in enumerate(best)}
    refiner = Refiner(
        config=config,
        scans=scans,
        settings=RefinementSettings(window_length=len(scans), prune_log_ratio=math.inf),
        objective=objective,
    )
    sure = refiner.confidence(tracks)
    assert sure.exact
    for tid, path in tracks.items():
        # Existence: some track uses one of the track's detections.
        used = [
            p
            for s, p in zip(sets, probabilities, strict=True)
            if any(q in path for t in s for q in t)
        ]
        assert sure.existence[tid] == pytest.approx(sum(used), abs=1e-9)
        # Association: the detection's track starts at one of the track's detections.
        for m, j in path:
            row = int(scans[m].rows[j])
            with_it = sum(
                p
                for s, p in zip(sets, probabilities, strict=True)
                if any(t[0] in path and (m, j) in t for t in s)
            )
            assert sure.associations[tid][row] == pytest.approx(with_it, abs=1e-9)
