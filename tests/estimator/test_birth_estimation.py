"""The "auto" birth model in the parameter EM (mapassoc.estimator.birth_estimation).

The M step on hand-built tracks against values derived by hand; on a population
simulated from known birth parameters with its true associations, within 20% of them,
and three times the birth rate estimated three times as large; starts; an end-to-end
estimate_parameters on a small built-in scenario whose written configuration loads and
runs.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np
import pytest

from mapassoc.data.config import (
    AUTO_BIRTH_KEYS,
    BIRTH_PLACEHOLDERS,
    AutoParameters,
    config_to_toml,
    parse_config,
)
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.birth_estimation import (
    UNSEEN_EVENTS,
    BirthAsked,
    BirthLevels,
    BlockTracks,
    birth_m_step,
    block_tracks,
    count_update,
    initial_birth,
    survival_update,
    with_birth_levels,
)
from mapassoc.estimator.noise_levels import levels_close
from mapassoc.estimator.parameters import estimate_parameters
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.oracle import true_associations
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.evaluation.simulate import TargetSpec, scan_plan_regular, simulate
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import ConstantVelocity
from mapassoc.models.population import BirthModel
from mapassoc.models.sensor import Region, Sensor


def _block(firsts, lasts, pd=1.0, scans=11, starts=True):  # type: ignore[no-untyped-def]
    return BlockTracks(
        times=np.arange(float(scans)), missed=np.full(scans, max(1.0 - pd, 1e-300)),
        firsts=np.array(firsts, dtype=np.int64), lasts=np.array(lasts, dtype=np.int64),
        starts_recording=starts,
    )  # fmt: skip


FIRSTS, LASTS = [0, 0, 0, 2, 3, 5, 7, 9], [4, 10, 6, 8, 10, 9, 10, 10]


def test_counts_with_every_detection_seen_are_the_hand_derived_mle() -> None:
    """Pd = 1: three tracks start at scan 0 and five later, over 11 scans.  The fixed
    point has u0 + rate = 3 (the scan-0 tracks split between the initial targets and a
    birth before scan 0) and rate = (5 + 3 rate / (u0 + rate)) / 11, so rate = 5 / 10
    and initial_count = 2.5."""
    initial, rate, estimable = count_update([_block(FIRSTS, LASTS)], 0.9, 1.0, 0.1)
    assert estimable
    assert rate == pytest.approx(0.5, rel=1e-6)
    assert initial == pytest.approx(2.5, rel=1e-6)
    # Fixed, the other is fitted around it: u0 = 1 gives rate from 3 - 1 at scan 0 ...
    _, rate_only, _ = count_update([_block(FIRSTS, LASTS)], 0.9, 1.0, 0.1, fit_initial=False)
    assert rate_only == pytest.approx((5 + 3 * rate_only / (1 + rate_only)) / 11, rel=1e-6)


def test_a_block_that_does_not_start_the_recording_has_no_initial_count() -> None:
    """Its scan-0 tracks are the nuisance population's: rate = 5 births over 10 scans."""
    initial, rate, estimable = count_update([_block(FIRSTS, LASTS, starts=False)], 0.9, 7.0, 0.1)
    assert not estimable and initial == 7.0
    assert rate == pytest.approx(0.5, rel=1e-6)


def test_sampled_blocks_pool_births_and_leave_out_a_later_block_s_first_scan() -> None:
    """The first block as above; a later one (nuisance start) with two tracks at its
    first scan and four after it.  rate = (5 + 3 r / (u0 + r) + 4) / (11 + 10) with
    u0 + r = 3, so rate = 9 / 20 and initial_count = 3 - 9 / 20."""
    later = _block([0, 0, 1, 4, 6, 8], [5, 10, 3, 9, 10, 10], starts=False)
    initial, rate, estimable = count_update([_block(FIRSTS, LASTS), later], 0.9, 1.0, 0.1)
    assert estimable
    assert rate == pytest.approx(9 / 20, rel=1e-6)
    assert initial == pytest.approx(3 - 9 / 20, rel=1e-6)


def test_without_tracks_the_counts_go_to_the_unseen_floor() -> None:
    initial, rate, _ = count_update([_block([], [], pd=0.5)], 0.9, 3.0, 0.4)
    assert rate == pytest.approx(UNSEEN_EVENTS / 11)
    assert initial < 1e-6


