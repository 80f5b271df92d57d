"""Motion models: state transition f(x, dt), its Jacobian F and process noise Q(dt).

Every model works for any scan interval ``dt > 0`` and on batches: a state array of
shape ``(..., n)`` maps to ``(..., n)``, a Jacobian to ``(..., n, n)``.

Linear models (seed 000, section 4.3, "Motion Model"):

* :class:`ConstantVelocity` and :class:`ConstantAcceleration` in 1, 2 or 3 spatial
  dimensions, discretised from continuous white-noise acceleration (respectively jerk)
  with power spectral density ``noise_intensity`` (Bar-Shalom, Li & Kirubarajan 2001,
  sections 6.2.2 and 6.2.3).
* :class:`RandomWalk`: ``x_k = x_{k-1} + q``, ``q ~ N(0, noise_intensity * dt * I)``
  (the scalar model of seeds 001 and 003 with ``dt = 1``).

Nonlinear model (seed 000, "Coordinated Turn"):

* :class:`CoordinatedTurn`: state ``(x, y, speed, heading, turn_rate)``, with the
  Jacobian used by the extended Kalman filter.

State layout of the Cartesian models is positions first, then velocities, then
accelerations: ``(x, y, vx, vy)`` for a 2-D constant-velocity model.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from mapassoc.errors import InputError
from mapassoc.validation import check_positive

__all__ = [
    "MotionModel",
    "ConstantVelocity",
    "ConstantAcceleration",
    "RandomWalk",
    "CoordinatedTurn",
]

_AXES = ("x", "y", "z")

FloatArray = NDArray[np.float64]


@runtime_checkable
class MotionModel(Protocol):
    """What the filters and the hypothesis generator need of a motion model."""

    @property
    def state_dim(self) -> int:
        """Length n of the state vector."""
        ...

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the state components, used as column names in files."""
        ...

    @property
    def position_indices(self) -> tuple[int, ...]:
        """Indices of the Cartesian position components in the state."""
        ...

    @property
    def is_linear(self) -> bool:
        """Whether :meth:`transition` is linear (then the Jacobian is F(dt))."""
        ...

    def transition(self, x: FloatArray, dt: float) -> FloatArray:
        """Predicted mean f(x, dt), shape ``(..., n)``."""
        ...

    def jacobian(self, x: FloatArray, dt: float) -> FloatArray:
        """Jacobian of f at x, shape ``(..., n, n)``."""
        ...

    def process_noise(self, dt: float) -> FloatArray:
        """Process noise covariance Q(dt), shape ``(n, n)``."""
        ...


def _check_dt(dt: float) -> float:
    if not (isinstance(dt, (int, float, np.floating)) and math.isfinite(dt) and dt > 0):
        raise InputError(f"dt must be a positive finite scan interval, got {dt!r}")
    return float(dt)


def _check_ndim(ndim: int) -> int:
    if not isinstance(ndim, (int, np.integer)) or isinstance(ndim, bool) or ndim not in (1, 2, 3):
        raise InputError(f"ndim must be 1, 2 or 3 spatial dimensions, got {ndim!r}")
    return int(ndim)


_MATRIX_CACHE_SIZE = 64
"""Distinct (time step, model) pairs whose F and Q a linear kinematic model remembers."""


