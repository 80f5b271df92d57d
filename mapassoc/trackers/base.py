"""The one interface every tracking method implements: scans in, a track table out.

A tracker is built from a :class:`~mapassoc.data.config.Config` (the same motion, sensor,
clutter and birth models for every method) plus its own keyword-only options, and
``tracker.track(scans)`` returns a :class:`TrackerOutput`.  Methods that end with hard
associations (MAP window estimator, GNN, MHT, network flow, the oracle) report them and
smooth them with :func:`mapassoc.filtering.smoothing.smooth_tracks`, so their states differ
only through the associations; methods with soft associations (JPDA) report their own
filtered states.  A method that estimates the number of targets reports it as a
:class:`CountSeries`.  The two output records live in :mod:`mapassoc.data.outputs`
(evaluation scores them without knowing the trackers) and are re-exported here.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

from mapassoc.data.config import Config
from mapassoc.data.outputs import CountSeries, TrackerOutput
from mapassoc.data.scans import Scan
from mapassoc.data.scans import check_scans as check_scan_list

__all__ = ["CountSeries", "Tracker", "TrackerOutput", "check_scans"]


@runtime_checkable
class Tracker(Protocol):
    """A tracking method: ``name`` and ``track(scans) -> TrackerOutput``."""

    name: str

    def track(self, scans: Sequence[Scan]) -> TrackerOutput:
        """Estimate tracks over all ``scans`` (sorted by (time, sensor))."""
        ...


def check_scans(scans: Sequence[Scan], config: Config) -> list[Scan]:
    """The scans as a list, after the checks every tracker makes up front
    (:func:`mapassoc.data.scans.check_scans`, the estimator's own).

    Raises
    ------
    InputError
        Not a sequence of Scan, no scans, scans out of (time, sensor) order, or a scan
        of a sensor the configuration does not define.
    """
    return check_scan_list(scans, config.sensors, what="track")