def test_survival_with_every_detection_seen_counts_ends_and_half_intervals() -> None:
    """Pd = 1: the four tracks whose last detection is before scan 10 ended, each in the
    interval after it (half of it exposure); exposure 43 time units."""
    exposure = (4 + 0.5) + 10 + (6 + 0.5) + (6 + 0.5) + 7 + (4 + 0.5) + 3 + 1
    assert exposure == 43
    found = survival_update([_block(FIRSTS, LASTS)], 0.99)
    assert found == pytest.approx(math.exp(-4 / 43), rel=1e-8)


def test_survival_weighs_the_missed_detections_after_a_track_s_end() -> None:
    """One track, detected at scans 0..8 of 10, Pd 0.5: dead before scan 9 with weight
    1 - s, alive and missed at scan 9 with weight 0.5 s (censored)."""
    found = survival_update([_block([0], [8], pd=0.5, scans=10)], 0.99)
    assert found is not None
    s = found
    w_end, w_alive = 1 - s, 0.5 * s
    ends = max(w_end / (w_end + w_alive), UNSEEN_EVENTS)
    exposure = 8 + (0.5 * w_end + 1.0 * w_alive) / (w_end + w_alive)
    assert s == pytest.approx(math.exp(-ends / exposure), rel=1e-6)
    # Pd 1 would have made the end certain: a lower survival.
    certain = survival_update([_block([0], [8], pd=1.0, scans=10)], 0.99)
    assert certain == pytest.approx(math.exp(-1 / 8.5)) and certain < s
    assert survival_update([_block([], [])], 0.99) is None


def _population(rate: float, seed: int, *, initial: float = 40.0, scans: int = 300,
                survival: float = 0.98, velocity_std: float = 1.0):  # type: ignore[no-untyped-def]
    """Targets drawn from the birth model (Poisson initial count and births before every
    scan, survival ``survival ** dt``, velocity components N(0, velocity_std^2)) in a
    region they do not leave, Pd 0.9 and almost no clutter."""  # fmt: skip
    rng = np.random.default_rng(seed)
    motion = ConstantVelocity(ndim=2, noise_intensity=1e-4)
    sensor = Sensor(
        name="pos", measurement=LinearMeasurement.position(motion, noise_std=1.0),
        detection_probability=0.9, false_alarms_per_scan=0.01,
        region=Region(np.array([-1e4, -1e4]), np.array([1e4, 1e4])),
    )  # fmt: skip
    targets = []
    for k in range(scans):
        for _ in range(rng.poisson(rate + (initial if k == 0 else 0.0))):
            life = int(np.floor(np.log(rng.random()) / np.log(survival)))  # alive k..k+life
            state = np.r_[rng.uniform(-5e3, 5e3, 2), rng.normal(0.0, velocity_std, 2)]
            targets.append(TargetSpec(state, float(k), float(min(k + life, scans - 1))))
    from mapassoc.data.config import Config
    from mapassoc.data.settings import EstimatorSettings

    config = Config(motion=motion, sensors={"pos": sensor}, birth=BirthModel(),
                    estimator=EstimatorSettings())  # fmt: skip
    return simulate(config, targets, scan_plan_regular(["pos"], 0.0, 1.0, scans), seed=seed)


def _estimated(scenario, iterations: int = 3) -> BirthLevels:  # type: ignore[no-untyped-def]
    """The M step from the true associations, iterated from the starts of the module."""
    config = scenario.config
    asked = BirthAsked(dict.fromkeys(AUTO_BIRTH_KEYS))
    levels = initial_birth(config, scenario.scans, asked)
    tracks = true_associations(scenario.scans, scenario.origins)
    for _ in range(iterations):
        levels, notes = birth_m_step(with_birth_levels(config, levels), [scenario.scans], [True],
                                     [tracks], levels)  # fmt: skip
        assert notes == ()
    return levels


