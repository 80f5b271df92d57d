"""TOML configuration: motion model, sensors, birth model and estimator settings.

Schema (unknown keys anywhere are an error; every value is checked)::

    [recording]                   # optional: a user's own file (mapassoc.data.recording)
    frame = "geodetic"            # "local" (x, y metres) or "geodetic" (lat, lon degrees)
    origin = {latitude = 52.3, longitude = 4.76, height = 0.0}   # or "auto"
    angles = "degrees"            # azimuth and elevation: "degrees" or "radians"
    # in a geodetic recording a range_bearing sensor is placed by latitude = ...,
    # longitude = ..., height = ... (metres; needed with an elevation column) instead
    # of position = [x, y]; regions are in metres from the origin

    [motion]
    model = "constant_velocity"   # constant_velocity | constant_acceleration | random_walk
                                  # | coordinated_turn | constant_turn | singer | imm
    ndim = 2                      # 1, 2 or 3; linear models only (coordinated_turn is 2-D)
    noise_intensity = 0.5         # constant_velocity, constant_acceleration, random_walk;
                                  # or "auto" (estimated from the recording)
    # noise_intensity_start = 2.0 # with "auto" only: the first pass's value
    # coordinated_turn instead: speed_noise_intensity = ..., turn_rate_noise_intensity = ...
    # singer instead: ndim, time_constant = ... (tau > 0), acceleration_std = ... (> 0)
    # constant_turn (2-D, constant_velocity's state) instead: turn_rate = ... (rad per
    # unit time, any sign), noise_intensity = ...
    # (the keys of each model: mapassoc.models.motion.MOTION_REGISTRY)
    # imm (interacting multiple models) instead: model = "imm", switch_probability = ...
    # (leaving the current model within one unit of time) or matrix = [[...], ...]
    # (M x M, per unit of time), optional initial_probabilities = [...] (default
    # uniform), and one [[motion.models]] table per model, each keyed as a single
    # [motion] table, all in one state space (mapassoc.models.interacting); a
    # component's noise_intensity may be "auto" (with its own noise_intensity_start),
    # the set's [motion] table takes none

    [[sensors]]                   # one table per sensor, at least one, distinct names
    name = "radar"
    measurement = "position"      # position | range_bearing (the keys of each:
                                  # mapassoc.models.measurement.MEASUREMENT_REGISTRY)
    noise_std = 1.0               # position: a number, or one std per position component,
                                  # or "auto" (estimated: one std for all components)
    # noise_std_start = 2.0       # with "auto" only: the first pass's std; one per
                                  # component ([2.0, 3.0]) estimates each on its own
    # range_bearing instead: position = [x, y], range_std = ..., bearing_std = ... (radians);
    # needs a motion model with a 2-D position (ndim = 2, or coordinated_turn)
    detection_probability = 0.9   # Pd in (0, 1], or "auto" (estimated from the recording)
    # detection_probability_start = 0.95  # with "auto" only: the first pass's Pd
    false_alarms_per_scan = 10.0  # expected false alarms per scan, > 0 (1e-6 for almost
                                  # no clutter), or "auto"
    region = [[-100.0, 100.0], [-100.0, 100.0]]   # one [low, high] per measured component

    [birth]        # optional; keys and defaults: the fields of mapassoc.data.settings.BirthModel
    # rate, initial_count, survival_probability and velocity_std may each be "auto"
    # (estimated from the recording), with an optional <key>_start (the first pass's value)

    # optional: the estimator's settings, one table per component it configures; keys
    # and defaults: the fields of each record of mapassoc.data.settings.EstimatorSettings
    [estimator.windows]     # WindowSettings: window_length, stride, time_limit
    [estimator.pruning]     # PruningSettings: gating, the trees' cap and pruning rules
    [estimator.search]      # SearchSettings: the per-cluster solve, integer programs
    [estimator.count]       # CountSettings: Kmax, the prior on K, which K is reported
    [estimator.refinement]  # RefinementSettings: the whole recording's refinement
    [estimator.parameters]  # ParameterSettings: the EM of "auto" sensor parameters

    [trackers.mht] # optional, one table per baseline tracker (mapassoc.trackers.registry):
    n_scan = 4     # its own keyword options, numbers, booleans or strings; checked when
                   # the tracker is built (mapassoc compare), names against the registry
                   # when the caller passes them (tracker_names)

The estimator's tables are sub-tables of ``[estimator]`` rather than sections of their
own: a dotted key path is then the attribute path (``estimator.windows.time_limit`` in a
file and in an error is ``config.estimator.windows.time_limit``), as
``[trackers.<name>]`` is ``config.trackers[name]``; everything the estimator reads stays
under one name, apart from the model (``[motion]``, ``[[sensors]]``, ``[birth]``); and
``[estimator]`` keeps its meaning for the missing-section warning below.  The old flat
``[estimator]`` keys (``window_length = 5`` directly in ``[estimator]``) still load, each
setting what :data:`~mapassoc.data.settings.FLAT_KEYS` says, with one
``DeprecationWarning`` naming the keys that replace them (``mapassoc migrate-config``
rewrites such a file); a setting given both ways is an error.

The ``[birth]`` and ``[estimator]`` sections are optional by design (every field has a
default), but :func:`load_config` warns (``UserWarning``) when one is missing, naming
the file and the defaults used: a forgotten section silently changes the model.

``"auto"`` leaves a sensor's ``detection_probability`` or ``false_alarms_per_scan``, a
position sensor's ``noise_std`` or the ``noise_intensity`` of a model whose process noise
is that number times a fixed matrix (:data:`AUTO_NOISE_MODELS`), in ``[motion]`` or in a
component's ``[[motion.models]]`` table of an IMM set (each component its own), to be
estimated from the recording (:mod:`mapassoc.estimator.parameters`, which ``mapassoc
run`` calls before the run): :attr:`Config.auto` lists them, the model holds
placeholders (``Pd`` = 1, no false alarms, noise levels :data:`NOISE_PLACEHOLDER`) until
then, and :func:`check_config` refuses such a configuration to anything that would run
on the placeholders.  The ``[birth]`` model's ``rate``, ``initial_count``,
``survival_probability`` and ``velocity_std`` may be ``"auto"`` too, each on its own
(:data:`AUTO_BIRTH_KEYS`, estimated by :mod:`mapassoc.estimator.birth_estimation`;
``velocity_std`` only for a motion model with velocity components); until then the
birth model holds :data:`BIRTH_PLACEHOLDERS`.  ``"auto"`` is refused, naming its key,
for the noise of the other models (coordinated turn, Singer, as an IMM component too)
and of range-bearing sensors: their noise has no single scale the EM update takes.  A
pooled ``noise_std`` is the default because the schema's one number already means ``R =
sigma^2 I``; a ``noise_std_start`` with one value per component asks for each to be
estimated.

``[trackers.<name>]`` tables belong to the baseline trackers of ``mapassoc compare``
(GNN, JPDA, MHT, network flow, LP relaxation): each holds options of that tracker's own
(``MhtTracker(n_scan=...)``), which the tracker registry hands to it when it builds it
and checks there, since this layer may not import the trackers.  The MAP estimator's own
settings stay under ``[estimator]``.

``estimator.search.solver`` is a name of the solver registry, which this layer may not import
(``tests/test_architecture.py``): the caller that wires the solvers passes the names it
accepts as ``solver_names`` (for example the integer-capable ones of
``mapassoc.solvers.available_solvers()``), and an unknown name is then a
:class:`~mapassoc.errors.ConfigError` naming the file and ``estimator.search.solver``
(``estimator.solver`` when the file gives it under its old flat key).

Key paths in errors are dotted, with 0-based indices for arrays: ``sensors[1].region[0]`` is
the first row of the region of the second ``[[sensors]]`` table.  Integer settings must be
TOML integers (``5``, not ``5.0``); numbers may be TOML integers or floats; booleans are
never numbers.  ``prune_log_ratio = inf`` (a TOML float literal) disables that pruning.

:func:`config_to_toml` writes the same schema (every key explicit, floats with ``repr`` so
that reading back reproduces them exactly).
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
import warnings
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from mapassoc.data.frames import GeodeticPoint, LocalFrame
from mapassoc.data.recording import Recording
from mapassoc.data.settings import COMPONENTS, FLAT_KEYS, EstimatorSettings
from mapassoc.errors import ConfigError, InputError
from mapassoc.models.interacting import InteractingModels
from mapassoc.models.measurement import (
    MEASUREMENT_REGISTRY,
    MeasurementModel,
    SettingValue,
    measurement_spec,
)
from mapassoc.models.motion import MOTION_REGISTRY, MotionModel, motion_spec
from mapassoc.models.population import BirthModel
from mapassoc.models.sensor import Region, Sensor
from mapassoc.models.switching import SwitchingLaw
from mapassoc.validation import (
    check_instance,
    check_names,
    check_nonnegative,
    check_path,
    check_positive,
    check_probability,
)

__all__ = [
    "AUTO",
    "AutoParameters",
    "AUTO_NOISE_MODELS",
    "NOISE_PLACEHOLDER",
    "AUTO_BIRTH_KEYS",
    "BIRTH_PLACEHOLDERS",
    "Config",
    "TrackerOption",
    "check_config",
    "MOTION_MODELS",
    "MEASUREMENTS",
    "load_config",
    "parse_config",
    "config_to_toml",
    "write_config",
]

PathLike = str | os.PathLike[str]

IMM = "imm"
"""``[motion] model = "imm"``: interacting multiple models
(:class:`~mapassoc.models.interacting.InteractingModels`), read and written here rather
than registered in :data:`~mapassoc.models.motion.MOTION_REGISTRY`, whose models are
single ones with flat settings; this one's models are nested ``[[motion.models]]`` tables."""
MOTION_MODELS = (*MOTION_REGISTRY, IMM)
"""Motion model names a configuration may give: those registered when this module was
imported (see :data:`mapassoc.models.motion.MOTION_REGISTRY`, which the reader and
writer use), and ``"imm"`` (interacting multiple models)."""
MEASUREMENTS = tuple(MEASUREMENT_REGISTRY)
"""Measurement model names registered when this module was imported (see
:data:`mapassoc.models.measurement.MEASUREMENT_REGISTRY`, which the reader and writer use)."""

