"""Settings of the window estimator, one record per component it configures.

Each record is a plain frozen dataclass, validated on construction; every field error
names the field, the value and what was expected, and carries the field name in
``InputError.key``.

==================  ======================  ==========================================
record              TOML table              configures
==================  ======================  ==========================================
WindowSettings      [estimator.windows]     the forward pass's sliding windows
PruningSettings     [estimator.pruning]     the hypothesis trees of the forward windows
SearchSettings      [estimator.search]      the per-cluster solve and integer programs
CountSettings       [estimator.count]       the number of targets: Kmax, prior, estimate
RefinementSettings  [estimator.refinement]  the whole recording's refinement
ParameterSettings   [estimator.parameters]  the EM of ``"auto"`` sensor parameters
==================  ======================  ==========================================

:class:`EstimatorSettings` composes them (``config.estimator.windows.window_length``);
:mod:`mapassoc.data.config` reads and writes them as the sub-tables above, whose dotted
key paths are the attribute paths.  Each field has one meaning.  The estimator's settings
used to be one flat record (and ``[estimator]`` table) of 19 keys, some of which set
several things at once; :data:`FLAT_KEYS` maps each old key to the field or fields it
set, and :class:`EstimatorSettings` still accepts the old keys as keyword arguments and
reads them as attributes (aliases, so code written for the flat record keeps working).

:func:`settings_to_json` writes a record as JSON (run folders' manifests) and
:func:`settings_from_json` reads that back.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

from mapassoc.errors import InputError
from mapassoc.log_space import json_number, number_from_json
from mapassoc.models.population import BirthModel
from mapassoc.models.target_count import (
    COUNT_PRIORS,
    K_ESTIMATORS,
    CountPrior,
    KEstimator,
    check_weights,
)
from mapassoc.validation import (
    check_integer,
    check_positive,
    check_probability,
)

__all__ = [
    "BirthModel",
    "CountSettings",
    "EstimatorSettings",
    "FLAT_KEYS",
    "K_PRIORS",
    "K_ESTIMATES",
    "ParameterSettings",
    "PruningSettings",
    "RefinementSettings",
    "SearchSettings",
    "WindowSettings",
    "settings_to_json",
    "settings_from_json",
]

K_PRIORS = COUNT_PRIORS
"""Names of the priors on the number of targets (``[estimator.count] k_prior``)."""
K_ESTIMATES = tuple(K_ESTIMATORS)
"""Names of the estimates of K (``[estimator.count] k_estimate``)."""

DEFAULT_PRUNE_LOG_RATIO = 9.0
"""The forward pass's pruning width: the default of every rule that prunes at it."""
DEFAULT_TIME_LIMIT = 2.0
"""The default seconds per window, and per integer program of the refinement."""


def _set_int(settings: object, name: str, *, minimum: int, optional: bool = False) -> None:
    """Check the integer field ``name`` (>= ``minimum``; None too if ``optional``) and
    store it as an ``int``, so a numpy integer given for it is written to JSON and TOML
    like a Python one."""
    value = getattr(settings, name)
    if optional and value is None:
        return
    expected = name if not optional else f"{name} (or None)"
    value = check_integer(expected, value, minimum=minimum, key=name)
    object.__setattr__(settings, name, value)


def _check_width(settings: object, name: str, *, optional: bool = False) -> None:
    """A pruning width: a number >= 0, ``inf`` disabling the rule (None if ``optional``)."""
    value = getattr(settings, name)
    if optional and value is None:
        return
    if isinstance(value, bool) or not (isinstance(value, (int, float)) and value >= 0):
        raise InputError(f"{name} must be a number >= 0 (inf disables), got {value!r}", key=name)


