"""Tests of mapassoc.evaluation.calibration: Brier score, hit rate and expected calibration
error of p(K | Z) against the true number of targets."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from mapassoc.data.io import TruthTable
from mapassoc.errors import InputError
from mapassoc.evaluation.calibration import (
    count_scores,
    count_series_scores,
    expected_calibration_error,
    span_target_counts,
    window_target_counts,
)
from mapassoc.trackers.base import CountSeries


@dataclass(frozen=True)
class Window:
    """What the scores read of a WindowReport."""

    p_k: tuple[float, ...]
    marginal_k: int
    start_time: float = 0.0
    end_time: float = 0.0


def truth_table(records: list[tuple[int, float]]) -> TruthTable:
    """Truth with one record per (target id, time) at the origin."""
    return TruthTable(
        target_ids=np.array([r[0] for r in records], dtype=np.int64),
        times=np.array([r[1] for r in records], dtype=float),
        states=np.zeros((len(records), 2)),
        state_names=("x", "y"),
    )


# ----------------------------------------------------------------------------------------------
# Brier score and hit rate by hand
# ----------------------------------------------------------------------------------------------


def test_brier_score_by_hand() -> None:
    # p = (0.1, 0.6, 0.3), true K = 2: 0.1^2 + 0.6^2 + (0.3 - 1)^2 = 0.86.
    scores = count_scores([Window((0.1, 0.6, 0.3), 1)], [2])
    assert scores.brier == pytest.approx(0.86)
    assert scores.hit_rate == 0.0
    assert scores.mean_p_true == pytest.approx(0.3)
    # True K beyond the vector: p padded with zeros, 0.5^2 + 0.5^2 + 0 + 1 = 1.5.
    assert count_scores([Window((0.5, 0.5), 0)], [3]).brier == pytest.approx(1.5)
    # Certainty on the true K scores 0, on a wrong K 2.
    assert count_scores([Window((0.0, 1.0), 1)], [1]).brier == 0.0
    assert count_scores([Window((0.0, 1.0), 1)], [0]).brier == pytest.approx(2.0)


def test_docstring_example_of_count_scores() -> None:
    windows = [Window((0.8, 0.2), 0), Window((0.5, 0.5), 0)]
    scores = count_scores(windows, np.array([0, 2]))
    assert scores.brier == pytest.approx((0.08 + 1.5) / 2)
    assert scores.hit_rate == 0.5
    assert scores.mean_p_true == pytest.approx(0.4)
    assert scores.ece == pytest.approx(0.35)
    assert (scores.num_spans, scores.num_bins) == (2, 10)


# ----------------------------------------------------------------------------------------------
# Expected calibration error by hand
# ----------------------------------------------------------------------------------------------


def test_ece_by_hand_with_bins() -> None:
    confidences = [0.95, 0.9, 0.55, 0.6, 0.15]
    correct = np.array([True, False, True, True, False])
    # 10 bins ((b-1)/10, b/10]: {0.95} acc 1 (gap 0.05); {0.9} in (0.8, 0.9], acc 0 (gap 0.9);
    # {0.55, 0.6} in (0.5, 0.6], acc 1 vs conf 0.575 (gap 0.425); {0.15} acc 0 (gap 0.15):
    # (0.05 + 0.9 + 2 * 0.425 + 0.15) / 5 = 0.39.
    assert expected_calibration_error(confidences, correct, num_bins=10) == pytest.approx(0.39)
    # 2 bins: (0, 0.5] holds 0.15 (gap 0.15); (0.5, 1] holds the rest, acc 3/4 = conf 0.75.
    assert expected_calibration_error(confidences, correct, num_bins=2) == pytest.approx(0.03)
    # 1 bin: |mean hit - mean confidence| = |0.6 - 0.63|.
    assert expected_calibration_error(confidences, correct, num_bins=1) == pytest.approx(0.03)
    # Zero confidence goes to the first bin.
    assert expected_calibration_error([0.0], np.array([True]), num_bins=4) == 1.0


def test_perfectly_calibrated_predictor_has_small_ece_and_miscalibrated_large() -> None:
    """Spans whose reported K (K = 0, probability q) is right with probability exactly q.

    With n = 20,000 spans and q uniform on [0.5, 1], the five bins (0.5, 0.6] .. (0.9, 1]
    hold ~4,000 spans each; the gap acc - conf of a bin has mean 0 and standard deviation
    sqrt(mean q (1 - q) / 4000) <= 0.008, so the ECE, a weighted mean of the |gaps|, is
    about 0.8 * 0.008 ~ 0.006 (0.0033 with this seed) and below 0.03 except with negligible
    probability.  An overconfident predictor, right with probability q - 0.2, has
    ECE 0.2 up to the same error (0.196 with this seed).
    """
    rng = np.random.default_rng(20240611)
    n = 20_000
    q = rng.uniform(0.5, 1.0, size=n)
    u = rng.uniform(size=n)

    def windows_and_truth(hit_probability: np.ndarray) -> tuple[list[Window], np.ndarray]:
        windows = [Window((float(qi), 1.0 - float(qi)), 0) for qi in q]
        true_k = np.where(u < hit_probability, 0, 1).astype(np.int64)
        return windows, true_k

    calibrated = count_scores(*windows_and_truth(q))
    assert calibrated.ece < 0.03
    assert calibrated.hit_rate == pytest.approx(0.75, abs=0.02)  # E[q] = 0.75
    overconfident = count_scores(*windows_and_truth(q - 0.2))
    assert overconfident.ece == pytest.approx(0.2, abs=0.03)
    assert overconfident.ece > calibrated.ece + 0.1
    # The Brier score sees it too: with two components the Brier score is 2 (q - y)^2, y the
    # hit, and E[(q - y)^2] = (q - h)^2 + h (1 - h) for a hit probability h; h = q gives
    # q (1 - q), h = q - 0.2 gives q (1 - q) + 0.4 q - 0.2, so the mean grows by
    # 2 (0.4 E[q] - 0.2) = 0.2.
    assert overconfident.brier - calibrated.brier == pytest.approx(0.2, abs=0.02)


def test_ece_bad_inputs() -> None:
    with pytest.raises(InputError, match="confidences"):
        expected_calibration_error([1.2], np.array([True]))
    with pytest.raises(InputError, match="confidences"):
        expected_calibration_error([], np.array([], dtype=bool))
    with pytest.raises(InputError, match="correct"):
        expected_calibration_error([0.5], [1])
    with pytest.raises(InputError, match="num_bins"):
        expected_calibration_error([0.5], np.array([True]), num_bins=0)


# ----------------------------------------------------------------------------------------------
# True K per span, and scores of a CountSeries
# ----------------------------------------------------------------------------------------------


def test_window_target_counts_docstring_example() -> None:
    truth = truth_table([(0, 0.0), (0, 1.0), (0, 2.0), (1, 2.0), (1, 3.0)])
    windows = [Window((1.0,), 0, start, end) for start, end in ((0, 1), (1, 2), (3, 4))]
    np.testing.assert_array_equal(window_target_counts(truth, windows), [1, 2, 1])
    np.testing.assert_array_equal(
        span_target_counts(truth, [0.0, 1.0, 3.0], [1.0, 2.0, 4.0]), [1, 2, 1]
    )
    np.testing.assert_array_equal(span_target_counts(truth, [5.0], [6.0]), [0])
    with pytest.raises(InputError, match="start_time"):
        span_target_counts(truth, [2.0], [1.0])


def test_count_series_scores_against_truth() -> None:
    truth = truth_table([(0, 0.0), (0, 1.0), (0, 2.0), (1, 2.0), (1, 3.0)])
    counts = CountSeries(
        start_times=np.array([0.0, 1.0, 3.0]),
        end_times=np.array([1.0, 2.0, 4.0]),
        probabilities=np.array([[0.2, 0.8, 0.0], [0.0, 0.5, 0.5], [0.1, 0.3, 0.6]]),
    )
    scores = count_series_scores(truth, counts, num_bins=10)
    # True K: 1, 2, 1.  Modes (first of ties): 1, 1, 2 -> hits T, F, F.
    brier = [0.04 + 0.04 + 0.0, 0.0 + 0.25 + 0.25, 0.01 + 0.49 + 0.36]
    assert scores.brier == pytest.approx(float(np.mean(brier)))
    assert scores.hit_rate == pytest.approx(1.0 / 3.0)
    assert scores.mean_p_true == pytest.approx((0.8 + 0.5 + 0.3) / 3.0)
    # Confidences 0.8 (hit), 0.5 (miss), 0.6 (miss), each alone in its bin.
    assert scores.ece == pytest.approx((0.2 + 0.5 + 0.6) / 3.0)


def test_count_scores_bad_inputs() -> None:
    with pytest.raises(InputError, match="at least one window"):
        count_scores([], [])
    with pytest.raises(InputError, match="true_counts"):
        count_scores([Window((1.0,), 0)], [0, 1])
    with pytest.raises(InputError, match="true_counts"):
        count_scores([Window((1.0,), 0)], [-1])
    with pytest.raises(InputError, match=r"p_k"):
        count_scores([Window((math.nan,), 0)], [0])
    with pytest.raises(InputError, match="marginal_k"):
        count_scores([Window((1.0,), -1)], [0])
