"""The LP-relaxation tracker: certificates against hand-worked and exact integer optima,
rounding, and the end-to-end comparison with the MAP estimator."""

from __future__ import annotations

import math

import numpy as np
import pytest
from support import random_problem, random_window

from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import RunEvaluation
from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario
from mapassoc.evaluation.tables import evaluate_tables
from mapassoc.formulations.packing import PackingProblem, set_packing_program
from mapassoc.solvers.cvxpy_backend import CvxpySolver
from mapassoc.solvers.enumeration import EnumerationSolver
from mapassoc.solvers.highs import HighsSolver
from mapassoc.solvers.results import SolveStatus
from mapassoc.trackers.lp_relaxation import (
    Decision,
    LpRelaxationDetails,
    LpRelaxationTracker,
    certify_relaxation,
    integrality_measure,
    round_selection,
    solve_lp,
)
from mapassoc.trackers.map_estimator import MapTracker
from mapassoc.trackers.registry import build_tracker

CLARABEL = CvxpySolver(backend="CLARABEL")
HIGHS = HighsSolver()


def _problem(resources: list[list[int]], scores: list[float], num_resources: int) -> PackingProblem:
    indptr = np.concatenate([[0], np.cumsum([len(r) for r in resources])])
    indices = np.array([i for r in resources for i in r], dtype=np.int64)
    return PackingProblem(
        scores=np.array(scores, dtype=float),
        resource_indptr=indptr,
        resource_indices=indices,
        exactly_one=np.zeros(num_resources, dtype=bool),
        counts=np.ones(len(resources), dtype=bool),
    )


def test_odd_cycle_is_fractional_with_gap_one_half_and_rounds_to_value_one() -> None:
    # Three hypotheses pairwise sharing a detection (h0: {0, 1}, h1: {1, 2}, h2: {0, 2}),
    # each scoring 1.  LP: every row x_a + x_b <= 1, so sum x <= 3/2, reached at x = 1/2
    # (unique optimum).  Integer: any two conflict, so the optimum is 1.
    problem = _problem([[0, 1], [1, 2], [0, 2]], [1.0, 1.0, 1.0], 3)
    lp = solve_lp(problem, None, solver=CLARABEL)
    assert lp.status is SolveStatus.OPTIMAL
    np.testing.assert_allclose(lp.point, [0.5, 0.5, 0.5], atol=1e-7)
    cert, selection, decision = certify_relaxation(problem, lp, ip_solver=HIGHS)
    assert cert.lp_value == pytest.approx(1.5, abs=1e-7)
    assert cert.lp_bound == pytest.approx(1.5, abs=1e-7)
    assert cert.lp_bound >= cert.lp_value - 1e-9
    assert cert.ip_value == 1.0
    assert cert.integrality_gap == pytest.approx(0.5, abs=1e-7)
    assert cert.integrality == pytest.approx(0.5, abs=1e-7)
    assert not cert.integral and not cert.tight
    assert cert.relative_duality_gap <= 1e-6
    assert decision is Decision.ROUNDED
    assert selection is not None and selection.tolist() == [0]  # x ties, score ties: index
    assert problem.is_feasible(selection) and problem.value(selection) == 1.0


def test_midpoint_of_an_integral_face_is_reported_fractional_but_tight() -> None:
    # Two hypotheses sharing detection 0 (and one more each), score 1 each: the LP
    # optimum 1 is attained at both vertices, and Clarabel returns the centre of that
    # face, (1/2, 1/2).
    problem = _problem([[0, 1], [0, 2]], [1.0, 1.0], 3)
    lp = solve_lp(problem, None, solver=CLARABEL)
    np.testing.assert_allclose(lp.point, [0.5, 0.5], atol=1e-6)
    cert, selection, decision = certify_relaxation(problem, lp, ip_solver=HIGHS)
    assert not cert.integral  # the point is a midpoint...
    assert cert.tight  # ...of an integral optimal face: no integrality gap
    assert cert.integrality_gap == pytest.approx(0.0, abs=1e-7)
    assert decision is Decision.ROUNDED and selection is not None
    assert problem.value(selection) == cert.ip_value == 1.0


