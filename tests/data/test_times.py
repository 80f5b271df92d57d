"""Times as time: ISO 8601 text and datetime64 to seconds since an epoch and back."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mapassoc.data.times import (
    SECONDS,
    TimeBase,
    datetime64_times,
    format_times,
    parse_time_cells,
    times_from_datetime64,
)


def _fail(message: str, position: int) -> ValueError:
    return ValueError(f"position {position}: {message}")


@given(
    st.lists(
        st.datetimes(
            min_value=dt.datetime(1990, 1, 1), max_value=dt.datetime(2090, 1, 1)
        ),
        min_size=1,
        max_size=20,
    )
)
def test_iso_text_round_trips_exactly_to_the_microsecond(stamps: list[dt.datetime]) -> None:
    cells = [stamp.isoformat(timespec="microseconds") + "Z" for stamp in sorted(stamps)]
    seconds, base = parse_time_cells(cells, _fail)
    assert base.kind == "iso8601" and base.zoned
    assert format_times(seconds, base) == cells
    assert seconds.min() >= 0.0 and seconds.min() < 1.0  # the epoch: the first second


def test_seconds_since_the_epoch_are_the_differences_of_the_timestamps() -> None:
    cells = ["2024-05-01T11:59:59.5Z", "2024-05-01T14:00:01.5+02:00", "2024-05-01T12:00:02Z"]
    seconds, base = parse_time_cells(cells, _fail)
    assert seconds.tolist() == [0.5, 2.5, 3.0]
    assert base.epoch == "2024-05-01T11:59:59.000000Z"


def test_times_without_a_zone_are_utc_and_written_without_one() -> None:
    seconds, base = parse_time_cells(["2024-05-01T12:00:00", "2024-05-01T12:00:01.25"], _fail)
    assert not base.zoned and seconds.tolist() == [0.0, 1.25]
    assert format_times(seconds, base) == [
        "2024-05-01T12:00:00.000000",
        "2024-05-01T12:00:01.250000",
    ]


def test_plain_seconds_stay_as_they_are() -> None:
    seconds, base = parse_time_cells(["0.5", "", "1e1"], _fail)
    assert base == SECONDS
    assert seconds[0] == 0.5 and np.isnan(seconds[1]) and seconds[2] == 10.0
    assert format_times(seconds[[0, 2]], base) == ["0.5", "10.0"]


@pytest.mark.parametrize(
    ("cells", "position", "words"),
    [
        (["1.0", "2024-05-01T12:00:00Z"], 1, "another kind"),
        (["2024-05-01T12:00:00Z", "3.0"], 1, "another kind"),
        (["2024-05-01T12:00:00Z", "2024-05-01T12:00:01"], 1, "with and without a time zone"),
        (["2024-05-01T12:00:00Z", "yesterday"], 1, "not an ISO 8601 timestamp"),
    ],
)
def test_mixed_or_bad_times_name_the_cell(cells: list[str], position: int, words: str) -> None:
    with pytest.raises(ValueError, match=f"position {position}: .*{words}"):
        parse_time_cells(cells, _fail)


def test_datetime64_round_trips_exactly() -> None:
    values = pd.to_datetime(
        ["2024-05-01T12:00:00.000001", "2024-05-01T12:00:10.999999", None]
    ).to_numpy()
    seconds, base = times_from_datetime64(values, zoned=False)
    assert base.kind == "datetime64" and np.isnan(seconds[2])
    back = datetime64_times(seconds[:2], base)
    assert np.array_equal(back, values[:2].astype("datetime64[us]"))


def test_the_time_base_records_its_epoch() -> None:
    base = TimeBase(kind="iso8601", epoch_us=1_714_564_800_000_000, zoned=True)
    assert base.to_json() == {
        "kind": "iso8601",
        "epoch": "2024-05-01T12:00:00.000000Z",
        "zoned": True,
    }
    assert SECONDS.to_json()["epoch"] is None
