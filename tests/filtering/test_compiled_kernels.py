"""The compiled Kalman kernels (numba, optional) against the textbook numpy filter.

* a step of the kernels gives the Joseph-form update and ``log N(nu; 0, S)`` of
  :mod:`mapassoc.filtering.kalman` for measurement dimensions 1, 2 (closed-form
  inverses) and 3 (Cholesky), and flags an ``S`` that is not positive-definite;
* ``continue_along_references`` (the refinement's batched continuation) agrees with the
  numpy path there (``MAPASSOC_COMPILED=0``) on the requests of
  ``test_batched_continuation_equals_one_request_at_a_time``, which itself runs on both
  paths;
* ``filter_along_path`` (a track's whole filter run, ``RecordingObjective.trajectory``)
  gives the numpy path's states and values on true tracks of a linear scene, a scene
  with a range-bearing sensor (its steps stay in numpy) and a coordinated-turn scene
  (numpy throughout);
* ``MAPASSOC_COMPILED=0`` turns the kernels off, and ``load_kernels`` compiles every
  kernel for the argument types the estimator passes (no compilation inside a window).
"""

from __future__ import annotations

import dataclasses
import math
from types import ModuleType

import numpy as np
import pytest

from mapassoc.accelerate import KERNEL_MODULES, compiled_module, load_kernels
from mapassoc.estimator.objective import RecordingObjective, paths_from_rows
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.refiltering import Refiltering
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.filtering import compiled
from mapassoc.filtering.kalman import update

pytest.importorskip("numba")


def _spd(rng: np.random.Generator, size: int, n: int) -> np.ndarray:
    A = rng.normal(size=(size, n, n))
    return A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(n)


