"""The oracle tracker: a Kalman smoother run on the true associations.

Given the true origin of every detection (simulated data), each target's detections are
filtered and smoothed as one track by :func:`mapassoc.filtering.smoothing.smooth_tracks`,
exactly as every tracker's output is.  It is the reference an association method is
compared against: its errors are estimation errors only, never association errors.
"""

from __future__ import annotations

from collections.abc import Sequence

from mapassoc.data.config import Config, check_config
from mapassoc.data.io import Origins, TrackTable
from mapassoc.data.scans import Scan, check_scans
from mapassoc.errors import InputError
from mapassoc.filtering.smoothing import smooth_tracks
from mapassoc.validation import check_instance

__all__ = ["oracle_tracks", "true_associations"]


def oracle_tracks(scans: Sequence[Scan], origins: Origins, config: Config) -> TrackTable:
    """Smoothed tracks of every target on its true detections.

    Parameters
    ----------
    scans : sequence of Scan
        Sorted by (time, sensor) (:func:`mapassoc.data.scans.check_scan_order`).
    origins : Origins
        Origin of every detection row of ``scans`` (``-1`` for a false alarm).
    config : Config
        Motion model, sensors (every scan's sensor must be configured) and birth model
        (single-point initiation priors).

    Returns
    -------
    TrackTable
        One row per target per scan from its first to its last detection (scans of every
        sensor count): ``track_id`` is the target id, ``states`` the smoothed mean in the
        motion model's state space, ``variances`` the smoothed covariance diagonal,
        ``detection_rows`` the row used or ``-1``.  Sorted by (time, track_id), then scan
        order.

    Raises
    ------
    InputError
        ``config`` not a Config, ``scans`` not a run of scans
        (:func:`mapassoc.data.scans.check_scans`: none, unsorted, an unknown sensor),
        ``origins`` not an Origins, a detection row without an origin or an origin
        row without a detection, or a target with two detections in one scan.
    """
    config = check_config(config)
    scans = check_scans(scans, config.sensors, what="track")
    check_instance(
        "oracle_tracks: origins",
        origins,
        Origins,
        hint="read them with mapassoc.data.formats.read_origins_file(path)",
    )
    return smooth_tracks(scans, true_associations(scans, origins), config)


def true_associations(scans: Sequence[Scan], origins: Origins) -> dict[int, dict[int, int]]:
    """Every target's true detections: target id -> {scan index: detection index}.

    The associations the oracle smooths (:func:`oracle_tracks`), validated once here so
    that code scoring the truth in other ways (a likelihood, parameter estimates) reads
    the same associations.

    Parameters
    ----------
    scans : sequence of Scan
    origins : Origins
        Origin of every detection row of ``scans`` (``-1`` for a false alarm).

    Returns
    -------
    dict of int to dict of int to int
        Targets with at least one detection, each with its scans in order.

    Raises
    ------
    InputError
        ``origins`` not an Origins, a detection row without an origin or an origin
        row without a detection, or a target with two detections in one scan.
    """
    check_instance(
        "true_associations: origins",
        origins,
        Origins,
        hint="read them with mapassoc.data.formats.read_origins_file(path)",
    )
    origin_of = dict(zip(origins.rows.tolist(), origins.target_ids.tolist(), strict=True))
    scan_rows = {int(row) for scan in scans for row in scan.rows}
    unknown = sorted(set(origin_of) - scan_rows)
    if unknown:
        raise InputError(
            f"origins name rows {unknown[:5]} that are not detection rows of the scans"
        )

    per_target: dict[int, dict[int, int]] = {}
    for scan_index, scan in enumerate(scans):
        for detection_index, row in enumerate(scan.rows.tolist()):
            if row not in origin_of:
                raise InputError(
                    f"detection row {row} (sensor {scan.sensor!r}, time {scan.time}) has no origin"
                )
            target = origin_of[row]
            if target < 0:
                continue
            target_scans = per_target.setdefault(target, {})
            if scan_index in target_scans:
                other = int(scan.rows[target_scans[scan_index]])
                raise InputError(
                    f"target {target} has two detections (rows {other} and {row}) in the scan "
                    f"of sensor {scan.sensor!r} at time {scan.time}; at most one is allowed"
                )
            target_scans[scan_index] = detection_index
    return per_target