class _LinearKinematic:
    """Shared machinery of the polynomial (nearly constant derivative) models.

    ``order`` is the number of per-axis state components: 2 for constant velocity
    (position, velocity), 3 for constant acceleration.
    """

    _order: int
    _prefixes: tuple[str, ...]

    def __init__(self, *, ndim: int = 2, noise_intensity: float) -> None:
        self.ndim = _check_ndim(ndim)
        self.noise_intensity = check_positive("noise_intensity", noise_intensity)

    @property
    def state_dim(self) -> int:
        return self.ndim * self._order

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(p + a for p in self._prefixes for a in _AXES[: self.ndim])

    @property
    def position_indices(self) -> tuple[int, ...]:
        return tuple(range(self.ndim))

    @property
    def velocity_indices(self) -> tuple[int, ...]:
        return tuple(range(self.ndim, 2 * self.ndim))

    @property
    def is_linear(self) -> bool:
        return True

    def _axis_blocks(self, dt: float) -> tuple[FloatArray, FloatArray]:
        raise NotImplementedError  # implemented by each concrete model

    def _matrices(self, dt: float) -> tuple[FloatArray, FloatArray]:
        """(F(dt), Q(dt)), read-only and remembered per time step.

        A recording has few distinct time steps, and the track trees predict with them
        thousands of times; the per-axis blocks (order x order) are expanded onto the
        layout [positions, velocities, ...].
        """
        key = (_check_dt(dt), self.ndim, self.noise_intensity)
        cache: dict[tuple[float, int, float], tuple[FloatArray, FloatArray]] = (
            self.__dict__.setdefault("_matrix_cache", {})
        )
        found = cache.get(key)
        if found is None:
            if len(cache) >= _MATRIX_CACHE_SIZE:
                cache.clear()
            eye = np.eye(self.ndim)
            F, Q = (np.kron(block, eye) for block in self._axis_blocks(key[0]))
            F.setflags(write=False)
            Q.setflags(write=False)
            found = cache[key] = (F, Q)
        return found

    def transition_matrix(self, dt: float) -> FloatArray:
        """F(dt), shape ``(n, n)`` (read-only)."""
        return self._matrices(dt)[0]

    def process_noise(self, dt: float) -> FloatArray:
        """Q(dt), shape ``(n, n)`` (read-only)."""
        return self._matrices(dt)[1]

    def transition(self, x: FloatArray, dt: float) -> FloatArray:
        return np.asarray(x, dtype=float) @ self.transition_matrix(dt).T

    def jacobian(self, x: FloatArray, dt: float) -> FloatArray:
        F = self.transition_matrix(dt)
        shape = np.shape(x)[:-1] + F.shape
        return np.broadcast_to(F, shape).copy()

    def __repr__(self) -> str:
        return f"{type(self).__name__}(ndim={self.ndim}, noise_intensity={self.noise_intensity})"


class ConstantVelocity(_LinearKinematic):
    """Nearly constant velocity, continuous white-noise acceleration model.

    Per axis, with ``q = noise_intensity`` (units: length^2 / time^3)::

        F = [[1, dt], [0, 1]],   Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]

    Parameters
    ----------
    ndim : {1, 2, 3}
        Number of spatial dimensions.
    noise_intensity : float
        Power spectral density q of the acceleration noise, > 0.
    """

    _order = 2
    _prefixes = ("", "v")

    def _axis_blocks(self, dt: float) -> tuple[FloatArray, FloatArray]:
        q = self.noise_intensity
        F = np.array([[1.0, dt], [0.0, 1.0]])
        Q = q * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
        return F, Q