_SECTIONS = ("recording", "motion", "sensors", "birth", "estimator", "trackers")

TrackerOption = bool | int | float | str
"""The value of a tracker's option in a ``[trackers.<name>]`` table."""
_StdStart = tuple[str, tuple[float, ...] | None]
"""A sensor whose ``noise_std`` is "auto", with its start."""
POSITION = "position"
"""The measurement model whose ``noise_std`` may be ``"auto"``."""
_SENSOR_COMMON_KEYS = (
    "name",
    "measurement",
    "detection_probability",
    "detection_probability_start",
    "false_alarms_per_scan",
    "region",
)
AUTO = "auto"
"""The value of a parameter left to be estimated from the recording."""
NOISE_PLACEHOLDER = 1.0
"""What a ``noise_intensity`` or ``noise_std`` of ``"auto"`` holds until it is estimated
(any positive number builds the model; :func:`check_config` refuses to run on it)."""
AUTO_NOISE_MODELS = ("constant_velocity", "constant_acceleration", "random_walk")
"""The motion models whose ``noise_intensity`` may be ``"auto"``: their process noise is
``noise_intensity`` times a fixed matrix, the form the EM update of
:mod:`mapassoc.filtering.noise_estimation` takes (coordinated turn and Singer have no
such single scale, nor has a set of models as a whole: its components of these models
may each be ``"auto"``)."""
AUTO_BIRTH_KEYS = ("rate", "initial_count", "survival_probability", "velocity_std")
"""The ``[birth]`` keys that may be ``"auto"``: the others (``acceleration_std``,
``speed_std``, ``turn_rate_std``) have no M step from the tracks yet."""
BIRTH_PLACEHOLDERS = {
    "rate": 0.0, "initial_count": 0.0, "survival_probability": 1.0, "velocity_std": 1.0,
}  # fmt: skip
"""What an ``"auto"`` ``[birth]`` key holds until it is estimated (valid values of
:class:`BirthModel`; :func:`check_config` refuses to run on them)."""
_DOCUMENT_KEY = "<file>"
"""Key reported for problems with the whole document (unreadable file, TOML syntax)."""


@dataclass(frozen=True)
class AutoParameters:
    """The sensor parameters a configuration leaves to the recording (``"auto"``).

    Attributes
    ----------
    false_alarms : tuple of str
        Sensors whose ``false_alarms_per_scan`` is estimated.
    detection_probability : tuple of (str, float or None)
        Sensors whose ``detection_probability`` is estimated, each with its
        ``detection_probability_start`` (None: the estimator's default start).
    noise_intensity : bool
        Whether ``[motion] noise_intensity`` is estimated (the motion model then holds
        the placeholder :data:`NOISE_PLACEHOLDER`).
    noise_intensity_start : float or None
        Its ``noise_intensity_start`` (None: the estimator's default start).
    noise_std : tuple of (str, tuple of float or None)
        Position sensors whose ``noise_std`` is estimated, each with its
        ``noise_std_start``: None (the estimator's default start, one pooled std), one
        number (pooled) or one per position component (each estimated on its own).
    birth : tuple of (str, float or None)
        The ``[birth]`` keys estimated (of :data:`AUTO_BIRTH_KEYS`, in that order), each
        with its ``<key>_start`` (None: the estimator's default start); the birth model
        holds :data:`BIRTH_PLACEHOLDERS` for them.
    model_noise_intensity : tuple of (int, float or None)
        The components of an interacting-multiple-model set whose ``noise_intensity`` is
        estimated, each by its index (its position in ``[[motion.models]]``, increasing)
        with its ``noise_intensity_start`` (None: the estimator's default start); each
        such component holds :data:`NOISE_PLACEHOLDER`.  Per component rather than one
        flag for the set: the components exist to move with different intensities.
    """

    false_alarms: tuple[str, ...] = ()
    detection_probability: tuple[tuple[str, float | None], ...] = ()
    noise_intensity: bool = False
    noise_intensity_start: float | None = None
    noise_std: tuple[tuple[str, tuple[float, ...] | None], ...] = ()
    birth: tuple[tuple[str, float | None], ...] = ()
    model_noise_intensity: tuple[tuple[int, float | None], ...] = ()

    @property
    def pending(self) -> bool:
        """Whether any parameter is still to be estimated."""
        return bool(
            self.false_alarms or self.detection_probability or self.noise_intensity
            or self.noise_std or self.birth or self.model_noise_intensity
        )  # fmt: skip

    def model_noise_starts(self) -> dict[int, float | None]:
        """``{index: start}`` of the ``[[motion.models]]`` components whose
        ``noise_intensity`` is estimated."""
        return dict(self.model_noise_intensity)

    def birth_starts(self) -> dict[str, float | None]:
        """``{key: start}`` of the ``[birth]`` keys estimated."""
        return dict(self.birth)

    def pd_starts(self) -> dict[str, float | None]:
        """``{sensor: start}`` of the sensors whose ``Pd`` is estimated."""
        return dict(self.detection_probability)

    def noise_std_starts(self) -> dict[str, tuple[float, ...] | None]:
        """``{sensor: start}`` of the position sensors whose ``noise_std`` is estimated
        (a start of one value: one pooled std; of one per component: each its own)."""
        return dict(self.noise_std)

    def names(self) -> list[str]:
        """The parameters still to be estimated, as messages name them."""
        out = ['motion.noise_intensity'] if self.noise_intensity else []
        out += [f"motion.models[{i}].noise_intensity" for i in self.model_noise_starts()]
        out += [f"sensor '{n}' false_alarms_per_scan" for n in self.false_alarms]
        out += [f"sensor '{n}' detection_probability" for n in self.pd_starts()]
        out += [f"sensor '{n}' noise_std" for n in self.noise_std_starts()]
        out += [f"birth.{key}" for key in self.birth_starts()]
        return out


@dataclass(frozen=True, eq=False)
class Config:
    """Everything a run needs besides data.

    Parameters
    ----------
    motion : MotionModel
        Target motion model.
    sensors : dict of str to Sensor
        Sensors by name, in file order (the first sensor fixes the detections-file column
        order).  At least one.
    birth : BirthModel
        Birth and survival model.
    estimator : EstimatorSettings
        Window estimator settings.
    source : str, optional
        The file the configuration came from, for messages.
    auto : AutoParameters
        Sensor parameters still to be estimated from the recording (``"auto"`` in the
        file); their sensors hold placeholders until
        :func:`mapassoc.estimator.parameters.estimate_parameters` fills them in.
    trackers : mapping of str to mapping of str to bool, int, float or str
        Options of the baseline trackers by tracker name (``[trackers.<name>]`` tables),
        handed to each tracker by :func:`mapassoc.trackers.registry.build_tracker`; empty
        (default): every tracker with its defaults.
    recording : Recording, optional
        The ``[recording]`` section: the file's kind of time and frame
        (:mod:`mapassoc.data.recording`); None: plain seconds in the local frame, read by
        :func:`mapassoc.data.io.read_detections`.
    """

    motion: MotionModel
    sensors: dict[str, Sensor]
    birth: BirthModel
    estimator: EstimatorSettings
    source: str | None = None
    auto: AutoParameters = AutoParameters()
    trackers: Mapping[str, Mapping[str, TrackerOption]] = dataclasses.field(
        default_factory=dict
    )
    recording: Recording | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.motion, MotionModel):
            raise InputError(f"motion must be a MotionModel, got {self.motion!r}")
        if not isinstance(self.sensors, Mapping) or len(self.sensors) == 0:
            raise InputError(
                f"sensors must be a non-empty mapping name -> Sensor, got {self.sensors!r}"
            )
        for name, sensor in self.sensors.items():
            if not isinstance(sensor, Sensor):
                raise InputError(f"sensors[{name!r}] must be a Sensor, got {sensor!r}")
            if sensor.name != name:
                raise InputError(
                    f"sensors key {name!r} differs from the sensor's name {sensor.name!r}"
                )
            _check_measurement_fits_motion(sensor.measurement, self.motion, name)
        if not isinstance(self.birth, BirthModel):
            raise InputError(f"birth must be a BirthModel, got {self.birth!r}")
        if not isinstance(self.estimator, EstimatorSettings):
            raise InputError(f"estimator must be an EstimatorSettings, got {self.estimator!r}")
        if self.source is not None and not isinstance(self.source, str):
            raise InputError(f"source must be a string or None, got {self.source!r}")
        if not isinstance(self.auto, AutoParameters):
            raise InputError(f"auto must be an AutoParameters, got {self.auto!r}")
        for name in (*self.auto.false_alarms, *self.auto.pd_starts(),
                     *self.auto.noise_std_starts()):  # fmt: skip
            if name not in self.sensors:
                raise InputError(
                    f"auto names sensor {name!r}, which is not configured "
                    f"(known: {sorted(self.sensors)})"
                )
        _check_auto_components(self.auto, self.motion)
        if self.recording is not None and not isinstance(self.recording, Recording):
            raise InputError(f"recording must be a Recording or None, got {self.recording!r}")
        object.__setattr__(self, "sensors", dict(self.sensors))
        object.__setattr__(self, "trackers", _checked_tracker_options(self.trackers))


