"""``mapassoc bench``: speed and accuracy over scenario families, seeds and priors on K.

For every family (a built-in scenario, :mod:`mapassoc.evaluation.scenarios`), every prior on the
number of targets in ``k_priors`` (``EstimatorSettings.k_prior``; default ``birth`` and
``uniform``) and every seed ``0..seeds-1`` the benchmark simulates the scenario, runs
the window estimator and reports

* throughput (scans per second of :meth:`~mapassoc.estimator.pipeline.WindowEstimator.run`) and
  window time (hypothesis generation plus solving) p50 / p95 / max, with the number of
  windows that took longer than the time limit;
* mean hypotheses and the largest cluster per window;
* the mix of window statuses (counted as the pipeline names them, whatever they are)
  and the smallest ``captured_mass``;
* GOSPA (cut-off :data:`GOSPA_CUTOFF` position-noise standard deviations, with the
  localisation / missed / false parts of GOSPA^2) next to the oracle's (Kalman smoother
  on the true associations) and their ratio;
* identity: P-GOSPA (Xia, García-Fernández, Karlsson, Yuan, Chang and Svensson,
  "Probabilistic GOSPA"), which also scores the existence probabilities the estimate
  reports; T-GOSPA of the trajectories (c = gamma = :data:`GOSPA_CUTOFF`, p = 2) next to
  the oracle's and their ratio; the fragments (track ids) per tracked target and the
  identity switches of its assignment; and the track ids per true target;
* how well p(K | Z) (``WindowReport.p_k``) predicts the true number K of
  targets in each window, i.e. the distinct truth targets with a truth record at a time
  in ``[start_time, end_time]`` of the window (:func:`window_target_counts`): the Brier
  score ``sum_K (p(K | Z) - 1[K = true K])^2`` (0 is a certain right answer, 2 a
  certain wrong one, ``1 - 1 / (Kmax + 1)`` the uniform guess), the fraction of windows
  whose ``marginal_k`` is the true K and the mean p(true K | Z), each averaged over
  windows (:func:`count_scores`).

Then, per family and prior, the mean GOSPA ratio over seeds with its spread, the mean
Brier score and hit rate, the mean fragments per target, identity switches, T-GOSPA
ratio and P-GOSPA over the oracle's GOSPA, and the mean throughput; how time per scan grows over the
``scale20 -> scale50 -> scale100`` family (fixed density, so linear in targets is the
goal); the throughput of batched gating; the goals (speed, GOSPA, time limit and growth
are judged on the first prior of ``k_priors`` only, so that no run is counted twice);
and a comparison of the priors: per family the mean GOSPA ratio and Brier score of each,
and which prior has the lower of each averaged over the families.  Numbers, not
pass/fail: the project's goals are printed beside them.

By default every family runs with the same untuned configuration,
:func:`mapassoc.evaluation.scenarios.generic_config`; ``config="scenario"`` uses each scenario's
own configuration (fitted to its truth) instead.  Either way only ``k_prior`` is set by
the benchmark (``"poisson"`` keeps the configuration's ``k_prior_mean``; ``"weights"``
needs weights per configuration and is not offered).  ``parameters=("auto",)`` estimates
every model parameter from the recording before each run instead of giving the
configuration's (:mod:`mapassoc.apps.bench_auto`), and prints the estimates beside the
truth under the run's line; with ``("given", "auto")`` every run is made both ways and
each family's summary adds the ``"auto"`` GOSPA over the given values' with the
estimates' errors, beside their goals.  Lines are printed (and flushed) as
soon as each run finishes: the whole benchmark can take minutes per prior.
"""

from __future__ import annotations

import math
import sys
import time
import warnings
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from mapassoc.apps.bench_auto import (
    AutoSummary,
    EstimatedValue,
    auto_config,
    auto_goals_text,
    auto_summary_line,
    check_parameter_choice,
    check_parameter_choices,
    estimates_line,
    run_auto,
    summarize_auto,
)
from mapassoc.apps.bench_defaults import DEFAULT_FAMILIES, DEFAULT_K_PRIORS
from mapassoc.apps.run_folders import write_json
from mapassoc.data.config import Config
from mapassoc.data.settings import K_PRIORS
from mapassoc.errors import InputError
from mapassoc.estimator.pipeline import EstimateResult, WindowEstimator, WindowReport
from mapassoc.evaluation.calibration import count_scores, window_target_counts
from mapassoc.evaluation.metrics import GospaSeries
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import (
    build_scenario,
    generic_config,
    length_unit,
    scenario_names,
    truncate_scenario,
)
from mapassoc.evaluation.tables import evaluate_tables, pgospa_tables
from mapassoc.filtering.kalman import pairwise_gate_and_loglik
from mapassoc.models.interacting import noise_levels
from mapassoc.validation import check_integer

if TYPE_CHECKING:
    from mapassoc.data.io import TrackTable
    from mapassoc.evaluation.simulate import Scenario

__all__ = [
    "DEFAULT_FAMILIES",
    "DEFAULT_K_PRIORS",
    "BENCH_K_PRIORS",
    "CONFIG_CHOICES",
    "GOSPA_CUTOFF",
    "GOSPA_RATIO_GOAL",
    "SPEED_GOALS",
    "SCALE_FAMILIES",
    "GospaParts",
    "RunResult",
    "FamilySummary",
    "ScaleGrowth",
    "BenchmarkResult",
    "bench_scenario",
    "summarize_family",
    "scale_growth",
    "run_benchmark",
    "bench_gating",
]

#: Priors on the number of targets in a window (``EstimatorSettings.k_prior``) the
#: benchmark can compare: every prior of :data:`mapassoc.data.settings.K_PRIORS` but
#: ``"weights"``, which needs weights fitted to each configuration's Kmax.
BENCH_K_PRIORS: tuple[str, ...] = tuple(name for name in K_PRIORS if name != "weights")
#: ``generic``: :func:`~mapassoc.evaluation.scenarios.generic_config`; ``scenario``: each
#: scenario's own configuration.
CONFIG_CHOICES: tuple[str, ...] = ("generic", "scenario")
#: GOSPA cut-off c and T-GOSPA's switch cost, in position-noise standard deviations
#: (:func:`~mapassoc.evaluation.scenarios.length_unit` of the scenario: 10 in the native
#: families, 10 x 50 m in ``aircraft``).
GOSPA_CUTOFF = 10.0
#: Goal: mean GOSPA over seeds at most this many times the oracle's.
GOSPA_RATIO_GOAL = 1.2
#: Goals: scans per second (mean over seeds) at window length 5.
SPEED_GOALS: dict[str, float] = {
    "crossing": 150.0,
    "parallel": 20.0,
    "dense_pd08": 20.0,
    "scale100": 2.0,
}
#: The fixed-density family whose time per scan should grow at most linearly in targets.
SCALE_FAMILIES: tuple[str, ...] = ("scale20", "scale50", "scale100")


# --------------------------------------------------------------------------- results


