"""``mapassoc bench --parameters auto``: every model parameter estimated from the recording.

With ``parameters="auto"`` a benchmark run does not get the model's values: before the
timed run, the values :func:`auto_fields` lists are turned to ``"auto"``
(:func:`auto_config`), :func:`mapassoc.estimator.parameters.estimate_parameters`
estimates them from the run's own scans, and the run uses the estimates
(:func:`run_auto`).  Its seconds include the estimation.  The fields are

* every sensor's ``false_alarms_per_scan`` and ``detection_probability``;
* every position sensor's ``noise_std``;
* ``[motion] noise_intensity`` where the motion model has one scale
  (:data:`~mapassoc.data.config.AUTO_NOISE_MODELS`: constant velocity, constant
  acceleration, random walk), and for a set of models (``[motion] model = "imm"``) each
  such component's (``motion.models[i].noise_intensity``; no truth to compare with:
  the scenarios simulate one model's noise and manoeuvres, not a set);
* the birth model's ``rate``, ``initial_count`` and ``survival_probability``
  (:data:`BIRTH_FIELDS`, which says why ``velocity_std`` is not among them).

No start is given: each value starts where :mod:`mapassoc.estimator.parameters` and
:mod:`mapassoc.estimator.noise_levels` start an ``"auto"`` value without one (the rate at
the mean detections per scan, ``Pd`` at :data:`~mapassoc.estimator.parameters.DEFAULT_PD_START`,
the noise levels from the data).  The ``"auto"`` configuration is the run configuration
written as TOML with those values ``"auto"`` and read back
(:func:`~mapassoc.data.config.config_to_toml`, :func:`~mapassoc.data.config.parse_config`),
so its models hold the reader's placeholders and nothing of the true values reaches the
estimation; a value the reader learns to take as ``"auto"`` is added to the benchmark by
one line of :func:`auto_fields`.

``motion="imm"``: the configured single model is wrapped as the benchmark wraps it
(:func:`~mapassoc.models.interacting.noise_levels`) before its values are turned to
``"auto"``, so the estimation runs under the set and estimates each component's process
noise (:mod:`mapassoc.estimator.noise_levels`, sets of models), as a user's
configuration of a set with ``"auto"`` components does.  The estimation's last pass is
the run itself when it covered the whole recording
(:attr:`~mapassoc.estimator.parameters.ParameterEstimate.result`), and no run is
repeated.

The estimates are compared with the truth: the scenario's own configuration
(``Scenario.config``), whose values are those the simulation drew from.  Goals:
:data:`AUTO_GOSPA_GOAL` (GOSPA of the ``"auto"`` run at most 1.05 times that of the
run given the configuration's values, mean over seeds), every estimate within
:data:`RELATIVE_GOAL` (20%) of the truth and ``Pd`` within :data:`PD_GOAL` (0.03).
"""

from __future__ import annotations

import dataclasses
import math
import time
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from mapassoc.data.config import AutoParameters, Config, config_to_toml, parse_config
from mapassoc.errors import InputError
from mapassoc.filtering.noise_estimation import position_sensor, scalable_process_noise
from mapassoc.models.interacting import InteractingModels

if TYPE_CHECKING:
    from mapassoc.data.scans import Scan
    from mapassoc.estimator.parameters import ParameterEstimate
    from mapassoc.estimator.pipeline import EstimateResult

__all__ = [
    "PARAMETER_CHOICES",
    "AUTO_GOSPA_GOAL",
    "RELATIVE_GOAL",
    "PD_GOAL",
    "AutoField",
    "BIRTH_FIELDS",
    "EstimatedValue",
    "AutoRun",
    "FieldErrors",
    "AutoSummary",
    "BenchRow",
    "auto_fields",
    "auto_config",
    "run_auto",
    "compare_to_truth",
    "check_parameter_choice",
    "check_parameter_choices",
    "summarize_auto",
    "estimates_line",
    "auto_summary_line",
    "auto_goals_text",
]

