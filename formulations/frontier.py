"""Exact per-k tables by dynamic programming over a resource order (a frontier search).

A feasible hypothesis set of a packing problem is built by walking the resources in a
fixed order and, at each resource ``r`` not yet covered, deciding whether it stays
unused (not allowed for an exactly-once resource) or is taken by one hypothesis whose
*first* resource in that order is ``r``.  Everything the rest of the walk needs to know
about the choices so far is the set of *later* resources they already cover: the
**frontier**.  Summing (log-sum-exp) and maximising over the choices frontier by
frontier gives, for every k, the best score, a best set and the log-mass of all
feasible sets with k counted hypotheses: the quantities of Perry's MAP formulation (eq. 14 and the
marginal over track sets) for one cluster.

The cost is the number of distinct frontiers, which the order decides.  Resources are
ordered by reverse Cuthill-McKee on the resource co-use graph (two resources are
adjacent when a hypothesis uses both), a bandwidth-reducing order: a hypothesis then
spans a short stretch of the order and the frontier stays narrow.  On a cluster of five
closely spaced parallel targets (444 hypotheses over 29 detections) this visits 13
thousand frontiers where detection order visits 339 thousand and a search over
remaining-hypothesis sets exceeds 50 thousand nodes.

Problems whose hypotheses each span fewer than 64 positions of the order (the usual
case after the reordering) are searched with every frontier of a step as a numpy row
(about 15 times faster per k-entry); the others by dictionaries.

The search is iterative (no recursion, whatever the size), counts its work in
*transitions* (one k-entry carried along one decision) and stops with
:class:`SearchLimitExceeded` past ``work_limit`` transitions or past a wall-clock
``deadline``.  With ``max_frontiers`` it becomes a beam search: after each resource only
the frontiers holding the most mass are kept, so the masses are lower bounds (sums over
a subset of the feasible sets, each counted once) and the best sets are feasible but
not necessarily optimal; the result says so (``exact=False``).

Ties.  Among sets of equal score the one with fewer hypotheses wins, and among those
the lexicographically smallest sorted tuple (equivalently: the set holding the smallest
index in which the two differ).  Adding the same later hypotheses to two sets keeps
their order, which is what makes the dynamic program's local choice the global one.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse.csgraph import reverse_cuthill_mckee

from mapassoc.accelerate import compiled_module
from mapassoc.formulations.convolution import max_plus, sum_product
from mapassoc.formulations.packing import PackingProblem

__all__ = [
    "SearchLimitExceeded",
    "FrontierResult",
    "WORK_COUNT_MIN_HYPOTHESES",
    "exact_search_work",
    "FRONTIER_KERNELS",
    "PAIR_BLOCK_ENTRIES",
    "fits_counted_work",
    "frontier_search",
    "frontier_words",
    "hypothesis_spans",
    "open_pairs",
    "pair_budget",
    "resource_order",
    "tie_precedes",
    "independent_sums",
    "kernel_work_limit",
]

_NEG_INF = -math.inf
_DEADLINE_CHECK_EVERY = 4096
"""Transitions between two reads of the clock."""

_SMALL_CLUSTER_RESOURCES = 12
"""Up to this many resources the canonical order is used as it is (no RCM)."""

# One k-entry of a frontier: (best score, a best set as a tuple, log-mass).
# A set is an integer whose bit H-1-h says that hypothesis h is in it: adding one is an
# OR, and the tie order is an integer comparison (the highest differing bit is the
# smallest differing index).
_Entry = tuple[float, int, float]


def _members(code: int, H: int) -> tuple[int, ...]:
    """Sorted hypothesis indices of a set code."""
    out = []
    while code:
        top = code.bit_length() - 1
        out.append(H - 1 - top)
        code ^= 1 << top
    return tuple(out)


def _code_precedes(a: int, b: int) -> bool:
    """:func:`tie_precedes` on set codes: fewer members, then the larger code."""
    na, nb = a.bit_count(), b.bit_count()
    return na < nb if na != nb else a > b


class SearchLimitExceeded(RuntimeError):
    """The search needed more work than allowed, or ran past its deadline.

    Attributes
    ----------
    reason : {"work", "projected", "deadline"}
        ``"projected"``: stopped early by ``work_projection`` (the search was on course
        for far more work than its limit).
    work : int
        Transitions done when it stopped.
    """

    def __init__(self, message: str, *, reason: str, work: int) -> None:
        super().__init__(message)
        self.reason = reason
        self.work = work


@dataclass(frozen=True, eq=False)
class FrontierResult:
    """Per-k best score, best set and log-mass of a packing problem.

    Attributes
    ----------
    best : ndarray, shape (min(kmax, counted hypotheses) + 1,)
        Best total score per k (``-inf``: no set found with that k).
    best_sets : tuple of (tuple of int or None)
        A set attaining ``best[k]`` (sorted hypothesis indices), ``None`` where infeasible.
    log_mass : ndarray, same shape as ``best``
        ``log sum exp`` of the total log-weights of the sets summed, per k.
    exact : bool
        Whether every feasible set was summed (False after the beam dropped frontiers:
        ``log_mass`` is then a lower bound and ``best`` the best of the sets kept).
    work : int
        Transitions done.
    max_frontiers : int
        Most frontiers alive after one resource.
    """

    best: NDArray[np.float64]
    best_sets: tuple[tuple[int, ...] | None, ...]
    log_mass: NDArray[np.float64]
    exact: bool
    work: int
    max_frontiers: int


def resource_order(problem: PackingProblem) -> NDArray[np.int64]:
    """A bandwidth-reducing order of the resources (reverse Cuthill-McKee).

    The resources are first sorted by the tuple of hypotheses using them, so the order
    depends only on the hypotheses' numbering, not on how the resources happen to be
    numbered (the sums along the search, and so exact ties, come out the same for any
    detection order).

    Parameters
    ----------
    problem : PackingProblem

    Returns
    -------
    ndarray of int, shape (R,)
        ``order[i]`` is the resource visited i-th.
    """
    R = problem.num_resources
    if R == 0:
        return np.zeros(0, dtype=np.int64)
    users: list[list[int]] = [[] for _ in range(R)]
    for h in range(problem.num_hypotheses):
        for r in problem.resources_of(h).tolist():
            users[r].append(h)
    canonical = np.array(sorted(range(R), key=lambda r: users[r]), dtype=np.int64)
    if R <= _SMALL_CLUSTER_RESOURCES:
        return canonical  # any order is cheap; the sparse machinery is not
    incidence = problem.incidence()[canonical]
    co_use = sp.csr_matrix(incidence @ incidence.T)
    rcm = np.asarray(reverse_cuthill_mckee(co_use, symmetric_mode=True), dtype=np.int64)
    return canonical[rcm]


def tie_precedes(a: tuple[int, ...], b: tuple[int, ...]) -> bool:
    """Whether ``a`` precedes ``b`` in the tie order: fewer hypotheses, then the one
    holding the smallest index in which they differ (for equal sizes, the
    lexicographically smaller sorted tuple)."""
    if len(a) != len(b):
        return len(a) < len(b)
    differ = set(a) ^ set(b)
    return bool(differ) and min(differ) in a


def _check_limits(work: int, work_limit: int | None, deadline: float | None) -> None:
    """Raise :class:`SearchLimitExceeded` past the work limit or the deadline."""
    if work_limit is not None and work > work_limit:
        raise SearchLimitExceeded(
            f"frontier search exceeded its work limit of {work_limit} transitions",
            reason="work",
            work=work,
        )
    if deadline is not None and time.perf_counter() > deadline:
        raise SearchLimitExceeded(
            "frontier search ran past its deadline", reason="deadline", work=work
        )


KERNEL_WORK_MAX = 2**63 - 1
"""Most work the compiled kernels count (int64): a larger limit is never reached."""


def kernel_work_limit(work_limit: int | None) -> int:
    """``work_limit`` as the compiled kernels take it: ``-1`` for none, and clamped to
    :data:`KERNEL_WORK_MAX` (a search that counts no further cannot pass a larger limit,
    and numba cannot pass a larger int)."""
    return -1 if work_limit is None else min(int(work_limit), KERNEL_WORK_MAX)


def projected_work_limit(work_projection: float | None, work_limit: int | None) -> float | None:
    """``work_projection * work_limit``, the work a search may be on course for (None
    without a projection); a projection needs a work limit and a factor >= 1."""
    if work_projection is None:
        return None
    if not (work_projection >= 1 and work_limit is not None):
        raise ValueError(
            f"work_projection must be >= 1 and come with a work_limit, got {work_projection!r}"
        )
    return work_projection * work_limit


def check_projection(
    what: str,
    work: int,
    step_work: int,
    remaining_steps: int,
    projected_limit: float | None,
    work_limit: int | None,
) -> None:
    """Raise :class:`SearchLimitExceeded` (reason ``"projected"``) when the work done plus
    this step's work repeated for every remaining step passes ``projected_limit``."""
    if projected_limit is not None and work + step_work * remaining_steps > projected_limit:
        raise _projected_stop(what, work, projected_limit, work_limit)


