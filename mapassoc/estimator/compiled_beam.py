"""Numba kernel of the group re-solve's child selection (:mod:`mapassoc.estimator.group_moves`).

Imported only through :func:`mapassoc.accelerate.compiled_module` (numba is an optional
accelerator).  :func:`best_children` is the same best-first search over partial joint
assignments as its Python twin ``group_moves._best_children``, with the partial
assignments stored as a tree of nodes (each node its parent node and its head's
detection) in growable arrays and a binary heap of node indices, so that the thousands
of heap operations per scan cost arithmetic rather than Python's tuple handling.  Ties of
the heap's key (the bound, the parent, the head and the score) are broken by the order
in which the nodes were made, where the twin compares its tuples further; both give the
same children wherever the scores differ.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from mapassoc.array_types import FloatArray, IntArray

_FIRST_CAPACITY = 1 << 12


@njit(cache=True)
def _options(gain: FloatArray) -> tuple[IntArray, IntArray, FloatArray]:
    """Per parent and head its finite detections best first (``order``, ``count``) and
    ``rest[b, i]``, the sum of the positive largest gains of heads ``i..K-1``."""
    B, K, D = gain.shape
    order = np.empty((B, K, D), dtype=np.int64)
    count = np.zeros((B, K), dtype=np.int64)
    rest = np.zeros((B, K + 1))
    for b in range(B):
        for i in range(K):
            ranked = np.argsort(-gain[b, i], kind="mergesort")
            n = 0
            for d in ranked:
                if np.isfinite(gain[b, i, d]):
                    order[b, i, n] = d
                    n += 1
            count[b, i] = n
        for i in range(K - 1, -1, -1):
            top = gain[b, i, order[b, i, 0]] if count[b, i] > 0 else 0.0
            rest[b, i] = rest[b, i + 1] + max(0.0, top)
    return order, count, rest


@njit(cache=True)
def _before(
    x: int, y: int, key: FloatArray, parent: IntArray, head: IntArray, total: FloatArray
) -> bool:
    """Whether node ``x`` pops before node ``y``: larger bound, then smaller parent,
    smaller head, smaller score (the twin's tuple order), then the earlier node."""
    if key[x] != key[y]:
        return key[x] > key[y]
    if parent[x] != parent[y]:
        return parent[x] < parent[y]
    if head[x] != head[y]:
        return head[x] < head[y]
    if total[x] != total[y]:
        return total[x] < total[y]
    return x < y


@njit(cache=True)
def _push(heap: IntArray, size: int, node: int, key: FloatArray, parent: IntArray,
          head: IntArray, total: FloatArray) -> None:  # fmt: skip
    at = size
    heap[at] = node
    while at > 0:
        up = (at - 1) // 2
        if not _before(heap[at], heap[up], key, parent, head, total):
            break
        heap[at], heap[up] = heap[up], heap[at]
        at = up


@njit(cache=True)
def _pop(heap: IntArray, size: int, key: FloatArray, parent: IntArray, head: IntArray,
         total: FloatArray) -> int:  # fmt: skip
    top = heap[0]
    size -= 1
    heap[0] = heap[size]
    at = 0
    while True:
        left, best = 2 * at + 1, at
        if left < size and _before(heap[left], heap[best], key, parent, head, total):
            best = left
        if left + 1 < size and _before(heap[left + 1], heap[best], key, parent, head, total):
            best = left + 1
        if best == at:
            return top
        heap[at], heap[best] = heap[best], heap[at]
        at = best


@njit(cache=True)
def _grown(a: np.ndarray) -> np.ndarray:
    out = np.empty(2 * a.shape[0], dtype=a.dtype)
    out[: a.shape[0]] = a
    return out


@njit(cache=True)
def _choice(node: int, K: int, prev: IntArray, pick: IntArray) -> IntArray:
    """The detections of heads ``0..K-1`` of a complete node, read back along its chain."""
    out = np.empty(K, dtype=np.int64)
    for i in range(K - 1, -1, -1):
        out[i] = pick[node]
        node = prev[node]
    return out


@njit(cache=True)
def _taken(node: int, d: int, prev: IntArray, pick: IntArray) -> bool:
    """Whether detection ``d`` is on the chain ending at ``node``."""
    while node >= 0:
        if pick[node] == d:
            return True
        node = prev[node]
    return False


@njit(cache=True)
def _seen(codes: IntArray, n_out: int, out_codes: IntArray, out_hash: IntArray, h: int) -> bool:
    for o in range(n_out):
        if out_hash[o] == h and np.all(out_codes[o] == codes):
            return True
    return False


@njit(cache=True)
def best_children(
    score: FloatArray, gain: FloatArray, history: IntArray, beam: int, branch: int
) -> tuple[IntArray, IntArray, FloatArray]:
    """The ``beam`` best children over all parents, best first: their parents (n,),
    choices (n, K; -1 a miss) and scores (n,).

    ``score`` (B,) the parents' scores; ``gain`` (B, K, D) each head's gain from each
    detection (``-inf`` outside its gate); ``history`` (B, K) an id of each parent
    head's recent detections: a child whose (history, choice) per head an earlier child
    had is merged into it; a parent stops at ``branch`` children.
    """
    B, K, D = gain.shape
    order, count, rest = _options(gain)
    cap = max(_FIRST_CAPACITY, 2 * B)
    key, total = np.empty(cap), np.empty(cap)
    parent, head = np.empty(cap, dtype=np.int64), np.empty(cap, dtype=np.int64)
    prev, pick = np.empty(cap, dtype=np.int64), np.empty(cap, dtype=np.int64)
    heap = np.empty(cap, dtype=np.int64)
    n_nodes = 0
    size = 0
    for b in range(B):
        key[n_nodes], total[n_nodes] = score[b] + rest[b, 0], score[b]
        parent[n_nodes], head[n_nodes], prev[n_nodes], pick[n_nodes] = b, 0, -1, -1
        _push(heap, size, n_nodes, key, parent, head, total)
        n_nodes += 1
        size += 1
    out_parent = np.empty(beam, dtype=np.int64)
    out_choice = np.empty((beam, K), dtype=np.int64)
    out_score = np.empty(beam)
    out_codes = np.empty((beam, K), dtype=np.int64)
    out_hash = np.empty(beam, dtype=np.int64)
    per_parent = np.zeros(B, dtype=np.int64)
    n_out = 0
    while size > 0 and n_out < beam:
        node = _pop(heap, size, key, parent, head, total)
        size -= 1
        b, i = parent[node], head[node]
        if per_parent[b] >= branch:
            continue
        if i == K:
            choice = _choice(node, K, prev, pick)
            codes = history[b] * (D + 1) + choice + 1
            h = 1469598103934665603
            for c in codes:
                h = (h ^ c) * 1099511628211
            if not _seen(codes, n_out, out_codes, out_hash, h):
                out_parent[n_out], out_score[n_out] = b, total[node]
                out_choice[n_out], out_codes[n_out], out_hash[n_out] = choice, codes, h
                per_parent[b] += 1
                n_out += 1
            continue
        if n_nodes + 1 + count[b, i] > key.shape[0]:
            key, total, parent, head = _grown(key), _grown(total), _grown(parent), _grown(head)
            prev, pick, heap = _grown(prev), _grown(pick), _grown(heap)
        bound = rest[b, i + 1]
        for option in range(-1, count[b, i]):
            d = -1 if option < 0 else order[b, i, option]
            if d >= 0 and _taken(node, d, prev, pick):
                continue
            t = total[node] + (0.0 if d < 0 else gain[b, i, d])
            key[n_nodes], total[n_nodes] = t + bound, t
            parent[n_nodes], head[n_nodes], prev[n_nodes], pick[n_nodes] = b, i + 1, node, d
            _push(heap, size, n_nodes, key, parent, head, total)
            n_nodes += 1
            size += 1
    return out_parent[:n_out], out_choice[:n_out], out_score[:n_out]


def _warm_up() -> None:
    """Compile (or load from numba's cache) for the argument types the package passes."""
    best_children(
        np.zeros(2), np.zeros((2, 2, 1)), np.zeros((2, 2), dtype=np.int64), 4, 2
    )


_warm_up()
