"""The backends of a recording's linear Kalman runs, chosen in one place.

:func:`filter_backend` gives the module that runs them: the compiled kernels
(:mod:`mapassoc.filtering.compiled_kernels`, numba) when numba is installed and
``MAPASSOC_COMPILED`` is not ``0`` (:mod:`mapassoc.accelerate`), else their numpy twin
(:mod:`mapassoc.filtering.scan_steps`).  Both expose ``filter_along_path`` (one track's
run through its detections) and ``continue_along_references`` (the refinement's batched
continuation) with the same arguments and returns, and the same algebra as the batched
interface :mod:`mapassoc.filtering.batch`, so a caller never asks which one it has; the
results agree up to rounding (the kernels sum in loops, numpy in its own order).

:func:`imm_kernels` gives the compiled steps of a set of linear motion models
(:mod:`mapassoc.filtering.compiled_imm`: the batched IMM prediction and the joins'
continuation), or None; their numpy twins are the batched filter's set steps and the
lockstep continuation, which the callers take then.
"""

from __future__ import annotations

from types import ModuleType

from mapassoc.accelerate import COMPILED_SWITCH, compiled_module
from mapassoc.filtering import scan_steps
from mapassoc.filtering.scan_steps import ScanModel

__all__ = ["COMPILED_SWITCH", "ScanModel", "filter_backend", "imm_kernels", "kalman_kernels"]


def kalman_kernels() -> ModuleType | None:
    """The compiled Kalman kernels module, or ``None`` without numba or with
    ``MAPASSOC_COMPILED=0`` (:func:`mapassoc.accelerate.compiled_module`)."""
    return compiled_module("mapassoc.filtering.compiled_kernels")


def imm_kernels() -> ModuleType | None:
    """The compiled kernels of the joins under a set of linear models
    (:mod:`mapassoc.filtering.compiled_imm`), or ``None`` where :func:`kalman_kernels`
    is: the caller then takes the batched lockstep continuation, their numpy twin."""
    return compiled_module("mapassoc.filtering.compiled_imm")


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
