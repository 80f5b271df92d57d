"""The compiled exact frontier search (numba, optional) is the numpy search.

On random window-like problems, the kernel and the numpy path (``MAPASSOC_COMPILED=0``)
give bit-identical tables (best scores and log-masses), the same best sets, the same
work and the same widest frontier; where a work limit or a projection stops the numpy
search, the kernel stops with the same reason and the same work; an exactly-once
resource that no set can meet gives the same infeasible result.  The compiled
forward-backward marginals are the numpy pass's (per-k masses bit for bit, the
per-hypothesis sums to round-off).  Hypotheses spanning 64 positions or more run in
the marginals kernel too, on frontiers of several words that order as the integers they
spell.
"""

from __future__ import annotations

import numpy as np
import pytest
from support import banded_problem

from mapassoc.accelerate import COMPILED_SWITCH
from mapassoc.formulations.frontier import (
    FrontierResult,
    SearchLimitExceeded,
    _vectorised_search,
    resource_order,
)
from mapassoc.formulations.marginals import FrontierMarginals, frontier_marginals
from mapassoc.formulations.packing import PackingProblem

pytest.importorskip("numba")


def _both(
    monkeypatch: pytest.MonkeyPatch,
    problem: PackingProblem,
    kmax: int,
    work_limit: int | None,
    projected_limit: float | None = None,
) -> list[FrontierResult | SearchLimitExceeded]:
    order = resource_order(problem)
    found: list[FrontierResult | SearchLimitExceeded] = []
    for switch in ("1", "0"):
        monkeypatch.setenv(COMPILED_SWITCH, switch)
        try:
            result = _vectorised_search(
                problem, kmax, order, work_limit, None, None, None, projected_limit
            )
            assert result is not None
            found.append(result)
        except SearchLimitExceeded as stop:
            found.append(stop)
    return found


def _assert_same(fast: FrontierResult, plain: FrontierResult) -> None:
    np.testing.assert_array_equal(fast.best, plain.best)
    np.testing.assert_array_equal(fast.log_mass, plain.log_mass)
    assert fast.best_sets == plain.best_sets
    assert (fast.work, fast.max_frontiers, fast.exact) == (
        plain.work,
        plain.max_frontiers,
        plain.exact,
    )