def _projected_stop(
    what: str, work: int, projected_limit: float, work_limit: int | None
) -> SearchLimitExceeded:
    return SearchLimitExceeded(
        f"{what} projected past {projected_limit:.0f} transitions "
        f"(work_projection x the work limit of {work_limit}) after {work}",
        reason="projected",
        work=work,
    )


def _log_add(a: float, b: float) -> float:
    if a < b:
        a, b = b, a
    if b == _NEG_INF:
        return a
    return a + math.log1p(math.exp(b - a))


def _carry(
    frontiers: dict[int, dict[int, _Entry]], shared: set[int], key: int, entries: dict[int, _Entry]
) -> None:
    """Merge ``entries`` into frontier ``key``: keep the better best set, add the masses.

    A frontier in ``shared`` still holds another frontier's dict and is copied before it
    is changed.
    """
    target = frontiers.get(key)
    if target is None:
        frontiers[key] = entries
        shared.add(key)
        return
    if key in shared:
        target = dict(target)
        frontiers[key] = target
        shared.discard(key)
    for k, (b, s, m) in entries.items():
        old = target.get(k)
        if old is None:
            target[k] = (b, s, m)
            continue
        ob, os_, om = old
        if b > ob or (b == ob and _code_precedes(s, os_)):
            target[k] = (b, s, _log_add(m, om))
        else:
            target[k] = (ob, os_, _log_add(m, om))