@dataclass(frozen=True)
class GospaParts:
    """Time-averaged GOSPA and its parts (α = 2, p = 2).

    Parameters
    ----------
    total : float
        Mean GOSPA over time (``mean_total``).
    localisation, missed, false : float
        Means over time of the localisation, missed-target and false-track parts of
        GOSPA^p (:class:`mapassoc.evaluation.metrics.GospaSeries`): they add up to the mean of
        GOSPA^2, not of GOSPA.
    """

    total: float
    localisation: float
    missed: float
    false: float

    @classmethod
    def from_series(cls, series: GospaSeries) -> GospaParts:
        """The means of a GOSPA series (from :func:`~.tables.evaluate_tables`)."""
        return cls(
            total=series.mean_total,
            localisation=series.mean_localisation,
            missed=series.mean_missed,
            false=series.mean_false,
        )


@dataclass(frozen=True)
class RunResult:
    """One family run with one prior on K and one seed.

    Parameters
    ----------
    family : str
        Scenario name.
    seed : int
    config : {"generic", "scenario"}
        Which configuration was used.
    k_prior : str
        ``EstimatorSettings.k_prior`` of the run (one of :data:`BENCH_K_PRIORS`).
    targets : int
        Distinct targets in the (possibly truncated) truth.
    scans : int
        Scans processed.
    detections_per_scan : float
        Mean detections per scan.
    max_detections : int
        Most detections in one scan.
    window_length : int
    time_limit : float
        ``EstimatorSettings.time_limit`` (seconds); also the per-window budget counted in
        ``windows_over_limit``.
    max_tracks : int
        Kmax of the configuration.
    seconds : float
        Wall time of the estimator run (simulation and evaluation excluded).
    scans_per_second, seconds_per_scan : float
    window_p50_ms, window_p95_ms, window_max_ms : float
        Window time (``generate_seconds + solve_seconds``) percentiles and maximum.
    windows : int
    windows_over_limit : int
        Windows whose time exceeded ``time_limit``.
    hypotheses_mean : float
        Mean hypotheses kept per window.
    hypotheses_max : int
    largest_cluster : int
        Largest cluster (hypotheses) of any window.
    status_counts : tuple of (str, int)
        Windows per ``WindowReport.status``, most frequent first.
    min_captured_mass : float
        Smallest ``captured_mass`` of any window.
    tracks : int
        Tracks reported.
    gospa, oracle_gospa : GospaParts
        Of the estimate and of the oracle.
    gospa_ratio : float
        ``gospa.total / oracle_gospa.total`` (``inf`` if only the oracle is perfect, 1 if
        both are).
    k_brier : float
        Mean Brier score of p(K | Z) over the windows (:class:`CountScores`), in [0, 2].
    k_hit_rate : float
        Fraction of windows whose ``marginal_k`` is the true number of targets.
    k_mean_p_true : float
        Mean over windows of p(true K | Z).
    tgospa, oracle_tgospa : float or None
        T-GOSPA of the estimate's and of the oracle's trajectories (c = gamma =
        ``GOSPA_CUTOFF``, p = 2; :mod:`mapassoc.evaluation.tgospa`).  ``None`` for runs
        built without it.
    fragments_per_target : float or None
        Mean track ids per tracked true target in the estimate's T-GOSPA assignment.
    tgospa_id_switches : int or None
        Track-id changes of a target between consecutive scans in that assignment.
    forward_scans_per_second : float or None
        Scans per second of the forward pass alone (the windows, up to the last one's
        commit; ``scans_per_second`` adds the whole recording's refinement and the
        smoothing).  ``None`` for runs built without it.
    tgospa_ratio : float or None
        ``tgospa / oracle_tgospa`` (``inf`` if only the oracle is perfect, 1 if both are);
        ``None`` without T-GOSPA.
    pgospa : float or None
        Mean over time of P-GOSPA (c = ``GOSPA_CUTOFF``, p = 2,
        :func:`mapassoc.evaluation.tables.pgospa_tables`) of the estimate with the
        existence probabilities it reports (1 where it reports none).  The oracle reports
        none, so its P-GOSPA is its GOSPA, ``oracle_gospa.total``.  ``None`` for runs
        built without it.
    parameters : {"given", "auto"}
        Whether the run was given the configuration's values or estimated them first
        (:mod:`mapassoc.apps.bench_auto`; its ``seconds`` then include the estimation).
    estimates : tuple of EstimatedValue or None
        With ``"auto"``: the estimates beside the truth (the scenario's configuration).
    """

    family: str
    seed: int
    config: str
    k_prior: str
    targets: int
    scans: int
    detections_per_scan: float
    max_detections: int
    window_length: int
    time_limit: float
    max_tracks: int
    seconds: float
    scans_per_second: float
    seconds_per_scan: float
    window_p50_ms: float
    window_p95_ms: float
    window_max_ms: float
    windows: int
    windows_over_limit: int
    hypotheses_mean: float
    hypotheses_max: int
    largest_cluster: int
    status_counts: tuple[tuple[str, int], ...]
    min_captured_mass: float
    tracks: int
    gospa: GospaParts
    oracle_gospa: GospaParts
    gospa_ratio: float
    k_brier: float
    k_hit_rate: float
    k_mean_p_true: float
    tgospa: float | None = None
    oracle_tgospa: float | None = None
    fragments_per_target: float | None = None
    tgospa_id_switches: int | None = None
    forward_scans_per_second: float | None = None
    tgospa_ratio: float | None = None
    pgospa: float | None = None
    parameters: str = "given"
    estimates: tuple[EstimatedValue, ...] | None = None

    @property
    def ids_per_target(self) -> float:
        """Track ids reported per true target (``tracks / targets``; 1 is ideal)."""
        return self.tracks / self.targets if self.targets else math.nan