class ConstantAcceleration(_LinearKinematic):
    """Nearly constant acceleration, continuous white-noise jerk model.

    Per axis, with ``q = noise_intensity``::

        F = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]
        Q = q [[dt^5/20, dt^4/8, dt^3/6], [dt^4/8, dt^3/3, dt^2/2], [dt^3/6, dt^2/2, dt]]

    Parameters
    ----------
    ndim : {1, 2, 3}
        Number of spatial dimensions.
    noise_intensity : float
        Power spectral density q of the jerk noise, > 0.
    """

    _order = 3
    _prefixes = ("", "v", "a")

    def _axis_blocks(self, dt: float) -> tuple[FloatArray, FloatArray]:
        q = self.noise_intensity
        F = np.array([[1.0, dt, dt**2 / 2.0], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
        Q = q * np.array(
            [
                [dt**5 / 20.0, dt**4 / 8.0, dt**3 / 6.0],
                [dt**4 / 8.0, dt**3 / 3.0, dt**2 / 2.0],
                [dt**3 / 6.0, dt**2 / 2.0, dt],
            ]
        )
        return F, Q


class RandomWalk(_LinearKinematic):
    """Random walk ``x_k = x_{k-1} + q_k`` with ``q_k ~ N(0, noise_intensity * dt * I)``.

    Seeds 001 and 003 use the scalar case (``ndim=1``, ``dt=1``), for which
    ``noise_intensity`` is the per-step motion variance (0.35 in seed 003).

    Parameters
    ----------
    ndim : {1, 2, 3}
        Number of spatial dimensions.
    noise_intensity : float
        Variance of the step per unit time, > 0.
    """

    _order = 1
    _prefixes = ("",)

    @property
    def velocity_indices(self) -> tuple[int, ...]:
        return ()

    def _axis_blocks(self, dt: float) -> tuple[FloatArray, FloatArray]:
        return np.array([[1.0]]), np.array([[self.noise_intensity * dt]])


def _sinc_half(u: FloatArray) -> FloatArray:
    """sin(u) / u, exact at u = 0."""
    return np.sinc(u / np.pi)


def _dsinc_half(u: FloatArray) -> FloatArray:
    """d/du [sin(u)/u] = (u cos u - sin u) / u^2, with its series near 0."""
    u = np.asarray(u, dtype=float)
    small = np.abs(u) < 1e-4
    safe = np.where(small, 1.0, u)
    exact = (safe * np.cos(safe) - np.sin(safe)) / safe**2
    series = -u / 3.0 + u**3 / 30.0
    return np.where(small, series, exact)


class CoordinatedTurn:
    """Coordinated turn with unknown, nearly constant turn rate (2-D).

    State ``(x, y, speed, heading, turn_rate)``; heading in radians from the x axis,
    turn rate in rad per unit time.  With ``u = turn_rate * dt / 2`` the exact
    transition is::

        x'  = x + speed * dt * sinc(u) * cos(heading + u)
        y'  = y + speed * dt * sinc(u) * sin(heading + u)
        heading' = heading + turn_rate * dt;  speed, turn_rate unchanged

    with ``sinc(u) = sin(u)/u``, which is exact and smooth through ``turn_rate = 0``
    (straight-line motion).  Process noise: white acceleration along the track
    (``speed_noise_intensity``) and white turn-rate acceleration
    (``turn_rate_noise_intensity``), the latter integrated into the heading::

        Q_speed = q_s dt,  Q_(heading, turn_rate) = q_w [[dt^3/3, dt^2/2], [dt^2/2, dt]]

    Parameters
    ----------
    speed_noise_intensity : float
        Power spectral density of the along-track acceleration, > 0.
    turn_rate_noise_intensity : float
        Power spectral density of the turn-rate derivative, > 0.
    """

    state_dim = 5
    state_names = ("x", "y", "speed", "heading", "turn_rate")
    position_indices = (0, 1)
    is_linear = False

    def __init__(self, *, speed_noise_intensity: float, turn_rate_noise_intensity: float) -> None:
        self.speed_noise_intensity = check_positive(
            "speed_noise_intensity", speed_noise_intensity
        )
        self.turn_rate_noise_intensity = check_positive(
            "turn_rate_noise_intensity", turn_rate_noise_intensity
        )

    def transition(self, x: FloatArray, dt: float) -> FloatArray:
        dt = _check_dt(dt)
        x = np.asarray(x, dtype=float)
        speed, heading, rate = x[..., 2], x[..., 3], x[..., 4]
        u = rate * dt / 2.0
        step = speed * dt * _sinc_half(u)
        angle = heading + u
        out = x.copy()
        out[..., 0] = x[..., 0] + step * np.cos(angle)
        out[..., 1] = x[..., 1] + step * np.sin(angle)
        out[..., 3] = heading + rate * dt
        return out

    def jacobian(self, x: FloatArray, dt: float) -> FloatArray:
        dt = _check_dt(dt)
        x = np.asarray(x, dtype=float)
        speed, heading, rate = x[..., 2], x[..., 3], x[..., 4]
        u = rate * dt / 2.0
        s = dt * _sinc_half(u)  # displacement per unit speed
        ds = dt * _dsinc_half(u) * dt / 2.0  # d s / d turn_rate
        angle = heading + u
        c, sn = np.cos(angle), np.sin(angle)
        J = np.zeros(x.shape[:-1] + (5, 5))
        J[..., 0, 0] = 1.0
        J[..., 1, 1] = 1.0
        J[..., 0, 2] = s * c
        J[..., 1, 2] = s * sn
        J[..., 0, 3] = -speed * s * sn
        J[..., 1, 3] = speed * s * c
        J[..., 0, 4] = speed * (ds * c - s * sn * dt / 2.0)
        J[..., 1, 4] = speed * (ds * sn + s * c * dt / 2.0)
        J[..., 2, 2] = 1.0
        J[..., 3, 3] = 1.0
        J[..., 3, 4] = dt
        J[..., 4, 4] = 1.0
        return J

    def process_noise(self, dt: float) -> FloatArray:
        dt = _check_dt(dt)
        Q = np.zeros((5, 5))
        Q[2, 2] = self.speed_noise_intensity * dt
        qw = self.turn_rate_noise_intensity
        Q[3:5, 3:5] = qw * np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
        return Q

    def __repr__(self) -> str:
        return (
            f"CoordinatedTurn(speed_noise_intensity={self.speed_noise_intensity}, "
            f"turn_rate_noise_intensity={self.turn_rate_noise_intensity})"
        )
