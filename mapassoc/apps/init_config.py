"""``mapassoc init-config``: a starter configuration inferred from a detections file.

What the file shows is written as values; what the recording can estimate better during
the run is written as ``"auto"``:

* sensors and their measurement kinds from the columns each sensor's lines fill
  (``lat, lon[, alt]``: a geodetic position report; ``range, azimuth[, elevation]``: a
  radar plot from a site, whose place is given with ``--site NAME=LAT,LON[,HEIGHT]``;
  ``x, y[, z]``; ``range, bearing``), and the kind of time (:mod:`mapassoc.data.times`);
* the origin of the plane (the first site, else the centre of the data) and each
  sensor's region: the extent of its detections with a margin of 5 % of the extent on
  each side (a position sensor: clutter fills the sensor's region already, and a wider
  box would dilute the clutter density the run estimates), or of its ranges and
  bearings (a range-bearing sensor; all bearings when they span nearly the circle);
* the scan period (the median time between a sensor's scans);
* a range-bearing sensor's noise from the moments of nearest-neighbour chains of
  detections (:func:`mapassoc.filtering.noise_moments.chain_moments`, which says how); a
  position sensor's ``noise_std`` and the constant-velocity model's ``noise_intensity``
  are written as ``"auto"`` with the chains' values in a comment (the run's EM starts
  from the same chains, :mod:`mapassoc.estimator.noise_levels`), the latter only with a
  position sensor (the EM's start of ``q`` needs one), else as the chains' number;
* the birth model's ``rate``, ``initial_count``, ``survival_probability`` and
  ``velocity_std`` as ``"auto"`` (:mod:`mapassoc.estimator.birth_estimation`), the last
  with the chains' velocity spread as its start;
* ``detection_probability`` and ``false_alarms_per_scan`` as ``"auto"`` (estimated by
  the run's EM, :mod:`mapassoc.estimator.parameters`).

Chains are mutual nearest neighbours between consecutive scans of a sensor, so clutter
enters them only where it lies nearer than the target's next detection; the estimates
are a start, said so in the file's comments.  The file is never overwritten.
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mapassoc.data.frames import GeodeticPoint
from mapassoc.errors import DataFileError, InputError, OutputError
from mapassoc.filtering.noise_moments import ChainMoments, chain_moments

__all__ = ["SensorGuess", "infer_config_text", "init_config", "parse_site"]

_MARGIN = 0.05
_MIN_NOISE_STD = 0.1
"""Metres: the least noise written (a recording of exact positions gives none)."""


@dataclass(frozen=True)
class SensorGuess:
    """What the columns say of one sensor: its name and measurement kind."""

    name: str
    kind: str  # "geo_position", "position", "geo_radar", "radar_azimuth", "range_bearing"
    dim: int


def parse_site(text: str) -> tuple[str, GeodeticPoint]:
    """``NAME=LAT,LON[,HEIGHT]`` (degrees, metres) of ``--site``."""
    name, _, place = text.partition("=")
    parts = place.split(",")
    try:
        numbers = [float(part) for part in parts]
    except ValueError:
        numbers = []
    if not name or len(numbers) not in (2, 3):
        raise InputError(f"--site {text!r}: expected NAME=LAT,LON[,HEIGHT] in degrees and metres")
    try:
        site = GeodeticPoint(*numbers)
    except InputError as exc:
        raise InputError(f"--site {text!r}: {exc}") from None
    return name, site


def _read_frame(path: str) -> Any:
    """The detections file as a DataFrame (CSV: every cell text; Parquet: typed)."""
    import pandas as pd

    from mapassoc.data.io import read_cells

    if path.lower().endswith((".parquet", ".pq")):
        try:
            return pd.read_parquet(path)
        except Exception as exc:  # pyarrow's errors: not a Parquet file and so on
            raise DataFileError(path, f"cannot read the Parquet file: {exc}") from None
    header, _, cells = read_cells(path)
    frame = pd.DataFrame({name: cells[k] for k, name in enumerate(header)}, dtype=object)
    return frame.replace("", None)


def _filled(frame: Any, name: str, rows: Any) -> bool:
    return name in frame.columns and bool(frame.loc[rows, name].notna().any())


def guess_sensors(
    frame: Any, path: str, sites: Mapping[str, GeodeticPoint]
) -> list[SensorGuess]:
    """Each sensor of the file and its measurement kind, from the columns it fills."""
    has_sensor = "sensor" in frame.columns
    names = list(dict.fromkeys(str(v) for v in frame["sensor"].dropna())) if has_sensor else []
    guesses = []
    for name in names or ["sensor"]:
        rows = frame["sensor"].astype(str) == name if has_sensor else frame.index
        columns = [c for c in frame.columns if c not in ("time", "sensor")]
        filled = {c for c in columns if _filled(frame, c, rows)}
        if {"lat", "lon"} <= filled:
            guesses.append(SensorGuess(name, "geo_position", 3 if "alt" in filled else 2))
        elif {"range", "azimuth"} <= filled:
            kind = "geo_radar" if name in sites else "radar_azimuth"
            guesses.append(SensorGuess(name, kind, 2))
        elif {"range", "bearing"} <= filled:
            guesses.append(SensorGuess(name, "range_bearing", 2))
        elif {"x", "y"} <= filled:
            guesses.append(SensorGuess(name, "position", 3 if "z" in filled else 2))
        else:
            raise DataFileError(
                path,
                f"sensor {name!r} fills the columns {sorted(filled)}; expected lat,lon[,alt], "
                "range,azimuth[,elevation], x,y[,z] or range,bearing",
                column="sensor",
            )
    if _geodetic(guesses):
        for guess in guesses:
            if guess.kind == "radar_azimuth":
                raise InputError(
                    f"{path}: sensor {guess.name!r} gives range and azimuth in a file of "
                    f"latitudes and longitudes; place its site with --site "
                    f"{guess.name}=LAT,LON[,HEIGHT]"
                )
    return guesses


def _geodetic(guesses: Sequence[SensorGuess]) -> bool:
    return any(g.kind.startswith("geo_") for g in guesses)


def _draft_toml(
    guesses: Sequence[SensorGuess],
    sites: Mapping[str, GeodeticPoint],
    origin: GeodeticPoint | None,
    noise: Mapping[str, tuple[float, float]] | None = None,
    regions: Mapping[str, list[list[float]]] | None = None,
) -> list[str]:
    """The ``[recording]`` and ``[[sensors]]`` lines (placeholders where not yet known)."""
    lines = []
    if _geodetic(guesses):
        lines += ["[recording]", 'frame = "geodetic"']
        if origin is not None:
            lines += [
                "# the plane's origin: metres east and north of it are the estimator's x, y",
                f"origin = {{ latitude = {origin.latitude!r}, longitude = {origin.longitude!r}, "
                f"height = {0.0 if origin.height is None else origin.height!r} }}",
            ]
    else:
        lines += ["[recording]", 'frame = "local"']
    lines += ['angles = "degrees"  # azimuth and elevation columns', ""]
    for guess in guesses:
        r_std, b_std = (noise or {}).get(guess.name, (1.0, 0.01))
        region = (regions or {}).get(guess.name)
        lines += ["[[sensors]]", f"name = {_quote(guess.name)}"]
        if guess.kind in ("geo_position", "position"):
            lines += [
                'measurement = "position"',
                f'noise_std = "auto"   # estimated by the run; the chains give {r_std!r} m',
            ]
        else:
            lines += ['measurement = "range_bearing"']
            if guess.kind == "geo_radar":
                site = sites[guess.name]
                lines += [f"latitude = {site.latitude!r}", f"longitude = {site.longitude!r}"]
                lines += [] if site.height is None else [f"height = {site.height!r}"]
            else:
                lines += ["position = [0.0, 0.0]  # the sensor's x, y in the file's frame"]
            lines += [f"range_std = {r_std!r}  # metres", f"bearing_std = {b_std!r}  # radians"]
        if region is None:
            region = [[-1.0, 1.0]] * (guess.dim if guess.kind.endswith("position") else 2)
        lines += [
            'detection_probability = "auto"   # estimated from the recording by the run',
            'false_alarms_per_scan = "auto"   # estimated from the recording by the run',
            "# the extent of the detections with a margin, in metres from the origin",
            f"region = {region!r}",
            "",
        ]
    return lines


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _draft_config(lines: Sequence[str], dim: int, source: str) -> Any:
    from mapassoc.data.config import parse_config

    text = "\n".join([*lines, "[motion]", 'model = "constant_velocity"', f"ndim = {dim}",
                      "noise_intensity = 1.0"])  # fmt: skip
    return parse_config(tomllib.loads(text), source=source)


# --------------------------------------------------------------------------- estimates


def _positions(scans: Sequence[Any], sensor: Any) -> list[Any]:
    """Each scan's detections as positions in the plane, shape ``(m, d)`` each."""
    from mapassoc.models.measurement import RangeBearing

    out = []
    for scan in scans:
        z = scan.detections
        if isinstance(sensor.measurement, RangeBearing):
            z = np.array([sensor.measurement.position_from_measurement(row)[0] for row in z])
            z = z.reshape(len(scan.detections), 2)
        out.append(z)
    return out


