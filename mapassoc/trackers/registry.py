"""Tracking methods by name: one table, :data:`TRACKERS`.

Each row names a method, the module and class that implement it (imported only when the
tracker is built) and whether it needs the true associations (the oracle).  Every class
is built as ``cls(config=config)`` (plus ``origins=`` for the oracle), so every method
runs on exactly the same motion, sensor, clutter and birth models.  Adding a method is
one module with a class implementing :class:`~mapassoc.trackers.base.Tracker` and one row
here.

=========  =====================================  ======================================
name       class                                  method
=========  =====================================  ======================================
``map``    :class:`~.map_estimator.MapTracker`    sliding-window MAP track sets, p(K | Z),
                                                  refined over the whole recording
``map-forward`` :class:`~.map_estimator.MapForwardTracker`  the forward pass alone
``gnn``    :class:`~.gnn.GnnTracker`              global nearest neighbour (2-D assignment)
``jpda``   :class:`~.jpda.JpdaTracker`            joint probabilistic data association
``mht``    :class:`~.mht.MhtTracker`              track-oriented MHT, N-scan pruning
``flow``   :class:`~.flow.FlowTracker`            min-cost network flow over a window
``lp``     :class:`~.lp_relaxation.LpRelaxationTracker`  LP relaxation of the MAP program
``oracle`` :class:`~.oracle.OracleTracker`        smoother on the true associations
=========  =====================================  ======================================
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mapassoc.errors import InputError

if TYPE_CHECKING:  # the table is read by the command line's parser: keep it light
    from mapassoc.data.config import Config
    from mapassoc.data.io import Origins
    from mapassoc.trackers.base import Tracker

__all__ = ["DEFAULT_TRACKERS", "TRACKERS", "TrackerSpec", "build_tracker", "tracker_names"]


@dataclass(frozen=True)
class TrackerSpec:
    """One row of :data:`TRACKERS`.

    Parameters
    ----------
    name : str
    module, class_name : str
        Where the tracker class lives; imported by :meth:`build` only.
    description : str
        One line for listings.
    needs_truth : bool
        Whether the tracker needs the true origins of the detections (simulated data).
    """

    name: str
    module: str
    class_name: str
    description: str
    needs_truth: bool = False

    def build(self, *, config: Config, origins: Origins | None = None) -> Tracker:
        """The tracker with its default options on ``config``."""
        cls = getattr(importlib.import_module(self.module), self.class_name)
        if self.needs_truth:
            if origins is None:
                raise InputError(
                    f"tracker '{self.name}' needs the true origins of the detections "
                    "(simulated data); none were given"
                )
            return cls(config=config, origins=origins)
        return cls(config=config)


TRACKERS: dict[str, TrackerSpec] = {
    spec.name: spec
    for spec in (
        TrackerSpec(
            "map",
            "mapassoc.trackers.map_estimator",
            "MapTracker",
            "sliding-window MAP track sets with the posterior over K (this library)",
        ),
        TrackerSpec(
            "map-forward",
            "mapassoc.trackers.map_estimator",
            "MapForwardTracker",
            "the MAP estimator's forward pass alone (no refinement of the whole recording)",
        ),
        TrackerSpec(
            "gnn",
            "mapassoc.trackers.gnn",
            "GnnTracker",
            "global nearest neighbour: 2-D assignment per scan, score-based track management",
        ),
        TrackerSpec(
            "jpda",
            "mapassoc.trackers.jpda",
            "JpdaTracker",
            "joint probabilistic data association, exact marginals per cluster",
        ),
        TrackerSpec(
            "mht",
            "mapassoc.trackers.mht",
            "MhtTracker",
            "track-oriented MHT: hypothesis trees, N-scan pruning, set-packing global hypothesis",
        ),
        TrackerSpec(
            "flow",
            "mapassoc.trackers.flow",
            "FlowTracker",
            "min-cost network flow over detections, every number of tracks in one pass",
        ),
        TrackerSpec(
            "lp",
            "mapassoc.trackers.lp_relaxation",
            "LpRelaxationTracker",
            "LP relaxation of the MAP program (cvxpy + Clarabel) with integrality certificates",
        ),
        TrackerSpec(
            "oracle",
            "mapassoc.trackers.oracle",
            "OracleTracker",
            "Kalman smoother on the true associations (simulated data only)",
            needs_truth=True,
        ),
    )
}


DEFAULT_TRACKERS: tuple[str, ...] = (
    "map",
    "map-forward",
    "gnn",
    "jpda",
    "mht",
    "flow",
    "lp",
    "oracle",
)
"""The methods ``mapassoc compare`` runs when none are named."""


def tracker_names() -> list[str]:
    """Names of every tracker, in table order."""
    return list(TRACKERS)


def build_tracker(name: str, *, config: Config, origins: Origins | None = None) -> Tracker:
    """Build the tracker ``name`` with its default options.

    Raises
    ------
    InputError
        Unknown name (the message lists the known ones), or the oracle without origins.
    """
    spec = TRACKERS.get(name)
    if spec is None:
        raise InputError(f"unknown tracker {name!r}; known trackers: {', '.join(TRACKERS)}")
    return spec.build(config=config, origins=origins)