@dataclass(frozen=True)
class FamilySummary:
    """One family with one prior on K over its seeds.

    Parameters
    ----------
    family : str
    k_prior : str
        ``EstimatorSettings.k_prior`` of the runs.
    seeds : tuple of int
    targets : int
        Most distinct targets of any seed's run.
    scans_per_second : float
        Mean over seeds.
    seconds_per_scan : float
        Mean over seeds.
    gospa_ratio_mean, gospa_ratio_min, gospa_ratio_max : float
        GOSPA ratio to the oracle: mean over seeds and spread.
    window_max_ms : float
        Slowest window of any seed.
    windows, windows_over_limit : int
        Totals over seeds.
    status_counts : tuple of (str, int)
        Totals over seeds, most frequent first.
    min_captured_mass : float
    k_brier_mean : float
        Mean over seeds of the runs' mean Brier score of p(K | Z).
    k_hit_rate_mean : float
        Mean over seeds of the runs' fraction of windows with ``marginal_k`` right.
    speed_goal : float or None
        Scans-per-second goal of the family (:data:`SPEED_GOALS`), if any.
    forward_scans_per_second : float or None
        Mean over seeds of the forward pass's own throughput (``None`` when a run
        lacks it).
    fragments_per_target_mean, id_switches_mean, tgospa_ratio_mean : float or None
        Means over seeds of the runs' fragments per tracked target, T-GOSPA identity
        switches and T-GOSPA ratio to the oracle (``None`` when a run lacks them).
    pgospa_ratio_mean : float or None
        Mean over seeds of the run's P-GOSPA over the oracle's GOSPA (the oracle's
        P-GOSPA: it reports no existence); ``None`` when a run lacks P-GOSPA.
    parameters : {"given", "auto"}
        ``RunResult.parameters`` of the runs.
    """

    family: str
    k_prior: str
    seeds: tuple[int, ...]
    targets: int
    scans_per_second: float
    seconds_per_scan: float
    gospa_ratio_mean: float
    gospa_ratio_min: float
    gospa_ratio_max: float
    window_max_ms: float
    windows: int
    windows_over_limit: int
    status_counts: tuple[tuple[str, int], ...]
    min_captured_mass: float
    k_brier_mean: float
    k_hit_rate_mean: float
    speed_goal: float | None
    forward_scans_per_second: float | None = None
    fragments_per_target_mean: float | None = None
    id_switches_mean: float | None = None
    tgospa_ratio_mean: float | None = None
    pgospa_ratio_mean: float | None = None
    parameters: str = "given"

    @property
    def speed_met(self) -> bool | None:
        """Whether the throughput goal is met (``None`` without a goal)."""
        if self.speed_goal is None:
            return None
        return self.scans_per_second >= self.speed_goal

    @property
    def gospa_met(self) -> bool:
        """Whether the mean GOSPA ratio is at most :data:`GOSPA_RATIO_GOAL`."""
        return self.gospa_ratio_mean <= GOSPA_RATIO_GOAL

    @property
    def time_limit_met(self) -> bool:
        """Whether every window finished within the time limit."""
        return self.windows_over_limit == 0


@dataclass(frozen=True)
class ScaleGrowth:
    """How time per scan grows with targets over the fixed-density scale family.

    Parameters
    ----------
    families : tuple of str
        The scale families run, by increasing targets.
    targets : tuple of int
    seconds_per_scan : tuple of float
        Mean over seeds.
    exponent : float
        Least-squares slope of log(time per scan) on log(targets): 1 is linear.
    """

    families: tuple[str, ...]
    targets: tuple[int, ...]
    seconds_per_scan: tuple[float, ...]
    exponent: float

    @property
    def linear_or_better(self) -> bool:
        """``exponent <= 1``."""
        return self.exponent <= 1.0


@dataclass(frozen=True)
class BenchmarkResult:
    """Everything :func:`run_benchmark` measured.

    Parameters
    ----------
    settings : dict
        The benchmark's arguments.
    runs : tuple of RunResult
        Family by family, prior by prior (in the order of ``k_priors``), parameters by
        parameters (in the order of ``parameters``), seed by seed.
    families : tuple of FamilySummary
        One per (family, prior, parameters), in the order of the runs.
    growth : ScaleGrowth or None
        ``None`` unless at least two scale families ran; from the runs with the first
        prior of ``k_priors`` and the first of ``parameters``.
    gating_pairs_per_second : float
    auto : tuple of AutoSummary
        One per (family, prior) with ``"auto"`` runs: their GOSPA over the given
        values' runs and their estimates' errors (:func:`~.bench_auto.summarize_auto`).
    """

    settings: dict[str, object]
    runs: tuple[RunResult, ...]
    families: tuple[FamilySummary, ...]
    growth: ScaleGrowth | None
    gating_pairs_per_second: float
    auto: tuple[AutoSummary, ...] = ()

    def to_json(self) -> dict[str, object]:
        """A JSON-ready dictionary; non-finite numbers become ``None``."""
        data = {
            "settings": self.settings,
            "runs": [asdict(run) for run in self.runs],
            "families": [
                {
                    **asdict(summary),
                    "speed_met": summary.speed_met,
                    "gospa_met": summary.gospa_met,
                    "time_limit_met": summary.time_limit_met,
                }
                for summary in self.families
            ],
            "growth": None
            if self.growth is None
            else {**asdict(self.growth), "linear_or_better": self.growth.linear_or_better},
            "gating_pairs_per_second": self.gating_pairs_per_second,
            "auto": [
                {**asdict(summary), "gospa_met": summary.gospa_met,
                 "estimates_met": summary.estimates_met}
                for summary in self.auto
            ],
        }  # fmt: skip
        return _finite(data)  # type: ignore[return-value]


def _finite(value: object) -> object:
    """``value`` with tuples as lists, status pairs as dicts and non-finite floats as None."""
    if isinstance(value, dict):
        return {
            key: dict(item) if key == "status_counts" else _finite(item)
            for key, item in value.items()
        }
    if isinstance(value, (list, tuple)):
        return [_finite(item) for item in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


# --------------------------------------------------------------------------- checks


def _check_time_limit(value: object) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value <= 0
    ):
        raise InputError(f"time_limit must be a finite number of seconds > 0, got {value!r}")
    return float(value)


BENCH_MOTIONS = ("configured", "imm")
"""Motion models a benchmark run can use (the ``motion`` of :func:`bench_scenario`)."""


def _check_motion_choice(value: object) -> str:
    if value not in BENCH_MOTIONS:
        raise InputError(f"motion must be one of {', '.join(BENCH_MOTIONS)}, got {value!r}")
    return str(value)


def _check_config_choice(value: object) -> str:
    if value not in CONFIG_CHOICES:
        raise InputError(f"config must be one of {', '.join(CONFIG_CHOICES)}, got {value!r}")
    return str(value)


def _check_families(families: Sequence[str]) -> list[str]:
    names = list(families)
    if not names:
        raise InputError("families must name at least one scenario")
    known = scenario_names()
    unknown = [name for name in names if name not in known]
    if unknown:
        raise InputError(
            f"families has unknown scenario(s) {', '.join(map(repr, unknown))}; expected names "
            f"from {', '.join(known)}"
        )
    if len(set(names)) != len(names):
        raise InputError(f"families must be distinct, got {names!r}")
    return names


def _check_k_prior(name: str, value: object) -> str:
    """``value`` if it is a prior the benchmark can run (:data:`BENCH_K_PRIORS`)."""
    if isinstance(value, str) and value == "weights":
        raise InputError(
            f"{name} cannot be 'weights' in the benchmark: that prior needs "
            "k_prior_weights fitted to each configuration's max_tracks; expected one of "
            f"{', '.join(BENCH_K_PRIORS)}"
        )
    if not isinstance(value, str) or value not in BENCH_K_PRIORS:
        raise InputError(f"{name} must be one of {', '.join(BENCH_K_PRIORS)}, got {value!r}")
    return value


def _check_k_priors(k_priors: Sequence[str]) -> list[str]:
    if isinstance(k_priors, str) or not isinstance(k_priors, Sequence):
        raise InputError(
            f"k_priors must be a sequence of prior names (e.g. ('birth', 'uniform')), got "
            f"{k_priors!r}"
        )
    names = [_check_k_prior(f"k_priors[{i}]", value) for i, value in enumerate(k_priors)]
    if not names:
        raise InputError(
            f"k_priors must name at least one prior of {', '.join(BENCH_K_PRIORS)}, got []"
        )
    if len(set(names)) != len(names):
        raise InputError(f"k_priors must be distinct, got {names!r}")
    return names