PARAMETER_CHOICES: tuple[str, ...] = ("given", "auto")
"""``given``: the run configuration's values; ``auto``: those of :func:`auto_fields`
estimated from the recording first (:func:`run_auto`)."""
AUTO_GOSPA_GOAL = 1.05
"""Goal: mean over seeds of the ``"auto"`` run's GOSPA over the given-values run's."""
RELATIVE_GOAL = 0.20
"""Goal: every estimate but ``Pd`` within this fraction of the truth."""
PD_GOAL = 0.03
"""Goal: every ``Pd`` estimate within this of the truth (absolute)."""


# --------------------------------------------------------------------------- the fields


@dataclass(frozen=True)
class AutoField:
    """One configuration value a run with ``parameters="auto"`` estimates.

    Attributes
    ----------
    key : str
        Where it is in the configuration file (``"motion.noise_intensity"``,
        ``"sensors.pos.detection_probability"``), as the JSON names it.
    label : str
        Its short name on the printed lines (``"q"``, ``"pos Pd"``).
    read : callable
        Its value in a configuration (raises ``KeyError`` or ``AttributeError`` where the
        configuration has no such value, as a truth without the sensor).
    mark : callable
        ``AutoParameters`` with this value added to those estimated.
    absolute : bool
        Its error is the absolute difference (``Pd``, goal :data:`PD_GOAL`); else the
        relative one (goal :data:`RELATIVE_GOAL`).
    """

    key: str
    label: str
    read: Callable[[Config], float]
    mark: Callable[[AutoParameters], AutoParameters]
    absolute: bool = False

    @property
    def goal(self) -> float:
        """The largest error the goal allows."""
        return PD_GOAL if self.absolute else RELATIVE_GOAL


def _noise_intensity(config: Config) -> float:
    return float(config.motion.noise_intensity)  # type: ignore[attr-defined]


def _rate(name: str) -> Callable[[Config], float]:
    return lambda config: float(config.sensors[name].false_alarms_per_scan)


def _pd(name: str) -> Callable[[Config], float]:
    return lambda config: float(config.sensors[name].detection_probability)


def _std(name: str) -> Callable[[Config], float]:
    """The sensor's noise std, the root mean of its components' variances (one std when
    they are equal, as a pooled estimate is)."""

    def read(config: Config) -> float:
        measurement = config.sensors[name].measurement
        return float(np.sqrt(np.mean(np.diag(measurement.noise_covariance))))

    return read


def _mark_noise_intensity(auto: AutoParameters) -> AutoParameters:
    return dataclasses.replace(auto, noise_intensity=True)


def _model_noise_intensity(index: int) -> Callable[[Config], float]:
    return lambda config: float(config.motion.models[index].noise_intensity)  # type: ignore[attr-defined]


def _mark_model_noise_intensity(index: int) -> Callable[[AutoParameters], AutoParameters]:
    return lambda auto: dataclasses.replace(
        auto, model_noise_intensity=(*auto.model_noise_intensity, (index, None))
    )


def _mark_rate(name: str) -> Callable[[AutoParameters], AutoParameters]:
    return lambda auto: dataclasses.replace(auto, false_alarms=(*auto.false_alarms, name))


def _mark_pd(name: str) -> Callable[[AutoParameters], AutoParameters]:
    return lambda auto: dataclasses.replace(
        auto, detection_probability=(*auto.detection_probability, (name, None))
    )


def _mark_std(name: str) -> Callable[[AutoParameters], AutoParameters]:
    return lambda auto: dataclasses.replace(auto, noise_std=(*auto.noise_std, (name, None)))


