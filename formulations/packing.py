"""The window's track-set choice as a set-packing problem, and its integer program.

A :class:`PackingProblem` is solver- and domain-neutral: hypotheses with scores, the
*resources* each one uses (detections, and for a carried track its track tree), which
resources must be used exactly once (carried tracks: a carried track continues,
misses or ends, but never vanishes) and which hypotheses count toward K.

For a given K the integer program is (Morefield 1977 set packing, plus the
cardinality row of Perry's MAP formulation, eq. 14)::

    maximise    sum_h score_h x_h
    subject to  sum_{h uses r} x_h <= 1      every detection r
                sum_{h uses g} x_h == 1      every carried track g
                sum_{h counts} x_h == K
                x binary
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from mapassoc.formulations.program import Program

__all__ = [
    "PackingProblem",
    "gather_rows",
    "MergedProblem",
    "merge_interchangeable",
    "set_packing_program",
    "resource_multipliers",
    "decode_selection",
]


def gather_rows(
    indptr: NDArray[np.int64],
    indices: NDArray[np.int64],
    rows: NDArray[np.int64],
    extra: NDArray[np.int64] | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Rows of a CSR list of resources, each followed by one more resource if asked.

    Parameters
    ----------
    indptr : ndarray of int, shape (n + 1,)
    indices : ndarray of int, shape (indptr[-1],)
        Row ``r`` lists ``indices[indptr[r]:indptr[r + 1]]``.
    rows : ndarray of int, shape (m,)
        The rows to take, in order (repeats allowed).
    extra : ndarray of int, shape (m,), optional
        A resource appended to each taken row; ``-1`` appends none.

    Returns
    -------
    indptr, indices : ndarray of int, shapes (m + 1,) and (total,)
        The taken rows as a CSR list.
    """
    rows = np.asarray(rows, dtype=np.int64)
    starts = indptr[rows]
    lengths = indptr[rows + 1] - starts
    added = np.zeros(rows.size, dtype=np.int64) if extra is None else (extra >= 0).astype(np.int64)
    out_ptr = np.concatenate([[0], np.cumsum(lengths + added)]).astype(np.int64)
    out = np.empty(int(out_ptr[-1]), dtype=np.int64)
    owner = np.repeat(np.arange(rows.size), lengths)
    within = np.arange(owner.size) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    out[out_ptr[owner] + within] = indices[starts[owner] + within]
    if extra is not None:
        has = np.flatnonzero(added)
        out[out_ptr[has] + lengths[has]] = extra[has]
    return out_ptr, out


