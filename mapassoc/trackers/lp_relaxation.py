"""The LP relaxation of the window's MAP program, with a certificate per window.

The tracker runs the window estimator (:class:`~mapassoc.estimator.pipeline.WindowEstimator`)
on the same windows and hypotheses, and replaces only the track set each window commits:
instead of the exact best set, it solves the linear-programming relaxation of the
set-packing program (:func:`~mapassoc.formulations.packing.set_packing_program`) through
cvxpy with the Clarabel interior-point solver, decodes it where its point is integral and
rounds it where it is not.  Commit, carrying, stitching and RTS smoothing are the
estimator's own (``WindowEstimator.run(select=...)``), so the two trackers differ only
through the sets chosen.

What is relaxed
---------------
Given the window's estimate K of the number of targets (the estimator's ``k_estimate`` on
its exact p(K | Z)), the estimator commits the MAP track set given K, the maximiser of
eq. (2) of ``docs/model.md`` (section 4) over track sets ω with T(ω) ≤ K tracks; the prior
factor π(K)/p_birth(K) is the same for every ω, so it maximises

    score(ω) + log Po(K − T(ω); ν)                                                 (R)

(ν the expected number of never-detected targets).  With x ∈ {0, 1}^H selecting
hypotheses, ``score(ω) = s·x`` and T(ω) = Σ_{h counts} x_h.  The relaxation solved here
keeps T integral and relaxes x: for T = 0..min(K, Kmax)

    LP[T] = max { s·x : Σ_{h uses r} x_h ≤ 1 (detections), = 1 (carried tracks),
                         Σ_{h counts} x_h = T,  0 ≤ x ≤ 1 },

and the window takes the T maximising ``LP[T] + log Po(K − T; ν)``, ties to the smaller
T as in the estimator.  ``LP[T] ≥ best[T]`` for every T, so the maximum bounds (R) from
above.  LP[T] is concave in T (the optimum of an LP is concave in its right-hand side)
and so is ``log Po(K − T; ν) = (K − T) log ν − ν − log (K − T)!``, so their sum is
unimodal: the search walks from the estimator's T until the value stops increasing
and solves only a few LPs per window.

K is not relaxed: the marginal estimate of K sums ``exp(score)`` over all track sets
(eq. 3), which no linear program bounds, and relaxing only the joint-MAP K would compare
against another estimator than the configured one.  With K fixed, a window whose LP is
integral at its T commits the estimator's own set (up to exact ties).

Certificates
------------
Per window a :class:`WindowCertificate` holds the LP value (the objective of Clarabel's
point), the dual objective computed from the returned duals (the Lagrangian bound
``b_ub·y + b_eq·w + Σ_i max(r_i, 0)``, :func:`~mapassoc.formulations.program.lagrangian_bound`,
a proven upper bound whatever the duals' accuracy), their primal–dual gap, the integer
optimum of the same program by HiGHS, the gap between the LP bound and it, the
integrality measure ``max_h min(x_h, 1 − x_h)`` and whether the point is integral within
``integrality_tolerance``.

An interior-point method converges to the analytic centre of the optimal face, so on
ties Clarabel returns a midpoint: its point can be fractional although the LP optimum is
attained at an integral vertex.  ``integral`` describes the point returned;
``tight`` says whether the LP bound equals the integer optimum (no integrality gap at
that T), which is the property of the program.

Where the point is fractional, :func:`round_selection` rounds it to a feasible set
(greedy by x, then score); if the greedy cannot meet every constraint the window
commits the integer program's set, and if neither the LP nor the integer program gave
an answer at any T, the estimator's set (:class:`Decision` says which).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.data.config import Config, check_config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.pipeline import EstimateResult, WindowEstimator, WindowSolution
from mapassoc.formulations.packing import PackingProblem, decode_selection, set_packing_program
from mapassoc.formulations.program import lagrangian_bound
from mapassoc.models.population import poisson_log_pmf
from mapassoc.solvers.cvxpy_backend import CvxpySolver
from mapassoc.solvers.highs import HighsSolver
from mapassoc.solvers.results import SolveStatus
from mapassoc.trackers.base import TrackerOutput, check_scans
from mapassoc.trackers.map_estimator import count_series, rows_to_associations

__all__ = [
    "Decision",
    "LpSolve",
    "RelaxationCertificate",
    "WindowCertificate",
    "LpRelaxationDetails",
    "LpRelaxationTracker",
    "solve_lp",
    "certify_relaxation",
    "round_selection",
    "integrality_measure",
]


class Decision(StrEnum):
    """Which set a window committed."""

    INTEGRAL = "integral"
    """The LP point was integral: its decoded set."""
    ROUNDED = "rounded"
    """The LP point was fractional: :func:`round_selection` of it."""
    INTEGER_PROGRAM = "integer_program"
    """Rounding found no feasible set: the integer program's set at the LP's T."""
    ESTIMATOR = "estimator"
    """Neither the LP nor the integer program gave an answer: the estimator's set."""


