"""The IMM filter and Kim's smoother against the exact mixture over model sequences.

Tiny linear-Gaussian recordings (1-D constant velocity, position detections, 2-4 scans,
two models) whose exact posterior is a mixture of one Kalman filter per model sequence,
enumerated here with the Kalman primitives: the exact log-likelihood of the detections,
the exact posterior mean and variance of every state (each sequence's RTS smoother,
weighted by its posterior probability) and the exact posterior model probabilities.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from mapassoc.errors import InputError
from mapassoc.filtering.imm import (
    IMMState,
    SwitchingLaw,
    check_models,
    check_switching_matrix,
    combine,
    imm_filter,
    imm_miss,
    imm_predict,
    imm_smooth,
    imm_update,
    mix,
)
from mapassoc.filtering.kalman import (
    FilterStep,
    filter_sequence,
    innovation,
    log_gaussian,
    predict_motion,
    rts_smooth,
    update,
)
from mapassoc.log_space import log_sum_exp
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import ConstantVelocity, CoordinatedTurn

LOW = ConstantVelocity(ndim=1, noise_intensity=0.01)
HIGH = ConstantVelocity(ndim=1, noise_intensity=2.0)
MEASUREMENT = LinearMeasurement.position(LOW, noise_std=1.0)
LAW = SwitchingLaw(n_models=2, switch_probability=0.2)
X0 = np.array([0.0, 0.0])
P0 = np.diag([4.0, 4.0])
UNIFORM = np.log([0.5, 0.5])


def _steps(rng: np.random.Generator, scans: int, misses: bool = True) -> list[FilterStep]:
    """Detections of a target whose acceleration is N(0, 1.5^2) per scan; later scans
    missed with probability 0.15."""
    truth = np.cumsum(np.cumsum(rng.normal(0.0, 1.5, scans)))
    steps = []
    for k in range(scans):
        if k and misses and rng.random() < 0.15:
            steps.append(FilterStep(time=float(k)))
        else:
            z = np.array([truth[k] + rng.normal()])
            steps.append(FilterStep(time=float(k), measurement=MEASUREMENT, z=z))
    return steps


def _sequence_smoother(models, sequence, steps):  # type: ignore[no-untyped-def]
    """One Kalman filter and RTS smoother with model ``sequence[k]`` into scan k."""
    T, n = len(steps), X0.size
    x, P = X0.copy(), P0.copy()
    xf, Pf, xp, Pp = np.empty((T, n)), np.empty((T, n, n)), np.empty((T, n)), np.empty((T, n, n))
    F = np.zeros((T, n, n))
    F[0] = np.eye(n)
    loglik = 0.0
    for k, step in enumerate(steps):
        if k:
            x, P, F[k] = predict_motion(models[sequence[k]], x, P, step.time - steps[k - 1].time)
        xp[k], Pp[k] = x, P
        if step.z is not None:
            nu, S, H = innovation(step.measurement, x, P, step.z)
            loglik += float(log_gaussian(nu, S))
            x, P = update(x, P, nu, S, H, step.measurement.noise_covariance)
        xf[k], Pf[k] = x, P
    xs, Ps = rts_smooth(xf, Pf, xp, Pp, F)
    return loglik, xs, np.diagonal(Ps, axis1=1, axis2=2)


def _exact(models, law, steps, log_mu0):  # type: ignore[no-untyped-def]
    """Exact log-likelihood, posterior means and variances (T, n), model probabilities (T, M)."""
    M, T = len(models), len(steps)
    log_weights, means, variances, sequences = [], [], [], []
    for sequence in itertools.product(range(M), repeat=T):
        log_prior = log_mu0[sequence[0]]
        for k in range(1, T):
            Pi = law.at(steps[k].time - steps[k - 1].time)
            with np.errstate(divide="ignore"):
                log_prior += float(np.log(Pi[sequence[k - 1], sequence[k]]))
        loglik, xs, vs = _sequence_smoother(models, sequence, steps)
        log_weights.append(log_prior + loglik)
        means.append(xs)
        variances.append(vs)
        sequences.append(sequence)
    total = float(log_sum_exp(np.array(log_weights)))
    w = np.exp(np.array(log_weights) - total)
    mean = np.einsum("s,stn->tn", w, np.array(means))
    spread = np.array(means) - mean
    variance = np.einsum("s,stn->tn", w, np.array(variances) + spread**2)
    probabilities = np.zeros((T, M))
    for weight, sequence in zip(w, sequences, strict=True):
        probabilities[np.arange(T), list(sequence)] += weight
    return total, mean, variance, probabilities


# --------------------------------------------------------------------------- exactness


def test_one_model_is_the_kalman_filter_and_the_rts_smoother() -> None:
    rng = np.random.default_rng(3)
    for scans in (1, 2, 4, 7):
        steps = _steps(rng, scans)
        law = SwitchingLaw(n_models=1, switch_probability=0.0)
        run = imm_filter([HIGH], law, X0, P0, steps)
        kalman = filter_sequence(HIGH, X0, P0, steps)
        assert run.log_likelihood == pytest.approx(kalman.log_likelihood, abs=1e-10)
        smoothed = imm_smooth([HIGH], law, run)
        assert np.allclose(smoothed.x, kalman.x_smoothed, atol=1e-9)
        assert np.allclose(smoothed.P, kalman.P_smoothed, atol=1e-9)
        assert np.allclose(smoothed.log_probabilities, 0.0)


def test_identical_models_are_the_kalman_filter_whatever_the_switching() -> None:
    rng = np.random.default_rng(4)
    steps = _steps(rng, 5)
    kalman = filter_sequence(HIGH, X0, P0, steps)
    twin = ConstantVelocity(ndim=1, noise_intensity=2.0)
    for p in (0.0, 0.1, 0.4):
        law = SwitchingLaw(n_models=2, switch_probability=p)
        run = imm_filter([HIGH, twin], law, X0, P0, steps, log_mu0=np.log([0.3, 0.7]))
        assert run.log_likelihood == pytest.approx(kalman.log_likelihood, abs=1e-10)
        exact, *_ = _exact([HIGH, twin], law, steps, np.log([0.3, 0.7]))
        assert exact == pytest.approx(kalman.log_likelihood, abs=1e-10)
        smoothed = imm_smooth([HIGH, twin], law, run)
        assert np.allclose(smoothed.x, kalman.x_smoothed, atol=1e-9)


def test_two_scans_are_exact_with_distinct_models() -> None:
    """After a common prior the first mixing merges identical Gaussians: the IMM's
    likelihood, its smoothed means and model probabilities are the exact mixture's."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        steps = _steps(rng, 2, misses=False)
        run = imm_filter([LOW, HIGH], LAW, X0, P0, steps, log_mu0=UNIFORM)
        smoothed = imm_smooth([LOW, HIGH], LAW, run)
        exact, mean, _, probabilities = _exact([LOW, HIGH], LAW, steps, UNIFORM)
        assert run.log_likelihood == pytest.approx(exact, abs=1e-10)
        assert np.allclose(smoothed.x, mean, atol=1e-9)
        assert np.allclose(np.exp(smoothed.log_probabilities), probabilities, atol=1e-12)


