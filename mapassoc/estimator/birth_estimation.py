"""The birth model from the recording: the ``"auto"`` ``[birth]`` keys of the parameter EM
(:mod:`mapassoc.estimator.parameters`).

The EM of the sensor parameters runs the window estimator (the E step of the
associations); the birth model joins it there, as the noise levels do
(:mod:`mapassoc.estimator.noise_levels`).  Each pass's committed tracks are read as the
targets of the model of :class:`~mapassoc.models.population.BirthModel`: ``initial_count``
targets (Poisson) at the recording's first scan, ``rate`` new ones (Poisson) before
every scan, survival ``s ** dt``, detection with the scan's ``Pd``.

Counts (``initial_count``, ``rate``).  A track first detected at scan ``k`` is a target
that was either present at the start and missed until ``k``, or born before some scan
``j <= k`` and missed from ``j`` to ``k - 1``.  The undetected-target intensity of
:mod:`mapassoc.models.population` is the sum of those origins' expected numbers,

    u_k = u_0 s^(t_k - t_0) prod_{i<k} (1 - Pd_i)
          + rate sum_{j<=k} s^(t_k - t_j) prod_{j<=i<k} (1 - Pd_i),

and each track's responsibilities over its origins are the terms over ``u_k``.  The
targets never detected are, by the thinning (colouring) theorem of Poisson processes
(Kingman, "Poisson Processes", section 5.1), Poisson and independent of the detected ones,
with means ``u_0 q_0`` (initial) and ``rate q_j`` (born before scan ``j``), ``q_j`` the
probability that a target alive at ``j`` is detected at none of the scans ``j..N-1``
(the recursion of :mod:`mapassoc.models.population`).  The M step of the complete-data
Poisson likelihood is then ``initial_count`` = the expected initial targets (their
responsibilities plus ``u_0 q_0``) and ``rate`` = the expected births over the scans
they could come before.  Responsibilities depend on ``(u_0, rate)``, so the two steps
alternate to their fixed point on the pass's tracks (:data:`MAX_BIRTH_UPDATES`,
:data:`BIRTH_TOLERANCE`; arithmetic on a few arrays per update).  The model's ``u_0`` at
the first scan is ``initial_count + rate`` (:func:`~mapassoc.models.population.window_population`
adds a birth before the first scan too), so births count before every scan of the
recording, the first included.

Survival.  The survival is estimated from the tracks' lifetimes: exposure from each
track's first detection (for exponential lifetimes the time before it says nothing more:
the lifetime left is memoryless, so left truncation at the first detection is exact) to
its end, and its ends.  A track whose last detection is at scan ``e`` may still be alive
but missed after it; the posterior over its last scan alive ``c >= e`` is proportional
to ``prod_{e<=i<c} s_i (1 - Pd_{i+1}) * (1 - s_c)`` (dead before ``c + 1``) and, for
``c = N - 1`` (alive at the block's end, censored), to the product alone.  The expected
ends and exposure (each death counted half-way through its interval, which makes the
exponential estimate agree with the discrete-time maximum likelihood ``s^T = n / (n +
d)`` to second order in ``d / n``) give ``s = exp(-ends / exposure)``, the maximum
likelihood survival of exponential lifetimes; it depends on ``s`` through the posterior,
so it too is iterated to its fixed point.  Approximations: the never-detected targets
are left out of the survival sums, and a target's detections are taken to be independent
of where it is (every target inside every sensor's region).

``velocity_std``.  The root mean square of the smoothed velocity components at each
track's first detection, with their smoothed variance (``E[v^2] = m^2 + P``), over the
tracks with at least :data:`~mapassoc.estimator.noise_levels.MIN_TRACK_DETECTIONS`
detections: Shumway and Stoffer's M step of the initial state's covariance ("An approach
to time series smoothing and forecasting using the EM algorithm", J. Time Series Analysis
1982) with the prior mean held at zero, as :class:`~mapassoc.models.population.BirthModel`
has it.  One update per pass: with five or more detections the smoothed velocity is the
data's, and the update barely depends on the prior it was smoothed under.

Sampled blocks.  Each block of a sampled recording is a recording of its own: only the
block that starts at the recording's first scan says anything about ``initial_count``
(without one it is kept, noted); every other block's population at its first scan is a
nuisance parameter, estimated beside the others the same way and then dropped, and its
births before its first scan are part of it (they cannot be told apart), so such a block
contributes births and scans from its second scan on.

Decisions:

* Only tracks with at least :data:`MIN_BIRTH_DETECTIONS` detections are counted: a
  single detection is as much a false alarm as a target's, and counting the estimator's
  single-detection tracks as targets would confirm whatever birth intensity made them.
* Existence weights (``soft_counts``, the default).  A track of the MAP set may be
  clutter joined by chance or a piece of a target's track; the confidence pass gives
  each the probability that its first detection starts a target
  (:attr:`~mapassoc.estimator.confidence.TrackConfidence.existence`), and each track's
  responsibilities, end and exposure count that much: the expected counts of the
  complete-data Poisson likelihood under the track set's uncertainty (Dempster, Laird
  and Rubin, "Maximum likelihood from incomplete data via the EM algorithm", 1977).
  ``velocity_std`` stays unweighted (its tracks have five detections or more).
* No event is never observed: where the tracks give no births or no ends, half of one is
  counted (:data:`UNSEEN_EVENTS`; the posterior mean of a Poisson count of 0 under
  Jeffreys' prior), since a rate of 0 lets no track start after the first scan and a
  survival of 1 lets none end.
* Starts (without ``<key>_start``).  The configured values are placeholders, and a start
  from the first pass's own tracks would be circular, so the starts are fixed rules.
  ``rate`` starts at :data:`RATE_START` births per scan (``BirthModel``'s default), at
  most :data:`RATE_START_SHARE` of the mean detections per scan and at least one birth
  over the sampled scans; ``initial_count`` at one target.  Below the clutter, because
  a birth intensity above it (``u Pd > lambda_bar``; the first pass assumes the mean
  detections per scan are all clutter) makes every unexplained detection a new track
  and the count of those tracks would confirm it, while a true target's detections
  outweigh the one cost ``log(u Pd / lambda_bar)`` of its start.  Not far below it: a
  start of one birth over the sample stayed there on ``dense_pd08`` (0.026 births per
  scan for 0.175, its late targets never started, GOSPA 15.2), where 0.1 rose to 0.206
  (GOSPA 2.77); the changelog has the runs.
  ``survival_probability`` starts where the mean lifetime is the sample's duration
  (``s = exp(-1 / duration)``, free of the time unit): from above, because a short
  assumed life ends tracks at their first missed detection and breaks them into pieces
  whose starts would inflate the rate.  ``velocity_std`` starts at the speed of the
  shortest nearest-neighbour displacements between consecutive scans of a sensor,
  ``sqrt(quantile(r^2 / dt^2, VELOCITY_START_QUANTILE) / d)`` with ``d`` the position
  components: a target's detection is usually nearest its own previous one (as close as
  its speed and twice the measurement noise allow) and clutter's nearest neighbours are
  further in all but the densest clutter, so the low quantile is the targets' speed
  with the measurement noise added, from above.  The median would be the clutter's
  spacing: a prior that wide makes the first pass's gating combinatorial (see the
  changelog for the measurement), and one too narrow breaks tracks.
* Convergence: every estimate moved by at most ``rate_tolerance`` (relative) from one
  pass to the next, with the false-alarm rates and noise levels.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mapassoc.array_types import FloatArray
from mapassoc.data.config import AUTO_BIRTH_KEYS, Config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.noise_levels import MIN_TRACK_DETECTIONS
from mapassoc.filtering.smoothing import smooth_track

__all__ = [
    "BIRTH_TOLERANCE",
    "MAX_BIRTH_UPDATES",
    "MIN_BIRTH_DETECTIONS",
    "UNSEEN_EVENTS",
    "RATE_START",
    "RATE_START_SHARE",
    "VELOCITY_START_QUANTILE",
    "BirthAsked",
    "BirthLevels",
    "BlockTracks",
    "block_tracks",
    "count_update",
    "survival_update",
    "velocity_update",
    "initial_birth",
    "birth_m_step",
    "with_birth_levels",
]

MAX_BIRTH_UPDATES = 2000
"""Most alternations of responsibilities and counts (or of the survival's posterior and
estimate) in one M step."""
BIRTH_TOLERANCE = 1e-9
"""Relative change of every estimate below which an inner iteration stops."""
MIN_BIRTH_DETECTIONS = 2
"""Fewest detections of a track counted as a target (module docstring)."""
UNSEEN_EVENTS = 0.5
"""Births or ends counted where the tracks show none (module docstring)."""
VELOCITY_START_QUANTILE = 0.1
"""The quantile of the squared displacement speeds ``velocity_std`` starts from (module
docstring)."""
_TINY = 1e-300
"""Smallest ``1 - Pd`` taken (``Pd = 1`` would make the logarithms infinite)."""


@dataclass(frozen=True)
class BirthAsked:
    """The ``[birth]`` keys a configuration leaves to the recording.

    Attributes
    ----------
    starts : dict of str to float or None
        Each key asked (of :data:`~mapassoc.data.config.AUTO_BIRTH_KEYS`) with its
        configured start (None: the start of the module docstring).
    """

    starts: dict[str, float | None]

    @classmethod
    def from_config(cls, config: Config) -> BirthAsked:
        """What ``config.auto`` asks, checked.

        Raises
        ------
        InputError
            ``velocity_std`` asked of a motion model without velocity components, or a
            key that cannot be estimated (naming the key).
        """
        starts = config.auto.birth_starts()
        for key in starts:
            if key not in AUTO_BIRTH_KEYS:
                raise InputError(f"birth.{key} cannot be \"auto\" (only {AUTO_BIRTH_KEYS})",
                                 key=f"birth.{key}")  # fmt: skip
        if "velocity_std" in starts and not getattr(config.motion, "velocity_indices", ()):
            raise InputError(
                f'birth.velocity_std = "auto" needs a motion model with velocity components, '
                f"got {config.motion!r}", key="birth.velocity_std",
            )  # fmt: skip
        return cls(starts)

    @property
    def any(self) -> bool:
        return bool(self.starts)


@dataclass(frozen=True)
class BirthLevels:
    """Values of the ``[birth]`` keys asked for.

    Attributes
    ----------
    values : dict of str to float
        Per key asked, in the order of :data:`~mapassoc.data.config.AUTO_BIRTH_KEYS`.
    """

    values: dict[str, float]

    def vector(self) -> FloatArray:
        """The values in one vector, shape (len(values),)."""
        return np.array(list(self.values.values()), dtype=float)

    def to_json(self) -> dict[str, object]:
        return dict(self.values)


def with_birth_levels(config: Config, levels: BirthLevels | None) -> Config:
    """``config`` with the birth model's estimated keys set (and no longer "auto")."""
    if levels is None:
        return config
    left = tuple(item for item in config.auto.birth if item[0] not in levels.values)
    return dataclasses.replace(
        config, birth=dataclasses.replace(config.birth, **levels.values),
        auto=dataclasses.replace(config.auto, birth=left),
    )  # fmt: skip


