"""The backends of a recording's linear Kalman runs, chosen in one place.

:func:`filter_backend` gives the module that runs them: the compiled kernels
(:mod:`mapassoc.filtering.compiled_kernels`, numba) when numba is installed and
``MAPASSOC_COMPILED`` is not ``0`` (:mod:`mapassoc.accelerate`), else their numpy twin
(:mod:`mapassoc.filtering.scan_steps`).  Both expose ``filter_along_path`` (one track's
run through its detections) and ``continue_along_references`` (the refinement's batched
continuation) with the same arguments and returns, and the same algebra as the batched
interface :mod:`mapassoc.filtering.batch`, so a caller never asks which one it has; the
results agree up to rounding (the kernels sum in loops, numpy in its own order).
"""

from __future__ import annotations

from types import ModuleType

from mapassoc.accelerate import COMPILED_SWITCH, compiled_module
from mapassoc.filtering import scan_steps
from mapassoc.filtering.scan_steps import ScanModel

__all__ = ["COMPILED_SWITCH", "ScanModel", "filter_backend", "kalman_kernels"]


def kalman_kernels() -> ModuleType | None:
    """The compiled Kalman kernels module, or ``None`` without numba or with
    ``MAPASSOC_COMPILED=0`` (:func:`mapassoc.accelerate.compiled_module`)."""
    return compiled_module("mapassoc.filtering.compiled_kernels")


def filter_backend() -> ModuleType:
    """The backend of the linear Kalman runs: the compiled kernels where they load
    (:func:`kalman_kernels`), else :mod:`mapassoc.filtering.scan_steps`.

    Asked at each use (a dictionary lookup), so that ``MAPASSOC_COMPILED`` set while the
    process runs takes effect.
    """
    kernels = kalman_kernels()
    if kernels is not None:
        return kernels
    return scan_steps