def _check_auto_components(auto: AutoParameters, motion: MotionModel) -> None:
    """``auto.model_noise_intensity`` names components of ``motion``, an IMM set: distinct
    indices in increasing order (the order :func:`parse_config` gives and the writer and
    the estimator keep), each start None or a positive number (raises InputError).
    Whether a component's process noise has the one scale "auto" needs is left to the
    estimator, as for ``auto.noise_intensity``."""
    entries = auto.model_noise_intensity
    if not entries:
        return
    if not isinstance(motion, InteractingModels):
        raise InputError(
            f"auto.model_noise_intensity names components {[e[0] for e in entries]!r} of a "
            f"set of motion models, but the motion model is not one: {motion!r}"
        )
    previous = -1
    for entry in entries:
        index, start = entry if isinstance(entry, tuple) and len(entry) == 2 else (None, None)
        if not isinstance(index, int) or isinstance(index, bool) or not (
            previous < index < len(motion.models)
        ):
            raise InputError(
                f"auto.model_noise_intensity must be (index, start) pairs of distinct "
                f"components 0..{len(motion.models) - 1} in increasing order, got {entries!r}"
            )
        if start is not None:
            check_positive(f"auto.model_noise_intensity start of component {index}", start)
        previous = index


def _checked_tracker_options(
    trackers: object,
) -> dict[str, dict[str, TrackerOption]]:
    """A copy of ``Config.trackers`` after checking its shape (raises InputError)."""
    if not isinstance(trackers, Mapping):
        raise InputError(
            f"trackers must be a mapping tracker name -> options, got {trackers!r}",
            key="trackers",
        )
    out: dict[str, dict[str, TrackerOption]] = {}
    for name, options in trackers.items():
        if not isinstance(name, str) or not name:
            raise InputError(f"trackers: a tracker name must be a string, got {name!r}")
        if not isinstance(options, Mapping):
            raise InputError(
                f"trackers.{name} must be a table of options, got {options!r}",
                key=f"trackers.{name}",
            )
        out[name] = {}
        for option, value in options.items():
            key = f"trackers.{name}.{option}"
            if not isinstance(option, str) or not option:
                raise InputError(
                    f"trackers.{name}: an option name must be a string, got {option!r}"
                )
            if not isinstance(value, (bool, int, float, str)) or (
                isinstance(value, float) and math.isnan(value)
            ):
                raise InputError(
                    f"{key} must be a number, a boolean or a string, got {value!r}", key=key
                )
            out[name][option] = value
    return out


def check_config(
    config: object, *, argument: str = "config", allow_auto: bool = False
) -> Config:
    """``config`` if it is a :class:`Config`, else an InputError saying how to get one.

    The estimator and every tracker take a ``Config`` object, not a file name: a path
    is loaded with :func:`load_config`, a parsed TOML document with
    :func:`parse_config`, and a scenario's is ``build_scenario(name).config``.  A
    configuration with ``"auto"`` parameters still to be estimated is refused too
    (unless ``allow_auto``): its sensors hold placeholders.
    """
    if isinstance(config, Config):
        if config.auto.pending and not allow_auto:
            names = config.auto.names()
            raise InputError(
                f"{argument} leaves {', '.join(names)} = \"auto\"; estimate them from the "
                "recording first: mapassoc.estimate_parameters(config, scans).config (what "
                "`mapassoc run` does), or give numbers"
            )
        return config
    kind = type(config).__name__
    if isinstance(config, (str, bytes)) or hasattr(config, "__fspath__"):
        hint = f"load the file first: config=mapassoc.load_config({config!r})"
    elif isinstance(config, Mapping):
        hint = "build one from a parsed TOML document with mapassoc.parse_config(data)"
    else:
        hint = (
            "load one with mapassoc.load_config(path) or build one with "
            "mapassoc.Config(motion=..., sensors=..., birth=..., estimator=...)"
        )
    raise InputError(
        f"{argument} must be a Config (mapassoc.Config), got {kind} {config!r:.80}; {hint}"
    )


def _check_measurement_fits_motion(
    measurement: MeasurementModel, motion: MotionModel, sensor_name: str
) -> None:
    problem = measurement.motion_mismatch(motion)
    if problem is not None:
        raise InputError(f"sensor {sensor_name!r}: {problem}")


# --------------------------------------------------------------------------- parsing


