"""The tracking flow program against brute-force enumeration of vertex-disjoint path covers.

A track is a path ``i_1 < i_2 < ... < i_m`` of items joined by links, costing
``entry[i_1] + sum observation + sum links + exit[i_m]``; a flow of value K is a set of K
item-disjoint tracks.  Enumerating every such set on small random graphs gives the exact
minimum for every K, which the program solved by networkx must reproduce within the
documented rounding bound ``sum of capacities / cost_scale``.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from mapassoc.formulations.tracking_flow import (
    EDGE_ENTRY,
    EDGE_EXIT,
    EDGE_LINK,
    EDGE_OBSERVATION,
    combine_convex_costs,
    reachable_items,
    successive_shortest_paths,
    through_costs,
    tracking_flow_program,
)
from mapassoc.solvers.networkx_flow import NetworkxFlowSolver
from mapassoc.solvers.results import SolveStatus

SOLVER = NetworkxFlowSolver()


def random_graph(rng: np.random.Generator, *, n_forced: int = 0) -> dict:
    """2-6 items, links i -> j (i < j) with probability 0.5 (some doubled), costs of both
    signs, missing entry/exit edges; the first ``n_forced`` items forced."""
    n = int(rng.integers(2, 7))
    entry = rng.normal(1.0, 2.0, size=n)
    exits = rng.normal(1.0, 2.0, size=n)
    entry[rng.random(n) < 0.2] = math.inf
    exits[rng.random(n) < 0.2] = math.inf
    forced = np.zeros(n, dtype=bool)
    forced[: min(n_forced, n)] = True
    entry[forced & ~np.isfinite(entry)] = rng.normal(0.0, 1.0)
    tails, heads = [], []
    for i, j in itertools.combinations(range(n), 2):
        if rng.random() < 0.5:
            repeat = 2 if rng.random() < 0.15 else 1  # parallel links: the cheaper one counts
            tails.extend([i] * repeat)
            heads.extend([j] * repeat)
    return {
        "entry_costs": entry,
        "observation_costs": rng.normal(-1.0, 2.0, size=n),
        "exit_costs": exits,
        "link_tails": np.array(tails, dtype=np.int64),
        "link_heads": np.array(heads, dtype=np.int64),
        "link_costs": rng.normal(-0.5, 2.0, size=len(tails)),
        "forced": forced,
    }


def all_paths(g: dict) -> dict[tuple[int, ...], float]:
    """Every track (item tuple) with its cheapest cost (cheapest of parallel links)."""
    n = g["observation_costs"].size
    link: dict[tuple[int, int], float] = {}
    for t, h, c in zip(g["link_tails"], g["link_heads"], g["link_costs"], strict=True):
        link[(int(t), int(h))] = min(link.get((int(t), int(h)), math.inf), float(c))
    paths: dict[tuple[int, ...], float] = {}

    def extend(path: tuple[int, ...], cost: float) -> None:
        last = path[-1]
        if math.isfinite(g["exit_costs"][last]):
            paths[path] = cost + float(g["exit_costs"][last])
        for j in range(last + 1, n):
            if (last, j) in link:
                extend(path + (j,), cost + link[(last, j)] + float(g["observation_costs"][j]))

    for i in range(n):
        if math.isfinite(g["entry_costs"][i]):
            extend((i,), float(g["entry_costs"][i] + g["observation_costs"][i]))
    return paths


def brute_force_costs(g: dict, kmax: int) -> np.ndarray:
    """Minimum cost of K item-disjoint tracks such that every forced item starts one,
    K = 0..kmax."""
    paths = list(all_paths(g).items())
    forced = set(np.flatnonzero(g["forced"]).tolist())
    best = np.full(kmax + 1, math.inf)

    def grow(start: int, firsts: frozenset[int], used: frozenset[int], k: int,
             cost: float) -> None:
        if forced <= firsts:
            best[k] = min(best[k], cost)
        if k == kmax:
            return
        for p in range(start, len(paths)):
            items, c = paths[p]
            if used.isdisjoint(items) and forced.isdisjoint(items[1:]):
                grow(p + 1, firsts | {items[0]}, used | set(items), k + 1, cost + c)

    grow(0, frozenset(), frozenset(), 0, 0.0)
    return best


def program_of(g: dict, max_flow: int, *, forced: bool = True):
    args = {k: v for k, v in g.items() if k != "forced"}
    return tracking_flow_program(**args, max_flow=max_flow, forced=g["forced"] if forced else None)


def tolerance(flow) -> float:
    """The solver's documented bound (sum of capacities / cost_scale), plus float error
    of the forced bonus's cancellation."""
    return float(flow.program.capacities.sum()) / SOLVER.cost_scale + 1e-9 * (1 + flow.bonus)


