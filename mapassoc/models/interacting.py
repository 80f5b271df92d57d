"""A set of motion models with a switching law: the model of interacting-multiple-model
(IMM) filtering.

A target moves by one of ``M`` models at a time and switches between them by the Markov
chain of :class:`~mapassoc.models.switching.SwitchingLaw` (Blom and Bar-Shalom, "The
interacting multiple model algorithm for systems with Markovian switching coefficients",
IEEE Trans. Automatic Control 33(8), 1988; Bar-Shalom, Li and Kirubarajan, *Estimation
with Applications to Tracking and Navigation*, 2001, chapter 11).  The usual set for
aircraft is constant velocity with a low process noise (straight legs) and with a high
one (turns and speed changes).

:class:`InteractingModels` is a :class:`~mapassoc.models.motion.MotionModel`, so every
component that takes a motion model takes a set: the hypothesis trees, the recording's
objective J, the refinement and the smoother.  Three decisions make that work without a
second code path.

* **Start.** A track starts at one detection with the first model alone (its
  :meth:`initiation_model`), exactly as a single-model track of that model does, and
  enters the set at its second detection (:meth:`convert_initiated`, the conversion
  coordinated-turn tracks make), each model from the same state with the prior
  probabilities ``initial_probabilities``.  Until then no detection can tell the models
  apart, so no turn model needs a speed prior.
* **One filter state.** The filter's state of a track in the set is one vector of
  length :attr:`filter_state_dim` = ``M n + M``: the ``M`` model-conditioned means, then
  the ``M`` log model probabilities; its covariance is block diagonal (the ``M``
  model-conditioned covariances, zeros for the probabilities).  The hypothesis trees
  store and pad states of any length, so a node of the set is a node like any other;
  the batched filter (:mod:`mapassoc.filtering.batch`) unpacks it.
* **The target's state.** :attr:`state_dim`, :attr:`state_names` and
  :attr:`position_indices` are those of the models' common space (what measurements
  read and the tracks file reports), and :meth:`transition`, :meth:`jacobian` and
  :meth:`process_noise` are the first model's (the dynamics a simulation or a step-size
  check asks of "the" model; the filters never use them for a track in the set).

Every model must share one state space, be linear or not convert itself: mixing adds
model-conditioned means and covariances, which is only meaningful in one space
(:func:`mapassoc.filtering.imm.check_models`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError
from mapassoc.models.motion import MotionModel, motion_spec
from mapassoc.models.population import BirthModel
from mapassoc.models.switching import SwitchingLaw

__all__ = [
    "InteractingModels",
    "NOISE_LEVELS",
    "filter_state_dim",
    "noise_levels",
    "pack_models",
    "unpack_models",
]

NOISE_LEVELS = (1.0, 10.0)
"""Process-noise factors of the models of :func:`noise_levels`, against the given
model's: the model itself (so that a set never fits straight motion worse than the
model it is built from) and a loud one for turns and speed changes."""


class InteractingModels(MotionModel):
    """``M`` motion models in one state space and the law of switching between them.

    Parameters
    ----------
    models : sequence of MotionModel
        At least one; all with the same ``state_names``, none converting its state
        (``needs_conversion()`` false).  ``models[0]`` starts every track.
    switching : SwitchingLaw
        For ``len(models)`` models.
    initial_probabilities : sequence of float, optional
        Prior model probabilities when a track enters the set (default uniform).
    """

    def __init__(
        self,
        *,
        models: Sequence[MotionModel],
        switching: SwitchingLaw,
        initial_probabilities: Sequence[float] | None = None,
    ) -> None:
        self.models = _checked_models(models)
        M = len(self.models)
        if not isinstance(switching, SwitchingLaw) or switching.n_models != M:
            raise InputError(
                f"switching must be a SwitchingLaw for {M} models, got {switching!r}",
                key="switching",
            )
        self.switching = switching
        self.initial_probabilities = _checked_probabilities(initial_probabilities, M)

    # -- the target's state (the models' common space) -------------------------------
    @property
    def n_models(self) -> int:
        """Number of models M."""
        return len(self.models)

    @property
    def model_names(self) -> tuple[str, ...]:
        """One name per model, ``<registry name>_<index>`` (``constant_velocity_0``,
        ``constant_velocity_1``): the tracks file's model probability columns are ``p_`` +
        each.

        The index makes the names distinct (two noise levels of one model share its
        registry name, :data:`~mapassoc.models.motion.MOTION_REGISTRY`) and stable (the
        position in ``models`` is what the configuration's ``[[motion.models]]`` order
        fixes); the registry name says which model it is without the settings, which
        would make column names change with every tuned noise level.  A model outside
        the registry is named by its class in lower case.
        """
        out = []
        for index, model in enumerate(self.models):
            spec = motion_spec(model)
            kind = spec.name if spec is not None else type(model).__name__.lower()
            out.append(f"{kind}_{index}")
        return tuple(out)

    @property
    def state_dim(self) -> int:
        return self.models[0].state_dim

    @property
    def filter_state_dim(self) -> int:
        """Length ``M n + M`` of a track's filter state in the set (module docstring)."""
        return self.n_models * (self.state_dim + 1)

    @property
    def state_names(self) -> tuple[str, ...]:
        return tuple(self.models[0].state_names)

    @property
    def position_indices(self) -> tuple[int, ...]:
        return tuple(self.models[0].position_indices)

    @property
    def velocity_indices(self) -> tuple[int, ...]:
        return tuple(getattr(self.models[0], "velocity_indices", ()))

    @property
    def is_linear(self) -> bool:
        """False: mixing makes the set's step nonlinear in the filter state."""
        return False

    def transition(self, x: FloatArray, dt: float) -> FloatArray:
        """The first model's ``f(x, dt)`` (module docstring)."""
        return self.models[0].transition(x, dt)

    def jacobian(self, x: FloatArray, dt: float) -> FloatArray:
        """The first model's Jacobian (module docstring)."""
        return self.models[0].jacobian(x, dt)

    def process_noise(self, dt: float) -> FloatArray:
        """The first model's ``Q(dt)`` (module docstring)."""
        return self.models[0].process_noise(dt)

    # -- track initiation ---------------------------------------------------------------
    def initiation_model(self) -> MotionModel:
        """The first model: a track starts with it alone."""
        return self.models[0]

    def needs_conversion(self) -> bool:
        """True: a track enters the set at its second detection."""
        return True

    def birth_prior(self, birth: BirthModel) -> tuple[FloatArray, FloatArray]:
        return self.models[0].birth_prior(birth)

    def convert_initiated(
        self, x: FloatArray, P: FloatArray, birth: BirthModel
    ) -> tuple[FloatArray, FloatArray]:
        """Every model from ``(x, P)``, with the prior probabilities: the filter state.

        Takes leading batch axes: ``x`` of shape ``(..., n)``, ``P`` ``(..., n, n)``.
        """
        M = self.n_models
        x = np.asarray(x, dtype=np.float64)
        P = np.asarray(P, dtype=np.float64)
        lead = x.shape[:-1]
        with np.errstate(divide="ignore"):
            log_mu = np.broadcast_to(np.log(self.initial_probabilities), (*lead, M))
        xs = np.broadcast_to(x[..., None, :], (*lead, M, x.shape[-1]))
        Ps = np.broadcast_to(P[..., None, :, :], (*lead, M, *P.shape[-2:]))
        return pack_models(log_mu, xs, Ps)

    def unconverted_state(
        self, x: FloatArray, P: FloatArray, birth: BirthModel
    ) -> tuple[FloatArray, FloatArray]:
        """A track detected at one time only: its first model's moments, unchanged."""
        return x, P

    def __repr__(self) -> str:
        return (
            f"InteractingModels(models={list(self.models)!r}, switching={self.switching!r}, "
            f"initial_probabilities={self.initial_probabilities.tolist()!r})"
        )


