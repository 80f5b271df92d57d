"""Per-cluster tables within a budget: exact where it fits, certified bounds where not.

Part of the pipeline layer (it wires :mod:`mapassoc.formulations` to
:mod:`mapassoc.solvers`).  :meth:`ClusterSolver.solve_window` owns a window's whole
dispatch: it splits the window's packing problem into clusters, gives single hypotheses
and lone optional ones their closed-form tables, merges and bound-prunes the rest, solves
each and combines the tables (:class:`WindowTables`).  For one cluster (a packing problem
whose interchangeable hypotheses are merged) :meth:`ClusterSolver.solve` returns the
per-k table of best scores, best sets and log-masses, and says how it got it:

``exact``
    The frontier search (:mod:`mapassoc.formulations.frontier`) finished within
    ``exact_work_limit`` transitions: every entry is exact.
``bounded``
    The exact search would take more work: it passed ``exact_work_limit`` transitions,
    or was on course for more than :data:`WORK_PROJECTION` times that (stopped early,
    deterministically, to spare the time it would spend before failing).  A beam
    frontier search (``beam_width`` frontiers) sums a subset of the feasible sets: lower
    bounds on every log-mass and a feasible set for every k it reaches.  LP relaxations
    with the cardinality row, walked outward from the best k (one LP kept by the backend
    and warm-started from k to k, :func:`~mapassoc.solvers.relaxation_sequence`), bound
    the best score of every k from above (the LP value is concave in k, so the supporting
    line of the last LP bounds every k beyond it); an integral LP optimum is k's best
    set; where the beam's set does not meet its LP bound and the k can matter (LP bound
    within ``map_margin`` of the best set found), the integer program is solved.  The LP
    duals also bound every log-mass from above
    (:func:`~mapassoc.formulations.bounds.log_mass_upper_bounds`).  So every k gets a
    best score that is proven optimal, or a proven upper bound that is reported, and the
    mass gets an interval ``[log_mass, log_mass_upper]``.
``time_limit``
    The window's deadline passed: whatever was certified by then is kept, the rest is
    a narrow beam's lower bound and a dual upper bound.  Never a silent wrong answer.

Work limits are deterministic (transitions, frontiers); the wall-clock deadline is the
outer guard, so a result depends on the machine's speed only when the status says
``time_limit``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.data.settings import SearchSettings
from mapassoc.errors import InputError
from mapassoc.estimator.bounded_tables import (
    CLUSTER_STATUSES,
    BoundedSearch,
    ClusterReport,
    ClusterStatus,
    lp_duals,
    remaining,
)
from mapassoc.formulations.bounds import fixed_variable_bounds, greedy_packing
from mapassoc.formulations.cardinality import (
    CardinalityTable,
    ClusterTable,
    CombinedTable,
    SearchLimitExceeded,
    combine_tables,
    exact_cardinality_table,
    independent_table,
    single_hypothesis_table,
)
from mapassoc.formulations.clusters import cluster_hypotheses
from mapassoc.formulations.frontier import frontier_search
from mapassoc.formulations.marginals import (
    ENUMERATION_MAX_HYPOTHESES,
    FrontierMarginals,
    enumerated_marginals,
    frontier_marginals,
)
from mapassoc.formulations.packing import (
    MergedProblem,
    PackingProblem,
    decode_selection,
    merge_interchangeable,
    set_packing_program,
)
from mapassoc.solvers import (
    HighsSolver,
    ProgramSolver,
    RelaxationSolver,
    SolveStatus,
    get_integer_solver,
)

__all__ = [
    "ClusterReport",
    "ClusterSolver",
    "ClusterStatus",
    "CLUSTER_STATUSES",
    "WindowCluster",
    "WindowTables",
    "best_set_by_fixing",
    "default_lp_solver",
]


@dataclass(frozen=True, eq=False)
class WindowCluster:
    """One cluster of a solved window, as :meth:`ClusterSolver.solve_window` left it.

    Attributes
    ----------
    kind : {"cluster", "single", "independent"}
        A cluster searched after merging (and maybe bound pruning), a cluster of one
        hypothesis, or the lone hypotheses that may each be taken or not.
    members : ndarray of int, shape (n,)
        Window hypothesis indices: the cluster's hypotheses (``"cluster"``: the
        subproblem the merge was applied to, in its order), the one hypothesis, or the
        lone hypotheses.
    table : ClusterTable
        The cluster's per-k table (over the merged, kept hypotheses for ``"cluster"``).
    status : ClusterStatus
    merged : MergedProblem or None
        ``"cluster"``: the merge before bound pruning (its ``members`` index
        ``members``).
    kept : ndarray of bool or None
        ``"cluster"``: which merged hypotheses the bound pruning kept (None: all).
    """

    kind: str
    members: IntArray
    table: ClusterTable
    status: ClusterStatus = ClusterStatus.EXACT
    merged: MergedProblem | None = None
    kept: NDArray[np.bool_] | None = None


@dataclass(frozen=True, eq=False)
class WindowTables:
    """The clusters of one window solved: what :meth:`ClusterSolver.solve_window` returns.

    Attributes
    ----------
    table : CombinedTable
        The window's per-k table, the clusters' tables combined (best set in window
        hypothesis indices).
    clusters : tuple of WindowCluster
        Every cluster, as it was solved.
    reports : tuple of ClusterReport
        The clusters that are not exact, in cluster order.
    cluster_sizes : tuple of int
        Hypotheses of every cluster before merging, in cluster order.
    bound_pruned : int
        Merged hypotheses the LP-bound pruning dropped, over all clusters.
    pruning_cut_short : bool
        The deadline, not the bound, left a cluster that would have been pruned unpruned.
    """

    table: CombinedTable
    clusters: tuple[WindowCluster, ...]
    reports: tuple[ClusterReport, ...]
    cluster_sizes: tuple[int, ...]
    bound_pruned: int
    pruning_cut_short: bool


WORK_PROJECTION = 8.0
"""The exact search of a cluster also stops when on course for more than this many times
its work limit (``work_projection`` of
:func:`~mapassoc.formulations.frontier.frontier_search`): a search that fails at the
limit would spend all of it first, and the projection stops most of those early while
stopping almost none that would finish (a higher multiple stops fewer that would finish,
a lower one more).  The exact search of a cluster of
:data:`~mapassoc.formulations.frontier.WORK_COUNT_MIN_HYPOTHESES` hypotheses or more counts
its work beforehand and needs no projection (it stops at once or runs whole); the
projection still applies to smaller clusters and to the window marginals."""

BEAM_WIDENING = 4
"""Factor by which the window marginals' beam widens when it kept no feasible set."""

