"""The forward-backward frontier search and the cluster messages
(``mapassoc.formulations.marginals``) against brute force."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.special import logsumexp
from support import random_problem

from mapassoc.formulations.convolution import sum_product
from mapassoc.formulations.frontier import frontier_search
from mapassoc.formulations.marginals import (
    ENUMERATION_MAX_HYPOTHESES,
    cluster_messages,
    enumerated_marginals,
    frontier_marginals,
    log_subtract,
)
from mapassoc.formulations.packing import PackingProblem

TOLERANCE = 1e-9


def brute_force(problem: PackingProblem, seed: np.ndarray) -> tuple[float, np.ndarray]:
    """log Z and log N_h by enumerating every subset of hypotheses."""
    kmax = seed.shape[0] - 1
    H = problem.num_hypotheses
    total: list[float] = []
    containing: list[list[float]] = [[] for _ in range(H)]
    for r in range(H + 1):
        for sel in itertools.combinations(range(H), r):
            chosen = np.array(sel, dtype=np.int64)
            if not problem.is_feasible(chosen):
                continue
            k = int(np.count_nonzero(problem.counts[chosen]))
            if k > kmax:
                continue
            value = float(np.sum(problem.log_weights[chosen])) + float(seed[k])  # type: ignore[index]
            total.append(value)
            for h in sel:
                containing[h].append(value)
    z = float(logsumexp(total)) if total else -math.inf
    n = np.array([float(logsumexp(c)) if c else -math.inf for c in containing])
    return z, n


def assert_log_close(a: np.ndarray, b: np.ndarray) -> None:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert np.array_equal(np.isneginf(a), np.isneginf(b)), (a, b)
    finite = np.isfinite(a)
    np.testing.assert_allclose(a[finite], b[finite], rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("trial", range(40))
def test_listed_subsets_give_the_frontier_searchs_sums(trial: int) -> None:
    """enumerated_marginals: the brute force's log Z and log N_h, and the forward-backward
    search's per-k masses, on problems with exactly-once resources, uncounted hypotheses,
    hypotheses without resources, seeds cut at kmax and seeds of -inf."""
    rng = np.random.default_rng(5000 + trial)
    H = int(rng.integers(1, ENUMERATION_MAX_HYPOTHESES + 1))
    problem = random_problem(rng, H, int(rng.integers(1, 6)), int(rng.integers(0, 3)))
    if trial % 4 == 0 and H < ENUMERATION_MAX_HYPOTHESES:  # plus one using no resource
        problem = PackingProblem(
            np.r_[problem.scores, rng.normal(0.0, 3.0)],
            np.r_[problem.resource_indptr, problem.resource_indptr[-1]],
            problem.resource_indices,
            problem.exactly_one,
            np.r_[problem.counts, trial % 8 == 0],
        )
        H += 1
    kmax = int(rng.integers(0, 5))
    seeds = rng.normal(0.0, 2.0, size=(3, kmax + 1))
    seeds[1, rng.integers(0, kmax + 1)] = -math.inf
    seeds[2] = -math.inf  # no count allowed: every sum is empty
    listed = enumerated_marginals(problem, seeds)
    searched = frontier_marginals(problem, seeds)
    assert listed.exact and listed.work == 2**H
    assert_log_close(listed.log_mass, searched.log_mass)
    for s in range(3):
        z, n = brute_force(problem, seeds[s])
        assert_log_close(np.array([listed.log_total[s]]), np.array([z]))
        assert_log_close(listed.log_containing[s], n)
    assert np.all(np.isneginf(listed.log_containing[2]))


def test_listing_subsets_refuses_a_large_problem() -> None:
    rng = np.random.default_rng(0)
    problem = random_problem(rng, ENUMERATION_MAX_HYPOTHESES + 1, 4, 1)
    with pytest.raises(ValueError, match="at most"):
        enumerated_marginals(problem, np.zeros(3))
    with pytest.raises(ValueError, match="seeds"):
        enumerated_marginals(random_problem(rng, 3, 2, 0), np.array([math.nan]))


@pytest.mark.parametrize("trial", range(60))
def test_frontier_marginals_equal_enumeration(trial: int) -> None:
    rng = np.random.default_rng(1000 + trial)
    problem = random_problem(
        rng, int(rng.integers(1, 13)), int(rng.integers(1, 6)), int(rng.integers(0, 3))
    )
    if trial % 3 == 0:  # merged-style log-weights that differ from the scores
        problem = PackingProblem(
            problem.scores,
            problem.resource_indptr,
            problem.resource_indices,
            problem.exactly_one,
            problem.counts,
            log_weights=problem.scores + rng.uniform(0.0, 2.0, size=problem.num_hypotheses),
        )
    kmax = int(rng.integers(0, 6))
    seeds = rng.normal(0.0, 2.0, size=(2, kmax + 1))
    seeds[1, rng.integers(0, kmax + 1)] = -math.inf  # a count the rest cannot take
    found = frontier_marginals(problem, seeds)
    assert found.exact
    for s in range(2):
        z, n = brute_force(problem, seeds[s])
        assert_log_close(np.array([found.log_total[s]]), np.array([z]))
        assert_log_close(found.log_containing[s], n)
    # The per-k masses are the frontier search's.
    reference = frontier_search(problem, kmax)
    assert_log_close(found.log_mass[: reference.log_mass.shape[0]], reference.log_mass)


def test_hypotheses_without_resources_are_free() -> None:
    """Two lone hypotheses (no resource) and one that conflicts with nothing either."""
    problem = PackingProblem(
        scores=np.array([0.5, -1.0, 2.0]),
        resource_indptr=np.array([0, 0, 0, 1]),
        resource_indices=np.array([0]),
        exactly_one=np.array([False]),
        counts=np.array([True, False, True]),
    )
    seed = np.array([0.0, -0.3, 0.7])
    found = frontier_marginals(problem, seed)
    z, n = brute_force(problem, seed)
    assert_log_close(found.log_total, np.array([z]))
    assert_log_close(found.log_containing[0], n)


def test_vectorised_sizes_agree_with_leaving_each_hypothesis_out() -> None:
    """On problems too large to enumerate (the numpy path, >= 40 hypotheses), the mass
    of the sets holding h is the total minus the mass of the problem without h, both
    from the plain frontier search."""
    rng = np.random.default_rng(7)
    for _ in range(3):
        problem = random_problem(rng, 60, 25, 4)
        kmax = 8
        seed = rng.normal(0.0, 1.0, size=kmax + 1)
        found = frontier_marginals(problem, seed)

        def total(p: PackingProblem, seed: np.ndarray = seed) -> float:
            mass = frontier_search(p, seed.shape[0] - 1).log_mass
            return float(logsumexp(mass + seed[: mass.shape[0]]))

        z = total(problem)
        assert abs(found.log_total[0] - z) <= TOLERANCE
        for h in range(problem.num_hypotheses):
            rest = np.delete(np.arange(problem.num_hypotheses), h)
            without = total(problem.subproblem(rest))
            # Resources only h used vanish from the subproblem: an exactly-once one makes
            # every set hold h.
            expected = log_subtract(np.array(z), np.array(min(without, z)))
            if np.isfinite(expected) and expected > z - 20.0:  # no cancellation
                assert abs(found.log_containing[0, h] - expected) <= 1e-7, h


def test_hypotheses_spanning_more_than_64_resources() -> None:
    """One hypothesis uses all 70 resources (frontiers wider than a machine word): the
    sets are any subset of the 70 singletons, or the big one alone."""
    n = 70
    rng = np.random.default_rng(3)
    w = rng.normal(0.0, 1.0, size=n + 1)
    indptr = np.r_[np.arange(n + 1), 2 * n].astype(np.int64)
    indices = np.r_[np.arange(n), np.arange(n)].astype(np.int64)
    problem = PackingProblem(w, indptr, indices, np.zeros(n, dtype=bool), np.zeros(n + 1, bool))
    found = frontier_marginals(problem, np.zeros(1))
    free = np.logaddexp(0.0, w[:n])
    z = np.logaddexp(np.sum(free), w[n])
    assert abs(found.log_total[0] - z) <= TOLERANCE
    expected = np.r_[w[:n] + np.sum(free) - free, w[n]]
    np.testing.assert_allclose(found.log_containing[0], expected, rtol=0, atol=TOLERANCE)


def test_beam_sums_a_subset() -> None:
    """With a beam, every sum is over the sets kept: at most the exact one, and the
    captured total is the captured per-k masses weighted by the seed."""
    rng = np.random.default_rng(11)
    problem = random_problem(rng, 60, 20, 3)
    seed = rng.normal(0.0, 1.0, size=7)
    exact = frontier_marginals(problem, seed)
    beam = frontier_marginals(problem, seed, max_frontiers=2, entry_margin=5.0)
    assert not beam.exact
    assert beam.log_total[0] < exact.log_total[0]
    assert np.all(beam.log_containing <= exact.log_containing + 1e-12)
    assert np.all(beam.log_containing <= beam.log_total[:, None] + 1e-12)
    width = beam.log_mass.shape[0]
    assert abs(beam.log_total[0] - logsumexp(beam.log_mass + seed[:width])) <= TOLERANCE


@pytest.mark.parametrize("trial", range(10))
def test_cluster_messages_equal_direct_convolution(trial: int) -> None:
    rng = np.random.default_rng(trial)
    tables = []
    for _ in range(int(rng.integers(1, 6))):
        table = rng.normal(0.0, 2.0, size=int(rng.integers(1, 5)))
        table[rng.random(table.shape[0]) < 0.2] = -math.inf
        tables.append(table)
    L = int(rng.integers(1, 12))
    log_w = rng.normal(0.0, 1.0, size=L)
    messages, total = cluster_messages(tables, log_w)
    everything = np.r_[0.0, np.full(L - 1, -math.inf)]
    for t in tables:
        everything = sum_product(everything, t, L)
    reached = np.any(np.isfinite(everything + log_w))
    direct_total = float(logsumexp(everything + log_w)) if reached else -math.inf
    assert (total == direct_total == -math.inf) or abs(total - direct_total) <= TOLERANCE
    for c, table in enumerate(tables):
        rest = np.r_[0.0, np.full(L - 1, -math.inf)]
        for j, t in enumerate(tables):
            if j != c:
                rest = sum_product(rest, t, L)
        for k in range(table.shape[0]):
            terms = [log_w[T] + rest[T - k] for T in range(k, L)]
            expected = float(logsumexp(terms)) if terms else -math.inf
            got = messages[c][k]
            assert (got == expected == -math.inf) or abs(got - expected) <= TOLERANCE


def test_log_subtract_refuses_a_negative_difference() -> None:
    np.testing.assert_allclose(log_subtract(np.log(3.0), np.log(1.0)), np.log(2.0))
    assert log_subtract(np.array(1.0), np.array(1.0)) == -math.inf
    with pytest.raises(ValueError):
        log_subtract(np.array(0.0), np.array(1.0))


def test_the_projection_stops_marginals_only_early_and_changes_no_result() -> None:
    """As for the frontier search: with a projection the marginals are exactly those
    without one, or the pass stops ("projected") before its limit."""
    from mapassoc.formulations.frontier import SearchLimitExceeded

    stopped = finished = 0
    for index in range(30):
        rng = np.random.default_rng(4100 + index)
        problem = random_problem(rng, int(rng.integers(40, 90)), D=int(rng.integers(10, 25)), G=0)
        seed = np.zeros(1)
        plain = frontier_marginals(problem, seed)
        for limit in (max(1, plain.work // 8), plain.work, 2 * plain.work):
            try:
                found = frontier_marginals(problem, seed, work_limit=limit, work_projection=2.0)
            except SearchLimitExceeded as stop:
                if stop.reason == "projected":
                    assert stop.work <= limit
                    stopped += 1
                continue
            finished += 1
            np.testing.assert_array_equal(found.log_containing, plain.log_containing)
            np.testing.assert_array_equal(found.log_total, plain.log_total)
    assert stopped >= 10 and finished >= 15
    with pytest.raises(ValueError, match="work_projection"):
        frontier_marginals(problem, seed, work_projection=2.0)


def _wide_problem(rng: np.random.Generator) -> PackingProblem:
    """Random hypotheses of one to three resources, and a few using 70 (spans of 64
    positions or more in any order)."""
    H, R = int(rng.integers(20, 50)), int(rng.integers(80, 120))
    rows = [rng.choice(R, size=int(rng.integers(1, 4)), replace=False) for _ in range(H)]
    for h in rng.choice(H, size=3, replace=False):
        rows[h] = np.union1d(rows[h], rng.choice(R, size=70, replace=False))
    w = rng.normal(0.0, 3.0, size=H)
    return PackingProblem(
        w,
        np.r_[0, np.cumsum([len(r) for r in rows])].astype(np.int64),
        np.concatenate(rows).astype(np.int64),
        rng.random(R) < 0.05,
        rng.random(H) < 0.7,
    )


@pytest.mark.parametrize("trial", range(8))
def test_a_beam_over_wide_hypotheses_sums_what_the_word_beam_sums(
    trial: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A beam over hypotheses spanning 64 positions or more keeps its frontiers as rows
    of covered positions: the same frontiers numbered, merged and ranked as with the
    span-wide integer words, so every sum is the same, to the bit; and a beam wide
    enough to keep every frontier is the exact search.  (The numpy pass: the compiled
    one takes these spans on rows of words, compared with it in
    ``test_compiled_frontier``.)"""
    from mapassoc.accelerate import COMPILED_SWITCH
    from mapassoc.formulations import marginals

    monkeypatch.setenv(COMPILED_SWITCH, "0")
    rng = np.random.default_rng(100 + trial)
    problem = _wide_problem(rng)
    seeds = np.stack([np.zeros(4), rng.normal(0.0, 1.0, size=4)])
    exact = frontier_marginals(problem, seeds)
    beams = [(1, None), (4, None), (16, 5.0), (4096, None)]
    rows = [frontier_marginals(problem, seeds, max_frontiers=f, entry_margin=m) for f, m in beams]
    monkeypatch.setattr(marginals, "_PositionRows", marginals._Words)
    words = [frontier_marginals(problem, seeds, max_frontiers=f, entry_margin=m) for f, m in beams]
    for a, b in zip(rows, words, strict=True):
        assert a.exact == b.exact and a.work == b.work
        for field in ("log_mass", "log_total", "log_containing"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field
    assert rows[-1].exact
    assert_log_close(rows[-1].log_total, exact.log_total)
    assert_log_close(rows[-1].log_containing, exact.log_containing)
    assert np.all(rows[0].log_containing <= exact.log_containing + 1e-9)
