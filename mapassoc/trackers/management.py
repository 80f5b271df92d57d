"""Track management shared by the scan-by-scan baselines (GNN, JPDA): start, confirm, delete.

Every live track is either *tentative* or *confirmed*; confirmation is permanent, and a
track leaves the live set only when its rule deletes it.  Scans are processed one at a
time in (time, sensor) order, so several sensors simply interleave: each scan of any
sensor is one step of every live track.

* **Start.**  Every detection that no live track used (the tracker decides what "used"
  means) starts a tentative track with the single-point initiation of
  :func:`mapassoc.filtering.track_filter.start_track`, the same as the rest of the library.
  The new-target density is the birth model's (:mod:`mapassoc.models.population`): a
  target never detected before has density ``u Pd / V`` at a scan, ``u`` the undetected
  targets' expected number, advanced scan by scan by
  :func:`~mapassoc.models.population.window_population`; when ``u = 0`` no detection
  starts a track.
* **Confirm and delete** by one of two rules, chosen by the tracker's ``management``
  keyword:

  - :class:`ScoreRule`, the sequential track score (log-likelihood ratio, Blackman &
    Popoli, *Design and Analysis of Modern Tracking Systems*, 1999, section 6.2).  The
    first detection scores ``log(beta_NT / beta_FT) = log(u Pd / V) - log(lambda_bar / V)
    = log u + log Pd - log lambda_bar`` (new-target over false-target density); a later
    detection adds ``log Pd + log N(nu; 0, S) - log lambda`` and a miss
    ``log(1 - Pd P_G)`` (eqs. 6.9-6.13; the trackers compute the increments).  A track
    is confirmed when its score reaches Wald's upper SPRT threshold
    ``T2 = log((1 - beta) / alpha)`` (Blackman & Popoli, eq. 6.18), alpha the probability
    of confirming a false track and beta that of missing (rejecting) a true one, and is
    deleted when its score falls ``deletion_drop`` below the highest score it has had
    (the score-drop deletion of Blackman & Popoli, section 6.3.3, as in common
    implementations).
  - :class:`MOfNRule`: confirmed with ``confirm_hits`` detections in its first
    ``confirm_scans`` scans (its first detection's scan is the first of them); a
    tentative track that can no longer reach ``confirm_hits`` is deleted; a confirmed
    track is deleted after ``delete_misses`` consecutive misses (Blackman & Popoli,
    section 6.3.1; Bar-Shalom, Willett & Tian, *Tracking and Data Fusion*, 2011, ch. 3).

A "detection" of a step is what the tracker says it is: an assigned detection (GNN), or
a probability above 1/2 that some detection is the track's (JPDA).

:class:`TrackManager` keeps the live tracks and every step of every track (filtered
moments and the detection used) so a tracker can report whole tracks, tentative history
included.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from mapassoc.array_types import BoolArray, FloatArray
from mapassoc.data.config import Config, check_config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.terms import SensorTerms, birth_term, miss_term
from mapassoc.filtering.track_filter import (
    FilteredTrack,
    Innovations,
    innovations,
    predict_track,
    start_track,
)
from mapassoc.models.population import UndetectedTargets, recording_start, window_population
from mapassoc.validation import check_positive, check_probability

__all__ = [
    "ManagedTrack",
    "ManagementRule",
    "MOfNRule",
    "ScoreRule",
    "StepOutcome",
    "TrackLife",
    "TrackManager",
    "TrackStep",
    "check_tracker_config",
    "gated_log_ratios",
    "with_own_gate",
    "management_rule",
    "new_target_log_ratio",
]


@dataclass(frozen=True)
class TrackLife:
    """Where a track stands in its management rule.

    Attributes
    ----------
    score : float
        Track score (log-likelihood ratio); kept by both rules, used by :class:`ScoreRule`.
    max_score : float
        Highest score so far.
    hits : int
        Steps with a detection, the first detection included.
    scans : int
        Steps so far, the first detection's scan included.
    consecutive_misses : int
        Steps without a detection since the last one.
    confirmed : bool
        Whether the track has been confirmed (permanent).
    """

    score: float
    max_score: float
    hits: int
    scans: int
    consecutive_misses: int
    confirmed: bool


def _advance(life: TrackLife, detected: bool, increment: float) -> TrackLife:
    score = life.score + increment
    return replace(
        life,
        score=score,
        max_score=max(life.max_score, score),
        hits=life.hits + int(detected),
        scans=life.scans + 1,
        consecutive_misses=0 if detected else life.consecutive_misses + 1,
    )


@dataclass(frozen=True)
class ScoreRule:
    """Sequential-track-score management (Blackman & Popoli 1999, section 6.2).

    Parameters
    ----------
    false_track_probability : float
        alpha, the probability of confirming a false track, in (0, 1).
    missed_track_probability : float
        beta, the probability of rejecting a true track, in (0, 1), alpha + beta < 1.
        The defaults (``T2 = log(0.95 / 1e-4) ~ 9.2``) were chosen by measurement: over
        alpha in {1e-5, 1e-4, 1e-3} (GNN; crossing, dense, dense_pd08, parallel, turning,
        seeds 0-2), 1e-4 was never worse than 1e-5 and better on dense_pd08, and 1e-3
        started false tracks on turning.
    deletion_drop : float
        A track is deleted when its score is more than this below its highest score, > 0.
        The default lets a confirmed track coast through three consecutive misses at
        ``Pd = 0.9`` (each ``log(1 - 0.9 P_G) ~ -2.3``) and deletes it at the fourth.
    """

    false_track_probability: float = 1e-4
    missed_track_probability: float = 0.05
    deletion_drop: float = 7.0

    def __post_init__(self) -> None:
        a = check_probability(
            "false_track_probability", self.false_track_probability,
            allow_zero=False, allow_one=False,
        )
        b = check_probability(
            "missed_track_probability", self.missed_track_probability,
            allow_zero=False, allow_one=False,
        )
        if not a + b < 1.0:
            raise InputError(
                f"false_track_probability + missed_track_probability must be < 1, got "
                f"{a} + {b}"
            )
        check_positive("deletion_drop", self.deletion_drop)

    @property
    def confirmation_threshold(self) -> float:
        """Wald's upper threshold ``T2 = log((1 - beta) / alpha)`` (Blackman & Popoli, eq. 6.18)."""
        return math.log1p(-self.missed_track_probability) - math.log(
            self.false_track_probability
        )

    @property
    def rejection_threshold(self) -> float:
        """Wald's lower threshold ``T1 = log(beta / (1 - alpha))`` (eq. 6.18); reported for
        reference: deletion uses the score drop, as the initial score of a birth among
        clutter is often already below ``T1``."""
        return math.log(self.missed_track_probability) - math.log1p(
            -self.false_track_probability
        )

    def start(self, initial_score: float) -> TrackLife:
        """A new track's life from its first detection's score."""
        return TrackLife(
            score=initial_score,
            max_score=initial_score,
            hits=1,
            scans=1,
            consecutive_misses=0,
            confirmed=initial_score >= self.confirmation_threshold,
        )

    def step(self, life: TrackLife, *, detected: bool, increment: float) -> TrackLife:
        """The life after one more scan whose score increment is ``increment``."""
        new = _advance(life, detected, increment)
        if not new.confirmed and new.score >= self.confirmation_threshold:
            new = replace(new, confirmed=True)
        return new

    def deleted(self, life: TrackLife) -> bool:
        """Whether the score dropped more than ``deletion_drop`` below its maximum."""
        return bool(life.max_score - life.score > self.deletion_drop)