@dataclass(frozen=True, eq=False)
class PackingProblem:
    """Hypotheses competing for resources.

    Parameters
    ----------
    scores : ndarray, shape (H,)
        Log-score of each hypothesis (to maximise).
    resource_indptr : ndarray of int, shape (H + 1,)
    resource_indices : ndarray of int, shape (nnz,)
        Resources used by hypothesis h: ``resource_indices[indptr[h]:indptr[h+1]]``.
    exactly_one : ndarray of bool, shape (R,)
        Resources that must be used exactly once; the others at most once.
    counts : ndarray of bool, shape (H,)
        Whether each hypothesis counts toward K.
    log_weights : ndarray, shape (H,), optional
        Log-weight of each hypothesis in the *sums* over sets (log-mass); defaults to
        ``scores``.  They differ after :func:`merge_interchangeable`, where one
        hypothesis stands for several with the same resources: its score is their best
        score and its log-weight the log-sum-exp of theirs.
    """

    scores: NDArray[np.float64]
    resource_indptr: NDArray[np.int64]
    resource_indices: NDArray[np.int64]
    exactly_one: NDArray[np.bool_]
    counts: NDArray[np.bool_]
    log_weights: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        scores = np.asarray(self.scores, dtype=float)
        H = scores.shape[0]
        indptr = np.asarray(self.resource_indptr, dtype=np.int64)
        indices = np.asarray(self.resource_indices, dtype=np.int64)
        exactly_one = np.asarray(self.exactly_one, dtype=bool)
        counts = np.asarray(self.counts, dtype=bool)
        if scores.ndim != 1 or not np.all(np.isfinite(scores)):
            raise ValueError("scores must be a finite 1-D array")
        if indptr.shape != (H + 1,) or indptr[0] != 0 or np.any(np.diff(indptr) < 0):
            raise ValueError(f"resource_indptr must be a CSR pointer of length {H + 1}")
        if indices.shape != (indptr[-1],):
            raise ValueError("resource_indices must have resource_indptr[-1] entries")
        R = exactly_one.shape[0]
        if indices.size and (indices.min() < 0 or indices.max() >= R):
            raise ValueError(f"resource indices must lie in 0..{R - 1}")
        if counts.shape != (H,):
            raise ValueError(f"counts must have shape ({H},)")
        log_weights = scores if self.log_weights is None else np.asarray(self.log_weights, float)
        if log_weights.shape != (H,) or not np.all(np.isfinite(log_weights)):
            raise ValueError(f"log_weights must be finite with shape ({H},)")
        owner = np.repeat(np.arange(H), np.diff(indptr))
        order = np.lexsort((indices, owner))
        repeated = (owner[order][1:] == owner[order][:-1]) & (
            indices[order][1:] == indices[order][:-1]
        )
        if np.any(repeated):
            h = int(owner[order][1:][repeated][0])
            raise ValueError(f"hypothesis {h} lists a resource twice")
        object.__setattr__(self, "scores", scores)
        object.__setattr__(self, "resource_indptr", indptr)
        object.__setattr__(self, "resource_indices", indices)
        object.__setattr__(self, "exactly_one", exactly_one)
        object.__setattr__(self, "counts", counts)
        object.__setattr__(self, "log_weights", log_weights)

    @classmethod
    def derived(
        cls,
        *,
        scores: NDArray[np.float64],
        resource_indptr: NDArray[np.int64],
        resource_indices: NDArray[np.int64],
        exactly_one: NDArray[np.bool_],
        counts: NDArray[np.bool_],
        log_weights: NDArray[np.float64],
    ) -> PackingProblem:
        """A problem built from a checked one's arrays, without checking them again.

        For transformations of a constructed problem (restrictions, merges, relabelled
        counts, charged scores) whose output satisfies the constructor's checks by
        construction: the arrays must already have their dtypes and shapes, the log-weights
        must be given, and each hypothesis must list a resource at most once.  The
        constructor's checks cost more than most of the searches run on small clusters
        (a sort of every resource entry), so the solvers' inner loops go through here.
        """
        problem = object.__new__(cls)
        for name, value in (
            ("scores", scores),
            ("resource_indptr", resource_indptr),
            ("resource_indices", resource_indices),
            ("exactly_one", exactly_one),
            ("counts", counts),
            ("log_weights", log_weights),
        ):
            object.__setattr__(problem, name, value)
        return problem

    @property
    def weights(self) -> NDArray[np.float64]:
        """The log-weights as construction filled them in: ``log_weights``, or ``scores``
        where none were given (never None), shape (H,)."""
        return cast("NDArray[np.float64]", self.log_weights)  # set by __post_init__

    @property
    def num_hypotheses(self) -> int:
        return int(self.scores.shape[0])

    @property
    def num_resources(self) -> int:
        return int(self.exactly_one.shape[0])

    def resources_of(self, h: int) -> NDArray[np.int64]:
        return self.resource_indices[self.resource_indptr[h] : self.resource_indptr[h + 1]]

    def uses_any(self, resources: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Whether each hypothesis uses at least one of the marked resources, shape (H,).

        Parameters
        ----------
        resources : ndarray of bool, shape (R,)
        """
        marked = np.asarray(resources, dtype=bool)
        if marked.shape != (self.num_resources,):
            raise ValueError(
                f"resources must be a bool mask of shape ({self.num_resources},), "
                f"got shape {marked.shape}"
            )
        owner = np.repeat(np.arange(self.num_hypotheses), np.diff(self.resource_indptr))
        out = np.zeros(self.num_hypotheses, dtype=bool)
        out[owner[marked[self.resource_indices]]] = True
        return out

    def incidence(self) -> sp.csr_array:
        """Resource-by-hypothesis 0/1 matrix, shape (R, H)."""
        H = self.num_hypotheses
        rows = self.resource_indices
        cols = np.repeat(np.arange(H), np.diff(self.resource_indptr))
        data = np.ones(len(rows))
        return sp.csr_array((data, (rows, cols)), shape=(self.num_resources, H))

    def subproblem(self, hypotheses: NDArray[np.int64]) -> PackingProblem:
        """The problem restricted to ``hypotheses`` (resources renumbered compactly)."""
        hyp = np.asarray(hypotheses, dtype=np.int64)
        starts = self.resource_indptr[hyp]
        lengths = self.resource_indptr[hyp + 1] - starts
        indptr = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
        # Positions of the chosen hypotheses' entries, in order.
        entry = np.repeat(starts - indptr[:-1], lengths) + np.arange(indptr[-1])
        resources = self.resource_indices[entry]
        used = np.unique(resources)
        # Renumbered by rank among the used ones (no array over every resource: a
        # window's many small clusters would each cost the whole window's resources).
        return PackingProblem.derived(
            scores=self.scores[hyp],
            resource_indptr=indptr,
            resource_indices=np.searchsorted(used, resources).astype(np.int64),
            exactly_one=self.exactly_one[used],
            counts=self.counts[hyp],
            log_weights=self.weights[hyp],
        )

    def is_feasible(self, selection: NDArray[np.int64], k: int | None = None) -> bool:
        """Whether the selected hypotheses respect every resource (and count k)."""
        sel = np.asarray(selection, dtype=np.int64)
        use = np.zeros(self.num_resources, dtype=np.int64)
        for h in sel:
            use[self.resources_of(int(h))] += 1
        if np.any(use > 1) or np.any(use[self.exactly_one] != 1):
            return False
        return k is None or int(np.count_nonzero(self.counts[sel])) == k

    def value(self, selection: NDArray[np.int64]) -> float:
        return float(np.sum(self.scores[np.asarray(selection, dtype=np.int64)]))


@dataclass(frozen=True, eq=False)
class MergedProblem:
    """A packing problem with interchangeable hypotheses merged.

    Attributes
    ----------
    problem : PackingProblem
        One hypothesis per class of interchangeable originals.
    representative : ndarray of int, shape (H',)
        For each merged hypothesis, the original with the best score (ties: the
        smallest index).
    members : tuple of ndarray of int
        The originals each merged hypothesis stands for.
    """

    problem: PackingProblem
    representative: NDArray[np.int64]
    members: tuple[NDArray[np.int64], ...]


def merge_interchangeable(problem: PackingProblem) -> MergedProblem:
    """Merge hypotheses that use the same resources and count the same toward K.

    Such hypotheses are interchangeable in every feasible set (they conflict with each
    other and with exactly the same others), so one hypothesis with the best score
    (for the maximum) and the log-sum-exp of the log-weights (for the sums over sets)
    gives the same per-k best scores and the same per-k log-masses.  Exact.
    """
    H = problem.num_hypotheses
    if H == 0:
        return MergedProblem(problem, np.zeros(0, dtype=np.int64), ())
    lengths = np.diff(problem.resource_indptr)
    owner = np.repeat(np.arange(H), lengths)
    # Each hypothesis' resources sorted, as a row padded with -1: equal rows (with equal
    # counts) are interchangeable hypotheses.
    order = np.lexsort((problem.resource_indices, owner))
    rank = np.arange(order.size) - np.repeat(problem.resource_indptr[:-1], lengths)
    keys = np.full((H, int(lengths.max()) + 1), -1, dtype=np.int64)
    keys[:, 0] = problem.counts
    keys[owner[order], 1 + rank] = problem.resource_indices[order]
    # Sort the rows (ties by index), label runs of equal rows, and number the classes
    # in order of their first member.
    rows = np.lexsort((np.arange(H), *keys.T[::-1]))
    sorted_keys = keys[rows]
    new_class = np.r_[True, np.any(sorted_keys[1:] != sorted_keys[:-1], axis=1)]
    label = np.empty(H, dtype=np.int64)
    label[rows] = np.cumsum(new_class) - 1
    first = rows[new_class]  # the smallest member of each class (ties sorted by index)
    class_of = np.argsort(np.argsort(first))[label]
    scores = problem.scores
    weights = problem.weights
    # Within a class: best score first (ties: smallest index) for the representative.
    by_class = np.lexsort((np.arange(H), -scores, class_of))
    starts = np.flatnonzero(np.r_[True, np.diff(class_of[by_class]) != 0])
    reps = by_class[starts].astype(np.int64)
    merged_weights = np.logaddexp.reduceat(weights[by_class], starts)
    grouped = np.argsort(class_of, kind="stable")  # members by class, ascending index
    members = tuple(
        np.asarray(m, dtype=np.int64)
        for m in np.split(grouped, np.flatnonzero(np.diff(class_of[grouped]) != 0) + 1)
    )
    rep_lengths = lengths[reps]
    indptr = np.concatenate([[0], np.cumsum(rep_lengths)]).astype(np.int64)
    entry = np.repeat(problem.resource_indptr[reps] - indptr[:-1], rep_lengths)
    indices = problem.resource_indices[entry + np.arange(indptr[-1])]
    merged = PackingProblem.derived(
        scores=scores[reps],
        resource_indptr=indptr,
        resource_indices=indices.astype(np.int64),
        exactly_one=problem.exactly_one,
        counts=problem.counts[reps],
        log_weights=merged_weights.astype(np.float64),
    )
    return MergedProblem(merged, reps, members)


def set_packing_program(problem: PackingProblem, k: int | None) -> Program:
    """The binary program choosing the best feasible hypothesis set with exactly ``k`` counted.

    Parameters
    ----------
    problem : PackingProblem
    k : int or None
        Required number of counted hypotheses (tracks); ``None`` leaves K free (no
        cardinality row).

    Returns
    -------
    Program
        Maximisation of the total score; decode with :func:`decode_selection`.
    """
    if k is not None and k < 0:
        raise ValueError(f"k must be >= 0, got {k}")
    A = problem.incidence()
    used = np.asarray(A.sum(axis=1)).ravel() > 0
    at_most = np.flatnonzero(used & ~problem.exactly_one)
    exactly = np.flatnonzero(problem.exactly_one)
    H = problem.num_hypotheses
    if k is None:
        A_eq = A[exactly]
        b_eq = np.ones(len(exactly))
    else:
        card = sp.csr_array(problem.counts.astype(float)[None, :])
        A_eq = sp.vstack([A[exactly], card], format="csr")
        b_eq = np.concatenate([np.ones(len(exactly)), [float(k)]])
    return Program(
        objective=problem.scores,
        A_ub=A[at_most],
        b_ub=np.ones(len(at_most)),
        A_eq=A_eq,
        b_eq=b_eq,
        lower=np.zeros(H),
        upper=np.ones(H),
        integrality=np.ones(H, dtype=bool),
    )


def resource_multipliers(
    problem: PackingProblem, ineq_duals: NDArray[np.float64], eq_duals: NDArray[np.float64]
) -> tuple[NDArray[np.float64], float]:
    """The duals of :func:`set_packing_program`'s rows as one multiplier per resource and
    one for the cardinality row.

    The program's rows are the at-most-once resources in use (``A_ub``), then the
    exactly-once resources and the cardinality row, if any (``A_eq``); unused resources
    get 0, and so does the cardinality row when K is free.

    Parameters
    ----------
    problem : PackingProblem
    ineq_duals, eq_duals : ndarray
        The duals of the program's ``A_ub`` and ``A_eq`` rows.

    Returns
    -------
    multipliers : ndarray, shape (R,)
    count_multiplier : float
    """
    usage = np.bincount(problem.resource_indices, minlength=problem.num_resources)
    at_most = np.flatnonzero((usage > 0) & ~problem.exactly_one)
    exactly = np.flatnonzero(problem.exactly_one)
    y = np.zeros(problem.num_resources)
    y[at_most] = ineq_duals
    eq = np.asarray(eq_duals)
    y[exactly] = eq[: exactly.size]
    return y, float(eq[exactly.size]) if eq.size > exactly.size else 0.0


def decode_selection(x: NDArray[np.float64]) -> NDArray[np.int64]:
    """Indices of the selected hypotheses of a (near-)binary solution vector."""
    x = np.asarray(x, dtype=float)
    return np.flatnonzero(x > 0.5).astype(np.int64)
