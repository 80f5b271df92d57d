"""Stone Soup interoperability: detections in, tracks and ground truth out.

`Stone Soup <https://stonesoup.readthedocs.io>`_ is an optional extra
(``pip install 'mapassoc[stonesoup]'``).  Importing this module does not import it; every
function here does, and raises an :class:`ImportError` naming the extra when it is missing.

* :func:`scans_from_stonesoup`: ``(datetime, set[Detection])`` pairs (what Stone Soup
  detectors and simulators yield) or bare detection sets -> our :class:`~mapassoc.data.scans.Scan`
  list, the epoch used, and the Stone Soup :class:`Detection` behind every detection row.
* :func:`scans_to_stonesoup`: our scans -> ``(datetime, set[Detection])`` pairs, one per scan.
* :func:`tracks_to_stonesoup`, :func:`truth_to_stonesoup`: our
  :class:`~mapassoc.data.io.TrackTable` / :class:`~mapassoc.data.io.TruthTable` -> Stone Soup
  ``Track`` / ``GroundTruthPath`` sets, for Stone Soup's metric managers and plotters.
* :func:`truth_from_stonesoup`, :func:`origins_from_stonesoup`: Stone Soup ground truth (and the
  ``TrueDetection``/``Clutter`` labels of its simulators) -> our truth table and origins.
* :func:`stonesoup_measurement_models`: the Stone Soup measurement model of every sensor of a
  :class:`~mapassoc.data.config.Config`.

Conventions
-----------
Time
    Stone Soup stamps states with :class:`datetime.datetime`; mapassoc uses float seconds.
    A datetime ``d`` becomes ``(d - epoch).total_seconds()``; a time ``t`` becomes
    ``epoch + timedelta(seconds=t)``.  :func:`scans_from_stonesoup` takes the earliest time of
    its input as the epoch (so the first scan is at time 0.0) unless one is given, and returns
    it: pass that same epoch to every other conversion of the run.  Datetimes resolve one
    microsecond, so times that are whole microseconds (all times read from Stone Soup, and
    scan grids such as 0.5 s) convert exactly both ways; other times are rounded to the
    nearest microsecond, and two distinct times that would round to the same datetime are
    refused.  Naive and timezone-aware datetimes cannot be mixed.
State order
    Our Cartesian states list all positions, then all velocities, then accelerations:
    ``(x, y, vx, vy)`` for a 2-D :class:`~mapassoc.models.motion.ConstantVelocity`.  Stone
    Soup's ``CombinedLinearGaussianTransitionModel`` of per-axis ``ConstantVelocity`` models
    interleaves the axes: ``(x, vx, y, vy)``.  Stone Soup states are therefore written in
    :func:`stonesoup_state_names` order: per axis x, y, z its position, velocity and
    acceleration (those present), then every other component in our order.  For the
    coordinated turn ``(x, y, speed, heading, turn_rate)`` that is the same order; no Stone
    Soup transition model uses that layout, but its metrics only need the positions
    (:func:`stonesoup_position_mapping`, for ``Euclidean(mapping=...)``).  Covariances are
    ``diag(variances)`` in the same order (a track table keeps only the marginal variances).
Measurement components
    A ``LinearGaussian`` detection holds the state components its ``mapping`` selects, in
    mapping order, which is our :class:`~mapassoc.models.measurement.LinearMeasurement`
    order (the rows of H).  ``CartesianToBearingRange`` measures ``(bearing, range)``; our
    :class:`~mapassoc.models.measurement.RangeBearing` measures ``(range, bearing)``, so the
    two components are swapped both ways.  Both measure the bearing counter-clockwise from
    the x axis, in radians; a ``rotation_offset`` other than zero has no counterpart here and
    is refused.  Detections without a measurement model are taken as they are.  Other
    Stone Soup measurement models are refused.
Detection rows
    Our detections are identified by detection ids (``Scan.rows``: opaque integers >= 0;
    a CSV file's line numbers, from 2).  :func:`scans_from_stonesoup` numbers them 2, 3,
    ... (the lines :func:`~mapassoc.data.io.write_detections` gives them) in scan order,
    and within a scan in lexicographic order of the (converted) measurement vectors, so
    that the numbering does not depend on the iteration order of Python sets.  With
    ``row_key`` it reads each id from ``detection.metadata[row_key]`` instead, where
    :func:`scans_to_stonesoup` writes it: our scans -> Stone Soup -> our scans is then the identity.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config
from mapassoc.data.io import FIRST_DATA_LINE, Origins, TrackTable, TruthTable
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.models.measurement import LinearMeasurement, MeasurementModel, RangeBearing

if TYPE_CHECKING:
    from stonesoup.models.measurement.base import MeasurementModel as StoneSoupMeasurement
    from stonesoup.types.detection import Detection
    from stonesoup.types.groundtruth import GroundTruthPath
    from stonesoup.types.track import Track

__all__ = [
    "INSTALL_HINT",
    "StoneSoupScans",
    "stonesoup_state_names",
    "stonesoup_position_mapping",
    "stonesoup_measurement_models",
    "scans_from_stonesoup",
    "scans_to_stonesoup",
    "tracks_to_stonesoup",
    "truth_to_stonesoup",
    "truth_from_stonesoup",
    "origins_from_stonesoup",
]

INSTALL_HINT = "Stone Soup is not installed: pip install 'mapassoc[stonesoup]'"
"""Message of the ImportError raised when Stone Soup is missing."""

_AXES = ("x", "y", "z")
_DERIVATIVE_PREFIXES = ("", "v", "a")
_DECIMAL = re.compile(r"0|[1-9][0-9]*")


# --------------------------------------------------------------------------- Stone Soup types


def _import(module: str) -> ModuleType:
    """``stonesoup.<module>``, or an ImportError with :data:`INSTALL_HINT` if Stone Soup (or
    one of its modules) is missing; any other import failure propagates unchanged."""
    try:
        return importlib.import_module(f"stonesoup.{module}")
    except ModuleNotFoundError as exc:
        if exc.name is not None and (exc.name == "stonesoup" or exc.name.startswith("stonesoup.")):
            raise ImportError(INSTALL_HINT) from None
        raise


@dataclass(frozen=True)
class _Types:
    """The Stone Soup classes this module uses, imported on each public call.

    Stone Soup has no type information, so its classes (and their instances) are typed Any.
    """

    Detection: type[Any]
    TrueDetection: type[Any]
    Clutter: type[Any]
    MissedDetection: type[Any]
    CompositeDetection: type[Any]
    LinearGaussian: type[Any]
    CartesianToBearingRange: type[Any]
    StateVector: type[Any]
    CovarianceMatrix: type[Any]
    GaussianState: type[Any]
    Track: type[Any]
    GroundTruthState: type[Any]
    GroundTruthPath: type[Any]

    @classmethod
    def load(cls) -> _Types:
        detection = _import("types.detection")
        array = _import("types.array")
        groundtruth = _import("types.groundtruth")
        return cls(
            Detection=detection.Detection,
            TrueDetection=detection.TrueDetection,
            Clutter=detection.Clutter,
            MissedDetection=detection.MissedDetection,
            CompositeDetection=detection.CompositeDetection,
            LinearGaussian=_import("models.measurement.linear").LinearGaussian,
            CartesianToBearingRange=_import("models.measurement.nonlinear").CartesianToBearingRange,
            StateVector=array.StateVector,
            CovarianceMatrix=array.CovarianceMatrix,
            GaussianState=_import("types.state").GaussianState,
            Track=_import("types.track").Track,
            GroundTruthState=groundtruth.GroundTruthState,
            GroundTruthPath=groundtruth.GroundTruthPath,
        )


# --------------------------------------------------------------------------- state order


def _check_state_names(state_names: object) -> tuple[str, ...]:
    if isinstance(state_names, str) or not isinstance(state_names, Sequence):
        raise InputError(f"state_names must be a sequence of names, got {state_names!r}")
    names = tuple(state_names)
    if not names or not all(isinstance(n, str) and n for n in names):
        raise InputError(f"state_names must be non-empty strings, got {names!r}")
    if len(set(names)) != len(names):
        raise InputError(f"state_names must be distinct, got {names!r}")
    return names


def stonesoup_state_names(state_names: Sequence[str]) -> tuple[str, ...]:
    """Our state components in the order of Stone Soup state vectors.

    Per axis x, y, z: its position, velocity and acceleration (those present, named
    ``x``, ``vx``, ``ax``); then the other components in their order in ``state_names``.

    Parameters
    ----------
    state_names : sequence of str, length n
        Our state component names (``MotionModel.state_names``, ``TrackTable.state_names``).

    Returns
    -------
    tuple of str, length n

    Examples
    --------
    >>> stonesoup_state_names(("x", "y", "vx", "vy"))
    ('x', 'vx', 'y', 'vy')
    """
    names = _check_state_names(state_names)
    order = [
        prefix + axis
        for axis in _AXES
        if axis in names
        for prefix in _DERIVATIVE_PREFIXES
        if prefix + axis in names
    ]
    order.extend(name for name in names if name not in order)
    return tuple(order)


def _permutation(state_names: Sequence[str]) -> NDArray[np.int64]:
    """Indices ``perm`` with ``stonesoup_vector = our_vector[perm]``, shape (n,)."""
    names = _check_state_names(state_names)
    return np.array([names.index(n) for n in stonesoup_state_names(names)], dtype=np.int64)


def stonesoup_position_mapping(state_names: Sequence[str]) -> tuple[int, ...]:
    """Indices of the positions x, y (, z) in Stone Soup state vectors of ``state_names``.

    This is the ``mapping`` of ``stonesoup.measures.Euclidean`` for position metrics
    (``(0, 2)`` for a 2-D constant-velocity state).

    Raises
    ------
    InputError
        ``state_names`` has no component named x, y or z.
    """
    order = stonesoup_state_names(state_names)
    mapping = tuple(order.index(axis) for axis in _AXES if axis in order)
    if not mapping:
        raise InputError(f"state_names {tuple(state_names)!r} have no position x, y or z")
    return mapping


# --------------------------------------------------------------------------- time


def _check_epoch(epoch: object) -> datetime:
    if not isinstance(epoch, datetime):
        raise InputError(f"epoch must be a datetime.datetime, got {epoch!r}")
    return epoch


def _seconds(when: datetime, epoch: datetime, what: str) -> float:
    """``(when - epoch)`` in float seconds."""
    try:
        return (when - epoch).total_seconds()
    except TypeError:
        raise InputError(
            f"{what} {when!r} and epoch {epoch!r} cannot be compared: naive and "
            "timezone-aware datetimes are mixed"
        ) from None


def _datetimes(times: FloatArray, epoch: datetime, what: str) -> dict[float, datetime]:
    """``epoch + timedelta(seconds=t)`` for every distinct ``t`` of ``times``.

    Raises
    ------
    InputError
        Two distinct times round to the same microsecond, or a time overflows a datetime.
    """
    out: dict[float, datetime] = {}
    seen: dict[datetime, float] = {}
    for t in np.unique(np.asarray(times, dtype=float)).tolist():
        try:
            stamp = epoch + timedelta(seconds=t)
        except OverflowError:
            raise InputError(
                f"{what} {t!r} seconds after the epoch {epoch!r} is beyond the datetime range"
            ) from None
        if stamp in seen:
            raise InputError(
                f"{what} {seen[stamp]!r} and {t!r} round to the same datetime {stamp!r} "
                "(datetimes resolve one microsecond)"
            )
        seen[stamp] = t
        out[t] = stamp
    return out


# --------------------------------------------------------------------------- measurement models


def _linear_model(
    ss: _Types, name: str, measurement: LinearMeasurement, state_names: tuple[str, ...]
) -> Any:
    """LinearGaussian selecting the components H selects (H must be a selection matrix)."""
    H = measurement.H
    selected: list[int] = []
    for row in H:
        nonzero = np.flatnonzero(row)
        if nonzero.size != 1 or row[nonzero[0]] != 1.0:
            raise InputError(
                f"sensor {name!r}: H={H.tolist()} is not a selection matrix (each row a single "
                "1), which is all Stone Soup's LinearGaussian (a mapping) can express"
            )
        selected.append(int(nonzero[0]))
    position = {n: i for i, n in enumerate(stonesoup_state_names(state_names))}
    mapping = tuple(position[state_names[j]] for j in selected)
    return ss.LinearGaussian(
        ndim_state=len(state_names),
        mapping=mapping,
        noise_covar=ss.CovarianceMatrix(np.array(measurement.R, dtype=float)),
    )


def _range_bearing_model(
    ss: _Types, measurement: RangeBearing, state_names: tuple[str, ...]
) -> Any:
    """CartesianToBearingRange: components swapped, so R is too."""
    position = {n: i for i, n in enumerate(stonesoup_state_names(state_names))}
    ix, iy = measurement.position_indices
    R = np.array(measurement.R, dtype=float)[::-1, ::-1]
    return ss.CartesianToBearingRange(
        ndim_state=len(state_names),
        mapping=(position[state_names[ix]], position[state_names[iy]]),
        noise_covar=ss.CovarianceMatrix(R.copy()),
        translation_offset=ss.StateVector(np.array(measurement.sensor_position, dtype=float)),
    )


def _models(ss: _Types, config: Config) -> dict[str, Any]:
    if not isinstance(config, Config):
        raise InputError(f"config must be a Config, got {config!r}")
    names = _check_state_names(config.motion.state_names)
    models: dict[str, Any] = {}
    for name, sensor in config.sensors.items():
        measurement = sensor.measurement
        if isinstance(measurement, RangeBearing):
            models[name] = _range_bearing_model(ss, measurement, names)
        elif isinstance(measurement, LinearMeasurement):
            models[name] = _linear_model(ss, name, measurement, names)
        else:
            raise InputError(
                f"sensor {name!r}: no Stone Soup counterpart for the measurement model "
                f"{measurement!r} (supported: LinearMeasurement, RangeBearing)"
            )
    return models


def stonesoup_measurement_models(config: Config) -> dict[str, StoneSoupMeasurement]:
    """The Stone Soup measurement model of every sensor of ``config``.

    A :class:`~mapassoc.models.measurement.LinearMeasurement` whose H selects state
    components becomes ``LinearGaussian(ndim_state, mapping, noise_covar=R)``; a
    :class:`~mapassoc.models.measurement.RangeBearing` becomes
    ``CartesianToBearingRange(ndim_state, mapping, noise_covar, translation_offset)`` with
    the (range, bearing) noise covariance reordered to (bearing, range).  Mappings index
    Stone Soup state vectors (:func:`stonesoup_state_names` of the motion model).

    Parameters
    ----------
    config : Config

    Returns
    -------
    dict of str to stonesoup MeasurementModel
        By sensor name, in ``config.sensors`` order.

    Raises
    ------
    InputError
        A sensor whose model has no Stone Soup counterpart (an H that is not a selection).
    ImportError
        Stone Soup is not installed.
    """
    return _models(_Types.load(), config)


def _components_from_stonesoup(ss: _Types, detection: Any, where: str) -> FloatArray:
    """Our measurement vector (dz,) of a Stone Soup detection (see the module docstring)."""
    vector = np.asarray(detection.state_vector, dtype=float)
    if vector.ndim != 2 or vector.shape[1] != 1:
        raise InputError(
            f"{where}: state_vector must be a (dz, 1) column, got shape {vector.shape}"
        )
    vector = vector[:, 0]
    model = detection.measurement_model
    if model is None or isinstance(model, ss.LinearGaussian):
        return vector
    if isinstance(model, ss.CartesianToBearingRange):
        rotation = np.asarray(model.rotation_offset, dtype=float)
        if np.any(rotation != 0.0):
            raise InputError(
                f"{where}: CartesianToBearingRange with rotation_offset "
                f"{rotation.ravel().tolist()}; mapassoc's RangeBearing measures bearings from "
                "the x axis, so rotation_offset must be zero"
            )
        return vector[::-1].copy()
    raise InputError(
        f"{where}: unsupported measurement model {type(model).__name__}; supported: "
        "LinearGaussian, CartesianToBearingRange, or none"
    )


def _components_to_stonesoup(measurement: MeasurementModel, z: FloatArray) -> FloatArray:
    """Inverse of :func:`_components_from_stonesoup` for our sensor's measurement."""
    return z[::-1].copy() if isinstance(measurement, RangeBearing) else z.copy()


