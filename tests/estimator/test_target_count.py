"""p(K | Z) against an independent brute force over **labelled** targets.

The brute force is written from the generative model of ``docs/model.md`` (section 4),
not from the hypothesis generator:

* the number K of targets present in the window has prior ``pi(K)`` on 0..Kmax;
* given K, the targets are i.i.d.: a target enters at the window's first scan with
  probability ``u_0 / mu`` (it was there, undetected, when the window started) or just
  before scan ``j >= 1`` with probability ``rate / mu`` (``mu = u_0 + (N - 1) rate``);
  it survives from scan ``j`` to ``j + 1`` with probability ``Ps ** dt`` and, once
  dead, stays dead; at every scan it is alive it is detected with probability Pd;
* at its first detection its position is uniform over the region (density 1/V) and
  its velocity N(0, velocity_std^2), so the first detection has density 1/V and, given
  it, the state is N([z, 0], diag(r, velocity_std^2)); the later detections are the
  stacked linear-Gaussian measurements of the constant-velocity motion from there
  (one joint Gaussian, not a Kalman recursion);
* the false alarms of a scan are Poisson(lambda_bar), uniform over the region, and the
  scan lists all its detections in a uniformly random order.

``p(K, Z)`` sums over every labelled configuration: for each of the K targets its
entry, death, and the detection or miss at every scan it is alive, disjoint across
targets, with the false alarms taking the rest (the scan shuffle gives each
configuration the factor ``F! / M!``).  ``pi(K)`` is the birth model's Poisson(mu) for
``"birth"``, else the named prior.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np
import pytest
from support import make_config, make_scans, partitions

from mapassoc.errors import InputError
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.posterior import COUNT_PRIORS, CountPrior, k_posterior
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.population import UndetectedTargets


@dataclass(frozen=True)
class Window:
    times: tuple[float, ...]
    detections: tuple[tuple[float, ...], ...]
    pd: float
    false_alarms: float
    volume: float
    rate: float
    initial: float  # expected undetected targets just after the previous scan
    previous_time: float | None  # None: the recording starts at the first scan
    survival: float
    velocity_std: float
    noise_intensity: float
    r: float  # measurement variance
    kmax: int
    prior_mean: float
    weights: tuple[float, ...]


def random_window(seed: int) -> Window:
    rng = np.random.default_rng(7000 + seed)
    n = int(rng.integers(1, 4))
    detections = []
    for _ in range(n):
        count = int(rng.integers(0, 3))
        detections.append(tuple(float(v) for v in rng.uniform(-3.0, 3.0, size=count)))
    gaps = rng.uniform(0.5, 2.0, size=n - 1)
    total = sum(len(d) for d in detections)
    kmax = total + int(rng.integers(0, 3))
    starts = rng.random() < 0.5
    return Window(
        times=tuple(float(t) for t in 10.0 + np.cumsum(np.r_[0.0, gaps])),
        detections=tuple(detections),
        pd=float(rng.choice([rng.uniform(0.3, 0.95), 1.0], p=[0.85, 0.15])),
        false_alarms=float(rng.uniform(0.3, 3.0)),
        volume=8.0,
        rate=float(rng.choice([0.0, rng.uniform(0.05, 1.5)], p=[0.2, 0.8])),
        initial=float(rng.uniform(0.1, 3.0)),
        previous_time=None if starts else 10.0 - float(rng.uniform(0.2, 2.0)),
        survival=float(rng.uniform(0.5, 0.99)),
        velocity_std=float(rng.uniform(0.3, 2.0)),
        noise_intensity=float(rng.uniform(0.1, 1.0)),
        r=float(rng.uniform(0.1, 1.0)),
        kmax=kmax,
        prior_mean=float(rng.uniform(0.5, 4.0)),
        weights=tuple(float(w) for w in rng.uniform(0.0, 1.0, size=kmax + 1)),
    )


def entry_masses(w: Window) -> list[float]:
    """Expected number of targets entering the window at each scan (alive there)."""
    if w.previous_time is None:
        first = w.initial + w.rate
    else:
        first = w.initial * w.survival ** (w.times[0] - w.previous_time) + w.rate
    return [first] + [w.rate] * (len(w.times) - 1)


def log_kinematic_density(w: Window, scans: list[int], values: list[float]) -> float:
    """log density of a target's detections: 1/V for the first, then the joint Gaussian."""
    out = -math.log(w.volume)
    if len(scans) == 1:
        return out
    t0 = w.times[scans[0]]
    later = [w.times[s] - t0 for s in scans[1:]]
    q = w.noise_intensity
    P0 = np.diag([w.r, w.velocity_std**2])

    def F(dt: float) -> np.ndarray:
        return np.array([[1.0, dt], [0.0, 1.0]])

    def Q(dt: float) -> np.ndarray:
        return q * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])

    n = len(later)
    mean = np.array([values[0]] * n)  # velocity mean 0: the position stays z_first
    cov = np.empty((n, n))
    for a, b in itertools.product(range(n), range(n)):
        ta, tb = sorted((later[a], later[b]))
        # Cov(x_a, x_b) = F_a P0 F_b' + Cov(noise to a) F(tb - ta)'  (ta <= tb)
        c = F(ta) @ P0 @ F(tb).T + Q(ta) @ F(tb - ta).T
        cov[a, b] = c[0, 0] + (w.r if a == b else 0.0)
    diff = np.array(values[1:]) - mean
    sign, logdet = np.linalg.slogdet(2.0 * math.pi * cov)
    assert sign > 0
    return out - 0.5 * logdet - 0.5 * float(diff @ np.linalg.solve(cov, diff))


