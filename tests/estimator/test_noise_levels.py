"""The "auto" noise levels in the parameter EM (mapassoc.estimator.noise_levels).

Starts, the rebuilt configuration, the associations of a run's tracks, and a simulated
recording with clutter whose configuration leaves both noise levels to the recording:
estimated within 20% of the truth, and the written configuration loads and runs.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np
import pytest

from mapassoc.data.config import AutoParameters, config_to_toml, parse_config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.noise_levels import (
    LEVEL_FLOOR,
    MIN_TRACK_DETECTIONS,
    QUIET_START,
    NoiseAsked,
    NoiseLevels,
    associations_of,
    initial_noise,
    noise_m_step,
    with_noise_levels,
)
from mapassoc.estimator.parameters import estimate_parameters
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.oracle import true_associations
from mapassoc.evaluation.scenarios import build_scenario, generic_config
from mapassoc.filtering.noise_moments import chain_moments
from mapassoc.filtering.smoothing import track_log_likelihood
from mapassoc.models.interacting import InteractingModels, noise_levels
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import RandomWalk
from mapassoc.models.sensor import Sensor
from mapassoc.models.switching import SwitchingLaw


def _auto(config, q_start=None, std_start=None):  # type: ignore[no-untyped-def]
    auto = AutoParameters(
        noise_intensity=True, noise_intensity_start=q_start,
        noise_std=tuple((name, std_start) for name in config.sensors),
    )  # fmt: skip
    return dataclasses.replace(config, auto=auto)


def test_starts_given_and_from_the_data() -> None:
    built = build_scenario("crossing", 0, scans=40)
    config = _auto(built.config, 0.5, (2.0,))
    levels = initial_noise(config, built.scans, NoiseAsked.from_config(config))
    assert levels == NoiseLevels(0.5, {"pos": (2.0, 2.0)})
    config = _auto(built.config)
    levels = initial_noise(config, built.scans, NoiseAsked.from_config(config))
    # From the chains' moments (true std 1, q 0.002): near or above, never far below.
    chains = chain_moments([s.time for s in built.scans], [s.detections for s in built.scans])
    assert chains.pairs > 0
    assert levels.noise_std["pos"] == (math.sqrt(chains.measurement_variance),) * 2
    # q low: QUIET_START r / T^3 (T = 1), a tenth of the std moved per scan.
    assert levels.noise_intensity == pytest.approx(QUIET_START * chains.measurement_variance)
    assert 0.9 < levels.noise_std["pos"][0] < 1.5
    assert levels.noise_intensity < 0.02
    # Three scans hold no chain of four detections: the std from nearest neighbours
    # (from above: motion and clutter only add distance) and q where the process noise
    # over one scan interval equals that measurement noise (T = 1: Q1[0, 0] = 1/3).
    levels = initial_noise(config, built.scans[:3], NoiseAsked.from_config(config))
    std = levels.noise_std["pos"][0]
    assert std > 1.0
    assert levels.noise_intensity == pytest.approx(3 * std**2)
    # A random walk's q is not a chain's (a constant-velocity model's): T = 1, Q1 = I.
    rw = RandomWalk(ndim=2, noise_intensity=1.0)
    pos = config.sensors["pos"]
    sensor = Sensor(
        name="pos", measurement=LinearMeasurement.position(rw, noise_std=1.0),
        detection_probability=pos.detection_probability,
        false_alarms_per_scan=pos.false_alarms_per_scan, region=pos.region,
    )  # fmt: skip
    walk = dataclasses.replace(config, motion=rw, sensors={"pos": sensor})
    levels = initial_noise(walk, built.scans, NoiseAsked.from_config(walk))
    assert levels.noise_intensity == pytest.approx(levels.noise_std["pos"][0] ** 2)
    empty = [Scan(float(t), "pos", np.zeros((0, 2)), np.zeros(0, np.int64)) for t in range(3)]
    with pytest.raises(InputError, match="give noise_std_start") as info:
        initial_noise(config, empty, NoiseAsked.from_config(config))
    assert info.value.key == "noise_std_start"


def test_the_levels_rebuild_the_model() -> None:
    config = build_scenario("crossing", 0, scans=5).config
    rebuilt = with_noise_levels(config, NoiseLevels(0.25, {"pos": (2.0, 3.0)}))
    assert rebuilt.motion.noise_intensity == 0.25  # type: ignore[attr-defined]
    np.testing.assert_array_equal(rebuilt.sensors["pos"].measurement.noise_covariance,
                                  np.diag([4.0, 9.0]))  # fmt: skip
    assert with_noise_levels(config, None) is config
    assert NoiseLevels(0.25, {"pos": (2.0, 3.0)}).vector().tolist() == [0.25, 2.0, 3.0]


def test_associations_of_keep_the_longer_tracks() -> None:
    scans = [Scan(float(t), "s", np.zeros((2, 2)), np.array([10 + 2 * t, 11 + 2 * t]))
             for t in range(MIN_TRACK_DETECTIONS)]  # fmt: skip
    long = tuple(10 + 2 * t for t in range(MIN_TRACK_DETECTIONS))
    out = associations_of(scans, {1: long, 2: (11, 13)})
    assert out == {1: dict.fromkeys(range(MIN_TRACK_DETECTIONS), 0)}


@pytest.mark.slow
def test_auto_noise_levels_are_estimated_and_the_written_configuration_runs() -> None:
    """crossing (targets crossing, 10 false alarms per scan, Pd 0.9; q = 0.002, std 1),
    600 scans, from four times q and twice the std: the std within 20%, q within 25%
    (the maximum of the tracks' likelihood the ECME rounds reach is 0.00159 on this
    seed, 20.5% below the truth; the EM alone stopped at 0.00164)."""
    built = build_scenario("crossing", 0, scans=600)
    truth = generic_config(built, time_limit=600.0)
    q_true = truth.motion.noise_intensity  # type: ignore[attr-defined]
    config = parse_config(tomllib.loads(config_to_toml(_auto(truth, 4 * q_true, (2.0,)))))
    assert config.auto.noise_intensity and config.auto.noise_std_starts() == {"pos": (2.0,)}
    estimate = estimate_parameters(config, built.scans, finish=False)
    assert estimate.noise is not None and estimate.noise.noise_intensity is not None
    assert estimate.noise.noise_intensity == pytest.approx(q_true, rel=0.25)
    assert estimate.noise.noise_std["pos"][0] == pytest.approx(1.0, rel=0.2)
    record = estimate.to_json(timings=False)
    assert record["noise"] == estimate.noise.to_json()
    assert all("noise_used" in p for p in record["passes"])  # type: ignore[union-attr]
    written = parse_config(tomllib.loads(config_to_toml(estimate.config)))
    assert not written.auto.pending
    assert written.motion.noise_intensity == estimate.noise.noise_intensity  # type: ignore[attr-defined]
    result = WindowEstimator(config=written).run(built.scans[:30])
    assert len(result.track_rows) > 0


def test_a_noise_free_track_stops_the_levels_at_their_floor() -> None:
    """Exact constant-velocity positions: the EM update of both levels is 0 (and, by
    rounding, below it); the M step returns the floor, with a note, not an error."""
    config = _auto(build_scenario("crossing", 0, scans=5).config, 0.5, (2.0,))
    scans = [Scan(float(t), "pos", np.array([[1.0 * t, 2.0 * t]]), np.array([t]))
             for t in range(12)]  # fmt: skip
    asked = NoiseAsked.from_config(config)
    start = NoiseLevels(0.5, {"pos": (2.0, 2.0)})
    levels, notes = noise_m_step(config, [scans], [{1: {k: 0 for k in range(12)}}], asked, start)
    assert levels.noise_intensity is not None
    floor = LEVEL_FLOOR * start.vector()
    assert np.all(levels.vector() >= floor)
    assert np.any(np.isclose(levels.vector(), floor))  # the update went down to it
    assert any("floor" in note for note in notes)


def _levels_of(built, tracks, weights=None):  # type: ignore[no-untyped-def]
    config = _auto(built.config)
    asked = NoiseAsked.from_config(config)
    start = NoiseLevels(built.config.motion.noise_intensity, {"pos": (1.0, 1.0)})
    levels, _ = noise_m_step(built.config, [built.scans], [tracks], asked, start, weights)
    return levels


def test_false_alarms_in_tracks_weighted_by_their_probability_leave_q_near_the_truth() -> None:
    """Every seventh interior detection of each true track is replaced by a false alarm
    six noise stds off (what a track takes where its target was missed).  Counted hard,
    their residuals inflate sigma and throw q off; weighted by a low association probability (0.02,
    as the confidence pass gives such a detection) they act as misses: the estimates are
    those of the tracks without them, near the truth (q 0.002, sigma 1).  The true
    detections weigh 1."""
    built = build_scenario("crossing", 0)
    tracks = true_associations(built.scans, built.origins)
    scans = list(built.scans)
    weights: dict[int, dict[int, float]] = {}
    missed = {track_id: dict(detections) for track_id, detections in tracks.items()}
    for track_id, detections in tracks.items():
        steps = sorted(detections)
        weights[track_id] = dict.fromkeys(steps, 1.0)
        for k in steps[3:-3:7]:
            scan, j = scans[k], detections[k]
            moved = scan.detections.copy()
            moved[j] += 6.0
            scans[k] = Scan(time=scan.time, sensor=scan.sensor, detections=moved, rows=scan.rows)
            weights[track_id][k] = 0.02
            del missed[track_id][k]
    corrupted = dataclasses.replace(built, scans=scans)
    truth_q = built.config.motion.noise_intensity
    without = _levels_of(built, missed)
    hard = _levels_of(corrupted, tracks)
    soft = _levels_of(corrupted, tracks, [weights])
    assert without.noise_intensity == pytest.approx(truth_q, rel=0.5)
    assert soft.noise_intensity == pytest.approx(without.noise_intensity, rel=0.1)
    assert soft.noise_std["pos"][0] == pytest.approx(without.noise_std["pos"][0], rel=0.1)
    assert soft.noise_std["pos"][0] == pytest.approx(1.0, rel=0.1)
    # Negative control: the same detections counted hard.
    # Negative control: the same detections counted hard.  Isolated jumps read as
    # measurement noise: sigma more than doubles and q, fitted beside it, falls far off.
    assert hard.noise_std["pos"][0] > 1.5
    assert not truth_q / 3 < hard.noise_intensity < 3 * truth_q


def test_the_process_noise_search_reaches_the_maximum_the_em_creeps_towards(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Nearly constant velocity (parallel: q 2e-5 against r 1, 40 scans) from 900 times
    the truth on the true tracks: the EM's steps shrink as the likelihood flattens and
    it stops far above (the negative control, without the ECME rounds), while the search
    over q reaches levels of higher likelihood, at or below the truth (the likelihood is
    flat there: 40 scans of this process noise move a target less than its measurement
    noise), and the std stays at 1."""
    from mapassoc.estimator import noise_levels
    from mapassoc.filtering.smoothing import track_log_likelihood

    built = build_scenario("parallel", 0)
    tracks = true_associations(built.scans, built.origins)
    config = _auto(built.config)
    asked = NoiseAsked.from_config(config)
    start = NoiseLevels(0.018, {"pos": (1.0, 1.0)})

    def log_likelihood(levels: NoiseLevels) -> float:
        run = with_noise_levels(built.config, levels)
        return sum(track_log_likelihood(built.scans, d, run) for d in tracks.values())

    levels, _ = noise_m_step(built.config, [built.scans], [tracks], asked, start)
    truth_q = built.config.motion.noise_intensity
    assert levels.noise_intensity < 3 * truth_q
    assert levels.noise_std["pos"][0] == pytest.approx(1.0, rel=0.1)
    monkeypatch.setattr(noise_levels, "ECME_ROUNDS", 0)
    creeping, _ = noise_m_step(built.config, [built.scans], [tracks], asked, start)
    assert creeping.noise_intensity > 10 * truth_q
    assert log_likelihood(levels) > log_likelihood(creeping)


