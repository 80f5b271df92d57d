"""The compiled kernels of a set of linear motion models (numba, optional) against the
numpy IMM of :mod:`mapassoc.filtering.batch` (``MAPASSOC_COMPILED=0``).

* ``predict_sets`` (mixing and each model's prediction, Blom and Bar-Shalom's IMM
  step 1 and 2) gives the numpy path's packed states for 2 and 3 models, including a
  switching matrix with a model no one can enter (``c_j = 0``: equal weights);
* the joins' kernel ``continue_sets_along_references`` is checked against its numpy
  twin, the lockstep continuation, in ``tests/estimator/test_interacting_models.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from mapassoc.filtering.batch import KalmanFilter
from mapassoc.filtering.compiled import imm_kernels
from mapassoc.models.interacting import InteractingModels, pack_models
from mapassoc.models.motion import ConstantTurn, ConstantVelocity
from mapassoc.models.switching import SwitchingLaw

pytest.importorskip("numba")


def _states(rng: np.random.Generator, B: int, M: int, n: int):
    A = rng.normal(size=(B, M, n, n))
    P = A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(n)
    x = rng.normal(scale=10.0, size=(B, M, n))
    log_mu = np.log(rng.dirichlet(np.ones(M), size=B))
    return pack_models(log_mu, x, P)


def _set(M: int, matrix: np.ndarray | None = None) -> InteractingModels:
    models = [ConstantVelocity(ndim=2, noise_intensity=0.5),
              ConstantTurn(turn_rate=0.05, noise_intensity=2.0),
              ConstantTurn(turn_rate=-0.05, noise_intensity=2.0)][:M]  # fmt: skip
    if matrix is not None:
        return InteractingModels(models=models, switching=SwitchingLaw(M, matrix=matrix))
    return InteractingModels(models=models, switching=SwitchingLaw(M, switch_probability=0.1))


@pytest.mark.parametrize(("M", "matrix"), [
    (2, None), (3, None),
    (3, np.array([[0.9, 0.1, 0.0], [0.1, 0.9, 0.0], [0.0, 0.0, 1.0]])),
])  # fmt: skip
@pytest.mark.parametrize("dt", [0.5, 4.0])
def test_predict_sets_is_the_numpy_imm_prediction(
    M: int, matrix: np.ndarray | None, dt: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert imm_kernels() is not None
    models = _set(M, matrix)
    x, P = _states(np.random.default_rng(M), 7, M, 4)
    if matrix is not None:  # the third model has probability 0 and no way in: c_3 = 0
        x[:, -1] = -np.inf
        x[:, -3:-1] -= np.logaddexp(x[:, -3], x[:, -2])[:, None]
    compiled = KalmanFilter(motion=models).predict(models, x, P, dt)
    monkeypatch.setenv("MAPASSOC_COMPILED", "0")
    assert imm_kernels() is None
    numpy_path = KalmanFilter(motion=models).predict(models, x, P, dt)
    np.testing.assert_allclose(compiled[0], numpy_path[0], rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(compiled[1], numpy_path[1], rtol=1e-12, atol=1e-10)
    assert not np.allclose(compiled[0], x)  # the step moved the states
    if matrix is not None:
        assert np.all(compiled[0][:, -1] == -np.inf)
