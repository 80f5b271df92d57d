"""The shared argument checks of ``mapassoc.validation``: what they accept, the exact
messages they give, and the configuration key they carry."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from mapassoc.errors import InputError
from mapassoc.models.sensor import Region
from mapassoc.validation import (
    SHOWN_WIDTH,
    check_callback,
    check_instance,
    check_integer,
    check_names,
    check_nonnegative,
    check_number,
    check_numeric_array,
    check_path,
    check_positive,
    check_probability,
    check_standard_deviation,
    check_text,
    shown,
)


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


# --------------------------------------------------- numbers, arrays, paths, types


@pytest.mark.parametrize("check", [check_number, check_positive, check_nonnegative,
                                   check_probability, check_standard_deviation])  # fmt: skip
@pytest.mark.parametrize(("value", "shown_as"), [("0.1", "'0.1' (str)"), (b"1", "b'1' (bytes)"),
                                                 (None, "None (NoneType)"),
                                                 ([0.1], "[0.1] (list)")])  # fmt: skip
def test_numbers_given_as_text_or_none_are_refused_not_parsed(
    check: Callable[..., float], value: object, shown_as: str
) -> None:
    """``float("0.1")`` is 0.1: the checks used it, so ``BirthModel(rate="0.1")`` passed
    and stored the string."""
    with pytest.raises(InputError) as error:
        check("rate", value, key="rate")
    assert str(error.value) == f"rate must be a number, got {shown_as}"
    assert error.value.key == "rate"


@pytest.mark.parametrize("value", [0.5, 1, np.float32(0.5), np.int64(1), Fraction(1, 2)])
def test_every_kind_of_real_number_is_a_number(value: object) -> None:
    assert check_number("x", value) == float(value)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "value",
    [["1", "2"], "12", [True, False], [None, 1.0], [[1.0, 2.0], [3.0]], None, {"a": 1},
     np.array(["1.5"]), [1.0, b"2"]],
)  # fmt: skip
def test_arrays_of_text_booleans_or_none_are_refused(value: object) -> None:
    """numpy would read ``"1.5"`` as 1.5, ``True`` as 1 and ``None`` as nan."""
    with pytest.raises(InputError) as error:
        check_numeric_array("detections", value)  # type: ignore[arg-type]
    assert str(error.value).startswith(f"detections must be a numeric array, got {value!r}"[:40])
    assert str(error.value).endswith(f"({type(value).__name__})")


def test_numeric_arrays_of_every_kind_are_floats() -> None:
    for value in ([1, 2], [np.float32(1.5), 2], np.arange(3), [[1.0, np.inf]], 4):
        out = check_numeric_array("a", value)  # type: ignore[arg-type]
        assert out.dtype == np.float64
        np.testing.assert_array_equal(out, np.asarray(value, dtype=float))


def test_paths_are_text_or_path_objects(tmp_path: Path) -> None:
    assert check_path("path", "a.csv") == "a.csv"
    assert check_path("path", tmp_path / "a.csv") == str(tmp_path / "a.csv")
    refused = [(None, "None (NoneType)"), (5, "5 (int)"), (b"a.csv", "b'a.csv' (bytes)")]
    for value, shown_as in refused:
        with pytest.raises(InputError) as error:
            check_path("load_config: path", value, hint="give the file's name")
        assert str(error.value) == (
            f"load_config: path must be a file path (str or os.PathLike), got {shown_as}; "
            "give the file's name"
        )


def test_shown_cuts_a_long_value_and_names_its_type() -> None:
    assert shown("12:00") == "'12:00' (str)"
    long = shown("x" * 500)
    assert long.endswith("... (str)") and len(long) == SHOWN_WIDTH + len(" (str)")


def test_instance_names_callbacks_and_name_lists() -> None:
    check_instance("flag", True, (bool, np.bool_))
    with pytest.raises(InputError, match=r"^flag must be True or False, got 'no' \(str\)$"):
        check_instance("flag", "no", (bool, np.bool_), expected="True or False")
    with pytest.raises(InputError, match=r"^region must be a Region, got None \(NoneType\); use"):
        check_instance("region", None, Region, hint="use Region.from_bounds")
    check_callback("stop", None)
    check_callback("stop", print)
    with pytest.raises(InputError, match=r"^stop must be a callable \(a function\) or None, got 1"):
        check_callback("stop", 1)
    check_names("solver_names", ["highs"])
    for bad in ("highs", 5, None):
        with pytest.raises(InputError, match=r"^solver_names must be a collection of names, got"):
            check_names("solver_names", bad)
    with pytest.raises(InputError, match=r"^every entry of solver_names must be a string, got 5"):
        check_names("solver_names", ["highs", 5])
    with pytest.raises(InputError, match=r"^sensor must be a non-empty string, got '' \(str\)"):
        check_text("sensor", "")