def frontier_search(
    problem: PackingProblem,
    kmax: int,
    *,
    work_limit: int | None = None,
    deadline: float | None = None,
    max_frontiers: int | None = None,
    entry_margin: float | None = None,
    work_projection: float | None = None,
) -> FrontierResult:
    """Best score, best set and log-mass for every k = 0..kmax by the frontier search.

    Parameters
    ----------
    problem : PackingProblem
        Scores are maximised; log-weights are summed (they differ after merging
        interchangeable hypotheses).
    kmax : int
        Largest k tabulated (>= 0); sets with more counted hypotheses are not followed.
    work_limit : int, optional
        Most transitions (k-entries carried along one decision) before
        :class:`SearchLimitExceeded` is raised.  A deterministic limit.
    deadline : float, optional
        A ``time.perf_counter()`` value after which the search stops with
        :class:`SearchLimitExceeded` (checked every few thousand transitions).
    max_frontiers : int, optional
        Beam width: after each resource keep only this many frontiers, those whose
        partial sets hold the most mass.  Makes the result a lower bound (``exact`` is
        then False if anything was dropped).
    entry_margin : float, optional
        With the beam: after each resource, drop a frontier's k-entries whose mass is
        more than this many nats below its heaviest entry (they hold a negligible share
        of what the frontier carries; dropping them keeps every mass a lower bound and
        bounds the entries per frontier).
    work_projection : float, optional
        With ``work_limit``: also stop (reason ``"projected"``) as soon as the work done
        plus the current step's work repeated for every remaining position exceeds
        ``work_projection * work_limit``.  The step's work grows or shrinks with the
        number of frontiers, so this is a projection, not a bound; a factor well above
        1 makes it stop only searches on course for far more than their limit (a search
        whose work was still to grow several-fold stops at the limit anyway), and spares
        the time they would spend before reaching it.  Deterministic, like the limit.
        Applies to the vectorised search (every hypothesis spans fewer than 64 positions
        of the resource order, the usual case); the general one stops at the limit.  An
        exact search (no beam) of :data:`WORK_COUNT_MIN_HYPOTHESES` hypotheses or more
        with a work limit needs no projection: its work is counted beforehand
        (:func:`exact_search_work`), so it stops at once when it would pass the limit
        and otherwise runs to the end.

    Returns
    -------
    FrontierResult

    Raises
    ------
    SearchLimitExceeded
        Past ``work_limit`` (or its projection) or ``deadline``.
    """
    projected_limit = projected_work_limit(work_projection, work_limit)
    if int(kmax) != kmax or kmax < 0:
        raise ValueError(f"kmax must be an integer >= 0, got {kmax!r}")
    if work_limit is not None and work_limit < 1:
        raise ValueError(f"work_limit must be >= 1, got {work_limit!r}")
    if max_frontiers is not None and max_frontiers < 1:
        raise ValueError(f"max_frontiers must be >= 1, got {max_frontiers!r}")
    kmax = min(int(kmax), int(np.count_nonzero(problem.counts)))  # no set counts more
    lone = np.diff(problem.resource_indptr) == 0
    if np.any(lone):
        # Hypotheses that use no resource are independent of everything: search the
        # rest, then add them in closed form.
        rest = np.flatnonzero(~lone)
        if rest.size:
            main = frontier_search(
                problem.subproblem(rest),
                kmax,
                work_limit=work_limit,
                deadline=deadline,
                max_frontiers=max_frontiers,
                entry_margin=entry_margin,
                work_projection=work_projection,
            )
        else:
            main = _result(np.zeros(1), np.zeros(1), [()], 0, 1)
        return _with_lone(main, rest, problem, np.flatnonzero(lone), kmax)
    order = resource_order(problem)
    if (
        work_limit is not None
        and max_frontiers is None
        and entry_margin is None
        and fits_counted_work(
            "frontier search", problem, kmax, order, work_limit=work_limit, deadline=deadline
        )
    ):
        projected_limit = None  # it runs whole: nothing to project
    vectorised = _vectorised_search(
        problem, kmax, order, work_limit, deadline, max_frontiers, entry_margin, projected_limit
    )
    if vectorised is not None:
        return vectorised
    return _dictionary_search(
        problem, kmax, order, work_limit, deadline, max_frontiers, entry_margin
    )


def _dictionary_search(
    problem: PackingProblem,
    kmax: int,
    order: NDArray[np.int64],
    work_limit: int | None,
    deadline: float | None,
    max_frontiers: int | None,
    entry_margin: float | None,
) -> FrontierResult:
    """The frontier search with one dictionary of k-entries per frontier (any problem
    whose hypotheses all use a resource; the general path behind the vectorised one)."""
    layout = _DictionaryLayout.of(problem, order)
    work = 0
    next_check = _DEADLINE_CHECK_EVERY
    exact = True
    widest = 1

    def spend(amount: int) -> None:
        nonlocal work, next_check
        work += amount
        clock = deadline is not None and work >= next_check
        if clock:
            next_check = work + _DEADLINE_CHECK_EVERY
        _check_limits(work, work_limit, deadline if clock else None)

    # frontier (bit mask of later resources already covered) -> {k: entry}
    states: dict[int, dict[int, _Entry]] = {0: {0: (0.0, 0, 0.0)}}
    for step in range(order.size):
        states = layout.step(states, step, kmax, spend)
        if entry_margin is not None and _drop_light_entries(states, entry_margin):
            exact = False
        if max_frontiers is not None and len(states) > max_frontiers:
            ranked = sorted(
                states.items(),
                key=lambda item: (-max(m for _, _, m in item[1].values()), item[0]),
            )
            states = dict(ranked[:max_frontiers])
            exact = False
        widest = max(widest, len(states))
    final = states.get(0, {})
    best = np.full(kmax + 1, _NEG_INF)
    mass = np.full(kmax + 1, _NEG_INF)
    sets: list[tuple[int, ...] | None] = [None] * (kmax + 1)
    for k, (b, s, m) in final.items():
        best[k], mass[k], sets[k] = b, m, _members(s, problem.num_hypotheses)
    return FrontierResult(
        best=best,
        best_sets=tuple(sets),
        log_mass=mass,
        exact=exact,
        work=work,
        max_frontiers=widest,
    )