@dataclass(frozen=True)
class WindowSettings:
    """The forward pass's sliding windows (``[estimator.windows]``;
    :class:`mapassoc.estimator.pipeline.WindowEstimator`).

    Parameters
    ----------
    window_length : int
        Scans per window N (>= 1).
    stride : int
        Scans committed per window, 1 <= stride <= window_length.
    time_limit : float
        Wall-clock seconds per window (hypothesis generation, solves and bounds
        together; a window past it reports ``status = "time_limit"`` with its best
        certified answer, and ``WindowSolution.timed_out``).  The outer guard: the work
        limits of :class:`SearchSettings` (and ``max_hypotheses_per_tree``) bind first
        on ordinary windows.  A window whose bounded path needs longer (those of the
        built-in ``parallel`` scenario take several seconds) stops at the limit with an
        answer that depends on the machine's speed.  For results that are a function of
        the input alone (tests, comparisons, notebooks), set a limit no window reaches,
        600 say: the deterministic work limits then bound every window.
    """

    window_length: int = 5
    stride: int = 1
    time_limit: float = DEFAULT_TIME_LIMIT

    def __post_init__(self) -> None:
        _set_int(self, "window_length", minimum=1)
        _set_int(self, "stride", minimum=1)
        if self.stride > self.window_length:
            raise InputError(
                f"stride must be <= window_length ({self.window_length}), got {self.stride}",
                key="stride",
            )
        check_positive("time_limit", self.time_limit, key="time_limit")


@dataclass(frozen=True)
class PruningSettings:
    """The hypothesis trees of the forward windows (``[estimator.pruning]``;
    :class:`mapassoc.estimator.hypotheses.HypothesisGenerator`).

    Parameters
    ----------
    gate_probability : float
        Chi-square gate probability P_G in (0, 1]; 1 disables gating (every detection
        of a scan may continue every track), which only small problems can afford.
    max_hypotheses_per_tree : int
        Cap on the leaves kept per track tree (best scores kept), >= 1.
    prune_log_ratio : float
        The new-tree rule: a new tree's node is pruned when even the most its path can
        still gain over the window leaves it more than this below 0 (not selecting the
        tree); and the sibling rule's width unless ``sibling_prune_log_ratio`` is set
        (>= 0; ``inf`` disables).  The rule is proven: what it drops is in no track set
        within this of the best.
    sibling_prune_log_ratio : float or None
        The sibling rule's width: nodes scoring more than this below the best node of
        their tree are pruned (>= 0, ``inf`` disables it); ``None`` (default):
        ``prune_log_ratio``.  The sibling rule is a heuristic (a branch far below its best
        sibling may still belong to the best track set when the sibling conflicts with
        another track).  So with ``sibling_prune_log_ratio = inf``, ``gate_probability =
        1``, a cap that does not bite and the clusters' rule
        (``SearchSettings.bound_prune_log_ratio``) at ``inf`` or wider than the window's
        range of scores, a window's MAP track set is the unpruned one.
    """

    gate_probability: float = 0.999
    max_hypotheses_per_tree: int = 64
    prune_log_ratio: float = DEFAULT_PRUNE_LOG_RATIO
    sibling_prune_log_ratio: float | None = None

    def __post_init__(self) -> None:
        check_probability(
            "gate_probability", self.gate_probability, allow_zero=False, key="gate_probability"
        )
        _set_int(self, "max_hypotheses_per_tree", minimum=1)
        _check_width(self, "prune_log_ratio")
        _check_width(self, "sibling_prune_log_ratio", optional=True)

    @property
    def sibling_log_ratio(self) -> float:
        """The sibling rule's width: ``sibling_prune_log_ratio``, else ``prune_log_ratio``."""
        if self.sibling_prune_log_ratio is None:
            return float(self.prune_log_ratio)
        return float(self.sibling_prune_log_ratio)


