"""Measurement models h(x) + v, v ~ N(0, R) (seed 000, section 4, "Measurement Modeling").

* :class:`LinearMeasurement`: ``z = H x + v``; :meth:`LinearMeasurement.position` builds
  the usual position-only H for a motion model.
* :class:`RangeBearing`: range and bearing of the target from a sensor at a known 2-D
  position (nonlinear; Jacobian for the EKF).  Bearing residuals are wrapped to
  (-pi, pi] so that innovations across the +-pi cut are small, as they should be.

Every model maps a batch of states ``(..., n)`` to predicted measurements ``(..., dz)``,
gives the Jacobian ``(..., dz, n)``, the residual ``z - z_hat`` (wrapped where needed),
and the inverse used to start a track at a single detection:
:meth:`position_from_measurement` returns the Cartesian position and its covariance.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.errors import InputError
from mapassoc.models.motion import MotionModel
from mapassoc.validation import check_covariance, check_finite_array

__all__ = ["MeasurementModel", "LinearMeasurement", "RangeBearing", "wrap_angle"]

FloatArray = NDArray[np.float64]


def wrap_angle(angle: ArrayLike) -> FloatArray:
    """Wrap angles to (-pi, pi].

    Parameters
    ----------
    angle : array_like
        Angles in radians, any shape.

    Returns
    -------
    ndarray
        Same shape, each value in (-pi, pi].
    """
    a = np.asarray(angle, dtype=float)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@runtime_checkable
class MeasurementModel(Protocol):
    """What the filters and the hypothesis generator need of a measurement model."""

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


class LinearMeasurement:
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
        names = tuple(component_names)
        if len(names) != dz or len(set(names)) != dz:
            raise InputError(
                f"component_names must be {dz} distinct names (one per row of H), got {names!r}"
            )
        self._names = names
        self._position_indices = None if position_indices is None else tuple(position_indices)

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
        idx = tuple(motion.position_indices)
        d = len(idx)
        std = np.broadcast_to(np.asarray(noise_std, dtype=float), (d,))
        if not np.all(np.isfinite(std)) or np.any(std <= 0):
            raise InputError(f"noise_std must be positive and finite, got {noise_std!r}")
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

    def __repr__(self) -> str:
        return f"LinearMeasurement(H={self.H.tolist()}, R={self.R.tolist()}, names={self._names})"


class RangeBearing:
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
        for name, val in (("range_std", range_std), ("bearing_std", bearing_std)):
            if not (np.isfinite(val) and val > 0):
                raise InputError(f"{name} must be positive and finite, got {val!r}")
        self.R = np.diag([float(range_std) ** 2, float(bearing_std) ** 2])
        idx = tuple(int(i) for i in position_indices)
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
