"""``mapassoc bench-reprocess``: throughput and memory of reprocessing, as numbers.

Three measurements, each ``mapassoc`` command in a child process (so that its wall time
and peak memory are its own, read with :func:`os.wait4`):

1. **batch**: ``R`` simulated recordings of ``S`` scans (crossing, dense, turning, ...)
   with ``batch --jobs 1`` (one after the other) and ``batch --jobs N`` (the local
   pool): wall time, scans per second, the speed-up, and whether both wrote the same
   files;
2. **long recording**: one recording of ``L`` scans with ``run``: wall time, scans per
   second and peak resident memory;
3. **segments**: per family, a recording of ``M`` scans with ``run`` and with
   ``run --segments N --jobs N``: the speed-up, GOSPA of both against the truth, and how
   many tracks are the same.

Numbers on shared machines are noisy: the variants of each measurement run one after
the other in the same session.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from mapassoc.apps.workers import check_jobs
from mapassoc.errors import InputError

__all__ = ["ChildRun", "run_child", "run_reprocess_benchmark"]

BATCH_FAMILIES = ("crossing", "dense", "turning")
RESULT_FILES = ("tracks.csv", "associations.csv", "windows.jsonl", "summary.json")


@dataclass(frozen=True)
class ChildRun:
    """Wall time and peak resident memory of one child command."""

    seconds: float
    max_rss_mb: float


def run_child(arguments: Sequence[str]) -> ChildRun:
    """Run ``mapassoc ARGUMENTS`` in a child process; raise unless it exits with 0."""
    command = [sys.executable, "-m", "mapassoc.apps.cli", *arguments]
    started = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    assert process.stderr is not None
    err = process.stderr.read().decode("utf-8", "replace")
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    seconds = time.perf_counter() - started
    if process.returncode != 0:
        raise InputError(f"`mapassoc {' '.join(arguments)}` failed: {err.strip()[-500:]}")
    # ru_maxrss is in KiB on Linux; a pool's workers are grandchildren, not counted here.
    return ChildRun(seconds, usage.ru_maxrss / 1024.0)


STARTUP_GOAL_SECONDS = 0.5
"""Start-up goal of the command line: every command, even ``--help``, pays it."""


def startup_times(repeats: int = 5) -> dict[str, float]:
    """Wall time of ``mapassoc --help`` and ``mapassoc scenarios`` (median and max of
    ``repeats`` child processes each), printed next to the goal."""
    out: dict[str, float] = {}
    print(f"start-up (goal < {STARTUP_GOAL_SECONDS} s), median / max of {repeats} runs:")
    for label, arguments in (("--help", ["--help"]), ("scenarios", ["scenarios"])):
        seconds = sorted(run_child(arguments).seconds for _ in range(repeats))
        out[f"{label} median"], out[f"{label} max"] = seconds[len(seconds) // 2], seconds[-1]
        met = "met" if seconds[len(seconds) // 2] < STARTUP_GOAL_SECONDS else "NOT met"
        print(f"  mapassoc {label:10s} {seconds[len(seconds) // 2]:.3f} / {seconds[-1]:.3f} s"
              f"  ({met})")
    return out


def _same_folders(a: Path, b: Path, names: Sequence[str]) -> bool:
    return all(
        (a / name / file).read_bytes() == (b / name / file).read_bytes()
        for name in names
        for file in RESULT_FILES
    )


def _gospa(tracks: Path, truth: Path) -> float:
    from mapassoc.data.io import read_tracks, read_truth
    from mapassoc.evaluation.tables import evaluate_tables

    return evaluate_tables(read_truth(truth), read_tracks(tracks), c=10.0).gospa.mean_total


def _track_sets(tracks: Path) -> set[tuple[int, ...]]:
    from mapassoc.data.io import read_tracks

    table = read_tracks(tracks)
    rows: dict[int, list[int]] = {}
    for tid, row in zip(table.track_ids.tolist(), table.detection_rows.tolist(), strict=True):
        if row >= 0:
            rows.setdefault(tid, []).append(row)
    return {tuple(sorted(r)) for r in rows.values()}


def run_reprocess_benchmark(
    *,
    recordings: int = 6,
    scans: int = 300,
    long_scans: int = 10_000,
    long_family: str = "crossing",
    segment_families: Sequence[str] = ("crossing", "dense"),
    segment_scans: int = 1000,
    jobs: int | None = None,
    out: str | os.PathLike[str] | None = None,
) -> dict[str, object]:
    """Run the three measurements (module docstring), print them, return the numbers."""
    _check_sizes(
        recordings=recordings, scans=scans, long_scans=long_scans, segment_scans=segment_scans
    )
    workers = check_jobs(jobs)
    results: dict[str, object] = {"jobs": workers, "startup": startup_times()}
    with tempfile.TemporaryDirectory(prefix="mapassoc-bench-") as scratch:
        root = Path(out) if out is not None else Path(scratch)
        root.mkdir(parents=True, exist_ok=True)
        if recordings:
            results["batch"] = _measure_batch(root, recordings, scans, workers)
        if long_scans:
            results["long"] = _measure_long_recording(root, long_family, long_scans)
        if segment_scans and segment_families:
            print(
                f"segments: {segment_scans} scans, sequential vs --segments {workers} "
                f"--jobs {workers}"
            )
        segments_out = {
            family: _measure_segments(root, family, segment_scans, workers)
            for family in (segment_families if segment_scans else ())
        }
        if segments_out:
            results["segments"] = segments_out
    return results


def _check_sizes(**sizes: object) -> None:
    """Raise unless every size is an integer >= 0 (the message names it)."""
    for name, value in sizes.items():
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise InputError(f"{name} must be an integer >= 0, got {value!r}")


def _simulate_recordings(source: Path, recordings: int, scans: int) -> list[str]:
    """Simulate ``recordings`` recordings of ``scans`` scans into ``source``, cycling
    through :data:`BATCH_FAMILIES` with a new seed each round; their folder names."""
    names = []
    for i in range(recordings):
        family = BATCH_FAMILIES[i % len(BATCH_FAMILIES)]
        seed = str(i // len(BATCH_FAMILIES))
        name = f"{family}-{seed}"
        run_child(
            ["simulate", family, "--scans", str(scans), "--seed", seed,
             "--out", str(source / name), "--overwrite"]
        )  # fmt: skip
        names.append(name)
    return names


def _measure_batch(root: Path, recordings: int, scans: int, workers: int) -> dict[str, object]:
    """Measurement 1: ``batch --jobs 1`` against ``batch --jobs N`` on simulated recordings."""
    source = root / "recordings"
    names = _simulate_recordings(source, recordings, scans)
    total = recordings * scans
    timing = {}
    for label, n in (("sequential", 1), ("pool", workers)):
        folder = root / f"batch-{label}"
        timing[label] = run_child(
            ["batch", str(source), "--out", str(folder), "--jobs", str(n), "--no-timings",
             "--no-progress", "--overwrite"]
        )  # fmt: skip
    same = _same_folders(root / "batch-sequential", root / "batch-pool", names)
    speedup = timing["sequential"].seconds / timing["pool"].seconds
    print(f"batch: {recordings} recordings x {scans} scans ({', '.join(BATCH_FAMILIES)})")
    for label in ("sequential", "pool"):
        t = timing[label].seconds
        print(f"  {label:10s} {t:7.1f} s  {total / t:7.1f} scans/s")
    print(f"  pool of {workers}: x{speedup:.2f}; same files: {same}")
    return {
        "recordings": recordings,
        "scans_each": scans,
        "same_files": same,
        "speedup": speedup,
        **{f"{k}_seconds": v.seconds for k, v in timing.items()},
    }


def _measure_long_recording(root: Path, family: str, scans: int) -> dict[str, object]:
    """Measurement 2: ``run`` on one long recording: wall time and peak memory."""
    scen = root / "long"
    run_child(
        ["simulate", family, "--scans", str(scans), "--seed", "0", "--out", str(scen),
         "--overwrite"]
    )  # fmt: skip
    child = run_child(
        ["run", str(scen / "config.toml"), str(scen / "detections.csv"),
         "--out", str(root / "long-run"), "--no-progress", "--overwrite"]
    )  # fmt: skip
    with open(scen / "detections.csv") as lines:
        detections = sum(1 for _ in lines) - 1
    print(f"long recording: {family}, {scans} scans, {detections} lines")
    print(
        f"  {child.seconds:7.1f} s  {scans / child.seconds:7.1f} scans/s  "
        f"peak memory {child.max_rss_mb:.0f} MB"
    )
    return {
        "family": family,
        "scans": scans,
        "seconds": child.seconds,
        "max_rss_mb": child.max_rss_mb,
    }


def _measure_segments(root: Path, family: str, scans: int, workers: int) -> dict[str, object]:
    """Measurement 3 for one family: ``run`` against ``run --segments N --jobs N``."""
    scen = root / f"seg-{family}"
    run_child(
        ["simulate", family, "--scans", str(scans), "--seed", "0", "--out", str(scen),
         "--overwrite"]
    )  # fmt: skip
    runs = {}
    for label, extra in (
        ("sequential", []),
        ("segments", ["--segments", str(max(2, workers)), "--jobs", str(workers)]),
    ):
        folder = root / f"seg-{family}-{label}"
        runs[label] = run_child(
            ["run", str(scen / "config.toml"), str(scen / "detections.csv"),
             "--out", str(folder), "--no-progress", "--overwrite", *extra]
        )  # fmt: skip
    tracks = {label: root / f"seg-{family}-{label}" / "tracks.csv" for label in runs}
    sets = {label: _track_sets(path) for label, path in tracks.items()}
    gospa = {label: _gospa(path, scen / "truth.csv") for label, path in tracks.items()}
    speedup = runs["sequential"].seconds / runs["segments"].seconds
    same_tracks = len(sets["sequential"] & sets["segments"])
    print(
        f"  {family:10s} x{speedup:.2f}  GOSPA {gospa['segments']:.3f} vs "
        f"{gospa['sequential']:.3f}  same tracks {same_tracks} of "
        f"{len(sets['sequential'])} ({len(sets['segments'])} stitched)"
    )
    return {
        "speedup": speedup,
        "gospa": gospa,
        "same_tracks": same_tracks,
        "tracks": {k: len(v) for k, v in sets.items()},
    }