def integrality_measure(x: FloatArray) -> float:
    """``max_h min(x_h, 1 − x_h)``: 0 for a 0/1 point, 1/2 at worst.

    Parameters
    ----------
    x : ndarray, shape (H,)
        A point of [0, 1]^H (entries outside are clipped first).
    """
    x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
    return float(np.max(np.minimum(x, 1.0 - x))) if x.size else 0.0


@dataclass(frozen=True, eq=False)
class LpSolve:
    """One LP relaxation solved by Clarabel.

    Attributes
    ----------
    tracks : int or None
        T of the cardinality row (``None``: no row).
    status : SolveStatus
    value : float
        ``s·x`` at the returned point (``-inf`` if infeasible, ``nan`` if failed).
    dual_value : float
        The dual objective at the returned duals (``-inf`` if infeasible, ``nan`` if
        failed): an upper bound on the LP optimum, hence on the integer optimum.
    point : ndarray, shape (H,), or None
    seconds : float
    """

    tracks: int | None
    status: SolveStatus
    value: float
    dual_value: float
    point: FloatArray | None
    seconds: float


def solve_lp(
    problem: PackingProblem,
    tracks: int | None,
    *,
    solver: CvxpySolver,
    time_limit: float | None = None,
) -> LpSolve:
    """The LP relaxation of ``set_packing_program(problem, tracks)`` by cvxpy + Clarabel.

    The dual value is recomputed here from the returned row duals ``y`` (``A_ub``) and
    ``w`` (``A_eq``): ``b_ub·y⁺ + b_eq·w + Σ_h max(r_h, 0)`` with reduced scores
    ``r = s − A_ubᵀ y⁺ − A_eqᵀ w`` (the bound rows 0 ≤ x ≤ 1 get their optimal duals
    ``max(r, 0)``), which is the LP dual objective and, by weak duality, an upper bound.
    """
    program = set_packing_program(problem, tracks).relaxed()
    result = solver.solve_relaxation(program, time_limit=time_limit)
    if result.status is SolveStatus.OPTIMAL:
        assert result.ineq_duals is not None and result.eq_duals is not None
        dual = lagrangian_bound(program, result.ineq_duals, result.eq_duals)
        return LpSolve(
            tracks, result.status, result.objective, dual, result.solution, result.solve_seconds
        )
    empty = -math.inf if result.status is SolveStatus.INFEASIBLE else math.nan
    return LpSolve(tracks, result.status, empty, empty, None, result.solve_seconds)