def _check_model_fits(ss: _Types, model: Any, expected: Any, sensor: str, where: str) -> None:
    """Raise unless ``model`` measures what ``expected`` (built from the config) measures."""
    if model is None:
        return
    same = type(model) is type(expected) or (
        isinstance(model, ss.LinearGaussian) and isinstance(expected, ss.LinearGaussian)
    )
    problem = None
    if not same:
        problem = f"is a {type(model).__name__}, the sensor a {type(expected).__name__}"
    elif model.ndim_state != expected.ndim_state:
        problem = f"has ndim_state {model.ndim_state}, the motion model {expected.ndim_state}"
    elif tuple(model.mapping) != tuple(expected.mapping):
        problem = (
            f"has mapping {tuple(model.mapping)}, the sensor measures Stone Soup state "
            f"components {tuple(expected.mapping)}"
        )
    elif isinstance(expected, ss.CartesianToBearingRange):
        offset = np.asarray(model.translation_offset, dtype=float).ravel()[:2]
        wanted = np.asarray(expected.translation_offset, dtype=float).ravel()
        if not np.array_equal(offset, wanted):
            problem = (
                f"has translation_offset {offset.tolist()}, the sensor is at {wanted.tolist()}"
            )
    if problem is not None:
        raise InputError(f"{where}: its measurement model {problem} (sensor {sensor!r})")


