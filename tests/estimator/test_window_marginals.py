"""Posterior marginals of a window (``mapassoc.estimator.marginals``).

1. Exact windows: every hypothesis' probability, every tree's existence, every
   (detection, tree) association and false alarm equal an enumeration of every feasible
   track set weighted by Perry's MAP formulation with K summed out (the weight of T
   computed here from the prior's laws), for each prior kind, to 1e-9; and the T law
   they imply is the posterior's ``track_probabilities``.
2. Bounded windows (a tiny ``exact_work_limit``): the bounds contain the exact values
   of the same window solved exactly; bound-pruned hypotheses' upper bounds contain
   their probability with the pruning off.
3. The one-scan window of the n-object posterior: association probabilities are its
   normalised weights summed per (object, measurement).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.special import logsumexp
from support import NO_TIME_LIMIT, SENSOR, make_config, make_scans, random_window

from mapassoc.data.config import Config
from mapassoc.errors import InputError
from mapassoc.estimator.hypotheses import CarriedTrack
from mapassoc.estimator.marginals import window_marginals
from mapassoc.estimator.pipeline import WindowEstimator, WindowSolution
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.formulations.packing import set_packing_program
from mapassoc.models.motion import RandomWalk
from mapassoc.models.population import poisson_log_pmf
from mapassoc.reference.association import n_object_posterior
from mapassoc.solvers import enumerate_feasible

TOLERANCE = 1e-9


def with_prior(config: Config, kind: str, **estimator: object) -> Config:
    settings = dataclasses.replace(
        config.estimator, k_prior=kind, k_prior_mean=1.7, time_limit=NO_TIME_LIMIT, **estimator
    )
    return dataclasses.replace(config, estimator=settings)


def weight_of_track_count(solution: WindowSolution, kmax: int) -> np.ndarray:
    """log W(T) = log sum_{K=T..kmax} pi(K) / p_birth(K) Po(K - T; nu), from the laws."""
    prior = solution.posterior.count_prior
    law = prior.log_prior(solution.population, kmax)
    birth = solution.population.log_count_prior(kmax)
    nu = solution.population.undetected_mean
    out = np.full(kmax + 1, -math.inf)
    for t in range(kmax + 1):
        terms = [
            law[k] - birth[k] + float(poisson_log_pmf(np.array([k - t]), nu)[0])
            for k in range(t, kmax + 1)
            if np.isfinite(law[k]) and np.isfinite(birth[k])
        ]
        if terms:
            out[t] = float(logsumexp(terms))
    return out


def enumerate_window(solution: WindowSolution) -> dict[str, np.ndarray]:
    """Every feasible track set of the window, weighted exp(score) W(T)."""
    problem = solution.problem
    hyps = solution.hypotheses
    kmax = solution.posterior.max_tracks
    log_w = weight_of_track_count(solution, kmax)
    H, D = hyps.count, hyps.detections.count
    trees = hyps.tree_track_ids.shape[0]
    sets, values = [], []
    for x in enumerate_feasible(set_packing_program(problem, None)):
        chosen = np.flatnonzero(x > 0.5)
        t = int(np.count_nonzero(problem.counts[chosen]))
        if t > kmax or not np.isfinite(log_w[t]):
            continue
        sets.append(chosen)
        values.append(problem.value(chosen) + log_w[t])
    p = np.exp(np.array(values) - logsumexp(values))
    hypothesis = np.zeros(H)
    existence = np.zeros(trees)
    association = np.zeros((D, trees))
    tracks = np.zeros(kmax + 1)
    for chosen, weight in zip(sets, p, strict=True):
        hypothesis[chosen] += weight
        counted = chosen[problem.counts[chosen]]
        existence[hyps.tree[counted]] += weight
        tracks[counted.size] += weight
        for h in chosen:
            association[hyps.detections_of(int(h)), hyps.tree[h]] += weight
    return {
        "hypothesis": hypothesis,
        "existence": existence,
        "association": association,
        "false_alarm": 1.0 - association.sum(axis=1),
        "tracks": tracks,
    }


# ------------------------------------------------------------------------ 1. exact


@pytest.mark.parametrize("kind", ["birth", "uniform", "poisson"])
@pytest.mark.parametrize(
    "seed", [pytest.param(s, marks=pytest.mark.slow) if s >= 12 else s for s in range(40)]
)
def test_marginals_equal_enumeration(kind: str, seed: int) -> None:
    case = random_window(seed)
    estimator = WindowEstimator(config=with_prior(case.estimator.config, kind))
    solution = estimator.solve_window(case.scans, case.carried)
    marginals = window_marginals(solution)
    expected = enumerate_window(solution)
    assert marginals.exact
    np.testing.assert_allclose(marginals.probabilities, expected["hypothesis"], atol=TOLERANCE)
    np.testing.assert_array_equal(marginals.lower, marginals.probabilities)
    np.testing.assert_array_equal(marginals.upper, marginals.probabilities)
    np.testing.assert_allclose(marginals.tree_existence, expected["existence"], atol=TOLERANCE)
    D = solution.hypotheses.detections.count
    trees = solution.hypotheses.tree_track_ids.shape[0]
    np.testing.assert_allclose(
        marginals.association_matrix(D, trees), expected["association"], atol=TOLERANCE
    )
    np.testing.assert_allclose(marginals.false_alarm, expected["false_alarm"], atol=TOLERANCE)
    # The law of T the marginals use is the posterior's.
    n = solution.posterior.track_probabilities.shape[0]
    np.testing.assert_allclose(
        solution.posterior.track_probabilities,
        np.r_[expected["tracks"], np.zeros(max(0, n - expected["tracks"].shape[0]))][:n],
        atol=TOLERANCE,
    )


def test_random_windows_have_uncertain_hypotheses() -> None:
    """The enumeration test is not trivial: many probabilities lie strictly inside (0, 1)."""
    inside = 0
    for seed in range(12):
        case = random_window(seed)
        marginals = window_marginals(case.estimator.solve_window(case.scans, case.carried))
        p = marginals.probabilities
        inside += int(np.count_nonzero((p > 0.01) & (p < 0.99)))
    assert inside >= 20


@pytest.fixture(scope="module")
def dense() -> tuple[WindowEstimator, list]:
    scenario = build_scenario("dense", seed=1)
    estimator = WindowEstimator(config=with_prior(scenario.config, "birth"))
    return estimator, list(scenario.scans)


def test_dense_window_expected_tracks_and_detection_sums(dense: tuple) -> None:
    """E[T] from the hypotheses equals E[T] from p(T | Z); every detection's association
    probabilities sum to at most 1; a tree's existence is at most 1."""
    estimator, scans = dense
    solution = estimator.solve_window(scans[30:35])
    marginals = window_marginals(solution)
    assert marginals.exact
    counted = solution.problem.counts
    p_tracks = solution.posterior.track_probabilities
    expected_tracks = float(np.dot(np.arange(p_tracks.shape[0]), p_tracks))
    assert abs(float(np.sum(marginals.probabilities[counted])) - expected_tracks) <= 1e-8
    per_detection = np.bincount(
        marginals.association_detection,
        weights=marginals.association_probability,
        minlength=solution.hypotheses.detections.count,
    )
    assert np.all(per_detection <= 1.0 + 1e-12)
    assert np.all(marginals.false_alarm >= -1e-12)
    assert np.all(marginals.tree_existence <= 1.0 + 1e-12)
    # Not all trivially certain: the dense scenario has doubtful detections.
    assert np.count_nonzero((per_detection > 0.05) & (per_detection < 0.95)) >= 5


