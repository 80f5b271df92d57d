"""T-GOSPA: the trajectory GOSPA metric with a switching cost, and track fragmentation.

Implements the metric of García-Fernández, Rahmathullah and Svensson, "A metric on the space
of finite sets of trajectories for evaluation of multi-target tracking algorithms", IEEE
Trans. Signal Processing 68 (2020) 3917-3928 (arXiv:1605.01177), for ``alpha = 2``.

Definition (the assignment form of the paper, its Definition 1 and Proposition 2)
----------------------------------------------------------------------------------
True trajectories ``X = {x_1..x_nx}`` and estimated trajectories ``Y = {y_1..y_ny}`` live on
the evaluation times ``t = 1..T``; a trajectory may be absent at some of them (born late,
dead early, or with holes).  An *assignment sequence* is one partial assignment ``pi^t`` per
time: ``pi^t(i) in {0, 1..ny}`` for every true trajectory ``i`` (0 = unassigned), no estimate
used twice at one time.  An assignment is a pairing of trajectories *indices*; it exists at
every time, also where one or both trajectories of the pair are absent.  Then::

    d(X, Y) = min over pi^1..pi^T of (  sum_t sum_i  d_t(i, pi^t(i))
                                      + gamma^p * sum_{t=1}^{T-1} s(pi^t, pi^{t+1})  )^(1/p)

with the per-time cost of true trajectory ``i`` (and alike of an unassigned estimate)::

    d_t(i, j) = min(||x_i(t) - y_j(t)||, c)^p   both present at t
              = c^p / 2                          exactly one of them present
              = 0                                neither present

(an unassigned present trajectory, either side, costs ``c^p / 2``), and the switching cost::

    s(pi, pi') = sum_i s_i,   s_i = 0     if pi(i) == pi'(i)
                              s_i = 1     if pi(i) != pi'(i) and both are non-zero
                              s_i = 1/2   otherwise (one of them is 0: an assignment begins
                                          or ends)

So a true trajectory whose estimate changes from ``j`` to ``k`` costs ``gamma^p`` (a *full
switch*); one that goes from assigned to unassigned, or the reverse, costs ``gamma^p / 2``.
This is the convention of the paper (eq. (5)-(6)) and of the authors' published code
(``Agarciafernandez/T-GOSPA-metric-python``), which writes the same thing as
``gamma^p / 2 * sum_{i, j} |W_ij(t+1) - W_ij(t)|`` over the binary assignment matrices
``W(t)`` of real indices: a change ``j -> k`` flips two entries, a start or an end one.

Because assignments persist through absences, a target that disappears for a few scans and
is picked up again by the *same* estimate pays nothing for the gap beyond ``c^p/2`` per
missed step; an assignment is never forced to break where a trajectory is absent.  A pair
assigned at distance ``>= c`` costs ``c^p``, exactly what a missed target plus a false estimate
costs, and is reported as one missed and one false in the decomposition (as GOSPA does).

Computation
-----------
The minimum is an integer linear program in the binary ``W_ij(t)`` (with dummy row and column
for "unassigned") and continuous ``h_ij(t) >= |W_ij(t+1) - W_ij(t)|``.  It is solved exactly by
:func:`scipy.optimize.milp` (HiGHS, ``mip_rel_gap = 0``), or relaxed to the paper's LP metric
(``method="lp"``, :func:`scipy.optimize.linprog`, ``0 <= W <= 1``), which is a lower bound and
itself a metric (Proposition 3 of the paper).

Three exact reductions keep the programs small, so a whole run is cheap:

* a pair ``(i, j)`` that is never closer than ``c`` at a common time is never assigned: setting
  its ``W_ij`` to 0 at every time leaves every per-time cost unchanged and can only remove
  switches.  The program then splits into the connected components of the bipartite graph of
  the remaining pairs, each solved on its own (a component without pairs is all missed or all
  false and needs no solver);
* within a component only the times at which one of its trajectories is present matter: at
  the other times every cost is 0 and holding the assignment costs nothing;
* for ``milp``, a component with at most 64 matchings of its pairs (most: one target and the
  one or two tracks near it) is solved by dynamic programming over the matchings (Viterbi:
  state = matching, step cost = ``gamma^p / 2`` times the number of pairs that change), which
  is the same minimum without the solver's set-up cost; larger components go to HiGHS.

The evaluation times are those of :func:`mapassoc.evaluation.metrics.gospa_over_time`: the
sorted union of the truth and estimate times, matched exactly.  A trajectory is the rows of one
id; ids are what make trajectories, so a track id reused for two objects is one trajectory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sps
from numpy.typing import NDArray
from scipy.optimize import Bounds, LinearConstraint, linprog, milp
from scipy.sparse.csgraph import connected_components

from mapassoc.errors import InputError
from mapassoc.evaluation.points import (
    TimedPoints,
    check_cost_powers,
    check_order,
    check_runs,
    readonly,
)
from mapassoc.validation import check_positive

__all__ = [
    "TgospaResult",
    "TrackFragmentation",
    "METHODS",
    "tgospa",
    "track_fragmentation",
    "fragmentation_of",
]

METHODS = ("milp", "lp")
"""``milp``: the exact metric; ``lp``: the paper's LP relaxation (a lower bound, a metric)."""

