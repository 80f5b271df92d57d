"""Measurement models h(x) + v, v ~ N(0, R) (Afzal's survey, section 4, "Measurement Modeling").

* :class:`LinearMeasurement`: ``z = H x + v``; :meth:`LinearMeasurement.position` builds
  the usual position-only H for a motion model.
* :class:`RangeBearing`: range and bearing of the target from a sensor at a known 2-D
  position (nonlinear; Jacobian for the EKF).  Bearing residuals are wrapped to
  (-pi, pi] so that innovations across the +-pi cut are small, as they should be.

Every model maps a batch of states ``(..., n)`` to predicted measurements ``(..., dz)``,
gives the Jacobian ``(..., dz, n)``, the residual ``z - z_hat`` (wrapped where needed),
and the inverse used to start a track at a single detection:
:meth:`position_from_measurement` returns the Cartesian position and its covariance.

Every model subclasses the :class:`MeasurementModel` protocol, which also says whether
it can act on the states of a motion model (:meth:`MeasurementModel.motion_mismatch`) and
how it acts on a track's initiation state (:meth:`MeasurementModel.on_initiation_state`,
:attr:`MeasurementModel.measures_position_directly`; used by :mod:`mapassoc.models.birth`).
:data:`MEASUREMENT_REGISTRY` maps the configuration names of ``[[sensors]] measurement``
to model classes, their settings keys and how to read and write them
(:mod:`mapassoc.data.config` reads and writes sensors through it): a new measurement model
is one class plus one :func:`register_measurement_model` call.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError
from mapassoc.models.angles import wrap_angle
from mapassoc.models.motion import MotionModel
from mapassoc.validation import (
    check_covariance,
    check_finite_array,
    check_instance,
    check_integer,
    check_numeric_array,
    check_standard_deviation,
    check_text,
    shown,
)

__all__ = [
    "MeasurementModel",
    "LinearMeasurement",
    "RangeBearing",
    "wrap_angle",
    "SettingsReader",
    "MeasurementSpec",
    "MEASUREMENT_REGISTRY",
    "register_measurement_model",
    "measurement_spec",
]





@runtime_checkable
class MeasurementModel(Protocol):
    """What the filters, the track initiation and the hypothesis generator need of a model.

    The members up to :meth:`position_from_measurement` describe the measurement.  The
    others say whether the model fits a motion model and how it acts on a track's
    initiation state (:mod:`mapassoc.models.birth`); they have default implementations
    here (a model that fits every motion model, reads only the position components and
    has no batch shortcut), so a concrete model subclasses this protocol and overrides
    only what differs.  A class that implements the protocol structurally, without
    subclassing it, must provide every member.
    """

    @property
    def measurement_dim(self) -> int: ...

    @property
    def component_names(self) -> tuple[str, ...]:
        """Column names of the measurement components in a detections file."""
        ...

    @property
    def noise_covariance(self) -> FloatArray:
        """R, shape ``(dz, dz)``."""
        ...

    @property
    def is_linear(self) -> bool: ...

    def predict(self, x: FloatArray) -> FloatArray:
        """h(x), shape ``(..., dz)``."""
        ...

    def jacobian(self, x: FloatArray) -> FloatArray:
        """dh/dx at x, shape ``(..., dz, n)``."""
        ...

    def residual(self, z: FloatArray, z_hat: FloatArray) -> FloatArray:
        """z - z_hat with angular components wrapped, broadcast shape ``(..., dz)``."""
        ...

    def position_from_measurement(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Cartesian position implied by one detection and its covariance."""
        ...

    # ------------------------------------------------------------ motion and initiation

    def motion_mismatch(self, motion: MotionModel) -> str | None:
        """Why this model cannot act on the states of ``motion``, or None if it can.

        Parameters
        ----------
        motion : MotionModel

        Returns
        -------
        str or None
            A description of the mismatch (the caller names the sensor); default None.
        """
        return None

    @property
    def measures_position_directly(self) -> bool:
        """Whether :meth:`position_from_measurement` is ``(z, R)`` for every detection.

        Then every track born at a detection of this model has the same covariance, and
        :func:`mapassoc.models.birth.birth_states` builds a batch of births without a
        loop.  Default False.
        """
        return False

    def on_initiation_state(self, motion: MotionModel, model: MotionModel) -> MeasurementModel:
        """This measurement acting on states of ``model``, the initiation model of ``motion``.

        Asked only when ``motion.needs_conversion()`` (the initiation state space differs
        from the motion model's).  Both spaces share the position components.

        Parameters
        ----------
        motion : MotionModel
            The motion model this measurement was written for.
        model : MotionModel
            ``motion.initiation_model()``.

        Returns
        -------
        MeasurementModel
            Default: ``self`` (a model that reads only the position components, through
            ``position_indices`` shared by both spaces).

        Raises
        ------
        InputError
            The measurement reads components the initiation state does not have.
        """
        return self