def filter_state_dim(motion: MotionModel) -> int:
    """Length of a track's filter state once it is in ``motion``'s space: ``M n + M`` for
    a set (:attr:`InteractingModels.filter_state_dim`), the state's length otherwise."""
    if isinstance(motion, InteractingModels):
        return motion.filter_state_dim
    return motion.state_dim


def noise_levels(
    model: MotionModel,
    *,
    factors: Sequence[float] = NOISE_LEVELS,
    switch_probability: float = 0.01,
) -> InteractingModels:
    """A model at several process-noise levels: the classic IMM of manoeuvring targets.

    Bar-Shalom, Li and Kirubarajan, *Estimation with Applications to Tracking and
    Navigation* (2001), section 11.7: a nearly constant velocity model whose noise
    fits the straight legs and one whose noise covers the manoeuvres.  The factors
    scale the noise intensity of ``model``; the defaults keep ``model`` as the first
    (quiet) model, add one ten times louder, and switch rarely (a target leaves its
    model within one unit of time with probability 0.01): quieter first models and
    more frequent switching cost accuracy on targets that do not manoeuvre, and the
    changelog has the side-by-side runs.

    Parameters
    ----------
    model : MotionModel
        A kinematic model with ``ndim`` and ``noise_intensity`` (constant velocity,
        constant acceleration, random walk).
    factors : sequence of float
        Noise intensity of each model as a multiple of that of ``model``, > 0; the
        first model starts every track.
    switch_probability : float
        Of the :class:`~mapassoc.models.switching.SwitchingLaw`, per unit time.
    """
    q = getattr(model, "noise_intensity", None)
    ndim = getattr(model, "ndim", None)
    if not isinstance(q, float) or ndim is None:
        raise InputError(
            f"model must be a kinematic model with ndim and noise_intensity, got {model!r}",
            key="model",
        )
    chosen = [float(f) for f in factors]
    if not chosen or not all(math.isfinite(f) and f > 0 for f in chosen):
        raise InputError(f"factors must be positive numbers, got {factors!r}", key="factors")
    kind: Any = type(model)  # a kinematic model: built from ndim and noise_intensity
    models = [kind(ndim=ndim, noise_intensity=f * q) for f in chosen]
    law = SwitchingLaw(len(models), switch_probability=switch_probability)
    return InteractingModels(models=models, switching=law)


