"""Min-cost network-flow tracking over sliding windows, for every number of tracks at once.

Zhang, Li & Nevatia, "Global data association for multi-object tracking using network
flows", CVPR 2008 (the graph and its costs, section 3); Berclaz, Fleuret, Türetken & Fua,
"Multiple object tracking using k-shortest paths optimization", IEEE TPAMI 33(9), 2011
(min-cost flow for every number of tracks K, whose cost is convex in K).

**Windows.**  The recording is cut like the MAP estimator cuts it: windows of
``window_length`` scans (default ``config.estimator.windows.window_length``), of which the first
``stride`` (default ``config.estimator.windows.stride``) are committed before the window slides;
the last window commits all its scans.  Each window is one flow program
(:mod:`mapassoc.formulations.tracking_flow`) whose items are

* the **carried tracks**, committed by earlier windows (forced: each lies on a path,
  so a carried track continues, misses or ends but never vanishes), and
* the window's **detections**, in scan order.

**Costs** are the negated terms of the MAP estimator's track score
(:mod:`mapassoc.estimator.hypotheses`, after Blackman & Popoli 1999, section 6.2, on the
models of Afzal's survey, eqs. 9-13), split over the edges so that a path's cost is minus its
track's log-likelihood ratio against "its detections are false alarms":

================================  ==========================================================
edge                              cost
================================  ==========================================================
entry at a detection of scan j    ``-(log u_j - log V_s)``: the new-target density
                                  ``u_j Pd_s / V_s`` (``u_j`` the undetected-target mean of
                                  :mod:`mapassoc.models.population`) over the ``Pd_s`` of the
                                  observation edge
observation (a detection)         ``-(log Pd_s - log lambda_s)``, ``lambda_s`` the clutter
                                  intensity ``lambda_bar_s / V_s`` (Afzal's survey, eq. 13)
link: detection i -> detection k  ``-(dt log Ps + sum of log(1 - Pd P_G) over the skipped
                                  scans + log N(nu; 0, S))``: a track started at detection i
                                  by single-point initiation
                                  (:func:`~mapassoc.filtering.track_filter.start_track`),
                                  predicted to scan k and scored by its innovation
                                  likelihood (Afzal's survey, eq. 3): the two-point Markov
                                  term of Zhang et al., eq. 7; only for
                                  ``k - i - 1 <= max_gap`` and ``d2 <=`` the chi-square
                                  gate of ``config.estimator.pruning.gate_probability``
link: carried track -> detection  the same with the carried track's filtered state
                                  (all its committed detections) instead of a
                                  two-point start; the gap counts its misses since its
                                  last detection
exit after scan j                 ``-max over endings``: either missed at every later scan
                                  of the window (``dt log Ps + log(1 - Pd P_G)`` each) or
                                  missed up to some scan then ended there
                                  (``log(1 - Ps^dt)``), the best of the MAP estimator's
                                  own tails of a track
carried track entry / exit        entry 0 (plus the forcing bonus of the program); exit
                                  as above from the carried state's time
================================  ==========================================================

**Pruning** (exact for the chosen K): detections whose cheapest path through them costs
more than 0 and that no carried track can reach are dropped before solving
(:func:`~mapassoc.formulations.tracking_flow.through_costs`); most false alarms go.

**Number of tracks.**  The kept graph splits into independent components (no link
between them).  Each is solved parametrically, K = its carried tracks, +1, +2, ...: by
successive shortest paths
(:func:`~mapassoc.formulations.tracking_flow.successive_shortest_paths`, the default:
one Dijkstra per K on the float costs) or by networkx's network simplex
(:meth:`NetworkxFlowSolver.solve_flow`, one call per K on integer-scaled costs), up to
two new tracks first and twice as many while the minimum sits at the largest K solved;
the components' convex costs are combined
(:func:`~mapassoc.formulations.tracking_flow.combine_convex_costs`) for K up to
``Kmax = max(C, min(config.estimator.count.max_tracks, items kept))`` (C carried tracks; no
flow has more tracks than items), and the window's
track set is the flow of the K >= C with the smallest total cost (ties: the smaller K).
Under these costs that is the most likely track set of the window over every K with the
birth model's own prior on K (Perry's joint MAP without a separate count prior).  The
cost is convex in K, so the minimum is global unless it sits at Kmax (reported,
``at_max_flow``).

**Carrying tracks across windows.**  The chosen paths are committed up to the window's
last committed scan: a path that starts at a committed scan, or at a carried track, keeps
its detections at committed scans.  It is carried into the next window (its state: the
Kalman filter over all its committed detections, predicted to the last committed scan)
iff its path also uses a detection after the committed scans, or a link from its last
detection could still reach a scan after the window (``last detection + max_gap + 1 >=``
the window's end; possible only when ``window_length - stride < max_gap + 1``): the
window could not see the detection that would continue it, so the next window decides,
and the track may still end there.  Otherwise the track ends at its last detection.
Paths born after the committed scans are left to a later window.  The undetected-target
intensity is carried as the MAP estimator carries it.

The output tracks are the committed associations smoothed by
:func:`~mapassoc.filtering.smoothing.smooth_tracks`.
"""

