"""Sensor parameters from the recording: false-alarm rate and detection probability by EM.

The estimator is exact under the model it is given, and two of its numbers are rarely
known: the expected false alarms per scan ``lambda_bar`` of each sensor (it depends on
thresholds, weather and terrain) and its detection probability ``Pd``.  A factor-2 error
in ``lambda_bar`` floods dense recordings with false tracks or erases their targets.  An
offline recording holds the answer, and this module finds it by expectation-maximisation
around the estimator itself: the track set each pass finds fixes the associations, as in
hard (classification) EM, and with ``soft_counts`` the statistics counted are their
expectations under the confidence pass's marginals around that set:

1. *E step*: run the window estimator's forward pass with the current parameters; its
   committed, smoothed tracks say which detection is a target's
   (:func:`association_counts`).  The whole recording's refinement is left out of the
   passes (it would cost one to three times each pass again) and runs once, on the last
   pass's run.  With ``soft_counts`` (the default) the confidence pass
   (:mod:`mapassoc.estimator.confidence`) runs over each pass's forward tracks
   (:func:`~mapassoc.estimator.refinement.track_confidence`, a fraction of a pass's
   cost) and the counts below are expected counts under its association
   probabilities; without it, or where a run has no confidence, they are hard.
2. *M step*: the parameters that maximise the complete-data likelihood of those
   associations under the sensor model of the n-object measurement model (Poisson false
   alarms, uniform over the region; each target detected with probability ``Pd``):

   * ``lambda_bar = (detections no track explains) / scans`` of the sensor, the maximum
     likelihood rate of the Poisson false-alarm counts;
   * ``Pd = (interior detections) / (interior track-scans)``: over every track, the scans
     of the sensor strictly between the track's first and last detection.  The first and
     last scans are left out because a track starts and ends with a detection by
     construction; given where they are, the scans between are independent Bernoulli(Pd)
     draws, so this ratio is unbiased where the associations are right.

   Why soft counts.  On closely spaced targets the MAP track set takes a neighbour's
   detection or a false alarm at a scan where its own target was missed, so a hard count
   sees a detection at nearly every interior track-scan and overstates ``Pd`` (and,
   through the tracks it keeps, the process noise).  The confidence pass's posterior
   marginals spread such a scan over the detection taken, the neighbour's and the miss,
   so the interior track-scan counts the probability that the track was detected there
   (the sum of its association probabilities over the scan's detections, capped at 1)
   and a detection the probability that it is clutter (1 minus the sum of its
   probabilities over the tracks): the expected complete-data statistics of EM
   (Dempster, Laird and Rubin, "Maximum likelihood from incomplete data via the EM
   algorithm"), here under the marginals of one window with the set outside held, not
   of the whole recording.  Soft weights of another kind were tried before and dropped:
   the PDA probability that the target was detected, from the track's smoothed state
   alone, let closely spaced targets explain each other's misses, since each track's
   weight ignored the others; the confidence pass's marginals are joint over the
   window's tracks, so one detection's probabilities over the tracks sum to at most 1.
   Soft counts are the default by measurement (CHANGELOG.md).

3. Repeat until a pass's update moves every estimate by less than the tolerance (a
   relative ``rate_tolerance`` on ``lambda_bar``, an absolute ``pd_tolerance`` on ``Pd``),
   or ``max_passes`` (default 3) is reached.  The estimates returned are those the last pass ran
   with, so the tracks of that pass are exactly the estimator's answer under them.

Starting values.  The rate starts where every detection is clutter: ``lambda_bar`` =
the mean detections per scan, an upper bound on the rate.  That start is cheap (with
much clutter assumed, few hypotheses survive) and descends to the estimate; a start
below the truth is not offered, because too little assumed clutter turns clutter into
tracks and every window into a combinatorial problem (on ``dense_pd08`` a first pass at a
quarter of the true rate took over two hundred times as long as one at the upper bound).  Where the
upper bound explains no detection at all (few false alarms among many targets: the
assumed clutter then hides every track), the next pass tries a quarter of it, once; a
recording without targets comes back to the mean detections per scan.  That probe is
not counted in ``max_passes``.  ``Pd`` starts at
:data:`DEFAULT_PD_START`, or at a configured start.  A sensor with too few scans
(:data:`MIN_SCANS`) keeps its configured rate, and one whose tracks give too few interior
scans (:data:`MIN_INTERIOR_SCANS`; a recording without targets gives none) keeps its
``Pd``, each with a message that says so.

Noise levels.  A configuration's ``"auto"`` process-noise intensity and position-sensor
noise stds (:attr:`Config.auto`) are estimated in the same passes: each pass's tracks,
smoothed, give their EM fixed point (:mod:`mapassoc.estimator.noise_levels`, where the
starts and the choice of returning the last update are explained), and the next pass
runs with it; the iteration has converged when they too moved by less than
``rate_tolerance`` (relative).  With ``soft_counts`` each detection of a track enters
the noise sums weighted by the confidence pass's probability that it is the track's
own (:func:`~mapassoc.estimator.noise_levels.association_weights`), so a false alarm or
a neighbour's detection the MAP set took does not count as the target's motion or the
sensor's noise.

Birth model.  The ``"auto"`` keys of ``[birth]`` (``rate``, ``initial_count``,
``survival_probability``, ``velocity_std``) join the passes the same way: each pass's
tracks, counted under the birth model and smoothed, give their M step
(:mod:`mapassoc.estimator.birth_estimation`, where the starts are explained), the next
pass runs with it, and they too must move by less than ``rate_tolerance`` (relative) for
the iteration to have converged; like the noise levels, the last pass's update is what
is returned.  With ``soft_counts`` each track counts as much as the confidence pass's
probability that it is a target (its existence), so clutter joined by chance and
fragments of a target's track do not count as births.

Long recordings are not run in full at every pass: the passes run on at most
``sample_scans`` scans, in blocks spread evenly over the recording (each block a
recording of its own, so a track cut at a block's edge only loses its first and last
scan, which the Pd count leaves out anyway); only the run with the final estimates
covers every scan.  A recording no longer than ``sample_scans`` is estimated on all of
it, and its last pass is the run itself (:attr:`ParameterEstimate.result`).
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.special import gammaln

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config
from mapassoc.data.io import TrackTable
from mapassoc.data.scans import Scan, check_scans
from mapassoc.errors import InputError, StopRequested
from mapassoc.estimator.birth_estimation import (
    BirthAsked,
    BirthLevels,
    birth_m_step,
    initial_birth,
    with_birth_levels,
)
from mapassoc.estimator.confidence import TrackConfidence
from mapassoc.estimator.noise_levels import (
    MIN_TRACK_DETECTIONS,
    NoiseAsked,
    NoiseLevels,
    association_weights,
    associations_of,
    initial_noise,
    levels_close,
    noise_m_step,
    with_noise_levels,
)
from mapassoc.estimator.refinement import track_confidence
from mapassoc.log_space import json_number
from mapassoc.models.sensor import Sensor
from mapassoc.validation import check_positive, check_probability

if TYPE_CHECKING:  # the pipeline imports this module's users; imported when estimating
    from mapassoc.estimator.pipeline import (
        EstimateResult,
        RunState,
        WindowEstimator,
        WindowReport,
    )

__all__ = [
    "DEFAULT_PD_START",
    "MIN_SCANS",
    "MIN_INTERIOR_SCANS",
    "UNSEEN_FALSE_ALARMS",
    "AssociationCounts",
    "SensorEstimate",
    "EstimationPass",
    "ParameterEstimate",
    "EstimationStopped",
    "association_counts",
    "estimate_parameters",
    "EMSettings",
    "EMState",
    "EStep",
    "MStep",
    "ParameterEM",
    "sample_blocks",
    "with_sensor_parameters",
]

DEFAULT_PD_START = 0.95
"""``Pd`` the first pass uses for a sensor whose ``detection_probability`` is "auto"
without a start value.  High on purpose: from above the iteration descends to the
estimate in two or three passes (0.95, 0.85, 0.81, 0.80 on ``dense_pd08``, true 0.8),
while from below the estimator's own preference for the assumed ``Pd`` slows it to a
creep (0.65, 0.66, 0.67, 0.69, 0.72, 0.74 in six passes on the same recording)."""
MIN_SCANS = 5
"""Fewest scans of a sensor for its false-alarm rate to be estimated."""
UNSEEN_FALSE_ALARMS = 0.5
"""The unexplained detections the rate update counts when a pass leaves none (every
detection in a track, as in clutter-free data): the estimator needs a rate > 0 (each
detection is scored against the false-alarm density), and half a false alarm over the
sampled scans is fewer than the recording could show (it is the posterior mean of a
Poisson rate under Jeffreys' prior after a count of 0)."""
MIN_INTERIOR_SCANS = 20
"""Fewest interior track-scans of a sensor for its ``Pd`` to be estimated (with 20 the
standard error of the ratio is at most 0.11; the bench recordings give hundreds)."""


ESTIMATION_PHASE = "the estimation of the sensor parameters"
"""The phase an :class:`EstimationStopped` names."""


class EstimationStopped(StopRequested):
    """``stop`` asked :func:`estimate_parameters` to stop (at a window boundary, or between
    two units of the last pass's refinement)."""

    def __init__(self, message: str) -> None:
        super().__init__(ESTIMATION_PHASE, message)


@dataclass(frozen=True)
class AssociationCounts:
    """What the associations of one run say about one sensor: hard (each detection a
    track's or clutter) or soft (expected counts under the confidence pass's
    probabilities; :func:`association_counts`).

    Attributes
    ----------
    scans : int
        Scans of the sensor (empty ones included).
    detections : int
        Its detections.
    explained : float
        Its detections some track uses (soft: their expected number).
    interior_scans : int
        Its scans strictly between a track's first and last detection, over every track.
    interior_detections : float
        Those of them at which the track has a detection (soft: the sum over them of the
        probability that it has one).
    clutter_per_scan : tuple of float
        Per scan of the sensor, the detections no track uses (soft: their expected
        number; for the objective).
    """

    scans: int
    detections: int
    explained: float
    interior_scans: int
    interior_detections: float
    clutter_per_scan: tuple[float, ...]

    @property
    def unexplained(self) -> float:
        return self.detections - self.explained


def association_counts(
    scans: Sequence[Scan],
    tracks: TrackTable,
    sensors: Collection[str],
    confidence: TrackConfidence | None = None,
) -> dict[str, AssociationCounts]:
    """Per sensor, the counts the M step needs from a run's tracks (module docstring).

    Without ``confidence`` the counts are hard: an interior track-scan counts 1 where the
    track has a detection and 0 where it has none, a detection is clutter when no track
    uses it.  With it they are soft, expected counts under its association
    probabilities: an interior track-scan counts the probability that the track was
    detected there (the sum of its probabilities over the scan's detections, capped at
    1: the confidence pass may give a target both its carried tree and a new tree rooted
    at one of its detections), and a detection the probability that it is clutter (1
    minus the sum of its probabilities over the tracks, capped at 1).  Where every
    probability is 0 or 1 the two agree.  A track the confidence does not cover is
    counted hard.

    Parameters
    ----------
    scans : sequence of Scan
        The scans the run was given.
    tracks : TrackTable
        Its tracks: one row per track per scan from the first to the last detection,
        ``detection_rows`` the detection used (-1 for a miss).
    sensors : collection of str
        The sensors to count (a sensor without scans gets zeros).
    confidence : TrackConfidence, optional
        The confidence pass over the same tracks (track ids and detection ids as in
        ``tracks``).

    Returns
    -------
    dict of str to AssociationCounts
    """
    hard = tracks.detection_rows >= 0
    if confidence is None:
        used = dict.fromkeys((int(r) for r in tracks.detection_rows[hard].tolist()), 1.0)
        detected = hard.astype(float)
    else:
        used, detected = _soft_uses(scans, tracks, confidence)
    per_sensor: dict[str, list[float]] = {name: [] for name in sensors}
    detections = dict.fromkeys(sensors, 0)
    for scan in scans:
        if scan.sensor in per_sensor:
            rows = scan.rows.tolist()
            per_sensor[scan.sensor].append(
                math.fsum(1.0 - used.get(row, 0.0) for row in rows) if rows else 0.0
            )
            detections[scan.sensor] += len(rows)
    interior = _interior(tracks)
    sensor_of_row = np.asarray(tracks.sensors, dtype=object)
    out = {}
    for name in sensors:
        inside = interior & (sensor_of_row == name) if tracks.track_ids.size else interior
        clutter = per_sensor[name]
        out[name] = AssociationCounts(
            scans=len(clutter),
            detections=detections[name],
            explained=detections[name] - math.fsum(clutter),
            interior_scans=int(np.count_nonzero(inside)),
            interior_detections=math.fsum(detected[inside].tolist()),
            clutter_per_scan=tuple(clutter),
        )
    return out


def _interior(tracks: TrackTable) -> NDArray[np.bool_]:
    """Whether each row of ``tracks`` is strictly inside its track (neither its first
    nor its last scan)."""
    interior = np.zeros(tracks.track_ids.size, dtype=bool)
    if tracks.track_ids.size:
        order = np.lexsort((tracks.times, tracks.track_ids))
        ids = tracks.track_ids[order]
        starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
        stops = np.r_[starts[1:], ids.size]
        for first, stop in zip(starts.tolist(), stops.tolist(), strict=True):
            interior[order[first + 1 : stop - 1]] = True
    return interior


def _soft_uses(
    scans: Sequence[Scan], tracks: TrackTable, confidence: TrackConfidence
) -> tuple[dict[int, float], FloatArray]:
    """Per detection id, the probability that some track uses it (capped at 1), and
    per row of ``tracks``, the probability that its track has a detection at the row's
    scan (capped at 1).  A track without probabilities counts hard: 1 where it has a
    detection, else 0, and its detections as used."""
    scan_of_row = {int(row): k for k, scan in enumerate(scans) for row in scan.rows.tolist()}
    scan_of_key = {(scan.time, scan.sensor): k for k, scan in enumerate(scans)}
    used: dict[int, float] = {}
    per_scan: dict[tuple[int, int], float] = {}
    for tid, probabilities in confidence.associations.items():
        for row, p in probabilities.items():
            used[row] = used.get(row, 0.0) + p
            key = (tid, scan_of_row[row])
            per_scan[key] = per_scan.get(key, 0.0) + p
    rows = tracks.detection_rows.tolist()
    detected = (tracks.detection_rows >= 0).astype(float)
    covered = set(confidence.associations)
    for i, (tid, at, sensor) in enumerate(
        zip(tracks.track_ids.tolist(), tracks.times.tolist(), tracks.sensors, strict=True)
    ):
        if tid in covered:
            detected[i] = min(1.0, per_scan.get((tid, scan_of_key[(at, sensor)]), 0.0))
        elif rows[i] >= 0:
            used[rows[i]] = used.get(rows[i], 0.0) + 1.0
    return {row: min(1.0, p) for row, p in used.items()}, detected


@dataclass(frozen=True)
class SensorEstimate:
    """The estimates of one sensor's parameters.

    Attributes
    ----------
    sensor : str
    false_alarms_per_scan : float
        The rate the final pass ran with (estimated, or as configured when not asked for
        or not estimable).
    detection_probability : float
        Likewise for ``Pd``.
    rate_estimated, pd_estimated : bool
        Whether the value is an estimate (False: asked for but not estimable, or not
        asked for; see ``notes``).
    notes : tuple of str
        Why a value asked for could not be estimated.
    """

    sensor: str
    false_alarms_per_scan: float
    detection_probability: float
    rate_estimated: bool
    pd_estimated: bool
    notes: tuple[str, ...] = ()

    def to_json(self) -> dict[str, object]:
        return {
            "false_alarms_per_scan": self.false_alarms_per_scan,
            "detection_probability": self.detection_probability,
            "rate_estimated": self.rate_estimated,
            "pd_estimated": self.pd_estimated,
            "notes": list(self.notes),
        }


@dataclass(frozen=True)
class EstimationPass:
    """One pass of the EM iteration.

    Attributes
    ----------
    index : int
        0 for the first pass.
    used : dict of str to (float, float)
        Per sensor, the ``(false_alarms_per_scan, detection_probability)`` the pass ran
        with.
    updated : dict of str to (float, float)
        Per sensor, the M step's values from the pass's associations (what the next pass
        would use).
    objective : float
        The complete-data log-likelihood of the pass's associations at the updated
        parameters, over the estimated parameters' terms only: per sensor, the Poisson
        log-probability of every scan's unexplained count and their uniform density
        ``-log V`` each, plus ``D log Pd + (N - D) log(1 - Pd)`` over the interior
        track-scans (the part of the n-object likelihood the M step maximises).
    tracks : int
        Tracks the pass found.
    scans : int
        Scans it ran on.
    seconds : float
    noise_used, noise_updated : NoiseLevels or None
        The "auto" noise levels the pass ran with and those its associations give
        (:mod:`mapassoc.estimator.noise_levels`); None when none is asked for.
    birth_used, birth_updated : BirthLevels or None
        Likewise for the "auto" birth keys (:mod:`mapassoc.estimator.birth_estimation`).
    """

    index: int
    used: dict[str, tuple[float, float]]
    updated: dict[str, tuple[float, float]]
    objective: float
    tracks: int
    scans: int
    seconds: float
    noise_used: NoiseLevels | None = None
    noise_updated: NoiseLevels | None = None
    birth_used: BirthLevels | None = None
    birth_updated: BirthLevels | None = None

    def to_json(self, *, timings: bool = True) -> dict[str, object]:
        out: dict[str, object] = {
            "pass": self.index,
            "used": {k: {"false_alarms_per_scan": a, "detection_probability": b}
                     for k, (a, b) in self.used.items()},
            "updated": {k: {"false_alarms_per_scan": a, "detection_probability": b}
                        for k, (a, b) in self.updated.items()},
            "objective": json_number(self.objective),  # -inf: "-inf" (a kept Pd of 1)
            "tracks": self.tracks,
            "scans": self.scans,
        }  # fmt: skip
        if self.noise_used is not None and self.noise_updated is not None:
            out["noise_used"] = self.noise_used.to_json()
            out["noise_updated"] = self.noise_updated.to_json()
        if self.birth_used is not None and self.birth_updated is not None:
            out["birth_used"] = self.birth_used.to_json()
            out["birth_updated"] = self.birth_updated.to_json()
        if timings:
            out["seconds"] = self.seconds
        return out


@dataclass(frozen=True)
class ParameterEstimate:
    """What :func:`estimate_parameters` found.

    Attributes
    ----------
    config : Config
        The configuration with the estimates filled in (what the final run uses).
    sensors : dict of str to SensorEstimate
        The sensors some parameter was asked for.
    passes : tuple of EstimationPass
    converged : bool
        Whether the last pass's update moved every estimate by less than the tolerance
        (False: the pass limit ended the iteration, the usual case with the default
        limit; the last pass's values are the estimates either way).
    sample_scans : int
        Scans the passes ran on (all of them when the recording is no longer than the
        sample).
    result : EstimateResult or None
        The last pass's run when it covered the whole recording, finished as
        :meth:`~mapassoc.estimator.pipeline.WindowEstimator.run` finishes it (the whole
        recording's refinement included: the passes themselves count the forward pass's
        associations, and the refinement runs once, here), so it is the estimator's
        answer under the returned configuration and a caller need not run again; None
        when the passes ran on a sample, or when :func:`estimate_parameters` was asked
        not to ``finish`` it.
    warnings : tuple of str
        What could not be estimated, and why.
    last_run : tuple of (RunState, tuple of WindowReport), optional
        The last pass's done forward run and its window reports when it covered the
        whole recording (else None): ``WindowEstimator(config=config).finish(scans,
        state, windows=reports)`` gives ``result``.  ``mapassoc run`` writes its windows
        and checkpoints the state before it refines, so a stop during the refinement
        loses no pass.
    noise : NoiseLevels or None
        The "auto" noise levels returned (None when none was asked for).
    birth : BirthLevels or None
        The "auto" birth keys returned (None when none was asked for).
    """

    config: Config
    sensors: dict[str, SensorEstimate]
    passes: tuple[EstimationPass, ...]
    converged: bool
    sample_scans: int
    result: EstimateResult | None
    warnings: tuple[str, ...]
    last_run: tuple[RunState, tuple[WindowReport, ...]] | None = None
    noise: NoiseLevels | None = None
    birth: BirthLevels | None = None

    def to_json(self, *, timings: bool = True) -> dict[str, object]:
        out: dict[str, object] = {
            "sensors": {name: est.to_json() for name, est in self.sensors.items()},
            "passes": [p.to_json(timings=timings) for p in self.passes],
            "converged": self.converged,
            "sample_scans": self.sample_scans,
        }
        if self.noise is not None:
            out["noise"] = self.noise.to_json()
        if self.birth is not None:
            out["birth"] = self.birth.to_json()
        return out


def sample_blocks(total: int, *, sample_scans: int, blocks: int) -> list[tuple[int, int]]:
    """``[(first, stop), ...]``: at most ``sample_scans`` of ``total`` scans in ``blocks``
    equal contiguous blocks spread evenly (the whole recording when it is no longer)."""
    if total <= sample_scans:
        return [(0, total)]
    size = max(1, sample_scans // blocks)
    count = max(1, min(blocks, sample_scans // size))
    gap = (total - count * size) / max(count - 1, 1) if count > 1 else 0.0
    out = []
    for i in range(count):
        first = int(round(i * (size + gap))) if count > 1 else (total - size) // 2
        out.append((first, min(first + size, total)))
    return out


def _check_starts(config: Config, values: Mapping[str, float | None]) -> dict[str, float | None]:
    """The ``Pd`` starts by sensor, checked: a known sensor, a probability in (0, 1]."""
    out: dict[str, float | None] = {}
    for sensor, start in values.items():
        _check_sensor(config, sensor, "detection_probability")
        out[sensor] = None if start is None else check_probability(
            f"sensor '{sensor}' detection_probability_start", start, allow_zero=False,
            key="detection_probability_start",
        )  # fmt: skip
    return out


def _check_sensor(config: Config, sensor: str, key: str) -> None:
    if sensor not in config.sensors:
        raise InputError(
            f"{key}: sensor {sensor!r} is not configured (known: {sorted(config.sensors)})",
            key=key,
        )


def with_sensor_parameters(config: Config, values: Mapping[str, tuple[float, float]]) -> Config:
    """``config`` with the sensors' ``(false_alarms_per_scan, detection_probability)``.

    The result has no ``"auto"`` parameter left (``Config.auto`` empty): it is what a run
    with those values uses.
    """
    sensors = {}
    for name, sensor in config.sensors.items():
        rate, pd = values.get(name, (sensor.false_alarms_per_scan, sensor.detection_probability))
        sensors[name] = Sensor(
            name=name,
            measurement=sensor.measurement,
            detection_probability=pd,
            false_alarms_per_scan=rate,
            region=sensor.region,
        )
    return Config(
        motion=config.motion,
        sensors=sensors,
        birth=config.birth,
        estimator=config.estimator,
        source=config.source,
    )


def _objective(counts: AssociationCounts, rate: float, pd: float, volume: float) -> float:
    """The estimated parameters' part of the complete-data log-likelihood (EstimationPass)."""
    clutter = np.asarray(counts.clutter_per_scan, dtype=float)
    total = float(clutter.sum())
    out = 0.0
    if rate > 0:
        out += total * math.log(rate) - rate * clutter.size - float(gammaln(clutter + 1).sum())
        out -= total * math.log(volume)
    elif total > 0:
        return -math.inf
    detected = counts.interior_detections
    missed = counts.interior_scans - detected
    if detected:
        out += detected * math.log(pd)
    if missed:
        out += missed * math.log1p(-pd) if pd < 1 else -math.inf
    return out


def estimate_parameters(
    config: Config,
    scans: Sequence[Scan],
    *,
    false_alarms: Collection[str] | None = None,
    detection_probability: Mapping[str, float | None] | None = None,
    rate_tolerance: float | None = None,
    pd_tolerance: float | None = None,
    max_passes: int | None = None,
    sample_scans: int | None = None,
    sample_blocks_count: int | None = None,
    soft_counts: bool | None = None,
    on_pass: Callable[[EstimationPass], None] | None = None,
    stop: Callable[[], bool] | None = None,
    finish: bool = True,
) -> ParameterEstimate:
    """Estimate sensors' false-alarm rates and detection probabilities (module docstring).

    The steps are those of a :class:`ParameterEM`: initialise, then E and M steps until
    the update converges or the pass limit, then finish.

    Parameters
    ----------
    config : Config
        Everything else of the model; the sensors' configured values serve where a
        parameter is not estimated.
    scans : sequence of Scan
        The whole recording, sorted by (time, sensor).
    false_alarms : collection of str, optional
        The sensors whose false-alarm rate to estimate.
    detection_probability : mapping of str to float or None, optional
        The sensors whose ``Pd`` to estimate, each with its starting value (None:
        :data:`DEFAULT_PD_START`).  When neither is given, the configuration's
        ``"auto"`` parameters (:attr:`Config.auto`) are estimated.  The noise levels
        and birth keys estimated are always the configuration's ``"auto"`` ones.
    rate_tolerance, pd_tolerance, max_passes, sample_scans, sample_blocks_count : optional
        Default: the configuration's (``config.estimator.parameters``, whose defaults are
        the values given below).
    rate_tolerance : float
        Relative change of every rate below which the iteration stops (> 0).
    pd_tolerance : float
        Absolute change of every ``Pd`` below which it stops (> 0).
    max_passes : int
        Most passes (>= 1).  The default 3 bounds the cost at three runs' worth and was
        chosen by measurement: from the starts above, the first two updates take the
        estimates most of the way, and later passes drift (the hard associations favour
        the assumed values: on ``dense_pd08`` with its own configuration, Pd 0.95, 0.85,
        0.80 then 0.77, 0.75, 0.72, 0.67 against the true 0.8).
    sample_scans : int
        Most scans a pass runs on (>= 1); see the module docstring.
    sample_blocks_count : int
        Blocks the sample of a longer recording is cut into (>= 1).
    soft_counts : bool, optional
        Whether each pass counts the association probabilities of a confidence pass over
        its tracks rather than its hard associations (module docstring); default: the
        configuration's.
    on_pass : callable, optional
        Called with each :class:`EstimationPass` as it ends.
    stop : callable, optional
        Polled after every window (and between the units of the last pass's
        refinement); when it returns True the estimation raises
        :class:`EstimationStopped`.
    finish : bool
        False leaves the last pass's run unfinished (``result`` None, ``last_run`` set
        when it covered the whole recording) for the caller to refine.

    Returns
    -------
    ParameterEstimate

    Raises
    ------
    InputError
        An unknown sensor, a start outside (0, 1], or a bad tolerance or count.
    EstimationStopped
        ``stop`` returned True.
    """
    rates, pds = _asked(config, false_alarms, detection_probability)  # checked first
    em = ParameterEM(
        config, scans, false_alarms=rates, detection_probability=pds,
        settings=EMSettings.resolve(
            config, rate_tolerance=rate_tolerance, pd_tolerance=pd_tolerance,
            max_passes=max_passes, sample_scans=sample_scans,
            sample_blocks_count=sample_blocks_count, soft_counts=soft_counts,
        ),
        on_pass=on_pass, stop=stop,
    )  # fmt: skip
    state = em.initialise()
    while not em.done(state):
        state = em.step(state)
    return em.finish(state, finish=finish)


@dataclass(frozen=True)
class EMSettings:
    """How the EM iterates (the arguments of :func:`estimate_parameters` of that name).

    Attributes
    ----------
    rate_tolerance : float
        Relative change of every rate below which the iteration stops (> 0).
    pd_tolerance : float
        Absolute change of every ``Pd`` below which it stops (> 0).
    max_passes, sample_scans, sample_blocks_count : int
        Most passes, most scans a pass runs on, blocks of that sample (each >= 1).
    soft_counts : bool
        Whether the E step counts the association probabilities of a confidence pass
        over each pass's tracks (True: for ``Pd``, the rate, the noise levels and the
        birth keys) or its hard associations (False).

    Raises
    ------
    InputError
        A tolerance <= 0 or a count that is not an integer >= 1 (naming its key).
    """

    rate_tolerance: float
    pd_tolerance: float
    max_passes: int
    sample_scans: int
    sample_blocks_count: int
    soft_counts: bool

    def __post_init__(self) -> None:
        if not isinstance(self.soft_counts, bool):
            raise InputError(
                f"soft_counts must be true or false, got {self.soft_counts!r}", key="soft_counts"
            )
        check = check_positive("rate_tolerance", self.rate_tolerance, key="rate_tolerance")
        object.__setattr__(self, "rate_tolerance", check)
        check = check_positive("pd_tolerance", self.pd_tolerance, key="pd_tolerance")
        object.__setattr__(self, "pd_tolerance", check)
        for name in ("max_passes", "sample_scans", "sample_blocks_count"):
            count = getattr(self, name)
            if isinstance(count, bool) or not isinstance(count, int) or count < 1:
                raise InputError(f"{name} must be an integer >= 1, got {count!r}", key=name)

    @classmethod
    def resolve(cls, config: Config, **given: float | int | bool | None) -> EMSettings:
        """The values ``given``, the configuration's ``[estimator.parameters]`` for those
        None (or not given)."""
        own = config.estimator.parameters
        values = {
            field.name: getattr(own, field.name) if given.get(field.name) is None
            else given[field.name]
            for field in dataclasses.fields(cls)
        }  # fmt: skip
        return cls(**values)  # type: ignore[arg-type]


@dataclass(frozen=True)
class EMState:
    """Where the EM iteration is: what :meth:`ParameterEM.step` maps to the next.

    Attributes
    ----------
    current : dict of str to (float, float)
        Per sensor, the ``(false_alarms_per_scan, detection_probability)`` the next pass
        runs with.
    rates : tuple of str
        The sensors whose rate is estimated (asked for, with enough scans).
    upper : dict of str to float
        Their starting rate, the upper bound (every detection clutter).
    notes : dict of str to tuple of str
        Per sensor, what the start could not estimate.
    passes : tuple of EstimationPass
        The passes so far.
    retried : bool
        Whether the probe at a quarter of the upper bound was made.
    converged : bool
        Whether the last pass's update moved every estimate by less than the tolerance.
    pd_estimable : dict of str to bool
        Per sensor whose ``Pd`` is asked for: whether the last pass could estimate it.
    no_clutter : dict of str to int
        Per sensor whose rate is estimated: its scans when the last pass left no
        detection unexplained, else 0.
    last_run : (WindowEstimator, RunState, list of WindowReport) or None
        The last pass's estimator, done run state and window reports when it covered the
        whole recording.
    noise : NoiseLevels or None
        The "auto" noise levels the next pass runs with (None: none asked for).
    noise_notes : tuple of str
        What the last pass could not estimate of them.
    birth, birth_notes : BirthLevels or None, tuple of str
        Likewise for the "auto" birth keys.
    """

    current: dict[str, tuple[float, float]]
    rates: tuple[str, ...]
    upper: dict[str, float]
    notes: dict[str, tuple[str, ...]]
    pd_estimable: dict[str, bool]
    no_clutter: dict[str, int]
    passes: tuple[EstimationPass, ...] = ()
    retried: bool = False
    converged: bool = False
    last_run: tuple[WindowEstimator, RunState, list[WindowReport]] | None = None
    noise: NoiseLevels | None = None
    noise_notes: tuple[str, ...] = ()
    birth: BirthLevels | None = None
    birth_notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class EStep:
    """One E step: a forward run with the current values and what its tracks say.

    Attributes
    ----------
    counts : dict of str to AssociationCounts
        Per sensor asked, the association counts merged over the sample's blocks.
    tracks : int
        Tracks the runs found.
    last_run : (WindowEstimator, RunState, list of WindowReport) or None
        The run when it covered the whole recording.
    associations : tuple of dict
        Per block, every track as scan index -> detection index
        (:func:`~mapassoc.estimator.noise_levels.associations_of`; empty when no noise
        level or birth key is asked for).
    weights : tuple of dict
        Per block, track id -> {scan index -> probability that its detection there is
        its own} (:func:`~mapassoc.estimator.noise_levels.association_weights`; a block
        without a confidence pass, hard counts, gives an empty dict; empty when no noise
        level is asked for).
    existence : tuple of dict or None
        Per block, track id -> the confidence pass's probability that the track is a
        target (None: no confidence pass; empty when no birth key is asked for).
    """

    counts: dict[str, AssociationCounts]
    tracks: int
    last_run: tuple[WindowEstimator, RunState, list[WindowReport]] | None
    associations: tuple[dict[int, dict[int, int]], ...] = ()
    weights: tuple[dict[int, dict[int, float]], ...] = ()
    existence: tuple[dict[int, float] | None, ...] = ()


@dataclass(frozen=True)
class MStep:
    """One M step: the updated values and what could be estimated.

    Attributes
    ----------
    updated : dict of str to (float, float)
        Per sensor asked, the new ``(false_alarms_per_scan, detection_probability)``.
    objective : float
        The complete-data log-likelihood at them (:attr:`EstimationPass.objective`).
    pd_estimable, no_clutter : dict
        As :class:`EMState`'s, for this pass.
    """

    updated: dict[str, tuple[float, float]]
    objective: float
    pd_estimable: dict[str, bool]
    no_clutter: dict[str, int]


class ParameterEM:
    """The EM of sensor parameters (module docstring), one method per step.

    :meth:`initialise` gives the starting :class:`EMState`; :meth:`step` makes one pass
    (:meth:`e_step`, :meth:`m_step`, then the probe or the :meth:`converged` test) and
    :meth:`done` says when to stop; :meth:`finish` gives the :class:`ParameterEstimate`.

    Parameters
    ----------
    config, scans, false_alarms, detection_probability, on_pass, stop
        As :func:`estimate_parameters`'s.
    settings : EMSettings
        The tolerances, the pass limit and the sample.

    Raises
    ------
    InputError
        An unknown sensor, a start outside (0, 1], an "auto" value not asked for, or
        scans that are not the configuration's.
    """

    def __init__(
        self,
        config: Config,
        scans: Sequence[Scan],
        *,
        false_alarms: Collection[str] | None = None,
        detection_probability: Mapping[str, float | None] | None = None,
        settings: EMSettings,
        on_pass: Callable[[EstimationPass], None] | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> None:
        self.rates, self.pds = _asked(config, false_alarms, detection_probability)
        self.config, self.settings, self.on_pass, self.stop = config, settings, on_pass, stop
        self.scans = check_scans(scans, config.sensors, what="estimate parameters from")
        self.asked = tuple(
            name for name in config.sensors if name in self.rates or name in self.pds
        )
        blocks = sample_blocks(
            len(self.scans), sample_scans=settings.sample_scans, blocks=settings.sample_blocks_count
        )
        self.pieces = [self.scans[first:stop] for first, stop in blocks]
        self.starts_recording = [first == 0 for first, _ in blocks]
        self.sampled = [scan for piece in self.pieces for scan in piece]
        self.whole = len(self.pieces) == 1 and len(self.pieces[0]) == len(self.scans)
        self.noise = NoiseAsked.from_config(config)
        self.birth = BirthAsked.from_config(config)

    def initialise(self) -> EMState:
        """The starting values: each estimated rate at its upper bound (the mean
        detections per scan of the sample), each ``Pd`` at its start; a sensor with fewer
        than :data:`MIN_SCANS` scans keeps its rate (an "auto" one: the mean), noted."""
        config, rates = self.config, list(self.rates)
        notes: dict[str, tuple[str, ...]] = {name: () for name in self.asked}
        current: dict[str, tuple[float, float]] = {}
        upper: dict[str, float] = {}
        for name in self.asked:
            sensor = config.sensors[name]
            of_sensor = [scan for scan in self.sampled if scan.sensor == name]
            rate = sensor.false_alarms_per_scan
            if name in rates and len(of_sensor) < MIN_SCANS:
                if name in config.auto.false_alarms:  # no configured number to keep
                    rate = _clutter_rate(sum(scan.size for scan in of_sensor), len(of_sensor))
                    kept = f"used the mean detections per scan, {rate!r}"
                else:
                    kept = f"kept {rate!r}"
                notes[name] += (
                    f"sensor '{name}': false_alarms_per_scan not estimable from "
                    f"{len(of_sensor)} scans (at least {MIN_SCANS} needed); {kept}",
                )
                rates.remove(name)
            elif name in rates:  # every detection clutter: an upper bound on the rate
                rate = upper[name] = _clutter_rate(sum(s.size for s in of_sensor), len(of_sensor))
            start = self.pds.get(name)
            pd = sensor.detection_probability if name not in self.pds else start or DEFAULT_PD_START
            current[name] = (rate, pd)
        return EMState(
            current=current, rates=tuple(rates), upper=upper, notes=notes,
            pd_estimable=dict.fromkeys(self.pds, False), no_clutter=dict.fromkeys(rates, 0),
            noise=initial_noise(self.config, self.sampled, self.noise) if self.noise.any else None,
            birth=initial_birth(self.config, self.sampled, self.birth) if self.birth.any else None,
        )  # fmt: skip

    def e_step(self, state: EMState) -> EStep:
        """Run the forward pass with ``state.current`` on each block of the sample (no
        refinement: it runs once, on the last pass) and count its associations.

        Raises
        ------
        EstimationStopped
            ``stop`` returned True after a window.
        """
        from mapassoc.estimator.pipeline import WindowEstimator

        estimator = WindowEstimator(config=self._pass_config(state))

        def check_stop(done: int, total: int) -> None:
            if self.stop is not None and self.stop():
                raise EstimationStopped(
                    "stopped while estimating the sensor parameters (pass "
                    f"{len(state.passes) + 1}, {done} of {total} scans)"
                )

        runs = [_forward_run(estimator, piece, check_stop) for piece in self.pieces]
        confidences = [
            self._confidence(state, piece, result)
            for piece, (result, _, _) in zip(self.pieces, runs, strict=True)
        ]
        by_piece = [
            association_counts(piece, result.tracks, self.asked, confidence)
            for piece, (result, _, _), confidence in zip(self.pieces, runs, confidences,
                                                          strict=True)
        ]  # fmt: skip
        return EStep(
            counts={name: _merge([counts[name] for counts in by_piece]) for name in self.asked},
            tracks=sum(len(result.track_rows) for result, _, _ in runs),
            last_run=(estimator, runs[0][1], runs[0][2]) if self.whole else None,
            associations=tuple(
                associations_of(piece, result.track_rows, min_detections=1)
                for piece, (result, _, _) in zip(self.pieces, runs, strict=True)
            ) if self.noise.any or self.birth.any else (),
            weights=tuple(
                {} if confidence is None
                else association_weights(piece, result.track_rows, confidence.associations)
                for piece, (result, _, _), confidence in zip(self.pieces, runs, confidences,
                                                              strict=True)
            ) if self.noise.any else (),
            existence=tuple(
                None if confidence is None else confidence.existence for confidence in confidences
            ) if self.birth.any else (),
        )  # fmt: skip

    def _confidence(
        self, state: EMState, piece: Sequence[Scan], result: EstimateResult
    ) -> TrackConfidence | None:
        """The confidence pass over a pass's forward tracks on ``piece``, for soft counts
        (None: hard counts asked for, or no track to count).

        Raises
        ------
        EstimationStopped
            ``stop`` returned True before one of its windows.
        """
        if not self.settings.soft_counts or not result.track_rows:
            return None
        try:
            return track_confidence(
                self._pass_config(state), piece, result.track_rows, stop=self.stop
            )
        except StopRequested as exc:
            raise EstimationStopped(
                "stopped while estimating the sensor parameters (pass "
                f"{len(state.passes) + 1}, {exc.phase})"
            ) from None

    def _pass_config(self, state: EMState) -> Config:
        """The configuration a pass runs with: ``state``'s sensor values, noise levels and
        birth keys."""
        config = with_sensor_parameters(self.config, state.current)
        return with_birth_levels(with_noise_levels(config, state.noise), state.birth)

    def m_step(self, state: EMState, counts: Mapping[str, AssociationCounts]) -> MStep:
        """The values that maximise the complete-data likelihood of ``counts``: per
        sensor, the unexplained detections per scan (:func:`_clutter_rate`) and the
        detected share of the interior track-scans (when there are at least
        :data:`MIN_INTERIOR_SCANS` and one detection; else ``Pd`` stays)."""
        updated: dict[str, tuple[float, float]] = {}
        pd_estimable = dict(state.pd_estimable)
        no_clutter = dict(state.no_clutter)
        objective = 0.0
        for name in self.asked:
            merged = counts[name]
            rate, pd = state.current[name]
            if name in state.rates:
                unseen = merged.unexplained < UNSEEN_FALSE_ALARMS  # the rate _clutter_rate floors
                no_clutter[name] = merged.scans if unseen else 0
                rate = _clutter_rate(merged.unexplained, merged.scans)
            if name in self.pds:
                pd_estimable[name] = (
                    merged.interior_scans >= MIN_INTERIOR_SCANS and merged.interior_detections > 0
                )
                if pd_estimable[name]:
                    pd = merged.interior_detections / merged.interior_scans
            updated[name] = (rate, pd)
            objective += _objective(merged, rate, pd, self.config.sensors[name].region.volume)
        return MStep(updated, objective, pd_estimable, no_clutter)

    def converged(
        self, current: Mapping[str, tuple[float, float]], updated: Mapping[str, tuple[float, float]]
    ) -> bool:
        """Whether the update moves every rate by at most ``rate_tolerance`` of the larger
        and every ``Pd`` by at most ``pd_tolerance``."""
        settings = self.settings
        return all(
            _close(current[name], updated[name], settings.rate_tolerance, settings.pd_tolerance)
            for name in self.asked
        )

    def done(self, state: EMState) -> bool:
        """Whether the iteration ends: converged, or ``max_passes`` made (the probe at a
        quarter of the upper bound is not counted)."""
        return state.converged or len(state.passes) >= self.settings.max_passes + state.retried

    def step(self, state: EMState) -> EMState:
        """One pass: E step, M step, its :class:`EstimationPass` (given to ``on_pass``),
        then the next values: a quarter of the upper bound once, where it hid every
        track; else the update, unless it :meth:`converged`."""
        started = time.perf_counter()
        e = self.e_step(state)
        m = self.m_step(state, e.counts)
        noise, noise_notes = state.noise, state.noise_notes
        if state.noise is not None:
            longer = [{i: d for i, d in tracks.items() if len(d) >= MIN_TRACK_DETECTIONS}
                      for tracks in e.associations]  # fmt: skip
            noise, noise_notes = noise_m_step(
                self._pass_config(state), self.pieces, longer, self.noise, state.noise,
                e.weights or None,
            )
        birth, birth_notes = state.birth, state.birth_notes
        if state.birth is not None:
            birth, birth_notes = birth_m_step(
                self._pass_config(state), self.pieces, self.starts_recording, e.associations,
                state.birth, e.existence or None,
            )  # fmt: skip
        record = EstimationPass(
            index=len(state.passes), used=dict(state.current), updated=m.updated,
            objective=m.objective, tracks=e.tracks, scans=len(self.sampled),
            seconds=time.perf_counter() - started, noise_used=state.noise, noise_updated=noise,
            birth_used=state.birth, birth_updated=birth,
        )  # fmt: skip
        if self.on_pass is not None:
            self.on_pass(record)
        after = dataclasses.replace(
            state, passes=(*state.passes, record), pd_estimable=m.pd_estimable,
            no_clutter=m.no_clutter, last_run=e.last_run, noise_notes=noise_notes,
            birth_notes=birth_notes,
        )  # fmt: skip
        current, upper = state.current, state.upper
        hidden = [
            name for name in state.rates
            if not state.retried and current[name][0] == upper[name]
            and m.updated[name][0] == upper[name] and upper[name] > 0
        ]  # fmt: skip
        if hidden:  # the upper bound hides every track: try a quarter of it, once
            probe = {
                name: (current[name][0] / 4 if name in hidden else m.updated[name][0],
                       m.updated[name][1])
                for name in self.asked
            }  # fmt: skip
            return dataclasses.replace(after, current=probe, retried=True, noise=noise,
                                       birth=birth)  # fmt: skip
        tolerance = self.settings.rate_tolerance
        if (
            self.converged(current, m.updated) and levels_close(state.noise, noise, tolerance)
            and levels_close(state.birth, birth, tolerance)
        ):  # fmt: skip
            return dataclasses.replace(after, converged=True)
        return dataclasses.replace(after, current=m.updated, noise=noise, birth=birth)

    def finish(self, state: EMState, *, finish: bool = True) -> ParameterEstimate:
        """The estimates: the values the last pass ran with, each sensor's notes, and
        (``finish``, the last pass covering the whole recording) that run finished as a
        run finishes it.

        Raises
        ------
        EstimationStopped
            ``stop`` returned True during the last run's refinement.
        """
        used = state.passes[-1].used
        estimates = {name: self._sensor_estimate(state, name) for name in self.asked}
        noise, birth, last_run = _final_levels(state)
        last_result = None
        if last_run is not None and finish:
            last_result = self._finished_run(last_run)
        return ParameterEstimate(
            config=with_birth_levels(
                with_noise_levels(with_sensor_parameters(self.config, used), noise), birth
            ),
            sensors=estimates,
            passes=state.passes,
            converged=state.converged,
            sample_scans=len(self.sampled),
            result=last_result,
            warnings=tuple(note for estimate in estimates.values() for note in estimate.notes)
            + state.noise_notes + state.birth_notes,
            last_run=None if last_run is None else (last_run[1], tuple(last_run[2])),
            noise=noise,
            birth=birth,
        )

    def _sensor_estimate(self, state: EMState, name: str) -> SensorEstimate:
        """One sensor's estimates after the last pass, with the notes of what was not
        estimable."""
        rate, pd = state.passes[-1].used[name]
        notes = list(state.notes[name])
        estimable = name in self.pds and state.pd_estimable[name]
        if name in self.pds and not estimable:
            notes.append(
                f"sensor '{name}': detection_probability not estimable: its tracks give "
                f"fewer than {MIN_INTERIOR_SCANS} scans between a first and a last "
                f"detection (a recording without targets gives none); kept {pd!r}"
            )
        if state.no_clutter.get(name, 0):
            notes.append(
                f"sensor '{name}': every detection is in a track, so the recording shows no "
                f"false alarms; false_alarms_per_scan = {rate:.4g} ({UNSEEN_FALSE_ALARMS:g} "
                f"false alarm over its {state.no_clutter[name]} scans: the estimator needs a "
                "rate > 0)"
            )
        return SensorEstimate(
            sensor=name, false_alarms_per_scan=rate, detection_probability=pd,
            rate_estimated=name in state.rates, pd_estimated=estimable, notes=tuple(notes),
        )  # fmt: skip

    def _finished_run(
        self, last_run: tuple[WindowEstimator, RunState, list[WindowReport]]
    ) -> EstimateResult:
        """The estimator's answer under the returned values: the last pass's windows,
        finished as a run finishes them (refined when refine_passes > 0).  The Kmax
        warning of its windows was given when the pass itself finished."""
        estimator, state, reports = last_run
        with warnings.catch_warnings():
            warnings.filterwarnings(
                "ignore", message=r"p\(K = Kmax \| Z\) exceeded", category=RuntimeWarning
            )
            try:
                return estimator.finish(self.scans, state, windows=reports, stop=self.stop)
            except StopRequested as exc:
                raise EstimationStopped(
                    f"stopped while estimating the sensor parameters ({exc.phase} of the last pass)"
                ) from None


def _final_levels(
    state: EMState,
) -> tuple[
    NoiseLevels | None,
    BirthLevels | None,
    tuple[WindowEstimator, RunState, list[WindowReport]] | None,
]:
    """The noise levels and birth keys returned, and the last run that goes with the
    estimates.

    Unlike the sensor parameters, the noise levels and birth keys returned are the last
    pass's update (the fixed point of their EM on that pass's associations), not the
    values it ran with: the update is an exact EM fixed point given the associations,
    and from a start far from the truth three passes may not reach it.  When it moved
    them by more than :data:`_NOISE_RUN_TOLERANCE`, the last pass's run is not the
    estimator's answer under them and is dropped (the caller runs again, as after a
    sampled recording); within it, the values the pass ran with are returned with it.
    """
    last = state.passes[-1]
    if levels_close(last.noise_used, last.noise_updated, _NOISE_RUN_TOLERANCE) and levels_close(
        last.birth_used, last.birth_updated, _NOISE_RUN_TOLERANCE
    ):
        return last.noise_used, last.birth_used, state.last_run
    return last.noise_updated, last.birth_updated, None


_NOISE_RUN_TOLERANCE = 0.02
"""Relative change of the noise levels below which the last pass's run is kept as the
run under the returned levels (they are then the levels it ran with)."""


def _asked(
    config: Config,
    false_alarms: Collection[str] | None,
    detection_probability: Mapping[str, float | None] | None,
) -> tuple[tuple[str, ...], dict[str, float | None]]:
    """The sensors whose rate to estimate and those whose ``Pd`` (with its start),
    checked; the configuration's "auto" ones when neither is given.

    Raises
    ------
    InputError
        An unknown sensor, a start outside (0, 1], or an "auto" value not asked for.
    """
    if false_alarms is None and detection_probability is None:
        false_alarms, detection_probability = config.auto.false_alarms, config.auto.pd_starts()
    rates = tuple(dict.fromkeys(false_alarms or ()))
    for name in rates:
        _check_sensor(config, name, "false_alarms_per_scan")
    pds = _check_starts(config, detection_probability or {})
    left = [
        f"sensor '{n}' false_alarms_per_scan" for n in config.auto.false_alarms if n not in rates
    ]
    left += [f"sensor '{n}' detection_probability" for n in config.auto.pd_starts()
             if n not in pds]  # fmt: skip
    if left:
        raise InputError(
            f'the configuration leaves {", ".join(left)} = "auto", which this call does '
            "not estimate; ask for it too, or call without false_alarms and "
            "detection_probability to estimate what the configuration asks",
            key="auto",
        )
    return rates, pds


def _clutter_rate(count: float, scans: int) -> float:
    """False alarms per scan from ``count`` over ``scans`` scans, never 0: a count of 0 is
    taken as :data:`UNSEEN_FALSE_ALARMS` (the estimator needs a rate > 0)."""
    return max(count, UNSEEN_FALSE_ALARMS) / max(scans, 1)


def _forward_run(
    estimator: WindowEstimator, scans: Sequence[Scan], check_stop: Callable[[int, int], None]
) -> tuple[EstimateResult, RunState, list[WindowReport]]:
    """The window estimator's forward pass over ``scans`` (no refinement): its result, its
    done run state and its window reports; ``check_stop`` polled after every window."""
    state = estimator.start(scans)
    reports: list[WindowReport] = []
    while not state.done:
        reports.append(estimator.step(scans, state))
        check_stop(state.next_scan, state.total_scans)
    return estimator.finish(scans, state, windows=reports, refine=False), state, reports


def _merge(parts: Sequence[AssociationCounts]) -> AssociationCounts:
    return AssociationCounts(
        scans=sum(p.scans for p in parts),
        detections=sum(p.detections for p in parts),
        explained=sum(p.explained for p in parts),
        interior_scans=sum(p.interior_scans for p in parts),
        interior_detections=sum(p.interior_detections for p in parts),
        clutter_per_scan=tuple(c for p in parts for c in p.clutter_per_scan),
    )


def _close(
    a: tuple[float, float], b: tuple[float, float], rate_tolerance: float, pd_tolerance: float
) -> bool:
    rate_a, pd_a = a
    rate_b, pd_b = b
    scale = max(rate_a, rate_b)
    rate_ok = scale == 0 or abs(rate_a - rate_b) <= rate_tolerance * scale
    return rate_ok and abs(pd_a - pd_b) <= pd_tolerance