# ----------------------------------------------------------------- sets of motion models


def _set_asked(config, starts=(None, None)):  # type: ignore[no-untyped-def]
    """``config`` with its motion wrapped in :func:`noise_levels` (1x, 10x), each
    component's ``noise_intensity`` and every sensor's std "auto"."""
    motion = noise_levels(config.motion)
    auto = AutoParameters(
        model_noise_intensity=tuple(enumerate(starts)),
        noise_std=tuple((name, None) for name in config.sensors),
    )  # fmt: skip
    return dataclasses.replace(config, motion=motion, auto=auto)


def test_a_set_of_identical_models_scores_a_track_as_the_model_does() -> None:
    """The IMM of identical models is the Kalman filter (Blom and Bar-Shalom), so the
    track likelihood the set's levels are fitted to is the single model's."""
    built = build_scenario("crossing", 0, scans=30)
    cv = built.config.motion
    same = InteractingModels(models=[cv, cv], switching=SwitchingLaw(2, switch_probability=0.1))
    as_set = dataclasses.replace(built.config, motion=same)
    tracks = true_associations(built.scans, built.origins)
    assert len(tracks) >= 2
    for found in tracks.values():
        single = track_log_likelihood(built.scans, found, built.config)
        assert track_log_likelihood(built.scans, found, as_set) == pytest.approx(single, rel=1e-9)


