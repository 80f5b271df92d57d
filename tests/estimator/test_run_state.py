"""start/step/finish: the stepped run equals run(); a pickled state continues exactly."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.scenarios import build_scenario


def test_pickled_state_continues_exactly_as_run() -> None:
    scenario = build_scenario("crossing", 1)
    estimator = WindowEstimator(config=scenario.config)
    whole = estimator.run(scenario.scans)
    state = estimator.start(scenario.scans)
    reports = []
    while not state.done:
        reports.append(estimator.step(scenario.scans, state))
        if len(reports) % 7 == 0:  # what a checkpoint and a resume do, with a new estimator
            state = pickle.loads(pickle.dumps(state))
            estimator = WindowEstimator(config=scenario.config)
    stepped = estimator.finish(scenario.scans, state, windows=reports)
    assert stepped.track_rows == whole.track_rows
    np.testing.assert_array_equal(stepped.tracks.states, whole.tracks.states)
    assert [r.to_json(timings=False) for r in stepped.windows] == [
        r.to_json(timings=False) for r in whole.windows
    ]
    assert stepped.summary(timings=False) == whole.summary(timings=False)
    assert whole.tally.windows == len(whole.windows)
    assert whole.tally.hypotheses == sum(r.hypotheses_kept for r in whole.windows)


def test_step_and_finish_check_the_state() -> None:
    scenario = build_scenario("crossing", 1)
    estimator = WindowEstimator(config=scenario.config)
    state = estimator.start(scenario.scans)
    with pytest.raises(InputError, match="not done: 0 of 60 scans"):
        estimator.finish(scenario.scans, state)
    with pytest.raises(InputError, match="run over 60 scans, got 59"):
        estimator.step(scenario.scans[:-1], state)


def test_an_absurd_time_step_is_an_input_error_up_front() -> None:
    scenario = build_scenario("crossing", 1)
    far = Scan(time=1e200, sensor=scenario.scans[-1].sensor,
               detections=np.zeros((0, 2)), rows=np.zeros(0, dtype=np.int64))
    estimator = WindowEstimator(config=scenario.config)
    with pytest.raises(InputError, match=r"1e\+200 apart: too long a step .* unit"):
        estimator.start([*scenario.scans, far])


def test_max_tracks_zero_warns() -> None:
    import dataclasses

    scenario = build_scenario("crossing", 1)
    settings = dataclasses.replace(scenario.config.estimator, max_tracks=0)
    config = dataclasses.replace(scenario.config, estimator=settings)
    with pytest.warns(RuntimeWarning, match="max_tracks = 0: every detection is a false alarm"):
        result = WindowEstimator(config=config).run(scenario.scans[:8])
    assert result.track_rows == {}