BEAM_WIDENINGS = 3
"""Most widenings of that beam; after them the cluster's marginals stay the beam's
(a total of ``-inf``: :meth:`ClusterSolver.marginals` then gives its hypotheses
``nan``, and the confidence pass leaves that window's probabilities unknown)."""

DEFAULT_BEAM_ENTRY_MARGIN = SearchSettings().beam_entry_margin
"""The beam's entry margin when none is given (``SearchSettings.beam_entry_margin``)."""


def count_multiplier_grid(search: SearchSettings) -> FloatArray:
    """The cardinality multipliers tried for the mass bound of the k no LP reached:
    ``search.mass_bound_multipliers`` values evenly spaced over
    [-``mass_bound_multiplier_limit``, ``mass_bound_multiplier_limit``] (one of them:
    0, the grid's centre, so the grid is symmetric whatever its size)."""
    limit = search.mass_bound_multiplier_limit
    if search.mass_bound_multipliers == 1:
        return np.zeros(1)
    return np.linspace(-limit, limit, search.mass_bound_multipliers)


_SMALL_AFTER_DEADLINE = 40
"""Past the deadline, clusters with fewer hypotheses still get the exact search (it
costs less than the bounds); larger ones go straight to the narrow beam."""

BOUND_PRUNE_MIN_HYPOTHESES = 100
"""Clusters with fewer merged hypotheses skip the LP-bound pruning: the exact search of
such a cluster costs about as much as the LP."""


def default_lp_solver(solver: ProgramSolver) -> RelaxationSolver:
    """The LP-relaxation backend that goes with an integer-program backend.

    ``solver`` itself when it declares ``supports_relaxation`` (it implements
    :class:`~mapassoc.solvers.RelaxationSolver`), otherwise a default
    :class:`~mapassoc.solvers.HighsSolver` (simplex duals at a vertex).
    """
    if getattr(solver, "supports_relaxation", False):
        return solver  # type: ignore[return-value]
    return HighsSolver()