class _Parser:
    """Typed access to TOML values; every failure is a ConfigError naming the key."""

    def __init__(self, *, source: str | None) -> None:
        self.source = source

    def fail(self, key: str, message: str) -> ConfigError:
        return ConfigError(key, message, source=self.source)

    def table(self, value: object, key: str) -> Mapping[str, object]:
        if not isinstance(value, Mapping):
            raise self.fail(key, f"must be a table, got {value!r}")
        return value

    def only_keys(
        self, table: Mapping[str, object], prefix: str, allowed: tuple[str, ...], context: str
    ) -> None:
        for name, value in table.items():
            if name not in allowed:
                raise self.fail(
                    f"{prefix}.{name}" if prefix else name,
                    f"unknown key (value {value!r}); allowed keys {context}: {', '.join(allowed)}",
                )

    def required(self, table: Mapping[str, object], prefix: str, name: str) -> object:
        if name not in table:
            raise self.fail(f"{prefix}.{name}", "missing required key")
        return table[name]

    def number(self, value: object, key: str) -> float:
        """A TOML integer or float (not a boolean, not a string), as float."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"must be a number, got {value!r}")
        return float(value)

    def integer(self, value: object, key: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(key, f"must be a TOML integer (such as 5, not 5.0), got {value!r}")
        return value

    def string(self, value: object, key: str) -> str:
        if not isinstance(value, str):
            raise self.fail(key, f"must be a string, got {value!r}")
        return value

    def choice(self, value: object, key: str, options: tuple[str, ...]) -> str:
        text = self.string(value, key)
        if text not in options:
            raise self.fail(key, f"must be one of {', '.join(options)}; got {text!r}")
        return text

    def array(self, value: object, key: str) -> list[object]:
        if not isinstance(value, list):
            raise self.fail(key, f"must be an array, got {value!r}")
        return value

    def positive(self, value: object, key: str) -> float:
        return self._range(check_positive, value, key)

    def nonnegative(self, value: object, key: str) -> float:
        return self._range(check_nonnegative, value, key)

    def probability(self, value: object, key: str) -> float:
        number = self.number(value, key)
        try:
            return check_probability(_leaf(key), number, allow_zero=False)
        except InputError as exc:
            raise self.fail(key, str(exc)) from None

    def finite(self, value: object, key: str) -> float:
        number = self.number(value, key)
        if not math.isfinite(number):
            raise self.fail(key, f"must be finite, got {value!r}")
        return number

    def _range(self, check: Callable[[str, object], float], value: object, key: str) -> float:
        number = self.number(value, key)
        try:
            return check(_leaf(key), number)
        except InputError as exc:
            raise self.fail(key, str(exc)) from None


def _subkey(prefix: str, exc: InputError) -> str:
    """The key of a model's error: ``prefix.<exc.key>`` when the model named its setting
    (``sensors[0].noise_std``), else the whole table ``prefix``."""
    return prefix if exc.key is None else f"{prefix}.{exc.key}"


def _leaf(key: str) -> str:
    """Last component of a dotted key: ``"sensors[0].noise_std"`` -> ``"noise_std"``."""
    return key.rsplit(".", 1)[-1]


_IMM_KEYS = ("model", "switch_probability", "matrix", "initial_probabilities", "models")


def _parse_motion(
    parser: _Parser, data: Mapping[str, object]
) -> tuple[MotionModel, AutoParameters]:
    """The motion model and what of its noise is "auto": an :class:`AutoParameters` with
    only ``noise_intensity``, ``noise_intensity_start`` (a single model) or
    ``model_noise_intensity`` (the components of an IMM set) filled in."""
    if "motion" not in data:
        raise parser.fail("motion", "missing required section [motion]")
    table = parser.table(data["motion"], "motion")
    if table.get("model") == IMM:
        imm, components = _parse_imm(parser, table)
        return imm, AutoParameters(model_noise_intensity=components)
    table, auto, start = _auto_noise_intensity(parser, table)
    motion = _parse_single_motion(parser, table, "motion", (*MOTION_REGISTRY, IMM))
    return motion, AutoParameters(noise_intensity=auto, noise_intensity_start=start)


def _auto_start(
    parser: _Parser, table: Mapping[str, object], prefix: str, key: str, auto: bool
) -> object | None:
    """The raw ``<key>_start`` of a table (None where absent), refused unless ``key`` is
    "auto": a start is the first pass's value of an estimated parameter, and means
    nothing for a given one."""
    start_key = f"{key}_start"
    if start_key not in table:
        return None
    if not auto:
        raise parser.fail(
            f"{prefix}.{start_key}", f'only goes with {key} = "auto"; remove it or write '
            f'{key} = "auto"',
        )  # fmt: skip
    return table[start_key]


def _auto_noise_intensity(
    parser: _Parser, table: Mapping[str, object], prefix: str = "motion"
) -> tuple[Mapping[str, object], bool, float | None]:
    """A single model's table (``[motion]``, or the ``[[motion.models]]`` item ``prefix``
    names) with an "auto" ``noise_intensity`` replaced by the placeholder and
    ``noise_intensity_start`` taken out: ``(table, auto, start)``.  The model is checked
    before its keys, so that "auto" of a model without that scale names
    ``<prefix>.noise_intensity`` rather than an unknown key."""
    auto = table.get("noise_intensity") == AUTO
    given = _auto_start(parser, table, prefix, "noise_intensity", auto)
    start = None if given is None else parser.positive(given, f"{prefix}.noise_intensity_start")
    if not auto:
        return table, False, None
    if table.get("model") not in AUTO_NOISE_MODELS:
        raise parser.fail(
            f"{prefix}.noise_intensity", f'"auto" needs model = one of '
            f"{list(AUTO_NOISE_MODELS)}, got {table.get('model')!r}",
        )  # fmt: skip
    rest = {key: value for key, value in table.items() if key != "noise_intensity_start"}
    rest["noise_intensity"] = NOISE_PLACEHOLDER
    return rest, True, start


def _parse_single_motion(
    parser: _Parser, table: Mapping[str, object], prefix: str, names: tuple[str, ...]
) -> MotionModel:
    """One registered motion model from ``table`` (``[motion]`` or one of
    ``[[motion.models]]``); ``names`` are the ``model`` values the error lists."""
    model = parser.choice(parser.required(table, prefix, "model"), f"{prefix}.model", names)
    if model not in MOTION_REGISTRY:  # "imm" inside an imm
        raise parser.fail(
            f"{prefix}.model", f"an {IMM!r} model's models must be single models, got {model!r}"
        )
    spec = MOTION_REGISTRY[model]
    parser.only_keys(table, prefix, spec.keys, spec.context)
    values: dict[str, object] = {}
    for setting in spec.settings:
        key = f"{prefix}.{setting.key}"
        raw = parser.required(table, prefix, setting.key)
        if raw == AUTO:  # an "auto" noise_intensity was replaced before
            raise parser.fail(
                key, '"auto" is only for [motion] noise_intensity (or a [[motion.models]] '
                f"one) of {', '.join(AUTO_NOISE_MODELS)} (not coordinated_turn or singer); "
                "give a number",
            )  # fmt: skip
        if setting.kind == "ndim":
            ndim = parser.integer(raw, key)
            if ndim not in (1, 2, 3):
                raise parser.fail(key, f"must be 1, 2 or 3 spatial dimensions, got {ndim!r}")
            values[setting.key] = ndim
        elif setting.kind == "real":
            values[setting.key] = parser.finite(raw, key)
        else:
            values[setting.key] = parser.positive(raw, key)
    try:
        motion: MotionModel = spec.cls(**values)
    except InputError as exc:  # a model's own checks of its settings (key: the setting)
        raise parser.fail(_subkey(prefix, exc), str(exc)) from None
    return motion


def _parse_imm(
    parser: _Parser, table: Mapping[str, object]
) -> tuple[InteractingModels, tuple[tuple[int, float | None], ...]]:
    """``[motion] model = "imm"``: its ``[[motion.models]]``, each read as a ``[motion]``
    table (its ``noise_intensity`` may be "auto"), the switching law
    (``switch_probability`` or ``matrix``) and the optional ``initial_probabilities``;
    with the ``(index, start)`` of each "auto" component.  The set's own table takes no
    ``noise_intensity``: the set has no single scale, each component its own."""
    parser.only_keys(table, "motion", _IMM_KEYS, f"for {IMM}")
    raw = parser.required(table, "motion", "models")
    if not isinstance(raw, list) or not raw or not all(isinstance(t, Mapping) for t in raw):
        raise parser.fail(
            "motion.models", f"must be a non-empty array of tables [[motion.models]], got {raw!r}"
        )
    models: list[MotionModel] = []
    components: list[tuple[int, float | None]] = []
    for index, item in enumerate(raw):
        prefix = f"motion.models[{index}]"
        component, auto, start = _auto_noise_intensity(parser, item, prefix)
        models.append(_parse_single_motion(parser, component, prefix, (*MOTION_REGISTRY, IMM)))
        if auto:
            components.append((index, start))
    given = [key for key in ("switch_probability", "matrix") if key in table]
    if len(given) != 1:
        raise parser.fail(
            "motion", f"an {IMM!r} model needs exactly one of switch_probability and matrix, "
            f"got {given or 'neither'}"
        )  # fmt: skip
    key = f"motion.{given[0]}"
    value = table[given[0]]
    if key == "motion.matrix":
        value = [parser.array(row, f"{key}[{i}]") for i, row in enumerate(parser.array(value, key))]
    elif isinstance(value, bool) or not isinstance(value, (int, float)):
        raise parser.fail(key, f"must be a number, got {value!r}")
    probabilities = table.get("initial_probabilities")
    if probabilities is not None:
        parser.array(probabilities, "motion.initial_probabilities")
    try:
        law = SwitchingLaw(len(models), **{given[0]: value})  # type: ignore[arg-type]
    except InputError as exc:
        raise parser.fail(key, str(exc)) from None
    try:
        motion = InteractingModels(
            models=models,
            switching=law,
            initial_probabilities=probabilities,  # type: ignore[arg-type]
        )
    except InputError as exc:
        raise parser.fail(_subkey("motion", exc), str(exc)) from None
    return motion, tuple(components)


def _parse_region(
    parser: _Parser, value: object, key: str, component_names: tuple[str, ...]
) -> Region:
    rows = parser.array(value, key)
    if len(rows) != len(component_names):
        raise parser.fail(
            key,
            f"has {len(rows)} rows {rows!r}; expected one [low, high] per measured component "
            f"({', '.join(component_names)}), {len(component_names)} rows",
        )
    lower: list[float] = []
    upper: list[float] = []
    for index, row in enumerate(rows):
        row_key = f"{key}[{index}]"
        pair = parser.array(row, row_key)
        if len(pair) != 2:
            raise parser.fail(row_key, f"must be a [low, high] pair, got {row!r}")
        low = parser.finite(pair[0], f"{row_key}[0]")
        high = parser.finite(pair[1], f"{row_key}[1]")
        if not high > low:
            raise parser.fail(
                row_key,
                f"empty interval {row!r} for component {component_names[index]!r}; "
                "expected low < high",
            )
        lower.append(low)
        upper.append(high)
    try:
        return Region(lower=np.array(lower), upper=np.array(upper))
    except InputError as exc:  # the volume: finite and > 0
        raise parser.fail(key, str(exc)) from None


class _SensorSettings:
    """The :class:`~mapassoc.models.measurement.SettingsReader` of one ``[[sensors]]`` table."""

    def __init__(self, parser: _Parser, table: Mapping[str, object], prefix: str) -> None:
        self._parser = parser
        self._table = table
        self._prefix = prefix

    def _key(self, key: str) -> str:
        return f"{self._prefix}.{key}"

    def _raw(self, key: str) -> object:
        return self._parser.required(self._table, self._prefix, key)

    def fail(self, key: str, message: str) -> ConfigError:
        return self._parser.fail(self._key(key), message)

    def number(self, key: str) -> float:
        return self._parser.number(self._raw(key), self._key(key))

    def integer(self, key: str) -> int:
        return self._parser.integer(self._raw(key), self._key(key))

    def string(self, key: str) -> str:
        return self._parser.string(self._raw(key), self._key(key))

    def positive(self, key: str) -> float:
        return self._parser.positive(self._raw(key), self._key(key))

    def nonnegative(self, key: str) -> float:
        return self._parser.nonnegative(self._raw(key), self._key(key))

    def finite(self, key: str) -> float:
        return self._parser.finite(self._raw(key), self._key(key))

    def finite_vector(self, key: str, names: tuple[str, ...]) -> list[float]:
        full = self._key(key)
        values = self._parser.array(self._raw(key), full)
        if len(values) != len(names):
            raise self._parser.fail(full, f"must be [{', '.join(names)}], got {values!r}")
        return [self._parser.finite(v, f"{full}[{i}]") for i, v in enumerate(values)]

    def positive_per_component(self, key: str, count: int) -> list[float]:
        full = self._key(key)
        value = self._raw(key)
        if isinstance(value, list):
            if len(value) != count:
                raise self._parser.fail(
                    full,
                    f"has {len(value)} entries {value!r}; expected a number or one standard "
                    f"deviation per position component ({count})",
                )
            return [self._parser.positive(item, f"{full}[{i}]") for i, item in enumerate(value)]
        return [self._parser.positive(value, full)] * count


def _parse_sensor(
    parser: _Parser, item: object, index: int, motion: MotionModel
) -> tuple[Sensor, bool, tuple[tuple[str, float | None], ...], tuple[_StdStart, ...]]:
    """The sensor, whether its rate is "auto", its ``(name, start)`` when Pd is, and its
    ``(name, start)`` when ``noise_std`` is."""
    prefix = f"sensors[{index}]"
    table = parser.table(item, prefix)
    kind = parser.choice(
        parser.required(table, prefix, "measurement"),
        f"{prefix}.measurement",
        tuple(MEASUREMENT_REGISTRY),
    )
    spec = MEASUREMENT_REGISTRY[kind]
    allowed = _SENSOR_COMMON_KEYS + spec.keys + (("noise_std_start",) if kind == POSITION else ())
    parser.only_keys(table, prefix, allowed, f"for a {kind} sensor")
    table, auto_std = _auto_noise_std(parser, table, prefix, kind, len(motion.position_indices))
    name = parser.string(parser.required(table, prefix, "name"), f"{prefix}.name")
    if not name or name != name.strip() or "," in name:
        raise parser.fail(
            f"{prefix}.name",
            f"must be a non-empty name without commas or surrounding spaces, got {name!r}",
        )
    try:
        measurement = spec.read(_SensorSettings(parser, table, prefix), motion)
    except InputError as exc:  # a model's own checks of its settings (key: the setting)
        raise parser.fail(_subkey(prefix, exc), str(exc)) from None
    detection_probability, false_alarms, auto_rate, start, auto_pd = _sensor_rates(
        parser, table, prefix
    )
    region = _parse_region(
        parser,
        parser.required(table, prefix, "region"),
        f"{prefix}.region",
        measurement.component_names,
    )
    try:
        sensor = Sensor(
            name=name,
            measurement=measurement,
            detection_probability=detection_probability,
            false_alarms_per_scan=false_alarms,
            region=region,
        )
    except InputError as exc:
        raise parser.fail(_subkey(prefix, exc), str(exc)) from None
    return sensor, auto_rate, ((name, start),) if auto_pd else (), (
        ((name, auto_std[1]),) if auto_std[0] else ()
    )


def _auto_noise_std(
    parser: _Parser, table: Mapping[str, object], prefix: str, kind: str, count: int
) -> tuple[Mapping[str, object], tuple[bool, tuple[float, ...] | None]]:
    """A sensor table with an "auto" ``noise_std`` replaced by the placeholder and
    ``noise_std_start`` taken out: ``(table, (auto, start))``; "auto" anywhere else among
    the measurement's keys is an error naming it."""
    spec = MEASUREMENT_REGISTRY[kind]
    for key in spec.keys:
        if table.get(key) == AUTO and (kind, key) != (POSITION, "noise_std"):
            raise parser.fail(
                f"{prefix}.{key}", '"auto" is only for noise_std of a position sensor (and '
                "detection_probability, false_alarms_per_scan); give a number",
            )  # fmt: skip
    auto = table.get("noise_std") == AUTO and kind == POSITION
    start_key = f"{prefix}.noise_std_start"
    start: tuple[float, ...] | None = None
    given = _auto_start(parser, table, prefix, "noise_std", auto)
    if given is not None:
        if isinstance(given, list):
            if len(given) != count:
                raise parser.fail(
                    start_key, f"has {len(given)} entries {given!r}; expected a number or one "
                    f"standard deviation per position component ({count})",
                )  # fmt: skip
            start = tuple(parser.positive(v, f"{start_key}[{i}]") for i, v in enumerate(given))
        else:
            start = (parser.positive(given, start_key),)
    if not auto:
        return table, (False, None)
    rest = {key: value for key, value in table.items() if key != "noise_std_start"}
    rest["noise_std"] = NOISE_PLACEHOLDER
    return rest, (True, start)


