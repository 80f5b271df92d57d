"""Min-cost flow for every flow value K with networkx's network simplex.

networkx documents that its min-cost-flow algorithms are not guaranteed to work with
floating-point weights, so costs are scaled to integers, ``round(cost * cost_scale)``
(default ``cost_scale = 1e6``), after checking that every scaled cost is exactly
representable (``|cost| * cost_scale < 2**53``).  The flow returned for each K is optimal
for the rounded costs; its reported cost is recomputed from the integer flows and the
program's float costs.  Each rounded cost is within ``0.5 / cost_scale`` of the true one,
so the reported cost exceeds the true minimum by at most ``Σ_e capacity_e / cost_scale``
(and usually by nothing: ties between distinct flows within that margin are rare).

Every K in ``0..max_flow`` is solved by its own ``nx.network_simplex`` call with supply K
at the source and demand K at the sink (negative-cost cycles, parallel edges and
self-loops are handled by networkx).  The feasible flow values form the interval
``0..maximum_flow_value``, computed once; larger K are INFEASIBLE without a simplex call.
The minimum cost is a convex function of K on that interval (parametric min-cost flow).
networkx is imported on first use, so importing :mod:`mapassoc.solvers` does not load it.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from mapassoc.formulations.program import FlowProgram
from mapassoc.solvers.results import (
    FlowResult,
    SolverError,
    SolveStatus,
    validate_time_limit,
)

__all__ = ["NetworkxFlowSolver"]

_EXACT_INTEGER_LIMIT = 2.0**53


def _networkx() -> Any:
    """networkx, imported on first use (importing :mod:`mapassoc.solvers` stays light)."""
    try:
        import networkx
    except ImportError as error:
        raise SolverError(f"networkx-flow: networkx is not importable ({error})") from error
    return networkx


class NetworkxFlowSolver:
    """Min-cost flow for K = 0..max_flow via integer-scaled ``nx.network_simplex``.

    Parameters
    ----------
    cost_scale : float, default 1e6
        Costs are rounded to multiples of ``1 / cost_scale`` for networkx.
    """

    name = "networkx-flow"
    supports_integer = False
    supports_flow = True
    supports_relaxation = False
    exact = True

    def __init__(self, *, cost_scale: float = 1e6) -> None:
        if not (math.isfinite(cost_scale) and cost_scale > 0):
            raise ValueError(f"cost_scale must be a positive finite number, got {cost_scale!r}")
        self.cost_scale = float(cost_scale)

    def __repr__(self) -> str:
        return f"NetworkxFlowSolver(cost_scale={self.cost_scale})"

    def integer_costs(self, flow_program: FlowProgram) -> list[int]:
        """The scaled integer costs ``round(cost * cost_scale)`` handed to networkx.

        Raises
        ------
        ValueError
            If a scaled cost is too large to be an exact integer in float64.
        """
        costs = flow_program.costs
        if costs.size:
            largest = float(np.max(np.abs(costs)))
            if largest * self.cost_scale >= _EXACT_INTEGER_LIMIT:
                raise ValueError(
                    f"flow_program.costs has |cost| = {largest:.6g}, too large for "
                    f"cost_scale={self.cost_scale:g} (|cost| * cost_scale must be < 2**53); "
                    "lower cost_scale"
                )
        return [int(round(c * self.cost_scale)) for c in costs.tolist()]

    def solve_flow(
        self, flow_program: FlowProgram, *, time_limit: float | None = None
    ) -> FlowResult:
        """Minimum-cost flow of every value K = 0..max_flow.

        Parameters
        ----------
        flow_program : FlowProgram
        time_limit : float or None
            Wall-clock seconds; checked before each K.  K not reached get TIME_LIMIT and
            cost ``nan``.

        Returns
        -------
        FlowResult
            ``costs[K]`` float (``inf`` infeasible), ``edge_flows[K]`` int.
        """
        if not isinstance(flow_program, FlowProgram):
            raise TypeError(
                f"flow_program must be a FlowProgram, got {type(flow_program).__name__}"
            )
        limit = validate_time_limit(time_limit)
        nx = _networkx()
        started = time.perf_counter()
        scaled = self.integer_costs(flow_program)
        num_edges = flow_program.num_edges
        tails = flow_program.tails.tolist()
        heads = flow_program.heads.tolist()
        graph = _flow_graph(nx, flow_program, scaled)
        largest_flow = _maximum_flow_value(flow_program)

        count = flow_program.max_flow + 1
        costs = np.full(count, np.inf)
        flows = np.zeros((count, num_edges), dtype=np.int64)
        statuses: list[SolveStatus] = []
        true_costs = flow_program.costs.tolist()
        for k in range(count):
            if k > largest_flow:
                statuses.append(SolveStatus.INFEASIBLE)
                continue
            if limit is not None and time.perf_counter() - started > limit:
                statuses.append(SolveStatus.TIME_LIMIT)
                costs[k] = np.nan
                continue
            graph.nodes[flow_program.source]["demand"] = -k
            graph.nodes[flow_program.sink]["demand"] = k
            try:
                _, flow_dict = nx.network_simplex(graph)
            except nx.NetworkXUnfeasible:
                statuses.append(SolveStatus.INFEASIBLE)
                continue
            except nx.NetworkXUnbounded:
                statuses.append(SolveStatus.UNBOUNDED)
                costs[k] = -np.inf
                continue
            for e in range(num_edges):
                flows[k, e] = flow_dict[tails[e]][heads[e]][e]
            costs[k] = math.fsum(
                c * f for c, f in zip(true_costs, flows[k].tolist(), strict=True) if f
            )
            statuses.append(SolveStatus.OPTIMAL)
        seconds = time.perf_counter() - started
        return FlowResult(
            costs=costs,
            edge_flows=flows,
            statuses=tuple(statuses),
            solve_seconds=seconds,
            solver=self.name,
            message=(
                f"maximum flow value {largest_flow}; costs rounded to 1/{self.cost_scale:g} "
                "for network simplex and recomputed in float"
            ),
        )


def _maximum_flow_value(flow_program: FlowProgram) -> int:
    """Largest feasible flow value from source to sink (parallel edges merged)."""
    nx = _networkx()
    merged = nx.DiGraph()
    merged.add_nodes_from(range(flow_program.num_nodes))
    for tail, head, capacity in zip(
        flow_program.tails.tolist(),
        flow_program.heads.tolist(),
        flow_program.capacities.tolist(),
        strict=True,
    ):
        if tail == head:
            continue
        if merged.has_edge(tail, head):
            merged[tail][head]["capacity"] += capacity
        else:
            merged.add_edge(tail, head, capacity=capacity)
    return int(nx.maximum_flow_value(merged, flow_program.source, flow_program.sink))


def _flow_graph(nx: Any, flow_program: FlowProgram, scaled: list[int]) -> Any:
    """``flow_program`` as a networkx MultiDiGraph for network simplex: its nodes with
    demand 0, and edge ``e`` keyed ``e`` with its capacity and integer cost
    ``scaled[e]``."""
    tails = flow_program.tails.tolist()
    heads = flow_program.heads.tolist()
    capacities = flow_program.capacities.tolist()
    graph = nx.MultiDiGraph()
    graph.add_nodes_from(range(flow_program.num_nodes), demand=0)
    for e in range(flow_program.num_edges):
        graph.add_edge(tails[e], heads[e], key=e, capacity=capacities[e], weight=scaled[e])
    return graph