def test_the_m_step_recovers_simulated_birth_parameters_and_tracks_three_times_the_rate() -> None:
    """300 scans, initial_count 40, rate 0.2, survival 0.98, velocity_std 1, Pd 0.9, the
    true associations (seeds 1-3 give rate 0.17-0.19, initial_count 30-41: a Poisson
    count of 40 has a standard deviation of 16%; seed 3 drew 30)."""
    found = _estimated(_population(0.2, seed=1)).values
    assert found["rate"] == pytest.approx(0.2, rel=0.2)
    assert found["initial_count"] == pytest.approx(40.0, rel=0.2)
    hazard = -math.log(found["survival_probability"])
    assert hazard == pytest.approx(-math.log(0.98), rel=0.2)
    assert found["velocity_std"] == pytest.approx(1.0, rel=0.2)
    tripled = _estimated(_population(0.6, seed=1), iterations=1).values
    assert tripled["rate"] / found["rate"] == pytest.approx(3.0, rel=0.2)
    assert tripled["initial_count"] == pytest.approx(found["initial_count"], rel=0.2)


def test_starts_are_the_rules_or_the_configured_values() -> None:
    built = build_scenario("crossing", 0, scans=40)
    levels = initial_birth(built.config, built.scans, BirthAsked(dict.fromkeys(AUTO_BIRTH_KEYS)))
    # crossing: ~13 detections per scan, so min(0.1, 0.01 x 13) = 0.1 births per scan
    assert levels.values["rate"] == pytest.approx(0.1)
    long = build_scenario("crossing", 0, scans=200)
    sparse = [Scan(s.time, s.sensor, s.detections[:2], s.rows[:2]) for s in long.scans]
    rule = initial_birth(long.config, sparse, BirthAsked({"rate": None}))
    assert rule.values["rate"] == pytest.approx(0.01 * 2)  # below 2 detections' clutter
    few = initial_birth(long.config, sparse[:40], BirthAsked({"rate": None}))
    assert few.values["rate"] == pytest.approx(1 / 40)  # at least one birth over the sample
    assert levels.values["initial_count"] == 1.0
    assert levels.values["survival_probability"] == pytest.approx(math.exp(-1 / 39))
    assert levels.values["velocity_std"] > 1.0  # targets' speeds ~1 plus the noise
    given = initial_birth(built.config, built.scans, BirthAsked({"rate": 0.3}))
    assert given.values == {"rate": 0.3}
    empty = [Scan(float(t), "pos", np.zeros((0, 2)), np.zeros(0, np.int64)) for t in range(3)]
    with pytest.raises(InputError, match="give velocity_std_start") as info:
        initial_birth(built.config, empty, BirthAsked({"velocity_std": None}))
    assert info.value.key == "birth.velocity_std_start"


def test_levels_rebuild_the_birth_model_and_compare() -> None:
    config = build_scenario("crossing", 0, scans=5).config
    asked = AutoParameters(birth=(("rate", None), ("velocity_std", 2.0)))
    auto = dataclasses.replace(config, auto=asked)
    rebuilt = with_birth_levels(auto, BirthLevels({"rate": 0.25}))
    assert rebuilt.birth.rate == 0.25 and rebuilt.auto.birth == (("velocity_std", 2.0),)
    assert rebuilt.birth.survival_probability == config.birth.survival_probability
    assert with_birth_levels(config, None) is config
    assert levels_close(BirthLevels({"rate": 1.0}), BirthLevels({"rate": 1.0005}), 1e-3)
    assert not levels_close(BirthLevels({"rate": 1.0}), BirthLevels({"rate": 1.01}), 1e-3)
    assert levels_close(None, None, 1e-3) and not levels_close(None, BirthLevels({}), 1e-3)


def test_block_tracks_count_tracks_of_two_detections_and_read_pd() -> None:
    config = build_scenario("crossing", 0, scans=5).config
    scans = [Scan(float(t), "pos", np.zeros((1, 2)), np.array([t])) for t in range(4)]
    block = block_tracks(config, scans, {1: {0: 0, 2: 0}, 2: {3: 0}}, True)
    assert block.firsts.tolist() == [0] and block.lasts.tolist() == [2]
    pd = config.sensors["pos"].detection_probability
    np.testing.assert_allclose(block.missed, 1 - pd)


