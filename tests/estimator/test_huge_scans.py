"""Scans far larger than a window usually sees: nothing may hit a recursion or size limit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from support import SENSOR, make_config

from mapassoc.data.scans import Scan
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.models.motion import ConstantVelocity


@pytest.mark.slow
def test_a_scan_of_thousands_of_detections_followed_by_another_runs() -> None:
    """One scan of 3,000 detections, then another (20,000 once raised a RecursionError;
    that size now runs in about 30 s on this machine, mostly combining 20,000
    clusters, so the suite uses 3,000).

    The detections lie on a grid with gaps much wider than the gate, plus a few
    near-coincident pairs, so most hypotheses are alone and some clusters interact;
    Kmax is huge and must cost nothing beyond the feasible number of tracks.
    """
    rng = np.random.default_rng(0)
    side = 55
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), axis=-1).reshape(-1, 2)
    first = (grid[:3_000] * 100.0 + rng.normal(0.0, 1.0, size=(3_000, 2))).astype(float)
    second = first + rng.normal(0.0, 1.0, size=first.shape) + np.array([1.0, 0.0])
    config = make_config(
        motion=ConstantVelocity(ndim=2, noise_intensity=0.01),
        noise_std=1.0,
        detection_probability=0.9,
        false_alarms_per_scan=100.0,
        region=[[-100.0, 5_600.0], [-100.0, 5_600.0]],
        rate=0.5,
        max_tracks=10**6,
        window_length=2,
        gate_probability=0.999,
        prune_log_ratio=9.0,
        max_hypotheses_per_tree=64,
    )
    scans = [
        Scan(0.0, SENSOR, first, np.arange(2, 3_002)),
        Scan(1.0, SENSOR, second, np.arange(3_002, 6_002)),
    ]
    # Combining thousands of clusters is not interruptible yet: give it the time.
    config = replace(config, estimator=replace(config.estimator, time_limit=120.0))
    estimator = WindowEstimator(config=config)
    window = estimator.solve_window(scans)
    assert window.posterior.max_tracks == 10**6
    # The arrays stop where p(K | Z) provably ends (k_posterior), far below Kmax.
    assert window.posterior.probabilities.shape[0] < 10**5
    assert abs(window.posterior.probabilities.sum() - 1.0) < 1e-9
    assert window.status in ("exact", "capped")
    # Each grid point is a pair of detections one scan apart: most become tracks.
    assert window.posterior.marginal_k > 2_000
    tracks = window.posterior.marginal_tracks
    assert tracks <= window.posterior.marginal_k
    chosen = window.selection(tracks)
    assert window.problem.is_feasible(chosen, tracks)


def test_a_huge_max_tracks_costs_nothing_per_window() -> None:
    """Kmax = 10^6 on the crossing scenario: every window reports p_k_length = 10^6 + 1
    but stores and writes only the K with p(K | Z) above 1e-300, with the same posterior
    as a Kmax that is just large enough."""
    from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario

    scenario = truncate_scenario(build_scenario("crossing", 0), 10)

    def run(kmax: int):  # type: ignore[no-untyped-def]
        # Under the birth prior Kmax only truncates p(K) (a uniform prior on 0..Kmax is a
        # different prior for every Kmax).
        estimator = replace(scenario.config.estimator, max_tracks=kmax, k_prior="birth")
        config = replace(scenario.config, estimator=estimator)
        return WindowEstimator(config=config).run(scenario.scans)

    huge, fitted = run(10**6), run(120)
    for a, b in zip(huge.windows, fitted.windows, strict=True):
        line = a.to_json(timings=False)
        assert line["p_k_length"] == 10**6 + 1
        assert len(a.p_k) < 100 and len(line["p_k"]) < 100  # type: ignore[arg-type]
        n = len(a.p_k)
        np.testing.assert_allclose(a.p_k, b.p_k[:n], atol=1e-12)
        assert np.all(b.p_k[n:] < 1e-300)
        assert a.marginal_k == b.marginal_k and a.chosen_k == b.chosen_k


@pytest.mark.slow
def test_a_huge_exact_work_limit_runs_as_the_default_does() -> None:
    """exact_work_limit = 2**62 (the compiled search counts work in int64) once made the
    windows with a carried track "infeasible" (no K in 0..Kmax had a feasible track
    set); it gives the default's result where the default suffices."""
    from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario

    scenario = truncate_scenario(build_scenario("crossing", 0), 12)

    def run(limit: int):  # type: ignore[no-untyped-def]
        estimator = replace(scenario.config.estimator, exact_work_limit=limit, refine_passes=0)
        config = replace(scenario.config, estimator=estimator)
        return WindowEstimator(config=config).run(scenario.scans)

    default, huge = run(scenario.config.estimator.exact_work_limit), run(2**62)
    assert huge.track_rows == default.track_rows
    assert default.track_rows
    for a, b in zip(huge.windows, default.windows, strict=True):
        assert a.to_json(timings=False) == b.to_json(timings=False)