@dataclass(frozen=True)
class RelaxationCertificate:
    """An LP relaxation against the integer program it relaxes (one T).

    Attributes
    ----------
    tracks : int or None
        T of the cardinality row (``None``: none).
    lp_status, ip_status : str
        :class:`~mapassoc.solvers.results.SolveStatus` values of Clarabel and HiGHS.
    lp_value : float
        ``s·x`` at Clarabel's point.
    lp_bound : float
        The dual objective from Clarabel's duals: a proven upper bound.
    ip_value : float
        The integer optimum by HiGHS (``nan`` unless HiGHS proved it; ``-inf`` when the
        integer program is infeasible).
    integrality : float
        ``max_h min(x_h, 1 − x_h)`` of Clarabel's point (``nan`` without a point).
    integral : bool
        ``integrality <= integrality_tolerance``.
    gap_tolerance : float
        Relative tolerance of :attr:`tight` (scaled by ``max(1, |ip_value|)``).
    lp_seconds, ip_seconds : float
    """

    tracks: int | None
    lp_status: str
    ip_status: str
    lp_value: float
    lp_bound: float
    ip_value: float
    integrality: float
    integral: bool
    gap_tolerance: float
    lp_seconds: float
    ip_seconds: float

    @property
    def duality_gap(self) -> float:
        """``lp_bound − lp_value``: the primal–dual gap of the LP solve."""
        return self.lp_bound - self.lp_value

    @property
    def relative_duality_gap(self) -> float:
        """``|duality_gap| / max(1, |lp_bound|)``."""
        return abs(self.duality_gap) / max(1.0, abs(self.lp_bound))

    @property
    def integrality_gap(self) -> float:
        """``lp_bound − ip_value`` (>= 0 up to the LP's tolerance)."""
        return self.lp_bound - self.ip_value

    @property
    def tight(self) -> bool:
        """Whether the LP bound equals the integer optimum within the tolerance (the LP
        optimum is integral even where Clarabel's point is a fractional midpoint)."""
        gap = self.integrality_gap
        return bool(math.isfinite(gap) and gap <= self.gap_tolerance * max(1.0, abs(self.ip_value)))


def round_selection(
    problem: PackingProblem, x: FloatArray, tracks: int | None = None
) -> IntArray | None:
    """A feasible set near a fractional point: greedy by ``x``, then score.

    1. Hypotheses in order of decreasing ``x`` (ties: decreasing score, then index) are
       taken while their resources are free and, if they count, fewer than ``tracks``
       counted ones are taken.
    2. Every carried track ("exactly once" resource) still unused gets its first
       hypothesis in that order whose resources are free (its no-detection hypothesis
       always is), even past ``tracks``.
    3. Past ``tracks``, the last-taken counted hypotheses without an "exactly once"
       resource (new tracks) are dropped; short of ``tracks``, counted hypotheses whose
       resources are still free are added in order.

    Parameters
    ----------
    problem : PackingProblem
    x : ndarray, shape (H,)
        The fractional point (an LP solution).
    tracks : int or None
        The number of counted hypotheses required (``None``: any).

    Returns
    -------
    ndarray of int or None
        The selected hypotheses, sorted; ``None`` when the greedy cannot satisfy every
        row (the caller then needs another answer).
    """
    H = problem.num_hypotheses
    x = np.asarray(x, dtype=float)
    if x.shape != (H,):
        raise InputError(f"x must have shape ({H},), got {x.shape}")
    budget = math.inf if tracks is None else int(tracks)
    order = np.lexsort((np.arange(H), -problem.scores, -x)).tolist()
    resources = [problem.resources_of(h) for h in range(H)]
    counts = problem.counts
    required = problem.exactly_one
    new_track = np.array([not np.any(required[r]) for r in resources], dtype=bool)
    free = np.ones(problem.num_resources, dtype=bool)
    taken: list[int] = []
    counted = 0

    def take(h: int) -> None:
        nonlocal counted
        free[resources[h]] = False
        taken.append(h)
        counted += int(counts[h])

    for h in order:  # 1
        if np.all(free[resources[h]]) and (not counts[h] or counted < budget):
            take(h)
    for h in order:  # 2
        if np.any(required[resources[h]] & free[resources[h]]) and np.all(free[resources[h]]):
            take(h)
    for h in reversed(list(taken)):  # 3, too many
        if counted <= budget:
            break
        if counts[h] and new_track[h]:
            taken.remove(h)
            free[resources[h]] = True
            counted -= 1
    for h in order:  # 3, too few
        if counted >= budget:
            break
        if counts[h] and h not in taken and np.all(free[resources[h]]):
            take(h)
    selection = np.sort(np.asarray(taken, dtype=np.int64))
    if not problem.is_feasible(selection, None if tracks is None else int(tracks)):
        return None
    return selection