from __future__ import annotations

import functools
import itertools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_array
from scipy.sparse.csgraph import connected_components

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.data.config import Config
from mapassoc.data.scans import Scan
from mapassoc.data.windows import window_spans
from mapassoc.errors import InputError
from mapassoc.estimator.terms import (
    ScanTerms,
    SensorTerms,
    earlier_ending,
    end_term,
    survival_term,
)
from mapassoc.filtering.smoothing import smooth_tracks
from mapassoc.filtering.track_filter import (
    FilteredTrack,
    innovations,
    predict_track,
    start_track,
    update_track,
)
from mapassoc.formulations.tracking_flow import (
    TrackingFlow,
    combine_convex_costs,
    reachable_items,
    successive_shortest_paths,
    through_costs,
    tracking_flow_program,
)
from mapassoc.models.population import (
    UndetectedTargets,
    WindowPopulation,
    recording_start,
    window_population,
)
from mapassoc.solvers.networkx_flow import NetworkxFlowSolver
from mapassoc.solvers.results import SolveStatus
from mapassoc.trackers.base import TrackerOutput, check_scans
from mapassoc.trackers.management import check_tracker_config, with_own_gate

__all__ = ["FlowTracker", "FlowWindowReport"]

_SSP = "successive-shortest-paths"
_SOLVERS = (_SSP, NetworkxFlowSolver.name)

_FIRST_NEW_TRACKS = 2
"""New tracks per component of the first parametric pass; the pass is repeated with twice
as many while the minimum cost sits at its largest K (convexity in K)."""


@dataclass(frozen=True, eq=False)
class FlowWindowReport:
    """One window of :class:`FlowTracker`.

    Attributes
    ----------
    window : int
    first_scan, last_scan : int
        Scan indices (into the recording) of the window's first and last scans.
    committed_scans : int
    carried_tracks : int
        C, the forced items.
    detections : int
        Detections in the window.
    items_kept : int
        Items (carried tracks and detections) left after the exact pruning.
    components : int
        Independent parts of the kept graph (no link between them), solved apart.
    links : int
        Links between kept items.
    track_costs : ndarray, shape (max_flow + 1,)
        Total cost of K tracks of the pruned graph, K = 0..max_flow (``inf`` for K < C
        and infeasible K); convex in K.  The minimum for every K up to
        :attr:`chosen_tracks`; beyond, each component was solved only up to the K past its
        own minimum, so an entry is an upper bound (``inf`` past what was solved).
    chosen_tracks : int
        The K of the committed flow (smallest total cost).
    at_max_flow : bool
        Whether the chosen K is max_flow while more items were kept (the minimum over
        all K may lie beyond).
    seconds : float
        Wall time of the window (scoring, pruning, solving).
    """

    window: int
    first_scan: int
    last_scan: int
    committed_scans: int
    carried_tracks: int
    detections: int
    items_kept: int
    components: int
    links: int
    track_costs: FloatArray = field(repr=False)
    chosen_tracks: int
    at_max_flow: bool
    seconds: float