# --------------------------------------------------------------------------- p(K | Z)


# --------------------------------------------------------------------------- one run


def _ratio(estimate: float, oracle: float) -> float:
    if oracle > 0.0:
        return estimate / oracle
    return 1.0 if estimate <= 0.0 else math.inf


def _bench_config(base: Config, window_length: int | None, time_limit: float) -> Config:
    """The scenario's own configuration with the bench's window length and time limit."""
    estimator = base.estimator.with_time_limit(time_limit)
    if window_length is not None:
        estimator = estimator.with_window_length(window_length)
    return replace(base, estimator=estimator)


def bench_scenario(
    name: str,
    seed: int = 0,
    window_length: int | None = 5,
    *,
    time_limit: float = 2.0,
    config: str = "generic",
    scans: int | None = None,
    k_prior: str = "birth",
    motion: str = "configured",
    parameters: str = "given",
) -> RunResult:
    """Simulate one family with one seed, estimate, and measure speed, GOSPA and p(K | Z).

    Parameters
    ----------
    name : str
        Scenario name (:func:`mapassoc.evaluation.scenarios.scenario_names`).
    seed : int
        Seed of the realisation.
    window_length : int or None
        Scans per window; ``None`` keeps the configuration's (the default of
        :class:`~mapassoc.data.settings.EstimatorSettings` for ``config="generic"``).
    time_limit : float
        ``EstimatorSettings.time_limit`` in seconds, also the budget a window's time is
        compared with.
    config : {"generic", "scenario"}
        :func:`~mapassoc.evaluation.scenarios.generic_config` of the (truncated) scenario, or the
        scenario's own configuration.
    scans : int, optional
        Keep only the first ``scans`` scans
        (:func:`~mapassoc.evaluation.scenarios.truncate_scenario`),
        for quick checks.
    k_prior : {"birth", "uniform", "poisson"}
        ``EstimatorSettings.k_prior`` of the run, set on either configuration
        (``"poisson"`` uses its ``k_prior_mean``).  ``"weights"`` is refused: the
        benchmark has no weights to give it.
    motion : {"configured", "imm"}
        The configuration's motion model, or a set of it at two process-noise levels
        (:func:`~mapassoc.models.interacting.noise_levels`, its defaults).
    parameters : {"given", "auto"}
        ``"auto"``: every sensor's false-alarm rate and ``Pd``, every position sensor's
        ``noise_std`` and the motion's ``noise_intensity`` (where the model has one
        scale) are estimated from the scenario's scans first, and the run uses the
        estimates (:func:`~mapassoc.apps.bench_auto.run_auto`; the seconds include the
        estimation).  With ``motion="imm"`` the set is built first and each of its
        models' ``noise_intensity`` is estimated.

    Returns
    -------
    RunResult

    Raises
    ------
    InputError
        An unknown scenario or a bad argument (checked before anything runs).
    """
    setup = _bench_setup(
        name, seed, window_length, time_limit, config, scans, k_prior, motion, parameters
    )
    timed = _timed_run(setup)
    return _run_result(name, seed, setup, timed)


@dataclass(frozen=True)
class _BenchSetup:
    """One benchmark run, checked and ready: the (truncated) scenario and its configuration.

    Attributes
    ----------
    scenario : Scenario
    config : Config
        With the run's window length, time limit and prior on K (with ``"auto"``
        parameters: their placeholders, :func:`~mapassoc.apps.bench_auto.auto_config`;
        with ``motion="imm"``: the set, with its models' placeholders where ``"auto"``).
    choice : {"generic", "scenario"}
    prior : str
    limit : float
        The time limit in seconds.
    motion : {"configured", "imm"}
    parameters : {"given", "auto"}
    """

    scenario: Scenario
    config: Config
    choice: str
    prior: str
    limit: float
    motion: str = "configured"
    parameters: str = "given"


def _bench_setup(
    name: str,
    seed: int,
    window_length: int | None,
    time_limit: float,
    config: str,
    scans: int | None,
    k_prior: str,
    motion: str = "configured",
    parameters: str = "given",
) -> _BenchSetup:
    """Check the arguments of :func:`bench_scenario`, build the scenario and its config."""
    prior = _check_k_prior("k_prior", k_prior)
    choice = _check_config_choice(config)
    limit = _check_time_limit(time_limit)
    if window_length is not None:
        check_integer("window_length", window_length, minimum=1)
    motion, parameters = _check_motion_choice(motion), check_parameter_choice(parameters)
    scenario = build_scenario(name, seed)
    if scans is not None:
        scenario = truncate_scenario(scenario, check_integer("scans", scans, minimum=1))
    if choice == "generic":
        run_config = generic_config(scenario, window_length=window_length, time_limit=limit)
    else:
        run_config = _bench_config(scenario.config, window_length, limit)
    count = replace(run_config.estimator.count, k_prior=prior)
    run_config = replace(run_config, estimator=replace(run_config.estimator, count=count))
    if motion == "imm":  # before "auto": the set's components are estimated
        run_config = replace(run_config, motion=noise_levels(run_config.motion))
    if parameters == "auto":
        run_config = auto_config(run_config)
    return _BenchSetup(scenario, run_config, choice, prior, limit, motion, parameters)


@dataclass(frozen=True)
class _TimedRun:
    """The estimator's result with its wall time, whole and up to the last window's commit
    (with ``"auto"`` parameters, the estimation included), and the estimates."""

    result: EstimateResult
    seconds: float
    forward_seconds: float
    estimates: tuple[EstimatedValue, ...] | None = None


def _timed_run(setup: _BenchSetup) -> _TimedRun:
    """Run the window estimator on the scenario, timing the run and its forward pass
    (with ``"auto"`` parameters: estimate them first, :func:`~.bench_auto.run_auto`)."""
    if setup.parameters == "auto":
        scenario = setup.scenario
        auto = run_auto(setup.config, scenario.scans, scenario.config)
        return _TimedRun(auto.result, auto.seconds, auto.forward_seconds, auto.values)
    estimator = WindowEstimator(config=setup.config)
    committed = [0.0]  # when the last window was committed: the forward pass's end

    def on_window(report: object) -> None:
        committed[0] = time.perf_counter()

    start = time.perf_counter()
    result = estimator.run(setup.scenario.scans, on_window=on_window)
    seconds = time.perf_counter() - start
    return _TimedRun(result, seconds, committed[0] - start)


@dataclass(frozen=True)
class _WindowStats:
    """What a run's window reports add up to (see :class:`RunResult`)."""

    p50_ms: float
    p95_ms: float
    max_ms: float
    windows: int
    over_limit: int
    hypotheses_mean: float
    hypotheses_max: int
    largest_cluster: int
    status_counts: tuple[tuple[str, int], ...]
    min_captured_mass: float


