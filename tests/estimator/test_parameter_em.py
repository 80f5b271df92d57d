"""The steps of the parameter EM (:class:`mapassoc.estimator.parameters.ParameterEM`),
each on hand-made inputs: the start, one M step, the convergence test, the probe and
the end of the iteration."""

from __future__ import annotations

import dataclasses
import math

import pytest

from mapassoc.errors import InputError
from mapassoc.estimator.parameters import (
    DEFAULT_PD_START,
    MIN_INTERIOR_SCANS,
    AssociationCounts,
    EMSettings,
    EMState,
    EStep,
    EstimationPass,
    ParameterEM,
)
from mapassoc.evaluation.scenarios import build_scenario


def _em(scans: int = 8, **settings: float) -> ParameterEM:
    """An EM of the crossing scenario's rate and Pd (its first ``scans`` scans)."""
    built = build_scenario("crossing", 0, scans=scans)
    return ParameterEM(
        built.config, built.scans, false_alarms=["pos"], detection_probability={"pos": None},
        settings=EMSettings.resolve(built.config, **settings),
    )  # fmt: skip


def _counts(clutter: tuple[int, ...], interior: int, detected: int) -> AssociationCounts:
    explained = 7
    return AssociationCounts(
        scans=len(clutter), detections=sum(clutter) + explained, explained=explained,
        interior_scans=interior, interior_detections=detected, clutter_per_scan=clutter,
    )  # fmt: skip


def test_initialise_starts_at_the_upper_bound_and_the_default_pd() -> None:
    em = _em()
    state = em.initialise()
    detections = sum(scan.size for scan in em.scans)
    assert state.current == {"pos": (detections / 8, DEFAULT_PD_START)}
    assert state.upper == {"pos": detections / 8} and state.rates == ("pos",)
    assert state.passes == () and not state.converged and not em.done(state)
    with pytest.raises(dataclasses.FrozenInstanceError):
        state.converged = True  # type: ignore[misc]


def test_one_m_step_gives_the_closed_form_rate_and_pd() -> None:
    em = _em()
    state = em.initialise()
    clutter = (3, 0, 5, 2, 4, 1, 6, 3)  # 24 unexplained detections over 8 scans
    m = em.m_step(state, {"pos": _counts(clutter, interior=40, detected=34)})
    assert m.updated == {"pos": (24 / 8, 34 / 40)}
    assert m.pd_estimable == {"pos": True} and m.no_clutter == {"pos": 0}
    volume = em.config.sensors["pos"].region.volume
    rate, pd = 3.0, 0.85
    poisson = sum(c * math.log(rate) - rate - math.lgamma(c + 1) for c in clutter)
    expected = poisson - 24 * math.log(volume) + 34 * math.log(pd) + 6 * math.log(1 - pd)
    assert m.objective == pytest.approx(expected, rel=1e-12)


def test_an_m_step_keeps_pd_with_too_few_interior_scans_and_notes_no_clutter() -> None:
    em = _em()
    state = em.initialise()
    m = em.m_step(state, {"pos": _counts((0,) * 8, interior=MIN_INTERIOR_SCANS - 1, detected=5)})
    assert m.updated["pos"][1] == DEFAULT_PD_START and m.pd_estimable == {"pos": False}
    assert m.updated["pos"][0] == 0.5 / 8  # half a false alarm over the scans
    assert m.no_clutter == {"pos": 8}


def test_converged_compares_against_the_tolerances() -> None:
    em = _em(rate_tolerance=0.02, pd_tolerance=0.005)
    assert em.converged({"pos": (10.0, 0.9)}, {"pos": (10.15, 0.903)})
    assert not em.converged({"pos": (10.0, 0.9)}, {"pos": (10.25, 0.9)})  # rate 2.4 %
    assert not em.converged({"pos": (10.0, 0.9)}, {"pos": (10.0, 0.91)})  # Pd 0.01


def test_a_step_probes_a_quarter_of_the_upper_bound_once_where_it_hid_every_track(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """An E step whose tracks explain nothing at the upper bound: the next pass tries a
    quarter of it, and that probe is not counted in ``max_passes``."""
    em = _em(max_passes=1)
    state = em.initialise()
    upper = state.upper["pos"]
    everything = tuple(scan.size for scan in em.scans)
    nothing = AssociationCounts(
        scans=8, detections=sum(everything), explained=0, interior_scans=0,
        interior_detections=0, clutter_per_scan=everything,
    )  # fmt: skip
    monkeypatch.setattr(em, "e_step", lambda state: EStep({"pos": nothing}, 0, None))
    after = em.step(state)
    assert after.retried and after.current["pos"] == (upper / 4, DEFAULT_PD_START)
    assert len(after.passes) == 1 and not em.done(after)
    last = em.step(after)
    assert em.done(last) and not last.converged and len(last.passes) == 2
    estimate = em.finish(last)
    assert estimate.sensors["pos"].false_alarms_per_scan == upper / 4
    assert any("detection_probability not estimable" in w for w in estimate.warnings)


def test_settings_come_from_the_configuration_unless_given() -> None:
    built = build_scenario("crossing", 0, scans=5)
    own = built.config.estimator.parameters
    settings = EMSettings.resolve(built.config, max_passes=7)
    assert settings.max_passes == 7 and settings.pd_tolerance == own.pd_tolerance
    with pytest.raises(InputError) as info:
        EMSettings.resolve(built.config, sample_blocks_count=0)
    assert info.value.key == "sample_blocks_count"


def test_done_when_converged_or_at_the_pass_limit_the_probe_not_counted() -> None:
    em = _em(max_passes=2)
    one = EstimationPass(0, {"pos": (1.0, 0.9)}, {"pos": (1.0, 0.9)}, 0.0, 1, 8, 0.0)
    state = EMState(
        current={"pos": (1.0, 0.9)}, rates=("pos",), upper={"pos": 2.0}, notes={"pos": ()},
        pd_estimable={"pos": False}, no_clutter={"pos": 0}, passes=(one,),
    )  # fmt: skip
    assert not em.done(state)
    assert em.done(dataclasses.replace(state, converged=True))
    assert em.done(dataclasses.replace(state, passes=(one, one)))
    assert not em.done(dataclasses.replace(state, passes=(one, one), retried=True))
