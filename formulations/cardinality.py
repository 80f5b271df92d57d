"""Per-cardinality tables of a packing problem: best score and total mass for every k.

For a packing problem (or one of its clusters) and every k = 0..kmax, a
:class:`CardinalityTable` holds

* ``best[k]``: the largest total score of a feasible hypothesis set with k counted
  hypotheses (``-inf`` if there is none) and one set attaining it;
* ``log_mass[k]``: ``log sum exp(total score)`` over all those sets (``-inf`` if none).

With scores equal to log-likelihood ratios, ``best`` gives the joint MAP track set for
each K and ``log_mass`` the marginal over track sets (Perry's MAP formulation: the track sets summed
out).  Independent clusters combine by :func:`convolve`: max-plus for ``best``,
sum-product (log-sum-exp) for ``log_mass``.

:func:`exact_cardinality_table` computes a table exactly with the frontier search of
:mod:`mapassoc.formulations.frontier`; a work limit (and a deadline) hands larger
clusters to the bounded path of the pipeline.

Ties in ``best`` are broken toward the set with fewer hypotheses, then the
lexicographically smallest sorted tuple of hypothesis indices, so the result does not
depend on the search order.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from mapassoc.formulations.convolution import max_plus, sum_product
from mapassoc.formulations.frontier import (
    SearchLimitExceeded,
    frontier_search,
    independent_sums,
    tie_precedes,
)
from mapassoc.formulations.packing import PackingProblem
from mapassoc.log_space import log_sum_exp

__all__ = [
    "CardinalityTable",
    "ClusterTable",
    "CombinedTable",
    "IndependentTable",
    "independent_table",
    "SearchLimitExceeded",
    "exact_cardinality_table",
    "convolve",
    "combine_tables",
    "single_hypothesis_table",
]

_NEG_INF = -math.inf

# Internal table: (best, log_mass, best_set) lists indexed by k.
_Table = tuple[list[float], list[float], list[tuple[int, ...] | None]]


@dataclass(frozen=True, eq=False)
class CardinalityTable:
    """Best score, one best set and total log-mass for every k = 0..kmax.

    A cluster's table may be shorter than the window's Kmax (the pipeline asks for no
    more k than the cluster has counted hypotheses): entries past its end are
    infeasible, which keeps a large Kmax cheap.

    Attributes
    ----------
    best : ndarray, shape (kmax + 1,)
        ``-inf`` where no feasible set has k counted hypotheses (or none was found).
    log_mass : ndarray, shape (kmax + 1,)
    best_sets : tuple of (tuple of int or None)
        A set attaining ``best[k]`` (hypothesis indices, sorted), ``None`` if none.
    exact : bool
        Whether ``log_mass`` sums every feasible set (False: a lower bound from the
        sets found).
    best_upper : ndarray, shape (kmax + 1,), optional
        Proven upper bound on the best score per k; defaults to ``best`` (every entry
        proven optimal).  ``best[k] == best_upper[k]`` says k's best set is optimal.
    log_mass_upper : ndarray, shape (kmax + 1,), optional
        Proven upper bound on the log-mass per k; defaults to ``log_mass`` (exact).
    """

    best: NDArray[np.float64]
    log_mass: NDArray[np.float64]
    best_sets: tuple[tuple[int, ...] | None, ...]
    exact: bool = True
    best_upper: NDArray[np.float64] | None = None
    log_mass_upper: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        n = self.best.shape[0]
        if self.log_mass.shape != (n,) or len(self.best_sets) != n:
            raise ValueError(
                f"best, log_mass and best_sets must have one length, got {n}, "
                f"{self.log_mass.shape[0]} and {len(self.best_sets)}"
            )
        if self.best_upper is None:
            object.__setattr__(self, "best_upper", self.best)
        if self.log_mass_upper is None:
            object.__setattr__(self, "log_mass_upper", self.log_mass)
        for name in ("best_upper", "log_mass_upper"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"{name} must have shape ({n},)")

    @property
    def kmax(self) -> int:
        return int(self.best.shape[0]) - 1

    @property
    def bounded(self) -> bool:
        """Whether some entry is only bounded (not proven optimal, or mass not exact)."""
        return not self.exact or bool(np.any(self.best_upper > self.best))  # type: ignore[operator]

    def best_set(self, k: int) -> tuple[int, ...] | None:
        """Hypotheses of a best set with k counted, ``None`` if infeasible."""
        return self.best_sets[k] if 0 <= k <= self.kmax else None

    def remapped(self, indices: NDArray[np.int64]) -> CardinalityTable:
        """The same table with hypothesis ``i`` renamed ``indices[i]``."""
        idx = np.asarray(indices, dtype=np.int64)
        sets = tuple(
            None if s is None else tuple(sorted(int(idx[i]) for i in s)) for s in self.best_sets
        )
        return CardinalityTable(
            self.best, self.log_mass, sets, self.exact, self.best_upper, self.log_mass_upper
        )


def _better(
    score: float, chosen: tuple[int, ...], best: float, best_set: tuple[int, ...] | None
) -> bool:
    """Whether (score, chosen) beats the incumbent; equal scores go by the tie order."""
    if best_set is None or score > best:
        return True
    return score == best and tie_precedes(chosen, best_set)


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
    mass = [float(log_sum_exp(t)) if t else _NEG_INF for t in terms]
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
    mass = [float(log_sum_exp(t)) if t else _NEG_INF for t in terms]
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


class ClusterTable(Protocol):
    """What :func:`combine_tables` needs of a cluster's table."""

    @property
    def best(self) -> NDArray[np.float64]: ...
    @property
    def log_mass(self) -> NDArray[np.float64]: ...
    @property
    def best_upper(self) -> NDArray[np.float64] | None: ...
    @property
    def log_mass_upper(self) -> NDArray[np.float64] | None: ...
    @property
    def exact(self) -> bool: ...
    @property
    def bounded(self) -> bool: ...
    @property
    def kmax(self) -> int: ...
    def best_set(self, k: int) -> tuple[int, ...] | None: ...


