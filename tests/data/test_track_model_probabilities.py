"""The model probability columns of tracks files (a set of motion models): the table's
checks, exact CSV and Parquet round trips, column placement, and named errors of files
that break the rules."""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mapassoc.data.formats import read_tracks_file, write_tracks_file
from mapassoc.data.io import TrackTable, read_tracks, write_tracks
from mapassoc.errors import DataFileError, InputError

NAMES = ("constant_velocity_0", "constant_velocity_1")
PROBABILITIES = np.array([[0.25, 0.75], [0.1, 0.9], [1.0, 0.0]])


def _arguments(**changes: Any) -> dict[str, Any]:
    arguments: dict[str, Any] = {
        "track_ids": np.array([1, 1, 2]),
        "times": np.array([0.0, 1.0, 0.0]),
        "sensors": ("s", "s", "s"),
        "states": np.arange(6.0).reshape(3, 2),
        "variances": np.ones((3, 2)),
        "detection_rows": np.array([2, -1, 3]),
        "state_names": ("x", "vx"),
        "model_probabilities": PROBABILITIES,
        "model_names": NAMES,
    }
    return {**arguments, **changes}


def _table(**changes: Any) -> TrackTable:
    return TrackTable(**_arguments(**changes))


def _header(path: Path) -> list[str]:
    with path.open(newline="", encoding="utf-8") as handle:
        return next(csv.reader(handle))


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
@pytest.mark.parametrize("existence", [False, True])
def test_model_probabilities_round_trip_exactly(
    tmp_path: Path, suffix: str, existence: bool
) -> None:
    if suffix == ".parquet":
        pytest.importorskip("pyarrow")
    table = _table(model_probabilities=[[1 / 3, 2 / 3], [0.1, 0.9], [1.0, 0.0]])
    if existence:
        table = table.with_existence({1: 0.3})  # track 2 unknown
    path = tmp_path / f"tracks{suffix}"
    write_tracks_file(path, table)
    back = read_tracks_file(path)
    assert back.model_names == NAMES
    assert back.model_probabilities is not None and table.model_probabilities is not None
    assert back.model_probabilities.tobytes() == table.model_probabilities.tobytes()
    assert np.array_equal(back.states, table.states)
    if existence:
        assert back.existence is not None
        assert back.existence[0] == 0.3 and np.isnan(back.existence[2])
    else:
        assert back.existence is None


def test_the_columns_follow_detection_row_and_existence_stays_last(tmp_path: Path) -> None:
    path = tmp_path / "tracks.csv"
    write_tracks(path, _table().with_existence({1: 0.5, 2: 0.5}))
    assert _header(path)[-4:] == [
        "detection_row", "p_constant_velocity_0", "p_constant_velocity_1", "existence",
    ]  # fmt: skip
    write_tracks(path, _table())
    assert _header(path)[-3:] == ["detection_row", *("p_" + n for n in NAMES)]


def test_parquet_columns_are_in_the_csv_order(tmp_path: Path) -> None:
    pq = pytest.importorskip("pyarrow.parquet")
    path = tmp_path / "tracks.parquet"
    write_tracks_file(path, _table().with_existence({1: 0.5}))
    names = pq.read_schema(path).names
    assert names == _csv_header_of(tmp_path, _table().with_existence({1: 0.5}))


def _csv_header_of(folder: Path, table: TrackTable) -> list[str]:
    path = folder / "header.csv"
    write_tracks(path, table)
    return _header(path)


def test_a_single_model_table_has_no_model_columns(tmp_path: Path) -> None:
    table = _table(model_probabilities=None, model_names=())
    path = tmp_path / "tracks.csv"
    write_tracks(path, table)
    assert not any(name.startswith("p_") for name in _header(path))
    back = read_tracks(path)
    assert back.model_probabilities is None and back.model_names == ()


def test_an_empty_table_of_a_set_keeps_its_columns(tmp_path: Path) -> None:
    empty = TrackTable(
        track_ids=np.zeros(0, np.int64), times=np.zeros(0), sensors=(),
        states=np.zeros((0, 2)), variances=np.zeros((0, 2)),
        detection_rows=np.zeros(0, np.int64), state_names=("x", "vx"),
        model_probabilities=np.zeros((0, 2)), model_names=NAMES,
    )  # fmt: skip
    path = tmp_path / "tracks.csv"
    write_tracks(path, empty)
    back = read_tracks(path)
    assert back.model_names == NAMES
    assert back.model_probabilities is not None and back.model_probabilities.shape == (0, 2)


def test_select_and_with_existence_carry_the_probabilities() -> None:
    table = _table()
    kept = table.select(table.track_ids == 1)
    assert kept.model_names == NAMES
    assert kept.model_probabilities is not None
    assert np.array_equal(kept.model_probabilities, PROBABILITIES[:2])
    again = table.with_existence({1: 0.9})
    assert again.model_probabilities is not None
    assert np.array_equal(again.model_probabilities, PROBABILITIES)
    with pytest.raises(InputError, match="keep must be a boolean mask"):
        table.select([0, 1])