@pytest.mark.parametrize("n_forced", [0, 1, 2])
def test_costs_for_every_k_equal_brute_force_path_covers(n_forced: int) -> None:
    rng = np.random.default_rng(10 + n_forced)
    for _ in range(25):
        g = random_graph(rng, n_forced=n_forced)
        n = g["observation_costs"].size
        flow = program_of(g, n)
        result = SOLVER.solve_flow(flow.program)
        got = flow.track_costs(result.costs)
        want = brute_force_costs(g, n)
        assert np.array_equal(np.isfinite(got), np.isfinite(want)), (got, want)
        finite = np.isfinite(want)
        assert np.all(np.abs(got[finite] - want[finite]) <= tolerance(flow)), (got, want)


def test_decoded_paths_are_disjoint_follow_links_and_cost_what_is_reported() -> None:
    rng = np.random.default_rng(4)
    for _ in range(25):
        g = random_graph(rng, n_forced=int(rng.integers(0, 2)))
        n = g["observation_costs"].size
        flow = program_of(g, n)
        result = SOLVER.solve_flow(flow.program)
        costs = flow.track_costs(result.costs)
        paths = all_paths(g)
        for k in np.flatnonzero(np.isfinite(costs)).tolist():
            decoded = flow.decode_paths(result.edge_flows[k])
            assert len(decoded) == k
            items = [i for path in decoded for i in path]
            assert len(items) == len(set(items))  # vertex-disjoint
            assert set(np.flatnonzero(g["forced"]).tolist()) <= {p[0] for p in decoded}
            # Every decoded path is a track of the graph (entry, links, exit all exist)...
            assert all(path in paths for path in decoded)
            assert [p[0] for p in decoded] == sorted(p[0] for p in decoded)
            # ... and the tracks' cheapest costs add up to the reported cost.
            assert math.fsum(paths[p] for p in decoded) == pytest.approx(
                costs[k], abs=tolerance(flow)
            )


def test_cost_is_convex_in_the_number_of_tracks() -> None:
    rng = np.random.default_rng(5)
    checked = 0
    for _ in range(40):
        g = random_graph(rng, n_forced=int(rng.integers(0, 3)))
        flow = program_of(g, g["observation_costs"].size)
        costs = flow.track_costs(SOLVER.solve_flow(flow.program).costs)
        finite = np.flatnonzero(np.isfinite(costs))
        assert finite.size or flow.num_forced  # K = 0 is feasible without forced items
        assert np.all(np.diff(finite) == 1)  # an interval of K
        second = np.diff(costs[finite], n=2)
        checked += second.size
        assert np.all(second >= -2 * tolerance(flow)), costs
    assert checked > 20


def test_forced_items_leave_k_without_a_cover_infinite() -> None:
    # Item 0 is forced but has no exit and no link: no flow can use it, so every K is
    # infinite (not the cost of a flow that silently leaves it out).
    flow = tracking_flow_program(
        entry_costs=np.array([0.0, -1.0]),
        observation_costs=np.array([0.0, -1.0]),
        exit_costs=np.array([math.inf, 0.0]),
        link_tails=np.zeros(0, dtype=np.int64),
        link_heads=np.zeros(0, dtype=np.int64),
        link_costs=np.zeros(0),
        max_flow=2,
        forced=np.array([True, False]),
    )
    costs = flow.track_costs(SOLVER.solve_flow(flow.program).costs)
    assert np.all(np.isinf(costs))
    # With an exit at item 0, K = 1 is item 0 alone and K = 2 adds item 1 (cost -2).
    flow = tracking_flow_program(
        entry_costs=np.array([0.0, -1.0]),
        observation_costs=np.array([0.0, -1.0]),
        exit_costs=np.array([0.5, 0.0]),
        link_tails=np.zeros(0, dtype=np.int64),
        link_heads=np.zeros(0, dtype=np.int64),
        link_costs=np.zeros(0),
        max_flow=2,
        forced=np.array([True, False]),
    )
    costs = flow.track_costs(SOLVER.solve_flow(flow.program).costs)
    assert costs[0] == math.inf
    assert costs[1:] == pytest.approx([0.5, -1.5], abs=1e-9)