@pytest.mark.parametrize("scans", [3, 4])
def test_the_imm_likelihood_is_within_its_stated_bound_of_the_exact_mixture(scans: int) -> None:
    """Distinct models (noise intensities 0.01 and 2, switching 0.2 per scan), 50 random
    recordings with misses: the IMM's log-likelihood of all detections differs from the
    exact mixture's by at most 0.05 nats at 3 scans and 0.25 at 4 (measured: 0.02 and
    0.14), and it does differ (the merge is an approximation)."""
    rng = np.random.default_rng(6 + scans)
    differences = []
    for _ in range(50):
        steps = _steps(rng, scans)
        run = imm_filter([LOW, HIGH], LAW, X0, P0, steps, log_mu0=UNIFORM)
        exact, *_ = _exact([LOW, HIGH], LAW, steps, UNIFORM)
        differences.append(abs(run.log_likelihood - exact))
    bound = {3: 0.05, 4: 0.25}[scans]
    assert max(differences) <= bound
    assert max(differences) > 1e-6


@pytest.mark.parametrize("scans", [3, 4])
def test_kims_smoother_is_within_its_stated_bound_of_the_brute_force_smoother(scans: int) -> None:
    """The same recordings: Kim's smoothed means within 0.3 (3 scans) and 0.7 (4 scans)
    exact posterior standard deviations of the exact posterior means (measured: 0.17 and
    0.52), model probabilities within 0.15 and 0.3 (measured 0.12 and 0.23); and on
    average far closer than a smoother of the high-noise model alone."""
    rng = np.random.default_rng(16 + scans)
    errors, probability_errors, single = [], [], []
    for _ in range(50):
        steps = _steps(rng, scans)
        run = imm_filter([LOW, HIGH], LAW, X0, P0, steps, log_mu0=UNIFORM)
        smoothed = imm_smooth([LOW, HIGH], LAW, run)
        _, mean, variance, probabilities = _exact([LOW, HIGH], LAW, steps, UNIFORM)
        errors.append(np.max(np.abs(smoothed.x - mean) / np.sqrt(variance)))
        probability_errors.append(np.max(np.abs(np.exp(smoothed.log_probabilities) -
                                                probabilities)))  # fmt: skip
        alone = filter_sequence(HIGH, X0, P0, steps).x_smoothed
        single.append(np.max(np.abs(alone - mean) / np.sqrt(variance)))
    assert max(errors) <= {3: 0.3, 4: 0.7}[scans]
    assert max(probability_errors) <= {3: 0.15, 4: 0.3}[scans]
    assert np.mean(errors) < 0.5 * np.mean(single)