_INTEGRAL_TOLERANCE = 1e-6
_MAX_DP_STATES = 64
"""Components with at most this many matchings are solved exactly by dynamic programming
(``milp`` only); larger ones by the integer program."""


@dataclass(frozen=True, eq=False)
class TgospaResult:
    """T-GOSPA between true and estimated trajectories, with its decomposition.

    Parameters
    ----------
    total : float
        ``(localisation + missed + false + switching)^(1/p)``.
    localisation, missed, false, switching : float
        The four p-th power parts: sum of ``d^p`` over assigned pairs closer than ``c``;
        ``c^p/2`` per missed target-time; ``c^p/2`` per false estimate-time; ``gamma^p`` per
        switch (``gamma^p / 2`` per half switch).
    num_missed, num_false : float
        Missed target-times and false estimate-times (integers for ``milp``; weighted, possibly
        fractional, for ``lp``).
    num_switches : float
        ``sum_t s(pi^t, pi^{t+1})``: full switches count 1, starts and ends of an assignment
        1/2 (see the module docstring).
    times : ndarray, shape (T,)
        Evaluation times.
    localisation_per_time, missed_per_time, false_per_time : ndarray, shape (T,)
        The three per-time parts (p-th powers).
    switching_per_step : ndarray, shape (T - 1,)
        Switching cost between ``times[k]`` and ``times[k + 1]``.
    truth_ids, estimate_ids : ndarray of int
        Ids of the true and the estimated trajectories, sorted; indices below refer to them.
    assignment : ndarray of int, shape (T, nx)
        Index into ``estimate_ids`` of the estimate true trajectory ``i`` is assigned to at each
        time where both are present and closer than ``c``, else -1 (for ``lp``: the estimate of
        weight > 1/2, if any).
    c, p, gamma : float
        Cut-off, order and switching cost used.
    method : str
        ``"milp"`` (exact) or ``"lp"`` (lower bound).
    status : str
        ``"optimal"`` when every program was solved to optimality (the only value returned;
        a solver failure raises).
    num_components : int
        Independent programs the problem split into.
    largest_component : int
        Trajectories (true + estimated) in the largest of them.
    """

    total: float
    localisation: float
    missed: float
    false: float
    switching: float
    num_missed: float
    num_false: float
    num_switches: float
    times: NDArray[np.float64]
    localisation_per_time: NDArray[np.float64]
    missed_per_time: NDArray[np.float64]
    false_per_time: NDArray[np.float64]
    switching_per_step: NDArray[np.float64]
    truth_ids: NDArray[np.int64]
    estimate_ids: NDArray[np.int64]
    assignment: NDArray[np.int64]
    c: float
    p: float
    gamma: float
    method: str
    status: str
    num_components: int
    largest_component: int

    @property
    def num_times(self) -> int:
        """Number of evaluation times T."""
        return int(self.times.shape[0])

    def summary(self) -> dict[str, float | int | str]:
        """The scalars as a JSON-ready dictionary of plain numbers and strings."""
        return {
            "c": float(self.c),
            "p": float(self.p),
            "gamma": float(self.gamma),
            "alpha": 2.0,
            "method": self.method,
            "status": self.status,
            "num_times": self.num_times,
            "total": float(self.total),
            "localisation": float(self.localisation),
            "missed": float(self.missed),
            "false": float(self.false),
            "switching": float(self.switching),
            "num_missed": float(self.num_missed),
            "num_false": float(self.num_false),
            "num_switches": float(self.num_switches),
        }


@dataclass(frozen=True, eq=False)
class TrackFragmentation:
    """How many estimated tracks cover each true target, from the T-GOSPA assignment.

    Parameters
    ----------
    truth_ids : ndarray of int, shape (nx,)
        True trajectories.
    fragments : ndarray of int, shape (nx,)
        Distinct estimate ids assigned (present, closer than ``c``) to each at some time.
    id_switches : ndarray of int, shape (nx,)
        Changes of the assigned estimate id between consecutive evaluation times at which the
        target is assigned both times.
    """

    truth_ids: NDArray[np.int64]
    fragments: NDArray[np.int64]
    id_switches: NDArray[np.int64]

    @property
    def num_tracked_targets(self) -> int:
        """True targets assigned to an estimate at least once."""
        return int(np.count_nonzero(self.fragments))

    @property
    def fragments_per_target(self) -> float:
        """Mean fragments over the targets tracked at least once (1.0 is ideal); ``nan`` when
        no target was ever tracked (never-tracked targets are in T-GOSPA's missed part)."""
        tracked = self.fragments[self.fragments > 0]
        return float(np.mean(tracked)) if tracked.size else math.nan

    @property
    def num_id_switches(self) -> int:
        """Identity switches summed over targets."""
        return int(np.sum(self.id_switches))

    def summary(self) -> dict[str, float | int | None]:
        """JSON-ready: ``fragments_per_target`` is ``None`` when no target was tracked."""
        value = self.fragments_per_target
        return {
            "num_targets": int(self.truth_ids.shape[0]),
            "num_tracked_targets": self.num_tracked_targets,
            "fragments_per_target": None if math.isnan(value) else value,
            "id_switches": self.num_id_switches,
        }