def test_cardinality_row_makes_the_odd_cycle_tight() -> None:
    # With exactly one track the LP optimum is 1 (= the integer optimum); Clarabel's point
    # is the centre (1/3, 1/3, 1/3), fractional.
    problem = _problem([[0, 1], [1, 2], [0, 2]], [1.0, 1.0, 1.0], 3)
    lp = solve_lp(problem, 1, solver=CLARABEL)
    np.testing.assert_allclose(lp.point, [1 / 3] * 3, atol=1e-6)
    cert, selection, _ = certify_relaxation(problem, lp, ip_solver=HIGHS)
    assert cert.tight and not cert.integral
    assert selection is not None and problem.is_feasible(selection, 1)
    # Two tracks: sum x <= 3/2 (add the three rows), so even the LP is infeasible.
    assert solve_lp(problem, 2, solver=CLARABEL).status is SolveStatus.INFEASIBLE


def test_lp_feasible_integer_infeasible_gives_no_selection() -> None:
    # The odd cycle with every resource used exactly once: x = 1/2 satisfies the LP, but
    # a triangle has no perfect matching, so no integer set exists.
    base = _problem([[0, 1], [1, 2], [0, 2]], [1.0, 1.0, 1.0], 3)
    problem = PackingProblem(
        base.scores, base.resource_indptr, base.resource_indices, np.ones(3, bool), base.counts
    )
    lp = solve_lp(problem, None, solver=CLARABEL)
    np.testing.assert_allclose(lp.point, [0.5, 0.5, 0.5], atol=1e-7)
    cert, selection, decision = certify_relaxation(problem, lp, ip_solver=HIGHS)
    assert cert.lp_value == pytest.approx(1.5, abs=1e-7)
    assert cert.ip_status == SolveStatus.INFEASIBLE.value and cert.ip_value == -math.inf
    assert cert.integrality_gap == math.inf and not cert.tight
    assert selection is None and decision is None
    assert round_selection(problem, lp.point) is None


def test_integrality_measure() -> None:
    assert integrality_measure(np.array([0.0, 1.0, 1.0])) == 0.0
    assert integrality_measure(np.array([0.2, 0.9, 1.0 + 1e-9])) == pytest.approx(0.2)
    assert integrality_measure(np.zeros(0)) == 0.0


def _check_against_enumeration(problem: PackingProblem, tracks: int, seen: dict[str, int]) -> None:
    exact = EnumerationSolver().solve(set_packing_program(problem, tracks))
    lp = solve_lp(problem, tracks, solver=CLARABEL)
    if lp.status is SolveStatus.INFEASIBLE:
        assert exact.status is SolveStatus.INFEASIBLE  # LP infeasible => IP infeasible
        return
    assert lp.status is SolveStatus.OPTIMAL
    cert, selection, decision = certify_relaxation(problem, lp, ip_solver=HIGHS)
    assert cert.relative_duality_gap <= 1e-6
    if exact.status is SolveStatus.INFEASIBLE:
        assert not cert.integral and cert.ip_value == -math.inf
        seen["lp_only"] += 1
        return
    scale = max(1.0, abs(exact.objective))
    assert cert.ip_value == pytest.approx(exact.objective, abs=1e-9 * scale)  # HiGHS exact
    assert cert.lp_bound >= exact.objective - 1e-7 * scale
    assert cert.lp_value >= exact.objective - 1e-6 * scale
    assert selection is not None and problem.is_feasible(selection, tracks)
    assert problem.value(selection) <= exact.objective + 1e-9 * scale
    if cert.integral:
        seen["integral"] += 1
        assert decision is Decision.INTEGRAL and cert.tight
        assert cert.lp_value == pytest.approx(exact.objective, abs=1e-6 * scale)
        assert problem.value(selection) == pytest.approx(exact.objective, abs=1e-9 * scale)
    else:
        seen["fractional"] += 1
        seen["gap"] += int(not cert.tight)


@pytest.mark.slow
def test_random_windows_lp_bounds_the_exact_optimum_and_equals_it_when_integral() -> None:
    seen = {"integral": 0, "fractional": 0, "gap": 0, "lp_only": 0}
    for seed in range(12):  # windows of the estimator (track trees, carried tracks)
        window = random_window(seed)
        solution = window.estimator.solve_window(window.scans, window.carried)
        top = int(np.flatnonzero(np.isfinite(solution.table.best))[-1])
        for tracks in range(top + 2):  # top + 1 has no track set
            _check_against_enumeration(solution.problem, tracks, seen)
    rng = np.random.default_rng(7)
    for _ in range(40):  # random packing problems: fractional LPs are common there
        problem = random_problem(rng, int(rng.integers(6, 13)), 4, int(rng.integers(0, 3)))
        for tracks in range(int(problem.counts.sum()) + 1):
            _check_against_enumeration(problem, tracks, seen)
    # Both branches of the comparison ran, and some LPs had a real integrality gap.
    assert seen["integral"] > 50 and seen["fractional"] > 5 and seen["gap"] >= 3, seen