class _WindowReportParts(TypedDict):
    """The :class:`FlowWindowReport` fields that :meth:`FlowTracker._solve_window` fills."""

    carried_tracks: int
    detections: int
    items_kept: int
    components: int
    links: int
    track_costs: FloatArray
    chosen_tracks: int
    at_max_flow: bool


@dataclass(frozen=True)
class _Path:
    """A chosen path: the carried track it starts at (or None) and its detections as
    (scan index, detection index) pairs in scan order."""

    carried: int | None
    detections: tuple[tuple[int, int], ...]


@dataclass
class _Track:
    """A committed track while the run goes on."""

    track_id: int
    associations: dict[int, int]
    state: FilteredTrack
    misses: int  # scans since its last detection, up to the last committed scan


@dataclass
class _WindowGraph:
    """One window's flow graph while it is built: items (carried tracks ``0..C-1``, then
    the detections in scan order, ``det_scan``/``det_index`` their recording scan and
    index), their entry, observation and exit costs, and the links found so far."""

    window: list[Scan]
    start: int
    times: FloatArray
    tails: FloatArray
    carried: int
    det_scan: NDArray[np.int64]
    det_index: NDArray[np.int64]
    first_item: NDArray[np.int64]
    entry: FloatArray
    observation: FloatArray
    exits: FloatArray
    link_tails: list[int] = field(default_factory=list)
    link_heads: list[int] = field(default_factory=list)
    link_costs: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class _LinkSource:
    """Where links start: an item, its state's window position (-1: a carried state
    before the window) and time, the state (None when every link is cached), the window
    positions it may link to, and its two-point cache key (None: not cached)."""

    item: int
    position: int
    time: float
    track: FilteredTrack | None
    first: int
    last: int
    key: tuple[int, int] | None


@dataclass(frozen=True)
class _Links:
    """Links between kept items, numbered in the kept items' order."""

    tails: NDArray[np.int64]
    heads: NDArray[np.int64]
    costs: FloatArray


@dataclass(frozen=True)
class _SolvedComponent:
    """One component's flow program, its items (window item numbers), the edge flows
    per K and the track costs per K."""

    flow: TrackingFlow
    items: NDArray[np.int64]
    edge_flows: list[NDArray[np.int64]]
    costs: FloatArray


def _shortest_paths_costs(
    program: Callable[..., TrackingFlow],
    items: NDArray[np.int64],
    cap: int,
    limit: int,
    forced: int,
) -> _SolvedComponent:
    """A component's costs by successive shortest paths: one program up to ``limit``
    whose steps are taken up to ``cap`` and further (doubling the new tracks) while the
    minimum sits at the cap; the flows of K <= cap are those of a program solved up to
    cap only."""
    flow = program(max_flow=limit)
    steps = successive_shortest_paths(flow)
    raw_costs: list[float] = []
    edge_flows: list[NDArray[np.int64]] = []
    while True:
        for cost, step_flows in itertools.islice(steps, cap + 1 - len(raw_costs)):
            raw_costs.append(cost)
            edge_flows.append(step_flows)
        solved = np.full(cap + 1, math.inf)
        solved[: len(raw_costs)] = raw_costs[: cap + 1]
        costs = flow.track_costs(solved)
        if cap >= limit or int(np.argmin(costs)) < cap:
            return _SolvedComponent(flow, items, edge_flows, costs)
        cap = min(limit, forced + 2 * (cap - forced))


