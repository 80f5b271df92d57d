"""A user's own recording in two commands: ``init-config`` then ``run``, geodetic and UTC.

The 'crossing' scenario, scaled to aircraft-like distances (x 50: a 10 km region, speeds
of 100 m/s), is written twice: in local metres and seconds, and as latitude/longitude
reports (or range/azimuth plots from a site given by latitude/longitude) with ISO 8601
UTC times around a real-looking site.  Both go through ``mapassoc init-config`` and
``mapassoc run``; the geodetic run's tracks, read back from ``tracks_recording.csv``
(latitude, longitude, UTC) and projected to the local frame, must score a GOSPA within
1.05 times the local run's.
"""

from __future__ import annotations

import datetime as dt
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("pyproj")

from mapassoc.apps.cli import main  # noqa: E402
from mapassoc.data.config import load_config  # noqa: E402
from mapassoc.data.formats import read_detections_file, read_truth_file  # noqa: E402
from mapassoc.data.frames import GeodeticPoint, LocalFrame, plane_to_site_polar  # noqa: E402
from mapassoc.data.io import read_tracks  # noqa: E402
from mapassoc.data.records import TrackTable, TruthTable  # noqa: E402
from mapassoc.evaluation.tables import evaluate_tables  # noqa: E402

SITE = GeodeticPoint(latitude=52.3086, longitude=4.7639, height=0.0)
"""A real-looking site: an airport's coordinates (degrees, metres)."""
EPOCH = dt.datetime(2024, 5, 1, 12, 0, tzinfo=dt.UTC)
SCALE = 50.0
SCANS = 30
GOSPA_C = 10.0 * SCALE


def _iso(seconds: float) -> str:
    return (EPOCH + dt.timedelta(seconds=seconds)).isoformat().replace("+00:00", "Z")


def _scenario(tmp: Path) -> tuple[pd.DataFrame, TruthTable]:
    """The scaled scenario's detections (time, x, y) and truth."""
    assert main(["simulate", "crossing", "--out", str(tmp / "sim"), "--scans", str(SCANS)]) == 0
    config = load_config(tmp / "sim" / "config.toml")
    scans = read_detections_file(tmp / "sim" / "detections.csv", config.sensors)
    rows = [
        (scan.time, float(x) * SCALE, float(y) * SCALE)
        for scan in scans
        for x, y in scan.detections
    ]
    truth = read_truth_file(tmp / "sim" / "truth.csv")
    scaled = TruthTable(
        target_ids=truth.target_ids,
        times=truth.times,
        states=truth.states * SCALE,
        state_names=truth.state_names,
    )
    return pd.DataFrame(rows, columns=["time", "x", "y"]), scaled


def _two_commands(tmp: Path, name: str, frame: pd.DataFrame, *sites: str) -> Path:
    detections = tmp / f"{name}.csv"
    frame.to_csv(detections, index=False)
    config = tmp / f"{name}.toml"
    site_args = [arg for site in sites for arg in ("--site", site)]
    assert main(["init-config", str(detections), "--out", str(config), *site_args]) == 0
    out = tmp / f"{name}-run"
    code = main(["run", str(config), str(detections), "--out", str(out), "--no-progress",
                 "--no-timings"])  # fmt: skip
    assert code == 0
    return out


def _local_gospa(run: Path, truth: TruthTable) -> float:
    return evaluate_tables(truth, read_tracks(run / "tracks.csv"), c=GOSPA_C).gospa.mean_total


def _geodetic_gospa(run: Path, truth: TruthTable) -> float:
    """GOSPA of the tracks as the user gets them: latitude, longitude and UTC."""
    tracks = pd.read_csv(run / "tracks_recording.csv", dtype={"time": str})
    summary = json.loads((run / "summary.json").read_text())
    assert summary["recording"]["time"]["kind"] == "iso8601"
    times = np.array(
        [(dt.datetime.fromisoformat(t) - EPOCH).total_seconds() for t in tracks["time"]]
    )
    xy = LocalFrame(origin=SITE).to_local(tracks["lat"], tracks["lon"])[:, :2]
    size = len(tracks)
    table = TrackTable(
        track_ids=tracks["track_id"].to_numpy(dtype=np.int64),
        times=times,
        sensors=tuple(tracks["sensor"]),
        states=xy,
        variances=np.zeros((size, 2)),
        detection_rows=np.full(size, -1, dtype=np.int64),
        state_names=("x", "y"),
    )
    return evaluate_tables(truth, table, c=GOSPA_C).gospa.mean_total