def test_a_set_s_starts_are_quiet_then_loud_and_given_ones_kept() -> None:
    built = build_scenario("crossing", 0, scans=40)
    config = _set_asked(built.config)
    asked = NoiseAsked.from_config(config)
    assert asked.models == {0: None, 1: None} and asked.any
    levels = initial_noise(config, built.scans, asked)
    single = initial_noise(_auto(built.config), built.scans, NoiseAsked.from_config(_auto(
        built.config)))  # fmt: skip
    # The first model as a single model starts; the second at a tracking index of one:
    # its process noise over the median scan interval (1) moves a position by sigma^2.
    assert levels.model_intensities[0] == single.noise_intensity
    sigma2 = levels.noise_std["pos"][0] ** 2
    assert levels.model_intensities[1] == pytest.approx(sigma2 / (1.0 / 3.0))
    assert levels.noise_intensity is None
    starts = _set_asked(built.config, (0.5, 7.0))
    given = initial_noise(starts, built.scans, NoiseAsked.from_config(starts))
    assert given.model_intensities == {0: 0.5, 1: 7.0}


def test_a_set_s_levels_rebuild_its_models_and_read_back() -> None:
    built = build_scenario("crossing", 0, scans=10)
    config = _set_asked(built.config)
    asked = NoiseAsked.from_config(config)
    levels = NoiseLevels(None, {"pos": (2.0, 2.0)}, {1: 3.0})
    run = with_noise_levels(config, levels)
    assert isinstance(run.motion, InteractingModels)
    assert [m.noise_intensity for m in run.motion.models] == [  # type: ignore[attr-defined]
        config.motion.models[0].noise_intensity, 3.0]  # type: ignore[attr-defined]  # fmt: skip
    assert run.motion.switching is config.motion.switching  # type: ignore[attr-defined]
    np.testing.assert_array_equal(levels.vector(), [3.0, 2.0, 2.0])
    assert levels.to_json()["model_noise_intensity"] == {"motion.models[1]": 3.0}
    from mapassoc.estimator.noise_levels import _from_vector

    assert _from_vector(asked, levels, levels.vector()) == levels


