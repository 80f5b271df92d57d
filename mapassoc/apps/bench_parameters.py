"""``mapassoc bench-parameters``: misstated sensor parameters against "auto" and the truth.

For every family (a built-in scenario) and seed, with the benchmark's untuned
configuration (:func:`mapassoc.evaluation.scenarios.generic_config`, whose sensors carry
the simulation's true false-alarm rate and ``Pd``), it runs the window estimator

* with the true values (the reference: GOSPA and seconds);
* with each misstatement: the rate times each of ``rate_factors``, ``Pd`` plus each of
  ``pd_offsets`` (kept in [0.05, 0.99]);
* with both parameters "auto" (:func:`mapassoc.estimator.parameters.estimate_parameters`;
  its tracks are the last pass's run, or a run with the estimates for a sampled
  recording),

and prints, per family, the mean over seeds of each run's GOSPA divided by the true
run's, the estimates beside the truth, and the cost of "auto" in true runs' time.  "auto"
does not start from a misstated number (the rate starts where every detection is clutter
and ``Pd`` high, see :mod:`mapassoc.estimator.parameters`), so one "auto" row serves
every misstatement.  The goals are printed beside the numbers: estimates within 10% of
the true rate and 0.05 of the true ``Pd``, GOSPA within 1.1 times the true run's, at most
three runs' worth of time.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from mapassoc.apps.bench_defaults import DEFAULT_PARAMETER_FAMILIES
from mapassoc.apps.run_folders import write_json
from mapassoc.errors import InputError

if TYPE_CHECKING:
    from mapassoc.data.config import Config
    from mapassoc.data.io import TrackTable
    from mapassoc.evaluation.simulate import Scenario

__all__ = ["DEFAULT_PARAMETER_FAMILIES", "ParameterRun", "run_parameter_benchmark"]

RATE_FACTORS = (0.25, 0.5, 2.0, 4.0)
PD_OFFSETS = (-0.15, 0.15)
GOSPA_CUTOFF = 10.0


@dataclass(frozen=True)
class ParameterRun:
    """One run of the parameter benchmark.

    Attributes
    ----------
    family, seed : str, int
    label : str
        ``"true"``, ``"rate x0.25"``, ..., ``"Pd -0.15"``, ..., ``"auto"``.
    gospa : float
        Mean GOSPA over time.
    seconds : float
        Wall time (for "auto": the estimation and, for a sampled recording, the final run).
    rate, pd : float
        The sensor values the run used (for "auto", the estimates).
    true_rate, true_pd : float
    """

    family: str
    seed: int
    label: str
    gospa: float
    seconds: float
    rate: float
    pd: float
    true_rate: float
    true_pd: float


def _gospa(scenario: Scenario, tracks: TrackTable) -> float:
    from mapassoc.evaluation.tables import evaluate_tables

    return evaluate_tables(scenario.truth, tracks, c=GOSPA_CUTOFF).gospa.mean_total


def run_parameter_benchmark(
    *,
    families: Sequence[str] = DEFAULT_PARAMETER_FAMILIES,
    seeds: int = 2,
    rate_factors: Sequence[float] = RATE_FACTORS,
    pd_offsets: Sequence[float] = PD_OFFSETS,
    time_limit: float = 2.0,
    scans: int | None = None,
    json_path: Path | str | None = None,
    out: TextIO | None = None,
) -> list[ParameterRun]:
    """Run and print the benchmark (module docstring); optionally write JSON rows.

    Raises
    ------
    InputError
        An unknown family, a scenario with more than one sensor, ``seeds < 1``.
    """
    from mapassoc.evaluation.scenarios import build_scenario, generic_config

    stream = out if out is not None else sys.stdout
    _check_families_and_seeds(families, seeds)
    rows: list[ParameterRun] = []

    def say(text: str) -> None:
        print(text, file=stream, flush=True)

    say(f"bench-parameters: {len(families)} families x {seeds} seeds, time limit {time_limit} s")
    for family in families:
        for seed in range(seeds):
            scenario = build_scenario(family, seed, scans=scans)
            config = generic_config(scenario, time_limit=time_limit)
            name, true = _the_sensor(family, config)
            settings = _settings(true, rate_factors, pd_offsets)
            runs = _runs_with(scenario, config, name, settings)
            rows += [ParameterRun(family, seed, label, *run, *true) for label, run in runs]
            auto = _auto_run(scenario, config, name)
            rows.append(ParameterRun(family, seed, "auto", *auto, *true))
            say(_seed_line(rows, family, seed, true))
    _print_summary(rows, families, say)
    if json_path is not None:
        write_json(Path(json_path), [r.__dict__ for r in rows])
    return rows


def _check_families_and_seeds(families: Sequence[str], seeds: object) -> None:
    """Raise unless every family is a built-in scenario and ``seeds`` an integer >= 1."""
    from mapassoc.evaluation.scenarios import scenario_names

    unknown = [name for name in families if name not in scenario_names()]
    if unknown:
        raise InputError(f"unknown families {unknown}; known: {', '.join(scenario_names())}")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise InputError(f"seeds must be an integer >= 1, got {seeds!r}")


def _the_sensor(family: str, config: Config) -> tuple[str, tuple[float, float]]:
    """The name of the configuration's one sensor and its true (false-alarm rate, Pd)."""
    if len(config.sensors) != 1:
        raise InputError(f"family {family!r} has {len(config.sensors)} sensors; "
                         "bench-parameters takes one-sensor families")  # fmt: skip
    name, sensor = next(iter(config.sensors.items()))
    return name, (sensor.false_alarms_per_scan, sensor.detection_probability)