def single_target_options(w: Window) -> list[tuple[int, int, float]]:
    """Every (detection mask, detected?, weight) of one target under the normalised law.

    Enumerates the entry scan, the last scan alive and, at every scan alive, a miss or
    one of the scan's detections.
    """
    n = len(w.times)
    masses = entry_masses(w)
    mu = sum(masses)
    ids = []
    index = 0
    for dets in w.detections:
        ids.append(list(range(index, index + len(dets))))
        index += len(dets)
    values = [v for dets in w.detections for v in dets]
    options = []
    for entry in range(n):
        if masses[entry] == 0.0:
            continue
        for last in range(entry, n):
            life = masses[entry] / mu
            for j in range(entry, last):
                life *= w.survival ** (w.times[j + 1] - w.times[j])
            if last < n - 1:
                life *= 1.0 - w.survival ** (w.times[last + 1] - w.times[last])
            alive = range(entry, last + 1)
            for choice in itertools.product(*[[None, *ids[j]] for j in alive]):
                weight = life
                for c in choice:
                    weight *= w.pd if c is not None else 1.0 - w.pd
                if weight == 0.0:
                    continue
                used = [c for c in choice if c is not None]
                mask = sum(1 << c for c in used)
                if used:
                    scans = [j for j, c in zip(alive, choice, strict=True) if c is not None]
                    weight *= math.exp(log_kinematic_density(w, scans, [values[c] for c in used]))
                options.append((mask, int(bool(used)), weight))
    return options


