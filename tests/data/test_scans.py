"""Tests of mapassoc.data.scans: detection ids (``Scan.rows``) are checked at construction."""

from __future__ import annotations

import numpy as np
import pytest

from mapassoc.data.scans import Scan, check_scan_order
from mapassoc.errors import InputError


def _scan(rows: object, m: int = 3, time: float = 1.5, sensor: str = "radar") -> Scan:
    return Scan(time=time, sensor=sensor, detections=np.zeros((m, 2)), rows=rows)


def test_ids_from_zero_are_detection_ids() -> None:
    scan = _scan(np.array([0, 1, 7]))
    assert scan.rows.tolist() == [0, 1, 7]
    assert scan.rows.dtype == np.int64 and not scan.rows.flags.writeable


def test_a_negative_id_raises_at_construction_naming_sensor_time_and_id() -> None:
    with pytest.raises(InputError) as info:
        _scan([4, -1, 5])
    message = str(info.value)
    assert "must be >= 0, got [-1]" in message
    assert "sensor 'radar'" in message and "time 1.5" in message


def test_an_id_repeated_within_a_scan_raises_naming_it() -> None:
    with pytest.raises(InputError) as info:
        _scan([3, 9, 3], time=2.0, sensor="esm")
    message = str(info.value)
    assert "must be distinct, got [3] more than once" in message
    assert "sensor 'esm'" in message and "time 2.0" in message


def test_float_ids_must_be_whole_numbers() -> None:
    assert _scan(np.array([2.0, 3.0, 4.0])).rows.tolist() == [2, 3, 4]
    with pytest.raises(InputError, match=r"whole numbers .*got \[2\.5\]"):
        _scan([1.0, 2.5, 3.0])
    with pytest.raises(InputError, match="whole numbers"):
        _scan([1.0, np.nan, 3.0])


def test_non_integer_ids_are_refused() -> None:
    with pytest.raises(InputError, match="dtype bool"):
        _scan(np.array([True, False, True]))
    with pytest.raises(InputError, match="dtype <U1"):
        _scan(np.array(["a", "b", "c"]))
    with pytest.raises(InputError, match="fit in int64"):
        _scan(np.array([0, 1, 2**63], dtype=np.uint64))
    with pytest.raises(InputError, match=r"shape \(3,\), got \(2,\)"):
        _scan([0, 1])


def test_an_empty_scan_takes_any_empty_rows() -> None:
    for rows in ([], np.zeros(0), np.zeros(0, dtype=np.int64)):
        assert _scan(rows, m=0).rows.dtype == np.int64


def test_ids_repeated_across_scans_are_refused_by_check_scan_order() -> None:
    first = _scan([0, 1, 2], time=0.0)
    check_scan_order([first, _scan([3, 4, 5], time=1.0)])
    with pytest.raises(InputError, match=r"\[2\] appear in more than one scan; scan 1"):
        check_scan_order([first, _scan([2, 3, 4], time=1.0)])
