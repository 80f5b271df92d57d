"""Noise levels from the recording: the ``"auto"`` process and measurement noise of the
parameter EM (:mod:`mapassoc.estimator.parameters`).

The EM of the sensor parameters runs the window estimator (the E step of the
associations) and counts what its tracks say; the noise levels join it there.  Given a
pass's associations, the noise levels are the fixed point of Shumway and Stoffer's EM
for linear state-space models ("An approach to time series smoothing and forecasting
using the EM algorithm", J. Time Series Analysis 1982) on those tracks: every track is
smoothed under the current levels with its lag-one cross-covariances, the M step of
:mod:`mapassoc.filtering.noise_estimation` gives new levels, and the two alternate,
accelerated by SQUAREM, until they settle (at most :data:`MAX_NOISE_UPDATES` smoothings
of the tracks; they are cheap beside a pass of the window estimator).  Iterating to the
fixed point within one pass, rather than making one M step per pass, is what lets three
passes suffice: one update closes only a few per cent of the distance where the
measurement noise hides the process noise.

ECME for the process noise.  Even accelerated, the EM creeps where the tracks'
likelihood is flat in ``q`` (nearly constant velocity: over the recording the process
noise moves a target less than the measurement noise does), and its stopping rule, a
small relative step, ends it far from the maximum: on ``parallel``'s true tracks (q
2e-5) it stopped at 6e-4 after :data:`MAX_NOISE_UPDATES` updates from the quiet start
and at 1.3e-4 with no limit.  So the EM's result is refined by rounds of Liu and Rubin's
ECME ("The ECME algorithm: a simple extension of EM and ECM with faster monotone
convergence", Biometrika 1994): an EM update of every level, then ``q`` replaced by the
maximiser of the tracks' observed-data (innovations) log-likelihood at the updated stds
(:func:`~mapassoc.filtering.smoothing.track_log_likelihood`, a golden-section search on
``log q``, about twenty forward passes of the tracks), at most :data:`ECME_ROUNDS`
rounds.  Each round cannot lower the likelihood, as an EM step cannot.  Where the
likelihood is flat the maximiser can lie far below the truth (on ``parallel``'s true
tracks, 40 scans, it is 1e-8 against 2e-5 at a likelihood 0.01 higher): the data do not
tell the two apart, and the tracks they give are the same.

Decisions:

* Only tracks with at least :data:`MIN_TRACK_DETECTIONS` detections enter the sums: a
  short track is more often clutter joined by chance, whose residuals are not the
  sensor's noise, and a two-detection track says little about either level.
* Starts.  Without a configured start, a position sensor's std starts at ``sqrt(r)``
  from the moments of nearest-neighbour chains of detections
  (:func:`mapassoc.filtering.noise_moments.chain_moments`, what ``mapassoc init-config``
  writes): clutter in the chains and manoeuvres only add to it, so it is near the truth
  or above, the side the std must start from (too small a std breaks tracks into single
  detections, which carry no information about the noise).  A constant-velocity model's
  ``noise_intensity`` starts low, at :data:`QUIET_START` ``r / T^3`` with ``T`` the
  chains' median scan interval (nearly constant velocity: the floor of the chains'
  estimate), and not at the chains' ``q``: from above, the wide gates of a large ``q``
  take false alarms into the tracks, whose residuals then confirm the large ``q`` (and a
  ``Pd`` near 1) pass after pass, while from below the tracks' pieces still measure the
  targets' accelerations and the EM rises.  On seed 0 (scenario truth in brackets) the
  chains' ``q`` ended at 1.62 (0.0005) on ``dense_pd08``, with ``Pd`` 1.00 (0.8), and
  the low start at 0.000503, ``Pd`` 0.851; on ``aircraft`` (turning, 50 m noise) the low
  start rose from 0.66 to 16 and gave a lower GOSPA than the configured values; the
  changelog has every number.  Without a chain of four detections the std starts at
  ``sqrt(median(r^2) / (2 d))``, ``r`` the distance of each detection to the nearest
  detection of the sensor's previous scan and ``d`` the position components (for a
  target that does not move between scans ``r^2`` is the squared difference of two
  measurement errors, ``2 sigma^2`` per component).  Then, and for the other models'
  ``noise_intensity`` (random walk, constant acceleration: the chains' moments are a
  constant-velocity model's), ``q`` starts where the process noise over the recording's
  median scan interval ``T`` moves a position as much as the measurement noise does:
  ``q Q1(T)[0, 0] = sigma^2`` (a tracking index of one in Kalata's sense), with
  ``sigma^2`` the mean position variance of the position sensors (their starts where
  estimated).
* Association weights (``soft_counts``, the default).  A hard association puts every
  detection a track took into its noise sums, and a false alarm taken at a scan where
  the target was missed (or a neighbour's detection) leaves a residual of many noise
  stds and bends the smoothed path: its acceleration inflates ``q``, the wider gates of
  the next pass take more false alarms, and the EM confirms itself (on ``parallel`` the
  hard estimate of ``q`` ended 34 to 166 times the truth).  The confidence pass the
  soft counts run (:mod:`mapassoc.estimator.confidence`) gives each detection the
  probability ``w`` that it is the track's own, and the noise sums take it as an EM
  takes an uncertain association (Dempster, Laird and Rubin, "Maximum likelihood from
  incomplete data via the EM algorithm", 1977): the detection is smoothed with noise
  covariance ``R / w`` (the synthetic measurement of Streit and Luginbuhl's
  probabilistic multi-hypothesis tracking, 1995) and counts ``w`` in the ``sigma``
  sums (:mod:`mapassoc.filtering.noise_estimation`), so a detection of low probability
  acts nearly as a miss.  The other detections the track could have taken are left
  out (PMHT would blend them in): the MAP set's choice is kept, only its certainty is
  weighed.  Weights are floored at :data:`MIN_DETECTION_WEIGHT`; a track the confidence
  does not cover counts hard.
* Convergence: the levels moved by at most ``rate_tolerance`` (relative) from one pass
  to the next, the tolerance of the false-alarm rates.

Sets of motion models (``[motion] model = "imm"``, a component's ``noise_intensity =
"auto"``). Shumway and Stoffer's M step needs one linear model's smoothed moments and
lag-one covariances; under a set the smoothed moments are Kim's approximation and the M
step of a component would weigh every transition by a smoothed model probability that is
itself approximate. So for a set every level asked for (each component's
``noise_intensity``, each sensor's std) is the maximiser of the tracks' IMM predictive
likelihood (:func:`~mapassoc.filtering.smoothing.track_log_likelihood`), the quantity
the trees, J and the refinement score tracks with: rounds of a golden-section search on
one level at a time in the log (coordinate ascent, at most :data:`ECME_ROUNDS` rounds,
each search as the ECME rounds' of a single model), a level kept only where the
likelihood does not fall. Then each process noise but the loudest is raised to the upper
end of its 95% likelihood interval (the largest level within :data:`INTERVAL_DROP` nats
of the maximum, the others held): the quiet model's likelihood is flat over decades
below the truth on nearly straight targets (the loud model takes every deviation), so
the maximiser wanders down that plateau pass after pass to the numerical floor, and a
quiet model with no process noise makes overconfident, rigid tracks that the data did
not ask for. Every search keeps a component's level between its neighbours' in the set's
order (the first the quietest): where the loud model is not needed its likelihood is
flat too, and the two would otherwise swap roles, leaving the track starter loud. Where
the data do determine a level its interval is narrow and the raise small; where they do
not, the level is the largest they do not reject. The likelihood is the IMM's own (Blom
and Bar-Shalom, IEEE TAC 1988), so the estimate inherits its one approximation, the
merging of the model-conditioned Gaussians (:mod:`mapassoc.filtering.imm`); Bar-Shalom,
Li and Kirubarajan (2001, chapter 11) leave a set's noise levels to its designer.
Starts: the first component, which starts every track and fits the straight legs, starts
as a single model does (quiet, above); each later one, there for the manoeuvres, at the
tracking index one start ``sigma^2 / Q1(T)[0, 0]`` of that component, times ten per
component after the second (:data:`~mapassoc.models.interacting.NOISE_LEVELS`' loud
factor), so that the set's models start apart and a manoeuvre is not fitted from the
quiet side only. A set's components keep their order: the first stays the track starter
whatever its estimate.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.filtering.noise_estimation import (
    NoiseSums,
    accelerated_em,
    noise_sums,
    position_sensor,
    scalable_process_noise,
    unit_process_noise,
)
from mapassoc.filtering.noise_moments import ChainMoments, chain_moments
from mapassoc.filtering.smoothing import interacting_log_likelihoods, track_log_likelihood
from mapassoc.models.interacting import NOISE_LEVELS, InteractingModels
from mapassoc.models.measurement import LinearMeasurement
from mapassoc.models.motion import ConstantVelocity, MotionModel
from mapassoc.models.sensor import Sensor

__all__ = [
    "LEVEL_FLOOR",
    "QUIET_START",
    "MAX_NOISE_UPDATES",
    "MIN_TRACK_DETECTIONS",
    "MIN_DETECTION_WEIGHT",
    "ECME_ROUNDS",
    "ECME_SPAN",
    "ECME_NEAR_SPAN",
    "ECME_LOG_TOLERANCE",
    "INTERVAL_DROP",
    "association_weights",
    "NOISE_TOLERANCE",
    "NoiseAsked",
    "NoiseLevels",
    "associations_of",
    "initial_noise",
    "noise_m_step",
    "Levels",
    "levels_close",
    "with_noise_levels",
]

MAX_NOISE_UPDATES = 30
"""Most smoothings of a pass's tracks in one noise M step."""
NOISE_TOLERANCE = 1e-3
"""Relative change of every level below which the inner iteration stops."""
QUIET_START = 0.01
"""A constant-velocity model's ``noise_intensity`` starts at ``QUIET_START r / T^3``:
the process noise moves a position over one scan interval ``T`` by a tenth of the
measurement noise's std (module docstring, starts)."""
LEVEL_FLOOR = 1e-6
"""The least level one pass's noise M step returns, as a share of the level the pass ran
with: the EM update of a noise-free recording is 0 and, by rounding, below it, which no
Gaussian model takes; a floor relative to the start keeps the scale of the data's units
and lets each pass move the levels by six orders of magnitude."""
MIN_TRACK_DETECTIONS = 5
"""Fewest detections of a track whose smoothed moments enter the noise sums."""
MIN_DETECTION_WEIGHT = 1e-3
"""The least weight of a track's detection in the noise sums (module docstring): the
confidence pass leaves out probabilities below 1e-4, and a weight must be > 0 (the
smoother divides ``R`` by it); at 1e-3 the detection's noise is 30 stds, a miss in all
but name."""


