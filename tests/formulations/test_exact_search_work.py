"""The exact search's work, counted on the frontier words before the search.

* ``exact_search_work`` returns exactly the work the vectorised exact search charges:
  its whole work where it fits the limit, and the work at which it raises where not;
* a step's (frontier, hypothesis) pairs are found block by block, and a step that would
  pass the limit stops after the block that shows it (count and search alike);
* ``frontier_search`` and ``frontier_marginals`` (whose forward pass is the same search)
  on a large problem stops at once, with that work and reason
  ``"work"``, where the search would pass the limit, and otherwise gives the same tables
  as the search without any limit (no projection cuts a search that fits).
"""

from __future__ import annotations

import numpy as np
import pytest
from support import banded_problem

import mapassoc.formulations.frontier as frontier
from mapassoc.formulations.frontier import (
    WORK_COUNT_MIN_HYPOTHESES,
    SearchLimitExceeded,
    _vectorised_search,
    exact_search_work,
    frontier_search,
    open_pairs,
    resource_order,
)
from mapassoc.formulations.marginals import frontier_marginals


@pytest.mark.parametrize("seed", range(12))
def test_open_pairs_are_the_whole_list_or_a_longer_prefix(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    rng = np.random.default_rng(300 + seed)
    covers = rng.integers(0, 1 << 12, size=int(rng.integers(1, 60))).astype(np.uint64)
    covered = rng.random(covers.size) < 0.3
    relative = rng.integers(1, 1 << 12, size=40).astype(np.uint64)
    starting = np.sort(rng.choice(40, size=int(rng.integers(1, 12)), replace=False))
    open_rows = np.flatnonzero(~covered)
    rows, cols = np.nonzero((covers[open_rows, None] & relative[starting][None, :]) == 0)
    whole_rows, whole_h = open_rows[rows], starting[cols]
    monkeypatch.setattr(frontier, "PAIR_BLOCK_ENTRIES", int(rng.integers(1, 30)))
    for most in (None, -1, 0, 1, whole_h.size // 2, whole_h.size - 1, whole_h.size):
        found_rows, found_h = open_pairs(covers, covered, relative, starting, most)
        if most is None or most >= whole_h.size:
            np.testing.assert_array_equal(found_rows, whole_rows)
            np.testing.assert_array_equal(found_h, whole_h)
        elif most < 0:
            assert found_h.size == 0
        else:
            assert most < found_h.size <= whole_h.size
            np.testing.assert_array_equal(found_rows, whole_rows[: found_h.size])
            np.testing.assert_array_equal(found_h, whole_h[: found_h.size])


@pytest.mark.parametrize("block", [1 << 18, 3])
@pytest.mark.parametrize("seed", range(16))
def test_the_count_is_the_searchs_work(
    seed: int, block: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Small blocks: a step past the limit stops part-way, in the count and the search.
    monkeypatch.setattr(frontier, "PAIR_BLOCK_ENTRIES", block)
    rng = np.random.default_rng(seed)
    problem = banded_problem(rng, int(rng.integers(60, 200)), D=int(rng.integers(20, 60)), band=8)
    kmax = int(rng.integers(1, 30))
    order = resource_order(problem)
    whole = _vectorised_search(problem, kmax, order, None, None)
    assert whole is not None
    assert exact_search_work(problem, kmax, order, work_limit=10**12) == whole.work
    for limit in (whole.work // 3, whole.work - 1, whole.work):
        counted = exact_search_work(problem, kmax, order, work_limit=limit)
        if limit >= whole.work:
            assert counted == whole.work
            continue
        with pytest.raises(SearchLimitExceeded) as stop:
            _vectorised_search(problem, kmax, order, limit, None)
        assert counted == stop.value.work > limit


@pytest.mark.parametrize("seed", range(6))
def test_a_large_search_stops_at_once_or_runs_whole(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    problem = banded_problem(rng, WORK_COUNT_MIN_HYPOTHESES + 100, D=80, band=8)
    kmax = 25
    free = frontier_search(problem, kmax)
    # Too little work: stops before searching, with the count, whatever the projection.
    with pytest.raises(SearchLimitExceeded) as stop:
        frontier_search(problem, kmax, work_limit=free.work - 1, work_projection=1.0)
    assert stop.value.reason == "work"
    assert stop.value.work == exact_search_work(
        problem, kmax, resource_order(problem), work_limit=free.work - 1
    )
    # Just enough: runs whole even with the tightest projection (which alone would
    # stop a search whose steps grow).
    with pytest.raises(SearchLimitExceeded, match="projected"):
        _vectorised_search(
            problem, kmax, resource_order(problem), free.work, None, None, None, free.work
        )
    fits = frontier_search(problem, kmax, work_limit=free.work, work_projection=1.0)
    np.testing.assert_array_equal(fits.best, free.best)
    np.testing.assert_array_equal(fits.log_mass, free.log_mass)
    assert fits.best_sets == free.best_sets and fits.work == free.work


@pytest.mark.parametrize("seed", range(4))
def test_the_marginals_forward_pass_is_counted_the_same_way(seed: int) -> None:
    rng = np.random.default_rng(200 + seed)
    problem = banded_problem(rng, WORK_COUNT_MIN_HYPOTHESES + 60, D=70, band=8)
    seeds = np.zeros(16)  # k = 0..15, every set weighted alike
    free = frontier_marginals(problem, seeds)
    with pytest.raises(SearchLimitExceeded) as stop:
        frontier_marginals(problem, seeds, work_limit=free.work - 1, work_projection=1.0)
    assert stop.value.reason == "work" and stop.value.work > free.work - 1
    fits = frontier_marginals(problem, seeds, work_limit=free.work, work_projection=1.0)
    assert fits.work == free.work
    np.testing.assert_array_equal(fits.log_containing, free.log_containing)
    np.testing.assert_array_equal(fits.log_total, free.log_total)
