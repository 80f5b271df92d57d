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
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from mapassoc.data.frames import GeodeticPoint
from mapassoc.data.io import TrackTable, TruthTable
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.models.sensor import Sensor

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.artist import Artist
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
    """Save ``fig`` to ``path`` in the format of its suffix (PNG without one), atomically:
    a failure leaves the previous file whole, or none."""
    import io

    from mapassoc.apps.run_folders import write_atomically

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    image = io.BytesIO()
    # ``tight`` keeps a legend drawn outside the axes inside the image.
    fig.savefig(image, format=out.suffix[1:].lower() or "png", bbox_inches="tight",
                pad_inches=0.15)  # fmt: skip
    write_atomically(out, image.getvalue())
    return out


#: At most this many estimated tracks get a legend entry each; more get one entry.
TRACK_LEGEND_LIMIT = 12

# Qualitative colours of the tracks, one per legend entry up to TRACK_LEGEND_LIMIT: tab10
# without its grey (grey is the detections' and truth's colour), then navy, teal and maroon.
_TRACK_COLOURS = (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22",
    "#17becf", "#000075", "#469990", "#800000",
)  # fmt: skip
_LABEL_FONTSIZE = 9.5
_LABEL_OFFSET_POINTS = 9.0


def _check_unit(name: str, value: object) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip():
        raise InputError(f"{name} must be None or a non-empty string such as 'm', got {value!r}")
    return value.strip()


def _axis_label(axis: str, unit: str | None) -> str:
    return f"{axis} [{unit}]" if unit is not None else f"{axis} (length unit of the data)"


def _lines(
    ids: np.ndarray, times: np.ndarray, xy: np.ndarray
) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """(id, times, positions) per id, in time order."""
    out = []
    for tid in np.unique(ids):
        sel = ids == tid
        order = np.argsort(times[sel], kind="stable")
        out.append((int(tid), times[sel][order], xy[sel][order]))
    return out


def _heading(line: np.ndarray, *, at_end: bool, min_length: float) -> np.ndarray | None:
    """Unit vector of motion at one end of ``line``, over at least ``min_length``.

    The vector points along the motion (from earlier to later points).  ``None`` when the
    line never leaves a ball of that radius around the end point (no direction to show).
    """
    pts = line if at_end else line[::-1]
    tip = pts[-1]
    for back in pts[-2::-1]:
        step = tip - back
        length = float(np.hypot(*step))
        if length >= min_length:
            unit = step / length
            return unit if at_end else -unit
    return None


def _alignment(direction: np.ndarray) -> tuple[str, str]:
    """Text alignment ``(ha, va)`` that keeps a label on the side ``direction`` points to."""
    dx, dy = float(direction[0]), float(direction[1])
    ha = "left" if dx > 0.35 else "right" if dx < -0.35 else "center"
    va = "bottom" if dy > 0.35 else "top" if dy < -0.35 else "center"
    return ha, va


def _span(times: np.ndarray, time_unit: str | None) -> str:
    first, last = float(times[0]), float(times[-1])
    unit = f" {time_unit}" if time_unit is not None else ""
    return f"t {first:g}\N{EN DASH}{last:g}{unit}"


def _check_draw_arguments(
    scans: Sequence[Scan],
    sensors: Mapping[str, Sensor],
    *,
    title: object,
    length_unit: object,
    time_unit: object,
    legend: object,
) -> tuple[str | None, str | None]:
    """Refuse :func:`draw_tracks`'s bad arguments; returns the checked length and time
    units."""
    checked_length = _check_unit("length_unit", length_unit)
    checked_time = _check_unit("time_unit", time_unit)
    if not isinstance(title, str):
        raise InputError(f"title must be a string, got {title!r}")
    if not isinstance(legend, bool):
        raise InputError(f"legend must be True or False, got {legend!r}")
    for scan in scans:
        if scan.sensor not in sensors:
            raise InputError(
                f"scan at time {scan.time:g} is from sensor {scan.sensor!r}, which is not in "
                f"sensors (got {sorted(sensors)})"
            )
    return checked_length, checked_time


_Line = tuple[int, np.ndarray, np.ndarray]
"""(id, times of shape (m,), positions of shape (m, 2)), as :func:`_lines` gives them."""


@dataclass(frozen=True, eq=False)
class _Scene:
    """What :func:`draw_tracks` draws, in plot coordinates.

    Attributes
    ----------
    detections : ndarray, shape (n, 2)
        Every detection's position.
    targets, estimated : list of (int, ndarray, ndarray)
        True targets and estimated tracks: id, times (m,) and positions (m, 2).
    min_length : float
        Shortest stretch of a line that shows its heading (a few thousandths of the
        plot's extent).
    """

    detections: np.ndarray
    targets: list[_Line]
    estimated: list[_Line]
    min_length: float