def certify_relaxation(
    problem: PackingProblem,
    lp: LpSolve,
    *,
    ip_solver: HighsSolver,
    integrality_tolerance: float = 1e-6,
    gap_tolerance: float = 1e-6,
    time_limit: float | None = None,
) -> tuple[RelaxationCertificate, IntArray | None, Decision | None]:
    """Certify an LP relaxation against its integer program and pick a set from it.

    Parameters
    ----------
    problem : PackingProblem
    lp : LpSolve
        :func:`solve_lp` of ``problem`` at ``lp.tracks``.
    ip_solver : HighsSolver
        Solves the integer program ``set_packing_program(problem, lp.tracks)``.
    integrality_tolerance, gap_tolerance : float
    time_limit : float or None
        Seconds for HiGHS.

    Returns
    -------
    certificate : RelaxationCertificate
    selection : ndarray of int or None
        The decoded LP point if integral (and feasible), else its rounding, else the
        integer program's set; ``None`` if there is none.
    decision : Decision or None
        INTEGRAL, ROUNDED or INTEGER_PROGRAM (``None`` with no selection).
    """
    program = set_packing_program(problem, lp.tracks)
    ip = ip_solver.solve(program, time_limit=time_limit)
    if ip.status is SolveStatus.OPTIMAL:
        ip_value = ip.objective
    elif ip.status is SolveStatus.INFEASIBLE:
        ip_value = -math.inf
    else:
        ip_value = math.nan
    point = lp.point
    integrality = integrality_measure(point) if point is not None else math.nan
    integral = bool(point is not None and integrality <= integrality_tolerance)
    certificate = RelaxationCertificate(
        tracks=lp.tracks,
        lp_status=lp.status.value,
        ip_status=ip.status.value,
        lp_value=lp.value,
        lp_bound=lp.dual_value,
        ip_value=ip_value,
        integrality=integrality,
        integral=integral,
        gap_tolerance=gap_tolerance,
        lp_seconds=lp.seconds,
        ip_seconds=ip.solve_seconds,
    )
    if point is not None:
        if integral:
            decoded = decode_selection(point)
            if problem.is_feasible(decoded, lp.tracks):
                return certificate, decoded, Decision.INTEGRAL
        rounded = round_selection(problem, point, lp.tracks)
        if rounded is not None:
            return certificate, rounded, Decision.ROUNDED
    if ip.status is SolveStatus.OPTIMAL:
        assert ip.solution is not None
        return certificate, decode_selection(ip.solution), Decision.INTEGER_PROGRAM
    return certificate, None, None


@dataclass(frozen=True)
class WindowCertificate:
    """What the LP relaxation of one window gave, against the integer program.

    Attributes
    ----------
    window : int
        Index of the window in the run.
    start_time, end_time : float
    target_count : int
        K, the estimator's estimate of the number of targets.
    tracks : int
        T of the LP choice (the argmax of ``LP[T] + log Po(K − T; ν)``).
    estimator_tracks : int
        T of the estimator's MAP set given K.
    tracks_solved : tuple of int
        The T whose LP was solved on the way.
    count_term : float
        ``log Po(K − T; ν)`` at :attr:`tracks`.
    estimator_objective : float
        The estimator's best score at its T (the window's exact tables).
    relaxation : RelaxationCertificate
        The LP at :attr:`tracks` against the integer program at that T.
    decision : Decision
    selected_value : float
        Score of the committed set.
    matches_estimator : bool
        Whether the committed set is the estimator's own.
    hypotheses : int
        Variables of the program.
    """

    window: int
    start_time: float
    end_time: float
    target_count: int
    tracks: int
    estimator_tracks: int
    tracks_solved: tuple[int, ...]
    count_term: float
    estimator_objective: float
    relaxation: RelaxationCertificate
    decision: Decision
    selected_value: float
    matches_estimator: bool
    hypotheses: int

    @property
    def integral(self) -> bool:
        """Whether Clarabel's point at :attr:`tracks` was integral."""
        return self.relaxation.integral

    @property
    def rounded(self) -> bool:
        """Whether the committed set was rounded from a fractional point."""
        return self.decision is Decision.ROUNDED