@dataclass(frozen=True)
class NoiseAsked:
    """The noise levels a configuration leaves to the recording.

    Attributes
    ----------
    process : bool
        Whether ``[motion] noise_intensity`` is "auto".
    process_start : float or None
    stds : dict of str to tuple of float or None
        Position sensors whose ``noise_std`` is "auto", with their starts.
    models : dict of int to float or None
        Components of a set of motion models (positions in ``[[motion.models]]``) whose
        ``noise_intensity`` is "auto", with their starts.
    """

    process: bool
    process_start: float | None
    stds: dict[str, tuple[float, ...] | None]
    models: dict[int, float | None] = field(default_factory=dict)

    @classmethod
    def from_config(cls, config: Config) -> NoiseAsked:
        """What ``config.auto`` asks, checked.

        Raises
        ------
        InputError
            A process noise asked of a model without one scale, or a std of a sensor
            that is not a position sensor (naming the key).
        """
        auto = config.auto
        if auto.noise_intensity and not scalable_process_noise(config.motion):
            unit_process_noise(config.motion, 1.0)  # raises, naming the key
        models = auto.model_noise_starts()
        if models and not isinstance(config.motion, InteractingModels):
            raise InputError(
                f"auto names components {sorted(models)} of [[motion.models]], but the motion "
                f"model is not a set: {config.motion!r}", key="motion.models",
            )  # fmt: skip
        for index in models:
            component = config.motion.models[index]  # type: ignore[attr-defined]
            if not scalable_process_noise(component):
                raise InputError(
                    f'"auto" needs a model whose process noise is noise_intensity times a '
                    f"fixed matrix, got {component!r}",
                    key=f"motion.models[{index}].noise_intensity",
                )  # fmt: skip
        for name in auto.noise_std_starts():
            if not position_sensor(config.sensors[name].measurement):
                raise InputError(
                    f"sensor '{name}' noise_std = \"auto\" needs a position sensor, got "
                    f"{config.sensors[name].measurement!r}", key="noise_std",
                )  # fmt: skip
        return cls(auto.noise_intensity, auto.noise_intensity_start, auto.noise_std_starts(),
                   dict(sorted(models.items())))  # fmt: skip

    @property
    def any(self) -> bool:
        return self.process or bool(self.stds) or bool(self.models)

    def pooled(self, name: str) -> bool:
        """Whether sensor ``name``'s std is one value for all components."""
        start = self.stds[name]
        return start is None or len(start) == 1