@dataclass(frozen=True)
class BlockTracks:
    """What one block's tracks say about the population, and the block's scans.

    Attributes
    ----------
    times : ndarray, shape (N,)
        The block's scan times.
    missed : ndarray, shape (N,)
        ``1 - Pd`` of each scan's sensor (at least ``1e-300``).
    firsts, lasts : ndarray of int, shape (M,)
        Each counted track's first and last detected scan (block scan indices).
    starts_recording : bool
        Whether the block starts at the recording's first scan (its population at the
        first scan is ``initial_count``; else a nuisance parameter).
    weights : ndarray, shape (M,), optional
        Each counted track's probability of being a target (module docstring, existence
        weights); None: 1 each.
    """

    times: FloatArray
    missed: FloatArray
    firsts: np.ndarray
    lasts: np.ndarray
    starts_recording: bool
    weights: FloatArray | None = None

    @property
    def track_weights(self) -> FloatArray:
        """:attr:`weights`, ones where None."""
        return np.ones(self.firsts.size) if self.weights is None else self.weights

    @property
    def birth_scans(self) -> int:
        """Scans a birth may come before: all, or all but the first (a nuisance start)."""
        return self.times.size - (0 if self.starts_recording else 1)


def block_tracks(
    config: Config,
    scans: Sequence[Scan],
    tracks: Mapping[int, Mapping[int, int]],
    starts_recording: bool,
    existence: Mapping[int, float] | None = None,
) -> BlockTracks:
    """One block's :class:`BlockTracks` from its tracks (track id -> scan index ->
    detection index), those with at least :data:`MIN_BIRTH_DETECTIONS` detections;
    ``Pd`` from ``config``'s sensors; with ``existence`` (track id -> probability of
    being a target), each track weighted by it (a track not given, or nan: 1)."""
    ids = [i for i, t in tracks.items() if len(t) >= MIN_BIRTH_DETECTIONS]
    counted = [sorted(tracks[i]) for i in ids]
    pd = np.array([config.sensors[scan.sensor].detection_probability for scan in scans], float)
    weights = None
    if existence is not None:
        given = [existence.get(i, 1.0) for i in ids]
        weights = np.clip(np.nan_to_num(np.array(given, float), nan=1.0), 0.0, 1.0)
    return BlockTracks(
        times=np.array([scan.time for scan in scans], dtype=float),
        missed=np.maximum(1.0 - pd, _TINY),
        firsts=np.array([t[0] for t in counted], dtype=np.int64),
        lasts=np.array([t[-1] for t in counted], dtype=np.int64),
        starts_recording=starts_recording,
        weights=weights,
    )