def _region(scans: Sequence[Any], positions: Sequence[Any], sensor: Any) -> list[list[float]]:
    """The extent of a sensor's detections with a margin of ``_MARGIN`` of it each side:
    of their positions, or of their ranges and bearings (all bearings when they span
    nearly the circle, as they do across the bearing's cut at +-pi)."""
    from mapassoc.models.measurement import RangeBearing

    if isinstance(sensor.measurement, RangeBearing):
        z = np.concatenate([scan.detections for scan in scans if scan.size])
        low, high = z.min(axis=0), z.max(axis=0)
        margin = np.maximum((high - low) * _MARGIN, [10.0, 1e-3])
        ranges = [max(0.0, float(low[0] - margin[0])), float(high[0] + margin[0])]
        if high[1] - low[1] > 0.9 * 2 * math.pi:
            return [ranges, [-math.pi, math.pi]]
        return [ranges, [float(low[1] - margin[1]), float(high[1] + margin[1])]]
    stacked = np.concatenate([p for p in positions if len(p)])
    low, high = stacked.min(axis=0), stacked.max(axis=0)
    margin = np.maximum((high - low) * _MARGIN, 10.0)
    return [[float(a), float(b)] for a, b in zip(low - margin, high + margin, strict=True)]


def _noise(moments: ChainMoments, positions: Sequence[Any], sensor: Any) -> tuple[float, float]:
    from mapassoc.models.measurement import RangeBearing

    std = max(math.sqrt(moments.measurement_variance), _MIN_NOISE_STD)
    if not isinstance(sensor.measurement, RangeBearing):
        return std, 0.01
    ranges = np.concatenate([np.hypot(*(p - sensor.measurement.sensor_position).T)
                             for p in positions if len(p)])  # fmt: skip
    return std, max(std / float(np.median(ranges)), 1e-4)


