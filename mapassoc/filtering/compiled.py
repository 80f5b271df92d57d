"""The optional compiled Kalman kernels, and the switch that turns them off.

With numba installed (``pip install 'mapassoc[accelerate]'``), the whole-recording
refinement takes its linear Kalman steps through the kernels of
:mod:`mapassoc.filtering.compiled_kernels`; without it, through numpy, with the same
results up to rounding.  The environment variable ``MAPASSOC_COMPILED=0`` turns the
kernels off (the numpy path alone, e.g. to compare the two).

The kernels are compiled on first use and cached next to the module (numba's
``cache=True``), so only the first run on a machine pays the compilation.
"""

from __future__ import annotations

import importlib.util
import os
import warnings
from types import ModuleType

__all__ = ["COMPILED_SWITCH", "kalman_kernels"]

COMPILED_SWITCH = "MAPASSOC_COMPILED"
"""Environment variable: ``0`` turns the compiled kernels off."""

_loaded: list[ModuleType | None] = []  # the kernels module (or None), once looked for


def kalman_kernels() -> ModuleType | None:
    """The compiled kernels module, or ``None`` for the numpy path.

    ``None`` when ``MAPASSOC_COMPILED=0`` or numba is not installed.  Where numba is
    installed but fails to import (e.g. built for another numpy), a ``RuntimeWarning``
    names the error once and the numpy path is taken.
    """
    if os.environ.get(COMPILED_SWITCH, "1").strip() == "0":
        return None
    if not _loaded:
        _loaded.append(_import_kernels())
    return _loaded[0]


def _import_kernels() -> ModuleType | None:
    if importlib.util.find_spec("numba") is None:
        return None
    try:
        from mapassoc.filtering import compiled_kernels
    except Exception as error:  # numba's import can fail in many ways; all are reported
        warnings.warn(
            f"numba is installed but the compiled Kalman kernels failed to load "
            f"({type(error).__name__}: {error}); using the numpy path",
            RuntimeWarning,
            stacklevel=3,
        )
        return None
    return compiled_kernels