def _never_detected(block: BlockTracks, survival: float) -> FloatArray:
    """``q_j``, shape (N,): a target alive at scan ``j`` is detected at none of ``j..N-1``."""
    steps = np.exp(np.diff(block.times) * math.log(survival))
    q = np.empty(block.times.size)
    q[-1] = block.missed[-1]
    for j in range(block.times.size - 2, -1, -1):
        q[j] = block.missed[j] * (1.0 - steps[j] + steps[j] * q[j + 1])
    return q


def _initial_share(block: BlockTracks, survival: float, start: float, rate: float) -> FloatArray:
    """Each counted track's responsibility of the initial population, shape (M,): the
    initial term of ``u_k`` over ``u_k`` (module docstring), in log space."""
    n = block.times.size
    log_missed = np.log(block.missed)
    # C_k = (t_k - t_0) log s + sum_{i<k} log(1 - Pd_i); an origin at j weighs exp(C_k - C_j).
    c = (block.times - block.times[0]) * math.log(survival) + np.r_[0.0, np.cumsum(log_missed[:-1])]
    first_birth = 0 if block.starts_recording else 1
    births = np.full(n, -math.inf)
    if first_birth < n and rate > 0:
        births[first_birth:] = math.log(rate) + np.logaddexp.accumulate(-c[first_birth:])
    with np.errstate(divide="ignore"):
        initial = math.log(start) if start > 0 else -math.inf
    k = block.firsts
    return np.exp(initial - np.logaddexp(initial, births[k]))


