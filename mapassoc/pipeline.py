"""The MAP window track-set estimator, end to end.

This is the only module that wires the domain (:mod:`mapassoc.hypotheses`), the
formulations (:mod:`mapassoc.formulations`) and the solvers (:mod:`mapassoc.solvers`).

For each window of ``window_length`` consecutive scans:

1. grow the track trees (carried tracks and tracks born in the window) and score every
   hypothesis (:class:`~mapassoc.hypotheses.HypothesisGenerator`);
2. turn the choice of a track set into a packing problem (detections used at most
   once, carried tracks exactly once) and split it into independent clusters;
3. per cluster, compute the best score and the log-mass of all track sets for every
   k: exactly (:func:`~mapassoc.formulations.cardinality.exact_cardinality_table`) when
   the search fits ``exact_node_limit``, otherwise with the integer-program solver (the
   MAP per k) and its ``m_best`` best sets per k (the marginal);
4. combine the clusters (max-plus and sum-product convolution), apply p(K) and get
   p(K | Z), the joint MAP K and the marginal K (:mod:`mapassoc.posterior`);
5. take the best track set of the chosen K, commit its oldest ``stride`` scans and carry
   the tracks alive at the last committed scan into the next window.

At the end every track is smoothed (RTS) over the detections it used.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from mapassoc.config import Config
from mapassoc.errors import InputError
from mapassoc.formulations.bounds import fixed_variable_bounds
from mapassoc.formulations.cardinality import (
    CardinalityTable,
    CombinedTable,
    NodeLimitExceeded,
    combine_tables,
    exact_cardinality_table,
    single_hypothesis_table,
    table_from_sets,
)
from mapassoc.formulations.clusters import cluster_hypotheses
from mapassoc.formulations.packing import (
    MergedProblem,
    PackingProblem,
    decode_selection,
    merge_interchangeable,
    set_packing_program,
)
from mapassoc.hypotheses import CarriedTrack, HypothesisGenerator, WindowHypotheses
from mapassoc.io import Origins, TrackTable
from mapassoc.oracle import oracle_tracks
from mapassoc.posterior import KPosterior, k_posterior
from mapassoc.scans import Scan, check_scan_order
from mapassoc.solvers import HighsSolver, SolveResult, SolveStatus, get_solver, solve_k_best

__all__ = [
    "ClusterReport",
    "WindowSolution",
    "WindowReport",
    "EstimateResult",
    "WindowEstimator",
    "packing_problem",
]

BOUND_PRUNE_MIN_HYPOTHESES = 30
"""Clusters with fewer merged hypotheses skip the LP-bound pruning (they are cheap anyway)."""

ProgressCallback = Callable[[int, int], None]
WindowCallback = Callable[["WindowReport"], None]


def packing_problem(hypotheses: WindowHypotheses) -> PackingProblem:
    """The packing problem of a window's hypotheses.

    Resources ``0..D-1`` are the window's detections (at most once); resource ``D + t``
    is carried tree ``t`` (exactly once).
    """
    D = hypotheses.detections.count
    carried = int(np.count_nonzero(hypotheses.tree_track_ids >= 0))
    H = hypotheses.count
    lengths = np.diff(hypotheses.detection_indptr)
    is_carried = hypotheses.tree < carried
    new_lengths = lengths + is_carried
    indptr = np.concatenate([[0], np.cumsum(new_lengths)]).astype(np.int64)
    indices = np.empty(indptr[-1], dtype=np.int64)
    for h in range(H):
        dets = hypotheses.detections_of(h)
        start = indptr[h]
        indices[start : start + len(dets)] = dets
        if is_carried[h]:
            indices[start + len(dets)] = D + hypotheses.tree[h]
    return PackingProblem(
        scores=hypotheses.scores,
        resource_indptr=indptr,
        resource_indices=indices,
        exactly_one=np.r_[np.zeros(D, dtype=bool), np.ones(carried, dtype=bool)],
        counts=hypotheses.counts_toward_k,
    )


@dataclass(frozen=True)
class ClusterReport:
    """How one large cluster was solved (clusters solved exactly are only counted).

    Attributes
    ----------
    size : int
        Hypotheses in the cluster.
    status : str
        Worst solver status over its solves.
    solves : int
        Integer programs solved.
    log_captured : float
        Lower bound on log(mass of the sets found / mass of all sets).
    """

    size: int
    status: str
    solves: int
    log_captured: float


@dataclass(frozen=True, eq=False)
class WindowSolution:
    """Everything computed for one window (for notebooks and tests).

    Attributes
    ----------
    hypotheses : WindowHypotheses
    problem : PackingProblem
    table : CombinedTable
        Per-K best score, best set and log-mass of the whole window.
    posterior : KPosterior
    cluster_sizes : tuple of int
    solver_clusters : tuple of ClusterReport
        Clusters too large for the exact search.
    generate_seconds, solve_seconds : float
    bound_pruned : int
        Merged hypotheses dropped by the LP bound (see ``WindowEstimator._bound_prune``).
    """

    hypotheses: WindowHypotheses
    problem: PackingProblem
    table: CombinedTable
    posterior: KPosterior
    cluster_sizes: tuple[int, ...]
    solver_clusters: tuple[ClusterReport, ...]
    generate_seconds: float
    solve_seconds: float
    bound_pruned: int = 0

    @property
    def status(self) -> str:
        """``"exact"``, or the worst solver status over the large clusters."""
        if not self.solver_clusters:
            return "exact"
        statuses = {c.status for c in self.solver_clusters}
        for s in ("failed", "time_limit", "work_limit"):
            if s in statuses:
                return s
        return "optimal"

    @property
    def captured_mass(self) -> float:
        """Lower bound on the share of the window's posterior mass that was summed."""
        return math.exp(sum(c.log_captured for c in self.solver_clusters))

    def selection(self, k: int) -> NDArray[np.int64]:
        """Hypotheses of the best track set with k tracks."""
        chosen = self.table.best_set(k)
        if chosen is None:
            raise InputError(f"no feasible track set with K = {k} in this window")
        return np.asarray(chosen, dtype=np.int64)