def brute_force(w: Window, prior: str) -> tuple[np.ndarray, np.ndarray]:
    """p(K | Z) and p(T | Z) (T: targets with a detection) by labelled enumeration."""
    masses = entry_masses(w)
    mu = sum(masses)
    options = single_target_options(w)
    scan_of = [m for m, dets in enumerate(w.detections) for _ in dets]
    D = len(scan_of)
    # dp[mask][t]: sum over ordered (labelled) k-tuples of targets using exactly `mask`
    # with t of them detected.
    dp = {0: np.zeros(w.kmax + 1)}
    dp[0][0] = 1.0
    joint = np.zeros((w.kmax + 1, w.kmax + 1))  # p(K, T, Z) up to one constant

    def false_alarm_factor(mask: int) -> float:
        used = np.bincount([scan_of[d] for d in range(D) if mask >> d & 1], minlength=len(w.times))
        out = 1.0
        for m, dets in enumerate(w.detections):
            f = len(dets) - int(used[m])
            out *= (w.false_alarms / w.volume) ** f
        return out

    for k in range(w.kmax + 1):
        if prior == "birth":
            pi = mu**k / math.factorial(k)  # Po(K; mu) up to e^-mu
        elif prior == "uniform":
            pi = 1.0
        elif prior == "poisson":
            pi = w.prior_mean**k / math.factorial(k)
        else:
            pi = w.weights[k]
        for mask, counts in dp.items():
            joint[k] += pi * counts * false_alarm_factor(mask)
        if k == w.kmax:
            break
        nxt: dict[int, np.ndarray] = {}
        for mask, counts in dp.items():
            for o_mask, detected, weight in options:
                if mask & o_mask:
                    continue
                row = nxt.setdefault(mask | o_mask, np.zeros(w.kmax + 1))
                row[detected:] += weight * counts[: w.kmax + 1 - detected]
        dp = nxt
    p_k = joint.sum(axis=1)
    p_t = joint.sum(axis=0)
    return p_k / p_k.sum(), p_t / p_t.sum()


def estimator_for(w: Window, prior: str) -> WindowEstimator:
    config = make_config(
        motion=ConstantVelocity(ndim=1, noise_intensity=w.noise_intensity),
        noise_std=math.sqrt(w.r),
        detection_probability=w.pd,
        false_alarms_per_scan=w.false_alarms,
        region=[[-w.volume / 2, w.volume / 2]],
        rate=w.rate,
        initial_count=w.initial if w.previous_time is None else 0.0,
        velocity_std=w.velocity_std,
        survival_probability=w.survival,
        max_tracks=w.kmax,
    )
    estimator = replace(
        config.estimator,
        k_prior=prior,
        k_prior_mean=w.prior_mean,
        k_prior_weights=w.weights if prior == "weights" else (),
    )
    return WindowEstimator(config=replace(config, estimator=estimator))


def solve(w: Window, prior: str):  # type: ignore[no-untyped-def]
    scans = make_scans(list(w.times), [[[z] for z in d] for d in w.detections], 1)
    undetected = (
        None
        if w.previous_time is None
        else UndetectedTargets(expected_count=w.initial, time=w.previous_time)
    )
    return estimator_for(w, prior).solve_window(scans, undetected=undetected)


WINDOWS = 320


@pytest.mark.parametrize("chunk", range(8))
def test_posterior_over_k_equals_labelled_brute_force(chunk: int) -> None:
    """320 random windows (births, deaths, late first detections, never-detected
    targets, windows that start the recording and windows that continue it), each
    checked under all four priors: p(K | Z) and p(T | Z) to 1e-9."""
    for seed in range(chunk, WINDOWS, 8):
        w = random_window(seed)
        configured = COUNT_PRIORS[seed % len(COUNT_PRIORS)]
        solution = solve(w, configured)
        for prior in COUNT_PRIORS:
            expected_k, expected_t = brute_force(w, prior)
            if prior == configured:
                post = solution.posterior
            else:
                post = k_posterior(
                    solution.table.best,
                    solution.table.log_mass,
                    prior=CountPrior(kind=prior, kmax=w.kmax, mean=w.prior_mean, weights=w.weights),
                    population=solution.population,
                )
            np.testing.assert_allclose(
                post.probabilities, expected_k, rtol=0, atol=1e-9, err_msg=f"{seed} {prior} K"
            )
            np.testing.assert_allclose(
                post.track_probabilities,
                expected_t,
                rtol=0,
                atol=1e-9,
                err_msg=f"{seed} {prior} T",
            )