@dataclass(frozen=True)
class NoiseLevels:
    """Values of the levels asked for.

    Attributes
    ----------
    noise_intensity : float or None
        None when not asked for.
    noise_std : dict of str to tuple of float
        Per sensor asked for, one std per position component.
    model_intensities : dict of int to float
        Per component of a set of motion models asked for (its position in
        ``[[motion.models]]``), its ``noise_intensity``; in increasing order.
    """

    noise_intensity: float | None
    noise_std: dict[str, tuple[float, ...]]
    model_intensities: dict[int, float] = field(default_factory=dict)

    def vector(self) -> FloatArray:
        """The values in one positive vector (``noise_intensity`` first, then the
        components' in their order, then the stds)."""
        head = [] if self.noise_intensity is None else [self.noise_intensity]
        head += list(self.model_intensities.values())
        return np.array(head + [v for stds in self.noise_std.values() for v in stds], float)

    def to_json(self) -> dict[str, object]:
        out: dict[str, object] = {}
        if self.noise_intensity is not None:
            out["noise_intensity"] = self.noise_intensity
        if self.model_intensities:
            out["model_noise_intensity"] = {
                f"motion.models[{index}]": value for index, value in self.model_intensities.items()
            }
        out["noise_std"] = {name: list(stds) for name, stds in self.noise_std.items()}
        return out


