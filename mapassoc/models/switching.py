"""How a target switches between motion models: the Markov chain of an interacting
multiple-model set.

A target's motion switches between ``M`` models by a Markov chain with switching matrix
``Pi[i, j] = P(model j at scan k | model i at scan k - 1)`` (Blom and Bar-Shalom, "The
interacting multiple model algorithm for systems with Markovian switching coefficients",
IEEE Trans. Automatic Control 33(8), 1988).  Scans are not evenly spaced, so the law is
given per unit of time and taken to each scan interval (:class:`SwitchingLaw`): either
``switch_probability``, the probability of leaving the current model within one unit of
time, for the chain that jumps to every model alike (``Pi(dt) = exp(-k dt) I + (1 -
exp(-k dt)) U`` with ``U`` the uniform matrix ``1/M``, so ``P(leave within 1) = (1 -
exp(-k)) (M - 1) / M``), or a full matrix per unit of time, taken to ``dt`` through its
generator (``Pi(dt) = expm(dt logm(Pi))``, refused when ``logm(Pi)`` is not a valid
generator).  Both compose: ``Pi(a) Pi(b) = Pi(a + b)``.

The law is part of the model (:class:`mapassoc.models.interacting.InteractingModels`);
the filter that uses it is :mod:`mapassoc.filtering.imm`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm, logm

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError

__all__ = ["SwitchingLaw", "check_switching_matrix"]

_ROW_TOLERANCE = 1e-9
"""How far from 1 a row of a switching matrix may sum."""


def check_switching_matrix(matrix: object, *, name: str = "matrix") -> FloatArray:
    """A validated switching matrix: square, entries in [0, 1], rows summing to 1.

    Parameters
    ----------
    matrix : array_like, shape (M, M)
    name : str
        The argument's name in error messages.

    Returns
    -------
    ndarray, shape (M, M)
    """
    try:
        Pi = np.array(matrix, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a square matrix of numbers, got {matrix!r}") from None
    if Pi.ndim != 2 or Pi.shape[0] != Pi.shape[1] or Pi.shape[0] < 1:
        raise InputError(f"{name} must be a square (M, M) matrix, got shape {Pi.shape}")
    if not np.all(np.isfinite(Pi)) or np.any(Pi < 0.0) or np.any(Pi > 1.0):
        raise InputError(f"{name} must have entries in [0, 1], got {Pi.tolist()!r}")
    sums = Pi.sum(axis=1)
    if np.any(np.abs(sums - 1.0) > _ROW_TOLERANCE):
        raise InputError(f"{name} rows must sum to 1, got row sums {sums.tolist()!r}")
    return Pi


@dataclass(frozen=True)
class SwitchingLaw:
    """How a target switches models: ``switch_probability`` per unit time, or a matrix.

    Give exactly one of the two (module docstring).

    Parameters
    ----------
    n_models : int
        Number of models M, >= 1.
    switch_probability : float, optional
        Probability of leaving the current model within one unit of time, in
        ``[0, (M - 1) / M)`` (the uniform chain cannot leave more often).
    matrix : array_like, shape (M, M), optional
        The switching matrix over one unit of time.
    """

    n_models: int
    switch_probability: float | None = None
    matrix: FloatArray | None = None

    def __post_init__(self) -> None:
        M = self.n_models
        if isinstance(M, bool) or not isinstance(M, (int, np.integer)) or M < 1:
            raise InputError(f"n_models must be an integer >= 1, got {M!r}")
        if (self.switch_probability is None) == (self.matrix is None):
            raise InputError("give exactly one of switch_probability and matrix")
        if self.matrix is not None:
            Pi = check_switching_matrix(self.matrix)
            if Pi.shape[0] != M:
                raise InputError(f"matrix must be ({M}, {M}) for n_models = {M}, got {Pi.shape}")
            _generator(Pi)  # refused here when Pi has no generator
            object.__setattr__(self, "matrix", Pi)
            return
        p = self.switch_probability
        top = (M - 1) / M
        if (
            isinstance(p, bool)
            or not isinstance(p, (int, float))
            or not (p == 0.0 if M == 1 else 0.0 <= p < top)
        ):
            allowed = "0 for one model" if M == 1 else f"a number in [0, {top:g}) for {M} models"
            raise InputError(f"switch_probability must be {allowed}, got {p!r}")

    def at(self, dt: float) -> FloatArray:
        """The switching matrix over a scan interval ``dt > 0``, shape ``(M, M)``."""
        if (
            isinstance(dt, bool)
            or not isinstance(dt, (int, float, np.floating))
            or not (math.isfinite(dt) and dt > 0)
        ):
            raise InputError(f"dt must be a positive finite scan interval, got {dt!r}")
        M = self.n_models
        if self.matrix is not None:
            Pi = expm(float(dt) * _generator(self.matrix))
            Pi = np.clip(np.real(Pi), 0.0, 1.0)
            return np.asarray(Pi / Pi.sum(axis=1, keepdims=True), dtype=np.float64)
        if M == 1:
            return np.ones((1, 1))
        stay = 1.0 - float(self.switch_probability or 0.0) * M / (M - 1)  # exp(-k)
        keep = stay ** float(dt)
        return np.asarray(keep * np.eye(M) + (1.0 - keep) / M, dtype=np.float64)


def _generator(Pi: FloatArray) -> FloatArray:
    """``logm(Pi)`` if it is a valid generator (off-diagonal >= 0, rows summing to 0)."""
    if np.allclose(Pi, np.eye(Pi.shape[0])):
        return np.zeros_like(Pi)
    logarithm = np.asarray(logm(Pi))
    G = np.real(logarithm)
    if np.any(np.abs(np.imag(logarithm)) > 1e-9):
        G = np.full_like(G, np.nan)  # a complex logarithm: no real generator
    off = G - np.diag(np.diag(G))
    if not (
        np.all(np.isfinite(G))
        and np.all(off >= -1e-9)
        and np.allclose(G.sum(axis=1), 0.0, atol=1e-9)
    ):
        raise InputError(
            f"matrix {Pi.tolist()!r} is the switching matrix of no continuous-time chain (its "
            "logarithm is not a generator), so it has no value for other scan intervals; give "
            "switch_probability, or a matrix that is"
        )  # fmt: skip
    return np.asarray(G, dtype=np.float64)
