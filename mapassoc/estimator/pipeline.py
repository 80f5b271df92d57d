"""The MAP window track-set estimator, end to end.

With its per-cluster strategy (:mod:`mapassoc.estimator.cluster_solving`) this is the only
module that wires the domain (:mod:`mapassoc.estimator.hypotheses`), the formulations
(:mod:`mapassoc.formulations`) and the solvers (:mod:`mapassoc.solvers`).

For each window of ``window_length`` consecutive scans:

1. grow the track trees (carried tracks and tracks born in the window) and score every
   hypothesis (:class:`~mapassoc.estimator.hypotheses.HypothesisGenerator`);
2. turn the choice of a track set into a packing problem (detections used at most
   once, carried tracks exactly once) and split it into independent clusters;
3. per cluster, compute the best score and the log-mass of all track sets for every
   k: exactly (the frontier search of :mod:`mapassoc.formulations.frontier`) when it
   fits ``exact_work_limit``, otherwise certified bounds (a beam search, LP relaxations
   per k, the integer program where a k can matter; :class:`ClusterSolver`), all
   within the window's ``time_limit``;
4. combine the clusters (max-plus and sum-product convolution) into per-T tables (T the
   number of tracks), add the targets never detected (:mod:`mapassoc.models.population`) and
   the prior on the number of targets K, and get p(K | Z), the joint MAP K and the
   marginal K (:mod:`mapassoc.estimator.posterior`);
5. take the best track set for the chosen K, commit its oldest ``stride`` scans and
   carry the tracks alive at the last committed scan, and the undetected-target
   intensity after it, into the next window.

At the end the whole recording's track set is refined where the recording objective J
rises (``refine_passes``, :mod:`mapassoc.estimator.refinement`) and every track is
smoothed (RTS) over the detections it used.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from enum import StrEnum
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from mapassoc.accelerate import load_kernels
from mapassoc.data.config import Config, check_config
from mapassoc.data.io import TrackTable
from mapassoc.data.scans import Scan, check_scans
from mapassoc.data.windows import window_span
from mapassoc.errors import InputError
from mapassoc.estimator.cluster_solving import (
    ClusterReport,
    ClusterSolver,
    ClusterStatus,
    WindowCluster,
)
from mapassoc.estimator.hypotheses import CarriedTrack, HypothesisGenerator, WindowHypotheses
from mapassoc.estimator.posterior import FULL_LENGTH_KMAX, KPosterior, k_posterior
from mapassoc.estimator.refinement import RefinementReport, TrackConfidence, refine_track_rows
from mapassoc.estimator.window_program import packing_problem
from mapassoc.filtering.smoothing import smooth_tracks
from mapassoc.formulations.cardinality import CombinedTable
from mapassoc.formulations.packing import PackingProblem
from mapassoc.models.population import UndetectedTargets, WindowPopulation
from mapassoc.models.target_count import CountPrior, KEstimator
from mapassoc.validation import check_callback, check_instance, check_integer, shown

__all__ = [
    "WindowStatus",
    "WINDOW_STATUSES",
    "ClusterReport",
    "WindowSolution",
    "WindowReport",
    "EstimateResult",
    "RunState",
    "WindowTally",
    "WindowEstimator",
    "packing_problem",
    "SelectionRule",
    "SPREAD_WARNING_RATIO",
    "time_scale_warning",
]


class WindowStatus(StrEnum):
    """A window's status, from best to worst.  Members are strings: they compare with
    and serialise as their values (``windows.jsonl``, ``summary.json``)."""

    EXACT = "exact"
    """Nothing cut but the documented score-ratio, gate and LP-bound pruning."""
    CAPPED = "capped"
    """The per-tree cap also cut nodes that passed the score tests."""
    BOUNDED = "bounded"
    """A cluster got certified bounds instead of exact tables."""
    TIME_LIMIT = "time_limit"
    """The deadline changed the answer: a cluster got what was certified by then."""

    @classmethod
    def of_cluster(cls, status: ClusterStatus) -> WindowStatus:
        """The window status a cluster's status implies at least."""
        return cls(ClusterStatus(status).value)


WINDOW_STATUSES = tuple(WindowStatus)
"""Window statuses from best to worst (:class:`WindowStatus`)."""

P_K_FLOOR = 1e-300
"""Trailing p(K | Z) below this are left out of ``windows.jsonl`` (``p_k_length`` says
how many entries the full vector has)."""

ProgressCallback = Callable[[int, int], None]
WindowCallback = Callable[["WindowReport"], None]
SelectionRule = Callable[["WindowSolution", int, int], NDArray[np.int64]]
"""Chooses the track set a window commits: called as ``rule(solution, chosen_k,
chosen_tracks)`` with the estimator's estimate of K and the T of its MAP set given K,
it returns hypothesis indices of ``solution.hypotheses`` forming a feasible set of
``solution.problem``.  :meth:`WindowEstimator.run` commits, carries and smooths that set
exactly as its own (``solution.selection(chosen_tracks)``, the default)."""


