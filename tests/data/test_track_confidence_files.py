"""The existence column of tracks files and the associations file."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from mapassoc.data.formats import read_tracks_file, write_tracks_file
from mapassoc.data.io import (
    ASSOCIATIONS_HEADER,
    TrackTable,
    read_tracks,
    write_associations,
)
from mapassoc.errors import DataFileError, InputError


def _table() -> TrackTable:
    return TrackTable(
        track_ids=np.array([1, 1, 2]),
        times=np.array([0.0, 1.0, 0.0]),
        sensors=("s", "s", "s"),
        states=np.arange(6.0).reshape(3, 2),
        variances=np.ones((3, 2)),
        detection_rows=np.array([2, -1, 3]),
        state_names=("x", "vx"),
    )


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_existence_round_trips_with_unknown_values(tmp_path: Path, suffix: str) -> None:
    if suffix == ".parquet":
        pytest.importorskip("pyarrow")
    table = _table().with_existence({1: 0.3})  # track 2 unknown
    path = tmp_path / f"tracks{suffix}"
    write_tracks_file(path, table)
    back = read_tracks_file(path)
    assert back.existence is not None
    np.testing.assert_array_equal(back.existence[:2], [0.3, 0.3])
    assert math.isnan(back.existence[2])
    np.testing.assert_array_equal(back.detection_rows, table.detection_rows)
    # Without existence the file has no such column and reads back without it.
    write_tracks_file(path, _table())
    assert read_tracks_file(path).existence is None


def test_the_existence_column_is_last_and_optional(tmp_path: Path) -> None:
    path = tmp_path / "tracks.csv"
    write_tracks_file(path, _table().with_existence({1: 0.5, 2: 1.0}))
    header = path.read_text().splitlines()[0].split(",")
    assert header[-2:] == ["detection_row", "existence"]


def test_an_existence_outside_zero_one_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "tracks.csv"
    write_tracks_file(path, _table().with_existence({1: 0.5, 2: 0.5}))
    text = path.read_text().replace(",0.5\n", ",1.5\n", 1)
    path.write_text(text)
    with pytest.raises(DataFileError, match="existence"):
        read_tracks(path)
    with pytest.raises(InputError, match="existence"):
        _table().with_existence({1: -0.1})


def test_associations_file_is_sorted_and_checked(tmp_path: Path) -> None:
    path = tmp_path / "associations.csv"
    write_associations(path, {2: {7: 0.25, 3: 1.0}, 1: {7: 0.75}})
    with path.open() as handle:
        rows = list(csv.reader(handle))
    assert tuple(rows[0]) == ASSOCIATIONS_HEADER
    assert rows[1:] == [["3", "2", "1.0"], ["7", "1", "0.75"], ["7", "2", "0.25"]]
    with pytest.raises(InputError, match="not in"):
        write_associations(path, {1: {7: 1.2}})
