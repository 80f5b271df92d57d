"""The batched filter interface (:mod:`mapassoc.filtering.batch`) and its two backends.

* a pair's gate, ``d2`` and log-likelihood have the same bits whichever batch it is
  scored in, and the strip search of a dense scan keeps exactly the pairs the full
  scoring keeps (so the trees' dense and sparse scans and J agree to the last bit);
* the numbers are the textbook ones: ``S = H P H^T + R``, ``log N(nu; 0, S)`` against
  scipy's density, the update against the information form of the posterior;
* an ``S`` that is not positive-definite raises naming its batch index;
* the numpy backend (:mod:`mapassoc.filtering.scan_steps`) and the compiled kernels give
  the same run on random linear recordings, for measurement dimensions 1, 2 and 3.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from mapassoc.errors import NotPositiveDefiniteError
from mapassoc.filtering import scan_steps
from mapassoc.filtering.batch import DENSE_GATING_PAIRS, KalmanFilter
from mapassoc.filtering.compiled import filter_backend, kalman_kernels
from mapassoc.filtering.kalman import inverse_and_logdet
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import ConstantVelocity


def _spd(rng: np.random.Generator, size: int, n: int) -> np.ndarray:
    A = rng.normal(size=(size, n, n))
    return A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(n)


def _batch(seed: int, size: int):
    rng = np.random.default_rng(seed)
    motion = ConstantVelocity(ndim=2, noise_intensity=0.3)
    measurement = LinearMeasurement.position(motion, noise_std=1.0)
    x = np.c_[rng.uniform(0, 40, size=(size, 2)), rng.normal(size=(size, 2))]
    P = _spd(rng, size, 4)
    return rng, motion, measurement, x, P


@pytest.mark.parametrize("seed", range(3))
def test_a_pairs_numbers_do_not_depend_on_its_batch_or_the_strip_search(seed: int) -> None:
    rng, _, measurement, x, P = _batch(seed, 120)
    Z = rng.uniform(0, 40, size=(60, 2))
    kalman = KalmanFilter()
    threshold = 9.21
    together = kalman.innovation(measurement, x, P).gate(Z, threshold)
    assert len(x) * len(Z) > DENSE_GATING_PAIRS  # the strip search ran
    assert len(together) > 20
    for name in ("row", "detection", "nu", "d2", "loglik"):
        alone = []
        for b in range(len(x)):  # one track: 60 pairs, all scored
            pairs = kalman.innovation(measurement, x[b : b + 1], P[b : b + 1]).gate(Z, threshold)
            values = getattr(pairs, name)
            alone.append(values + b if name == "row" else values)
        np.testing.assert_array_equal(getattr(together, name), np.concatenate(alone))


@pytest.mark.parametrize("d", [1, 2, 3])
def test_the_steps_are_the_textbook_steps(d: int) -> None:
    rng = np.random.default_rng(d)
    n, B = 4, 5
    H = rng.normal(size=(d, n))
    R = _spd(rng, 1, d)[0]
    measurement = LinearMeasurement(H=H, R=R, component_names=[f"z{i}" for i in range(d)])
    x, P = rng.normal(size=(B, n)), _spd(rng, B, n)
    kalman = KalmanFilter()
    innovation = kalman.innovation(measurement, x, P)
    np.testing.assert_allclose(innovation.S, H @ P @ H.T + R, rtol=1e-12)
    z = rng.normal(size=(B, d))
    rows = np.arange(B)
    nu = innovation.residuals(z, rows)
    d2, loglik = innovation.scores(nu, rows)
    for b in range(B):
        S = H @ P[b] @ H.T + R
        assert d2[b] == pytest.approx(float(nu[b] @ np.linalg.solve(S, nu[b])), rel=1e-10)
        expected = multivariate_normal(mean=H @ x[b], cov=S).logpdf(z[b])
        assert loglik[b] == pytest.approx(expected, rel=1e-10)
    x_post, P_post = kalman.update(x, P, innovation, rows, nu)
    for b in range(B):
        # The information form: P+^-1 = P^-1 + H^T R^-1 H, x+ = P+ (P^-1 x + H^T R^-1 z).
        info = np.linalg.inv(P[b]) + H.T @ np.linalg.solve(R, H)
        expected_P = np.linalg.inv(info)
        expected_x = expected_P @ (np.linalg.solve(P[b], x[b]) + H.T @ np.linalg.solve(R, z[b]))
        np.testing.assert_allclose(P_post[b], expected_P, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(x_post[b], expected_x, rtol=1e-8, atol=1e-10)
        np.testing.assert_array_equal(P_post[b], P_post[b].T)


def test_the_prediction_is_the_models_linear_step() -> None:
    _, motion, _, x, P = _batch(0, 3)
    F, Q = motion.transition_matrix(1.5), motion.process_noise(1.5)
    x_pred, P_pred, F_used = KalmanFilter().predict(motion, x, P, 1.5)
    np.testing.assert_allclose(x_pred, x @ F.T, rtol=1e-14)
    np.testing.assert_allclose(P_pred, F @ P @ F.T + Q, rtol=1e-12)
    np.testing.assert_array_equal(F_used, F)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_an_innovation_covariance_that_is_not_positive_definite_names_its_index(d: int) -> None:
    S = np.tile(np.eye(d), (3, 1, 1))
    S[1] *= -1.0
    with pytest.raises(NotPositiveDefiniteError, match=r"\[1\]"):
        inverse_and_logdet(S)


def _scan_model(rng: np.random.Generator, M: int, n: int, d: int):
    F = np.tile(np.eye(n), (M, 1, 1))
    F[:, 0, 1] = rng.uniform(0.5, 1.5, size=M)
    Q = _spd(rng, M, n) * 0.1
    H = np.zeros((M, 3, n))
    H[:, :d] = rng.normal(size=(d, n))
    R = np.zeros((M, 3, 3))
    R[:, :d, :d] = _spd(rng, 1, d)[0]
    terms = [rng.normal(size=M) for _ in range(4)]
    moves = rng.random(M) < 0.8
    codes = np.arange(M, dtype=np.int64)
    return (
        moves, F, Q, H, R, np.full(M, d, dtype=np.int64), *terms, np.full(M, 50.0),
        codes, np.zeros(M, dtype=np.int64),
    )  # fmt: skip


@pytest.mark.parametrize("d", [1, 2, 3])
def test_the_numpy_backend_is_the_compiled_one(d: int) -> None:
    pytest.importorskip("numba")
    kernels = kalman_kernels()
    assert kernels is not None and filter_backend() is kernels
    rng = np.random.default_rng(10 + d)
    n, M = 4, 12
    scan_model = _scan_model(rng, M, n, d)
    path = np.array([2, 3, 6, 7, 11], dtype=np.int64)
    z = np.zeros((len(path), 3))
    z[:, :d] = rng.normal(size=(len(path), d))
    x0, P0 = rng.normal(size=n), _spd(rng, 1, n)[0]
    fast = kernels.filter_along_path(x0, P0, 0.5, 0, path, z, scan_model)
    plain = scan_steps.filter_along_path(x0, P0, 0.5, 0, path, z, scan_model)
    assert fast[3] and plain[3]
    for a, b in zip(fast[:3], plain[:3], strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-10)
