"""Motion and measurement models, Kalman/EKF filtering, gating and RTS smoothing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import multivariate_normal

import mapassoc.filtering.kalman as kalman_module
from mapassoc.errors import InputError, NotPositiveDefiniteError
from mapassoc.filtering.kalman import (
    FilterStep,
    filter_sequence,
    gate_threshold,
    gated_pairs_and_loglik,
    innovation,
    log_gaussian,
    pairwise_gate_and_loglik,
    predict_motion,
    update,
)
from mapassoc.models.measurement import LinearMeasurement, RangeBearing, wrap_angle
from mapassoc.models.motion import (
    ConstantAcceleration,
    ConstantVelocity,
    CoordinatedTurn,
    RandomWalk,
)


def numeric_jacobian(f, x: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    cols = [(f(x + eps * e) - f(x - eps * e)) / (2 * eps) for e in np.eye(len(x))]
    return np.stack(cols, axis=-1)


def test_constant_velocity_matrices_closed_form() -> None:
    cv = ConstantVelocity(ndim=2, noise_intensity=0.5)
    dt = 2.0
    F = cv.transition_matrix(dt)
    Q = cv.process_noise(dt)
    assert cv.state_names == ("x", "y", "vx", "vy")
    np.testing.assert_array_equal(F[0], [1, 0, 2, 0])
    np.testing.assert_array_equal(F[3], [0, 0, 0, 1])
    # q * [[dt^3/3, dt^2/2], [dt^2/2, dt]] per axis = 0.5 * [[8/3, 2], [2, 2]]
    assert Q[0, 0] == pytest.approx(0.5 * 8 / 3)
    assert Q[0, 2] == pytest.approx(1.0)
    assert Q[2, 2] == pytest.approx(1.0)
    assert Q[0, 1] == 0.0 and Q[0, 3] == 0.0


def test_constant_acceleration_and_random_walk() -> None:
    ca = ConstantAcceleration(ndim=1, noise_intensity=1.0)
    F = ca.transition_matrix(1.0)
    np.testing.assert_allclose(F, [[1, 1, 0.5], [0, 1, 1], [0, 0, 1]])
    Q = ca.process_noise(1.0)
    assert Q[0, 0] == pytest.approx(1 / 20) and Q[1, 2] == pytest.approx(0.5)
    assert np.all(np.linalg.eigvalsh(Q) > 0)
    rw = RandomWalk(ndim=1, noise_intensity=0.35)
    assert rw.process_noise(1.0)[0, 0] == pytest.approx(0.35)
    assert rw.process_noise(2.0)[0, 0] == pytest.approx(0.7)


@pytest.mark.parametrize("rate", [0.3, -0.05, 0.0, 1e-9])
def test_coordinated_turn_jacobian_matches_finite_differences(rate: float) -> None:
    ct = CoordinatedTurn(speed_noise_intensity=1.0, turn_rate_noise_intensity=0.01)
    x = np.array([3.0, -2.0, 12.0, 0.7, rate])
    J = ct.jacobian(x, 1.5)
    np.testing.assert_allclose(J, numeric_jacobian(lambda s: ct.transition(s, 1.5), x), atol=1e-6)


def test_coordinated_turn_straight_line_and_full_circle() -> None:
    ct = CoordinatedTurn(speed_noise_intensity=1.0, turn_rate_noise_intensity=0.01)
    x = np.array([0.0, 0.0, 2.0, math.pi / 2, 0.0])
    np.testing.assert_allclose(ct.transition(x, 3.0)[:2], [0.0, 6.0], atol=1e-12)
    # Turning at 2*pi / 10 rad per unit time for 10 units closes the circle.
    x = np.array([1.0, 1.0, 5.0, 0.3, 2 * math.pi / 10])
    np.testing.assert_allclose(ct.transition(x, 10.0)[:2], [1.0, 1.0], atol=1e-9)


def test_range_bearing_jacobian_and_wrapping() -> None:
    rb = RangeBearing(sensor_position=[10.0, -5.0], range_std=1.0, bearing_std=0.01)
    x = np.array([40.0, 25.0, 1.0, 2.0])
    np.testing.assert_allclose(rb.jacobian(x), numeric_jacobian(rb.predict, x), atol=1e-7)
    z_hat = np.array([10.0, math.pi - 0.01])
    z = np.array([10.0, -math.pi + 0.01])
    assert rb.residual(z, z_hat)[1] == pytest.approx(0.02)
    np.testing.assert_allclose(wrap_angle([math.pi, -math.pi, 3 * math.pi]), [math.pi] * 3)


def test_kalman_scalar_closed_form() -> None:
    rw = RandomWalk(ndim=1, noise_intensity=0.35)
    meas = LinearMeasurement(H=[[1.0]], R=[[0.2]], component_names=("x",), position_indices=(0,))
    x, P, _ = predict_motion(rw, np.array([0.5]), np.array([[0.2]]), 1.0)
    assert P[0, 0] == pytest.approx(0.55)
    nu, S, H = innovation(meas, x, P, np.array([1.3]))
    assert S[0, 0] == pytest.approx(0.75)
    x_post, P_post = update(x, P, nu, S, H, meas.R)
    gain = 0.55 / 0.75
    assert x_post[0] == pytest.approx(0.5 + gain * 0.8)
    assert P_post[0, 0] == pytest.approx(0.55 - gain * 0.55)
    expected = -0.5 * (math.log(2 * math.pi * 0.75) + 0.8**2 / 0.75)
    assert float(log_gaussian(nu, S)) == pytest.approx(expected)


class _LinearAsNonlinear:
    """A linear measurement presented through the nonlinear interface."""

    is_linear = False

    def __init__(self, inner: LinearMeasurement) -> None:
        self.inner = inner
        self.measurement_dim = inner.measurement_dim
        self.component_names = inner.component_names
        self.noise_covariance = inner.noise_covariance

    def predict(self, x):
        return np.asarray(x) @ self.inner.H.T

    def jacobian(self, x):
        return numeric_jacobian(self.predict, np.asarray(x, dtype=float))

    def residual(self, z, z_hat):
        return np.asarray(z) - np.asarray(z_hat)


def test_ekf_equals_kf_on_a_linear_model() -> None:
    cv = ConstantVelocity(ndim=2, noise_intensity=0.3)
    lin = LinearMeasurement.position(cv, noise_std=[1.0, 2.0])
    ekf_meas = _LinearAsNonlinear(lin)
    rng = np.random.default_rng(0)
    x = rng.normal(size=4)
    P = np.diag([4.0, 3.0, 2.0, 1.0])
    for _ in range(5):
        x, P, _ = predict_motion(cv, x, P, 0.7)
        z = rng.normal(size=2) * 3
        a = innovation(lin, x, P, z)
        b = innovation(ekf_meas, x, P, z)
        for u, v in zip(a, b, strict=True):
            np.testing.assert_allclose(u, v, atol=1e-8)
        x, P = update(x, P, *a, lin.R)


def test_smoother_equals_batch_least_squares() -> None:
    """RTS on a linear-Gaussian chain equals the posterior of the stacked linear model."""
    cv = ConstantVelocity(ndim=1, noise_intensity=0.8)
    meas = LinearMeasurement.position(cv, noise_std=0.5)
    rng = np.random.default_rng(3)
    T = 6
    times = np.cumsum(rng.uniform(0.5, 1.5, size=T))
    zs = [rng.normal(size=1) * 2 if k != 3 else None for k in range(T)]  # a miss at step 3
    x0 = np.array([0.0, 1.0])
    P0 = np.diag([2.0, 1.0])
    steps = [
        FilterStep(t, meas if z is not None else None, z) for t, z in zip(times, zs, strict=True)
    ]
    result = filter_sequence(cv, x0, P0, steps)
    # Batch: information matrix over the stacked states x_0..x_{T-1}.
    n = 2
    Lam = np.zeros((T * n, T * n))
    eta = np.zeros(T * n)
    P0i = np.linalg.inv(P0)
    Lam[:n, :n] += P0i
    eta[:n] += P0i @ x0
    for k in range(1, T):
        dt = times[k] - times[k - 1]
        F, Qi = cv.transition_matrix(dt), np.linalg.inv(cv.process_noise(dt))
        a, b = slice((k - 1) * n, k * n), slice(k * n, (k + 1) * n)
        Lam[a, a] += F.T @ Qi @ F
        Lam[a, b] -= F.T @ Qi
        Lam[b, a] -= Qi @ F
        Lam[b, b] += Qi
    Ri = np.linalg.inv(meas.R)
    for k, z in enumerate(zs):
        if z is None:
            continue
        s = slice(k * n, (k + 1) * n)
        Lam[s, s] += meas.H.T @ Ri @ meas.H
        eta[s] += meas.H.T @ Ri @ z
    cov = np.linalg.inv(Lam)
    mean = cov @ eta
    np.testing.assert_allclose(result.x_smoothed.ravel(), mean, atol=1e-9)
    for k in range(T):
        s = slice(k * n, (k + 1) * n)
        np.testing.assert_allclose(result.P_smoothed[k], cov[s, s], atol=1e-9)
    # The last smoothed state is the last filtered state.
    np.testing.assert_allclose(result.x_smoothed[-1], result.x_filtered[-1])


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    noise=st.floats(1e-4, 1e3),
    meas_std=st.floats(1e-3, 1e2),
)
def test_covariance_stays_symmetric_positive_definite(
    seed: int, noise: float, meas_std: float
) -> None:
    cv = ConstantVelocity(ndim=2, noise_intensity=noise)
    meas = LinearMeasurement.position(cv, noise_std=meas_std)
    rng = np.random.default_rng(seed)
    x = np.zeros(4)
    P = np.eye(4) * 1e4
    for _ in range(200):
        x, P, _ = predict_motion(cv, x, P, float(rng.uniform(0.01, 3.0)))
        z = x[:2] + rng.normal(size=2) * meas_std
        x, P = update(x, P, *innovation(meas, x, P, z), meas.R)
        np.testing.assert_array_equal(P, P.T)
        assert np.linalg.eigvalsh(P).min() > 0


def test_pairwise_scores_match_single_evaluations() -> None:
    rng = np.random.default_rng(1)
    T, M, d = 4, 6, 2
    A = rng.normal(size=(T, d, d))
    S = A @ np.swapaxes(A, 1, 2) + np.eye(d)
    nu = rng.normal(size=(T, M, d))
    d2, ll = pairwise_gate_and_loglik(nu, S)
    for t in range(T):
        for m in range(M):
            assert ll[t, m] == pytest.approx(
                multivariate_normal(mean=np.zeros(d), cov=S[t]).logpdf(nu[t, m])
            )
            assert d2[t, m] == pytest.approx(nu[t, m] @ np.linalg.solve(S[t], nu[t, m]))


def test_gate_threshold_values() -> None:
    assert gate_threshold(0.99, 2) == pytest.approx(9.2103, abs=1e-4)
    # Bit for bit scipy.stats.chi2.ppf, which the module no longer imports.
    from scipy.stats import chi2

    for p in (0.5, 0.9, 0.99, 0.999, 0.99999):
        for dim in (1, 2, 3, 4, 6):
            assert gate_threshold(p, dim) == float(chi2.ppf(p, dim))
    assert gate_threshold(1.0, 2) == math.inf
    with pytest.raises(InputError, match="gate probability"):
        gate_threshold(0.0, 2)


def test_not_positive_definite_covariances_raise() -> None:
    bad = np.array([[[1.0, 0.0], [0.0, 1.0]], [[1.0, 2.0], [2.0, 1.0]]])
    with pytest.raises(NotPositiveDefiniteError, match=r"\[1\]"):
        pairwise_gate_and_loglik(np.zeros((2, 1, 2)), bad)
    with pytest.raises(NotPositiveDefiniteError):
        log_gaussian(np.zeros(2), np.array([[1.0, 0.0], [0.0, -1.0]]))
    with pytest.raises(NotPositiveDefiniteError):
        LinearMeasurement(H=[[1.0, 0.0]], R=[[-1.0]], component_names=("x",))


@pytest.mark.parametrize(
    ("factory", "message"),
    [
        (lambda: ConstantVelocity(ndim=4, noise_intensity=1.0), "ndim"),
        (lambda: ConstantVelocity(ndim=2, noise_intensity=0.0), "noise_intensity"),
        (lambda: CoordinatedTurn(speed_noise_intensity=-1, turn_rate_noise_intensity=1), "speed"),
        (lambda: ConstantVelocity(ndim=2, noise_intensity=1.0).transition_matrix(0.0), "dt"),
        (lambda: RangeBearing(sensor_position=[0, 0], range_std=0, bearing_std=1), "range_std"),
    ],
)
def test_bad_model_parameters_raise(factory, message: str) -> None:
    with pytest.raises(InputError, match=message):
        factory()


@pytest.mark.parametrize("dz", [1, 2, 3])
def test_update_equals_the_textbook_gain_for_every_measurement_dimension(dz: int) -> None:
    """The closed-form inverse (dz <= 2) and the Cholesky solves (dz = 3) both give
    K = P H^T S^-1 and the Joseph-form covariance, for a batch."""
    rng = np.random.default_rng(dz)
    n, B = 4, 6
    A = rng.normal(size=(B, n, n))
    P = A @ np.swapaxes(A, -1, -2) + np.eye(n)
    x = rng.normal(size=(B, n))
    H = rng.normal(size=(dz, n))
    C = rng.normal(size=(dz, dz))
    R = C @ C.T + 0.5 * np.eye(dz)
    S = H @ P @ H.T + R
    nu = rng.normal(size=(B, dz))
    x_post, P_post = update(x, P, nu, S, H, R)
    for b in range(B):
        K = P[b] @ H.T @ np.linalg.inv(S[b])
        I_KH = np.eye(n) - K @ H
        np.testing.assert_allclose(x_post[b], x[b] + K @ nu[b], rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(
            P_post[b], I_KH @ P[b] @ I_KH.T + K @ R @ K.T, rtol=1e-10, atol=1e-10
        )


@pytest.mark.parametrize("dz", [1, 2])
def test_update_names_the_innovation_covariance_that_is_not_positive_definite(dz: int) -> None:
    P = np.stack([np.eye(2), np.eye(2)])
    H = np.eye(dz, 2)
    S = np.stack([np.eye(dz), -np.eye(dz)])
    with pytest.raises(NotPositiveDefiniteError, match=r"innovation covariance S.*\[1\]"):
        update(np.zeros((2, 2)), P, np.zeros((2, dz)), S, H, np.eye(dz))


@pytest.mark.parametrize("layout", ["spread", "on_a_line", "small_blocks"])
@pytest.mark.parametrize("d", [1, 2, 3])
def test_gated_pairs_are_the_dense_gate_pairs(
    d: int, layout: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The strip search's gated pairs (closed forms for d = 2, Cholesky otherwise) are
    the pairs of the dense computation within the gate, with the same d2 and loglik:
    detections spread out, detections strung along one line (every strip holds most of
    them), and candidates taken a few at a time (tracks in many blocks)."""
    rng = np.random.default_rng(10 + d)
    T, M = 40, 60
    A = rng.normal(size=(T, d, d))
    S = A @ np.swapaxes(A, -1, -2) + 0.3 * np.eye(d)
    z_hat = rng.uniform(-5.0, 5.0, size=(T, d))
    Z = rng.uniform(-5.0, 5.0, size=(M, d))
    if layout == "on_a_line":  # one coordinate spreads, the others barely
        Z[:, 1:] = 0.01 * Z[:, 1:]
        z_hat[:, 1:] = 0.01 * z_hat[:, 1:]
    if layout == "small_blocks":
        monkeypatch.setattr(kalman_module, "_STRIP_BLOCK", 5)
    threshold = 6.0
    track, detection, nu, d2, loglik = gated_pairs_and_loglik(z_hat, S, Z, threshold)
    dense_d2, dense_loglik = pairwise_gate_and_loglik(Z[None, :, :] - z_hat[:, None, :], S)
    t_ref, m_ref = np.nonzero(dense_d2 <= threshold)
    assert t_ref.size > 20  # the gate holds pairs, and not all of them
    assert t_ref.size < T * M
    np.testing.assert_array_equal(track, t_ref)
    np.testing.assert_array_equal(detection, m_ref)
    np.testing.assert_allclose(nu, Z[m_ref] - z_hat[t_ref])
    np.testing.assert_allclose(d2, dense_d2[t_ref, m_ref], rtol=1e-9)
    np.testing.assert_allclose(loglik, dense_loglik[t_ref, m_ref], rtol=1e-9, atol=1e-9)
    bad = S.copy()
    bad[3] = -np.eye(d)
    with pytest.raises(NotPositiveDefiniteError, match=r"\[3\]"):
        gated_pairs_and_loglik(z_hat, bad, Z, threshold)
    for none in (
        gated_pairs_and_loglik(z_hat, S, Z[:0], threshold),
        gated_pairs_and_loglik(z_hat[:0], S[:0], Z, threshold),
    ):
        assert all(part.shape[0] == 0 for part in none)
