"""Argument checks shared by the public constructors and functions.

Each check raises :class:`~mapassoc.errors.InputError` (or
:class:`~mapassoc.errors.NotPositiveDefiniteError`) with a message naming the
argument, the value received and what was expected.  Nothing is clamped.
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Collection
from typing import NoReturn

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.errors import InputError, NotPositiveDefiniteError

__all__ = [
    "shown",
    "check_instance",
    "check_path",
    "check_text",
    "check_names",
    "check_callback",
    "check_number",
    "check_numeric_array",
    "check_standard_deviation",
    "check_integer",
    "check_probability",
    "check_positive",
    "check_nonnegative",
    "check_finite_array",
    "check_covariance",
]


SHOWN_WIDTH = 60
"""Characters of a value's ``repr`` an error message shows before cutting it short."""


def shown(value: object) -> str:
    """How a message shows a value: its ``repr`` (cut to :data:`SHOWN_WIDTH` characters,
    ending ``...`` when cut) and its type, as in ``'12:00' (str)``."""
    text = repr(value)
    if len(text) > SHOWN_WIDTH:
        text = text[: SHOWN_WIDTH - 3] + "..."
    return f"{text} ({type(value).__name__})"


def _refuse(
    name: str, value: object, expected: str, hint: str | None, key: str | None
) -> NoReturn:
    tail = f"; {hint}" if hint else ""
    raise InputError(f"{name} must be {expected}, got {shown(value)}{tail}", key=key)


def check_instance(
    name: str,
    value: object,
    cls: type | tuple[type, ...],
    *,
    expected: str | None = None,
    hint: str | None = None,
    key: str | None = None,
) -> None:
    """Raise unless ``value`` is an instance of ``cls`` (a runtime-checkable protocol
    too): an InputError naming ``name``, the value (:func:`shown`) and ``expected``
    (default ``"a <cls name>"``, the first of a tuple), then ``hint`` (what to pass
    instead) when given."""
    if not isinstance(value, cls):
        first = cls[0] if isinstance(cls, tuple) else cls
        _refuse(name, value, expected or f"a {first.__name__}", hint, key)


def check_path(name: str, value: object, *, hint: str | None = None) -> str:
    """``value`` as a path string: a ``str`` or an ``os.PathLike`` giving one.

    Bytes paths are refused (every path the package writes into a manifest or a message
    is text).  An empty string is left to the file system to refuse, naming the file.
    """
    if isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        text = os.fspath(value)
        if isinstance(text, str):
            return text
    _refuse(name, value, "a file path (str or os.PathLike)", hint, None)


def check_text(name: str, value: object, *, key: str | None = None) -> str:
    """``value`` if it is a non-empty ``str``, else an InputError naming it."""
    if not isinstance(value, str) or not value:
        _refuse(name, value, "a non-empty string", None, key)
    return value


def check_callback(name: str, value: object) -> None:
    """Raise unless ``value`` is ``None`` or callable (a function to call back)."""
    if value is not None and not callable(value):
        _refuse(name, value, "a callable (a function) or None", None, None)


def check_names(name: str, value: object) -> None:
    """Raise unless ``value`` is a collection of strings (a list, tuple or set; one
    string is refused: it is a collection of its characters)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, Collection):
        _refuse(name, value, "a collection of names", "a list, tuple or set of strings", None)
    for item in value:
        if not isinstance(item, str):
            _refuse(f"every entry of {name}", item, "a string", None, None)


def check_number(name: str, value: object, *, key: str | None = None) -> float:
    """``value`` as a float after checking it is a finite real number: not a boolean, not
    a string (no parsing: ``"0.1"`` is refused, so a number read as text is found where it
    was read, not converted here)."""
    return _as_float(name, value, key)


def _as_float(name: str, value: object, key: str | None = None) -> float:
    if isinstance(value, bool):
        raise InputError(f"{name} must be a number, got the boolean {value!r}", key=key)
    if isinstance(value, (str, bytes)):
        raise InputError(f"{name} must be a number, got {shown(value)}", key=key)
    try:
        out = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {shown(value)}", key=key) from None
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
        raise InputError(f"{name} must be {expected}, got {shown(value)}", key=key)
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


def _numeric(raw: NDArray[object]) -> bool:  # type: ignore[type-var]
    """Whether an array holds numbers only: numpy would parse ``"1.5"``, take ``True`` as
    1 and ``None`` as nan, and each of these is a mistake to report, not to convert."""
    if raw.dtype.kind in "iuf":
        return True
    if raw.dtype.kind != "O":
        return False
    return all(
        isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)) for v in raw.flat
    )


def check_numeric_array(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """``value`` as a float array, after checking that it holds numbers only (no text,
    no booleans, no ``None``, not ragged); finiteness and shape are the caller's."""
    try:
        raw = np.asarray(value)
        if not _numeric(raw):
            raise TypeError
        return np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a numeric array, got {shown(value)}") from None


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
    arr = check_numeric_array(name, value)
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
