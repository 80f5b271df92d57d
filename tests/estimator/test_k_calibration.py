"""Calibration: windows simulated from the prior give a p(K | Z) that matches frequencies.

Each window is simulated from the generative model the estimator assumes
(``docs/model.md`` section 4): K drawn from the configured prior on the number of
targets, each target i.i.d. (entering at the window's first scan with probability
``u_0 / mu``, before a later scan with probability ``rate / mu``; surviving each second
with probability Ps; detected with probability Pd at each scan it is alive; constant
velocity motion), plus Poisson false alarms uniform over the region.  If p(K | Z) is
the posterior, then for every K the sum over windows of p(K | Z) estimates the number
of windows whose true count is K, with variance ``sum p (1 - p)``; and in every bin of
predicted probability the predicted mean matches the observed frequency within its
binomial error.  The tolerances are 4 standard errors plus 0.02 for the model's
approximations (the gate, the region's edges, pruning).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mapassoc.data.config import Config
from mapassoc.data.scans import Scan
from mapassoc.data.settings import BirthModel, EstimatorSettings
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.sensor import Region, Sensor

HALF_WIDTH = 50.0
SCANS = 3
PD = 0.75
FALSE_ALARMS = 2.0
NOISE_STD = 1.0
VELOCITY_STD = 1.0
NOISE_INTENSITY = 0.05
SURVIVAL = 0.85
INITIAL = 2.0
RATE = 0.4
KMAX = 8
WINDOWS = 400


def config_for(prior: str) -> Config:
    motion = ConstantVelocity(ndim=2, noise_intensity=NOISE_INTENSITY)
    sensor = Sensor(
        name="s",
        measurement=LinearMeasurement.position(motion, noise_std=NOISE_STD),
        detection_probability=PD,
        false_alarms_per_scan=FALSE_ALARMS,
        region=Region.from_bounds([[-HALF_WIDTH, HALF_WIDTH]] * 2),
    )
    return Config(
        motion=motion,
        sensors={"s": sensor},
        birth=BirthModel(
            rate=RATE,
            initial_count=INITIAL,
            velocity_std=VELOCITY_STD,
            survival_probability=SURVIVAL,
        ),
        estimator=EstimatorSettings(window_length=SCANS, max_tracks=KMAX, k_prior=prior),
    )


def simulate_window(rng: np.random.Generator, prior: str) -> tuple[list[Scan], int]:
    """Scans of one window that starts the recording, and its true number of targets."""
    masses = np.array([INITIAL + RATE] + [RATE] * (SCANS - 1))
    mu = float(masses.sum())
    if prior == "birth":
        k = int(rng.poisson(mu))
    else:
        k = int(rng.integers(0, KMAX + 1))
    motion = ConstantVelocity(ndim=2, noise_intensity=NOISE_INTENSITY)
    F, Q = motion.transition_matrix(1.0), motion.process_noise(1.0)
    detections: list[list[np.ndarray]] = [[] for _ in range(SCANS)]
    for _ in range(k):
        entry = int(rng.choice(SCANS, p=masses / mu))
        state = np.r_[
            rng.uniform(-HALF_WIDTH, HALF_WIDTH, 2), rng.normal(0.0, VELOCITY_STD, 2)
        ]
        for j in range(entry, SCANS):
            if j > entry:
                if rng.random() > SURVIVAL:
                    break
                state = F @ state + rng.multivariate_normal(np.zeros(4), Q)
            if rng.random() < PD:
                detections[j].append(state[:2] + rng.normal(0.0, NOISE_STD, 2))
    scans = []
    row = 2
    for j in range(SCANS):
        clutter = rng.uniform(-HALF_WIDTH, HALF_WIDTH, (int(rng.poisson(FALSE_ALARMS)), 2))
        points = np.vstack([*detections[j], clutter]) if detections[j] else clutter
        points = points[rng.permutation(len(points))].reshape(-1, 2)
        scans.append(Scan(float(j), "s", points, np.arange(row, row + len(points))))
        row += len(points)
    return scans, k


def scored_windows(simulated_from: str, scored_with: str, count: int, seed: int):  # type: ignore[no-untyped-def]
    """p(K | Z) of ``count`` windows simulated from one prior and scored with another."""
    rng = np.random.default_rng(seed)
    estimator = WindowEstimator(config=config_for(scored_with))
    predicted = np.zeros((count, KMAX + 1))
    truth = np.zeros(count, dtype=int)
    for i in range(count):
        scans, k = simulate_window(rng, simulated_from)
        predicted[i] = estimator.solve_window(scans).posterior.probabilities
        truth[i] = min(k, KMAX)  # the birth prior is cut at Kmax: its tail is below 1e-3
    return predicted, np.eye(KMAX + 1)[truth]


def calibration_failures(predicted: np.ndarray, observed: np.ndarray) -> list[tuple]:
    """The per-K and per-bin checks of the module docstring that fail."""
    failures: list[tuple] = []
    n_windows = predicted.shape[0]
    # Per K: expected number of windows with that count vs the observed number.
    expected = predicted.sum(axis=0)
    spread = np.sqrt((predicted * (1.0 - predicted)).sum(axis=0))
    for k in range(KMAX + 1):
        seen = observed[:, k].sum()
        if abs(seen - expected[k]) > 4.0 * spread[k] + 0.02 * n_windows:
            failures.append(("K", k, seen, expected[k]))
    # Reliability: bins of predicted probability over every (window, K) pair.
    p, y = predicted.ravel(), observed.ravel()
    bins = np.clip(np.digitize(p, np.linspace(0.0, 1.0, 11)) - 1, 0, 9)
    for b in range(10):
        inside = bins == b
        n = int(inside.sum())
        if n < 20:
            continue
        mean_p, freq = float(p[inside].mean()), float(y[inside].mean())
        tolerance = 4.0 * math.sqrt(max(mean_p * (1.0 - mean_p), 0.01) / n) + 0.02
        if abs(freq - mean_p) > tolerance:
            failures.append(("bin", b, freq, mean_p))
    return failures


@pytest.mark.slow
@pytest.mark.parametrize("prior", ["birth", "uniform"])
def test_posterior_over_k_is_calibrated(prior: str) -> None:
    predicted, observed = scored_windows(prior, prior, WINDOWS, 20261201)
    assert calibration_failures(predicted, observed) == []
    # And the posterior is informative: better (lower Brier score) than the prior alone.
    brier = float(((predicted - observed) ** 2).sum(axis=1).mean())
    prior_p = observed.mean(axis=0)
    brier_prior = float(((prior_p - observed) ** 2).sum(axis=1).mean())
    assert brier < 0.9 * brier_prior, (brier, brier_prior)


def test_the_simulator_draws_the_prior() -> None:
    """Sanity of the simulator: under the birth prior the mean count is mu."""
    rng = np.random.default_rng(3)
    counts = [simulate_window(rng, "birth")[1] for _ in range(2000)]
    mu = INITIAL + RATE * SCANS
    assert abs(np.mean(counts) - mu) < 4.0 * math.sqrt(mu / 2000)


@pytest.mark.slow
def test_the_calibration_check_fails_under_the_wrong_prior() -> None:
    """The check can fail: windows simulated with K uniform on 0..Kmax but scored with
    the birth prior (mean 3.2) are not calibrated."""
    predicted, observed = scored_windows("uniform", "birth", 200, 11)
    assert calibration_failures(predicted, observed) != []
