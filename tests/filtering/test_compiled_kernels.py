"""The compiled Kalman kernels (numba, optional) against the textbook numpy filter.

* ``kalman_update`` gives the Joseph-form update, ``d^2`` and ``log N(nu; 0, S)`` of
  :mod:`mapassoc.filtering.kalman` for measurement dimensions 1, 2 (closed-form
  inverses) and 3 (Cholesky), and flags an ``S`` that is not positive-definite;
* ``continue_along_references`` (the refinement's batched continuation) agrees with the
  numpy path there (``MAPASSOC_COMPILED=0``) on the requests of
  ``test_batched_continuation_equals_one_request_at_a_time``, which itself runs on both
  paths;
* ``MAPASSOC_COMPILED=0`` turns the kernels off.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mapassoc.filtering import compiled
from mapassoc.filtering.kalman import update

pytest.importorskip("numba")


def _spd(rng: np.random.Generator, size: int, n: int) -> np.ndarray:
    A = rng.normal(size=(size, n, n))
    return A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(n)


@pytest.mark.parametrize("d", [1, 2, 3])
@pytest.mark.parametrize("seed", range(4))
def test_kalman_update_is_the_textbook_update(d: int, seed: int) -> None:
    kernels = compiled.kalman_kernels()
    assert kernels is not None
    rng = np.random.default_rng(seed)
    n, B = 4, 7
    x = rng.normal(size=(B, n))
    P = _spd(rng, B, n)
    H = rng.normal(size=(d, n))
    R = _spd(rng, 1, d)[0]
    z = rng.normal(size=(B, d))
    d2, loglik, x_post, P_post, positive = kernels.kalman_update(x, P, z, H, R)
    assert positive
    S = H @ P @ H.T + R
    nu = z - x @ H.T
    expected_x, expected_P = update(x, P, nu, S, H, R)
    np.testing.assert_allclose(x_post, expected_x, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(P_post, expected_P, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(P_post, np.swapaxes(P_post, -1, -2), rtol=0, atol=0)
    expected_d2 = np.einsum("bi,bi->b", nu, np.linalg.solve(S, nu[..., None])[..., 0])
    np.testing.assert_allclose(d2, expected_d2, rtol=1e-10)
    _, logdet = np.linalg.slogdet(S)
    expected_loglik = -0.5 * (d * math.log(2 * math.pi) + logdet + expected_d2)
    np.testing.assert_allclose(loglik, expected_loglik, rtol=1e-10)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_a_covariance_that_is_not_positive_definite_is_flagged(d: int) -> None:
    kernels = compiled.kalman_kernels()
    assert kernels is not None
    n = 4
    x = np.zeros((2, n))
    P = np.zeros((2, n, n))
    H = np.eye(d, n)
    R = -np.eye(d)  # S = H P H^T + R = -I
    *_, positive = kernels.kalman_update(x, P, np.zeros((2, d)), H, R)
    assert not positive


def test_the_switch_turns_the_kernels_off(monkeypatch: pytest.MonkeyPatch) -> None:
    assert compiled.kalman_kernels() is not None
    monkeypatch.setenv(compiled.COMPILED_SWITCH, "0")
    assert compiled.kalman_kernels() is None
    monkeypatch.setenv(compiled.COMPILED_SWITCH, "1")
    assert compiled.kalman_kernels() is not None