def _auto_birth(config, **starts):  # type: ignore[no-untyped-def]
    birth = dataclasses.replace(config.birth, **{k: BIRTH_PLACEHOLDERS[k] for k in AUTO_BIRTH_KEYS})
    auto = AutoParameters(birth=tuple((k, starts.get(k)) for k in AUTO_BIRTH_KEYS))
    return dataclasses.replace(config, birth=birth, auto=auto)


def test_estimate_parameters_estimates_an_auto_birth_model_and_the_result_runs() -> None:
    """crossing, 100 scans (rate 0.08, three targets at the start, survival 0.979 per
    scan, true velocity components of RMS 1.5): every key from the default starts."""
    built = build_scenario("crossing", 0, scans=100)
    config = parse_config(tomllib.loads(config_to_toml(_auto_birth(built.config))))
    assert config.auto.birth_starts() == dict.fromkeys(AUTO_BIRTH_KEYS)
    estimate = estimate_parameters(config, built.scans, finish=False)
    assert estimate.birth is not None
    found = estimate.birth.values
    assert found["rate"] == pytest.approx(built.config.birth.rate, rel=0.2)
    assert found["initial_count"] == pytest.approx(3.0, abs=1.0)
    assert found["survival_probability"] == pytest.approx(
        built.config.birth.survival_probability, abs=0.01
    )
    assert 1.2 < found["velocity_std"] < 1.8
    record = estimate.to_json(timings=False)
    assert record["birth"] == found
    assert all("birth_used" in p for p in record["passes"])  # type: ignore[union-attr]
    written = parse_config(tomllib.loads(config_to_toml(estimate.config)))
    assert not written.auto.pending and written.birth.rate == found["rate"]
    result = WindowEstimator(config=written).run(built.scans[:30])
    assert len(result.track_rows) > 0


def test_a_sampled_recording_estimates_from_its_blocks() -> None:
    """crossing, 300 scans sampled as three blocks of 40: the first block gives
    initial_count, all three the births (measured: rate 0.0915 against 0.0867)."""
    built = build_scenario("crossing", 0, scans=300)
    config = _auto_birth(built.config)
    estimate = estimate_parameters(config, built.scans, finish=False, sample_scans=120,
                                   sample_blocks_count=3)  # fmt: skip
    assert estimate.sample_scans == 120 and estimate.warnings == ()
    assert estimate.birth is not None
    found = estimate.birth.values
    assert found["rate"] == pytest.approx(built.config.birth.rate, rel=0.2)
    assert found["initial_count"] == pytest.approx(3.0, abs=1.0)
    assert found["survival_probability"] == pytest.approx(
        built.config.birth.survival_probability, abs=0.01
    )


def test_tracks_weighted_by_existence_count_as_targets_only_that_much() -> None:
    """Sixty spurious three-scan tracks (clutter joined by chance) beside the true tracks
    of the birth-model recording (rate 0.2): with the confidence pass's existence 0 for
    them and 1 for the true ones, the M step gives what the true tracks alone give; the
    same tracks counted hard (negative control) more than double the rate and shorten
    the lives."""
    scenario = _population(0.2, seed=1)
    config = scenario.config
    asked = BirthAsked(dict.fromkeys(("rate", "initial_count", "survival_probability")))
    levels = initial_birth(config, scenario.scans, asked)
    run = with_birth_levels(config, levels)
    tracks = true_associations(scenario.scans, scenario.origins)
    rng = np.random.default_rng(5)
    starts = rng.integers(1, len(scenario.scans) - 3, 60).tolist()
    spurious = {10_000 + i: {k: 0, k + 1: 0, k + 2: 0} for i, k in enumerate(starts)}
    existence = {**dict.fromkeys(tracks, 1.0), **dict.fromkeys(spurious, 0.0)}
    both = {**tracks, **spurious}
    alone, _ = birth_m_step(run, [scenario.scans], [True], [tracks], levels)
    weighted, _ = birth_m_step(run, [scenario.scans], [True], [both], levels, [existence])
    hard, _ = birth_m_step(run, [scenario.scans], [True], [both], levels)
    for key, value in alone.values.items():
        assert weighted.values[key] == pytest.approx(value, rel=1e-9)
    assert alone.values["rate"] == pytest.approx(0.2, rel=0.2)
    assert hard.values["rate"] > 2 * alone.values["rate"]
    assert hard.values["survival_probability"] < alone.values["survival_probability"]
