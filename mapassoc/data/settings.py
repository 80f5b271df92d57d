"""Settings of the window estimator: target birth and death, windows, K, solving.

Plain frozen dataclasses, validated on construction; every field error names the
field, the value and what was expected, and carries the field name in
``InputError.key``.  :mod:`mapassoc.data.config` builds them from a
TOML file (section and key names equal the field names); :func:`settings_to_json` writes
them as JSON (run folders' manifests) and :func:`settings_from_json` reads that back.
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
    "EstimatorSettings",
    "K_PRIORS",
    "K_ESTIMATES",
    "settings_to_json",
    "settings_from_json",
]

K_PRIORS = COUNT_PRIORS
K_ESTIMATES = tuple(K_ESTIMATORS)


def _set_int(settings: object, name: str, *, minimum: int) -> None:
    """Check the integer field ``name`` (>= ``minimum``) and store it as an ``int``, so a
    numpy integer given for it is written to JSON and TOML like a Python one."""
    value = check_integer(name, getattr(settings, name), minimum=minimum, key=name)
    object.__setattr__(settings, name, value)


@dataclass(frozen=True)
class EstimatorSettings:
    """How windows are built, pruned and solved, and which K is reported.

    Parameters
    ----------
    window_length : int
        Scans per window N (>= 1).
    stride : int
        Scans committed per window, 1 <= stride <= window_length.
    max_tracks : int
        Kmax: the largest number of targets in a window; the window is solved for every
        number of tracks T = 0..Kmax.
    gate_probability : float
        Chi-square gate probability P_G in (0, 1]; 1 disables gating (every detection
        of a scan may continue every track), which only small problems can afford.
    max_hypotheses_per_tree : int
        Cap on the leaves kept per track tree (best scores kept), >= 1.
    prune_log_ratio : float
        Nodes scoring more than this below the best node of their tree are pruned (the
        sibling rule, unless ``sibling_prune_log_ratio`` is set); a new tree's node is
        also pruned when even the most its path can still gain over the window leaves it
        more than this below 0 (not selecting the tree); clusters drop hypotheses whose
        LP bound is this far below the cluster's best set (>= 0; ``inf`` disables all
        three).
    sibling_prune_log_ratio : float or None
        The sibling rule's own width, when set (>= 0, ``inf`` disables it); ``None``
        (default): ``prune_log_ratio``.  The sibling rule is a heuristic (a branch far
        below its best sibling may still belong to the best track set when the sibling
        conflicts with another track); the other two rules are proven (what they drop is
        in no track set within ``prune_log_ratio`` of the best).  So with
        ``sibling_prune_log_ratio = inf``, ``gate_probability = 1`` and a cap that does
        not bite, a window's MAP track set is the unpruned one.  The refinement's
        windows prune at their own widths (``refine_prune_log_ratio``).
    k_prior : {"birth", "uniform", "poisson", "weights"}
        Prior p(K) on the number K of targets present in a window (detected or not),
        K = 0..Kmax; the reported p(K | Z) is the exact posterior under it
        (:mod:`mapassoc.estimator.posterior`).  ``"birth"`` (default): the law the birth model
        implies (Poisson for a window that starts the recording), no extra factor;
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
    solver : str
        Integer-program backend for clusters too large for the exact search (a name
        from ``mapassoc.solvers.available_solvers()``).
    time_limit : float
        Wall-clock seconds per window (hypothesis generation, solves and bounds
        together; a window past it reports ``status = "time_limit"`` with its best
        certified answer, and ``WindowSolution.timed_out``).  The outer guard: the work
        limits below (and ``max_hypotheses_per_tree``) bind first on ordinary windows.
        A window whose bounded path needs longer (those of the built-in ``parallel``
        scenario take several seconds) stops at the limit with an answer that depends
        on the machine's speed.  For results that are a function of the input alone
        (tests, comparisons, notebooks), set a limit no window reaches, 600 say: the
        deterministic work limits then bound every window.
    exact_work_limit : int
        Transitions the exact per-cluster frontier search may take before the cluster
        gets certified bounds instead (deterministic; about a microsecond each).
    beam_width : int
        Frontiers kept by the beam search that gives a cluster too large for the exact
        search its lower bounds on the mass per K.
    refine_passes : int
        Sweeps of the whole recording's refinement after the forward pass
        (:mod:`mapassoc.estimator.refinement`: window re-solves with both boundaries and
        fragment linking, each accepted only where the recording objective J rises):
        windows of ``window_length`` scans, then of twice that, then of single scans,
        forward, then all three backward; 0 turns it off and gives the forward pass's
        tracks.
    refine_link_gap : int
        Most scans between one track's last detection and another's first for the
        refinement to try joining them (0: no fragment linking).
    refine_prune_log_ratio : float
        ``prune_log_ratio`` of the refinement's re-solved short windows (sibling and
        new-tree pruning of their trees, and the joins to one anchor; >= 0, ``inf``
        disables); its long windows are pruned at ``prune_log_ratio``.
        Wider than the forward pass's by default: a re-solve must see alternatives the
        forward pass dropped (``mapassoc bench-refinement``, 2 seeds: twice the width
        takes parallel lanes from 4.6x to 2.2x the oracle's GOSPA, converging targets
        from 6.0x to 4.8x, dense_radar from 2.2x to 1.75x, for 1.1-1.9x the
        refinement's time).
    min_existence : float
        After the refinement, report only the tracks whose existence probability
        (:meth:`mapassoc.estimator.refinement.Refiner.confidence`) is at least this, in
        [0, 1]; 0 reports every track of the refined set.
    """

    window_length: int = 5
    stride: int = 1
    max_tracks: int = 20
    gate_probability: float = 0.999
    max_hypotheses_per_tree: int = 64
    prune_log_ratio: float = 9.0
    sibling_prune_log_ratio: float | None = None
    k_prior: str = "birth"
    k_prior_mean: float = 5.0
    k_prior_weights: tuple[float, ...] = field(default_factory=tuple)
    k_estimate: str = "marginal"
    solver: str = "highs"
    time_limit: float = 2.0
    exact_work_limit: int = 500_000
    beam_width: int = 200
    refine_passes: int = 6
    refine_link_gap: int = 10
    refine_prune_log_ratio: float = 18.0
    min_existence: float = 0.0

    def __post_init__(self) -> None:
        _set_int(self, "window_length", minimum=1)
        _set_int(self, "stride", minimum=1)
        if self.stride > self.window_length:
            raise InputError(
                f"stride must be <= window_length ({self.window_length}), got {self.stride}",
                key="stride",
            )
        _set_int(self, "max_tracks", minimum=0)
        check_probability(
            "gate_probability", self.gate_probability, allow_zero=False, key="gate_probability"
        )
        _set_int(self, "max_hypotheses_per_tree", minimum=1)
        for name in ("prune_log_ratio", "sibling_prune_log_ratio", "refine_prune_log_ratio"):
            value = getattr(self, name)
            if value is None and name == "sibling_prune_log_ratio":
                continue
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and value >= 0):
                raise InputError(
                    f"{name} must be a number >= 0 (inf disables), got {value!r}", key=name
                )
        object.__setattr__(self, "k_prior_weights", check_weights(self.k_prior_weights))
        self.count_prior()  # validates k_prior, k_prior_mean and k_prior_weights
        if self.k_estimate not in K_ESTIMATES:
            raise InputError(
                f"k_estimate must be one of {K_ESTIMATES}, got {self.k_estimate!r}",
                key="k_estimate",
            )
        if not isinstance(self.solver, str) or not self.solver:
            raise InputError(f"solver must be a backend name, got {self.solver!r}", key="solver")
        check_positive("time_limit", self.time_limit, key="time_limit")
        _set_int(self, "exact_work_limit", minimum=1)
        _set_int(self, "beam_width", minimum=1)
        _set_int(self, "refine_passes", minimum=0)
        _set_int(self, "refine_link_gap", minimum=0)
        check_probability("min_existence", self.min_existence, key="min_existence")

    @property
    def sibling_log_ratio(self) -> float:
        """The sibling rule's width: ``sibling_prune_log_ratio``, else ``prune_log_ratio``."""
        if self.sibling_prune_log_ratio is None:
            return float(self.prune_log_ratio)
        return float(self.sibling_prune_log_ratio)

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


_Settings = TypeVar("_Settings", BirthModel, EstimatorSettings)


def _to_json(value: object) -> object:
    return json_number(value) if isinstance(value, float) else value


def settings_to_json(settings: BirthModel | EstimatorSettings) -> dict[str, object]:
    """``{field: value}`` of a settings object, every value valid JSON.

    Tuples become lists and an infinite float (``prune_log_ratio = inf``) the string
    ``"inf"`` (:func:`mapassoc.log_space.json_number`), so that ``json.dumps(...,
    allow_nan=False)`` writes it and :func:`settings_from_json` reads back an equal
    object.
    """
    out: dict[str, object] = {}
    for name, value in dataclasses.asdict(settings).items():
        out[name] = [_to_json(v) for v in value] if isinstance(value, tuple) else _to_json(value)
    return out


def settings_from_json(cls: type[_Settings], record: Mapping[str, Any]) -> _Settings:
    """The settings object :func:`settings_to_json` wrote (``"inf"`` read as a float).

    Raises
    ------
    InputError
        A field the class does not have, a string where a number belongs, or a value
        the class's checks refuse.
    """
    kinds = {f.name: f.type for f in dataclasses.fields(cls)}
    unknown = sorted(set(record) - set(kinds))
    if unknown:
        raise InputError(f"{cls.__name__} has no fields {unknown}; got {dict(record)!r:.200}")
    values: dict[str, Any] = {}
    for name, value in record.items():
        try:
            if isinstance(value, list):
                values[name] = tuple(number_from_json(item) for item in value)
            elif isinstance(value, str) and kinds[name] not in ("str", str):
                values[name] = number_from_json(value)
            else:
                values[name] = value
        except ValueError as exc:
            raise InputError(f"{cls.__name__}.{name}: {exc}", key=name) from None
    return cls(**values)