# ----------------------------------------------------------------------------------------------
# Inputs as arrays over the evaluation times
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Trajectories:
    ids: NDArray[np.int64]  # (n,)
    present: NDArray[np.bool_]  # (T, n)
    rows_time: NDArray[np.int64]  # (N,) time index of each row
    rows_index: NDArray[np.int64]  # (N,) trajectory index of each row
    positions: NDArray[np.float64]  # (N, d)


def _trajectories(run: TimedPoints, times: NDArray[np.float64]) -> _Trajectories:
    ids, index = np.unique(run.ids, return_inverse=True)
    time_index = np.searchsorted(times, run.times)
    present = np.zeros((times.shape[0], ids.shape[0]), dtype=bool)
    present[time_index, index] = True
    return _Trajectories(
        ids=ids.astype(np.int64),
        present=present,
        rows_time=time_index.astype(np.int64),
        rows_index=index.astype(np.int64),
        positions=run.positions,
    )


@dataclass(frozen=True, eq=False)
class _ClosePairs:
    """Every truth/estimate pair present together closer than c, once per such time.

    Attributes
    ----------
    time, i, j : ndarray of int, shape (N,)
        Time index, truth index and estimate index of each.
    distance : ndarray, shape (N,)
    """

    time: NDArray[np.int64]
    i: NDArray[np.int64]
    j: NDArray[np.int64]
    distance: NDArray[np.float64]


def _close_pairs(
    truth: _Trajectories, estimates: _Trajectories, num_times: int, c: float
) -> _ClosePairs:
    """(time, i, j, distance) of every truth/estimate pair present together closer than c."""
    out_t, out_i, out_j, out_d = [], [], [], []
    truth_order = np.argsort(truth.rows_time, kind="stable")
    est_order = np.argsort(estimates.rows_time, kind="stable")
    truth_bounds = np.searchsorted(truth.rows_time[truth_order], np.arange(num_times + 1))
    est_bounds = np.searchsorted(estimates.rows_time[est_order], np.arange(num_times + 1))
    for t in range(num_times):
        rows_x = truth_order[truth_bounds[t] : truth_bounds[t + 1]]
        rows_y = est_order[est_bounds[t] : est_bounds[t + 1]]
        if rows_x.size == 0 or rows_y.size == 0:
            continue
        diff = truth.positions[rows_x][:, None, :] - estimates.positions[rows_y][None, :, :]
        distance = np.linalg.norm(diff, axis=-1)
        a, b = np.nonzero(distance < c)
        if a.size:
            out_t.append(np.full(a.size, t, dtype=np.int64))
            out_i.append(truth.rows_index[rows_x[a]])
            out_j.append(estimates.rows_index[rows_y[b]])
            out_d.append(distance[a, b])
    if not out_t:
        empty = np.zeros(0, dtype=np.int64)
        return _ClosePairs(empty, empty, empty, np.zeros(0))
    return _ClosePairs(
        np.concatenate(out_t),
        np.concatenate(out_i),
        np.concatenate(out_j),
        np.concatenate(out_d),
    )


# ----------------------------------------------------------------------------------------------
# One component: the program and its solution
# ----------------------------------------------------------------------------------------------


def _edge_costs(
    present_x: NDArray[np.bool_],
    present_y: NDArray[np.bool_],
    edges: NDArray[np.int64],
    edge_distance: NDArray[np.float64],
    c: float,
    p: float,
) -> NDArray[np.float64]:
    """Per-time cost of each assigned pair, shape (Tc, nE): ``d_t(i, j)`` of the module."""
    both = present_x[:, edges[:, 0]] & present_y[:, edges[:, 1]]
    one = present_x[:, edges[:, 0]] ^ present_y[:, edges[:, 1]]
    return np.where(both, np.minimum(edge_distance, c) ** p, np.where(one, c**p / 2.0, 0.0))


def _matchings(edges: NDArray[np.int64], limit: int) -> NDArray[np.bool_] | None:
    """Every matching (edge subset without a shared row or column) as rows of an incidence
    matrix (S, nE), the empty one first; ``None`` when there are more than ``limit``."""
    found: list[list[int]] = []
    rows = edges[:, 0].tolist()
    cols = edges[:, 1].tolist()

    def extend(start: int, chosen: list[int], used_r: set[int], used_c: set[int]) -> bool:
        found.append(list(chosen))
        if len(found) > limit:
            return False
        for e in range(start, len(rows)):
            if rows[e] in used_r or cols[e] in used_c:
                continue
            chosen.append(e)
            used_r.add(rows[e])
            used_c.add(cols[e])
            ok = extend(e + 1, chosen, used_r, used_c)
            chosen.pop()
            used_r.discard(rows[e])
            used_c.discard(cols[e])
            if not ok:
                return False
        return True

    if not extend(0, [], set(), set()):
        return None
    incidence = np.zeros((len(found), len(rows)), dtype=bool)
    for k, chosen in enumerate(found):
        incidence[k, chosen] = True
    return incidence