def test_program_layout_hand_worked() -> None:
    # Two items, one link 0 -> 1; item 1 has no entry edge.
    flow = tracking_flow_program(
        entry_costs=np.array([1.0, math.inf]),
        observation_costs=np.array([-2.0, -3.0]),
        exit_costs=np.array([0.5, 0.25]),
        link_tails=np.array([0]),
        link_heads=np.array([1]),
        link_costs=np.array([0.75]),
        max_flow=1,
    )
    prog = flow.program
    assert prog.num_nodes == 6 and (prog.source, prog.sink) == (0, 1)
    edges = sorted(zip(flow.edge_kind.tolist(), prog.tails.tolist(), prog.heads.tolist(),
                       prog.costs.tolist(), strict=True))
    assert edges == [
        (EDGE_ENTRY, 0, 2, 1.0),
        (EDGE_OBSERVATION, 2, 3, -2.0),
        (EDGE_OBSERVATION, 4, 5, -3.0),
        (EDGE_LINK, 3, 4, 0.75),
        (EDGE_EXIT, 3, 1, 0.5),
        (EDGE_EXIT, 5, 1, 0.25),
    ]
    assert np.all(prog.capacities == 1) and flow.bonus == 0.0
    result = SOLVER.solve_flow(prog)
    # K = 1: 1 - 2 + 0.75 - 3 + 0.25 = -3 (better than item 0 alone: -0.5).
    assert flow.track_costs(result.costs).tolist() == pytest.approx([0.0, -3.0])
    assert flow.decode_paths(result.edge_flows[1]) == ((0, 1),)


def test_bonus_is_one_plus_twice_the_absolute_costs() -> None:
    g = random_graph(np.random.default_rng(6), n_forced=2)
    plain = program_of(g, 2, forced=False)
    forced = program_of(g, 2)
    S = math.fsum(np.abs(plain.program.costs).tolist())
    assert forced.bonus == pytest.approx(1.0 + 2.0 * S)
    shift = plain.program.costs - forced.program.costs
    entry_forced = (forced.edge_kind == EDGE_ENTRY) & forced.forced[forced.edge_item]
    assert np.allclose(shift[entry_forced], forced.bonus) and np.all(shift[~entry_forced] == 0)


# ------------------------------------------------------------------ successive shortest paths


def ssp_costs(flow) -> tuple[np.ndarray, list[np.ndarray]]:
    steps = list(successive_shortest_paths(flow))
    costs = np.full(flow.program.max_flow + 1, math.inf)
    costs[: len(steps)] = [c for c, _ in steps]
    return flow.track_costs(costs), [f for _, f in steps]


@pytest.mark.parametrize("n_forced", [0, 1, 2])
def test_successive_shortest_paths_equal_brute_force_for_every_k(n_forced: int) -> None:
    rng = np.random.default_rng(20 + n_forced)
    for _ in range(30):
        g = random_graph(rng, n_forced=n_forced)
        n = g["observation_costs"].size
        flow = program_of(g, n)
        got, flows = ssp_costs(flow)
        want = brute_force_costs(g, n)
        assert np.array_equal(np.isfinite(got), np.isfinite(want)), (got, want)
        finite = np.isfinite(want)
        assert np.allclose(got[finite], want[finite], rtol=0, atol=1e-9 * (1 + flow.bonus))
        paths = all_paths(g)
        for k in np.flatnonzero(finite).tolist():
            decoded = flow.decode_paths(flows[k])
            assert len(decoded) == k and all(p in paths for p in decoded)
            assert math.fsum(paths[p] for p in decoded) == pytest.approx(got[k], abs=1e-9)
        # It stops at the largest feasible flow value (without forced items K = 0 is
        # always feasible, and every K up to the maximum flow).
        assert len(flows) - 1 == (np.flatnonzero(np.isfinite(brute_force_costs(
            {**g, "forced": np.zeros(n, dtype=bool)}, n)))[-1])