@dataclass(frozen=True)
class _DictionaryLayout:
    """What the dictionary search needs of a problem in the resource order, as Python
    lists: each hypothesis's score, log-weight, count and member code (a bit, the first
    hypothesis the highest), which positions are exactly-once, and the hypotheses
    starting at each position with the bit mask of the positions they use."""

    scores: list[float]
    weights: list[float]
    counts: list[int]
    codes: list[int]
    exactly_one: list[bool]
    starting: list[list[tuple[int, int]]]

    @classmethod
    def of(cls, problem: PackingProblem, order: NDArray[np.int64]) -> _DictionaryLayout:
        H = problem.num_hypotheses
        position = np.empty(problem.num_resources, dtype=np.int64)
        position[order] = np.arange(order.size)
        starting: list[list[tuple[int, int]]] = [[] for _ in range(order.size)]
        for h in range(H):
            spots = position[problem.resources_of(h)]
            mask = 0
            for p in spots.tolist():
                mask |= 1 << p
            starting[int(spots.min())].append((h, mask))
        return cls(
            scores=problem.scores.tolist(),
            weights=problem.weights.tolist(),
            counts=problem.counts.astype(np.int64).tolist(),
            codes=[1 << (H - 1 - h) for h in range(H)],
            exactly_one=problem.exactly_one[order].tolist(),
            starting=starting,
        )

    def step(
        self,
        states: dict[int, dict[int, _Entry]],
        step: int,
        kmax: int,
        spend: Callable[[int], None],
    ) -> dict[int, dict[int, _Entry]]:
        """The frontiers after position ``step``: each frontier's entries carried when
        the position is covered or may stay unused, and shifted through every
        hypothesis starting here that fits it; ``spend`` charges the work."""
        bit = 1 << step
        new: dict[int, dict[int, _Entry]] = {}
        shared: set[int] = set()  # keys whose dict is still another frontier's (copy on write)
        for cover, entries in states.items():
            spend(len(entries))
            if cover & bit:
                _carry(new, shared, cover ^ bit, entries)
                continue
            if not self.exactly_one[step]:
                _carry(new, shared, cover, entries)
            for h, mask in self.starting[step]:
                if mask & cover:
                    continue
                c, score, weight, member = (
                    self.counts[h],
                    self.scores[h],
                    self.weights[h],
                    self.codes[h],
                )
                shifted = {
                    k + c: (b + score, s | member, m + weight)
                    for k, (b, s, m) in entries.items()
                    if k + c <= kmax
                }
                if shifted:
                    spend(len(shifted))
                    _carry(new, shared, (cover | mask) ^ bit, shifted)
        return new


def _drop_light_entries(states: dict[int, dict[int, _Entry]], entry_margin: float) -> bool:
    """Drop, in place, each frontier's k-entries whose mass is more than
    ``entry_margin`` below its heaviest; whether any was dropped."""
    dropped = False
    for key, entries in states.items():
        heaviest = max(m for _, _, m in entries.values())
        light = [k for k, (_, _, m) in entries.items() if m < heaviest - entry_margin]
        if light:
            states[key] = {k: e for k, e in entries.items() if k not in light}
            dropped = True
    return dropped


FRONTIER_KERNELS = "mapassoc.formulations.compiled_frontier"
"""The compiled frontier kernels, the exact search and the forward-backward marginals
(:func:`mapassoc.accelerate.compiled_module`)."""

_WORD_BITS = 64
"""Frontiers of the vectorised search are one unsigned 64-bit word."""

_VECTOR_ENTRIES_PER_TRANSITION = 8
"""Work is counted in transitions of the dictionary search (about a microsecond each);
the vectorised search handles a k-entry 8 to 15 times faster (less on wide steps) and
counts it as an eighth."""

_VECTORISE_MIN_HYPOTHESES = 40
"""Smaller problems take the dictionary search (numpy's per-call cost would dominate)."""

WORK_COUNT_MIN_HYPOTHESES = 200
"""Exact searches with a work limit of at least this many hypotheses count their work on
the frontier words first (:func:`exact_search_work`, about a tenth of the search's
cost).  On the clusters of the converging, dense_radar, parallel and dense_pd08
families, those that pass the default limit all have 200 hypotheses or more, so a
smaller search never needs the count; on a larger one, the count costs far less than
running the search up to the limit, and adds a small share to a search that fits."""