def _from_vector(asked: NoiseAsked, like: NoiseLevels, values: FloatArray) -> NoiseLevels:
    """:meth:`NoiseLevels.vector` read back (a pooled std given once per component)."""
    it = iter(values.tolist())
    q = next(it) if like.noise_intensity is not None else None
    models = {index: next(it) for index in like.model_intensities}
    return NoiseLevels(q, {name: tuple(next(it) for _ in stds) for name, stds in
                           like.noise_std.items()}, models)  # fmt: skip


def with_noise_levels(config: Config, levels: NoiseLevels | None) -> Config:
    """``config`` with the levels: the motion model rebuilt with ``noise_intensity``, the
    sensors asked for with position measurements of their stds (the rest unchanged)."""
    if levels is None:
        return config
    motion = config.motion
    if levels.noise_intensity is not None:
        motion = _scaled(motion, levels.noise_intensity)
    if levels.model_intensities and isinstance(motion, InteractingModels):
        motion = InteractingModels(
            models=[_scaled(model, levels.model_intensities[index])
                    if index in levels.model_intensities else model
                    for index, model in enumerate(motion.models)],
            switching=motion.switching,
            initial_probabilities=motion.initial_probabilities.tolist(),
        )  # fmt: skip
    sensors = {}
    for name, sensor in config.sensors.items():
        measurement = sensor.measurement
        if name in levels.noise_std:
            measurement = LinearMeasurement.position(motion, noise_std=levels.noise_std[name])
        sensors[name] = Sensor(
            name=name, measurement=measurement, detection_probability=sensor.detection_probability,
            false_alarms_per_scan=sensor.false_alarms_per_scan, region=sensor.region,
        )  # fmt: skip
    return Config(
        motion=motion, sensors=sensors, birth=config.birth, estimator=config.estimator,
        source=config.source, auto=config.auto, trackers=config.trackers,
        recording=config.recording,
    )  # fmt: skip


def _scaled(motion: MotionModel, noise_intensity: float) -> MotionModel:
    """A kinematic model (:func:`scalable_process_noise`) rebuilt with another
    ``noise_intensity``."""
    kind: Any = type(motion)  # built from ndim and noise_intensity
    return kind(ndim=motion.ndim, noise_intensity=noise_intensity)  # type: ignore[attr-defined]


def _std_start(scans: Sequence[Scan], name: str) -> float | None:
    """The data's start of sensor ``name``'s std (module docstring); None without two
    consecutive scans with detections."""
    squares: list[FloatArray] = []
    previous: FloatArray | None = None
    for scan in scans:
        if scan.sensor != name:
            continue
        if previous is not None and previous.size and scan.size:
            diff = scan.detections[:, None, :] - previous[None, :, :]
            squares.append(np.min(np.sum(diff**2, axis=-1), axis=1))
        previous = scan.detections
    if not squares:
        return None
    d = previous.shape[1] if previous is not None else 1
    return float(np.sqrt(np.median(np.concatenate(squares)) / (2 * d))) or None


def initial_noise(config: Config, scans: Sequence[Scan], asked: NoiseAsked) -> NoiseLevels:
    """The first pass's levels: the configured starts, else the data's (module docstring).

    Raises
    ------
    InputError
        No start can be found (naming the start key to give).
    """
    chains = _chains(config, scans)
    stds: dict[str, tuple[float, ...]] = {}
    for name, start in asked.stds.items():
        d = config.sensors[name].measurement.measurement_dim
        if start is None and name in chains:
            start = (math.sqrt(chains[name].measurement_variance),)
        if start is None:
            found = _std_start(scans, name)
            if found is None:
                raise InputError(
                    f"sensor '{name}' noise_std = \"auto\": the recording has no two "
                    "consecutive scans with detections to start from; give noise_std_start",
                    key="noise_std_start",
                )
            start = (found,)
        stds[name] = tuple(start) * d if len(start) == 1 else tuple(start)
    q = None
    if asked.process:
        q = asked.process_start
        if q is None:
            q = _quiet_start(config, scans, stds, chains, config.motion)
    models: dict[int, float] = {}
    for index, given in asked.models.items():
        component: MotionModel = config.motion.models[index]  # type: ignore[attr-defined]
        if given is None and index == 0:
            given = _quiet_start(config, scans, stds, chains, component)
        elif given is None:
            loud = NOISE_LEVELS[-1] ** (index - 1)
            given = loud * _q_start(config, scans, stds, component, f"motion.models[{index}]")
        models[index] = given
    return NoiseLevels(q, stds, models)


