"""``mapassoc bench``: speed and accuracy over scenario families and seeds.

For every family (a built-in scenario, :mod:`mapassoc.scenarios`) and every seed
``0..seeds-1`` the benchmark simulates the scenario, runs the window estimator and
reports

* throughput (scans per second of :meth:`~mapassoc.pipeline.WindowEstimator.run`) and
  window time (hypothesis generation plus solving) p50 / p95 / max, with the number of
  windows that took longer than the time limit;
* mean hypotheses and the largest cluster per window;
* the mix of window statuses (counted as the pipeline names them, whatever they are)
  and the smallest ``captured_mass``;
* GOSPA (cut-off :data:`GOSPA_CUTOFF`, with the localisation / missed / false parts of
  GOSPA^2) next to the oracle's (Kalman smoother on the true associations) and their ratio.

Then, per family, the mean GOSPA ratio over seeds with its spread and the mean
throughput; how time per scan grows over the ``scale20 -> scale50 -> scale100`` family
(fixed density, so linear in targets is the goal); and the throughput of batched gating.
Numbers, not pass/fail: the project's goals are printed beside them.

By default every family runs with the same untuned configuration,
:func:`mapassoc.scenarios.generic_config`; ``config="scenario"`` uses each scenario's
own configuration (fitted to its truth) instead.  Lines are printed (and flushed) as
soon as each run finishes: the whole benchmark can take minutes.
"""

from __future__ import annotations

import json
import math
import sys
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TextIO

import numpy as np

from mapassoc.config import Config
from mapassoc.errors import InputError
from mapassoc.evaluation import evaluate_tables
from mapassoc.kalman import pairwise_gate_and_loglik
from mapassoc.oracle import oracle_tracks
from mapassoc.pipeline import WindowEstimator
from mapassoc.scenarios import build_scenario, generic_config, scenario_names, truncate_scenario

__all__ = [
    "DEFAULT_FAMILIES",
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

#: Families run by default, in this order.
DEFAULT_FAMILIES: tuple[str, ...] = (
    "crossing",
    "parallel",
    "dense_pd08",
    "scale20",
    "scale50",
    "scale100",
    "burst",
    "dense",
    "dense50",
)
#: ``generic``: :func:`~mapassoc.scenarios.generic_config`; ``scenario``: each
#: scenario's own configuration.
CONFIG_CHOICES: tuple[str, ...] = ("generic", "scenario")
#: GOSPA cut-off c (length units, noise standard deviations).
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
        GOSPA^p (:class:`mapassoc.metrics.GospaSeries`): they add up to the mean of
        GOSPA^2, not of GOSPA.
    """

    total: float
    localisation: float
    missed: float
    false: float

    @classmethod
    def from_summary(cls, summary: dict[str, object]) -> GospaParts:
        """From the ``"gospa"`` entry of :func:`mapassoc.evaluation.evaluate_tables`."""
        return cls(
            total=float(summary["mean_total"]),  # type: ignore[arg-type]
            localisation=float(summary["mean_localisation"]),  # type: ignore[arg-type]
            missed=float(summary["mean_missed"]),  # type: ignore[arg-type]
            false=float(summary["mean_false"]),  # type: ignore[arg-type]
        )


@dataclass(frozen=True)
class RunResult:
    """One family run with one seed.

    Parameters
    ----------
    family : str
        Scenario name.
    seed : int
    config : {"generic", "scenario"}
        Which configuration was used.
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
    """

    family: str
    seed: int
    config: str
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


@dataclass(frozen=True)
class FamilySummary:
    """One family over its seeds.

    Parameters
    ----------
    family : str
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
    speed_goal : float or None
        Scans-per-second goal of the family (:data:`SPEED_GOALS`), if any.
    """

    family: str
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
    speed_goal: float | None

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
    families : tuple of FamilySummary
    growth : ScaleGrowth or None
        ``None`` unless at least two scale families ran.
    gating_pairs_per_second : float
    """

    settings: dict[str, object]
    runs: tuple[RunResult, ...]
    families: tuple[FamilySummary, ...]
    growth: ScaleGrowth | None
    gating_pairs_per_second: float

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
        }
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


def _check_int(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _check_time_limit(value: object) -> float:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value <= 0
    ):
        raise InputError(f"time_limit must be a finite number of seconds > 0, got {value!r}")
    return float(value)


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


# --------------------------------------------------------------------------- one run


def _ratio(estimate: float, oracle: float) -> float:
    if oracle > 0.0:
        return estimate / oracle
    return 1.0 if estimate <= 0.0 else math.inf


def _bench_config(base: Config, window_length: int | None, time_limit: float) -> Config:
    """The scenario's own configuration with the bench's window length and time limit."""
    changes: dict[str, object] = {"time_limit": time_limit}
    if window_length is not None:
        changes["window_length"] = window_length
    return replace(base, estimator=replace(base.estimator, **changes))  # type: ignore[arg-type]


