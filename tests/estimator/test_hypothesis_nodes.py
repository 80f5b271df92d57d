"""The node record of the track trees and the commit of a window
(``mapassoc.estimator.hypotheses``).

What is checked, against what:

1. :class:`HypothesisNodes` is one record of equal-length arrays: ``take`` by positions
   and by a boolean mask agree, ``concat`` of the pieces ``take`` cut gives the record
   back (values and dtypes), ``concat`` of nothing is ``empty``, and arrays of unequal
   lengths are refused.
2. :meth:`WindowHypotheses.commit` on a hand-made window of two scans (one carried
   track, two births), every expected row, scan position, "ended" flag and carried state
   written out by hand from the tree drawn below, for one and two committed scans.
3. ``WindowEstimator._commit`` on the same window: new tracks get ids in selection
   order, a birth after the committed scans gets none, the carried list is sorted by id.
4. On a generated window of a built-in scenario, every hypothesis committed after each
   scan uses exactly its detections at the committed scans
   (:meth:`WindowHypotheses.detections_of`), is "ended" exactly when its leaf is an
   "ended" node at a committed scan, and carries a state exactly when it is alive at the
   last committed scan (not ended there or before, leaf at that scan or later).
"""

from __future__ import annotations

import numpy as np
import pytest

from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.hypotheses import (
    CarriedTrack,
    HypothesisNodes,
    WindowDetections,
    WindowHypotheses,
)
from mapassoc.estimator.pipeline import WindowEstimator, _TrackRecord
from mapassoc.evaluation.scenarios import build_scenario

# ---------------------------------------------------------------------------------- window
#
# Two scans (times 1 and 2), two detections each: window detections 0, 1 (rows 10, 11,
# scan 0) and 2, 3 (rows 12, 13, scan 1).  Trees and nodes:
#
#   tree 0, carried track 7:  node 0 (scan 0, det 0) -> node 3 (scan 1, det 2)
#                             node 1 (scan 0, ended before the window)
#   tree 1, new:              node 2 (scan 0, det 1) -> node 4 (scan 1, ended)
#   tree 2, new:              node 5 (scan 1, det 3), a 1-D state padded to 2
#
# Hypotheses: 0 = leaf 3, 1 = leaf 1, 2 = leaf 4, 3 = leaf 5.

MEANS = np.array([[1.0, 0.1], [0.0, 0.0], [5.0, 0.5], [2.0, 0.2], [0.0, 0.0], [9.0, 0.0]])
COVS = np.array([np.diag([1.0 + v, 2.0 + v]) for v in range(6)])
COVS[5] = np.diag([7.0, 0.0])


def hand_nodes() -> HypothesisNodes:
    return HypothesisNodes(
        parent=np.array([-1, -1, -1, 0, 2, -1], dtype=np.int64),
        layer=np.array([0, 0, 0, 1, 1, 1], dtype=np.int64),
        detection=np.array([0, -1, 1, 2, -1, 3], dtype=np.int64),
        alive=np.array([True, False, True, True, False, True]),
        tree=np.array([0, 0, 1, 0, 1, 2], dtype=np.int64),
        initiated=np.array([True, True, True, True, True, False]),
        num_detections=np.array([4, 3, 1, 5, 1, 1], dtype=np.int64),
        first_time=np.array([0.5, 0.5, 1.0, 0.5, 1.0, 2.0]),
        score=np.array([1.0, -2.0, -3.0, 4.0, -5.0, -6.0]),
        protected=np.array([False, True, False, False, False, False]),
        means=MEANS.copy(),
        covariances=COVS.copy(),
        state_dims=np.array([2, 2, 2, 2, 2, 1], dtype=np.int64),
    )


def hand_window() -> WindowHypotheses:
    scans = (
        Scan(1.0, "s", np.array([[0.0], [1.0]]), np.array([10, 11], dtype=np.int64)),
        Scan(2.0, "s", np.array([[2.0], [3.0]]), np.array([12, 13], dtype=np.int64)),
    )
    nodes = hand_nodes()
    leaf = np.array([3, 1, 4, 5], dtype=np.int64)
    return WindowHypotheses(
        scans=scans,
        detections=WindowDetections(
            scan_position=np.array([0, 0, 1, 1], dtype=np.int64),
            index_in_scan=np.array([0, 1, 0, 1], dtype=np.int64),
            rows=np.array([10, 11, 12, 13], dtype=np.int64),
        ),
        tree_track_ids=np.array([7, -1, -1], dtype=np.int64),
        scores=nodes.score[leaf],
        tree=nodes.tree[leaf],
        leaf=leaf,
        counts_toward_k=np.array([True, False, True, True]),
        detection_indptr=np.array([0, 2, 2, 3, 4], dtype=np.int64),
        detection_indices=np.array([0, 2, 1, 3], dtype=np.int64),
        nodes=nodes,
        nodes_generated=6,
        nodes_pruned=0,
    )