def test_one_scan_three_detections_under_a_uniform_prior() -> None:
    """The issue's smallest case: one scan, 3 detections, Pd = 1, lambda_bar = 1, one
    target expected at the start, Kmax = 3.  Each unordered track set with K tracks
    stands for K! labelled assignments: p(K | Z) ∝ C(3, K) K! = [1, 3, 6, 6] / 16."""
    w = Window(
        times=(0.0,),
        detections=((-3.0, 0.0, 3.0),),
        pd=1.0,
        false_alarms=1.0,
        volume=8.0,
        rate=0.0,
        initial=1.0,
        previous_time=None,
        survival=0.9,
        velocity_std=1.0,
        noise_intensity=0.1,
        r=0.1,
        kmax=3,
        prior_mean=1.0,
        weights=(1.0, 1.0, 1.0, 1.0),
    )
    uniform = solve(w, "uniform").posterior
    np.testing.assert_allclose(uniform.probabilities, [0.0625, 0.1875, 0.375, 0.375], atol=1e-12)
    assert uniform.marginal_k == 2 and uniform.marginal_tracks == 2
    birth = solve(w, "birth").posterior  # Poisson(1) truncated: C(3, K) = [1, 3, 3, 1] / 8
    np.testing.assert_allclose(birth.probabilities, [0.125, 0.375, 0.375, 0.125], atol=1e-12)
    assert birth.marginal_k == 1


def test_brute_force_counts_labelled_assignments() -> None:
    """Sanity of the evaluator: two detections in one scan, Pd = 1, no false alarms to
    speak of: K = 2 has 2 labelled assignments of the two detections."""
    w = replace(
        random_window(0),
        times=(0.0,),
        detections=((-1.0, 1.0),),
        pd=1.0,
        false_alarms=1e-9,
        rate=0.0,
        initial=1.0,
        previous_time=None,
        kmax=2,
        weights=(1.0, 1.0, 1.0),
    )
    p_k, p_t = brute_force(w, "uniform")
    assert p_k[2] > 1.0 - 1e-6 and p_t[2] > 1.0 - 1e-6
    options = single_target_options(w)
    assert sorted(o[0] for o in options) == [1, 2]  # each detection alone


# ------------------------------------------------------ reductions through the config


def perry_posterior(w: Window) -> np.ndarray:
    """Perry's MAP formulation's p(K | Z), literally: a uniform p(K) on 0..Kmax; K labelled targets
    present at every scan of the window; each detected with probability Pd at every
    scan; a track set omega with T tracks can be given to the K targets in
    K! / (K - T)! ways, and the K - T targets without a track are missed at all N
    scans; a track's first detection has density 1/V (uniform position) and its later
    ones the stacked Gaussian; Poisson false alarms, uniform, shuffled (eqs. 8-13)."""
    n = len(w.times)
    scan_of = [m for m, dets in enumerate(w.detections) for _ in dets]
    values = [v for dets in w.detections for v in dets]
    counts = [len(d) for d in w.detections]
    weight_by_t = np.zeros(w.kmax + 1)
    for partition in partitions(scan_of):
        t = len(partition)
        if t > w.kmax:
            continue
        log_w = 0.0
        for track in partition:
            scans = [scan_of[d] for d in track]
            log_w += len(track) * math.log(w.pd) + (n - len(track)) * math.log1p(-w.pd)
            log_w += log_kinematic_density(w, scans, [values[d] for d in track])
        for m in range(n):
            used = sum(1 for track in partition for d in track if scan_of[d] == m)
            log_w += (counts[m] - used) * math.log(w.false_alarms / w.volume)
        weight_by_t[t] += math.exp(log_w)
    p = np.zeros(w.kmax + 1)
    for k in range(w.kmax + 1):
        for t in range(k + 1):
            arrangements = math.factorial(k) / math.factorial(k - t)
            p[k] += arrangements * weight_by_t[t] * (1.0 - w.pd) ** (n * (k - t))
    return p / p.sum()


