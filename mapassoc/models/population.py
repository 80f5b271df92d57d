"""The target population of a window: undetected targets and the prior on their number.

The birth model (:class:`BirthModel`) is one generative model of the
targets (``docs/model.md``, section 3):

* ``initial_count`` targets (Poisson) are present at the first scan of the recording;
* before every scan, ``rate`` new targets (Poisson) appear, alive at that scan;
* a target alive at time ``t`` is alive at ``t + dt`` with probability ``Ps ** dt``;
* at each scan a target is detected with the scanning sensor's probability ``Pd``.

The targets never detected so far form a Poisson process whose expected number is
data independent (a Poisson multi-Bernoulli mixture filter's undetected intensity,
taken uniform over the scanning sensor's region).  Just before scan ``j`` it is

    u_j = Ps ** (t_j - t_{j-1}) * (1 - Pd_{j-1}) * u_{j-1} + rate,   u_0 = initial_count + rate

(``u_0`` at the recording's first scan; a later window starts from the state the
previous windows left, :class:`UndetectedTargets`).  A new track's first detection at
scan ``j`` is scored against this intensity: density ``u_j Pd_j / V`` against the
clutter density ``lambda_bar / V`` (``mapassoc.estimator.hypotheses``), so a target missed at
first is still started when it is detected.

For the posterior over the number of targets K present in a window
(:mod:`mapassoc.estimator.posterior`) the window needs three more numbers:

* ``new_target_mean``: the expected number of targets present in the window (alive at
  one of its scans) that were never detected before it, ``u_0 + (N - 1) rate``;
* ``undetected_mean``: the expected number of those never detected in the window
  either (``nu`` below); they are part of K but of no track;
* ``carried_alive``: for every track carried into the window, the probability that it
  is still alive at the window's first scan (``Ps ** dt``).

With ``q_j`` the probability that a target alive at scan ``j`` is not detected at any
scan ``j..N-1`` of the window,

    q_{N-1} = 1 - Pd_{N-1},   q_j = (1 - Pd_j) (1 - s_j + s_j q_{j+1}),
    s_j = Ps ** (t_{j+1} - t_j),

    nu = u_0 q_0 + rate * sum_{j >= 1} q_j.

Under the birth model the number of targets in the window is, given the carried tracks,
``sum_i Bernoulli(carried_alive_i) + Poisson(new_target_mean)``
(:meth:`WindowPopulation.log_count_prior`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.special import gammaln

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError
from mapassoc.validation import (
    check_nonnegative,
    check_number,
    check_probability,
    check_standard_deviation,
)

__all__ = [
    "BirthModel",
    "Timed",
    "MAX_KMAX",
    "UndetectedTargets",
    "WindowPopulation",
    "poisson_log_pmf",
    "recording_start",
    "window_population",
]


class Timed(Protocol):
    """Anything with a ``time`` (a :class:`~mapassoc.data.scans.Scan`, for one): what
    :func:`window_population` reads of a window's scans."""

    @property
    def time(self) -> float: ...


MAX_KMAX = 2**53
"""Largest ``max_tracks``: every K up to it is exact in double precision (the Poisson and
factorial terms take K as a float).  Beyond what the data and the prior can reach a
Kmax costs nothing (:func:`k_posterior`), so this bound only refuses nonsense."""


