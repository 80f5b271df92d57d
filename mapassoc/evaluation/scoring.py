"""Every metric of one tracker run as one typed, flat result.

:func:`score_tracks` scores a :class:`~mapassoc.data.outputs.TrackerOutput` against a
:class:`~mapassoc.data.io.TruthTable`: GOSPA (:mod:`mapassoc.evaluation.metrics`), OSPA and
OSPA(2) (:mod:`mapassoc.evaluation.ospa`), CLEAR-MOT (:mod:`mapassoc.evaluation.clear_mot`,
needs the optional extra ``metrics``) and, for trackers that report p(K | Z), the count
scores of :mod:`mapassoc.evaluation.calibration`, T-GOSPA of the trajectories with the
fragments per target of its assignment (:mod:`mapassoc.evaluation.tgospa`), and P-GOSPA
(Xia, García-Fernández, Karlsson, Yuan, Chang and Svensson, "Probabilistic GOSPA";
:func:`mapassoc.evaluation.tables.pgospa_tables`), which scores the existence
probabilities of the track table as well (a tracker that reports none gets its GOSPA).
Positions are the ``x``, ``y`` (and ``z``) columns both tables have, and a track written
twice at one time keeps its last row (:mod:`mapassoc.evaluation.tables`).
:meth:`TrackingScores.as_row` gives a flat dictionary for one row of a pandas DataFrame.
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass

import numpy as np

from mapassoc.data.io import TruthTable
from mapassoc.data.outputs import TrackerOutput
from mapassoc.errors import InputError
from mapassoc.evaluation.calibration import DEFAULT_BINS, CountScores, count_series_scores
from mapassoc.evaluation.clear_mot import ClearMotResult, clear_mot
from mapassoc.evaluation.metrics import GospaSeries, gospa_over_time
from mapassoc.evaluation.ospa import ospa2, ospa2_over_time, ospa_over_time
from mapassoc.evaluation.pgospa import PgospaSeries
from mapassoc.evaluation.points import TimedPoints, check_cost_powers, check_order
from mapassoc.evaluation.tables import (
    disjoint_times_message,
    pgospa_tables,
    position_names,
    track_points,
    truth_points,
)
from mapassoc.evaluation.tgospa import (
    TgospaResult,
    TrackFragmentation,
    _check_method,
    fragmentation_of,
    tgospa,
)
from mapassoc.validation import check_positive

__all__ = ["TrackingScores", "score_tracks"]


@dataclass(frozen=True)
class TrackingScores:
    """Scores of one tracker run against the truth.

    Parameters
    ----------
    c : float
        Cut-off of GOSPA, OSPA and OSPA(2).
    p : float
        Order of GOSPA, OSPA and OSPA(2).
    gospa : float
        Mean over evaluation times of GOSPA (alpha = 2).
    gospa_localisation, gospa_missed, gospa_false : float
        Means over times of the three p-th power parts of GOSPA.
    ospa : float
        Mean over evaluation times of OSPA.
    ospa2 : float
        OSPA(2) over the whole run, or the mean over sliding windows when
        ``ospa2_window`` is set.
    ospa2_window : int or None
        Evaluation times per OSPA(2) window; ``None`` for the whole run.
    mota, motp : float or None
        CLEAR-MOT accuracy and precision (``motp`` is a mean distance, ``nan`` without any
        match); ``None`` when CLEAR-MOT was not computed.
    id_switches, fragmentations, mostly_tracked, mostly_lost : int or None
        CLEAR-MOT counts; ``None`` when CLEAR-MOT was not computed.
    motp_threshold : float or None
        Distance below which a truth and a track row may correspond in CLEAR-MOT.
    k_brier, k_ece, k_hit_rate : float or None
        Count scores of the tracker's p(K | Z); ``None`` when it reports none.
    num_tracks : int
        Distinct track ids of the output.
    seconds : float
        The tracker's wall time.
    tgospa : float
        T-GOSPA of the whole run (same ``c`` and ``p``, switching cost ``tgospa_gamma``).
    tgospa_switching : float
        Its switching part (a p-th power: ``gamma^p`` per switch).
    tgospa_gamma : float
        The switching cost gamma used.
    fragments_per_target : float
        Mean distinct track ids per true target tracked at least once, from the T-GOSPA
        assignment (1.0 is ideal; ``nan`` when no target was tracked).
    tgospa_id_switches : int
        Changes of a target's track id between consecutive times in that assignment.
    pgospa : float
        Mean over evaluation times of P-GOSPA (same ``c`` and ``p``, alpha = 2) with the
        existence probabilities of the output's track table (1 where it has none, and then
        equal to ``gospa``).
    pgospa_existence_mismatch : float
        Mean over times of its existence-mismatch part (a p-th power quantity; 0 without
        existence probabilities).
    """

    c: float
    p: float
    gospa: float
    gospa_localisation: float
    gospa_missed: float
    gospa_false: float
    ospa: float
    ospa2: float
    ospa2_window: int | None
    mota: float | None
    motp: float | None
    id_switches: int | None
    fragmentations: int | None
    mostly_tracked: int | None
    mostly_lost: int | None
    motp_threshold: float | None
    k_brier: float | None
    k_ece: float | None
    k_hit_rate: float | None
    num_tracks: int
    seconds: float
    tgospa: float
    tgospa_switching: float
    tgospa_gamma: float
    fragments_per_target: float
    tgospa_id_switches: int
    pgospa: float
    pgospa_existence_mismatch: float

    def as_row(self) -> dict[str, float | int | None]:
        """The fields as a flat dictionary (one DataFrame row), in declaration order."""
        return asdict(self)


def score_tracks(
    truth: TruthTable,
    output: TrackerOutput,
    *,
    c: float,
    p: float = 2.0,
    motp_threshold: float | None = None,
    clear_mot_scores: bool = True,
    ospa2_window: int | None = None,
    num_bins: int = DEFAULT_BINS,
    switch_cost: float | None = None,
    tgospa_method: str = "milp",
) -> TrackingScores:
    """Score a tracker's output against the truth.

    Parameters
    ----------
    truth : TruthTable
        True states; at least one record.
    output : TrackerOutput
        The tracker's result; its ``counts`` (if any) are scored too.
    c : float
        Cut-off of GOSPA, OSPA and OSPA(2), > 0.
    p : float
        Their order, ``1 <= p < inf``.
    motp_threshold : float, optional
        CLEAR-MOT correspondence threshold (> 0); ``None`` uses ``c``.
    clear_mot_scores : bool
        Compute CLEAR-MOT (needs ``motmetrics``: ``pip install 'mapassoc[metrics]'``); with
        ``False`` its fields are ``None``.
    ospa2_window : int, optional
        Evaluation times per OSPA(2) sliding window; ``None`` scores the whole run at once.
    num_bins : int
        Bins of the expected calibration error of p(K | Z).
    switch_cost : float, optional
        T-GOSPA switching cost gamma (> 0); ``None`` uses ``c``.
    tgospa_method : {"milp", "lp"}
        Exact T-GOSPA, or its LP relaxation (a lower bound) for very large runs.

    Returns
    -------
    TrackingScores

    Raises
    ------
    InputError
        Bad arguments, no truth record, tables without a shared position column, or
        ``clear_mot_scores`` without ``motmetrics`` installed.

    Warns (``UserWarning``) when the tracks and the truth share no time
    (:func:`~mapassoc.evaluation.tables.disjoint_times_message`).
    """
    _check_tables(truth, output)
    settings = _ScoringSettings.checked(
        c=c,
        p=p,
        motp_threshold=motp_threshold,
        clear_mot_scores=clear_mot_scores,
        ospa2_window=ospa2_window,
        switch_cost=switch_cost,
        tgospa_method=tgospa_method,
    )
    names = position_names(truth, output.tracks)
    message = disjoint_times_message(truth, output.tracks)
    if message is not None:
        warnings.warn(message, UserWarning, stacklevel=2)
    metrics = _measure(truth_points(truth, names), track_points(output.tracks, names), settings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # warned just above
        probabilistic = pgospa_tables(truth, output.tracks, c=settings.cutoff, p=settings.order)

    counts = (
        None
        if output.counts is None
        else count_series_scores(truth, output.counts, num_bins=num_bins)
    )
    return _tracking_scores(settings, metrics, counts, output, probabilistic)


def _check_tables(truth: object, output: object) -> None:
    """Raise unless ``truth`` is a TruthTable with a record and ``output`` a TrackerOutput."""
    if not isinstance(truth, TruthTable):
        raise InputError(f"truth must be a TruthTable, got {type(truth).__name__}")
    if not isinstance(output, TrackerOutput):
        raise InputError(f"output must be a TrackerOutput, got {type(output).__name__}")
    if truth.times.shape[0] == 0:
        raise InputError("truth has no records: there is nothing to score against")


@dataclass(frozen=True)
class _ScoringSettings:
    """The checked arguments of :func:`score_tracks` that the metrics read.

    Attributes
    ----------
    cutoff, order : float
        ``c`` and ``p``.
    threshold : float
        The CLEAR-MOT correspondence threshold (``c`` unless given).
    gamma : float
        The T-GOSPA switching cost (``c`` unless given).
    method : str
        ``"milp"`` or ``"lp"``.
    clear_mot_scores : bool
    ospa2_window : int or None
    """

    cutoff: float
    order: float
    threshold: float
    gamma: float
    method: str
    clear_mot_scores: bool
    ospa2_window: int | None

    @classmethod
    def checked(
        cls,
        *,
        c: float,
        p: float,
        motp_threshold: float | None,
        clear_mot_scores: bool,
        ospa2_window: int | None,
        switch_cost: float | None,
        tgospa_method: str,
    ) -> _ScoringSettings:
        """The settings after checking each argument (messages name the argument)."""
        cutoff = check_positive("c", c)
        order = check_order(p)
        threshold = (
            cutoff if motp_threshold is None else check_positive("motp_threshold", motp_threshold)
        )
        gamma = cutoff if switch_cost is None else check_positive("switch_cost", switch_cost)
        check_cost_powers(order, c=cutoff, switch_cost=gamma)
        method = _check_method(tgospa_method, "tgospa_method")
        if not isinstance(clear_mot_scores, bool):
            raise InputError(f"clear_mot_scores must be True or False, got {clear_mot_scores!r}")
        return cls(cutoff, order, threshold, gamma, method, clear_mot_scores, ospa2_window)


@dataclass(frozen=True)
class _Metrics:
    """The metrics of one run, before they are flattened into :class:`TrackingScores`."""

    gospa: GospaSeries
    ospa: float
    ospa2: float
    trajectory: TgospaResult
    fragmentation: TrackFragmentation
    mot: ClearMotResult | None


def _measure(
    truth_run: TimedPoints, track_run: TimedPoints, settings: _ScoringSettings
) -> _Metrics:
    """GOSPA, OSPA, OSPA(2), T-GOSPA with its fragmentation, and CLEAR-MOT if asked for."""
    cutoff, order = settings.cutoff, settings.order
    gospa_series = gospa_over_time(truth_run, track_run, c=cutoff, p=order)
    ospa_series = ospa_over_time(truth_run, track_run, c=cutoff, p=order)
    if settings.ospa2_window is None:
        ospa2_value = ospa2(truth_run, track_run, c=cutoff, p=order).total
    else:
        ospa2_value = ospa2_over_time(
            truth_run, track_run, c=cutoff, p=order, window_length=settings.ospa2_window
        ).mean_total
    trajectory = tgospa(
        truth_run, track_run, c=cutoff, gamma=settings.gamma, p=order, method=settings.method
    )
    fragmentation = fragmentation_of(trajectory)
    mot = (
        clear_mot(truth_run, track_run, threshold=settings.threshold)
        if settings.clear_mot_scores
        else None
    )
    return _Metrics(
        gospa=gospa_series,
        ospa=ospa_series.mean_total,
        ospa2=float(ospa2_value),
        trajectory=trajectory,
        fragmentation=fragmentation,
        mot=mot,
    )


def _tracking_scores(
    settings: _ScoringSettings,
    metrics: _Metrics,
    counts: CountScores | None,
    output: TrackerOutput,
    probabilistic: PgospaSeries,
) -> TrackingScores:
    """The metrics as one flat :class:`TrackingScores` (``None`` for what was not computed)."""
    gospa, mot, window = metrics.gospa, metrics.mot, settings.ospa2_window
    return TrackingScores(
        c=settings.cutoff,
        p=settings.order,
        gospa=gospa.mean_total,
        gospa_localisation=gospa.mean_localisation,
        gospa_missed=gospa.mean_missed,
        gospa_false=gospa.mean_false,
        ospa=metrics.ospa,
        ospa2=metrics.ospa2,
        ospa2_window=None if window is None else int(window),
        mota=None if mot is None else mot.mota,
        motp=None if mot is None else mot.motp,
        id_switches=None if mot is None else mot.num_switches,
        fragmentations=None if mot is None else mot.num_fragmentations,
        mostly_tracked=None if mot is None else mot.mostly_tracked,
        mostly_lost=None if mot is None else mot.mostly_lost,
        motp_threshold=None if mot is None else settings.threshold,
        k_brier=None if counts is None else counts.brier,
        k_ece=None if counts is None else counts.ece,
        k_hit_rate=None if counts is None else counts.hit_rate,
        num_tracks=int(np.unique(output.tracks.track_ids).size),
        seconds=float(output.seconds),
        tgospa=metrics.trajectory.total,
        tgospa_switching=metrics.trajectory.switching,
        tgospa_gamma=settings.gamma,
        fragments_per_target=metrics.fragmentation.fragments_per_target,
        tgospa_id_switches=metrics.fragmentation.num_id_switches,
        pgospa=probabilistic.mean_total,
        pgospa_existence_mismatch=float(np.mean(probabilistic.existence_mismatch)),
    )
