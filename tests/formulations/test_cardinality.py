"""Exact per-k tables of packing problems against brute-force subset enumeration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import brute_force_tables, random_problem

from mapassoc.formulations.cardinality import (
    SearchLimitExceeded,
    combine_tables,
    exact_cardinality_table,
)
from mapassoc.formulations.clusters import cluster_hypotheses
from mapassoc.formulations.packing import PackingProblem


@pytest.mark.parametrize("seed", range(60))
def test_exact_table_matches_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    H = int(rng.integers(1, 13))
    problem = random_problem(rng, H, D=int(rng.integers(1, 8)), G=int(rng.integers(0, 3)))
    kmax = int(rng.integers(1, 6))
    table = exact_cardinality_table(problem, kmax)
    best, mass = brute_force_tables(problem, kmax)
    np.testing.assert_allclose(table.best, best, rtol=0, atol=1e-9)
    np.testing.assert_allclose(table.log_mass, mass, rtol=0, atol=1e-9)
    for k in range(kmax + 1):
        s = table.best_sets[k]
        if math.isinf(best[k]):
            assert s is None
        else:
            sel = np.array(s, dtype=np.int64)
            assert problem.is_feasible(sel, k)
            assert problem.value(sel) == pytest.approx(best[k], abs=1e-9)


@pytest.mark.parametrize("seed", range(20))
def test_clusters_convolve_to_whole(seed: int) -> None:
    rng = np.random.default_rng(1000 + seed)
    problem = random_problem(rng, int(rng.integers(4, 14)), D=10, G=2)
    kmax = 6
    whole = exact_cardinality_table(problem, kmax)
    clusters = cluster_hypotheses(problem)
    assert sorted(np.concatenate(clusters).tolist()) == list(range(problem.num_hypotheses))
    tables = [
        exact_cardinality_table(problem.subproblem(c), kmax).remapped(c) for c in clusters
    ]
    combined = combine_tables(tables, kmax)
    np.testing.assert_allclose(combined.best, whole.best, atol=1e-9)
    np.testing.assert_allclose(combined.log_mass, whole.log_mass, atol=1e-9)
    assert combined.best_sets == whole.best_sets


def test_ties_go_to_lexicographically_smallest_set() -> None:
    # Two hypotheses compete for one detection with equal scores.
    problem = PackingProblem(
        np.array([1.5, 1.5]), np.array([0, 1, 2]), np.array([0, 0]), np.zeros(1, bool),
        np.ones(2, bool),
    )
    table = exact_cardinality_table(problem, 2)
    assert table.best_sets == ((), (0,), None)
    assert table.log_mass[1] == pytest.approx(math.log(2 * math.exp(1.5)))


def test_infeasible_k_gets_minus_infinity_and_group_forces_choice() -> None:
    # One carried track (group resource 1) with two hypotheses: ended (not counted) or
    # continued with detection 0 (counted); one new track also wants detection 0.
    problem = PackingProblem(
        scores=np.array([-1.0, 2.0, 0.5]),
        resource_indptr=np.array([0, 1, 3, 4]),
        resource_indices=np.array([1, 0, 1, 0]),
        exactly_one=np.array([False, True]),
        counts=np.array([False, True, True]),
    )
    table = exact_cardinality_table(problem, 3)
    # k=0: {ended} = -1; k=1: {continued}=2 or {ended, new}=-0.5; k>=2 impossible.
    np.testing.assert_allclose(table.best, [-1.0, 2.0, -math.inf, -math.inf])
    assert table.log_mass[1] == pytest.approx(np.logaddexp(2.0, -0.5))
    assert table.best_sets[1] == (1,)


def test_work_limit_raises() -> None:
    rng = np.random.default_rng(5)
    problem = random_problem(rng, 40, D=12, G=0)
    with pytest.raises(SearchLimitExceeded):
        exact_cardinality_table(problem, 10, work_limit=5)


@pytest.mark.parametrize("seed", range(20))
def test_independent_table_equals_the_convolution_of_single_tables(seed: int) -> None:
    from mapassoc.formulations.cardinality import independent_table, single_hypothesis_table

    rng = np.random.default_rng(2000 + seed)
    n = int(rng.integers(1, 30))
    scores = np.round(rng.normal(0.0, 3.0, size=n), 1)  # rounded: exact ties happen
    weights = scores + np.abs(rng.normal(0.0, 0.5, size=n))
    indices = np.sort(rng.choice(1000, size=n, replace=False))
    kmax = int(rng.integers(0, n + 3))
    singles = [
        single_hypothesis_table(float(s), float(w), True, False, 1).remapped(np.array([h]))
        for s, w, h in zip(scores, weights, indices, strict=True)
    ]
    expected = combine_tables(singles, kmax)
    got = combine_tables([independent_table(scores, weights, indices)], kmax)
    np.testing.assert_allclose(got.best, expected.best, atol=1e-9)
    np.testing.assert_allclose(got.log_mass, expected.log_mass, atol=1e-9)
    for k in range(kmax + 1):
        chosen = got.best_set(k)
        if chosen is None:
            assert expected.best_set(k) is None
            continue
        assert len(chosen) == k
        assert sum(float(scores[np.searchsorted(indices, h)]) for h in chosen) == pytest.approx(
            got.best[k]
        )
    # Ties go to the smaller indices: with equal scores the first k indices are chosen.
    flat = independent_table(np.zeros(5), np.zeros(5), np.array([9, 3, 7, 1, 5]))
    assert flat.best_set(2) == (1, 3)


@pytest.mark.parametrize("seed", range(40))
def test_vectorised_and_dictionary_searches_agree(seed: int) -> None:
    """Problems of 40+ hypotheses take the vectorised search; the dictionary search is
    the general path.  Same values, and every best set is feasible with its score; the
    same holds for their beams (lower bounds, exact only if nothing was dropped)."""
    from mapassoc.formulations.frontier import (
        _dictionary_search,
        _vectorised_search,
        frontier_search,
        resource_order,
    )

    rng = np.random.default_rng(3000 + seed)
    problem = random_problem(
        rng, int(rng.integers(40, 70)), D=int(rng.integers(15, 40)), G=int(rng.integers(0, 4))
    )
    kmax = int(rng.integers(0, 12))
    order = resource_order(problem)
    vectorised = frontier_search(problem, kmax)
    kmax = vectorised.best.shape[0] - 1  # frontier_search caps kmax at the counted ones
    assert _vectorised_search(problem, kmax, order, None, None) is not None
    dictionary = _dictionary_search(problem, kmax, order, None, None, None, None)
    assert dictionary.exact and vectorised.exact
    for width, margin in ((1, None), (4, 5.0), (10**9, None)):
        beam = _vectorised_search(problem, kmax, order, None, None, width, margin)
        assert beam is not None
        assert beam.exact or width < 10**9
        assert np.all(beam.log_mass <= dictionary.log_mass + 1e-9)
        assert np.all(beam.best <= dictionary.best + 1e-9)
        if beam.exact:
            np.testing.assert_allclose(beam.log_mass, dictionary.log_mass, atol=1e-9)
        for k, chosen in enumerate(beam.best_sets):
            if chosen is not None:
                selection = np.array(chosen, dtype=np.int64)
                assert problem.is_feasible(selection, k)
                assert problem.value(selection) == pytest.approx(beam.best[k], abs=1e-9)
    np.testing.assert_allclose(vectorised.best, dictionary.best, atol=1e-9)
    np.testing.assert_allclose(vectorised.log_mass, dictionary.log_mass, atol=1e-9)
    for k, chosen in enumerate(vectorised.best_sets):
        if chosen is None:
            assert vectorised.best[k] == -math.inf
            continue
        selection = np.array(chosen, dtype=np.int64)
        assert problem.is_feasible(selection, k)
        assert problem.value(selection) == pytest.approx(vectorised.best[k], abs=1e-9)


@pytest.mark.parametrize("seed", range(30))
def test_hypotheses_without_resources_are_added_exactly(seed: int) -> None:
    """Lone hypotheses (no resource; counted or not) are taken or left freely."""
    rng = np.random.default_rng(4000 + seed)
    base = random_problem(rng, int(rng.integers(0, 8)) or 1, D=int(rng.integers(1, 5)), G=1)
    extra = int(rng.integers(1, 5))
    scores = np.r_[base.scores, np.round(rng.normal(0.0, 2.0, size=extra), 1)]
    counts = np.r_[base.counts, rng.random(extra) < 0.7]
    indptr = np.r_[base.resource_indptr, np.full(extra, base.resource_indptr[-1])]
    problem = PackingProblem(scores, indptr, base.resource_indices, base.exactly_one, counts)
    kmax = int(rng.integers(0, problem.num_hypotheses + 1))
    best, mass = brute_force_tables(problem, kmax)
    table = exact_cardinality_table(problem, kmax)
    np.testing.assert_allclose(table.best, best, atol=1e-9)
    np.testing.assert_allclose(table.log_mass, mass, atol=1e-9)
    for k, chosen in enumerate(table.best_sets):
        if chosen is not None:
            selection = np.array(chosen, dtype=np.int64)
            assert problem.is_feasible(selection, k)
            assert problem.value(selection) == pytest.approx(best[k], abs=1e-9)


@pytest.mark.parametrize("seed", range(40))
def test_merge_interchangeable_groups_by_resources_and_count(seed: int) -> None:
    """Against the definition: hypotheses with the same resource set and count flag form
    one class (classes in order of their first member), represented by the best score
    (ties: smallest index), weighted by the log-sum-exp of the class."""
    from mapassoc.formulations.packing import merge_interchangeable

    rng = np.random.default_rng(5000 + seed)
    problem = random_problem(
        rng, int(rng.integers(1, 40)), D=int(rng.integers(1, 6)), G=int(rng.integers(0, 3))
    )
    groups: dict[tuple[bool, tuple[int, ...]], list[int]] = {}
    for h in range(problem.num_hypotheses):
        key = (bool(problem.counts[h]), tuple(sorted(problem.resources_of(h).tolist())))
        groups.setdefault(key, []).append(h)
    classes = sorted(groups.values(), key=lambda g: g[0])
    merged = merge_interchangeable(problem)
    assert [m.tolist() for m in merged.members] == classes
    for i, members in enumerate(classes):
        best = min(members, key=lambda h: (-problem.scores[h], h))
        assert merged.representative[i] == best
        assert merged.problem.scores[i] == problem.scores[best]
        assert merged.problem.log_weights[i] == pytest.approx(  # type: ignore[index]
            np.logaddexp.reduce(problem.log_weights[members])  # type: ignore[index]
        )
        assert sorted(merged.problem.resources_of(i).tolist()) == sorted(
            problem.resources_of(best).tolist()
        )
    # Merging changes no table.
    whole = exact_cardinality_table(problem, 6)
    merged_table = exact_cardinality_table(merged.problem, 6)
    np.testing.assert_allclose(merged_table.best, whole.best, atol=1e-9)
    np.testing.assert_allclose(merged_table.log_mass, whole.log_mass, atol=1e-9)


# ----------------------------------------------------------- the projected work stop


def _searches() -> list[tuple[PackingProblem, int]]:
    from mapassoc.formulations.frontier import frontier_search

    found = []
    for seed in range(30):
        rng = np.random.default_rng(3100 + seed)
        problem = random_problem(rng, int(rng.integers(40, 90)), D=int(rng.integers(10, 25)), G=0)
        found.append((problem, frontier_search(problem, 12).work))
    return found


def test_the_projection_stops_only_early_and_changes_no_result() -> None:
    """With a projection, a search either returns exactly what it returns without one, or
    stops (reason "projected") before its limit; the stop is deterministic."""
    from mapassoc.formulations.frontier import frontier_search

    stopped = finished = 0
    for problem, work in _searches():
        plain = frontier_search(problem, 12)
        for limit in (work // 8, work // 3, work, 2 * work):
            limit = max(limit, 1)
            try:
                result = frontier_search(problem, 12, work_limit=limit, work_projection=2.0)
            except SearchLimitExceeded as stop:
                assert stop.reason in ("work", "projected")
                if stop.reason == "projected":
                    assert stop.work <= limit
                    stopped += 1
                with pytest.raises(SearchLimitExceeded) as again:
                    frontier_search(problem, 12, work_limit=limit, work_projection=2.0)
                assert (again.value.reason, again.value.work) == (stop.reason, stop.work)
                continue
            finished += 1
            assert work <= limit
            np.testing.assert_array_equal(result.best, plain.best)
            np.testing.assert_array_equal(result.log_mass, plain.log_mass)
            assert result.best_sets == plain.best_sets
    assert stopped >= 10 and finished >= 20  # both outcomes are exercised


def test_the_projection_stops_a_hopeless_search_before_its_limit() -> None:
    from mapassoc.formulations.frontier import frontier_search

    problem, work = max(_searches(), key=lambda pair: pair[1])
    limit = work // 20
    with pytest.raises(SearchLimitExceeded) as plain:
        frontier_search(problem, 12, work_limit=limit)
    with pytest.raises(SearchLimitExceeded) as projected:
        frontier_search(problem, 12, work_limit=limit, work_projection=1.5)
    assert plain.value.reason == "work" and projected.value.reason == "projected"
    assert projected.value.work < plain.value.work


def test_the_projection_needs_a_limit_and_a_factor_of_at_least_one() -> None:
    from mapassoc.formulations.frontier import frontier_search

    problem, _ = _searches()[0]
    for bad in ({"work_projection": 2.0}, {"work_projection": 0.5, "work_limit": 10}):
        with pytest.raises(ValueError, match="work_projection"):
            frontier_search(problem, 3, **bad)  # type: ignore[arg-type]
