"""``mapassoc batch``: recordings found, failures isolated, resume skips, pool and Dask."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mapassoc.apps.batch import (
    BATCH_SUMMARY_NAME,
    SUMMARY_COLUMNS,
    Recording,
    find_recordings,
    run_batch,
)
from mapassoc.apps.cli import main
from mapassoc.apps.run_folders import read_manifest
from mapassoc.apps.runs import RunOptions, run_files
from mapassoc.errors import InputError, OutputError

RESULT_FILES = ("tracks.csv", "associations.csv", "windows.jsonl", "summary.json")
QUIET = RunOptions(timings=False)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two simulated recordings with their own configs, one on the shared config, one broken."""
    root = tmp_path_factory.mktemp("recordings")
    # 30 scans: what is tested is the batch's bookkeeping, not the tracking.
    for name, family, seed in (("alpha", "crossing", "0"), ("beta", "turning", "1")):
        simulate = ["simulate", family, "--out", str(root / name), "--seed", seed, "--scans", "30"]
        assert main(simulate) == 0
    for name in ("alpha", "beta"):  # the tests compare batch and single runs byte for byte
        _no_time_limit(root / name / "config.toml")
    for name in ("truth.csv", "origins.csv"):
        (root / "alpha" / name).unlink()
    # A flat file on the shared config (crossing's), and a broken one beside it.
    shutil.copy(root / "alpha" / "detections.csv", root / "gamma.csv")
    lines = (root / "alpha" / "detections.csv").read_text().splitlines()
    cells = lines[3].split(",")
    cells[2] = "nan"
    lines[3] = ",".join(cells)
    (root / "broken.csv").write_text("\n".join(lines) + "\n")
    (root / "notes.txt").write_text("not a recording")
    return root


def _summary(out: Path) -> list[dict[str, str]]:
    with open(out / BATCH_SUMMARY_NAME, newline="") as handle:
        reader = csv.DictReader(handle)
        assert tuple(reader.fieldnames or ()) == SUMMARY_COLUMNS
        return list(reader)


def _no_time_limit(config: Path) -> None:
    """A time limit no window reaches: the windows the wall clock cuts short (status
    time_limit) differ from run to run under load, and these tests compare bytes."""
    text = config.read_text()
    assert "time_limit = 2.0" in text
    config.write_text(text.replace("time_limit = 2.0", "time_limit = 600.0"))


def test_find_recordings_of_a_folder(recordings: Path) -> None:
    found = find_recordings(recordings)
    assert [r.name for r in found] == ["alpha", "beta", "broken", "gamma"]
    by_name = {r.name: r for r in found}
    assert by_name["alpha"].config == recordings / "alpha" / "config.toml"
    assert by_name["gamma"].config is None and by_name["gamma"].detections.name == "gamma.csv"


def test_find_recordings_of_a_list(recordings: Path, tmp_path: Path) -> None:
    listing = tmp_path / "list.csv"
    listing.write_text(
        f"name,detections,config\none,{recordings}/alpha/detections.csv,\n"
        f"two,{recordings}/beta/detections.csv,{recordings}/beta/config.toml\n"
    )
    found = find_recordings(listing)
    assert found == [
        Recording("one", recordings / "alpha" / "detections.csv", None),
        Recording("two", recordings / "beta" / "detections.csv",
                  recordings / "beta" / "config.toml"),
    ]
    listing.write_text("name,detections\none,a.csv\none,b.csv\n")
    with pytest.raises(InputError, match="'one' appears twice"):
        find_recordings(listing)
    listing.write_text("name,path\none,a.csv\n")
    with pytest.raises(Exception, match="expected name,detections"):
        find_recordings(listing)


def test_a_failing_recording_is_isolated_and_resume_skips_the_rest(
    recordings: Path, tmp_path: Path
) -> None:
    out = tmp_path / "batch"
    shared = recordings / "alpha" / "config.toml"
    rows = run_batch(find_recordings(recordings), out, shared_config=shared, options=QUIET,
                     jobs=2, progress=False)
    status = {row["name"]: row["status"] for row in rows}
    assert status == {"alpha": "complete", "beta": "complete", "broken": "failed",
                      "gamma": "complete"}
    broken = next(row for row in rows if row["name"] == "broken")
    assert "broken.csv" in str(broken["error"]) and "nan" in str(broken["error"]).lower()
    assert not (out / "broken").exists()
    # Each recording's folder is what a run of it alone writes.
    alone = tmp_path / "alone"
    run_files(shared, recordings / "gamma.csv", alone, RunOptions(timings=False, progress=False))
    for name in RESULT_FILES:
        assert (out / "gamma" / name).read_bytes() == (alone / name).read_bytes()
    # alpha and gamma are the same recording with the same config.
    tracks = {name: (out / name / "tracks.csv").read_bytes() for name in ("alpha", "gamma")}
    assert tracks["alpha"] == tracks["gamma"]
    table = _summary(out)
    assert [row["name"] for row in table] == ["alpha", "beta", "broken", "gamma"]
    beta = next(row for row in table if row["name"] == "beta")
    assert int(beta["scans"]) == 30 and int(beta["tracks"]) >= 1 and float(beta["seconds"]) > 0
    assert float(beta["scans_per_second"]) > 0

    # Without --resume or --overwrite a used batch folder is refused.
    with pytest.raises(OutputError, match="not empty; pass --resume"):
        run_batch(find_recordings(recordings), out, shared_config=shared, options=QUIET,
                  jobs=1, progress=False)
    stamps = {name: (out / name / "manifest.json").stat().st_mtime_ns
              for name in ("alpha", "beta", "gamma")}
    rows = run_batch(find_recordings(recordings), out, shared_config=shared,
                     options=RunOptions(timings=False, resume=True), jobs=1, progress=False)
    status = {row["name"]: row["status"] for row in rows}
    assert status == {"alpha": "skipped", "beta": "skipped", "broken": "failed",
                      "gamma": "skipped"}
    assert stamps == {name: (out / name / "manifest.json").stat().st_mtime_ns
                      for name in ("alpha", "beta", "gamma")}


