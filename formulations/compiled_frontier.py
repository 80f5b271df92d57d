"""Numba kernels of the exact vectorised frontier search and of the forward-backward
marginals (optional accelerator).

Imported only through :func:`mapassoc.accelerate.compiled_module` (numba is the
``accelerate`` extra).  :func:`exact_search` takes the steps of
:func:`mapassoc.formulations.frontier._vectorised_search` without a beam: the same
frontier words, the same candidate rows in the same order (frontiers kept first, then
(frontier, hypothesis) pairs row by row), the same stable sort by the next word, masses
summed by ``logaddexp`` in the same order and best scores taken by the first candidate
reaching the maximum, so the tables and best sets are the numpy search's.  Work is
charged as there, with the open pairs found in the same blocks, so a search stops at
the same work; it also stops on the same projection.  The kernel does not raise: it
returns a status the caller turns into the search's exception.

A small search costs microseconds here instead of numpy's thousand array calls.
:func:`forward_backward` is :func:`mapassoc.formulations.marginals.frontier_marginals`'s
pass in the same way (its own docstring says what is the same).  Its frontiers are rows
of several words (:func:`_row_step`, :func:`_row_candidates`), so that it takes
hypotheses spanning 64 positions or more as well (the beam over a window's burst of
clutter, which the numpy pass ran on position rows); the exact search keeps one word a
frontier (:func:`_step`, :func:`_candidates`), as the numpy search it follows does.
The marginals carry and sum their k-entries through :func:`_carried` and :func:`_summed`
(the exact search fuses the same loops with its best scores).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray, IntArray

FOUND, PAST_WORK_LIMIT, PAST_PROJECTION, INFEASIBLE = 0, 1, 2, 3
"""Statuses of :func:`exact_search` and :func:`forward_backward`."""

_INT64_MAX = 2**63 - 1
"""The largest work the kernels count (their integers are int64): callers clamp work
limits to it (:func:`mapassoc.formulations.frontier.kernel_work_limit`)."""


@njit(cache=True)
def _log_add(a: float, b: float) -> float:
    """``np.logaddexp(a, b)``, as numpy computes it."""
    if a == b:
        return a + math.log(2.0)
    tmp = a - b
    if tmp > 0:
        return a + math.log1p(math.exp(-tmp))
    if tmp <= 0:
        return b + math.log1p(math.exp(tmp))
    return tmp  # NaN


_INSERTION_SORT_BELOW = 32
"""Fewer keys than this are ordered by insertion sort (radix passes cost more there)."""


@njit(cache=True)
def _stable_order(keys: NDArray[np.uint64]) -> IntArray:
    """``np.argsort(keys, kind="stable")``: insertion sort for a few keys, else a
    least-significant-digit radix sort by bytes (each pass stable, so the whole is; bytes
    on which all keys agree are skipped).  numba's own sorts cost seconds to compile,
    and a merge sort made large searches slower than these passes."""
    n = keys.shape[0]
    order = np.arange(n)
    if n < _INSERTION_SORT_BELOW:
        for i in range(1, n):
            moving = order[i]
            key = keys[moving]
            j = i - 1
            while j >= 0 and keys[order[j]] > key:  # ties keep their order
                order[j + 1] = order[j]
                j -= 1
            order[j + 1] = moving
        return order
    ones = np.uint64(0)
    zeros = ~np.uint64(0)
    for i in range(n):
        ones |= keys[i]
        zeros &= keys[i]
    varying = ones ^ zeros
    spare = np.empty(n, dtype=np.int64)
    starts = np.empty(257, dtype=np.int64)
    byte = np.uint64(0xFF)
    for pass_ in range(8):
        shift = np.uint64(8 * pass_)
        if (varying >> shift) & byte == np.uint64(0):
            continue
        starts[:] = 0
        for i in range(n):
            starts[np.int64((keys[order[i]] >> shift) & byte) + 1] += 1
        for d in range(256):
            starts[d + 1] += starts[d]
        for i in range(n):
            digit = np.int64((keys[order[i]] >> shift) & byte)
            spare[starts[digit]] = order[i]
            starts[digit] += 1
        order, spare = spare, order
    return order


@njit(cache=True)
def _step_pairs(
    covers: NDArray[np.uint64],
    relative: NDArray[np.uint64],
    by_start: IntArray,
    first: int,
    n_start: int,
    exactly_once: bool,
    work_limit: int,
    work: int,
    span_now: int,
    entries_per_transition: int,
    pair_block_entries: int,
) -> tuple[IntArray, int, IntArray, IntArray, int]:
    """One step's candidate rows before any k-entry: the frontiers kept (all, or those
    covering an exactly-once position), then the open (frontier, hypothesis) pairs found
    block by block of open frontiers as
    :func:`~mapassoc.formulations.frontier.open_pairs` finds them, stopping after the
    block that passes what ``work_limit`` leaves (``-1``: no limit)."""
    F = covers.shape[0]
    keep = np.empty(F, dtype=np.int64)
    n_keep = 0
    for row in range(F):
        if (not exactly_once) or (covers[row] & np.uint64(1)) != np.uint64(0):
            keep[n_keep] = row
            n_keep += 1
    most = -1
    if work_limit >= 0:
        left = work_limit - work
        if left > _INT64_MAX // entries_per_transition:
            most = _INT64_MAX  # more pairs than any step can hold (and no int64 overflow)
        else:
            most = left * entries_per_transition // span_now - n_keep
    pair_row = np.empty(16, dtype=np.int64)
    pair_h = np.empty(16, dtype=np.int64)
    n_pairs = 0
    if n_start > 0 and not (work_limit >= 0 and most < 0):
        block = max(1, pair_block_entries // n_start)
        in_block = 0
        for row in range(F):
            word = covers[row]
            if (word & np.uint64(1)) != np.uint64(0):
                continue
            for i in range(n_start):
                h = by_start[first + i]
                if (word & relative[h]) == np.uint64(0):
                    if n_pairs == pair_row.shape[0]:
                        pair_row = np.concatenate((pair_row, np.empty_like(pair_row)))
                        pair_h = np.concatenate((pair_h, np.empty_like(pair_h)))
                    pair_row[n_pairs] = row
                    pair_h[n_pairs] = h
                    n_pairs += 1
            in_block += 1
            if in_block == block:
                in_block = 0
                if work_limit >= 0 and n_pairs > most:
                    break
    return keep, n_keep, pair_row, pair_h, n_pairs


@njit(cache=True)
def _grows(counts: IntArray, pair_h: IntArray, n_pairs: int, span_now: int, kmax: int) -> int:
    """1 when a step's pairs add a k column (a counted hypothesis is taken and the span
    is still at most ``kmax``), else 0."""
    if n_pairs > 0 and span_now <= kmax:
        for p in range(n_pairs):
            if counts[pair_h[p]] > 0:
                return 1
    return 0


@njit(cache=True)
def _step_work(
    counts: IntArray,
    pair_h: IntArray,
    n_keep: int,
    n_pairs: int,
    span_now: int,
    kmax: int,
    work: int,
    limits: tuple[int, float, int],
    steps_left: int,
) -> tuple[int, int, int, int]:
    """A step's k columns after it, its work and the work so far, and whether the search
    stops here, from its kept frontiers and pairs (both layouts' steps count alike).
    ``limits``: the work limit, the projected limit and the entries per transition.

    Returns
    -------
    status, work, step_work, cols
    """
    work_limit, projected_limit, entries_per_transition = limits
    cols = span_now + _grows(counts, pair_h, n_pairs, span_now, kmax)
    C = n_keep + n_pairs
    step_work = -(-C * cols // entries_per_transition)
    work += step_work
    status = FOUND
    if work_limit >= 0 and work > work_limit:
        status = PAST_WORK_LIMIT
    elif work + step_work * steps_left > projected_limit:
        status = PAST_PROJECTION
    elif C == 0:  # an exactly-once resource no frontier can satisfy
        status = INFEASIBLE
    return status, work, step_work, cols


@njit(cache=True)
def _step(
    covers: NDArray[np.uint64],
    relative: NDArray[np.uint64],
    by_start: IntArray,
    bounds: IntArray,
    exactly_one: NDArray[np.bool_],
    counts: IntArray,
    step: int,
    span_now: int,
    kmax: int,
    work: int,
    work_limit: int,
    projected_limit: float,
    entries_per_transition: int,
    pair_block_entries: int,
) -> tuple[int, int, int, IntArray, int, IntArray, IntArray, int, int]:
    """One step's candidate rows and work, as both kernels take them: the frontiers kept,
    the open pairs (:func:`_step_pairs`), the k columns after the step, the step's work
    and the work so far, and whether the search stops here (:data:`PAST_WORK_LIMIT`,
    :data:`PAST_PROJECTION`, :data:`INFEASIBLE`; :data:`FOUND`: it goes on).

    Returns
    -------
    status, work, step_work, keep, n_keep, pair_row, pair_h, n_pairs, cols
    """
    R = bounds.shape[0] - 1
    keep, n_keep, pair_row, pair_h, n_pairs = _step_pairs(
        covers,
        relative,
        by_start,
        bounds[step],
        bounds[step + 1] - bounds[step],
        exactly_one[step],
        work_limit,
        work,
        span_now,
        entries_per_transition,
        pair_block_entries,
    )
    status, work, step_work, cols = _step_work(
        counts, pair_h, n_keep, n_pairs, span_now, kmax, work, (work_limit, projected_limit,
        entries_per_transition), R - 1 - step,
    )  # fmt: skip
    return status, work, step_work, keep, n_keep, pair_row, pair_h, n_pairs, cols


@njit(cache=True)
def _candidates(
    covers: NDArray[np.uint64],
    relative: NDArray[np.uint64],
    keep: IntArray,
    n_keep: int,
    pair_row: IntArray,
    pair_h: IntArray,
    n_pairs: int,
) -> tuple[NDArray[np.uint64], IntArray, IntArray, IntArray, IntArray]:
    """The step's candidate rows in order (frontiers kept, then pairs): the frontier words
    after the step (sorted, distinct), each candidate's frontier before the step and its
    hypothesis (``-1``: none), the candidates by next word (stable) and each one's
    frontier after the step."""
    C = n_keep + n_pairs
    words = np.empty(C, dtype=np.uint64)
    source = np.empty(C, dtype=np.int64)
    decision = np.empty(C, dtype=np.int64)
    for c in range(n_keep):
        source[c] = keep[c]
        decision[c] = -1
        words[c] = covers[keep[c]] >> np.uint64(1)
    for p in range(n_pairs):
        c = n_keep + p
        source[c] = pair_row[p]
        decision[c] = pair_h[p]
        words[c] = (covers[pair_row[p]] | relative[pair_h[p]]) >> np.uint64(1)
    ranked = _stable_order(words)
    target = np.empty(C, dtype=np.int64)
    reached = np.empty(C, dtype=np.uint64)
    group = -1
    for i in range(C):
        if i == 0 or words[ranked[i]] != words[ranked[i - 1]]:
            group += 1
            reached[group] = words[ranked[i]]
        target[ranked[i]] = group
    return reached[: group + 1].copy(), source, decision, ranked, target


@njit(cache=True)
def _carried(
    table: FloatArray,
    add: FloatArray,
    source: IntArray,
    decision: IntArray,
    counts: IntArray,
    cols: int,
) -> FloatArray:
    """Each candidate's k-entries after the step, shape (C, cols): its frontier's row of
    ``table`` (k-entries before the step), shifted by the hypothesis's count and plus its
    ``add`` (score or log-weight) where it takes one; ``-inf`` elsewhere."""
    C = source.shape[0]
    span_now = table.shape[1]
    cand = np.full((C, cols), -np.inf)
    for c in range(C):
        row = source[c]
        h = decision[c]
        if h < 0:
            for k in range(span_now):
                cand[c, k] = table[row, k]
            continue
        shift = counts[h]
        for k in range(min(span_now, cols - shift)):
            cand[c, k + shift] = table[row, k] + add[h]
    return cand


@njit(cache=True)
def _summed(cand: FloatArray, ranked: IntArray, target: IntArray, n_new: int) -> FloatArray:
    """Each frontier's k-entries after the step: its candidates' entries summed by
    ``logaddexp`` in the stable order by word (``np.logaddexp.reduceat``'s order)."""
    cols = cand.shape[1]
    out = np.empty((n_new, cols))
    for i in range(ranked.shape[0]):
        c = ranked[i]
        g = target[c]
        if i == 0 or g != target[ranked[i - 1]]:
            for k in range(cols):
                out[g, k] = cand[c, k]
        else:
            for k in range(cols):
                out[g, k] = _log_add(out[g, k], cand[c, k])
    return out


@njit(cache=True)
def _log_sum_exp(a: FloatArray, b: FloatArray) -> float:
    """``log sum_k exp(a[k] + b[k])`` over ``k < len(a)`` (``-inf`` for no finite term)."""
    top = -np.inf
    for k in range(a.shape[0]):
        if a[k] + b[k] > top:
            top = a[k] + b[k]
    if top == -np.inf:
        return -np.inf
    total = 0.0
    for k in range(a.shape[0]):
        total += math.exp(a[k] + b[k] - top)
    return top + math.log(total)


@njit(cache=True)
def _carried_best_and_mass(
    best: FloatArray,
    mass: FloatArray,
    scores: FloatArray,
    weights: FloatArray,
    source: IntArray,
    decision: IntArray,
    counts: IntArray,
    cols: int,
) -> tuple[FloatArray, FloatArray]:
    """:func:`_carried` of the best scores (plus ``scores``) and of the masses (plus
    ``weights``) in one pass over the candidates: two passes made the exact search
    slower, for the same entries."""
    C = source.shape[0]
    span_now = best.shape[1]
    cand_best = np.full((C, cols), -np.inf)
    cand_mass = np.full((C, cols), -np.inf)
    for c in range(C):
        row = source[c]
        h = decision[c]
        if h < 0:
            for k in range(span_now):
                cand_best[c, k] = best[row, k]
                cand_mass[c, k] = mass[row, k]
            continue
        shift = counts[h]
        for k in range(min(span_now, cols - shift)):
            cand_best[c, k + shift] = best[row, k] + scores[h]
            cand_mass[c, k + shift] = mass[row, k] + weights[h]
    return cand_best, cand_mass


@njit(cache=True)
def _merged_best_and_mass(
    cand_best: FloatArray, cand_mass: FloatArray, ranked: IntArray, target: IntArray, n_new: int
) -> tuple[FloatArray, FloatArray, NDArray[np.int32]]:
    """Each frontier's best scores, masses and winning candidates after the step, in one
    pass in the stable order by word: masses summed as :func:`_summed` sums them, and
    the best score of each k taken by the first candidate in that order reaching the
    maximum (``np.maximum.reduceat`` and the first hit, as the numpy search takes it)."""
    cols = cand_best.shape[1]
    new_best = np.empty((n_new, cols))
    new_mass = np.empty((n_new, cols))
    winner = np.empty((n_new, cols), dtype=np.int32)
    for i in range(ranked.shape[0]):
        c = ranked[i]
        g = target[c]
        if i == 0 or g != target[ranked[i - 1]]:
            for k in range(cols):
                new_best[g, k] = cand_best[c, k]
                new_mass[g, k] = cand_mass[c, k]
                winner[g, k] = c
        else:
            for k in range(cols):
                new_mass[g, k] = _log_add(new_mass[g, k], cand_mass[c, k])
                if cand_best[c, k] > new_best[g, k]:
                    new_best[g, k] = cand_best[c, k]
                    winner[g, k] = c
    return new_best, new_mass, winner


@njit(cache=True)
def _sort_prefix(sets: IntArray, k: int, size: int) -> None:
    """Sort ``sets[k, :size]`` in place by insertion (a set has a few members)."""
    for i in range(1, size):
        member = sets[k, i]
        j = i - 1
        while j >= 0 and sets[k, j] > member:
            sets[k, j + 1] = sets[k, j]
            j -= 1
        sets[k, j + 1] = member


@njit(cache=True)
def _trace_best_sets(
    back_winner: list[NDArray[np.int32]],
    back_source: list[IntArray],
    back_decision: list[IntArray],
    counts: IntArray,
    final_best: FloatArray,
    steps: int,
    sets: IntArray,
    set_sizes: IntArray,
) -> None:
    """Fill ``sets`` and ``set_sizes`` in place: each k with a finite best score follows
    the winners back from the last of ``steps`` steps to the first (entry 0 of each list
    is a placeholder), collecting the hypotheses taken, in increasing order."""
    for k in range(final_best.shape[0]):
        if not np.isfinite(final_best[k]):
            continue
        size = 0
        state = 0
        remaining = k
        for s in range(steps, 0, -1):
            candidate = back_winner[s][state, remaining]
            h = back_decision[s][candidate]
            state = back_source[s][candidate]
            if h >= 0:
                sets[k, size] = h
                size += 1
                remaining -= counts[h]
        _sort_prefix(sets, k, size)
        set_sizes[k] = size


@njit(cache=True)
def exact_search(
    relative: NDArray[np.uint64],
    by_start: IntArray,
    bounds: IntArray,
    exactly_one: NDArray[np.bool_],
    counts: IntArray,
    scores: FloatArray,
    weights: FloatArray,
    kmax: int,
    work_limit: int,
    projected_limit: float,
    entries_per_transition: int,
    pair_block_entries: int,
) -> tuple[int, int, int, FloatArray, FloatArray, IntArray, IntArray]:
    """The exact frontier search over the resource positions ``0..R-1``.

    Parameters
    ----------
    relative : ndarray of uint64, shape (H,)
        Each hypothesis's resources as a word relative to its first position.
    by_start, bounds : ndarray of int, shapes (H,) and (R + 1,)
        Hypotheses by first position, and each position's run of them.
    exactly_one : ndarray of bool, shape (R,)
        Which positions are exactly-once resources.
    counts, scores, weights : ndarray, shape (H,)
    kmax : int
    work_limit : int
        Most work (``-1``: no limit).
    projected_limit : float
        Most projected work (``inf``: no projection).
    entries_per_transition, pair_block_entries : int
        The search's work unit and its block of (frontier, hypothesis) tests.

    Returns
    -------
    status : int
        :data:`FOUND`, :data:`PAST_WORK_LIMIT`, :data:`PAST_PROJECTION` or
        :data:`INFEASIBLE`.
    work, widest : int
        Work charged (at the stop, for a stopped search) and most frontiers at once.
    best, mass : ndarray, shape (kmax + 1,)
    sets, set_sizes : ndarray of int, shapes (kmax + 1, H) and (kmax + 1,)
        Each k's best set in its first ``set_sizes[k]`` entries (``-1`` sizes: none).
    """
    H = relative.shape[0]
    R = bounds.shape[0] - 1
    width = kmax + 1
    problem = (relative, by_start, bounds, exactly_one, counts)
    limits = (work_limit, projected_limit, entries_per_transition, pair_block_entries)
    covers = np.zeros(1, dtype=np.uint64)
    best = np.zeros((1, 1))
    mass = np.zeros((1, 1))
    work = 0
    widest = 1
    final_best = np.full(width, -np.inf)
    final_mass = np.full(width, -np.inf)
    sets = np.full((width, max(H, 1)), -1, dtype=np.int64)
    set_sizes = np.full(width, -1, dtype=np.int64)
    back_winner = [np.zeros((0, 0), dtype=np.int32)]
    back_source = [np.zeros(0, dtype=np.int64)]
    back_decision = [np.zeros(0, dtype=np.int64)]
    for step in range(R):
        status, work, covers, best, mass, winner, source, decision = _exact_step(
            covers, best, mass, problem, limits, scores, weights, step, kmax, work
        )
        if status != FOUND:
            return status, work, widest, final_best, final_mass, sets, set_sizes
        widest = max(widest, covers.shape[0])
        back_winner.append(winner)
        back_source.append(source)
        back_decision.append(decision)
    # Every frontier word is 0 after the last position: one state remains.
    for k in range(best.shape[1]):
        final_best[k] = best[0, k]
        final_mass[k] = mass[0, k]
    _trace_best_sets(
        back_winner, back_source, back_decision, counts, final_best, R, sets, set_sizes
    )
    return FOUND, work, widest, final_best, final_mass, sets, set_sizes


@njit(cache=True)
def _exact_step(
    covers: NDArray[np.uint64],
    best: FloatArray,
    mass: FloatArray,
    problem: tuple[NDArray[np.uint64], IntArray, IntArray, NDArray[np.bool_], IntArray],
    limits: tuple[int, float, int, int],
    scores: FloatArray,
    weights: FloatArray,
    step: int,
    kmax: int,
    work: int,
) -> tuple[
    int, int, NDArray[np.uint64], FloatArray, FloatArray, NDArray[np.int32], IntArray, IntArray
]:
    """One step of :func:`exact_search` from the frontiers ``covers`` with their best
    scores and masses (``problem``: its ``relative, by_start, bounds, exactly_one,
    counts``; ``limits``: its ``work_limit, projected_limit, entries_per_transition,
    pair_block_entries``): the status and work, then the frontiers, best scores, masses
    and winning candidates after the step with the candidates' previous frontiers and
    decisions (for a stop: the frontiers as they were and empty back-pointers)."""
    relative, by_start, bounds, exactly_one, counts = problem
    work_limit, projected_limit, entries_per_transition, pair_block_entries = limits
    status, work, _, keep, n_keep, pair_row, pair_h, n_pairs, cols = _step(
        covers,
        relative,
        by_start,
        bounds,
        exactly_one,
        counts,
        step,
        best.shape[1],
        kmax,
        work,
        work_limit,
        projected_limit,
        entries_per_transition,
        pair_block_entries,
    )
    if status != FOUND:
        none = np.zeros(0, dtype=np.int64)
        return status, work, covers, best, mass, np.zeros((0, 0), dtype=np.int32), none, none
    covers, source, decision, ranked, target = _candidates(
        covers, relative, keep, n_keep, pair_row, pair_h, n_pairs
    )
    cand_best, cand_mass = _carried_best_and_mass(
        best, mass, scores, weights, source, decision, counts, cols
    )
    best, mass, winner = _merged_best_and_mass(
        cand_best, cand_mass, ranked, target, covers.shape[0]
    )
    return FOUND, work, covers, best, mass, winner, source, decision


# -- frontier words of several uint64 (the forward-backward marginals) ---------------------
# A frontier of the marginals' pass is a row of W words, bit i of word w standing for the
# position 64 w + i ahead: hypotheses spanning 64 positions or more (a burst of clutter in
# a long window) fit in a few words.  Rows order as the integers they spell (the last
# word the most significant), which is the order of the numpy pass's Python integers and
# position rows, so the frontiers are numbered, merged and ranked as there.


@njit(cache=True)
def _row_greater(keys: NDArray[np.uint64], a: int, b: int) -> bool:
    """Whether row ``a`` of ``keys`` spells a larger integer than row ``b``."""
    for w in range(keys.shape[1] - 1, -1, -1):
        if keys[a, w] != keys[b, w]:
            return keys[a, w] > keys[b, w]
    return False


@njit(cache=True)
def _stable_row_order(keys: NDArray[np.uint64]) -> IntArray:
    """:func:`_stable_order` of rows of words (shape (n, W)): insertion sort for a few
    rows, else the radix passes by bytes from the least significant word's lowest byte
    up (bytes on which all rows agree skipped); ties keep their order."""
    n, W = keys.shape
    order = np.arange(n)
    if n < _INSERTION_SORT_BELOW:
        for i in range(1, n):
            moving = order[i]
            j = i - 1
            while j >= 0 and _row_greater(keys, order[j], moving):
                order[j + 1] = order[j]
                j -= 1
            order[j + 1] = moving
        return order
    spare = np.empty(n, dtype=np.int64)
    starts = np.empty(257, dtype=np.int64)
    byte = np.uint64(0xFF)
    for w in range(W):
        ones = np.uint64(0)
        zeros = ~np.uint64(0)
        for i in range(n):
            ones |= keys[i, w]
            zeros &= keys[i, w]
        varying = ones ^ zeros
        for pass_ in range(8):
            shift = np.uint64(8 * pass_)
            if (varying >> shift) & byte == np.uint64(0):
                continue
            starts[:] = 0
            for i in range(n):
                starts[np.int64((keys[order[i], w] >> shift) & byte) + 1] += 1
            for d in range(256):
                starts[d + 1] += starts[d]
            for i in range(n):
                digit = np.int64((keys[order[i], w] >> shift) & byte)
                spare[starts[digit]] = order[i]
                starts[digit] += 1
            order, spare = spare, order
    return order


@njit(cache=True)
def _row_fits(covers: NDArray[np.uint64], row: int, relative: NDArray[np.uint64], h: int) -> bool:
    """Whether hypothesis ``h`` covers no position frontier ``row`` covers."""
    for w in range(covers.shape[1]):
        if (covers[row, w] & relative[h, w]) != np.uint64(0):
            return False
    return True


@njit(cache=True)
def _row_step_pairs(
    covers: NDArray[np.uint64],
    relative: NDArray[np.uint64],
    by_start: IntArray,
    first: int,
    n_start: int,
    exactly_once: bool,
    most: int,
    pair_block_entries: int,
) -> tuple[IntArray, int, IntArray, IntArray, int]:
    """:func:`_step_pairs` over rows of words; ``most`` is the most candidate rows
    (kept frontiers and pairs) the work limit leaves the step (:func:`_pair_budget`),
    so the pairs stop after the same block."""
    F = covers.shape[0]
    keep = np.empty(F, dtype=np.int64)
    n_keep = 0
    for row in range(F):
        if (not exactly_once) or (covers[row, 0] & np.uint64(1)) != np.uint64(0):
            keep[n_keep] = row
            n_keep += 1
    pair_row = np.empty(16, dtype=np.int64)
    pair_h = np.empty(16, dtype=np.int64)
    n_pairs = 0
    if n_start > 0 and most - n_keep >= 0:
        block = max(1, pair_block_entries // n_start)
        in_block = 0
        for row in range(F):
            if (covers[row, 0] & np.uint64(1)) != np.uint64(0):
                continue
            for i in range(n_start):
                h = by_start[first + i]
                if _row_fits(covers, row, relative, h):
                    if n_pairs == pair_row.shape[0]:
                        pair_row = np.concatenate((pair_row, np.empty_like(pair_row)))
                        pair_h = np.concatenate((pair_h, np.empty_like(pair_h)))
                    pair_row[n_pairs] = row
                    pair_h[n_pairs] = h
                    n_pairs += 1
            in_block += 1
            if in_block == block:
                in_block = 0
                if n_pairs > most - n_keep:
                    break
    return keep, n_keep, pair_row, pair_h, n_pairs


@njit(cache=True)
def _pair_budget(work_limit: int, work: int, span_now: int, entries_per_transition: int) -> int:
    """The most candidate rows (kept frontiers and pairs) a step may have without passing
    ``work_limit`` (:func:`_step_pairs`'s ``most`` plus its kept rows; ``_INT64_MAX``
    without a limit or past any step's size)."""
    if work_limit < 0:
        return _INT64_MAX
    left = work_limit - work
    if left > _INT64_MAX // entries_per_transition:
        return _INT64_MAX
    return left * entries_per_transition // span_now


@njit(cache=True)
def _row_step(
    covers: NDArray[np.uint64],
    problem: tuple[NDArray[np.uint64], IntArray, IntArray, NDArray[np.bool_], IntArray],
    limits: tuple[int, float, int, int],
    step: int,
    span_now: int,
    kmax: int,
    work: int,
) -> tuple[int, int, int, IntArray, int, IntArray, IntArray, int, int]:
    """:func:`_step` over rows of words (``problem`` and ``limits`` as
    :func:`_forward_step` takes them): the same rows, work and stops."""
    relative, by_start, bounds, exactly_one, counts = problem
    work_limit, projected_limit, entries_per_transition, pair_block_entries = limits
    R = bounds.shape[0] - 1
    most = _pair_budget(work_limit, work, span_now, entries_per_transition)
    keep, n_keep, pair_row, pair_h, n_pairs = _row_step_pairs(
        covers,
        relative,
        by_start,
        bounds[step],
        bounds[step + 1] - bounds[step],
        exactly_one[step],
        most,
        pair_block_entries,
    )
    status, work, step_work, cols = _step_work(
        counts, pair_h, n_keep, n_pairs, span_now, kmax, work, (work_limit, projected_limit,
        entries_per_transition), R - 1 - step,
    )  # fmt: skip
    return status, work, step_work, keep, n_keep, pair_row, pair_h, n_pairs, cols


@njit(cache=True)
def _row_candidates(
    covers: NDArray[np.uint64],
    relative: NDArray[np.uint64],
    keep: IntArray,
    n_keep: int,
    pair_row: IntArray,
    pair_h: IntArray,
    n_pairs: int,
) -> tuple[NDArray[np.uint64], IntArray, IntArray, IntArray, IntArray]:
    """:func:`_candidates` over rows of words: each row shifted one position (one bit
    down across the words)."""
    C = n_keep + n_pairs
    W = covers.shape[1]
    words = np.empty((C, W), dtype=np.uint64)
    source = np.empty(C, dtype=np.int64)
    decision = np.empty(C, dtype=np.int64)
    taken = np.empty(W, dtype=np.uint64)
    for c in range(C):
        if c < n_keep:
            source[c] = keep[c]
            decision[c] = -1
            for w in range(W):
                taken[w] = covers[keep[c], w]
        else:
            source[c] = pair_row[c - n_keep]
            decision[c] = pair_h[c - n_keep]
            for w in range(W):
                taken[w] = covers[source[c], w] | relative[decision[c], w]
        for w in range(W - 1):
            words[c, w] = (taken[w] >> np.uint64(1)) | (taken[w + 1] << np.uint64(63))
        words[c, W - 1] = taken[W - 1] >> np.uint64(1)
    ranked = _stable_row_order(words)
    target = np.empty(C, dtype=np.int64)
    reached = np.empty((C, W), dtype=np.uint64)
    group = -1
    for i in range(C):
        if i == 0 or _row_greater(words, ranked[i], ranked[i - 1]):
            group += 1
            reached[group] = words[ranked[i]]
        target[ranked[i]] = group
    return reached[: group + 1].copy(), source, decision, ranked, target


@njit(cache=True)
def _float_key(x: float) -> np.uint64:
    """A uint64 whose unsigned order is the order of the float ``x`` (not NaN)."""
    bits = np.array([x]).view(np.uint64)[0]
    if bits >> np.uint64(63):
        return ~bits
    return bits | (np.uint64(1) << np.uint64(63))


@njit(cache=True)
def _apply_entry_margin(mass: FloatArray, entry_margin: float) -> tuple[FloatArray, bool]:
    """Each frontier's heaviest entry of ``mass`` (shape (F, cols)), after setting to
    ``-inf`` in place the entries more than ``entry_margin`` below it (``inf``: none);
    and whether any entry was dropped."""
    n_new, cols = mass.shape
    heaviest = np.empty(n_new)
    dropped = False
    for g in range(n_new):
        top = -np.inf
        for k in range(cols):
            if mass[g, k] > top:
                top = mass[g, k]
        heaviest[g] = top
        if entry_margin < np.inf:
            for k in range(cols):
                if mass[g, k] < top - entry_margin:
                    mass[g, k] = -np.inf
                    dropped = True
    return heaviest, dropped


@njit(cache=True)
def _apply_beam(
    covers: NDArray[np.uint64],
    mass: FloatArray,
    target: IntArray,
    heaviest: FloatArray,
    max_frontiers: int,
) -> tuple[NDArray[np.uint64], FloatArray]:
    """The ``max_frontiers`` frontiers of heaviest entry (ties: the earlier word), in
    their order: their words and masses, with ``target`` renumbered in place (``-1``:
    a candidate whose frontier was dropped)."""
    n_new, cols = mass.shape
    keys = np.empty(n_new, dtype=np.uint64)
    for g in range(n_new):
        keys[g] = _float_key(-heaviest[g])
    chosen = _stable_order(keys)
    kept = np.zeros(n_new, dtype=np.bool_)
    for i in range(max_frontiers):
        kept[chosen[i]] = True
    renumber = np.full(n_new, -1, dtype=np.int64)
    n_kept = 0
    for g in range(n_new):
        if kept[g]:
            renumber[g] = n_kept
            covers[n_kept] = covers[g]
            for k in range(cols):
                mass[n_kept, k] = mass[g, k]
            n_kept += 1
    for c in range(target.shape[0]):
        target[c] = renumber[target[c]]
    return covers[:n_kept].copy(), mass[:n_kept].copy()


@njit(cache=True)
def _forward_masses(
    covers: NDArray[np.uint64],
    mass: FloatArray,
    weights: FloatArray,
    counts: IntArray,
    candidates: tuple[IntArray, IntArray, IntArray, IntArray],
    cols: int,
    entry_margin: float,
    max_frontiers: int,
) -> tuple[NDArray[np.uint64], FloatArray, bool]:
    """The frontiers after a step (words ``covers``, from :func:`_candidates`) and their
    masses, from the masses before it and the step's ``candidates`` (source, decision,
    ranked, target), with the entry margin and the beam applied (``target`` renumbered
    in place); and whether they dropped anything."""
    source, decision, ranked, target = candidates
    cand = _carried(mass, weights, source, decision, counts, cols)
    new_mass = _summed(cand, ranked, target, covers.shape[0])
    heaviest, inexact = _apply_entry_margin(new_mass, entry_margin)
    if max_frontiers >= 0 and covers.shape[0] > max_frontiers:
        covers, new_mass = _apply_beam(covers, new_mass, target, heaviest, max_frontiers)
        inexact = True
    return covers, new_mass, inexact


_ForwardPass = tuple[
    int,
    int,
    int,
    int,
    bool,
    int,
    FloatArray,
    list[FloatArray],
    list[IntArray],
    list[IntArray],
    list[IntArray],
]
"""What :func:`_forward_pass` returns (its docstring)."""


@njit(cache=True)
def _forward_pass(
    relative: NDArray[np.uint64],
    by_start: IntArray,
    bounds: IntArray,
    exactly_one: NDArray[np.bool_],
    counts: IntArray,
    weights: FloatArray,
    kmax: int,
    max_frontiers: int,
    entry_margin: float,
    work_limit: int,
    projected_limit: float,
    entries_per_transition: int,
    pair_block_entries: int,
) -> _ForwardPass:
    """The forward pass of :func:`forward_backward` (arguments as there).

    Returns
    -------
    status, work, step_work, remaining, exact
        As :func:`forward_backward` returns them (``step_work`` and ``remaining`` of
        the stopping step; 0 for a pass that ran to the end).
    frontiers : int
        Frontiers after the last position (0 or 1).
    mass : ndarray, shape (frontiers, k columns)
        Their masses.
    alphas, sources, decisions, targets : list of ndarray
        Entry ``r`` (from 1): the masses before step ``r - 1`` and its candidates'
        frontiers before and after the step and hypotheses (entry 0: a placeholder).
    """
    R = bounds.shape[0] - 1
    problem = (relative, by_start, bounds, exactly_one, counts)
    limits = (work_limit, projected_limit, entries_per_transition, pair_block_entries)
    beam = (entry_margin, max_frontiers)
    covers = np.zeros((1, relative.shape[1]), dtype=np.uint64)
    mass = np.zeros((1, 1))
    work = 0
    exact = True
    alphas = [np.zeros((0, 0))]
    sources = [np.zeros(0, dtype=np.int64)]
    decisions = [np.zeros(0, dtype=np.int64)]
    targets = [np.zeros(0, dtype=np.int64)]
    for step in range(R):
        status, work, step_work, new_covers, new_mass, inexact, source, decision, target = (
            _forward_step(covers, mass, problem, limits, beam, weights, step, kmax, work)
        )
        if status != FOUND:
            remaining = R - 1 - step
            return (
                status,
                work,
                step_work,
                remaining,
                exact,
                0,
                mass,
                alphas,
                sources,
                decisions,
                targets,
            )
        exact = exact and not inexact
        alphas.append(mass)
        sources.append(source)
        decisions.append(decision)
        targets.append(target)
        covers = new_covers
        mass = new_mass
    frontiers = covers.shape[0]
    return FOUND, work, 0, 0, exact, frontiers, mass, alphas, sources, decisions, targets


@njit(cache=True)
def _forward_step(
    covers: NDArray[np.uint64],
    mass: FloatArray,
    problem: tuple[NDArray[np.uint64], IntArray, IntArray, NDArray[np.bool_], IntArray],
    limits: tuple[int, float, int, int],
    beam: tuple[float, int],
    weights: FloatArray,
    step: int,
    kmax: int,
    work: int,
) -> tuple[int, int, int, NDArray[np.uint64], FloatArray, bool, IntArray, IntArray, IntArray]:
    """One step of :func:`_forward_pass` from the frontiers ``covers`` (rows of words)
    with their masses (``problem`` and ``limits`` as :func:`_exact_step` takes them, its
    ``relative`` rows of words; ``beam``: the
    ``entry_margin, max_frontiers`` of :func:`forward_backward`): the status, work and
    step's work, then the frontiers and masses after the step, whether the beam dropped
    anything, and the candidates' frontiers before the step, hypotheses and frontiers
    after it (for a stop: the frontiers as they were and no candidates)."""
    relative, counts = problem[0], problem[4]
    entry_margin, max_frontiers = beam
    status, work, step_work, keep, n_keep, pair_row, pair_h, n_pairs, cols = _row_step(
        covers, problem, limits, step, mass.shape[1], kmax, work
    )
    if status != FOUND:
        none = np.zeros(0, dtype=np.int64)
        return status, work, step_work, covers, mass, False, none, none, none
    new_covers, source, decision, ranked, target = _row_candidates(
        covers, relative, keep, n_keep, pair_row, pair_h, n_pairs
    )
    candidates = (source, decision, ranked, target)
    new_covers, new_mass, inexact = _forward_masses(
        new_covers, mass, weights, counts, candidates, cols, entry_margin, max_frontiers
    )
    return FOUND, work, step_work, new_covers, new_mass, inexact, source, decision, target


@njit(cache=True)
def _backward_step(
    beta: FloatArray,
    alpha: FloatArray,
    candidates: tuple[IntArray, IntArray, IntArray],
    counts: IntArray,
    weights: FloatArray,
    containing: FloatArray,
) -> FloatArray:
    """The completions' weights ``beta`` (shape (F after, j columns)) one step back, to
    the frontiers before it (masses ``alpha``, shape (F before, k columns)), adding in
    place to ``containing`` (shape (H,)) the weight of the sets through each
    candidate's hypothesis; ``candidates`` are the step's (source, decision, target)."""
    source, decision, target = candidates
    frontiers, w_before = alpha.shape
    n = min(beta.shape[1], w_before + 1)
    new_beta = np.full((frontiers, w_before), -np.inf)
    row = np.empty(w_before)
    for c in range(source.shape[0]):
        t = target[c]
        if t < 0:
            continue
        h = decision[c]
        shift = 0
        add = 0.0
        if h >= 0:
            shift = counts[h]
            add = weights[h]
        for k in range(w_before):
            j = k + shift
            row[k] = beta[t, j] + add if j < n else -np.inf
        f = source[c]
        for k in range(w_before):
            new_beta[f, k] = _log_add(new_beta[f, k], row[k])
        if h >= 0:
            through = _log_sum_exp(alpha[f], row)
            if through > -np.inf:
                containing[h] = _log_add(containing[h], through)
    return new_beta


@njit(cache=True)
def _backward_pass(
    mass: FloatArray,
    seed: FloatArray,
    alphas: list[FloatArray],
    sources: list[IntArray],
    decisions: list[IntArray],
    targets: list[IntArray],
    counts: IntArray,
    weights: FloatArray,
    containing: FloatArray,
) -> None:
    """The backward pass of :func:`forward_backward` for one ``seed`` (shape
    (kmax + 1,)): ``beta[frontier, j]``, the completions' weight from each frontier,
    from the last position (final masses ``mass``) back to the first (the forward
    pass's lists), adding to ``containing`` (shape (H,)) in place.  A completion counts
    only where its frontier's forward mass is finite."""
    final_cols = mass.shape[1]
    beta = np.full((1, final_cols), -np.inf)
    for k in range(final_cols):
        beta[0, k] = seed[k]
    after = mass
    for r in range(len(alphas) - 1, 0, -1):
        for f in range(beta.shape[0]):
            for k in range(beta.shape[1]):
                if not np.isfinite(after[f, k]):
                    beta[f, k] = -np.inf
        candidates = (sources[r], decisions[r], targets[r])
        beta = _backward_step(beta, alphas[r], candidates, counts, weights, containing)
        after = alphas[r]


@njit(cache=True)
def forward_backward(
    relative: NDArray[np.uint64],
    by_start: IntArray,
    bounds: IntArray,
    exactly_one: NDArray[np.bool_],
    counts: IntArray,
    weights: FloatArray,
    seeds: FloatArray,
    max_frontiers: int,
    entry_margin: float,
    work_limit: int,
    projected_limit: float,
    entries_per_transition: int,
    pair_block_entries: int,
) -> tuple[int, int, int, int, bool, FloatArray, FloatArray, FloatArray]:
    """The forward-backward frontier search of
    :func:`mapassoc.formulations.marginals.frontier_marginals` (module docstring there).

    The forward pass takes the numpy pass's steps: the same candidate rows, the same
    stable order by next word, masses summed by ``logaddexp`` in the same order, the same
    entry margin and beam (frontiers ranked by their heaviest entry, ties by word); the
    backward pass and the per-hypothesis sums take the same terms, with sums of
    exponentials in another order (equal to round-off).

    Parameters
    ----------
    relative : ndarray of uint64, shape (H, W)
        Each hypothesis's resources as a row of W words relative to its first position
        (bit i of word w: the position 64 w + i ahead), so that hypotheses spanning 64
        positions or more are taken too.
    by_start, bounds, exactly_one, counts
        As for :func:`exact_search`.
    weights : ndarray, shape (H,)
    seeds : ndarray, shape (S, kmax + 1)
    max_frontiers : int
        Beam width (``-1``: none).
    entry_margin : float
        Entry margin (``inf``: none).
    work_limit, projected_limit, entries_per_transition, pair_block_entries
        As for :func:`exact_search`.

    Returns
    -------
    status : int
        :data:`FOUND`, :data:`PAST_WORK_LIMIT`, :data:`PAST_PROJECTION` or
        :data:`INFEASIBLE` (no set: every sum ``-inf``).
    work, step_work, remaining : int
        Work charged, the last step's work and the steps after it (for the caller's
        projection message).
    exact : bool
        Whether nothing was dropped by the margin or the beam.
    log_mass : ndarray, shape (kmax + 1,)
    log_total : ndarray, shape (S,)
    log_containing : ndarray, shape (S, H)
    """
    H = relative.shape[0]
    S, width = seeds.shape
    log_mass = np.full(width, -np.inf)
    log_total = np.full(S, -np.inf)
    containing = np.full((S, H), -np.inf)
    forward = _forward_pass(
        relative,
        by_start,
        bounds,
        exactly_one,
        counts,
        weights,
        width - 1,
        max_frontiers,
        entry_margin,
        work_limit,
        projected_limit,
        entries_per_transition,
        pair_block_entries,
    )
    status, work, step_work, remaining, exact, frontiers, mass = forward[:7]
    if status != FOUND:
        return status, work, step_work, remaining, exact, log_mass, log_total, containing
    alphas, sources, decisions, targets = forward[7:]
    # Every frontier word is 0 after the last position: one frontier remains.
    if frontiers:
        for k in range(mass.shape[1]):
            log_mass[k] = mass[0, k]
    for s in range(S):
        log_total[s] = _log_sum_exp(log_mass, seeds[s])
        _backward_pass(
            mass, seeds[s], alphas, sources, decisions, targets, counts, weights, containing[s]
        )
    return FOUND, work, 0, 0, exact, log_mass, log_total, containing


def _warm_up() -> None:
    """Compile (or load) :func:`forward_backward` and :func:`exact_search` for the
    argument types their callers pass."""
    forward_backward(
        np.array([[1], [1]], dtype=np.uint64),
        np.arange(2, dtype=np.int64),
        np.array([0, 1, 2], dtype=np.int64),
        np.array([True, False]),
        np.ones(2, dtype=np.int64),
        np.zeros(2),
        np.zeros((1, 2)),
        4,
        30.0,
        100,
        math.inf,
        8,
        1 << 18,
    )
    exact_search(
        np.array([1, 1], dtype=np.uint64),
        np.arange(2, dtype=np.int64),
        np.array([0, 1, 2], dtype=np.int64),
        np.array([True, False]),
        np.ones(2, dtype=np.int64),
        np.zeros(2),
        np.zeros(2),
        1,
        100,
        math.inf,
        8,
        1 << 18,
    )


_warm_up()