@dataclass(frozen=True)
class BirthModel:
    """Where targets come from and how long they live: one generative model.

    ``initial_count`` targets (Poisson) are present at the first scan of the recording;
    before every scan ``rate`` new targets (Poisson) appear; a target alive at time t
    is still alive at t + dt with probability ``survival_probability ** dt``; at each
    scan it is detected with the sensor's detection probability.  Positions are
    uniform over the scanning sensor's region.  The targets not detected so far are
    carried through the recording as an expected number (the undetected-target
    intensity, :mod:`mapassoc.models.population`), so a target's first detection, at the
    first scan or later, has density ``u * Pd / V`` with ``u`` that expected number.
    At its first detection a track starts (single-point initiation): the unmeasured
    state components start from zero mean with the standard deviations below (each
    motion model picks its own: ``MotionModel.birth_prior``, :mod:`mapassoc.models.motion`).

    Parameters
    ----------
    rate : float
        Expected number of new targets per scan, >= 0 (0: no target appears after the
        start, as in Perry's fixed population).
    initial_count : float
        Expected number of targets present at the first scan of the recording, >= 0.
    velocity_std : float
        Prior standard deviation of each velocity component at birth (Cartesian
        models), > 0.
    acceleration_std : float
        Prior standard deviation of each acceleration component at birth (constant
        acceleration and Singer models), > 0.
    speed_std : float
        Prior standard deviation of the speed at birth (coordinated turn), > 0.
    turn_rate_std : float
        Prior standard deviation of the turn rate at birth (coordinated turn), > 0.
    survival_probability : float
        Probability that a target survives one unit of time, in (0, 1].
    """

    rate: float = 0.1
    initial_count: float = 0.0
    velocity_std: float = 10.0
    acceleration_std: float = 1.0
    speed_std: float = 10.0
    turn_rate_std: float = 0.1
    survival_probability: float = 0.99

    def __post_init__(self) -> None:
        for name in ("rate", "initial_count"):
            value = check_nonnegative(f"birth {name}", getattr(self, name), key=name)
            if value > MAX_KMAX:
                raise InputError(
                    f"birth {name} = {value!r} is an expected number of targets beyond "
                    f"2**53 = {MAX_KMAX}, the largest count of targets (max_tracks) that "
                    "is exact in double precision; expected a smaller number",
                    key=name,
                )
        for name in ("velocity_std", "acceleration_std", "speed_std", "turn_rate_std"):
            check_standard_deviation(f"birth {name}", getattr(self, name), key=name)
        check_probability(
            "birth survival_probability",
            self.survival_probability,
            allow_zero=False,
            key="survival_probability",
        )


@dataclass(frozen=True)
class UndetectedTargets:
    """The targets never detected so far, just after a scan (or at the recording's start).

    Parameters
    ----------
    expected_count : float
        Expected number of targets alive at ``time`` and never detected, >= 0.
    time : float
        Time of the scan after which this holds (the first scan's time at the start).
    """

    expected_count: float
    time: float

    def __post_init__(self) -> None:
        check_nonnegative("UndetectedTargets.expected_count", self.expected_count)
        check_number("UndetectedTargets.time", self.time)


def recording_start(birth: BirthModel, time: float) -> UndetectedTargets:
    """The undetected targets when the recording starts: ``initial_count`` of them.

    Parameters
    ----------
    birth : BirthModel
    time : float
        Time of the recording's first scan.
    """
    return UndetectedTargets(expected_count=float(birth.initial_count), time=float(time))


@dataclass(frozen=True, eq=False)
class WindowPopulation:
    """What the birth model says about the targets of one window (module docstring).

    Attributes
    ----------
    first_detection_means : ndarray, shape (N,)
        ``u_j``: expected number of targets alive at scan ``j`` and never detected before
        it; a new track's first detection at scan ``j`` has density ``u_j Pd_j / V``.
    after_scan : tuple of UndetectedTargets, length N
        The undetected targets just after each scan (the state a window starting at the
        next scan continues from).
    new_target_mean : float
        Expected number of targets present in the window and never detected before it.
    undetected_mean : float
        Expected number of targets present in the window and never detected in it (nor
        before): ``nu``.
    carried_alive : ndarray, shape (C,)
        Probability that each carried track is alive at the window's first scan.
    """

    first_detection_means: FloatArray
    after_scan: tuple[UndetectedTargets, ...]
    new_target_mean: float
    undetected_mean: float
    carried_alive: FloatArray

    def log_count_prior(self, kmax: int) -> FloatArray:
        """log p(K) for K = 0..kmax under the birth model, given the carried tracks.

        ``K = sum_i B_i + P`` with independent ``B_i ~ Bernoulli(carried_alive_i)`` and
        ``P ~ Poisson(new_target_mean)``: the Bernoulli laws are multiplied out as a
        polynomial, then convolved with the Poisson law, in log space.  Not normalised
        over 0..kmax (the tail beyond kmax is cut).

        Returns
        -------
        ndarray, shape (kmax + 1,)
            ``-inf`` where p(K) = 0.
        """
        log_poisson = poisson_log_pmf(np.arange(kmax + 1), self.new_target_mean)
        with np.errstate(divide="ignore", invalid="ignore"):
            bern = np.full(min(kmax, self.carried_alive.size) + 1, -math.inf)
            bern[0] = 0.0
            for a in self.carried_alive:
                log_a = math.log(a) if a > 0 else -math.inf
                log_not = math.log1p(-a) if a < 1 else -math.inf
                shifted = np.r_[-math.inf, bern[:-1]] + log_a
                bern = np.logaddexp(bern + log_not, shifted)
        out = np.full(kmax + 1, -math.inf)
        for c, log_b in enumerate(bern):
            if log_b > -math.inf:
                out[c:] = np.logaddexp(out[c:], log_b + log_poisson[: kmax + 1 - c])
        return out


