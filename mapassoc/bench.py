"""``mapassoc bench``: speed and accuracy on seeded standard scenarios.

Prints, per scenario: scans per second, window time (hypothesis generation plus
solving) p50/p95, hypotheses and largest cluster per window, GOSPA with its parts
next to the oracle's; then how time per scan grows from 10 to 50 targets at fixed
density, and the throughput of batched gating + likelihood.  Numbers, not pass/fail:
the goals of the project are printed beside them.
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from mapassoc.evaluation import evaluate_tables
from mapassoc.kalman import pairwise_gate_and_loglik
from mapassoc.oracle import oracle_tracks
from mapassoc.pipeline import WindowEstimator
from mapassoc.scenarios import build_scenario

__all__ = ["run_benchmark", "bench_scenario", "bench_gating"]

GOSPA_CUTOFF = 10.0
GOALS = {
    "crossing": "goal >= 50 scans/s, GOSPA <= 1.25 x oracle",
    "dense": "goal >= 10 scans/s",
    "dense50": "time per scan at most linear in targets vs dense",
}


def bench_scenario(name: str, seed: int = 0, window_length: int | None = None) -> dict[str, object]:
    """Run one scenario with its built-in configuration (optionally another window length)."""
    scenario = build_scenario(name, seed)
    config = scenario.config
    if window_length is not None:
        settings = replace(config.estimator, window_length=window_length)
        config = replace(config, estimator=settings)
    estimator = WindowEstimator(config=config)
    start = time.perf_counter()
    result = estimator.run(scenario.scans)
    seconds = time.perf_counter() - start
    window_seconds = np.array([w.generate_seconds + w.solve_seconds for w in result.windows])
    estimate = evaluate_tables(scenario.truth, result.tracks, c=GOSPA_CUTOFF)["gospa"]
    oracle = evaluate_tables(
        scenario.truth,
        oracle_tracks(scenario.scans, scenario.origins, scenario.config),
        c=GOSPA_CUTOFF,
    )["gospa"]
    targets = len(np.unique(scenario.truth.target_ids))
    return {
        "scenario": name,
        "seed": seed,
        "targets": targets,
        "scans": len(scenario.scans),
        "detections_per_scan": float(np.mean([s.size for s in scenario.scans])),
        "window_length": config.estimator.window_length,
        "seconds": seconds,
        "scans_per_second": len(scenario.scans) / seconds,
        "seconds_per_scan": seconds / len(scenario.scans),
        "window_p50_ms": float(np.percentile(window_seconds, 50) * 1e3),
        "window_p95_ms": float(np.percentile(window_seconds, 95) * 1e3),
        "hypotheses_mean": float(np.mean([w.hypotheses for w in result.windows])),
        "hypotheses_max": int(max(w.hypotheses for w in result.windows)),
        "largest_cluster_mean": float(np.mean([w.largest_cluster for w in result.windows])),
        "largest_cluster_max": int(max(w.largest_cluster for w in result.windows)),
        "windows": len(result.windows),
        "windows_exact": int(sum(w.status == "exact" for w in result.windows)),
        "tracks": len(result.track_rows),
        "gospa": estimate,
        "oracle_gospa": oracle,
        "gospa_ratio": estimate["mean_total"] / oracle["mean_total"],  # type: ignore[operator]
    }


def bench_gating(tracks: int = 2000, detections: int = 50, repeats: int = 5) -> float:
    """(track, detection) pairs per second through batched gating + log-likelihood."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(tracks, 2, 2))
    S = A @ np.swapaxes(A, 1, 2) + np.eye(2)
    nu = rng.normal(size=(tracks, detections, 2))
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        pairwise_gate_and_loglik(nu, S)
        best = min(best, time.perf_counter() - t)
    return tracks * detections / best


def _line(r: dict[str, object]) -> str:
    g, o = r["gospa"], r["oracle_gospa"]
    return (
        f"{r['scenario']:9s} {r['targets']:4d} {r['detections_per_scan']:7.1f} "
        f"{r['scans_per_second']:8.1f} {r['window_p50_ms']:8.1f} {r['window_p95_ms']:8.1f} "
        f"{r['hypotheses_mean']:7.0f} {r['largest_cluster_max']:6d} "
        f"{r['windows_exact']:3d}/{r['windows']:<3d} "
        f"{g['mean_total']:6.2f} ({g['mean_localisation']:.2f}/{g['mean_missed']:.2f}/"  # type: ignore[index]
        f"{g['mean_false']:.2f}) {o['mean_total']:6.2f} {r['gospa_ratio']:6.2f}"  # type: ignore[index]
    )


def run_benchmark(
    *,
    scenarios: list[str],
    seed: int = 0,
    window_length: int | None = 5,
    json_path: Path | None = None,
) -> list[dict[str, object]]:
    """Run and print the benchmark; optionally write the results as JSON.

    ``window_length`` overrides the scenarios' setting (5 by default, the window of the
    project's speed goals); ``None`` keeps each scenario's own.
    """
    print(f"window length: {window_length if window_length else 'scenario default'}, seed {seed}")
    print(
        f"{'scenario':9s} {'tgts':>4s} {'det/scn':>7s} {'scans/s':>8s} {'p50 ms':>8s} "
        f"{'p95 ms':>8s} {'hyps':>7s} {'maxcl':>6s} {'exact':>7s} "
        f"{'GOSPA (loc/miss/false)':>24s} {'oracle':>6s} {'ratio':>6s}"
    )
    results = []
    for name in scenarios:
        r = bench_scenario(name, seed, window_length)
        results.append(r)
        print(_line(r) + (f"   [{GOALS[name]}]" if name in GOALS else ""), flush=True)
    by_name = {r["scenario"]: r for r in results}
    if "dense" in by_name and "dense50" in by_name:
        a, b = by_name["dense"], by_name["dense50"]
        growth = b["seconds_per_scan"] / a["seconds_per_scan"]  # type: ignore[operator]
        targets = b["targets"] / a["targets"]  # type: ignore[operator]
        print(
            f"time per scan grows {growth:.2f}x from {a['targets']} to {b['targets']} targets "
            f"({targets:.1f}x targets; linear or better means <= {targets:.1f}x)"
        )
    pairs = bench_gating()
    print(f"batched gating + likelihood: {pairs / 1e6:.1f} million (track, detection) pairs/s")
    if json_path is not None:
        json_path.write_text(
            json.dumps({"results": results, "gating_pairs_per_second": pairs}, indent=2) + "\n",
            encoding="utf-8",
        )
    return results