def auto_fields(config: Config) -> tuple[AutoField, ...]:
    """The values of ``config`` a run with ``parameters="auto"`` estimates (module
    docstring): the one list of them, in the order they are printed, each with no start.

    The process noise is listed for a single model with one scale, and for each such
    component of a set of models (``InteractingModels``).

    A value the configuration reader and writer take as ``"auto"`` joins with one line
    here (as the birth model's, :data:`BIRTH_FIELDS`): :func:`auto_config`, the
    estimation, the printed estimates, the JSON and the summaries follow from the list.
    """
    motion = config.motion
    fields: list[AutoField] = []
    if scalable_process_noise(motion) and not isinstance(motion, InteractingModels):
        fields.append(AutoField("motion.noise_intensity", "q", _noise_intensity,
                                _mark_noise_intensity))  # fmt: skip
    for index, model in enumerate(getattr(motion, "models", ()) if isinstance(
            motion, InteractingModels) else ()):  # fmt: skip
        if scalable_process_noise(model):
            fields.append(AutoField(f"motion.models[{index}].noise_intensity", f"q{index}",
                                    _model_noise_intensity(index),
                                    _mark_model_noise_intensity(index)))  # fmt: skip
    for name, sensor in config.sensors.items():
        key = f"sensors.{name}"
        fields.append(AutoField(f"{key}.false_alarms_per_scan", f"{name} rate", _rate(name),
                                _mark_rate(name)))  # fmt: skip
        fields.append(AutoField(f"{key}.detection_probability", f"{name} Pd", _pd(name),
                                _mark_pd(name), absolute=True))  # fmt: skip
        if position_sensor(sensor.measurement):
            fields.append(AutoField(f"{key}.noise_std", f"{name} std", _std(name),
                                    _mark_std(name)))  # fmt: skip
    for key, label in BIRTH_FIELDS:
        fields.append(AutoField(f"birth.{key}", label, _birth(key), _mark_birth(key)))
    return tuple(fields)


BIRTH_FIELDS = (("rate", "births"), ("initial_count", "initial"),
                ("survival_probability", "survival"))  # fmt: skip
"""The birth model's values an "auto" run estimates, with their printed names.
``velocity_std`` stays as configured: the scenarios configure it as a prior spread (1.5
times the top speed), not as the spread of the simulated velocities its estimate is, so
no truth to compare it with exists."""


def _birth(key: str) -> Callable[[Config], float]:
    return lambda config: float(getattr(config.birth, key))


def _mark_birth(key: str) -> Callable[[AutoParameters], AutoParameters]:
    return lambda auto: dataclasses.replace(auto, birth=(*auto.birth, (key, None)))


def auto_config(config: Config) -> Config:
    """``config`` with every value of :func:`auto_fields` ``"auto"``, no start given: the
    configuration written as TOML and read back, so that those values hold the reader's
    placeholders (:attr:`Config.auto` lists them) and the others are as they were."""
    auto = config.auto
    for field in auto_fields(config):
        auto = field.mark(auto)
    text = config_to_toml(dataclasses.replace(config, auto=auto))
    return parse_config(tomllib.loads(text), source=config.source)


# --------------------------------------------------------------------------- one run


@dataclass(frozen=True)
class EstimatedValue:
    """One estimate beside the truth.

    Attributes
    ----------
    key, label : str
        As :class:`AutoField`'s.
    estimate : float
        The value the run used.
    truth : float or None
        The truth's (the scenario's configuration); None where it has no such value.
    error : float or None
        ``|estimate - truth|``, over ``truth`` unless ``absolute`` (None without a truth,
        ``inf`` for a relative error of a true 0 missed).
    goal : float
        The largest error the goal allows.
    absolute : bool
    """

    key: str
    label: str
    estimate: float
    truth: float | None
    error: float | None
    goal: float
    absolute: bool

    @property
    def met(self) -> bool | None:
        """Whether the error is within the goal (None without a truth)."""
        return None if self.error is None else self.error <= self.goal


def _error(estimate: float, truth: float, absolute: bool) -> float:
    gap = abs(estimate - truth)
    if absolute:
        return gap
    if truth != 0:
        return gap / abs(truth)
    return 0.0 if gap == 0 else math.inf


