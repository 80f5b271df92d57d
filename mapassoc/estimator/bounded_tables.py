"""The bounded path of a cluster too large for the exact search: certified bounds per k.

What :class:`~mapassoc.estimator.cluster_solving.ClusterSolver` falls back to when the
exact frontier search of a cluster passes its work limit (statuses ``bounded`` and
``time_limit``; the strategy is described in
:mod:`mapassoc.estimator.cluster_solving`).  A beam frontier search gives feasible sets
and lower bounds on every log-mass; LP relaxations walked over k from the best one, a
Lagrangian relaxation solved by the frontier search, and the integer program where a k
can matter, give proven upper bounds.  Kept apart from the dispatch so that each class
holds one concern.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

from mapassoc.formulations.bounds import (
    exclusive_groups,
    log_mass_upper_bounds,
    relaxed_problem,
)
from mapassoc.formulations.cardinality import CardinalityTable, SearchLimitExceeded
from mapassoc.formulations.frontier import FrontierResult, frontier_search
from mapassoc.formulations.packing import (
    PackingProblem,
    decode_selection,
    resource_multipliers,
    set_packing_program,
)
from mapassoc.log_space import log_sum_exp
from mapassoc.solvers import (
    LPResult,
    ProgramSolver,
    RelaxationSequence,
    RelaxationSolver,
    SolverError,
    SolveStatus,
    relaxation_sequence,
)

__all__ = [
    "BoundedSearch",
    "CLUSTER_STATUSES",
    "ClusterReport",
    "ClusterStatus",
    "lp_duals",
    "remaining",
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


_EMERGENCY_BEAM = 2
"""Beam width once the deadline has passed: feasible sets at little cost."""

_EMERGENCY_ENTRY_MARGIN = 10.0
"""Entry margin of that beam: only the k near each frontier's heaviest are followed."""

_NEGLIGIBLE_LOG_MASS = 50.0
"""A k whose mass bound is this far below the mass found holds < e^-50 of it."""

_INTEGRAL_VERTEX = 1e-9
"""An LP optimum whose every variable is this close to an integer is taken as integral
(:meth:`BoundedSearch._take_integral_vertex`; the HiGHS backend's relaxation-first test)."""



def remaining(deadline: float) -> float | None:
    """Seconds left before ``deadline`` for a solver's time limit (``None``: no limit)."""
    return None if math.isinf(deadline) else max(deadline - time.perf_counter(), 1e-3)