# --------------------------------------------------------------------------- scans


@dataclass(frozen=True, eq=False)
class StoneSoupScans:
    """Scans converted from Stone Soup detections.

    Parameters
    ----------
    scans : list of Scan
        Sorted by (time, sensor); times in seconds since ``epoch``.
    epoch : datetime.datetime
        The datetime of time 0.0.
    detections : dict of int to stonesoup Detection
        The original detection of every detection row.
    """

    scans: list[Scan]
    epoch: datetime
    detections: dict[int, Detection]


@dataclass(frozen=True, eq=False)
class _Entry:
    """One detection while grouping: its vector and original object."""

    vector: FloatArray
    detection: Any


def _check_sensor_of(sensor_of: object) -> tuple[str, ...]:
    """Sensor names of ``sensor_of`` (sorted), after checking it."""
    if isinstance(sensor_of, str):
        if not sensor_of:
            raise InputError("sensor_of must be a non-empty sensor name or a mapping, got ''")
        return (sensor_of,)
    if not isinstance(sensor_of, Mapping) or len(sensor_of) == 0:
        raise InputError(
            "sensor_of must be a sensor name or a non-empty mapping from measurement model "
            f"to sensor name, got {sensor_of!r}"
        )
    for model, name in sensor_of.items():
        if not isinstance(name, str) or not name:
            raise InputError(f"sensor_of[{model!r}] must be a non-empty sensor name, got {name!r}")
    return tuple(sorted(set(sensor_of.values())))