def test_a_set_s_levels_fit_its_tracks_at_least_as_well_as_the_hand_made_set() -> None:
    """Turning aircraft (coordinated turns, 50 m noise, true associations): the set's
    levels maximise the tracks' IMM likelihood (then each process level goes to the top
    of its interval, within INTERVAL_DROP nats), so they fit at least as well as the set
    built on the true single model (the bench's ``noise_levels`` of it) and as the
    start, the quiet model stays below the loud one, and the std comes out near the
    truth (the loud model takes the turns, not the measurement noise)."""
    built = build_scenario("aircraft", 0, scans=30)
    tracks = {i: d for i, d in true_associations(built.scans, built.origins).items()
              if len(d) >= MIN_TRACK_DETECTIONS}  # fmt: skip
    config = _set_asked(built.config)
    asked = NoiseAsked.from_config(config)
    start = initial_noise(config, built.scans, asked)
    levels, notes = noise_m_step(config, [built.scans], [tracks], asked, start)
    assert notes == ()

    def fit(run) -> float:  # type: ignore[no-untyped-def]
        return sum(track_log_likelihood(built.scans, d, run) for d in tracks.values())

    truth_std = float(np.sqrt(built.config.sensors["pos"].measurement.noise_covariance[0, 0]))
    hand_made = dataclasses.replace(built.config, motion=noise_levels(built.config.motion))
    found = fit(with_noise_levels(config, levels))
    assert found >= fit(hand_made)
    assert found >= fit(with_noise_levels(config, start))
    assert levels.model_intensities[0] < levels.model_intensities[1]
    assert levels.noise_std["pos"][0] == pytest.approx(truth_std, rel=0.2)