def _sensor_rates(
    parser: _Parser, table: Mapping[str, object], prefix: str
) -> tuple[float, float, bool, float | None, bool]:
    """A sensor's Pd and false-alarm rate: ``(pd, rate, rate is auto, Pd start, Pd is
    auto)``; "auto" values hold placeholders (Pd 1, rate 0)."""
    pd_value = parser.required(table, prefix, "detection_probability")
    rate_value = parser.required(table, prefix, "false_alarms_per_scan")
    for value, what, expected in (
        (pd_value, "detection_probability", "a probability in (0, 1]"),
        (rate_value, "false_alarms_per_scan", "a number >= 0"),
    ):
        if isinstance(value, str) and value != AUTO:
            raise parser.fail(
                f"{prefix}.{what}", f'must be {expected} or "auto", got {value!r}'
            )
    auto_pd = pd_value == AUTO
    start_key = f"{prefix}.detection_probability_start"
    start = None
    given = _auto_start(parser, table, prefix, "detection_probability", auto_pd)
    if given is not None:
        start = parser.probability(given, start_key)
        if start == 0:
            raise parser.fail(start_key, "must be a probability in (0, 1], got 0")
    detection_probability = (
        1.0 if auto_pd else parser.probability(pd_value, f"{prefix}.detection_probability")
    )
    auto_rate = rate_value == AUTO
    false_alarms = 0.0 if auto_rate else _false_alarm_rate(parser, rate_value, prefix)
    return detection_probability, false_alarms, auto_rate, start, auto_pd


def _false_alarm_rate(parser: _Parser, value: object, prefix: str) -> float:
    """A sensor's ``false_alarms_per_scan``: a number > 0 (module docstring)."""
    key = f"{prefix}.false_alarms_per_scan"
    rate = parser.nonnegative(value, key)
    if rate == 0:
        raise parser.fail(
            key,
            f"must be > 0, got {value!r}: the estimator and the trackers weigh each "
            "detection against the false-alarm density, and with none a detection has no "
            'score; for data with (almost) no clutter give a small rate such as 1e-6, or "auto"',
        )
    return rate


_RECORDING_KEYS = ("frame", "origin", "angles")
_SITE_KEYS = ("latitude", "longitude", "height")


def _geodetic_point(parser: _Parser, table: Mapping[str, object], prefix: str) -> GeodeticPoint:
    """``latitude, longitude[, height]`` of a table (an origin or a site)."""
    values: dict[str, float | None] = {}
    for name in _SITE_KEYS:
        key = f"{prefix}.{name}" if prefix else name
        if name not in table:
            if name == "height":
                values[name] = None
                continue
            raise parser.fail(key, f"missing; a place needs {', '.join(_SITE_KEYS[:2])}")
        values[name] = parser.finite(table[name], key)
    lat, lon = values["latitude"], values["longitude"]
    assert lat is not None and lon is not None
    for name, value, bound in (("latitude", lat, 90.0), ("longitude", lon, 360.0)):
        low = -90.0 if name == "latitude" else -180.0
        if not low <= value <= bound:
            key = f"{prefix}.{name}" if prefix else name
            raise parser.fail(key, f"{value!r} is outside [{low:g}, {bound:g}] degrees")
    return GeodeticPoint(latitude=lat, longitude=lon, height=values["height"])


def _parse_recording(parser: _Parser, data: Mapping[str, object]) -> Recording | None:
    """The optional ``[recording]`` section (module docstring)."""
    if "recording" not in data:
        return None
    table = parser.table(data["recording"], "recording")
    parser.only_keys(table, "recording", _RECORDING_KEYS, "in [recording]")
    frame = parser.choice(table.get("frame", "local"), "recording.frame", ("local", "geodetic"))
    angles = parser.choice(
        table.get("angles", "degrees"), "recording.angles", ("degrees", "radians")
    )
    origin = None
    value = table.get("origin", AUTO)
    if frame == "local" and "origin" in table:
        raise parser.fail("recording.origin", 'only goes with frame = "geodetic"')
    if value != AUTO:
        origin_table = parser.table(value, "recording.origin")
        parser.only_keys(origin_table, "recording.origin", _SITE_KEYS, "for a place")
        origin = _geodetic_point(parser, origin_table, "recording.origin")
    return Recording(frame=frame, origin=origin, angles=angles)  # type: ignore[arg-type]