def compare_to_truth(
    fields: Sequence[AutoField], estimated: Config, truth: Config
) -> tuple[EstimatedValue, ...]:
    """Each field's value in ``estimated`` beside its value in ``truth``."""
    out = []
    for field in fields:
        value = field.read(estimated)
        try:
            true: float | None = field.read(truth)
        except (KeyError, AttributeError):
            true = None
        error = None if true is None else _error(value, true, field.absolute)
        out.append(EstimatedValue(field.key, field.label, value, true, error, field.goal,
                                  field.absolute))  # fmt: skip
    return tuple(out)


@dataclass(frozen=True)
class AutoRun:
    """A run with its parameters estimated first (:func:`run_auto`).

    Attributes
    ----------
    result : EstimateResult
        The estimator's answer under the estimates.
    seconds : float
        The estimation and the run (when the estimation's last pass was not the run).
    forward_seconds : float
        Up to the end of the forward pass of the answer: the estimation's last pass, or
        the last window of the run after it.
    config : Config
        What the run used: the estimates, no ``"auto"`` left.
    estimate : ParameterEstimate
    values : tuple of EstimatedValue
        The estimates beside the truth, in the order of :func:`auto_fields`.
    reran : bool
        Whether a run followed the estimation (a sampled recording, or noise levels
        moved by the last pass).
    """

    result: EstimateResult
    seconds: float
    forward_seconds: float
    config: Config
    estimate: ParameterEstimate
    values: tuple[EstimatedValue, ...]
    reran: bool


def run_auto(config: Config, scans: Sequence[Scan], truth: Config) -> AutoRun:
    """Estimate the ``"auto"`` values of ``config`` from ``scans``, then run with them.

    Parameters
    ----------
    config : Config
        The run's configuration, :func:`auto_config` of it or not (a configuration with
        the values to estimate ``"auto"``; one without is made so here).
    scans : sequence of Scan
    truth : Config
        What the estimates are compared with (the scenario's configuration).

    Returns
    -------
    AutoRun
    """
    from mapassoc.estimator.parameters import estimate_parameters
    from mapassoc.estimator.pipeline import WindowEstimator

    fields = auto_fields(config)
    if not config.auto.pending:
        config = auto_config(config)
    start = time.perf_counter()
    marks = [start]  # when the last pass ended, then when the last window was committed
    estimate = estimate_parameters(config, scans,
                                   on_pass=lambda _: marks.append(time.perf_counter()))  # fmt: skip
    final = estimate.config
    result = estimate.result
    if result is None:
        result = WindowEstimator(config=final).run(
            scans, on_window=lambda _: marks.append(time.perf_counter())
        )
    seconds = time.perf_counter() - start
    return AutoRun(
        result=result, seconds=seconds, forward_seconds=marks[-1] - start, config=final,
        estimate=estimate, values=compare_to_truth(fields, estimate.config, truth),
        reran=result is not estimate.result,
    )  # fmt: skip


# --------------------------------------------------------------------------- choices


def check_parameter_choice(value: object, name: str = "parameters") -> str:
    """``value`` if it is one of :data:`PARAMETER_CHOICES` (InputError naming ``name``)."""
    if not isinstance(value, str) or value not in PARAMETER_CHOICES:
        raise InputError(
            f"{name} must be one of {', '.join(PARAMETER_CHOICES)}, got {value!r}", key=name
        )
    return value


def check_parameter_choices(values: object) -> tuple[str, ...]:
    """A non-empty sequence of distinct :data:`PARAMETER_CHOICES`, checked."""
    if isinstance(values, str) or not isinstance(values, Sequence):
        raise InputError(
            f"parameters must be a sequence of {', '.join(map(repr, PARAMETER_CHOICES))} "
            f"(e.g. ('given', 'auto')), got {values!r}", key="parameters",
        )  # fmt: skip
    names = tuple(check_parameter_choice(v, f"parameters[{i}]") for i, v in enumerate(values))
    if not names:
        raise InputError(f"parameters must name at least one of {', '.join(PARAMETER_CHOICES)}, "
                         "got []", key="parameters")  # fmt: skip
    if len(set(names)) != len(names):
        raise InputError(f"parameters must be distinct, got {list(names)!r}", key="parameters")
    return names


