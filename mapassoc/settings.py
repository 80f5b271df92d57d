"""Settings of the window estimator: target birth and death, windows, K, solving.

Plain frozen dataclasses, validated on construction; every field error names the
field, the value and what was expected.  :mod:`mapassoc.config` builds them from a
TOML file (section and key names equal the field names).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from mapassoc.errors import InputError
from mapassoc.validation import check_nonnegative, check_positive, check_probability

__all__ = ["BirthModel", "EstimatorSettings", "K_PRIORS", "K_ESTIMATES"]

K_PRIORS = ("uniform", "poisson", "weights")
K_ESTIMATES = ("marginal", "joint")


def _check_int(name: str, value: object, *, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return value


@dataclass(frozen=True)
class BirthModel:
    """Where new tracks come from and how long tracks live.

    A new track starts at a detection.  First detections of new targets are Poisson
    with mean ``rate`` per scan, uniform over the sensor's surveillance region, so
    their density in a scan of a sensor with detection probability Pd and region
    volume V is ``rate * Pd / V`` (a target is taken to be born at its first
    detection).  The unmeasured state components start from zero mean with the
    standard deviations below (single-point initiation).  A track alive at time t
    is still alive at t + dt with probability ``survival_probability ** dt``.

    The targets already present when the recording starts are not births at a rate:
    ``initial_count`` (the expected number of targets present at the start, Poisson)
    adds to ``rate`` for detections in each sensor's first scan.

    Parameters
    ----------
    rate : float
        Expected number of new targets per scan, >= 0 (0: no target appears after the
        start, Perry's fixed population over a window; then only ``initial_count`` starts
        tracks, in each sensor's first scan).
    initial_count : float
        Expected number of targets present at the start of the data, >= 0 (their first
        detections are expected in each sensor's first scan).
    velocity_std : float
        Prior standard deviation of each velocity component at birth (Cartesian
        models), > 0.
    acceleration_std : float
        Prior standard deviation of each acceleration component at birth (constant
        acceleration model), > 0.
    speed_std : float
        Prior standard deviation of the speed at birth (coordinated turn), > 0.
    turn_rate_std : float
        Prior standard deviation of the turn rate at birth (coordinated turn), > 0.
    survival_probability : float
        Probability that a track survives one unit of time, in (0, 1].
    """

    rate: float = 0.1
    initial_count: float = 0.0
    velocity_std: float = 10.0
    acceleration_std: float = 1.0
    speed_std: float = 10.0
    turn_rate_std: float = 0.1
    survival_probability: float = 0.99

    def __post_init__(self) -> None:
        check_nonnegative("birth rate", self.rate)
        check_nonnegative("birth initial_count", self.initial_count)
        check_positive("birth velocity_std", self.velocity_std)
        check_positive("birth acceleration_std", self.acceleration_std)
        check_positive("birth speed_std", self.speed_std)
        check_positive("birth turn_rate_std", self.turn_rate_std)
        check_probability(
            "birth survival_probability", self.survival_probability, allow_zero=False
        )


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
        Kmax: the window is solved for every K = 0..Kmax.
    gate_probability : float
        Chi-square gate probability P_G in (0, 1]; 1 disables gating (every detection
        of a scan may continue every track), which only small problems can afford.
    max_hypotheses_per_tree : int
        Cap on the leaves kept per track tree (best scores kept), >= 1.
    prune_log_ratio : float
        Nodes scoring more than this below the best node of their tree are pruned; a new
        tree's node is also pruned when even the most its path can still gain over the
        window leaves it more than this below 0 (not selecting the tree); clusters drop
        hypotheses whose LP bound is this far below the cluster's best set (>= 0;
        ``inf`` disables all three).
    k_prior : {"uniform", "poisson", "weights"}
        Prior p(K) on 0..Kmax (seed 002 uses uniform).
    k_prior_mean : float
        Mean of the Poisson prior (used when ``k_prior == "poisson"``).
    k_prior_weights : tuple of float
        Unnormalised p(K) for K = 0..Kmax (used when ``k_prior == "weights"``).
    k_estimate : {"marginal", "joint"}
        Which K the committed track set uses: ``argmax p(K | Z)`` (marginal, default) or
        the K of the joint MAP (K, track set) (seed 002, eq. 14).
    solver : str
        Integer-program backend for clusters too large for the exact search (a name
        from ``mapassoc.solvers.available_solvers()``).
    time_limit : float
        Wall-clock seconds per window (hypothesis generation, solves and bounds
        together; a window past it reports ``status = "time_limit"`` with its best
        certified answer).  The outer guard: the work limits below bind first on
        ordinary windows, so results do not depend on the machine's speed.
    exact_work_limit : int
        Transitions the exact per-cluster frontier search may take before the cluster
        gets certified bounds instead (deterministic; about a microsecond each).
    beam_width : int
        Frontiers kept by the beam search that gives a cluster too large for the exact
        search its lower bounds on the mass per K.
    """

    window_length: int = 5
    stride: int = 1
    max_tracks: int = 20
    gate_probability: float = 0.999
    max_hypotheses_per_tree: int = 64
    prune_log_ratio: float = 9.0
    k_prior: str = "uniform"
    k_prior_mean: float = 5.0
    k_prior_weights: tuple[float, ...] = field(default_factory=tuple)
    k_estimate: str = "marginal"
    solver: str = "highs"
    time_limit: float = 2.0
    exact_work_limit: int = 500_000
    beam_width: int = 200

    def __post_init__(self) -> None:
        _check_int("window_length", self.window_length, minimum=1)
        _check_int("stride", self.stride, minimum=1)
        if self.stride > self.window_length:
            raise InputError(
                f"stride must be <= window_length ({self.window_length}), got {self.stride}"
            )
        _check_int("max_tracks", self.max_tracks, minimum=0)
        check_probability("gate_probability", self.gate_probability, allow_zero=False)
        _check_int("max_hypotheses_per_tree", self.max_hypotheses_per_tree, minimum=1)
        if not (isinstance(self.prune_log_ratio, (int, float)) and self.prune_log_ratio >= 0):
            raise InputError(
                f"prune_log_ratio must be a number >= 0 (inf disables), got "
                f"{self.prune_log_ratio!r}"
            )
        if self.k_prior not in K_PRIORS:
            raise InputError(f"k_prior must be one of {K_PRIORS}, got {self.k_prior!r}")
        check_positive("k_prior_mean", self.k_prior_mean)
        if self.k_prior == "weights":
            w = tuple(self.k_prior_weights)
            if len(w) != self.max_tracks + 1:
                raise InputError(
                    f"k_prior_weights must have max_tracks + 1 = {self.max_tracks + 1} "
                    f"entries, got {len(w)}"
                )
            for i, v in enumerate(w):
                check_nonnegative(f"k_prior_weights[{i}]", v)
            if not any(v > 0 for v in w):
                raise InputError("k_prior_weights must have at least one positive entry")
        if self.k_estimate not in K_ESTIMATES:
            raise InputError(f"k_estimate must be one of {K_ESTIMATES}, got {self.k_estimate!r}")
        if not isinstance(self.solver, str) or not self.solver:
            raise InputError(f"solver must be a backend name, got {self.solver!r}")
        check_positive("time_limit", self.time_limit)
        _check_int("exact_work_limit", self.exact_work_limit, minimum=1)
        _check_int("beam_width", self.beam_width, minimum=1)

    def log_k_prior(self) -> list[float]:
        """log p(K) for K = 0..Kmax, normalised (``-inf`` where p(K) = 0)."""
        kmax = self.max_tracks
        if self.k_prior == "uniform":
            return [-math.log(kmax + 1)] * (kmax + 1)
        if self.k_prior == "poisson":
            mu = self.k_prior_mean
            raw = [k * math.log(mu) - mu - math.lgamma(k + 1) for k in range(kmax + 1)]
        else:
            raw = [math.log(v) if v > 0 else -math.inf for v in self.k_prior_weights]
        top = max(raw)
        norm = top + math.log(sum(math.exp(r - top) for r in raw))
        return [r - norm for r in raw]