def _split_item(ss: _Types, item: object, index: int) -> tuple[datetime, list[Any]]:
    """``(time, detections)`` of one element of ``detection_sets``.

    The time is the pair's datetime, or else the timestamp all the detections share.
    """
    where = f"detection_sets[{index}]"
    when: datetime | None = None
    collection = item
    if isinstance(item, tuple | list) and len(item) == 2 and isinstance(item[0], datetime):
        when, collection = item
    if isinstance(collection, str | bytes | Mapping) or not isinstance(collection, Iterable):
        raise InputError(
            f"{where} must be a (datetime, set of Detection) pair or a set of Detection, "
            f"got {item!r}"
        )
    detections = list(collection)
    for detection in detections:
        if not isinstance(detection, ss.Detection) or isinstance(
            detection, ss.MissedDetection | ss.CompositeDetection
        ):
            raise InputError(
                f"{where} holds a {type(detection).__name__}; expected Stone Soup Detection "
                "objects (not MissedDetection or CompositeDetection)"
            )
    if when is None:
        stamps = {d.timestamp for d in detections}
        if not detections:
            raise InputError(
                f"{where} is an empty detection set, which has no time; pass "
                "(datetime, set of Detection) pairs"
            )
        if None in stamps or len(stamps) != 1:
            raise InputError(
                f"{where}: the detections of a set without a time must share one timestamp, "
                f"got {sorted(map(str, stamps))}"
            )
        when = detections[0].timestamp
    return when, detections


def _describe_model(model: object) -> str:
    """One-line description of a Stone Soup measurement model (its repr spans lines)."""
    if model is None:
        return "None"
    mapping = getattr(model, "mapping", None)
    shown = "" if mapping is None else f"mapping={tuple(mapping)}, "
    return f"{type(model).__name__}({shown}id=0x{id(model):x})"


def _describe_detection(detection: Any, where: str) -> str:
    """One-line description of a detection: type, vector, timestamp and where it is."""
    vector: list[Any] | str
    try:
        vector = np.asarray(detection.state_vector, dtype=float).ravel().tolist()
    except (TypeError, ValueError):
        vector = "?"
    return f"{type(detection).__name__} {vector} at {detection.timestamp} in {where}"


def _row_of(detection: Any, row_key: str, where: str) -> int:
    metadata = detection.metadata
    if row_key not in metadata:
        raise InputError(f"{where}: metadata has no {row_key!r} (row_key); got {metadata!r}")
    row = metadata[row_key]
    if isinstance(row, bool) or not isinstance(row, int | np.integer) or row < 0:
        raise InputError(
            f"{where}: metadata[{row_key!r}] = {row!r}; expected an integer detection id >= 0"
        )
    return int(row)