def count_update(
    blocks: Sequence[BlockTracks], survival: float, initial_count: float, rate: float,
    *, fit_initial: bool = True, fit_rate: bool = True,
) -> tuple[float, float, bool]:
    """The counts' EM fixed point on the blocks' tracks (module docstring).

    Parameters
    ----------
    blocks : sequence of BlockTracks
    survival : float
        ``s`` per unit time, in (0, 1].
    initial_count, rate : float
        The start (and the value kept of one not fitted).
    fit_initial, fit_rate : bool
        Which of the two to estimate.

    Returns
    -------
    initial_count, rate : float
    estimable : bool
        Whether some block starts the recording (else ``initial_count`` is kept).
    """  # fmt: skip
    q = [_never_detected(block, survival) for block in blocks]
    nuisance = [initial_count + 1.0 if not b.starts_recording else initial_count for b in blocks]
    scans = sum(block.birth_scans for block in blocks)
    estimable = any(block.starts_recording for block in blocks)
    for _ in range(MAX_BIRTH_UPDATES):
        births, new_starts = 0.0, []
        for block, q_b, start in zip(blocks, q, nuisance, strict=True):
            share = _initial_share(block, survival, start, rate)
            weight = block.track_weights
            new_starts.append(float(weight @ share) + start * q_b[0])
            unseen = float(q_b[block.times.size - block.birth_scans :].sum())
            births += float(weight @ (1.0 - share)) + rate * unseen
        new_rate = max(births, UNSEEN_EVENTS) / max(scans, 1) if fit_rate else rate
        new_starts = [
            value if (fit_initial or not block.starts_recording) else initial_count
            for block, value in zip(blocks, new_starts, strict=True)
        ]
        moved = _moved([rate, *nuisance], [new_rate, *new_starts])
        rate, nuisance = new_rate, new_starts
        if moved <= BIRTH_TOLERANCE:
            break
    first = [s for block, s in zip(blocks, nuisance, strict=True) if block.starts_recording]
    return float(first[0] if first and fit_initial else initial_count), float(rate), estimable