# --------------------------------------------------------------------------- summaries


@dataclass(frozen=True)
class FieldErrors:
    """One estimated value's errors over the seeds of a family.

    Attributes
    ----------
    label : str
    error_mean, error_max : float
        Mean and largest error over the seeds with a truth.
    goal : float
    absolute : bool
    """

    label: str
    error_mean: float
    error_max: float
    goal: float
    absolute: bool

    @property
    def met(self) -> bool:
        """Whether the mean error is within the goal."""
        return self.error_mean <= self.goal


@dataclass(frozen=True)
class AutoSummary:
    """The ``"auto"`` runs of one family and prior on K against the given-values runs.

    Attributes
    ----------
    family, k_prior : str
    seeds : tuple of int
        Seeds of the ``"auto"`` runs.
    gospa_ratio_mean, gospa_ratio_max : float or None
        Over the seeds run both ways: mean and largest ``"auto"`` GOSPA over the
        given-values run's (None when no given-values run of a seed ran).
    errors : tuple of FieldErrors
        Per estimated value with a truth, in the order of :func:`auto_fields`.
    """

    family: str
    k_prior: str
    seeds: tuple[int, ...]
    gospa_ratio_mean: float | None
    gospa_ratio_max: float | None
    errors: tuple[FieldErrors, ...]

    @property
    def gospa_met(self) -> bool | None:
        """Whether the mean ratio is at most :data:`AUTO_GOSPA_GOAL` (None without it)."""
        return None if self.gospa_ratio_mean is None else self.gospa_ratio_mean <= AUTO_GOSPA_GOAL

    @property
    def estimates_met(self) -> bool:
        """Whether every value's mean error is within its goal."""
        return all(errors.met for errors in self.errors)


class _Total(Protocol):
    @property
    def total(self) -> float: ...