def test_from_steps_sorts_the_probabilities_with_the_records() -> None:
    table = TrackTable.from_steps(
        track_ids=[2, 1], times=[1.0, 0.0], sensors=["s", "s"], scan_indices=[1, 0],
        states=[np.zeros(2), np.ones(2)], variances=[np.ones(2), np.ones(2)],
        detection_rows=[-1, 4], state_names=("x", "vx"),
        model_probabilities=[np.array([0.2, 0.8]), np.array([0.6, 0.4])], model_names=NAMES,
    )  # fmt: skip
    assert table.track_ids.tolist() == [1, 2]
    assert table.model_probabilities is not None
    assert table.model_probabilities.tolist() == [[0.6, 0.4], [0.2, 0.8]]


def test_the_probabilities_are_read_only() -> None:
    probabilities = _table().model_probabilities
    assert probabilities is not None
    with pytest.raises(ValueError):
        probabilities[0, 0] = 0.5


@pytest.mark.parametrize(
    ("changes", "fragment"),
    [
        ({"model_probabilities": [[0.5, 0.5]] * 2}, r"probabilities must have shape \(3, 2\)"),
        ({"model_probabilities": [0.5, 0.5, 0.5]}, r"must have shape \(3, 2\).*got \(3,\)"),
        ({"model_probabilities": "0.5"}, "model_probabilities must be a numeric array"),
        ({"model_probabilities": [[0.5, 0.5], [np.nan, 1.0], [1, 0]]}, "only finite values"),
        ({"model_probabilities": [[1.5, -0.5], [0.5, 0.5], [1, 0]]},
         r"\[0, 1\], got the value 1.5"),
        ({"model_probabilities": [[0.5, 0.4], [0.5, 0.5], [1, 0]]}, "row 0 sums to 0.9; expected"),
        ({"model_names": ("a",)}, r"must have shape \(3, 1\)"),
        ({"model_names": ()}, "model_names must name its columns"),
        ({"model_names": ("a", "a")}, "model_names must be distinct"),
        ({"model_names": ("a", "b,c")}, "model name 'b,c' must be a non-empty string"),
        ({"model_names": "ab"}, "model_names must be a tuple of model names, got 'ab'"),
        ({"model_names": None}, "model_names must be a tuple of model names, got None"),
        ({"model_probabilities": None}, "model_names is .* but model_probabilities is None"),
        ({"state_names": ("x", "p_a"), "model_names": ("a", "b")}, "column 'p_a'"),
    ],
)  # fmt: skip
def test_bad_model_probabilities_are_refused_naming_the_argument(
    changes: dict[str, Any], fragment: str
) -> None:
    with pytest.raises(InputError, match=fragment):
        _table(**changes)


def test_a_row_within_the_tolerance_is_accepted() -> None:
    table = _table(model_probabilities=[[0.5, 0.5 + 5e-7], [0.5, 0.5], [1.0, 0.0]])
    assert table.model_probabilities is not None


HEADER = "track_id,time,sensor,x,var_x,detection_row,p_a,p_b"


@pytest.mark.parametrize(
    ("text", "line", "column", "fragment"),
    [
        (f"{HEADER}\n0,0,s,1,1,,,1\n", 2, "p_a", "empty cell; expected a model probability"),
        (f"{HEADER}\n0,0,s,1,1,,1.5,-0.5\n", 2, "p_a", r"'1.5' is not in \[0, 1\]"),
        (f"{HEADER}\n0,0,s,1,1,,0.5,0.6\n", 2, "p_a", "sum to 1.1; expected 1 within 1e-06"),
        (f"{HEADER}\n0,0,s,1,1,,x,1\n", 2, "p_a", None),
        (f"{HEADER},q\n0,0,s,1,1,,0.5,0.5,1\n", 1, "q", "column 'q' after 'detection_row'"),
        (
            "track_id,time,sensor,x,var_x,detection_row,existence,p_a\n0,0,s,1,1,,1,1\n",
            1, "existence", "then 'existence' last",
        ),
    ],
)  # fmt: skip
def test_bad_model_columns_of_a_file_are_named(
    tmp_path: Path, text: str, line: int, column: str, fragment: str | None
) -> None:
    path = tmp_path / "tracks.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DataFileError) as info:
        read_tracks(path)
    assert info.value.row == line
    assert info.value.column == column
    if fragment is not None:
        assert re.search(fragment, str(info.value)), str(info.value)


def test_a_parquet_row_that_does_not_sum_to_one_is_named(tmp_path: Path) -> None:
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    path = tmp_path / "tracks.parquet"
    columns = {
        "track_id": pa.array([0, 0], pa.int64()), "time": pa.array([0.0, 1.0]),
        "sensor": pa.array(["s", "s"]), "x": pa.array([1.0, 2.0]), "var_x": pa.array([1.0, 1.0]),
        "detection_row": pa.array([None, None], pa.int64()),
        "p_a": pa.array([0.5, 0.5]), "p_b": pa.array([0.5, 0.25]),
    }  # fmt: skip
    pq.write_table(pa.table(columns), path)
    with pytest.raises(DataFileError, match=r"row index 1 \(0-based\): model probabilities sum"):
        read_tracks_file(path)