@pytest.mark.parametrize("seed", range(30))
def test_public_configuration_reduces_to_perrys_formulation(seed: int) -> None:
    """rate = 0, survival_probability = 1, k_prior = "uniform", no gate and no pruning,
    a window that starts the recording: p(K | Z) is the posterior of Perry's MAP
    formulation under its uniform prior, whatever initial_count is (it scales every track set with T
    tracks by initial_count^T, which the uniform prior's reweighting removes)."""
    w = replace(
        random_window(seed),
        rate=0.0,
        survival=1.0,
        previous_time=None,
        pd=float(np.random.default_rng(seed).uniform(0.3, 0.95)),
    )
    expected = perry_posterior(w)
    for initial in (0.3, w.initial, 5.0):
        post = solve(replace(w, initial=initial), "uniform").posterior
        np.testing.assert_allclose(post.probabilities, expected, rtol=0, atol=1e-9)


def test_solve_window_is_the_first_window_of_run() -> None:
    """No hidden flag: solve_window(scans[:N]) computes what run() computes for its first
    window (the recording starts there), and the undetected-target state run() carries
    is the one the window reports after its committed scan."""
    from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario

    scenario = truncate_scenario(build_scenario("crossing", 0), 8)
    estimator = WindowEstimator(config=scenario.config)
    n = scenario.config.estimator.window_length
    result = estimator.run(scenario.scans)
    window = estimator.solve_window(scenario.scans[:n])
    report = result.windows[0]
    k = len(report.p_k)
    np.testing.assert_array_equal(report.p_k, window.posterior.probabilities[:k])
    assert report.marginal_k == window.posterior.marginal_k
    assert report.chosen_tracks == window.posterior.marginal_tracks
    assert report.undetected_mean == window.posterior.undetected_mean
    # The first scan's undetected targets: initial_count + rate, thinned by 1 - Pd.
    birth = scenario.config.birth
    pd = scenario.config.sensors["pos"].detection_probability
    after = window.population.after_scan[0]
    assert after.expected_count == pytest.approx((birth.initial_count + birth.rate) * (1 - pd))