def infer_config_text(path: str | os.PathLike[str], *, sites: Mapping[str, GeodeticPoint]) -> str:
    """The starter configuration of a detections file, as commented TOML.

    Parameters
    ----------
    path : str or os.PathLike
        The detections file (CSV, or Parquet by its suffix).
    sites : mapping of str to GeodeticPoint
        The places of the sensors that give range and azimuth.

    Raises
    ------
    DataFileError, InputError
        A defect of the file (one line naming it), or a radar without its site.
    """
    from mapassoc.data.config import parse_config
    from mapassoc.data.recording import scans_from_recording_frame

    name = os.fspath(path)
    frame = _read_frame(name)
    guesses = guess_sensors(frame, name, sites)
    dim = max(g.dim for g in guesses)
    draft = _draft_config(_draft_toml(guesses, sites, None), dim, name)

    def fail(message: str, column: str | None, row: int | None) -> Exception:
        line = None if row is None else row + 2  # a CSV file's line (a Parquet row + 2)
        return DataFileError(name, message, row=line, column=column)

    text = not name.lower().endswith((".parquet", ".pq"))  # else typed Parquet columns
    scans, base = scans_from_recording_frame(frame, draft, fail=fail, text=text)
    noise, regions, moments = {}, {}, []
    for guess in guesses:
        sensor = draft.sensors[guess.name]
        own = [scan for scan in scans if scan.sensor == guess.name]
        positions = _positions(own, sensor)
        moment = chain_moments([scan.time for scan in own], positions)
        noise[guess.name] = _noise(moment, positions, sensor)
        regions[guess.name] = _region(own, positions, sensor)
        moments.append(moment)
    origin = None if base.frame is None else base.frame.origin
    lines = _header_lines(name, base) + _draft_toml(guesses, sites, origin, noise, regions)
    has_position = any(guess.kind in ("geo_position", "position") for guess in guesses)
    lines += _model_lines(moments, dim, scans, auto_q=has_position)
    document = "\n".join(lines) + "\n"
    parse_config(tomllib.loads(document), source=name)  # what is written must read back
    return document


