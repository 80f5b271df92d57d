"""Priors on the number of targets are small registered objects: adding one is a class."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mapassoc.data.scans import Scan
from mapassoc.data.settings import BirthModel
from mapassoc.estimator.posterior import (
    COUNT_LAWS,
    COUNT_PRIORS,
    CountLaw,
    CountPrior,
    k_posterior,
)
from mapassoc.models.population import recording_start, window_population


class GeometricLaw(CountLaw):
    """p(K) ∝ 2^-K: a throwaway law registered by the test."""

    name = "geometric"

    def log_prior(self, prior, population, top):  # type: ignore[no-untyped-def]
        return -math.log(2.0) * np.arange(top + 1, dtype=float)


def _population():  # type: ignore[no-untyped-def]
    birth = BirthModel(rate=0.5, initial_count=1.0, survival_probability=0.9)
    scans = [Scan(t, "s", np.zeros((0, 1)), np.zeros(0, dtype=np.int64)) for t in (0.0, 1.0)]
    return window_population(scans, [0.8, 0.8], birth, recording_start(birth, 0.0))


def test_the_registry_names_the_four_priors() -> None:
    assert COUNT_PRIORS == ("birth", "uniform", "poisson", "weights")
    assert all(law.name == name for name, law in COUNT_LAWS.items())


def test_a_registered_law_is_a_prior(monkeypatch: pytest.MonkeyPatch) -> None:
    """With no track (one feasible set, T = 0) p(K | Z) ∝ pi(K) / p_birth(K) Po(K; nu):
    for pi = 2^-K and p_birth = Po(mu) that is (q / 2)^K K! / K! = (q / 2)^K, q = nu / mu."""
    monkeypatch.setitem(COUNT_LAWS, "geometric", GeometricLaw())
    population = _population()
    prior = CountPrior(kind="geometric", kmax=6)
    post = k_posterior(np.array([0.0]), np.array([0.0]), prior=prior, population=population)
    q = population.undetected_mean / population.new_target_mean
    expected = (q / 2.0) ** np.arange(7)
    np.testing.assert_allclose(post.probabilities, expected / expected.sum(), rtol=1e-12)


def test_an_unregistered_name_is_refused_with_the_registered_ones() -> None:
    with pytest.raises(Exception, match="k_prior must be one of .*'birth'"):
        CountPrior(kind="geometric", kmax=3)
