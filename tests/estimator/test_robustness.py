"""A huge max_tracks costs what the data need, not Kmax; p(K | Z) stays exact (issue 19).

``max_tracks = 10**9`` once filled 24 GB; the per-T tables now stop at the counted
hypotheses and the K range where a proven geometric tail bound says the rest of the
posterior is below e^-800 of it (:func:`mapassoc.estimator.posterior.k_posterior`).
"""

from __future__ import annotations

import json
import math
import tracemalloc
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from support import NO_TIME_LIMIT

from mapassoc.apps.cli import main
from mapassoc.data.config import load_config, write_config
from mapassoc.errors import ConfigError, InputError
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.posterior import (
    COUNT_LAWS,
    FULL_LENGTH_KMAX,
    MAX_KMAX,
    CountPrior,
    k_posterior,
)
from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario
from mapassoc.models.population import WindowPopulation, poisson_log_pmf

BILLION = 10**9
AMPLE = 600
"""A Kmax past every K these windows reach (their posteriors end below K = 200), and
below FULL_LENGTH_KMAX, so its arrays run to Kmax in full."""


def _crossing(kmax: int, prior: str):  # type: ignore[no-untyped-def]
    scenario = truncate_scenario(build_scenario("crossing", 0), 10)
    estimator = replace(
        scenario.config.estimator, max_tracks=kmax, k_prior=prior, time_limit=NO_TIME_LIMIT
    )
    return scenario, replace(scenario.config, estimator=estimator)


@pytest.mark.parametrize("prior", ["birth", "uniform", "poisson"])
def test_a_billion_max_tracks_gives_the_posterior_of_an_ample_one(prior: str) -> None:
    """Every reported p_k entry to 1e-12, every estimate of K and the tracks are those of
    Kmax = 600 (a uniform prior on 0..Kmax is a different prior for each Kmax, but the
    same posterior once Kmax is past where it ends: the constant cancels)."""
    scenario, huge_config = _crossing(BILLION, prior)
    _, ample_config = _crossing(AMPLE, prior)
    huge = WindowEstimator(config=huge_config).run(scenario.scans)
    ample = WindowEstimator(config=ample_config).run(scenario.scans)
    assert huge.track_rows == ample.track_rows
    for a, b in zip(huge.windows, ample.windows, strict=True):
        assert a.p_k_length == BILLION + 1 and b.p_k_length == AMPLE + 1
        n = max(len(a.p_k), len(b.p_k))
        pa = np.zeros(n)
        pb = np.zeros(n)
        pa[: len(a.p_k)], pb[: len(b.p_k)] = a.p_k, b.p_k
        np.testing.assert_allclose(pa, pb, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a.p_tracks, b.p_tracks, rtol=0, atol=1e-12)
        assert (a.marginal_k, a.joint_map_k, a.chosen_k, a.chosen_tracks) == (
            b.marginal_k,
            b.joint_map_k,
            b.chosen_k,
            b.chosen_tracks,
        )
        line = a.to_json(timings=False)
        assert line["p_k_length"] == BILLION + 1
        assert len(line["p_k"]) < 300  # type: ignore[arg-type]


@pytest.mark.parametrize("prior", ["birth", "uniform", "poisson"])
def test_a_billion_max_tracks_needs_small_arrays_and_little_memory(prior: str) -> None:
    """The window's arrays are sized by its hypotheses and its posterior's reach: a
    float64 vector of Kmax + 1 entries alone would be 8 GB."""
    scenario, config = _crossing(BILLION, prior)
    estimator = WindowEstimator(config=config)
    tracemalloc.start()
    try:
        window = estimator.solve_window(scenario.scans[:5])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50 * 2**20, peak
    post = window.posterior
    assert post.max_tracks == BILLION
    assert post.probabilities.shape[0] < 10**4
    for array in (post.best_log_score, post.log_mass, post.track_probabilities,
                  post.probabilities_lower, post.probabilities_upper):  # fmt: skip
        assert array.shape == post.probabilities.shape
    counted = int(np.count_nonzero(window.problem.counts))
    assert window.table.best.shape[0] == max(counted, FULL_LENGTH_KMAX) + 1
    assert abs(float(post.probabilities.sum()) - 1.0) < 1e-12
    assert not post.piles_up_at_kmax


def _population(rng: np.random.Generator, most_undetected: float = 0.999) -> WindowPopulation:
    """A window's population with carried tracks and nu = q mu < mu (q: the probability
    that a target of the window is never detected), as window_population makes."""
    mu = float(rng.uniform(0.05, 30.0))
    q = float(rng.uniform(0.0, most_undetected))
    return WindowPopulation(
        first_detection_means=np.array([mu]),
        after_scan=(),
        new_target_mean=mu,
        undetected_mean=q * mu,
        carried_alive=rng.uniform(0.0, 1.0, size=int(rng.integers(0, 6))),
    )


