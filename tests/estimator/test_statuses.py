"""Window and cluster statuses: ordered enums that are also their JSON strings."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from mapassoc.estimator.cluster_solving import CLUSTER_STATUSES, ClusterStatus
from mapassoc.estimator.pipeline import WINDOW_STATUSES, WindowSolution, WindowStatus


def test_statuses_are_their_strings_in_order() -> None:
    assert [str(s) for s in WINDOW_STATUSES] == ["exact", "capped", "bounded", "time_limit"]
    assert [str(s) for s in CLUSTER_STATUSES] == ["exact", "bounded", "time_limit"]
    assert json.dumps({"status": WindowStatus.TIME_LIMIT}) == '{"status": "time_limit"}'
    assert WindowStatus.CAPPED == "capped" and ClusterStatus.BOUNDED == "bounded"


@pytest.mark.parametrize("capped", [False, True])
@pytest.mark.parametrize(
    "clusters",
    [(), ("bounded",), ("time_limit", "bounded"), ("bounded", "time_limit")],
)
def test_window_status_is_the_worst_that_applies(capped: bool, clusters: tuple[str, ...]) -> None:
    window = SimpleNamespace(
        hypotheses=SimpleNamespace(nodes_capped=int(capped)),
        bounded_clusters=[SimpleNamespace(status=ClusterStatus(c)) for c in clusters],
        pruning_cut_short=False,
    )
    status = WindowSolution.status.fget(window)  # type: ignore[attr-defined]
    expected = "time_limit" if "time_limit" in clusters else (
        "bounded" if clusters else ("capped" if capped else "exact")
    )
    assert status is WindowStatus(expected)
    # Pruning skipped for the deadline is time_limit whatever the clusters say.
    window.pruning_cut_short = True
    assert WindowSolution.status.fget(window) is WindowStatus.TIME_LIMIT  # type: ignore[attr-defined]
