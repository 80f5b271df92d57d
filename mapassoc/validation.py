"""Argument checks shared by the public constructors and functions.

Each check raises :class:`~mapassoc.errors.InputError` (or
:class:`~mapassoc.errors.NotPositiveDefiniteError`) with a message naming the
argument, the value received and what was expected.  Nothing is clamped.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.errors import InputError, NotPositiveDefiniteError

__all__ = [
    "check_standard_deviation",
    "check_integer",
    "check_probability",
    "check_positive",
    "check_nonnegative",
    "check_finite_array",
    "check_covariance",
]


def _as_float(name: str, value: object, key: str | None = None) -> float:
    if isinstance(value, bool):
        raise InputError(f"{name} must be a number, got the boolean {value!r}", key=key)
    try:
        out = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}", key=key) from None
    if not math.isfinite(out):
        raise InputError(f"{name} must be finite, got {value!r}", key=key)
    return out


def check_probability(
    name: str,
    value: object,
    *,
    allow_zero: bool = True,
    allow_one: bool = True,
    key: str | None = None,
) -> float:
    """Return ``value`` as a float after checking it is a probability.

    Parameters
    ----------
    name : str
        Argument name used in the error message.
    value : object
        The value to check.
    allow_zero, allow_one : bool
        Whether the closed ends of [0, 1] are accepted.
    key : str, optional
        Field name stored in the raised error's ``InputError.key``.
    """
    p = _as_float(name, value, key)
    lo_ok = p >= 0.0 if allow_zero else p > 0.0
    hi_ok = p <= 1.0 if allow_one else p < 1.0
    if not (lo_ok and hi_ok):
        lo = "[0" if allow_zero else "(0"
        hi = "1]" if allow_one else "1)"
        raise InputError(f"{name} must be a probability in {lo}, {hi}, got {value!r}", key=key)
    return p


def check_positive(name: str, value: object, *, key: str | None = None) -> float:
    """Return ``value`` as a float after checking it is finite and > 0.

    ``key`` is stored in the raised error's ``InputError.key``.
    """
    v = _as_float(name, value, key)
    if v <= 0.0:
        raise InputError(f"{name} must be positive, got {value!r}", key=key)
    return v


def check_nonnegative(name: str, value: object, *, key: str | None = None) -> float:
    """Return ``value`` as a float after checking it is finite and >= 0.

    ``key`` is stored in the raised error's ``InputError.key``.
    """
    v = _as_float(name, value, key)
    if v < 0.0:
        raise InputError(f"{name} must be non-negative, got {value!r}", key=key)
    return v


def check_integer(
    name: str,
    value: object,
    *,
    minimum: int | None = None,
    maximum: int | None = None,
    key: str | None = None,
) -> int:
    """Return ``value`` as an int after checking it is an integer within the bounds.

    Python and numpy integers are accepted; booleans, floats (even ``3.0``) and strings
    are not.

    Parameters
    ----------
    name : str
        Argument name used in the error message.
    value : object
        The value to check.
    minimum, maximum : int, optional
        Inclusive bounds.
    key : str, optional
        Field name stored in the raised error's ``InputError.key``.
    """
    if minimum is not None and maximum is not None:
        expected = f"an integer in {minimum}..{maximum}"
    elif minimum is not None:
        expected = f"an integer >= {minimum}"
    elif maximum is not None:
        expected = f"an integer <= {maximum}"
    else:
        expected = "an integer"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name} must be {expected}, got {value!r}", key=key)
    out = int(value)
    if (minimum is not None and out < minimum) or (maximum is not None and out > maximum):
        raise InputError(f"{name} must be {expected}, got {value!r}", key=key)
    return out


def check_standard_deviation(name: str, value: object, *, key: str | None = None) -> float:
    """``value`` as a float after checking that it is a standard deviation the filters
    can square: finite, > 0, and with a square (the variance) that is finite and > 0 in
    double precision (so from about 1.5e-154 to 1.3e154).  Nothing is clamped.

    ``key`` is stored in the raised error's ``InputError.key``.
    """
    std = check_positive(name, value, key=key)
    variance = std * std
    if not (math.isfinite(variance) and variance > 0.0):
        raise InputError(
            f"{name} = {value!r} is a standard deviation whose square (the variance, "
            f"{variance!r}) is not a finite number > 0 in double precision; expected a "
            f"value between 1.5e-154 and 1.3e154 (check its unit)",
            key=key,
        )
    return std


def check_finite_array(
    name: str, value: ArrayLike, *, shape: tuple[int | None, ...] | None = None
) -> NDArray[np.float64]:
    """Return ``value`` as a float array after checking shape and finiteness.

    Parameters
    ----------
    name : str
        Argument name used in the error message.
    value : array_like
        The array.
    shape : tuple of int or None, optional
        Expected shape; ``None`` entries accept any length on that axis.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a numeric array, got {value!r}") from None
    if shape is not None:
        ok = arr.ndim == len(shape) and all(
            want is None or have == want for have, want in zip(arr.shape, shape, strict=True)
        )
        if not ok:
            expected = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
            raise InputError(f"{name} must have shape {expected}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must contain only finite values, got {arr.tolist()!r}")
    return arr


def check_covariance(
    name: str, value: ArrayLike, *, dim: int | None = None, allow_semidefinite: bool = False
) -> NDArray[np.float64]:
    """Return ``value`` as a symmetric positive-(semi)definite matrix or raise.

    Parameters
    ----------
    name : str
        Argument name used in the error message.
    value : array_like, shape (n, n)
        The matrix.
    dim : int, optional
        Required size n.
    allow_semidefinite : bool
        Accept singular positive-semidefinite matrices (process noise may be singular).

    Raises
    ------
    InputError
        Wrong shape or non-finite entries.
    NotPositiveDefiniteError
        Not symmetric, or not positive-(semi)definite.
    """
    P = check_finite_array(name, value, shape=(dim, dim))
    if P.shape[0] != P.shape[1]:
        raise InputError(f"{name} must be square, got shape {P.shape}")
    scale = max(1.0, float(np.max(np.abs(P)))) if P.size else 1.0
    if not np.allclose(P, P.T, rtol=1e-9, atol=1e-12 * scale):
        raise NotPositiveDefiniteError(f"{name} must be symmetric, got {P.tolist()!r}")
    if allow_semidefinite:
        eig = np.linalg.eigvalsh(P)
        if eig.size and eig.min() < -1e-10 * scale:
            raise NotPositiveDefiniteError(
                f"{name} must be positive-semidefinite, got eigenvalues {eig.tolist()!r}"
            )
    else:
        try:
            np.linalg.cholesky(P)
        except np.linalg.LinAlgError:
            raise NotPositiveDefiniteError(
                f"{name} must be positive-definite, got {P.tolist()!r}"
            ) from None
    return P
