"""Per-cardinality tables of a packing problem: best score and total mass for every k.

For a packing problem (or one of its clusters) and every k = 0..kmax, a
:class:`CardinalityTable` holds

* ``best[k]``: the largest total score of a feasible hypothesis set with k counted
  hypotheses (``-inf`` if there is none) and one set attaining it;
* ``log_mass[k]``: ``log sum exp(total score)`` over all those sets (``-inf`` if none).

With scores equal to log-likelihood ratios, ``best`` gives the joint MAP track set for
each K and ``log_mass`` the marginal over track sets (seed 002: the track sets summed
out).  Independent clusters combine by :func:`convolve`: max-plus for ``best``,
sum-product (log-sum-exp) for ``log_mass``.

:func:`exact_cardinality_table` computes a table exactly: it branches on a resource
(a carried track must pick exactly one hypothesis; a detection is unused or used by
exactly one hypothesis), splits what remains into independent components, and
memoises sub-results by the set of remaining hypotheses.  On the sparse conflict
graphs of tracking windows this visits far fewer nodes than plain enumeration; a node
limit hands larger clusters to an integer-program solver.

Ties in ``best`` are broken toward the lexicographically smallest sorted tuple of
hypothesis indices, so the result does not depend on the search order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.formulations.packing import PackingProblem

__all__ = [
    "CardinalityTable",
    "CombinedTable",
    "NodeLimitExceeded",
    "exact_cardinality_table",
    "convolve",
    "combine_tables",
    "table_from_sets",
    "single_hypothesis_table",
]

_NEG_INF = -math.inf

# Internal table: (best, log_mass, best_set) lists indexed by k.
_Table = tuple[list[float], list[float], list[tuple[int, ...] | None]]


class NodeLimitExceeded(RuntimeError):
    """The exact search needed more nodes than allowed."""


@dataclass(frozen=True, eq=False)
class CardinalityTable:
    """Best score, one best set and total log-mass for every k = 0..kmax.

    Attributes
    ----------
    best : ndarray, shape (kmax + 1,)
        ``-inf`` where no feasible set has k counted hypotheses.
    log_mass : ndarray, shape (kmax + 1,)
    best_sets : tuple of (tuple of int or None)
        A set attaining ``best[k]`` (hypothesis indices, sorted), ``None`` if infeasible.
    exact : bool
        Whether ``log_mass`` sums every feasible set (False: a lower bound from the
        sets found).
    """

    best: NDArray[np.float64]
    log_mass: NDArray[np.float64]
    best_sets: tuple[tuple[int, ...] | None, ...]
    exact: bool = True

    @property
    def kmax(self) -> int:
        return int(self.best.shape[0]) - 1

    def best_set(self, k: int) -> tuple[int, ...] | None:
        """Hypotheses of a best set with k counted, ``None`` if infeasible."""
        return self.best_sets[k] if 0 <= k <= self.kmax else None

    def remapped(self, indices: NDArray[np.int64]) -> CardinalityTable:
        """The same table with hypothesis ``i`` renamed ``indices[i]``."""
        idx = np.asarray(indices, dtype=np.int64)
        sets = tuple(
            None if s is None else tuple(sorted(int(idx[i]) for i in s)) for s in self.best_sets
        )
        return CardinalityTable(self.best, self.log_mass, sets, self.exact)


def _logaddexp(a: float, b: float) -> float:
    if a == _NEG_INF:
        return b
    if b == _NEG_INF:
        return a
    if a > b:
        return a + math.log1p(math.exp(b - a))
    return b + math.log1p(math.exp(a - b))


def _log_sum(terms: list[float]) -> float:
    if len(terms) == 1:
        return terms[0]
    top = max(terms)
    return top + math.log(math.fsum(math.exp(t - top) for t in terms))


def _better(
    score: float, chosen: tuple[int, ...], best: float, best_set: tuple[int, ...] | None
) -> bool:
    """Whether (score, chosen) beats the incumbent; equal scores go to the smaller sorted set.

    Sets are kept unsorted inside the search; they are sorted only to break exact ties.
    """
    if best_set is None or score > best:
        return True
    return score == best and sorted(chosen) < sorted(best_set)


def _zero_table() -> _Table:
    return [0.0], [0.0], [()]


def _convolve(a: _Table, b: _Table, kmax: int) -> _Table:
    length = min(len(a[0]) + len(b[0]) - 1, kmax + 1)
    best = [_NEG_INF] * length
    terms: list[list[float]] = [[] for _ in range(length)]
    sets: list[tuple[int, ...] | None] = [None] * length
    for i, (ab, am, aset) in enumerate(zip(*a, strict=True)):
        if am == _NEG_INF:
            continue
        for j, (bb, bm, bset) in enumerate(zip(*b, strict=True)):
            k = i + j
            if k >= length:
                break
            if bm == _NEG_INF:
                continue
            terms[k].append(am + bm)
            score = ab + bb
            if sets[k] is None or score >= best[k]:
                cand = aset + bset  # type: ignore[operator]
                if _better(score, cand, best[k], sets[k]):
                    best[k], sets[k] = score, cand
    mass = [_log_sum(t) if t else _NEG_INF for t in terms]
    return best, mass, sets


def _merge(options: list[_Table]) -> _Table:
    """Alternatives: pointwise best and log-sum of masses."""
    if len(options) == 1:
        return options[0]
    length = max(len(t[0]) for t in options)
    best = [_NEG_INF] * length
    terms: list[list[float]] = [[] for _ in range(length)]
    sets: list[tuple[int, ...] | None] = [None] * length
    for t in options:
        for k, (tb, tm, ts) in enumerate(zip(*t, strict=True)):
            if tm == _NEG_INF:
                continue
            terms[k].append(tm)
            if _better(tb, ts, best[k], sets[k]):  # type: ignore[arg-type]
                best[k], sets[k] = tb, ts
    mass = [_log_sum(t) if t else _NEG_INF for t in terms]
    return best, mass, sets


def _shift(t: _Table, count: int, score: float, weight: float, h: int, kmax: int) -> _Table:
    """Add hypothesis h (``count`` toward k) to every set of ``t``."""
    length = min(len(t[0]) + count, kmax + 1)
    best = [_NEG_INF] * length
    mass = [_NEG_INF] * length
    sets: list[tuple[int, ...] | None] = [None] * length
    for k, (tb, tm, ts) in enumerate(zip(*t, strict=True)):
        kk = k + count
        if kk >= length or tm == _NEG_INF:
            continue
        best[kk] = tb + score
        mass[kk] = tm + weight
        sets[kk] = ts + (h,)  # type: ignore[operator]
    return best, mass, sets


def _to_public(t: _Table, kmax: int, exact: bool = True) -> CardinalityTable:
    best = np.full(kmax + 1, _NEG_INF)
    mass = np.full(kmax + 1, _NEG_INF)
    sets: list[tuple[int, ...] | None] = [None] * (kmax + 1)
    n = min(len(t[0]), kmax + 1)
    best[:n] = t[0][:n]
    mass[:n] = t[1][:n]
    sets[:n] = [None if x is None else tuple(sorted(x)) for x in t[2][:n]]
    return CardinalityTable(best, mass, tuple(sets), exact)


def _from_public(t: CardinalityTable) -> _Table:
    return t.best.tolist(), t.log_mass.tolist(), list(t.best_sets)


def convolve(a: CardinalityTable, b: CardinalityTable, kmax: int) -> CardinalityTable:
    """Table of the union of two independent problems (max-plus and sum-product)."""
    return _to_public(_convolve(_from_public(a), _from_public(b), kmax), kmax, a.exact and b.exact)


@dataclass(frozen=True, eq=False)
class CombinedTable:
    """The table of several independent clusters, with the best sets kept implicit.

    ``best`` and ``log_mass`` are the max-plus and sum-product convolutions of the
    cluster tables; the best set of a k is rebuilt on demand from back-pointers
    (:meth:`best_set`), so combining hundreds of clusters for a large Kmax stays cheap.
    When two ways of splitting k over the clusters score exactly the same, the earlier
    cluster takes the fewer hypotheses.
    """

    best: NDArray[np.float64]
    log_mass: NDArray[np.float64]
    exact: bool
    tables: tuple[CardinalityTable, ...]
    pointers: tuple[NDArray[np.int64], ...]

    @property
    def kmax(self) -> int:
        return int(self.best.shape[0]) - 1

    def best_set(self, k: int) -> tuple[int, ...] | None:
        """Hypotheses of a best set with k counted (sorted), ``None`` if infeasible."""
        if not 0 <= k <= self.kmax or not np.isfinite(self.best[k]):
            return None
        chosen: list[int] = []
        remaining = k
        for table, pointer in zip(reversed(self.tables), reversed(self.pointers), strict=True):
            share = int(pointer[remaining])
            part = table.best_sets[share]
            if part is None:  # pragma: no cover - pointers only name feasible entries
                raise RuntimeError("inconsistent cluster back-pointer")
            chosen.extend(part)
            remaining -= share
        return tuple(sorted(chosen))

    @property
    def best_sets(self) -> tuple[tuple[int, ...] | None, ...]:
        return tuple(self.best_set(k) for k in range(self.kmax + 1))


def combine_tables(tables: list[CardinalityTable], kmax: int) -> CombinedTable:
    """Convolve the tables of independent clusters (hypothesis indices already global).

    Vectorised over k; cost O(sum of table lengths x kmax).
    """
    best = np.full(kmax + 1, _NEG_INF)
    mass = np.full(kmax + 1, _NEG_INF)
    best[0] = mass[0] = 0.0
    pointers: list[NDArray[np.int64]] = []
    for table in tables:
        finite = np.flatnonzero(np.isfinite(table.log_mass[: kmax + 1]))
        length = int(finite[-1]) + 1 if finite.size else 0
        new_best = np.full(kmax + 1, _NEG_INF)
        pointer = np.full(kmax + 1, -1, dtype=np.int64)
        terms = np.full((max(length, 1), kmax + 1), _NEG_INF)
        for j in range(length):
            if not np.isfinite(table.log_mass[j]):
                continue
            candidate = np.full(kmax + 1, _NEG_INF)
            candidate[j:] = best[: kmax + 1 - j] + table.best[j]
            better = candidate > new_best
            new_best[better] = candidate[better]
            pointer[better] = j
            terms[j, j:] = mass[: kmax + 1 - j] + table.log_mass[j]
        top = np.max(terms, axis=0)
        safe = np.where(np.isfinite(top), top, 0.0)
        with np.errstate(divide="ignore"):
            mass = np.where(
                np.isfinite(top), safe + np.log(np.sum(np.exp(terms - safe), axis=0)), _NEG_INF
            )
        best = new_best
        pointers.append(pointer)
    return CombinedTable(
        best=best,
        log_mass=mass,
        exact=all(t.exact for t in tables),
        tables=tuple(tables),
        pointers=tuple(pointers),
    )


def single_hypothesis_table(
    score: float, log_weight: float, counts: bool, required: bool, kmax: int
) -> CardinalityTable:
    """Table of a cluster with one hypothesis (index 0).

    ``required``: the hypothesis holds an exactly-once resource, so it must be chosen.
    """
    k = int(counts)
    options: list[_Table] = [
        ([_NEG_INF] * k + [score], [_NEG_INF] * k + [log_weight], [None] * k + [(0,)])
    ]
    if not required:
        options.append(_zero_table())
    return _to_public(_merge(options), kmax)


def table_from_sets(
    sets: list[tuple[tuple[int, ...], int, float, float]], kmax: int, *, exact: bool
) -> CardinalityTable:
    """Table from explicit feasible sets ``(hypotheses, k, score, log_weight)``.

    Each set must appear once; ``exact`` says whether they are all the feasible sets.
    """
    if not sets:
        return _to_public(([_NEG_INF], [_NEG_INF], [None]), kmax, exact)
    options: list[_Table] = []
    for hyps, k, score, weight in sets:
        if k > kmax:
            continue
        options.append(
            ([_NEG_INF] * k + [score], [_NEG_INF] * k + [weight], [None] * k + [tuple(hyps)])
        )
    if not options:
        return _to_public(([_NEG_INF], [_NEG_INF], [None]), kmax, exact)
    return _to_public(_merge(options), kmax, exact)


def exact_cardinality_table(
    problem: PackingProblem, kmax: int, *, node_limit: int = 20000
) -> CardinalityTable:
    """Exact best score, best set and log-mass for every k = 0..kmax.

    Parameters
    ----------
    problem : PackingProblem
    kmax : int
    node_limit : int
        Most search nodes (distinct sub-problems) to visit.

    Returns
    -------
    CardinalityTable

    Raises
    ------
    NodeLimitExceeded
        When the search would visit more than ``node_limit`` nodes.
    """
    H = problem.num_hypotheses
    R = problem.num_resources
    scores = problem.scores.tolist()
    weights = problem.log_weights.tolist()  # type: ignore[union-attr]
    counts = problem.counts.astype(int).tolist()
    members = [0] * R
    for h in range(H):
        for r in problem.resources_of(h).tolist():
            members[r] |= 1 << h
    conflict = [1 << h for h in range(H)]
    for h in range(H):
        for r in problem.resources_of(h).tolist():
            conflict[h] |= members[r]
    hyp_resources = [problem.resources_of(h).tolist() for h in range(H)]
    groups = [members[r] for r in range(R) if problem.exactly_one[r]]
    if any(g == 0 for g in groups):
        return _to_public(([_NEG_INF], [_NEG_INF], [None]), kmax)
    memo: dict[int, _Table] = {}
    visited = 0

    def empties_group(old: int, new: int, chosen: int) -> bool:
        """Whether going from ``old`` to ``new`` drops every member of an unsatisfied group."""
        for g in groups:
            if g & old and not g & new and not (chosen >= 0 and (g >> chosen) & 1):
                return True
        return False

    def components(mask: int) -> list[int]:
        comps = []
        remaining = mask
        while remaining:
            low = remaining & -remaining
            comp = low
            frontier = low
            while frontier:
                bit = frontier & -frontier
                frontier ^= bit
                grow = conflict[bit.bit_length() - 1] & mask & ~comp
                comp |= grow
                frontier |= grow
            comps.append(comp)
            remaining &= ~comp
        return comps

    def choose(mask: int, h: int) -> _Table | None:
        new = mask & ~conflict[h]
        if empties_group(mask, new, h):
            return None
        return _shift(solve(new), counts[h], scores[h], weights[h], h, kmax)

    def branch(mask: int) -> _Table:
        options: list[_Table] = []
        active = next((g & mask for g in groups if g & mask), 0)
        if active:
            candidates = active
        else:
            low = mask & -mask
            h0 = low.bit_length() - 1
            if not hyp_resources[h0]:
                # A hypothesis that uses nothing: take it or leave it.
                rest = mask & ~low
                sub = solve(rest)
                return _merge([sub, _shift(sub, counts[h0], scores[h0], weights[h0], h0, kmax)])
            r = max(hyp_resources[h0], key=lambda res: (members[res] & mask).bit_count())
            candidates = members[r] & mask
            unused = mask & ~members[r]
            if not empties_group(mask, unused, -1):
                options.append(solve(unused))
        while candidates:
            bit = candidates & -candidates
            candidates ^= bit
            t = choose(mask, bit.bit_length() - 1)
            if t is not None:
                options.append(t)
        if not options:
            return [_NEG_INF], [_NEG_INF], [None]
        return _merge(options)

    def solve(mask: int) -> _Table:
        nonlocal visited
        if mask == 0:
            return _zero_table()
        hit = memo.get(mask)
        if hit is not None:
            return hit
        visited += 1
        if visited > node_limit:
            raise NodeLimitExceeded(f"exact search exceeded {node_limit} nodes")
        comps = components(mask)
        if len(comps) > 1:
            out = _zero_table()
            for c in comps:
                out = _convolve(out, solve(c), kmax)
        else:
            out = branch(mask)
        memo[mask] = out
        return out

    return _to_public(solve((1 << H) - 1), kmax)