@pytest.mark.parametrize("seed", range(30))
def test_each_laws_step_bound_holds_beyond_top(seed: int) -> None:
    """The proof's premise, checked: for every K >= top, W_T(K + 1) <= r_T W_T(K) with
    ``W_T(K) = pi(K) / p_birth(K) Po(K - T; nu)`` and r_T the law's tail_step."""
    rng = np.random.default_rng(seed)
    population = _population(rng)
    top = int(rng.integers(1, 60))
    tracks = np.arange(0, top + 1, dtype=np.int64)
    far = top + 400
    for name, law in COUNT_LAWS.items():
        prior = CountPrior(kind=name, kmax=far, mean=float(rng.uniform(0.5, 40.0)),
                           weights=tuple(np.ones(far + 1)))  # fmt: skip
        steps = law.tail_step(prior, population, top, tracks)
        if steps is None:
            assert name == "weights"
            continue
        ratio = law.log_ratio(prior, population, far)
        ks = np.arange(top, far + 1)
        for T, r in zip(tracks, steps, strict=True):
            w = ratio[ks] + poisson_log_pmf(ks - T, population.undetected_mean)
            live = np.isfinite(w[:-1])
            rise = w[1:][live] - w[:-1][live]
            with np.errstate(divide="ignore"):
                assert np.all(rise <= math.log(r) + 1e-9), (name, T, float(np.max(rise)), r)


@pytest.mark.parametrize("seed", range(30))
def test_the_cut_k_range_loses_nothing_above_1e_300(seed: int) -> None:
    """k_posterior with Kmax = 10**9 against eq. (3) summed directly over K = 0..20000
    (far past where these posteriors end): the same p(K | Z) to 1e-12, every K it leaves
    out below 1e-300, and the same estimates."""
    rng = np.random.default_rng(100 + seed)
    population = _population(rng, most_undetected=0.9)
    n = int(rng.integers(1, 40))
    best = np.cumsum(rng.normal(0.5, 3.0, size=n))
    best[0] = 0.0
    log_mass = best + np.abs(rng.normal(0.0, 2.0, size=n))
    reach = 20_000
    ks = np.arange(reach + 1)
    for name in ("birth", "uniform", "poisson"):
        prior = CountPrior(kind=name, kmax=BILLION, mean=float(rng.uniform(0.5, 40.0)))
        cut = k_posterior(best, log_mass, prior=prior, population=population)
        ratio = prior.log_ratio(population, reach)
        terms = [
            log_mass[t] + ratio + poisson_log_pmf(ks - t, population.undetected_mean)
            for t in range(n)
        ]
        weight = np.logaddexp.reduce(np.array(terms), axis=0)
        expected = np.exp(weight - np.max(weight))
        expected /= expected.sum()
        got = np.zeros(reach + 1)
        got[: min(reach + 1, cut.probabilities.shape[0])] = cut.probabilities[: reach + 1]
        assert np.all(cut.probabilities[reach + 1 :] == 0.0)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12, err_msg=name)
        assert np.all(expected[got == 0.0] < 1e-300), name
        assert cut.marginal_k == int(np.argmax(expected))


def test_a_max_tracks_beyond_2_53_is_refused_naming_the_key(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="max_tracks must be at most 2\\*\\*53") as info:
        CountPrior(kmax=MAX_KMAX + 1)
    assert info.value.key == "max_tracks"
    scenario, config = _crossing(AMPLE, "birth")
    write_config(tmp_path / "config.toml", config)
    text = (tmp_path / "config.toml").read_text().replace(
        f"max_tracks = {AMPLE}", f"max_tracks = {MAX_KMAX + 1}"
    )
    (tmp_path / "config.toml").write_text(text)
    with pytest.raises(ConfigError) as error:
        load_config(tmp_path / "config.toml")
    assert error.value.key == "estimator.count.max_tracks"
    assert str(MAX_KMAX + 1) in str(error.value) and "\n" not in str(error.value)


def test_a_prior_far_beyond_the_data_is_refused_instead_of_filling_the_memory() -> None:
    """A Poisson prior of mean 1e15 under Kmax = 10**9 puts the posterior at K ~ Kmax:
    computing it would need 10**9 values; refused at once, naming max_tracks."""
    scenario, config = _crossing(BILLION, "poisson")
    config = replace(config, estimator=replace(config.estimator, k_prior_mean=1e15))
    with pytest.raises(InputError, match="does not provably end") as info:
        WindowEstimator(config=config).solve_window(scenario.scans[:5])
    assert info.value.key == "max_tracks"
    assert "max_tracks = 1000000000" in str(info.value)


def test_the_command_line_runs_a_billion_max_tracks(tmp_path: Path) -> None:
    scenario, config = _crossing(AMPLE, "birth")
    scen = tmp_path / "scen"
    assert main(["simulate", "crossing", "--out", str(scen), "--seed", "0", "--scans", "8"]) == 0
    text = (scen / "config.toml").read_text()
    results = {}
    for kmax in (AMPLE, BILLION):
        edited = tmp_path / f"config_{kmax}.toml"
        lines = [
            f"max_tracks = {kmax}" if line.startswith("max_tracks") else line
            for line in text.splitlines()
        ]
        edited.write_text("\n".join(lines) + "\n")
        out = tmp_path / f"run_{kmax}"
        args = ["run", str(edited), str(scen / "detections.csv"), "--out", str(out)]
        assert main([*args, "--no-timings", "--no-progress"]) == 0
        results[kmax] = (
            [json.loads(line) for line in (out / "windows.jsonl").read_text().splitlines()],
            (out / "tracks.csv").read_text(),
        )
    (ample, ample_tracks), (huge, huge_tracks) = results[AMPLE], results[BILLION]
    assert huge_tracks == ample_tracks
    for a, b in zip(huge, ample, strict=True):
        assert a["p_k_length"] == BILLION + 1
        assert len(a["p_k"]) < 300
        n = max(len(a["p_k"]), len(b["p_k"]))
        np.testing.assert_allclose(
            np.pad(a["p_k"], (0, n - len(a["p_k"]))),
            np.pad(b["p_k"], (0, n - len(b["p_k"]))),
            rtol=0,
            atol=1e-12,
        )