@dataclass(frozen=True)
class WindowReport:
    """One line of ``windows.jsonl``."""

    index: int
    first_scan: int
    last_scan: int
    start_time: float
    end_time: float
    committed_scans: int
    probabilities: tuple[float, ...]
    best_objective: tuple[float | None, ...]
    joint_map_k: int
    marginal_k: int
    chosen_k: int
    marginal_exact: bool
    captured_mass: float
    status: str
    hypotheses: int
    generated: int
    pruned: int
    bound_pruned: int
    clusters: int
    largest_cluster: int
    solver_clusters: int
    carried_tracks: int
    piles_up_at_kmax: bool
    generate_seconds: float
    solve_seconds: float

    def to_json(self, *, timings: bool = True) -> dict[str, object]:
        out: dict[str, object] = {
            "window": self.index,
            "first_scan": self.first_scan,
            "last_scan": self.last_scan,
            "start_time": self.start_time,
            "end_time": self.end_time,
            "committed_scans": self.committed_scans,
            "p_k": list(self.probabilities),
            "joint_map_k": self.joint_map_k,
            "marginal_k": self.marginal_k,
            "chosen_k": self.chosen_k,
            "best_objective": list(self.best_objective),
            "status": self.status,
            "marginal_exact": self.marginal_exact,
            "captured_mass": self.captured_mass,
            "hypotheses": self.hypotheses,
            "hypotheses_generated": self.generated,
            "hypotheses_pruned": self.pruned,
            "hypotheses_pruned_by_bound": self.bound_pruned,
            "clusters": self.clusters,
            "largest_cluster": self.largest_cluster,
            "solver_clusters": self.solver_clusters,
            "carried_tracks": self.carried_tracks,
            "piles_up_at_kmax": self.piles_up_at_kmax,
        }
        if timings:
            out["generate_seconds"] = self.generate_seconds
            out["solve_seconds"] = self.solve_seconds
        return out


@dataclass
class _TrackRecord:
    """Committed history of one track (mutable while the run goes on)."""

    track_id: int
    rows: list[int] = field(default_factory=list)
    scan_indices: list[int] = field(default_factory=list)
    ended: bool = False