def _moved(old: Sequence[float], new: Sequence[float]) -> float:
    """The largest relative change between two vectors of non-negative values."""
    a, b = np.asarray(old, dtype=float), np.asarray(new, dtype=float)
    scale = np.maximum(np.maximum(a, b), 1e-300)
    return float(np.max(np.abs(a - b) / scale)) if a.size else 0.0


def _survival_sums(block: BlockTracks, survival: float) -> tuple[float, float]:
    """Expected ends and exposure of a block's counted tracks (module docstring).

    Returns
    -------
    ends : float
    exposure : float
        In the scans' time unit.
    """
    n, times = block.times.size, block.times
    if block.firsts.size == 0:
        return 0.0, 0.0
    dt = np.diff(times)
    log_step = dt * math.log(survival)
    # H_c = sum_{i<c} (log s_i + log(1 - Pd_{i+1})); alive at c, missed at e+1..c: H_c - H_e.
    h = np.r_[0.0, np.cumsum(log_step + np.log(block.missed[1:]))]
    last = block.lasts[:, None]
    after = np.arange(n)[None, :]
    with np.errstate(over="ignore", invalid="ignore"):
        log_w = np.where(after >= last, h[None, :] - h[block.lasts][:, None], -math.inf)
    die = np.r_[-np.expm1(log_step), 1.0]  # dead before c + 1; the last: censored
    weights = np.exp(log_w) * die[None, :]
    weights /= weights.sum(axis=1, keepdims=True)
    weights *= block.track_weights[:, None]  # each track's end counts as it exists
    half = np.r_[dt / 2.0, 0.0]
    extra = (times[None, :] - times[block.lasts][:, None] + half[None, :]) * weights
    ends = float(weights[:, :-1].sum())
    span = block.track_weights @ (times[block.lasts] - times[block.firsts])
    exposure = float(span + extra.sum())
    return ends, exposure


def survival_update(blocks: Sequence[BlockTracks], survival: float) -> float | None:
    """The survival's fixed point ``exp(-ends / exposure)`` on the blocks' tracks (module
    docstring), from ``survival``; None without exposure (no track of two scans' span)."""
    for _ in range(MAX_BIRTH_UPDATES):
        sums = [_survival_sums(block, survival) for block in blocks]
        exposure = sum(s[1] for s in sums)
        if exposure <= 0:
            return None
        ends = max(sum(s[0] for s in sums), UNSEEN_EVENTS)
        new = math.exp(-ends / exposure)
        if abs(new - survival) <= BIRTH_TOLERANCE * max(new, survival):
            return new
        survival = new
    return survival


def velocity_update(
    config: Config, pieces: Sequence[Sequence[Scan]],
    associations: Sequence[Mapping[int, Mapping[int, int]]],
) -> float | None:
    """``sqrt(mean(m^2 + P))`` of the smoothed velocity components at the first detection
    of every track with at least :data:`MIN_TRACK_DETECTIONS` detections, smoothed under
    ``config``; None without such a track."""  # fmt: skip
    indices = list(config.motion.velocity_indices)  # type: ignore[attr-defined]
    squares: list[FloatArray] = []
    for piece, tracks in zip(pieces, associations, strict=True):
        for track_id in sorted(tracks):
            detections = tracks[track_id]
            if len(detections) < MIN_TRACK_DETECTIONS:
                continue
            _, states, covariances, _ = smooth_track(piece, detections, config)
            mean, cov = states[0][indices], covariances[0][np.ix_(indices, indices)]
            squares.append(mean**2 + np.diag(cov))
    if not squares:
        return None
    return float(np.sqrt(np.mean(np.concatenate(squares))))