@dataclass(frozen=True)
class SearchSettings:
    """The per-cluster solve of a window's program (``[estimator.search]``;
    :class:`mapassoc.estimator.cluster_solving.ClusterSolver`, and the refinement's
    integer programs).

    Parameters
    ----------
    solver : str
        Integer-program backend for clusters too large for the exact search (a name
        from ``mapassoc.solvers.available_solvers()``).
    exact_work_limit : int
        Transitions the exact per-cluster frontier search may take before the cluster
        gets certified bounds instead (deterministic; about a microsecond each).
    beam_width : int
        Frontiers kept by the beam search that gives a cluster too large for the exact
        search its lower bounds on the mass per K.
    bound_prune_log_ratio : float
        Clusters drop the hypotheses whose LP bound is more than this below the
        cluster's best set (a proven rule; >= 0, ``inf`` disables).
    program_time_limit : float
        Seconds a window solve of the refinement may take (its re-solves' best sets,
        integer programs included; the forward pass's windows have
        ``WindowSettings.time_limit`` instead).
    beam_entry_margin : float
        Every beam (a bounded cluster's tables, the confidence pass's marginals) drops
        a frontier's entries this many nats below the frontier's heaviest one (> 0):
        e^-40 of the mass, below double precision's share of a sum.
    mass_bound_multiplier_limit : float
        The mass bounds of the k no LP of a bounded cluster reached try cardinality
        multipliers evenly spaced over [-limit, limit] (> 0) ...
    mass_bound_multipliers : int
        ... this many of them (>= 1; one alone is 0); the best of them bounds each k.
    """

    solver: str = "highs"
    exact_work_limit: int = 500_000
    beam_width: int = 200
    bound_prune_log_ratio: float = DEFAULT_PRUNE_LOG_RATIO
    program_time_limit: float = DEFAULT_TIME_LIMIT
    beam_entry_margin: float = 40.0
    mass_bound_multiplier_limit: float = 30.0
    mass_bound_multipliers: int = 25

    def __post_init__(self) -> None:
        if not isinstance(self.solver, str) or not self.solver:
            raise InputError(f"solver must be a backend name, got {self.solver!r}", key="solver")
        _set_int(self, "exact_work_limit", minimum=1)
        _set_int(self, "beam_width", minimum=1)
        _check_width(self, "bound_prune_log_ratio")
        check_positive("program_time_limit", self.program_time_limit, key="program_time_limit")
        check_positive("beam_entry_margin", self.beam_entry_margin, key="beam_entry_margin")
        check_positive(
            "mass_bound_multiplier_limit",
            self.mass_bound_multiplier_limit,
            key="mass_bound_multiplier_limit",
        )
        _set_int(self, "mass_bound_multipliers", minimum=1)


@dataclass(frozen=True)
class CountSettings:
    """The number of targets K in a window (``[estimator.count]``;
    :func:`mapassoc.estimator.posterior.k_posterior` and the per-K tables).

    Parameters
    ----------
    max_tracks : int
        Kmax: the largest number of targets in a window; the window is solved for every
        number of tracks T = 0..Kmax.
    k_prior : {"birth", "uniform", "poisson", "weights"}
        Prior p(K) on the number K of targets present in a window (detected or not),
        K = 0..Kmax; the reported p(K | Z) is the exact posterior under it
        (:mod:`mapassoc.estimator.posterior`).  ``"birth"`` (default): the law the birth
        model implies (Poisson for a window that starts the recording), no extra factor;
        ``"uniform"``: uniform on 0..Kmax (Perry's MAP formulation); ``"poisson"``:
        Poisson with mean ``k_prior_mean``; ``"weights"``: ``k_prior_weights``.  The
        default was chosen by measurement (README, "Prior on the number of targets").
    k_prior_mean : float
        Mean of the Poisson prior (used when ``k_prior == "poisson"``).
    k_prior_weights : tuple of float
        Unnormalised p(K) for K = 0..Kmax (used when ``k_prior == "weights"``).
    k_estimate : {"marginal", "joint", "median"}
        Which estimate of K the committed track set uses
        (``mapassoc.models.target_count.K_ESTIMATORS``):
        ``argmax p(K | Z)`` (marginal, default), the K of the joint MAP (K, track set)
        (Perry's MAP formulation, eq. 14) with its set, or the posterior median; for the
        marginal and the median the set is the MAP track set given that K.
    """

    max_tracks: int = 20
    k_prior: str = "birth"
    k_prior_mean: float = 5.0
    k_prior_weights: tuple[float, ...] = field(default_factory=tuple)
    k_estimate: str = "marginal"

    def __post_init__(self) -> None:
        _set_int(self, "max_tracks", minimum=0)
        object.__setattr__(self, "k_prior_weights", check_weights(self.k_prior_weights))
        self.count_prior()  # validates k_prior, k_prior_mean and k_prior_weights
        if self.k_estimate not in K_ESTIMATES:
            raise InputError(
                f"k_estimate must be one of {K_ESTIMATES}, got {self.k_estimate!r}",
                key="k_estimate",
            )

    def k_estimator(self) -> KEstimator:
        """The estimator of K these settings name."""
        return K_ESTIMATORS[self.k_estimate]

    def count_prior(self) -> CountPrior:
        """The prior on the number of targets in a window these settings name."""
        return CountPrior(
            kind=self.k_prior,
            kmax=self.max_tracks,
            mean=self.k_prior_mean,
            weights=tuple(self.k_prior_weights),
        )