@pytest.mark.parametrize("seed", range(40))
def test_the_kernel_is_the_numpy_search(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(seed)
    problem = banded_problem(
        rng,
        int(rng.integers(40, 260)),
        D=int(rng.integers(20, 70)),
        band=int(rng.integers(3, 10)),
    )
    kmax = int(rng.integers(0, 30))
    fast, plain = _both(monkeypatch, problem, kmax, None)
    assert isinstance(fast, FrontierResult) and isinstance(plain, FrontierResult)
    _assert_same(fast, plain)
    # Stopped by a work limit (at the same work) or by a projection, or not.
    for limit, projection in ((fast.work // 4, None), (fast.work - 1, None), (fast.work, 1.0)):
        projected = None if projection is None else projection * limit
        fast_stop, plain_stop = _both(monkeypatch, problem, kmax, limit, projected)
        assert type(fast_stop) is type(plain_stop)
        if isinstance(fast_stop, SearchLimitExceeded):
            assert isinstance(plain_stop, SearchLimitExceeded)
            assert (fast_stop.reason, fast_stop.work) == (plain_stop.reason, plain_stop.work)
            assert str(fast_stop) == str(plain_stop)
        else:
            assert isinstance(fast_stop, FrontierResult)
            assert isinstance(plain_stop, FrontierResult)
            _assert_same(fast_stop, plain_stop)


def test_an_exactly_once_resource_no_set_meets_is_infeasible_on_both(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Two exactly-once resources, each used only by hypotheses that also use a shared
    # detection: no set holds both.
    rng = np.random.default_rng(7)
    base = banded_problem(rng, 60, D=30, band=6)
    lists = [
        base.resource_indices[base.resource_indptr[h] : base.resource_indptr[h + 1]].tolist()
        for h in range(base.num_hypotheses)
    ]
    R = base.exactly_one.size
    lists += [[0, R], [0, R + 1]]
    indptr = np.concatenate([[0], np.cumsum([len(r) for r in lists])])
    problem = PackingProblem(
        np.r_[base.scores, 1.0, 1.0],
        indptr,
        np.concatenate([np.asarray(r, dtype=np.int64) for r in lists]),
        np.r_[base.exactly_one, True, True],
        np.r_[base.counts, True, True],
    )
    fast, plain = _both(monkeypatch, problem, 10, None)
    assert isinstance(fast, FrontierResult) and isinstance(plain, FrontierResult)
    assert np.all(np.isneginf(fast.best)) and fast.best_sets == (None,) * 11
    _assert_same(fast, plain)


@pytest.mark.parametrize("size", [0, 1, 5, 31, 32, 33, 500, 4000])
def test_the_kernels_stable_order_is_numpys(size: int) -> None:
    """The kernel's argsort (insertion sort below 32 keys, radix passes by byte above)
    is ``np.argsort(kind="stable")``: keys over the whole 64 bits, keys differing in one
    high byte only, and many ties."""
    from mapassoc.formulations.compiled_frontier import _stable_order

    rng = np.random.default_rng(size)
    full = rng.integers(0, 2**63, size=size, dtype=np.uint64) * np.uint64(2)
    one_byte = np.uint64(7) | (rng.integers(0, 4, size=size).astype(np.uint64) << np.uint64(56))
    ties = rng.integers(0, 3, size=size).astype(np.uint64)
    for keys in (full, one_byte, ties):
        np.testing.assert_array_equal(_stable_order(keys), np.argsort(keys, kind="stable"))


def _marginals_both(
    monkeypatch: pytest.MonkeyPatch, problem: PackingProblem, seeds: np.ndarray, **options: object
) -> list[FrontierMarginals | tuple[str, int, str]]:
    found: list[FrontierMarginals | tuple[str, int, str]] = []
    for switch in ("1", "0"):
        monkeypatch.setenv(COMPILED_SWITCH, switch)
        try:
            found.append(frontier_marginals(problem, seeds, **options))  # type: ignore[arg-type]
        except SearchLimitExceeded as stop:
            found.append((stop.reason, stop.work, str(stop)))
    return found

def _assert_both_agree(
    monkeypatch: pytest.MonkeyPatch,
    problem: PackingProblem,
    seeds: np.ndarray,
    runs: list[dict[str, object]],
) -> None:
    """The compiled and the numpy marginals under each run's options: the same stop, or
    the same per-k masses bit for bit, ``exact`` and work, and log N_h and log Z to
    round-off (the same -inf entries)."""
    for options in runs:
        fast, plain = _marginals_both(monkeypatch, problem, seeds, **options)
        if not isinstance(plain, FrontierMarginals):
            assert fast == plain
            continue
        assert isinstance(fast, FrontierMarginals)
        assert (fast.exact, fast.work) == (plain.exact, plain.work)
        np.testing.assert_array_equal(fast.log_mass, plain.log_mass)
        for a, b in (
            (fast.log_total, plain.log_total),
            (fast.log_containing, plain.log_containing),
        ):
            assert np.array_equal(np.isneginf(a), np.isneginf(b))
            finite = np.isfinite(a)
            np.testing.assert_allclose(a[finite], b[finite], rtol=0, atol=1e-12)



@pytest.mark.parametrize("seed", range(30))
def test_the_marginals_kernel_is_the_numpy_forward_backward(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Exact, with a beam and an entry margin, and stopped by a work limit or its
    projection: the same per-k masses bit for bit (the forward pass takes the same
    steps), ``exact`` and work, the same stops, and log N_h and log Z equal to round-off
    (the backward sums of exponentials run in another order)."""
    rng = np.random.default_rng(300 + seed)
    problem = banded_problem(
        rng, int(rng.integers(20, 200)), D=int(rng.integers(10, 50)), band=int(rng.integers(3, 9))
    )
    kmax = int(rng.integers(0, 8))
    seeds = rng.normal(0.0, 2.0, size=(2, kmax + 1))
    seeds[1, rng.integers(0, kmax + 1)] = -np.inf
    whole, _ = _marginals_both(monkeypatch, problem, seeds)
    assert isinstance(whole, FrontierMarginals)
    runs: list[dict[str, object]] = [
        {},
        {"max_frontiers": int(rng.integers(1, 20)), "entry_margin": float(rng.uniform(1, 10))},
        {"max_frontiers": 3},
        {"work_limit": max(1, whole.work // 2), "work_projection": 1.0},
        {"work_limit": whole.work - 1},
    ]
    _assert_both_agree(monkeypatch, problem, seeds, runs)


@pytest.mark.parametrize("work_limit", [2**62, 2**63 - 1, 2**64])
def test_a_huge_work_limit_is_no_limit(monkeypatch: pytest.MonkeyPatch, work_limit: int) -> None:
    """A work limit near or past int64's range (the kernels count in int64) searches as
    no limit does: (limit - work) x entries per transition once overflowed into a
    negative pair budget, so no pair was opened and the window came out infeasible."""
    problem = banded_problem(np.random.default_rng(3), 120, 40, 5)
    monkeypatch.setenv(COMPILED_SWITCH, "1")
    order = resource_order(problem)
    unlimited = _vectorised_search(problem, 6, order, None, None, None, None, None)
    huge = _vectorised_search(problem, 6, order, work_limit, None, None, None, None)
    assert unlimited is not None and huge is not None
    assert np.isfinite(unlimited.log_mass).any()
    np.testing.assert_array_equal(huge.best, unlimited.best)
    np.testing.assert_array_equal(huge.log_mass, unlimited.log_mass)
    assert huge.best_sets == unlimited.best_sets and huge.work == unlimited.work
    seeds = np.zeros(7)
    free = frontier_marginals(problem, seeds)
    limited = frontier_marginals(problem, seeds, work_limit=work_limit)
    np.testing.assert_array_equal(limited.log_containing, free.log_containing)
    np.testing.assert_array_equal(limited.log_total, free.log_total)


def _wide_problem(rng: np.random.Generator, span: int) -> PackingProblem:
    """Hypotheses of one to three resources, and a few using ``span + 1`` resources, so
    that they span ``span`` positions or more in any resource order (a frontier of
    several words)."""
    H, R = int(rng.integers(20, 50)), span + int(rng.integers(10, 40))
    rows = [rng.choice(R, size=int(rng.integers(1, 4)), replace=False) for _ in range(H)]
    for h in rng.choice(H, size=int(rng.integers(1, 4)), replace=False):
        rows[h] = np.sort(rng.choice(R, size=span + 1, replace=False))
    return PackingProblem(
        rng.normal(0.0, 3.0, size=H),
        np.r_[0, np.cumsum([len(r) for r in rows])].astype(np.int64),
        np.concatenate(rows).astype(np.int64),
        rng.random(R) < 0.05,
        rng.random(H) < 0.7,
    )


@pytest.mark.parametrize("span", [64, 65, 128, 129, 300])
@pytest.mark.parametrize("seed", range(6))
def test_the_marginals_kernel_takes_hypotheses_spanning_64_positions_or_more(
    seed: int, span: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Frontiers of several words (the sizes the kernel once refused, numpy running them
    on Python integers or, for a beam, position rows): the same per-k masses bit for bit,
    ``exact``, work and stops, and log N_h and log Z to round-off, exact or with a beam."""
    from mapassoc.formulations.marginals import _word_rows

    rng = np.random.default_rng(700 + 10 * seed + span)
    problem = _wide_problem(rng, span)
    kmax = int(rng.integers(0, 6))
    seeds = rng.normal(0.0, 2.0, size=(2, kmax + 1))
    layout = _word_rows(problem, resource_order(problem))
    assert layout is not None and layout[0].shape[1] > 1  # several words a frontier
    whole, _ = _marginals_both(monkeypatch, problem, seeds)
    assert isinstance(whole, FrontierMarginals)
    runs: list[dict[str, object]] = [
        {},
        {"max_frontiers": 32, "entry_margin": 40.0},
        {"max_frontiers": int(rng.integers(1, 8))},
        {"max_frontiers": 4096},
        {"work_limit": max(1, whole.work // 2), "work_projection": 1.0},
        {"work_limit": whole.work - 1},
    ]
    _assert_both_agree(monkeypatch, problem, seeds, runs)


@pytest.mark.parametrize("size", [0, 1, 5, 31, 32, 33, 500, 4000])
def test_the_kernels_row_order_is_the_integers_order(size: int) -> None:
    """Rows of words sort (stably) as the integers they spell, last word most significant."""
    from mapassoc.formulations.compiled_frontier import _stable_row_order

    rng = np.random.default_rng(size)
    keys = rng.integers(0, 4, size=(size, 3)).astype(np.uint64)
    keys[:, 0] |= rng.integers(0, 2**63, size=size).astype(np.uint64) << np.uint64(1)
    as_int = [int(k[0]) | int(k[1]) << 64 | int(k[2]) << 128 for k in keys]
    np.testing.assert_array_equal(
        _stable_row_order(keys), np.argsort(np.array(as_int, dtype=object), kind="stable")
    )
