"""The known-rate turn model in the constant-velocity state (Bar-Shalom, Li and
Kirubarajan 2001, section 11.7.1): its closed forms against the matrix exponential, its
limit, its motion, its configuration, and its place in a model set."""

from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np
import pytest
import scipy.linalg

from mapassoc.data.config import config_to_toml, parse_config
from mapassoc.errors import ConfigError, InputError
from mapassoc.estimator.objective import RecordingObjective, paths_from_rows
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.models.interacting import InteractingModels
from mapassoc.models.motion import ConstantTurn, ConstantVelocity
from mapassoc.models.switching import SwitchingLaw


def _van_loan(omega: float, q: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """F and Q of ``dx = A x dt + G dw`` by Van Loan's matrix exponential ("Computing
    integrals involving the matrix exponential", IEEE TAC 1978), independent of the
    closed forms."""
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2, 3], A[3, 2] = -omega, omega
    G = np.zeros((4, 2))
    G[2, 0] = G[3, 1] = 1.0
    block = np.block([[-A, q * G @ G.T], [np.zeros((4, 4)), A.T]]) * dt
    E = scipy.linalg.expm(block)
    F = E[4:, 4:].T
    return F, F @ E[:4, 4:]


@pytest.mark.parametrize("omega", [0.0, 1e-7, 4e-4, 0.03, -0.2, 1.5, -3.0])
@pytest.mark.parametrize("dt", [0.5, 5.0])
def test_closed_forms_equal_the_matrix_exponential(omega: float, dt: float) -> None:
    F, Q = ConstantTurn(turn_rate=omega, noise_intensity=0.7).matrices(dt)
    F_ref, Q_ref = _van_loan(omega, 0.7, dt)
    np.testing.assert_allclose(F, F_ref, rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(Q, Q_ref, rtol=1e-10, atol=1e-12 * max(1.0, dt**3))
    np.testing.assert_array_equal(Q, Q.T)
    assert np.all(np.linalg.eigvalsh(Q) > 0)


def test_no_turn_is_constant_velocity() -> None:
    cv = ConstantVelocity(ndim=2, noise_intensity=0.7)
    turn = ConstantTurn(turn_rate=0.0, noise_intensity=0.7)
    assert turn.state_names == cv.state_names
    np.testing.assert_allclose(turn.matrices(3.0)[0], cv.transition_matrix(3.0), atol=1e-15)
    np.testing.assert_allclose(turn.process_noise(3.0), cv.process_noise(3.0), rtol=1e-14)


def test_a_full_circle_returns_to_its_start_at_constant_speed() -> None:
    """Noise-free, a state goes round a circle of radius speed / omega: after 2 pi / omega
    it is back, and at every step its speed is the same and its centre fixed."""
    omega, x0 = 0.1, np.array([100.0, -50.0, 30.0, 40.0])
    model = ConstantTurn(turn_rate=omega, noise_intensity=1.0)
    steps = 40
    dt = 2 * math.pi / omega / steps
    x = x0
    centre = x0[:2] + np.array([-x0[3], x0[2]]) / omega  # left of the velocity
    for _ in range(steps):
        x = model.transition(x, dt)
        assert np.hypot(x[2], x[3]) == pytest.approx(50.0, rel=1e-12)
        assert np.hypot(*(x[:2] - centre)) == pytest.approx(50.0 / omega, rel=1e-10)
    np.testing.assert_allclose(x, x0, atol=1e-9)


def test_a_turn_rate_must_be_finite() -> None:
    with pytest.raises(InputError, match="turn_rate"):
        ConstantTurn(turn_rate=math.inf, noise_intensity=1.0)
    with pytest.raises(InputError, match="noise_intensity"):
        ConstantTurn(turn_rate=0.1, noise_intensity=0.0)


def test_a_set_with_turns_is_read_and_written_back() -> None:
    """``model = "constant_turn"`` inside ``model = "imm"``: a negative rate is read, and
    the written file reads back to the same models."""
    scenario = build_scenario("crossing", seed=0)
    base = scenario.config
    models = [
        ConstantVelocity(ndim=2, noise_intensity=base.motion.noise_intensity),
        ConstantTurn(turn_rate=0.05, noise_intensity=base.motion.noise_intensity),
        ConstantTurn(turn_rate=-0.05, noise_intensity=base.motion.noise_intensity),
    ]
    motion = InteractingModels(models=models, switching=SwitchingLaw(3, switch_probability=0.02))
    text = config_to_toml(dataclasses.replace(base, motion=motion))
    assert 'model = "constant_turn"' in text and "turn_rate = -0.05" in text
    back = parse_config(tomllib.loads(text)).motion
    assert isinstance(back, InteractingModels)
    assert [type(m) for m in back.models] == [ConstantVelocity, ConstantTurn, ConstantTurn]
    assert [m.omega for m in back.models[1:]] == [0.05, -0.05]
    bad = text.replace("turn_rate = -0.05", 'turn_rate = "left"')
    with pytest.raises(ConfigError, match=r"motion\.models\[2\]\.turn_rate"):
        parse_config(tomllib.loads(bad))


def test_j_of_a_turning_set_runs_in_the_compiled_path_and_agrees_with_numpy(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A turn model alone is linear: J of a track takes the compiled re-filtering, which
    agrees with the numpy steps."""
    scenario = build_scenario("crossing", seed=0)
    config = dataclasses.replace(
        scenario.config,
        motion=ConstantTurn(turn_rate=0.02, noise_intensity=scenario.config.motion.noise_intensity),
    )
    scans = scenario.scans[:15]
    forward = dataclasses.replace(
        config, estimator=dataclasses.replace(config.estimator, refine_passes=0)
    )
    objective = RecordingObjective(config=config, scans=scans)
    rows = WindowEstimator(config=forward).run(scans).track_rows
    paths = [p for p in paths_from_rows(objective, rows).values() if len(p) >= 6]
    assert paths
    path = paths[0]
    values = []
    for switch in ("0", "1"):
        monkeypatch.setenv("MAPASSOC_COMPILED", switch)
        values.append(RecordingObjective(config=config, scans=scans).trajectory(path).values)
    assert np.all(np.isfinite(values[0]))
    np.testing.assert_allclose(values[0], values[1], rtol=1e-10, atol=1e-8)