def test_successive_shortest_paths_stop_at_max_flow() -> None:
    g = random_graph(np.random.default_rng(21))
    flow = program_of(g, 1)
    steps = list(successive_shortest_paths(flow))
    assert len(steps) <= 2 and steps[0][0] == 0.0 and not steps[0][1].any()


# ------------------------------------------------------------------ integer scaling


def test_networkx_sees_integer_costs_scaled_and_rounded(monkeypatch: pytest.MonkeyPatch) -> None:
    import networkx as nx

    g = random_graph(np.random.default_rng(7), n_forced=1)
    flow = program_of(g, 3)
    seen: list[list[object]] = []
    real = nx.network_simplex

    def spy(graph, *args, **kwargs):
        seen.append([d["weight"] for _, _, d in graph.edges(data=True)])
        return real(graph, *args, **kwargs)

    monkeypatch.setattr(nx, "network_simplex", spy)
    SOLVER.solve_flow(flow.program)
    assert seen
    expected = sorted(round(c * SOLVER.cost_scale) for c in flow.program.costs.tolist())
    for weights in seen:
        assert all(type(w) is int for w in weights)
        assert sorted(weights) == expected


def test_rounding_error_is_within_the_documented_bound_and_the_bound_is_reached() -> None:
    # With a coarse scale (costs rounded to integers) the flow is optimal for the rounded
    # costs only: its true cost is >= the true minimum and within sum(capacities) / scale.
    coarse = NetworkxFlowSolver(cost_scale=1.0)
    rng = np.random.default_rng(8)
    worse = 0
    for _ in range(40):
        g = random_graph(rng)
        n = g["observation_costs"].size
        flow = program_of(g, n)
        got = flow.track_costs(coarse.solve_flow(flow.program).costs)
        want = brute_force_costs(g, n)
        finite = np.isfinite(want)
        bound = float(flow.program.capacities.sum()) / coarse.cost_scale
        gap = got[finite] - want[finite]
        assert np.all(gap >= -1e-9) and np.all(gap <= bound)
        worse += int(np.any(gap > 1e-9))
    assert worse > 0  # the rounding does cost something at this scale: the check has teeth


# ------------------------------------------------------------------ pruning helpers


def test_through_costs_are_the_cheapest_track_through_each_item() -> None:
    rng = np.random.default_rng(9)
    for _ in range(30):
        g = random_graph(rng)
        args = {k: v for k, v in g.items() if k != "forced"}
        through = through_costs(**args)
        paths = all_paths(g)
        for i in range(g["observation_costs"].size):
            want = min((c for p, c in paths.items() if i in p), default=math.inf)
            assert through[i] == pytest.approx(want, abs=1e-9) or through[i] == want


def test_dropping_items_dearer_than_zero_keeps_the_minimum_over_k() -> None:
    rng = np.random.default_rng(11)
    dropped = 0
    for _ in range(30):
        g = random_graph(rng)
        n = g["observation_costs"].size
        args = {k: v for k, v in g.items() if k != "forced"}
        keep = through_costs(**args) <= 0.0
        dropped += int(np.count_nonzero(~keep))
        remap = np.cumsum(keep) - 1
        inside = keep[g["link_tails"]] & keep[g["link_heads"]]
        pruned = {
            "entry_costs": g["entry_costs"][keep],
            "observation_costs": g["observation_costs"][keep],
            "exit_costs": g["exit_costs"][keep],
            "link_tails": remap[g["link_tails"][inside]],
            "link_heads": remap[g["link_heads"][inside]],
            "link_costs": g["link_costs"][inside],
            "forced": np.zeros(int(keep.sum()), dtype=bool),
        }
        full = brute_force_costs(g, n)
        small = brute_force_costs(pruned, int(keep.sum()))
        assert np.min(small) == pytest.approx(np.min(full), abs=1e-12)
    assert dropped > 0


def test_reachable_items_follow_links_forward() -> None:
    rng = np.random.default_rng(12)
    for _ in range(30):
        g = random_graph(rng)
        n = g["observation_costs"].size
        start = rng.random(n) < 0.3
        want = start.copy()
        for _ in range(n):
            for t, h in zip(g["link_tails"], g["link_heads"], strict=True):
                want[h] |= want[t]
        order = rng.permutation(g["link_tails"].size)  # link order must not matter
        got = reachable_items(start, g["link_tails"][order], g["link_heads"][order])
        assert got.tolist() == want.tolist()