# ---------------------------------------------------------------------- 2. bounded


@pytest.mark.slow
@pytest.mark.parametrize("start", [0, 30])
def test_bounds_contain_the_exact_marginals(dense: tuple, start: int) -> None:
    estimator, scans = dense
    window = scans[start : start + 5]
    exact = window_marginals(estimator.solve_window(window))
    tiny = WindowEstimator(config=with_prior(estimator.config, "birth", exact_work_limit=200))
    solution = tiny.solve_window(window)
    assert solution.bounded_clusters
    bounded = window_marginals(solution)
    assert not bounded.exact
    slack = 1e-12
    assert np.all(bounded.lower <= exact.probabilities + slack)
    assert np.all(exact.probabilities <= bounded.upper + slack)
    assert np.all(bounded.lower <= bounded.probabilities + slack)
    assert np.all(bounded.probabilities <= bounded.upper + slack)
    assert np.all(bounded.tree_existence_lower <= exact.tree_existence + slack)
    assert np.all(exact.tree_existence <= bounded.tree_existence_upper + slack)
    assert np.all(bounded.false_alarm_lower <= exact.false_alarm + slack)
    assert np.all(exact.false_alarm <= bounded.false_alarm_upper + slack)
    # The bounds say something: some strictly inside (0, 1), some narrow.
    width = bounded.upper - bounded.lower
    assert np.any(width > 1e-6)
    assert np.count_nonzero(width < 0.05) >= solution.hypotheses.count // 8