@dataclass(frozen=True)
class RefinementSettings:
    """How the whole recording's track set is refined after the forward pass
    (``[estimator.refinement]``; :class:`mapassoc.estimator.refinement.Refiner`).

    Parameters
    ----------
    passes : int
        Most sweeps over the recording's windows; 0 turns refinement off (the forward
        pass's tracks are reported).  Sweeps cycle through the window lengths (short,
        long, single scan, short, ...), forward then backward once per cycle; they stop
        once a sweep of each length changed nothing.  Each move is accepted only where
        the recording objective J rises.
    window_length : int or None
        Scans per short re-solved window; ``None``: the estimator's ``window_length``.
    long_window_length : int or None
        Scans per long re-solved window; ``None``: twice the short one; a value no longer
        than the short one leaves the long sweeps out.  Long windows let a target that no
        forward window found worth a track (low Pd in dense clutter: its first scans
        score below zero) start a track that pays over more scans, and join fragments
        further apart.
    stride : int or None
        Scans between the starts of consecutive re-solved windows; ``None``: about half
        the window (``(window_length + 1) // 2``), so that every window boundary of one
        sweep lies inside a window of the next.
    scan_windows : bool
        Also sweep windows of a single scan (when the short window is longer) at the
        scans of the re-solved windows whose trees the per-tree cap cut: the scan's
        associations re-solved with both boundaries, the tracks before it carried in and
        the tracks after it anchors (where nothing was capped, the longer window's
        program already held every change of one scan that its width keeps). A one-scan
        tree is a carried track's gated detections, its miss and its ending, so the
        per-tree cap never cuts it, and the re-solve is exact over what the refinement's
        width keeps: block coordinate ascent on J, one scan's associations at a time. It
        completes what the cap cuts from the longer windows' trees where targets are
        closely spaced (the converging family's measurements are in the changelog).
    link_gap : int
        Most scans between a track's last detection and another's first for a
        fragment-linking candidate; 0 turns fragment linking off.
    refilter_detections : int
        How many of a joined track piece's detections are re-filtered from the joining
        state when a move is *proposed*; past them the piece's own filter's terms are
        taken (:meth:`~mapassoc.estimator.objective.RecordingObjective.continue_converging`).
        Moves are *accepted* on the exact J of the changed tracks (every detection
        re-filtered), so this trades the proposals' accuracy against speed, never J's
        monotonicity.
    prune_log_ratio : float
        Pruning width of the re-solved short windows' trees (sibling and new-tree rules)
        and of the joins to one anchor (>= 0, ``inf`` disables).  Wider than the forward
        pass's by default: a re-solve must see alternatives the forward pass dropped
        (``mapassoc bench-refinement``: twice the width brings the GOSPA of parallel
        lanes, converging targets and dense_radar markedly closer to the oracle's, for
        a longer refinement).
    long_prune_log_ratio : float or None
        The same for the long windows; ``None``: ``prune_log_ratio``.  The estimator's
        default (``EstimatorSettings().refinement``) is the forward pass's width, 9:
        long windows are there to start tracks and join fragments no short window can,
        and at the wide width a long window's trees cost about four short ones' (over
        the bench families the narrower width found the same J on most runs and a
        fraction of a nat less on the others, in less of the refinement's time).
    identity_moves : bool
        After each sweep's fragment linking, also make the identity moves of
        :mod:`mapassoc.estimator.identity_moves` over the whole recording: switches of
        two tracks' tails at close approaches, splits before detections that cost their
        track more than they pay, extensions by free detections next to a track's end or
        start, and merges over any gap; each only where J rises.
        They run after each round of sweeps (one of every window length), where the
        sweeps have converged and at the last pass, and if they change the set the sweeps
        go on: they cost little beside a sweep and catch what a window cannot see, such
        as two pieces of one target further apart than ``link_gap``.  Not only once
        converged: where targets travel closely spaced the sweeps go on changing the set
        to the last pass, and moves made only then would leave no sweep to polish what
        they open.
    group_moves : bool
        After the identity moves, re-track each group of closely spaced tracks together
        (:mod:`mapassoc.estimator.group_moves`: a beam over joint assignments from a
        start scan to the group's end, applied only where J rises). It lifts J and the
        identity where several targets travel together for longer than a window, where
        the windows and the pairwise moves leave fewer tracks than targets hopping
        between them; elsewhere it finds no group or changes nothing.
    min_existence : float
        After the refinement, report only the tracks whose existence probability
        (:meth:`mapassoc.estimator.refinement.Refiner.confidence`) is at least this, in
        [0, 1]; 0 reports every track of the refined set.
    """

    passes: int = 6
    window_length: int | None = None
    long_window_length: int | None = None
    stride: int | None = None
    scan_windows: bool = True
    link_gap: int = 10
    refilter_detections: int = 15
    prune_log_ratio: float = 18.0
    long_prune_log_ratio: float | None = None
    identity_moves: bool = True
    group_moves: bool = True
    min_existence: float = 0.0

    def __post_init__(self) -> None:
        _set_int(self, "passes", minimum=0)
        for name in ("window_length", "long_window_length", "stride"):
            _set_int(self, name, minimum=1, optional=True)
        for name in ("scan_windows", "identity_moves", "group_moves"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(
                    f"{name} must be true or false, got {getattr(self, name)!r}", key=name
                )
        _set_int(self, "link_gap", minimum=0)
        _set_int(self, "refilter_detections", minimum=1)
        _check_width(self, "prune_log_ratio")
        _check_width(self, "long_prune_log_ratio", optional=True)
        check_probability("min_existence", self.min_existence, key="min_existence")


@dataclass(frozen=True)
class ParameterSettings:
    """The EM that estimates ``"auto"`` sensor parameters from the recording
    (``[estimator.parameters]``; :func:`mapassoc.estimator.parameters.estimate_parameters`,
    whose docstring explains each).

    Parameters
    ----------
    rate_tolerance : float
        Relative change of every false-alarm rate below which the iteration stops (> 0).
    pd_tolerance : float
        Absolute change of every ``Pd`` below which it stops (> 0).
    max_passes : int
        Most passes (>= 1); 3 was chosen by measurement (later passes drift).
    sample_scans : int
        Most scans a pass runs on (>= 1); a longer recording is sampled in blocks.
    sample_blocks_count : int
        Blocks the sample of a longer recording is cut into (>= 1).
    soft_counts : bool
        Whether each pass counts association probabilities (a confidence pass over its
        tracks) rather than hard associations when it updates ``Pd``, the false-alarm
        rate, the "auto" noise levels (each detection weighted by the probability that
        it is its track's) and the "auto" birth keys (each track weighted by its
        existence probability).
    """

    rate_tolerance: float = 0.02
    pd_tolerance: float = 0.005
    max_passes: int = 3
    sample_scans: int = 600
    sample_blocks_count: int = 6
    soft_counts: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.soft_counts, bool):
            raise InputError(
                f"soft_counts must be true or false, got {self.soft_counts!r}", key="soft_counts"
            )
        check_positive("rate_tolerance", self.rate_tolerance, key="rate_tolerance")
        check_positive("pd_tolerance", self.pd_tolerance, key="pd_tolerance")
        _set_int(self, "max_passes", minimum=1)
        _set_int(self, "sample_scans", minimum=1)
        _set_int(self, "sample_blocks_count", minimum=1)