def _scene(
    scans: Sequence[Scan],
    sensors: Mapping[str, Sensor],
    tracks: TrackTable,
    truth: TruthTable | None,
) -> _Scene:
    """The detections, truth and tracks as x-y points and lines."""
    points = [
        sensors[scan.sensor].measurement.position_from_measurement(z)[0][:2]
        for scan in scans
        for z in scan.detections
    ]
    detections = np.array(points, dtype=float).reshape(-1, 2)
    targets = (
        _lines(truth.target_ids, truth.times, _xy(truth.state_names, truth.states))
        if truth is not None and truth.target_ids.size
        else []
    )
    estimated = (
        _lines(tracks.track_ids, tracks.times, _xy(tracks.state_names, tracks.states))
        if tracks.track_ids.size
        else []
    )
    everything = np.vstack([detections, *(line for _, _, line in targets + estimated)])
    extent = float(np.ptp(everything, axis=0).max()) if everything.shape[0] else 1.0
    return _Scene(
        detections=detections,
        targets=targets,
        estimated=estimated,
        min_length=0.004 * extent if extent > 0 else 0.0,
    )


def _arrow_head(
    ax: Axes,
    line: np.ndarray,
    heading: np.ndarray,
    min_length: float,
    *,
    colour: str,
    scale: float,
    zorder: int,
) -> None:
    """An arrow head of size ``scale`` at the end of ``line`` (shape (m, 2)), pointing
    along the unit vector ``heading`` (shape (2,))."""
    ax.annotate(
        "", xy=line[-1], xytext=line[-1] - heading * 2 * min_length,
        arrowprops={"arrowstyle": "-|>", "color": colour, "lw": 0,
                    "mutation_scale": scale, "shrinkA": 0, "shrinkB": 0},
        zorder=zorder,
    )  # fmt: skip


def _draw_detections(ax: Axes, detections: np.ndarray) -> list[Artist]:
    """Detections (shape (n, 2)) as small grey points; their legend handle, if any."""
    from matplotlib.lines import Line2D

    count = detections.shape[0]
    if not count:
        return []
    # Smaller points when there are many, so clutter stays a light texture.
    size = float(np.clip(5.0 * np.sqrt(2000.0 / count), 1.5, 5.0))
    ax.scatter(detections[:, 0], detections[:, 1], s=size, c="0.68", linewidths=0, zorder=1)
    return [
        Line2D([], [], ls="", marker="o", ms=3.5, mfc="0.68", mec="none",
               label=f"detections ({count})")
    ]  # fmt: skip


def _draw_truth(ax: Axes, targets: list[_Line], min_length: float) -> list[Artist]:
    """True targets as thick dashed grey lines with an arrow head; their legend handle."""
    from matplotlib.lines import Line2D

    # Line properties shared by the truth lines and their legend entry (matplotlib checks them).
    truth_style: dict[str, Any] = {"color": "0.1", "lw": 3.2, "alpha": 0.4, "ls": (0, (4, 2))}
    for _, _, line in targets:
        ax.plot(*line.T, zorder=2, solid_capstyle="round", **truth_style)
        heading = _heading(line, at_end=True, min_length=min_length)
        if heading is not None:
            _arrow_head(ax, line, heading, min_length, colour="0.35", scale=16, zorder=2)
    if not targets:
        return []
    return [Line2D([], [], label=f"truth ({len(targets)} targets)", **truth_style)]


def _track_marker_handles() -> list[Artist]:
    """Legend handles of a track's start and end markers."""
    from matplotlib.lines import Line2D

    return [
        Line2D([], [], ls="", marker="o", ms=6, mfc="white", mec="0.2", label="track start"),
        Line2D([], [], ls="", marker=">", ms=7, color="0.2", label="track end, heading"),
    ]


def _draw_track_ids(
    ax: Axes, tid: int, colour: str, ends: list[tuple[np.ndarray, np.ndarray | None]]
) -> None:
    """The id of a track written beyond each of ``ends`` ((position (2,), outward unit
    vector (2,) or None)), on the side it points to (above when None)."""
    from matplotlib import patheffects

    halo = [patheffects.withStroke(linewidth=3.0, foreground="white")]
    for where, outward in ends:
        away = outward if outward is not None else np.array([0.0, 1.0])
        ha, va = _alignment(away)
        ax.annotate(
            # The stubs ask a tuple for ``xy``; matplotlib takes the (2,) array as it is.
            str(tid), xy=cast("tuple[float, float]", where),
            xytext=tuple(_LABEL_OFFSET_POINTS * away), textcoords="offset points",
            fontsize=_LABEL_FONTSIZE, fontweight="bold", color=colour, path_effects=halo,
            zorder=5, ha=ha, va=va,
        )  # fmt: skip