def _quiet_start(
    config: Config,
    scans: Sequence[Scan],
    stds: Mapping[str, tuple[float, ...]],
    chains: Mapping[str, ChainMoments],
    model: MotionModel,
) -> float:
    """The start of a single model's ``noise_intensity``, or of a set's first model's:
    :data:`QUIET_START` of the chains' for constant velocity, else :func:`_q_start`
    (module docstring, starts)."""
    if chains and isinstance(model, ConstantVelocity):
        return float(np.median([QUIET_START * m.measurement_variance / m.period**3
                                for m in chains.values()]))  # fmt: skip
    return _q_start(config, scans, stds, model, "motion")


def _chains(config: Config, scans: Sequence[Scan]) -> dict[str, ChainMoments]:
    """The nearest-neighbour chain moments of each position sensor with at least one
    chain of four detections (module docstring, starts)."""
    out: dict[str, ChainMoments] = {}
    for name, sensor in config.sensors.items():
        if not position_sensor(sensor.measurement):
            continue
        own = [scan for scan in scans if scan.sensor == name]
        moments = chain_moments([scan.time for scan in own], [scan.detections for scan in own])
        if moments.pairs and moments.measurement_variance > 0:
            out[name] = moments
    return out


def _q_start(
    config: Config,
    scans: Sequence[Scan],
    stds: Mapping[str, tuple[float, ...]],
    model: MotionModel,
    key: str,
) -> float:
    """``sigma^2 / Q1(T)[0, 0]`` of ``model`` (module docstring); ``key``: the table whose
    ``noise_intensity_start`` an error asks for."""
    variances = [
        np.array(stds[name]) ** 2 if name in stds else np.diag(sensor.measurement.noise_covariance)
        for name, sensor in config.sensors.items()
        if position_sensor(sensor.measurement)
    ]
    steps = np.diff(np.unique([scan.time for scan in scans]))
    if not variances or steps.size == 0:
        raise InputError(
            f'{key}.noise_intensity = "auto" has no start: the recording needs a position '
            "sensor and two scan times; give noise_intensity_start",
            key=f"{key}.noise_intensity_start",
        )
    unit = unit_process_noise(model, float(np.median(steps)))
    return float(np.mean(np.concatenate(variances)) / unit[0, 0])


def associations_of(
    scans: Sequence[Scan],
    track_rows: Mapping[int, Sequence[int]],
    min_detections: int = MIN_TRACK_DETECTIONS,
) -> dict[int, dict[int, int]]:
    """Track id -> {scan index -> detection index} of the tracks with at least
    ``min_detections`` detections (default :data:`MIN_TRACK_DETECTIONS`), from their
    detection ids."""
    where = {int(row): (k, j) for k, scan in enumerate(scans)
             for j, row in enumerate(scan.rows.tolist())}  # fmt: skip
    out: dict[int, dict[int, int]] = {}
    for track_id, rows in track_rows.items():
        if len(rows) >= min_detections:
            out[int(track_id)] = dict(where[int(row)] for row in rows)
    return out


def association_weights(
    scans: Sequence[Scan],
    track_rows: Mapping[int, Sequence[int]],
    probabilities: Mapping[int, Mapping[int, float]],
) -> dict[int, dict[int, float]]:
    """Track id -> {scan index -> weight of its detection there}: the probability that the
    detection is the track's own (module docstring), within
    [:data:`MIN_DETECTION_WEIGHT`, 1].

    Parameters
    ----------
    scans : sequence of Scan
        The scans the tracks were found on.
    track_rows : mapping of int to sequence of int
        Track id -> its detection ids.
    probabilities : mapping of int to mapping of int to float
        Track id -> {detection id -> probability that the track uses it}
        (:attr:`~mapassoc.estimator.confidence.TrackConfidence.associations`); a track
        without an entry is left out (its detections count 1).
    """
    scan_of = {int(row): k for k, scan in enumerate(scans) for row in scan.rows.tolist()}
    out: dict[int, dict[int, float]] = {}
    for track_id, rows in track_rows.items():
        own = probabilities.get(int(track_id))
        if own is None:
            continue
        out[int(track_id)] = {
            scan_of[int(row)]: min(1.0, max(MIN_DETECTION_WEIGHT, own.get(int(row), 0.0)))
            for row in rows
        }
    return out


