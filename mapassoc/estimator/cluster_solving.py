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
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import IntArray
from mapassoc.data.settings import SearchSettings
from mapassoc.errors import InputError
from mapassoc.formulations.bounds import (
    exclusive_groups,
    fixed_variable_bounds,
    greedy_packing,
    log_mass_upper_bounds,
    relaxed_problem,
)
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
from mapassoc.formulations.frontier import FrontierResult, frontier_search
from mapassoc.formulations.packing import (
    MergedProblem,
    PackingProblem,
    decode_selection,
    merge_interchangeable,
    resource_multipliers,
    set_packing_program,
)
from mapassoc.log_space import log_sum_exp
from mapassoc.solvers import (
    HighsSolver,
    LPResult,
    ProgramSolver,
    RelaxationSequence,
    RelaxationSolver,
    SolverError,
    SolveStatus,
    get_integer_solver,
    relaxation_sequence,
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


class ClusterStatus(StrEnum):
    """How a cluster's tables were obtained, from best to worst (a window reports the
    worst of its clusters).  Members are strings, so they compare with and serialise as
    ``"exact"``, ``"bounded"`` and ``"time_limit"``."""

    EXACT = "exact"
    """Exact tables (the frontier search within ``exact_work_limit``)."""
    BOUNDED = "bounded"
    """Certified bounds: beam lower bounds, LP / Lagrangian upper bounds."""
    TIME_LIMIT = "time_limit"
    """The window's deadline changed the answer: what was certified by then."""


CLUSTER_STATUSES = tuple(ClusterStatus)
"""From best to worst."""


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
:func:`~mapassoc.formulations.frontier.frontier_search`).  Measured on the forward passes
of converging, dense_radar, parallel and dense_pd08 (seeds 0 and 1, 1,093 exact searches,
52 of them failing at the limit after up to 0.9 s each): 8 stops 33 of the failing ones
early and 1 that would have finished; 4 would stop 50 of them, and 11 that finish.
Since, the exact search of a cluster of
:data:`~mapassoc.formulations.frontier.WORK_COUNT_MIN_HYPOTHESES` hypotheses or more counts
its work beforehand and needs no projection (it stops at once or runs whole); the
projection still applies to smaller clusters and to the window marginals."""

BOUND_PRUNE_MIN_HYPOTHESES = 100
"""Clusters with fewer merged hypotheses skip the LP-bound pruning: the exact search of
such a cluster costs about as much as the LP (a few milliseconds)."""

_SMALL_AFTER_DEADLINE = 40
"""Past the deadline, clusters with fewer hypotheses still get the exact search (it
costs less than the bounds); larger ones go straight to the narrow beam."""

_EMERGENCY_BEAM = 2
"""Beam width once the deadline has passed: feasible sets at little cost."""

_EMERGENCY_ENTRY_MARGIN = 10.0
"""Entry margin of that beam: only the k near each frontier's heaviest are followed."""

_BEAM_ENTRY_MARGIN = 40.0
"""The beam drops a frontier's k-entries this many nats below its heaviest one."""

_NEGLIGIBLE_LOG_MASS = 50.0
"""A k whose mass bound is this far below the mass found holds < e^-50 of it."""

_INTEGRAL_VERTEX = 1e-9
"""An LP optimum whose every variable is this close to an integer is taken as integral
(:meth:`ClusterSolver._take_integral_vertex`; the HiGHS backend's relaxation-first test)."""

_MU_GRID = np.linspace(-30.0, 30.0, 25)
"""Cardinality multipliers tried for the mass bound of k values no LP reached."""


@dataclass(frozen=True)
class ClusterReport:
    """How one cluster was solved.

    Attributes
    ----------
    size : int
        Merged hypotheses in the cluster (after bound pruning).
    status : ClusterStatus
    work : int
        Transitions of the frontier searches.
    solves : int
        Linear and integer programs solved.
    log_captured : float
        Lower bound on log(mass summed / mass of all sets): 0 when exact.
    seconds : float
    """

    size: int
    status: ClusterStatus
    work: int
    solves: int
    log_captured: float
    seconds: float