def test_rounding_respects_carried_tracks_and_cardinality() -> None:
    # Resource 0, 1: detections; resource 2: a carried track (exactly once) whose
    # hypotheses are h0 (uses detection 0) and h1 (no detection, counts).  h2, h3: new
    # tracks on detections 0 and 1.  A point favouring the new tracks must still give
    # the carried track a hypothesis and stop at two tracks.
    problem = PackingProblem(
        scores=np.array([2.0, 0.5, 3.0, 1.0]),
        resource_indptr=np.array([0, 2, 3, 4, 5]),
        resource_indices=np.array([0, 2, 2, 0, 1]),
        exactly_one=np.array([False, False, True]),
        counts=np.ones(4, dtype=bool),
    )
    x = np.array([0.1, 0.2, 0.9, 0.8])
    selection = round_selection(problem, x, 2)
    assert selection is not None and selection.tolist() == [1, 2]  # h3 dropped for h1
    assert problem.is_feasible(selection, 2)
    assert round_selection(problem, x, 3).tolist() == [1, 2, 3]
    assert round_selection(problem, x, 0) is None  # the carried track always counts
    with pytest.raises(InputError, match=r"x must have shape \(4,\)"):
        round_selection(problem, x[:3], 2)


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("integrality_tolerance", 0.5),
        ("integrality_tolerance", 0.0),
        ("gap_tolerance", -1e-6),
        ("gap_tolerance", math.nan),
        ("time_limit", 0.0),
        ("time_limit", True),
    ],
)
def test_options_are_validated(option: str, value: object) -> None:
    config = build_scenario("crossing", seed=0).config
    with pytest.raises(InputError, match=rf"{option} must be .*got {value!r}"):
        LpRelaxationTracker(config=config, **{option: value})  # type: ignore[arg-type]


def _gospa(truth, output) -> float:
    evaluation = evaluate_tables(truth, output.tracks, c=10.0)
    assert isinstance(evaluation, RunEvaluation)
    return evaluation.gospa.mean_total


@pytest.mark.slow
def test_crossing_lp_is_integral_in_every_window_and_gives_the_map_tracks() -> None:
    scenario = truncate_scenario(build_scenario("crossing", seed=0), 20)
    tracker = build_tracker("lp", config=scenario.config)
    assert isinstance(tracker, LpRelaxationTracker) and tracker.name == "lp"
    lp = tracker.track(scenario.scans)
    reference = MapTracker(config=scenario.config).track(scenario.scans)
    details = lp.details
    assert isinstance(details, LpRelaxationDetails)
    certificates = details.certificates
    assert len(certificates) == len(reference.details.windows) == 16
    # Measured: Clarabel's point is integral in every window of crossing seed 0.
    assert details.integral_share == 1.0 and details.tight_share == 1.0
    for c in certificates:
        r = c.relaxation
        assert r.relative_duality_gap <= 1e-6
        assert r.lp_bound >= r.ip_value - 1e-9 * max(1.0, abs(r.ip_value))
        assert 0 <= r.integrality_gap <= 1e-6 * max(1.0, abs(r.ip_value))
        assert c.target_count >= c.tracks
        # An integral LP at the estimator's T commits the estimator's own set.
        assert c.decision is Decision.INTEGRAL and c.tracks == c.estimator_tracks
        assert c.matches_estimator
        assert c.selected_value == pytest.approx(c.estimator_objective, abs=1e-9)
    # Same sets in every window: the same stitched, smoothed tracks.
    assert lp.associations == reference.associations
    assert details.estimate.track_rows == reference.details.track_rows
    np.testing.assert_array_equal(lp.tracks.states, reference.tracks.states)
    assert _gospa(scenario.truth, lp) == _gospa(scenario.truth, reference)
    assert [w.chosen_tracks for w in details.estimate.windows] == [
        w.chosen_tracks for w in reference.details.windows
    ]