@dataclass(frozen=True, eq=False)
class EstimateResult:
    """Output of :meth:`WindowEstimator.run`.

    Attributes
    ----------
    tracks : TrackTable
        Smoothed tracks, one row per track per scan from its first to its last detection.
    windows : tuple of WindowReport
    track_rows : dict of int to tuple of int
        Detection rows used by each track.
    seconds : float
        Wall time of the run.
    num_scans : int
    """

    tracks: TrackTable
    windows: tuple[WindowReport, ...]
    track_rows: dict[int, tuple[int, ...]]
    seconds: float
    num_scans: int

    def summary(self, *, timings: bool = True) -> dict[str, object]:
        w = self.windows
        out: dict[str, object] = {
            "scans": self.num_scans,
            "windows": len(w),
            "tracks": len(self.track_rows),
            "detections_in_tracks": int(sum(len(r) for r in self.track_rows.values())),
            "windows_exact": int(sum(1 for r in w if r.status == "exact")),
            "windows_marginal_exact": int(sum(1 for r in w if r.marginal_exact)),
            "windows_piling_up_at_kmax": int(sum(1 for r in w if r.piles_up_at_kmax)),
            "mean_hypotheses_per_window": float(np.mean([r.hypotheses for r in w])) if w else 0.0,
            "max_cluster": int(max((r.largest_cluster for r in w), default=0)),
            "min_captured_mass": float(min((r.captured_mass for r in w), default=1.0)),
        }
        if timings:
            out["seconds"] = self.seconds
            out["scans_per_second"] = self.num_scans / self.seconds if self.seconds > 0 else None
        return out


