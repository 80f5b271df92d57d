"""Every later phase of a run polls the same ``stop`` between its units of work.

The refinement (re-solves, linking rounds), the confidence pass (windows) and the
parameter estimation's last pass raise :class:`~mapassoc.errors.StopRequested` naming
their phase at the first poll that returns True, and a stopped call that is made again
gives what an uninterrupted one gives.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable

import pytest
from support import polling_unit

from mapassoc.errors import StopRequested
from mapassoc.estimator.parameters import EstimationStopped, estimate_parameters
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.refinement import CONFIDENCE_PHASE, REFINEMENT_PHASE
from mapassoc.evaluation.scenarios import build_scenario

pytestmark = pytest.mark.slow

_UNITS = ("link_fragments", "refine", "confidence", "_forward_run")


def _unit() -> str:
    """The phase method that polled ``stop`` (the innermost of :data:`_UNITS` on the stack)."""
    return polling_unit(_UNITS)


class _StopAt:
    """A ``stop`` that records which phase polls it and fires at the n-th poll of one."""

    def __init__(self, unit: str = "", n: int = 1) -> None:
        self.unit, self.n = unit, n
        self.polls: Counter[str] = Counter()
        self.fired = False
        self.after = 0  # polls after it fired: a stop ends the phase at that same poll

    def __call__(self) -> bool:
        if self.fired:
            self.after += 1
            return True
        unit = _unit()
        self.polls[unit] += 1
        self.fired = unit == self.unit and self.polls[unit] == self.n
        return self.fired


@pytest.fixture(scope="module")
def forward() -> tuple[WindowEstimator, list, object]:
    scenario = build_scenario("crossing", seed=2, scans=30)
    estimator = WindowEstimator(config=scenario.config)
    state = estimator.start(scenario.scans)
    while not state.done:
        estimator.step(scenario.scans, state)
    return estimator, list(scenario.scans), state


def _finish(forward: tuple[WindowEstimator, list, object], stop: Callable[[], bool]) -> object:
    estimator, scans, state = forward
    return estimator.finish(scans, state, stop=stop)  # type: ignore[arg-type]


def test_each_phase_polls_the_stop_between_its_units(
    forward: tuple[WindowEstimator, list, object],
) -> None:
    counting = _StopAt()
    whole = _finish(forward, counting)
    assert counting.polls["refine"] >= 2 and counting.polls["confidence"] >= 2
    assert counting.polls["link_fragments"] >= 1
    for unit, n, phase in [
        ("refine", 1, REFINEMENT_PHASE),
        ("refine", counting.polls["refine"], REFINEMENT_PHASE),
        ("link_fragments", 1, REFINEMENT_PHASE),
        ("confidence", counting.polls["confidence"], CONFIDENCE_PHASE),
    ]:
        stop = _StopAt(unit, n)
        with pytest.raises(StopRequested) as stopped:
            _finish(forward, stop)
        assert stopped.value.phase == phase and phase in str(stopped.value)
        assert stop.after == 0, f"{unit}: polled again after the stop"
    # The state is left as it was: finishing it again gives the uninterrupted result.
    again = _finish(forward, _StopAt())
    assert again.track_rows == whole.track_rows  # type: ignore[attr-defined]
    assert again.confidence.existence == whole.confidence.existence  # type: ignore[attr-defined]


def test_the_parameter_estimation_stops_in_its_last_refinement() -> None:
    scenario = build_scenario("crossing", seed=2, scans=30)
    asked = {"false_alarms": tuple(scenario.config.sensors), "detection_probability": {}}
    stop = _StopAt("refine", 1)
    with pytest.raises(EstimationStopped) as stopped:
        estimate_parameters(scenario.config, scenario.scans, max_passes=1, stop=stop, **asked)
    assert isinstance(stopped.value, StopRequested)
    assert REFINEMENT_PHASE in str(stopped.value) and stop.after == 0
    assert stop.polls["_forward_run"] >= 1  # the pass's windows polled it first
    # finish=False leaves the refinement to the caller, with the pass's done forward run.
    estimate = estimate_parameters(
        scenario.config, scenario.scans, max_passes=1, finish=False, stop=_StopAt(), **asked
    )
    assert estimate.result is None and estimate.last_run is not None
    state, reports = estimate.last_run
    assert state.done and len(reports) == state.tally.windows