def scans_from_stonesoup(
    detection_sets: Iterable[tuple[datetime, Iterable[Detection]]] | Iterable[Iterable[Detection]],
    *,
    sensor_of: str | Mapping[StoneSoupMeasurement, str],
    epoch: datetime | None = None,
    empty_scans: bool = True,
    row_key: str | None = None,
    config: Config | None = None,
) -> StoneSoupScans:
    """Our scans from Stone Soup detection sets.

    Parameters
    ----------
    detection_sets : iterable
        ``(datetime, set of Detection)`` pairs, as Stone Soup detectors and simulators
        yield them (empty sets included), or detection sets whose detections carry one
        common timestamp (a set without a time cannot be empty).  Pairs with the same
        time are merged.  A detection's own timestamp, when set, must equal its pair's time.
    sensor_of : str or mapping of stonesoup MeasurementModel to str
        Our sensor name for all detections, or for the detections of each measurement model
        (``detection.measurement_model``; models are compared by identity).
    epoch : datetime.datetime, optional
        The datetime of time 0.0; default the earliest time of ``detection_sets``.
    empty_scans : bool
        With a mapping ``sensor_of``: True (default) gives every sensor of the mapping a scan,
        empty if need be, at every time of ``detection_sets`` (every sensor looks at every
        step); False gives a sensor a scan only at the times it has a detection (asynchronous
        sensors: a Stone Soup detection set does not say which sensors looked and saw
        nothing).  With a single name, every time is a scan of that sensor.
    row_key : str, optional
        Read each detection's id from ``detection.metadata[row_key]`` (integers >= 0,
        distinct; detections within a scan are then in row order) instead of numbering the
        rows 2, 3, ... (see the module docstring).
    config : Config, optional
        If given, every sensor name must be one of its sensors, every detection must have
        its sensor's measurement dimension, and every measurement model must measure what
        the sensor measures (same kind, ``ndim_state``, ``mapping`` and, for range-bearing,
        sensor position; noise covariances may differ).  It also gives the measurement
        dimension of empty scans of a sensor that has no detection at all.

    Returns
    -------
    StoneSoupScans
        ``scans`` (sorted by (time, sensor), times ``(t - epoch).total_seconds()``),
        ``epoch``, and ``detections``: row -> the original Detection.

    Raises
    ------
    InputError
        Anything above violated; a detection of a measurement model ``sensor_of`` does not
        map or that is not supported (module docstring); a detection given twice; no
        detection set at all.
    ImportError
        Stone Soup is not installed.
    """
    ss = _Types.load()
    sensors, expected = _check_import_arguments(
        ss, detection_sets, sensor_of, epoch, empty_scans, row_key, config
    )
    grouped = _group_detections(ss, detection_sets, sensor_of, sensors, config, expected)
    ordered_times = _sorted_times(grouped.times)
    origin = ordered_times[0] if epoch is None else epoch
    scans, rows_to_detections = _build_scans(
        grouped,
        ordered_times,
        origin,
        sensors,
        every_sensor=isinstance(sensor_of, str) or empty_scans,
        row_key=row_key,
    )
    return StoneSoupScans(scans=scans, epoch=origin, detections=rows_to_detections)


def _check_import_arguments(
    ss: _Types,
    detection_sets: object,
    sensor_of: object,
    epoch: object,
    empty_scans: object,
    row_key: object,
    config: Config | None,
) -> tuple[tuple[str, ...], dict[str, Any]]:
    """The sensor names of ``sensor_of`` and, with ``config``, each sensor's Stone Soup
    model, after checking the arguments of :func:`scans_from_stonesoup`."""
    sensors = _check_sensor_of(sensor_of)
    if epoch is not None:
        _check_epoch(epoch)
    if not isinstance(empty_scans, bool):
        raise InputError(f"empty_scans must be True or False, got {empty_scans!r}")
    if row_key is not None and (not isinstance(row_key, str) or not row_key):
        raise InputError(f"row_key must be a non-empty string or None, got {row_key!r}")
    expected: dict[str, Any] = {}
    if config is not None:
        expected = _models(ss, config)
        unknown = [name for name in sensors if name not in config.sensors]
        if unknown:
            raise InputError(
                f"sensor_of names sensors {unknown} that config does not define (known: "
                f"{list(config.sensors)})"
            )
    if isinstance(detection_sets, str | bytes) or not isinstance(detection_sets, Iterable):
        raise InputError(f"detection_sets must be an iterable, got {detection_sets!r}")
    return sensors, expected


@dataclass(frozen=True, eq=False)
class _Grouped:
    """The detections of :func:`scans_from_stonesoup` grouped by (time, sensor).

    Attributes
    ----------
    groups : dict of (datetime, str) to list of _Entry
        The detections of each time and sensor, in input order.
    times : set of datetime
        Every time of the detection sets, empty sets included.
    dims : dict of str to int
        The measurement dimension of each sensor (from ``config`` or its first detection).
    """

    groups: dict[tuple[datetime, str], list[_Entry]]
    times: set[datetime]
    dims: dict[str, int]


def _group_detections(
    ss: _Types,
    detection_sets: Iterable[Any],
    sensor_of: str | Mapping[Any, str],
    sensors: tuple[str, ...],
    config: Config | None,
    expected: dict[str, Any],
) -> _Grouped:
    """Every detection checked and converted to our components, grouped by time and sensor."""
    groups: dict[tuple[datetime, str], list[_Entry]] = {}
    times: set[datetime] = set()
    dims: dict[str, int] = {}
    if config is not None:
        dims = {n: config.sensors[n].measurement.measurement_dim for n in sensors}
    seen: set[int] = set()
    checked_models: set[int] = set()
    for index, item in enumerate(detection_sets):
        when, detections = _split_item(ss, item, index)
        times.add(when)
        for detection in detections:
            where = _describe_detection(detection, f"detection_sets[{index}]")
            _check_once_and_on_time(detection, when, where, seen)
            model = detection.measurement_model
            sensor = _sensor_for(sensor_of, model, where)
            vector = _components_from_stonesoup(ss, detection, where)
            if config is not None and id(model) not in checked_models:
                _check_model_fits(ss, model, expected[sensor], sensor, where)
                checked_models.add(id(model))
            dim = dims.setdefault(sensor, vector.shape[0])
            if vector.shape[0] != dim:
                raise InputError(
                    f"{where} has {vector.shape[0]} components; sensor {sensor!r} measures {dim}"
                )
            groups.setdefault((when, sensor), []).append(_Entry(vector, detection))
    if not times:
        raise InputError("detection_sets is empty: there is no detection set to convert")
    return _Grouped(groups, times, dims)