@pytest.mark.slow
def test_lat_lon_reports_with_utc_times_track_as_well_as_local_metres(tmp_path: Path) -> None:
    local, truth = _scenario(tmp_path)
    local_frame = local.assign(sensor="adsb")[["time", "sensor", "x", "y"]]
    geo = LocalFrame(origin=SITE).plane_to_geodetic(local["x"], local["y"])
    reports = pd.DataFrame(
        {"time": [_iso(t) for t in local["time"]], "sensor": "adsb",
         "lat": geo[:, 0], "lon": geo[:, 1]}
    )  # fmt: skip
    local_run = _two_commands(tmp_path, "local", local_frame)
    geo_run = _two_commands(tmp_path, "geo", reports)
    local_gospa = _local_gospa(local_run, truth)
    geo_gospa = _geodetic_gospa(geo_run, truth)
    print(f"lat/lon: GOSPA local {local_gospa:.3f}, geodetic {geo_gospa:.3f}, "
          f"ratio {geo_gospa / local_gospa:.4f}")  # fmt: skip
    assert geo_gospa <= 1.05 * local_gospa


@pytest.mark.slow
def test_range_azimuth_plots_from_a_site_track_as_well_as_local_range_bearing(
    tmp_path: Path,
) -> None:
    local, truth = _scenario(tmp_path)
    # the radar stands 3 km south of the region's centre, as a local range-bearing sensor
    offset = np.array([0.0, -3000.0])
    dx, dy = local["x"] - offset[0], local["y"] - offset[1]
    local_plots = pd.DataFrame(
        {"time": local["time"], "sensor": "radar", "range": np.hypot(dx, dy),
         "bearing": np.arctan2(dy, dx)}
    )  # fmt: skip
    site_geo = LocalFrame(origin=SITE).plane_to_geodetic(offset[0], offset[1])[0]
    site = GeodeticPoint(float(site_geo[0]), float(site_geo[1]), 0.0)
    polar = plane_to_site_polar(LocalFrame(origin=SITE), site, local["x"], local["y"])
    plots = pd.DataFrame(
        {"time": [_iso(t) for t in local["time"]], "sensor": "radar", "range": polar[:, 0],
         "azimuth": np.degrees(polar[:, 1])}
    )  # fmt: skip
    local_run = _two_commands(tmp_path, "local", local_plots)
    text = (tmp_path / "local.toml").read_text()
    assert "position = [0.0, 0.0]" in text  # a local radar's place is the user's to give
    (tmp_path / "local.toml").unlink()
    placed = f"position = [{float(offset[0])!r}, {float(offset[1])!r}]"
    (tmp_path / "local.toml").write_text(text.replace("position = [0.0, 0.0]", placed))
    import shutil

    shutil.rmtree(local_run)
    code = main(["run", str(tmp_path / "local.toml"), str(tmp_path / "local.csv"), "--out",
                 str(local_run), "--no-progress", "--no-timings"])  # fmt: skip
    assert code == 0
    geo_run = _two_commands(
        tmp_path, "geo", plots, f"radar={site.latitude!r},{site.longitude!r},0"
    )
    local_gospa = _local_gospa(local_run, truth)
    geo_gospa = _geodetic_gospa(geo_run, truth)
    print(f"range/azimuth: GOSPA local {local_gospa:.3f}, geodetic {geo_gospa:.3f}, "
          f"ratio {geo_gospa / local_gospa:.4f}")  # fmt: skip
    assert geo_gospa <= 1.05 * local_gospa
