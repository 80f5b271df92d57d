"""gather_rows: CSR rows taken (repeats, empty rows) with an optional resource appended;
PackingProblem.derived: the transformations that skip the checks produce checked arrays."""

from __future__ import annotations

import numpy as np
import pytest
from support import random_problem

from mapassoc.formulations.bounds import relaxed_problem
from mapassoc.formulations.marginals import _with_private_resources
from mapassoc.formulations.packing import PackingProblem, gather_rows, merge_interchangeable


def _rows_by_loop(indptr, indices, rows, extra):  # type: ignore[no-untyped-def]
    out = []
    for j, r in enumerate(rows):
        row = indices[indptr[r] : indptr[r + 1]].tolist()
        if extra is not None and extra[j] >= 0:
            row.append(int(extra[j]))
        out.append(row)
    return out


@pytest.mark.parametrize("seed", range(20))
def test_gather_rows_matches_a_loop(seed: int) -> None:
    rng = np.random.default_rng(seed)
    lengths = rng.integers(0, 4, size=rng.integers(1, 12))
    indptr = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    indices = rng.integers(0, 50, size=int(indptr[-1])).astype(np.int64)
    rows = rng.integers(0, lengths.size, size=rng.integers(0, 15)).astype(np.int64)
    for extra in (None, np.where(rng.random(rows.size) < 0.5, rng.integers(50, 60, rows.size), -1)):
        ptr, got = gather_rows(indptr, indices, rows, extra)
        expected = _rows_by_loop(indptr, indices, rows, extra)
        assert ptr.tolist() == np.concatenate([[0], np.cumsum([len(r) for r in expected])]).tolist()
        assert got.tolist() == [v for row in expected for v in row]


def test_gather_rows_golden() -> None:
    indptr = np.array([0, 2, 2, 3])
    indices = np.array([4, 5, 6])
    ptr, got = gather_rows(indptr, indices, np.array([2, 0, 1, 0]), np.array([9, -1, 8, 7]))
    assert ptr.tolist() == [0, 2, 4, 5, 8]
    assert got.tolist() == [6, 9, 4, 5, 8, 4, 5, 7]


def _checked_again(problem: PackingProblem) -> PackingProblem:
    """The constructor's checks run on a derived problem's arrays (raises if one fails)."""
    return PackingProblem(
        scores=problem.scores,
        resource_indptr=problem.resource_indptr,
        resource_indices=problem.resource_indices,
        exactly_one=problem.exactly_one,
        counts=problem.counts,
        log_weights=problem.log_weights,
    )


@pytest.mark.parametrize("seed", range(15))
def test_derived_problems_pass_the_constructor_checks(seed: int) -> None:
    """PackingProblem.derived skips the checks: every transformation that uses it must
    produce arrays the checked constructor accepts, with the same dtypes."""
    rng = np.random.default_rng(seed)
    problem = random_problem(rng, int(rng.integers(1, 14)), 6, int(rng.integers(0, 3)))
    members = np.sort(
        rng.choice(
            problem.num_hypotheses, size=rng.integers(1, problem.num_hypotheses + 1), replace=False
        )
    )
    relaxed = ~problem.exactly_one & (rng.random(problem.num_resources) < 0.5)
    derived = [
        problem.subproblem(members),
        merge_interchangeable(problem).problem,
        _with_private_resources(problem),
        relaxed_problem(problem, relaxed, rng.random(problem.num_resources))[0],
    ]
    for out in derived:
        again = _checked_again(out)
        for name in ("scores", "resource_indptr", "resource_indices", "exactly_one", "counts"):
            assert getattr(out, name).dtype == getattr(again, name).dtype, name
            assert np.array_equal(getattr(out, name), getattr(again, name)), name
        assert out.weights.dtype == np.float64
        assert np.array_equal(out.weights, again.weights)


def test_uses_any_marks_the_hypotheses_of_the_marked_resources() -> None:
    # hypothesis 0 uses resources {0, 2}, 1 uses none, 2 uses {1}, 3 uses {2}
    problem = PackingProblem(
        scores=np.zeros(4),
        resource_indptr=np.array([0, 2, 2, 3, 4]),
        resource_indices=np.array([0, 2, 1, 2]),
        exactly_one=np.array([False, True, False]),
        counts=np.ones(4, dtype=bool),
    )
    assert problem.uses_any(problem.exactly_one).tolist() == [False, False, True, False]
    assert problem.uses_any(~problem.exactly_one).tolist() == [True, False, False, True]
    assert problem.uses_any(np.zeros(3, dtype=bool)).tolist() == [False] * 4
    with pytest.raises(ValueError, match="shape \\(3,\\)"):
        problem.uses_any(np.ones(2, dtype=bool))