def _weak_components(
    tails: NDArray[np.int64], heads: NDArray[np.int64], num_items: int
) -> tuple[int, NDArray[np.int32]]:
    """The weakly connected components of the links ``tails[e] -> heads[e]`` (shape
    (E,)) over ``num_items`` items: their number and each item's component label."""
    count, label = connected_components(
        coo_array(
            (np.ones(tails.size), (tails, heads)),
            shape=(num_items, num_items),
        ),
        directed=True,
        connection="weak",
    )
    return int(count), label


def _decode_paths(
    graph: _WindowGraph, solved: list[_SolvedComponent], tracks_per_component: IntArray
) -> list[_Path]:
    """The chosen flow's paths as carried track and (scan, detection) pairs."""
    C = graph.carried
    paths: list[_Path] = []
    for component, k in zip(solved, tracks_per_component, strict=True):
        for path in component.flow.decode_paths(component.edge_flows[k]):
            ids = [int(component.items[i]) for i in path]
            paths.append(
                _Path(
                    carried=ids[0] if ids[0] < C else None,
                    detections=tuple(
                        (int(graph.det_scan[i - C]), int(graph.det_index[i - C]))
                        for i in ids
                        if i >= C
                    ),
                )
            )
    return paths


class FlowTracker:
    """Sliding-window min-cost network-flow tracker (module docstring).

    Parameters
    ----------
    config : Config
        Models; ``estimator.gate_probability`` (gate of the links), ``max_tracks``
        (largest K solved per window), ``window_length`` and ``stride`` (defaults).
    gate_probability : float, optional
        The links' own gate probability, in (0, 1]; default
        ``config.estimator.pruning.gate_probability``.
    max_gap : int, default 2
        Most consecutive scans a link may skip (0: links join consecutive scans only).
    window_length : int, optional
        Scans per window (default ``config.estimator.windows.window_length``).
    stride : int, optional
        Scans committed per window, 1..window_length (default ``config.estimator.windows.stride``).
    solver : {"successive-shortest-paths", "networkx-flow"}
        How each window's flows are found: successive shortest paths on the float costs
        (:func:`~mapassoc.formulations.tracking_flow.successive_shortest_paths`, one
        Dijkstra per K), or networkx's network simplex on integer-scaled costs, one call
        per K (:class:`~mapassoc.solvers.networkx_flow.NetworkxFlowSolver`; slower, which
        is why it is not the default, with the same tracks unless two track sets tie
        within its rounding of the costs).
    name : str, default "flow"

    Raises
    ------
    InputError
        Bad ``max_gap``, ``window_length``, ``stride`` or ``solver``, or a sensor without
        false alarms (the observation cost needs ``log lambda``).
    """

    def __init__(
        self,
        *,
        config: Config,
        gate_probability: float | None = None,
        max_gap: int = 2,
        window_length: int | None = None,
        stride: int | None = None,
        solver: str = _SSP,
        name: str = "flow",
    ) -> None:
        config = with_own_gate(config, gate_probability)
        if isinstance(max_gap, bool) or not isinstance(max_gap, int) or max_gap < 0:
            raise InputError(f"max_gap must be an integer >= 0, got {max_gap!r}")
        length = config.estimator.windows.window_length if window_length is None else window_length
        if isinstance(length, bool) or not isinstance(length, int) or length < 1:
            raise InputError(f"window_length must be an integer >= 1, got {window_length!r}")
        step = config.estimator.windows.stride if stride is None else stride
        if isinstance(step, bool) or not isinstance(step, int) or not 1 <= step <= length:
            raise InputError(
                f"stride must be an integer in 1..window_length ({length}), got {step!r}"
            )
        if solver not in _SOLVERS:
            raise InputError(f"solver must be one of {', '.join(_SOLVERS)}, got {solver!r}")
        check_tracker_config(config)  # lambda > 0 and Pd * P_G < 1, as for GNN and JPDA
        self.config = config
        self.max_gap = max_gap
        self.window_length = length
        self.stride = step
        self.name = name
        self.solver_name = solver
        self.solver = NetworkxFlowSolver()
        self._log_survival = math.log(config.birth.survival_probability)
        self._sensor_terms = SensorTerms.of_all(
            config.sensors, config.estimator.pruning.gate_probability
        )

    def _gated(self, track: FilteredTrack, scan: Scan) -> tuple[NDArray[np.int64], FloatArray]:
        """Detections of ``scan`` in the gate of ``track`` and their ``log N(nu; 0, S)``."""
        if scan.size == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        innov = innovations(self.config, predict_track(self.config, track, scan.time), scan)
        inside = np.flatnonzero(innov.d2 <= self._sensor_terms[scan.sensor].threshold)
        return inside.astype(np.int64), innov.log_likelihood[inside]

    # -- run -------------------------------------------------------------------------
    def track(self, scans: Sequence[Scan]) -> TrackerOutput:
        """Track over ``scans``; ``details`` is a tuple of :class:`FlowWindowReport`."""
        scans = check_scans(scans, self.config)
        started = time.perf_counter()
        total = len(scans)
        terms = ScanTerms.of_recording(self.config, scans)
        two_point: dict[tuple[int, int, int], tuple[NDArray[np.int64], FloatArray]] = {}
        births: dict[tuple[int, int], FilteredTrack] = {}  # two-point starts, per detection
        carried: list[_Track] = []
        finished: list[_Track] = []
        undetected = recording_start(self.config.birth, scans[0].time)
        reports: list[FlowWindowReport] = []
        next_id = 1
        for span in window_spans(total, length=self.window_length, stride=self.stride):
            start, end, commit = span.start, span.end, span.commit
            for key in [k for k in two_point if k[0] < start]:
                del two_point[key]
            for birth_key in [k for k in births if k[0] < start]:
                del births[birth_key]
            window_started = time.perf_counter()
            paths, report_parts, undetected_after = self._solve_window(
                scans, start, end, commit, carried, undetected, terms, two_point, births
            )
            undetected = undetected_after
            carried, next_id, ended = self._commit(
                scans, start, commit, end, paths, carried, next_id
            )
            finished.extend(ended)
            reports.append(
                FlowWindowReport(
                    window=len(reports),
                    first_scan=start,
                    last_scan=end - 1,
                    committed_scans=commit,
                    seconds=time.perf_counter() - window_started,
                    **report_parts,
                )
            )
        finished.extend(carried)
        associations = {
            t.track_id: dict(sorted(t.associations.items()))
            for t in sorted(finished, key=lambda t: t.track_id)
        }
        tracks = smooth_tracks(scans, associations, self.config)
        return TrackerOutput(
            tracks=tracks,
            seconds=time.perf_counter() - started,
            associations=associations,
            details=tuple(reports),
        )

    # -- one window ------------------------------------------------------------------
    def _solve_window(
        self,
        scans: list[Scan],
        start: int,
        end: int,
        commit: int,
        carried: list[_Track],
        undetected: UndetectedTargets,
        terms: ScanTerms,
        two_point: dict[tuple[int, int, int], tuple[NDArray[np.int64], FloatArray]],
        births: dict[tuple[int, int], FilteredTrack],
    ) -> tuple[list[_Path], _WindowReportParts, UndetectedTargets]:
        """Score, prune and solve one window.

        ``two_point`` caches the gated links of a detection's single-point start to a later
        scan, ``births`` the start itself, both keyed by recording scan indices.

        Returns the chosen paths, the report fields and the undetected targets after
        the last committed scan.
        """
        window = scans[start:end]
        population = window_population(
            window,
            [self.config.sensors[s.sensor].detection_probability for s in window],
            self.config.birth,
            undetected,
            [t.state.time for t in carried],
        )
        log_miss = terms.miss
        tails = terms.window_tails(start, end)
        graph = self._window_items(window, start, len(carried), population, tails)
        self._carried_links(graph, carried, log_miss, tails)
        self._detection_links(graph, log_miss, two_point, births)
        kept, forced, sub = self._kept_subgraph(graph)
        # No flow has more tracks than items kept (each track holds one at least), so
        # a huge max_tracks costs no more than that.
        kmax = max(graph.carried, min(self.config.estimator.count.max_tracks, int(kept.size)))
        count, label = _weak_components(sub.tails, sub.heads, int(kept.size))
        solved = [
            self._solve_component(graph, kept, forced, sub, label == comp, kmax)
            for comp in range(count)
        ]
        if solved:
            costs, split = combine_convex_costs([s.costs for s in solved], kmax)
        else:
            costs, split = np.r_[0.0, np.full(kmax, math.inf)], np.zeros((kmax + 1, 0), int)
        if not np.any(np.isfinite(costs)):
            raise RuntimeError(
                f"flow window at scans {start}..{end - 1}: no flow of K >= {graph.carried} "
                "tracks was found"
            )
        chosen = int(np.argmin(costs))
        report: _WindowReportParts = {
            "carried_tracks": graph.carried,
            "detections": int(graph.det_scan.size),
            "items_kept": int(kept.size),
            "components": int(count),
            "links": int(sub.tails.size),
            "track_costs": costs,
            "chosen_tracks": chosen,
            "at_max_flow": chosen == kmax and kmax < kept.size,
        }
        paths = _decode_paths(graph, solved, split[chosen])
        return paths, report, population.after_scan[commit - 1]

    def _window_items(
        self,
        window: list[Scan],
        start: int,
        carried: int,
        population: WindowPopulation,
        tails: FloatArray,
    ) -> _WindowGraph:
        """The window's items (carried tracks, then detections in scan order) with their
        entry, observation and exit costs (module docstring's table); no links yet."""
        det_scan = np.concatenate(
            [np.full(s.size, start + p, dtype=np.int64) for p, s in enumerate(window)]
            + [np.zeros(0, dtype=np.int64)]
        )
        det_index = np.concatenate(
            [np.arange(s.size, dtype=np.int64) for s in window] + [np.zeros(0, dtype=np.int64)]
        )
        first_item = carried + np.concatenate([[0], np.cumsum([s.size for s in window])])
        n = carried + int(det_scan.size)
        graph = _WindowGraph(
            window=window,
            start=start,
            times=np.array([s.time for s in window]),
            tails=tails,
            carried=carried,
            det_scan=det_scan,
            det_index=det_index,
            first_item=first_item.astype(np.int64),
            entry=np.full(n, math.inf),
            observation=np.zeros(n),
            exits=np.full(n, math.inf),
        )
        graph.entry[:carried] = 0.0
        for p, scan in enumerate(window):
            sensor = self.config.sensors[scan.sensor]
            sl = slice(first_item[p], first_item[p + 1])
            u = float(population.first_detection_means[p])
            if u > 0.0:
                graph.entry[sl] = -(math.log(u) - math.log(sensor.region.volume))
            own = self._sensor_terms[scan.sensor]
            graph.observation[sl] = -(own.log_pd - own.log_clutter)
            if math.isfinite(tails[p]):
                graph.exits[sl] = -tails[p]
        return graph

    def _add_links(
        self,
        graph: _WindowGraph,
        log_miss: FloatArray,
        two_point: dict[tuple[int, int, int], tuple[NDArray[np.int64], FloatArray]],
        link: _LinkSource,
    ) -> None:
        """Links from item ``link.item`` (state ``link.track`` at window position
        ``link.position``, -1 for a carried state before the window) to the detections of
        positions ``link.first..link.last``; two-point links are cached under
        ``link.key`` (``link.track`` may be None when every one of them is cached)."""
        start, times = graph.start, graph.times
        for q in range(link.first, min(link.last, len(graph.window) - 1) + 1):
            # log(1 - Pd P_G) of the scans skipped between the two.
            misses = float(np.sum(log_miss[start + link.position + 1 : start + q]))
            if not math.isfinite(misses):
                break
            cache_key = None if link.key is None else (link.key[0], link.key[1], start + q)
            if cache_key is not None and cache_key in two_point:
                inside, loglik = two_point[cache_key]
            else:
                assert link.track is not None
                inside, loglik = self._gated(link.track, graph.window[q])
                if cache_key is not None:
                    two_point[cache_key] = (inside, loglik)
            base = survival_term(times[q] - link.time, self._log_survival) + misses
            graph.link_tails.extend([link.item] * inside.size)
            graph.link_heads.extend((graph.first_item[q] + inside).tolist())
            graph.link_costs.extend((-(base + loglik)).tolist())

    def _carried_links(
        self,
        graph: _WindowGraph,
        carried: list[_Track],
        log_miss: FloatArray,
        tails: FloatArray,
    ) -> None:
        """Each carried track's exit cost (from its state at the scan before the window)
        and its links to the window's detections."""
        start = graph.start
        for c, track in enumerate(carried):
            t_c = track.state.time
            dt0 = float(graph.times[0] - t_c)
            tail0 = earlier_ending(
                float(end_term(dt0, self._log_survival)),
                float(survival_term(dt0, self._log_survival)),
                float(log_miss[start]),
                float(tails[0]),
            )
            if math.isfinite(tail0):
                graph.exits[c] = -tail0
            source = _LinkSource(c, -1, t_c, track.state, 0, self.max_gap - track.misses, None)
            self._add_links(graph, log_miss, {}, source)

    def _detection_links(
        self,
        graph: _WindowGraph,
        log_miss: FloatArray,
        two_point: dict[tuple[int, int, int], tuple[NDArray[np.int64], FloatArray]],
        births: dict[tuple[int, int], FilteredTrack],
    ) -> None:
        """The two-point links of every detection's single-point start to the detections
        of the next ``max_gap + 1`` scans (cached across windows in ``two_point``, the
        starts in ``births``)."""
        start, n_scans = graph.start, len(graph.window)
        for p, scan in enumerate(graph.window):
            for a in range(scan.size):
                key = (start + p, a)
                last = min(p + 1 + self.max_gap, n_scans - 1)
                if all((key[0], a, start + q) in two_point for q in range(p + 1, last + 1)):
                    born = None
                else:
                    born = births.get(key)
                    if born is None:
                        born = births[key] = start_track(self.config, scan, a)
                item = int(graph.first_item[p] + a)
                source = _LinkSource(
                    item, p, float(graph.times[p]), born, p + 1, p + 1 + self.max_gap, key
                )
                self._add_links(graph, log_miss, two_point, source)

    @staticmethod
    def _kept_subgraph(
        graph: _WindowGraph,
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_], _Links]:
        """Exact pruning (:func:`~mapassoc.formulations.tracking_flow.through_costs`):
        the items kept, which items are forced (the carried tracks), and the links between
        kept items renumbered to the kept items' order."""
        n = graph.entry.size
        link_tails = np.asarray(graph.link_tails, dtype=np.int64)
        link_heads = np.asarray(graph.link_heads, dtype=np.int64)
        link_costs = np.asarray(graph.link_costs, dtype=float)
        forced = np.zeros(n, dtype=bool)
        forced[: graph.carried] = True
        through = through_costs(
            entry_costs=graph.entry,
            observation_costs=graph.observation,
            exit_costs=graph.exits,
            link_tails=link_tails,
            link_heads=link_heads,
            link_costs=link_costs,
        )
        keep = (through <= 0.0) | reachable_items(forced, link_tails, link_heads)
        kept = np.flatnonzero(keep)
        remap = np.full(n, -1, dtype=np.int64)
        remap[kept] = np.arange(kept.size)
        inside = keep[link_tails] & keep[link_heads]
        sub = _Links(remap[link_tails[inside]], remap[link_heads[inside]], link_costs[inside])
        return kept, forced, sub

    def _solve_component(
        self,
        graph: _WindowGraph,
        kept: NDArray[np.int64],
        forced: NDArray[np.bool_],
        sub: _Links,
        in_component: NDArray[np.bool_],
        kmax: int,
    ) -> _SolvedComponent:
        """One independent component's flow costs for every K up to its limit: up to two
        new tracks first, twice as many while the minimum sits at the largest K solved
        (the cost is convex in K, so a minimum below the cap is the minimum over all K)."""
        members = np.flatnonzero(in_component)
        local = np.full(kept.size, -1, dtype=np.int64)
        local[members] = np.arange(members.size)
        mine = in_component[sub.tails]
        items = kept[members]
        forced_here = int(np.count_nonzero(forced[items]))
        limit = min(int(members.size), forced_here + kmax - graph.carried)
        cap = min(limit, forced_here + _FIRST_NEW_TRACKS)
        program = functools.partial(
            tracking_flow_program,
            entry_costs=graph.entry[items],
            observation_costs=graph.observation[items],
            exit_costs=graph.exits[items],
            link_tails=local[sub.tails[mine]],
            link_heads=local[sub.heads[mine]],
            link_costs=sub.costs[mine],
            forced=forced[items],
        )
        if self.solver_name == _SSP:
            return _shortest_paths_costs(program, items, cap, limit, forced_here)
        while True:
            flow = program(max_flow=cap)
            result = self.solver.solve_flow(flow.program)
            comp_costs = flow.track_costs(result.costs)
            optimal = np.array([s is SolveStatus.OPTIMAL for s in result.statuses])
            comp_costs[~optimal] = math.inf
            if cap >= limit or int(np.argmin(comp_costs)) < cap:
                return _SolvedComponent(flow, items, list(result.edge_flows), comp_costs)
            cap = min(limit, forced_here + 2 * (cap - forced_here))

    # -- commit ----------------------------------------------------------------------
    def _commit(
        self,
        scans: list[Scan],
        start: int,
        commit: int,
        end: int,
        paths: list[_Path],
        carried: list[_Track],
        next_id: int,
    ) -> tuple[list[_Track], int, list[_Track]]:
        """Commit the window's first ``commit`` scans (module docstring); return the
        tracks carried on, the next free id and the tracks that ended."""
        config = self.config
        last = start + commit - 1
        last_time = scans[last].time
        new_carried: list[_Track] = []
        ended: list[_Track] = []
        on_path: set[int] = set()
        for path in paths:
            detections = list(path.detections)
            if path.carried is not None:
                track = carried[path.carried]
                on_path.add(path.carried)
                state = track.state
                last_detection: int | None = None
            else:
                k0, j0 = detections.pop(0)
                if k0 > last:
                    continue  # born after the committed scans: a later window decides
                state = start_track(config, scans[k0], j0)
                track = _Track(next_id, {k0: j0}, state, 0)
                next_id += 1
                last_detection = k0
            for k, j in detections:
                if k > last:
                    break
                state = update_track(
                    config, predict_track(config, state, scans[k].time), scans[k], j
                )
                track.associations[k] = j
                last_detection = k
            misses = track.misses + commit if last_detection is None else last - last_detection
            # Continued in this window, or still linkable to a scan this window did not see
            # (its last detection, at scan last - misses, is within max_gap of scan end).
            if any(k > last for k, _ in detections) or (
                end < len(scans) and last - misses + self.max_gap + 1 >= end
            ):
                track.state = predict_track(config, state, last_time)
                track.misses = misses
                new_carried.append(track)
            else:
                track.state = state
                ended.append(track)
        ended.extend(t for c, t in enumerate(carried) if c not in on_path)
        new_carried.sort(key=lambda t: t.track_id)
        return new_carried, next_id, ended
