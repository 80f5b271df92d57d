"""The optional compiled Kalman kernels (:mod:`mapassoc.filtering.compiled_kernels`).

With numba installed, the whole-recording refinement takes its linear Kalman steps
through these kernels; without it, or with ``MAPASSOC_COMPILED=0``
(:mod:`mapassoc.accelerate`), through numpy, with the same results up to rounding.
"""

from __future__ import annotations

from types import ModuleType

from mapassoc.accelerate import COMPILED_SWITCH, compiled_module

__all__ = ["COMPILED_SWITCH", "kalman_kernels"]


def kalman_kernels() -> ModuleType | None:
    """The compiled Kalman kernels module, or ``None`` for the numpy path
    (:func:`mapassoc.accelerate.compiled_module`)."""
    return compiled_module("mapassoc.filtering.compiled_kernels")
