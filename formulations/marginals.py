"""Posterior marginals of a packing problem's hypotheses: the frontier search run forward
and backward, and the messages between independent clusters.

A feasible set S of a cluster has log-weight ``w(S) = sum_{h in S} log_weight_h`` and
``k(S)`` counted hypotheses.  Given a *seed* ``g[k]`` (log space, k = 0..kmax: what the
rest of the window makes of a cluster with k counted hypotheses, see
:func:`cluster_messages`), :func:`frontier_marginals` computes for every hypothesis h

    log N_h = log sum_{S feasible, h in S} exp(w(S) + g[k(S)])

and ``log Z = log sum_S exp(w(S) + g[k(S)])``, so that ``N_h / Z`` is the marginal
probability that h is in the set under the weights ``exp(w(S) + g[k(S)])``.

It is the dynamic program of :mod:`mapassoc.formulations.frontier` (same resource
order, same frontiers) run twice: the forward pass stores, per step, every frontier's
per-k log-mass ``alpha`` (sets of the decisions so far); the backward pass, seeded at
the last step with ``g``, carries ``beta[frontier, j]``: the log of the summed weight of
every completion from that frontier, times ``g`` at ``j`` plus the completion's count.
A hypothesis h is taken at the step of its first resource from some frontier ``f`` into
a frontier ``f'``; its sets are exactly the paths through one such transition, so

    N_h = sum_{transitions (f -> f') taking h} sum_j alpha[f, j] e^{w_h} beta[f', j + c_h]

with ``c_h`` whether h counts.  Forward, backward and this combination each cost about
one k-entry per (frontier, decision) pair: about three times the plain search, whatever
kmax, because the seed folds the per-k sum into the backward messages (a per-k table of
sets containing h would cost kmax times more).

With ``max_frontiers`` (and ``entry_margin``) the forward pass is the beam of
:func:`~mapassoc.formulations.frontier.frontier_search`; the backward pass then runs only
through the (frontier, k) entries the beam kept, so ``log_mass``, ``N_h`` and ``Z`` are
all sums over the *same* subset of feasible sets (each counted once): lower bounds of
the full sums, and ``N_h / Z`` the marginal among the sets captured.  A beam's memory
grows with its frontiers times the hypotheses and positions, not with how far the
hypotheses span: where a hypothesis spans 64 positions or more (a clutter burst's
cluster: hundreds of thousands of hypotheses spanning thousands of positions), its
frontiers are rows of the positions they cover ahead, which order, merge and rank as
the bit words do.  The compiled pass takes frontiers of several 64-bit words, up to
:data:`_KERNEL_WORDS` of them (the clusters of a confidence window in dense clutter);
wider spans stay on the numpy pass.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mapassoc.accelerate import compiled_module
from mapassoc.formulations import frontier as frontier_module
from mapassoc.formulations.convolution import sum_product
from mapassoc.formulations.frontier import (
    FRONTIER_KERNELS,
    SearchLimitExceeded,
    check_projection,
    fits_counted_work,
    frontier_words,
    hypothesis_spans,
    kernel_work_limit,
    open_pairs,
    pair_budget,
    projected_work_limit,
    resource_order,
)
from mapassoc.formulations.packing import PackingProblem
from mapassoc.log_space import log_sum_exp

__all__ = [
    "ENUMERATION_MAX_HYPOTHESES",
    "FrontierMarginals",
    "enumerated_marginals",
    "frontier_marginals",
    "cluster_messages",
    "log_subtract",
]

_NEG_INF = -math.inf
_WORD_BITS = 64
_ENTRIES_PER_TRANSITION = 8
"""Work is counted as in the vectorised frontier search: eight k-entries a transition."""


@dataclass(frozen=True, eq=False)
class FrontierMarginals:
    """Per-hypothesis log-masses of the sets containing it, for one or more seeds.

    Attributes
    ----------
    log_mass : ndarray, shape (kmax + 1,)
        Per k, the log-mass of the sets summed (all feasible sets when ``exact``).
    log_total : ndarray, shape (S,)
        ``log Z`` for each of the S seeds: ``logsumexp_k(log_mass[k] + seed[k])``.
    log_containing : ndarray, shape (S, H)
        ``log N_h`` for each seed and hypothesis (``-inf``: no set summed contains h).
    exact : bool
        Whether every feasible set was summed (False when the beam dropped something).
    work : int
        Transitions of the forward pass (the backward pass and the combination cost
        about as much again each).
    """

    log_mass: NDArray[np.float64]
    log_total: NDArray[np.float64]
    log_containing: NDArray[np.float64]
    exact: bool
    work: int


def log_subtract(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``log(exp(a) - exp(b))`` elementwise, for ``b <= a``; ``-inf`` where ``b == a``.

    Raises
    ------
    ValueError
        Where ``b > a`` (the difference would be negative).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if np.any(b > a):
        raise ValueError("log_subtract needs b <= a elementwise")
    out = np.full(np.broadcast(a, b).shape, _NEG_INF)
    live = np.broadcast_to(np.isfinite(a), out.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        diff = np.broadcast_to(b, out.shape) - np.broadcast_to(a, out.shape)
        out[live] = np.broadcast_to(a, out.shape)[live] + np.log(-np.expm1(diff[live]))
    return out


def _checked_seeds(seeds: NDArray[np.float64]) -> NDArray[np.float64]:
    """``seeds`` as a (S, kmax + 1) float array (one row for a 1-D input); raises
    ValueError for another shape or NaN."""
    seeds = np.asarray(seeds, dtype=float)
    if seeds.ndim == 1:
        seeds = seeds[None, :]
    if seeds.ndim != 2 or seeds.shape[1] < 1 or np.any(np.isnan(seeds)):
        raise ValueError("seeds must be a (S, kmax + 1) array without NaN")
    return seeds


def _with_private_resources(problem: PackingProblem) -> PackingProblem:
    """The problem with every hypothesis that uses no resource given one of its own
    (at most once): the feasible sets, weights and counts are unchanged."""
    lengths = np.diff(problem.resource_indptr)
    lone = np.flatnonzero(lengths == 0)
    if lone.size == 0:
        return problem
    R = problem.num_resources
    new_lengths = np.where(lengths == 0, 1, lengths)
    indptr = np.concatenate([[0], np.cumsum(new_lengths)]).astype(np.int64)
    indices = np.empty(int(indptr[-1]), dtype=np.int64)
    owner_old = np.repeat(np.arange(problem.num_hypotheses), lengths)
    offset_old = np.arange(problem.resource_indices.size) - problem.resource_indptr[owner_old]
    indices[indptr[owner_old] + offset_old] = problem.resource_indices
    indices[indptr[lone]] = R + np.arange(lone.size)
    return PackingProblem.derived(
        scores=problem.scores,
        resource_indptr=indptr,
        resource_indices=indices,
        exactly_one=np.r_[problem.exactly_one, np.zeros(lone.size, dtype=bool)],
        counts=problem.counts,
        log_weights=problem.weights,
    )


@dataclass
class _Step:
    """What the backward pass needs of one forward step."""

    alpha: NDArray[np.float64]  # (F, cols): log-mass per frontier before the step
    source: NDArray[np.int64]  # candidate -> frontier row before the step
    decision: NDArray[np.int64]  # candidate -> hypothesis taken (-1: none)
    target: NDArray[np.int64]  # candidate -> frontier row after the step (-1: dropped)


def frontier_marginals(
    problem: PackingProblem,
    seeds: NDArray[np.float64],
    *,
    max_frontiers: int | None = None,
    entry_margin: float | None = None,
    work_limit: int | None = None,
    deadline: float | None = None,
    work_projection: float | None = None,
) -> FrontierMarginals:
    """Forward-backward frontier search: ``log N_h`` and ``log Z`` for each seed.

    Where numba is installed (the ``accelerate`` extra) and no ``deadline`` is given, both
    passes run compiled (:func:`mapassoc.formulations.compiled_frontier.forward_backward`:
    the same per-k masses, work, stops and ``exact``; ``log N_h`` and ``log Z`` equal to
    round-off); ``MAPASSOC_COMPILED=0`` keeps them in numpy.

    Parameters
    ----------
    problem : PackingProblem
        Log-weights are summed (scores are not used).
    seeds : ndarray, shape (S, kmax + 1) or (kmax + 1,)
        Log-factor of a set by its number of counted hypotheses k; sets with more than
        kmax counted are not followed (their factor is 0).  ``-inf`` entries allowed.
    max_frontiers, entry_margin : optional
        The beam of :func:`~mapassoc.formulations.frontier.frontier_search` (frontiers
        ranked by their heaviest entry, ties by frontier word); every result is then a
        sum over the sets the beam kept (``exact`` False when it dropped any).
    work_limit : int, optional
        Most transitions of the forward pass, as in the frontier search.
    work_projection : float, optional
        With ``work_limit``: also stop when on course for more than this many times the
        limit, as :func:`~mapassoc.formulations.frontier.frontier_search` does (reason
        ``"projected"``); and, as there, an exact run of
        :data:`~mapassoc.formulations.frontier.WORK_COUNT_MIN_HYPOTHESES` hypotheses or
        more counts its work first and stops at once or runs whole.
    deadline : float, optional
        ``time.perf_counter()`` value past which the search stops.

    Returns
    -------
    FrontierMarginals

    Raises
    ------
    SearchLimitExceeded
        Past ``work_limit`` (or its projection) or ``deadline``.
    """
    seeds = _checked_seeds(seeds)
    if max_frontiers is not None and max_frontiers < 1:
        raise ValueError(f"max_frontiers must be >= 1, got {max_frontiers!r}")
    projected_limit = projected_work_limit(work_projection, work_limit)
    private = _with_private_resources(problem)
    order = resource_order(private)
    # The forward pass is the exact frontier search's (the same rows and columns, the
    # same work per entry): its work is counted first, as the search's is.
    if (
        work_limit is not None
        and max_frontiers is None
        and entry_margin is None
        and fits_counted_work(
            "frontier marginals",
            private,
            seeds.shape[1] - 1,
            order,
            work_limit=work_limit,
            deadline=deadline,
        )
    ):
        projected_limit = None  # it runs whole: nothing to project
    kernel = compiled_module(FRONTIER_KERNELS) if deadline is None else None
    if kernel is not None:
        compiled = _compiled_forward_backward(
            kernel,
            private,
            order,
            seeds,
            max_frontiers,
            entry_margin,
            work_limit,
            projected_limit,
        )
        if compiled is not None:
            return compiled
    with np.errstate(invalid="ignore", over="ignore"):
        return _forward_backward(
            private,
            order,
            seeds,
            max_frontiers,
            entry_margin,
            work_limit,
            deadline,
            projected_limit,
        )


def _compiled_forward_backward(
    kernel: ModuleType,
    problem: PackingProblem,
    order: NDArray[np.int64],
    seeds: NDArray[np.float64],
    max_frontiers: int | None,
    entry_margin: float | None,
    work_limit: int | None,
    projected_limit: float | None,
) -> FrontierMarginals | None:
    """:func:`_forward_backward` in the compiled kernel
    (:func:`mapassoc.formulations.compiled_frontier.forward_backward`): the same sums to
    round-off, the same work, stops and ``exact``.  A frontier is a row of
    :func:`_word_rows` words; ``None`` where a hypothesis spans more positions than
    :data:`_KERNEL_WORDS` words hold, or the hypotheses' rows would pass
    :data:`_KERNEL_ROW_WORDS` words (the numpy pass then takes Python integers as words,
    or, for a beam, rows of covered positions: :class:`_PositionRows`)."""
    layout = _word_rows(problem, order)
    if layout is None:
        return None
    relative, by_start, bounds, exactly_one = layout
    status, work, step_work, remaining, exact, log_mass, log_total, containing = (
        kernel.forward_backward(
            relative,
            by_start,
            bounds,
            exactly_one,
            problem.counts.astype(np.int64),
            np.ascontiguousarray(problem.weights, dtype=np.float64),
            np.ascontiguousarray(seeds, dtype=np.float64),
            -1 if max_frontiers is None else int(max_frontiers),
            math.inf if entry_margin is None else float(entry_margin),
            kernel_work_limit(work_limit),
            math.inf if projected_limit is None else float(projected_limit),
            _ENTRIES_PER_TRANSITION,
            frontier_module.PAIR_BLOCK_ENTRIES,  # read at the call, as open_pairs does
        )
    )
    work = int(work)
    if status == kernel.PAST_WORK_LIMIT:
        _check(work, work_limit, None)
    if status == kernel.PAST_PROJECTION:
        check_projection(
            "frontier marginals", work, int(step_work), int(remaining), projected_limit, work_limit
        )
    return FrontierMarginals(log_mass, log_total, containing, bool(exact), work)


_KERNEL_WORDS = 16
"""Most uint64 words of a frontier of the compiled pass (spans up to 1,024 positions):
past them, the numpy pass, whose beam's position rows cost the positions covered
rather than a bit per position spanned (a clutter burst's cluster spans thousands)."""

_KERNEL_ROW_WORDS = 1 << 22
"""Most words of the hypotheses' rows the compiled pass builds (32 MB), for the same
reason."""


def _word_rows(
    problem: PackingProblem, order: NDArray[np.int64]
) -> tuple[NDArray[np.uint64], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]] | None:
    """:func:`~mapassoc.formulations.frontier.frontier_words` with each hypothesis's
    resources as a row of W words (bit i of word w: the position 64 w + i after its
    first), W the fewest that hold the widest span; ``None`` past :data:`_KERNEL_WORDS`
    or :data:`_KERNEL_ROW_WORDS`."""
    layout = frontier_words(problem, order)
    if layout is not None:
        relative, by_start, bounds, exactly_one = layout
        return relative[:, None].copy(), by_start, bounds, exactly_one
    H = problem.num_hypotheses
    owner, offsets, first, last = hypothesis_spans(problem, order)
    W = int(np.max(last - first)) // _WORD_BITS + 1
    if W > _KERNEL_WORDS or H * W > _KERNEL_ROW_WORDS:
        return None
    rows = np.zeros((H, W), dtype=np.uint64)
    bits = np.left_shift(np.uint64(1), (offsets % _WORD_BITS).astype(np.uint64))
    np.bitwise_or.at(rows, (owner, offsets // _WORD_BITS), bits)
    by_start = np.argsort(first, kind="stable").astype(np.int64, copy=False)
    bounds = np.searchsorted(first[by_start], np.arange(order.size + 1)).astype(np.int64)
    exactly_one = np.ascontiguousarray(problem.exactly_one[order], dtype=np.bool_)
    return rows, by_start, bounds, exactly_one


_Spans = tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]
""":func:`~mapassoc.formulations.frontier.hypothesis_spans`: owner, offsets, first, last."""


class _Words:
    """Frontier words as bit words relative to the current position: one uint64 when
    every hypothesis spans fewer than 64 positions, Python integers (an object array)
    otherwise.  Bit ``i`` of a word: the position ``i`` ahead of the current one is
    covered by a hypothesis already taken."""

    def __init__(self, problem: PackingProblem, spans: _Spans) -> None:
        H = problem.num_hypotheses
        owner, offsets, first, last = spans
        self.first = first
        if H == 0 or np.all(last - first < _WORD_BITS):
            self.relative: NDArray[Any] = np.zeros(H, dtype=np.uint64)
            np.bitwise_or.at(
                self.relative, owner, np.left_shift(np.uint64(1), offsets.astype(np.uint64))
            )
            self.one: Any = np.uint64(1)
            self.word: Any = np.uint64
        else:
            codes = [0] * H
            for h, o in zip(owner.tolist(), offsets.tolist(), strict=True):
                codes[h] |= 1 << o
            self.relative = np.empty(H, dtype=object)
            self.relative[:] = codes
            self.one, self.word = 1, object

    def initial(self) -> NDArray[Any]:
        return np.zeros(1, dtype=self.word)

    def covered(self, covers: NDArray[Any], step: int) -> NDArray[np.bool_]:
        return (covers & self.one).astype(bool)

    def pairs(
        self,
        covers: NDArray[Any],
        covered: NDArray[np.bool_],
        starting: NDArray[np.int64],
        step: int,
        most: int | None,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        return open_pairs(covers, covered, self.relative, starting, most)

    def candidates(
        self,
        covers: NDArray[Any],
        keep: NDArray[np.int64],
        pair_row: NDArray[np.int64],
        pair_h: NDArray[np.int64],
        step: int,
    ) -> NDArray[Any]:
        one = self.one
        return np.concatenate(
            [covers[keep] >> one, (covers[pair_row] | self.relative[pair_h]) >> one]
        ).astype(self.word)

    @staticmethod
    def grouped(cand: NDArray[Any]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Candidates ranked by word (stable) and where a new word starts in that rank."""
        ranked = np.argsort(cand, kind="stable")
        ordered = cand[ranked]
        return ranked, np.r_[True, ordered[1:] != ordered[:-1]]


class _PositionRows(_Words):
    """Frontier words for a beam over hypotheses spanning 64 positions or more: each
    frontier is the row of the positions it covers ahead (absolute, descending, padded
    with -1), so a word costs the positions covered rather than a bit per position
    spanned, and the step's memory stays proportional to its candidates.

    Rows compare as the bit words do (highest position first; a row that is a prefix of
    another is the smaller), so frontiers are numbered, merged and ranked exactly as
    with :class:`_Words`, and the sums are the same.
    """

    def __init__(self, problem: PackingProblem, spans: _Spans) -> None:
        H = problem.num_hypotheses
        owner, offsets, first, _ = spans
        self.first = first
        spots = first[owner] + offsets
        lengths = np.diff(problem.resource_indptr)
        width = int(lengths.max()) if H else 0
        rows = np.full((H, max(width, 1)), -1, dtype=np.int64)
        column = np.arange(spots.size) - np.repeat(problem.resource_indptr[:-1], lengths)
        rows[owner, column] = spots
        self.rows = -np.sort(-rows, axis=1)  # descending, -1 last

    def initial(self) -> NDArray[Any]:
        return np.full((1, 1), -1, dtype=np.int64)

    def covered(self, covers: NDArray[Any], step: int) -> NDArray[np.bool_]:
        return np.any(covers == step, axis=1)

    def pairs(
        self,
        covers: NDArray[Any],
        covered: NDArray[np.bool_],
        starting: NDArray[np.int64],
        step: int,
        most: int | None,
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Every fitting (open frontier, starting hypothesis) pair, rows first, as
        :func:`open_pairs` orders them (all of them: ``most`` only spares work there)."""
        open_rows = np.flatnonzero(~covered)
        if not (starting.size and open_rows.size):
            empty = np.zeros(0, dtype=np.int64)
            return empty, empty
        cover = covers[open_rows]
        held = np.unique(cover[cover >= 0])  # positions some open frontier covers
        clash = np.zeros((starting.size, open_rows.size), dtype=bool)
        if held.size:
            wanted = self.rows[starting]
            spot = np.minimum(np.searchsorted(held, wanted), held.size - 1)
            hit_h, hit_col = np.nonzero((wanted >= 0) & (held[spot] == wanted))
            if hit_h.size:
                # (open frontier, hit): the frontier covers the hit's position
                holds = np.any(cover[:, :, None] == wanted[hit_h, hit_col], axis=1)
                np.logical_or.at(clash, hit_h, holds.T)
        pair_row, pair_h = np.nonzero(~clash.T)
        return open_rows[pair_row], starting[pair_h]

    def candidates(
        self,
        covers: NDArray[Any],
        keep: NDArray[np.int64],
        pair_row: NDArray[np.int64],
        pair_h: NDArray[np.int64],
        step: int,
    ) -> NDArray[Any]:
        width = covers.shape[1] + self.rows.shape[1]
        cand = np.full((keep.size + pair_row.size, width), -1, dtype=np.int64)
        cand[: keep.size, : covers.shape[1]] = covers[keep]
        taken = cand[keep.size :]
        taken[:, : covers.shape[1]] = covers[pair_row]
        taken[:, covers.shape[1] :] = self.rows[pair_h]
        cand[cand == step] = -1  # the position passed
        cand[keep.size :] = -np.sort(-taken, axis=1)
        used = np.flatnonzero(np.any(cand >= 0, axis=0))
        return cand[:, : max(int(used[-1]) + 1 if used.size else 0, 1)]

    @staticmethod
    def grouped(cand: NDArray[Any]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        ranked = np.lexsort(cand.T[::-1])  # first column (the highest position) first
        ordered = cand[ranked]
        return ranked, np.r_[True, np.any(ordered[1:] != ordered[:-1], axis=1)]


def _forward_backward(
    problem: PackingProblem,
    order: NDArray[np.int64],
    seeds: NDArray[np.float64],
    max_frontiers: int | None,
    entry_margin: float | None,
    work_limit: int | None,
    deadline: float | None,
    projected_limit: float | None = None,
) -> FrontierMarginals:
    H = problem.num_hypotheses
    S, width = seeds.shape
    kmax = width - 1
    R = order.size
    words = _frontier_words(problem, order, max_frontiers)
    counts = problem.counts.astype(np.int64)
    weights = problem.weights
    by_start = np.argsort(words.first, kind="stable")
    bounds = np.searchsorted(words.first[by_start], np.arange(R + 1))
    exactly_one = problem.exactly_one[order]

    exact = True
    covers: NDArray[Any] = words.initial()
    mass = np.zeros((1, 1))
    steps: list[_Step] = []
    work = 0
    for step in range(R):
        covered = words.covered(covers, step)
        keep = np.flatnonzero(covered) if exactly_one[step] else np.arange(len(covers))
        starting = by_start[bounds[step] : bounds[step + 1]]
        reach = mass.shape[1] - 1
        most = pair_budget(work_limit, work, reach + 1, keep.size, _ENTRIES_PER_TRANSITION)
        pair_row, pair_h = words.pairs(covers, covered, starting, step, most)
        grow = int(pair_h.size > 0 and counts[pair_h].max() > 0 and reach < kmax)
        cols = reach + 1 + grow
        source = np.concatenate([keep, pair_row]).astype(np.int64)
        step_work = -(-source.size * cols // _ENTRIES_PER_TRANSITION)
        work += step_work
        _check(work, work_limit, deadline)
        check_projection(
            "frontier marginals", work, step_work, R - 1 - step, projected_limit, work_limit
        )
        if source.size == 0:  # an exactly-once resource no frontier can satisfy
            return FrontierMarginals(
                np.full(width, _NEG_INF),
                np.full(S, _NEG_INF),
                np.full((S, H), _NEG_INF),
                exact,
                work,
            )
        cand = _candidate_masses(mass, keep, pair_row, pair_h, counts, weights, cols)
        cand_covers = words.candidates(covers, keep, pair_row, pair_h, step)
        decision = np.concatenate([np.full(keep.size, -1, dtype=np.int64), pair_h])
        ranked, new_frontier = words.grouped(cand_covers)
        starts = np.flatnonzero(new_frontier)
        target = np.empty(source.size, dtype=np.int64)
        target[ranked] = np.cumsum(new_frontier) - 1
        new_mass = np.logaddexp.reduceat(cand[ranked], starts, axis=0)
        new_covers = cand_covers[ranked[starts]]
        new_covers, new_mass, target, whole = _beam_cut(
            new_covers, new_mass, target, entry_margin, max_frontiers
        )
        exact = exact and whole
        # Only the candidates that reach a kept frontier carry anything backward.
        live = np.flatnonzero(target >= 0)
        steps.append(_Step(mass, source[live], decision[live], target[live]))
        covers, mass = new_covers, new_mass

    # Every frontier word is 0 after the last position: one frontier remains.
    log_mass = np.full(width, _NEG_INF)
    if len(covers):
        log_mass[: mass.shape[1]] = mass[0]
    total = np.array([_lse(log_mass + seed) for seed in seeds])
    containing = np.full((S, H), _NEG_INF)
    for s, seed in enumerate(seeds):
        containing[s] = _backward(steps, mass, seed, counts, weights, H)
    return FrontierMarginals(log_mass, total, containing, exact, work)


def _frontier_words(
    problem: PackingProblem, order: NDArray[np.int64], max_frontiers: int | None
) -> _Words:
    """The frontier words of a forward pass over ``problem`` in ``order``."""
    spans = hypothesis_spans(problem, order)
    _, _, first, last = spans
    if max_frontiers is not None and problem.num_hypotheses and np.any(
        last - first >= _WORD_BITS
    ):
        # A beam keeps few frontiers, each covering few positions ahead: rows of them
        # cost less than Python integers as wide as the hypotheses' spans.
        return _PositionRows(problem, spans)
    return _Words(problem, spans)


def _candidate_masses(
    mass: NDArray[np.float64],
    keep: NDArray[np.int64],
    pair_row: NDArray[np.int64],
    pair_h: NDArray[np.int64],
    counts: NDArray[np.int64],
    weights: NDArray[np.float64],
    cols: int,
) -> NDArray[np.float64]:
    """Per-k log-masses of one step's candidates, shape ``(keep + pairs, cols)``: the
    frontiers ``keep`` passed on as they are, then each (frontier, hypothesis) pair with
    the hypothesis' weight added and its count shifting k."""
    reach = mass.shape[1] - 1
    cand = np.full((keep.size + pair_row.size, cols), _NEG_INF)
    cand[: keep.size, : reach + 1] = mass[keep]
    taken = keep.size + np.arange(pair_h.size)
    for c in (0, 1):
        sel = counts[pair_h] == c
        if not np.any(sel):
            continue
        span = min(reach + 1, cols - c)
        cand[taken[sel], c : c + span] = mass[pair_row[sel], :span] + weights[pair_h[sel], None]
    return cand


def _beam_cut(
    covers: NDArray[Any],
    mass: NDArray[np.float64],
    target: NDArray[np.int64],
    entry_margin: float | None,
    max_frontiers: int | None,
) -> tuple[NDArray[Any], NDArray[np.float64], NDArray[np.int64], bool]:
    """The beam's cut of one step's new frontiers: entries ``entry_margin`` below their
    frontier's heaviest dropped, then only the ``max_frontiers`` heaviest frontiers kept
    (candidates reaching a dropped one get target -1); and whether nothing was cut."""
    whole = True
    if entry_margin is not None:
        light = mass < mass.max(axis=1, keepdims=True) - entry_margin
        if np.any(light):
            mass[light] = _NEG_INF
            whole = False
    if max_frontiers is not None and len(covers) > max_frontiers:
        heaviest = mass.max(axis=1)
        kept = np.sort(np.argsort(-heaviest, kind="stable")[:max_frontiers])
        renumber = np.full(len(covers), -1, dtype=np.int64)
        renumber[kept] = np.arange(kept.size)
        target = renumber[target]
        covers, mass = covers[kept], mass[kept]
        whole = False
    return covers, mass, target, whole


def _lse(values: NDArray[np.float64]) -> float:
    top = float(np.max(values)) if values.size else _NEG_INF
    if not math.isfinite(top):
        return _NEG_INF
    return top + math.log(float(np.sum(np.exp(values - top))))


def _backward(
    steps: Sequence[_Step],
    final_mass: NDArray[np.float64],
    seed: NDArray[np.float64],
    counts: NDArray[np.int64],
    weights: NDArray[np.float64],
    H: int,
) -> NDArray[np.float64]:
    """``log N_h`` for one seed (see the module docstring)."""
    containing = np.full(H, _NEG_INF)
    cols = final_mass.shape[1]
    beta = seed[None, :cols].copy()
    after = final_mass  # forward masses of the frontiers after the current step
    for rec in reversed(steps):
        # Paths run only through (frontier, k) entries the forward pass kept.
        beta = np.where(np.isfinite(after), beta, _NEG_INF)
        frontiers, width = rec.alpha.shape
        padded = np.full((beta.shape[0], width + 1), _NEG_INF)
        n = min(beta.shape[1], width + 1)
        padded[:, :n] = beta[:, :n]
        live = rec.target >= 0
        taken = np.maximum(rec.decision, 0)
        c = np.where(rec.decision >= 0, counts[taken], 0)
        w = np.where(rec.decision >= 0, weights[taken], 0.0)
        cand = np.full((rec.source.size, width), _NEG_INF)
        for shift in (0, 1):
            sel = live & (c == shift)
            if np.any(sel):
                cand[sel] = padded[rec.target[sel], shift : shift + width] + w[sel, None]
        pairs = np.flatnonzero(rec.decision >= 0)
        if pairs.size:
            through = log_sum_exp(rec.alpha[rec.source[pairs]] + cand[pairs], axis=1)
            np.logaddexp.at(containing, rec.decision[pairs], through)
        by_source = np.argsort(rec.source, kind="stable")
        sorted_source = rec.source[by_source]
        starts = np.flatnonzero(np.r_[True, sorted_source[1:] != sorted_source[:-1]])
        beta = np.full((frontiers, width), _NEG_INF)
        beta[sorted_source[starts]] = np.logaddexp.reduceat(cand[by_source], starts, axis=0)
        after = rec.alpha
    return containing


def _check(work: int, work_limit: int | None, deadline: float | None) -> None:
    if work_limit is not None and work > work_limit:
        raise SearchLimitExceeded(
            f"frontier marginals exceeded the work limit of {work_limit} transitions",
            reason="work",
            work=work,
        )
    if deadline is not None and time.perf_counter() > deadline:
        raise SearchLimitExceeded(
            "frontier marginals ran past the deadline", reason="deadline", work=work
        )


ENUMERATION_MAX_HYPOTHESES = 12
"""Most hypotheses :func:`enumerated_marginals` takes: at most 4,096 subsets.  Up to
this size listing every subset costs less than the frontier search forward and backward
(one vectorised pass against a step per position), and most clusters of a confidence
pass are this small."""


def enumerated_marginals(problem: PackingProblem, seeds: NDArray[np.float64]) -> FrontierMarginals:
    """``log N_h`` and ``log Z`` of a small problem by listing every subset of hypotheses.

    The same sums as :func:`frontier_marginals` without a beam (module docstring), each
    set weighted ``exp(w(S) + g[k(S)])``, summed in another order (equal to round-off).

    Parameters
    ----------
    problem : PackingProblem
        At most :data:`ENUMERATION_MAX_HYPOTHESES` hypotheses; log-weights are summed.
    seeds : ndarray, shape (S, kmax + 1) or (kmax + 1,)
        As in :func:`frontier_marginals`.

    Returns
    -------
    FrontierMarginals
        ``exact`` True; ``work`` the number of subsets listed (``2 ** H``).

    Raises
    ------
    ValueError
        With more than :data:`ENUMERATION_MAX_HYPOTHESES` hypotheses, or bad seeds.
    """
    seeds = _checked_seeds(seeds)
    H = problem.num_hypotheses
    if H > ENUMERATION_MAX_HYPOTHESES:
        raise ValueError(
            f"problem has {H} hypotheses; enumerated_marginals takes at most "
            f"{ENUMERATION_MAX_HYPOTHESES}"
        )
    S, width = seeds.shape
    member = _subsets(H)  # (2^H, H)
    incidence = np.zeros((H, problem.num_resources), dtype=np.int64)
    owner = np.repeat(np.arange(H), np.diff(problem.resource_indptr))
    incidence[owner, problem.resource_indices] = 1
    use = member.astype(np.int64) @ incidence  # (2^H, R): how often a set uses each
    feasible = np.all(use <= 1, axis=1) & np.all(use[:, problem.exactly_one] == 1, axis=1)
    k = member[:, problem.counts].sum(axis=1)
    feasible &= k < width
    member, k = member[feasible], k[feasible]
    weight = np.where(member, problem.weights[None, :], 0.0).sum(axis=1)
    log_mass = np.full(width, _NEG_INF)
    for j in np.unique(k).tolist():
        log_mass[j] = _lse(weight[k == j])
    value = weight[None, :] + seeds[:, k]  # (S, sets)
    top = np.max(value, axis=1, initial=_NEG_INF)
    live = np.isfinite(top)
    scaled = np.zeros_like(value)
    scaled[live] = np.exp(value[live] - top[live, None])
    with np.errstate(divide="ignore"):
        total = np.where(live, top + np.log(scaled.sum(axis=1)), _NEG_INF)
        containing = np.where(
            live[:, None], top[:, None] + np.log(scaled @ member.astype(float)), _NEG_INF
        )
    return FrontierMarginals(log_mass, total, containing, True, 1 << H)


@functools.cache
def _subsets(H: int) -> NDArray[np.bool_]:
    """Every subset of ``H`` hypotheses as a row of membership flags, shape (2^H, H)
    (read-only: shared between calls)."""
    member = ((np.arange(1 << H)[:, None] >> np.arange(H)) & 1).astype(bool)
    member.flags.writeable = False
    return member


def cluster_messages(
    tables: Sequence[NDArray[np.float64]], log_track_weights: NDArray[np.float64]
) -> tuple[list[NDArray[np.float64]], float]:
    """What the rest of the window makes of each independent cluster, per its own k.

    The window's sets are the products of one set per cluster, with count ``T`` the sum
    of the clusters' counts and weight ``exp(sum of log-weights) * W(T)``.  For cluster
    ``c`` with per-k log-masses ``m_c``, the message

        G_c[k] = log sum_T W(T) R_c[T - k],   R_c = the sum-product convolution of the
                                               other clusters' masses,

    makes ``sum_k exp(m_c[k] + G_c[k])`` the window's total for every c, and turns a
    per-k mass of sets of c containing h into that of the window's sets containing h.
    Computed with prefix convolutions forward and correlations with ``W`` backward: one
    pass each over the clusters, ``O(len(W) * table length)`` per cluster.

    Parameters
    ----------
    tables : sequence of ndarray, each shape (k_c + 1,)
        Per-k log-masses of the clusters (``-inf`` where none).
    log_track_weights : ndarray, shape (L,)
        ``log W(T)`` for T = 0..L-1; ``W(T) = 0`` beyond.

    Returns
    -------
    messages : list of ndarray, the c-th of shape (k_c + 1,)
    log_total : float
        ``log sum_T W(T) (convolution of every table)[T]``.
    """
    log_w = np.asarray(log_track_weights, dtype=float)
    L = log_w.shape[0]
    C = len(tables)
    # backward[c][j] = log sum_T W(T) (conv of tables c..C-1)[T - j], j = 0..L-1.
    backward: list[NDArray[np.float64]] = [np.empty(0)] * (C + 1)
    backward[C] = log_w
    for c in range(C - 1, -1, -1):
        table = np.asarray(tables[c], dtype=float)
        nxt = backward[c + 1]
        out = np.full(L, _NEG_INF)
        for i in np.flatnonzero(np.isfinite(table[:L])).tolist():
            window = out[: L - i]
            np.logaddexp(window, nxt[i:] + table[i], out=window)
        backward[c] = out
    messages: list[NDArray[np.float64]] = []
    prefix = np.full(L, _NEG_INF)
    prefix[0] = 0.0
    for c in range(C):
        table = np.asarray(tables[c], dtype=float)
        nxt = backward[c + 1]
        message = np.full(table.shape[0], _NEG_INF)
        for k in range(min(table.shape[0], L)):
            message[k] = _lse(prefix[: L - k] + nxt[k:])
        messages.append(message)
        prefix = sum_product(prefix, table, L)
    return messages, float(backward[0][0]) if L else _NEG_INF