def _viterbi_component(
    *,
    present_x: NDArray[np.bool_],
    present_y: NDArray[np.bool_],
    edges: NDArray[np.int64],
    edge_distance: NDArray[np.float64],
    incidence: NDArray[np.bool_],
    c: float,
    p: float,
    gamma: float,
) -> NDArray[np.float64]:
    """Exact minimum by dynamic programming over the component's matchings.

    A state is one matching ``M`` (an assignment of the component's indices restricted to
    its pairs); its cost at ``t`` is the pair costs of ``M`` plus ``c^p / 2`` per present
    index ``M`` leaves unassigned, and going from ``M`` to ``M'`` costs
    ``gamma^p / 2 * |M xor M'|``, the ``sum |W(t+1) - W(t)|`` of the integer program.
    """
    half = c**p / 2.0
    edge_cost = _edge_costs(present_x, present_y, edges, edge_distance, c, p)
    m = incidence.astype(float)  # (S, nE)
    covered_x = np.zeros((m.shape[0], present_x.shape[1]))
    covered_y = np.zeros((m.shape[0], present_y.shape[1]))
    np.add.at(covered_x.T, edges[:, 0], m.T)
    np.add.at(covered_y.T, edges[:, 1], m.T)
    state_cost = (
        edge_cost @ m.T
        + half * (present_x.astype(float) @ (1.0 - covered_x).T)
        + half * (present_y.astype(float) @ (1.0 - covered_y).T)
    )  # (Tc, S)
    transition = gamma**p / 2.0 * (m @ (1.0 - m).T + (1.0 - m) @ m.T)  # (S, S) Hamming
    num_times = state_cost.shape[0]
    back = np.zeros((num_times, m.shape[0]), dtype=np.int64)
    value = state_cost[0].copy()
    for t in range(1, num_times):
        through = value[:, None] + transition  # from (rows) -> to (columns)
        back[t] = np.argmin(through, axis=0)
        value = through[back[t], np.arange(m.shape[0])] + state_cost[t]
    states = np.zeros(num_times, dtype=np.int64)
    states[-1] = int(np.argmin(value))
    for t in range(num_times - 1, 0, -1):
        states[t - 1] = back[t, states[t]]
    return m[states]


@dataclass(frozen=True, eq=False)
class _ProgramLayout:
    """Where the variables of one component's program sit.

    Per time ``t`` the variables ``W(t)`` are ``[edges, row dummies, column dummies]``
    (``per_time`` of them, at ``t * per_time``); the ``num_h`` switching variables
    ``h_e(t)`` follow all ``num_w`` of them.
    """

    num_times: int
    nx: int
    ny: int
    num_edges: int

    @property
    def per_time(self) -> int:
        return self.num_edges + self.nx + self.ny

    @property
    def num_w(self) -> int:
        return self.num_times * self.per_time

    @property
    def num_h(self) -> int:
        return (self.num_times - 1) * self.num_edges


@dataclass(frozen=True, eq=False)
class _Program:
    """One component's program: minimise ``cost @ v`` subject to ``a_eq v = 1``,
    ``a_ub v <= 0``, ``0 <= W <= 1``, ``h >= 0``.

    Attributes
    ----------
    layout : _ProgramLayout
    cost : ndarray, shape (num_w + num_h,)
    a_eq : scipy.sparse.csr_matrix, shape (num_times * (nx + ny), num_w + num_h)
    a_ub : scipy.sparse.csr_matrix, shape (2 * num_h, num_w + num_h)
    """

    layout: _ProgramLayout
    cost: NDArray[np.float64]
    a_eq: sps.csr_matrix
    a_ub: sps.csr_matrix

    @property
    def upper(self) -> NDArray[np.float64]:
        """Upper bounds of the variables, shape (num_w + num_h,): 1 for W, none for h."""
        return np.concatenate([np.ones(self.layout.num_w), np.full(self.layout.num_h, np.inf)])


def _program_cost(
    layout: _ProgramLayout,
    edge_cost: NDArray[np.float64],
    present_x: NDArray[np.bool_],
    present_y: NDArray[np.bool_],
    half: float,
    switch_cost: float,
) -> NDArray[np.float64]:
    """Costs of ``W(t) = [edges, row dummies, column dummies]`` and of h.

    Parameters
    ----------
    edge_cost : ndarray, shape (Tc, nE)
    present_x, present_y : ndarray of bool, shape (Tc, nx) and (Tc, ny)

    Returns
    -------
    ndarray, shape (num_w + num_h,)
    """
    return np.concatenate(
        [
            np.hstack([edge_cost, half * present_x, half * present_y]).ravel(),
            np.full(layout.num_h, switch_cost / 2.0),
        ]
    )