def _names(argument: str, value: object) -> tuple[str, ...]:
    """``value`` as a tuple of strings (a sequence of names, not one string)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        raise InputError(
            f"{argument} must be a list or tuple of strings, got {shown(value)}", key=argument
        )
    for i, name in enumerate(value):
        check_text(f"{argument}[{i}]", name, key=argument)
    return tuple(value)


def _indices(argument: str, value: object) -> tuple[int, ...]:
    """``value`` as a tuple of state indices (integers >= 0)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        raise InputError(
            f"{argument} must be a list or tuple of integers, got {shown(value)}", key=argument
        )
    return tuple(check_integer(f"{argument}[{i}]", v, minimum=0) for i, v in enumerate(value))


class LinearMeasurement(MeasurementModel):
    """Linear-Gaussian measurement ``z = H x + v``, ``v ~ N(0, R)``.

    Parameters
    ----------
    H : array_like, shape (dz, n)
        Measurement matrix.
    R : array_like, shape (dz, dz)
        Measurement noise covariance, symmetric positive-definite.
    component_names : sequence of str
        Names of the dz measurement components (file column names).
    position_indices : sequence of int, optional
        For a position measurement: state indices measured by each component, so that
        a track can be started from one detection.  ``None`` if the measurement is not
        a direct position measurement.
    """

    is_linear = True

    def __init__(
        self,
        *,
        H: ArrayLike,
        R: ArrayLike,
        component_names: tuple[str, ...] | list[str],
        position_indices: tuple[int, ...] | list[int] | None = None,
    ) -> None:
        H_arr = check_finite_array("H", H)
        if H_arr.ndim != 2:
            raise InputError(f"H must be a 2-D (dz, n) matrix, got shape {H_arr.shape}")
        dz = H_arr.shape[0]
        self.H = H_arr
        self.R = check_covariance("R", R, dim=dz)
        names = _names("component_names", component_names)
        if len(names) != dz or len(set(names)) != dz:
            raise InputError(
                f"component_names must be {dz} distinct names (one per row of H), got {names!r}"
            )
        self._names = names
        self._position_indices = (
            None if position_indices is None else _indices("position_indices", position_indices)
        )

    @classmethod
    def position(
        cls, motion: MotionModel, *, noise_std: float | ArrayLike
    ) -> LinearMeasurement:
        """Position-only measurement of a Cartesian motion model.

        Parameters
        ----------
        motion : MotionModel
            Motion model whose ``position_indices`` are measured.
        noise_std : float or array_like, shape (d,)
            Standard deviation of each position component (same units as the state).
        """
        check_instance("motion", motion, MotionModel, expected="a motion model")
        idx = tuple(motion.position_indices)
        d = len(idx)
        std = np.broadcast_to(check_numeric_array("noise_std", noise_std), (d,))
        if not np.all(np.isfinite(std)) or np.any(std <= 0):
            raise InputError(
                f"noise_std must be positive and finite, got {noise_std!r}", key="noise_std"
            )
        same = bool(np.all(std == std[0]))
        for i, value in enumerate(std):
            name = "noise_std" if same else f"noise_std[{i}]"
            check_standard_deviation(name, float(value), key=name)
        H = np.zeros((d, motion.state_dim))
        H[np.arange(d), idx] = 1.0
        names = tuple(motion.state_names[i] for i in idx)
        return cls(H=H, R=np.diag(std**2), component_names=names, position_indices=idx)

    @property
    def measurement_dim(self) -> int:
        return self.H.shape[0]

    @property
    def component_names(self) -> tuple[str, ...]:
        return self._names

    @property
    def noise_covariance(self) -> FloatArray:
        return self.R

    def predict(self, x: FloatArray) -> FloatArray:
        return np.asarray(x, dtype=float) @ self.H.T

    def jacobian(self, x: FloatArray) -> FloatArray:
        shape = np.shape(x)[:-1] + self.H.shape
        return np.broadcast_to(self.H, shape).copy()

    def residual(self, z: FloatArray, z_hat: FloatArray) -> FloatArray:
        return np.asarray(z, dtype=float) - np.asarray(z_hat, dtype=float)

    def position_from_measurement(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Position = z, covariance R (needs ``position_indices``)."""
        if self._position_indices is None:
            raise InputError(
                "position_from_measurement needs a position measurement "
                "(LinearMeasurement built with position_indices)"
            )
        return np.asarray(z, dtype=float).copy(), self.R.copy()

    @property
    def position_indices(self) -> tuple[int, ...] | None:
        return self._position_indices

    def motion_mismatch(self, motion: MotionModel) -> str | None:
        """A message if H has not one column per state of ``motion``."""
        if self.H.shape[1] != motion.state_dim:
            return (
                f"measurement matrix H has {self.H.shape[1]} "
                f"columns but the motion model {motion!r} has {motion.state_dim} states"
            )
        return None

    @property
    def measures_position_directly(self) -> bool:
        """True for a position measurement (built with ``position_indices``)."""
        return self._position_indices is not None

    def on_initiation_state(self, motion: MotionModel, model: MotionModel) -> LinearMeasurement:
        """H re-indexed from ``motion``'s position columns onto ``model``'s.

        Raises
        ------
        InputError
            H reads state components other than the position.
        """
        source = list(motion.position_indices)
        others = [i for i in range(motion.state_dim) if i not in source]
        if np.any(self.H[:, others] != 0.0):
            raise InputError(
                f"the linear measurement H={self.H.tolist()} reads state components other "
                f"than the position {[motion.state_names[i] for i in source]}, so it cannot be "
                f"applied to a {type(model).__name__} initiation state"
            )
        H = np.zeros((self.measurement_dim, model.state_dim))
        H[:, list(model.position_indices)] = self.H[:, source]
        return LinearMeasurement(
            H=H,
            R=self.R,
            component_names=self.component_names,
            position_indices=self.position_indices,
        )

    def __repr__(self) -> str:
        return f"LinearMeasurement(H={self.H.tolist()}, R={self.R.tolist()}, names={self._names})"


class RangeBearing(MeasurementModel):
    """Range and bearing from a sensor at a known 2-D position.

    ``h(x) = (sqrt(dx^2 + dy^2), atan2(dy, dx))`` with ``(dx, dy)`` the target
    position minus the sensor position.  Bearing is measured from the x axis,
    counter-clockwise, in radians, and residuals are wrapped to (-pi, pi].

    Parameters
    ----------
    sensor_position : array_like, shape (2,)
        Sensor position in the state's Cartesian frame.
    range_std : float
        Range noise standard deviation, > 0.
    bearing_std : float
        Bearing noise standard deviation in radians, > 0.
    position_indices : tuple of int
        State indices of the target's x and y (``motion.position_indices[:2]``).
    """

    is_linear = False
    component_names = ("range", "bearing")
    measurement_dim = 2

    def __init__(
        self,
        *,
        sensor_position: ArrayLike,
        range_std: float,
        bearing_std: float,
        position_indices: tuple[int, int] = (0, 1),
    ) -> None:
        self.sensor_position = check_finite_array("sensor_position", sensor_position, shape=(2,))
        stds = [
            check_standard_deviation(name, val, key=name)
            for name, val in (("range_std", range_std), ("bearing_std", bearing_std))
        ]
        self.R = np.diag([stds[0] ** 2, stds[1] ** 2])
        idx = _indices("position_indices", position_indices)
        if len(idx) != 2:
            raise InputError(f"position_indices must name the x and y indices, got {idx!r}")
        self.position_indices = idx

    @property
    def noise_covariance(self) -> FloatArray:
        return self.R

    def _offsets(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        x = np.asarray(x, dtype=float)
        dx = x[..., self.position_indices[0]] - self.sensor_position[0]
        dy = x[..., self.position_indices[1]] - self.sensor_position[1]
        return dx, dy

    def predict(self, x: FloatArray) -> FloatArray:
        dx, dy = self._offsets(x)
        return np.stack([np.hypot(dx, dy), np.arctan2(dy, dx)], axis=-1)

    def jacobian(self, x: FloatArray) -> FloatArray:
        x = np.asarray(x, dtype=float)
        dx, dy = self._offsets(x)
        r2 = dx**2 + dy**2
        if np.any(r2 == 0.0):
            raise InputError(
                "range-bearing Jacobian is undefined for a state at the sensor position "
                f"{self.sensor_position.tolist()}"
            )
        r = np.sqrt(r2)
        J = np.zeros(x.shape[:-1] + (2, x.shape[-1]))
        ix, iy = self.position_indices
        J[..., 0, ix] = dx / r
        J[..., 0, iy] = dy / r
        J[..., 1, ix] = -dy / r2
        J[..., 1, iy] = dx / r2
        return J

    def residual(self, z: FloatArray, z_hat: FloatArray) -> FloatArray:
        d = np.asarray(z, dtype=float) - np.asarray(z_hat, dtype=float)
        d = np.array(d, copy=True)
        d[..., 1] = wrap_angle(d[..., 1])
        return d

    def motion_mismatch(self, motion: MotionModel) -> str | None:
        """A message if ``position_indices`` exceed the states of ``motion``."""
        if max(self.position_indices) >= motion.state_dim:
            return (
                f"range-bearing position indices "
                f"{self.position_indices} exceed the motion model's "
                f"{motion.state_dim} states"
            )
        return None

    def position_from_measurement(self, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Cartesian position of a detection and its first-order covariance J R J^T."""
        z = np.asarray(z, dtype=float)
        r, b = z[0], z[1]
        pos = self.sensor_position + r * np.array([np.cos(b), np.sin(b)])
        J = np.array([[np.cos(b), -r * np.sin(b)], [np.sin(b), r * np.cos(b)]])
        return pos, J @ self.R @ J.T

    def __repr__(self) -> str:
        return (
            f"RangeBearing(sensor_position={self.sensor_position.tolist()}, "
            f"range_std={np.sqrt(self.R[0, 0])}, bearing_std={np.sqrt(self.R[1, 1])})"
        )


# --------------------------------------------------------------------------- registry


class SettingsReader(Protocol):
    """Typed, checked access to the settings of one ``[[sensors]]`` table.

    :mod:`mapassoc.data.config` provides it.  Keys are the setting names inside the table
    (``"noise_std"``); every accessor reads a required key and fails with an error that
    names the full dotted key and the offending value.
    """

    def fail(self, key: str, message: str) -> Exception:
        """The error to raise for a problem with ``key`` (``"measurement"`` for the kind)."""
        ...

    def number(self, key: str) -> float:
        """A TOML integer or float, as float."""
        ...

    def integer(self, key: str) -> int:
        """A TOML integer."""
        ...

    def string(self, key: str) -> str:
        """A TOML string."""
        ...

    def positive(self, key: str) -> float:
        """A number > 0 (finite)."""
        ...

    def nonnegative(self, key: str) -> float:
        """A number >= 0 (finite)."""
        ...

    def finite(self, key: str) -> float:
        """A finite number."""
        ...

    def finite_vector(self, key: str, names: tuple[str, ...]) -> list[float]:
        """An array of one finite number per entry of ``names`` (``[x, y]``)."""
        ...

    def positive_per_component(self, key: str, count: int) -> list[float]:
        """One positive number for all ``count`` components, or an array of ``count`` of them.

        Made for standard deviations: a wrong length is reported as "one standard
        deviation per position component".
        """
        ...


SettingValue = float | int | str | bool | Sequence[float] | NDArray[np.float64]
"""A setting as written: a scalar, or an array of floats."""

MeasurementReader = Callable[[SettingsReader, MotionModel], MeasurementModel]
MeasurementWriter = Callable[[MeasurementModel, MotionModel], Mapping[str, SettingValue] | None]


@dataclass(frozen=True)
class MeasurementSpec:
    """A registered measurement model: its configuration name, class and settings.

    Parameters
    ----------
    name : str
        Value of ``measurement`` in a ``[[sensors]]`` table.
    cls : type
        The model class (instances of it and of its subclasses are written by :attr:`write`).
    keys : tuple of str
        Its keys in the sensor table besides the common ones, in file order.
    read : callable
        ``read(settings, motion)`` builds the model from a :class:`SettingsReader` for the
        motion model ``motion``; it reports bad settings with ``settings.fail``.
    write : callable
        ``write(measurement, motion)`` returns ``{key: value}`` for every key of
        :attr:`keys` (floats, ints, strings, booleans or arrays of floats), or None if
        this particular model cannot be expressed by the settings.
    """

    name: str
    cls: type
    keys: tuple[str, ...]
    read: MeasurementReader
    write: MeasurementWriter


MEASUREMENT_REGISTRY: dict[str, MeasurementSpec] = {}
"""Registered measurement models by configuration name, in registration order."""


def register_measurement_model(
    name: str,
    cls: type,
    keys: tuple[str, ...],
    *,
    read: MeasurementReader,
    write: MeasurementWriter,
) -> MeasurementSpec:
    """Register ``cls`` under the configuration name ``name``.

    Parameters
    ----------
    name : str
        New, non-empty configuration name.
    cls : type
        Model class, not registered yet.
    keys : tuple of str
        Its settings keys (see :class:`MeasurementSpec`).
    read, write : callable
        See :class:`MeasurementSpec`.

    Returns
    -------
    MeasurementSpec

    Raises
    ------
    InputError
        A name or class already registered, or keys that are not distinct strings.
    """
    if not isinstance(name, str) or not name or name in MEASUREMENT_REGISTRY:
        raise InputError(f"name must be a new, non-empty string, got {name!r}")
    if any(spec.cls is cls for spec in MEASUREMENT_REGISTRY.values()):
        raise InputError(f"cls {cls.__name__} is already registered")
    keys = tuple(keys)
    if not all(isinstance(key, str) and key for key in keys) or len(set(keys)) != len(keys):
        raise InputError(f"keys must be distinct non-empty strings, got {keys!r}")
    spec = MeasurementSpec(name, cls, keys, read, write)
    MEASUREMENT_REGISTRY[name] = spec
    return spec


def measurement_spec(measurement: object) -> MeasurementSpec | None:
    """The registration of the nearest registered class of ``measurement``, or None.

    The class's method resolution order is searched, so a subclass of a registered model
    is written like it.
    """
    for klass in type(measurement).__mro__:
        for spec in MEASUREMENT_REGISTRY.values():
            if spec.cls is klass:
                return spec
    return None


def _read_position(settings: SettingsReader, motion: MotionModel) -> LinearMeasurement:
    count = len(tuple(motion.position_indices))
    std = settings.positive_per_component("noise_std", count)
    return LinearMeasurement.position(motion, noise_std=np.array(std))


def _write_position(
    measurement: MeasurementModel, motion: MotionModel
) -> dict[str, SettingValue] | None:
    """``noise_std`` if ``measurement`` is exactly the position measurement it rebuilds."""
    if not isinstance(measurement, LinearMeasurement):
        return None
    variances = np.diag(measurement.R)
    if not np.all(variances > 0):
        return None
    std = np.sqrt(variances)
    rebuilt = LinearMeasurement.position(motion, noise_std=std)
    if (
        np.array_equal(rebuilt.H, measurement.H)
        and np.array_equal(rebuilt.R, measurement.R)
        and rebuilt.component_names == measurement.component_names
    ):
        return {"noise_std": float(std[0]) if np.all(std == std[0]) else std}
    return None


def _read_range_bearing(settings: SettingsReader, motion: MotionModel) -> RangeBearing:
    position_indices = tuple(motion.position_indices)
    if len(position_indices) != 2:
        raise settings.fail(
            "measurement",
            f"'range_bearing' needs a motion model with a 2-D position (ndim = 2 or "
            f"coordinated_turn); the motion model {motion!r} has "
            f"{len(position_indices)} position components",
        )
    xy = settings.finite_vector("position", ("x", "y"))
    return RangeBearing(
        sensor_position=np.array(xy),
        range_std=settings.positive("range_std"),
        bearing_std=settings.positive("bearing_std"),
        position_indices=(position_indices[0], position_indices[1]),
    )


def _write_range_bearing(
    measurement: MeasurementModel, motion: MotionModel
) -> dict[str, SettingValue] | None:
    if not isinstance(measurement, RangeBearing):
        return None
    return {
        "position": measurement.sensor_position,
        "range_std": math.sqrt(measurement.R[0, 0]),
        "bearing_std": math.sqrt(measurement.R[1, 1]),
    }


register_measurement_model(
    "position", LinearMeasurement, ("noise_std",), read=_read_position, write=_write_position
)
register_measurement_model(
    "range_bearing",
    RangeBearing,
    ("position", "range_std", "bearing_std"),
    read=_read_range_bearing,
    write=_write_range_bearing,
)