def _window_stats(windows: Sequence[WindowReport], limit: float) -> _WindowStats:
    """Window time percentiles, windows over ``limit``, hypotheses, clusters and statuses."""
    window_seconds = np.array([w.generate_seconds + w.solve_seconds for w in windows])
    statuses = Counter(str(w.status) for w in windows)
    return _WindowStats(
        p50_ms=float(np.percentile(window_seconds, 50) * 1e3),
        p95_ms=float(np.percentile(window_seconds, 95) * 1e3),
        max_ms=float(window_seconds.max() * 1e3),
        windows=len(windows),
        over_limit=int(np.sum(window_seconds > limit)),
        hypotheses_mean=float(np.mean([w.hypotheses_kept for w in windows])),
        hypotheses_max=int(max(w.hypotheses_kept for w in windows)),
        largest_cluster=int(max(w.largest_cluster for w in windows)),
        status_counts=_ordered(statuses),
        min_captured_mass=float(min(w.captured_mass for w in windows)),
    )


@dataclass(frozen=True)
class _Accuracy:
    """GOSPA and T-GOSPA of the estimate and of the oracle, and the estimate's fragments."""

    gospa: GospaParts
    oracle_gospa: GospaParts
    tgospa: float | None
    oracle_tgospa: float | None
    fragments_per_target: float | None
    id_switches: int | None
    pgospa: float


def _accuracy(scenario: Scenario, tracks: TrackTable) -> _Accuracy:
    """The estimate's ``tracks`` and the oracle's scored against the scenario's truth."""
    c = GOSPA_CUTOFF * length_unit(scenario.config)
    estimate = evaluate_tables(scenario.truth, tracks, c=c, switch_cost=c)
    oracle = evaluate_tables(
        scenario.truth,
        oracle_tracks(scenario.scans, scenario.origins, scenario.config),
        c=c,
        switch_cost=c,
    )
    trajectory, oracle_trajectory = estimate.tgospa, oracle.tgospa
    fragmentation = estimate.fragmentation
    with warnings.catch_warnings():
        # evaluate_tables has warned about these tables already.
        warnings.simplefilter("ignore", UserWarning)
        probabilistic = pgospa_tables(scenario.truth, tracks, c=c)
    return _Accuracy(
        gospa=GospaParts.from_series(estimate.gospa),
        oracle_gospa=GospaParts.from_series(oracle.gospa),
        tgospa=None if trajectory is None else trajectory.total,
        oracle_tgospa=None if oracle_trajectory is None else oracle_trajectory.total,
        fragments_per_target=None if fragmentation is None else fragmentation.fragments_per_target,
        id_switches=None if fragmentation is None else fragmentation.num_id_switches,
        pgospa=probabilistic.mean_total,
    )


def _run_result(name: str, seed: int, setup: _BenchSetup, timed: _TimedRun) -> RunResult:
    """The :class:`RunResult` of one timed run: speed, windows, accuracy and p(K | Z)."""
    scenario, windows = setup.scenario, timed.result.windows
    seconds, forward = timed.seconds, timed.forward_seconds
    stats = _window_stats(windows, setup.limit)
    accuracy = _accuracy(scenario, timed.result.tracks)
    counts = count_scores(windows, window_target_counts(scenario.truth, windows))
    sizes = [scan.size for scan in scenario.scans]
    n_scans = len(scenario.scans)
    return RunResult(
        family=name,
        seed=int(seed),
        config=setup.choice,
        k_prior=setup.prior,
        targets=len(np.unique(scenario.truth.target_ids)),
        scans=n_scans,
        detections_per_scan=float(np.mean(sizes)),
        max_detections=int(max(sizes)),
        window_length=setup.config.estimator.windows.window_length,
        time_limit=setup.limit,
        max_tracks=setup.config.estimator.count.max_tracks,
        seconds=seconds,
        scans_per_second=n_scans / seconds if seconds > 0 else math.inf,
        seconds_per_scan=seconds / n_scans,
        window_p50_ms=stats.p50_ms,
        window_p95_ms=stats.p95_ms,
        window_max_ms=stats.max_ms,
        windows=stats.windows,
        windows_over_limit=stats.over_limit,
        hypotheses_mean=stats.hypotheses_mean,
        hypotheses_max=stats.hypotheses_max,
        largest_cluster=stats.largest_cluster,
        status_counts=stats.status_counts,
        min_captured_mass=stats.min_captured_mass,
        tracks=len(timed.result.track_rows),
        gospa=accuracy.gospa,
        oracle_gospa=accuracy.oracle_gospa,
        gospa_ratio=_ratio(accuracy.gospa.total, accuracy.oracle_gospa.total),
        k_brier=counts.brier,
        k_hit_rate=counts.hit_rate,
        k_mean_p_true=counts.mean_p_true,
        tgospa=accuracy.tgospa,
        oracle_tgospa=accuracy.oracle_tgospa,
        fragments_per_target=accuracy.fragments_per_target,
        tgospa_id_switches=accuracy.id_switches,
        forward_scans_per_second=n_scans / forward if forward > 0 else math.inf,
        tgospa_ratio=None
        if accuracy.tgospa is None or accuracy.oracle_tgospa is None
        else _ratio(accuracy.tgospa, accuracy.oracle_tgospa),
        pgospa=accuracy.pgospa,
        parameters=setup.parameters,
        estimates=timed.estimates,
    )


def _ordered(counts: Counter[str]) -> tuple[tuple[str, int], ...]:
    """Counts most frequent first, ties by name."""
    return tuple(sorted(counts.items(), key=lambda item: (-item[1], item[0])))


# --------------------------------------------------------------------------- summaries


def summarize_family(runs: Sequence[RunResult]) -> FamilySummary:
    """Combine the runs of one family with one prior on K (and one ``parameters``) over
    its seeds.

    Raises
    ------
    InputError
        No runs, or runs of different families, priors or parameters.
    """
    runs = list(runs)
    if not runs:
        raise InputError("runs must contain at least one RunResult")
    families = {run.family for run in runs}
    if len(families) != 1:
        raise InputError(f"runs must all be of one family, got {sorted(families)}")
    priors = {run.k_prior for run in runs}
    if len(priors) != 1:
        raise InputError(f"runs must all be of one k_prior, got {sorted(priors)}")
    choices = {run.parameters for run in runs}
    if len(choices) != 1:
        raise InputError(f"runs must all be of one parameters choice, got {sorted(choices)}")
    family = runs[0].family
    ratios = np.array([run.gospa_ratio for run in runs])
    statuses: Counter[str] = Counter()
    for run in runs:
        statuses.update(dict(run.status_counts))
    return FamilySummary(
        family=family,
        k_prior=runs[0].k_prior,
        seeds=tuple(run.seed for run in runs),
        targets=max(run.targets for run in runs),
        scans_per_second=float(np.mean([run.scans_per_second for run in runs])),
        seconds_per_scan=float(np.mean([run.seconds_per_scan for run in runs])),
        gospa_ratio_mean=float(np.mean(ratios)),
        gospa_ratio_min=float(np.min(ratios)),
        gospa_ratio_max=float(np.max(ratios)),
        window_max_ms=max(run.window_max_ms for run in runs),
        windows=sum(run.windows for run in runs),
        windows_over_limit=sum(run.windows_over_limit for run in runs),
        status_counts=_ordered(statuses),
        min_captured_mass=min(run.min_captured_mass for run in runs),
        k_brier_mean=float(np.mean([run.k_brier for run in runs])),
        k_hit_rate_mean=float(np.mean([run.k_hit_rate for run in runs])),
        speed_goal=SPEED_GOALS.get(family),
        forward_scans_per_second=_mean_of([run.forward_scans_per_second for run in runs]),
        fragments_per_target_mean=_mean_of([run.fragments_per_target for run in runs]),
        id_switches_mean=_mean_of([run.tgospa_id_switches for run in runs]),
        tgospa_ratio_mean=_mean_of([run.tgospa_ratio for run in runs]),
        pgospa_ratio_mean=_mean_of(
            [
                None if run.pgospa is None else _ratio(run.pgospa, run.oracle_gospa.total)
                for run in runs
            ]
        ),
        parameters=runs[0].parameters,
    )