def _check_once_and_on_time(detection: Any, when: datetime, where: str, seen: set[int]) -> None:
    """Raise if ``detection`` was seen before or its own timestamp is not its set's time;
    add it to ``seen``."""
    if id(detection) in seen:
        raise InputError(f"{where} appears more than once")
    seen.add(id(detection))
    if detection.timestamp is not None and detection.timestamp != when:
        raise InputError(f"{where} has timestamp {detection.timestamp}, its set {when}")


def _sensor_for(sensor_of: str | Mapping[Any, str], model: object, where: str) -> str:
    """Our sensor name of a detection of measurement model ``model``."""
    if isinstance(sensor_of, str):
        return sensor_of
    if model in sensor_of:
        return sensor_of[model]
    raise InputError(
        f"{where}: sensor_of has no sensor for its measurement model "
        f"{_describe_model(model)} (models are looked up by identity)"
    )


def _sorted_times(times: set[datetime]) -> list[datetime]:
    """``times`` in increasing order; an error where naive and aware datetimes are mixed."""
    try:
        return sorted(times)
    except TypeError:
        raise InputError("detection_sets mixes naive and timezone-aware datetimes") from None


def _build_scans(
    grouped: _Grouped,
    ordered_times: list[datetime],
    origin: datetime,
    sensors: tuple[str, ...],
    *,
    every_sensor: bool,
    row_key: str | None,
) -> tuple[list[Scan], dict[int, Any]]:
    """The scans, time by time and sensor by sensor, with the detection of every row.

    ``every_sensor``: every sensor has a scan at every time (empty if need be); otherwise
    only where it has a detection.
    """
    scans: list[Scan] = []
    rows_to_detections: dict[int, Any] = {}
    next_row = FIRST_DATA_LINE
    for when in ordered_times:
        t = _seconds(when, origin, "detection set time")
        names = (
            sensors if every_sensor else tuple(n for n in sensors if (when, n) in grouped.groups)
        )
        for name in names:
            entries = grouped.groups.get((when, name), [])
            if name not in grouped.dims:
                raise InputError(
                    f"sensor {name!r} has no detection, so the measurement dimension of its "
                    "empty scans is unknown; pass config"
                )
            if row_key is None:
                entries, rows = _numbered_in_order(entries, next_row)
                next_row += len(entries)
            else:
                entries, rows = _numbered_by_key(entries, row_key)
            _record_rows(rows, entries, rows_to_detections, row_key)
            scan_detections = np.array([e.vector for e in entries], dtype=float).reshape(
                len(entries), grouped.dims[name]
            )
            scans.append(Scan(t, name, scan_detections, np.array(rows, dtype=np.int64)))
    return scans, rows_to_detections


def _numbered_in_order(entries: list[_Entry], first: int) -> tuple[list[_Entry], list[int]]:
    """The entries in lexicographic order of their vectors, numbered from ``first``"""
    ordered = sorted(entries, key=lambda e: tuple(e.vector.tolist()))
    return ordered, list(range(first, first + len(ordered)))


def _numbered_by_key(entries: list[_Entry], row_key: str) -> tuple[list[_Entry], list[int]]:
    """The entries in order of their ``metadata[row_key]``, with those rows."""
    keyed = [
        (_row_of(e.detection, row_key, _describe_detection(e.detection, "input")), e)
        for e in entries
    ]
    keyed.sort(key=lambda pair: pair[0])
    return [e for _, e in keyed], [row for row, _ in keyed]


def _record_rows(
    rows: list[int], entries: list[_Entry], rows_to_detections: dict[int, Any], row_key: str | None
) -> None:
    """Add each row's detection to ``rows_to_detections``; an error for a row seen before."""
    for row, entry in zip(rows, entries, strict=True):
        if row in rows_to_detections:
            raise InputError(f"metadata[{row_key!r}] = {row} appears on more than one detection")
        rows_to_detections[row] = entry.detection


def scans_to_stonesoup(
    scans: Sequence[Scan],
    *,
    config: Config,
    epoch: datetime,
    measurement_models: Mapping[str, StoneSoupMeasurement] | None = None,
    row_key: str = "row",
) -> list[tuple[datetime, set[Detection]]]:
    """Stone Soup detection sets of our scans: one ``(datetime, set)`` pair per scan.

    Like Stone Soup's platform simulator, which yields one pair per sensor per step; an
    empty scan is a pair with an empty set.  Each detection is a plain ``Detection`` with
    the sensor's :func:`stonesoup_measurement_models` model, timestamp
    ``epoch + timedelta(seconds=scan.time)``, the components in Stone Soup order, and its
    row in ``metadata[row_key]``.

    Parameters
    ----------
    scans : sequence of Scan
    config : Config
        Defines the sensors of the scans.
    epoch : datetime.datetime
        The datetime of time 0.0.
    measurement_models : mapping of str to stonesoup MeasurementModel, optional
        The model of each sensor's detections; default :func:`stonesoup_measurement_models`
        of ``config`` (new objects: keep them to map models back to sensors in
        :func:`scans_from_stonesoup`, which looks models up by identity).
    row_key : str
        Metadata key of the detection rows.

    Returns
    -------
    list of (datetime.datetime, set of stonesoup Detection)
        In the order of ``scans``.

    Raises
    ------
    InputError
        A scan of a sensor ``config`` does not define or of the wrong measurement dimension,
        times that round to one datetime, or a bad argument.
    ImportError
        Stone Soup is not installed.
    """
    ss = _Types.load()
    _check_epoch(epoch)
    models = _models(ss, config)
    if measurement_models is not None:
        if not isinstance(measurement_models, Mapping):
            raise InputError(
                f"measurement_models must be a mapping sensor name -> Stone Soup measurement "
                f"model, got {measurement_models!r}"
            )
        missing = [name for name in config.sensors if name not in measurement_models]
        if missing:
            raise InputError(f"measurement_models has no model for the sensors {missing}")
        for name in config.sensors:
            _check_model_fits(
                ss, measurement_models[name], models[name], name, f"measurement_models[{name!r}]"
            )
        models = {name: measurement_models[name] for name in config.sensors}
    if not isinstance(row_key, str) or not row_key:
        raise InputError(f"row_key must be a non-empty string, got {row_key!r}")
    if isinstance(scans, Scan) or not isinstance(scans, Sequence):
        raise InputError(f"scans must be a sequence of Scan, got {scans!r}")
    for index, scan in enumerate(scans):
        if not isinstance(scan, Scan):
            raise InputError(f"scans[{index}] must be a Scan, got {scan!r}")
        if scan.sensor not in config.sensors:
            raise InputError(
                f"scans[{index}] names sensor {scan.sensor!r}, which config does not define "
                f"(known: {list(config.sensors)})"
            )
        dim = config.sensors[scan.sensor].measurement.measurement_dim
        if scan.size and scan.detections.shape[1] != dim:
            raise InputError(
                f"scans[{index}] has {scan.detections.shape[1]} components per detection; "
                f"sensor {scan.sensor!r} measures {dim}"
            )
    stamps = _datetimes(np.array([scan.time for scan in scans]), epoch, "scan time")
    pairs: list[tuple[datetime, set[Any]]] = []
    for scan in scans:
        when = stamps[scan.time]
        measurement = config.sensors[scan.sensor].measurement
        detections = {
            ss.Detection(
                ss.StateVector(_components_to_stonesoup(measurement, z)),
                timestamp=when,
                measurement_model=models[scan.sensor],
                metadata={row_key: int(row)},
            )
            for z, row in zip(scan.detections, scan.rows.tolist(), strict=True)
        }
        pairs.append((when, detections))
    return pairs


