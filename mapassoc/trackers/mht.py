"""Track-oriented multiple hypothesis tracking (MHT) with N-scan pruning.

Kurien, "Issues in the design of practical multitarget tracking algorithms", in
*Multitarget-Multisensor Tracking: Advanced Applications*, 1990; Blackman & Popoli,
*Design and Analysis of Modern Tracking Systems*, 1999, ch. 16; Blackman, "Multiple
hypothesis tracking for multiple target tracking", IEEE AES Magazine 19(1), 2004.  Run on
exactly the library's motion, sensor, clutter and birth models (the
:class:`~mapassoc.data.config.Config`), with the track scores of the shared track
management (:mod:`mapassoc.trackers.management`).

**Hypothesis trees.**  Every detection roots a tree (a potential target whose first
detection it is).  A tree's leaves are its track hypotheses: one detection or a miss per
scan from the root's scan on.  At every scan each live leaf branches into a miss and into
each detection inside its chi-square gate (Kalman/EKF update,
:func:`~mapassoc.filtering.track_filter.update_track`).  A leaf's score is the sequential
track log-likelihood ratio against "its detections are false alarms" (Blackman & Popoli
1999, section 6.2, eqs. 6.8-6.13), with the increments of the GNN/JPDA management:

==================================  ===================================================
root (first detection, scan j)      ``log u_j + log Pd - log lambda_bar`` (eq. 6.8: the
                                    birth model's new-target density ``u_j Pd / V``
                                    over the false-alarm density ``lambda_bar / V``;
                                    ``u_j`` from :mod:`mapassoc.models.population`)
detection in the gate               ``log Pd + log N(nu; 0, S) - log lambda``
                                    (:func:`~mapassoc.trackers.management.gated_log_ratios`)
miss                                ``log(1 - Pd P_G)``
                                    (:func:`~mapassoc.estimator.terms.miss_term`)
==================================  ===================================================

When ``u_j = 0`` no detection of scan j roots a tree.

**Track termination.**  A leaf whose score has dropped more than ``termination_drop``
(default: the :class:`~mapassoc.trackers.management.ScoreRule`'s ``deletion_drop``)
below the highest score on its path is a *terminated* track (the score-drop deletion of
Blackman & Popoli, section 6.3.3, that GNN and JPDA use): it keeps its score and branches
no more, so a target that has gone stays explained without coasting into clutter.
``termination_drop = inf`` switches termination off.

**Per-tree pruning** after each scan's branching: the gate; leaves scoring more than
``prune_log_ratio`` below the best leaf of their tree; then all but the ``max_leaves``
best leaves of each tree (defaults: ``config.estimator.pruning.prune_log_ratio`` and
``config.estimator.pruning.max_hypotheses_per_tree``).

**Global hypothesis.** At every scan the best *global hypothesis* chooses at most one
leaf per tree, no detection used twice, maximising the summed leaf scores (Blackman
2004, section "track-oriented MHT"; Morefield 1977): a set packing
(:class:`~mapassoc.formulations.packing.PackingProblem`,
:func:`~mapassoc.formulations.packing.set_packing_program`) whose resources are the
trees and the detections not yet decided. A tree with no selected leaf is a set of false
alarms (score 0). A tree whose first scans are decided (below) is a track: its leaves
enter the program with their score minus the decided part's (a constant of the
hypothesis) plus :data:`CONTINUE_BONUS`, so one of them is selected whenever the
detections allow it and the track ends only through a terminated leaf, as in the score
management of GNN (leaving such a track out for free would end a true track after
``n_scan`` misses in a row; on ``dense`` it fragmented or cut short three of ten
targets). The problem splits into clusters of interacting trees
(:func:`~mapassoc.formulations.clusters.cluster_hypotheses`); a cluster of one tree is
solved in closed form (its best leaf, or nothing), the others with the ``solver`` (HiGHS
by default). The ``m_best`` best global hypotheses come from the ``m_best`` best of each
cluster (no-good cuts, :func:`~mapassoc.solvers.k_best.solve_k_best`) merged best-first
over the clusters (the j-th best sum of independent parts uses only the top j of each
part). With ``m_best = 1`` leaves with value <= 0 are left out of the program: dropping
such a leaf from any global hypothesis gives one at least as good, so the best is
unchanged (with ``m_best > 1`` every leaf enters, which makes the programs larger and
the tracker several times slower on ``dense``). Global hypothesis probabilities are
``exp(score)`` normalised over the M best (Blackman 2004, restricted to the hypotheses formed;
:meth:`MhtDetails.m_best_probabilities`). With ``m_best_pruning`` every tree that has a
leaf in one of the M best hypotheses keeps only such leaves (hypothesis-probability
pruning; trees in none are left to the rules below, so that a young tree can still
grow).

**N-scan pruning** (Blackman & Popoli 1999, ch. 16): after the best global
hypothesis of scan k, the decision of scan ``s = k - n_scan`` is final.

* In every tree with a selected leaf, only the leaves that agree with that leaf on every
  scan up to ``s`` survive; the tree's path up to ``s`` is decided (its detections are no
  longer resources of the program).  When that leaf is terminated at or before ``s`` the
  track is closed.
* A tree with a decided part and no selected leaf (only when all its leaves conflict with
  other such tracks) is closed with its decided part: the track ended there.
* A tree with nothing decided and no selected leaf is *tentative*: it loses every leaf
  that uses a detection now decided for another tree, and it is deleted when it has no
  leaf left, when all its leaves are terminated (score drop), or, with
  ``tentative_scans``, once its root is that many scans old.  The default (no age
  limit) was chosen by measurement: deleting unselected trees once older than N scans
  (``tentative_scans = n_scan``, the textbook rule) started the track of a target born
  among clutter 6 scans late on ``crossing`` (GOSPA 1.49 against 1.30) because one
  missed detection among a new tree's first N scans kept its score below 0.

At the end of the recording the last best global hypothesis decides every branch left.

**Output.**  The tracks of the final hypothesis (closed trees and the last selected
leaves) whose score reached the SPRT confirmation threshold
``T2 = log((1 - beta) / alpha)`` of the :class:`~mapassoc.trackers.management.ScoreRule`
somewhere on their path, with their hard associations, smoothed by
:func:`~mapassoc.filtering.smoothing.smooth_tracks` like every hard-association method.
``details`` is an :class:`MhtDetails` with per-scan counts.
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from mapassoc.array_types import FloatArray, IntArray
from mapassoc.data.config import Config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.terms import miss_term
from mapassoc.filtering.smoothing import smooth_tracks
from mapassoc.filtering.track_filter import (
    FilteredTrack,
    predict_track,
    start_track,
    update_track,
)
from mapassoc.formulations.clusters import cluster_hypotheses
from mapassoc.formulations.packing import (
    PackingProblem,
    decode_selection,
    set_packing_program,
)
from mapassoc.models.population import UndetectedTargets
from mapassoc.solvers import ProgramSolver, get_integer_solver
from mapassoc.solvers.k_best import solve_k_best
from mapassoc.solvers.results import SolverError, SolveStatus
from mapassoc.trackers.base import TrackerOutput, check_scans
from mapassoc.trackers.management import (
    ScoreRule,
    check_tracker_config,
    gated_log_ratios,
    new_target_log_ratio,
    with_own_gate,
)
from mapassoc.validation import check_integer

__all__ = ["MhtDetails", "MhtTracker"]

CONTINUE_BONUS = 1.0e4
"""Added to the program value of every leaf of a tree with a decided part, so that such a
track continues (one of its leaves is selected) whenever the detections allow it: its
end comes from a terminated leaf (score drop), not from leaving it out (module
docstring).  It exceeds by far what freeing one track's few undecided detections can
gain, and it is taken off the reported scores."""

MAX_M_BEST = 100
"""Largest ``m_best`` accepted (each cluster's k-best adds one dense cut per point)."""


@dataclass(frozen=True, eq=False)
class MhtDetails:
    """Per-scan counts of an MHT run (:attr:`TrackerOutput.details`).

    Attributes
    ----------
    trees, leaves : ndarray of int, shape (S,)
        Active trees and their leaves at each scan after branching and per-tree
        pruning (what the global hypothesis chooses from).
    clusters : ndarray of int, shape (S,)
        Clusters of interacting trees solved by the integer-programming solver (clusters
        of one tree are solved in closed form and not counted).
    best_scores : ndarray, shape (S,)
        Score of the best global hypothesis at each scan: its selected leaves' scores plus
        those of the closed (fully decided) tracks.
    m_best_scores : tuple of tuple of float, length S
        The scores of the (up to) M best global hypotheses of each scan, best first
        (same convention as ``best_scores``).
    tracks_started : int
        Trees rooted over the run.
    """

    trees: IntArray
    leaves: IntArray
    clusters: IntArray
    best_scores: FloatArray
    m_best_scores: tuple[tuple[float, ...], ...]
    tracks_started: int

    def __post_init__(self) -> None:
        for name in ("trees", "leaves", "clusters", "best_scores"):
            a = np.array(getattr(self, name), copy=True)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def m_best_probabilities(self, scan_index: int) -> FloatArray:
        """Probabilities of the M best global hypotheses of one scan, ``∝ exp(score)``
        normalised over them (Blackman 2004, restricted to those formed).

        Returns
        -------
        ndarray, shape (m,)
        """
        scores = np.asarray(self.m_best_scores[scan_index], dtype=float)
        w = np.exp(scores - scores.max())
        return np.asarray(w / w.sum(), dtype=float)


@dataclass(frozen=True, eq=False, slots=True)
class _Leaf:
    """One track hypothesis of a tree rooted at scan r.

    ``path[i]`` is its detection at scan ``r + i`` (-1: a miss) and ``scores[i]`` its
    score after that scan; ``max_score = max(scores)``.
    """

    path: tuple[int, ...]
    scores: tuple[float, ...]
    filtered: FilteredTrack
    max_score: float
    terminated: bool

    @property
    def score(self) -> float:
        return self.scores[-1]


@dataclass(frozen=True)
class _Track:
    """A decided track: its tree, root scan, detections per scan and scores."""

    tree_id: int
    root_scan: int
    path: tuple[int, ...]
    score: float
    max_score: float


class _Tree:
    """The track hypotheses rooted at one detection (mutable, internal).

    Scans up to ``fixed_scan`` are decided: every leaf starts with ``fixed_path``, whose
    score is ``fixed_score`` (0 and empty while nothing is decided).
    """

    __slots__ = ("tree_id", "root_scan", "fixed_scan", "fixed_path", "fixed_score",
                 "fixed_max", "leaves")

    def __init__(self, tree_id: int, root_scan: int, leaf: _Leaf) -> None:
        self.tree_id = tree_id
        self.root_scan = root_scan
        self.fixed_scan = root_scan - 1
        self.fixed_path: tuple[int, ...] = ()
        self.fixed_score = 0.0
        self.fixed_max = -math.inf
        self.leaves = [leaf]

    @property
    def committed(self) -> bool:
        """Whether part of the tree is decided (it then is a track whatever comes)."""
        return bool(self.fixed_path)

    def decided_track(self) -> _Track:
        return _Track(self.tree_id, self.root_scan, self.fixed_path, self.fixed_score,
                      self.fixed_max)


@dataclass(frozen=True, eq=False)
class _ClusterOption:
    value: float
    leaves: tuple[int, ...]  # indices into the scan's flat leaf list


def _check_drop(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
        raise InputError(f"{name} must be a number > 0 (inf allowed), got {value!r}")
    v = float(value)
    if math.isnan(v) or v <= 0.0:
        raise InputError(f"{name} must be a number > 0 (inf allowed), got {value!r}")
    return v


def _top_sums(
    options: Sequence[Sequence[_ClusterOption]], m: int
) -> list[tuple[float, tuple[int, ...]]]:
    """The ``m`` best choices of one option per cluster by summed value, best first.

    Each ``options[c]`` is sorted best first.  Best-first search over index vectors (each
    successor raises one index by one); exact because values are non-increasing along
    every list.  Ties are broken by the index vector (lexicographically smallest first).
    """
    start = tuple(0 for _ in options)
    first = sum(opts[0].value for opts in options)
    heap: list[tuple[float, tuple[int, ...]]] = [(-first, start)]
    seen = {start}
    out: list[tuple[float, tuple[int, ...]]] = []
    while heap and len(out) < m:
        neg, idx = heapq.heappop(heap)
        out.append((-neg, idx))
        for c, opts in enumerate(options):
            if idx[c] + 1 < len(opts):
                nxt = idx[:c] + (idx[c] + 1,) + idx[c + 1:]
                if nxt not in seen:
                    seen.add(nxt)
                    value = -neg - opts[idx[c]].value + opts[idx[c] + 1].value
                    heapq.heappush(heap, (-value, nxt))
    return out


@dataclass(frozen=True, eq=False)
class _Candidates:
    """The leaves that enter one scan's global-hypothesis program.

    Attributes
    ----------
    owner : ndarray of int, shape (H,)
        Index (into the scan's tree list) of each candidate's tree.
    leaves : list of _Leaf, length H
    problem : PackingProblem
        Set packing over H candidates whose resources are the trees, then the detections
        of every scan (offset by the scan's first detection index); a candidate's value is
        its score minus its tree's decided part, plus :data:`CONTINUE_BONUS` for a track.
    """

    owner: IntArray
    leaves: list[_Leaf]
    problem: PackingProblem


def _candidates(trees: list[_Tree], offsets: IntArray, m_best: int) -> _Candidates | None:
    """The candidate leaves and their set-packing problem; ``None`` when there are none.

    With ``m_best = 1`` leaves of value <= 0 are left out (module docstring).
    ``offsets`` (shape (S + 1,)) are the first detection index of every scan and the total.
    """
    owner: list[int] = []
    candidates: list[_Leaf] = []
    values: list[float] = []
    indptr = [0]
    indices: list[int] = []
    T = len(trees)
    for t, tree in enumerate(trees):
        for leaf in tree.leaves:
            value = leaf.score - tree.fixed_score
            if tree.committed:
                value += CONTINUE_BONUS
            if m_best == 1 and not value > 0.0:
                continue  # never in the best hypothesis: dropping it cannot hurt
            owner.append(t)
            candidates.append(leaf)
            values.append(value)
            indices.append(t)
            for i, j in enumerate(leaf.path):
                scan_index = tree.root_scan + i
                if j >= 0 and scan_index > tree.fixed_scan:
                    indices.append(T + int(offsets[scan_index]) + j)
            indptr.append(len(indices))
    if not candidates:
        return None
    problem = PackingProblem(
        scores=np.asarray(values, dtype=float),
        resource_indptr=np.asarray(indptr, dtype=np.int64),
        resource_indices=np.asarray(indices, dtype=np.int64),
        exactly_one=np.zeros(T + int(offsets[-1]), dtype=bool),
        counts=np.ones(len(candidates), dtype=bool),
    )
    return _Candidates(np.asarray(owner, dtype=np.int64), candidates, problem)


def _one_tree_options(
    problem: PackingProblem, cluster: IntArray, m_best: int
) -> list[_ClusterOption]:
    """The ``m_best`` best options of a cluster of one tree, in closed form: nothing, or
    any one of its leaves (candidate indices ``cluster``)."""
    ranked = sorted(
        [_ClusterOption(0.0, ())]
        + [_ClusterOption(float(problem.scores[h]), (int(h),)) for h in cluster],
        key=lambda o: -o.value,
    )
    return ranked[:m_best]


def _program_options(
    problem: PackingProblem, cluster: IntArray, m_best: int, solver: ProgramSolver
) -> list[_ClusterOption]:
    """The ``m_best`` best options of a cluster of several trees (candidate indices
    ``cluster``), by the integer program and no-good cuts."""
    program = set_packing_program(problem.subproblem(cluster), None)
    options = []
    for result in solve_k_best(program, m_best, solver=solver):
        if result.status is not SolveStatus.OPTIMAL or result.solution is None:
            raise SolverError(
                f"{result.solver}: the MHT's global-hypothesis program ended "
                f"with status {result.status.value}: {result.message}"
            )
        chosen = cluster[decode_selection(result.solution)]
        options.append(_ClusterOption(float(result.objective), tuple(int(h) for h in chosen)))
    return options


def _merged_hypotheses(
    options: list[list[_ClusterOption]],
    candidates: _Candidates,
    trees: list[_Tree],
    m_best: int,
) -> list[tuple[float, dict[int, _Leaf]]]:
    """The ``m_best`` best global hypotheses (score, tree id -> selected leaf) from the
    options of every cluster, best first; a score leaves out the trees' decided parts."""
    out = []
    for _, idx in _top_sums(options, m_best):
        chosen_leaves: dict[int, _Leaf] = {}
        total = []
        for c, i in enumerate(idx):
            for h in options[c][i].leaves:
                tree = trees[candidates.owner[h]]
                chosen_leaves[tree.tree_id] = candidates.leaves[h]
                total.append(candidates.leaves[h].score - tree.fixed_score)
        out.append((math.fsum(total), chosen_leaves))
    return out


@dataclass(eq=False)
class _RunState:
    """Where an MHT run stands between scans (mutable, internal).

    Attributes
    ----------
    offsets : ndarray of int, shape (S + 1,)
        Index of each scan's first detection among all, then the total.
    trees : list of _Tree
        The active trees.
    closed : list of _Track
        Tracks fully decided and ended.
    fixed_owner : dict of (int, int) to int
        Decided (scan, detection) -> tree id.
    selected : dict of int to _Leaf
        Tree id -> its leaf in the last best global hypothesis.
    next_id : int
        Id of the next tree rooted.
    undetected : UndetectedTargets or None
        The birth model's undetected targets carried from scan to scan.
    """

    offsets: IntArray
    trees: list[_Tree] = field(default_factory=list)
    closed: list[_Track] = field(default_factory=list)
    fixed_owner: dict[tuple[int, int], int] = field(default_factory=dict)
    selected: dict[int, _Leaf] = field(default_factory=dict)
    next_id: int = 1
    undetected: UndetectedTargets | None = None


@dataclass(eq=False)
class _History:
    """The per-scan counts of a run, appended scan by scan (:class:`MhtDetails`)."""

    trees: list[int] = field(default_factory=list)
    leaves: list[int] = field(default_factory=list)
    clusters: list[int] = field(default_factory=list)
    best_scores: list[float] = field(default_factory=list)
    m_scores: list[tuple[float, ...]] = field(default_factory=list)

    def details(self, tracks_started: int) -> MhtDetails:
        return MhtDetails(
            trees=np.asarray(self.trees, dtype=np.int64),
            leaves=np.asarray(self.leaves, dtype=np.int64),
            clusters=np.asarray(self.clusters, dtype=np.int64),
            best_scores=np.asarray(self.best_scores, dtype=float),
            m_best_scores=tuple(self.m_scores),
            tracks_started=tracks_started,
        )


def _keep_m_best_leaves(
    trees: list[_Tree], hypotheses: list[tuple[float, dict[int, _Leaf]]]
) -> None:
    """Hypothesis-probability pruning: every tree with a leaf in one of ``hypotheses``
    keeps only such leaves (in place)."""
    keep: dict[int, set[int]] = {}
    for _, chosen in hypotheses:
        for t, leaf in chosen.items():
            keep.setdefault(t, set()).add(id(leaf))
    for tree in trees:
        if tree.tree_id in keep:
            tree.leaves = [lf for lf in tree.leaves if id(lf) in keep[tree.tree_id]]


def _final_tracks(run: _RunState) -> list[_Track]:
    """The tracks of the final hypothesis: the closed ones, the selected leaves, and the
    decided parts of committed trees without one (the last best hypothesis decides every
    branch left)."""
    selected = run.selected
    return run.closed + [
        _Track(t.tree_id, t.root_scan, selected[t.tree_id].path,
               selected[t.tree_id].score, selected[t.tree_id].max_score)
        if t.tree_id in selected else t.decided_track()
        for t in run.trees
        if t.tree_id in selected or t.committed
    ]  # fmt: skip


class MhtTracker:
    """Track-oriented MHT (module docstring) on the library's models.

    Parameters
    ----------
    config : Config
        Motion, sensor, clutter and birth models; ``config.estimator.pruning.gate_probability``
        is the gate.  Every sensor needs ``false_alarms_per_scan > 0`` and
        ``Pd * P_G < 1`` (:func:`~mapassoc.trackers.management.check_tracker_config`).
    gate_probability : float, optional
        This tracker's own gate probability, in (0, 1]; default
        ``config.estimator.pruning.gate_probability``.
    n_scan : int
        N >= 1: the decision of scan ``k - N`` is fixed after scan k.  Default 3.
    m_best : int
        Global hypotheses formed per scan, 1..100.  Default 1.
    m_best_pruning : bool
        Keep, in every tree with a leaf in one of the M best hypotheses, only such
        leaves.  Default False.
    prune_log_ratio : float, optional
        Leaves more than this below the best leaf of their tree are pruned (> 0, ``inf``
        disables); default ``config.estimator.pruning.prune_log_ratio``.
    max_leaves : int, optional
        Most leaves per tree after each scan (>= 1); default
        ``config.estimator.pruning.max_hypotheses_per_tree``.
    termination_drop : float, optional
        Score drop below a path's maximum at which a leaf is a terminated track (> 0,
        ``inf`` disables); default ``management.deletion_drop``.
    tentative_scans : int, optional
        Age (scans, >= 1) at which a tree with nothing decided and no selected leaf is
        deleted; default ``None``: no age limit (module docstring).
    management : ScoreRule, optional
        Gives the confirmation threshold of the output (and the default
        ``termination_drop``); default :class:`~mapassoc.trackers.management.ScoreRule` ().
    solver : str
        Registry name of an exact integer-programming solver for clusters of several
        trees; default ``"highs"``.
    name : str
        Label in comparisons.
    """

    def __init__(
        self,
        *,
        config: Config,
        gate_probability: float | None = None,
        n_scan: int = 3,
        m_best: int = 1,
        m_best_pruning: bool = False,
        prune_log_ratio: float | None = None,
        max_leaves: int | None = None,
        termination_drop: float | None = None,
        tentative_scans: int | None = None,
        management: ScoreRule | None = None,
        solver: str = "highs",
        name: str = "mht",
    ) -> None:
        config = with_own_gate(config, gate_probability)
        check_tracker_config(config)
        self.config = config
        self.n_scan = check_integer("n_scan", n_scan, minimum=1)
        self.m_best = check_integer("m_best", m_best, minimum=1, maximum=MAX_M_BEST)
        if not isinstance(m_best_pruning, bool):
            raise InputError(f"m_best_pruning must be True or False, got {m_best_pruning!r}")
        self.m_best_pruning = m_best_pruning
        pruning = config.estimator.pruning
        self.prune_log_ratio = _check_drop(
            "prune_log_ratio",
            pruning.prune_log_ratio if prune_log_ratio is None else prune_log_ratio,
        )
        self.max_leaves = check_integer(
            "max_leaves",
            config.estimator.pruning.max_hypotheses_per_tree if max_leaves is None else max_leaves,
            minimum=1,
        )
        self.tentative_scans = (
            None
            if tentative_scans is None
            else check_integer("tentative_scans", tentative_scans, minimum=1)
        )
        if management is None:
            management = ScoreRule()
        if not isinstance(management, ScoreRule):
            raise InputError(
                f"management must be a ScoreRule (MHT scores every hypothesis), got "
                f"{type(management).__name__}"
            )
        self.management = management
        self.termination_drop = _check_drop(
            "termination_drop",
            management.deletion_drop if termination_drop is None else termination_drop,
        )
        if not isinstance(solver, str):
            raise InputError(f"solver must be a solver name (str), got {solver!r}")
        try:
            self._solver = get_integer_solver(solver, exact=True)
        except ValueError as exc:
            raise InputError(f"solver {solver!r}: {exc}") from exc
        if not isinstance(name, str):
            raise InputError(f"name must be a str, got {name!r}")
        self.name = name

    # ------------------------------------------------------------------ the run

    def track(self, scans: Sequence[Scan]) -> TrackerOutput:
        """Track over ``scans``; ``associations`` are the confirmed tracks' detections.

        ``details`` is an :class:`MhtDetails`.
        """
        scans = check_scans(scans, self.config)
        started = time.perf_counter()
        offsets = np.concatenate([[0], np.cumsum([s.size for s in scans])]).astype(np.int64)
        run = _RunState(offsets=offsets)
        history = _History()
        for k, scan in enumerate(scans):
            self._grow(run, k, scan)
            history.trees.append(len(run.trees))
            history.leaves.append(sum(len(t.leaves) for t in run.trees))
            hypotheses = self._choose(run, history)
            if self.m_best_pruning:
                _keep_m_best_leaves(run.trees, hypotheses)
            self._decide(run, k)
        associations = self._confirmed(_final_tracks(run))
        tracks = smooth_tracks(scans, associations, self.config)
        return TrackerOutput(
            tracks=tracks,
            seconds=time.perf_counter() - started,
            associations=associations,
            details=history.details(run.next_id - 1),
        )

    # ------------------------------------------------------------------ steps

    def _grow(self, run: _RunState, k: int, scan: Scan) -> None:
        """Branch and prune every tree on scan ``k``, then root a tree at each of its
        detections (unless the birth model gives none there)."""
        log_new, run.undetected = new_target_log_ratio(self.config, scan, run.undetected)
        for tree in run.trees:
            tree.leaves = self._prune(self._branch(tree.leaves, scan))
        if log_new > -math.inf:
            for j in range(scan.size):
                root = _Leaf(
                    (j,), (log_new,), start_track(self.config, scan, j), log_new, False
                )
                run.trees.append(_Tree(run.next_id, k, root))
                run.next_id += 1

    def _choose(self, run: _RunState, history: _History) -> list[tuple[float, dict[int, _Leaf]]]:
        """The M best global hypotheses of the scan (recorded in ``history``; the best
        becomes ``run.selected``)."""
        hypotheses, n_clusters = self._global_hypotheses(run.trees, run.offsets)
        # Decided parts: closed tracks and the committed trees' fixed paths.
        constant = math.fsum([t.score for t in run.closed] + [t.fixed_score for t in run.trees])
        history.clusters.append(n_clusters)
        history.best_scores.append(hypotheses[0][0] + constant)
        history.m_scores.append(tuple(v + constant for v, _ in hypotheses))
        run.selected = hypotheses[0][1]
        return hypotheses

    def _decide(self, run: _RunState, k: int) -> None:
        """N-scan pruning after scan ``k``, then the end of tentative trees (nothing
        decided, not selected) whose every leaf has terminated or that are past the age
        limit."""
        decided = k - self.n_scan
        if decided >= 0:
            run.trees = self._fix_decisions(
                run.trees, run.selected, decided, run.fixed_owner, run.closed
            )
        oldest = -1 if self.tentative_scans is None else k - self.tentative_scans
        run.trees = [
            t for t in run.trees
            if t.tree_id in run.selected
            or (t.root_scan > oldest and not all(lf.terminated for lf in t.leaves))
        ]  # fmt: skip

    def _confirmed(self, final: list[_Track]) -> dict[int, dict[int, int]]:
        """Tree id -> {scan index: detection} of the tracks whose score reached the
        confirmation threshold somewhere on their path, by tree id."""
        threshold = self.management.confirmation_threshold
        associations: dict[int, dict[int, int]] = {}
        for track in sorted(final, key=lambda t: t.tree_id):
            detections = {track.root_scan + i: j for i, j in enumerate(track.path) if j >= 0}
            if track.max_score >= threshold and detections:
                associations[track.tree_id] = detections
        return associations

    def _branch(self, leaves: list[_Leaf], scan: Scan) -> list[_Leaf]:
        """Every live leaf's miss and gated-detection children; terminated leaves as they are."""
        live = [leaf for leaf in leaves if not leaf.terminated]
        out = [leaf for leaf in leaves if leaf.terminated]
        if not live:
            return out
        predicted = [predict_track(self.config, leaf.filtered, scan.time) for leaf in live]
        log_ratio, _ = gated_log_ratios(self.config, predicted, scan)
        log_miss = miss_term(
            self.config.sensors[scan.sensor].detection_probability,
            self.config.estimator.pruning.gate_probability,
        )
        drop = self.termination_drop
        for leaf, track, row in zip(live, predicted, log_ratio, strict=True):
            score = leaf.score + log_miss
            out.append(
                _Leaf(leaf.path + (-1,), leaf.scores + (score,), track, leaf.max_score,
                      leaf.max_score - score > drop)
            )
            for j in np.flatnonzero(row > -math.inf).tolist():
                score = leaf.score + float(row[j])
                top = max(leaf.max_score, score)
                out.append(
                    _Leaf(leaf.path + (j,), leaf.scores + (score,),
                          update_track(self.config, track, scan, j), top, top - score > drop)
                )
        return out

    @staticmethod
    def _fix_decisions(
        trees: list[_Tree],
        selected: dict[int, _Leaf],
        decided: int,
        fixed_owner: dict[tuple[int, int], int],
        closed: list[_Track],
    ) -> list[_Tree]:
        """N-scan pruning at scan ``decided`` (module docstring); updates ``selected``,
        ``fixed_owner`` and ``closed`` in place and returns the trees still active."""
        survivors: list[_Tree] = []
        for tree in trees:
            leaf = selected.get(tree.tree_id)
            if leaf is None:
                if tree.committed:
                    # Nothing after its decided part: the track ended there.
                    closed.append(tree.decided_track())
                else:
                    survivors.append(tree)
                continue
            if tree.root_scan > decided:
                survivors.append(tree)
                continue
            upto = decided - tree.root_scan + 1
            prefix = leaf.path[:upto]
            tree.leaves = [lf for lf in tree.leaves if lf.path[:upto] == prefix]
            for i in range(len(tree.fixed_path), len(prefix)):
                if prefix[i] >= 0:
                    fixed_owner[(tree.root_scan + i, prefix[i])] = tree.tree_id
            tree.fixed_scan = decided
            tree.fixed_path = prefix
            tree.fixed_score = leaf.scores[len(prefix) - 1]
            tree.fixed_max = max(leaf.scores[: len(prefix)])
            if leaf.terminated and len(prefix) == len(leaf.path):
                closed.append(tree.decided_track())  # fully decided
                del selected[tree.tree_id]
                continue
            survivors.append(tree)
        # Tentative trees lose every leaf that uses a detection now decided for another tree.
        out: list[_Tree] = []
        for tree in survivors:
            if tree.tree_id not in selected and tree.root_scan <= decided:
                tree.leaves = [
                    lf for lf in tree.leaves
                    if all(
                        fixed_owner.get((tree.root_scan + i, j), tree.tree_id) == tree.tree_id
                        for i, j in enumerate(lf.path[: decided - tree.root_scan + 1])
                        if j >= 0
                    )
                ]
                if not tree.leaves:
                    continue
            out.append(tree)
        return out

    def _prune(self, leaves: list[_Leaf]) -> list[_Leaf]:
        """Score-ratio pruning against the tree's best leaf, then the ``max_leaves`` best."""
        if not leaves:
            return leaves
        best = max(leaf.score for leaf in leaves)
        kept = [leaf for leaf in leaves if leaf.score >= best - self.prune_log_ratio]
        if len(kept) > self.max_leaves:
            order = sorted(range(len(kept)), key=lambda i: -kept[i].score)[: self.max_leaves]
            kept = [kept[i] for i in sorted(order)]
        return kept

    def _global_hypotheses(
        self, trees: list[_Tree], offsets: IntArray
    ) -> tuple[list[tuple[float, dict[int, _Leaf]]], int]:
        """The M best global hypotheses (score, tree id -> selected leaf), best first, and
        the number of clusters solved by the integer-programming solver."""
        candidates = _candidates(trees, offsets, self.m_best)
        if candidates is None:
            return [(0.0, {})], 0
        problem, owners = candidates.problem, candidates.owner
        options: list[list[_ClusterOption]] = []
        solved = 0
        for cluster in cluster_hypotheses(problem):
            if np.all(owners[cluster] == owners[cluster[0]]):
                options.append(_one_tree_options(problem, cluster, self.m_best))
                continue
            solved += 1
            options.append(_program_options(problem, cluster, self.m_best, self._solver))
        return _merged_hypotheses(options, candidates, trees, self.m_best), solved
