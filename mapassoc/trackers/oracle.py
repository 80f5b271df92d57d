"""The oracle (a smoother on the true associations) as a
:class:`~mapassoc.trackers.base.Tracker`: the reference every method is compared with."""

from __future__ import annotations

import time
from collections.abc import Sequence

from mapassoc.data.config import Config, check_config
from mapassoc.data.io import Origins
from mapassoc.data.scans import Scan
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.trackers.base import TrackerOutput, check_scans

__all__ = ["OracleTracker"]


class OracleTracker:
    """Tracks smoothed on the true origin of every detection (simulated data only).

    Parameters
    ----------
    config : Config
    origins : Origins
        The true origin of every detection row.
    name : str
    """

    def __init__(self, *, config: Config, origins: Origins, name: str = "oracle") -> None:
        self.config = check_config(config)
        self.origins = origins
        self.name = name

    def track(self, scans: Sequence[Scan]) -> TrackerOutput:
        scans = check_scans(scans, self.config)
        start = time.perf_counter()
        tracks = oracle_tracks(scans, self.origins, self.config)
        origin_of = dict(
            zip(self.origins.rows.tolist(), self.origins.target_ids.tolist(), strict=True)
        )
        associations: dict[int, dict[int, int]] = {}
        for k, scan in enumerate(scans):
            for j, row in enumerate(scan.rows.tolist()):
                target = origin_of[row]
                if target >= 0:
                    associations.setdefault(target, {})[k] = j
        return TrackerOutput(
            tracks=tracks, seconds=time.perf_counter() - start, associations=associations
        )