# --------------------------------------------------------------------------- the steps


def test_mixing_by_hand() -> None:
    """Two 1-D models: mu = (0.8, 0.2), Pi = [[0.9, 0.1], [0.3, 0.7]]."""
    Pi = np.array([[0.9, 0.1], [0.3, 0.7]])
    x = np.array([[0.0], [10.0]])
    P = np.array([[[1.0]], [[4.0]]])
    log_c, x0, P0 = mix(np.log([0.8, 0.2]), x, P, Pi)
    c = np.array([0.8 * 0.9 + 0.2 * 0.3, 0.8 * 0.1 + 0.2 * 0.7])  # 0.78, 0.22
    assert np.allclose(np.exp(log_c), c)
    w = np.array([[0.72 / 0.78, 0.06 / 0.78], [0.08 / 0.22, 0.14 / 0.22]])  # row j: mu_(i|j)
    assert np.allclose(x0[:, 0], w @ x[:, 0])
    spread = [sum(w[j, i] * (P[i, 0, 0] + (x[i, 0] - x0[j, 0]) ** 2) for i in range(2))
              for j in range(2)]  # fmt: skip
    assert np.allclose(P0[:, 0, 0], spread)


def test_a_miss_propagates_the_probabilities_by_the_switching_law_alone() -> None:
    state = IMMState(np.log([0.8, 0.2]), np.zeros((2, 2)), np.broadcast_to(np.eye(2), (2, 2, 2)))
    Pi = LAW.at(1.0)
    after = imm_miss(imm_predict(state, [LOW, HIGH], Pi, 1.0))
    assert np.allclose(np.exp(after.log_probabilities), np.array([0.8, 0.2]) @ Pi)
    # Many misses: the chain's stationary law (uniform for the uniform switching chain).
    for _ in range(200):
        after = imm_miss(imm_predict(after, [LOW, HIGH], Pi, 1.0))
    assert np.allclose(np.exp(after.log_probabilities), [0.5, 0.5])


def test_batched_hypotheses_equal_one_at_a_time() -> None:
    rng = np.random.default_rng(8)
    B, n = 5, 2
    log_mu = np.log(rng.dirichlet([1.0, 1.0], size=B))
    x = rng.normal(size=(B, 2, n))
    A = rng.normal(size=(B, 2, n, n))
    P = A @ np.swapaxes(A, -1, -2) + np.eye(n)
    z = np.array([0.3])
    Pi = LAW.at(2.0)
    batched, loglik = imm_update(imm_predict(IMMState(log_mu, x, P), [LOW, HIGH], Pi, 2.0),
                                 MEASUREMENT, z)  # fmt: skip
    for b in range(B):
        one, one_loglik = imm_update(
            imm_predict(IMMState(log_mu[b], x[b], P[b]), [LOW, HIGH], Pi, 2.0), MEASUREMENT, z
        )
        assert np.allclose(batched.log_probabilities[b], one.log_probabilities)
        assert np.allclose(batched.means[b], one.means)
        assert np.allclose(batched.covariances[b], one.covariances)
        assert loglik[b] == pytest.approx(float(one_loglik))
    mean, cov = combine(batched.log_probabilities, batched.means, batched.covariances)
    assert mean.shape == (B, n) and cov.shape == (B, n, n)
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_the_predictive_likelihood_is_the_mixture_of_model_likelihoods() -> None:
    state = IMMState(np.log([0.6, 0.4]), np.zeros((2, 2)), np.broadcast_to(np.eye(2), (2, 2, 2)))
    prediction = imm_predict(state, [LOW, HIGH], LAW.at(1.0), 1.0)
    z = np.array([1.7])
    _, loglik = imm_update(prediction, MEASUREMENT, z)
    by_model = [
        float(log_gaussian(*innovation(MEASUREMENT, prediction.means[j],
                                       prediction.covariances[j], z)[:2]))
        for j in range(2)
    ]  # fmt: skip
    expected = math.log(sum(math.exp(prediction.log_predicted[j] + by_model[j]) for j in range(2)))
    assert float(loglik) == pytest.approx(expected)