def test_a_set_s_tracks_in_lockstep_score_as_each_track_alone() -> None:
    """The lockstep IMM over all tracks (one batched step per scan) sums each track's own
    run, with weighted detections, and with two sensors (a range-bearing one)."""
    from mapassoc.filtering.smoothing import interacting_log_likelihoods

    for name in ("aircraft", "two_sensors"):
        built = build_scenario(name, 0, scans=30)
        config = dataclasses.replace(built.config, motion=noise_levels(built.config.motion))
        tracks = list(true_associations(built.scans, built.origins).values())
        rng = np.random.default_rng(1)
        weights = ([{k: float(rng.uniform(0.2, 1.0)) for k in t} for t in tracks]
                   if name == "aircraft" else [None] * len(tracks))  # position sensor only
        alone = [track_log_likelihood(built.scans, t, config, w)
                 for t, w in zip(tracks, weights, strict=True)]
        together = interacting_log_likelihoods(built.scans, tracks, config, weights)
        np.testing.assert_allclose(together, alone, rtol=1e-10, atol=1e-9)
    with pytest.raises(InputError, match="must be a set of models"):
        interacting_log_likelihoods(built.scans, tracks, built.config)


def test_a_process_level_is_raised_to_the_upper_end_of_its_likelihood_interval() -> None:
    """A likelihood flat below 1 and falling as ``(log q)^2`` above: from a maximiser
    deep in the plateau (1e-5, several steps below) the raise reaches the largest level
    within INTERVAL_DROP of the maximum, ``exp(sqrt(INTERVAL_DROP))``; a peaked one (a
    level the data determine) moves by its own interval only."""
    from mapassoc.estimator.noise_levels import INTERVAL_DROP, _upper_end

    def plateau(values: np.ndarray) -> float:
        return -max(0.0, math.log(values[1])) ** 2

    raised = _upper_end(plateau, np.array([3.0, 1e-5]), [1], 0.0)
    assert raised == pytest.approx(math.exp(math.sqrt(INTERVAL_DROP)), rel=0.03)
    assert plateau(np.array([3.0, raised])) >= -INTERVAL_DROP

    def peaked(values: np.ndarray) -> float:
        return -100.0 * math.log(values[0] / 2.0) ** 2

    raised = _upper_end(peaked, np.array([2.0]), [0], 0.0)
    assert raised == pytest.approx(2.0 * math.exp(math.sqrt(INTERVAL_DROP / 100.0)), rel=0.03)


def test_a_set_s_levels_keep_its_order_on_straight_targets() -> None:
    """Nearly straight targets (crossing, q 0.002, true associations): the loud model is
    not needed, so its likelihood is flat and, unbounded, the two would swap; every
    search keeps the first model the quietest, and it is raised no further than the
    loud one."""
    from mapassoc.estimator.noise_levels import _neighbours

    built = build_scenario("crossing", 0, scans=40)
    tracks = true_associations(built.scans, built.origins)
    config = _set_asked(built.config)
    asked = NoiseAsked.from_config(config)
    start = initial_noise(config, built.scans, asked)
    levels, _ = noise_m_step(with_noise_levels(config, start), [built.scans], [tracks], asked,
                             start)  # fmt: skip
    assert levels.model_intensities[0] <= levels.model_intensities[1]
    values = np.array([1.0, 5.0, 2.0, 2.0])
    assert _neighbours(config.motion, NoiseLevels(None, {"pos": (2.0, 2.0)}, {0: 1.0, 1: 5.0}),
                       values, 0) == (0.0, 5.0)  # fmt: skip
    assert _neighbours(config.motion, levels, values, 1) == (1.0, math.inf)
    assert _neighbours(config.motion, levels, values, 2) == (0.0, math.inf)  # a std
