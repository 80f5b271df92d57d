"""Tests of mapassoc.data.formats: dispatch on the file suffix."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from mapassoc.apps.batch import find_recordings
from mapassoc.apps.runs import RunOptions
from mapassoc.data.formats import (
    FILE_FORMATS,
    FileFormat,
    detection_formats,
    file_format,
    file_name,
    format_names,
    read_detections_file,
    read_origins_file,
    read_tracks_file,
    read_truth_file,
    sniff_format,
    write_detections_file,
    write_tracks_file,
    write_truth_file,
)
from mapassoc.data.io import (
    TrackTable,
    number_rows,
    read_detections,
    read_origins,
    read_tracks,
    read_truth,
    write_detections,
    write_origins,
    write_tracks,
    write_truth,
)
from mapassoc.data.scans import Scan
from mapassoc.errors import DataFileError, InputError
from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario
from mapassoc.evaluation.simulate import write_scenario

PARQUET_SUFFIXES = (".parquet", ".pq", ".PARQUET")


def test_known_suffixes() -> None:
    assert detection_formats() == (".csv", ".parquet", ".pq")
    assert [file_format(f"a/b{s}") for s in (".csv", ".CSV", *PARQUET_SUFFIXES)] == [
        "csv",
        "csv",
        "parquet",
        "parquet",
        "parquet",
    ]


@pytest.mark.parametrize(
    ("name", "what"),
    [("data.txt", "unknown file suffix '.txt'"), ("data", "no file suffix")],
)
def test_unknown_suffix_names_the_file_and_the_known_suffixes(
    tmp_path: Path, name: str, what: str
) -> None:
    path = tmp_path / name
    calls = [
        lambda: write_detections_file(path, [], {}),
        lambda: read_tracks_file(path),
        lambda: write_tracks_file(path, None),  # type: ignore[arg-type]
        lambda: read_truth_file(path),
        lambda: write_truth_file(path, None),  # type: ignore[arg-type]
    ]
    for call in calls:
        with pytest.raises(DataFileError) as info:
            call()
        assert info.value.path == str(path)
        assert (
            str(info.value)
            == f"{path}: {what}; expected one of .csv, .parquet, .pq (CSV or Parquet)"
        )
    assert not path.exists()


def test_an_unknown_detections_suffix_says_how_to_name_the_format(tmp_path: Path) -> None:
    path = tmp_path / "data.csv.gz"
    with pytest.raises(DataFileError) as info:
        read_detections_file(path, {})
    assert str(info.value) == (
        f"{path}: unknown file suffix '.gz'; expected one of .csv, .parquet, .pq (CSV or "
        "Parquet); or name its format: --format csv|parquet"
    )
    with pytest.raises(InputError, match="format_name must be one of csv, parquet, got 'tsv'"):
        read_detections_file(path, {}, format_name="tsv")
    with pytest.raises(InputError, match="detections_format must be one of"):
        RunOptions(detections_format="tsv")


def test_detections_without_a_suffix_are_sniffed(tmp_path: Path) -> None:
    """No suffix (a stream: /dev/stdin, <(zcat ...)): Parquet's magic PAR1, else CSV; a
    named format wins over the suffix."""
    assert sniff_format(b"PAR1\x15\x04") == "parquet"
    assert sniff_format(b"time,sensor,x\n") == sniff_format(b"") == "csv"
    scenario = build_scenario("two_sensors", 1)
    sensors = scenario.config.sensors
    scans = number_rows(scenario.scans[:4])
    write_detections_file(tmp_path / "d.csv", scans, sensors)
    (tmp_path / "d").write_bytes((tmp_path / "d.csv").read_bytes())
    (tmp_path / "d.txt").write_bytes((tmp_path / "d.csv").read_bytes())
    _same(read_detections_file(tmp_path / "d", sensors), scans)
    _same(read_detections_file(tmp_path / "d.txt", sensors, format_name="csv"), scans)
    with pytest.raises(DataFileError, match="cannot read the file"):
        read_detections_file(tmp_path / "missing", sensors)
    if importlib.util.find_spec("pyarrow") is not None:
        write_detections_file(tmp_path / "d.parquet", scans, sensors)
        (tmp_path / "p").write_bytes((tmp_path / "d.parquet").read_bytes())
        _same(read_detections_file(tmp_path / "p", sensors), scans)
        with pytest.raises(DataFileError, match="not a readable Parquet file"):
            read_detections_file(tmp_path / "d.csv", sensors, format_name="parquet")


def _same(got: list[Scan], want: list[Scan]) -> None:
    assert [(s.time, s.sensor) for s in got] == [(s.time, s.sensor) for s in want]
    for a, b in zip(got, want, strict=True):
        assert a.detections.tobytes() == b.detections.tobytes()
        assert np.array_equal(a.rows, b.rows)


def test_detections_csv_and_parquet_files_hold_the_same_scans(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    scenario = build_scenario("two_sensors", 1)
    sensors = scenario.config.sensors
    scans = number_rows(scenario.scans[:10])
    write_detections_file(tmp_path / "d.csv", scans, sensors)
    from_csv = read_detections_file(tmp_path / "d.csv", sensors)
    _same(from_csv, read_detections(tmp_path / "d.csv", sensors))  # the CSV reader's answer
    _same(from_csv, scans)
    for suffix in PARQUET_SUFFIXES:
        path = tmp_path / f"d{suffix}"
        write_detections_file(path, scans, sensors)
        assert path.read_bytes()[:4] == b"PAR1"
        _same(read_detections_file(path, sensors), scans)


def test_tracks_and_truth_files_by_suffix(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    scenario = build_scenario("crossing", 0)
    tracks = TrackTable(
        track_ids=[0, 0, 1],
        times=[0.0, 1.0, 1.0],
        sensors=("radar", "radar", "radar"),
        states=[[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]],
        variances=[[1.0, 1.0], [0.5, 0.5], [2.0, 2.0]],
        detection_rows=[0, -1, 9],
        state_names=("x", "y"),
    )
    for suffix in (".csv", ".parquet"):
        write_tracks_file(tmp_path / f"t{suffix}", tracks)
        back = read_tracks_file(tmp_path / f"t{suffix}")
        assert back.detection_rows.tolist() == [0, -1, 9]
        assert back.states.tobytes() == tracks.states.tobytes()
        write_truth_file(tmp_path / f"truth{suffix}", scenario.truth)
        truth = read_truth_file(tmp_path / f"truth{suffix}")
        assert truth.states.tobytes() == scenario.truth.states.tobytes()
        assert np.array_equal(truth.target_ids, scenario.truth.target_ids)
    # the .csv files are plain CSV: the CSV readers read them
    assert read_tracks(tmp_path / "t.csv").size == 3
    assert read_truth(tmp_path / "truth.csv").size == scenario.truth.size
    assert (tmp_path / "t.parquet").read_bytes()[:4] == b"PAR1"


def test_csv_files_need_no_pyarrow(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for name in ("pyarrow", "pyarrow.parquet", "pyarrow.compute"):
        monkeypatch.setitem(sys.modules, name, None)  # import raises ImportError
    scenario = build_scenario("crossing", 0)
    sensors = scenario.config.sensors
    write_detections_file(tmp_path / "d.csv", scenario.scans[:3], sensors)
    _same(read_detections_file(tmp_path / "d.csv", sensors), scenario.scans[:3])
    with pytest.raises(InputError, match=r"^reading Parquet needs pyarrow: pip install"):
        read_detections_file(tmp_path / "d.pq", sensors)


# A throwaway format for the test below: CSV text under another suffix, its functions
# named as the format table expects (read_<kind>_copy, write_<kind>_copy).
read_detections_copy = read_detections
read_tracks_copy = read_tracks
read_truth_copy = read_truth
read_origins_copy = read_origins
write_detections_copy = write_detections
write_tracks_copy = write_tracks
write_truth_copy = write_truth
write_origins_copy = write_origins


def test_a_new_format_is_one_module_and_one_row(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    row = FileFormat("copy", (".csvx",), __name__, "_copy", "CSV copy")
    monkeypatch.setitem(FILE_FORMATS, "copy", row)
    assert format_names() == ("csv", "parquet", "copy")
    assert detection_formats()[-1] == ".csvx" and file_format("d.CSVX") == "copy"
    assert file_name("tracks", "copy") == "tracks.csvx"
    # simulate writes it, every *_file function reads it back
    scenario = truncate_scenario(build_scenario("crossing", 0), 4)
    paths = write_scenario(scenario, tmp_path / "rec1", data_format="copy")
    assert {p.name for p in paths.values()} == {
        "detections.csvx",
        "truth.csvx",
        "origins.csvx",
        "config.toml",
    }
    sensors = scenario.config.sensors
    _same(read_detections_file(paths["detections"], sensors), scenario.scans)
    assert read_truth_file(paths["truth"]).size == scenario.truth.size
    assert read_origins_file(paths["origins"]).rows.size == scenario.origins.rows.size
    # a run folder's tracks file, and a batch finds the recording
    options = RunOptions(tracks_format="copy", progress=False)
    assert options.tracks_format == "copy"
    assert [r.detections.name for r in find_recordings(tmp_path)] == ["detections.csvx"]
    with pytest.raises(InputError, match="format_name must be one of csv, parquet, copy, got"):
        file_name("tracks", "nope")