def _remaining(deadline: float) -> float | None:
    """Seconds left before ``deadline`` for a solver's time limit (``None``: no limit)."""
    return None if math.isinf(deadline) else max(deadline - time.perf_counter(), 1e-3)


def _duals(lp: LPResult) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The duals of an OPTIMAL relaxation (a backend that gives none is broken)."""
    if lp.ineq_duals is None or lp.eq_duals is None:
        raise SolverError(f"{lp.solver}: an OPTIMAL LP relaxation came without its duals")
    return lp.ineq_duals, lp.eq_duals


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
    lp = lp_solver.solve_relaxation(program, time_limit=_remaining(deadline))
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
            bounds = fixed_variable_bounds(program, *_duals(lp))
            floor = float(np.sum(problem.scores[incumbent]))
            kept = np.flatnonzero(bounds >= floor - 1e-7 * (1.0 + abs(floor)))
    result = solver.solve(
        set_packing_program(problem.subproblem(kept), None), time_limit=_remaining(deadline)
    )
    proven = result.is_optimal or result.status is SolveStatus.INFEASIBLE
    if result.solution is None:
        return None, proven
    return kept[decode_selection(result.solution)], proven


@dataclass
class _BoundedTables:
    """What the bounded path knows of one cluster so far, per k: the best set found and
    its score, the mass found, and proven upper bounds of both; filled in place, step by
    step, by :meth:`ClusterSolver._bounded`."""

    best: NDArray[np.float64]
    sets: list[tuple[int, ...] | None]
    log_mass: NDArray[np.float64]
    best_upper: NDArray[np.float64]
    mass_upper: NDArray[np.float64]
    spent: int
    limited: bool
    solves: int = 0


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
    ) -> None:
        self.solver = solver
        self.lp_solver = default_lp_solver(solver) if lp_solver is None else lp_solver
        self.exact_work_limit = int(exact_work_limit)
        self.beam_width = int(beam_width)
        self.prune_log_ratio = float(prune_log_ratio)
        self.map_margin = float(map_margin)
        self.bound_prune_min_hypotheses = int(bound_prune_min_hypotheses)
        self.work_projection = None if work_projection is None else float(work_projection)

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
        lp = self.lp_solver.solve_relaxation(program, time_limit=_remaining(deadline))
        if lp.status is not SolveStatus.OPTIMAL or lp.solution is None:
            return None
        x = lp.solution
        if np.all(np.abs(x - np.round(x)) <= 1e-9):
            incumbent = lp.objective  # the relaxation is integral: the integer optimum
        else:
            if time.perf_counter() >= deadline:
                return None
            best = self.solver.solve(program, time_limit=_remaining(deadline))
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
        if (
            problem.num_hypotheses >= _SMALL_AFTER_DEADLINE
            and time.perf_counter() >= deadline
        ):
            return self._bounded(problem, kmax, deadline, 0, started)
        try:
            table = exact_cardinality_table(
                problem,
                kmax,
                work_limit=self.exact_work_limit,
                deadline=deadline,
                work_projection=self.work_projection,
            )
        except SearchLimitExceeded as stop:
            return self._bounded(problem, kmax, deadline, stop.work, started)
        return table, ClusterReport(
            size=problem.num_hypotheses,
            status=ClusterStatus.EXACT,
            work=0,
            solves=0,
            log_captured=0.0,
            seconds=time.perf_counter() - started,
        )

    def _bounded(
        self, problem: PackingProblem, kmax: int, deadline: float, spent: int, started: float
    ) -> tuple[CardinalityTable, ClusterReport]:
        """The bounded path (module docstring), in four steps: the beam's feasible sets
        (lower bounds), bounds that need no LP, the LP of the relaxed cluster, then the
        walk over k outward from the best one (:meth:`_walk_k`)."""
        top = min(kmax, int(np.count_nonzero(problem.counts)))
        beam, spent, limited = self._beam(problem, top, deadline, spent)
        if beam.exact:  # the beam never had to drop a frontier: it was the exact search
            table = CardinalityTable(beam.best, beam.log_mass, beam.best_sets, True)
            return table, ClusterReport(
                size=problem.num_hypotheses,
                status=ClusterStatus.TIME_LIMIT if limited else ClusterStatus.EXACT,
                work=spent,
                solves=0,
                log_captured=0.0,
                seconds=time.perf_counter() - started,
            )
        groups = exclusive_groups(problem)
        # Upper bounds valid without any LP: zero resource multipliers, a grid of mu;
        # best(k) <= log-mass(k), since log-weights >= scores.
        zeros = np.zeros(problem.num_resources)
        ks = np.arange(top + 1)
        mass_upper = np.min(
            [log_mass_upper_bounds(problem, zeros, mu, ks, groups) for mu in _MU_GRID], axis=0
        )
        tables = _BoundedTables(
            best=beam.best.copy(),
            sets=list(beam.best_sets),
            log_mass=beam.log_mass.copy(),
            best_upper=mass_upper.copy(),
            mass_upper=mass_upper,
            spent=spent,
            limited=limited,
        )
        if not tables.limited:
            relaxed = self._relaxed_bounds(problem, top, deadline)
            tables.solves += 1
            if relaxed is None:
                tables.limited = time.perf_counter() >= deadline
            else:
                relaxed_best, relaxed_mass, work = relaxed
                tables.spent += work
                tables.best_upper = np.minimum(tables.best_upper, relaxed_best)
                tables.mass_upper = np.minimum(tables.mass_upper, relaxed_mass)
        start_k = int(np.argmax(tables.best))
        # One LP kept over the walk: only the cardinality row's right-hand side changes.
        lps = relaxation_sequence(self.lp_solver, set_packing_program(problem, start_k))
        for step, k in ((-1, start_k), (1, start_k + 1)):
            self._walk_k(problem, groups, tables, lps, k, step, top, deadline)
        return self._bounded_result(problem, tables, started)

    def _beam(
        self, problem: PackingProblem, top: int, deadline: float, spent: int
    ) -> tuple[FrontierResult, int, bool]:
        """The beam frontier search of ``beam_width`` frontiers (the emergency beam of
        :data:`_EMERGENCY_BEAM` once the deadline has passed), the work spent so far and
        whether the deadline cut something short."""
        limited = time.perf_counter() >= deadline
        beam = None
        if not limited:
            try:
                beam = frontier_search(
                    problem,
                    top,
                    max_frontiers=self.beam_width,
                    deadline=deadline,
                    entry_margin=_BEAM_ENTRY_MARGIN,
                )
            except SearchLimitExceeded as stop:
                spent += stop.work
                limited = True
        if beam is None:
            beam = frontier_search(
                problem,
                top,
                max_frontiers=_EMERGENCY_BEAM,
                entry_margin=_EMERGENCY_ENTRY_MARGIN,
            )
        return beam, spent + beam.work, limited

    def _walk_k(
        self,
        problem: PackingProblem,
        groups: tuple[NDArray[np.int64], NDArray[np.bool_]],
        tables: _BoundedTables,
        lps: RelaxationSequence,
        k: int,
        step: int,
        top: int,
        deadline: float,
    ) -> None:
        """LP relaxations with the cardinality row at k, k + step, ... (one direction),
        tightening ``tables`` in place.  ``lps`` holds the relaxation (its last row the
        cardinality row), warm-started from one k to the next.

        At each k: the LP value bounds best(k) (and proves the beam's set optimal where
        they meet), its duals bound the mass; where the beam's set falls short of a
        bound that can matter (within ``map_margin`` of the best set found) the integer
        program is solved.  The walk stops once the supporting line of the concave LP
        value, and the mass bound with this LP's multipliers, show every further k
        negligible; those bounds of the last LP are then applied to every k beyond it.
        """
        size = top + 1
        line: tuple[int, float, float, NDArray[np.float64]] | None = None
        right_hand_sides = np.array(lps.program.b_eq, dtype=float)
        while 0 <= k <= top:
            if time.perf_counter() >= deadline:
                tables.limited = True
                break
            right_hand_sides[-1] = k
            lp = lps.solve(right_hand_sides, time_limit=_remaining(deadline))
            tables.solves += 1
            if lp.status is SolveStatus.INFEASIBLE:
                tables.best_upper[k] = tables.mass_upper[k] = -math.inf
                tables.best[k], tables.log_mass[k], tables.sets[k] = -math.inf, -math.inf, None
                k += step
                continue
            if lp.status is not SolveStatus.OPTIMAL:
                tables.limited = True
                break
            multipliers, mu = resource_multipliers(problem, *_duals(lp))
            tables.best_upper[k] = min(tables.best_upper[k], lp.objective)
            self._take_integral_vertex(problem, k, lp, tables)
            upper = tables.best_upper[k]
            if tables.best[k] >= upper - 1e-9 * (1.0 + abs(upper)):
                tables.best_upper[k] = tables.best[k]  # the beam's set meets the LP bound
            at_k = log_mass_upper_bounds(problem, multipliers, mu, np.array([k]), groups)
            tables.mass_upper[k] = min(tables.mass_upper[k], float(at_k[0]))
            line = (k, lp.objective, mu, multipliers)
            found_best = float(np.max(tables.best))
            if (
                tables.best[k] < tables.best_upper[k] - 1e-9
                and tables.best_upper[k] >= found_best - self.map_margin
            ):
                self._tighten_by_integer_program(problem, k, deadline, tables)
                found_best = float(np.max(tables.best))
            ahead = np.arange(k + step, -1 if step < 0 else size, step)
            if ahead.size == 0:
                break
            if np.all(lp.objective + mu * (ahead - k) < found_best - self.map_margin) and (
                np.all(
                    log_mass_upper_bounds(problem, multipliers, mu, ahead, groups)
                    < float(log_sum_exp(tables.log_mass)) - _NEGLIGIBLE_LOG_MASS
                )
            ):
                break
            k += step
        if line is not None:
            # Bounds from the last LP in this direction hold for every k beyond it.
            k_last, value, mu, multipliers = line
            ahead = np.arange(k_last + step, -1 if step < 0 else size, step)
            if ahead.size:
                tables.best_upper[ahead] = np.minimum(
                    tables.best_upper[ahead], value + mu * (ahead - k_last)
                )
                tables.mass_upper[ahead] = np.minimum(
                    tables.mass_upper[ahead],
                    log_mass_upper_bounds(problem, multipliers, mu, ahead, groups),
                )

    @staticmethod
    def _take_integral_vertex(
        problem: PackingProblem, k: int, lp: LPResult, tables: _BoundedTables
    ) -> None:
        """An integral LP optimum at k is a best set of k (no set beats the relaxation):
        it becomes the table's set when it beats the beam's, and the LP bound is met."""
        x = lp.solution
        if x is None or np.any(np.abs(x - np.round(x)) > _INTEGRAL_VERTEX):
            return
        chosen = decode_selection(np.round(x))
        if not problem.is_feasible(chosen, k):
            return
        score = problem.value(chosen)
        if score > tables.best[k] or tables.sets[k] is None:
            tables.best[k], tables.sets[k] = score, tuple(int(h) for h in chosen)

    def _tighten_by_integer_program(
        self, problem: PackingProblem, k: int, deadline: float, tables: _BoundedTables
    ) -> None:
        """Solve the integer program at k: its optimum closes the gap at k; a backend's
        own deterministic limit (a node limit, say) leaves its proven dual bound; the
        clock leaves ``tables.limited``."""
        status, bound = self._solve_integer(problem, k, deadline, tables.best, tables.sets)
        tables.solves += 1
        if status is SolveStatus.OPTIMAL:
            tables.best_upper[k] = tables.best[k]
        elif status is SolveStatus.WORK_LIMIT:
            if math.isfinite(bound):
                tables.best_upper[k] = min(tables.best_upper[k], bound)
        elif status is not SolveStatus.INFEASIBLE:
            tables.limited = True

    def _bounded_result(
        self, problem: PackingProblem, tables: _BoundedTables, started: float
    ) -> tuple[CardinalityTable, ClusterReport]:
        """The bounded table and its report, after checking that no bound claims less
        than a set that exists (beyond LP round-off: that would be a broken backend)."""
        best, log_mass = tables.best, tables.log_mass
        slack = 1e-7 * (1.0 + np.abs(best))
        if np.any(np.isfinite(best) & (tables.best_upper < best - slack)):
            raise SolverError(
                f"{self.lp_solver.name}: an LP upper bound fell below a feasible set's score"
            )
        best_upper = np.maximum(tables.best_upper, best)
        mass_upper = np.maximum(tables.mass_upper, log_mass)
        table = CardinalityTable(
            best, log_mass, tuple(tables.sets), False, best_upper, mass_upper
        )
        found, bound = float(log_sum_exp(log_mass)), float(log_sum_exp(mass_upper))
        return table, ClusterReport(
            size=problem.num_hypotheses,
            status=ClusterStatus.TIME_LIMIT if tables.limited else ClusterStatus.BOUNDED,
            work=tables.spent,
            solves=tables.solves,
            log_captured=found - bound if math.isfinite(bound) else 0.0,
            seconds=time.perf_counter() - started,
        )

    def _solve_integer(
        self,
        problem: PackingProblem,
        k: int,
        deadline: float,
        best: NDArray[np.float64],
        sets: list[tuple[int, ...] | None],
    ) -> tuple[SolveStatus, float]:
        """Solve the integer program of k; keep its set if it beats the beam's.

        Returns the solver's status and its proven upper bound on the best score of k
        (``nan`` when it has none).
        """
        if time.perf_counter() >= deadline:
            return SolveStatus.TIME_LIMIT, math.nan
        result = self.solver.solve(set_packing_program(problem, k), time_limit=_remaining(deadline))
        if result.solution is not None and result.status in (
            SolveStatus.OPTIMAL,
            SolveStatus.TIME_LIMIT,
            SolveStatus.WORK_LIMIT,
        ):
            chosen = decode_selection(result.solution)
            if not problem.is_feasible(chosen, k):
                raise RuntimeError(
                    f"solver {result.solver!r} returned an infeasible set for k={k}"
                )
            score = problem.value(chosen)
            if score > best[k] or sets[k] is None:
                best[k], sets[k] = score, tuple(int(h) for h in chosen)
        return result.status, result.bound

    def _relaxed_bounds(
        self, problem: PackingProblem, top: int, deadline: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], int] | None:
        """Upper bounds per k from a Lagrangian relaxation solved by the frontier search.

        The at-most-once resources with the most users are relaxed, priced by the duals
        of the LP relaxation with K free
        (:func:`~mapassoc.formulations.bounds.relaxed_problem`): a quarter of them
        first, twice as many each time the search of the relaxed problem exceeds an
        eighth of ``exact_work_limit``.  Returns (best upper bounds, log-mass upper bounds,
        work), or ``None`` if no relaxation fitted or the deadline passed.
        """
        lp = self.lp_solver.solve_relaxation(
            set_packing_program(problem, None), time_limit=_remaining(deadline)
        )
        if lp.status is not SolveStatus.OPTIMAL:
            return None
        multipliers, _ = resource_multipliers(problem, *_duals(lp))
        usage = np.bincount(problem.resource_indices, minlength=problem.num_resources)
        shared = np.flatnonzero((usage > 1) & ~problem.exactly_one)
        candidates = shared[np.lexsort((shared, -usage[shared]))]
        count = max(1, candidates.size // 4)
        work = 0
        while candidates.size:
            mask = np.zeros(problem.num_resources, dtype=bool)
            mask[candidates[:count]] = True
            relaxed, constant = relaxed_problem(problem, mask, multipliers)
            try:
                found = frontier_search(
                    relaxed, top, work_limit=max(1, self.exact_work_limit // 8), deadline=deadline
                )
            except SearchLimitExceeded as stop:
                work += stop.work
                if stop.reason == "deadline" or count >= candidates.size:
                    return None
                count = min(2 * count, candidates.size)
                continue
            size = top + 1
            best = np.full(size, -math.inf)
            mass = np.full(size, -math.inf)
            n = found.best.shape[0]
            best[:n], mass[:n] = found.best + constant, found.log_mass + constant
            return best, mass, work + found.work
        return None

