"""gather_rows: CSR rows taken (repeats, empty rows) with an optional resource appended."""

from __future__ import annotations

import numpy as np
import pytest

from mapassoc.formulations.packing import gather_rows


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