def _checked_models(models: object) -> tuple[MotionModel, ...]:
    if isinstance(models, MotionModel) or not isinstance(models, Sequence) or not models:
        raise InputError(
            f"models must be a non-empty sequence of motion models, got {models!r}", key="models"
        )
    out = tuple(models)
    for i, model in enumerate(out):
        if not isinstance(model, MotionModel) or isinstance(model, InteractingModels):
            raise InputError(f"models[{i}] must be a single motion model, got {model!r}",
                             key=f"models[{i}]")  # fmt: skip
        if model.needs_conversion():
            raise InputError(
                f"models[{i}] ({model!r}) converts its state after a track's start, so it "
                "cannot share one state space with the other models",
                key=f"models[{i}]",
            )
        if tuple(model.state_names) != tuple(out[0].state_names):
            raise InputError(
                f"models[{i}] ({model!r}) has the state {tuple(model.state_names)}, models[0] "
                f"({out[0]!r}) {tuple(out[0].state_names)}: mixing needs one state space",
                key=f"models[{i}]",
            )
    return out


def _checked_probabilities(values: object, M: int) -> FloatArray:
    if values is None:
        return np.full(M, 1.0 / M)
    try:
        p = np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        p = np.full(0, math.nan)
    if p.shape != (M,) or not np.all(np.isfinite(p)) or np.any(p < 0) or abs(p.sum() - 1) > 1e-9:
        raise InputError(
            f"initial_probabilities must be {M} probabilities summing to 1, got {values!r}",
            key="initial_probabilities",
        )
    return p


def pack_models(
    log_mu: FloatArray, x: FloatArray, P: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The filter state of a set from its parts (module docstring).

    Parameters
    ----------
    log_mu : ndarray, shape (..., M)
    x : ndarray, shape (..., M, n)
    P : ndarray, shape (..., M, n, n)

    Returns
    -------
    state : ndarray, shape (..., M n + M)
    covariance : ndarray, shape (..., M n + M, M n + M)
        Block diagonal: ``P[..., j]`` at block ``j``, zeros elsewhere.
    """
    *lead, M, n = x.shape
    N = M * (n + 1)
    state = np.concatenate([x.reshape(*lead, M * n), log_mu], axis=-1)
    cov = np.zeros((*lead, N, N))
    for j in range(M):
        cov[..., j * n : (j + 1) * n, j * n : (j + 1) * n] = P[..., j, :, :]
    return state, cov


def unpack_models(
    state: FloatArray, covariance: FloatArray, M: int
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The parts of filter states of a set of ``M`` models (:func:`pack_models` undone).

    Parameters
    ----------
    state : ndarray, shape (..., M n + M)
    covariance : ndarray, shape (..., M n + M, M n + M)
    M : int

    Returns
    -------
    log_mu : ndarray, shape (..., M)
    x : ndarray, shape (..., M, n)
    P : ndarray, shape (..., M, n, n)
    """
    N = state.shape[-1]
    n = N // M - 1
    if N != M * (n + 1) or covariance.shape[-2:] != (N, N):
        raise InputError(
            f"a filter state of {M} models must have length M (n + 1) and a square "
            f"covariance, got {state.shape} and {covariance.shape}"
        )
    lead = state.shape[:-1]
    x = state[..., : M * n].reshape(*lead, M, n)
    P = np.stack(
        [covariance[..., j * n : (j + 1) * n, j * n : (j + 1) * n] for j in range(M)], axis=-3
    )
    return state[..., M * n :], x, P