def birth_m_step(
    config: Config,
    pieces: Sequence[Sequence[Scan]],
    starts_recording: Sequence[bool],
    associations: Sequence[Mapping[int, Mapping[int, int]]],
    current: BirthLevels,
    existence: Sequence[Mapping[int, float] | None] | None = None,
) -> tuple[BirthLevels, tuple[str, ...]]:
    """The birth keys the pass's tracks give (module docstring), and notes of what they
    could not estimate (kept).

    Parameters
    ----------
    config : Config
        The pass's configuration (its sensors' ``Pd``, its birth model with ``current``).
    pieces : sequence of sequence of Scan
        The sample's blocks.
    starts_recording : sequence of bool
        Per block, whether it starts at the recording's first scan.
    associations : sequence of mapping
        Per block, every track as scan index -> detection index.
    current : BirthLevels
        The values the pass ran with.
    existence : sequence of mapping or None, optional
        Per block, track id -> probability that the track is a target (the confidence
        pass's existence; module docstring); None: every track counts 1.
    """
    values, notes = dict(current.values), []
    exist = [None] * len(pieces) if existence is None else list(existence)
    blocks = [block_tracks(config, piece, tracks, first, e) for piece, tracks, first, e
              in zip(pieces, associations, starts_recording, exist, strict=True)]  # fmt: skip
    birth = config.birth
    survival = birth.survival_probability
    if "survival_probability" in values:
        found = survival_update(blocks, survival)
        if found is None:
            notes.append("birth.survival_probability not estimable: no track spans two scans; kept")
        else:
            values["survival_probability"] = survival = found
    if "rate" in values or "initial_count" in values:
        initial, rate, estimable = count_update(
            blocks, survival, birth.initial_count, birth.rate,
            fit_initial="initial_count" in values, fit_rate="rate" in values,
        )  # fmt: skip
        if "rate" in values:
            values["rate"] = rate
        if "initial_count" in values:
            if estimable:
                values["initial_count"] = initial
            else:
                notes.append("birth.initial_count not estimable: no sampled block starts at "
                             "the recording's first scan; kept")  # fmt: skip
    if "velocity_std" in values:
        found = velocity_update(config, pieces, associations)
        if found is None:
            notes.append(f"birth.velocity_std not estimable: no track with {MIN_TRACK_DETECTIONS} "
                         "detections; kept")  # fmt: skip
        else:
            values["velocity_std"] = found
    return BirthLevels(values), tuple(notes)


def _speed_start(scans: Sequence[Scan]) -> float | None:
    """``sqrt(quantile(r^2 / dt^2, VELOCITY_START_QUANTILE) / d)`` over the
    nearest-neighbour displacements between consecutive scans of each sensor (module
    docstring); None without two such scans."""
    squares: list[FloatArray] = []
    previous: dict[str, Scan] = {}
    for scan in scans:
        before = previous.get(scan.sensor)
        if before is not None and before.size and scan.size and scan.time > before.time:
            diff = scan.detections[:, None, :] - before.detections[None, :, :]
            nearest = np.min(np.sum(diff**2, axis=-1), axis=1)
            squares.append(nearest / (scan.time - before.time) ** 2 / scan.detections.shape[1])
        previous[scan.sensor] = scan
    if not squares:
        return None
    found = np.quantile(np.concatenate(squares), VELOCITY_START_QUANTILE)
    return float(np.sqrt(found)) or None


RATE_START = 0.1
"""Births per scan the first pass assumes at most (``BirthModel``'s default rate)."""
RATE_START_SHARE = 0.01
"""The rate's start is at most this share of the mean detections per scan."""


def _rate_start(scans: Sequence[Scan]) -> float:
    """``max(1 / S, min(RATE_START, RATE_START_SHARE * mean detections per scan))`` over
    the ``S`` sampled scans (module docstring, starts)."""
    if not scans:
        return 1.0
    mean = sum(scan.size for scan in scans) / len(scans)
    return max(1.0 / len(scans), min(RATE_START, RATE_START_SHARE * mean))


def initial_birth(config: Config, scans: Sequence[Scan], asked: BirthAsked) -> BirthLevels:
    """The first pass's values: the configured starts, else the rules of the module
    docstring (``scans``: the sampled scans).

    Raises
    ------
    InputError
        No start can be found (naming the start key to give).
    """
    times = [scan.time for scan in scans]
    duration = max(times) - min(times) if times else 0.0
    values: dict[str, float] = {}
    for key in AUTO_BIRTH_KEYS:
        if key not in asked.starts:
            continue
        start = asked.starts[key]
        if start is None:
            if key == "rate":
                start = _rate_start(scans)
            elif key == "initial_count":
                start = 1.0
            elif key == "survival_probability":
                start = math.exp(-1.0 / duration) if duration > 0 else 0.99
            else:
                start = _speed_start(scans)
                if start is None:
                    raise InputError(
                        'birth.velocity_std = "auto": the recording has no two consecutive '
                        "scans of a sensor with detections to start from; give "
                        "velocity_std_start", key="birth.velocity_std_start",
                    )  # fmt: skip
        values[key] = float(start)
    return BirthLevels(values)