def _draw_track(
    ax: Axes, index: int, track: _Line, *, each: bool, min_length: float, time_unit: str | None
) -> Artist:
    """Track number ``index``: its coloured line (returned: its legend handle), an open
    circle at its start, an arrow head at its end and its id (at both ends when ``each``
    track has its own legend entry, else at the end only)."""
    tid, times, line = track
    colour = _TRACK_COLOURS[index % len(_TRACK_COLOURS)]
    label = f"track {tid}  ({_span(times, time_unit)})" if each else None
    (drawn,) = ax.plot(
        *line.T, "-", lw=1.6, color=colour, alpha=0.9, zorder=3, label=label,
        solid_capstyle="round",
    )  # fmt: skip
    ax.plot(*line[0], "o", ms=6, mfc="white", mec=colour, mew=1.6, zorder=4)
    end_heading = _heading(line, at_end=True, min_length=min_length)
    if end_heading is not None:
        _arrow_head(ax, line, end_heading, min_length, colour=colour, scale=18, zorder=4)
    start_heading = _heading(line, at_end=False, min_length=min_length)
    # Labels sit beyond each end, on the side the track leaves it (ahead of the
    # arrow, behind the start); a track with no direction gets one label above.
    ends = [(line[-1], end_heading)]
    if each and len(line) > 1:
        ends.append((line[0], None if start_heading is None else -start_heading))
    _draw_track_ids(ax, tid, colour, ends)
    return drawn


def _draw_estimated(
    ax: Axes, estimated: list[_Line], min_length: float, time_unit: str | None
) -> list[Artist]:
    """Every estimated track (:func:`_draw_track`); the legend handles: markers, then one
    per track up to :data:`TRACK_LEGEND_LIMIT` tracks, else one for them all."""
    from matplotlib.lines import Line2D

    if not estimated:
        return []
    handles = _track_marker_handles()
    each = len(estimated) <= TRACK_LEGEND_LIMIT
    for i, track in enumerate(estimated):
        drawn = _draw_track(ax, i, track, each=each, min_length=min_length, time_unit=time_unit)
        if each:
            handles.append(drawn)
    if not each:
        label = f"tracks ({len(estimated)}), id at end"
        handles.append(Line2D([], [], lw=1.6, color=_TRACK_COLOURS[0], label=label))
    return handles


def origin_labels(origin: GeodeticPoint) -> tuple[str, str]:
    """Axis labels of a geodetic recording's plane: metres east and north of the origin."""
    where = f"{abs(origin.latitude):.4f}\N{DEGREE SIGN}{'N' if origin.latitude >= 0 else 'S'} "
    where += f"{abs(origin.longitude):.4f}\N{DEGREE SIGN}{'E' if origin.longitude >= 0 else 'W'}"
    return f"east of {where} [m]", f"north of {where} [m]"


def _finish_axes(
    ax: Axes,
    handles: list[Artist],
    *,
    title: str,
    length_unit: str | None,
    legend: bool,
    origin: GeodeticPoint | None = None,
) -> None:
    """Equal aspect, axis labels, title and (when ``legend``) the legend beside the axes."""
    ax.set_aspect("equal", adjustable="datalim")
    if origin is None:
        ax.set_xlabel(_axis_label("x", length_unit))
        ax.set_ylabel(_axis_label("y", length_unit))
    else:
        xlabel, ylabel = origin_labels(origin)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
    ax.set_title(title or "mapassoc tracks")
    if legend and handles:
        ax.legend(
            handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
            fontsize=9, frameon=False, handlelength=3.0,
        )  # fmt: skip


