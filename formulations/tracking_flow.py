"""The network-flow program of multi-object tracking, from generic item and link arrays.

Zhang, Li & Nevatia, "Global data association for multi-object tracking using network
flows", CVPR 2008, section 3 (the graph of fig. 2); Berclaz, Fleuret, Türetken & Fua,
"Multiple object tracking using k-shortest paths optimization", IEEE TPAMI 33(9), 2011
(the same program solved for every number of tracks).  A track is a source-to-sink path
through *items* (detections, or tracks carried in from earlier, for the caller to
decide) in a directed acyclic graph::

    source --entry_i--> in_i --observation_i--> out_i --exit_i--> sink
                                                out_i --link(i, j)--> in_j

Every ``in_i -> out_i`` edge has capacity 1, so the paths of an integer flow are
item-disjoint: a flow of value K is a set of K tracks, and its cost is the sum of the
path costs.  With costs that are negated log-likelihood ratios, the min-cost flow of
value K is the most likely set of K tracks (Zhang et al., eq. 9).

*Forced* items (a carried track: it continues, misses or ends, but never vanishes) must
each *start* a path of every flow, so a flow has K >= C (the number of forced items)
paths.  Their entry edge gets a bonus ``-M`` with ``M = 1 + 2 S``, ``S`` the sum of
``|cost|`` over every edge (bonus excluded).  Edges have capacity 1, so the cost of any
flow without the bonus lies in ``[-S, S]``, and two flows differ by at most ``S < M``:
every min-cost flow of value K starts a path at all C forced items whenever some flow of
value K does, and :meth:`TrackingFlow.track_costs` adds ``C M`` back.  A flow that leaves
a forced entry unused costs at least ``M - S - C M > M / 2 - C M`` while one that uses
them all costs at most ``S - C M < M / 2 - C M``, so the costs alone tell which K admit
no such flow (``track_costs`` reports ``inf`` there).  The bonus rewards entries only: a
path that runs *through* a forced item (a link into it) does not count, which is why
carried tracks get no incoming links.

Nodes: ``0`` source, ``1`` sink, ``2 + 2 i`` and ``3 + 2 i`` the in and out nodes of
item ``i``.  Items are numbered in a topological order: every link goes from a lower to
a higher item index (for tracking, scan order), which makes the graph acyclic.

This module imports no solver library and no domain code; so bad arguments raise
``ValueError`` naming the argument (``mapassoc.errors.InputError``, which callers raise,
is a subclass).
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.formulations.program import FlowProgram

__all__ = [
    "EDGE_ENTRY",
    "EDGE_OBSERVATION",
    "EDGE_LINK",
    "EDGE_EXIT",
    "TrackingFlow",
    "tracking_flow_program",
    "through_costs",
    "reachable_items",
    "combine_convex_costs",
    "successive_shortest_paths",
]

EDGE_ENTRY = 0
"""Edge kind: source -> in node of an item (a track starts there)."""
EDGE_OBSERVATION = 1
"""Edge kind: in -> out node of an item (capacity 1: the item is used at most once)."""
EDGE_LINK = 2
"""Edge kind: out node of one item -> in node of a later one (consecutive in a track)."""
EDGE_EXIT = 3
"""Edge kind: out node of an item -> sink (a track's last item)."""

SOURCE = 0
SINK = 1


def _in_node(item: IntArray | int) -> IntArray | int:
    return 2 + 2 * item


def _out_node(item: IntArray | int) -> IntArray | int:
    return 3 + 2 * item


@dataclass(frozen=True, eq=False)
class TrackingFlow:
    """A tracking flow program and what decodes its flows into tracks.

    Attributes
    ----------
    program : FlowProgram
        The network (forced items' entry costs include the bonus ``-bonus``).
    num_items : int
    edge_kind : ndarray of int, shape (E,)
        :data:`EDGE_ENTRY`, :data:`EDGE_OBSERVATION`, :data:`EDGE_LINK` or
        :data:`EDGE_EXIT` for each edge of ``program``.
    edge_item : ndarray of int, shape (E,)
        The item of an entry, observation or exit edge; the tail item of a link.
    forced : ndarray of bool, shape (num_items,)
    bonus : float
        ``M = 1 + 2 S`` (module docstring), subtracted from each forced item's entry cost
        (0 without forced items).
    """

    program: FlowProgram
    num_items: int
    edge_kind: NDArray[np.int64]
    edge_item: IntArray
    forced: NDArray[np.bool_]
    bonus: float

    @property
    def num_forced(self) -> int:
        """C, the number of forced items."""
        return int(np.count_nonzero(self.forced))

    def track_costs(self, flow_costs: FloatArray) -> FloatArray:
        """Costs per flow value K without the forced items' bonus.

        Parameters
        ----------
        flow_costs : ndarray, shape (max_flow + 1,)
            ``FlowResult.costs`` of :attr:`program`.

        Returns
        -------
        ndarray, shape (max_flow + 1,)
            ``flow_costs[K] + C M`` where a flow of value K starts a path at every forced
            item (then the min-cost one does, module docstring); ``inf`` where none does
            (every K < C among them), which the cost shows (above ``M / 2 - C M``).
        """
        costs = np.asarray(flow_costs, dtype=float)
        c = self.num_forced
        out = costs + c * self.bonus
        if c:
            out[out > 0.5 * self.bonus] = math.inf  # nan (not solved) stays nan
        return out

    def decode_paths(self, edge_flows: IntArray) -> tuple[tuple[int, ...], ...]:
        """The tracks (item sequences) of one integer flow.

        Parameters
        ----------
        edge_flows : ndarray of int, shape (E,)
            One row of ``FlowResult.edge_flows``.

        Returns
        -------
        tuple of tuple of int
            One path per unit of flow leaving the source, as item indices in path
            order; paths sorted by their first item.

        Raises
        ------
        ValueError
            Wrong shape, or a flow that is not a set of item-disjoint 0/1 paths.
        """
        flows = np.asarray(edge_flows)
        if flows.shape != (self.program.num_edges,):
            raise ValueError(
                f"edge_flows must have shape ({self.program.num_edges},), got {flows.shape}"
            )
        if np.any((flows != 0) & (flows != 1)):
            raise ValueError("edge_flows must be 0/1 (every item edge has capacity 1)")
        used = flows == 1
        heads = self.program.heads
        successor: dict[int, int] = {}
        for e in np.flatnonzero(used & (self.edge_kind == EDGE_LINK)).tolist():
            tail = int(self.edge_item[e])
            if tail in successor:
                raise ValueError(f"item {tail} has two outgoing links with flow")
            successor[tail] = (int(heads[e]) - 2) // 2
        starts = sorted(int(self.edge_item[e]) for e in np.flatnonzero(
            used & (self.edge_kind == EDGE_ENTRY)))
        paths = []
        for item in starts:
            path = [item]
            while path[-1] in successor:
                path.append(successor[path[-1]])
            paths.append(tuple(path))
        return tuple(paths)


def _check_items(name: str, values: FloatArray, n: int, allow_inf: bool) -> FloatArray:
    a = np.asarray(values, dtype=float)
    if a.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {a.shape}")
    bad = np.isnan(a) | (np.isinf(a) & ((a < 0) | (not allow_inf)))
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        allowed = "finite or +inf (no edge)" if allow_inf else "finite"
        raise ValueError(f"{name}[{i}] = {float(a[i])!r}; expected {allowed}")
    return a


def _check_links(
    n: int, link_tails: IntArray, link_heads: IntArray, link_costs: FloatArray
) -> tuple[IntArray, IntArray, FloatArray]:
    tails = np.asarray(link_tails, dtype=np.int64).reshape(-1)
    heads = np.asarray(link_heads, dtype=np.int64).reshape(-1)
    costs = np.asarray(link_costs, dtype=float).reshape(-1)
    if not (tails.shape == heads.shape == costs.shape):
        raise ValueError(
            f"link_tails, link_heads and link_costs must have equal lengths, got "
            f"{tails.shape}, {heads.shape} and {costs.shape}"
        )
    for name, ends in (("link_tails", tails), ("link_heads", heads)):
        outside = (ends < 0) | (ends >= n)
        if np.any(outside):
            e = int(np.flatnonzero(outside)[0])
            raise ValueError(
                f"{name}[{e}] = {int(ends[e])}; expected an item index in 0..{n - 1}"
            )
    if np.any(tails >= heads):
        e = int(np.flatnonzero(tails >= heads)[0])
        raise ValueError(
            f"link_tails[{e}] = {int(tails[e])} and link_heads[{e}] = {int(heads[e])}; links "
            "must go from a lower to a higher item index (a topological order)"
        )
    if not np.all(np.isfinite(costs)):
        e = int(np.flatnonzero(~np.isfinite(costs))[0])
        raise ValueError(f"link_costs[{e}] = {float(costs[e])!r}; expected finite")
    return tails, heads, costs


def tracking_flow_program(
    *,
    entry_costs: FloatArray,
    observation_costs: FloatArray,
    exit_costs: FloatArray,
    link_tails: IntArray,
    link_heads: IntArray,
    link_costs: FloatArray,
    max_flow: int,
    forced: NDArray[np.bool_] | None = None,
) -> TrackingFlow:
    """Build the tracking flow program (module docstring).

    Parameters
    ----------
    entry_costs : ndarray, shape (n,)
        Cost of starting a track at each item; ``+inf`` for no entry edge.
    observation_costs : ndarray, shape (n,)
        Cost of using each item (finite).
    exit_costs : ndarray, shape (n,)
        Cost of ending a track at each item; ``+inf`` for no exit edge.
    link_tails, link_heads : ndarray of int, shape (L,)
        Links ``tail -> head`` with ``tail < head``.
    link_costs : ndarray, shape (L,)
        Finite.
    max_flow : int
        Largest number of tracks K to solve for (>= 0).
    forced : ndarray of bool, shape (n,), optional
        Items at which every flow (of K >= their number) must start a path; each needs a
        finite entry cost.

    Returns
    -------
    TrackingFlow

    Raises
    ------
    ValueError
        Inconsistent shapes, NaN or ``-inf`` costs, a link against the item order, or
        a forced item without an entry edge.
    """
    observation = np.asarray(observation_costs, dtype=float)
    if observation.ndim != 1:
        raise ValueError(f"observation_costs must be 1-D, got shape {observation.shape}")
    n = observation.shape[0]
    observation = _check_items("observation_costs", observation, n, allow_inf=False)
    entry = _check_items("entry_costs", entry_costs, n, allow_inf=True)
    exits = _check_items("exit_costs", exit_costs, n, allow_inf=True)
    tails, heads, costs = _check_links(n, link_tails, link_heads, link_costs)
    must = _check_forced(forced, entry, n)
    if isinstance(max_flow, bool) or not isinstance(max_flow, (int, np.integer)) or max_flow < 0:
        raise ValueError(f"max_flow must be an integer >= 0, got {max_flow!r}")
    kind, edge_item, edge_tail, edge_head, edge_cost = _tracking_edges(
        entry, observation, exits, tails, heads, costs
    )
    bonus = 0.0
    if np.any(must):
        bonus = 1.0 + 2.0 * math.fsum(np.abs(edge_cost).tolist())
        forced_entry = (kind == EDGE_ENTRY) & must[edge_item]
        edge_cost = edge_cost.copy()
        edge_cost[forced_entry] -= bonus
    program = FlowProgram(
        num_nodes=2 + 2 * n,
        source=SOURCE,
        sink=SINK,
        tails=edge_tail,
        heads=edge_head,
        capacities=np.ones(kind.size, dtype=np.int64),
        costs=edge_cost,
        max_flow=int(max_flow),
    )
    return TrackingFlow(
        program=program,
        num_items=n,
        edge_kind=kind,
        edge_item=edge_item,
        forced=must,
        bonus=bonus,
    )


def _check_forced(forced: NDArray[np.bool_] | None, entry: FloatArray, n: int) -> NDArray[np.bool_]:
    """``forced`` as a bool array of shape (n,) (``None``: none), refused where a forced
    item has no finite entry cost."""
    must = np.zeros(n, dtype=bool) if forced is None else np.asarray(forced, dtype=bool)
    if must.shape != (n,):
        raise ValueError(f"forced must have shape ({n},), got {must.shape}")
    if np.any(must & ~np.isfinite(entry)):
        i = int(np.flatnonzero(must & ~np.isfinite(entry))[0])
        raise ValueError(
            f"forced[{i}] is set but entry_costs[{i}] = {float(entry[i])!r}; every forced item "
            "needs a finite entry cost"
        )
    return must


def _tracking_edges(
    entry: FloatArray,
    observation: FloatArray,
    exits: FloatArray,
    tails: IntArray,
    heads: IntArray,
    costs: FloatArray,
) -> tuple[IntArray, IntArray, IntArray, IntArray, FloatArray]:
    """The program's edges, entries (finite ones, by item), observations, links, then
    exits (finite ones, by item): each edge's kind, item (a link's: its tail), tail
    node, head node and cost."""
    n = observation.shape[0]
    items = np.arange(n, dtype=np.int64)
    has_entry = np.flatnonzero(np.isfinite(entry))
    has_exit = np.flatnonzero(np.isfinite(exits))
    parts = [
        (EDGE_ENTRY, has_entry, np.full(has_entry.size, SOURCE), _in_node(has_entry),
         entry[has_entry]),
        (EDGE_OBSERVATION, items, _in_node(items), _out_node(items), observation),
        (EDGE_LINK, tails, _out_node(tails), _in_node(heads), costs),
        (EDGE_EXIT, has_exit, _out_node(has_exit), np.full(has_exit.size, SINK),
         exits[has_exit]),
    ]
    kind = np.concatenate([np.full(p[1].size, p[0], dtype=np.int64) for p in parts])
    edge_item = np.concatenate([p[1] for p in parts]).astype(np.int64)
    edge_tail = np.concatenate([p[2] for p in parts]).astype(np.int64)
    edge_head = np.concatenate([p[3] for p in parts]).astype(np.int64)
    edge_cost = np.concatenate([p[4] for p in parts]).astype(float)
    return kind, edge_item, edge_tail, edge_head, edge_cost


def through_costs(
    *,
    entry_costs: FloatArray,
    observation_costs: FloatArray,
    exit_costs: FloatArray,
    link_tails: IntArray,
    link_heads: IntArray,
    link_costs: FloatArray,
) -> FloatArray:
    """Cost of the cheapest source-to-sink path through each item.

    Dynamic programming over the topological item order (links go from lower to higher
    indices): ``f_i = o_i + min(entry_i, min_{links h -> i} f_h + c_hi)`` is the
    cheapest path from the source to ``out_i``, ``g_i = min(exit_i, min_{links i -> j}
    c_ij + o_j + g_j)`` the cheapest from ``out_i`` to the sink, and the answer is
    ``f_i + g_i``.

    **Use: exact pruning.**  In a min-cost flow over every flow value K >= C, removing a
    path that holds no forced item leaves a flow of value K - 1 >= C, so such a path of
    an overall min-cost flow costs <= 0.  An item whose cheapest through-path costs
    more than 0, and that is joined by no path of links to a forced item (neither
    reachable from one nor reaching one; :func:`reachable_items` gives the first, which
    suffices when no link enters a forced item), therefore lies on no path of some
    overall min-cost flow, and may be deleted without changing the minimum over K (the
    costs of other K may rise).

    Parameters
    ----------
    entry_costs, observation_costs, exit_costs : ndarray, shape (n,)
    link_tails, link_heads, link_costs : ndarray, shape (L,)
        As for :func:`tracking_flow_program` (without forced bonuses).

    Returns
    -------
    ndarray, shape (n,)
        ``inf`` for an item on no source-to-sink path.
    """
    observation = np.asarray(observation_costs, dtype=float)
    if observation.ndim != 1:
        raise ValueError(f"observation_costs must be 1-D, got shape {observation.shape}")
    n = observation.shape[0]
    observation = _check_items("observation_costs", observation, n, allow_inf=False)
    entry = _check_items("entry_costs", entry_costs, n, allow_inf=True)
    exits = _check_items("exit_costs", exit_costs, n, allow_inf=True)
    tails, heads, costs = _check_links(n, link_tails, link_heads, link_costs)
    order = np.argsort(heads, kind="stable")
    by_head_tails, by_head_costs = tails[order], costs[order]
    head_ptr = np.searchsorted(heads[order], np.arange(n + 1))
    forward = np.empty(n)
    for i in range(n):
        lo, hi = head_ptr[i], head_ptr[i + 1]
        best = entry[i]
        if hi > lo:
            best = min(best, float(np.min(forward[by_head_tails[lo:hi]] + by_head_costs[lo:hi])))
        forward[i] = observation[i] + best
    order = np.argsort(tails, kind="stable")
    by_tail_heads, by_tail_costs = heads[order], costs[order]
    tail_ptr = np.searchsorted(tails[order], np.arange(n + 1))
    backward = np.empty(n)
    for i in range(n - 1, -1, -1):
        lo, hi = tail_ptr[i], tail_ptr[i + 1]
        best = exits[i]
        if hi > lo:
            nxt = by_tail_heads[lo:hi]
            best = min(best, float(np.min(by_tail_costs[lo:hi] + observation[nxt] + backward[nxt])))
        backward[i] = best
    return forward + backward


def reachable_items(
    start: NDArray[np.bool_], link_tails: IntArray, link_heads: IntArray
) -> NDArray[np.bool_]:
    """Items reachable from the ``start`` items along links (the start items included).

    Parameters
    ----------
    start : ndarray of bool, shape (n,)
    link_tails, link_heads : ndarray of int, shape (L,)
        Links with ``tail < head``.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    reach = np.array(start, dtype=bool, copy=True)
    tails = np.asarray(link_tails, dtype=np.int64)
    heads = np.asarray(link_heads, dtype=np.int64)
    order = np.argsort(tails, kind="stable")
    tails, heads = tails[order], heads[order]
    # Links go forward, so one pass in tail order propagates reachability.
    for e in range(tails.size):
        if reach[tails[e]]:
            reach[heads[e]] = True
    return reach


def combine_convex_costs(
    costs: Sequence[FloatArray], max_total: int
) -> tuple[FloatArray, IntArray]:
    """Min-plus convolution of convex per-component costs, with the counts that attain it.

    Independent components (no link between them) of one flow program: the minimum cost
    of K tracks in all of them is ``min over K_1 + ... + K_m = K of sum_i c_i[K_i]``.
    Each ``c_i`` is convex on its finite range (parametric min-cost flow), so the
    minimum for every K is reached greedily: start every component at its smallest
    finite K_i and repeatedly raise the component whose next increment
    ``c_i[K_i + 1] - c_i[K_i]`` is smallest (ties: the lower component index).  For convex
    sequences this greedy merge is exact (the classical exchange argument: the chosen
    increments are the K - sum min_i smallest of all, taken in each component's order).

    Parameters
    ----------
    costs : sequence of ndarray, shape (M_i + 1,)
        ``c_i[K]`` for K = 0..M_i: ``inf`` below the smallest feasible K and where
        infeasible; finite values contiguous and convex.
    max_total : int
        Largest total K to report.

    Returns
    -------
    total : ndarray, shape (max_total + 1,)
        Minimum total cost of each K (``inf`` where infeasible or beyond the components'
        ranges).
    counts : ndarray of int, shape (max_total + 1, m)
        A per-component split attaining ``total[K]`` (-1 where ``total[K]`` is ``inf``).

    Raises
    ------
    ValueError
        A component with no finite cost, or finite costs that are not contiguous.
    """
    m = len(costs)
    arrays = [np.asarray(c, dtype=float) for c in costs]
    current = np.zeros(m, dtype=np.int64)
    for i, c in enumerate(arrays):
        finite = np.flatnonzero(np.isfinite(c))
        if finite.size == 0:
            raise ValueError(f"costs[{i}] has no finite entry")
        if finite[-1] - finite[0] + 1 != finite.size:
            raise ValueError(f"costs[{i}] has non-contiguous finite entries")
        current[i] = finite[0]
    total = np.full(max_total + 1, math.inf)
    counts = np.full((max_total + 1, m), -1, dtype=np.int64)
    k = int(current.sum())
    value = math.fsum(float(arrays[i][current[i]]) for i in range(m))
    heap: list[tuple[float, int]] = []

    def push(i: int) -> None:
        nxt = current[i] + 1
        if nxt < arrays[i].size and math.isfinite(arrays[i][nxt]):
            heapq.heappush(heap, (float(arrays[i][nxt] - arrays[i][current[i]]), i))

    for i in range(m):
        push(i)
    while k <= max_total:
        total[k] = value
        counts[k] = current
        if not heap:
            break
        _, i = heapq.heappop(heap)
        current[i] += 1
        value = math.fsum(float(arrays[j][current[j]]) for j in range(m))
        k += 1
        push(i)
    return total, counts


def successive_shortest_paths(flow: TrackingFlow) -> Iterator[tuple[float, IntArray]]:
    """Min-cost flows of value K = 0, 1, 2, ... of a tracking flow program, one at a time.

    Successive shortest paths (Ahuja, Magnanti & Orlin, *Network Flows*, 1993, section
    9.7; the k-shortest-paths view of Berclaz et al. 2011): node potentials start as the
    shortest distances from the source, computed by one pass over the acyclic graph in
    item order (so negative costs, the forcing bonus included, need no Bellman-Ford);
    each further unit of flow follows a shortest source-to-sink path of the residual
    graph under the reduced costs (Dijkstra), and the potentials then add the distances.
    Every flow so obtained is a min-cost flow of its value, on the program's float costs
    (no rounding: the residual graph has no negative reduced cost, up to float error,
    which is clamped at 0).  The cost increments are non-decreasing: the cost is convex
    in K.

    Parameters
    ----------
    flow : TrackingFlow
        Its ``program.max_flow`` is the largest K yielded.

    Yields
    ------
    cost : float
        ``fsum`` of ``cost_e * flow_e`` over the edges (the program's costs, forcing
        bonus included, like ``FlowResult.costs``; see :meth:`TrackingFlow.track_costs`).
    edge_flows : ndarray of int, shape (E,)
        A min-cost flow of value K (a fresh array each time).

    Stops after ``program.max_flow`` or when no further unit of flow is feasible.
    """
    prog = flow.program
    graph = _ResidualGraph.of(prog)
    potential = _dag_distances(graph)
    used = [0] * prog.num_edges
    yield 0.0, np.zeros(prog.num_edges, dtype=np.int64)
    for _ in range(prog.max_flow):
        if potential[SINK] == math.inf:
            return
        dist, via, done = _residual_dijkstra(graph, potential, used)
        if not done[SINK]:
            return
        _augment(graph, via, used)
        # Nodes not reached stay unreachable (new residual edges join reached nodes only).
        for node in range(prog.num_nodes):
            potential[node] = potential[node] + dist[node] if done[node] else math.inf
        total = math.fsum(graph.costs[e] for e in range(prog.num_edges) if used[e])
        yield total, np.array(used, dtype=np.int64)


@dataclass(frozen=True)
class _ResidualGraph:
    """A flow program's edges as Python lists (tails, heads, costs) with each node's
    outgoing and incoming edges, for :func:`successive_shortest_paths`."""

    tails: list[int]
    heads: list[int]
    costs: list[float]
    out_edges: list[list[int]]
    in_edges: list[list[int]]

    @classmethod
    def of(cls, prog: FlowProgram) -> _ResidualGraph:
        tails = prog.tails.tolist()
        heads = prog.heads.tolist()
        out_edges: list[list[int]] = [[] for _ in range(prog.num_nodes)]
        in_edges: list[list[int]] = [[] for _ in range(prog.num_nodes)]
        for e in range(prog.num_edges):
            out_edges[tails[e]].append(e)
            in_edges[heads[e]].append(e)
        return cls(tails, heads, prog.costs.tolist(), out_edges, in_edges)


def _dag_distances(graph: _ResidualGraph) -> list[float]:
    """Shortest distances from the source (``inf``: unreachable), by one pass over the
    nodes in a topological order: the source, then the in and out node of each item in
    item order, then the sink."""
    num_nodes = len(graph.out_edges)
    potential = [math.inf] * num_nodes
    potential[SOURCE] = 0.0
    for node in [SOURCE, *range(2, num_nodes), SINK]:
        here = potential[node]
        if here == math.inf:
            continue
        for e in graph.out_edges[node]:
            there = here + graph.costs[e]
            if there < potential[graph.heads[e]]:
                potential[graph.heads[e]] = there
    return potential


def _residual_dijkstra(
    graph: _ResidualGraph, potential: list[float], used: list[int]
) -> tuple[list[float], list[int], list[bool]]:
    """Dijkstra on the residual graph of the flow ``used`` (forward edges without flow,
    backward edges with) under the costs reduced by ``potential``, negative reduced
    costs (float error) clamped at 0.

    Returns
    -------
    dist : list of float
        Each node's reduced distance from the source.
    via : list of int
        The edge reaching each node: ``e`` forward, ``~e`` backward (``-1``: none).
    done : list of bool
        Which nodes were reached.
    """
    num_nodes = len(graph.out_edges)
    tails, heads, costs = graph.tails, graph.heads, graph.costs
    dist = [math.inf] * num_nodes
    via = [-1] * num_nodes
    dist[SOURCE] = 0.0
    heap = [(0.0, SOURCE)]
    done = [False] * num_nodes
    while heap:
        d, node = heapq.heappop(heap)
        if done[node]:
            continue
        done[node] = True
        pu = potential[node]
        for e in graph.out_edges[node]:
            if used[e]:
                continue
            v = heads[e]
            if done[v]:
                continue
            nd = d + max(costs[e] + pu - potential[v], 0.0)
            if nd < dist[v]:
                dist[v] = nd
                via[v] = e
                heapq.heappush(heap, (nd, v))
        for e in graph.in_edges[node]:
            if not used[e]:
                continue
            v = tails[e]
            if done[v]:
                continue
            nd = d + max(-costs[e] + pu - potential[v], 0.0)
            if nd < dist[v]:
                dist[v] = nd
                via[v] = ~e
                heapq.heappush(heap, (nd, v))
    return dist, via, done


def _augment(graph: _ResidualGraph, via: list[int], used: list[int]) -> None:
    """Push one unit of flow along the path ``via`` from the sink back to the source,
    in place in ``used`` (a backward edge cancels its flow)."""
    node = SINK
    while node != SOURCE:
        e = via[node]
        if e >= 0:
            used[e] = 1
            node = graph.tails[e]
        else:
            used[~e] = 0
            node = graph.heads[~e]
