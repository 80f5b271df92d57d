"""Plots of detections, truth and tracks (needs the optional ``matplotlib``).

Detections of range-bearing sensors are drawn at their Cartesian position
(``measurement.position_from_measurement``); tracks and truth use their ``x`` and
``y`` state columns.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from mapassoc.data.io import TrackTable, TruthTable
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.models.sensor import Sensor

__all__ = ["plot_tracks"]


def _xy(names: tuple[str, ...], states: np.ndarray) -> np.ndarray:
    if "x" not in names or "y" not in names:
        raise InputError(f"plotting needs x and y state columns, got {names}")
    return states[:, [names.index("x"), names.index("y")]]


def plot_tracks(
    path: str | Path,
    *,
    scans: Sequence[Scan],
    sensors: Mapping[str, Sensor],
    tracks: TrackTable,
    truth: TruthTable | None = None,
    title: str = "",
) -> Path:
    """Write a PNG of the detections (grey), truth (dashed) and tracks (coloured).

    Parameters
    ----------
    path : str or Path
        Output PNG file.
    scans : sequence of Scan
    sensors : mapping of str to Sensor
    tracks : TrackTable
    truth : TruthTable, optional
    title : str

    Returns
    -------
    Path
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise InputError("plotting needs matplotlib: pip install 'mapassoc[plot]'") from None
    fig, ax = plt.subplots(figsize=(8, 8), dpi=110)
    points = []
    for scan in scans:
        model = sensors[scan.sensor].measurement
        for z in scan.detections:
            points.append(model.position_from_measurement(z)[0][:2])
    if points:
        pts = np.array(points)
        ax.scatter(pts[:, 0], pts[:, 1], s=4, c="0.7", label="detections", zorder=1)
    if truth is not None and truth.target_ids.size:
        xy = _xy(truth.state_names, truth.states)
        for i, tid in enumerate(np.unique(truth.target_ids)):
            sel = truth.target_ids == tid
            order = np.argsort(truth.times[sel], kind="stable")
            ax.plot(*xy[sel][order].T, "k--", lw=1.2, label="truth" if i == 0 else None, zorder=2)
    cmap = plt.get_cmap("tab10")
    if tracks.track_ids.size:
        xy = _xy(tracks.state_names, tracks.states)
        for i, tid in enumerate(np.unique(tracks.track_ids)):
            sel = tracks.track_ids == tid
            order = np.argsort(tracks.times[sel], kind="stable")
            line = xy[sel][order]
            ax.plot(*line.T, "-", lw=2.0, color=cmap(i % 10), zorder=3)
            ax.annotate(str(int(tid)), line[0], fontsize=8, color=cmap(i % 10))
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(title or "mapassoc tracks")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out
