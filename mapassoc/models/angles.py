"""Angle arithmetic shared by the measurement models (bearings) and the motion models
(headings)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from mapassoc.array_types import FloatArray

__all__ = ["wrap_angle"]


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