@dataclass(frozen=True)
class MOfNRule:
    """M-of-N confirmation, deletion after consecutive misses.

    Parameters
    ----------
    confirm_hits : int
        M >= 1: detections needed within the first N scans (the first detection counts).
    confirm_scans : int
        N >= M: the scans (of any sensor) from the first detection's on in which the M
        detections must fall.
    delete_misses : int
        A confirmed track is deleted after this many consecutive misses (>= 1).
    """

    confirm_hits: int = 3
    confirm_scans: int = 4
    delete_misses: int = 3

    def __post_init__(self) -> None:
        for name in ("confirm_hits", "confirm_scans", "delete_misses"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InputError(f"{name} must be an integer >= 1, got {value!r}")
        if self.confirm_hits > self.confirm_scans:
            raise InputError(
                f"confirm_hits (M = {self.confirm_hits}) must be <= confirm_scans "
                f"(N = {self.confirm_scans})"
            )

    def start(self, initial_score: float) -> TrackLife:
        """A new track's life (one hit in one scan; confirmed at once when M = 1)."""
        return TrackLife(
            score=initial_score,
            max_score=initial_score,
            hits=1,
            scans=1,
            consecutive_misses=0,
            confirmed=self.confirm_hits <= 1,
        )

    def step(self, life: TrackLife, *, detected: bool, increment: float) -> TrackLife:
        """The life after one more scan (``increment`` only updates the kept score)."""
        new = _advance(life, detected, increment)
        if (
            not new.confirmed
            and new.scans <= self.confirm_scans
            and new.hits >= self.confirm_hits
        ):
            new = replace(new, confirmed=True)
        return new

    def deleted(self, life: TrackLife) -> bool:
        """Tentative: M can no longer be reached in N; confirmed: ``delete_misses`` misses
        in a row."""
        if life.confirmed:
            return life.consecutive_misses >= self.delete_misses
        return (
            life.scans >= self.confirm_scans
            or life.hits + self.confirm_scans - life.scans < self.confirm_hits
        )


ManagementRule = ScoreRule | MOfNRule
"""A track-management rule of the baselines: a score rule or an M-of-N rule."""


def management_rule(rule: ManagementRule | None) -> ManagementRule:
    """``rule``, or the default :class:`ScoreRule` for ``None``; refuses anything else."""
    if rule is None:
        return ScoreRule()
    if not isinstance(rule, (ScoreRule, MOfNRule)):
        raise InputError(
            f"management must be a ScoreRule or an MOfNRule, got {type(rule).__name__}"
        )
    return rule


def with_own_gate(config: Config, gate_probability: float | None) -> Config:
    """``config`` as a baseline tracker sees it: with its own gate probability, if given.

    The baselines gate with ``config.estimator.pruning.gate_probability`` unless their
    ``gate_probability`` option (``[trackers.<name>] gate_probability = ...``) says
    otherwise; the option is checked as that setting is (a probability in (0, 1], by
    :class:`~mapassoc.data.settings.EstimatorSettings`).
    """
    check_config(config)
    if gate_probability is None:
        return config
    pruning = replace(config.estimator.pruning, gate_probability=gate_probability)
    return replace(config, estimator=replace(config.estimator, pruning=pruning))


def check_tracker_config(config: Config) -> None:
    """Refuse models the track scores cannot express.

    Every sensor needs ``false_alarms_per_scan > 0`` (scores are ratios against the
    false-alarm density, as in the window estimator) and ``Pd * P_G < 1`` (otherwise a
    track could never miss a scan: ``log(1 - Pd P_G) = -inf``).
    """
    check_config(config)
    pg = config.estimator.pruning.gate_probability
    for name, sensor in config.sensors.items():
        if not sensor.false_alarms_per_scan > 0:
            raise InputError(
                f"sensor '{name}' has false_alarms_per_scan = {sensor.false_alarms_per_scan}; "
                "track scores are ratios against the false-alarm density and need a positive "
                "rate (use a small value such as 1e-6 for nearly clutter-free data)"
            )
        if not sensor.detection_probability * pg < 1.0:
            raise InputError(
                f"sensor '{name}' has detection_probability {sensor.detection_probability} "
                f"and gate_probability is {pg}: with Pd * P_G = 1 a track can never miss a "
                "scan; use gate_probability < 1"
            )


def new_target_log_ratio(
    config: Config, scan: Scan, undetected: UndetectedTargets | None
) -> tuple[float, UndetectedTargets]:
    """The score of a track that starts at a detection of ``scan``, and the undetected
    targets after the scan.

    ``log(beta_NT / beta_FT) = log u + log Pd - log lambda_bar`` (Blackman & Popoli 1999,
    eq. 6.8, with the new-target density ``beta_NT = u Pd / V`` and the false-alarm density
    ``beta_FT = lambda_bar / V``; the window estimator's first-detection score,
    :mod:`mapassoc.estimator.hypotheses`), where ``u`` is the expected number of targets
    not detected before the scan (:func:`~mapassoc.models.population.window_population`);
    ``-inf`` when ``u = 0``.

    Parameters
    ----------
    config : Config
    scan : Scan
    undetected : UndetectedTargets or None
        The undetected targets after the previous scan; ``None`` at the recording's start.
    """
    sensor = config.sensors[scan.sensor]
    start = recording_start(config.birth, scan.time) if undetected is None else undetected
    population = window_population([scan], [sensor.detection_probability], config.birth, start)
    u = float(population.first_detection_means[0])
    own = SensorTerms.of(sensor, config.estimator.pruning.gate_probability)
    log_new = birth_term(u, own.log_pd, own.log_false_alarms)
    return log_new, population.after_scan[0]


def gated_log_ratios(
    config: Config, tracks: Sequence[FilteredTrack], scan: Scan
) -> tuple[FloatArray, list[Innovations]]:
    """Detection log-likelihood ratios of every (track, detection) pair inside the gate.

    ``log Pd + log N(nu; 0, S) - log lambda`` (Blackman & Popoli 1999, eq. 6.10; Afzal's survey,
    eqs. 11-13) where ``nu^T S^-1 nu`` is within the chi-square gate of probability
    ``config.estimator.pruning.gate_probability``; ``-inf`` outside.

    Parameters
    ----------
    config : Config
    tracks : sequence of FilteredTrack, length T
        Predicted to ``scan.time``.
    scan : Scan
        ``M`` detections.

    Returns
    -------
    log_ratio : ndarray, shape (T, M)
    innovations : list of Innovations, length T
    """
    sensor = config.sensors[scan.sensor]
    own = SensorTerms.of(sensor, config.estimator.pruning.gate_probability)
    threshold, offset = own.threshold, own.log_pd - own.log_clutter
    out = np.full((len(tracks), scan.size), -math.inf)
    innov = []
    for t, track in enumerate(tracks):
        inn = innovations(config, track, scan)
        inside = inn.d2 <= threshold
        out[t, inside] = offset + inn.log_likelihood[inside]
        innov.append(inn)
    return out, innov


@dataclass(frozen=True, eq=False)
class ManagedTrack:
    """One live track: its filter and its life.

    Attributes
    ----------
    track_id : int
        Unique id, >= 1, in order of birth.
    filtered : FilteredTrack
    life : TrackLife
    """

    track_id: int
    filtered: FilteredTrack
    life: TrackLife


@dataclass(frozen=True, eq=False)
class TrackStep:
    """One scan of one track, after its update.

    Attributes
    ----------
    scan_index : int
    filtered : FilteredTrack
        Filtered moments after the scan.
    detection : int
        Index of the detection the track used (hard association) or reports (JPDA: the
        most probable one when its probability exceeds 1/2), ``-1`` for none.
    detected : bool
        Whether the step counted as a detection for the management rule.
    hard : bool
        Whether ``detection`` is a hard association (GNN, tentative JPDA tracks).
    score : float
        Track score after the scan.
    confirmed : bool
        Whether the track is confirmed after the scan.
    """

    scan_index: int
    filtered: FilteredTrack
    detection: int
    detected: bool
    hard: bool
    score: float
    confirmed: bool


@dataclass(frozen=True, eq=False)
class StepOutcome:
    """What a tracker decided for one live track at one scan.

    Attributes
    ----------
    filtered : FilteredTrack
        Updated moments.
    detection : int
        As :attr:`TrackStep.detection`.
    detected : bool
        Whether the scan counts as a detection (hit) for the management rule.
    increment : float
        Score increment of the scan (log-likelihood ratio).
    hard : bool
        Whether ``detection`` is a hard association.
    """

    filtered: FilteredTrack
    detection: int
    detected: bool
    increment: float
    hard: bool = True


class TrackManager:
    """Live tracks, their histories, births and the management rule.

    Use per scan: :meth:`predict` (returns the live tracks predicted to the scan), then
    :meth:`commit` with one :class:`StepOutcome` per live track and the detections free
    to start tracks.

    Parameters
    ----------
    config : Config
        Models; :func:`check_tracker_config` must accept it.
    rule : ScoreRule or MOfNRule
    """

    def __init__(self, *, config: Config, rule: ManagementRule) -> None:
        check_tracker_config(config)
        self.config = config
        self.rule = management_rule(rule)
        self.live: list[ManagedTrack] = []
        self.history: dict[int, list[TrackStep]] = {}
        self.confirmed_ids: set[int] = set()
        self._next_id = 1
        self._undetected: UndetectedTargets | None = None
        self._log_new_target = -math.inf
        self._scan_index = -1

    @property
    def tracks_started(self) -> int:
        """Tracks started so far."""
        return self._next_id - 1

    def predict(self, scan_index: int, scan: Scan) -> list[ManagedTrack]:
        """Advance to scan ``scan_index``: live tracks predicted to its time.

        Also advances the undetected-target intensity to the scan (the new-target
        density of births).
        """
        if scan_index != self._scan_index + 1:
            raise InputError(
                f"scans must be processed in order: expected scan {self._scan_index + 1}, "
                f"got {scan_index}"
            )
        self._scan_index = scan_index
        self._log_new_target, self._undetected = new_target_log_ratio(
            self.config, scan, self._undetected
        )
        self.live = [
            replace(track, filtered=predict_track(self.config, track.filtered, scan.time))
            for track in self.live
        ]
        return list(self.live)

    def miss_log_ratio(self, scan: Scan) -> float:
        """``log(1 - Pd P_G)`` of the scan's sensor (Blackman & Popoli, eq. 6.13)."""
        return miss_term(
            self.config.sensors[scan.sensor].detection_probability,
            self.config.estimator.pruning.gate_probability,
        )

    def commit(
        self,
        scan: Scan,
        outcomes: Sequence[StepOutcome],
        free: BoolArray,
    ) -> None:
        """Apply one scan's outcomes, delete tracks, start tracks at free detections.

        Parameters
        ----------
        scan : Scan
            The scan of the last :meth:`predict`.
        outcomes : sequence of StepOutcome
            One per live track, in the order :meth:`predict` returned them.
        free : ndarray of bool, shape (M,)
            Detections no live track used: each starts a tentative track.
        """
        if len(outcomes) != len(self.live):
            raise InputError(
                f"outcomes must have one entry per live track ({len(self.live)}), got "
                f"{len(outcomes)}"
            )
        free = np.asarray(free, dtype=bool)
        if free.shape != (scan.size,):
            raise InputError(f"free must have shape ({scan.size},), got {free.shape}")
        k = self._scan_index
        kept: list[ManagedTrack] = []
        for track, outcome in zip(self.live, outcomes, strict=True):
            life = self.rule.step(
                track.life, detected=outcome.detected, increment=outcome.increment
            )
            self.history[track.track_id].append(
                TrackStep(
                    k, outcome.filtered, outcome.detection, outcome.detected, outcome.hard,
                    life.score, life.confirmed,
                )
            )
            if life.confirmed:
                self.confirmed_ids.add(track.track_id)
            if not self.rule.deleted(life):
                kept.append(ManagedTrack(track.track_id, outcome.filtered, life))
        if self._log_new_target > -math.inf:
            for j in np.flatnonzero(free).tolist():
                track_id = self._next_id
                self._next_id += 1
                filtered = start_track(self.config, scan, j)
                life = self.rule.start(self._log_new_target)
                self.history[track_id] = [
                    TrackStep(k, filtered, j, True, True, life.score, life.confirmed)
                ]
                if life.confirmed:
                    self.confirmed_ids.add(track_id)
                kept.append(ManagedTrack(track_id, filtered, life))
        self.live = kept

    def confirmed_histories(self) -> dict[int, list[TrackStep]]:
        """Every track ever confirmed (live or deleted), with all its steps."""
        return {tid: self.history[tid] for tid in sorted(self.confirmed_ids)}