@dataclass(frozen=True, eq=False)
class LpRelaxationDetails:
    """``TrackerOutput.details`` of :class:`LpRelaxationTracker`.

    Attributes
    ----------
    certificates : tuple of WindowCertificate
        One per window, in order.
    estimate : EstimateResult
        The run (its reports are the estimator's posterior; ``chosen_tracks`` is the T
        of the committed LP set).
    """

    certificates: tuple[WindowCertificate, ...]
    estimate: EstimateResult

    @property
    def integral_share(self) -> float:
        """Share of the windows whose LP point was integral."""
        c = self.certificates
        return sum(w.integral for w in c) / len(c) if c else 1.0

    @property
    def tight_share(self) -> float:
        """Share of the windows whose LP bound equals the integer optimum."""
        c = self.certificates
        return sum(w.relaxation.tight for w in c) / len(c) if c else 1.0

    @property
    def max_integrality_gap(self) -> float:
        """Largest LP-bound-minus-integer-optimum over the windows with both finite."""
        gaps = [w.relaxation.integrality_gap for w in self.certificates]
        finite = [g for g in gaps if math.isfinite(g)]
        return max(finite, default=0.0)


def _check_positive(name: str, value: object, *, below: float = math.inf) -> float:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not ok or not (math.isfinite(float(value)) and 0 < float(value) < below):  # type: ignore[arg-type]
        bound = "" if below == math.inf else f" and < {below}"
        raise InputError(f"{name} must be a finite number > 0{bound}, got {value!r}")
    return float(value)  # type: ignore[arg-type]


def _walked_track_count(
    value: Callable[[int], float], tolerance: Callable[[float], float], start: int
) -> int:
    """The track count T of largest ``value(T)`` (a concave function of T), walking from
    ``start``: up while the value rises by more than ``tolerance`` of the best so far,
    then down while it stays within it (ties go to the smaller T)."""
    best_T = start
    best = value(best_T)
    while value(best_T + 1) > best + tolerance(best):  # concave: walk up while it rises
        best_T += 1
        best = value(best_T)
    while True:  # ties go to the smaller T
        below = value(best_T - 1)
        if not (math.isfinite(below) and below >= best - tolerance(best)):
            break
        best_T -= 1
        best = below
    return best_T


