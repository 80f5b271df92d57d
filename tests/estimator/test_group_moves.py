"""Group re-solves (``mapassoc.estimator.group_moves``): the beam's child selection
against enumeration, and the move's exact, monotone J on a converging recording."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest

from mapassoc.accelerate import compiled_module
from mapassoc.estimator import group_moves
from mapassoc.estimator.group_moves import close_groups, regroup_tracks
from mapassoc.estimator.objective import RecordingObjective
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.scenarios import build_scenario, generic_config


def _enumerated(score: np.ndarray, gain: np.ndarray, branch: int, width: int) -> list[float]:
    """Every parent's partial assignments by brute force, its ``branch`` best kept, then
    the ``width`` best scores over all parents."""
    B, K, D = gain.shape
    kept = []
    for b in range(B):
        totals = []
        for choice in itertools.product(range(-1, D), repeat=K):
            used = [d for d in choice if d >= 0]
            if len(used) != len(set(used)):
                continue
            parts = [gain[b, i, d] for i, d in enumerate(choice) if d >= 0]
            if all(np.isfinite(parts)):
                totals.append(score[b] + sum(parts))
        kept.extend(sorted(totals, reverse=True)[:branch])
    return sorted(kept, reverse=True)[:width]


@pytest.mark.parametrize("seed", range(25))
def test_best_children_are_the_enumerated_best(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(seed)
    B, K, D = int(rng.integers(1, 4)), int(rng.integers(1, 4)), int(rng.integers(0, 4))
    monkeypatch.setattr(group_moves, "GROUP_BRANCH", int(rng.integers(1, 5)))
    monkeypatch.setattr(group_moves, "GROUP_BEAM", int(rng.integers(1, 9)))
    score = rng.normal(size=B)
    gain = rng.normal(size=(B, K, D))
    gain[rng.random((B, K, D)) < 0.4] = -np.inf
    history = np.arange(B * K).reshape(B, K)  # every parent its own past: no merging
    children = group_moves._best_children(score, gain, history)
    expected = _enumerated(score, gain, group_moves.GROUP_BRANCH, group_moves.GROUP_BEAM)
    got = [total for total, _, _ in children]
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    for total, b, choice in children:  # each child's score is its parent's plus its gains
        used = [d for d in choice if d >= 0]
        assert len(used) == len(set(used))
        parts = [gain[b, i, d] for i, d in enumerate(choice) if d >= 0]
        assert total == pytest.approx(score[b] + sum(parts), abs=1e-12)


def test_merged_children_keep_the_best_of_each_key() -> None:
    # Two parents with the same recent past, whose children share keys: only the first
    # (best) of a key is kept.
    score = np.array([0.0, -0.5])
    gain = np.array([[[1.0, 0.5]], [[1.0, 0.5]]])  # one head, two detections
    children = group_moves._best_children(score, gain, np.zeros((2, 1), dtype=np.int64))
    assert [(total, b, c) for total, b, c in children] == [
        (1.0, 0, (0,)),
        (0.5, 0, (1,)),
        (0.0, 0, (-1,)),
    ]
    # Different pasts: nothing merges; best first, a tie to the first parent.
    children = group_moves._best_children(score, gain, np.array([[0], [1]]))
    assert [(total, b) for total, b, _ in children] == [
        (1.0, 0), (0.5, 0), (0.5, 1), (0.0, 0), (0.0, 1), (-0.5, 1)
    ]  # fmt: skip


@pytest.mark.parametrize("seed", range(40))
def test_compiled_child_selection_equals_its_twin(seed: int) -> None:
    kernels = compiled_module("mapassoc.estimator.compiled_beam")
    if kernels is None:
        pytest.skip("numba is not installed (the accelerate extra)")
    rng = np.random.default_rng(seed)
    B, K, D = int(rng.integers(1, 7)), int(rng.integers(1, 5)), int(rng.integers(0, 7))
    score = rng.normal(size=B)
    gain = rng.normal(size=(B, K, D))
    gain[rng.random((B, K, D)) < 0.4] = -np.inf
    history = rng.integers(0, 2, size=(B, K))
    twin = group_moves._best_children(score, gain, history)
    parents, choices, scores = kernels.best_children(
        score, gain, history, group_moves.GROUP_BEAM, group_moves.GROUP_BRANCH
    )
    assert [(t, b, c) for t, b, c in twin] == [
        (float(t), int(b), tuple(int(d) for d in c))
        for t, b, c in zip(scores, parents, choices, strict=True)
    ]


def test_recent_detections_shift_by_one_scan() -> None:
    # Two rows, three scans kept: the new detection first, the oldest dropped.
    parents = np.array([[4, 5, 6], [-1, 2, 3]])
    got = group_moves._recent(parents, np.array([1, -1]), np.array([7, 9]))
    np.testing.assert_array_equal(got, [[9, 4, 5], [-1, -1, 2]])
    history = group_moves._history(np.array([[1, 2], [1, 2], [1, 3]]))
    assert history[0] == history[1] != history[2]


def test_children_share_rows_of_equal_histories() -> None:
    # Parent rows 0 and 1; children (0: miss, 1: detection 2) and (0: miss, 1: miss).
    rows, picks, slot = group_moves._child_rows(
        np.array([[0, 1], [0, 1]]), np.array([[-1, 2], [-1, -1]]), 3
    )
    assert list(zip(rows.tolist(), picks.tolist(), strict=True)) == [(0, -1), (1, -1), (1, 2)]
    np.testing.assert_array_equal(slot, [[0, 2], [0, 1]])  # the first heads share a row


@pytest.mark.slow
def test_regroup_raises_the_exact_objective_on_converging_targets() -> None:
    scenario = build_scenario("converging", 0, scans=30)
    config = generic_config(scenario, time_limit=2.0)
    forward = dataclasses.replace(  # the forward pass's set: no refinement has regrouped it
        config.estimator,
        refinement=dataclasses.replace(config.estimator.refinement, passes=0),
    )
    result = WindowEstimator(config=dataclasses.replace(config, estimator=forward)).run(
        scenario.scans
    )
    objective = RecordingObjective(config=config, scans=scenario.scans)
    tracks = {t: objective.path_of_rows(rows) for t, rows in result.track_rows.items()}
    values = {t: objective.track_value(path) for t, path in tracks.items()}
    before = sum(values.values())
    assert close_groups(objective, tracks), "the targets converge: a group must be found"

    made = regroup_tracks(objective, tracks, values)

    assert made >= 1
    after = objective.value(tracks.values())
    assert after == pytest.approx(sum(values.values()), abs=1e-9)  # the values are exact
    assert after > before + 1.0
    for tid, path in tracks.items():
        assert values[tid] == pytest.approx(objective.track_value(path), abs=1e-9)
    used = [d for path in tracks.values() for d in path]
    assert len(used) == len(set(used))  # no detection in two tracks
