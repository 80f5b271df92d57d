"""False-alarm rate and Pd from the recording (mapassoc.estimator.parameters).

Hand-counted association statistics, the M step's fixed point at the truth, estimates of
seeded simulations within stated tolerances, a recording without targets, the sampling
of long recordings, and the argument checks.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mapassoc.data.io import TrackTable
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.confidence import TrackConfidence
from mapassoc.estimator.parameters import (
    DEFAULT_PD_START,
    MIN_INTERIOR_SCANS,
    EMSettings,
    ParameterEM,
    association_counts,
    estimate_parameters,
    sample_blocks,
)
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.estimator.refinement import track_confidence
from mapassoc.evaluation.scenarios import build_scenario, generic_config


def _tracks(rows: list[tuple[int, float, int]]) -> TrackTable:
    """A TrackTable of ``(track_id, time, detection_row)`` rows of sensor "s"."""
    n = len(rows)
    return TrackTable(
        track_ids=np.array([r[0] for r in rows], dtype=np.int64),
        times=np.array([r[1] for r in rows]),
        sensors=("s",) * n,
        states=np.zeros((n, 2)),
        variances=np.ones((n, 2)),
        detection_rows=np.array([r[2] for r in rows], dtype=np.int64),
        state_names=("x", "y"),
    )


def test_association_counts_by_hand() -> None:
    # Five scans of sensor "s" with detections 10.. (ids), three per scan.
    scans = [
        Scan(float(t), "s", np.zeros((3, 2)), np.arange(10 + 3 * t, 13 + 3 * t, dtype=np.int64))
        for t in range(5)
    ]
    # Track 0: scans 0..4, detected at 0, 1, 3, 4 (ids 10, 13, 19, 22), missed at 2.
    # Track 1: scans 1..2, detected at both (ids 14, 17): no interior scan.
    tracks = _tracks([(0, 0.0, 10), (0, 1.0, 13), (0, 2.0, -1), (0, 3.0, 19), (0, 4.0, 22),
                      (1, 2.0, 17), (1, 1.0, 14)])  # fmt: skip
    counts = association_counts(scans, tracks, ["s", "other"])["s"]
    assert (counts.scans, counts.detections, counts.explained) == (5, 15, 6)
    assert counts.unexplained == 9
    assert counts.clutter_per_scan == (2, 1, 2, 2, 2)
    # Interior of track 0: scans 1, 2, 3 (two detections); track 1 has none.
    assert (counts.interior_scans, counts.interior_detections) == (3, 2)
    other = association_counts(scans, tracks, ["other"])["other"]
    assert (other.scans, other.detections, other.interior_scans) == (0, 0, 0)


def _five_scans() -> list[Scan]:
    """Five scans of sensor "s" with detections 10.. (ids), three per scan."""
    return [
        Scan(float(t), "s", np.zeros((3, 2)), np.arange(10 + 3 * t, 13 + 3 * t, dtype=np.int64))
        for t in range(5)
    ]


def _confidence(associations: dict[int, dict[int, float]]) -> TrackConfidence:
    return TrackConfidence(dict.fromkeys(associations, 1.0), associations, True, 1)


def test_soft_association_counts_by_hand() -> None:
    scans = _five_scans()
    # Track 0: scans 0..4 (ids 10, 13, -, 19, 22); track 1: scans 1..4 (14, -, 20, 23).
    tracks = _tracks([(0, 0.0, 10), (0, 1.0, 13), (0, 2.0, -1), (0, 3.0, 19), (0, 4.0, 22),
                      (1, 1.0, 14), (1, 2.0, -1), (1, 3.0, 20), (1, 4.0, 23)])  # fmt: skip
    confidence = _confidence({
        0: {10: 1.0, 13: 0.9, 14: 0.05, 16: 0.3, 17: 0.5, 19: 0.8, 22: 1.0},
        1: {14: 0.9, 17: 0.6, 18: 0.6, 20: 1.0, 23: 1.0},
    })  # fmt: skip
    counts = association_counts(scans, tracks, ["s"], confidence)["s"]
    # Interior of track 0, scans 1..3: 0.9 + 0.05, 0.3 + 0.5, 0.8; of track 1, scans 2..3:
    # 0.6 + 0.6 capped at 1, then 1.0.  D = 0.95 + 0.8 + 0.8 + 1 + 1 = 4.55 over N = 5.
    assert counts.interior_scans == 5
    assert counts.interior_detections == pytest.approx(4.55, abs=1e-12)
    assert counts.interior_detections / counts.interior_scans == pytest.approx(0.91, abs=1e-12)
    # Clutter: 1 - (sum over tracks, capped at 1) per detection; 17 is 0.5 + 0.6 -> 0.
    expected = (0 + 1 + 1, 0.1 + 0.05 + 1, 0.7 + 0 + 0.4, 0.2 + 0 + 1, 0 + 0 + 1)
    assert counts.clutter_per_scan == pytest.approx(expected, abs=1e-12)
    assert counts.unexplained == pytest.approx(6.45, abs=1e-12)
    assert counts.explained == pytest.approx(15 - 6.45, abs=1e-12)
    hard = association_counts(scans, tracks, ["s"])["s"]
    assert (hard.interior_scans, hard.interior_detections, hard.unexplained) == (5, 3, 8)


def test_soft_counts_equal_the_hard_counts_when_every_probability_is_0_or_1() -> None:
    scans = _five_scans()
    tracks = _tracks([(0, 0.0, 10), (0, 1.0, 13), (0, 2.0, -1), (0, 3.0, 19), (0, 4.0, 22),
                      (1, 1.0, 14), (1, 2.0, 17), (1, 3.0, -1), (1, 4.0, 23)])  # fmt: skip
    own = {0: {10: 1.0, 13: 1.0, 19: 1.0, 22: 1.0}, 1: {14: 1.0, 17: 1.0, 23: 1.0}}
    own[0][16] = 0.0  # a detection the track could take, with probability 0
    soft = association_counts(scans, tracks, ["s", "other"], _confidence(own))
    hard = association_counts(scans, tracks, ["s", "other"])
    assert soft == hard
    assert (hard["s"].interior_scans, hard["s"].interior_detections) == (5, 3)
    # A track the confidence does not cover is counted hard.
    assert association_counts(scans, tracks, ["s"], _confidence({0: own[0]})) == {"s": hard["s"]}


def test_an_e_step_with_soft_counts_counts_the_confidence_of_its_tracks() -> None:
    built = build_scenario("crossing", 0, scans=20)
    em = {
        soft: ParameterEM(
            built.config, built.scans, false_alarms=["pos"], detection_probability={"pos": None},
            settings=EMSettings.resolve(built.config, soft_counts=soft),
        )
        for soft in (False, True)
    }  # fmt: skip
    state = em[True].initialise()
    steps = {soft: em[soft].e_step(state) for soft in em}
    estimator = WindowEstimator(config=em[True]._pass_config(state))
    done = estimator.start(built.scans)
    while not done.done:
        estimator.step(built.scans, done)
    run = estimator.finish(built.scans, done, refine=False)  # the passes' forward run
    confidence = track_confidence(em[True]._pass_config(state), built.scans, run.track_rows)
    assert steps[True].counts == association_counts(built.scans, run.tracks, ["pos"], confidence)
    assert steps[False].counts == association_counts(built.scans, run.tracks, ["pos"])
    assert steps[True].counts != steps[False].counts


def test_sample_blocks_cover_the_recording_evenly() -> None:
    assert sample_blocks(100, sample_scans=600, blocks=6) == [(0, 100)]
    blocks = sample_blocks(6000, sample_scans=600, blocks=6)
    assert len(blocks) == 6 and all(stop - first == 100 for first, stop in blocks)
    assert blocks[0][0] == 0 and blocks[-1][1] == 6000
    assert all(a[1] <= b[0] for a, b in zip(blocks, blocks[1:], strict=False))
    assert sample_blocks(1000, sample_scans=600, blocks=1) == [(200, 800)]


def _scenario(name: str, seed: int, scans: int | None = None):  # type: ignore[no-untyped-def]
    built = build_scenario(name, seed, scans=scans)
    return built, generic_config(built, time_limit=600.0)


@pytest.mark.slow
def test_the_truth_is_a_fixed_point_of_the_update() -> None:
    """Run with the true parameters, the M step lands within the tolerances the README
    states (10% of the rate, 0.05 of Pd) of them: the iteration stays at the truth."""
    built, config = _scenario("dense_pd08", 1)
    result = WindowEstimator(config=config).run(built.scans)
    counts = association_counts(built.scans, result.tracks, ["pos"])["pos"]
    sensor = config.sensors["pos"]
    rate = counts.unexplained / counts.scans
    pd = counts.interior_detections / counts.interior_scans
    assert rate == pytest.approx(sensor.false_alarms_per_scan, rel=0.10)
    assert pd == pytest.approx(sensor.detection_probability, abs=0.05)


@pytest.mark.slow
def test_soft_counts_recover_pd_of_closely_spaced_lanes_better_than_hard_counts() -> None:
    """Run with the true parameters on the parallel lanes (2.5 noise stds apart), the
    soft count's Pd lies within 0.03 of the truth and closer to it than the hard count's,
    which the tracks' taking of neighbours' detections pushes up."""
    built, config = _scenario("parallel", 0)
    estimator = WindowEstimator(config=config)
    state = estimator.start(built.scans)
    while not state.done:
        estimator.step(built.scans, state)
    result = estimator.finish(built.scans, state, refine=False)  # the passes' forward run
    confidence = track_confidence(config, built.scans, result.track_rows)
    hard = association_counts(built.scans, result.tracks, ["pos"])["pos"]
    soft = association_counts(built.scans, result.tracks, ["pos"], confidence)["pos"]
    true = config.sensors["pos"].detection_probability
    hard_pd = hard.interior_detections / hard.interior_scans
    soft_pd = soft.interior_detections / soft.interior_scans
    assert hard_pd > true + 0.03  # the overstatement soft counts are for
    assert abs(soft_pd - true) < 0.03
    assert abs(soft_pd - true) < abs(hard_pd - true)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "seed"), [("dense_pd08", 2), ("crossing", 1)])
def test_estimates_land_near_the_truth(name: str, seed: int) -> None:
    built, config = _scenario(name, seed)
    true = config.sensors["pos"]
    passes = []
    estimate = estimate_parameters(
        config, built.scans, false_alarms=["pos"], detection_probability={"pos": None},
        on_pass=passes.append,
    )  # fmt: skip
    found = estimate.sensors["pos"]
    assert found.rate_estimated and found.pd_estimated
    assert found.false_alarms_per_scan == pytest.approx(true.false_alarms_per_scan, rel=0.10)
    assert found.detection_probability == pytest.approx(true.detection_probability, abs=0.05)
    assert estimate.warnings == ()
    assert list(estimate.passes) == passes and len(passes) <= 3
    # The first pass starts where every detection is clutter and Pd at the default.
    mean = sum(scan.size for scan in built.scans) / len(built.scans)
    assert passes[0].used["pos"] == (mean, DEFAULT_PD_START)
    # The returned values are those the last pass ran with, and its run is the result.
    assert passes[-1].used["pos"] == (found.false_alarms_per_scan, found.detection_probability)
    sensor = estimate.config.sensors["pos"]
    assert (sensor.false_alarms_per_scan, sensor.detection_probability) == passes[-1].used["pos"]
    rerun = WindowEstimator(config=estimate.config).run(built.scans)
    assert estimate.result is not None
    assert rerun.track_rows == estimate.result.track_rows  # type: ignore[attr-defined]


def test_a_recording_without_targets() -> None:
    """No target: Pd is not estimable (kept, with a message) and the rate is the mean
    detections per scan within the rate tolerance (the scenario's own configuration,
    whose birth model finds no false track in this clutter at the upper bound; the probe
    at a quarter of it finds one, and the pass after it, back at no track, lands within
    the tolerance of the mean under soft counts and exactly on it under hard ones)."""
    built = build_scenario("crossing", 0, scans=30)
    config = built.config
    rng = np.random.default_rng(7)
    region = config.sensors["pos"].region
    scans, row = [], 0
    for scan in built.scans:
        count = int(rng.poisson(3))
        z = rng.uniform(region.lower, region.upper, size=(count, 2))
        scans.append(Scan(scan.time, "pos", z, np.arange(row, row + count, dtype=np.int64)))
        row += count
    estimate = estimate_parameters(
        config, scans, false_alarms=["pos"], detection_probability={"pos": 0.9}
    )
    found = estimate.sensors["pos"]
    assert estimate.passes[-1].tracks == 0
    mean = sum(s.size for s in scans) / len(scans)
    assert found.false_alarms_per_scan == pytest.approx(mean, rel=0.02)  # rate_tolerance
    assert estimate.passes[-1].updated["pos"][0] == mean
    hard = estimate_parameters(
        config, scans, false_alarms=["pos"], detection_probability={"pos": 0.9}, soft_counts=False
    )
    assert hard.sensors["pos"].false_alarms_per_scan == mean
    assert found.rate_estimated
    assert not found.pd_estimated and found.detection_probability == 0.9
    assert any("detection_probability not estimable" in w and str(MIN_INTERIOR_SCANS) in w
               for w in estimate.warnings)  # fmt: skip
    assert estimate.converged


def test_too_few_scans_keep_the_configured_rate() -> None:
    built, config = _scenario("crossing", 0, scans=3)
    estimate = estimate_parameters(config, built.scans, false_alarms=["pos"])
    found = estimate.sensors["pos"]
    assert not found.rate_estimated
    assert found.false_alarms_per_scan == config.sensors["pos"].false_alarms_per_scan
    assert any("not estimable from 3 scans" in w for w in estimate.warnings)


@pytest.mark.slow
def test_a_long_recording_is_estimated_on_a_sample() -> None:
    built, config = _scenario("crossing", 3, scans=400)
    true = config.sensors["pos"]
    estimate = estimate_parameters(
        config, built.scans, false_alarms=["pos"], detection_probability={"pos": None},
        sample_scans=150, sample_blocks_count=3,
    )  # fmt: skip
    assert estimate.sample_scans == 150 and estimate.result is None
    assert all(p.scans == 150 for p in estimate.passes)
    found = estimate.sensors["pos"]
    assert found.false_alarms_per_scan == pytest.approx(true.false_alarms_per_scan, rel=0.10)
    assert found.detection_probability == pytest.approx(true.detection_probability, abs=0.05)


@pytest.mark.parametrize(
    ("arguments", "key"),
    [
        ({"false_alarms": ["radar"]}, "false_alarms_per_scan"),
        ({"detection_probability": {"radar": None}}, "detection_probability"),
        ({"detection_probability": {"pos": 0.0}}, "detection_probability_start"),
        ({"detection_probability": {"pos": 1.5}}, "detection_probability_start"),
        ({"detection_probability": {"pos": math.nan}}, "detection_probability_start"),
        ({"rate_tolerance": 0.0}, "rate_tolerance"),
        ({"pd_tolerance": -1.0}, "pd_tolerance"),
        ({"max_passes": 0}, "max_passes"),
        ({"sample_scans": 2.5}, "sample_scans"),
    ],
)
def test_bad_arguments_name_their_key(arguments: dict[str, object], key: str) -> None:
    built, config = _scenario("crossing", 0, scans=5)
    with pytest.raises(InputError) as info:
        estimate_parameters(config, built.scans, **arguments)  # type: ignore[arg-type]
    assert info.value.key == key


def test_the_configuration_s_auto_parameters_are_the_default_request() -> None:
    import dataclasses

    from mapassoc.data.config import AutoParameters

    built = build_scenario("crossing", 0, scans=30)
    auto = dataclasses.replace(
        built.config, auto=AutoParameters(("pos",), (("pos", 0.9),))
    )
    estimate = estimate_parameters(auto, built.scans)
    assert estimate.passes[0].used["pos"][1] == 0.9
    assert not estimate.config.auto.pending
    WindowEstimator(config=estimate.config)  # runnable: no placeholder left
    with pytest.raises(InputError) as info:
        estimate_parameters(auto, built.scans, false_alarms=["pos"])
    assert info.value.key == "auto" and "detection_probability" in str(info.value)


def test_too_few_scans_for_an_auto_rate_use_the_mean_detections() -> None:
    """An "auto" rate has no configured number to keep: with too few scans it is the mean
    detections per scan (never the configuration's placeholder of no false alarms)."""
    import dataclasses

    from mapassoc.data.config import AutoParameters

    built = build_scenario("crossing", 0, scans=3)
    auto = dataclasses.replace(built.config, auto=AutoParameters(("pos",), ()))
    estimate = estimate_parameters(auto, built.scans)
    found = estimate.sensors["pos"]
    assert found.false_alarms_per_scan == sum(s.size for s in built.scans) / 3 > 0
    assert any("used the mean detections per scan" in w for w in estimate.warnings)


def _clutter_free_lanes(scans: int) -> list[Scan]:
    """Two targets crossing the region on straight lanes, detected every scan, no clutter."""
    rng = np.random.default_rng(0)
    out = []
    for t in range(scans):
        z = np.array([[-40.0 + 2 * t, 0.0], [40.0 - 2 * t, 50.0]]) + rng.normal(size=(2, 2))
        out.append(Scan(float(t), "pos", z, np.array([2 * t, 2 * t + 1], dtype=np.int64)))
    return out


def test_a_clutter_free_recording_gets_a_small_positive_rate() -> None:
    """Every detection in a track: the update would say 0 false alarms, which the
    estimator cannot score against ("auto" once failed with "needs a positive rate");
    it is half a false alarm over the scans instead, with a note, and the two lanes are
    the two tracks."""
    from mapassoc.estimator.parameters import UNSEEN_FALSE_ALARMS

    built = build_scenario("crossing", 0, scans=3)
    config = generic_config(built, time_limit=600.0)
    scans = _clutter_free_lanes(20)
    estimate = estimate_parameters(config, scans, false_alarms=["pos"])
    found = estimate.sensors["pos"]
    assert found.rate_estimated
    assert found.false_alarms_per_scan == UNSEEN_FALSE_ALARMS / 20
    assert any("shows no false alarms" in w and "20 scans" in w for w in estimate.warnings)
    assert estimate.result is not None
    rows = sorted(sorted(r) for r in estimate.result.track_rows.values())  # type: ignore[attr-defined]
    assert rows == [list(range(0, 40, 2)), list(range(1, 40, 2))]

