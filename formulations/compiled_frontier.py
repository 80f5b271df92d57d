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
pass in the same way (its own docstring says what is the same); both kernels take a
step through :func:`_step` and :func:`_candidates`, and the marginals carry and sum their
k-entries through :func:`_carried` and :func:`_summed` (the exact search fuses the same
loops with its best scores).
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
    on which all keys agree are skipped).  numba's own sorts cost seconds to compile; a
    merge sort here made a search of 708 hypotheses (1.06 million transitions) take
    0.29 s against 0.22 s."""
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
    cols = span_now + _grows(counts, pair_h, n_pairs, span_now, kmax)
    C = n_keep + n_pairs
    step_work = -(-C * cols // entries_per_transition)
    work += step_work
    status = FOUND
    if work_limit >= 0 and work > work_limit:
        status = PAST_WORK_LIMIT
    elif work + step_work * (R - 1 - step) > projected_limit:
        status = PAST_PROJECTION
    elif C == 0:  # an exactly-once resource no frontier can satisfy
        status = INFEASIBLE
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
        span_now = best.shape[1]
        status, work, _, keep, n_keep, pair_row, pair_h, n_pairs, cols = _step(
            covers,
            relative,
            by_start,
            bounds,
            exactly_one,
            counts,
            step,
            span_now,
            kmax,
            work,
            work_limit,
            projected_limit,
            entries_per_transition,
            pair_block_entries,
        )
        if status != FOUND:
            return status, work, widest, final_best, final_mass, sets, set_sizes
        new_covers, source, decision, ranked, target = _candidates(
            covers, relative, keep, n_keep, pair_row, pair_h, n_pairs
        )
        n_new = new_covers.shape[0]
        # Best scores and masses in one pass each (two passes through _carried and
        # _summed made this search 12-15% slower); the same steps as theirs, plus the
        # best score, where the first candidate in the order reaching the maximum wins.
        C = source.shape[0]
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
        new_best = np.empty((n_new, cols))
        new_mass = np.empty((n_new, cols))
        winner = np.empty((n_new, cols), dtype=np.int32)
        for i in range(C):
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
        covers = new_covers
        best = new_best
        mass = new_mass
        widest = max(widest, n_new)
        back_winner.append(winner)
        back_source.append(source)
        back_decision.append(decision)
    # Every frontier word is 0 after the last position: one state remains.
    for k in range(best.shape[1]):
        final_best[k] = best[0, k]
        final_mass[k] = mass[0, k]
    for k in range(best.shape[1]):
        if not np.isfinite(final_best[k]):
            continue
        size = 0
        state = 0
        remaining = k
        for s in range(R, 0, -1):
            candidate = back_winner[s][state, remaining]
            h = back_decision[s][candidate]
            state = back_source[s][candidate]
            if h >= 0:
                sets[k, size] = h
                size += 1
                remaining -= counts[h]
        for i in range(1, size):  # insertion sort: a set has a few members
            member = sets[k, i]
            j = i - 1
            while j >= 0 and sets[k, j] > member:
                sets[k, j + 1] = sets[k, j]
                j -= 1
            sets[k, j + 1] = member
        set_sizes[k] = size
    return FOUND, work, widest, final_best, final_mass, sets, set_sizes


@njit(cache=True)
def _float_key(x: float) -> np.uint64:
    """A uint64 whose unsigned order is the order of the float ``x`` (not NaN)."""
    bits = np.array([x]).view(np.uint64)[0]
    if bits >> np.uint64(63):
        return ~bits
    return bits | (np.uint64(1) << np.uint64(63))


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
    relative, by_start, bounds, exactly_one, counts
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
    R = bounds.shape[0] - 1
    S, width = seeds.shape
    kmax = width - 1
    log_mass = np.full(width, -np.inf)
    log_total = np.full(S, -np.inf)
    containing = np.full((S, H), -np.inf)
    covers = np.zeros(1, dtype=np.uint64)
    mass = np.zeros((1, 1))
    work = 0
    exact = True
    alphas = [np.zeros((0, 0))]
    sources = [np.zeros(0, dtype=np.int64)]
    decisions = [np.zeros(0, dtype=np.int64)]
    targets = [np.zeros(0, dtype=np.int64)]
    for step in range(R):
        reach = mass.shape[1] - 1
        status, work, step_work, keep, n_keep, pair_row, pair_h, n_pairs, cols = _step(
            covers,
            relative,
            by_start,
            bounds,
            exactly_one,
            counts,
            step,
            reach + 1,
            kmax,
            work,
            work_limit,
            projected_limit,
            entries_per_transition,
            pair_block_entries,
        )
        if status != FOUND:
            return status, work, step_work, R - 1 - step, exact, log_mass, log_total, containing
        new_covers, source, decision, ranked, target = _candidates(
            covers, relative, keep, n_keep, pair_row, pair_h, n_pairs
        )
        n_new = new_covers.shape[0]
        C = source.shape[0]
        cand = _carried(mass, weights, source, decision, counts, cols)
        new_mass = _summed(cand, ranked, target, n_new)
        heaviest = np.empty(n_new)
        for g in range(n_new):
            top = -np.inf
            for k in range(cols):
                if new_mass[g, k] > top:
                    top = new_mass[g, k]
            heaviest[g] = top
            if entry_margin < np.inf:
                for k in range(cols):
                    if new_mass[g, k] < top - entry_margin:
                        new_mass[g, k] = -np.inf
                        exact = False
        if max_frontiers >= 0 and n_new > max_frontiers:
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
                    new_covers[n_kept] = new_covers[g]
                    for k in range(cols):
                        new_mass[n_kept, k] = new_mass[g, k]
                    n_kept += 1
            for c in range(C):
                target[c] = renumber[target[c]]
            new_covers = new_covers[:n_kept].copy()
            new_mass = new_mass[:n_kept].copy()
            exact = False
        alphas.append(mass)
        sources.append(source)
        decisions.append(decision)
        targets.append(target)
        covers = new_covers
        mass = new_mass
    # Every frontier word is 0 after the last position: one frontier remains.
    final_cols = mass.shape[1]
    if covers.shape[0]:
        for k in range(final_cols):
            log_mass[k] = mass[0, k]
    for s in range(S):
        log_total[s] = _log_sum_exp(log_mass, seeds[s])
        # Backward: beta[frontier, j], the completions' weight from each frontier.
        beta = np.full((1, final_cols), -np.inf)
        for k in range(final_cols):
            beta[0, k] = seeds[s, k]
        after = mass
        for r in range(R, 0, -1):
            alpha = alphas[r]
            source = sources[r]
            decision = decisions[r]
            target = targets[r]
            for f in range(beta.shape[0]):
                for k in range(beta.shape[1]):
                    if not np.isfinite(after[f, k]):
                        beta[f, k] = -np.inf
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
                        containing[s, h] = _log_add(containing[s, h], through)
            beta = new_beta
            after = alpha
    return FOUND, work, 0, 0, exact, log_mass, log_total, containing


def _warm_up() -> None:
    """Compile (or load) :func:`forward_backward` and :func:`exact_search` for the
    argument types their callers pass."""
    forward_backward(
        np.array([1, 1], dtype=np.uint64),
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