class _LpRule:
    """The selection rule of one run (:data:`~mapassoc.estimator.pipeline.SelectionRule`):
    solves the relaxation of a window, records its certificate, returns its set."""

    def __init__(self, tracker: LpRelaxationTracker) -> None:
        self.tracker = tracker
        self.certificates: list[WindowCertificate] = []

    def __call__(self, solution: WindowSolution, chosen_k: int, chosen_tracks: int) -> IntArray:
        t = self.tracker
        problem = solution.problem
        nu = solution.posterior.undetected_mean
        top = min(chosen_k, t.config.estimator.count.max_tracks)
        solved: dict[int, LpSolve] = {}

        def value(T: int) -> float:
            if not 0 <= T <= top:
                return -math.inf
            if T not in solved:
                solved[T] = solve_lp(problem, T, solver=t.lp_solver, time_limit=t.time_limit)
            v = solved[T].value
            term = float(poisson_log_pmf(np.array([chosen_k - T]), nu)[0])
            return v + term if math.isfinite(v) else -math.inf

        def tolerance(v: float) -> float:
            return t.gap_tolerance * max(1.0, abs(v)) if math.isfinite(v) else 0.0

        best_T = _walked_track_count(value, tolerance, chosen_tracks)
        estimator_set = solution.selection(chosen_tracks)
        lp = solved[best_T]
        certificate, selection, decision = certify_relaxation(
            problem,
            lp,
            ip_solver=t.ip_solver,
            integrality_tolerance=t.integrality_tolerance,
            gap_tolerance=t.gap_tolerance,
            time_limit=t.time_limit,
        )
        if selection is None or decision is None:
            selection, decision = estimator_set, Decision.ESTIMATOR
        scans = solution.hypotheses.scans
        self.certificates.append(
            WindowCertificate(
                window=len(self.certificates),
                start_time=float(scans[0].time),
                end_time=float(scans[-1].time),
                target_count=int(chosen_k),
                tracks=int(best_T),
                estimator_tracks=int(chosen_tracks),
                tracks_solved=tuple(sorted(solved)),
                count_term=float(poisson_log_pmf(np.array([chosen_k - best_T]), nu)[0]),
                estimator_objective=float(solution.table.best[chosen_tracks]),
                relaxation=certificate,
                decision=decision,
                selected_value=problem.value(selection),
                matches_estimator=bool(
                    np.array_equal(np.sort(selection), np.sort(estimator_set))
                ),
                hypotheses=problem.num_hypotheses,
            )
        )
        return selection


class LpRelaxationTracker:
    """Window tracks from the LP relaxation of the MAP program (module docstring).

    Parameters
    ----------
    config : Config
        The estimator's configuration (windows, hypotheses, K prior and estimate).
    name : str
        Label in comparisons.
    integrality_tolerance : float, default 1e-6
        An LP point is integral when ``max_h min(x_h, 1 − x_h)`` is at most this
        (in (0, 0.5)).
    gap_tolerance : float, default 1e-6
        Relative tolerance (times ``max(1, |value|)``) of ties between track counts and
        of :attr:`RelaxationCertificate.tight`.
    time_limit : float or None, default None
        Seconds per LP and per integer program (``None``: no limit).

    Raises
    ------
    InputError
        An option out of range, or a configuration the estimator refuses.
    """

    def __init__(
        self,
        *,
        config: Config,
        name: str = "lp",
        integrality_tolerance: float = 1e-6,
        gap_tolerance: float = 1e-6,
        time_limit: float | None = None,
    ) -> None:
        self.config = check_config(config)
        self.name = name
        self.integrality_tolerance = _check_positive(
            "integrality_tolerance", integrality_tolerance, below=0.5
        )
        self.gap_tolerance = _check_positive("gap_tolerance", gap_tolerance)
        self.time_limit = None if time_limit is None else _check_positive("time_limit", time_limit)
        # The windows' LP-rounded sets as they are: refining the whole recording
        # afterwards (refinement.passes) would show the refinement, not the relaxation.
        no_refinement = dataclasses.replace(config.estimator.refinement, passes=0)
        self.estimator = WindowEstimator(
            config=dataclasses.replace(
                config, estimator=dataclasses.replace(config.estimator, refinement=no_refinement)
            )
        )
        self.lp_solver = CvxpySolver(backend="CLARABEL")
        self.ip_solver = HighsSolver()

    def track(self, scans: Sequence[Scan]) -> TrackerOutput:
        """Run the windows with the LP's sets; ``details`` is :class:`LpRelaxationDetails`."""
        scans = check_scans(scans, self.config)
        start = time.perf_counter()
        rule = _LpRule(self)
        result = self.estimator.run(scans, select=rule)
        seconds = time.perf_counter() - start
        return TrackerOutput(
            tracks=result.tracks,
            seconds=seconds,
            associations=rows_to_associations(scans, result.track_rows),
            counts=count_series(result),
            details=LpRelaxationDetails(tuple(rule.certificates), result),
        )
