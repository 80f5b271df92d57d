"""End to end: a configuration with ``[motion] model = "imm"`` run through the estimator
API and the run folder writes each scan's model probabilities into the tracks file."""

from __future__ import annotations

import csv
import warnings
from pathlib import Path

import numpy as np
import pytest
from support import make_scans

from mapassoc.apps.runs import RunOptions, run_files
from mapassoc.data.config import load_config
from mapassoc.data.formats import read_tracks_file, write_tracks_file
from mapassoc.data.io import write_detections
from mapassoc.estimator.pipeline import WindowEstimator

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")  # no [estimator.<other>]

COLUMNS = ["p_constant_velocity_0", "p_constant_velocity_1"]

IMM_TOML = """
[motion]
model = "imm"
switch_probability = 0.05
initial_probabilities = [0.25, 0.75]

[[motion.models]]
model = "constant_velocity"
ndim = 2
noise_intensity = 1.0

[[motion.models]]
model = "constant_velocity"
ndim = 2
noise_intensity = 100.0

[[sensors]]
name = "s"
measurement = "position"
noise_std = 1.0
detection_probability = 0.9
false_alarms_per_scan = 1e-6
region = [[-100.0, 100.0], [-100.0, 100.0]]

[birth]
rate = 0.1
initial_count = 2.0
velocity_std = 5.0

[estimator.windows]
window_length = 3
"""


def _recording(folder: Path) -> tuple[Path, list]:
    """The configuration file and scans: one target straight along x, one turning hard
    halfway (the loud model's case)."""
    config_path = folder / "imm.toml"
    config_path.write_text(IMM_TOML, encoding="utf-8")
    times = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    first = [[-50.0 + 5.0 * t, 0.0] for t in times]
    second = [[20.0, 40.0 - 4.0 * t] if t < 4 else [20.0 + 6.0 * (t - 4), 24.0] for t in times]
    scans = make_scans(times, [[a, b] for a, b in zip(first, second, strict=True)], dz=2)
    return config_path, scans


def _header_and_rows(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open(newline="", encoding="utf-8") as handle:
        reader = csv.DictReader(handle)
        rows = list(reader)
        return list(reader.fieldnames or []), rows


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_the_estimator_writes_model_probabilities_summing_to_one(
    tmp_path: Path, suffix: str
) -> None:
    if suffix == ".parquet":
        pytest.importorskip("pyarrow")
    config_path, scans = _recording(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        config = load_config(config_path)
    result = WindowEstimator(config=config).run(scans)
    path = tmp_path / f"tracks{suffix}"
    write_tracks_file(path, result.tracks)
    back = read_tracks_file(path)
    assert back.size == result.tracks.size > 0
    assert ["p_" + name for name in back.model_names] == COLUMNS
    assert back.model_probabilities is not None
    np.testing.assert_allclose(back.model_probabilities.sum(axis=1), 1.0, atol=1e-12)
    if suffix == ".csv":
        header, _ = _header_and_rows(path)
        end = header.index("detection_row") + 1
        assert header[end : end + 2] == COLUMNS


def test_a_run_folder_tracks_file_has_the_columns(tmp_path: Path) -> None:
    config_path, scans = _recording(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        sensors = load_config(config_path).sensors
    detections = tmp_path / "detections.csv"
    write_detections(detections, scans, sensors)
    outcome = run_files(config_path, detections, tmp_path / "run",
                        RunOptions(progress=False))  # fmt: skip
    header, rows = _header_and_rows(outcome.out / "tracks.csv")
    end = header.index("detection_row") + 1
    assert header[end : end + 2] == COLUMNS
    assert header[end + 2 :] in ([], ["existence"])
    assert len(rows) > 0
    for row in rows:
        assert abs(sum(float(row[c]) for c in COLUMNS) - 1.0) <= 1e-9
