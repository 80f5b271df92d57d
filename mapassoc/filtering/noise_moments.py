"""Noise levels from raw detections, before any track exists: moments of
nearest-neighbour chains.

A chain links a detection to its mutual nearest neighbour in the sensor's next scan; four
linked detections ``x_{k-1}, x_k, x_{k+1}, x_{k+2}`` of a nearly-constant-velocity
target a time ``T`` apart give two consecutive second differences
``d_k = x_{k+1} - 2 x_k + x_{k-1}``, with (per position component, white acceleration
of intensity ``q``, measurement noise of variance ``r``)::

    V = Var(d_k) = (2/3) q T^3 + 6 r          C = Cov(d_k, d_{k+1}) = q T^3 / 6 - 4 r

so ``r = (V - 4 C) / 22`` and ``q T^3 = 6 (C + 4 r)``: a method of moments on the
autocovariances of a linear function of the data, in the spirit of Odelson, Rajamani
and Rawlings, "A new autocovariance least-squares method for estimating noise
covariances" (Automatica, 2006).  Decisions:

* Variances are robust (the median of squares over the median of a chi-square with one
  degree of freedom): a chain through a false alarm gives second differences far in the
  tails, and pairs beyond three robust standard deviations are dropped before the
  moments are taken.
* ``r`` is floored at ``V / 200`` and ``q T^3`` at ``r / 100``: where the measurement
  noise dominates the motion within a scan, ``C + 4 r`` is the small difference of two
  large numbers, and a level at zero or below would be no start at all.
* The velocity spread (for a birth model) is the robust spread of the chains'
  scan-to-scan velocities.

``mapassoc init-config`` writes these as a starter configuration, and the parameter
EM (:mod:`mapassoc.estimator.noise_levels`) starts its ``"auto"`` noise levels from them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray

__all__ = ["MIN_PROCESS_NOISE", "ChainMoments", "chain_moments"]

MIN_PROCESS_NOISE = 1e-4
"""The least process-noise intensity :func:`chain_moments` gives (position units^2 per
time^3)."""


@dataclass(frozen=True)
class ChainMoments:
    """One sensor's estimates from nearest-neighbour chains (module docstring).

    Attributes
    ----------
    measurement_variance : float
        ``r``, per position component (1.0 when ``pairs`` is 0).
    process_noise : float
        ``q`` of a constant-velocity model (1.0 when ``pairs`` is 0).
    speed_spread : float
        Robust spread of the scan-to-scan velocity components.
    period : float
        Median time between the sensor's scans (1.0 with fewer than two scans).
    pairs : int
        Pairs of consecutive second differences the moments come from (0: no chain of
        four detections; ``r`` and ``q`` are then placeholders).
    """

    measurement_variance: float
    process_noise: float
    speed_spread: float
    period: float
    pairs: int = 0


def _links(a: FloatArray, b: FloatArray) -> list[tuple[int, int]]:
    """Mutual nearest neighbours of the rows of ``a`` and ``b``."""
    if len(a) == 0 or len(b) == 0:
        return []
    d = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=-1)
    ab, ba = np.argmin(d, axis=1), np.argmin(d, axis=0)
    return [(i, int(j)) for i, j in enumerate(ab) if ba[j] == i]


def _robust_variance(values: FloatArray) -> float:
    """Variance from the median of squares (median of chi-square(1) is 0.4549)."""
    return float(np.median(np.square(values)) / 0.4549) if len(values) else math.nan


def _second_differences(
    times: Sequence[float], positions: Sequence[FloatArray]
) -> tuple[list[FloatArray], list[tuple[FloatArray, FloatArray]]]:
    """The chains' scan-to-scan velocities and their pairs of consecutive second
    differences."""
    nxt = [dict(_links(positions[k], positions[k + 1])) for k in range(len(positions) - 1)]
    velocities, pairs = [], []
    for k in range(len(nxt) - 2):
        for i, j in nxt[k].items():
            dt = times[k + 1] - times[k]
            velocities.append((positions[k + 1][j] - positions[k][i]) / dt)
            third = nxt[k + 1].get(j)
            fourth = None if third is None else nxt[k + 2].get(third)
            if third is None or fourth is None:
                continue
            d1 = positions[k + 2][third] - 2 * positions[k + 1][j] + positions[k][i]
            d2 = positions[k + 3][fourth] - 2 * positions[k + 2][third] + positions[k + 1][j]
            pairs.append((d1, d2))
    return velocities, pairs


def chain_moments(times: Sequence[float], positions: Sequence[FloatArray]) -> ChainMoments:
    """``r``, ``q``, the velocity spread and the median scan period of one sensor.

    Parameters
    ----------
    times : sequence of float, length S
        The sensor's scan times, increasing.
    positions : sequence of ndarray, each of shape (m_k, d)
        Each scan's detections as positions.

    Returns
    -------
    ChainMoments
    """
    period = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
    velocities, pairs = _second_differences(times, positions)
    v = np.concatenate(velocities) if velocities else np.zeros(1)
    spread = max(math.sqrt(_robust_variance(v)), 1e-3)
    if not pairs:
        return ChainMoments(1.0, 1.0, spread, period, 0)
    d1s, d2s = np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])
    scale = 3.0 * math.sqrt(_robust_variance(d1s.ravel()))
    keep = (np.abs(d1s) <= scale).all(axis=1) & (np.abs(d2s) <= scale).all(axis=1)
    if np.any(keep):
        d1s, d2s = d1s[keep], d2s[keep]
    d1s, d2s = d1s.ravel(), d2s.ravel()
    variance = _robust_variance(np.concatenate([d1s, d2s]))
    lag = (_robust_variance(d1s + d2s) - _robust_variance(d1s - d2s)) / 4
    r = max((variance - 4 * lag) / 22, variance / 200)
    q_t3 = max(6 * (lag + 4 * r), r / 100)
    q = max(q_t3 / period**3, MIN_PROCESS_NOISE)
    return ChainMoments(r, q, spread, period, len(pairs))