def _placed_sensor(
    parser: _Parser,
    item: object,
    index: int,
    recording: Recording | None,
    sites: Mapping[str, GeodeticPoint],
) -> tuple[object, GeodeticPoint | None]:
    """A geodetic recording's range-bearing sensor placed by latitude, longitude and
    height: its table with ``position`` in metres in the origin's plane, and its site.
    Any other sensor table is returned as it is."""
    prefix = f"sensors[{index}]"
    if recording is None or recording.frame != "geodetic" or not isinstance(item, Mapping):
        return item, None
    if item.get("measurement") != "range_bearing":
        return item, None
    if "position" in item:
        raise parser.fail(
            f"{prefix}.position",
            "a geodetic recording places a site by latitude, longitude and height "
            "(metres), not by position",
        )
    site = _geodetic_point(parser, item, prefix)
    origin = recording.origin or next(iter(sites.values()), site)
    east, north = LocalFrame(origin=origin).to_local(
        site.latitude, site.longitude, 0.0 if site.height is None else site.height
    )[0, :2]
    table = {key: value for key, value in item.items() if key not in _SITE_KEYS}
    table["position"] = [float(east), float(north)]
    return table, site


def _parse_sensors(
    parser: _Parser, data: Mapping[str, object], motion: MotionModel, recording: Recording | None
) -> tuple[dict[str, Sensor], AutoParameters, dict[str, GeodeticPoint]]:
    if "sensors" not in data:
        raise parser.fail("sensors", "missing required [[sensors]] tables (at least one)")
    items = parser.array(data["sensors"], "sensors")
    if not items:
        raise parser.fail("sensors", "must hold at least one [[sensors]] table, got []")
    sensors: dict[str, Sensor] = {}
    first_index: dict[str, int] = {}
    auto_rates: list[str] = []
    auto_pds: list[tuple[str, float | None]] = []
    auto_stds: list[tuple[str, tuple[float, ...] | None]] = []
    sites: dict[str, GeodeticPoint] = {}
    for index, item in enumerate(items):
        item, site = _placed_sensor(parser, item, index, recording, sites)
        sensor, auto_rate, auto_pd, auto_std = _parse_sensor(parser, item, index, motion)
        if site is not None:
            sites[sensor.name] = site
        auto_rates += [sensor.name] if auto_rate else []
        auto_pds += auto_pd
        auto_stds += auto_std
        if sensor.name in sensors:
            raise parser.fail(
                f"sensors[{index}].name",
                f"duplicate sensor name {sensor.name!r} (also sensors[{first_index[sensor.name]}]"
                ".name); expected distinct names",
            )
        sensors[sensor.name] = sensor
        first_index[sensor.name] = index
    auto = AutoParameters(tuple(auto_rates), tuple(auto_pds), noise_std=tuple(auto_stds))
    return sensors, auto, sites


def _field_kind(field: dataclasses.Field[object]) -> str:
    """``"int"``, ``"int | None"``, ``"float"``, ``"float | None"``, ``"bool"``, ``"str"``
    or ``"tuple[float, ...]"`` for a settings field (``... | None``: a key that may be
    left out, and is not written when unset)."""
    annotation = field.type
    if isinstance(annotation, str):
        return annotation
    if isinstance(annotation, type):
        return annotation.__name__
    return str(annotation)


def _setting_value(parser: _Parser, value: object, key: str, kind: str, owner: str) -> Any:
    """A TOML value checked against the type of the settings field it sets."""
    if kind in ("int", "int | None"):
        return parser.integer(value, key)
    if kind in ("float", "float | None"):
        return parser.number(value, key)
    if kind == "bool":
        return value  # the record says "true or false", naming its field
    if kind == "str":
        return parser.string(value, key)
    if kind == "tuple[float, ...]":
        entries = parser.array(value, key)
        return tuple(parser.finite(v, f"{key}[{i}]") for i, v in enumerate(entries))
    raise TypeError(f"{owner} has a field of unsupported type {kind!r} ({key})")


_Record = TypeVar("_Record")


def _parse_record(
    parser: _Parser, value: object, prefix: str, base: _Record
) -> tuple[_Record, dict[str, Any]]:
    """The record ``base`` with the keys of the table ``value`` (at key ``prefix``)
    replaced, and those keys' values."""
    fields = {field.name: field for field in dataclasses.fields(base)}  # type: ignore[arg-type]
    table = parser.table(value, prefix)
    parser.only_keys(table, prefix, tuple(fields), f"in [{prefix}]")
    owner = type(base).__name__
    values = {
        name: _setting_value(parser, item, f"{prefix}.{name}", _field_kind(fields[name]), owner)
        for name, item in table.items()
    }
    try:
        return dataclasses.replace(base, **values), values  # type: ignore[type-var]
    except InputError as exc:
        # The settings constructors name the offending field in ``exc.key``; an error
        # without one is reported against the whole table.
        raise parser.fail(_subkey(prefix, exc), str(exc)) from None


def _parse_birth(
    parser: _Parser, data: Mapping[str, object], motion: MotionModel
) -> tuple[BirthModel, tuple[tuple[str, float | None], ...]]:
    """The birth model and its ``"auto"`` keys with their starts (module docstring):
    an "auto" key holds its placeholder, its ``<key>_start`` is taken out."""
    if "birth" not in data:
        return BirthModel(), ()
    table = parser.table(data["birth"], "birth")
    rest = dict(table)
    auto: list[tuple[str, float | None]] = []
    for key in AUTO_BIRTH_KEYS:
        asked = table.get(key) == AUTO
        given = _auto_start(parser, table, "birth", key, asked)
        rest.pop(f"{key}_start", None)
        if not asked:
            continue
        if key == "velocity_std" and not getattr(motion, "velocity_indices", ()):
            raise parser.fail(
                "birth.velocity_std", '"auto" needs a motion model with velocity components '
                f"(constant velocity or acceleration, Singer, constant turn), got {motion!r}",
            )  # fmt: skip
        start_key = f"birth.{key}_start"
        start = None if given is None else (
            parser.probability(given, start_key) if key == "survival_probability"
            else parser.positive(given, start_key)
        )  # fmt: skip
        auto.append((key, start))
        rest[key] = BIRTH_PLACEHOLDERS[key]
    for key, value in rest.items():
        if value == AUTO:
            raise parser.fail(
                f"birth.{key}", f'"auto" is only for [birth] {", ".join(AUTO_BIRTH_KEYS)}'
            )
    return _parse_record(parser, rest, "birth", BirthModel())[0], tuple(auto)


def _parse_estimator(
    parser: _Parser, data: Mapping[str, object]
) -> tuple[EstimatorSettings, tuple[str, ...]]:
    """The ``[estimator]`` table: its sub-tables, one per record of
    :class:`EstimatorSettings`, and any keys of the old flat table, which set what
    :data:`~mapassoc.data.settings.FLAT_KEYS` says (returned, to be warned about)."""
    if "estimator" not in data:
        return EstimatorSettings(), ()
    table = parser.table(data["estimator"], "estimator")
    parser.only_keys(
        table, "estimator", (*COMPONENTS, *FLAT_KEYS), "in [estimator] (sub-tables, and "
        "the old flat keys `mapassoc migrate-config` rewrites)",
    )  # fmt: skip
    defaults = EstimatorSettings()
    records: dict[str, Any] = {}
    given: set[tuple[str, str]] = set()
    for name in COMPONENTS:
        if name in table:
            prefix = f"estimator.{name}"
            records[name], values = _parse_record(
                parser, table[name], prefix, getattr(defaults, name)
            )
            given |= {(name, field) for field in values}
    flat: dict[str, Any] = {}
    for name in (key for key in table if key in FLAT_KEYS):
        record, target = FLAT_KEYS[name][0]
        kind = _field_kind(_fields_of(COMPONENTS[record])[target])
        flat[name] = _setting_value(parser, table[name], f"estimator.{name}", kind, "estimator")
        both = [f"estimator.{r}.{f}" for r, f in FLAT_KEYS[name] if (r, f) in given]
        if both:
            raise parser.fail(
                f"estimator.{name}",
                f"set twice: the old key estimator.{name} and {both[0]}; keep {both[0]}",
            )
    try:
        return EstimatorSettings(**records, **flat), tuple(flat)
    except InputError as exc:
        raise parser.fail(_subkey("estimator", exc), str(exc)) from None


def _fields_of(cls: type) -> dict[str, dataclasses.Field[object]]:
    return {field.name: field for field in dataclasses.fields(cls)}


def _deprecation_message(source: str | None, flat: Collection[str]) -> str:
    """One message for every old flat ``[estimator]`` key a document holds, naming the
    keys that replace each."""
    where = source or "the configuration"
    moves = "; ".join(
        f"{name} -> {' and '.join(f'estimator.{r}.{f}' for r, f in FLAT_KEYS[name])}"
        for name in flat
    )
    command = f"mapassoc migrate-config {source}" if source else "mapassoc migrate-config"
    return (
        f"{where}: the flat [estimator] keys are deprecated, each setting now lives in the "
        f"table of what it configures ({moves}); `{command}` rewrites the file"
    )