def best_set_by_fixing(
    problem: PackingProblem,
    *,
    solver: ProgramSolver,
    lp_solver: RelaxationSolver,
    time_limit: float | None,
) -> tuple[IntArray | None, bool]:
    """The best feasible set of ``problem`` (K free): LP relaxation, reduced-cost fixing,
    then the integer program over the hypotheses that can still be in a best set.

    The LP relaxation's optimum is the answer when it is integral.  Otherwise a greedy
    rounding of it (:func:`~mapassoc.formulations.bounds.greedy_packing`) is an
    incumbent of score ``z``, and every hypothesis whose fixed-variable Lagrangian bound
    (:func:`~mapassoc.formulations.bounds.fixed_variable_bounds`, the reduced-cost
    bound of integer programming) is below ``z`` is in no set scoring ``z`` or more, so
    in no best set: the integer program is solved over the others only (on the
    refinement's long windows of a 100-target scene, a quarter of the hypotheses or
    fewer).  Exact: the same optimum value as the integer program over all of them.

    Parameters
    ----------
    problem : PackingProblem
    solver : ProgramSolver
        Integer-program backend.
    lp_solver : RelaxationSolver
        LP backend with duals.
    time_limit : float or None
        Seconds for all the solves together.

    Returns
    -------
    selection : ndarray of int or None
        The chosen hypotheses in increasing order, ``None`` when no feasible set was
        found (infeasible, or the time limit came first).
    optimal : bool
        Whether the set is proven best (False: the time limit stopped a solve).
    """
    deadline = math.inf if time_limit is None else time.perf_counter() + time_limit
    program = set_packing_program(problem, None)
    if program.num_variables == 0:
        return np.zeros(0, dtype=np.int64), True
    lp = lp_solver.solve_relaxation(program, time_limit=remaining(deadline))
    if lp.status is SolveStatus.INFEASIBLE:
        return None, True
    kept = np.arange(problem.num_hypotheses)
    if lp.status is SolveStatus.OPTIMAL and lp.solution is not None:
        x = lp.solution
        rounded = np.round(x)
        if np.all(np.abs(x - rounded) <= 1e-9) and program.is_feasible(rounded):
            return decode_selection(rounded), True
        incumbent = greedy_packing(problem, x)
        if incumbent is not None:
            bounds = fixed_variable_bounds(program, *lp_duals(lp))
            floor = float(np.sum(problem.scores[incumbent]))
            kept = np.flatnonzero(bounds >= floor - 1e-7 * (1.0 + abs(floor)))
    result = solver.solve(
        set_packing_program(problem.subproblem(kept), None), time_limit=remaining(deadline)
    )
    proven = result.is_optimal or result.status is SolveStatus.INFEASIBLE
    if result.solution is None:
        return None, proven
    return kept[decode_selection(result.solution)], proven


def uncounted(problem: PackingProblem) -> PackingProblem:
    """``problem`` with no hypothesis counted: its per-k tables have one entry, k = 0,
    the best set and the mass over every size (questions asked with K free)."""
    return PackingProblem.derived(
        scores=problem.scores,
        resource_indptr=problem.resource_indptr,
        resource_indices=problem.resource_indices,
        exactly_one=problem.exactly_one,
        counts=np.zeros(problem.num_hypotheses, dtype=bool),
        log_weights=problem.weights,
    )


def _probability(total: float) -> float:
    """A sum of the probabilities of exclusive events, rounded into [0, 1].

    The hypotheses of one tree are exclusive, so the sum is at most 1 but for rounding
    (a few ulps); more than 1e-9 over is a fault, not rounding, and raises.
    """
    if not -1e-9 <= total <= 1.0 + 1e-9:
        raise RuntimeError(f"a sum of exclusive probabilities came out {total!r}")
    return min(1.0, max(0.0, total))


@dataclass(frozen=True, eq=False)
class BestSet:
    """The best feasible set of a window's problem with K free (:meth:`ClusterSolver.best_set`).

    Attributes
    ----------
    selection : ndarray of int or None
        The chosen hypotheses in increasing order; ``None`` when no feasible set was
        found (the problem is infeasible, or the deadline came first).
    status : ClusterStatus
        ``exact``: proven best; ``bounded``: a backend's own deterministic limit left
        its incumbent; ``time_limit``: the deadline stopped a solve.
    """

    selection: IntArray | None
    status: ClusterStatus