def _mean_of(values: Sequence[float | None]) -> float | None:
    """The mean of ``values``, or ``None`` when one is missing."""
    if any(value is None for value in values):
        return None
    return float(np.mean([float(value) for value in values if value is not None]))


def scale_growth(summaries: Sequence[FamilySummary]) -> ScaleGrowth | None:
    """Time per scan against targets over the scale families present (at least two).

    Raises
    ------
    InputError
        ``summaries`` of more than one ``k_prior`` (pass one prior's summaries).
    """
    priors = {summary.k_prior for summary in summaries}
    if len(priors) > 1:
        raise InputError(f"summaries must all be of one k_prior, got {sorted(priors)}")
    by_name = {summary.family: summary for summary in summaries}
    present = [by_name[name] for name in SCALE_FAMILIES if name in by_name]
    if len(present) < 2:
        return None
    targets = np.array([s.targets for s in present], dtype=float)
    seconds = np.array([s.seconds_per_scan for s in present])
    exponent = float(np.polyfit(np.log(targets), np.log(seconds), 1)[0])
    return ScaleGrowth(
        families=tuple(s.family for s in present),
        targets=tuple(s.targets for s in present),
        seconds_per_scan=tuple(float(t) for t in seconds),
        exponent=exponent,
    )


def bench_gating(tracks: int = 2000, detections: int = 50, repeats: int = 5) -> float:
    """(track, detection) pairs per second through batched gating + log-likelihood."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(tracks, 2, 2))
    S = A @ np.swapaxes(A, 1, 2) + np.eye(2)
    nu = rng.normal(size=(tracks, detections, 2))
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        pairwise_gate_and_loglik(nu, S)
        best = min(best, time.perf_counter() - t)
    return tracks * detections / best


# --------------------------------------------------------------------------- printing

@dataclass(frozen=True)
class _Column:
    """One column of a run's printed line: its label, width and the run's cell text."""

    label: str
    width: int
    text: Callable[[RunResult], str]
    left: bool = False


def _cell(value: float | int | None, fmt: str) -> str:
    """``value`` in ``fmt``, or ``-`` for a value the run lacks."""
    return "-" if value is None else format(value, fmt)


def _gospa_cell(r: RunResult) -> str:
    g = r.gospa
    return f"{g.total:6.2f} ({g.localisation:7.2f}/{g.missed:7.2f}/{g.false:7.2f})"


# Each cell is padded to its column's width, so header and lines align whatever the widths.
_COLUMNS: tuple[_Column, ...] = (
    _Column("seed", 4, lambda r: f"{r.seed:d}"),
    _Column("k_prior", 7, lambda r: r.k_prior, left=True),
    _Column("param", 5, lambda r: r.parameters, left=True),
    _Column("tgts", 4, lambda r: f"{r.targets:d}"),
    _Column("det/scn", 7, lambda r: f"{r.detections_per_scan:.1f}"),
    _Column("scans", 5, lambda r: f"{r.scans:d}"),
    _Column("scans/s", 8, lambda r: f"{r.scans_per_second:.1f}"),
    _Column("p50 ms", 8, lambda r: f"{r.window_p50_ms:.1f}"),
    _Column("p95 ms", 8, lambda r: f"{r.window_p95_ms:.1f}"),
    _Column("max ms", 8, lambda r: f"{r.window_max_ms:.1f}"),
    _Column(">lim", 4, lambda r: f"{r.windows_over_limit:d}"),
    _Column("hyps", 7, lambda r: f"{r.hypotheses_mean:.0f}"),
    _Column("maxcl", 6, lambda r: f"{r.largest_cluster:d}"),
    _Column("minmass", 7, lambda r: f"{r.min_captured_mass:.3f}"),
    _Column("GOSPA (GOSPA^2: loc/miss/false)", 32, _gospa_cell),
    _Column("oracle", 6, lambda r: f"{r.oracle_gospa.total:.2f}"),
    _Column("ratio", 6, lambda r: f"{r.gospa_ratio:.2f}"),
    _Column("P-GOSPA", 7, lambda r: _cell(r.pgospa, ".2f")),
    _Column("T-GOSPA", 8, lambda r: _cell(r.tgospa, ".2f")),
    _Column("oracle T", 8, lambda r: _cell(r.oracle_tgospa, ".2f")),
    _Column("T-ratio", 7, lambda r: _cell(r.tgospa_ratio, ".2f")),
    _Column("frag", 5, lambda r: _cell(r.fragments_per_target, ".2f")),
    _Column("ids/tg", 6, lambda r: f"{r.ids_per_target:.2f}"),
    _Column("IDsw", 4, lambda r: _cell(r.tgospa_id_switches, "d")),
    _Column("Brier", 5, lambda r: f"{r.k_brier:.3f}"),
    _Column("K hit", 5, lambda r: f"{r.k_hit_rate:.2f}"),
)


def _family_width(families: Sequence[str]) -> int:
    """Width of the family column: the longest name, at least 10."""
    return max(10, *(len(name) for name in families))


def _header(family_width: int = 10) -> str:
    """The column labels of :func:`_run_line`, each over its column."""
    cells = [
        column.label.ljust(column.width) if column.left else column.label.rjust(column.width)
        for column in _COLUMNS
    ]
    return f"{'family':{family_width}s} " + " ".join(cells) + "  status"


def _run_line(r: RunResult, family_width: int = 10) -> str:
    """One run's printed line, aligned with :func:`_header` of the same width."""
    cells = [
        column.text(r).ljust(column.width) if column.left else column.text(r).rjust(column.width)
        for column in _COLUMNS
    ]
    return (
        f"{r.family:{family_width}s} " + " ".join(cells) + f"  {_status_text(r.status_counts)}"
    )


def _mark(met: bool | None) -> str:
    return "" if met is None else ("met" if met else "NOT met")


def _status_text(counts: Sequence[tuple[str, int]]) -> str:
    return " ".join(f"{status}:{count}" for status, count in counts)