@dataclass(frozen=True, eq=False)
class WindowSolution:
    """Everything computed for one window (for notebooks and tests).

    Attributes
    ----------
    hypotheses : WindowHypotheses
    problem : PackingProblem
    table : CombinedTable
        Per-T best score, best set and log-mass of the whole window (T the number of
        tracks), with proven upper bounds where a cluster was only bounded.
    posterior : KPosterior
        p(K | Z) over the number of targets K and the estimates of K.
    population : WindowPopulation
        The birth model's undetected targets in the window.
    cluster_sizes : tuple of int
    bounded_clusters : tuple of ClusterReport
        Clusters too large for the exact search (they got certified bounds).
    generate_seconds, solve_seconds : float
    bound_pruned : int
        Merged hypotheses dropped by the LP bound (``ClusterSolver.bound_prune``).
    timed_out : bool
        Whether the window ran past ``time_limit`` (whether or not that changed the
        answer; see :attr:`status`).
    pruning_cut_short : bool
        Whether a cluster the LP bound would have pruned went unpruned because the
        deadline had passed (conservatively: also when the bound would have kept every
        hypothesis anyway).  Its mass then depends on the clock, so the window's status
        is ``time_limit`` even where every cluster was solved exactly.
    clusters : tuple of WindowCluster
        Each cluster's hypotheses, merge, bound-pruning mask and table.
    """

    hypotheses: WindowHypotheses
    problem: PackingProblem
    table: CombinedTable
    posterior: KPosterior
    population: WindowPopulation
    cluster_sizes: tuple[int, ...]
    bounded_clusters: tuple[ClusterReport, ...]
    generate_seconds: float
    solve_seconds: float
    bound_pruned: int = 0
    timed_out: bool = False
    pruning_cut_short: bool = False
    clusters: tuple[WindowCluster, ...] = ()

    @property
    def status(self) -> WindowStatus:
        """The worst of :class:`WindowStatus` that applies.

        ``time_limit`` means that the deadline (may have) changed the answer: a cluster
        got only what was certified by then, or went unpruned because the deadline had
        passed (:attr:`pruning_cut_short`).  A window that merely ran long, every
        cluster still solved as it would have been without a clock, keeps its status and
        says so in :attr:`timed_out`.
        """
        if self.pruning_cut_short:
            return WindowStatus.TIME_LIMIT
        worst = WindowStatus.CAPPED if self.hypotheses.nodes_capped else WindowStatus.EXACT
        for report in self.bounded_clusters:
            worst = max(worst, WindowStatus.of_cluster(report.status), key=WINDOW_STATUSES.index)
        return worst

    @property
    def captured_mass(self) -> float:
        """Lower bound on the share of the window's posterior mass that was summed."""
        return math.exp(sum(c.log_captured for c in self.bounded_clusters))

    def selection(self, tracks: int) -> NDArray[np.int64]:
        """Hypotheses of the best track set with ``tracks`` tracks (T, not K).

        The track set of an estimate of K is ``selection(posterior.marginal_tracks)``
        or ``selection(posterior.joint_map_tracks)``.
        """
        chosen = self.table.best_set(tracks)
        if chosen is None:
            raise InputError(f"no feasible track set with T = {tracks} tracks in this window")
        return np.asarray(chosen, dtype=np.int64)


_JSON = "json"
"""Key of a :class:`WindowReport` field's metadata saying how ``to_json`` writes it (no
key: as it is)."""
_COMPACT = "compact"  # a probability vector without its trailing entries below P_K_FLOOR
_FEASIBLE = "feasible"  # the best objective up to the last feasible T, null where -inf
_TIMING = "timing"  # only with timings=True
_INEXACT = "inexact"  # compact, and only where the mass is not exact
_UPPER = "upper"  # null where -inf, and only where it differs from best_objective


def _compact(values: NDArray[np.float64], floor: float) -> list[float]:
    """``values`` without its trailing entries below ``floor`` (at least one kept)."""
    above = np.flatnonzero(values >= floor)
    end = int(above[-1]) + 1 if above.size else 1
    return [float(v) for v in values[:end]]


