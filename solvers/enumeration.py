"""Exact oracle for binary programs: depth-first enumeration of every feasible 0/1 point.

Search.  Variables are fixed in index order, 0 before 1, so feasible points are visited
in increasing lexicographic order.  After fixing a variable, every row it appears in is
checked against the most favourable completion of the still-free variables:

    A_ub row i:  activity_i + Σ_{j free} min(A_ij, 0)            <= b_ub_i + tol
    A_eq row i:  activity_i + Σ_{j free} min(A_ij, 0)            <= b_eq_i + tol
                 activity_i + Σ_{j free} max(A_ij, 0)            >= b_eq_i - tol

A partial assignment failing a test has no feasible completion and is pruned.  The
tests are exact for any real coefficients (they are the row's range over the remaining
box), and for the 0/1 set-packing rows of our formulations they prune as soon as a row
is over-used or an "exactly one" group can no longer be met.  The free-variable sums are
precomputed suffix sums (``math.fsum``), so no round-off accumulates along the search.

Feasibility of a point means ``A_ub x <= b_ub + tol`` and ``|A_eq x - b_eq| <= tol``
with ``tol = feasibility_tolerance`` (default 1e-9; exact for integer data).

Values and ties.  The value of a point is ``math.fsum`` of its selected objective
coefficients and the constant: the correctly rounded real sum, so two points whose
coefficient sums are equal as real numbers get bit-identical values.  Among optimal
points the lexicographically smallest one (the first visited) is returned.

The partition function ``log Σ_x exp(value(x))`` is accumulated with a running maximum
(``m``) and ``fsum`` of ``exp(value - m)``, rescaled whenever the maximum grows.

Limits.  ``max_variables`` refuses programs too large to enumerate (SolverError, a
misuse); ``node_limit`` and ``time_limit`` stop a running search with WORK_LIMIT /
TIME_LIMIT, returning the best point and the partial sums found so far.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

from mapassoc.formulations.program import Program
from mapassoc.solvers.results import (
    EnumerationResult,
    SolverError,
    SolveStatus,
    validate_time_limit,
)

__all__ = ["EnumerationSolver", "enumerate_feasible", "check_binary"]

_NAME = "enumeration"
_TIME_CHECK_INTERVAL = 1024  # nodes between clock readings


def check_binary(program: Program, backend: str = _NAME) -> None:
    """Raise :class:`SolverError` unless every variable is integer with bounds in [0, 1].

    Parameters
    ----------
    program : Program
    backend : str
        Name that starts the error message.
    """
    if not isinstance(program, Program):
        raise TypeError(f"program must be a Program, got {type(program).__name__}")
    for index in range(program.num_variables):
        label = program.variable_labels[index] if program.variable_labels else f"x[{index}]"
        if not program.integrality[index]:
            raise SolverError(
                f"{backend}: needs a binary program, but variable {index} ({label}) is "
                "continuous"
            )
        low, high = program.lower[index], program.upper[index]
        if low < 0 or high > 1:
            raise SolverError(
                f"{backend}: needs a binary program, but variable {index} ({label}) has "
                f"bounds [{low}, {high}], not within [0, 1]"
            )


class _BinarySearch:
    """Depth-first search state over the 0/1 points of one binary program."""

    def __init__(
        self,
        program: Program,
        *,
        tolerance: float,
        node_limit: int | None = None,
        deadline: float | None = None,
    ) -> None:
        n = program.num_variables
        self.n = n
        self.tolerance = tolerance
        self.node_limit = node_limit
        self.deadline = deadline
        self.nodes = 0
        self.stop_reason: SolveStatus | None = None
        # Rows: inequality rows first, then equality rows.
        self.num_ub = program.A_ub.shape[0]
        self.rhs = [float(b) for b in np.concatenate([program.b_ub, program.b_eq])]
        num_rows = len(self.rhs)
        # columns[j]: (row, coefficient) pairs of variable j in row order, explicit zeros
        # dropped (built from the CSR rows; cheaper than a sparse transpose for tiny programs).
        self.columns: list[list[tuple[int, float]]] = [[] for _ in range(n)]
        for offset, matrix in ((0, program.A_ub), (self.num_ub, program.A_eq)):
            indptr = matrix.indptr.tolist()
            indices = matrix.indices.tolist()
            data = matrix.data.tolist()
            for r in range(matrix.shape[0]):
                for k in range(indptr[r], indptr[r + 1]):
                    if data[k] != 0.0:
                        self.columns[indices[k]].append((offset + r, data[k]))
        # suffix_low[j][r] / suffix_high[j][r]: Σ_{k >= j} min/max(A_rk, 0), i.e. the range
        # of row r over the free variables once variables 0..j-1 are fixed.
        row_terms_low: list[list[float]] = [[] for _ in range(num_rows)]
        row_terms_high: list[list[float]] = [[] for _ in range(num_rows)]
        self.suffix_low: list[list[float]] = [[0.0] * num_rows for _ in range(n + 1)]
        self.suffix_high: list[list[float]] = [[0.0] * num_rows for _ in range(n + 1)]
        for j in range(n - 1, -1, -1):
            # Rows untouched by variable j keep the suffix of j + 1.
            self.suffix_low[j] = list(self.suffix_low[j + 1])
            self.suffix_high[j] = list(self.suffix_high[j + 1])
            for r, a in self.columns[j]:
                (row_terms_low if a < 0 else row_terms_high)[r].append(a)
            for r, _ in self.columns[j]:
                self.suffix_low[j][r] = math.fsum(row_terms_low[r])
                self.suffix_high[j][r] = math.fsum(row_terms_high[r])
        self.domains: list[tuple[int, ...]] = [
            tuple(v for v in (0, 1) if program.lower[j] <= v <= program.upper[j])
            for j in range(n)
        ]
        self.activity = [0.0] * num_rows
        self.point = [0] * n

    def _row_possible(self, r: int, next_free: int) -> bool:
        """Whether row ``r`` can still be met once variables ``< next_free`` are fixed."""
        act, rhs, tol = self.activity[r], self.rhs[r], self.tolerance
        if act + self.suffix_low[next_free][r] > rhs + tol:
            return False
        return r < self.num_ub or act + self.suffix_high[next_free][r] >= rhs - tol

    def root_feasible(self) -> bool:
        """Whether every row can be met at all (catches rows no variable can satisfy)."""
        return all(self._row_possible(r, 0) for r in range(len(self.rhs)))

    def leaves(self) -> Iterator[tuple[int, ...]]:
        """Feasible points in increasing lexicographic order (stops early on a limit)."""
        if self.root_feasible():
            yield from self._descend(0)

    def _descend(self, j: int) -> Iterator[tuple[int, ...]]:
        self.nodes += 1
        if self.node_limit is not None and self.nodes > self.node_limit:
            self.stop_reason = SolveStatus.WORK_LIMIT
            return
        if (
            self.deadline is not None
            and self.nodes % _TIME_CHECK_INTERVAL == 0
            and time.perf_counter() > self.deadline
        ):
            self.stop_reason = SolveStatus.TIME_LIMIT
            return
        if j == self.n:
            yield tuple(self.point)
            return
        column = self.columns[j]
        for value in self.domains[j]:
            saved = [self.activity[r] for r, _ in column]
            if value:
                for r, a in column:
                    self.activity[r] += a
            self.point[j] = value
            if all(self._row_possible(r, j + 1) for r, _ in column):
                yield from self._descend(j + 1)
            for (r, _), old in zip(column, saved, strict=True):
                self.activity[r] = old
            self.point[j] = 0
            if self.stop_reason is not None:
                return


def enumerate_feasible(
    program: Program, *, feasibility_tolerance: float = 1e-9
) -> Iterator[NDArray[np.float64]]:
    """Every feasible 0/1 point of a binary program, in increasing lexicographic order.

    Parameters
    ----------
    program : Program
        Binary: every variable integer with bounds within [0, 1].
    feasibility_tolerance : float, default 1e-9
        Slack allowed on each constraint row.

    Yields
    ------
    ndarray, shape (n,)
        A feasible point with entries 0.0 / 1.0 (a fresh array each time).

    Raises
    ------
    SolverError
        If the program is not binary.
    """
    check_binary(program)
    _check_tolerance(feasibility_tolerance)
    search = _BinarySearch(program, tolerance=feasibility_tolerance)
    for leaf in search.leaves():
        yield np.array(leaf, dtype=float)


def _check_tolerance(tolerance: float) -> None:
    if not (math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"feasibility_tolerance must be finite and >= 0, got {tolerance!r}")


class EnumerationSolver:
    """Exact oracle for binary programs by complete enumeration (see the module notes).

    Parameters
    ----------
    max_variables : int, default 40
        Programs with more variables are refused with :class:`SolverError`.
    node_limit : int or None, default 5_000_000
        Search nodes before stopping with :attr:`SolveStatus.WORK_LIMIT`; ``None`` for none.
    feasibility_tolerance : float, default 1e-9
        Slack allowed on each constraint row.
    """

    name = _NAME
    supports_integer = True
    supports_flow = False
    supports_relaxation = False
    exact = True

    def __init__(
        self,
        *,
        max_variables: int = 40,
        node_limit: int | None = 5_000_000,
        feasibility_tolerance: float = 1e-9,
    ) -> None:
        if int(max_variables) != max_variables or max_variables < 0:
            raise ValueError(f"max_variables must be an integer >= 0, got {max_variables!r}")
        if node_limit is not None and (int(node_limit) != node_limit or node_limit < 1):
            raise ValueError(f"node_limit must be a positive integer or None, got {node_limit!r}")
        _check_tolerance(feasibility_tolerance)
        self.max_variables = int(max_variables)
        self.node_limit = None if node_limit is None else int(node_limit)
        self.feasibility_tolerance = float(feasibility_tolerance)

    def __repr__(self) -> str:
        return (
            f"EnumerationSolver(max_variables={self.max_variables}, node_limit="
            f"{self.node_limit}, feasibility_tolerance={self.feasibility_tolerance})"
        )

    def solve(self, program: Program, *, time_limit: float | None = None) -> EnumerationResult:
        """Enumerate every feasible point: optimum, partition function and count.

        Parameters
        ----------
        program : Program
            Binary, with at most ``max_variables`` variables.
        time_limit : float or None
            Wall-clock seconds before stopping with TIME_LIMIT (checked every 1024 nodes).

        Returns
        -------
        EnumerationResult
            OPTIMAL with the lexicographically smallest optimum, ``bound == objective``,
            ``log_sum_exp`` and ``num_feasible``; INFEASIBLE with ``log_sum_exp == -inf``;
            or TIME_LIMIT / WORK_LIMIT with the best point and partial sums so far.

        Raises
        ------
        SolverError
            If the program is not binary or has more than ``max_variables`` variables.
        """
        check_binary(program)
        limit = validate_time_limit(time_limit)
        if program.num_variables > self.max_variables:
            raise SolverError(
                f"{self.name}: program has {program.num_variables} variables, more than "
                f"max_variables={self.max_variables}; enumeration is exponential, use an "
                "exact MILP backend such as 'highs'"
            )
        started = time.perf_counter()
        search = _BinarySearch(
            program,
            tolerance=self.feasibility_tolerance,
            node_limit=self.node_limit,
            deadline=None if limit is None else started + limit,
        )
        best_value, best_point, log_sum_exp, count = _enumerated(search, program)
        seconds = time.perf_counter() - started
        solution = None if best_point is None else np.array(best_point, dtype=float)
        objective = math.nan if best_point is None else best_value
        stats = f"{count} feasible points, {search.nodes} search nodes"
        if search.stop_reason is not None:
            return EnumerationResult(
                status=search.stop_reason, objective=objective, solution=solution,
                solve_seconds=seconds, solver=self.name, bound=math.nan,
                message=f"stopped by the {search.stop_reason.value} after {stats}; sums "
                "cover the points found so far",
                log_sum_exp=log_sum_exp, num_feasible=count,
            )
        if best_point is None:
            return EnumerationResult(
                status=SolveStatus.INFEASIBLE, objective=math.nan, solution=None,
                solve_seconds=seconds, solver=self.name, message=f"no feasible point ({stats})",
                log_sum_exp=-math.inf, num_feasible=0,
            )
        return EnumerationResult(
            status=SolveStatus.OPTIMAL, objective=objective, solution=solution,
            solve_seconds=seconds, solver=self.name, bound=objective,
            message=f"complete enumeration: {stats}",
            log_sum_exp=log_sum_exp, num_feasible=count,
        )


def _enumerated(
    search: _BinarySearch, program: Program
) -> tuple[float, tuple[int, ...] | None, float, int]:
    """Every leaf of ``search`` valued by ``program``'s objective (plus its constant,
    summed exactly): the best value and its first (lexicographically smallest) point
    (``-inf``, ``None``: no leaf), the log of the sum of exp(value) (``-inf``: no leaf)
    and the number of leaves.  The exponentials are kept relative to the running
    maximum, so that none overflows."""
    coefficients = [float(c) for c in program.objective]
    constant = program.constant
    best_value = -math.inf
    best_point: tuple[int, ...] | None = None
    running_max = -math.inf
    scaled_terms: list[float] = []  # exp(value - running_max)
    count = 0
    for leaf in search.leaves():
        value = math.fsum([constant, *(c for c, v in zip(coefficients, leaf, strict=True) if v)])
        count += 1
        if value > best_value:  # strict: the first (lexicographically smallest) optimum
            best_value, best_point = value, leaf
        if value > running_max:
            if scaled_terms:
                scaled_terms = [math.fsum(scaled_terms) * math.exp(running_max - value)]
            running_max = value
        scaled_terms.append(math.exp(value - running_max))
    log_sum_exp = running_max + math.log(math.fsum(scaled_terms)) if scaled_terms else -math.inf
    return best_value, best_point, log_sum_exp, count