def draw_tracks(
    ax: Axes,
    *,
    scans: Sequence[Scan],
    sensors: Mapping[str, Sensor],
    tracks: TrackTable,
    truth: TruthTable | None = None,
    title: str = "",
    length_unit: str | None = None,
    time_unit: str | None = None,
    legend: bool = True,
    origin: GeodeticPoint | None = None,
) -> None:
    """Draw detections, truth and estimated tracks on ``ax``, with a legend beside it.

    Detections are small grey points.  Each true target is a thick dashed grey line
    under the tracks, with an arrow head at its last position.  Each estimated track is
    a coloured line on top (thin and slightly transparent, so the truth shows through),
    with an open circle at its first position, an arrow head at its last one and its id
    written in bold with a white halo.  The legend sits outside the axes, to the right,
    so it never covers data.  With at most ``TRACK_LEGEND_LIMIT`` tracks the legend has
    one entry per track (id and time span) and the id is written at both ends; with more,
    one entry ``tracks (N)`` and the id at the track's end only (both ends of 50 tracks
    are unreadable).  A track (or target) whose positions all lie within a few
    thousandths of the plot's extent of its end has no arrow (no direction to show).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    scans : sequence of Scan
    sensors : mapping of str to Sensor
        Every scan's sensor (its measurement model places the detections).
    tracks : TrackTable
    truth : TruthTable, optional
    title : str
        Axes title; empty gives "mapassoc tracks".
    length_unit : str, optional
        Unit of the x and y positions (e.g. ``"m"``): the axes read ``x [m]``.  ``None``
        says the data's own length unit, which the plot cannot know.
    time_unit : str, optional
        Unit of the scan times, shown with each track's time span in the legend
        (e.g. ``"s"`` or ``"scans"``).
    legend : bool
        Draw the legend (outside the axes, upper right).  ``False`` for a grid of small
        panels where one legend is enough.
    origin : GeodeticPoint, optional
        The origin of a geodetic recording's plane (``summary.json``'s
        ``recording.origin``): the axes then read metres east and north of it.

    Raises
    ------
    InputError
        A unit that is not ``None`` or a non-empty string, a scan whose sensor is not in
        ``sensors``, or tracks or truth without ``x`` and ``y`` state columns.
    """
    length_unit, time_unit = _check_draw_arguments(
        scans, sensors, title=title, length_unit=length_unit, time_unit=time_unit, legend=legend
    )
    scene = _scene(scans, sensors, tracks, truth)
    handles = [
        *_draw_detections(ax, scene.detections),
        *_draw_truth(ax, scene.targets, scene.min_length),
        *_draw_estimated(ax, scene.estimated, scene.min_length, time_unit),
    ]
    _finish_axes(
        ax, handles, title=title, length_unit=length_unit, legend=legend, origin=origin
    )


def plot_tracks(
    path: str | Path,
    *,
    scans: Sequence[Scan],
    sensors: Mapping[str, Sensor],
    tracks: TrackTable,
    truth: TruthTable | None = None,
    title: str = "",
    length_unit: str | None = None,
    time_unit: str | None = None,
    origin: GeodeticPoint | None = None,
) -> Path:
    """Write a PNG of :func:`draw_tracks` (legend beside the axes); returns its path.

    ``length_unit``, ``time_unit`` and ``origin`` are :func:`draw_tracks`'s.
    """
    fig = _figure(figsize=(10.5, 8), dpi=110)
    draw_tracks(
        fig.add_subplot(), scans=scans, sensors=sensors, tracks=tracks, truth=truth,
        title=title, length_unit=length_unit, time_unit=time_unit, origin=origin,
    )  # fmt: skip
    return _save(fig, path)


_COMPARISON_PANELS = (
    ("gospa", "GOSPA (mean over time)"),
    ("ospa2", "OSPA(2) (trajectories)"),
    ("tgospa", "T-GOSPA (trajectories, switch cost)"),
    ("fragments_per_target", "fragments per target"),
    ("seconds", "seconds per run"),
)
"""The panels of :func:`draw_comparison`, in order: (summary column, title).  Identity
is shown by fragments per target (distinct tracks assigned to a tracked target; 1 is one
unbroken track each) and by T-GOSPA (García-Fernández, Rahmathullah and Svensson, "A
metric on the space of finite sets of trajectories for evaluation of multi-target
tracking algorithms"), whose switching cost charges every change of a target's assigned
track; CLEAR-MOT's identity-switch counts were zero for nearly every method and scenario
of the notebooks, a panel that compared nothing."""


def draw_comparison(axes: Sequence[Axes], summary: pd.DataFrame) -> None:
    """Grouped bars per scenario and tracker of GOSPA, OSPA(2), T-GOSPA, fragments per
    target and time (log scale), one panel each (:data:`_COMPARISON_PANELS`).

    Parameters
    ----------
    axes : sequence of 5 matplotlib Axes
        One per panel, in the order above; the first gets the legend.
    summary : pandas.DataFrame
        :func:`mapassoc.apps.compare.summarize` of a comparison; a missing column gives
        an empty panel.

    Raises
    ------
    InputError
        ``axes`` does not hold exactly one Axes per panel.
    """
    axes = list(axes)
    if len(axes) != len(_COMPARISON_PANELS):
        raise InputError(
            f"axes: got {len(axes)} Axes, expected {len(_COMPARISON_PANELS)} (one per "
            f"panel: {', '.join(column for column, _ in _COMPARISON_PANELS)})"
        )
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
    """Write a PNG of :func:`draw_comparison` (2 x 3 panels, the last cell empty);
    returns its path."""
    fig = _figure(figsize=(12, 8), dpi=100)
    grid = [fig.add_subplot(2, 3, i + 1) for i in range(6)]
    draw_comparison(grid[: len(_COMPARISON_PANELS)], summary)
    for ax in grid[len(_COMPARISON_PANELS) :]:
        ax.set_axis_off()
    return _save(fig, path)
