"""Interacting multiple models (Blom and Bar-Shalom, IEEE TAC 1988) in the estimator:
the hypothesis trees, the recording objective J and the smoother run a model set through
the batched filter interface, and agree with the reference IMM of
:mod:`mapassoc.filtering.imm` (itself checked against the exact sum over model sequences
in ``tests/filtering/test_imm.py``)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from support import NO_TIME_LIMIT, all_track_sets, fresh_hypothesis_paths, tiny_recording

from mapassoc.errors import InputError
from mapassoc.estimator.objective import RecordingObjective, paths_from_rows
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.filtering.compiled import imm_kernels
from mapassoc.filtering.imm import imm_filter
from mapassoc.filtering.kalman import FilterStep, filter_sequence
from mapassoc.models.birth import birth_state
from mapassoc.models.interacting import (
    InteractingModels,
    noise_levels,
    pack_models,
    unpack_models,
)
from mapassoc.models.motion import ConstantVelocity, CoordinatedTurn
from mapassoc.models.switching import SwitchingLaw
from mapassoc.trackers.gnn import GnnTracker
from mapassoc.trackers.jpda import JpdaTracker
from mapassoc.trackers.mht import MhtTracker

SWITCH = 0.2
"""Probability of leaving a model within one unit of time, in the sets here."""


def _with_set(config, factors: tuple[float, ...]):
    """``config`` whose constant-velocity model becomes a set of constant-velocity models
    with noise intensities ``factor * q`` (the first factor 1: the set starts tracks with
    the configuration's own model)."""
    cv = config.motion
    models = [ConstantVelocity(ndim=cv.ndim, noise_intensity=f * cv.noise_intensity)
              for f in factors]  # fmt: skip
    law = SwitchingLaw(len(models), switch_probability=SWITCH if len(models) > 1 else 0.0)
    return dataclasses.replace(config, motion=InteractingModels(models=models, switching=law))


def test_packing_round_trips() -> None:
    rng = np.random.default_rng(0)
    log_mu = np.log(rng.dirichlet(np.ones(3), size=(4,)))
    x = rng.normal(size=(4, 3, 5))
    P = rng.normal(size=(4, 3, 5, 5))
    state, cov = pack_models(log_mu, x, P)
    assert state.shape == (4, 18) and cov.shape == (4, 18, 18)
    back = unpack_models(state, cov, 3)
    for got, want in zip(back, (log_mu, x, P), strict=True):
        np.testing.assert_array_equal(got, want)
    assert np.all(cov[:, 15:, :] == 0) and np.all(cov[:, 0:5, 5:10] == 0)


@pytest.mark.parametrize("seed", range(8))
def test_a_set_of_identical_models_is_the_single_model(seed: int) -> None:
    """Mixing identical Gaussians changes nothing and every model scores a detection alike,
    so J of every track set, the forward pass's tracks and their smoothed states are the
    single model's."""
    config, scans = tiny_recording(seed)
    same = _with_set(config, (1.0, 1.0))
    single = RecordingObjective(config=config, scans=scans)
    doubled = RecordingObjective(config=same, scans=scans)
    finite = 0
    for tracks in all_track_sets(scans):
        a, b = single.value(tracks), doubled.value(tracks)
        assert b == pytest.approx(a, abs=1e-9, rel=1e-12) if math.isfinite(a) else b == a
        finite += math.isfinite(a)
    assert finite >= 1
    one = WindowEstimator(config=config).run(scans)
    two = WindowEstimator(config=same).run(scans)
    assert one.track_rows == two.track_rows
    np.testing.assert_allclose(two.tracks.states, one.tracks.states, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(two.tracks.variances, one.tracks.variances, rtol=1e-9, atol=1e-9)


def _steps(scans, config, path, first: int, last: int) -> list[FilterStep]:
    """The filter steps of scans ``first..last`` of a track: its detections, else misses
    (the step at ``first`` carries no detection: the prior is already its posterior)."""
    used = dict(path)
    steps = [FilterStep(scans[first].time)]
    for m in range(first + 1, last + 1):
        measurement = config.sensors[scans[m].sensor].measurement
        if m in used:
            steps.append(FilterStep(scans[m].time, measurement, scans[m].detections[used[m]]))
        else:
            steps.append(FilterStep(scans[m].time))
    return steps


def _reference_log_likelihood(config, scans, path) -> float:
    """The track's log-likelihood of its detections after the first, as J defines it for
    a set: the first model alone up to the second detection, then the reference IMM from
    that posterior with the prior model probabilities."""
    motion = config.motion
    (m1, j1), (m2, _) = path[0], path[1]
    measurement = config.sensors[scans[m1].sensor].measurement
    x0, P0 = birth_state(motion, measurement, scans[m1].detections[j1], config.birth)
    head = filter_sequence(motion.models[0], x0, P0, _steps(scans, config, path, m1, m2),
                           smooth=False)  # fmt: skip
    tail = imm_filter(
        motion.models,
        motion.switching,
        head.x_filtered[-1],
        head.P_filtered[-1],
        _steps(scans, config, path, m2, path[-1][0]),
        log_mu0=np.log(motion.initial_probabilities),
    )
    return head.log_likelihood + tail.log_likelihood


def _single_log_likelihood(config, scans, path) -> float:
    m1, j1 = path[0]
    measurement = config.sensors[scans[m1].sensor].measurement
    x0, P0 = birth_state(config.motion, measurement, scans[m1].detections[j1], config.birth)
    steps = _steps(scans, config, path, m1, path[-1][0])
    return filter_sequence(config.motion, x0, P0, steps, smooth=False).log_likelihood


@pytest.mark.parametrize("seed", [0, 2, 4, 6, 9, 10, 12])
def test_j_of_a_track_takes_the_imm_predictive_likelihood(seed: int) -> None:
    """J under a set differs from J under its first model by exactly the difference of
    the two filters' log-likelihoods of the track's detections (every other term of J is
    the same): the trees' and J's IMM steps are the reference IMM's."""
    config, scans = tiny_recording(seed, num_scans=4, most=2)
    config = dataclasses.replace(config, estimator=dataclasses.replace(
        config.estimator, pruning=dataclasses.replace(
            config.estimator.pruning, gate_probability=1.0)))  # fmt: skip
    mixed = _with_set(config, (1.0, 40.0))
    single = RecordingObjective(config=config, scans=scans)
    imm = RecordingObjective(config=mixed, scans=scans)
    checked = 0
    for tracks in all_track_sets(scans):
        for path in tracks:
            if len(path) < 3:
                continue
            expected = _reference_log_likelihood(mixed, scans, path) - _single_log_likelihood(
                config, scans, path
            )
            got = imm.track_value(path) - single.track_value(path)
            assert got == pytest.approx(expected, abs=1e-8)
            checked += 1
    assert checked >= 1  # the seeds are those with a track of three detections or more


@pytest.mark.parametrize("name", ["crossing", "two_sensors"])
def test_the_trees_and_j_take_the_same_imm_steps(name: str) -> None:
    """Along every kept hypothesis of a window that starts the recording, the tree's
    filter state after each detection is J's, and its score J's value."""
    scenario = build_scenario(name, seed=1)
    config = _with_set(scenario.config, (1.0, 30.0))
    config = dataclasses.replace(config, estimator=dataclasses.replace(
        config.estimator, refine_passes=0, time_limit=NO_TIME_LIMIT))  # fmt: skip
    scans = scenario.scans[: config.estimator.window_length]
    hypotheses = WindowEstimator(config=config).generator.generate(scans)
    objective = RecordingObjective(config=config, scans=scans)
    nodes = hypotheses.nodes
    checked = in_set = 0
    for along, path in fresh_hypothesis_paths(hypotheses):
        run = objective.trajectory(path)
        for k, v in enumerate(along):
            mean, covariance = nodes.state(v)
            np.testing.assert_allclose(mean, run.means[k], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(covariance, run.covariances[k], rtol=1e-12, atol=1e-12)
            assert nodes.score[v] == pytest.approx(run.values[k], rel=1e-12, abs=1e-10)
            in_set += mean.shape[0] == config.motion.filter_state_dim
        checked += 1
    assert checked >= 10 and in_set >= 10


def test_the_smoother_of_identical_models_is_the_rts_smoother() -> None:
    """Kim's smoother of a set of identical models is the Rauch-Tung-Striebel smoother,
    on the true associations of a two-sensor scenario."""
    scenario = build_scenario("two_sensors", seed=0)
    single = oracle_tracks(scenario.scans, scenario.origins, scenario.config)
    same = _with_set(scenario.config, (1.0, 1.0))
    doubled = oracle_tracks(scenario.scans, scenario.origins, same)
    np.testing.assert_allclose(doubled.states, single.states, rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(doubled.variances, single.variances, rtol=1e-7, atol=1e-6)


@pytest.mark.parametrize("tracker", [GnnTracker, MhtTracker])
def test_scan_by_scan_trackers_run_a_set_of_identical_models_as_the_single_model(
    tracker: type,
) -> None:
    scenario = build_scenario("crossing", seed=0)
    scans = scenario.scans[:20]
    one = tracker(config=scenario.config).track(scans).tracks
    two = tracker(config=_with_set(scenario.config, (1.0, 1.0))).track(scans).tracks
    np.testing.assert_array_equal(two.track_ids, one.track_ids)
    np.testing.assert_array_equal(two.detection_rows, one.detection_rows)
    np.testing.assert_allclose(two.states, one.states, rtol=1e-7, atol=1e-6)


def test_jpda_refuses_a_model_set_by_name() -> None:
    scenario = build_scenario("crossing", seed=0)
    config = _with_set(scenario.config, (1.0, 10.0))
    with pytest.raises(InputError, match="probabilistic-data-association.*model set"):
        JpdaTracker(config=config).track(scenario.scans[:20])


def test_noise_levels_scales_the_models_noise_and_refuses_other_models() -> None:
    cv = ConstantVelocity(ndim=3, noise_intensity=2.0)
    models = noise_levels(cv, factors=(0.5, 4.0), switch_probability=0.1)
    assert [m.noise_intensity for m in models.models] == [1.0, 8.0]
    assert all(m.ndim == 3 for m in models.models) and models.switching.switch_probability == 0.1
    assert models.filter_state_dim == 2 * (6 + 1)
    with pytest.raises(InputError, match="kinematic model"):
        noise_levels(CoordinatedTurn(speed_noise_intensity=1.0, turn_rate_noise_intensity=0.1))
    with pytest.raises(InputError, match="factors must be positive"):
        noise_levels(cv, factors=(1.0, 0.0))


@pytest.mark.parametrize(("name", "factors"), [
    ("crossing", (1.0, 30.0)), ("crossing", (1.0, 3.0, 30.0)), ("two_sensors", (1.0, 30.0)),
])  # fmt: skip
def test_joins_in_a_set_continued_in_lockstep_are_the_whole_re_filtering(
    name: str, factors: tuple[float, ...], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The refinement's joins in a model set (continue_converging_many: requests of
    different starts and references stacked, each stopped where its state meets the
    reference's; with numba, in the compiled kernel of a set of linear models) give each
    track what re-filtering it along the whole rest of the reference gives, and what
    each request alone gives (the lockstep continuation, the kernel's numpy twin)."""
    kernels = imm_kernels()
    calls = []
    if kernels is not None:
        kernel = kernels.continue_sets_along_references
        monkeypatch.setattr(kernels, "continue_sets_along_references",
                            lambda *a: calls.append(1) or kernel(*a))  # fmt: skip
    scenario = build_scenario(name, seed=1)
    config = _with_set(scenario.config, factors)
    scans = scenario.scans[:25]
    forward = dataclasses.replace(scenario.config, estimator=dataclasses.replace(
        scenario.config.estimator, refine_passes=0))  # fmt: skip
    objective = RecordingObjective(config=config, scans=scans)
    rows = WindowEstimator(config=forward).run(scans).track_rows
    paths = [p for p in paths_from_rows(objective, rows).values() if len(p) > 6]
    assert len(paths) >= 2
    requests = []
    for i, path in enumerate(paths):
        reference, other = objective.trajectory(path), objective.trajectory(paths[i - 1])
        for cut in (2, 3, len(path) // 2):
            own = reference.state(cut - 1)
            before = [k for k in range(2, len(other.path)) if other.path[k][0] < path[cut][0]]
            starts = [own] + ([other.state(before[-1])] if before else [])
            requests.extend((start, reference, cut) for start in starts)
    many = objective.continue_converging_many(requests)
    finite = 0
    for (start, reference, first), got in zip(requests, many, strict=True):
        alone = objective.continue_converging(start, reference, first)
        np.testing.assert_allclose(got, alone, rtol=1e-12, atol=1e-9)
        whole = objective.continue_paths(start, reference.path[first:])
        expected = whole.value + objective.terms.tails[reference.path[-1][0]]
        np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-6)
        finite += int(np.isfinite(got).sum())
    assert finite >= len(paths)
    # two_sensors has a range-bearing sensor: its joins stay in the lockstep path.
    assert len(calls) == (kernels is not None and name == "crossing")
