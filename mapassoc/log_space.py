"""Log-space arithmetic shared by the domain and the formulations (numpy only).

Probabilities and masses are carried as logarithms throughout (a window's per-k masses
span hundreds of nats); sums of them are log-sum-exps taken around the largest term.
A logarithm may be infinite (``log 0``, a width that disables pruning), which JSON cannot
hold: :func:`json_number` writes it as the string ``"inf"`` or ``"-inf"`` (TOML's
literals) and :func:`number_from_json` reads it back.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["log_sum_exp", "json_number", "number_from_json"]

_INFINITIES = {"inf": math.inf, "-inf": -math.inf}


def log_sum_exp(values: ArrayLike, axis: int | None = None) -> NDArray[np.float64]:
    """``log(sum(exp(values)))`` over ``axis`` (every entry when ``None``), computed
    around the maximum: ``-inf`` where every term is ``-inf`` or there is none, ``inf``
    where a term is ``inf``, NaN where one is NaN.

    The same values as :func:`scipy.special.logsumexp` (to rounding), without its
    per-call overhead (about ten times this function's on the small arrays of one
    window's tables and posterior).

    Parameters
    ----------
    values : array_like
    axis : int, optional

    Returns
    -------
    ndarray
        ``values``' shape without ``axis`` (a 0-d array when ``axis`` is ``None``).
    """
    x = np.asarray(values, dtype=np.float64)
    top = np.max(x, axis=axis, keepdims=True, initial=-np.inf)
    shift = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        total = np.log(np.sum(np.exp(x - shift), axis=axis, keepdims=True)) + shift
    return np.squeeze(total, axis=axis) if axis is not None else total.reshape(())


def json_number(value: float) -> float | str:
    """``value`` as JSON can hold it: ``"inf"`` / ``"-inf"`` for the infinities, else the
    float itself (NaN stays NaN: a JSON writer with ``allow_nan=False`` refuses it)."""
    number = float(value)
    if math.isinf(number):
        return "inf" if number > 0 else "-inf"
    return number


def number_from_json(value: float | str) -> float:
    """The float :func:`json_number` wrote (``"inf"``, ``"-inf"`` or a number).

    Raises
    ------
    ValueError
        ``value`` is another string.
    """
    if isinstance(value, str):
        if value not in _INFINITIES:
            raise ValueError(f"expected a number, 'inf' or '-inf', got {value!r}")
        return _INFINITIES[value]
    return float(value)