def hypothesis_spans(
    problem: PackingProblem, order: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Where each hypothesis's resources lie in the resource ``order``.

    Returns
    -------
    owner : ndarray of int, shape (nnz,)
        The hypothesis of each entry of ``problem.resource_indices``.
    offsets : ndarray of int, shape (nnz,)
        Each entry's position relative to its hypothesis's first position.
    first, last : ndarray of int, shape (H,)
        Each hypothesis's first and last position (``R`` and 0 for one without
        resources).
    """
    H = problem.num_hypotheses
    R = order.size
    position = np.empty(R, dtype=np.int64)
    position[order] = np.arange(R)
    owner = np.repeat(np.arange(H), np.diff(problem.resource_indptr))
    spots = position[problem.resource_indices]
    first = np.full(H, R, dtype=np.int64)
    np.minimum.at(first, owner, spots)
    last = np.zeros(H, dtype=np.int64)
    np.maximum.at(last, owner, spots)
    return owner, spots - first[owner], first, last


_WordLayout = tuple[NDArray[np.uint64], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]


def _word_layout(problem: PackingProblem, order: NDArray[np.int64]) -> _WordLayout | None:
    """What the vectorised search needs of ``problem`` in the resource ``order``
    (:func:`frontier_words`); ``None`` where the vectorised search does not apply (fewer
    than :data:`_VECTORISE_MIN_HYPOTHESES` hypotheses, none with a resource, or one
    spanning :data:`_WORD_BITS` positions or more)."""
    if problem.num_hypotheses < _VECTORISE_MIN_HYPOTHESES or order.size == 0:
        return None
    return frontier_words(problem, order)


def frontier_words(problem: PackingProblem, order: NDArray[np.int64]) -> _WordLayout | None:
    """Each hypothesis's resources as a 64-bit word relative to its first position in the
    resource ``order``, the hypotheses by first position with the bounds of each
    position's run, and which positions are exactly-once resources; ``None`` where a
    hypothesis spans :data:`_WORD_BITS` positions or more (its word would not fit).
    The arrays are as the compiled kernels take them (uint64, int64, contiguous bool)."""
    H = problem.num_hypotheses
    R = order.size
    owner, offsets, first, last = hypothesis_spans(problem, order)
    if np.any(last - first >= _WORD_BITS):
        return None
    relative = np.zeros(H, dtype=np.uint64)
    np.bitwise_or.at(relative, owner, np.left_shift(np.uint64(1), offsets.astype(np.uint64)))
    by_start = np.argsort(first, kind="stable").astype(np.int64, copy=False)
    bounds = np.searchsorted(first[by_start], np.arange(R + 1)).astype(np.int64, copy=False)
    exactly_one = np.ascontiguousarray(problem.exactly_one[order], dtype=np.bool_)
    return relative, by_start, bounds, exactly_one


PAIR_BLOCK_ENTRIES = 1 << 18
"""Open frontiers are tested against a step's hypotheses in blocks of about this many
(frontier, hypothesis) entries, so a step past the work limit stops after a block."""


def open_pairs(
    covers: NDArray[Any],
    covered: NDArray[np.bool_],
    relative: NDArray[Any],
    starting: NDArray[np.int64],
    most: int | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Every (frontier, hypothesis) pair where a hypothesis starting at this position
    fits a frontier that has not covered it: frontier rows, hypotheses (rows first).

    ``covers`` and ``relative`` are frontier and hypothesis words (uint64, or Python
    integers in object arrays).  With ``most``, the open frontiers are tested block by
    block and the test stops once more than ``most`` pairs are found: the pairs returned
    are then a prefix of the whole list, more than ``most`` of them (none when ``most``
    is negative).  A search whose work limit leaves room for ``most`` pairs knows then
    that the step passes the limit without building the step's whole pair matrix.
    """
    open_rows = np.flatnonzero(~covered)
    if not (starting.size and open_rows.size) or (most is not None and most < 0):
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    words = relative[starting][None, :]
    block = max(1, PAIR_BLOCK_ENTRIES // starting.size)
    rows_found: list[NDArray[np.int64]] = []
    hypotheses_found: list[NDArray[np.int64]] = []
    found = 0
    for lo in range(0, open_rows.size, block):
        rows = open_rows[lo : lo + block]
        fits = np.asarray((covers[rows, None] & words) == 0, dtype=bool)
        pair_row, pair_h = np.nonzero(fits)
        rows_found.append(rows[pair_row])
        hypotheses_found.append(starting[pair_h])
        found += pair_row.size
        if most is not None and found > most:
            break
    if len(rows_found) == 1:
        return rows_found[0], hypotheses_found[0]
    return np.concatenate(rows_found), np.concatenate(hypotheses_found)


def pair_budget(
    work_limit: int | None, work: int, columns: int, kept: int, entries_per_transition: int
) -> int | None:
    """The most (frontier, hypothesis) pairs a step can add to ``kept`` rows of at least
    ``columns`` k-entries each without taking the work past ``work_limit`` (``None``
    without a limit): the ``most`` of :func:`open_pairs`."""
    if work_limit is None:
        return None
    return (work_limit - work) * entries_per_transition // columns - kept


def exact_search_work(
    problem: PackingProblem,
    kmax: int,
    order: NDArray[np.int64],
    *,
    work_limit: int,
    deadline: float | None = None,
) -> int | None:
    """The work the exact vectorised search would charge, from the frontier words alone.

    Without a beam every frontier reached is kept, so which frontiers exist at each
    position, how many candidate rows a step has and how many k columns they span do
    not depend on any score or weight: this runs the search on the words only (no
    k-entries, a fraction of the search's cost) and adds the work each step would charge.
    It stops as soon as the sum passes ``work_limit`` and returns it (the search would
    raise there, with that work), or returns the whole search's work.  ``None`` where
    the vectorised search does not apply.
    """
    layout = _word_layout(problem, order)
    if layout is None:
        return None
    relative, by_start, bounds, exactly_one = layout
    counts = problem.counts
    one = np.uint64(1)
    covers = np.zeros(1, dtype=np.uint64)
    span = 1  # k columns, as in the search: k = 0..span - 1
    work = 0
    for step in range(order.size):
        _check_limits(0, None, deadline)
        covered = (covers & one).astype(bool)
        keep = np.flatnonzero(covered) if exactly_one[step] else np.arange(covers.size)
        starting = by_start[bounds[step] : bounds[step + 1]]
        most = pair_budget(work_limit, work, span, keep.size, _VECTOR_ENTRIES_PER_TRANSITION)
        pair_row, pair_h = open_pairs(covers, covered, relative, starting, most)
        grow = int(pair_h.size > 0 and bool(np.any(counts[pair_h])) and span <= kmax)
        span += grow
        rows = keep.size + pair_h.size
        work += -(-rows * span // _VECTOR_ENTRIES_PER_TRANSITION)
        if work > work_limit or rows == 0:
            return work
        # Sorted distinct words (np.unique's hashing is several times slower on these).
        reached = np.sort(
            np.concatenate([covers[keep] >> one, (covers[pair_row] | relative[pair_h]) >> one])
        )
        covers = reached[np.r_[True, reached[1:] != reached[:-1]]]
    return work


def fits_counted_work(
    what: str,
    problem: PackingProblem,
    kmax: int,
    order: NDArray[np.int64],
    *,
    work_limit: int,
    deadline: float | None,
) -> bool:
    """Count an exact search's work before it runs (:func:`exact_search_work`), for a
    problem of :data:`WORK_COUNT_MIN_HYPOTHESES` hypotheses or more.

    Returns True when the search fits ``work_limit`` (it will run whole), False when the
    work was not counted (a smaller problem, or one the vectorised search does not
    take).  Raises :class:`SearchLimitExceeded` (reason ``"work"``, with the work at
    which the search would stop) when it would pass the limit; ``what`` names the
    search in the message.
    """
    if problem.num_hypotheses < WORK_COUNT_MIN_HYPOTHESES:
        return False
    needed = exact_search_work(problem, kmax, order, work_limit=work_limit, deadline=deadline)
    if needed is None:
        return False
    if needed > work_limit:
        raise SearchLimitExceeded(
            f"{what} would exceed its work limit of {work_limit} transitions (counted on "
            "the frontier words, before the search)",
            reason="work",
            work=needed,
        )
    return True


_ONE = np.uint64(1)

_Back = tuple[NDArray[np.int32], NDArray[np.int64], NDArray[np.int64], int]
"""One step of the vectorised search, for tracing the best sets back: the winning
candidate of each (frontier, k) (int32, the big array), each candidate's previous
frontier and decision, and the k of the winners' column 0."""


def _vectorised_search(
    problem: PackingProblem,
    kmax: int,
    order: NDArray[np.int64],
    work_limit: int | None,
    deadline: float | None,
    max_frontiers: int | None = None,
    entry_margin: float | None = None,
    projected_limit: float | None = None,
) -> FrontierResult | None:
    """The frontier search with all frontiers of a step as numpy rows.

    ``max_frontiers`` and ``entry_margin`` make it the beam of :func:`frontier_search`
    (frontiers ranked by their heaviest entry, ties by frontier word);
    ``projected_limit`` is its ``work_projection`` times ``work_limit``.

    Applies when every hypothesis spans fewer than 64 positions of the resource order
    (then a frontier, taken relative to the current position, is one 64-bit word) and
    uses at least one resource; returns ``None`` otherwise.  Per step, every
    (frontier, decision) pair is one row of k-entries; rows reaching the same frontier
    are merged by ``logaddexp.reduceat`` (masses) and ``maximum.reduceat`` (best
    scores), with back-pointers for the best sets.  Exact ties go to the first
    candidate in a fixed order (covered or unused before taking a hypothesis,
    hypotheses by index, frontiers by their word), so the result is deterministic and
    does not depend on the numbering of the resources.
    """
    layout = _word_layout(problem, order)
    if layout is None:
        return None
    if (
        max_frontiers is None
        and entry_margin is None
        and (work_limit is not None or deadline is None)
    ):
        # Exact and bounded by its work (or by nothing): the compiled kernel, where
        # numba is installed, takes the same steps.
        kernel = compiled_module(FRONTIER_KERNELS)
        if kernel is not None:
            _check_limits(0, None, deadline)
            return _compiled_search(kernel, problem, kmax, layout, work_limit, projected_limit)
    R = order.size
    width = kmax + 1
    exact = True
    covers = np.zeros(1, dtype=np.uint64)
    # Columns: k = low..reach, reach growing with the sets; low rises when every
    # frontier's entries below it are empty (the beam's entry margin drops them).
    best = np.zeros((1, 1))
    mass = np.zeros((1, 1))
    low = 0
    back: list[_Back] = []
    work = 0
    widest = 1
    for step in range(R):
        keep, pair_row, pair_h, cols, step_work = _vector_step_rows(
            problem, layout, covers, step, best.shape[1], low, kmax, work, work_limit
        )
        work += step_work
        _check_limits(work, work_limit, deadline)
        check_projection(
            "frontier search", work, step_work, R - 1 - step, projected_limit, work_limit
        )
        if keep.size + pair_row.size == 0:  # an exactly-once resource no frontier meets
            infeasible = np.full(width, _NEG_INF)
            return _result(infeasible, infeasible, [None] * width, work, widest, exact)
        cand_best, cand_mass = _vector_candidates(problem, best, mass, keep, pair_row, pair_h, cols)
        cand_covers = np.concatenate(
            [covers[keep] >> _ONE, (covers[pair_row] | layout[0][pair_h]) >> _ONE]
        )
        covers, best, mass, winner = _vector_merged(cand_covers, cand_best, cand_mass)
        widest = max(widest, covers.size)
        covers, best, mass, winner, lo, kept_all = _vector_pruned(
            covers, best, mass, winner, entry_margin, max_frontiers
        )
        low += lo
        exact = exact and kept_all
        decision = np.concatenate([np.full(keep.size, -1, dtype=np.int64), pair_h])
        back.append((winner.astype(np.int32), np.concatenate([keep, pair_row]), decision, low))
    # Every frontier word is 0 after the last position: one state remains.
    return _final_vector_result(problem, back, best[0], mass[0], low, width, work, widest, exact)


def _vector_pruned(
    covers: NDArray[np.uint64],
    best: NDArray[np.float64],
    mass: NDArray[np.float64],
    winner: NDArray[np.int64],
    entry_margin: float | None,
    max_frontiers: int | None,
) -> tuple[
    NDArray[np.uint64], NDArray[np.float64], NDArray[np.float64], NDArray[np.int64], int, bool
]:
    """A step's merged frontiers after the beam (:func:`_vector_entry_margin`, then
    :func:`_vector_beam`; ``None``: that part off): the tables, the columns dropped on
    the left and whether nothing was dropped."""
    low_rise = 0
    kept_all = True
    if entry_margin is not None:
        best, mass, winner, low_rise, dropped = _vector_entry_margin(
            best, mass, winner, entry_margin
        )
        kept_all = not dropped
    if max_frontiers is not None and covers.size > max_frontiers:
        covers, best, mass, winner = _vector_beam(covers, best, mass, winner, max_frontiers)
        kept_all = False
    return covers, best, mass, winner, low_rise, kept_all


def _final_vector_result(
    problem: PackingProblem,
    back: list[_Back],
    best: NDArray[np.float64],
    mass: NDArray[np.float64],
    low: int,
    width: int,
    work: int,
    widest: int,
    exact: bool,
) -> FrontierResult:
    """The result from the last frontier's best scores and masses (shape (columns,),
    for k = low..) and the steps ``back``."""
    final_best = np.full(width, _NEG_INF)
    final_mass = np.full(width, _NEG_INF)
    final_best[low : low + best.shape[0]] = best
    final_mass[low : low + mass.shape[0]] = mass
    sets = _traced_vector_sets(back, problem.counts.astype(np.int64), final_best, low)
    return _result(final_best, final_mass, sets, work, widest, exact)


def _vector_step_rows(
    problem: PackingProblem,
    layout: _WordLayout,
    covers: NDArray[np.uint64],
    step: int,
    span_now: int,
    low: int,
    kmax: int,
    work: int,
    work_limit: int | None,
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], int, int]:
    """A step's candidate rows: the frontiers kept (all, or those covering an
    exactly-once position), then the open (frontier, hypothesis) pairs
    (:func:`open_pairs`, within what ``work_limit`` leaves); the k columns after the
    step (the ``span_now`` columns k = low..low + span_now - 1, one more where a
    counted hypothesis is taken and ``low + span_now`` is at most ``kmax``) and the
    step's work, charged before the step's arrays are built so that a limit never
    overshoots.

    Returns
    -------
    keep, pair_row, pair_h : ndarray of int
    cols, step_work : int
    """
    relative, by_start, bounds, exactly_one = layout
    counts = problem.counts.astype(np.int64)
    covered = (covers & _ONE).astype(bool)
    keep = np.flatnonzero(covered) if exactly_one[step] else np.arange(covers.size)
    starting = by_start[bounds[step] : bounds[step + 1]]
    most = pair_budget(work_limit, work, span_now, keep.size, _VECTOR_ENTRIES_PER_TRANSITION)
    pair_row, pair_h = open_pairs(covers, covered, relative, starting, most)
    grow = int(pair_h.size > 0 and counts[pair_h].max() > 0 and low + span_now <= kmax)
    cols = span_now + grow
    step_work = -(-(keep.size + pair_row.size) * cols // _VECTOR_ENTRIES_PER_TRANSITION)
    return keep, pair_row, pair_h, cols, step_work


def _vector_candidates(
    problem: PackingProblem,
    best: NDArray[np.float64],
    mass: NDArray[np.float64],
    keep: NDArray[np.int64],
    pair_row: NDArray[np.int64],
    pair_h: NDArray[np.int64],
    cols: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each candidate row's best scores and masses after the step, shape (C, cols): a
    kept frontier's entries as they were, a pair's frontier's entries shifted by the
    hypothesis's count and plus its score and log-weight; ``-inf`` elsewhere."""
    counts = problem.counts.astype(np.int64)
    span_now = best.shape[1]
    size = keep.size + pair_row.size
    cand_best = np.full((size, cols), _NEG_INF)
    cand_mass = np.full((size, cols), _NEG_INF)
    cand_best[: keep.size, :span_now] = best[keep]
    cand_mass[: keep.size, :span_now] = mass[keep]
    taken = keep.size + np.arange(pair_h.size)
    for c in (0, 1):
        sel = counts[pair_h] == c
        if not np.any(sel):
            continue
        rows_in, rows_out = pair_row[sel], taken[sel]
        span = min(span_now, cols - c)
        scores, weights = problem.scores[pair_h[sel], None], problem.weights[pair_h[sel], None]
        cand_best[rows_out, c : c + span] = best[rows_in, :span] + scores
        cand_mass[rows_out, c : c + span] = mass[rows_in, :span] + weights
    return cand_best, cand_mass


def _vector_merged(
    cand_covers: NDArray[np.uint64],
    cand_best: NDArray[np.float64],
    cand_mass: NDArray[np.float64],
) -> tuple[NDArray[np.uint64], NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """The frontiers the candidates reach (sorted distinct words), their best scores and
    masses, and each (frontier, k)'s winning candidate: one stable sort by word keeps a
    frontier's candidates in order, masses are summed by ``logaddexp.reduceat`` and the
    first candidate reaching the maximum wins."""
    ranked = np.argsort(cand_covers, kind="stable")
    sorted_covers = cand_covers[ranked]
    new_frontier = np.r_[True, sorted_covers[1:] != sorted_covers[:-1]]
    starts = np.flatnonzero(new_frontier)
    group_sorted = np.cumsum(new_frontier) - 1
    sorted_best = cand_best[ranked]
    with np.errstate(invalid="ignore"):
        mass = np.logaddexp.reduceat(cand_mass[ranked], starts, axis=0)
    best = np.maximum.reduceat(sorted_best, starts, axis=0)
    hits = np.where(sorted_best == best[group_sorted], np.arange(ranked.size)[:, None], ranked.size)
    winner = ranked[np.minimum.reduceat(hits, starts, axis=0)]
    return sorted_covers[starts], best, mass, winner


def _vector_entry_margin(
    best: NDArray[np.float64],
    mass: NDArray[np.float64],
    winner: NDArray[np.int64],
    entry_margin: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64], int, bool]:
    """Drop each frontier's k-entries more than ``entry_margin`` below its heaviest, and
    the columns then empty in every frontier at either end (the next steps' work
    shrinks).  Returns the tables, the columns dropped on the left (``low`` rises by
    them) and whether anything was dropped."""
    light = mass < mass.max(axis=1, keepdims=True) - entry_margin
    if not np.any(light):
        return best, mass, winner, 0, False
    mass[light] = best[light] = _NEG_INF
    live = np.flatnonzero(np.isfinite(mass).any(axis=0))
    if live.size and (live[0] > 0 or live[-1] < mass.shape[1] - 1):
        lo, hi = int(live[0]), int(live[-1]) + 1
        return best[:, lo:hi], mass[:, lo:hi], winner[:, lo:hi], lo, True
    return best, mass, winner, 0, True


def _vector_beam(
    covers: NDArray[np.uint64],
    best: NDArray[np.float64],
    mass: NDArray[np.float64],
    winner: NDArray[np.int64],
    max_frontiers: int,
) -> tuple[NDArray[np.uint64], NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """The ``max_frontiers`` frontiers of heaviest entry (ties: the earlier word), in
    their order."""
    heaviest = mass.max(axis=1)
    kept = np.sort(np.argsort(-heaviest, kind="stable")[:max_frontiers])
    return covers[kept], best[kept], mass[kept], winner[kept]


def _traced_vector_sets(
    back: list[_Back], counts: NDArray[np.int64], final_best: NDArray[np.float64], low: int
) -> list[tuple[int, ...] | None]:
    """Each k's best set (``None`` where the best score is not finite), by following
    the winners of the steps ``back`` from the last frontier to the first."""
    sets: list[tuple[int, ...] | None] = [None] * final_best.shape[0]
    for k in range(low, final_best.shape[0]):
        if not np.isfinite(final_best[k]):
            continue
        chosen = []
        state, remaining = 0, k
        for winners, src, decision, first_k in reversed(back):
            candidate = int(winners[state, remaining - first_k])
            h = int(decision[candidate])
            state = int(src[candidate])
            if h >= 0:
                chosen.append(h)
                remaining -= int(counts[h])
        sets[k] = tuple(sorted(chosen))
    return sets


def _compiled_search(
    kernel: ModuleType,
    problem: PackingProblem,
    kmax: int,
    layout: _WordLayout,
    work_limit: int | None,
    projected_limit: float | None,
) -> FrontierResult:
    """The exact vectorised search in the compiled kernel
    (:func:`mapassoc.formulations.compiled_frontier.exact_search`): the same result, the
    same work, and the same stops as :func:`_vectorised_search` without a beam."""
    relative, by_start, bounds, exactly_one = layout
    status, work, widest, best, mass, members, sizes = kernel.exact_search(
        relative,
        by_start,
        bounds,
        exactly_one,
        problem.counts.astype(np.int64),
        np.ascontiguousarray(problem.scores, dtype=np.float64),
        np.ascontiguousarray(problem.weights, dtype=np.float64),
        int(kmax),
        kernel_work_limit(work_limit),
        math.inf if projected_limit is None else float(projected_limit),
        _VECTOR_ENTRIES_PER_TRANSITION,
        PAIR_BLOCK_ENTRIES,
    )
    work, widest = int(work), int(widest)
    if status == kernel.PAST_WORK_LIMIT:
        _check_limits(work, work_limit, None)
    if status == kernel.PAST_PROJECTION and projected_limit is not None:
        raise _projected_stop("frontier search", work, projected_limit, work_limit)
    if status == kernel.INFEASIBLE:
        infeasible = np.full(kmax + 1, _NEG_INF)
        return _result(infeasible, infeasible, [None] * (kmax + 1), work, widest)
    sets: list[tuple[int, ...] | None] = [
        None if size < 0 else tuple(members[k, :size].tolist())
        for k, size in enumerate(sizes.tolist())
    ]
    return _result(best, mass, sets, work, widest)


def _result(
    best: NDArray[np.float64],
    mass: NDArray[np.float64],
    sets: list[tuple[int, ...] | None],
    work: int,
    widest: int,
    exact: bool = True,
) -> FrontierResult:
    return FrontierResult(
        best=np.asarray(best, dtype=float).copy(),
        best_sets=tuple(sets),
        log_mass=np.asarray(mass, dtype=float).copy(),
        exact=exact,
        work=work,
        max_frontiers=widest,
    )


def independent_sums(
    scores: NDArray[np.float64], log_weights: NDArray[np.float64], indices: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """Per-k best score and log-mass of hypotheses that are each taken or not, freely.

    The best set of k holds the k best scores (equal scores: smaller index first, the
    tie order), so ``best`` is a prefix sum; the mass of k is the k-th elementary
    symmetric polynomial of the weights, by the recursion
    ``e_k(first i+1) = e_k(first i) + w_i e_(k-1)(first i)`` in log space.

    Returns
    -------
    best, log_mass : ndarray, shape (n + 1,)
    ranked : ndarray of int, shape (n,)
        ``indices`` by decreasing score.
    """
    order = np.lexsort((indices, -scores))
    best = np.concatenate([[0.0], np.cumsum(scores[order])])
    mass = np.full(scores.shape[0] + 1, _NEG_INF)
    mass[0] = 0.0
    for i, w in enumerate(np.asarray(log_weights, dtype=float).tolist()):
        mass[1 : i + 2] = np.logaddexp(mass[1 : i + 2], mass[: i + 1] + w)
    return best, mass, np.asarray(indices, dtype=np.int64)[order]


def _with_lone(
    main: FrontierResult,
    main_index: NDArray[np.int64],
    problem: PackingProblem,
    lone: NDArray[np.int64],
    kmax: int,
) -> FrontierResult:
    """Add hypotheses without resources to a search result (of the others, renumbered).

    Uncounted ones change no k: each is taken when its score is positive and adds
    ``log(1 + e^w)`` to every mass.  Counted ones form :func:`independent_sums`,
    combined by max-plus and sum-product convolution (fewer of them on exact ties).
    """
    counted = problem.counts[lone]
    free_scores, free_weights = problem.scores[lone], problem.weights[lone]
    uncounted = ~counted
    always = lone[uncounted][free_scores[uncounted] > 0]
    shift_best = float(np.sum(np.maximum(free_scores[uncounted], 0.0)))
    shift_mass = float(np.sum(np.logaddexp(0.0, free_weights[uncounted])))
    part_best, part_mass, ranked = independent_sums(
        free_scores[counted], free_weights[counted], lone[counted]
    )
    size = kmax + 1
    best, share = max_plus(main.best, part_best, size)
    mass = sum_product(main.log_mass, part_mass, size)
    sets: list[tuple[int, ...] | None] = [None] * size
    for k in np.flatnonzero(share >= 0).tolist():
        inner = main.best_sets[k - share[k]]
        if inner is None:
            continue
        members = [int(main_index[h]) for h in inner] + ranked[: share[k]].tolist()
        sets[k] = tuple(sorted(members + always.tolist()))
    found = np.isfinite(best)
    best[found] += shift_best
    mass[np.isfinite(mass)] += shift_mass
    return FrontierResult(
        best=best,
        best_sets=tuple(sets),
        log_mass=mass,
        exact=main.exact,
        work=main.work + int(part_best.shape[0]) * size,
        max_frontiers=main.max_frontiers,
    )