class BenchRow(Protocol):
    """What :func:`summarize_auto` reads of a run: the fields of that name of
    :class:`mapassoc.apps.bench.RunResult` (a protocol, so that this module need not import
    the benchmark, which imports it)."""

    @property
    def family(self) -> str: ...
    @property
    def k_prior(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def parameters(self) -> str: ...
    @property
    def gospa(self) -> _Total: ...
    @property
    def estimates(self) -> tuple[EstimatedValue, ...] | None: ...


def _gospa_ratio(auto: float, given: float) -> float:
    if given > 0:
        return auto / given
    return 1.0 if auto <= 0 else math.inf


def summarize_auto(runs: Sequence[BenchRow]) -> list[AutoSummary]:
    """Per family and prior on K with ``"auto"`` runs (in the order of the runs), their
    GOSPA over the given-values run's of the same seed and their estimates' errors."""
    keys = list(dict.fromkeys((r.family, r.k_prior) for r in runs if r.parameters == "auto"))
    out = []
    for family, prior in keys:
        mine = [r for r in runs if (r.family, r.k_prior) == (family, prior)]
        given = {r.seed: r for r in mine if r.parameters == "given"}
        auto = [r for r in mine if r.parameters == "auto"]
        ratios = [_gospa_ratio(r.gospa.total, given[r.seed].gospa.total)
                  for r in auto if r.seed in given]  # fmt: skip
        values = [v for r in auto for v in r.estimates or ()]
        errors = []
        for label in dict.fromkeys(v.label for v in values):
            of_label = [v for v in values if v.label == label and v.error is not None]
            if of_label:
                found = [v.error for v in of_label if v.error is not None]
                errors.append(FieldErrors(label, float(np.mean(found)), float(np.max(found)),
                                          of_label[0].goal, of_label[0].absolute))  # fmt: skip
        out.append(AutoSummary(
            family=family, k_prior=prior, seeds=tuple(r.seed for r in auto),
            gospa_ratio_mean=float(np.mean(ratios)) if ratios else None,
            gospa_ratio_max=float(np.max(ratios)) if ratios else None, errors=tuple(errors),
        ))  # fmt: skip
    return out


# --------------------------------------------------------------------------- printing


def _number(value: float) -> str:
    return f"{value:.3g}"


def _error_text(error: float | None, absolute: bool) -> str:
    """An absolute error as a number, a relative one in per cent, or past 100% as the
    estimate over the truth (an estimate below the truth is less than 100% off)."""
    if error is None:
        return "no truth"
    if absolute:
        return f"{error:.3f}"
    return f"{100 * error:.0f}%" if error < 1 else f"{1 + error:.3g}x the truth"


def estimates_line(values: Sequence[EstimatedValue]) -> str:
    """The line under an ``"auto"`` run's: each estimate, the truth and the error."""
    cells = [
        f"{v.label} {_number(v.estimate)}"
        + ("" if v.truth is None
           else f" (true {_number(v.truth)}, {_error_text(v.error, v.absolute)})")
        for v in values
    ]  # fmt: skip
    return "    auto estimates: " + ", ".join(cells)


def _mark_text(met: bool | None) -> str:
    return "" if met is None else ("met" if met else "NOT met")


def _errors_text(summary: AutoSummary) -> str:
    return ", ".join(
        f"{e.label} {_error_text(e.error_mean, e.absolute)} (max "
        f"{_error_text(e.error_max, e.absolute)})"
        for e in summary.errors
    )


def _ratio_text(summary: AutoSummary) -> str:
    if summary.gospa_ratio_mean is None or summary.gospa_ratio_max is None:
        return "GOSPA over the given values' run: not run (add given to parameters)"
    return (
        f"GOSPA {summary.gospa_ratio_mean:.3f}x the given values' run (max "
        f"{summary.gospa_ratio_max:.3f}) [goal <= {AUTO_GOSPA_GOAL:g}x: "
        f"{_mark_text(summary.gospa_met)}]"
    )


def auto_summary_line(summary: AutoSummary) -> str:
    """A family's ``"auto"`` summary: the GOSPA ratio and the mean errors, with goals."""
    return (
        f"  => {summary.family} (k_prior {summary.k_prior}) auto, {len(summary.seeds)} "
        f"seed(s): {_ratio_text(summary)}; mean errors {_errors_text(summary)} [goal "
        f"{100 * RELATIVE_GOAL:.0f}%, Pd {PD_GOAL:g}: {_mark_text(summary.estimates_met)}]"
    )


def auto_goals_text(summaries: Sequence[AutoSummary]) -> str:
    """The goals of ``"auto"`` over every family, one line each."""
    ratios = [s for s in summaries if s.gospa_ratio_mean is not None]
    lines = [f"goals of parameters auto (k_prior {summaries[0].k_prior}):"]
    if ratios:
        worst = max(ratios, key=lambda s: s.gospa_ratio_mean or 0.0)
        missed = [s.family for s in ratios if not s.gospa_met]
        lines.append(
            f"  auto GOSPA <= {AUTO_GOSPA_GOAL:g}x the given values' (mean over seeds) in "
            f"every family: worst {worst.gospa_ratio_mean:.3f}x ({worst.family}) "
            + ("met" if not missed else f"NOT met in {', '.join(missed)}")
        )
    else:
        lines.append("  auto GOSPA over the given values': not run (add given to parameters)")
    missed = [f"{s.family} ({', '.join(e.label for e in s.errors if not e.met)})"
              for s in summaries if not s.estimates_met]  # fmt: skip
    lines.append(
        f"  estimates within {100 * RELATIVE_GOAL:.0f}% of the truth (Pd within {PD_GOAL:g}) "
        "in every family: " + ("met" if not missed else f"NOT met in {'; '.join(missed)}")
    )
    return "\n".join(lines)