@dataclass(frozen=True)
class WindowReport:
    """One line of ``windows.jsonl``.

    Two counts are reported.  K is the number of **targets** present in the window
    (Perry's K, detected or not): ``p_k`` is p(K | Z) under the configured
    ``k_prior``, and ``joint_map_k``, ``marginal_k`` and
    ``chosen_k`` are estimates of it.  T is the number of **tracks** of a track set
    (carried tracks alive in the window plus tracks started in it; what the set packing
    chooses): ``p_tracks`` is p(T | Z), ``best_objective`` the
    best score per T, and ``chosen_tracks`` the T of the committed set (the MAP set
    given ``chosen_k``).  ``undetected_mean`` is the expected number of targets in the
    window that no track explains (never detected).

    Every field is written under its own name, in field order; a field's ``metadata``
    says how (:data:`_JSON`): timings only with ``timings=True``, ``p_k_lower``/
    ``p_k_upper`` only where the mass is not exact.  The vectors stop
    where they become exactly 0 (beyond the largest reachable T) or, for p(K | Z), where
    its upper bound falls below :data:`P_K_FLOOR`; ``p_k_length`` is the full length
    Kmax + 1, so a huge Kmax costs no memory.  The JSON line also leaves out
    trailing probabilities below :data:`P_K_FLOOR`.  ``best_objective_upper`` holds the
    proven upper bounds of the best objective per T; it is written only where it
    differs from ``best_objective`` (a bounded cluster), and ``null`` in
    ``best_objective`` then means "no set found", not "none exists".
    """

    window: int
    first_scan: int
    last_scan: int
    start_time: float
    end_time: float
    committed_scans: int
    p_k_length: int
    k_prior: str
    p_k: NDArray[np.float64] = field(metadata={_JSON: _COMPACT})
    joint_map_k: int
    marginal_k: int
    chosen_k: int
    undetected_mean: float
    p_tracks: NDArray[np.float64] = field(metadata={_JSON: _COMPACT})
    joint_map_tracks: int
    marginal_tracks: int
    chosen_tracks: int
    best_objective: NDArray[np.float64] = field(metadata={_JSON: _FEASIBLE})
    status: WindowStatus
    marginal_exact: bool
    marginal_certain: bool
    joint_certain: bool
    captured_mass: float
    hypotheses_kept: int
    nodes_generated: int
    nodes_pruned: int
    nodes_capped: int
    hypotheses_pruned_by_bound: int
    clusters: int
    largest_cluster: int
    bounded_clusters: int
    carried_tracks: int
    piles_up_at_kmax: bool
    over_time_limit: bool = field(metadata={_JSON: _TIMING})
    p_k_lower: NDArray[np.float64] = field(metadata={_JSON: _INEXACT})
    p_k_upper: NDArray[np.float64] = field(metadata={_JSON: _INEXACT})
    best_objective_upper: NDArray[np.float64] = field(metadata={_JSON: _UPPER})
    generate_seconds: float = field(metadata={_JSON: _TIMING})
    solve_seconds: float = field(metadata={_JSON: _TIMING})

    def to_json(self, *, timings: bool = True) -> dict[str, object]:
        """The ``windows.jsonl`` line: every field under its name, in field order, as
        its ``metadata`` says (class docstring)."""
        feasible = np.flatnonzero(np.isfinite(self.best_objective))
        end = int(feasible[-1]) + 1 if feasible.size else 0
        out: dict[str, object] = {}
        for item in fields(self):
            value = getattr(self, item.name)
            rule = item.metadata.get(_JSON)
            if rule == _TIMING and not timings:
                continue
            if rule == _INEXACT and self.marginal_exact:
                continue
            if rule == _UPPER and not np.any(self.best_objective_upper > self.best_objective):
                continue
            if rule in (_COMPACT, _INEXACT):
                value = _compact(value, P_K_FLOOR)
            elif rule in (_FEASIBLE, _UPPER):
                values = value[:end] if rule == _FEASIBLE else value
                value = [float(b) if math.isfinite(b) else None for b in values]
            out[item.name] = value
        return out


@dataclass
class _TrackRecord:
    """Committed history of one track (mutable while the run goes on)."""

    track_id: int
    rows: list[int] = field(default_factory=list)


@dataclass
class WindowTally:
    """Running totals of a run's windows: what ``summary.json`` reports of them.

    Kept window by window (constant size, so a checkpoint of a long run stays small), and
    equal to the totals over :attr:`EstimateResult.windows`.
    """

    windows: int = 0
    status_counts: dict[str, int] = field(
        default_factory=lambda: {status.value: 0 for status in WindowStatus}
    )
    marginal_certain: int = 0
    marginal_exact: int = 0
    nodes_capped: int = 0
    piling_up_at_kmax: int = 0
    hypotheses: int = 0
    max_cluster: int = 0
    min_captured_mass: float = 1.0
    over_time_limit: int = 0
    seconds: float = 0.0

    def add(self, report: WindowReport) -> None:
        """Count one committed window."""
        self.windows += 1
        self.status_counts[report.status.value] += 1
        self.marginal_certain += int(report.marginal_certain)
        self.marginal_exact += int(report.marginal_exact)
        self.nodes_capped += int(report.nodes_capped)
        self.piling_up_at_kmax += int(report.piles_up_at_kmax)
        self.hypotheses += int(report.hypotheses_kept)
        self.max_cluster = max(self.max_cluster, int(report.largest_cluster))
        self.min_captured_mass = min(self.min_captured_mass, float(report.captured_mass))
        self.over_time_limit += int(report.over_time_limit)

    def kmax_warning(self, max_tracks: int) -> str | None:
        """The warning that Kmax cuts the posterior off, when some window piled up at it."""
        if not self.piling_up_at_kmax:
            return None
        return (
            f"p(K = Kmax | Z) exceeded 1% in {self.piling_up_at_kmax} of {self.windows} "
            f"windows: max_tracks = {max_tracks} probably cuts off the posterior; raise it"
        )