COMPONENTS: dict[str, type[Any]] = {
    "windows": WindowSettings,
    "pruning": PruningSettings,
    "search": SearchSettings,
    "count": CountSettings,
    "refinement": RefinementSettings,
    "parameters": ParameterSettings,
}
"""The records :class:`EstimatorSettings` composes, by attribute (and TOML sub-table) name."""

_DEFAULT_COMPONENTS: dict[str, object] = {
    **{name: cls() for name, cls in COMPONENTS.items()},
    # The refinement's long windows prune at the forward pass's width (see
    # RefinementSettings.long_prune_log_ratio): what the flat record's refine_track_rows did.
    "refinement": RefinementSettings(long_prune_log_ratio=DEFAULT_PRUNE_LOG_RATIO),
}

FLAT_KEYS: dict[str, tuple[tuple[str, str], ...]] = {
    "window_length": (("windows", "window_length"),),
    "stride": (("windows", "stride"),),
    "max_tracks": (("count", "max_tracks"),),
    "gate_probability": (("pruning", "gate_probability"),),
    "max_hypotheses_per_tree": (("pruning", "max_hypotheses_per_tree"),),
    "prune_log_ratio": (
        ("pruning", "prune_log_ratio"),
        ("search", "bound_prune_log_ratio"),
        ("refinement", "long_prune_log_ratio"),
    ),
    "sibling_prune_log_ratio": (("pruning", "sibling_prune_log_ratio"),),
    "k_prior": (("count", "k_prior"),),
    "k_prior_mean": (("count", "k_prior_mean"),),
    "k_prior_weights": (("count", "k_prior_weights"),),
    "k_estimate": (("count", "k_estimate"),),
    "solver": (("search", "solver"),),
    "time_limit": (("windows", "time_limit"), ("search", "program_time_limit")),
    "exact_work_limit": (("search", "exact_work_limit"),),
    "beam_width": (("search", "beam_width"),),
    "refine_passes": (("refinement", "passes"),),
    "refine_link_gap": (("refinement", "link_gap"),),
    "refine_prune_log_ratio": (("refinement", "prune_log_ratio"),),
    "min_existence": (("refinement", "min_existence"),),
}
"""Each key of the old flat record (and ``[estimator]`` table) -> the ``(record, field)``
pairs it set, in the order of :class:`EstimatorSettings`'s records.  Two old keys set
several things: ``time_limit`` was a window's deadline and the refinement's integer
programs' limit, ``prune_log_ratio`` the new-tree rule (and, through it, the sibling
rule), the clusters' bound rule and the refinement's long windows."""


