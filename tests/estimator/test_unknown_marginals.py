"""Windows whose marginals cannot be had: the confidence pass's beam is widened, and where
it still keeps no feasible set the window's probabilities are unknown, not a stopped run.

Found on a converging recording (six closely spaced tracks, a cluster of 2,213
hypotheses) where the marginals beam lost every frontier that could still meet the
cluster's exactly-once resources and the run stopped on a nan probability."""

from __future__ import annotations

import dataclasses
import math
import types

import numpy as np
import pytest

from mapassoc.estimator import cluster_solving
from mapassoc.estimator.cluster_solving import BEAM_WIDENING, BEAM_WIDENINGS, ClusterSolver
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.refinement import refine_track_rows
from mapassoc.evaluation.scenarios import build_scenario, generic_config


def _fake_search(finite_from: float, widths: list[int]):
    """A stand-in for the beam's frontier search: no set below ``finite_from`` frontiers."""

    def search(sub, seed, *, max_frontiers, entry_margin):
        widths.append(max_frontiers)
        total = 0.0 if max_frontiers >= finite_from else -math.inf
        return types.SimpleNamespace(log_total=np.array([total]))

    return search


@pytest.mark.parametrize("found_at", [0, 1, 2, BEAM_WIDENINGS])
def test_the_beam_widens_until_it_keeps_a_set(
    monkeypatch: pytest.MonkeyPatch, found_at: int
) -> None:
    widths: list[int] = []
    width = 7
    monkeypatch.setattr(
        cluster_solving, "frontier_marginals", _fake_search(width * BEAM_WIDENING**found_at, widths)
    )
    solver = ClusterSolver.__new__(ClusterSolver)
    solver.beam_entry_margin = 40.0
    found = solver._beam_marginals(None, np.zeros(1), width)
    assert widths == [width * BEAM_WIDENING**i for i in range(found_at + 1)]
    assert np.isfinite(found.log_total[0])


def test_the_beam_gives_up_after_its_widenings(monkeypatch: pytest.MonkeyPatch) -> None:
    widths: list[int] = []
    monkeypatch.setattr(cluster_solving, "frontier_marginals", _fake_search(math.inf, widths))
    solver = ClusterSolver.__new__(ClusterSolver)
    solver.beam_entry_margin = 40.0
    found = solver._beam_marginals(None, np.zeros(1), 5)
    assert widths == [5 * BEAM_WIDENING**i for i in range(BEAM_WIDENINGS + 1)]
    assert found.log_total[0] == -math.inf


def test_unknown_marginals_leave_existence_unknown_and_keep_the_tracks(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    scenario = build_scenario("crossing", 0, scans=10)
    config, scans = generic_config(scenario, time_limit=2.0), scenario.scans
    rows = WindowEstimator(config=config).run(scans).track_rows
    assert rows, "the crossing targets are tracked"
    known = refine_track_rows(config, scans, rows, min_existence=0.5)
    assert known.confidence is not None and known.confidence.exact
    assert all(0.0 <= p <= 1.0 for p in known.confidence.existence.values())

    original = ClusterSolver.marginals

    def unknown(self, problem, *, work_limit, beam_width):
        found = original(self, problem, work_limit=work_limit, beam_width=beam_width)
        return dataclasses.replace(found, probabilities=np.full_like(found.probabilities, np.nan))

    monkeypatch.setattr(ClusterSolver, "marginals", unknown)
    result = refine_track_rows(config, scans, rows, min_existence=0.5)

    assert result.track_rows == known.track_rows  # the refinement itself is untouched
    assert result.confidence is not None and not result.confidence.exact
    assert all(math.isnan(p) for p in result.confidence.existence.values())
    assert result.dropped == ()  # an unknown existence is not a low one
