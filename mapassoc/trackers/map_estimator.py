"""The MAP window estimator (:class:`~mapassoc.estimator.pipeline.WindowEstimator`) as a
:class:`~mapassoc.trackers.base.Tracker`."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence

from mapassoc.data.config import Config, check_config
from mapassoc.data.scans import Scan
from mapassoc.estimator.pipeline import EstimateResult, WindowEstimator
from mapassoc.trackers.base import CountSeries, TrackerOutput, check_scans

__all__ = ["MapTracker", "MapForwardTracker", "rows_to_associations"]


def rows_to_associations(
    scans: Sequence[Scan], track_rows: dict[int, tuple[int, ...]]
) -> dict[int, dict[int, int]]:
    """Track id -> {scan index -> detection index}, from the detection rows each track used."""
    where = {int(row): (k, j) for k, scan in enumerate(scans) for j, row in enumerate(scan.rows)}
    return {tid: dict(where[row] for row in rows) for tid, rows in track_rows.items()}


def count_series(result: EstimateResult) -> CountSeries:
    """p(K | Z) of every window of a run, over the window's time span."""
    w = result.windows
    return CountSeries.from_rows(
        [r.start_time for r in w], [r.end_time for r in w], [r.p_k for r in w]
    )


class MapTracker:
    """Sliding-window MAP track sets with the posterior over K (this library's method).

    Parameters
    ----------
    config : Config
        Models and :class:`~mapassoc.data.settings.EstimatorSettings` (window length,
        K prior and estimator, solver, limits).
    name : str
        Label in comparisons.
    """

    def __init__(self, *, config: Config, name: str = "map") -> None:
        self.config = check_config(config)
        self.name = name
        self._estimator = WindowEstimator(config=config)

    def track(self, scans: Sequence[Scan]) -> TrackerOutput:
        """Run the estimator over ``scans``; ``details`` is its ``EstimateResult``."""
        scans = check_scans(scans, self.config)
        start = time.perf_counter()
        result = self._estimator.run(scans)
        seconds = time.perf_counter() - start
        return TrackerOutput(
            tracks=result.tracks,
            seconds=seconds,
            associations=rows_to_associations(scans, result.track_rows),
            counts=count_series(result),
            details=result,
        )


class MapForwardTracker(MapTracker):
    """The MAP estimator's forward pass alone: each window's decision is final.

    The same estimator with ``refinement.passes = 0`` (no refinement of the whole
    recording, :mod:`mapassoc.estimator.refinement`): in comparisons it shows what the
    refinement adds.
    """

    def __init__(self, *, config: Config, name: str = "map-forward") -> None:
        config = check_config(config)
        no_refinement = dataclasses.replace(config.estimator.refinement, passes=0)
        forward = dataclasses.replace(
            config, estimator=dataclasses.replace(config.estimator, refinement=no_refinement)
        )
        super().__init__(config=forward, name=name)
