"""The shared argument checks of ``mapassoc.validation``: what they accept, the exact
messages they give, and the configuration key they carry."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mapassoc.errors import InputError
from mapassoc.validation import check_integer


@pytest.mark.parametrize("value", [0, 3, np.int64(3), np.int32(-2), np.uint8(7)])
def test_integers_of_every_kind_are_returned_as_int(value: object) -> None:
    out = check_integer("n", value)
    assert type(out) is int and out == value


@pytest.mark.parametrize(
    ("value", "kwargs", "message"),
    [
        (True, {}, "n must be an integer, got True"),
        (3.0, {}, "n must be an integer, got 3.0"),
        ("3", {"minimum": 0}, "n must be an integer >= 0, got '3'"),
        (None, {"maximum": 4}, "n must be an integer <= 4, got None"),
        (-1, {"minimum": 0}, "n must be an integer >= 0, got -1"),
        (5, {"maximum": 4}, "n must be an integer <= 4, got 5"),
        (5, {"minimum": 1, "maximum": 4}, "n must be an integer in 1..4, got 5"),
        (np.int64(0), {"minimum": 1, "maximum": 4}, "n must be an integer in 1..4, got "),
    ],
)
def test_rejections_name_the_argument_the_value_and_the_bounds(
    value: object, kwargs: dict[str, int], message: str
) -> None:
    with pytest.raises(InputError) as error:
        check_integer("n", value, **kwargs)
    assert str(error.value).startswith(message)
    assert error.value.key is None


def test_bounds_are_inclusive_and_the_key_is_carried() -> None:
    assert check_integer("n", 1, minimum=1, maximum=1) == 1
    with pytest.raises(InputError) as error:
        check_integer("window_length", 0, minimum=1, key="window_length")
    assert error.value.key == "window_length"


def test_integer_settings_are_stored_as_python_ints() -> None:
    """A numpy integer passes the checks and is stored as an ``int``, which JSON writes
    (a ``numpy.int64`` it would refuse)."""
    import json

    from mapassoc.apps.runs import RunOptions
    from mapassoc.data.settings import EstimatorSettings

    settings = EstimatorSettings(
        window_length=np.int64(6), stride=np.int32(2), max_tracks=np.uint8(7)
    )
    assert [type(v) for v in (settings.window_length, settings.stride, settings.max_tracks)] == [
        int,
        int,
        int,
    ]
    assert json.loads(json.dumps(dataclasses.asdict(settings)))["windows"]["window_length"] == 6
    assert type(RunOptions(segments=np.int64(3)).segments) is int
    below = r"window_length must be an integer >= 1, got np.int64\(0\)"
    with pytest.raises(InputError, match=below):
        EstimatorSettings(window_length=np.int64(0))