# --------------------------------------------------------------------------- tracks and truth


def _groups(ids: NDArray[np.int64], times: FloatArray) -> list[tuple[int, NDArray[np.int64]]]:
    """``(id, row indices sorted stably by time)`` for every distinct id, ids ascending."""
    out = []
    for identity in np.unique(ids).tolist():
        rows = np.flatnonzero(ids == identity)
        out.append((int(identity), rows[np.argsort(times[rows], kind="stable")]))
    return out


def tracks_to_stonesoup(tracks: TrackTable, *, epoch: datetime) -> set[Track]:
    """Stone Soup tracks of ``GaussianState`` s from our track table.

    Track ``i`` becomes ``Track(id=str(i))`` with one state per table row, sorted stably by
    time: state vector in :func:`stonesoup_state_names` order, covariance
    ``diag(variances)`` in the same order, timestamp ``epoch + timedelta(seconds=time)``.
    A track written twice at one time (two sensors) keeps both rows in table order; Stone
    Soup's metrics, like :mod:`mapassoc.evaluation.tables`, then use the last.

    Parameters
    ----------
    tracks : TrackTable
    epoch : datetime.datetime
        The datetime of time 0.0 (the ``epoch`` of :func:`scans_from_stonesoup`).

    Returns
    -------
    set of stonesoup Track

    Raises
    ------
    InputError
        Bad arguments, or times that round to one datetime.
    ImportError
        Stone Soup is not installed.
    """
    ss = _Types.load()
    if not isinstance(tracks, TrackTable):
        raise InputError(f"tracks must be a TrackTable, got {tracks!r}")
    _check_epoch(epoch)
    perm = _permutation(tracks.state_names)
    stamps = _datetimes(tracks.times, epoch, "track time")
    out: set[Any] = set()
    for track_id, rows in _groups(tracks.track_ids, tracks.times):
        states = [
            ss.GaussianState(
                ss.StateVector(tracks.states[i, perm]),
                ss.CovarianceMatrix(np.diag(tracks.variances[i, perm])),
                timestamp=stamps[float(tracks.times[i])],
            )
            for i in rows.tolist()
        ]
        out.add(ss.Track(states, id=str(track_id)))
    return out


def truth_to_stonesoup(truth: TruthTable, *, epoch: datetime) -> set[GroundTruthPath]:
    """Stone Soup ground truth paths from our truth table.

    Target ``i`` becomes ``GroundTruthPath(id=str(i))`` of ``GroundTruthState`` s sorted by
    time, state vectors in :func:`stonesoup_state_names` order.

    Parameters
    ----------
    truth : TruthTable
    epoch : datetime.datetime
        The datetime of time 0.0.

    Returns
    -------
    set of stonesoup GroundTruthPath

    Raises
    ------
    InputError
        Bad arguments, or times that round to one datetime.
    ImportError
        Stone Soup is not installed.
    """
    ss = _Types.load()
    if not isinstance(truth, TruthTable):
        raise InputError(f"truth must be a TruthTable, got {truth!r}")
    _check_epoch(epoch)
    perm = _permutation(truth.state_names)
    stamps = _datetimes(truth.times, epoch, "truth time")
    out: set[Any] = set()
    for target_id, rows in _groups(truth.target_ids, truth.times):
        states = [
            ss.GroundTruthState(
                ss.StateVector(truth.states[i, perm]), timestamp=stamps[float(truth.times[i])]
            )
            for i in rows.tolist()
        ]
        out.add(ss.GroundTruthPath(states, id=str(target_id)))
    return out


def _check_paths(ss: _Types, paths: object) -> list[Any]:
    if isinstance(paths, str | bytes) or not isinstance(paths, Iterable):
        raise InputError(f"paths must be an iterable of GroundTruthPath, got {paths!r}")
    out = list(paths)
    for path in out:
        if not isinstance(path, ss.GroundTruthPath):
            raise InputError(f"paths holds {path!r}; expected Stone Soup GroundTruthPath objects")
    return out