# --------------------------------------------------------------------------- switching law


@pytest.mark.parametrize(
    "law",
    [
        SwitchingLaw(n_models=2, switch_probability=0.1),
        SwitchingLaw(n_models=3, switch_probability=0.3),
        SwitchingLaw(n_models=2, matrix=np.array([[0.95, 0.05], [0.2, 0.8]])),
        SwitchingLaw(
            n_models=3, matrix=np.array([[0.9, 0.05, 0.05], [0.1, 0.8, 0.1], [0.02, 0.08, 0.9]])
        ),  # fmt: skip
    ],
)
def test_switching_matrices_are_stochastic_and_compose_over_time(law: SwitchingLaw) -> None:
    for dt in (0.5, 1.0, 4.5):
        Pi = law.at(dt)
        assert np.all(Pi >= 0.0)
        assert np.allclose(Pi.sum(axis=1), 1.0)
    assert np.allclose(law.at(1.5) @ law.at(2.5), law.at(4.0))
    assert np.allclose(law.at(1.0) @ law.at(1.0) @ law.at(1.0), law.at(3.0))
    if law.matrix is not None:
        assert np.allclose(law.at(1.0), law.matrix)
    else:  # the probability of leaving the current model within one unit of time
        assert np.allclose(1.0 - np.diag(law.at(1.0)), law.switch_probability)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n_models": 2}, "exactly one of"),
        ({"n_models": 2, "switch_probability": 0.1, "matrix": np.eye(2)}, "exactly one of"),
        ({"n_models": 2, "switch_probability": 0.5}, r"switch_probability must be .*\[0, 0.5\)"),
        ({"n_models": 2, "switch_probability": -0.1}, "switch_probability must be"),
        ({"n_models": 0, "switch_probability": 0.1}, "n_models must be an integer >= 1"),
        ({"n_models": 2, "matrix": [[0.9, 0.2], [0.1, 0.9]]}, "rows must sum to 1"),
        ({"n_models": 2, "matrix": [[1.1, -0.1], [0.1, 0.9]]}, r"entries in \[0, 1\]"),
        ({"n_models": 3, "matrix": np.eye(2)}, r"must be \(3, 3\)"),
        ({"n_models": 2, "matrix": [[0.0, 1.0], [1.0, 0.0]]}, "no continuous-time chain"),
    ],
)
def test_bad_switching_laws_are_refused_naming_the_argument(kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        SwitchingLaw(**kwargs)


def test_bad_intervals_and_matrices_are_refused() -> None:
    with pytest.raises(InputError, match="dt must be a positive finite"):
        LAW.at(0.0)
    with pytest.raises(InputError, match="square"):
        check_switching_matrix(np.ones((2, 3)) / 3)


def test_models_must_share_one_state_space() -> None:
    turn = CoordinatedTurn(speed_noise_intensity=1.0, turn_rate_noise_intensity=0.01)
    cv = ConstantVelocity(ndim=2, noise_intensity=1.0)
    with pytest.raises(InputError, match="IMM mixing needs one state space"):
        check_models([cv, turn])
    with pytest.raises(InputError, match="non-empty sequence"):
        check_models([])
    assert check_models([cv, ConstantVelocity(ndim=2, noise_intensity=9.0)])[0] is cv
