"""Max-plus and sum-product convolution of per-k vectors (log space).

Independent parts of a packing problem combine this way: the best score with k counted
is the best split of k over the parts (max-plus), the log-mass the log of the sum over
splits of the product of masses (sum-product).  Entries are ``-inf`` where a part has no
set with that k.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["finite_length", "max_plus", "sum_product"]

_NEG_INF = -np.inf


def finite_length(values: NDArray[np.float64], size: int) -> int:
    """One past the last finite entry among the first ``size``."""
    finite = np.flatnonzero(np.isfinite(values[:size]))
    return int(finite[-1]) + 1 if finite.size else 0


def sum_product(
    acc: NDArray[np.float64], entries: NDArray[np.float64], size: int
) -> NDArray[np.float64]:
    """Log-space convolution of ``acc`` with ``entries``, truncated to ``size`` terms.

    One ``logaddexp`` pass per finite entry of the shorter operand.
    """
    out = np.full(size, _NEG_INF)
    a_len, e_len = finite_length(acc, size), finite_length(entries, size)
    short, long_ = (acc, entries) if a_len < e_len else (entries, acc)
    for j in range(min(a_len, e_len)):
        if np.isfinite(short[j]):
            n = min(long_.shape[0], size - j)
            window = out[j : j + n]
            np.logaddexp(window, long_[:n] + short[j], out=window)
    return out


def max_plus(
    acc: NDArray[np.float64], entries: NDArray[np.float64], size: int
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Max-plus convolution with the share of the second operand at each k (-1: none).

    Loops over the finite entries of the shorter operand; on exact ties the smaller
    share of ``entries`` wins.
    """
    out = np.full(size, _NEG_INF)
    pointer = np.full(size, -1, dtype=np.int64)
    a_len, e_len = finite_length(acc, size), finite_length(entries, size)
    shift_entries = e_len <= a_len
    # Shift the longer operand by each finite entry of the shorter one; when the shorter
    # is `acc`, go from its last entry down so that the share k - i of `entries` rises.
    base, offsets = (acc, range(e_len)) if shift_entries else (entries, reversed(range(a_len)))
    shorter = entries if shift_entries else acc
    ks = np.arange(size)
    for offset in offsets:
        if not np.isfinite(shorter[offset]):
            continue
        candidate = np.full(size, _NEG_INF)
        n = min(base.shape[0], size - offset)
        candidate[offset : offset + n] = base[:n] + shorter[offset]
        better = candidate > out
        out[better] = candidate[better]
        pointer[better] = offset if shift_entries else ks[better] - offset
    return out, pointer