class WindowEstimator:
    """Sliding-window MAP estimator of track sets and of the number of tracks.

    Parameters
    ----------
    config : Config
        Motion model, sensors, birth model and estimator settings.
    """

    def __init__(self, *, config: Config) -> None:
        self.config = config
        s = config.estimator
        self.settings = s
        self.generator = HypothesisGenerator(
            motion=config.motion,
            sensors=config.sensors,
            birth=config.birth,
            gate_probability=s.gate_probability,
            max_hypotheses_per_tree=s.max_hypotheses_per_tree,
            prune_log_ratio=s.prune_log_ratio,
        )
        try:
            self.solver = get_solver(s.solver)
        except ValueError as exc:
            raise InputError(f"estimator solver: {exc}") from None
        if not self.solver.supports_integer:
            raise InputError(
                f"solver '{s.solver}' cannot solve integer programs; choose one of the "
                "integer-capable backends (for example 'highs')"
            )
        self._lp_solver = HighsSolver()
        self.log_k_prior = np.asarray(s.log_k_prior())

    # -- one window ------------------------------------------------------------------
    def solve_window(
        self,
        scans: Sequence[Scan],
        carried: Sequence[CarriedTrack] = (),
        *,
        first_scans: Sequence[bool] | None = None,
    ) -> WindowSolution:
        """Hypotheses, per-K tables and posterior over K of one window.

        ``first_scans`` flags the scans that are their sensor's first scan of the data
        (births there include the initial population, ``BirthModel.initial_count``).
        """
        kmax = self.settings.max_tracks
        t0 = time.perf_counter()
        hyps = self.generator.generate(scans, carried, first_scans=first_scans)
        t1 = time.perf_counter()
        problem = packing_problem(hyps)
        clusters = cluster_hypotheses(problem)
        tables: list[CardinalityTable] = []
        reports: list[ClusterReport] = []
        bound_pruned = 0
        required = problem.exactly_one[problem.resource_indices]
        has_required = np.zeros(problem.num_hypotheses, dtype=bool)
        np.logical_or.at(
            has_required,
            np.repeat(np.arange(problem.num_hypotheses), np.diff(problem.resource_indptr)),
            required,
        )
        for members in clusters:
            if len(members) == 1:
                h = int(members[0])
                single = single_hypothesis_table(
                    float(problem.scores[h]),
                    float(problem.log_weights[h]),  # type: ignore[index]
                    bool(problem.counts[h]),
                    bool(has_required[h]),
                    kmax,
                )
                tables.append(single.remapped(members))
                continue
            # Interchangeable hypotheses (same detections, e.g. "ended" and "missed to
            # the end") merge exactly: best score for the MAP, summed weight for the mass.
            merged = merge_interchangeable(problem.subproblem(members))
            keep = self._bound_prune(merged.problem)
            if keep is not None:
                bound_pruned += int(np.count_nonzero(~keep))
                kept = np.flatnonzero(keep)
                merged = MergedProblem(
                    merged.problem.subproblem(kept),
                    merged.representative[kept],
                    tuple(merged.members[i] for i in kept),
                )
            try:
                table = exact_cardinality_table(
                    merged.problem, kmax, node_limit=self.settings.exact_node_limit
                )
            except NodeLimitExceeded:
                table, report = self._solve_large_cluster(merged.problem, kmax)
                reports.append(report)
            tables.append(table.remapped(members[merged.representative]))
        table = combine_tables(tables, kmax)
        posterior = k_posterior(table.best, table.log_mass, self.log_k_prior, exact=table.exact)
        t2 = time.perf_counter()
        return WindowSolution(
            hypotheses=hyps,
            problem=problem,
            table=table,
            posterior=posterior,
            cluster_sizes=tuple(len(c) for c in clusters),
            solver_clusters=tuple(reports),
            generate_seconds=t1 - t0,
            solve_seconds=t2 - t1,
            bound_pruned=bound_pruned,
        )

    def _bound_prune(self, problem: PackingProblem) -> NDArray[np.bool_] | None:
        """Hypotheses that can be in a set within ``prune_log_ratio`` of the cluster's best.

        One LP relaxation (K free) gives duals; every set containing hypothesis h scores at
        most its fixed-variable Lagrangian bound (:mod:`mapassoc.formulations.bounds`).
        Hypotheses whose bound is more than ``prune_log_ratio`` below the best integer set
        are dropped across trees (duplicates of carried tracks, mostly).  The best set
        itself always survives, and so does every hypothesis that uses no detection.
        Returns ``None`` when nothing is pruned or the cluster is too small to bother
        (fewer than :data:`BOUND_PRUNE_MIN_HYPOTHESES`).
        """
        ratio = self.settings.prune_log_ratio
        if problem.num_hypotheses < BOUND_PRUNE_MIN_HYPOTHESES or not math.isfinite(ratio):
            return None
        program = set_packing_program(problem, None)
        lp = self._lp_solver.solve_relaxation(program, time_limit=self.settings.time_limit)
        if lp.status is not SolveStatus.OPTIMAL or lp.solution is None:
            return None
        x = lp.solution
        if np.all(np.abs(x - np.round(x)) <= 1e-9):
            incumbent = lp.objective  # the relaxation is integral: the integer optimum
        else:
            best = self.solver.solve(program, time_limit=self.settings.time_limit)
            if best.solution is None:
                return None
            incumbent = best.objective
        bounds = fixed_variable_bounds(program, lp.ineq_duals, lp.eq_duals)  # type: ignore[arg-type]
        keep = bounds >= incumbent - ratio - 1e-9
        # A hypothesis that uses no detection (a carried track ended, or missed
        # throughout) is never dropped: with it every K down to 0 stays feasible, so a
        # K reported infeasible really has no track set.
        uses_detection = np.zeros(problem.num_hypotheses, dtype=bool)
        owner = np.repeat(np.arange(problem.num_hypotheses), np.diff(problem.resource_indptr))
        uses_detection[owner[~problem.exactly_one[problem.resource_indices]]] = True
        keep |= ~uses_detection
        return None if np.all(keep) else keep

    def _solve_large_cluster(
        self, problem: PackingProblem, kmax: int
    ) -> tuple[CardinalityTable, ClusterReport]:
        """MAP per k by the integer program; marginal from the m best sets per k.

        The m best sets are searched only for the k whose best set could carry mass:
        with at most ``N <= prod_r (1 + hypotheses using r)`` feasible sets (each set
        picks at most one user per resource), a k whose best set is more than
        ``log N + 40`` below the best over all k holds less than ``e^-40`` of the
        cluster's mass, and only its best set is kept.  The captured share is bounded
        below the same way: every set not found weighs at most the m-th best of its k.
        """
        m = self.settings.m_best
        usage = np.bincount(problem.resource_indices, minlength=problem.num_resources)
        log_num_sets = float(np.sum(np.log1p(usage)))
        excess = problem.log_weights - problem.scores  # type: ignore[operator]
        max_excess = float(np.sum(np.clip(excess, 0.0, None)))
        time_limit = self.settings.time_limit
        sets: list[tuple[tuple[int, ...], int, float, float]] = []
        worst = SolveStatus.OPTIMAL
        solves = 0
        seen: set[tuple[int, ...]] = set()

        def found(result: SolveResult, k: int) -> float | None:
            """Record the set of a solve (once) and return its score."""
            nonlocal worst
            if result.status not in (SolveStatus.OPTIMAL, SolveStatus.INFEASIBLE):
                worst = result.status
            if result.solution is None or result.status not in (
                SolveStatus.OPTIMAL,
                SolveStatus.TIME_LIMIT,
            ):
                return None
            chosen = decode_selection(result.solution)
            key = tuple(int(i) for i in chosen)
            if key in seen:
                return problem.value(chosen)
            seen.add(key)
            if not problem.is_feasible(chosen, k):
                raise RuntimeError(f"solver {result.solver!r} returned an infeasible set for k={k}")
            score = problem.value(chosen)
            weight = float(np.sum(problem.log_weights[chosen]))  # type: ignore[index]
            sets.append((key, k, score, weight))
            return score

        top_k = min(kmax, int(np.count_nonzero(problem.counts)))
        best_per_k: dict[int, float] = {}
        for k in range(top_k + 1):
            result = self.solver.solve(set_packing_program(problem, k), time_limit=time_limit)
            solves += 1
            score = found(result, k)
            if score is not None:
                best_per_k[k] = score
        tail_terms: list[float] = []
        overall = max(best_per_k.values(), default=-math.inf)
        for k, best in best_per_k.items():
            if best + max_excess + log_num_sets < overall - 40.0:
                tail_terms.append(log_num_sets + best + max_excess)
                continue
            program = set_packing_program(problem, k)
            results = solve_k_best(program, m, solver=self.solver, time_limit=time_limit)
            solves += len(results)
            scores_k = []
            for r in results:
                score = found(r, k)
                if score is not None:
                    scores_k.append(score)
            complete = len(results) < m and all(r.status == SolveStatus.OPTIMAL for r in results)
            if not complete:
                lowest = min(scores_k, default=best)
                tail_terms.append(log_num_sets + lowest + max_excess)
        found_terms = [w for *_, w in sets]
        table = table_from_sets(sets, kmax, exact=not tail_terms)
        if tail_terms:
            captured = float(np.logaddexp.reduce(found_terms))
            log_captured = captured - float(np.logaddexp.reduce([captured, *tail_terms]))
        else:
            log_captured = 0.0
        return table, ClusterReport(
            size=problem.num_hypotheses,
            status=worst.value,
            solves=solves,
            log_captured=log_captured,
        )

    # -- whole run -------------------------------------------------------------------
    def run(
        self,
        scans: Sequence[Scan],
        *,
        progress: ProgressCallback | None = None,
        on_window: WindowCallback | None = None,
    ) -> EstimateResult:
        """Estimate tracks over all scans.

        Parameters
        ----------
        scans : sequence of Scan
            Sorted by (time, sensor); may include empty scans.
        progress : callable, optional
            Called as ``progress(scans_committed, total_scans)`` after each window.
        on_window : callable, optional
            Called with each :class:`WindowReport` as soon as its window is committed
            (the command line writes ``windows.jsonl`` line by line with it, so a run
            that fails later keeps what it computed).
        """
        scans = list(scans)
        if not scans:
            raise InputError("scans is empty: there is nothing to estimate")
        check_scan_order(scans)
        for scan in scans:
            if scan.sensor not in self.config.sensors:
                raise InputError(
                    f"scan at time {scan.time} names sensor '{scan.sensor}', which the "
                    f"configuration does not define (known: {sorted(self.config.sensors)})"
                )
        t_start = time.perf_counter()
        seen_sensors: set[str] = set()
        first_of_sensor = []
        for scan in scans:
            first_of_sensor.append(scan.sensor not in seen_sensors)
            seen_sensors.add(scan.sensor)
        N = self.settings.window_length
        stride = self.settings.stride
        records: dict[int, _TrackRecord] = {}
        carried: list[CarriedTrack] = []
        reports: list[WindowReport] = []
        next_id = 1
        start = 0
        total = len(scans)
        piled = 0
        while start < total:
            end = min(start + N, total)
            commit = stride if end < total else end - start
            solution = self.solve_window(
                scans[start:end], carried, first_scans=first_of_sensor[start:end]
            )
            post = solution.posterior
            chosen_k = (
                post.marginal_k if self.settings.k_estimate == "marginal" else post.joint_map_k
            )
            selection = solution.selection(chosen_k)
            carried, next_id = self._commit(
                solution.hypotheses, selection, start, commit, carried, records, next_id
            )
            piled += post.piles_up_at_kmax
            reports.append(
                WindowReport(
                    index=len(reports),
                    first_scan=start,
                    last_scan=end - 1,
                    start_time=scans[start].time,
                    end_time=scans[end - 1].time,
                    committed_scans=commit,
                    probabilities=tuple(float(p) for p in post.probabilities),
                    best_objective=tuple(
                        float(b) if math.isfinite(b) else None for b in post.best_log_score
                    ),
                    joint_map_k=post.joint_map_k,
                    marginal_k=post.marginal_k,
                    chosen_k=chosen_k,
                    marginal_exact=post.exact,
                    captured_mass=solution.captured_mass,
                    status=solution.status,
                    hypotheses=solution.hypotheses.count,
                    generated=solution.hypotheses.generated,
                    pruned=solution.hypotheses.pruned,
                    bound_pruned=solution.bound_pruned,
                    clusters=len(solution.cluster_sizes),
                    largest_cluster=max(solution.cluster_sizes, default=0),
                    solver_clusters=len(solution.solver_clusters),
                    carried_tracks=int(np.count_nonzero(solution.hypotheses.tree_track_ids >= 0)),
                    piles_up_at_kmax=post.piles_up_at_kmax,
                    generate_seconds=solution.generate_seconds,
                    solve_seconds=solution.solve_seconds,
                )
            )
            start += commit
            if on_window is not None:
                on_window(reports[-1])
            if progress is not None:
                progress(start, total)
        if piled:
            warnings.warn(
                f"p(K = Kmax | Z) exceeded 1% in {piled} of {len(reports)} windows: "
                f"max_tracks = {self.settings.max_tracks} probably cuts off the posterior; "
                "raise it",
                RuntimeWarning,
                stacklevel=2,
            )
        tracks = self._smooth(scans, records)
        return EstimateResult(
            tracks=tracks,
            windows=tuple(reports),
            track_rows={tid: tuple(r.rows) for tid, r in sorted(records.items()) if r.rows},
            seconds=time.perf_counter() - t_start,
            num_scans=total,
        )

    def _commit(
        self,
        hyps: WindowHypotheses,
        selection: NDArray[np.int64],
        start: int,
        commit: int,
        carried: list[CarriedTrack],
        records: dict[int, _TrackRecord],
        next_id: int,
    ) -> tuple[list[CarriedTrack], int]:
        """Commit the first ``commit`` scans of the chosen set; return the new carried tracks."""
        nodes = hyps.nodes
        scans = hyps.scans
        new_carried: list[CarriedTrack] = []
        last_layer = commit - 1
        for h in selection.tolist():
            tree = int(hyps.tree[h])
            path = nodes.path(int(hyps.leaf[h]))
            track_id = int(hyps.tree_track_ids[tree])
            if track_id < 0:
                if nodes.layer[path[0]] > last_layer:
                    continue  # born after the committed scans: decided by a later window
                track_id = next_id
                next_id += 1
                records[track_id] = _TrackRecord(track_id)
            record = records[track_id]
            carry_node = -1
            for v in path:
                layer = int(nodes.layer[v])
                if layer > last_layer:
                    break
                if not nodes.alive[v]:
                    record.ended = True
                    break
                det = int(nodes.detection[v])
                if det >= 0:
                    record.rows.append(int(hyps.detections.rows[det]))
                    record.scan_indices.append(start + layer)
                if layer == last_layer:
                    carry_node = v
            if carry_node >= 0:
                mean, cov = nodes.state(carry_node)
                new_carried.append(
                    CarriedTrack(
                        track_id=track_id,
                        mean=mean,
                        covariance=cov,
                        time=scans[last_layer].time,
                        initiated=bool(nodes.initiated[carry_node]),
                        num_detections=int(nodes.num_detections[carry_node]),
                        first_detection_time=float(nodes.first_time[carry_node]),
                    )
                )
        new_carried.sort(key=lambda t: t.track_id)
        return new_carried, next_id

    def _smooth(self, scans: Sequence[Scan], records: dict[int, _TrackRecord]) -> TrackTable:
        """RTS-smooth every track over the detections it used."""
        all_rows = np.concatenate([s.rows for s in scans]).astype(np.int64)
        owner = {row: tid for tid, rec in records.items() for row in rec.rows}
        ids = np.array([owner.get(int(r), -1) for r in all_rows], dtype=np.int64)
        return oracle_tracks(scans, Origins(rows=all_rows, target_ids=ids), self.config)