def flat_key_targets(name: str) -> str:
    """``"windows.time_limit and search.program_time_limit"``: what old key ``name`` sets."""
    return " and ".join(f"{record}.{field}" for record, field in FLAT_KEYS[name])


def _with_flat(records: dict[str, Any], flat: Mapping[str, object]) -> dict[str, Any]:
    """``records`` with the old flat keys of ``flat`` applied to the fields they set.

    Raises InputError for an unknown key (naming the known ones) or a bad value (its
    ``key`` the old name)."""
    unknown = sorted(set(flat) - set(FLAT_KEYS))
    if unknown:
        raise InputError(
            f"EstimatorSettings has no settings {unknown}; its records are "
            f"{list(COMPONENTS)} and its old flat keys {list(FLAT_KEYS)}",
            key=unknown[0],
        )
    changes: dict[str, dict[str, object]] = {}
    given_as: dict[tuple[str, str], str] = {}
    for name, value in flat.items():
        for record, target in FLAT_KEYS[name]:
            changes.setdefault(record, {})[target] = value
            given_as[(record, target)] = name
    out = dict(records)
    for record, fields in changes.items():
        try:
            out[record] = dataclasses.replace(records[record], **fields)
        except InputError as exc:
            as_given: str | None = given_as.get((record, exc.key or ""), exc.key)
            raise InputError(str(exc), key=as_given) from None
    return out