def lp_duals(lp: LPResult) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The duals of an OPTIMAL relaxation (a backend that gives none is broken)."""
    if lp.ineq_duals is None or lp.eq_duals is None:
        raise SolverError(f"{lp.solver}: an OPTIMAL LP relaxation came without its duals")
    return lp.ineq_duals, lp.eq_duals


@dataclass
class _BoundedTables:
    """What the bounded path knows of one cluster so far, per k: the best set found and
    its score, the mass found, and proven upper bounds of both; filled in place, step by
    step, by :meth:`BoundedSearch.tables`."""

    best: NDArray[np.float64]
    sets: list[tuple[int, ...] | None]
    log_mass: NDArray[np.float64]
    best_upper: NDArray[np.float64]
    mass_upper: NDArray[np.float64]
    spent: int
    limited: bool
    solves: int = 0


@dataclass(frozen=True, eq=False)
class BoundedSearch:
    """The bounded path of one cluster, configured as its
    :class:`~mapassoc.estimator.cluster_solving.ClusterSolver` is.

    Attributes
    ----------
    solver : ProgramSolver
        Integer programs of the k that can matter.
    lp_solver : RelaxationSolver
        LP relaxations, with duals.
    exact_work_limit : int
        The exact search's limit (the Lagrangian relaxation's search may take an eighth).
    beam_width : int
        Frontiers of the beam.
    map_margin : float
        A k whose LP bound is this far below the best set found gets no integer program.
    beam_entry_margin : float
        The beam drops a frontier's k-entries this many nats below its heaviest one.
    count_multipliers : ndarray, shape (m,)
        Cardinality multipliers tried for the mass bound of the k no LP reached.
    """

    solver: ProgramSolver
    lp_solver: RelaxationSolver
    exact_work_limit: int
    beam_width: int
    map_margin: float
    beam_entry_margin: float
    count_multipliers: NDArray[np.float64]

    def tables(
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
            [
                log_mass_upper_bounds(problem, zeros, mu, ks, groups)
                for mu in self.count_multipliers
            ],
            axis=0,
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
                    entry_margin=self.beam_entry_margin,
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

        At each k (:meth:`_lp_step`): the LP value bounds best(k) (and proves the beam's
        set optimal where they meet), its duals bound the mass; where the beam's set
        falls short of a bound that can matter (within ``map_margin`` of the best set
        found) the integer program is solved.  The walk stops once the supporting line
        of the concave LP value, and the mass bound with this LP's multipliers, show
        every further k negligible; those bounds of the last LP are then applied to every
        k beyond it.
        """
        size = top + 1
        line: tuple[int, float, float, NDArray[np.float64]] | None = None
        right_hand_sides = np.array(lps.program.b_eq, dtype=float)
        while 0 <= k <= top:
            if time.perf_counter() >= deadline:
                tables.limited = True
                break
            right_hand_sides[-1] = k
            lp = lps.solve(right_hand_sides, time_limit=remaining(deadline))
            tables.solves += 1
            if lp.status is SolveStatus.INFEASIBLE:
                tables.best_upper[k] = tables.mass_upper[k] = -math.inf
                tables.best[k], tables.log_mass[k], tables.sets[k] = -math.inf, -math.inf, None
                k += step
                continue
            if lp.status is not SolveStatus.OPTIMAL:
                tables.limited = True
                break
            line = self._lp_step(problem, groups, tables, lp, k, deadline)
            found_best = float(np.max(tables.best))
            ahead = np.arange(k + step, -1 if step < 0 else size, step)
            if ahead.size == 0:
                break
            _, value, mu, multipliers = line
            if np.all(value + mu * (ahead - k) < found_best - self.map_margin) and (
                np.all(
                    log_mass_upper_bounds(problem, multipliers, mu, ahead, groups)
                    < float(log_sum_exp(tables.log_mass)) - _NEGLIGIBLE_LOG_MASS
                )
            ):
                break
            k += step
        if line is not None:
            _extend_line(problem, groups, tables, line, step, size)

    def _lp_step(
        self,
        problem: PackingProblem,
        groups: tuple[NDArray[np.int64], NDArray[np.bool_]],
        tables: _BoundedTables,
        lp: LPResult,
        k: int,
        deadline: float,
    ) -> tuple[int, float, float, NDArray[np.float64]]:
        """What the OPTIMAL LP at k proves (its value bounds best(k), its duals the
        mass), and the integer program at k where the gap can matter; returns the LP's
        supporting line (k, value, mu, resource multipliers)."""
        multipliers, mu = resource_multipliers(problem, *lp_duals(lp))
        tables.best_upper[k] = min(tables.best_upper[k], lp.objective)
        self._take_integral_vertex(problem, k, lp, tables)
        upper = tables.best_upper[k]
        if tables.best[k] >= upper - 1e-9 * (1.0 + abs(upper)):
            tables.best_upper[k] = tables.best[k]  # the beam's set meets the LP bound
        at_k = log_mass_upper_bounds(problem, multipliers, mu, np.array([k]), groups)
        tables.mass_upper[k] = min(tables.mass_upper[k], float(at_k[0]))
        found_best = float(np.max(tables.best))
        if (
            tables.best[k] < tables.best_upper[k] - 1e-9
            and tables.best_upper[k] >= found_best - self.map_margin
        ):
            self._tighten_by_integer_program(problem, k, deadline, tables)
        return k, lp.objective, mu, multipliers

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
        result = self.solver.solve(set_packing_program(problem, k), time_limit=remaining(deadline))
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
            set_packing_program(problem, None), time_limit=remaining(deadline)
        )
        if lp.status is not SolveStatus.OPTIMAL:
            return None
        multipliers, _ = resource_multipliers(problem, *lp_duals(lp))
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


def _extend_line(
    problem: PackingProblem,
    groups: tuple[NDArray[np.int64], NDArray[np.bool_]],
    tables: _BoundedTables,
    line: tuple[int, float, float, NDArray[np.float64]],
    step: int,
    size: int,
) -> None:
    """Bounds from the last LP of a walk, which hold for every k beyond it: its
    supporting line for the best score, its multipliers for the mass."""
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
