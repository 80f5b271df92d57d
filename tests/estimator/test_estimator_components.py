"""WindowEstimator built from its components: ``from_config`` builds them from the
configuration's records, and one passed in is the one used."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import pytest

from mapassoc.data.settings import PruningSettings, SearchSettings
from mapassoc.errors import InputError
from mapassoc.estimator.cluster_solving import ClusterSolver
from mapassoc.estimator.hypotheses import HypothesisGenerator, WindowHypotheses
from mapassoc.estimator.pipeline import WindowEstimator, default_generator
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.models.target_count import CountPrior


class RecordingGenerator(HypothesisGenerator):
    """A generator that counts the windows it grows."""

    windows: int = 0

    def generate(self, scans: Sequence[Any], *args: Any, **kwargs: Any) -> WindowHypotheses:
        self.windows += 1
        return super().generate(scans, *args, **kwargs)


def _config() -> Any:
    scenario = build_scenario("crossing", seed=0)
    estimator = scenario.config.estimator.with_time_limit(600.0)
    return dataclasses.replace(scenario.config, estimator=estimator), scenario.scans[:8]


def test_from_config_builds_each_component_from_its_record() -> None:
    config, _ = _config()
    config = dataclasses.replace(
        config,
        estimator=dataclasses.replace(
            config.estimator,
            pruning=PruningSettings(prune_log_ratio=6.0, sibling_prune_log_ratio=4.0),
            search=SearchSettings(beam_width=17, bound_prune_log_ratio=8.0),
        ),
    )
    estimator = WindowEstimator.from_config(config)
    assert estimator.generator.prune_log_ratio == 6.0
    assert estimator.generator.sibling_prune_log_ratio == 4.0
    assert estimator.cluster_solver.beam_width == 17
    assert estimator.cluster_solver.prune_log_ratio == 8.0  # the clusters' own rule
    assert estimator.count_prior == config.estimator.count.count_prior()


def test_a_generator_passed_in_is_the_one_used_and_the_result_is_the_same() -> None:
    config, scans = _config()
    base = default_generator(config)
    recording = RecordingGenerator(
        motion=config.motion,
        sensors=config.sensors,
        birth=config.birth,
        gate_probability=base.gate_probability,
        max_hypotheses_per_tree=base.max_hypotheses_per_tree,
        prune_log_ratio=base.prune_log_ratio,
        sibling_prune_log_ratio=base.sibling_prune_log_ratio,
    )
    no_refinement = dataclasses.replace(config.estimator.refinement, passes=0)
    config = dataclasses.replace(
        config, estimator=dataclasses.replace(config.estimator, refinement=no_refinement)
    )
    swapped = WindowEstimator(config=config, generator=recording)
    assert swapped.generator is recording
    result = swapped.run(scans)
    assert recording.windows == len(result.windows) > 0
    plain = WindowEstimator.from_config(config).run(scans)
    assert result.track_rows == plain.track_rows


def test_components_of_the_wrong_kind_are_refused_by_name() -> None:
    config, _ = _config()
    with pytest.raises(InputError, match="cluster_solver must be a ClusterSolver") as info:
        WindowEstimator(config=config, cluster_solver="highs")  # type: ignore[arg-type]
    assert info.value.key == "cluster_solver"
    prior = CountPrior(kind="uniform", kmax=config.estimator.count.max_tracks)
    assert WindowEstimator(config=config, count_prior=prior).count_prior is prior
    solver = ClusterSolver.from_settings(config.estimator.search)
    assert WindowEstimator(config=config, cluster_solver=solver).cluster_solver is solver
