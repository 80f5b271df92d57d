"""The sliding window shared by the windowed methods."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from mapassoc.data.windows import WindowSpan, window_span, window_spans
from mapassoc.errors import InputError


@given(
    total=st.integers(1, 60),
    length=st.integers(1, 12),
    data=st.data(),
)
def test_committed_scans_cover_the_recording_once_in_order(
    total: int, length: int, data: st.DataObject
) -> None:
    stride = data.draw(st.integers(1, length))
    spans = list(window_spans(total, length=length, stride=stride))
    committed = [m for s in spans for m in range(s.start, s.start + s.commit)]
    assert committed == list(range(total))
    for span in spans[:-1]:
        assert span.end - span.start == length and span.commit == stride
    last = spans[-1]
    assert last.end == total and last.commit == last.end - last.start <= length


def test_golden_spans() -> None:
    assert list(window_spans(7, length=5, stride=2)) == [
        WindowSpan(0, 5, 2),
        WindowSpan(2, 7, 5),
    ]
    assert list(window_spans(3, length=5, stride=1)) == [WindowSpan(0, 3, 3)]
    assert list(window_spans(0, length=5, stride=1)) == []


@pytest.mark.parametrize(
    ("start", "total", "length", "stride", "key"),
    [(3, 3, 5, 1, "start"), (0, 3, 0, 1, "length"), (0, 3, 2, 3, "stride"), (0, 0, 2, 1, "total")],
)
def test_bad_windows_name_their_argument(
    start: int, total: int, length: int, stride: int, key: str
) -> None:
    with pytest.raises(InputError, match=key):
        window_span(start, total, length=length, stride=stride)