def noise_m_step(
    config: Config,
    pieces: Sequence[Sequence[Scan]],
    associations: Sequence[Mapping[int, Mapping[int, int]]],
    asked: NoiseAsked,
    current: NoiseLevels,
    weights: Sequence[Mapping[int, Mapping[int, float]]] | None = None,
) -> tuple[NoiseLevels, tuple[str, ...]]:
    """The levels the pass's associations give (module docstring), and notes of what
    they could not estimate (a level without a transition or a detection stays).

    Parameters
    ----------
    config : Config
        The pass's configuration (sensor parameters filled in).
    pieces : sequence of sequence of Scan
        The sample's blocks.
    associations : sequence of mapping
        Per block, its tracks (:func:`associations_of`).
    asked : NoiseAsked
    current : NoiseLevels
        The levels the pass ran with (the iteration's start).
    weights : sequence of mapping, optional
        Per block, track id -> {scan index -> weight of its detection}
        (:func:`association_weights`); default: every detection counts 1.
    """
    if isinstance(config.motion, InteractingModels):
        return _interacting_m_step(config, pieces, associations, asked, current, weights)
    notes: list[str] = []
    per_block = [None] * len(pieces) if weights is None else list(weights)

    def sums_at(levels: NoiseLevels) -> NoiseSums:
        run = with_noise_levels(config, levels)
        parts = [noise_sums(piece, assoc, run, list(asked.stds), weight)
                 for piece, assoc, weight in zip(pieces, associations, per_block,
                                                 strict=True)]  # fmt: skip
        total = parts[0]
        for part in parts[1:]:
            total = total.plus(part)
        return total

    def update(values: FloatArray) -> FloatArray:
        levels = _from_vector(asked, current, values)
        sums = sums_at(levels)
        q = levels.noise_intensity
        if q is not None and sums.process.intensity is not None:
            q = sums.process.intensity
        stds = dict(levels.noise_std)
        for name in stds:
            found = sums.measurement[name].stds(pooled=asked.pooled(name))
            if found is not None:
                stds[name] = tuple(found.tolist())
        # A noise-free recording drives the levels to 0, and rounding below it.
        return np.maximum(NoiseLevels(q, stds).vector(), floor)

    floor = LEVEL_FLOOR * current.vector()
    probe = sums_at(current)
    if current.noise_intensity is not None and probe.process.intensity is None:
        notes.append("motion.noise_intensity not estimable: no track with a transition; kept")
    notes += [f"sensor '{name}' noise_std not estimable: no track detection; kept"
              for name in current.noise_std if probe.measurement[name].count == 0]  # fmt: skip
    values = accelerated_em(update, current.vector(), tolerance=NOISE_TOLERANCE,
                            max_updates=MAX_NOISE_UPDATES).values  # fmt: skip
    if current.noise_intensity is not None and probe.process.intensity is not None:

        def log_likelihood(levels: NoiseLevels) -> float:
            run = with_noise_levels(config, levels)
            return math.fsum(
                track_log_likelihood(piece, assoc[i], run, (weight or {}).get(i))
                for piece, assoc, weight in zip(pieces, associations, per_block, strict=True)
                for i in sorted(assoc) if assoc[i]
            )  # fmt: skip

        values = _ecme(asked, current, update, log_likelihood, values, floor[0])
    notes += _floor_note(values, floor)
    return _from_vector(asked, current, values), tuple(notes)


def _floor_note(values: FloatArray, floor: FloatArray) -> tuple[str, ...]:
    """The M step's note where a level ended at its floor (:data:`LEVEL_FLOOR`)."""
    if np.any(values <= floor * (1 + 1e-9)):  # exp(log(floor)) may round above
        return (f"noise levels at their floor ({LEVEL_FLOOR!r} of the pass's start): the "
                "tracks are nearly noise-free",)  # fmt: skip
    return ()


def _interacting_m_step(
    config: Config,
    pieces: Sequence[Sequence[Scan]],
    associations: Sequence[Mapping[int, Mapping[int, int]]],
    asked: NoiseAsked,
    current: NoiseLevels,
    weights: Sequence[Mapping[int, Mapping[int, float]]] | None,
) -> tuple[NoiseLevels, tuple[str, ...]]:
    """:func:`noise_m_step` for a set of motion models: the levels that maximise the
    tracks' IMM predictive likelihood (:func:`track_log_likelihood`, all tracks of a
    block in lockstep: :func:`~mapassoc.filtering.smoothing.interacting_log_likelihoods`),
    by rounds of golden-section searches on one level at a time (module docstring, sets
    of models).

    A round searches every level in turn, each at the others' latest values, and keeps a
    search's level only where the likelihood does not fall (so no round lowers it), each
    level between its neighbours' in the set's order (:func:`_neighbours`); then each
    process noise but the loudest is raised to the upper end of its likelihood interval
    (:func:`_upper_end`).  The rounds stop when one moves no level by more than the
    search's resolution (:data:`ECME_LOG_TOLERANCE` in the log) or after
    :data:`ECME_ROUNDS`.  The first round's search of a process noise spans
    :data:`ECME_SPAN` either side of the start, every other search :data:`ECME_NEAR_SPAN`:
    a std starts near its value (the chains' moments), a process noise may start orders
    of magnitude away.
    """
    per_block = [None] * len(pieces) if weights is None else list(weights)
    blocks = [(piece, [assoc[i] for i in sorted(assoc) if len(assoc[i]) >= 2],
               [(weight or {}).get(i) for i in sorted(assoc) if len(assoc[i]) >= 2])
              for piece, assoc, weight in zip(pieces, associations, per_block, strict=True)]
    blocks = [block for block in blocks if block[1]]  # fmt: skip
    if not blocks:
        return current, ("noise levels not estimable: no track with two detections; kept",)

    def log_likelihood(values: FloatArray) -> float:
        run = with_noise_levels(config, _from_vector(asked, current, values))
        return math.fsum(float(np.sum(interacting_log_likelihoods(piece, tracks, run, w)))
                         for piece, tracks, w in blocks)  # fmt: skip

    coordinates = _coordinates(asked, current)
    floor = LEVEL_FLOOR * current.vector()

    def bounds(values: FloatArray, where: list[int]) -> tuple[float, float]:
        return _neighbours(config.motion, current, values, where[0])

    values, best = _coordinate_ascent(log_likelihood, current.vector(), floor, coordinates,
                                      bounds)  # fmt: skip
    for where, process in coordinates:
        ceiling = bounds(values, where)[1]
        if process and ceiling < math.inf:  # the loudest keeps its maximiser
            values[where] = _upper_end(log_likelihood, values, where, best, ceiling)
    return _from_vector(asked, current, values), _floor_note(values, floor)


