"""CLEAR-MOT: MOTA, MOTP, identity switches, fragmentations, mostly tracked / lost.

Definitions (Bernardin and Stiefelhagen, "Evaluating multiple object tracking performance:
the CLEAR MOT metrics", EURASIP J. Image and Video Processing 2008, Sec. 2.1-2.2), at every
evaluation time (frame) ``t`` with ``g_t`` true objects:

* a truth object and an estimate (hypothesis) may correspond only when their Euclidean
  distance is below the threshold ``T`` (here: ``< threshold``);
* *mapping persistence*: a correspondence of the previous frames is kept while it stays
  valid (both present and within ``T``); the remaining objects and hypotheses are matched by
  the Hungarian algorithm on their distances (maximum number of matches, then minimum total
  distance);
* a *mismatch* (identity switch) is counted when an object is matched to a hypothesis other
  than the one it was last matched to; ``m_t`` of them at frame ``t``;
* ``misses`` are unmatched objects, ``false positives`` unmatched hypotheses;
* ``MOTP = sum_{t,i} d_t^i / sum_t c_t`` (eq. 1: mean distance over matches, switches
  included; lower is better; ``nan`` without any match);
* ``MOTA = 1 - sum_t (misses_t + fp_t + mme_t) / sum_t g_t`` (eq. 2; may be negative).

Mostly tracked (matched at >= 80 % of the frames the object exists), mostly lost (< 20 %),
partially tracked (the rest) and fragmentations (for each object, the times its matched
state is interrupted by a miss between its first and last match) are the definitions of
Li, Huang and Nevatia ("Learning to associate: HybridBoosted multi-target tracker for
crowded scene", CVPR 2009), which MOT benchmarks report next to CLEAR-MOT.

Engine: py-motmetrics (``motmetrics``, the optional extra ``metrics``:
``pip install 'mapassoc[metrics]'``), which implements exactly these definitions and was
checked here with numpy 2 and pandas 3.  Its persistence rule keeps an object's *last*
correspondence (also across frames where the object was missed) and counts a switch against
it, as in the paper's Fig. 4.  Without ``motmetrics`` :func:`clear_mot` raises
:class:`~mapassoc.errors.InputError` naming the extra.

Frames are the sorted union of the distinct truth and estimate times, matched exactly (as in
:mod:`mapassoc.evaluation.metrics`); object and hypothesis identities are the row ids.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import ModuleType

import numpy as np

from mapassoc.errors import InputError
from mapassoc.evaluation.points import TimedPoints, check_runs
from mapassoc.validation import check_positive

__all__ = ["ClearMotResult", "clear_mot", "motmetrics_available"]

_METRICS = (
    "mota",
    "motp",
    "num_objects",
    "num_unique_objects",
    "num_matches",
    "num_misses",
    "num_false_positives",
    "num_switches",
    "num_fragmentations",
    "mostly_tracked",
    "partially_tracked",
    "mostly_lost",
)


@dataclass(frozen=True)
class ClearMotResult:
    """CLEAR-MOT scores of a run.

    Parameters
    ----------
    mota : float
        ``1 - (num_misses + num_false_positives + num_switches) / num_objects``, <= 1.
    motp : float
        Mean distance over matched pairs (switches included); ``nan`` without any match.
    num_objects : int
        Truth rows summed over frames, ``sum_t g_t`` (> 0).
    num_unique_objects : int
        Distinct truth ids.
    num_matches : int
        Correspondences that are not switches.
    num_misses : int
        Unmatched truth rows.
    num_false_positives : int
        Unmatched estimate rows.
    num_switches : int
        Identity switches (mismatches).
    num_fragmentations : int
        Interruptions of an object's matched state (Li et al. 2009).
    mostly_tracked, partially_tracked, mostly_lost : int
        Truth objects matched at >= 80 %, [20 %, 80 %) and < 20 % of their frames.
    threshold : float
        Distance below which a pair may correspond.
    """

    mota: float
    motp: float
    num_objects: int
    num_unique_objects: int
    num_matches: int
    num_misses: int
    num_false_positives: int
    num_switches: int
    num_fragmentations: int
    mostly_tracked: int
    partially_tracked: int
    mostly_lost: int
    threshold: float


def motmetrics_available() -> bool:
    """Whether the optional engine ``motmetrics`` can be imported."""
    try:
        import motmetrics  # noqa: F401
    except ImportError:
        return False
    return True


def _motmetrics() -> ModuleType:
    try:
        import motmetrics
    except ImportError:
        raise InputError(
            "CLEAR-MOT needs motmetrics: pip install 'mapassoc[metrics]' (or motmetrics)"
        ) from None
    return motmetrics


def clear_mot(truth: TimedPoints, estimates: TimedPoints, *, threshold: float) -> ClearMotResult:
    """CLEAR-MOT (Bernardin and Stiefelhagen 2008) of estimates against truth.

    Parameters
    ----------
    truth : TimedPoints
        True positions; ids are target identities.  At least one row (MOTA divides by the
        number of truth rows).
    estimates : TimedPoints
        Estimated positions, same dimension; ids are track identities.
    threshold : float
        A truth row and an estimate row may correspond only at Euclidean distance
        ``< threshold`` (> 0).

    Returns
    -------
    ClearMotResult

    Raises
    ------
    InputError
        ``threshold <= 0``, inputs that are not TimedPoints or of different dimensions,
        no truth row, or ``motmetrics`` not installed.

    Examples
    --------
    Truth ids 1, 2 at four frames; track 1 follows target 1 throughout; target 2 is tracked
    by track 2 at frame 0, by track 3 at frame 1 (a switch), missed at frame 2 and tracked by
    3 again at frame 3 (a fragmentation); a track 4 far from all at frame 3 (a false
    positive): 8 truth rows, MOTA = 1 - (1 + 1 + 1) / 8 = 0.625.
    """
    limit = check_positive("threshold", threshold)
    check_runs(truth, estimates)
    if truth.times.shape[0] == 0:
        raise InputError("truth has no rows: MOTA (which divides by the truth rows) is undefined")
    mm = _motmetrics()
    accumulator = mm.MOTAccumulator(auto_id=False)
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    for frame, t in enumerate(times):
        at_truth = truth.times == t
        at_estimates = estimates.times == t
        distance = np.linalg.norm(
            truth.positions[at_truth][:, None, :] - estimates.positions[at_estimates][None, :, :],
            axis=-1,
        )
        distance[distance >= limit] = np.nan  # motmetrics: nan = may not correspond
        accumulator.update(
            truth.ids[at_truth].tolist(),
            estimates.ids[at_estimates].tolist(),
            distance,
            frameid=frame,
        )
    summary = mm.metrics.create().compute(accumulator, metrics=list(_METRICS), name="run")
    row = summary.loc["run"]
    motp = float(row["motp"])
    return ClearMotResult(
        mota=float(row["mota"]),
        motp=motp if math.isfinite(motp) else math.nan,
        num_objects=int(row["num_objects"]),
        num_unique_objects=int(row["num_unique_objects"]),
        num_matches=int(row["num_matches"]),
        num_misses=int(row["num_misses"]),
        num_false_positives=int(row["num_false_positives"]),
        num_switches=int(row["num_switches"]),
        num_fragmentations=int(row["num_fragmentations"]),
        mostly_tracked=int(row["mostly_tracked"]),
        partially_tracked=int(row["partially_tracked"]),
        mostly_lost=int(row["mostly_lost"]),
        threshold=limit,
    )