def _check_solver(
    parser: _Parser,
    settings: EstimatorSettings,
    solver_names: Collection[str] | None,
    key: str = "estimator.search.solver",
) -> None:
    if solver_names is None:
        return
    if isinstance(solver_names, str) or not all(isinstance(n, str) for n in solver_names):
        raise InputError(f"solver_names must be a collection of names, got {solver_names!r}")
    if settings.search.solver not in solver_names:
        known = ", ".join(solver_names) if solver_names else "(none)"
        raise parser.fail(
            key, f"unknown solver {settings.search.solver!r}; known solvers: {known}"
        )


def parse_config(
    data: Mapping[str, object],
    *,
    source: str | None = None,
    solver_names: Collection[str] | None = None,
    tracker_names: Collection[str] | None = None,
) -> Config:
    """Build a :class:`Config` from a parsed TOML document (schema in the module docstring).

    Parameters
    ----------
    data : mapping
        The document, as returned by :func:`tomllib.loads`.
    source : str, optional
        File name reported in errors and kept in ``Config.source``.
    solver_names : collection of str, optional
        The solver names ``estimator.solver`` may take (the caller's registry, for example
        the integer-capable names of ``mapassoc.solvers.available_solvers()``); ``None``
        (default) leaves the name to be checked when the solver is built.
    tracker_names : collection of str, optional
        The tracker names a ``[trackers.<name>]`` table may take (the caller's registry,
        ``mapassoc.trackers.registry.tracker_names()``); ``None`` (default) leaves them
        to be checked when a tracker is built.

    Raises
    ------
    ConfigError
        A missing, unknown or invalid key; ``key`` is its dotted path.  With
        ``solver_names``, an ``estimator.solver`` (given or default) outside it; with
        ``tracker_names``, a ``[trackers.<name>]`` table of another name.
    """
    for argument, names in (("solver_names", solver_names), ("tracker_names", tracker_names)):
        if names is not None:
            check_names(argument, names)
    parser = _Parser(source=source)
    document = parser.table(data, _DOCUMENT_KEY)
    parser.only_keys(document, "", _SECTIONS, "at the top level")
    motion, motion_auto = _parse_motion(parser, document)
    recording = _parse_recording(parser, document)
    sensors, auto, sites = _parse_sensors(parser, document, motion, recording)
    auto = dataclasses.replace(
        auto,
        noise_intensity=motion_auto.noise_intensity,
        noise_intensity_start=motion_auto.noise_intensity_start,
        model_noise_intensity=motion_auto.model_noise_intensity,
    )
    if recording is not None and sites:
        recording = dataclasses.replace(recording, sites=sites)
    birth, auto_birth = _parse_birth(parser, document, motion)
    auto = dataclasses.replace(auto, birth=auto_birth)
    estimator, flat = _parse_estimator(parser, document)
    if flat:
        warnings.warn(_deprecation_message(source, flat), DeprecationWarning, stacklevel=2)
    solver_key = "estimator.solver" if "solver" in flat else "estimator.search.solver"
    _check_solver(parser, estimator, solver_names, solver_key)
    trackers = _parse_trackers(parser, document, tracker_names)
    return Config(
        motion=motion,
        sensors=sensors,
        birth=birth,
        estimator=estimator,
        source=source,
        auto=auto,
        trackers=trackers,
        recording=recording,
    )


def _parse_trackers(
    parser: _Parser, document: Mapping[str, object], tracker_names: Collection[str] | None
) -> dict[str, dict[str, TrackerOption]]:
    """The ``[trackers.<name>]`` tables: names (against ``tracker_names`` if given) and
    value types checked here, each option by the tracker that takes it."""
    if "trackers" not in document:
        return {}
    tables = parser.table(document["trackers"], "trackers")
    for name in tables:
        if tracker_names is not None and name not in tracker_names:
            raise parser.fail(
                f"trackers.{name}",
                f"unknown tracker; known trackers: {', '.join(sorted(tracker_names))}",
            )
    try:
        return _checked_tracker_options(tables)
    except InputError as exc:
        raise parser.fail(exc.key or "trackers", str(exc)) from None


def _defaults_text(settings: object, prefix: str = "") -> str:
    """``"name value, ..."`` of every field of a settings record, a composed record's by
    dotted path (an optional key, unset by default, is left out)."""
    parts = []
    for field in dataclasses.fields(settings):  # type: ignore[arg-type]
        value = getattr(settings, field.name)
        if dataclasses.is_dataclass(value):
            parts.append(_defaults_text(value, f"{prefix}{field.name}."))
        elif value is not None:
            shown = list(value) if isinstance(value, tuple) else value
            parts.append(f"{prefix}{field.name} {shown!r}")
    return ", ".join(parts)


def _warn_missing_sections(data: Mapping[str, object], source: str) -> None:
    for section, cls in (("birth", BirthModel), ("estimator", EstimatorSettings)):
        if section not in data:
            warnings.warn(
                f"{source} has no [{section}] section: the defaults of {cls.__name__} are "
                f"used ({_defaults_text(cls())})",
                UserWarning,
                stacklevel=3,
            )


def load_config(
    path: PathLike,
    *,
    solver_names: Collection[str] | None = None,
    tracker_names: Collection[str] | None = None,
    content: bytes | None = None,
) -> Config:
    """Read and parse a TOML configuration file.

    Warns (``UserWarning``, naming the file and the defaults) when the optional
    ``[birth]`` or ``[estimator]`` section is missing.

    Parameters
    ----------
    path : str or os.PathLike
    solver_names : collection of str, optional
        The solver names ``estimator.solver`` may take (see :func:`parse_config`).
    tracker_names : collection of str, optional
        The tracker names ``[trackers.<name>]`` tables may take (see :func:`parse_config`).
    content : bytes, optional
        The file's bytes when the caller has read them already (a named pipe can be read
        only once); ``path`` then only names the file in errors and ``Config.source``.

    Raises
    ------
    ConfigError
        Unreadable file or TOML syntax error, arrays or tables nested too deeply to read
        (key ``"<file>"``), or any schema error; with ``solver_names``, an unknown
        ``estimator.solver``.
    """
    source = check_path("load_config: path", path)
    if content is not None:
        check_instance("load_config: content", content, bytes, expected="bytes (the file's)")
    try:
        if content is None:
            with open(source, "rb") as handle:
                content = handle.read()
        data = tomllib.loads(content.decode("utf-8"))
    except OSError as exc:
        raise ConfigError(
            _DOCUMENT_KEY, f"cannot read the file: {exc.strerror or exc}", source=source
        ) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(_DOCUMENT_KEY, f"invalid TOML: {exc}", source=source) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(_DOCUMENT_KEY, f"not UTF-8 text ({exc.reason})", source=source) from None
    except RecursionError:  # tomllib reads nested arrays and inline tables recursively
        raise ConfigError(
            _DOCUMENT_KEY,
            "invalid TOML: arrays or inline tables nested too deeply to read (the schema "
            "nests arrays two deep at most: region = [[low, high], ...])",
            source=source,
        ) from None
    config = parse_config(
        data, source=source, solver_names=solver_names, tracker_names=tracker_names
    )
    _warn_missing_sections(data, source)
    return config


# --------------------------------------------------------------------------- writing