def poisson_log_pmf(counts: NDArray[np.int64], mean: float) -> FloatArray:
    """``log Po(counts; mean)`` elementwise: ``-inf`` for a negative count, and for a
    positive one when ``mean = 0``.

    Parameters
    ----------
    counts : ndarray of int
    mean : float
        >= 0.
    """
    counts = np.asarray(counts)
    out = np.full(counts.shape, -math.inf)
    ok = counts >= 0
    if mean > 0:
        k = counts[ok].astype(float)
        out[ok] = k * math.log(mean) - mean - gammaln(k + 1.0)
    else:
        out[ok & (counts == 0)] = 0.0
    return out


def window_population(
    scans: Sequence[Timed],
    detection_probabilities: Sequence[float],
    birth: BirthModel,
    start: UndetectedTargets,
    carried_times: Sequence[float] = (),
) -> WindowPopulation:
    """Undetected-target intensity and target counts of a window (module docstring).

    Parameters
    ----------
    scans : sequence of Scan (or anything with a ``time``)
        The window's scans in time order (at least one).
    detection_probabilities : sequence of float
        Pd of each scan's sensor, in (0, 1].
    birth : BirthModel
    start : UndetectedTargets
        The undetected targets just after the scan before the window
        (:func:`recording_start` for a window that starts the recording).
    carried_times : sequence of float
        Time of each carried track's last committed scan (<= the first scan's time).

    Returns
    -------
    WindowPopulation

    Raises
    ------
    InputError
        No scans, a length mismatch, or a time before ``start.time``.
    """
    n = len(scans)
    if n == 0:
        raise InputError("a window needs at least one scan")
    if len(detection_probabilities) != n:
        raise InputError(
            f"detection_probabilities must have one entry per scan ({n}), got "
            f"{len(detection_probabilities)}"
        )
    times = np.array([s.time for s in scans], dtype=float)
    pd = np.asarray(detection_probabilities, dtype=float)
    if times[0] < start.time:
        raise InputError(
            f"the window's first scan at time {times[0]} is before the undetected-target "
            f"state's time {start.time}"
        )
    log_ps = math.log(birth.survival_probability)
    rate = float(birth.rate)
    u = np.empty(n)
    after: list[UndetectedTargets] = []
    remaining, previous = start.expected_count, start.time
    for j in range(n):
        u[j] = remaining * math.exp((times[j] - previous) * log_ps) + rate
        remaining, previous = u[j] * (1.0 - pd[j]), float(times[j])
        after.append(UndetectedTargets(expected_count=float(remaining), time=previous))
    # q_j: a target alive at scan j is detected at none of scans j..N-1.
    q = np.empty(n)
    q[-1] = 1.0 - pd[-1]
    for j in range(n - 2, -1, -1):
        s = math.exp((times[j + 1] - times[j]) * log_ps)
        q[j] = (1.0 - pd[j]) * (1.0 - s + s * q[j + 1])
    carried = np.asarray(carried_times, dtype=float)
    if np.any(carried > times[0]):
        raise InputError(
            f"carried track times {carried[carried > times[0]].tolist()} are after the "
            f"window's first scan at {times[0]}"
        )
    return WindowPopulation(
        first_detection_means=u,
        after_scan=tuple(after),
        new_target_mean=float(u[0] + rate * (n - 1)),
        undetected_mean=float(u[0] * q[0] + rate * q[1:].sum()),
        carried_alive=np.exp((times[0] - carried) * log_ps),
    )