def assert_same_nodes(a: HypothesisNodes, b: HypothesisNodes) -> None:
    for name in (
        "parent",
        "layer",
        "detection",
        "alive",
        "tree",
        "initiated",
        "num_detections",
        "first_time",
        "score",
        "protected",
        "means",
        "covariances",
        "state_dims",
    ):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype, name
        assert x.shape == y.shape, name
        assert np.array_equal(x, y), name


def assert_state(
    state: CarriedTrack | None, *, track_id: int, mean, cov, time, num_detections, first_time
) -> None:
    assert state is not None
    assert state.track_id == track_id
    assert np.array_equal(state.mean, mean)
    assert np.array_equal(state.covariance, cov)
    assert state.time == time
    assert state.num_detections == num_detections
    assert state.first_detection_time == first_time


# ---------------------------------------------------------------------------------- record


def test_take_by_mask_and_by_positions_agree() -> None:
    nodes = hand_nodes()
    mask = nodes.alive
    assert_same_nodes(nodes.take(mask), nodes.take(np.flatnonzero(mask)))
    assert len(nodes.take(mask)) == 4
    assert nodes.take(mask).detection.tolist() == [0, 1, 2, 3]
    assert_same_nodes(nodes.take(np.zeros(6, dtype=bool)), HypothesisNodes.empty(2))


def test_concat_of_pieces_gives_the_record_back() -> None:
    nodes = hand_nodes()
    assert len(nodes) == 6
    nothing = np.array([], dtype=np.int64)
    pieces = [nodes.take([0, 1]), nodes.take(nothing), nodes.take([2, 3, 4, 5])]
    assert [len(p) for p in pieces] == [2, 0, 4]
    assert_same_nodes(HypothesisNodes.concat(pieces), nodes)
    # A permutation and its inverse.
    perm = np.array([5, 3, 0, 4, 1, 2])
    assert_same_nodes(nodes.take(perm).take(np.argsort(perm)), nodes)
    # Concatenation of the record with itself, split again.
    twice = HypothesisNodes.concat([nodes, nodes])
    assert len(twice) == 12
    assert_same_nodes(twice.take(np.arange(6, 12)), nodes)


def test_concat_of_nothing_is_empty() -> None:
    empty = HypothesisNodes.concat([], state_dim=3)
    assert len(empty) == 0
    assert empty.means.shape == (0, 3) and empty.covariances.shape == (0, 3, 3)
    assert_same_nodes(empty, HypothesisNodes.empty(3))
    assert empty.parent.dtype == np.int64 and empty.alive.dtype == bool
    assert empty.first_time.dtype == np.float64


def test_record_refuses_unequal_lengths_and_bad_masks() -> None:
    nodes = hand_nodes()
    with pytest.raises(ValueError, match="score"):
        HypothesisNodes(**{**nodes.__dict__, "score": np.zeros(5)})
    with pytest.raises(ValueError, match="mask"):
        nodes.take(np.ones(5, dtype=bool))


def test_path_and_state() -> None:
    nodes = hand_nodes()
    assert nodes.path(3) == [0, 3]
    assert nodes.path(4) == [2, 4]
    assert nodes.path(5) == [5]
    mean, cov = nodes.state(5)
    assert mean.tolist() == [9.0] and cov.tolist() == [[7.0]]


# ---------------------------------------------------------------------------------- commit


def test_commit_one_scan_by_hand() -> None:
    hyps = hand_window()
    out = hyps.commit(np.array([0, 2, 3]), 1)
    # Hypothesis 3 is born at scan 1, after the committed scan: left out.
    assert [c.hypothesis for c in out] == [0, 2]
    carried, birth = out
    assert carried.track_id == 7 and not carried.is_new
    assert carried.detections.tolist() == [0]
    assert carried.rows.tolist() == [10]
    assert carried.scan_positions.tolist() == [0]
    assert not carried.ended
    assert_state(
        carried.state,
        track_id=7,
        mean=MEANS[0],
        cov=COVS[0],
        time=1.0,
        num_detections=4,
        first_time=0.5,
    )
    assert birth.track_id == -1 and birth.is_new
    assert birth.detections.tolist() == [1]
    assert birth.rows.tolist() == [11]
    assert birth.scan_positions.tolist() == [0]
    assert not birth.ended  # it ends at scan 1, which is not committed
    assert_state(
        birth.carried(42),
        track_id=42,
        mean=MEANS[2],
        cov=COVS[2],
        time=1.0,
        num_detections=1,
        first_time=1.0,
    )