def test_undetected_targets_by_hand() -> None:
    """Golden values of the recursion (docs/model.md section 3), derived by hand:
    scans at t = 0, 1, 3; Pd = 0.5; Ps = 0.8 per unit time; initial_count = 2; rate 1.

    u_1 = 2 + 1 = 3;  u_2 = 3 * 0.5 * 0.8 + 1 = 2.2;  u_3 = 2.2 * 0.5 * 0.64 + 1 = 1.704;
    q_3 = 0.5;  q_2 = 0.5 (0.36 + 0.64 * 0.5) = 0.34;  q_1 = 0.5 (0.2 + 0.8 * 0.34) = 0.236;
    nu = 3 * 0.236 + 1 * (0.34 + 0.5) = 1.548;  mu_new = 3 + 2 = 5."""
    from mapassoc.data.scans import Scan
    from mapassoc.data.settings import BirthModel
    from mapassoc.models.population import recording_start, window_population

    birth = BirthModel(rate=1.0, initial_count=2.0, survival_probability=0.8)
    scans = [Scan(t, "s", np.zeros((0, 1)), np.zeros(0, dtype=np.int64)) for t in (0.0, 1.0, 3.0)]
    carried_times = [-1.0, 0.0]
    population = window_population(
        scans, [0.5] * 3, birth, recording_start(birth, 0.0), carried_times
    )
    np.testing.assert_allclose(population.first_detection_means, [3.0, 2.2, 1.704])
    assert population.undetected_mean == pytest.approx(1.548)
    assert population.new_target_mean == pytest.approx(5.0)
    np.testing.assert_allclose(population.carried_alive, [0.8, 1.0])
    assert population.after_scan[-1].expected_count == pytest.approx(0.852)
    # p_birth(K) = Bernoulli(0.8) + 1 + Poisson(5): by direct convolution.
    poisson = np.array([math.exp(-5.0) * 5.0**k / math.factorial(k) for k in range(12)])
    expected = np.zeros(12)
    expected[1:] += 0.2 * poisson[:11]
    expected[2:] += 0.8 * poisson[:10]
    np.testing.assert_allclose(np.exp(population.log_count_prior(11)), expected, rtol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_cut_range_of_k_equals_the_full_range(seed: int) -> None:
    """The uniform prior's K range is found by doubling and cut where the weights are
    negligible; equal weights ("weights", always the full range) give the same
    posterior over a Kmax of 3,000."""
    w = random_window(seed)
    solution = solve(w, "uniform")
    kmax = 3000
    posts = [
        k_posterior(
            solution.table.best,
            solution.table.log_mass,
            prior=CountPrior(kind=kind, kmax=kmax, weights=weights),
            population=solution.population,
        )
        for kind, weights in (("uniform", ()), ("weights", (1.0,) * (kmax + 1)))
    ]
    np.testing.assert_allclose(posts[0].probabilities, posts[1].probabilities, atol=1e-14)
    assert posts[0].marginal_k == posts[1].marginal_k
    assert posts[0].joint_map_k == posts[1].joint_map_k


def test_k_estimators_on_the_one_scan_case() -> None:
    """Hand-derived: uniform p(K | Z) = [1, 3, 6, 6] / 16 has CDF [1, 4, 10, 16] / 16, so
    the median is 2 (the marginal too); the birth prior's [1, 3, 3, 1] / 8 has CDF
    [1, 4, 7, 8] / 8, so the median is 1.  With Pd = 1 nothing goes undetected, so the
    committed track count equals K."""
    from mapassoc.estimator.posterior import K_ESTIMATORS, MedianK

    w = replace(random_window(0), times=(0.0,), detections=((-3.0, 0.0, 3.0),), pd=1.0,
                false_alarms=1.0, rate=0.0, initial=1.0, previous_time=None, kmax=3,
                weights=(1.0,) * 4)
    uniform, birth = solve(w, "uniform").posterior, solve(w, "birth").posterior
    assert MedianK().choose(uniform) == (2, 2)
    assert MedianK().choose(birth) == (1, 1)
    assert K_ESTIMATORS["marginal"].choose(uniform) == (uniform.marginal_k, uniform.marginal_tracks)
    assert K_ESTIMATORS["joint"].choose(birth) == (birth.joint_map_k, birth.joint_map_tracks)
    assert birth.tracks_given(3) == 3
    with pytest.raises(InputError, match="k must be an integer in 0..3"):
        birth.tracks_given(4)


@pytest.mark.parametrize("seed", range(40))
def test_the_joint_map_set_is_the_map_set_given_its_k(seed: int) -> None:
    """Two code paths agree: the joint MAP (K, T) from the sweep over the (T, K) table,
    and ``tracks_given`` (eq. 2 maximised over T for a fixed K); likewise the marginal."""
    w = random_window(seed)
    for prior in ("uniform", "birth"):
        post = solve(w, prior).posterior
        assert post.tracks_given(post.joint_map_k) == post.joint_map_tracks
        assert post.tracks_given(post.marginal_k) == post.marginal_tracks
        assert post.joint_map_tracks <= post.joint_map_k


def test_every_registered_k_estimator_runs_end_to_end() -> None:
    """k_estimate names any registered estimator; the committed set has its T tracks."""
    from mapassoc.estimator.posterior import K_ESTIMATORS
    from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario

    scenario = truncate_scenario(build_scenario("crossing", 0), 8)
    for name, estimator in K_ESTIMATORS.items():
        settings = replace(scenario.config.estimator, k_estimate=name)
        result = WindowEstimator(config=replace(scenario.config, estimator=settings)).run(
            scenario.scans
        )
        for report in result.windows:
            assert report.chosen_tracks <= report.chosen_k
            assert name != "marginal" or report.chosen_k == report.marginal_k
            assert name != "joint" or report.chosen_tracks == report.joint_map_tracks
        assert estimator.name == name