@dataclass(frozen=True, eq=False)
class WindowMarginals:
    """Posterior marginals of a window's hypotheses with K free (:meth:`ClusterSolver.marginals`).

    Attributes
    ----------
    probabilities : ndarray, shape (H,)
        P(h in the set) under the weights ``exp(log_weights)``.
    status : ClusterStatus
        ``exact`` over the hypotheses kept, or ``bounded``: a cluster past the work
        limit had the beam's marginals (its probabilities are among the sets it kept).
    clusters : tuple of (ndarray of int, float)
        Each cluster's members and log-mass (``nan`` where the beam gave only a part).
    cluster_of : ndarray of int, shape (H,)
        The cluster of every hypothesis.
    problem : PackingProblem
        The problem with no hypothesis counted (what the masses are sums over).
    """

    probabilities: FloatArray
    status: ClusterStatus
    clusters: tuple[tuple[IntArray, float], ...]
    cluster_of: IntArray
    problem: PackingProblem

    @property
    def exact(self) -> bool:
        return self.status is ClusterStatus.EXACT


class ClusterSolver:
    """Solves the clusters of a window: exact frontier search, else certified bounds.

    Parameters
    ----------
    solver : ProgramSolver
        Exact integer-program backend.
    lp_solver : RelaxationSolver or None, default None
        Backend of the LP relaxations (``solve_relaxation``, with duals).  ``None``
        (default) picks :func:`default_lp_solver` of ``solver``: ``solver`` itself when
        it has ``supports_relaxation``, else a :class:`~mapassoc.solvers.HighsSolver`.
    exact_work_limit : int
        Transitions the exact frontier search may take per cluster.
    beam_width : int
        Frontiers the beam search keeps when the exact search does not fit.
    prune_log_ratio : float
        Hypotheses whose LP bound is this far below the cluster's best set are dropped
        before the search (documented pruning; ``inf`` disables).
    map_margin : float
        A k whose LP bound is this far below the best set found is not solved as an
        integer program; its best score is reported as bounded.
    bound_prune_min_hypotheses : int
        Smaller clusters skip the LP-bound pruning (default
        :data:`BOUND_PRUNE_MIN_HYPOTHESES`).
    work_projection : float or None
        The exact search also stops when on course for more than this many times
        ``exact_work_limit`` (default :data:`WORK_PROJECTION`; ``None``: only at the
        limit).
    """

    def __init__(
        self,
        *,
        solver: ProgramSolver,
        lp_solver: RelaxationSolver | None = None,
        exact_work_limit: int,
        beam_width: int,
        prune_log_ratio: float,
        map_margin: float = 30.0,
        bound_prune_min_hypotheses: int = BOUND_PRUNE_MIN_HYPOTHESES,
        work_projection: float | None = WORK_PROJECTION,
        beam_entry_margin: float = DEFAULT_BEAM_ENTRY_MARGIN,
        count_multipliers: FloatArray | None = None,
    ) -> None:
        self.solver = solver
        self.lp_solver = default_lp_solver(solver) if lp_solver is None else lp_solver
        self.exact_work_limit = int(exact_work_limit)
        self.beam_width = int(beam_width)
        self.prune_log_ratio = float(prune_log_ratio)
        self.map_margin = float(map_margin)
        self.bound_prune_min_hypotheses = int(bound_prune_min_hypotheses)
        self.work_projection = None if work_projection is None else float(work_projection)
        self.beam_entry_margin = float(beam_entry_margin)
        self.count_multipliers = (
            count_multiplier_grid(SearchSettings())
            if count_multipliers is None
            else np.asarray(count_multipliers, dtype=float)
        )

    @classmethod
    def from_settings(cls, search: SearchSettings) -> ClusterSolver:
        """The solver a configuration's ``[estimator.search]`` describes.

        Raises
        ------
        InputError
            ``search.solver`` names no integer-program backend (key ``solver``).
        """
        try:
            solver = get_integer_solver(search.solver)
        except ValueError as exc:
            raise InputError(f"estimator solver: {exc}", key="solver") from None
        return cls(
            solver=solver,
            exact_work_limit=search.exact_work_limit,
            beam_width=search.beam_width,
            prune_log_ratio=search.bound_prune_log_ratio,
            beam_entry_margin=search.beam_entry_margin,
            count_multipliers=count_multiplier_grid(search),
        )

    def _bounded_search(self) -> BoundedSearch:
        """The bounded path, configured as this solver is now."""
        return BoundedSearch(
            solver=self.solver,
            lp_solver=self.lp_solver,
            exact_work_limit=self.exact_work_limit,
            beam_width=self.beam_width,
            map_margin=self.map_margin,
            beam_entry_margin=self.beam_entry_margin,
            count_multipliers=self.count_multipliers,
        )

    # -- the window -------------------------------------------------------------------
    def solve_window(self, problem: PackingProblem, kmax: int, deadline: float) -> WindowTables:
        """Every cluster of a window's packing problem solved, and their tables combined.

        The dispatch: the problem splits into clusters (hypotheses linked through shared
        detections or trees).  A cluster of one hypothesis gets its table in closed
        form; the lone hypotheses that may each be taken or not share one table of
        independent choices; every other cluster has its interchangeable hypotheses
        merged exactly (best score for the MAP, summed weight for the mass), is
        bound-pruned (:meth:`bound_prune`) and solved (:meth:`solve`).  The tables
        combine into the window's per-k table up to ``kmax`` tracks.
        """
        clusters = cluster_hypotheses(problem)
        tables: list[ClusterTable] = []
        reports: list[ClusterReport] = []
        parts: list[WindowCluster] = []
        bound_pruned = 0
        pruning_cut_short = False
        has_required = problem.uses_any(problem.exactly_one)
        independent: list[int] = []  # lone hypotheses that may be taken or not
        for members in clusters:
            if len(members) == 1:
                h = int(members[0])
                if problem.counts[h] and not has_required[h]:
                    independent.append(h)
                    continue
                single = single_hypothesis_table(
                    float(problem.scores[h]),
                    float(problem.weights[h]),
                    bool(problem.counts[h]),
                    bool(has_required[h]),
                    min(kmax, 1),
                )
                tables.append(single.remapped(members))
                parts.append(WindowCluster("single", members, single))
                continue
            # Interchangeable hypotheses (same detections, e.g. "ended" and "missed to
            # the end") merge exactly: best score for the MAP, summed weight for the mass.
            merged = unpruned = merge_interchangeable(problem.subproblem(members))
            keep = self.bound_prune(merged.problem, deadline)
            if keep is None and time.perf_counter() >= deadline and self._prunable(merged):
                pruning_cut_short = True  # the clock, not the bound, left it unpruned
            if keep is not None:
                bound_pruned += int(np.count_nonzero(~keep))
                kept = np.flatnonzero(keep)
                merged = MergedProblem(
                    merged.problem.subproblem(kept),
                    merged.representative[kept],
                    tuple(merged.members[i] for i in kept),
                )
            table, report = self.solve(merged.problem, kmax, deadline)
            if report.status is not ClusterStatus.EXACT:
                reports.append(report)
            tables.append(table.remapped(members[merged.representative]))
            parts.append(WindowCluster("cluster", members, table, report.status, unpruned, keep))
        if independent:
            lone = np.asarray(independent, dtype=np.int64)
            tables.append(independent_table(problem.scores[lone], problem.weights[lone], lone))
            parts.append(WindowCluster("independent", lone, tables[-1]))
        return WindowTables(
            table=combine_tables(tables, kmax),
            clusters=tuple(parts),
            reports=tuple(reports),
            cluster_sizes=tuple(len(c) for c in clusters),
            bound_pruned=bound_pruned,
            pruning_cut_short=pruning_cut_short,
        )

    def _prunable(self, merged: MergedProblem) -> bool:
        """Whether :meth:`bound_prune` would have tried ``merged``."""
        return merged.problem.num_hypotheses >= self.bound_prune_min_hypotheses and math.isfinite(
            self.prune_log_ratio
        )

    # -- pruning -----------------------------------------------------------------------
    def bound_prune(self, problem: PackingProblem, deadline: float) -> NDArray[np.bool_] | None:
        """Hypotheses that can be in a set within ``prune_log_ratio`` of the cluster's best.

        One LP relaxation (K free) gives duals; every set containing hypothesis h scores at
        most its fixed-variable Lagrangian bound (:mod:`mapassoc.formulations.bounds`).
        Hypotheses whose bound is more than ``prune_log_ratio`` below the best integer set
        are dropped across trees (duplicates of carried tracks, mostly).  The best set
        itself always survives, and so does every hypothesis that uses no detection.
        Returns ``None`` when nothing is pruned, the cluster is too small to bother
        (fewer than ``bound_prune_min_hypotheses``) or the deadline has passed.
        """
        ratio = self.prune_log_ratio
        if problem.num_hypotheses < self.bound_prune_min_hypotheses or not math.isfinite(ratio):
            return None
        if time.perf_counter() >= deadline:
            return None
        program = set_packing_program(problem, None)
        lp = self.lp_solver.solve_relaxation(program, time_limit=remaining(deadline))
        if lp.status is not SolveStatus.OPTIMAL or lp.solution is None:
            return None
        x = lp.solution
        if np.all(np.abs(x - np.round(x)) <= 1e-9):
            incumbent = lp.objective  # the relaxation is integral: the integer optimum
        else:
            if time.perf_counter() >= deadline:
                return None
            best = self.solver.solve(program, time_limit=remaining(deadline))
            if best.solution is None:
                return None
            incumbent = best.objective
        bounds = fixed_variable_bounds(program, lp.ineq_duals, lp.eq_duals)  # type: ignore[arg-type]
        keep = bounds >= incumbent - ratio - 1e-9
        # A hypothesis that uses no detection (a carried track ended, or missed
        # throughout) is never dropped: with it every K down to 0 stays feasible, so a
        # K reported infeasible really has no track set.
        keep |= ~problem.uses_any(~problem.exactly_one)
        return None if np.all(keep) else keep

    # -- tables ------------------------------------------------------------------------
    def solve(
        self, problem: PackingProblem, kmax: int, deadline: float
    ) -> tuple[CardinalityTable, ClusterReport]:
        """The per-k table of one cluster and how it was obtained.

        The table covers k = 0..min(kmax, counted hypotheses): no set reaches further.
        """
        started = time.perf_counter()
        kmax = min(kmax, int(np.count_nonzero(problem.counts)))
        if problem.num_hypotheses >= _SMALL_AFTER_DEADLINE and time.perf_counter() >= deadline:
            return self._bounded_search().tables(problem, kmax, deadline, 0, started)
        try:
            table = exact_cardinality_table(
                problem,
                kmax,
                work_limit=self.exact_work_limit,
                deadline=deadline,
                work_projection=self.work_projection,
            )
        except SearchLimitExceeded as stop:
            return self._bounded_search().tables(problem, kmax, deadline, stop.work, started)
        return table, ClusterReport(
            size=problem.num_hypotheses,
            status=ClusterStatus.EXACT,
            work=0,
            solves=0,
            log_captured=0.0,
            seconds=time.perf_counter() - started,
        )

    # -- K free: the best set and the marginals ------------------------------------------
    def best_set(
        self, problem: PackingProblem, deadline: float, *, small_cluster: int = 12
    ) -> BestSet:
        """The best feasible set of ``problem`` over every size (the refinement's
        re-solves: their program has no cardinality row).

        The problem splits into independent clusters; a lone hypothesis is taken when
        it must be (it alone holds an exactly-once resource) or when it adds (score > 0,
        as the frontier search breaks the tie at 0 towards the empty set); a cluster of
        at most ``small_cluster`` hypotheses is searched exactly by the frontier search
        (within ``exact_work_limit`` and the deadline); the others go to one integer
        program together (a solver call costs about as much whatever its size),
        reduced by :func:`best_set_by_fixing`.
        """
        free = uncounted(problem)
        chosen: list[IntArray] = []
        large: list[IntArray] = []
        clusters = cluster_hypotheses(free)
        lone = np.array([int(m[0]) for m in clusters if len(m) == 1], dtype=np.int64)
        if lone.size:
            required = problem.uses_any(problem.exactly_one)
            chosen.append(lone[required[lone] | (problem.scores[lone] > 0)])
        for members in clusters:
            if len(members) == 1:
                continue
            if len(members) > small_cluster:
                large.append(members)
                continue
            try:
                found = frontier_search(
                    free.subproblem(members),
                    0,
                    work_limit=self.exact_work_limit,
                    deadline=deadline,
                )
            except SearchLimitExceeded:
                large.append(members)
                continue
            if found.best_sets[0] is None:
                return BestSet(None, ClusterStatus.EXACT)
            chosen.append(members[np.asarray(found.best_sets[0], dtype=np.int64)])
        status = ClusterStatus.EXACT
        if large:
            members = np.concatenate(large)
            selection, optimal = best_set_by_fixing(
                problem.subproblem(members),
                solver=self.solver,
                lp_solver=self.lp_solver,
                time_limit=remaining(deadline),
            )
            if not optimal:
                late = time.perf_counter() >= deadline
                status = ClusterStatus.TIME_LIMIT if late else ClusterStatus.BOUNDED
            if selection is None:
                return BestSet(None, status)
            chosen.append(members[selection])
        if not chosen:
            return BestSet(np.zeros(0, dtype=np.int64), status)
        return BestSet(np.sort(np.concatenate(chosen)), status)

    def marginals(
        self, problem: PackingProblem, *, work_limit: int, beam_width: int
    ) -> WindowMarginals:
        """P(h in the set) of every hypothesis over sets of every size, by cluster.

        A lone hypothesis in closed form (the sets {h} and, unless it alone holds an
        exactly-once resource, {}); a cluster of at most
        :data:`~mapassoc.formulations.marginals.ENUMERATION_MAX_HYPOTHESES` lists its
        subsets; the others run the frontier search forward and backward within
        ``work_limit`` transitions (and :data:`WORK_PROJECTION`), else a beam of
        ``beam_width`` frontiers at ``beam_entry_margin`` (status ``bounded``).
        """
        free = uncounted(problem)
        out = np.zeros(problem.num_hypotheses)
        status = ClusterStatus.EXACT
        seed = np.zeros(1)
        clusters: list[tuple[IntArray, float]] = []
        cluster_of = np.full(problem.num_hypotheses, -1, dtype=np.int64)
        required = free.uses_any(free.exactly_one)
        for members in cluster_hypotheses(free):
            cluster_of[members] = len(clusters)
            if len(members) == 1:
                h = int(members[0])
                weight = float(free.weights[h])
                total = weight if required[h] else float(np.logaddexp(0.0, weight))
                out[h] = math.exp(weight - total)
                clusters.append((members, total))
                continue
            sub = free.subproblem(members)
            try:
                if len(members) <= ENUMERATION_MAX_HYPOTHESES:
                    found = enumerated_marginals(sub, seed)  # every subset listed
                else:
                    found = frontier_marginals(
                        sub, seed, work_limit=work_limit, work_projection=WORK_PROJECTION
                    )
            except SearchLimitExceeded:
                found = self._beam_marginals(sub, seed, beam_width)
            if not found.exact:
                status = ClusterStatus.BOUNDED
            with np.errstate(invalid="ignore"):  # no set found: nan, see BEAM_WIDENINGS
                out[members] = np.exp(found.log_containing[0] - found.log_total[0])
            clusters.append((members, float(found.log_total[0]) if found.exact else math.nan))
        return WindowMarginals(out, status, tuple(clusters), cluster_of, free)

    def _beam_marginals(
        self, sub: PackingProblem, seed: FloatArray, beam_width: int
    ) -> FrontierMarginals:
        """The beam's marginals of a cluster the exact search could not finish, the beam
        widened (by :data:`BEAM_WIDENING` each time, at most :data:`BEAM_WIDENINGS` times)
        while it kept no feasible set (a total of ``-inf``: every frontier that could
        still meet the cluster's exactly-once resources fell out of the beam, as on a
        window of six closely spaced tracks with thousands of hypotheses)."""
        width = beam_width
        for _ in range(BEAM_WIDENINGS + 1):
            found = frontier_marginals(
                sub, seed, max_frontiers=width, entry_margin=self.beam_entry_margin
            )
            if np.isfinite(found.log_total[0]):
                break
            width *= BEAM_WIDENING
        return found

    @staticmethod
    def any_of(marginals: WindowMarginals, chosen: IntArray, *, work_limit: int) -> float:
        """P(at least one of the hypotheses ``chosen`` is in the set): one minus the mass
        of the sets without any of them over the total, cluster by cluster (only the
        clusters holding one of them); ``nan`` where a cluster had only the beam's part
        of the mass, or the search of the rest passed ``work_limit``."""
        if chosen.size == 0:
            return 0.0
        log_none = 0.0
        for c in np.unique(marginals.cluster_of[chosen]).tolist():
            members, log_total = marginals.clusters[c]
            if math.isnan(log_total):
                return math.nan  # the beam's part of the mass: no ratio to take
            rest = members[~np.isin(members, chosen)]
            if rest.size == 0:
                log_none += -log_total  # only the empty set is left: weight 1
                continue
            try:
                found = frontier_search(
                    marginals.problem.subproblem(rest), 0, work_limit=work_limit
                )
            except SearchLimitExceeded:
                return math.nan  # (its order differs from the whole cluster's)
            log_none += float(found.log_mass[0]) - log_total
        return _probability(-math.expm1(min(0.0, log_none)))