def _toml_string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped."""
    out = ['"']
    for ch in text:
        if ch in ('"', "\\"):
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def _toml_float(value: float) -> str:
    """``repr`` of the float: exact on reading back; ``inf``/``nan`` are TOML literals."""
    return repr(float(value))


def _toml_floats(values: object) -> str:
    return "[" + ", ".join(_toml_float(v) for v in np.asarray(values, dtype=float).ravel()) + "]"


def _motion_lines(motion: MotionModel, key: str = "motion") -> list[str]:
    """The ``[motion]`` table's lines (and, for an IMM set, its ``[[motion.models]]``);
    ``key`` names the table in errors."""
    if isinstance(motion, InteractingModels):
        return _imm_lines(motion)
    spec = motion_spec(motion)
    if spec is None:
        raise ConfigError(key, f"cannot write motion model {motion!r} as TOML")
    lines = [f"model = {_toml_string(spec.name)}"]
    for setting in spec.settings:
        value = getattr(motion, setting.attribute or setting.key)
        written = str(int(value)) if setting.kind == "ndim" else _toml_float(value)
        lines.append(f"{setting.key} = {written}")
    return lines


def _imm_lines(
    motion: InteractingModels, auto: Mapping[int, float | None] | None = None
) -> list[str]:
    """The ``[motion]`` table of an IMM set and its ``[[motion.models]]``; ``auto`` maps
    the components whose ``noise_intensity`` is "auto" to their start, written as such in
    their own table."""
    law = motion.switching
    lines = [f"model = {_toml_string(IMM)}"]
    if law.matrix is not None:
        lines.append("matrix = [" + ", ".join(_toml_floats(row) for row in law.matrix) + "]")
    else:
        lines.append(f"switch_probability = {_toml_float(law.switch_probability or 0.0)}")
    lines.append(f"initial_probabilities = {_toml_floats(motion.initial_probabilities)}")
    for index, model in enumerate(motion.models):
        component = _motion_lines(model, f"motion.models[{index}]")
        if auto is not None and index in auto:
            component = _auto_noise_lines(component, auto[index])
        lines += ["", "[[motion.models]]", *component]
    return lines


def _toml_value(value: SettingValue) -> str:
    """A measurement setting as TOML: boolean, integer, float, string or array of floats."""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return _toml_float(value)
    if isinstance(value, str):
        return _toml_string(value)
    return _toml_floats(value)


def _measurement_lines(measurement: MeasurementModel, motion: MotionModel, key: str) -> list[str]:
    spec = measurement_spec(measurement)
    settings = None if spec is None else spec.write(measurement, motion)
    if spec is None or settings is None:
        raise ConfigError(
            f"{key}.measurement",
            f"cannot write {measurement!r} as TOML: only position measurements of the motion "
            "model with independent noise, and range-bearing measurements, are in the schema",
        )
    lines = [f"measurement = {_toml_string(spec.name)}"]
    for name in spec.keys:
        lines.append(f"{name} = {_toml_value(settings[name])}")
    return lines


def _auto_motion_lines(config: Config) -> list[str]:
    """:func:`_motion_lines`, with ``noise_intensity = "auto"`` (and its start) where the
    configuration leaves it to the recording: in ``[motion]`` for a single model, in the
    ``[[motion.models]]`` table of each such component for an IMM set, whose own
    ``[motion]`` table has no ``noise_intensity`` to write an ``auto.noise_intensity`` in
    (refused, rather than written as something the reader would not give back)."""
    if isinstance(config.motion, InteractingModels):
        if config.auto.noise_intensity:
            raise ConfigError(
                "motion.noise_intensity", f"an {IMM!r} set has no noise_intensity of its own "
                "to leave to the recording; give its components' in "
                "auto.model_noise_intensity",
            )  # fmt: skip
        return _imm_lines(config.motion, config.auto.model_noise_starts())
    lines = _motion_lines(config.motion)
    if not config.auto.noise_intensity:
        return lines
    return _auto_noise_lines(lines, config.auto.noise_intensity_start)


def _auto_noise_lines(lines: list[str], start: float | None) -> list[str]:
    """One single model's table lines with ``noise_intensity = "auto"`` in place of the
    placeholder and ``noise_intensity_start`` after them where given."""
    lines = [f"noise_intensity = {_toml_string(AUTO)}" if line.startswith("noise_intensity =")
             else line for line in lines]  # fmt: skip
    return lines + ([] if start is None else [f"noise_intensity_start = {_toml_float(start)}"])


def _auto_measurement_lines(config: Config, name: str, key: str) -> list[str]:
    """:func:`_measurement_lines` of sensor ``name``, with ``noise_std = "auto"`` (and its
    start) where the configuration leaves it to the recording."""
    lines = _measurement_lines(config.sensors[name].measurement, config.motion, key)
    starts = config.auto.noise_std_starts()
    if name not in starts:
        return lines
    lines = [f"noise_std = {_toml_string(AUTO)}" if line.startswith("noise_std =") else line
             for line in lines]  # fmt: skip
    start = starts[name]
    if start is not None:
        lines.append(
            f"noise_std_start = {_toml_float(start[0]) if len(start) == 1 else _toml_floats(start)}"
        )
    return lines


def config_to_toml(config: Config) -> str:
    """The configuration as a TOML document that :func:`parse_config` reads back.

    Every key is written explicitly; floats with ``repr``, so reading back reproduces them
    exactly.

    Parameters
    ----------
    config : Config

    Returns
    -------
    str
        The document.

    Raises
    ------
    ConfigError
        A motion or measurement model outside the schema (e.g. a general
        :class:`~mapassoc.models.measurement.LinearMeasurement`), or an
        ``auto.noise_intensity`` of an IMM set (``motion.noise_intensity``).
    """
    check_config(config, allow_auto=True)
    lines = ["# mapassoc configuration", *_recording_lines(config.recording)]
    lines += ["", "[motion]", *_auto_motion_lines(config)]
    pd_starts = config.auto.pd_starts()
    for index, sensor in enumerate(config.sensors.values()):
        key = f"sensors[{index}]"
        if sensor.name in pd_starts:
            start = pd_starts[sensor.name]
            pd_lines = [f"detection_probability = {_toml_string(AUTO)}"]
            if start is not None:
                pd_lines.append(f"detection_probability_start = {_toml_float(start)}")
        else:
            pd_lines = [f"detection_probability = {_toml_float(sensor.detection_probability)}"]
        rate = (
            _toml_string(AUTO)
            if sensor.name in config.auto.false_alarms
            else _toml_float(sensor.false_alarms_per_scan)
        )
        lines += [
            "",
            "[[sensors]]",
            f"name = {_toml_string(sensor.name)}",
            *_site_lines(
                _auto_measurement_lines(config, sensor.name, key),
                None if config.recording is None else config.recording.sites.get(sensor.name),
            ),
            *pd_lines,
            f"false_alarms_per_scan = {rate}",
            "region = ["
            + ", ".join(
                f"[{_toml_float(low)}, {_toml_float(high)}]"
                for low, high in zip(sensor.region.lower, sensor.region.upper, strict=True)
            )
            + "]",
        ]
    lines += ["", "[birth]", *_auto_birth_lines(config)]
    for name in COMPONENTS:
        lines += ["", f"[estimator.{name}]", *_record_lines(getattr(config.estimator, name))]
    for name, options in config.trackers.items():
        lines += ["", f"[trackers.{_toml_key(name)}]"]
        for option, value in options.items():
            lines.append(f"{_toml_key(option)} = {_toml_option(value)}")
    return "\n".join(lines) + "\n"


def _place_text(point: GeodeticPoint) -> list[str]:
    lines = [f"latitude = {_toml_float(point.latitude)}"]
    lines.append(f"longitude = {_toml_float(point.longitude)}")
    return lines + ([] if point.height is None else [f"height = {_toml_float(point.height)}"])


def _recording_lines(recording: Recording | None) -> list[str]:
    """The ``[recording]`` section (none for a configuration without one)."""
    if recording is None:
        return []
    lines = ["", "[recording]", f"frame = {_toml_string(recording.frame)}"]
    if recording.frame == "geodetic":
        if recording.origin is None:
            lines.append(f"origin = {_toml_string(AUTO)}")
        else:
            lines.append("origin = { " + ", ".join(_place_text(recording.origin)) + " }")
    return lines + [f"angles = {_toml_string(recording.angles)}"]


def _site_lines(lines: list[str], site: GeodeticPoint | None) -> list[str]:
    """A range-bearing sensor's lines with its site's place instead of ``position``."""
    if site is None:
        return lines
    return [line for line in lines if not line.startswith("position =")] + _place_text(site)


def _auto_birth_lines(config: Config) -> list[str]:
    """:func:`_record_lines` of the birth model, with ``<key> = "auto"`` (and its start)
    for the keys still to be estimated."""
    starts = config.auto.birth_starts()
    lines = []
    for line in _record_lines(config.birth):
        key = line.split(" = ", 1)[0]
        if key not in starts:
            lines.append(line)
            continue
        lines.append(f"{key} = {_toml_string(AUTO)}")
        start = starts[key]
        if start is not None:
            lines.append(f"{key}_start = {_toml_float(start)}")
    return lines


def _record_lines(settings: object) -> list[str]:
    """``key = value`` of every field of a settings record (an unset optional one left
    out, as in the file it came from)."""
    lines = []
    for field in dataclasses.fields(settings):  # type: ignore[arg-type]
        value = getattr(settings, field.name)
        kind = _field_kind(field)
        if value is None and kind.endswith(" | None"):
            continue
        if kind in ("int", "int | None"):
            text = str(int(value))
        elif kind in ("float", "float | None"):
            text = _toml_float(value)
        elif kind == "bool":
            text = "true" if value else "false"
        elif kind == "str":
            text = _toml_string(value)
        elif kind == "tuple[float, ...]":
            text = _toml_floats(value) if len(value) else "[]"
        else:
            raise TypeError(f"{type(settings).__name__}.{field.name} has unsupported type")
        lines.append(f"{field.name} = {text}")
    return lines


def _toml_key(name: str) -> str:
    """A bare TOML key when it is one, else a quoted one."""
    if name and all(ch.isascii() and (ch.isalnum() or ch in "_-") for ch in name):
        return name
    return _toml_string(name)


def _toml_option(value: TrackerOption) -> str:
    """A tracker option as TOML (booleans before integers: ``True`` is an ``int``)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _toml_float(value)
    return _toml_string(value)


def write_config(path: PathLike, config: Config) -> None:
    """Write :func:`config_to_toml` of ``config`` to ``path`` (UTF-8, overwritten).

    Raises
    ------
    ConfigError
        The model is outside the schema, or the file cannot be written (key ``"<file>"``).
    """
    text = config_to_toml(config)
    target = check_path("write_config: path", path)
    try:
        with open(target, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
    except OSError as exc:
        raise ConfigError(
            _DOCUMENT_KEY, f"cannot write the file: {exc.strerror or exc}", source=target
        ) from None