@dataclass
class RunState:
    """Everything a run carries from one window to the next.

    :meth:`WindowEstimator.start` makes it, :meth:`WindowEstimator.step` advances it by
    one window and :meth:`WindowEstimator.finish` turns it into the result.  It holds no
    scans, only numbers, so it pickles: a checkpoint of it, restored and stepped on with
    the same scans and configuration, continues the run exactly as if it had never
    stopped (``mapassoc run --resume``).

    Attributes
    ----------
    total_scans : int
        Number of scans of the run.
    next_scan : int
        Index of the first scan not committed yet (``== total_scans`` when done).
    next_track_id : int
        Id the next new track gets.
    carried : list of CarriedTrack
        Tracks alive at the last committed scan.
    undetected : UndetectedTargets or None
        Targets never detected after the last committed scan (None: the recording starts).
    records : dict of int to _TrackRecord
        Committed detection ids of every track.
    tally : WindowTally
        Totals of the committed windows.
    """

    total_scans: int
    next_scan: int = 0
    next_track_id: int = 1
    carried: list[CarriedTrack] = field(default_factory=list)
    undetected: UndetectedTargets | None = None
    records: dict[int, _TrackRecord] = field(default_factory=dict)
    tally: WindowTally = field(default_factory=WindowTally)

    def __post_init__(self) -> None:
        for name in ("total_scans", "next_scan", "next_track_id"):
            setattr(self, name, check_integer(f"RunState {name}", getattr(self, name), minimum=0))
        _check_carried(self.carried, self.undetected)
        check_instance("RunState records", self.records, dict)
        check_instance("RunState tally", self.tally, WindowTally)

    @property
    def done(self) -> bool:
        """Whether every scan is committed."""
        return self.next_scan >= self.total_scans


@dataclass(frozen=True, eq=False)
class EstimateResult:
    """Output of :meth:`WindowEstimator.run` (and :meth:`WindowEstimator.finish`).

    Attributes
    ----------
    tracks : TrackTable
        Smoothed tracks, one row per track per scan from its first to its last detection.
    windows : tuple of WindowReport
        Every window's report (empty from :meth:`WindowEstimator.finish` unless given).
    track_rows : dict of int to tuple of int
        Detection ids used by each track.
    seconds : float
        Wall time of the run (summed over the sessions of a resumed run).
    num_scans : int
    tally : WindowTally
        Totals over the windows (what :meth:`summary` reports).
    refinement : RefinementReport or None
        What the whole recording's refinement did (None when ``refine_passes = 0``);
        ``tracks`` and ``track_rows`` are then the refined ones.
    confidence : TrackConfidence or None
        Existence and association probabilities of the refined tracks (``tracks`` carries
        the existence column); None without refinement.
    dropped : tuple of int
        Refined tracks left out for an existence below ``min_existence``.
    """

    tracks: TrackTable
    windows: tuple[WindowReport, ...]
    track_rows: dict[int, tuple[int, ...]]
    seconds: float
    num_scans: int
    tally: WindowTally
    refinement: RefinementReport | None = None
    confidence: TrackConfidence | None = None
    dropped: tuple[int, ...] = ()

    def summary(self, *, timings: bool = True) -> dict[str, object]:
        t = self.tally
        out: dict[str, object] = {
            "scans": self.num_scans,
            "windows": t.windows,
            "tracks": len(self.track_rows),
            "detections_in_tracks": int(sum(len(r) for r in self.track_rows.values())),
            "windows_exact": t.status_counts[WindowStatus.EXACT.value],
            "window_statuses": {status: t.status_counts[status] for status in WINDOW_STATUSES},
            "windows_marginal_certain": t.marginal_certain,
            "nodes_capped": t.nodes_capped,
            "windows_marginal_exact": t.marginal_exact,
            "windows_piling_up_at_kmax": t.piling_up_at_kmax,
            "mean_hypotheses_per_window": t.hypotheses / t.windows if t.windows else 0.0,
            "max_cluster": t.max_cluster,
            "min_captured_mass": t.min_captured_mass,
        }
        if timings:
            out["seconds"] = self.seconds
            out["scans_per_second"] = self.num_scans / self.seconds if self.seconds > 0 else None
            out["windows_over_time_limit"] = t.over_time_limit
        if self.refinement is not None:
            out["refinement"] = self.refinement.to_json(timings=timings)
        if self.confidence is not None:
            known = [r for r in self.confidence.existence.values() if not math.isnan(r)]
            out["confidence"] = {
                "exact": self.confidence.exact,
                "windows": self.confidence.windows,
                "mean_existence": float(np.mean(known)) if known else None,
                "tracks_below_min_existence": len(self.dropped),
            }
        return out


SPREAD_WARNING_RATIO = 4.0
""":func:`time_scale_warning` fires when one typical time step spreads a new track's
predicted position (one standard deviation) over more than this many times the largest
side of the position sensors' regions.  The built-in scenarios stay below 0.02 of it."""