@dataclass(frozen=True, init=False)
class EstimatorSettings:
    """The window estimator's settings: one record per component it configures.

    Parameters
    ----------
    windows : WindowSettings, optional
    pruning : PruningSettings, optional
    search : SearchSettings, optional
    count : CountSettings, optional
    refinement : RefinementSettings, optional
        Default: ``RefinementSettings(long_prune_log_ratio=9.0)``, the forward pass's
        width for the long re-solved windows (a ``RefinementSettings()`` given here
        prunes them at its own ``prune_log_ratio`` instead).
    parameters : ParameterSettings, optional
    **flat
        Keys of the old flat record (:data:`FLAT_KEYS`), applied on top of the records:
        ``EstimatorSettings(time_limit=600)`` sets ``windows.time_limit`` and
        ``search.program_time_limit``, as the flat record's ``time_limit`` did.  The same
        names read as attributes (``settings.window_length``) are read-only aliases of
        the fields they set first; ``dataclasses.replace(settings, refine_passes=0)``
        works through them too.  New code names the record:
        ``settings.windows.window_length``.

    Raises
    ------
    InputError
        A record of the wrong type, an unknown keyword, or a bad value (``key`` the
        field, or the old name it was given as).
    """

    windows: WindowSettings
    pruning: PruningSettings
    search: SearchSettings
    count: CountSettings
    refinement: RefinementSettings
    parameters: ParameterSettings

    def __init__(
        self,
        windows: WindowSettings | None = None,
        pruning: PruningSettings | None = None,
        search: SearchSettings | None = None,
        count: CountSettings | None = None,
        refinement: RefinementSettings | None = None,
        parameters: ParameterSettings | None = None,
        **flat: Any,
    ) -> None:
        given = dict(
            windows=windows,
            pruning=pruning,
            search=search,
            count=count,
            refinement=refinement,
            parameters=parameters,
        )
        records: dict[str, Any] = {}
        for name, cls in COMPONENTS.items():
            value: Any = given[name]
            if value is None:
                value = _DEFAULT_COMPONENTS[name]
            elif not isinstance(value, cls):
                raise InputError(f"{name} must be a {cls.__name__}, got {value!r}", key=name)
            records[name] = value
        for name, value in _with_flat(records, flat).items():
            object.__setattr__(self, name, value)

    def with_time_limit(self, seconds: float) -> EstimatorSettings:
        """These settings with ``seconds`` for a window (``windows.time_limit``) and for
        each integer program of the refinement (``search.program_time_limit``): what the
        flat key ``time_limit`` set, and what the benchmarks' ``--time-limit`` sets."""
        return dataclasses.replace(
            self,
            windows=dataclasses.replace(self.windows, time_limit=seconds),
            search=dataclasses.replace(self.search, program_time_limit=seconds),
        )

    def with_window_length(self, length: int) -> EstimatorSettings:
        """These settings with ``windows.window_length = length``."""
        return dataclasses.replace(
            self, windows=dataclasses.replace(self.windows, window_length=length)
        )

    # -- what the estimator asks of several records --------------------------------------
    def k_estimator(self) -> KEstimator:
        """The estimator of K the count settings name."""
        return self.count.k_estimator()

    def count_prior(self) -> CountPrior:
        """The prior on the number of targets in a window the count settings name."""
        return self.count.count_prior()

    @property
    def sibling_log_ratio(self) -> float:
        """The sibling rule's width (:attr:`PruningSettings.sibling_log_ratio`)."""
        return self.pruning.sibling_log_ratio

    # -- read-only aliases of the old flat record (FLAT_KEYS) ----------------------------
    @property
    def window_length(self) -> int:
        """Alias of ``windows.window_length``."""
        return self.windows.window_length

    @property
    def stride(self) -> int:
        """Alias of ``windows.stride``."""
        return self.windows.stride

    @property
    def time_limit(self) -> float:
        """Alias of ``windows.time_limit`` (the old key also set
        ``search.program_time_limit``)."""
        return self.windows.time_limit

    @property
    def max_tracks(self) -> int:
        """Alias of ``count.max_tracks``."""
        return self.count.max_tracks

    @property
    def gate_probability(self) -> float:
        """Alias of ``pruning.gate_probability``."""
        return self.pruning.gate_probability

    @property
    def max_hypotheses_per_tree(self) -> int:
        """Alias of ``pruning.max_hypotheses_per_tree``."""
        return self.pruning.max_hypotheses_per_tree

    @property
    def prune_log_ratio(self) -> float:
        """Alias of ``pruning.prune_log_ratio`` (the old key also set
        ``search.bound_prune_log_ratio`` and ``refinement.long_prune_log_ratio``)."""
        return self.pruning.prune_log_ratio

    @property
    def sibling_prune_log_ratio(self) -> float | None:
        """Alias of ``pruning.sibling_prune_log_ratio``."""
        return self.pruning.sibling_prune_log_ratio

    @property
    def k_prior(self) -> str:
        """Alias of ``count.k_prior``."""
        return self.count.k_prior

    @property
    def k_prior_mean(self) -> float:
        """Alias of ``count.k_prior_mean``."""
        return self.count.k_prior_mean

    @property
    def k_prior_weights(self) -> tuple[float, ...]:
        """Alias of ``count.k_prior_weights``."""
        return self.count.k_prior_weights

    @property
    def k_estimate(self) -> str:
        """Alias of ``count.k_estimate``."""
        return self.count.k_estimate

    @property
    def solver(self) -> str:
        """Alias of ``search.solver``."""
        return self.search.solver

    @property
    def exact_work_limit(self) -> int:
        """Alias of ``search.exact_work_limit``."""
        return self.search.exact_work_limit

    @property
    def beam_width(self) -> int:
        """Alias of ``search.beam_width``."""
        return self.search.beam_width

    @property
    def refine_passes(self) -> int:
        """Alias of ``refinement.passes``."""
        return self.refinement.passes

    @property
    def refine_link_gap(self) -> int:
        """Alias of ``refinement.link_gap``."""
        return self.refinement.link_gap

    @property
    def refine_prune_log_ratio(self) -> float:
        """Alias of ``refinement.prune_log_ratio``."""
        return self.refinement.prune_log_ratio

    @property
    def min_existence(self) -> float:
        """Alias of ``refinement.min_existence``."""
        return self.refinement.min_existence