def test_a_recording_without_any_config_fails_alone(recordings: Path, tmp_path: Path) -> None:
    rows = run_batch(
        [Recording("gamma", recordings / "gamma.csv", None),
         Recording("alpha", recordings / "alpha" / "detections.csv",
                   recordings / "alpha" / "config.toml")],
        tmp_path / "b", options=QUIET, jobs=1, progress=False,
    )  # fmt: skip
    assert [row["status"] for row in rows] == ["failed", "complete"]
    assert "no shared --config" in str(rows[0]["error"])


def test_cli_batch_exits_1_when_a_recording_failed(
    recordings: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cli"
    code = main(["batch", str(recordings), "--out", str(out), "--config",
                 str(recordings / "alpha" / "config.toml"), "--jobs", "1", "--no-timings"])
    assert code == 1
    captured = capsys.readouterr()
    assert "4 recordings: 3 complete, 1 failed" in captured.out
    assert "broken: failed" in captured.err


@pytest.mark.slow
def test_batch_on_a_dask_local_cluster(recordings: Path, tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        out = tmp_path / "dask"
        rows = run_batch(find_recordings(recordings), out,
                         shared_config=recordings / "alpha" / "config.toml", options=QUIET,
                         scheduler=cluster.scheduler_address, progress=False)
    status = {row["name"]: row["status"] for row in rows}
    assert status == {"alpha": "complete", "beta": "complete", "broken": "failed",
                      "gamma": "complete"}
    local = tmp_path / "local"
    run_batch(find_recordings(recordings), local,
              shared_config=recordings / "alpha" / "config.toml", options=QUIET, jobs=1,
              progress=False)
    for name in ("alpha", "beta", "gamma"):
        for file in RESULT_FILES:
            assert (out / name / file).read_bytes() == (local / name / file).read_bytes()


@pytest.mark.slow
def test_an_interrupted_batch_resumes_to_the_same_folders(tmp_path: Path) -> None:
    """SIGINT stops every worker at a window boundary (exit 130); --resume finishes."""
    source = tmp_path / "source"
    for seed in range(3):
        assert main(["simulate", "dense", "--out", str(source / f"p{seed}"),
                     "--seed", str(seed), "--scans", "30"]) == 0
        _no_time_limit(source / f"p{seed}" / "config.toml")
    out = tmp_path / "out"
    command = [sys.executable, "-m", "mapassoc.apps.cli", "batch", str(source), "--out",
               str(out), "--jobs", "2", "--no-timings", "--checkpoint-seconds", "0"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    # SIGINT once a worker has committed a window (not after a fixed sleep: under load
    # the workers' start-up alone can take that long), with two of the three recordings
    # still to finish.
    deadline = time.monotonic() + 120
    while not any(path.stat().st_size for path in out.glob("*.partial/windows.jsonl")):
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, "no worker committed a window in 120 s"
        time.sleep(0.02)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    assert "recordings; the batch so far is in" in err and "--resume" in err
    table = _summary(out)
    assert {row["status"] for row in table} <= {"interrupted", "pending", "complete"}
    assert any(row["status"] != "complete" for row in table)
    assert main(["batch", str(source), "--out", str(out), "--jobs", "2", "--no-timings",
                 "--resume", "--no-progress"]) == 0
    assert {row["status"] for row in _summary(out)} <= {"complete", "skipped"}
    for seed in range(3):
        alone = tmp_path / f"alone{seed}"
        run_files(
            source / f"p{seed}" / "config.toml",
            source / f"p{seed}" / "detections.csv",
            alone,
            RunOptions(timings=False, progress=False),
        )
        manifest = read_manifest(out / f"p{seed}")
        assert manifest is not None and manifest["status"] == "complete"
        for name in RESULT_FILES:
            assert (out / f"p{seed}" / name).read_bytes() == (alone / name).read_bytes()


@pytest.mark.parametrize("options", [["--overwrite"], ["--resume"], []])
def test_a_batch_folder_holding_its_recordings_is_refused(
    recordings: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], options: list[str]
) -> None:
    """`mapassoc batch recs --out recs --overwrite` once deleted every recording: an
    --out that is (or holds) the source is refused before anything runs, and a parent of
    the source too; every input stays byte for byte."""
    source = tmp_path / "recs"
    shutil.copytree(recordings / "alpha", source / "alpha")
    shutil.copy(recordings / "gamma.csv", source / "gamma.csv")
    before = {p: p.read_bytes() for p in source.rglob("*") if p.is_file()}
    for out in (source, tmp_path):
        code = main(["batch", str(source), "--out", str(out), "--config",
                     str(source / "alpha" / "config.toml"), "--jobs", "1", *options])
        assert code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "holds the input" in err and str(out) in err
    assert {p: p.read_bytes() for p in source.rglob("*") if p.is_file()} == before
    assert not (source / BATCH_SUMMARY_NAME).exists()


def test_a_batch_takes_run_options_but_not_segments(tmp_path: Path) -> None:
    recording = Recording("one", tmp_path / "one.csv", None)
    with pytest.raises(InputError, match="options.segments must be 1 in a batch"):
        run_batch([recording], tmp_path / "out", options=RunOptions(segments=2), progress=False)
    with pytest.raises(InputError, match="options must be a RunOptions"):
        run_batch(
            [recording], tmp_path / "out", options={"timings": False}, progress=False  # type: ignore[arg-type]
        )
    assert not (tmp_path / "out").exists()  # refused before anything was written


# ------------------------------------------------------------ the batch folder's rule


def _one_recording(recordings: Path, tmp_path: Path) -> Path:
    source = tmp_path / "recs"
    shutil.copytree(recordings / "alpha", source / "alpha")
    return source


def _files(folder: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.mark.parametrize("options", [["--overwrite"], ["--resume"], []])
def test_a_users_folder_with_a_batch_summary_is_never_written(
    recordings: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], options: list[str]
) -> None:
    """`batch recs --out b --overwrite`, b a folder of the user's holding a
    batch_summary.csv of their own: refused in one line before anything runs."""
    source = _one_recording(recordings, tmp_path)
    out = tmp_path / "b"
    out.mkdir()
    (out / BATCH_SUMMARY_NAME).write_text("name,score\nmine,1\n")
    (out / "notes.txt").write_text("keep")
    before = _files(out)
    code = main(["batch", str(source), "--out", str(out), "--jobs", "1", "--no-progress",
                 *options])  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(out) in err
    assert "not a mapassoc batch folder" in err
    assert _files(out) == before and sorted(p.name for p in out.iterdir()) == [
        BATCH_SUMMARY_NAME, "notes.txt"]  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b", "recs"]


def test_a_batch_folder_is_marked_and_an_unmarked_one_of_before_still_resumes(
    recordings: Path, tmp_path: Path
) -> None:
    source = _one_recording(recordings, tmp_path)
    out = tmp_path / "b"
    options = RunOptions(timings=False, progress=False)
    run_batch(find_recordings(source), out, options=options, jobs=1, progress=False)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["format"] == "mapassoc-batch/1" and manifest["status"] == "complete"
    assert manifest["ended"] >= manifest["started"]
    # A batch folder of the version before, which wrote no manifest: resumed as before.
    (out / "manifest.json").unlink()
    again = RunOptions(timings=False, progress=False, resume=True)
    rows = run_batch(find_recordings(source), out, options=again, jobs=1, progress=False)
    assert [row["status"] for row in rows] == ["skipped"]
    assert json.loads((out / "manifest.json").read_text())["format"] == "mapassoc-batch/1"
    # --overwrite runs it again, into the same folder.
    again = RunOptions(timings=False, progress=False, overwrite=True)
    rows = run_batch(find_recordings(source), out, options=again, jobs=1, progress=False)
    assert [row["status"] for row in rows] == ["complete"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b", "recs"]  # no lock left


def test_a_second_batch_into_the_same_folder_is_refused_at_once(
    recordings: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two batches into one folder used to fail each other's recordings; the second is
    now refused before it runs anything, naming the first one's pid."""
    from mapassoc.apps.run_folders import take_lock

    source = _one_recording(recordings, tmp_path)
    out = tmp_path / "b"
    args = ["batch", str(source), "--out", str(out), "--jobs", "1", "--no-progress"]
    held = take_lock(out, out, noun="batch")  # what a batch in another process holds
    try:
        for options in ([], ["--resume"], ["--overwrite"]):
            assert main([*args, *options]) == 2
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and str(out) in err
            assert f"another mapassoc batch (pid {os.getpid()}) is writing it" in err
        assert not out.exists()
    finally:
        held[1].close()  # the holder dies: its lock file stays, its flock goes
    assert (tmp_path / ".b.lock").exists()
    assert main(args) == 0
    assert [row["status"] for row in _summary(out)] == ["complete"]
    assert not (tmp_path / ".b.lock").exists()
