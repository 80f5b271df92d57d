"""Single-point track initiation: the state of a track born at one detection.

The detection fixes the position (``measurement.position_from_measurement``: the
detection itself for a position measurement, the polar-to-Cartesian conversion with
covariance ``J R J^T`` for range-bearing).  The unmeasured components start at zero
with the prior standard deviations of :class:`~mapassoc.models.population.BirthModel`.

The coordinated-turn state (speed, heading, turn rate) cannot be started from one
position: a Gaussian over heading cannot express "any direction".  A coordinated-turn
track therefore starts in a 2-D constant-velocity state ``(x, y, vx, vy)`` (the
*initiation model*), and :func:`convert_initiated` turns it into
``(x, y, speed, heading, turn_rate)`` after its second detection, when the velocity
is observed (first-order conversion through the polar Jacobian; turn rate
``N(0, turn_rate_std^2)``).  For every other model the initiation model is the motion
model itself and the conversion is the identity.

Each model says all this itself (:class:`~mapassoc.models.motion.MotionModel`:
``initiation_model``, ``needs_conversion``, ``birth_prior``, ``convert_initiated``;
:class:`~mapassoc.models.measurement.MeasurementModel`: ``position_from_measurement``,
``on_initiation_state``, ``measures_position_directly``); the functions here delegate to it.
"""

from __future__ import annotations

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError
from mapassoc.models.interacting import InteractingModels
from mapassoc.models.measurement import MeasurementModel
from mapassoc.models.motion import MotionModel
from mapassoc.models.population import BirthModel

__all__ = [
    "initiation_model",
    "initiation_measurement",
    "birth_state",
    "birth_states",
    "convert_initiated",
    "convert_initiated_many",
    "needs_conversion",
]


def initiation_model(motion: MotionModel) -> MotionModel:
    """The motion model a track uses until its second detection."""
    return motion.initiation_model()


def initiation_measurement(motion: MotionModel, measurement: MeasurementModel) -> MeasurementModel:
    """The measurement model acting on :func:`~mapassoc.models.birth.initiation_model` states.

    Identical to ``measurement`` unless the motion model converts (coordinated turn).  Then
    a linear measurement's H, written for the turn state, is re-indexed onto the
    constant-velocity initiation state: both spaces share the position components, and a
    measurement of anything but position cannot act on the initiation state.  A
    range-bearing measurement reads only the position components and is used as it is.
    The measurement model does this itself
    (:meth:`~mapassoc.models.measurement.MeasurementModel.on_initiation_state`).
    """
    model = initiation_model(motion)
    if not needs_conversion(motion) or tuple(model.state_names) == tuple(motion.state_names):
        return measurement  # the same state space (a model set starts with its first model)
    return measurement.on_initiation_state(motion, model)


def needs_conversion(motion: MotionModel) -> bool:
    """Whether :func:`convert_initiated` changes the state space of ``motion``."""
    return motion.needs_conversion()


def birth_state(
    motion: MotionModel, measurement: MeasurementModel, z: FloatArray, birth: BirthModel
) -> tuple[FloatArray, FloatArray]:
    """Mean and covariance, in :func:`initiation_model` space, of a track born at ``z``.

    Parameters
    ----------
    motion : MotionModel
    measurement : MeasurementModel
        Model of the sensor that made the detection.
    z : ndarray, shape (dz,)
    birth : BirthModel

    Returns
    -------
    x : ndarray, shape (n0,)
    P : ndarray, shape (n0, n0)
    """
    model = initiation_model(motion)
    pos, pos_cov = measurement.position_from_measurement(np.asarray(z, dtype=float))
    idx = list(model.position_indices)
    if pos.shape != (len(idx),):
        raise InputError(
            f"a {type(measurement).__name__} detection gives a {pos.shape[0]}-D position but "
            f"the {type(model).__name__} model has {len(idx)} position components"
        )
    n = model.state_dim
    x = np.zeros(n)
    P = np.zeros((n, n))
    x[idx] = pos
    P[np.ix_(idx, idx)] = pos_cov
    rest = [i for i in range(n) if i not in idx]
    mean, cov = model.birth_prior(birth)
    if np.shape(mean) != (len(rest),) or np.shape(cov) != (len(rest), len(rest)):
        raise InputError(
            f"the birth prior of {type(model).__name__} has shapes {np.shape(mean)}, "
            f"{np.shape(cov)}; expected ({len(rest)},) and ({len(rest)}, {len(rest)}) for its "
            "unmeasured components"
        )
    if rest:
        x[rest] = mean
        P[np.ix_(rest, rest)] = cov
    return x, P


def birth_states(
    motion: MotionModel, measurement: MeasurementModel, Z: FloatArray, birth: BirthModel
) -> tuple[FloatArray, FloatArray]:
    """:func:`birth_state` for every row of ``Z`` (shape (m, dz)): means (m, n0), covs (m, n0, n0).

    A measurement that measures the position directly (a linear position measurement,
    ``measurement.measures_position_directly``) gives every birth the same covariance, so
    the batch is built without a loop; other measurements fall back to one call per
    detection.
    """
    Z = np.asarray(Z, dtype=float)
    model = initiation_model(motion)
    n = model.state_dim
    if Z.shape[0] == 0:
        return np.zeros((0, n)), np.zeros((0, n, n))
    if measurement.measures_position_directly:
        _, P0 = birth_state(motion, measurement, Z[0], birth)  # the same for every row
        x = np.zeros((Z.shape[0], n))
        x[:, list(model.position_indices)] = Z
        return x, np.broadcast_to(P0, (Z.shape[0], n, n)).copy()
    states = [birth_state(motion, measurement, z, birth) for z in Z]
    return np.array([s[0] for s in states]), np.array([s[1] for s in states])


def convert_initiated(
    motion: MotionModel, x: FloatArray, P: FloatArray, birth: BirthModel
) -> tuple[FloatArray, FloatArray]:
    """Map an initiation-model state into ``motion``'s state space.

    Parameters
    ----------
    motion : MotionModel
    x : ndarray, shape (n0,)
    P : ndarray, shape (n0, n0)
    birth : BirthModel

    Returns
    -------
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
    """
    return motion.convert_initiated(x, P, birth)


def convert_initiated_many(
    motion: MotionModel, x: FloatArray, P: FloatArray, birth: BirthModel
) -> tuple[FloatArray, FloatArray]:
    """:func:`convert_initiated` of a batch: means ``(B, n0)``, covariances ``(B, n0, n0)``.

    A model set converts the batch at once (its conversion copies the state to every
    model); other models are converted state by state.
    """
    if isinstance(motion, InteractingModels):
        return motion.convert_initiated(x, P, birth)
    converted = [motion.convert_initiated(x[b], P[b], birth) for b in range(len(x))]
    if not converted:
        n = motion.state_dim
        return np.zeros((0, n)), np.zeros((0, n, n))
    return np.stack([c[0] for c in converted]), np.stack([c[1] for c in converted])