@pytest.mark.slow
def test_the_confidence_pass_memory_grows_with_the_kept_hypotheses() -> None:
    """The confidence step once held a hypotheses x detections array (a 147,677 x 40,020
    one, 5.5 GiB, on a scan of 40,000 detections): its peak memory must grow with
    what the window keeps, under 2 KiB per kept hypothesis here (the dense array
    alone would be 4 KiB per hypothesis at 4,000 detections, and more with more)."""
    import tracemalloc

    from mapassoc.estimator.refinement import RefinementSettings, Refiner

    def refiner_of(n: int) -> Refiner:
        side = int(np.ceil(np.sqrt(n)))
        rng = np.random.default_rng(0)
        grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), axis=-1).reshape(-1, 2)
        first = grid[:n] * 100.0 + rng.normal(0.0, 1.0, size=(n, 2))
        second = first + rng.normal(0.0, 1.0, size=first.shape) + np.array([1.0, 0.0])
        config = make_config(
            motion=ConstantVelocity(ndim=2, noise_intensity=0.01),
            noise_std=1.0,
            detection_probability=0.9,
            false_alarms_per_scan=100.0,
            region=[[-100.0, side * 100.0], [-100.0, side * 100.0]],
            rate=0.5,
            window_length=2,
            gate_probability=0.999,
            prune_log_ratio=9.0,
            max_hypotheses_per_tree=64,
        )
        scans = [
            Scan(0.0, SENSOR, first, np.arange(n)),
            Scan(1.0, SENSOR, second, np.arange(n, 2 * n)),
        ]
        return Refiner(config=config, scans=scans, settings=RefinementSettings())

    refiner_of(20).confidence({0: ((0, 0), (1, 0))})  # imports and compiled kernels loaded
    n = 2_000
    refiner = refiner_of(n)
    tracks = {t: ((0, t), (1, t)) for t in range(0, n, 100)}
    values = refiner._exact_values(tracks)
    hyps = refiner.boundaries.hypotheses(tracks, values, 0, 2, refiner.generator)[0]
    assert hyps.detections.count == 2 * n and hyps.count >= 2 * n
    tracemalloc.start()
    try:
        sure = refiner.confidence(tracks)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert 2048 * hyps.count < hyps.count * hyps.detections.count  # the dense array, bytes
    assert peak < 2048 * hyps.count
    assert sure.exact and set(sure.existence) == set(tracks)
    assert all(0.5 < p <= 1.0 for p in sure.existence.values())


_BURST_RUN = """
import json, resource, sys
limit = int(sys.argv[1])
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
import numpy as np
from mapassoc.data.scans import Scan
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario
n, length, at = (int(a) for a in sys.argv[2:5])
scenario = truncate_scenario(build_scenario("crossing", 1), length)
scans = list(scenario.scans)
region = scenario.config.sensors[scans[at].sensor].region
clutter = np.random.default_rng(1).uniform(region.lower, region.upper, size=(n, region.lower.size))
first = max(int(s.rows.max()) for s in scans if s.rows.size) + 1
burst = scans[at]
scans[at] = Scan(
    burst.time,
    burst.sensor,
    np.vstack([burst.detections, clutter]),
    np.r_[burst.rows, first + np.arange(n)],
)
result = WindowEstimator(config=scenario.config).run(scans)
sure = result.confidence
print(json.dumps({"tracks": len(result.track_rows), "windows": len(result.windows),
                  "exact": sure.exact, "existence": sorted(sure.existence.values())}))
"""


@pytest.mark.slow
def test_a_recording_with_a_clutter_burst_runs_in_bounded_memory() -> None:
    """One scan of 20,000 uniform clutter detections in ten scans of the crossing
    scenario, the whole run (forward pass, refinement, confidence) under a 1.2 GiB
    address-space cap in a subprocess.  The confidence window holds one cluster of about
    200,000 hypotheses spanning thousands of resources; its beam once stored frontiers
    as integers as wide as those spans and needed more than the cap (1.0 GB resident);
    it now needs about 0.6 GB."""
    import json
    import os
    import subprocess
    import sys

    env = dict(os.environ)
    # One thread per pool and few malloc arenas: the address space is then the heap,
    # not per-thread reservations that vary with the machine's cores.
    for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        env[name] = "1"
    env["NUMBA_NUM_THREADS"] = "1"
    env["MALLOC_ARENA_MAX"] = "2"
    cap = int(1.2 * 2**30)
    done = subprocess.run(
        [sys.executable, "-c", _BURST_RUN, str(cap), "20000", "10", "5"],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["windows"] == 6 and out["tracks"] >= 2
    assert not out["exact"]  # the burst's cluster went to the beam
    # The crossing targets' tracks stay sure of themselves through the burst.
    assert all(0.9 < p <= 1.0 for p in out["existence"])