def bench_scenario(
    name: str,
    seed: int = 0,
    window_length: int | None = 5,
    *,
    time_limit: float = 2.0,
    config: str = "generic",
    scans: int | None = None,
) -> RunResult:
    """Simulate one family with one seed, estimate, and measure speed and GOSPA.

    Parameters
    ----------
    name : str
        Scenario name (:func:`mapassoc.scenarios.scenario_names`).
    seed : int
        Seed of the realisation.
    window_length : int or None
        Scans per window; ``None`` keeps the configuration's (the default of
        :class:`~mapassoc.settings.EstimatorSettings` for ``config="generic"``).
    time_limit : float
        ``EstimatorSettings.time_limit`` in seconds, also the budget a window's time is
        compared with.
    config : {"generic", "scenario"}
        :func:`~mapassoc.scenarios.generic_config` of the (truncated) scenario, or the
        scenario's own configuration.
    scans : int, optional
        Keep only the first ``scans`` scans (:func:`~mapassoc.scenarios.truncate_scenario`),
        for quick checks.

    Returns
    -------
    RunResult

    Raises
    ------
    InputError
        An unknown scenario or a bad argument.
    """
    choice = _check_config_choice(config)
    limit = _check_time_limit(time_limit)
    if window_length is not None:
        _check_int("window_length", window_length, 1)
    scenario = build_scenario(name, seed)
    if scans is not None:
        scenario = truncate_scenario(scenario, _check_int("scans", scans, 1))
    if choice == "generic":
        run_config = generic_config(scenario, window_length=window_length, time_limit=limit)
    else:
        run_config = _bench_config(scenario.config, window_length, limit)

    estimator = WindowEstimator(config=run_config)
    start = time.perf_counter()
    result = estimator.run(scenario.scans)
    seconds = time.perf_counter() - start

    windows = result.windows
    window_seconds = np.array([w.generate_seconds + w.solve_seconds for w in windows])
    statuses = Counter(str(w.status) for w in windows)
    estimate = GospaParts.from_summary(
        evaluate_tables(scenario.truth, result.tracks, c=GOSPA_CUTOFF)["gospa"]  # type: ignore[arg-type]
    )
    oracle = GospaParts.from_summary(
        evaluate_tables(
            scenario.truth,
            oracle_tracks(scenario.scans, scenario.origins, scenario.config),
            c=GOSPA_CUTOFF,
        )["gospa"]  # type: ignore[arg-type]
    )
    sizes = [scan.size for scan in scenario.scans]
    n_scans = len(scenario.scans)
    return RunResult(
        family=name,
        seed=int(seed),
        config=choice,
        targets=len(np.unique(scenario.truth.target_ids)),
        scans=n_scans,
        detections_per_scan=float(np.mean(sizes)),
        max_detections=int(max(sizes)),
        window_length=run_config.estimator.window_length,
        time_limit=limit,
        max_tracks=run_config.estimator.max_tracks,
        seconds=seconds,
        scans_per_second=n_scans / seconds if seconds > 0 else math.inf,
        seconds_per_scan=seconds / n_scans,
        window_p50_ms=float(np.percentile(window_seconds, 50) * 1e3),
        window_p95_ms=float(np.percentile(window_seconds, 95) * 1e3),
        window_max_ms=float(window_seconds.max() * 1e3),
        windows=len(windows),
        windows_over_limit=int(np.sum(window_seconds > limit)),
        hypotheses_mean=float(np.mean([w.hypotheses for w in windows])),
        hypotheses_max=int(max(w.hypotheses for w in windows)),
        largest_cluster=int(max(w.largest_cluster for w in windows)),
        status_counts=_ordered(statuses),
        min_captured_mass=float(min(w.captured_mass for w in windows)),
        tracks=len(result.track_rows),
        gospa=estimate,
        oracle_gospa=oracle,
        gospa_ratio=_ratio(estimate.total, oracle.total),
    )


def _ordered(counts: Counter[str]) -> tuple[tuple[str, int], ...]:
    """Counts most frequent first, ties by name."""
    return tuple(sorted(counts.items(), key=lambda item: (-item[1], item[0])))


# --------------------------------------------------------------------------- summaries


def summarize_family(runs: Sequence[RunResult]) -> FamilySummary:
    """Combine the runs of one family over its seeds.

    Raises
    ------
    InputError
        No runs, or runs of different families.
    """
    runs = list(runs)
    if not runs:
        raise InputError("runs must contain at least one RunResult")
    families = {run.family for run in runs}
    if len(families) != 1:
        raise InputError(f"runs must all be of one family, got {sorted(families)}")
    family = runs[0].family
    ratios = np.array([run.gospa_ratio for run in runs])
    statuses: Counter[str] = Counter()
    for run in runs:
        statuses.update(dict(run.status_counts))
    return FamilySummary(
        family=family,
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
        speed_goal=SPEED_GOALS.get(family),
    )


def scale_growth(summaries: Sequence[FamilySummary]) -> ScaleGrowth | None:
    """Time per scan against targets over the scale families present (at least two)."""
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