def _assignment_equalities(layout: _ProgramLayout, edges: NDArray[np.int64]) -> sps.csr_matrix:
    """Every true (row) and every estimated (column) index assigned once per time.

    Parameters
    ----------
    edges : ndarray of int, shape (nE, 2)

    Returns
    -------
    scipy.sparse.csr_matrix, shape (Tc * (nx + ny), num_w + num_h)
    """
    nx, ny, per_time = layout.nx, layout.ny, layout.per_time
    t_of = np.repeat(np.arange(layout.num_times), per_time)
    local = np.tile(np.arange(per_time), layout.num_times)
    rows_of_local = np.concatenate([edges[:, 0], np.arange(nx), np.full(ny, -1)])
    cols_of_local = np.concatenate([edges[:, 1], np.full(nx, -1), np.arange(ny)])
    var = np.arange(layout.num_w)
    r = rows_of_local[local]
    k = cols_of_local[local]
    has_r = r >= 0
    has_k = k >= 0
    eq_row = np.concatenate(
        [t_of[has_r] * (nx + ny) + r[has_r], t_of[has_k] * (nx + ny) + nx + k[has_k]]
    )
    eq_col = np.concatenate([var[has_r], var[has_k]])
    return sps.csr_matrix(
        (np.ones(eq_row.size), (eq_row, eq_col)),
        shape=(layout.num_times * (nx + ny), layout.num_w + layout.num_h),
    )


def _switch_inequalities(layout: _ProgramLayout) -> sps.csr_matrix:
    """``+-(W_e(t+1) - W_e(t)) - h_e(t) <= 0``, shape (2 * num_h, num_w + num_h)."""
    num_w, num_h, num_edges = layout.num_w, layout.num_h, layout.num_edges
    step = np.repeat(np.arange(layout.num_times - 1), num_edges)
    edge = np.tile(np.arange(num_edges), layout.num_times - 1)
    w_now = step * layout.per_time + edge
    w_next = w_now + layout.per_time
    h_var = num_w + np.arange(num_h)
    base = np.arange(num_h)
    ub_row = np.concatenate([base, base, base, num_h + base, num_h + base, num_h + base])
    ub_col = np.concatenate([w_next, w_now, h_var, w_now, w_next, h_var])
    ub_val = np.concatenate([np.ones(num_h), -np.ones(num_h), -np.ones(num_h)] * 2)
    return sps.csr_matrix((ub_val, (ub_row, ub_col)), shape=(2 * num_h, num_w + num_h))


def _component_program(
    present_x: NDArray[np.bool_],
    present_y: NDArray[np.bool_],
    edges: NDArray[np.int64],
    edge_distance: NDArray[np.float64],
    c: float,
    p: float,
    gamma: float,
) -> _Program:
    """The integer program of one component (arguments as :func:`_solve_component`'s)."""
    layout = _ProgramLayout(
        num_times=present_x.shape[0],
        nx=present_x.shape[1],
        ny=present_y.shape[1],
        num_edges=edges.shape[0],
    )
    edge_cost = _edge_costs(present_x, present_y, edges, edge_distance, c, p)
    return _Program(
        layout=layout,
        cost=_program_cost(layout, edge_cost, present_x, present_y, c**p / 2.0, gamma**p),
        a_eq=_assignment_equalities(layout, edges),
        a_ub=_switch_inequalities(layout),
    )


def _solve_integer(program: _Program) -> tuple[NDArray[np.float64], float]:
    """The exact optimum by HiGHS: the W part of the solution, shape (num_w,), and its
    value."""
    num_w, num_h = program.layout.num_w, program.layout.num_h
    integrality = np.concatenate([np.ones(num_w), np.zeros(num_h)])
    constraints = [LinearConstraint(program.a_eq, 1.0, 1.0)]
    if num_h:
        constraints.append(LinearConstraint(program.a_ub, -np.inf, 0.0))
    res = milp(
        program.cost,
        integrality=integrality,
        bounds=Bounds(np.zeros(num_w + num_h), program.upper),
        constraints=constraints,
        options={"mip_rel_gap": 0.0},
    )
    if res.status != 0 or res.x is None:
        raise InputError(f"the T-GOSPA integer program was not solved: {res.message}")
    weights = np.round(res.x[:num_w])
    if np.max(np.abs(weights - res.x[:num_w])) > _INTEGRAL_TOLERANCE:
        raise InputError("the T-GOSPA integer program returned a non-integral assignment")
    return weights, float(res.fun)


def _solve_relaxed(program: _Program) -> tuple[NDArray[np.float64], float]:
    """The LP relaxation's optimum by HiGHS: the W part, shape (num_w,), and its value."""
    num_w, num_h = program.layout.num_w, program.layout.num_h
    res = linprog(
        program.cost,
        A_ub=program.a_ub if num_h else None,
        b_ub=np.zeros(2 * num_h) if num_h else None,
        A_eq=program.a_eq,
        b_eq=np.ones(program.a_eq.shape[0]),
        bounds=np.stack([np.zeros(num_w + num_h), program.upper], axis=1),
        method="highs",
    )
    if res.status != 0 or res.x is None:
        raise InputError(f"the T-GOSPA linear program was not solved: {res.message}")
    return res.x[:num_w], float(res.fun)