def _one_update(
    kernels: ModuleType,
    x: np.ndarray,
    P: np.ndarray,
    z: np.ndarray,
    H: np.ndarray,
    R: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """``filter_along_path`` through one detection at the next scan, with no time
    step between (no prediction): the update alone."""
    n, d = x.shape[0], z.shape[0]
    zeros, still = np.zeros(2), np.zeros((2, n, n))
    scan_model = (
        np.zeros(2, dtype=bool),  # no time step: no prediction
        still,
        still,
        np.stack([H, H]),
        np.stack([R, R]),
        np.full(2, d),
        zeros,
        zeros,
        zeros,
        zeros,
        np.full(2, np.inf),
        np.zeros(2, dtype=np.int64),
        np.zeros(2, dtype=np.int64),
    )
    return kernels.filter_along_path(x, P, 0.0, 0, np.array([1]), z[None, :], scan_model)


@pytest.mark.parametrize("d", [1, 2, 3])
@pytest.mark.parametrize("seed", range(4))
def test_one_step_is_the_textbook_update(d: int, seed: int) -> None:
    kernels = compiled.kalman_kernels()
    assert kernels is not None
    rng = np.random.default_rng(seed)
    n = 4
    x = rng.normal(size=n)
    P = _spd(rng, 1, n)[0]
    H = rng.normal(size=(d, n))
    R = _spd(rng, 1, d)[0]
    z = rng.normal(size=d)
    means, covariances, values, positive = _one_update(kernels, x, P, z, H, R)
    assert positive
    S = H @ P @ H.T + R
    nu = z - H @ x
    expected_x, expected_P = update(x, P, nu, S, H, R)
    np.testing.assert_allclose(means[0], expected_x, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(covariances[0], expected_P, rtol=1e-10, atol=1e-10)
    np.testing.assert_array_equal(covariances[0], covariances[0].T)
    # The value adds log N(nu; 0, S) (log Pd = log lambda = 0 here, no survival term).
    _, logdet = np.linalg.slogdet(S)
    d2 = float(nu @ np.linalg.solve(S, nu))
    assert values[0] == pytest.approx(-0.5 * (d * math.log(2 * math.pi) + logdet + d2))


@pytest.mark.parametrize("d", [1, 2, 3])
def test_a_covariance_that_is_not_positive_definite_is_flagged(d: int) -> None:
    kernels = compiled.kalman_kernels()
    assert kernels is not None
    n = 4
    # S = H P H^T + R = -I.
    *_, positive = _one_update(
        kernels, np.zeros(n), np.zeros((n, n)), np.zeros(d), np.eye(d, n), -np.eye(d)
    )
    assert not positive


def test_the_switch_turns_the_kernels_off(monkeypatch: pytest.MonkeyPatch) -> None:
    assert compiled.kalman_kernels() is not None
    monkeypatch.setenv(compiled.COMPILED_SWITCH, "0")
    assert compiled.kalman_kernels() is None
    monkeypatch.setenv(compiled.COMPILED_SWITCH, "1")
    assert compiled.kalman_kernels() is not None


@pytest.mark.parametrize("family", ["crossing", "two_sensors", "turning"])
def test_a_tracks_filter_run_is_the_numpy_run(family: str, monkeypatch: pytest.MonkeyPatch) -> None:
    scenario = build_scenario(family, seed=0)
    scans = scenario.scans[:40]
    rows = np.concatenate([scan.rows for scan in scans])
    origins = scenario.origins
    origin = dict(zip(origins.rows.tolist(), origins.target_ids.tolist(), strict=True))
    true_rows: dict[int, list[int]] = {}
    for row in rows.tolist():
        if origin.get(row, -1) >= 0:
            true_rows.setdefault(origin[row], []).append(row)
    backends: dict[str, list[str]] = {"1": [], "0": []}
    filter_path = Refiltering.filter_path
    runs = {}
    for switch in ("1", "0"):

        def spy(self: Refiltering, state: object, path: tuple, switch: str = switch) -> object:
            backends[switch].append(compiled.filter_backend().__name__)
            return filter_path(self, state, path)  # type: ignore[arg-type]

        monkeypatch.setattr(Refiltering, "filter_path", spy)
        monkeypatch.setenv(compiled.COMPILED_SWITCH, switch)
        objective = RecordingObjective(config=scenario.config, scans=scans)  # fresh cache
        paths = paths_from_rows(objective, true_rows)
        # Whole tracks and pieces starting part-way (their first steps initiate).
        pieces = [p for path in paths.values() for p in (path, path[len(path) // 2 :])]
        runs[switch] = [objective.trajectory(p) for p in pieces if p]
    assert len(runs["1"]) >= 4
    # Linear motion: the backend's run took over (the kernel with the switch on, its numpy
    # twin with it off); coordinated turn: never.
    assert (len(backends["1"]) > 0) == (family != "turning")
    assert set(backends["1"]) <= {"mapassoc.filtering.compiled_kernels"}
    assert set(backends["0"]) <= {"mapassoc.filtering.scan_steps"}
    assert len(backends["0"]) == len(backends["1"])
    for fast, plain in zip(runs["1"], runs["0"], strict=True):
        assert fast.path == plain.path
        np.testing.assert_array_equal(fast.initiated, plain.initiated)
        np.testing.assert_allclose(fast.values, plain.values, rtol=1e-9, atol=1e-9)
        assert fast.value == pytest.approx(plain.value, rel=1e-9, abs=1e-9)
        for a, b in zip(fast.means, plain.means, strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)
        for a, b in zip(fast.covariances, plain.covariances, strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)


def test_kernels_compile_once_before_any_window(monkeypatch: pytest.MonkeyPatch) -> None:
    """load_kernels (which the estimator calls before a window's clock starts) compiles
    each kernel for the argument types the package passes: a run adds no other
    compiled version (which would be compiled inside a window, on its time)."""
    monkeypatch.setenv(compiled.COMPILED_SWITCH, "0")
    assert all(compiled_module(name) is None for name in KERNEL_MODULES)
    monkeypatch.setenv(compiled.COMPILED_SWITCH, "1")
    load_kernels()
    modules = [compiled_module(name) for name in KERNEL_MODULES]
    assert all(module is not None for module in modules)
    kernels = [
        getattr(module, name)
        for module in modules
        for name in ("exact_search", "filter_along_path", "continue_along_references")
        if hasattr(module, name)
    ]
    assert len(kernels) == 3
    before = [len(kernel.signatures) for kernel in kernels]
    assert min(before) >= 1
    scenario = build_scenario("parallel", seed=0)
    config = dataclasses.replace(
        scenario.config,
        estimator=dataclasses.replace(scenario.config.estimator, window_length=4),
    )
    WindowEstimator(config=config).run(scenario.scans[:12])
    assert [len(kernel.signatures) for kernel in kernels] == before
