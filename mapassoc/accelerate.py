"""The switch of the optional compiled kernels (numba), shared by every layer.

With numba installed (``pip install 'mapassoc[accelerate]'``), the hot loops that numpy
runs one small array operation at a time (a track's Kalman steps in the whole-recording
refinement, the exact frontier search) run in compiled kernels instead, with the same
results.  The environment variable ``MAPASSOC_COMPILED=0`` turns them off (the numpy
path alone, e.g. to compare the two).  Kernels are compiled on first use and cached
next to their module (numba's ``cache=True``), so only a machine's first run pays the
compilation.

Imports nothing of the package (every layer may import it, as ``array_types``).
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import warnings
from types import ModuleType

__all__ = ["COMPILED_SWITCH", "KERNEL_MODULES", "compiled_module", "load_kernels"]

COMPILED_SWITCH = "MAPASSOC_COMPILED"
"""Environment variable: ``0`` turns the compiled kernels off."""

KERNEL_MODULES = (
    "mapassoc.formulations.compiled_frontier",
    "mapassoc.filtering.compiled_kernels",
    "mapassoc.filtering.compiled_imm",
    "mapassoc.estimator.compiled_beam",
)
"""Every kernel module: each compiles (or loads from numba's cache) its kernels for the
argument types the package passes when it is imported."""

_loaded: dict[str, ModuleType | None] = {}  # kernel module name -> module (or None)


def compiled_module(name: str) -> ModuleType | None:
    """The kernel module ``name`` (which imports numba), or ``None`` for the numpy path.

    ``None`` when ``MAPASSOC_COMPILED=0`` or numba is not installed.  Where numba is
    installed but the module fails to import (e.g. numba built for another numpy), a
    ``RuntimeWarning`` names the error once and the numpy path is taken.
    """
    if os.environ.get(COMPILED_SWITCH, "1").strip() == "0":
        return None
    if name not in _loaded:
        _loaded[name] = _import(name)
    return _loaded[name]


def _import(name: str) -> ModuleType | None:
    if importlib.util.find_spec("numba") is None:
        return None
    try:
        return importlib.import_module(name)
    except Exception as error:  # numba's import can fail in many ways; all are reported
        warnings.warn(
            f"numba is installed but the compiled kernels of {name} failed to load "
            f"({type(error).__name__}: {error}); using the numpy path",
            RuntimeWarning,
            stacklevel=3,
        )
        return None


def load_kernels() -> None:
    """Load every kernel module now (:data:`KERNEL_MODULES`; nothing without numba or
    with ``MAPASSOC_COMPILED=0``).

    A machine's first run compiles the kernels (seconds); the estimator calls this
    before it starts a window's clock, so the compilation is never charged to a
    window's time limit.  Later calls cost a dictionary lookup.
    """
    for name in KERNEL_MODULES:
        compiled_module(name)