def _family_line(s: FamilySummary, time_limit: float) -> str:
    speed = f"{s.scans_per_second:.1f} scans/s"
    if s.forward_scans_per_second is not None:
        speed += f" (forward pass alone {s.forward_scans_per_second:.1f})"
    if s.speed_goal is not None:
        speed += f" [goal >= {s.speed_goal:g}: {_mark(s.speed_met)}]"
    return (
        f"  => {s.family} (k_prior {s.k_prior}"
        + ("" if s.parameters == "given" else f", parameters {s.parameters}")
        + f"), {len(s.seeds)} seed(s): {speed}; GOSPA "
        f"{s.gospa_ratio_mean:.2f}x oracle (min {s.gospa_ratio_min:.2f}, max "
        f"{s.gospa_ratio_max:.2f}) [goal <= {GOSPA_RATIO_GOAL:g}x: {_mark(s.gospa_met)}]; "
        f"{_identity_text(s)}"
        f"p(K | Z) Brier {s.k_brier_mean:.3f}, marginal K right in {s.k_hit_rate_mean:.0%} of "
        f"windows; windows over {time_limit:g} s: "
        f"{s.windows_over_limit}/{s.windows} [goal 0: {_mark(s.time_limit_met)}], slowest "
        f"{s.window_max_ms:.0f} ms; status {_status_text(s.status_counts)}; min captured mass "
        f"{s.min_captured_mass:.3f}"
    )


def _identity_text(s: FamilySummary) -> str:
    """The family line's identity part (``""`` when the runs lack it): mean fragments per
    target, switches, T-GOSPA ratio to the oracle and P-GOSPA over the oracle's GOSPA."""
    parts = [
        template.format(value)
        for template, value in (
            ("frag {:.2f}", s.fragments_per_target_mean),
            ("IDsw {:.1f}", s.id_switches_mean),
            ("T-GOSPA {:.2f}x oracle", s.tgospa_ratio_mean),
            ("P-GOSPA {:.2f}x oracle GOSPA", s.pgospa_ratio_mean),
        )
        if value is not None
    ]
    return f"identity: {', '.join(parts)}; " if parts else ""


def _growth_line(g: ScaleGrowth) -> str:
    times = " -> ".join(f"{1e3 * t:.1f}" for t in g.seconds_per_scan)
    steps = ", ".join(
        f"x{b / a:.2f} for x{nb / na:.1f} targets"
        for a, b, na, nb in zip(
            g.seconds_per_scan, g.seconds_per_scan[1:], g.targets, g.targets[1:], strict=False
        )
    )
    return (
        f"time per scan {' -> '.join(g.families)} ({' -> '.join(map(str, g.targets))} targets): "
        f"{times} ms ({steps}); exponent {g.exponent:.2f} "
        f"[goal linear or better, <= 1: {_mark(g.linear_or_better)}]"
    )


def _lowest(means: dict[str, float], fmt: str) -> str:
    """Which prior has the smallest mean, with every prior's mean."""
    every = ", ".join(f"{prior} {value:{fmt}}" for prior, value in means.items())
    if len(means) == 1:
        return f"{every} (one prior only)"
    best = min(means.values())
    winners = [prior for prior, value in means.items() if value == best]
    if len(winners) == len(means):
        return f"tie ({every})"
    return f"{' and '.join(winners)} ({every})"


def _comparison_text(summaries: Sequence[FamilySummary], priors: Sequence[str]) -> str:
    """Per family and prior: mean GOSPA ratio / mean Brier; then the best prior overall."""
    by_key = {(s.family, s.k_prior): s for s in summaries}
    families = list(dict.fromkeys(s.family for s in summaries))
    width = max(10, *(len(family) for family in families))
    lines = [
        "k_prior comparison, GOSPA ratio to the oracle / Brier score of p(K | Z) (means over "
        "seeds; lower is better):",
        f"  {'family':{width}s}" + "".join(f" {prior:>14s}" for prior in priors),
    ]
    for family in families:
        cells = [by_key[family, prior] for prior in priors]
        lines.append(
            f"  {family:{width}s}"
            + "".join(f" {c.gospa_ratio_mean:6.2f} / {c.k_brier_mean:5.3f}" for c in cells)
        )
    ratio = {
        prior: float(np.mean([by_key[f, prior].gospa_ratio_mean for f in families]))
        for prior in priors
    }
    brier = {
        prior: float(np.mean([by_key[f, prior].k_brier_mean for f in families]))
        for prior in priors
    }
    lines.append(
        f"  {'mean':{width}s}"
        + "".join(f" {ratio[prior]:6.2f} / {brier[prior]:5.3f}" for prior in priors)
    )
    word = "lower" if len(priors) == 2 else "lowest"
    lines.append(
        f"  {word} mean GOSPA ratio over families: {_lowest(ratio, '.2f')}; {word} mean "
        f"Brier: {_lowest(brier, '.3f')}"
    )
    return "\n".join(lines)


# --------------------------------------------------------------------------- benchmark


def run_benchmark(
    *,
    families: Sequence[str] = DEFAULT_FAMILIES,
    seeds: int = 5,
    window_length: int | None = 5,
    time_limit: float = 2.0,
    config: str = "generic",
    scans: int | None = None,
    json_path: Path | str | None = None,
    gating: bool = True,
    out: TextIO | None = None,
    k_priors: Sequence[str] = DEFAULT_K_PRIORS,
    motion: str = "configured",
    parameters: Sequence[str] = ("given",),
) -> BenchmarkResult:
    """Run and print the benchmark; optionally write the results as JSON.

    Parameters
    ----------
    families : sequence of str
        Scenario names (default :data:`DEFAULT_FAMILIES`).
    seeds : int
        Seeds ``0..seeds-1`` per family, >= 1.
    window_length : int or None
        Scans per window for every family (default 5, the window of the speed goals);
        ``None`` keeps the configuration's.
    time_limit : float
        ``EstimatorSettings.time_limit`` (seconds), also the per-window budget counted.
    config : {"generic", "scenario"}
        Configuration of every run (see :func:`bench_scenario`).
    scans : int, optional
        Truncate every scenario to its first ``scans`` scans.
    json_path : path, optional
        Also write :meth:`BenchmarkResult.to_json` there.
    gating : bool
        Also measure batched gating throughput (:func:`bench_gating`).
    out : text stream, optional
        Where to print (default ``sys.stdout``); every line is flushed.
    k_priors : sequence of str
        Priors on K (``EstimatorSettings.k_prior``, from :data:`BENCH_K_PRIORS`,
        distinct) to run every family and seed with (default :data:`DEFAULT_K_PRIORS`);
        the goals and the scale growth use the first only.
    motion : {"configured", "imm"}
        The motion model of every run (see :func:`bench_scenario`).
    parameters : sequence of {"given", "auto"}
        Distinct; every family, prior and seed runs with each (see
        :func:`bench_scenario`).  The goals, the scale growth and the comparison of the
        priors use the first; with ``"auto"`` every family's ``"auto"`` summary follows
        its runs (:func:`~.bench_auto.summarize_auto`: its GOSPA over the given values'
        when ``"given"`` ran too) and the goals of ``"auto"`` are printed last.

    Returns
    -------
    BenchmarkResult

    Raises
    ------
    InputError
        An unknown family or a bad argument (checked before anything runs).
    """
    settings = _check_benchmark_arguments(
        families, k_priors, seeds, window_length, time_limit, config, scans, motion, parameters
    )
    stream = sys.stdout if out is None else out

    def say(text: str) -> None:
        print(text, file=stream, flush=True)

    say(settings.heading())
    say(_header(_family_width(settings.families)))
    runs, summaries = _run_families(settings, say)
    first = [s for s in summaries if s.parameters == settings.parameters[0]]
    growth, pairs = _print_totals(first, settings.priors, gating, say)
    auto = summarize_auto(runs)
    if auto:
        say(auto_goals_text([s for s in auto if s.k_prior == settings.priors[0]]))
    result = BenchmarkResult(
        settings=settings.as_dict(),
        runs=tuple(runs),
        families=tuple(summaries),
        growth=growth,
        gating_pairs_per_second=pairs,
        auto=tuple(auto),
    )
    if json_path is not None:
        write_json(Path(json_path), result.to_json())
    return result