def _settings(
    true: tuple[float, float], rate_factors: Sequence[float], pd_offsets: Sequence[float]
) -> list[tuple[str, tuple[float, float]]]:
    """The labelled (rate, Pd) of every run but "auto": the truth, then each misstatement."""
    settings = [("true", true)]
    settings += [(f"rate x{f:g}", (true[0] * f, true[1])) for f in rate_factors]
    settings += [
        (f"Pd {o:+g}", (true[0], float(np.clip(true[1] + o, 0.05, 0.99)))) for o in pd_offsets
    ]
    return settings


_Measured = tuple[float, float, float, float]
"""(GOSPA, seconds, rate, Pd) of one run: the fields of a :class:`ParameterRun` it sets."""


def _runs_with(
    scenario: Scenario,
    config: Config,
    name: str,
    settings: Sequence[tuple[str, tuple[float, float]]],
) -> list[tuple[str, _Measured]]:
    """The window estimator with each labelled (rate, Pd) of sensor ``name``, timed."""
    from mapassoc.estimator.parameters import with_sensor_parameters
    from mapassoc.estimator.pipeline import WindowEstimator

    runs: list[tuple[str, _Measured]] = []
    for label, (rate, pd) in settings:
        started = time.perf_counter()
        misstated = with_sensor_parameters(config, {name: (rate, pd)})
        result = WindowEstimator(config=misstated).run(scenario.scans)
        seconds = time.perf_counter() - started
        runs.append((label, (_gospa(scenario, result.tracks), seconds, rate, pd)))
    return runs


def _auto_run(scenario: Scenario, config: Config, name: str) -> _Measured:
    """Both parameters of sensor ``name`` estimated ("auto"), then the tracks of the last
    pass (or of a run with the estimates, when the passes ran on a sample), timed."""
    from mapassoc.estimator.parameters import estimate_parameters
    from mapassoc.estimator.pipeline import WindowEstimator

    started = time.perf_counter()
    estimate = estimate_parameters(
        config, scenario.scans, false_alarms=[name],
        detection_probability={name: None},
    )  # fmt: skip
    final = estimate.result
    if final is None:  # the passes ran on a sample
        final = WindowEstimator(config=estimate.config).run(scenario.scans)
    found = estimate.sensors[name]
    gospa = _gospa(scenario, final.tracks)
    seconds = time.perf_counter() - started
    return gospa, seconds, found.false_alarms_per_scan, found.detection_probability


def _seed_line(
    rows: Sequence[ParameterRun], family: str, seed: int, true: tuple[float, float]
) -> str:
    """One family and seed: GOSPA of each run over the true run's, and what "auto" found."""
    by_label = {r.label: r for r in rows if r.family == family and r.seed == seed}
    base = by_label["true"]
    parts = [f"{lab} {r.gospa / base.gospa:.2f}" for lab, r in by_label.items()
             if lab != "true"]  # fmt: skip
    auto = by_label["auto"]
    return (
        f"  {family} seed {seed}: true GOSPA {base.gospa:.3f}; ratios "
        + ", ".join(parts)
        + f"; auto rate {auto.rate:.3g} (true {true[0]:g}), Pd {auto.pd:.3f} "
        f"(true {true[1]:g}), {auto.seconds / base.seconds:.2f} true runs' time"
    )


def _print_summary(rows: list[ParameterRun], families: Sequence[str], say: object) -> None:
    labels = list(dict.fromkeys(r.label for r in rows if r.label != "true"))
    header = f"{'family':11s} " + " ".join(f"{lab:>10s}" for lab in labels)
    header += f" {'rate err':>9s} {'Pd err':>7s} {'cost':>6s}"
    lines = ["", "GOSPA / true run's, mean over seeds (goal: auto <= 1.10); auto's "
             "estimates: relative rate error (goal <= 0.10), Pd error (goal <= 0.05); "
             "cost in true runs' time (goal <= 3)", header, "-" * len(header)]  # fmt: skip
    for family in families:
        mine = [r for r in rows if r.family == family]
        base = {r.seed: r for r in mine if r.label == "true"}
        cells = []
        for lab in labels:
            ratios = [r.gospa / base[r.seed].gospa for r in mine if r.label == lab]
            cells.append(f"{np.mean(ratios):10.2f}")
        auto = [r for r in mine if r.label == "auto"]
        rate_err = np.mean([abs(r.rate - r.true_rate) / r.true_rate for r in auto])
        pd_err = np.mean([abs(r.pd - r.true_pd) for r in auto])
        cost = np.mean([r.seconds / base[r.seed].seconds for r in auto])
        lines.append(f"{family:11s} " + " ".join(cells)
                     + f" {rate_err:9.3f} {pd_err:7.3f} {cost:6.2f}")  # fmt: skip
    for line in lines:
        say(line)  # type: ignore[operator]