def _solve_component(
    *,
    present_x: NDArray[np.bool_],  # (Tc, nx) over the component's times
    present_y: NDArray[np.bool_],  # (Tc, ny)
    edges: NDArray[np.int64],  # (nE, 2) local (i, j)
    edge_distance: NDArray[np.float64],  # (Tc, nE) distance, inf where not closer than c
    c: float,
    p: float,
    gamma: float,
    method: str,
) -> tuple[NDArray[np.float64], float]:
    """Return the edge weights W_e(t), shape (Tc, nE), and the objective value."""
    program = _component_program(present_x, present_y, edges, edge_distance, c, p, gamma)
    solve = _solve_integer if method == "milp" else _solve_relaxed
    weights, value = solve(program)
    layout = program.layout
    w = weights.reshape(layout.num_times, layout.per_time)[:, : layout.num_edges]
    return w, value


# ----------------------------------------------------------------------------------------------
# The whole problem: its components, their weights, the parts they add up to
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Metric:
    """The metric's parameters, checked: cut-off, switching cost, order and method."""

    c: float
    gamma: float
    p: float
    method: str


@dataclass(frozen=True, eq=False)
class _Components:
    """Connected components of the bipartite graph of the close pairs.

    Attributes
    ----------
    pairs : ndarray of int, shape (P, 2)
        Distinct (truth index, estimate index) pairs ever closer than c, sorted.
    label : ndarray of int, shape (nx + ny,)
        Component of every truth index, then of every estimate index.
    pair_label : ndarray of int, shape (P,)
        Component of each pair.
    count : int
        Number of components (trajectories without a pair are components of their own).
    largest : int
        Trajectories in the largest component.
    nx, ny : int
        Number of true and of estimated trajectories.
    """

    pairs: NDArray[np.int64]
    label: NDArray[np.int64]
    pair_label: NDArray[np.int64]
    count: int
    largest: int
    nx: int
    ny: int


def _components(close: _ClosePairs, nx: int, ny: int) -> _Components:
    """Split the problem into the components of the graph of close pairs."""
    pairs = (
        np.unique(np.stack([close.i, close.j], axis=1), axis=0)
        if close.i.size
        else (np.zeros((0, 2), dtype=np.int64))
    )
    graph = sps.coo_matrix(
        (np.ones(pairs.shape[0]), (pairs[:, 0], nx + pairs[:, 1])), shape=(nx + ny, nx + ny)
    )
    num_components, label = connected_components(graph, directed=False)
    return _Components(
        pairs=pairs,
        label=label,
        pair_label=label[pairs[:, 0]] if pairs.shape[0] else np.zeros(0, dtype=np.int64),
        count=int(num_components),
        largest=int(np.max(np.bincount(label))) if label.size else 0,
        nx=nx,
        ny=ny,
    )


@dataclass(frozen=True, eq=False)
class _Component:
    """One component with at least one pair, over the Tc times where it has a trajectory.

    Attributes
    ----------
    xs, ys : ndarray of int, shape (nx_c,) and (ny_c,)
        Its truth and estimate indices (local index = position in these).
    edges : ndarray of int, shape (nE, 2)
        Its pairs as local (i, j).
    active : ndarray of int, shape (Tc,)
        The time indices at which one of its trajectories is present.
    edge_distance : ndarray, shape (Tc, nE)
        Distance of each pair, ``inf`` where it is not present together closer than c.
    """

    xs: NDArray[np.int64]
    ys: NDArray[np.int64]
    edges: NDArray[np.int64]
    active: NDArray[np.int64]
    edge_distance: NDArray[np.float64]


def _component(
    components: _Components, index: int, close: _ClosePairs, tx: _Trajectories, ty: _Trajectories
) -> _Component:
    """The pairs, times and distances of component ``index``."""
    nx, ny, label = components.nx, components.ny, components.label
    xs = np.flatnonzero(label[:nx] == index)
    ys = np.flatnonzero(label[nx:] == index)
    comp_pairs = components.pairs[components.pair_label == index]
    local_x = np.searchsorted(xs, comp_pairs[:, 0])
    local_y = np.searchsorted(ys, comp_pairs[:, 1])
    edges = np.stack([local_x, local_y], axis=1)
    active = np.flatnonzero(tx.present[:, xs].any(axis=1) | ty.present[:, ys].any(axis=1))
    position = np.full(tx.present.shape[0], -1, dtype=np.int64)
    position[active] = np.arange(active.size)
    edge_distance = np.full((active.size, edges.shape[0]), np.inf)
    in_comp = label[close.i] == index
    # np.unique sorted the pairs, so their keys i * ny + j are sorted too.
    comp_keys = comp_pairs[:, 0] * ny + comp_pairs[:, 1]
    e_index = np.searchsorted(comp_keys, close.i[in_comp] * ny + close.j[in_comp])
    edge_distance[position[close.time[in_comp]], e_index] = close.distance[in_comp]
    return _Component(xs=xs, ys=ys, edges=edges, active=active, edge_distance=edge_distance)


