"""The array type aliases used across the package: numpy arrays by dtype.

Shapes are not part of the type; each function's numpydoc docstring gives them
(``(n,)`` states, ``(n, n)`` covariances, batches on the leading axis).  This module
imports nothing of the package, so every layer may use it, ``mapassoc.formulations`` and
``mapassoc.solvers`` included.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["BoolArray", "FloatArray", "IntArray"]

FloatArray = NDArray[np.float64]
"""Float arrays (states, covariances, scores, log-probabilities)."""

IntArray = NDArray[np.int64]
"""Integer arrays (indices, counts, ids)."""

BoolArray = NDArray[np.bool_]
"""Boolean arrays (masks)."""