def _neighbours(
    motion: object, current: NoiseLevels, values: FloatArray, position: int
) -> tuple[float, float]:
    """The ``noise_intensity`` of the set's components either side of the one at
    ``position`` of ``values`` (0 and inf where none; ``(0, inf)`` for a std): a
    component's level stays between its neighbours', so the set keeps its order, quiet
    first (module docstring, sets of models)."""
    asked = list(current.model_intensities)
    if not isinstance(motion, InteractingModels) or position >= len(asked):
        return 0.0, math.inf
    levels: list[float | None] = [getattr(m, "noise_intensity", None) for m in motion.models]
    for offset, index in enumerate(asked):
        levels[index] = float(values[offset])
    index = asked[position]
    below = [level for level in levels[:index] if level is not None]
    above = [level for level in levels[index + 1:] if level is not None]
    return (below[-1] if below else 0.0), (above[0] if above else math.inf)


def _coordinate_ascent(
    log_likelihood: Callable[[FloatArray], float],
    values: FloatArray,
    floor: FloatArray,
    coordinates: Sequence[tuple[list[int], bool]],
    bounds: Callable[[FloatArray, list[int]], tuple[float, float]],
) -> tuple[FloatArray, float]:
    """Rounds of :func:`_best_intensity` on one coordinate at a time, each within its
    ``bounds`` (the levels and the likelihood they reach): :func:`_interacting_m_step`'s
    maximisation."""
    values = values.copy()
    best = log_likelihood(values)
    for round_index in range(ECME_ROUNDS):
        before = values.copy()
        for where, process in coordinates:
            span = ECME_SPAN if process and round_index == 0 else ECME_NEAR_SPAN

            def along(level: float, where: list[int] = where) -> float:
                trial = values.copy()
                trial[where] = level
                return log_likelihood(trial)

            below, above = bounds(values, where)
            low = max(float(floor[where[0]]), below)
            start = min(max(float(values[where[0]]), low), above)
            level = _best_intensity(along, start, low, span, max(above, low))
            found = along(level)
            if found >= best:  # the bracket's midpoint may lie below the level it started at
                values[where], best = level, found
        if np.all(np.abs(np.log(values / before)) <= ECME_LOG_TOLERANCE):
            break
    return values, best


INTERVAL_DROP = 1.92
"""Nats below the maximum at the ends of a level's 95% likelihood interval: half the
0.95 quantile of chi-square with one degree of freedom (Wilks's theorem)."""


def _upper_end(
    log_likelihood: Callable[[FloatArray], float],
    values: FloatArray,
    where: list[int],
    best: float,
    ceiling: float = math.inf,
) -> float:
    """The largest level of coordinate ``where`` (the others at ``values``) whose
    likelihood is within :data:`INTERVAL_DROP` of ``best`` (module docstring, sets of
    models), at most ``ceiling`` (the next louder component's): steps of
    :data:`ECME_NEAR_SPAN` up from the maximiser until one drops further (at most
    ``1 / LEVEL_FLOOR`` above it: a plateau as deep as one pass's floor), then bisection
    on the log of that step to :data:`ECME_LOG_TOLERANCE`."""

    def along(log_level: float) -> float:
        trial = values.copy()
        trial[where] = math.exp(log_level)
        return log_likelihood(trial)

    low = math.log(float(values[where[0]]))
    top = min(low - math.log(LEVEL_FLOOR), math.log(ceiling))
    if low >= top:
        return math.exp(low)
    high = min(low + math.log(ECME_NEAR_SPAN), top)
    while along(high) >= best - INTERVAL_DROP:
        if high >= top:
            return math.exp(high)
        low, high = high, min(high + math.log(ECME_NEAR_SPAN), top)
    while high - low > ECME_LOG_TOLERANCE:
        middle = (low + high) / 2.0
        if along(middle) >= best - INTERVAL_DROP:
            low = middle
        else:
            high = middle
    return math.exp(low)