def _component_weights(
    component: _Component, tx: _Trajectories, ty: _Trajectories, metric: _Metric
) -> NDArray[np.float64]:
    """The optimal edge weights ``W_e(t)`` of one component, shape (Tc, nE): by dynamic
    programming when it has few matchings (``milp`` only), else by its program."""
    edges = component.edges
    incidence = _matchings(edges, _MAX_DP_STATES) if metric.method == "milp" else None
    present_x = tx.present[component.active][:, component.xs]
    present_y = ty.present[component.active][:, component.ys]
    if incidence is not None:
        return _viterbi_component(
            present_x=present_x,
            present_y=present_y,
            edges=edges,
            edge_distance=component.edge_distance,
            incidence=incidence,
            c=metric.c,
            p=metric.p,
            gamma=metric.gamma,
        )
    w, _ = _solve_component(
        present_x=present_x,
        present_y=present_y,
        edges=edges,
        edge_distance=component.edge_distance,
        c=metric.c,
        p=metric.p,
        gamma=metric.gamma,
        method=metric.method,
    )
    return w


@dataclass(frozen=True, eq=False)
class _Parts:
    """Per-time parts accumulated (in place) from the weights of every component.

    Attributes
    ----------
    localisation : ndarray, shape (T,)
    assigned : ndarray, shape (T,)
        Weight of the effective (present, closer than c) assignments.
    switching : ndarray, shape (T - 1,)
    assignment : ndarray of int, shape (T, nx)
        As :attr:`TgospaResult.assignment`.
    """

    localisation: NDArray[np.float64]
    assigned: NDArray[np.float64]
    switching: NDArray[np.float64]
    assignment: NDArray[np.int64]

    @classmethod
    def zeros(cls, num_times: int, nx: int) -> _Parts:
        """Nothing assigned yet."""
        return cls(
            localisation=np.zeros(num_times),
            assigned=np.zeros(num_times),
            switching=np.zeros(max(num_times - 1, 0)),
            assignment=np.full((num_times, nx), -1, dtype=np.int64),
        )


def _add_component(
    parts: _Parts, component: _Component, w: NDArray[np.float64], metric: _Metric
) -> None:
    """Add one component's localisation, assignments and switches, given its weights
    ``w`` of shape (Tc, nE), to ``parts``."""
    active, edges, edge_distance = component.active, component.edges, component.edge_distance
    effective = np.isfinite(edge_distance)  # both present and closer than c
    close = np.where(effective, edge_distance, 0.0)
    parts.localisation[active] += np.sum(np.where(effective, w * close**metric.p, 0.0), axis=1)
    parts.assigned[active] += np.sum(np.where(effective, w, 0.0), axis=1)
    if active.size > 1:
        change = np.sum(np.abs(np.diff(w, axis=0)), axis=1) * metric.gamma**metric.p / 2.0
        parts.switching[active[1:] - 1] += change
    chosen_t, chosen_e = np.nonzero(effective & (w > 0.5))
    truth_index = component.xs[edges[chosen_e, 0]]
    parts.assignment[active[chosen_t], truth_index] = component.ys[edges[chosen_e, 1]]


def _result(
    parts: _Parts,
    tx: _Trajectories,
    ty: _Trajectories,
    times: NDArray[np.float64],
    metric: _Metric,
    components: _Components,
) -> TgospaResult:
    """The metric and its decomposition from the accumulated per-time parts."""
    half = metric.c**metric.p / 2.0
    num_present_x = tx.present.sum(axis=1).astype(float)
    num_present_y = ty.present.sum(axis=1).astype(float)
    missed_t = half * (num_present_x - parts.assigned)
    false_t = half * (num_present_y - parts.assigned)
    localisation = float(np.sum(parts.localisation))
    missed = float(np.sum(missed_t))
    false = float(np.sum(false_t))
    switching = float(np.sum(parts.switching))
    total = max(localisation + missed + false + switching, 0.0) ** (1.0 / metric.p)
    return TgospaResult(
        total=float(total),
        localisation=localisation,
        missed=missed,
        false=false,
        switching=switching,
        num_missed=float(np.sum(num_present_x - parts.assigned)),
        num_false=float(np.sum(num_present_y - parts.assigned)),
        num_switches=switching / metric.gamma**metric.p,
        times=readonly(times.astype(float)),
        localisation_per_time=readonly(parts.localisation),
        missed_per_time=readonly(missed_t),
        false_per_time=readonly(false_t),
        switching_per_step=readonly(parts.switching),
        truth_ids=readonly(tx.ids),
        estimate_ids=readonly(ty.ids),
        assignment=readonly(parts.assignment),
        c=metric.c,
        p=metric.p,
        gamma=metric.gamma,
        method=metric.method,
        status="optimal",
        num_components=components.count,
        largest_component=components.largest,
    )


