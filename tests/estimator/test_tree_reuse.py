"""The refinement's reuse of a window's trees (``WindowBoundaries.reuse_trees``): the
trees given again equal the trees grown anew, and the refinement and its confidence
pass come out the same with and without the reuse."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mapassoc.estimator.objective import RecordingObjective, paths_from_rows
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.refinement import RefinementSettings, Refiner
from mapassoc.evaluation.scenarios import build_scenario


def _stretch(family: str, start: int, stop: int):  # type: ignore[no-untyped-def]
    scenario = build_scenario(family, seed=0)
    config = scenario.config
    no_refinement = dataclasses.replace(config.estimator.refinement, passes=0)
    config = dataclasses.replace(
        config, estimator=dataclasses.replace(config.estimator, refinement=no_refinement)
    )
    scans = scenario.scans[start:stop]
    forward = WindowEstimator(config=config).run(scans)
    objective = RecordingObjective(config=config, scans=scans)
    return config, scans, objective, paths_from_rows(objective, forward.track_rows)


def _same_trees(one, other) -> None:  # type: ignore[no-untyped-def]
    for name in ("scores", "tree", "leaf", "counts_toward_k", "detection_indptr",
                 "detection_indices"):  # fmt: skip
        np.testing.assert_array_equal(getattr(one, name), getattr(other, name))
    np.testing.assert_array_equal(one.nodes.means, other.nodes.means)
    np.testing.assert_array_equal(one.nodes.covariances, other.nodes.covariances)
    assert one.nodes_capped == other.nodes_capped


def test_a_window_gets_its_trees_again_only_while_what_enters_it_is_unchanged() -> None:
    config, scans, objective, paths = _stretch("converging", 20, 40)
    refiner = Refiner(config=config, scans=scans, settings=RefinementSettings())
    boundaries, generator = refiner.boundaries, refiner.generator
    values = {tid: objective.track_value(path) for tid, path in paths.items()}
    a, b = 8, 13
    first = boundaries.hypotheses(paths, values, a, b, generator)[0]
    again = boundaries.hypotheses(paths, values, a, b, generator)[0]
    assert again is first  # nothing changed: the same trees
    # A track entering the window loses its last detection before it: its carried
    # state changes, and the trees are grown anew (and equal those grown without reuse).
    tid = next(t for t, p in sorted(paths.items()) if p[0][0] < a - 1 and p[-1][0] >= b)
    changed = dict(paths)
    changed[tid] = tuple(p for p in paths[tid] if p[0] != max(q[0] for q in paths[tid] if q[0] < a))
    values[tid] = objective.track_value(changed[tid])
    regrown = boundaries.hypotheses(changed, values, a, b, generator)[0]
    assert regrown is not first
    fresh = Refiner(config=config, scans=scans, settings=RefinementSettings())
    fresh.boundaries.reuse_trees = False
    _same_trees(regrown, fresh.boundaries.hypotheses(changed, values, a, b, fresh.generator)[0])


@pytest.mark.parametrize(
    ("family", "start", "stop"),
    [("converging", 20, 45), pytest.param("dense_pd08", 0, 25, marks=pytest.mark.slow)],
)
def test_refinement_and_confidence_are_the_same_with_and_without_reused_trees(
    family: str, start: int, stop: int
) -> None:
    config, scans, objective, paths = _stretch(family, start, stop)
    results = []
    grown: list[int] = []
    for reuse in (True, False):
        refiner = Refiner(
            config=config, scans=scans, settings=RefinementSettings(), objective=objective
        )
        refiner.boundaries.reuse_trees = reuse
        generate = refiner.generator.generate
        calls = [0]

        def counted(*args, _generate=generate, _calls=calls, **kwargs):  # type: ignore[no-untyped-def]
            _calls[0] += 1
            return _generate(*args, **kwargs)

        refiner.generator.generate = counted  # type: ignore[method-assign]
        refined, report = refiner.refine(paths)
        sure = refiner.confidence(refined)
        grown.append(calls[0])
        results.append((refined, report.objective_after_pass, sure.existence, sure.associations))
    assert grown[0] < grown[1]  # the reuse happened
    (tracks, history, existence, associations), other = results
    assert tracks == other[0]
    assert history == other[1]
    assert existence == other[2]
    assert associations == other[3]
