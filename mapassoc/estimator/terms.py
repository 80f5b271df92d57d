"""The model's score terms, written once: the equations, per sensor, and per recording.

Every score of the estimator is a sum of the terms below (derivation: ``docs/model.md``,
sections 2-3; the sum over a track set plus a constant is ``log p(track set, K | Z)`` of
Perry's MAP formulation, eqs. 8-14).  A track is scored against "all its detections are
false alarms and the track does not exist":

====================================  ===============================================
event at a scan of sensor s           term (function)
====================================  ===============================================
first detection at scan j             ``log u_j + log Pd_s - log lambda_bar_s``
                                      (:func:`birth_term`)
survival over dt                      ``dt log Ps`` (:func:`survival_term`)
continued by a detection              ``log Pd_s + log N(nu; 0, S) - log lambda_s``
                                      (:func:`detection_term`)
missed                                ``log(1 - Pd_s P_G)`` (:func:`miss_term`)
ended over dt                         ``log(1 - Ps^dt)`` (:func:`end_term`)
after the last detection              the best ending (:func:`best_endings`), or all
                                      endings summed (:func:`ending_masses`)
====================================  ===============================================

``u_j`` is the undetected-target mean of :mod:`mapassoc.models.population`, ``lambda_bar_s``
the sensor's false alarms per scan and ``lambda_s = lambda_bar_s / V_s`` their density,
``P_G`` the gate probability (the gate itself: :func:`~mapassoc.filtering.kalman.gate_threshold`).

The hypothesis trees (:mod:`mapassoc.estimator.hypotheses`), the recording objective J
(:mod:`mapassoc.estimator.objective`, and through its :class:`ScanTerms` the compiled
kernels and the refinement), and the trackers that score with the same model (network
flow, MHT, GNN, JPDA) all take their numbers from here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.data.config import Config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.filtering.kalman import gate_threshold
from mapassoc.models.population import UndetectedTargets, recording_start, window_population
from mapassoc.models.sensor import Sensor

__all__ = [
    "survival_term",
    "end_term",
    "miss_term",
    "detection_term",
    "birth_term",
    "earlier_ending",
    "best_endings",
    "ending_masses",
    "SensorTerms",
    "ScanTerms",
]


# -- the equations -------------------------------------------------------------------------
def survival_term(dt: float | FloatArray, log_survival: float) -> float | FloatArray:
    """``dt log Ps``: log of a target surviving a time step.

    A target alive at ``t`` is alive at ``t + dt`` with probability ``Ps^dt``
    (:class:`~mapassoc.models.population.BirthModel`).

    Parameters
    ----------
    dt : float or ndarray
        Time steps, >= 0.
    log_survival : float
        ``log Ps`` per unit time (<= 0).

    Returns
    -------
    float or ndarray
        Same shape as ``dt``.
    """
    return dt * log_survival


def end_term(dt: float | FloatArray, log_survival: float) -> FloatArray:
    """``log(1 - Ps^dt)``: log of a target alive at ``t`` being dead at ``t + dt``.

    Parameters
    ----------
    dt : float or ndarray
        Time steps, >= 0.
    log_survival : float
        ``log Ps`` per unit time (<= 0).

    Returns
    -------
    ndarray
        Same shape as ``dt``; ``-inf`` where ending is impossible (``dt = 0`` or
        ``Ps = 1``).
    """
    with np.errstate(divide="ignore"):
        return np.log(-np.expm1(np.multiply(dt, log_survival)))


def miss_term(detection_probability: float, gate_probability: float) -> float:
    """``log(1 - Pd P_G)``: log of a target's scan without a detection in its gate.

    Blackman & Popoli (1999), eq. (6.13); Perry's MAP formulation, eq. (10).

    Parameters
    ----------
    detection_probability : float
        ``Pd`` of the scan's sensor.
    gate_probability : float
        ``P_G``.

    Returns
    -------
    float
        ``-inf`` when ``Pd P_G = 1`` (a miss is impossible).
    """
    p = detection_probability * gate_probability
    return math.log1p(-p) if p < 1.0 else -math.inf


def detection_term(
    log_pd: float | FloatArray, log_likelihood: FloatArray, log_clutter: float | FloatArray
) -> FloatArray:
    """``log Pd + log N(nu; 0, S) - log lambda``: a track continued by a detection.

    The detection's density under the track (its Kalman innovation ``nu`` with covariance
    ``S``; Afzal's survey, eq. 3) against the false-alarm density ``lambda``, with the
    detection probability: the n-object posterior weight of Afzal's survey, eq. 11, and
    Blackman & Popoli (1999), eq. (6.10).  Outside the gate the term is ``-inf``; the
    caller applies the gate.

    Parameters
    ----------
    log_pd : float or ndarray
        ``log Pd`` of the scan's sensor.
    log_likelihood : ndarray
        ``log N(nu; 0, S)`` per (track, detection).
    log_clutter : float or ndarray
        ``log lambda`` (false alarms per unit measurement volume).

    Returns
    -------
    ndarray
        Broadcast shape of the arguments.
    """
    return np.asarray(log_pd + log_likelihood - log_clutter)


def birth_term(undetected_mean: float, log_pd: float, log_false_alarms: float) -> float:
    """``log u + log Pd - log lambda_bar``: the first detection of a track.

    The density ``u Pd / V`` of a target not detected before (``u`` the expected number
    of such targets at the scan, :mod:`mapassoc.models.population`) against the clutter
    density ``lambda_bar / V``: Blackman & Popoli (1999), eq. (6.8), with the new-target
    density ``beta_NT = u Pd / V``; ``docs/model.md`` section 2.

    Parameters
    ----------
    undetected_mean : float
        ``u`` >= 0.
    log_pd : float
        ``log Pd`` of the scan's sensor.
    log_false_alarms : float
        ``log lambda_bar``, the sensor's false alarms per scan.

    Returns
    -------
    float
        ``-inf`` when ``u = 0`` (no undetected target can be there).
    """
    if undetected_mean == 0.0:
        return -math.inf
    return math.log(undetected_mean) + log_pd - log_false_alarms


def earlier_ending(end: float, survival: float, miss: float, later: float) -> float:
    """The best ending of a track alive at a scan, given the best one at the next scan.

    ``max(end, survival + miss + later)``: the track ends in the gap to the next scan
    (``end``, :func:`end_term`), or survives to it (``survival``), is missed there
    (``miss``) and ends as best it can after it (``later``).
    """
    return max(end, survival + miss + later)


def best_endings(survival: FloatArray, miss: FloatArray, end: FloatArray) -> FloatArray:
    """``tail(m)``: the best of a track's endings after its last detection at scan ``m``.

    The backward recursion over a run of ``N`` scans (the recording, or a window whose
    later scans are another window's business)

        tail(N - 1) = 0,
        tail(m) = max(end[m], survival[m + 1] + miss[m + 1] + tail(m + 1))

    (:func:`earlier_ending`): the track ends in the gap after scan ``m``, or is missed at
    scan ``m + 1`` and ends later, or lives to the last scan.  The death time is thus
    maximised over, as the windows' "ended" and "missed to the end" hypotheses are.

    Parameters
    ----------
    survival : ndarray, shape (N,)
        :func:`survival_term` of the step into each scan (entry 0 unused).
    miss : ndarray, shape (N,)
        :func:`miss_term` of each scan (entry 0 unused).
    end : ndarray, shape (N,)
        :func:`end_term` of the gap after each scan (the last entry unused).

    Returns
    -------
    ndarray, shape (N,)
        ``-inf`` where every ending is impossible.
    """
    n = len(end)
    tails = np.zeros(n)
    for m in range(n - 2, -1, -1):
        tails[m] = earlier_ending(
            float(end[m]), float(survival[m + 1]), float(miss[m + 1]), float(tails[m + 1])
        )
    return tails


def ending_masses(survival: FloatArray, miss: FloatArray, end: FloatArray) -> FloatArray:
    """The log of the *summed* probability of a track's endings after scan ``m``.

    :func:`best_endings` with log-sum-exp for max: what a track's endings weigh in a sum
    over track sets (the confidence pass's marginals) rather than in the best set.

        mass(N - 1) = 0,
        mass(m) = logaddexp(end[m], survival[m + 1] + miss[m + 1] + mass(m + 1)).

    Parameters and returns as :func:`best_endings`.
    """
    n = len(end)
    masses = np.zeros(n)
    for m in range(n - 2, -1, -1):
        missed = survival[m + 1] + miss[m + 1] + masses[m + 1]
        masses[m] = np.logaddexp(end[m], missed)
    return masses


# -- per sensor ---------------------------------------------------------------------------
@dataclass(frozen=True)
class SensorTerms:
    """A sensor's constant terms under a gate probability.

    Attributes
    ----------
    log_pd : float
        ``log Pd``.
    log_clutter : float
        ``log lambda``, the log false-alarm density (per unit measurement volume).
    log_false_alarms : float
        ``log lambda_bar``, the log false alarms per scan.
    miss : float
        :func:`miss_term`.
    threshold : float
        The chi-square gate of probability ``P_G`` in the sensor's measurement dimension
        (:func:`~mapassoc.filtering.kalman.gate_threshold`).
    """

    log_pd: float
    log_clutter: float
    log_false_alarms: float
    miss: float
    threshold: float

    @classmethod
    def of(cls, sensor: Sensor, gate_probability: float) -> SensorTerms:
        """The terms of ``sensor`` (which needs ``false_alarms_per_scan > 0``)."""
        if not sensor.false_alarms_per_scan > 0:
            raise InputError(
                f"sensor '{sensor.name}' has false_alarms_per_scan = "
                f"{sensor.false_alarms_per_scan}; the estimator scores detections against "
                "the false-alarm density and needs a positive rate (use a small value such "
                "as 1e-6 for nearly clutter-free data)"
            )
        return cls(
            log_pd=math.log(sensor.detection_probability),
            log_clutter=sensor.log_clutter_density,
            log_false_alarms=math.log(sensor.false_alarms_per_scan),
            miss=miss_term(sensor.detection_probability, gate_probability),
            threshold=gate_threshold(gate_probability, sensor.measurement.measurement_dim),
        )

    @staticmethod
    def of_all(sensors: Mapping[str, Sensor], gate_probability: float) -> dict[str, SensorTerms]:
        """:meth:`of` every sensor, by name."""
        return {name: SensorTerms.of(s, gate_probability) for name, s in sensors.items()}


# -- per recording ------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ScanTerms:
    """The terms of every scan of a recording, built once (:meth:`of_recording`).

    ``M`` is the number of scans; entry ``m`` is scan ``m``'s (its sensor's terms, the
    step from scan ``m - 1`` to it, the gap after it).

    Attributes
    ----------
    times : ndarray, shape (M,)
    log_survival : float
        ``log Ps`` per unit time.
    log_pd : ndarray, shape (M,)
        ``log Pd`` of each scan's sensor.
    log_clutter : ndarray, shape (M,)
        ``log lambda`` of each scan's sensor.
    thresholds : ndarray, shape (M,)
        The gate of each scan's sensor.
    miss : ndarray, shape (M,)
        :func:`miss_term`.
    survival : ndarray, shape (M,)
        :func:`survival_term` of the step from scan ``m - 1`` to scan ``m`` (0 for
        ``m = 0``).
    end : ndarray, shape (M,)
        :func:`end_term` of ending in the gap from scan ``m`` to scan ``m + 1`` (``-inf``
        after the last scan).
    birth : ndarray, shape (M,)
        :func:`birth_term` of a first detection at scan ``m``, ``u_m`` counted from the
        recording's first scan (``-inf`` where ``u_m = 0``).
    tails : ndarray, shape (M,)
        :func:`best_endings` over the recording.
    tail_masses : ndarray, shape (M,)
        :func:`ending_masses` over the recording.
    undetected_after : tuple of UndetectedTargets, length M
        The targets never detected, just after each scan (where a window starting at the
        next scan continues from).
    """

    times: FloatArray
    log_survival: float
    log_pd: FloatArray
    log_clutter: FloatArray
    thresholds: FloatArray
    miss: FloatArray
    survival: FloatArray
    end: FloatArray
    birth: FloatArray
    tails: FloatArray
    tail_masses: FloatArray
    undetected_after: tuple[UndetectedTargets, ...]

    @classmethod
    def of_recording(cls, config: Config, scans: Sequence[Scan]) -> ScanTerms:
        """The table of ``scans`` (sorted by time, at least one) under ``config``'s model
        and its ``estimator.gate_probability``."""
        if not scans:
            raise InputError("a table of scan terms needs at least one scan")
        birth = config.birth
        per_sensor = SensorTerms.of_all(config.sensors, config.estimator.pruning.gate_probability)
        rows = [per_sensor[s.sensor] for s in scans]
        times = np.array([s.time for s in scans], dtype=float)
        pd = [config.sensors[s.sensor].detection_probability for s in scans]
        population = window_population(scans, pd, birth, recording_start(birth, scans[0].time))
        log_survival = math.log(birth.survival_probability)
        gaps = np.diff(times)
        survival = np.concatenate([[0.0], survival_term(gaps, log_survival)])
        end = np.concatenate([end_term(gaps, log_survival), [-math.inf]])
        miss = np.array([r.miss for r in rows], dtype=float)
        return cls(
            times=times,
            log_survival=log_survival,
            log_pd=np.array([r.log_pd for r in rows], dtype=float),
            log_clutter=np.array([r.log_clutter for r in rows], dtype=float),
            thresholds=np.array([r.threshold for r in rows], dtype=float),
            miss=miss,
            survival=survival,
            end=end,
            birth=np.array(
                [
                    birth_term(float(u), r.log_pd, r.log_false_alarms)
                    for u, r in zip(population.first_detection_means, rows, strict=True)
                ],
                dtype=float,
            ),
            tails=best_endings(survival, miss, end),
            tail_masses=ending_masses(survival, miss, end),
            undetected_after=tuple(population.after_scan),
        )

    def __len__(self) -> int:
        return int(self.times.shape[0])

    def misses_between(self, first: int, last: int) -> float:
        """Sum of ``dt log Ps + log(1 - Pd P_G)`` over scans ``first..last`` (0 if empty)."""
        if last < first:
            return 0.0
        steps = slice(first, last + 1)
        return float(np.sum(self.survival[steps]) + np.sum(self.miss[steps]))

    def window_tails(self, start: int, stop: int) -> FloatArray:
        """:func:`best_endings` of scans ``start..stop-1`` alone (0 at scan ``stop - 1``:
        a sliding window's scans after it are another window's business)."""
        return best_endings(
            self.survival[start:stop], self.miss[start:stop], self.end[start:stop]
        )

    def endings_before(self, value: float, first: int, stop: int) -> tuple[float, float]:
        """A track valued ``value`` alive at scan ``first`` that ends before scan ``stop``.

        It is missed at every scan after ``first`` up to one ``g < stop`` and ends in the
        gap after ``g``.  Returns the best of those values and their log-sum-exp
        (``-inf`` for both when ``first >= stop``).
        """
        best = mass = -math.inf
        running = value
        for g in range(first, stop):
            best = max(best, running + float(self.end[g]))
            mass = float(np.logaddexp(mass, running + float(self.end[g])))
            if g + 1 < stop:
                running += float(self.survival[g + 1] + self.miss[g + 1])
        return best, mass
