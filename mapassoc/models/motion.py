"""Motion models: state transition f(x, dt), its Jacobian F and process noise Q(dt).

Every model works for any scan interval ``dt > 0`` and on batches: a state array of
shape ``(..., n)`` maps to ``(..., n)``, a Jacobian to ``(..., n, n)``.

Linear models (Afzal's survey, section 4.3, "Motion Model"):

* :class:`ConstantVelocity` and :class:`ConstantAcceleration` in 1, 2 or 3 spatial
  dimensions, discretised from continuous white-noise acceleration (respectively jerk)
  with power spectral density ``noise_intensity`` (Bar-Shalom, Li & Kirubarajan 2001,
  sections 6.2.2 and 6.2.3).
* :class:`Singer`: exponentially correlated (Ornstein-Uhlenbeck) acceleration with time
  constant ``tau`` and standard deviation ``sigma`` (Singer 1970), 1-3 D.
* :class:`RandomWalk`: ``x_k = x_{k-1} + q``, ``q ~ N(0, noise_intensity * dt * I)``
  (the scalar model of the n-object posterior's and of single-object tracking in clutter's
  worked examples, with ``dt = 1``).

* :class:`ConstantTurn`: a turn at a known rate in the 2-D constant-velocity state
  (Bar-Shalom, Li & Kirubarajan 2001, section 11.7.1), the turn model of a model set.

Nonlinear model (Afzal's survey, "Coordinated Turn"):

* :class:`CoordinatedTurn`: state ``(x, y, speed, heading, turn_rate)``, with the
  Jacobian used by the extended Kalman filter.

State layout of the Cartesian models is positions first, then velocities, then
accelerations: ``(x, y, vx, vy)`` for a 2-D constant-velocity model.

Every model subclasses the :class:`MotionModel` protocol, which also says how a track of
the model is initiated and smoothed (:mod:`mapassoc.models.birth`,
:mod:`mapassoc.evaluation.oracle`).
:data:`MOTION_REGISTRY` maps configuration names to model classes and their settings
(:mod:`mapassoc.data.config` reads and writes ``[motion]`` through it): a new model is one
class plus one :func:`register_motion_model` call.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError
from mapassoc.models.angles import wrap_angle
from mapassoc.validation import check_positive, check_standard_deviation

if TYPE_CHECKING:
    from mapassoc.models.population import BirthModel

__all__ = [
    "MotionModel",
    "ConstantVelocity",
    "ConstantAcceleration",
    "RandomWalk",
    "CoordinatedTurn",
    "ConstantTurn",
    "Singer",
    "MotionSetting",
    "MotionSpec",
    "MOTION_REGISTRY",
    "register_motion_model",
    "motion_spec",
]

_AXES = ("x", "y", "z")


@runtime_checkable
class MotionModel(Protocol):
    """What the filters, the track initiation and the hypothesis generator need of a model.

    The first seven members (``state_dim`` to ``process_noise``) describe the dynamics.  The
    others say how a track of this model starts and what the smoother needs; they have
    default implementations here (a model that starts in its own state space and needs no
    conversion), so a concrete model subclasses this protocol and overrides only what
    differs.  A class that implements the protocol structurally, without subclassing it,
    must provide every member.

    Track initiation (:mod:`mapassoc.models.birth`): a track starts at one detection in the state
    space of :meth:`initiation_model` (the detection fixes the position components; the
    other components are drawn from :meth:`birth_prior` of the initiation model).  If
    :meth:`needs_conversion`, the track is mapped into this model's space with
    :meth:`convert_initiated` after its first detection update at a later time (normally
    its second detection).  The smoother (:mod:`mapassoc.evaluation.oracle`) undoes that conversion
    with :meth:`revert_conversion`, carries the components in
    :attr:`conversion_prior_indices` over from the converted state, reports a track never
    converted through :meth:`unconverted_state` and canonicalises states with
    :meth:`canonical_states`.
    """

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

    # ------------------------------------------------------------ track initiation

    def initiation_model(self) -> MotionModel:
        """The model a track uses from its first detection until its conversion.

        Default: the model itself.
        """
        return self

    def needs_conversion(self) -> bool:
        """Whether :meth:`convert_initiated` changes the state space.  Default: False."""
        return False

    def birth_prior(self, birth: BirthModel) -> tuple[FloatArray, FloatArray]:
        """Prior mean and covariance of the unmeasured components at a track's birth.

        The unmeasured components are all but :attr:`position_indices`, in state order;
        asked of the :meth:`initiation_model` only.

        Parameters
        ----------
        birth : BirthModel
            Its per-model prior standard deviations.

        Returns
        -------
        mean : ndarray, shape (m,)
        cov : ndarray, shape (m, m)
            With ``m = state_dim - len(position_indices)``.

        Raises
        ------
        InputError
            The default: no prior is defined for this model.
        """
        raise InputError(f"no birth prior is defined for motion model {type(self).__name__}")

    def convert_initiated(
        self, x: FloatArray, P: FloatArray, birth: BirthModel
    ) -> tuple[FloatArray, FloatArray]:
        """Map :meth:`initiation_model` moments ``(n0,), (n0, n0)`` into this model's space.

        Default: the identity (the same arrays are returned).
        """
        return x, P

    # ------------------------------------------------------------ smoothing

    @property
    def conversion_prior_indices(self) -> tuple[int, ...]:
        """Components :meth:`convert_initiated` takes from the birth prior, not the state.

        The smoother reports early (pre-conversion) states with these components copied
        from the smoothed state at the conversion step.  Default: none.
        """
        return ()

    def revert_conversion(self, x: FloatArray, P: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Smoothed :meth:`initiation_model` moments from smoothed moments of this model.

        The inverse change of variables of :meth:`convert_initiated` with the components
        of :attr:`conversion_prior_indices` marginalised.  Default: the identity.
        """
        return x, P

    def unconverted_state(
        self, x: FloatArray, P: FloatArray, birth: BirthModel
    ) -> tuple[FloatArray, FloatArray]:
        """Moments in this model's space of a track that was never converted.

        ``x, P`` are :meth:`initiation_model` moments of a track detected at a single
        time.  Default: :meth:`convert_initiated`.
        """
        return self.convert_initiated(x, P, birth)

    def canonical_states(
        self, states: FloatArray, covariances: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Equivalent states ``(T, n)`` and covariances ``(T, n, n)`` in a canonical form.

        Default: unchanged (the same arrays are returned).
        """
        return states, covariances

    # ------------------------------------------------------------ scenario helpers

    def speed(self, state: FloatArray) -> float:
        """Speed of one state ``(n,)``; default: norm of the ``velocity_indices`` (0 if none)."""
        velocity = [state[i] for i in getattr(self, "velocity_indices", ())]
        return float(np.hypot(*velocity)) if len(velocity) == 2 else float(np.linalg.norm(velocity))

    def turn_rate(self, state: FloatArray) -> float:
        """Turn rate of one state ``(n,)`` (rad per unit time); default 0."""
        return 0.0


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


class _LinearKinematic(MotionModel):
    """Shared machinery of the polynomial (nearly constant derivative) models.

    ``order`` is the number of per-axis state components: 2 for constant velocity
    (position, velocity), 3 for constant acceleration.
    """

    _order: int
    _prefixes: tuple[str, ...]
    _birth_std_fields: tuple[str, ...] = ("velocity_std", "acceleration_std")
    """BirthModel fields of the prior std of the 2nd, 3rd, ... per-axis components."""

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

    def _parameters(self) -> tuple[float, ...]:
        """The parameters F and Q depend on besides dt and ndim (the cache key)."""
        return (self.noise_intensity,)

    def _axis_blocks(self, dt: float) -> tuple[FloatArray, FloatArray]:
        raise NotImplementedError  # implemented by each concrete model

    def birth_prior(self, birth: BirthModel) -> tuple[FloatArray, FloatArray]:
        """Zero mean; per derivative order, ``velocity_std^2`` then ``acceleration_std^2``.

        Diagonal covariance, one variance per unmeasured component (layout
        ``[velocities, accelerations]``, ``ndim`` of each); empty for a random walk.
        """
        stds = [getattr(birth, name) for name in self._birth_std_fields[: self._order - 1]]
        variances = np.repeat(np.array([std**2 for std in stds], dtype=float), self.ndim)
        return np.zeros(variances.shape[0]), np.diag(variances)

    def _matrices(self, dt: float) -> tuple[FloatArray, FloatArray]:
        """(F(dt), Q(dt)), read-only and remembered per time step.

        A recording has few distinct time steps, and the track trees predict with them
        thousands of times; the per-axis blocks (order x order) are expanded onto the
        layout [positions, velocities, ...].
        """
        key = (_check_dt(dt), self.ndim, *self._parameters())
        cache: dict[tuple[float, ...], tuple[FloatArray, FloatArray]] = (
            self.__dict__.setdefault("_matrix_cache", {})
        )
        found = cache.get(key)
        if found is None:
            if len(cache) >= _MATRIX_CACHE_SIZE:
                cache.clear()
            eye = np.eye(self.ndim)
            F, Q = (
                np.asarray(np.kron(block, eye), dtype=np.float64)
                for block in self._axis_blocks(key[0])
            )
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

    The worked examples of the n-object posterior and of single-object tracking in clutter
    (L. Svensson et al., "Multi-Object Tracking for Automotive Systems") use the scalar case
    (``ndim=1``, ``dt=1``), for which ``noise_intensity`` is the per-step motion variance
    (0.35 in the clutter example).

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


class _ExpBracket:
    """``f(x) = poly(x) + a e^-x + b x e^-x + c e^-2x``, a function with ``f(x) = O(x^p)``.

    :meth:`scaled` returns ``f(x) / x^p`` without the cancellation of the closed form at
    small ``x``: there it sums the Taylor series, whose coefficients are computed exactly
    (rational arithmetic) when the bracket is built; building checks that the
    coefficients below ``x^p`` vanish, so a mistyped formula fails at import.
    """

    _SERIES_BELOW = 1.0
    _SERIES_TERMS = 30

    def __init__(
        self, poly: tuple[Fraction, ...], a: Fraction, b: Fraction, c: Fraction, order: int
    ) -> None:
        self.poly = tuple(float(v) for v in poly)
        self.a, self.b, self.c = float(a), float(b), float(c)
        self.order = order
        coefficients = []
        for k in range(order + self._SERIES_TERMS):
            value = poly[k] if k < len(poly) else Fraction(0)
            value += a * Fraction((-1) ** k, math.factorial(k))
            if k >= 1:
                value += b * Fraction((-1) ** (k - 1), math.factorial(k - 1))
            value += c * Fraction((-2) ** k, math.factorial(k))
            coefficients.append(value)
        if any(v != 0 for v in coefficients[:order]) or coefficients[order] == 0:
            raise AssertionError(
                f"bracket is not of order exactly x^{order}: {coefficients[: order + 1]}"
            )
        self.series = tuple(float(v) for v in coefficients[order:])

    def scaled(self, x: float) -> float:
        """``f(x) / x^p`` for ``x > 0``."""
        if x < self._SERIES_BELOW:
            total = 0.0
            for coefficient in reversed(self.series):
                total = total * x + coefficient
            return total
        e1 = math.exp(-x)
        value = sum(p * x**k for k, p in enumerate(self.poly))
        value += self.a * e1 + self.b * x * e1 + self.c * math.exp(-2.0 * x)
        return value / x**self.order


def _bracket(poly: tuple[int | Fraction, ...], a: int, b: int, c: int, order: int) -> _ExpBracket:
    fractions = tuple(Fraction(v) for v in poly)
    return _ExpBracket(fractions, Fraction(a), Fraction(b), Fraction(c), order)


# Singer (1970) discretisation, with x = alpha T (E = e^-x, E2 = e^-2x):
#   F_pa = (x - 1 + E) / alpha^2,  F_va = (1 - E) / alpha
#   Q = 2 alpha sigma^2 * [q_ij], q_ij = B_ij(x) / (2 alpha^p_ij):
_SINGER_F_PA = _bracket((-1, 1), 1, 0, 0, 2)
_SINGER_F_VA = _bracket((1,), -1, 0, 0, 1)
_SINGER_Q = {
    # B11 = 1 - E2 + 2x + 2x^3/3 - 2x^2 - 4x E                 (p = 5)
    (0, 0): _bracket((1, 2, -2, Fraction(2, 3)), 0, -4, -1, 5),
    # B12 = E2 + 1 - 2E + 2x E - 2x + x^2                      (p = 4)
    (0, 1): _bracket((1, -2, 1), -2, 2, 1, 4),
    # B13 = 1 - E2 - 2x E                                      (p = 3)
    (0, 2): _bracket((1,), 0, -2, -1, 3),
    # B22 = 4E - 3 - E2 + 2x                                   (p = 3)
    (1, 1): _bracket((-3, 2), 4, 0, -1, 3),
    # B23 = E2 + 1 - 2E                                        (p = 2)
    (1, 2): _bracket((1,), -2, 0, 1, 2),
    # B33 = 1 - E2                                             (p = 1)
    (2, 2): _bracket((1,), 0, 0, -1, 1),
}


class Singer(_LinearKinematic):
    """Singer model: exponentially correlated (first-order Markov) acceleration.

    Per axis the state is (position, velocity, acceleration) and the acceleration is a
    zero-mean Ornstein-Uhlenbeck process with autocorrelation
    ``sigma^2 exp(-|t| / tau)`` (Singer 1970)::

        da/dt = -alpha a + w,   alpha = 1 / tau,   w white with PSD q = 2 alpha sigma^2

    With ``T = dt``, ``x = alpha T``, ``E = exp(-x)``, the exact discretisation is
    ([1]_; [2]_ gives the same Q)::

        F = [[1, T, (x - 1 + E) / alpha^2],
             [0, 1, (1 - E) / alpha],
             [0, 0, E]]

        Q = q [[q11, q12, q13], [q12, q22, q23], [q13, q23, q33]],  with
        q11 = (1 - E^2 + 2x + 2x^3/3 - 2x^2 - 4x E) / (2 alpha^5)
        q12 = (E^2 + 1 - 2E + 2x E - 2x + x^2) / (2 alpha^4)
        q13 = (1 - E^2 - 2x E) / (2 alpha^3)
        q22 = (4E - 3 - E^2 + 2x) / (2 alpha^3)
        q23 = (E^2 + 1 - 2E) / (2 alpha^2)
        q33 = (1 - E^2) / (2 alpha)

    For ``x < 1`` the entries are evaluated from their Taylor series (exact rational
    coefficients), which avoids the cancellation of the closed form.  As
    ``tau -> infinity`` with ``q`` fixed the model tends to :class:`ConstantAcceleration`
    with ``noise_intensity = q``; the acceleration's stationary variance is ``sigma^2``.

    Parameters
    ----------
    ndim : {1, 2, 3}
        Number of spatial dimensions.
    time_constant : float
        Correlation time tau of the acceleration (maneuver time constant), > 0.
    acceleration_std : float
        Standard deviation sigma of the acceleration (stationary), > 0.

    Raises
    ------
    InputError
        ``ndim`` not 1, 2 or 3, or ``time_constant`` / ``acceleration_std`` not a finite
        positive number (the message names the argument and its value).

    Notes
    -----
    The closed form of Q was checked against Van Loan's matrix-exponential computation
    (``tests/models/test_motion_models.py``) to 1e-10 over ``x`` from 1e-6 to 50.

    References
    ----------
    .. [1] R. A. Singer, "Estimating optimal tracking filter performance for manned
       maneuvering targets", IEEE Trans. Aerospace and Electronic Systems AES-6(4),
       473-483, 1970.
    .. [2] X. R. Li and V. P. Jilkov, "Survey of maneuvering target tracking. Part I:
       Dynamic models", IEEE Trans. Aerospace and Electronic Systems 39(4), 1333-1364,
       2003 (the Singer model section).
    """

    _order = 3
    _prefixes = ("", "v", "a")

    def __init__(self, *, ndim: int = 2, time_constant: float, acceleration_std: float) -> None:
        self.ndim = _check_ndim(ndim)
        self.time_constant = check_positive("time_constant", time_constant)
        self.acceleration_std = check_standard_deviation(
            "acceleration_std", acceleration_std, key="acceleration_std"
        )
        if not math.isfinite(self.noise_intensity):
            raise InputError(
                f"acceleration_std = {acceleration_std!r} and time_constant = "
                f"{time_constant!r} give the noise intensity 2 sigma^2 / tau = "
                f"{self.noise_intensity!r}; expected a finite number",
                key="acceleration_std",
            )

    @property
    def noise_intensity(self) -> float:  # type: ignore[override]
        """PSD ``q = 2 sigma^2 / tau`` of the white noise driving the acceleration."""
        return 2.0 * self.acceleration_std**2 / self.time_constant

    def _parameters(self) -> tuple[float, ...]:
        return (self.time_constant, self.acceleration_std)

    def _axis_blocks(self, dt: float) -> tuple[FloatArray, FloatArray]:
        alpha = 1.0 / self.time_constant
        x = alpha * dt
        F = np.array(
            [
                [1.0, dt, dt**2 * _SINGER_F_PA.scaled(x)],
                [0.0, 1.0, dt * _SINGER_F_VA.scaled(x)],
                [0.0, 0.0, math.exp(-x)],
            ]
        )
        Q = np.zeros((3, 3))
        for (i, j), bracket in _SINGER_Q.items():
            Q[i, j] = Q[j, i] = dt**bracket.order * bracket.scaled(x) / 2.0
        return F, self.noise_intensity * Q

    def __repr__(self) -> str:
        return (
            f"Singer(ndim={self.ndim}, time_constant={self.time_constant}, "
            f"acceleration_std={self.acceleration_std})"
        )


# Variance of a heading uniform on (-pi, pi]: (2 pi)^2 / 12.
_UNIFORM_HEADING_VARIANCE = math.pi**2 / 3.0


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


class CoordinatedTurn(MotionModel):
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

    Track initiation: a Gaussian over the heading cannot express "any direction", so a
    track starts in the 2-D constant-velocity :meth:`initiation_model` ``(x, y, vx, vy)``
    and :meth:`convert_initiated` maps it to the turn state once the velocity is
    observed (first-order conversion through the polar Jacobian; turn rate
    ``N(0, turn_rate_std^2)`` of the birth model).

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

    def initiation_model(self) -> MotionModel:
        """2-D constant velocity with the along-track acceleration noise on both axes."""
        return ConstantVelocity(ndim=2, noise_intensity=self.speed_noise_intensity)

    def needs_conversion(self) -> bool:
        return True

    def convert_initiated(
        self, x: FloatArray, P: FloatArray, birth: BirthModel
    ) -> tuple[FloatArray, FloatArray]:
        """``(x, y, vx, vy)`` -> ``(x, y, speed, heading, turn_rate)``, first order.

        The covariance goes through the Jacobian of the polar conversion; the turn rate
        is independent ``N(0, turn_rate_std^2)``.

        Raises
        ------
        InputError
            Zero velocity (undefined heading).
        """
        px, py, vx, vy = x
        speed = float(np.hypot(vx, vy))
        if speed == 0.0:
            raise InputError(
                "cannot convert a zero-velocity initiation state to coordinated turn "
                "(heading undefined)"
            )
        J = np.zeros((5, 4))
        J[0, 0] = J[1, 1] = 1.0
        J[2, 2], J[2, 3] = vx / speed, vy / speed
        J[3, 2], J[3, 3] = -vy / speed**2, vx / speed**2
        x_ct = np.array([px, py, speed, np.arctan2(vy, vx), 0.0])
        P_ct = J @ P @ J.T
        P_ct[4, 4] = birth.turn_rate_std**2
        return x_ct, 0.5 * (P_ct + P_ct.T)

    @property
    def conversion_prior_indices(self) -> tuple[int, ...]:
        return (4,)

    def revert_conversion(self, x: FloatArray, P: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(x, y, speed, heading)`` -> ``(x, y, speed cos heading, speed sin heading)``.

        The conversion is a change of variables ``(vx, vy) -> (speed, heading)`` plus an
        independent turn-rate prior: it adds no information about the constant-velocity
        state.  For a linear change of variables ``x_ct = J x_cv + b`` the RTS gain of
        this step is ``G = [J^-1, 0]`` and the smoothed moments are exactly the inverse map
        of the smoothed turn-state moments (turn rate marginalised).  Here the inverse map
        is applied at the given (smoothed) mean, with its Jacobian there for the
        covariance.  Linearising at the smoothed mean, rather than at the filtered
        velocity of two detections, keeps the early states as accurate as the rest of
        the track.

        Parameters
        ----------
        x : ndarray, shape (5,)
        P : ndarray, shape (5, 5)

        Returns
        -------
        x_cv : ndarray, shape (4,)
        P_cv : ndarray, shape (4, 4)
        """
        px, py, speed, heading = (float(v) for v in x[:4])
        cos_h, sin_h = math.cos(heading), math.sin(heading)
        x_cv = np.array([px, py, speed * cos_h, speed * sin_h])
        J = np.zeros((4, 4))
        J[0, 0] = J[1, 1] = 1.0
        J[2, 2], J[2, 3] = cos_h, -speed * sin_h
        J[3, 2], J[3, 3] = sin_h, speed * cos_h
        P_cv = J @ P[:4, :4] @ J.T
        return x_cv, 0.5 * (P_cv + P_cv.T)

    def unconverted_state(
        self, x: FloatArray, P: FloatArray, birth: BirthModel
    ) -> tuple[FloatArray, FloatArray]:
        """Turn moments of a track detected at a single time (no velocity information).

        Speed, heading and turn rate 0 with variances ``speed_std^2``, ``pi^2 / 3`` (a
        heading uniform on (-pi, pi]) and ``turn_rate_std^2``.
        """
        out = np.array([x[0], x[1], 0.0, 0.0, 0.0])
        cov = np.zeros((5, 5))
        cov[:2, :2] = P[:2, :2]
        cov[2, 2] = birth.speed_std**2
        cov[3, 3] = _UNIFORM_HEADING_VARIANCE
        cov[4, 4] = birth.turn_rate_std**2
        return out, cov

    def canonical_states(
        self, states: FloatArray, covariances: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """States with speed >= 0 and heading in (-pi, pi].

        ``(speed, heading)`` and ``(-speed, heading + pi)`` are the same motion; an EKF
        whose first heading estimate (from two noisy detections) is more than 90 degrees
        off can settle on the negative-speed form.  The reflection ``speed -> -speed``
        flips the signs of the speed's covariances with the other components; the shift
        of the heading by pi and its wrapping change no covariance.
        """

        states = np.array(states, dtype=float, copy=True)
        covariances = np.array(covariances, dtype=float, copy=True)
        reversed_ = states[:, 2] < 0.0
        flip = np.ones(5)
        flip[2] = -1.0
        states[reversed_, 2] *= -1.0
        states[reversed_, 3] += math.pi
        covariances[reversed_] *= np.outer(flip, flip)
        states[:, 3] = wrap_angle(states[:, 3])
        return states, covariances

    def speed(self, state: FloatArray) -> float:
        return abs(float(state[2]))

    def turn_rate(self, state: FloatArray) -> float:
        return float(state[4])

    def __repr__(self) -> str:
        return (
            f"CoordinatedTurn(speed_noise_intensity={self.speed_noise_intensity}, "
            f"turn_rate_noise_intensity={self.turn_rate_noise_intensity})"
        )


def _turn_terms(u: float) -> tuple[float, float, float, float]:
    """``sin(u) / u``, ``(1 - cos u) / u``, ``(1 - cos u) / u^2`` and
    ``(u - sin u) / u^3`` of ``u = omega dt``, stable as ``u -> 0`` (their series below
    ``|u| = 1e-3``, where the closed forms lose digits; the first omitted terms are then
    below 1e-13 relative)."""
    if abs(u) < 1e-3:
        u2 = u * u
        return 1.0 - u2 / 6.0, u / 2.0 - u * u2 / 24.0, 0.5 - u2 / 24.0, 1.0 / 6.0 - u2 / 120.0
    s, c = math.sin(u), math.cos(u)
    return s / u, (1.0 - c) / u, (1.0 - c) / u**2, (u - s) / u**3


class ConstantTurn(MotionModel):
    """Coordinated turn at a known turn rate, in the constant-velocity state space.

    State ``(x, y, vx, vy)``, as :class:`ConstantVelocity` with ``ndim = 2``; the velocity
    turns at ``omega = turn_rate`` (rad per unit time, positive counter-clockwise) and is
    perturbed by continuous white acceleration noise of power spectral density
    ``q = noise_intensity`` on each axis (Bar-Shalom, Li and Kirubarajan 2001, section
    11.7.1, the turn model of a known rate).  With ``u = omega dt``, ``s = sin u``,
    ``c = cos u``::

        F = [[1, 0, s/omega, -(1-c)/omega],
             [0, 1, (1-c)/omega, s/omega],
             [0, 0, c, -s],
             [0, 0, s, c]]

    and ``Q = integral_0^dt e^(A t) G q G^T e^(A^T t) dt`` in closed form: the velocity
    block ``q dt I`` (a rotation keeps isotropic noise isotropic), the position block
    ``2 q (dt - s/omega) / omega^2 I``, the cross block
    ``(q / omega) [[(1-c)/omega, dt - s/omega], [-(dt - s/omega), (1-c)/omega]]``.  At
    ``omega = 0`` it is :class:`ConstantVelocity` exactly.

    Why a linear turn model: in a model set with constant-velocity models it shares
    their state space, so the IMM mixes it with them directly (the nonlinear
    :class:`CoordinatedTurn` has another state); a set of a few turn rates of either
    sign covers a target's turns as the classic IMM of manoeuvring aircraft does.

    Parameters
    ----------
    turn_rate : float
        omega, rad per unit time (any finite value; 0 is constant velocity).
    noise_intensity : float
        q, > 0.
    """

    def __init__(self, *, turn_rate: float, noise_intensity: float) -> None:
        if not (isinstance(turn_rate, (int, float, np.floating)) and math.isfinite(turn_rate)):
            raise InputError(f"turn_rate must be a finite number of rad per unit time, "
                             f"got {turn_rate!r}")  # fmt: skip
        self.omega = float(turn_rate)
        self.noise_intensity = check_positive("noise_intensity", noise_intensity)
        self.ndim = 2

    state_dim = property(lambda self: 4)
    state_names = property(lambda self: ("x", "y", "vx", "vy"))
    position_indices = property(lambda self: (0, 1))
    velocity_indices = property(lambda self: (2, 3))
    is_linear = property(lambda self: True)

    def turn_rate(self, state: FloatArray) -> float:
        """omega, whatever the state (the protocol's turn rate of a state)."""
        return self.omega

    def matrices(self, dt: float) -> tuple[FloatArray, FloatArray]:
        """``(F(dt), Q(dt))``, shapes ``(4, 4)`` (class docstring)."""
        dt = _check_dt(dt)
        w, q = self.omega, self.noise_intensity
        u = w * dt
        sinc, cosc, cosc2, tail = _turn_terms(u)
        s, one_c = sinc * dt, cosc * dt  # sin(u) / omega, (1 - cos u) / omega
        c, sn = math.cos(u), math.sin(u)
        F = np.array([[1, 0, s, -one_c], [0, 1, one_c, s], [0, 0, c, -sn], [0, 0, sn, c]])
        diag = q * cosc2 * dt**2  # q (1 - c) / omega^2
        off = q * tail * w * dt**3  # q (dt - s / omega) / omega
        Q = np.zeros((4, 4))
        Q[0, 0] = Q[1, 1] = 2.0 * q * tail * dt**3  # 2 q (dt - s / omega) / omega^2
        Q[2, 2] = Q[3, 3] = q * dt
        Q[:2, 2:] = [[diag, off], [-off, diag]]
        Q[2:, :2] = Q[:2, 2:].T
        return F, Q

    def transition(self, x: FloatArray, dt: float) -> FloatArray:
        return np.asarray(x, dtype=float) @ self.matrices(dt)[0].T

    def jacobian(self, x: FloatArray, dt: float) -> FloatArray:
        F = self.matrices(dt)[0]
        return np.broadcast_to(F, np.shape(x)[:-1] + F.shape).copy()

    def process_noise(self, dt: float) -> FloatArray:
        return self.matrices(dt)[1]

    def birth_prior(self, birth: BirthModel) -> tuple[FloatArray, FloatArray]:
        """That of the 2-D constant-velocity model: zero mean, ``velocity_std^2``."""
        return np.zeros(2), np.eye(2) * birth.velocity_std**2

    def __repr__(self) -> str:
        return f"ConstantTurn(turn_rate={self.omega}, noise_intensity={self.noise_intensity})"


# --------------------------------------------------------------------------- registry


@dataclass(frozen=True)
class MotionSetting:
    """One setting of a motion model in configuration files.

    Parameters
    ----------
    key : str
        TOML key under ``[motion]``; also the constructor keyword and, unless
        ``attribute`` says otherwise, the attribute that holds the value.
    kind : {"ndim", "positive", "real"}
        ``"ndim"``: a TOML integer 1, 2 or 3; ``"positive"``: a number > 0; ``"real"``:
        any finite number.
    attribute : str, optional
        The attribute that holds the value, where ``key`` names a protocol member
        (``ConstantTurn``'s ``turn_rate`` is held in ``omega``: ``turn_rate(state)`` is
        the protocol's method).
    """

    key: str
    kind: str
    attribute: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("ndim", "positive", "real"):
            raise InputError(f"kind must be 'ndim', 'positive' or 'real', got {self.kind!r}")


@dataclass(frozen=True)
class MotionSpec:
    """A registered motion model: its configuration name, class and settings schema.

    Parameters
    ----------
    name : str
        Value of ``model`` under ``[motion]``.
    cls : type
        The model class; ``cls(**{setting.key: value, ...})`` builds it.
    settings : tuple of MotionSetting
        Its keys besides ``model``, in file order (also the order of checks).
    context : str
        How error messages qualify the allowed keys ("for <name>" unless given).
    """

    name: str
    cls: type
    settings: tuple[MotionSetting, ...]
    context: str

    @property
    def keys(self) -> tuple[str, ...]:
        """Allowed keys under ``[motion]``: ``model`` then the settings."""
        return ("model", *(setting.key for setting in self.settings))


MOTION_REGISTRY: dict[str, MotionSpec] = {}
"""Registered motion models by configuration name, in registration order."""


def register_motion_model(
    name: str, cls: type, settings: tuple[MotionSetting, ...], *, context: str | None = None
) -> MotionSpec:
    """Register ``cls`` under the configuration name ``name`` (read and written by
    :mod:`mapassoc.data.config`)."""
    if not isinstance(name, str) or not name or name in MOTION_REGISTRY:
        raise InputError(f"name must be a new, non-empty string, got {name!r}")
    if any(spec.cls is cls for spec in MOTION_REGISTRY.values()):
        raise InputError(f"cls {cls.__name__} is already registered")
    spec = MotionSpec(name, cls, tuple(settings), context or f"for {name}")
    MOTION_REGISTRY[name] = spec
    return spec


def motion_spec(motion: object) -> MotionSpec | None:
    """The registration of ``motion``'s exact class, or None."""
    for spec in MOTION_REGISTRY.values():
        if type(motion) is spec.cls:
            return spec
    return None


_NDIM = MotionSetting("ndim", "ndim")
register_motion_model(
    "constant_velocity", ConstantVelocity, (_NDIM, MotionSetting("noise_intensity", "positive"))
)
register_motion_model(
    "constant_acceleration",
    ConstantAcceleration,
    (_NDIM, MotionSetting("noise_intensity", "positive")),
)
register_motion_model(
    "random_walk", RandomWalk, (_NDIM, MotionSetting("noise_intensity", "positive"))
)
register_motion_model(
    "coordinated_turn",
    CoordinatedTurn,
    (
        MotionSetting("speed_noise_intensity", "positive"),
        MotionSetting("turn_rate_noise_intensity", "positive"),
    ),
    context="for coordinated_turn (always 2-D)",
)
register_motion_model(
    "constant_turn",
    ConstantTurn,
    (
        MotionSetting("turn_rate", "real", attribute="omega"),
        MotionSetting("noise_intensity", "positive"),
    ),
    context="for constant_turn (always 2-D)",
)
register_motion_model(
    "singer",
    Singer,
    (
        _NDIM,
        MotionSetting("time_constant", "positive"),
        MotionSetting("acceleration_std", "positive"),
    ),
)