def time_scale_warning(config: Config, scans: Sequence[Scan]) -> str | None:
    """A warning when the scans' time step looks like a unit mistake, else None.

    The rule: take the median step ``dt`` between distinct scan times and a track born
    at a detection (position exact, velocity and the other unmeasured components from
    the birth prior: ``BirthModel.velocity_std`` and so on, in position units per time
    unit), predict it by ``dt`` with the motion model (its initiation model, as a new
    track does: ``F P F^T + Q(dt)``) and take the largest standard deviation of the
    predicted position.  When that is more than :data:`SPREAD_WARNING_RATIO` times the
    largest side of every position sensor's region, a target could be anywhere after
    one scan and hardly any track can start: the times are probably not in the unit
    the model's standard deviations and noise are per (milliseconds or nanoseconds
    against a model in seconds).  Only sensors that measure the position directly
    have a region in position units; without one there is no warning.

    Parameters
    ----------
    config : Config
    scans : sequence of Scan
        Checked already (sorted).

    Returns
    -------
    str or None
        The message: the step, the spread, the velocity_std and the region, and which
        key to check.
    """
    times = np.unique([scan.time for scan in scans])
    if times.size < 2:
        return None
    dt = float(np.median(np.diff(times)))
    model = config.motion.initiation_model()
    sides = [
        (float(np.max(sensor.region.upper - sensor.region.lower)), name)
        for name, sensor in config.sensors.items()
        if sensor.measurement.measures_position_directly
    ]
    if not model.is_linear or not sides:
        return None
    extent, sensor = max(sides)
    n = model.state_dim
    position = list(model.position_indices)
    rest = [i for i in range(n) if i not in position]
    with np.errstate(over="ignore", invalid="ignore"):
        P = np.zeros((n, n))
        if rest:
            P[np.ix_(rest, rest)] = model.birth_prior(config.birth)[1]
        F = model.jacobian(np.zeros(n), dt)  # a linear model's Jacobian is F(dt)
        predicted = F @ P @ F.T + model.process_noise(dt)
        spread = float(np.sqrt(np.max(np.diag(predicted)[position])))
    if math.isfinite(spread) and spread <= SPREAD_WARNING_RATIO * extent:
        return None  # (an overflow to inf or nan warns)
    return (
        f"the scans are {dt:.6g} time units apart (median step), and over one step a new "
        f"track's predicted position spreads by {spread:.3g} (one standard deviation; "
        f"birth velocity_std = {config.birth.velocity_std!r} per time unit, and the "
        f"motion model's process noise), {spread / extent:.3g} times the largest side "
        f"{extent:.6g} of the region of sensor '{sensor}': a target could be anywhere after "
        "one scan, so hardly any track can start. Is the detections' time column in the "
        "unit of birth.velocity_std and of the [motion] noise (seconds, say, not "
        "milliseconds or nanoseconds)?"
    )


def _check_carried(carried: object, undetected: object) -> list[CarriedTrack]:
    """``carried`` (of ``solve_window`` or a RunState) as a list of CarriedTrack, after
    checking it and ``undetected`` (None or an UndetectedTargets)."""
    if isinstance(carried, (str, bytes)) or not isinstance(carried, Sequence):
        raise InputError(
            f"carried must be a sequence of CarriedTrack (RunState.carried), got {shown(carried)}"
        )
    for i, track in enumerate(carried):
        check_instance(f"carried[{i}]", track, CarriedTrack)
    if undetected is not None:
        check_instance(
            "undetected",
            undetected,
            UndetectedTargets,
            hint="None starts the recording at the window's first scan",
        )
    return list(carried)


_Component = TypeVar("_Component")


def _component(
    name: str, given: object, kind: type[_Component], build: Callable[[], _Component]
) -> _Component:
    """``given`` when it is a ``kind`` (InputError naming ``name`` otherwise), else
    ``build()``."""
    if given is None:
        return build()
    if not isinstance(given, kind):
        raise InputError(f"{name} must be a {kind.__name__}, got {given!r:.80}", key=name)
    return given


def default_generator(config: Config) -> HypothesisGenerator:
    """The forward pass's hypothesis generator: ``config``'s models and its
    ``[estimator.pruning]`` settings."""
    pruning = config.estimator.pruning
    return HypothesisGenerator(
        motion=config.motion,
        sensors=config.sensors,
        birth=config.birth,
        gate_probability=pruning.gate_probability,
        max_hypotheses_per_tree=pruning.max_hypotheses_per_tree,
        prune_log_ratio=pruning.prune_log_ratio,
        sibling_prune_log_ratio=pruning.sibling_log_ratio,
    )


def _window_report(
    solution: WindowSolution,
    *,
    window: int,
    scans: Sequence[Scan],
    first: int,
    end: int,
    commit: int,
    chosen_k: int,
    chosen_tracks: int,
) -> WindowReport:
    """The report of window number ``window`` over ``scans[first:end]``, solved as
    ``solution``, of which the first ``commit`` scans were committed with ``chosen_k``
    targets and ``chosen_tracks`` tracks.  The per-k arrays stop where nothing is left
    (p(K) entries after the last one of at least :data:`P_K_FLOOR` in its upper bound,
    track-count entries after the last finite upper mass)."""
    post = solution.posterior
    possible = np.flatnonzero(np.isfinite(solution.table.log_mass_upper))
    reach = int(possible[-1]) + 1 if possible.size else 1
    positive = np.flatnonzero(post.probabilities_upper >= P_K_FLOOR)
    k_reach = int(positive[-1]) + 1 if positive.size else 1
    return WindowReport(
        window=window,
        first_scan=first,
        last_scan=end - 1,
        start_time=scans[first].time,
        end_time=scans[end - 1].time,
        committed_scans=commit,
        p_k_length=post.max_tracks + 1,
        p_k=post.probabilities[:k_reach].copy(),
        p_k_lower=post.probabilities_lower[:k_reach].copy(),
        p_k_upper=post.probabilities_upper[:k_reach].copy(),
        p_tracks=post.track_probabilities[:reach].copy(),
        best_objective=post.best_log_score[:reach].copy(),
        best_objective_upper=solution.table.best_upper[:reach].copy(),
        joint_map_k=post.joint_map_k,
        marginal_k=post.marginal_k,
        chosen_k=chosen_k,
        joint_map_tracks=post.joint_map_tracks,
        marginal_tracks=post.marginal_tracks,
        chosen_tracks=chosen_tracks,
        undetected_mean=post.undetected_mean,
        k_prior=post.count_prior.kind,
        marginal_exact=post.exact,
        marginal_certain=post.marginal_certain,
        joint_certain=post.joint_certain,
        captured_mass=solution.captured_mass,
        status=solution.status,
        hypotheses_kept=solution.hypotheses.count,
        nodes_generated=solution.hypotheses.nodes_generated,
        nodes_pruned=solution.hypotheses.nodes_pruned,
        nodes_capped=solution.hypotheses.nodes_capped,
        hypotheses_pruned_by_bound=solution.bound_pruned,
        clusters=len(solution.cluster_sizes),
        largest_cluster=max(solution.cluster_sizes, default=0),
        bounded_clusters=len(solution.bounded_clusters),
        carried_tracks=int(np.count_nonzero(solution.hypotheses.tree_track_ids >= 0)),
        piles_up_at_kmax=post.piles_up_at_kmax,
        over_time_limit=solution.timed_out,
        generate_seconds=solution.generate_seconds,
        solve_seconds=solution.solve_seconds,
    )