def _coordinates(asked: NoiseAsked, levels: NoiseLevels) -> list[tuple[list[int], bool]]:
    """The levels one search moves at a time, as positions in :meth:`NoiseLevels.vector`
    and whether each is a process noise: ``noise_intensity``, each component's, then per
    sensor its std (one search for a pooled std, whose components are equal)."""
    out: list[tuple[list[int], bool]] = []
    position = 0
    for _ in range((levels.noise_intensity is not None) + len(levels.model_intensities)):
        out.append(([position], True))
        position += 1
    for name, stds in levels.noise_std.items():
        size = len(stds)
        if asked.pooled(name):
            out.append((list(range(position, position + size)), False))
        else:
            out += [([position + i], False) for i in range(size)]
        position += size
    return out


def _ecme(
    asked: NoiseAsked,
    like: NoiseLevels,
    update: Callable[[FloatArray], FloatArray],
    log_likelihood: Callable[[NoiseLevels], float],
    values: FloatArray,
    floor: float,
) -> FloatArray:
    """The EM's levels refined by ECME rounds (module docstring): each an EM update of
    every level, then ``noise_intensity`` replaced by the maximiser of the tracks'
    observed-data log-likelihood at the updated stds (:func:`_best_intensity`), until a
    round moves ``noise_intensity`` by at most the search's own resolution
    (:data:`ECME_LOG_TOLERANCE` in ``log q``; a finer test would never pass) and every
    std by at most :data:`NOISE_TOLERANCE` (relative), or :data:`ECME_ROUNDS` rounds.
    After the first round the search spans :data:`ECME_NEAR_SPAN` either side."""
    span = ECME_SPAN
    for _ in range(ECME_ROUNDS):
        stds = _from_vector(asked, like, update(values)).noise_std

        def at_stds(q: float, stds: dict[str, tuple[float, ...]] = stds) -> float:
            return log_likelihood(NoiseLevels(q, stds))

        q = _best_intensity(at_stds, float(values[0]), floor, span)
        new = NoiseLevels(q, stds).vector()
        settled = abs(math.log(q / values[0])) <= ECME_LOG_TOLERANCE and bool(
            np.all(np.abs(new[1:] - values[1:]) <= NOISE_TOLERANCE * np.maximum(new, values)[1:])
        )
        values, span = new, ECME_NEAR_SPAN
        if settled:
            break
    return values


def _best_intensity(
    log_likelihood: Callable[[float], float],
    q: float,
    floor: float,
    span: float,
    ceiling: float = math.inf,
) -> float:
    """The ``noise_intensity`` in ``[q / span, q * span]`` (and within ``[floor,
    ceiling]``) that maximises ``log_likelihood``: golden-section search on ``log q`` to
    :data:`ECME_LOG_TOLERANCE` (the profile likelihood of the process noise given the
    tracks is unimodal in the cases measured and flat on a wide range near its top, where
    the EM creeps)."""
    low = max(math.log(q) - math.log(span), math.log(floor))
    high = min(math.log(q) + math.log(span), math.log(ceiling))
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = high - ratio * (high - low), low + ratio * (high - low)
    fa, fb = log_likelihood(math.exp(a)), log_likelihood(math.exp(b))
    while high - low > ECME_LOG_TOLERANCE:
        if fa >= fb:
            high, b, fb = b, a, fa
            a = high - ratio * (high - low)
            fa = log_likelihood(math.exp(a))
        else:
            low, a, fa = a, b, fb
            b = low + ratio * (high - low)
            fb = log_likelihood(math.exp(b))
    if low <= math.log(floor):  # at the floor: return it, so the M step notes it
        return floor
    return math.exp((low + high) / 2.0)


ECME_ROUNDS = 4
"""Most ECME rounds after the EM in one noise M step (each an EM update and a search)."""
ECME_SPAN = 1e3
"""The first round's search for ``noise_intensity`` spans this factor either side of the
EM's result."""
ECME_NEAR_SPAN = 10.0
"""A later round's search spans this factor either side of the last round's result."""
ECME_LOG_TOLERANCE = 0.02
"""Width in ``log q`` at which the search stops (2 per cent in ``q``)."""


class Levels(Protocol):
    """Estimated values that read as one positive vector (:class:`NoiseLevels`,
    :class:`~mapassoc.estimator.birth_estimation.BirthLevels`)."""

    def vector(self) -> FloatArray:
        """The values, in a fixed order."""
        ...


def levels_close(a: Levels | None, b: Levels | None, tolerance: float) -> bool:
    """Whether every value of ``a`` and ``b`` (both None, or of one kind and layout)
    differs by at most ``tolerance`` of the larger: the parameter EM's convergence test
    of the noise levels and of the birth model."""
    if a is None or b is None:
        return a is b
    x, y = a.vector(), b.vector()
    return bool(np.all(np.abs(x - y) <= tolerance * np.maximum(x, y)))