def test_commit_two_scans_by_hand() -> None:
    hyps = hand_window()
    carried, birth, late = hyps.commit([0, 2, 3], 2)
    assert carried.rows.tolist() == [10, 12]
    assert carried.scan_positions.tolist() == [0, 1]
    assert carried.detections.tolist() == [0, 2]
    assert not carried.ended
    assert_state(
        carried.state,
        track_id=7,
        mean=MEANS[3],
        cov=COVS[3],
        time=2.0,
        num_detections=5,
        first_time=0.5,
    )
    assert birth.rows.tolist() == [11]
    assert birth.ended
    assert birth.state is None and birth.carried(3) is None
    assert late.is_new
    assert late.rows.tolist() == [13]
    assert late.scan_positions.tolist() == [1]
    assert_state(
        late.carried(5),
        track_id=5,
        mean=[9.0],
        cov=[[7.0]],
        time=2.0,
        num_detections=1,
        first_time=2.0,
    )
    assert late.state is not None and not late.state.initiated


def test_commit_of_a_track_ended_before_the_window() -> None:
    (ended,) = hand_window().commit([1], 1)
    assert ended.track_id == 7
    assert ended.ended
    assert ended.detections.size == 0 and ended.rows.size == 0
    assert ended.detections.dtype == np.int64
    assert ended.state is None


def test_commit_refuses_bad_arguments() -> None:
    hyps = hand_window()
    with pytest.raises(InputError, match="committed_scans"):
        hyps.commit([0], 0)
    with pytest.raises(InputError, match="committed_scans"):
        hyps.commit([0], 3)
    with pytest.raises(InputError, match="hypothesis 4"):
        hyps.commit([4], 1)


def test_estimator_commit_assigns_ids_in_selection_order() -> None:
    estimator = WindowEstimator(config=build_scenario("crossing", 0).config)
    hyps = hand_window()
    records = {7: _TrackRecord(7, rows=[1, 2])}
    carried, next_id = estimator._commit(hyps, np.array([3, 2, 0]), 2, records, 8)
    # Hypothesis 3 (born at scan 1) gets 8, hypothesis 2 gets 9 and ends; 7 goes on.
    assert next_id == 10
    assert {k: r.rows for k, r in records.items()} == {7: [1, 2, 10, 12], 8: [13], 9: [11]}
    assert [t.track_id for t in carried] == [7, 8]
    assert carried[1].mean.tolist() == [9.0]

    records = {7: _TrackRecord(7)}
    carried, next_id = estimator._commit(hyps, np.array([3, 2, 0]), 1, records, 8)
    # Hypothesis 3 is born after the committed scan: no id.
    assert next_id == 9
    assert {k: r.rows for k, r in records.items()} == {7: [10], 8: [11]}
    assert [t.track_id for t in carried] == [7, 8]
    assert [t.time for t in carried] == [1.0, 1.0]


def test_commit_matches_the_hypotheses_on_a_generated_window() -> None:
    scenario = build_scenario("crossing", 0)
    estimator = WindowEstimator(config=scenario.config)
    scans = scenario.scans[:4]
    first = estimator.generator.generate(scans[:2])
    carried = [
        c.carried(100 + i)
        for i, c in enumerate(first.commit(np.arange(first.count), 2))
        if c.state is not None
    ][:5]
    hyps = estimator.generator.generate(scans[2:], carried)
    assert hyps.count > 0 and np.any(hyps.tree_track_ids >= 0)
    nodes = hyps.nodes
    for committed in range(1, len(hyps.scans) + 1):
        out = {c.hypothesis: c for c in hyps.commit(np.arange(hyps.count), committed)}
        for h in range(hyps.count):
            path = nodes.path(int(hyps.leaf[h]))
            tree = int(hyps.tree[h])
            born_late = hyps.tree_track_ids[tree] < 0 and nodes.layer[path[0]] >= committed
            assert (h not in out) == born_late
            if born_late:
                continue
            c = out[h]
            dets = hyps.detections_of(h)
            dets = dets[hyps.detections.scan_position[dets] < committed]
            assert c.detections.tolist() == dets.tolist()
            assert c.rows.tolist() == hyps.detections.rows[dets].tolist()
            leaf = int(hyps.leaf[h])
            ended = not nodes.alive[leaf] and nodes.layer[leaf] < committed
            assert c.ended == ended
            assert (c.state is not None) == (not ended and nodes.layer[leaf] >= committed - 1)
            assert c.track_id == int(hyps.tree_track_ids[tree])
