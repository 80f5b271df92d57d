"""Plots of detections, truth and tracks (needs the optional ``matplotlib``).

Figures are drawn on matplotlib's object-oriented API (``matplotlib.figure.Figure``),
never through ``pyplot`` state or a forced backend: the ``draw_*`` functions draw on axes
a notebook owns (and shows), the ``plot_*`` functions write a PNG file.

Detections of range-bearing sensors are drawn at their Cartesian position
(``measurement.position_from_measurement``); tracks and truth use their ``x`` and
``y`` state columns.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mapassoc.data.io import TrackTable, TruthTable
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.models.sensor import Sensor

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["draw_comparison", "draw_tracks", "plot_comparison", "plot_tracks"]


def _xy(names: tuple[str, ...], states: np.ndarray) -> np.ndarray:
    if "x" not in names or "y" not in names:
        raise InputError(f"plotting needs x and y state columns, got {names}")
    return states[:, [names.index("x"), names.index("y")]]


def _figure(*, figsize: tuple[float, float], dpi: int) -> Figure:
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise InputError("plotting needs matplotlib: pip install 'mapassoc[plot]'") from None
    return Figure(figsize=figsize, dpi=dpi)


def _save(fig: Figure, path: str | Path) -> Path:
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out)
    return out


def draw_tracks(
    ax: Axes,
    *,
    scans: Sequence[Scan],
    sensors: Mapping[str, Sensor],
    tracks: TrackTable,
    truth: TruthTable | None = None,
    title: str = "",
) -> None:
    """Draw the detections (grey), truth (dashed) and tracks (coloured) on ``ax``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    scans : sequence of Scan
    sensors : mapping of str to Sensor
    tracks : TrackTable
    truth : TruthTable, optional
    title : str
    """
    from matplotlib import colormaps

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
    cmap = colormaps["tab10"]
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


def plot_tracks(
    path: str | Path,
    *,
    scans: Sequence[Scan],
    sensors: Mapping[str, Sensor],
    tracks: TrackTable,
    truth: TruthTable | None = None,
    title: str = "",
) -> Path:
    """Write a PNG of :func:`draw_tracks`; returns its path."""
    fig = _figure(figsize=(8, 8), dpi=110)
    draw_tracks(
        fig.add_subplot(), scans=scans, sensors=sensors, tracks=tracks, truth=truth, title=title
    )
    return _save(fig, path)


_COMPARISON_PANELS = (
    ("gospa", "GOSPA (mean over time)"),
    ("ospa2", "OSPA(2) (trajectories)"),
    ("id_switches", "ID switches"),
    ("seconds", "seconds per run"),
)


def draw_comparison(axes: Sequence[Axes], summary: pd.DataFrame) -> None:
    """Grouped bars per scenario and tracker of GOSPA, OSPA(2), ID switches and time.

    Parameters
    ----------
    axes : sequence of 4 matplotlib Axes
    summary : pandas.DataFrame
        :func:`mapassoc.apps.compare.summarize` of a comparison.
    """
    scenarios = list(dict.fromkeys(summary["scenario"]))
    trackers = list(dict.fromkeys(summary["tracker"]))
    width = 0.8 / max(len(trackers), 1)
    positions = np.arange(len(scenarios))
    for ax, (column, label) in zip(axes, _COMPARISON_PANELS, strict=True):
        for i, tracker in enumerate(trackers):
            rows = summary[summary["tracker"] == tracker].set_index("scenario")
            values = [
                float(rows[column].get(s, np.nan)) if column in rows else np.nan
                for s in scenarios
            ]
            ax.bar(positions + i * width, values, width, label=tracker)
        ax.set_xticks(positions + 0.4 - width / 2, scenarios, rotation=20)
        ax.set_title(label)
        if column == "seconds":
            ax.set_yscale("log")
    axes[0].legend(fontsize=8)


def plot_comparison(path: str | Path, summary: pd.DataFrame) -> Path:
    """Write a PNG of :func:`draw_comparison`; returns its path."""
    fig = _figure(figsize=(12, 8), dpi=100)
    draw_comparison([fig.add_subplot(2, 2, i + 1) for i in range(4)], summary)
    return _save(fig, path)