@pytest.mark.slow
def test_pruned_hypotheses_upper_bounds(dense: tuple) -> None:
    """Window 30 of the dense scenario has one cluster with bound-pruned hypotheses:
    their upper bounds hold the probabilities they get with the pruning off."""
    estimator, scans = dense
    window = scans[30:35]
    solution = estimator.solve_window(window)
    pruned_clusters = [c for c in solution.clusters if c.kept is not None]
    assert len(pruned_clusters) == 1
    marginals = window_marginals(solution)
    assert np.any(marginals.pruned)
    assert np.all(marginals.probabilities[marginals.pruned] == 0.0)
    unpruned_estimator = WindowEstimator(config=estimator.config)
    unpruned_estimator.cluster_solver.bound_prune_min_hypotheses = 10**9
    unpruned = unpruned_estimator.solve_window(window)
    assert unpruned.bound_pruned == 0
    reference = window_marginals(unpruned)
    assert reference.exact
    restored = reference.probabilities[marginals.pruned]
    assert np.all(restored <= marginals.upper[marginals.pruned] + 1e-12)
    assert np.all(marginals.upper[marginals.pruned] < 1.0)


def test_a_solution_without_cluster_records_is_refused() -> None:
    case = random_window(1)
    solution = case.estimator.solve_window(case.scans, case.carried)
    bare = dataclasses.replace(solution, clusters=())
    with pytest.raises(InputError, match="cluster records"):
        window_marginals(bare)


# ---------------------------------------------------------- 3. the n-object posterior


def test_one_scan_window_associations_are_the_n_object_posterior() -> None:
    """The n-object posterior's worked example (docs/model.md section 6): the probability
    that object i took measurement j is the sum of its normalised weights of the
    association vectors with theta_i = j; both objects exist for certain."""
    config = make_config(
        motion=RandomWalk(ndim=1, noise_intensity=0.01),
        noise_std=math.sqrt(0.2),
        detection_probability=0.85,
        false_alarms_per_scan=3.0,
        region=[[-5.0, 5.0]],
        rate=0.0,
        initial_count=0.0,
        survival_probability=1.0,
    )
    carried = [
        CarriedTrack(
            track_id=i + 1,
            mean=np.array([m]),
            covariance=np.array([[0.35]]),
            time=-1.0,
            initiated=True,
            num_detections=2,
            first_detection_time=-2.0,
        )
        for i, m in enumerate([-2.5, 2.5])
    ]
    scans = make_scans([0.0], [[[-1.6], [1.0]]], 1)
    solution = WindowEstimator(config=config).solve_window(scans, carried)
    marginals = window_marginals(solution)
    reference = n_object_posterior(
        prior_means=np.array([[-2.5], [2.5]]),
        prior_covs=np.array([[[0.36]], [[0.36]]]),
        measurements=np.array([[-1.6], [1.0]]),
        measurement_model=config.sensors[SENSOR].measurement,
        detection_probability=0.85,
        clutter_intensity=0.3,
    )
    expected = np.zeros((2, 2))  # (measurement, object)
    for theta, weight in zip(reference.associations, reference.weights, strict=True):
        for i, j in enumerate(theta):
            if j > 0:
                expected[j - 1, i] += weight
    # Window detections are numbered in scan order as given; trees by track id.
    ids = solution.hypotheses.tree_track_ids
    carried_trees = [int(np.flatnonzero(ids == i + 1)[0]) for i in range(2)]
    got = marginals.association_matrix(2, ids.shape[0])
    np.testing.assert_allclose(got[:, carried_trees], expected, atol=TOLERANCE)
    np.testing.assert_allclose(marginals.tree_existence[carried_trees], [1.0, 1.0], atol=TOLERANCE)
    np.testing.assert_allclose(marginals.false_alarm, 1.0 - expected.sum(axis=1), atol=TOLERANCE)
    assert 0.05 < expected[0, 0] < 0.99  # an uncertain association, not a certainty