# ----------------------------------------------------------------------------------------------
# Public functions
# ----------------------------------------------------------------------------------------------


def _check_method(method: object, argument: str = "method") -> str:
    if not isinstance(method, str) or method not in METHODS:
        raise InputError(f"{argument} must be one of {', '.join(METHODS)}, got {method!r}")
    return method


def tgospa(
    truth: TimedPoints,
    estimates: TimedPoints,
    *,
    c: float,
    gamma: float,
    p: float = 2.0,
    method: str = "milp",
) -> TgospaResult:
    """T-GOSPA metric (alpha = 2) between true and estimated trajectories.

    See the module docstring for the definition, the switching convention and how it is
    computed.

    Parameters
    ----------
    truth, estimates : TimedPoints
        Rows of the trajectories (one id = one trajectory), same position dimension; at least
        one row in total.
    c : float
        Cut-off distance, > 0: a missed or a false trajectory costs ``c^p / 2`` per time.
    gamma : float
        Switching cost, > 0: a full switch costs ``gamma^p``, a start or end of an assignment
        ``gamma^p / 2``.
    p : float
        Order, ``1 <= p < inf``.
    method : {"milp", "lp"}
        ``milp`` solves the integer program exactly; ``lp`` its relaxation (a lower bound).

    Returns
    -------
    TgospaResult
        ``total ** p == localisation + missed + false + switching`` up to rounding.

    Raises
    ------
    InputError
        Bad ``c``, ``gamma``, ``p`` or ``method``, inputs that are not TimedPoints, different
        dimensions, no rows at all, or a solver failure.
    """
    metric = _Metric(
        c=check_positive("c", c),
        gamma=check_positive("gamma", gamma),
        p=check_order(p),
        method=_check_method(method),
    )
    check_cost_powers(metric.p, c=metric.c, gamma=metric.gamma)
    check_runs(truth, estimates)
    times = np.union1d(truth.distinct_times, estimates.distinct_times)
    tx = _trajectories(truth, times)
    ty = _trajectories(estimates, times)
    close = _close_pairs(tx, ty, times.shape[0], metric.c)
    components = _components(close, tx.ids.shape[0], ty.ids.shape[0])
    parts = _Parts.zeros(times.shape[0], tx.ids.shape[0])
    for index in np.unique(components.pair_label):
        component = _component(components, int(index), close, tx, ty)
        weights = _component_weights(component, tx, ty, metric)
        _add_component(parts, component, weights, metric)
    return _result(parts, tx, ty, times, metric, components)


def fragmentation_of(result: TgospaResult) -> TrackFragmentation:
    """Fragments per true target and identity switches of a T-GOSPA assignment.

    Parameters
    ----------
    result : TgospaResult
        Its ``assignment`` (present, closer than ``c``) is what is counted.

    Returns
    -------
    TrackFragmentation
    """
    if not isinstance(result, TgospaResult):
        raise InputError(f"result must be a TgospaResult, got {type(result).__name__}")
    assignment = result.assignment
    nx = assignment.shape[1]
    fragments = np.array(
        [np.unique(assignment[assignment[:, i] >= 0, i]).size for i in range(nx)], dtype=np.int64
    )
    if assignment.shape[0] > 1:
        now, nxt = assignment[:-1], assignment[1:]
        switches = np.sum((now >= 0) & (nxt >= 0) & (now != nxt), axis=0).astype(np.int64)
    else:
        switches = np.zeros(nx, dtype=np.int64)
    return TrackFragmentation(
        truth_ids=result.truth_ids,
        fragments=readonly(fragments),
        id_switches=readonly(switches),
    )


def track_fragmentation(
    truth: TimedPoints,
    tracks: TimedPoints,
    *,
    c: float,
    gamma: float | None = None,
    p: float = 2.0,
) -> TrackFragmentation:
    """Fragments per true target and identity switches, from the exact T-GOSPA assignment.

    The assignment is T-GOSPA's (``method="milp"``), not GOSPA's per time step: the switching
    cost keeps a target on one track where that is about as cheap, so a switch counted here is
    one the metric itself pays for.  A target counts an estimate id as a fragment when it is
    assigned to it (both present, closer than ``c``) at some time; an identity switch is a
    change of that id between consecutive evaluation times at which the target is assigned
    both times.

    Parameters
    ----------
    truth, tracks : TimedPoints
        True and estimated trajectories.
    c : float
        Cut-off distance, > 0.
    gamma : float, optional
        T-GOSPA switching cost, > 0; ``None`` uses ``c`` (a full switch then costs as much as
        a missed target plus a false track at one time).
    p : float
        Order, ``1 <= p < inf``.

    Returns
    -------
    TrackFragmentation
    """
    cutoff = check_positive("c", c)
    switch = cutoff if gamma is None else check_positive("gamma", gamma)
    return fragmentation_of(tgospa(truth, tracks, c=cutoff, gamma=switch, p=p, method="milp"))