def _target_ids(paths: list[Any]) -> dict[str, int]:
    """Our target id of every non-empty path, by path id.

    ``int(path.id)`` when every path id is a decimal integer (the ids
    :func:`truth_to_stonesoup` writes), else 0, 1, ... in order of (first timestamp, id).
    """
    filled = [path for path in paths if len(path.states) > 0]
    ids = [str(path.id) for path in filled]
    if len(set(ids)) != len(ids):
        raise InputError(f"paths have repeated ids: {sorted(i for i in ids if ids.count(i) > 1)}")
    if all(_DECIMAL.fullmatch(i) for i in ids):
        return {i: int(i) for i in ids}
    firsts = []
    for path in filled:
        stamps = [state.timestamp for state in path.states]
        if any(stamp is None for stamp in stamps):
            raise InputError(f"ground truth path {path.id!r} has a state without a timestamp")
        try:
            firsts.append((min(stamps), str(path.id)))
        except TypeError:
            raise InputError(
                f"ground truth path {path.id!r} mixes naive and timezone-aware datetimes"
            ) from None
    try:
        firsts.sort()
    except TypeError:
        raise InputError("paths mix naive and timezone-aware datetimes") from None
    return {path_id: number for number, (_, path_id) in enumerate(firsts)}


def truth_from_stonesoup(
    paths: Iterable[GroundTruthPath], *, epoch: datetime, state_names: Sequence[str]
) -> TruthTable:
    """Our truth table from Stone Soup ground truth paths.

    Parameters
    ----------
    paths : iterable of stonesoup GroundTruthPath
        State vectors in :func:`stonesoup_state_names` order of ``state_names`` (for a 2-D
        constant velocity: Stone Soup's ``(x, vx, y, vy)``).  Empty paths are skipped.
    epoch : datetime.datetime
        The datetime of time 0.0 (the ``epoch`` of :func:`scans_from_stonesoup`).
    state_names : sequence of str
        Our state names (``config.motion.state_names``), the table's columns.

    Returns
    -------
    TruthTable
        Rows by target id, then time.  Target ids are ``int(path.id)`` when every path id is
        a decimal integer (the ids :func:`truth_to_stonesoup` writes), otherwise 0, 1, ...
        in order of (first timestamp, path id); :func:`origins_from_stonesoup` uses the
        same ids.

    Raises
    ------
    InputError
        A state of the wrong length or without a timestamp, a (target, time) twice, bad
        arguments.
    ImportError
        Stone Soup is not installed.
    """
    ss = _Types.load()
    _check_epoch(epoch)
    names = _check_state_names(state_names)
    inverse = np.argsort(_permutation(names))
    path_list = _check_paths(ss, paths)
    numbers = _target_ids(path_list)
    ids: list[int] = []
    times: list[float] = []
    states: list[FloatArray] = []
    for path in sorted(
        (p for p in path_list if len(p.states) > 0), key=lambda p: numbers[str(p.id)]
    ):
        for state in path.states:
            where = f"a state of ground truth path {path.id!r}"
            if state.timestamp is None:
                raise InputError(f"{where} has no timestamp")
            vector = np.asarray(state.state_vector, dtype=float).ravel()
            if vector.shape != (len(names),):
                raise InputError(
                    f"{where} has {vector.shape[0]} components; state_names {names} has "
                    f"{len(names)}"
                )
            ids.append(numbers[str(path.id)])
            times.append(_seconds(state.timestamp, epoch, "ground truth time"))
            states.append(vector[inverse])
    count = len(ids)
    table_states = np.array(states, dtype=float).reshape(count, len(names))
    order = np.lexsort((np.array(times), np.array(ids, dtype=np.int64)))
    return TruthTable(
        target_ids=np.array(ids, dtype=np.int64)[order],
        times=np.array(times, dtype=float)[order],
        states=table_states[order],
        state_names=names,
    )


def origins_from_stonesoup(
    detections: Mapping[int, Detection], paths: Iterable[GroundTruthPath]
) -> Origins:
    """Our origins (row -> target id, -1 for a false alarm) from Stone Soup's labels.

    A ``TrueDetection`` comes from the target of its ``groundtruth_path`` (numbered as in
    :func:`truth_from_stonesoup` of the same ``paths``), a ``Clutter`` is a false alarm.

    Parameters
    ----------
    detections : mapping of int to stonesoup Detection
        Row -> detection (:attr:`StoneSoupScans.detections`).
    paths : iterable of stonesoup GroundTruthPath
        The ground truth the detections were simulated from.

    Returns
    -------
    Origins
        Rows in increasing order.

    Raises
    ------
    InputError
        A detection that is neither a TrueDetection nor Clutter, or whose path is not in
        ``paths``.
    ImportError
        Stone Soup is not installed.
    """
    ss = _Types.load()
    if not isinstance(detections, Mapping):
        raise InputError(f"detections must be a mapping row -> Detection, got {detections!r}")
    numbers = _target_ids(_check_paths(ss, paths))
    rows = sorted(detections)
    targets: list[int] = []
    for row in rows:
        detection = detections[row]
        if isinstance(detection, ss.TrueDetection):
            path_id = str(detection.groundtruth_path.id)
            if path_id not in numbers:
                raise InputError(
                    f"detection row {row} comes from ground truth path {path_id!r}, which is "
                    "not among paths"
                )
            targets.append(numbers[path_id])
        elif isinstance(detection, ss.Clutter):
            targets.append(-1)
        else:
            raise InputError(
                f"detection row {row} is a {type(detection).__name__}, neither TrueDetection "
                "nor Clutter, so its origin is unknown"
            )
    return Origins(
        rows=np.array(rows, dtype=np.int64), target_ids=np.array(targets, dtype=np.int64)
    )