_Settings = TypeVar(
    "_Settings",
    BirthModel,
    EstimatorSettings,
    WindowSettings,
    PruningSettings,
    SearchSettings,
    CountSettings,
    RefinementSettings,
    ParameterSettings,
)


def _to_json(value: object) -> object:
    return json_number(value) if isinstance(value, float) else value


def settings_to_json(settings: object) -> dict[str, object]:
    """``{field: value}`` of a settings record, every value valid JSON.

    Tuples become lists and an infinite float (``prune_log_ratio = inf``) the string
    ``"inf"`` (:func:`mapassoc.log_space.json_number`), so that ``json.dumps(...,
    allow_nan=False)`` writes it and :func:`settings_from_json` reads back an equal
    object.  :class:`EstimatorSettings` is written as one object per record.
    """
    out: dict[str, object] = {}
    for item in dataclasses.fields(settings):  # type: ignore[arg-type]
        value = getattr(settings, item.name)
        if dataclasses.is_dataclass(value):
            out[item.name] = settings_to_json(value)
        elif isinstance(value, tuple):
            out[item.name] = [_to_json(v) for v in value]
        else:
            out[item.name] = _to_json(value)
    return out


def settings_from_json(cls: type[_Settings], record: Mapping[str, Any]) -> _Settings:
    """The settings object :func:`settings_to_json` wrote (``"inf"`` read as a float).

    An :class:`EstimatorSettings` record may also hold keys of the old flat record
    (:data:`FLAT_KEYS`), as run folders written before the records did.

    Raises
    ------
    InputError
        A field the class does not have, a string where a number belongs, or a value
        the class's checks refuse.
    """
    kinds = {f.name: f.type for f in dataclasses.fields(cls)}
    if cls is EstimatorSettings:  # the old flat keys, typed as the first field they set
        for name, ((component, target), *_) in FLAT_KEYS.items():
            fields = {f.name: f.type for f in dataclasses.fields(COMPONENTS[component])}
            kinds[name] = fields[target]
    unknown = sorted(set(record) - set(kinds))
    if unknown:
        raise InputError(f"{cls.__name__} has no fields {unknown}; got {dict(record)!r:.200}")
    values: dict[str, Any] = {}
    for name, value in record.items():
        try:
            if cls is EstimatorSettings and name in COMPONENTS:
                if not isinstance(value, Mapping):
                    raise ValueError(f"expected an object, got {value!r}")
                values[name] = settings_from_json(COMPONENTS[name], value)
            elif isinstance(value, list):
                values[name] = tuple(number_from_json(item) for item in value)
            elif isinstance(value, str) and kinds[name] not in ("str", str):
                values[name] = number_from_json(value)
            else:
                values[name] = value
        except ValueError as exc:
            raise InputError(f"{cls.__name__}.{name}: {exc}", key=name) from None
    return cls(**values)