def random_convex(rng: np.random.Generator) -> np.ndarray:
    length = int(rng.integers(1, 5))
    first = int(rng.integers(0, 2))
    steps = np.sort(rng.normal(0.0, 2.0, size=length - 1))
    values = rng.normal() + np.concatenate([[0.0], np.cumsum(steps)])
    return np.concatenate([np.full(first, math.inf), values])


def test_combining_convex_components_is_their_min_plus_convolution() -> None:
    rng = np.random.default_rng(13)
    for _ in range(40):
        parts = [random_convex(rng) for _ in range(int(rng.integers(1, 4)))]
        max_total = int(rng.integers(0, 9))
        total, counts = combine_convex_costs(parts, max_total)
        want = np.full(max_total + 1, math.inf)
        for split in itertools.product(*(range(p.size) for p in parts)):
            k = sum(split)
            if k <= max_total:
                want[k] = min(want[k], sum(p[s] for p, s in zip(parts, split, strict=True)))
        assert np.allclose(total, want, rtol=0, atol=1e-9) or np.array_equal(total, want)
        for k in range(max_total + 1):
            if math.isfinite(total[k]):
                assert counts[k].sum() == k
                assert sum(p[s] for p, s in zip(parts, counts[k], strict=True)) == pytest.approx(
                    total[k]
                )
            else:
                assert np.all(counts[k] == -1)


# ------------------------------------------------------------------ validation


def valid() -> dict:
    return {
        "entry_costs": np.zeros(3),
        "observation_costs": np.zeros(3),
        "exit_costs": np.zeros(3),
        "link_tails": np.array([0, 1]),
        "link_heads": np.array([1, 2]),
        "link_costs": np.zeros(2),
        "max_flow": 2,
    }


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"entry_costs": np.zeros(2)}, r"entry_costs must have shape \(3,\)"),
        ({"exit_costs": np.array([0.0, np.nan, 0.0])}, r"exit_costs\[1\] = nan"),
        ({"entry_costs": np.array([0.0, -np.inf, 0.0])}, r"entry_costs\[1\] = -inf"),
        ({"observation_costs": np.array([0.0, np.inf, 0.0])}, r"observation_costs\[1\] = inf"),
        ({"observation_costs": np.zeros((3, 1))}, "observation_costs must be 1-D"),
        ({"link_heads": np.array([1, 3])}, r"link_heads\[1\] = 3"),
        ({"link_tails": np.array([-1, 1])}, r"link_tails\[0\] = -1"),
        ({"link_tails": np.array([0, 2])}, r"link_tails\[1\] = 2 and link_heads\[1\] = 2"),
        ({"link_costs": np.array([0.0, np.inf])}, r"link_costs\[1\] = inf"),
        ({"link_costs": np.zeros(3)}, "link_tails, link_heads and link_costs"),
        ({"max_flow": -1}, "max_flow must be an integer >= 0"),
        ({"max_flow": True}, "max_flow must be an integer >= 0"),
        ({"forced": np.array([True, False])}, r"forced must have shape \(3,\)"),
        (
            {"forced": np.array([False, True, False]),
             "entry_costs": np.array([0.0, np.inf, 0.0])},
            r"forced\[1\] is set but entry_costs\[1\] = inf",
        ),
    ],
)
def test_invalid_arguments_raise_naming_the_argument(change: dict, message: str) -> None:
    # formulations may not import mapassoc.errors (tests/test_architecture.py): they raise
    # ValueError, of which InputError is a subclass.
    with pytest.raises(ValueError, match=message):
        tracking_flow_program(**{**valid(), **change})


def test_decode_refuses_flows_that_are_not_item_disjoint_paths() -> None:
    flow = tracking_flow_program(**valid())
    with pytest.raises(ValueError, match="edge_flows must have shape"):
        flow.decode_paths(np.zeros(3, dtype=np.int64))
    with pytest.raises(ValueError, match="0/1"):
        flow.decode_paths(np.full(flow.program.num_edges, 2))
    result = SOLVER.solve_flow(flow.program)
    assert result.statuses[0] is SolveStatus.OPTIMAL
    assert flow.decode_paths(result.edge_flows[0]) == ()