_HEADER = (
    f"{'family':10s} {'seed':>4s} {'tgts':>4s} {'det/scn':>7s} {'scans':>5s} {'scans/s':>8s} "
    f"{'p50 ms':>8s} {'p95 ms':>8s} {'max ms':>8s} {'>lim':>4s} {'hyps':>7s} {'maxcl':>6s} "
    f"{'minmass':>7s} {'GOSPA (GOSPA^2: loc/miss/false)':>31s} {'oracle':>6s} {'ratio':>6s}  "
    "status"
)


def _mark(met: bool | None) -> str:
    return "" if met is None else ("met" if met else "NOT met")


def _status_text(counts: Sequence[tuple[str, int]]) -> str:
    return " ".join(f"{status}:{count}" for status, count in counts)


def _run_line(r: RunResult) -> str:
    g = r.gospa
    return (
        f"{r.family:10s} {r.seed:4d} {r.targets:4d} {r.detections_per_scan:7.1f} {r.scans:5d} "
        f"{r.scans_per_second:8.1f} {r.window_p50_ms:8.1f} {r.window_p95_ms:8.1f} "
        f"{r.window_max_ms:8.1f} {r.windows_over_limit:4d} {r.hypotheses_mean:7.0f} "
        f"{r.largest_cluster:6d} {r.min_captured_mass:7.3f} "
        f"{g.total:6.2f} ({g.localisation:7.2f}/{g.missed:7.2f}/{g.false:7.2f}) "
        f"{r.oracle_gospa.total:6.2f} {r.gospa_ratio:6.2f}  {_status_text(r.status_counts)}"
    )


def _family_line(s: FamilySummary, time_limit: float) -> str:
    speed = f"{s.scans_per_second:.1f} scans/s"
    if s.speed_goal is not None:
        speed += f" [goal >= {s.speed_goal:g}: {_mark(s.speed_met)}]"
    return (
        f"  => {s.family}, {len(s.seeds)} seed(s): {speed}; GOSPA {s.gospa_ratio_mean:.2f}x "
        f"oracle (min {s.gospa_ratio_min:.2f}, max {s.gospa_ratio_max:.2f}) "
        f"[goal <= {GOSPA_RATIO_GOAL:g}x: {_mark(s.gospa_met)}]; windows over {time_limit:g} s: "
        f"{s.windows_over_limit}/{s.windows} [goal 0: {_mark(s.time_limit_met)}], slowest "
        f"{s.window_max_ms:.0f} ms; status {_status_text(s.status_counts)}; min captured mass "
        f"{s.min_captured_mass:.3f}"
    )


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

    Returns
    -------
    BenchmarkResult

    Raises
    ------
    InputError
        An unknown family or a bad argument (checked before anything runs).
    """
    names = _check_families(families)
    n_seeds = _check_int("seeds", seeds, 1)
    if window_length is not None:
        _check_int("window_length", window_length, 1)
    limit = _check_time_limit(time_limit)
    choice = _check_config_choice(config)
    if scans is not None:
        _check_int("scans", scans, 1)
    stream = sys.stdout if out is None else out

    def say(text: str) -> None:
        print(text, file=stream, flush=True)

    settings: dict[str, object] = {
        "families": names,
        "seeds": list(range(n_seeds)),
        "window_length": window_length,
        "time_limit": limit,
        "config": choice,
        "scans": scans,
        "gospa_cutoff": GOSPA_CUTOFF,
    }
    say(
        f"window length {window_length if window_length is not None else 'of the config'}, "
        f"time limit {limit:g} s, {choice} configuration, seeds 0..{n_seeds - 1}"
        + (f", first {scans} scans" if scans is not None else "")
        + f", GOSPA cut-off {GOSPA_CUTOFF:g}"
    )
    say(_HEADER)
    runs: list[RunResult] = []
    summaries: list[FamilySummary] = []
    for name in names:
        family_runs = []
        for seed in range(n_seeds):
            run = bench_scenario(
                name, seed, window_length, time_limit=limit, config=choice, scans=scans
            )
            family_runs.append(run)
            say(_run_line(run))
        summary = summarize_family(family_runs)
        summaries.append(summary)
        runs.extend(family_runs)
        say(_family_line(summary, limit))

    growth = scale_growth(summaries)
    if growth is not None:
        say(_growth_line(growth))
    pairs = bench_gating() if gating else math.nan
    if gating:
        say(f"batched gating + likelihood: {pairs / 1e6:.1f} million (track, detection) pairs/s")
    say(_goals_text(summaries, growth))

    result = BenchmarkResult(
        settings=settings,
        runs=tuple(runs),
        families=tuple(summaries),
        growth=growth,
        gating_pairs_per_second=pairs,
    )
    if json_path is not None:
        Path(json_path).write_text(
            json.dumps(result.to_json(), indent=2, allow_nan=False) + "\n", encoding="utf-8"
        )
    return result


def _goals_text(summaries: Sequence[FamilySummary], growth: ScaleGrowth | None) -> str:
    """The goals, one line each, with the measured number and whether it is met."""
    lines = ["goals:"]
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