def _header_lines(name: str, base: Any) -> list[str]:
    kind = base.time.kind
    when = "plain seconds" if kind == "seconds" else f"timestamps from {base.time.epoch}"
    return [
        f"# mapassoc starter configuration inferred from {Path(name).name} by "
        "`mapassoc init-config`",
        f"# times: {when}; values marked 'auto' are estimated from the recording by the run;",
        "# the others are estimates from nearest-neighbour chains of detections: a start,",
        "# to be checked.",
        "",
    ]


def _model_lines(
    moments: Sequence[ChainMoments], dim: int, scans: Sequence[Any], *, auto_q: bool
) -> list[str]:
    """``[motion]``, ``[birth]`` and the window length; ``noise_intensity`` "auto" when
    ``auto_q`` (a position sensor, which the noise EM's start needs), else the chains'."""
    q = float(np.median([m.process_noise for m in moments]))
    spread = float(max(m.speed_spread for m in moments))
    period = float(np.median([m.period for m in moments]))
    first = scans[0]
    initial = sum(s.size for s in scans if s.time == first.time)
    return [
        "[motion]",
        f"# scan period {period!r} s; the chains' second differences give a process noise",
        f"# of {q!r} m^2/s^3" + ("; the run estimates it" if auto_q else ""),
        'model = "constant_velocity"',
        f"ndim = {dim}",
        'noise_intensity = "auto"' if auto_q else f"noise_intensity = {q!r}",
        "",
        "[birth]",
        "# estimated by the run; the first pass starts velocity_std at the spread of the",
        "# chains' scan-to-scan velocities (m/s); the first scan holds "
        f"{initial} detections",
        'rate = "auto"',
        'initial_count = "auto"',
        'survival_probability = "auto"',
        'velocity_std = "auto"',
        f"velocity_std_start = {spread!r}",
        "",
        "[estimator.windows]",
        "# scans per window; the other [estimator.*] tables are left at their defaults",
        "window_length = 5",
    ]


def init_config(
    detections: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    sites: Mapping[str, GeodeticPoint] | None = None,
) -> str:
    """Write the starter configuration of ``detections`` to ``out``; its text.

    Raises
    ------
    OutputError
        ``out`` exists (it is never overwritten) or cannot be written.
    """
    target = Path(out)
    if target.exists():
        raise OutputError(
            str(target), "exists; init-config never overwrites a file (give another --out)"
        )
    text = infer_config_text(detections, sites=dict(sites or {}))
    try:
        with open(target, "x", encoding="utf-8") as handle:
            handle.write(text)
    except FileExistsError:
        raise OutputError(str(target), "exists; init-config never overwrites a file") from None
    except OSError as exc:
        raise OutputError(str(target), f"cannot write: {exc.strerror or exc}") from None
    return text