@dataclass(frozen=True, eq=False)
class IndependentTable:
    """The table of hypotheses that conflict with nothing, each taken or not.

    Such hypotheses (a detection that could start a track and interacts with no other
    hypothesis) are thousands in a scan of heavy clutter.  Combined as one table they
    cost one vector operation each instead of one convolution each: the best set of k
    holds the k best scores (prefix sums of the sorted scores), and the mass of k is
    the k-th elementary symmetric polynomial of their weights (a recursion over the
    hypotheses).  Exact; best sets are built on demand.

    Attributes
    ----------
    best, log_mass : ndarray, shape (n + 1,)
    ranked : ndarray of int, shape (n,)
        Hypothesis indices by decreasing score (equal scores: smaller index first, the
        tie order of :func:`~mapassoc.formulations.frontier.tie_precedes`).
    """

    best: NDArray[np.float64]
    log_mass: NDArray[np.float64]
    ranked: NDArray[np.int64]
    exact: bool = True
    bounded: bool = False

    @property
    def best_upper(self) -> NDArray[np.float64]:
        return self.best

    @property
    def log_mass_upper(self) -> NDArray[np.float64]:
        return self.log_mass

    @property
    def kmax(self) -> int:
        return int(self.best.shape[0]) - 1

    def best_set(self, k: int) -> tuple[int, ...] | None:
        if not 0 <= k <= self.kmax:
            return None
        return tuple(sorted(int(h) for h in self.ranked[:k]))


def independent_table(
    scores: NDArray[np.float64], log_weights: NDArray[np.float64], indices: NDArray[np.int64]
) -> IndependentTable:
    """:class:`IndependentTable` of hypotheses ``indices`` (each counts toward k).

    Parameters
    ----------
    scores, log_weights : ndarray, shape (n,)
    indices : ndarray of int, shape (n,)
        The hypotheses' indices (in the window's numbering).
    """
    scores = np.asarray(scores, dtype=float)
    log_weights = np.asarray(log_weights, dtype=float)
    indices = np.asarray(indices, dtype=np.int64)
    n = scores.shape[0]
    if log_weights.shape != (n,) or indices.shape != (n,):
        raise ValueError(
            f"scores, log_weights and indices must have one shape, got {scores.shape}, "
            f"{log_weights.shape} and {indices.shape}"
        )
    best, mass, ranked = independent_sums(scores, log_weights, indices)
    return IndependentTable(best=best, log_mass=mass, ranked=ranked)