class WindowEstimator:
    """Sliding-window MAP estimator of track sets and of the number of tracks.

    Parameters
    ----------
    config : Config
        Motion model, sensors, birth model and estimator settings.
    generator : HypothesisGenerator, optional
        Grows the windows' hypothesis trees; default :func:`default_generator` of
        ``config`` (its ``[estimator.pruning]``).
    cluster_solver : ClusterSolver, optional
        Solves the windows' clusters; default
        ``ClusterSolver.from_settings(config.estimator.search)``.
    count_prior : CountPrior, optional
        Prior on the number of targets in a window; default
        ``config.estimator.count.count_prior()``.
    k_estimator : KEstimator, optional
        Which K the committed track set has; default
        ``config.estimator.count.k_estimator()``.

    Every component not given is built from ``config`` (:meth:`from_config` builds them
    all), so a test or an experiment can swap one piece and keep the rest.
    """

    def __init__(
        self,
        *,
        config: Config,
        generator: HypothesisGenerator | None = None,
        cluster_solver: ClusterSolver | None = None,
        count_prior: CountPrior | None = None,
        k_estimator: KEstimator | None = None,
    ) -> None:
        self.config = check_config(config)
        s = config.estimator
        self.settings = s
        self.generator = _component(
            "generator", generator, HypothesisGenerator, lambda: default_generator(config)
        )
        self.cluster_solver = _component(
            "cluster_solver",
            cluster_solver,
            ClusterSolver,
            lambda: ClusterSolver.from_settings(s.search),
        )
        self.solver = self.cluster_solver.solver
        self.count_prior = _component("count_prior", count_prior, CountPrior, s.count_prior)
        self.k_estimator = _component("k_estimator", k_estimator, KEstimator, s.k_estimator)

    @classmethod
    def from_config(cls, config: Config) -> WindowEstimator:
        """The estimator with every component built from ``config``'s settings."""
        return cls(config=config)

    # -- one window ------------------------------------------------------------------
    def solve_window(
        self,
        scans: Sequence[Scan],
        carried: Sequence[CarriedTrack] = (),
        *,
        undetected: UndetectedTargets | None = None,
    ) -> WindowSolution:
        """Hypotheses, per-T tables and posterior over K of one window.

        Parameters
        ----------
        scans : sequence of Scan
            The window's scans in time order.
        carried : sequence of CarriedTrack
            Tracks committed by earlier windows.
        undetected : UndetectedTargets, optional
            The targets never detected before the window (what :meth:`run` carries
            from window to window, ``WindowSolution.population.after_scan``).  Default:
            the recording starts at the window's first scan, with
            ``BirthModel.initial_count`` targets present; so ``solve_window(scans[:N])``
            is exactly the first window of ``run(scans)``.

        Raises
        ------
        InputError
            The scans fail the checks of :meth:`start` (not a sequence of Scan, none,
            out of (time, sensor) order or repeated, an unknown sensor).
        """
        scans = check_scans(scans, self.config.sensors, what="solve")
        carried = _check_carried(carried, undetected)
        load_kernels()  # a first run's compilation is not the window's time
        t0 = time.perf_counter()
        deadline = t0 + self.settings.windows.time_limit
        population = self.generator.population(scans, carried, undetected)
        hyps = self.generator.generate(scans, carried, population=population)
        t1 = time.perf_counter()
        problem = packing_problem(hyps)
        # No track set has more tracks than counted hypotheses: beyond
        # FULL_LENGTH_KMAX the per-T tables stop there whatever max_tracks says (the K
        # beyond are the posterior's business, k_posterior).
        counted = int(np.count_nonzero(problem.counts))
        kmax = min(self.settings.count.max_tracks, max(counted, FULL_LENGTH_KMAX))
        solved = self.cluster_solver.solve_window(problem, kmax, deadline)
        combined = solved.table
        posterior = k_posterior(
            combined.best,
            combined.log_mass,
            prior=self.count_prior,
            population=population,
            exact=combined.exact,
            best_upper=combined.best_upper,
            log_mass_upper=combined.log_mass_upper,
        )
        t2 = time.perf_counter()
        return WindowSolution(
            hypotheses=hyps,
            problem=problem,
            table=combined,
            posterior=posterior,
            population=population,
            cluster_sizes=solved.cluster_sizes,
            bounded_clusters=solved.reports,
            generate_seconds=t1 - t0,
            solve_seconds=t2 - t1,
            bound_pruned=solved.bound_pruned,
            timed_out=t2 > deadline,
            pruning_cut_short=solved.pruning_cut_short,
            clusters=solved.clusters,
        )

    # -- whole run -------------------------------------------------------------------
    def run(
        self,
        scans: Sequence[Scan],
        *,
        progress: ProgressCallback | None = None,
        on_window: WindowCallback | None = None,
        select: SelectionRule | None = None,
    ) -> EstimateResult:
        """Estimate tracks over all scans.

        Equal to :meth:`start`, then :meth:`step` until the state is done, then
        :meth:`finish` (what ``mapassoc run`` does, with checkpoints in between).

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
        select : SelectionRule, optional
            Replaces the MAP set given the estimate of K as the set each window commits
            (for comparisons, e.g. the LP relaxation tracker); the window's report then
            gives that set's T as ``chosen_tracks``.  Default: the estimator's own set.
        """
        scans = check_scans(scans, self.config.sensors)
        for name, call in (("progress", progress), ("on_window", on_window), ("select", select)):
            check_callback(f"run: {name}", call)
        state = self.start(scans)
        reports: list[WindowReport] = []
        while not state.done:
            reports.append(self.step(scans, state, select=select))
            if on_window is not None:
                on_window(reports[-1])
            if progress is not None:
                progress(state.next_scan, state.total_scans)
        return self.finish(scans, state, windows=reports)

    def start(self, scans: Sequence[Scan]) -> RunState:
        """Check the scans and return the state of a run that has committed nothing.

        Parameters
        ----------
        scans : sequence of Scan
            Sorted by (time, sensor); may include empty scans.

        Warns (RuntimeWarning) when ``max_tracks = 0``, and when the typical time step
        looks like a unit mistake (:func:`time_scale_warning`: times in milliseconds
        or nanoseconds against a model in seconds).

        Raises
        ------
        InputError
            Not a sequence of Scan (the message says how to read a file, a DataFrame or
            arrays), no scans, scans out of order, an unknown sensor, or a time step so
            large that the motion model's matrices are not finite.
        """
        scans = check_scans(scans, self.config.sensors)
        self._check_time_steps(scans)
        message = time_scale_warning(self.config, scans)
        if message is not None:
            warnings.warn(message, RuntimeWarning, stacklevel=2)
        if self.settings.count.max_tracks == 0:
            warnings.warn(
                "max_tracks = 0: every detection is a false alarm and p(K = 0 | Z) = 1 by "
                "construction, so no window can show that Kmax cuts the posterior off; "
                "raise max_tracks to estimate tracks",
                RuntimeWarning,
                stacklevel=2,
            )
        return RunState(total_scans=len(scans))

    def _check_time_steps(self, scans: Sequence[Scan]) -> None:
        """Raise unless the motion model's F and Q are finite for the largest time step."""
        times = np.unique([scan.time for scan in scans])
        if times.size < 2:
            return
        gaps = np.diff(times)
        widest = int(np.argmax(gaps))
        dt = float(gaps[widest])
        problem = None
        try:
            with np.errstate(over="raise", invalid="raise"):
                matrices = [self.config.motion.process_noise(dt)]
                if self.config.motion.is_linear:  # its Jacobian is F(dt)
                    n = self.config.motion.state_dim
                    matrices.append(self.config.motion.jacobian(np.zeros(n), dt))
            if not all(np.all(np.isfinite(m)) for m in matrices):
                problem = "its matrices are not finite"
        except (OverflowError, FloatingPointError) as exc:
            problem = f"computing them overflows ({exc})"
        if problem is not None:
            raise InputError(
                f"scans at times {times[widest]!r} and {times[widest + 1]!r} are {dt!r} apart: "
                f"too long a step for the motion model {self.config.motion!r}, {problem}; "
                "check the unit of the detections' time column"
            )

    def step(
        self, scans: Sequence[Scan], state: RunState, *, select: SelectionRule | None = None
    ) -> WindowReport:
        """Solve and commit the next window, advancing ``state`` in place.

        Parameters
        ----------
        scans : sequence of Scan
            The run's scans (the same as given to :meth:`start`).
        state : RunState
            Not done; advanced past the committed scans.
        select : SelectionRule, optional
            As in :meth:`run`.

        Returns
        -------
        WindowReport
        """
        self._check_step(scans, state, select)
        t_start = time.perf_counter()
        span = window_span(
            state.next_scan,
            state.total_scans,
            length=self.settings.windows.window_length,
            stride=self.settings.windows.stride,
        )
        start, end, commit = span.start, span.end, span.commit
        solution = self.solve_window(scans[start:end], state.carried, undetected=state.undetected)
        chosen_k, chosen_tracks = self.k_estimator.choose(solution.posterior)
        if select is None:
            selection = solution.selection(chosen_tracks)
        else:
            selection = np.asarray(select(solution, chosen_k, chosen_tracks), dtype=np.int64)
            chosen_tracks = int(np.count_nonzero(solution.problem.counts[selection]))
        state.carried, state.next_track_id = self._commit(
            solution.hypotheses, selection, commit, state.records, state.next_track_id
        )
        state.undetected = solution.population.after_scan[commit - 1]
        report = _window_report(
            solution,
            window=state.tally.windows,
            scans=scans,
            first=start,
            end=end,
            commit=commit,
            chosen_k=chosen_k,
            chosen_tracks=chosen_tracks,
        )
        state.next_scan = start + commit
        state.tally.add(report)
        state.tally.seconds += time.perf_counter() - t_start
        return report

    @staticmethod
    def _check_step(scans: Sequence[Scan], state: RunState, select: SelectionRule | None) -> None:
        """Refuse what :meth:`step` cannot take: a state that is not a RunState, is of
        another run or is done; scans that are not a sequence; a ``select`` that is not
        callable."""
        check_instance("step: state", state, RunState, hint="start a run with start(scans)")
        if isinstance(scans, (str, bytes)) or not isinstance(scans, Sequence):
            raise InputError(
                f"step: scans must be the sequence of Scan given to start, got {shown(scans)}"
            )
        check_callback("step: select", select)
        if len(scans) != state.total_scans:
            raise InputError(
                f"state is of a run over {state.total_scans} scans, got {len(scans)} scans"
            )
        if state.done:
            raise InputError("state is done: every scan is committed already")

    def finish(
        self,
        scans: Sequence[Scan],
        state: RunState,
        *,
        windows: Sequence[WindowReport] = (),
        refine: bool = True,
        stop: Callable[[], bool] | None = None,
    ) -> EstimateResult:
        """Refine (``refine_passes > 0``) and smooth every track of a done run.

        Warns (RuntimeWarning) when p(K = Kmax | Z) exceeded 1% in some window.

        Parameters
        ----------
        scans : sequence of Scan
            The run's scans.
        state : RunState
            Done.
        windows : sequence of WindowReport, optional
            The reports to keep in the result (:meth:`run` passes all of them).
        refine : bool
            False leaves the forward pass's tracks as they are whatever
            ``refine_passes`` says (a segment of a longer recording, refined once
            stitched: :mod:`mapassoc.estimator.segments`).
        stop : callable, optional
            Polled between the units of the refinement and of its confidence pass (a
            re-solve, a linking round, a window): see :func:`refine_track_rows`.

        Raises
        ------
        StopRequested
            ``stop`` returned True; ``state`` is unchanged, so finishing it again gives
            the result an uninterrupted call would have.
        """
        if not state.done:
            raise InputError(
                f"state is not done: {state.next_scan} of {state.total_scans} scans committed"
            )
        t_start = time.perf_counter()
        tally = state.tally
        message = tally.kmax_warning(self.settings.count.max_tracks)
        if message is not None:
            warnings.warn(message, RuntimeWarning, stacklevel=3)
        track_rows = {tid: tuple(r.rows) for tid, r in sorted(state.records.items()) if r.rows}
        refined = None
        if refine and self.settings.refinement.passes > 0 and track_rows:
            refined = refine_track_rows(self.config, scans, track_rows, stop=stop)
            track_rows = refined.track_rows
        tracks = self._smooth(scans, track_rows)
        if refined is not None and refined.confidence is not None:
            tracks = tracks.with_existence(refined.confidence.existence)
        tally.seconds += time.perf_counter() - t_start
        return EstimateResult(
            tracks=tracks,
            windows=tuple(windows),
            track_rows=track_rows,
            seconds=tally.seconds,
            num_scans=state.total_scans,
            tally=tally,
            refinement=None if refined is None else refined.report,
            confidence=None if refined is None else refined.confidence,
            dropped=() if refined is None else refined.dropped,
        )

    def _commit(
        self,
        hyps: WindowHypotheses,
        selection: NDArray[np.int64],
        commit: int,
        records: dict[int, _TrackRecord],
        next_id: int,
    ) -> tuple[list[CarriedTrack], int]:
        """Commit the first ``commit`` scans of the chosen set; return the new carried tracks."""
        new_carried: list[CarriedTrack] = []
        for track in hyps.commit(selection, commit):
            if track.is_new:
                track_id = next_id
                next_id += 1
                records[track_id] = _TrackRecord(track_id)
            else:
                track_id = track.track_id
            records[track_id].rows.extend(track.rows.tolist())
            state = track.carried(track_id)
            if state is not None:
                new_carried.append(state)
        new_carried.sort(key=lambda t: t.track_id)
        return new_carried, next_id

    def _smooth(self, scans: Sequence[Scan], track_rows: dict[int, tuple[int, ...]]) -> TrackTable:
        """RTS-smooth every track over the detections it used."""
        where = {
            int(row): (k, j) for k, scan in enumerate(scans) for j, row in enumerate(scan.rows)
        }
        associations = {tid: dict(where[row] for row in rows) for tid, rows in track_rows.items()}
        return smooth_tracks(scans, associations, self.config)
