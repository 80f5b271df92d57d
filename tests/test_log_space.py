"""log_sum_exp: scipy's logsumexp values (to rounding) on every axis, and the edge cases
the window tables reach (no terms, every term -inf, an inf, a NaN)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import logsumexp

from mapassoc.log_space import json_number, log_sum_exp, number_from_json


@pytest.mark.parametrize("seed", range(10))
@pytest.mark.parametrize("axis", [None, 0, 1])
def test_equals_scipy_to_rounding(seed: int, axis: int | None) -> None:
    rng = np.random.default_rng(seed)
    x = rng.normal(scale=300.0, size=(int(rng.integers(1, 6)), int(rng.integers(1, 9))))
    x[rng.random(x.shape) < 0.3] = -np.inf  # some rows or columns all -inf
    got = log_sum_exp(x, axis=axis)
    want = logsumexp(x, axis=axis)
    assert got.shape == np.shape(want)
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-12)


def test_a_hand_derived_value() -> None:
    # log(e^1 + e^2 + e^3) = 3 + log(1 + e^-1 + e^-2)
    assert float(log_sum_exp([1.0, 2.0, 3.0])) == pytest.approx(
        3.0 + math.log(1.0 + math.exp(-1.0) + math.exp(-2.0)), rel=1e-15
    )
    # terms far apart: the larger one alone, no overflow
    assert float(log_sum_exp([1000.0, -1000.0])) == 1000.0


def test_edge_cases() -> None:
    assert float(log_sum_exp([])) == -math.inf
    assert float(log_sum_exp([-math.inf, -math.inf])) == -math.inf
    assert float(log_sum_exp([0.0, math.inf])) == math.inf
    assert math.isnan(float(log_sum_exp([0.0, math.nan])))
    rows = log_sum_exp(np.zeros((3, 0)), axis=1)
    assert rows.shape == (3,) and np.all(rows == -math.inf)
    mixed = log_sum_exp(np.array([[-math.inf, -math.inf], [0.0, 0.0]]), axis=1)
    assert mixed[0] == -math.inf and mixed[1] == pytest.approx(math.log(2.0), rel=1e-15)


@pytest.mark.parametrize("value", [math.inf, -math.inf, 0.0, -2.5, 1e308, 5e-324])
def test_json_number_round_trips_through_strict_json(value: float) -> None:
    import json

    text = json.dumps(json_number(value), allow_nan=False)
    assert number_from_json(json.loads(text)) == value


def test_number_from_json_refuses_other_strings() -> None:
    assert json_number(math.inf) == "inf" and json_number(-math.inf) == "-inf"
    with pytest.raises(ValueError, match="'nan'"):
        number_from_json("nan")