@dataclass(frozen=True, eq=False)
class CombinedTable:
    """The table of several independent clusters, with the best sets kept implicit.

    ``best`` and ``log_mass`` are the max-plus and sum-product convolutions of the
    cluster tables, ``best_upper`` and ``log_mass_upper`` those of their upper bounds
    (a max-plus or sum-product convolution is monotone in every entry, so bounds
    combine into bounds); the best set of a k is rebuilt on demand from back-pointers
    (:meth:`best_set`), so combining hundreds of clusters for a large Kmax stays cheap.
    When two ways of splitting k over the clusters score exactly the same, the earlier
    cluster takes the fewer hypotheses.
    """

    best: NDArray[np.float64]
    log_mass: NDArray[np.float64]
    exact: bool
    tables: tuple[ClusterTable, ...]
    pointers: tuple[NDArray[np.integer], ...]
    best_upper: NDArray[np.float64]
    log_mass_upper: NDArray[np.float64]

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
            part = table.best_set(share)
            if part is None:  # pragma: no cover - pointers only name feasible entries
                raise RuntimeError("inconsistent cluster back-pointer")
            chosen.extend(part)
            remaining -= share
        return tuple(sorted(chosen))

    @property
    def best_sets(self) -> tuple[tuple[int, ...] | None, ...]:
        return tuple(self.best_set(k) for k in range(self.kmax + 1))


def combine_tables(tables: Sequence[ClusterTable], kmax: int) -> CombinedTable:
    """Convolve the tables of independent clusters (hypothesis indices already global).

    Vectorised over k.  The work stops at the largest k any set can reach (the sum of
    the tables' lengths), so a huge ``kmax`` costs no more than the feasible one; the
    arrays returned have ``kmax + 1`` entries, ``-inf`` past that k.
    """
    reach = sum(t.kmax for t in tables)
    size = min(kmax, reach) + 1
    best = np.full(size, _NEG_INF)
    mass = np.full(size, _NEG_INF)
    best[0] = mass[0] = 0.0
    # The bounds equal the values until the first bounded table (None: "the same").
    best_upper: NDArray[np.float64] | None = None
    mass_upper: NDArray[np.float64] | None = None
    pointers: list[NDArray[np.int64]] = []
    done = 0  # largest k the tables combined so far can reach
    for table in tables:
        done = min(done + table.kmax, size - 1)
        # Entries past `done` are -inf before and after: convolve the reachable part.
        new_best, pointer = max_plus(best, table.best, done + 1)
        new_mass = sum_product(mass, table.log_mass, done + 1)
        if table.bounded and best_upper is None:
            best_upper, mass_upper = best.copy(), mass.copy()
        if best_upper is not None and mass_upper is not None:
            best_upper[: done + 1] = max_plus(best_upper, table.best_upper, done + 1)[0]  # type: ignore[arg-type]
            mass_upper[: done + 1] = sum_product(mass_upper, table.log_mass_upper, done + 1)  # type: ignore[arg-type]
        best[: done + 1] = new_best
        mass[: done + 1] = new_mass
        # A cluster's share is at most its own kmax: a small integer type keeps
        # thousands of clusters' back-pointers small (each covers k = 0..done only).
        small = np.int16 if table.kmax < np.iinfo(np.int16).max else np.int64
        pointers.append(pointer.astype(small))
    if best_upper is None or mass_upper is None:
        best_upper, mass_upper = best, mass

    def padded(a: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.full(kmax + 1, _NEG_INF)
        out[:size] = a
        return out

    return CombinedTable(
        best=padded(best),
        log_mass=padded(mass),
        exact=all(t.exact for t in tables),
        tables=tuple(tables),
        pointers=tuple(pointers),
        best_upper=padded(best_upper),
        log_mass_upper=padded(mass_upper),
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


def exact_cardinality_table(
    problem: PackingProblem,
    kmax: int,
    *,
    work_limit: int = 1_000_000,
    deadline: float | None = None,
    work_projection: float | None = None,
) -> CardinalityTable:
    """Exact best score, best set and log-mass for every k = 0..kmax.

    The frontier search of :mod:`mapassoc.formulations.frontier` (a dynamic program
    over a bandwidth-reducing resource order; iterative, so any size runs).

    Parameters
    ----------
    problem : PackingProblem
    kmax : int
    work_limit : int
        Most transitions of the search (deterministic).
    deadline : float, optional
        ``time.perf_counter()`` value past which the search stops.
    work_projection : float, optional
        Stop early when on course for more than this many times ``work_limit``
        (:func:`~mapassoc.formulations.frontier.frontier_search`).

    Returns
    -------
    CardinalityTable

    Raises
    ------
    SearchLimitExceeded
        Past ``work_limit`` (or its projection) or ``deadline``.
    """
    found = frontier_search(
        problem,
        kmax,
        work_limit=work_limit,
        deadline=deadline,
        work_projection=work_projection,
    )
    n = found.best.shape[0]
    best = np.full(kmax + 1, _NEG_INF)
    mass = np.full(kmax + 1, _NEG_INF)
    best[:n], mass[:n] = found.best, found.log_mass
    sets = found.best_sets + (None,) * (kmax + 1 - n)
    return CardinalityTable(best, mass, sets, found.exact)
