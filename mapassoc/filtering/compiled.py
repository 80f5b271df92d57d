"""The optional compiled Kalman kernels (:mod:`mapassoc.filtering.compiled_kernels`).

With numba installed, the whole-recording refinement takes its linear Kalman steps
through these kernels; without it, or with ``MAPASSOC_COMPILED=0``
(:mod:`mapassoc.accelerate`), through numpy, with the same results up to rounding.
"""

from __future__ import annotations

from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from mapassoc.accelerate import COMPILED_SWITCH, compiled_module
from mapassoc.array_types import FloatArray, IntArray

__all__ = ["COMPILED_SWITCH", "ScanModel", "kalman_kernels"]

ScanModel = tuple[
    NDArray[np.bool_],
    FloatArray,
    FloatArray,
    FloatArray,
    FloatArray,
    IntArray,
    FloatArray,
    FloatArray,
    FloatArray,
    FloatArray,
    FloatArray,
]
"""What every kernel reads of the recording, per scan ``m`` (M scans):

* ``moves`` (M,) bool: whether the step from scan ``m - 1`` to ``m`` has a positive
  time step; ``F``, ``Q`` (M, n, n): the motion model's matrices of that step;
* ``H`` (M, dz, n), ``R`` (M, dz, dz), ``dims`` (M,) int: the scan's linear
  measurement, in its first ``dims[m]`` rows and columns;
* ``survival``, ``miss``, ``log_pd``, ``log_clutter``, ``thresholds`` (M,): the
  per-scan terms and the gate, from the recording's table of terms
  (``mapassoc.estimator.terms.ScanTerms``).

Built once per recording by ``RecordingObjective``."""


def kalman_kernels() -> ModuleType | None:
    """The compiled Kalman kernels module, or ``None`` for the numpy path
    (:func:`mapassoc.accelerate.compiled_module`)."""
    return compiled_module("mapassoc.filtering.compiled_kernels")