@dataclass(frozen=True)
class _BenchSettings:
    """The checked arguments of :func:`run_benchmark`.

    Attributes
    ----------
    families, priors : list of str
        Scenario names and priors on K, distinct.
    seeds : int
        Seeds ``0..seeds-1``.
    window_length : int or None
    limit : float
        The time limit in seconds.
    choice : {"generic", "scenario"}
    scans : int or None
    motion : {"configured", "imm"}
    parameters : tuple of {"given", "auto"}
    """

    families: list[str]
    priors: list[str]
    seeds: int
    window_length: int | None
    limit: float
    choice: str
    scans: int | None
    motion: str = "configured"
    parameters: tuple[str, ...] = ("given",)

    def as_dict(self) -> dict[str, object]:
        """The settings as :attr:`BenchmarkResult.settings` holds them."""
        return {
            "families": self.families,
            "seeds": list(range(self.seeds)),
            "window_length": self.window_length,
            "time_limit": self.limit,
            "config": self.choice,
            "k_priors": self.priors,
            "scans": self.scans,
            "motion": self.motion,
            "parameters": list(self.parameters),
            "gospa_cutoff": GOSPA_CUTOFF,
        }

    def heading(self) -> str:
        """The benchmark's first printed line: what every run uses."""
        window = self.window_length if self.window_length is not None else "of the config"
        return (
            f"window length {window}, "
            f"time limit {self.limit:g} s, {self.choice} configuration, "
            + ("" if self.motion == "configured" else f"motion {self.motion}, ")
            + ("" if self.parameters == ("given",)
               else f"parameters {','.join(self.parameters)}, ")
            + f"k_priors {','.join(self.priors)}, seeds 0..{self.seeds - 1}"
            + (f", first {self.scans} scans" if self.scans is not None else "")
            + f", GOSPA cut-off {GOSPA_CUTOFF:g} noise stds"
        )


def _check_benchmark_arguments(
    families: Sequence[str],
    k_priors: Sequence[str],
    seeds: int,
    window_length: int | None,
    time_limit: float,
    config: str,
    scans: int | None,
    motion: str = "configured",
    parameters: Sequence[str] = ("given",),
) -> _BenchSettings:
    """The arguments of :func:`run_benchmark`, checked before anything runs."""
    names = _check_families(families)
    priors = _check_k_priors(k_priors)
    n_seeds = check_integer("seeds", seeds, minimum=1)
    if window_length is not None:
        check_integer("window_length", window_length, minimum=1)
    limit = _check_time_limit(time_limit)
    choice = _check_config_choice(config)
    if scans is not None:
        check_integer("scans", scans, minimum=1)
    return _BenchSettings(names, priors, n_seeds, window_length, limit, choice, scans,
                          _check_motion_choice(motion),
                          check_parameter_choices(parameters))  # fmt: skip


def _run_families(
    settings: _BenchSettings, say: Callable[[str], None]
) -> tuple[list[RunResult], list[FamilySummary]]:
    """Every family with every prior, parameters and seed, each run's line (and its
    estimates' line) and each family's summaries printed as they finish."""
    runs: list[RunResult] = []
    summaries: list[FamilySummary] = []
    for name in settings.families:
        for prior in settings.priors:
            prior_runs: list[RunResult] = []
            for parameters in settings.parameters:
                family_runs = []
                for seed in range(settings.seeds):
                    run = bench_scenario(
                        name,
                        seed,
                        settings.window_length,
                        time_limit=settings.limit,
                        config=settings.choice,
                        scans=settings.scans,
                        k_prior=prior,
                        motion=settings.motion,
                        parameters=parameters,
                    )
                    family_runs.append(run)
                    say(_run_line(run, _family_width(settings.families)))
                    if run.estimates is not None:
                        say(estimates_line(run.estimates))
                summary = summarize_family(family_runs)
                summaries.append(summary)
                prior_runs.extend(family_runs)
                say(_family_line(summary, settings.limit))
            for auto in summarize_auto(prior_runs):
                say(auto_summary_line(auto))
            runs.extend(prior_runs)
    return runs, summaries


def _print_totals(
    summaries: Sequence[FamilySummary],
    priors: Sequence[str],
    gating: bool,
    say: Callable[[str], None],
) -> tuple[ScaleGrowth | None, float]:
    """Print the scale growth, the gating throughput, the goals and the comparison of the
    priors; return the growth and the gating pairs per second (``nan`` without gating)."""
    first = [summary for summary in summaries if summary.k_prior == priors[0]]
    growth = scale_growth(first)
    if growth is not None:
        say(_growth_line(growth))
    pairs = bench_gating() if gating else math.nan
    if gating:
        say(f"batched gating + likelihood: {pairs / 1e6:.1f} million (track, detection) pairs/s")
    say(_goals_text(first, growth))
    say(_comparison_text(summaries, priors))
    return growth, pairs


def _goals_text(summaries: Sequence[FamilySummary], growth: ScaleGrowth | None) -> str:
    """The goals, one line each, with the measured number and whether it is met.

    ``summaries`` are of one prior (the first of ``k_priors``), named in the heading.
    """
    first = summaries[0]
    parameters = "" if first.parameters == "given" else f", parameters {first.parameters}"
    lines = [f"goals (k_prior {first.k_prior}{parameters}):"]
    for s in summaries:
        if s.speed_goal is not None:
            lines.append(
                f"  {s.family} >= {s.speed_goal:g} scans/s: {s.scans_per_second:.1f} "
                f"{_mark(s.speed_met)}"
            )
    worst = max(summaries, key=lambda s: s.gospa_ratio_mean)
    missed = [s.family for s in summaries if not s.gospa_met]
    lines.append(
        f"  GOSPA <= {GOSPA_RATIO_GOAL:g}x oracle (mean over seeds) in every family: worst "
        f"{worst.gospa_ratio_mean:.2f}x ({worst.family}) "
        + ("met" if not missed else f"NOT met in {', '.join(missed)}")
    )
    over = sum(s.windows_over_limit for s in summaries)
    total = sum(s.windows for s in summaries)
    lines.append(f"  every window within its time limit: {over}/{total} over {_mark(over == 0)}")
    if growth is not None:
        lines.append(
            f"  time per scan linear or better in targets: exponent {growth.exponent:.2f} "
            f"{_mark(growth.linear_or_better)}"
        )
    return "\n".join(lines)
