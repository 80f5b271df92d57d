"""``mapassoc init-config``: what it infers from a recording, and what it refuses."""

from __future__ import annotations

import datetime as dt
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyproj")

from mapassoc.apps.cli import main  # noqa: E402
from mapassoc.apps.init_config import infer_config_text  # noqa: E402
from mapassoc.data.config import parse_config  # noqa: E402
from mapassoc.filtering.noise_moments import chain_moments  # noqa: E402


def _cv_chain(rng: np.random.Generator, scans: int, q: float, r: float, period: float) -> list:
    """One 2-D constant-velocity target with white-noise acceleration (intensity q) seen
    with position noise variance r, one detection per scan."""
    T = period
    F = np.array([[1, T], [0, 1]])
    Q = q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    states = np.zeros((2, 2))  # per axis: position, velocity
    states[:, 1] = [50.0, -20.0]
    out = []
    for _ in range(scans):
        states = states @ F.T + rng.multivariate_normal(np.zeros(2), Q, size=2)
        out.append((states[:, 0] + rng.normal(0.0, math.sqrt(r), 2)).reshape(1, 2))
    return out


def test_the_chain_moments_recover_the_noises_of_a_constant_velocity_target() -> None:
    # V = (2/3) q T^3 + 6 r and C = q T^3 / 6 - 4 r of the second differences
    rng = np.random.default_rng(7)
    q, r, T = 4.0, 1.0, 2.0
    positions = _cv_chain(rng, 4000, q, r, T)
    moments = chain_moments([T * k for k in range(len(positions))], positions)
    assert moments.period == T
    assert moments.measurement_variance == pytest.approx(r, rel=0.25)
    assert moments.process_noise == pytest.approx(q, rel=0.25)


def _geo_file(path: Path) -> Path:
    lines = ["time,sensor,lat,lon"]
    for k in range(12):
        for lat0, lon0, dlat in ((52.30, 4.70, 0.001), (52.32, 4.80, -0.0005)):
            stamp = f"2024-05-01T12:00:{2 * k:02d}Z"
            lines.append(f"{stamp},adsb,{lat0 + dlat * k!r},{lon0 + 0.0008 * k!r}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_a_lat_lon_file_gives_a_geodetic_configuration_with_auto_rates(tmp_path: Path) -> None:
    text = infer_config_text(_geo_file(tmp_path / "det.csv"), sites={})
    data = tomllib.loads(text)
    config = parse_config(data, source="c.toml")
    assert data["recording"]["frame"] == "geodetic"
    origin = data["recording"]["origin"]
    assert origin["latitude"] == pytest.approx((52.30 + 52.3145) / 2, abs=0.01)
    (sensor,) = data["sensors"]
    assert sensor["detection_probability"] == "auto" and sensor["false_alarms_per_scan"] == "auto"
    assert config.auto.false_alarms == ("adsb",)
    assert sensor["noise_std"] == "auto" and data["motion"]["noise_intensity"] == "auto"
    assert config.auto.noise_intensity and "adsb" in config.auto.noise_std_starts()
    assert "# scan period 2.0 s" in text
    # region: the extent of the data (0.1088 deg of longitude, 7.4 km) and 5 % each side
    (low, high), _ = sensor["region"]
    assert 1.08 < (high - low) / 7400 < 1.12
    # a speed of ~ 0.001 deg lat per 2 s (55 m/s north) and 0.0008 deg lon (27 m/s east)
    assert 20.0 < data["birth"]["velocity_std_start"] < 70.0
    assert all(data["birth"][key] == "auto"
               for key in ("rate", "initial_count", "survival_probability", "velocity_std"))
    assert len(config.auto.names()) == 8  # every value a run can estimate: all "auto"


def test_init_config_then_run_on_a_users_file(tmp_path: Path) -> None:
    det = _geo_file(tmp_path / "det.csv")
    assert main(["init-config", str(det), "--out", str(tmp_path / "c.toml")]) == 0
    assert main(["run", str(tmp_path / "c.toml"), str(det), "--out", str(tmp_path / "r"),
                 "--no-progress", "--no-timings"]) == 0  # fmt: skip
    lines = (tmp_path / "r" / "tracks_recording.csv").read_text().splitlines()
    assert lines[0].startswith("track_id,time,sensor,lat,lon,x,y")
    # every track time is one of the input's instants, exactly
    inputs = {
        dt.datetime.fromisoformat(line.split(",")[0]) for line in det.read_text().splitlines()[1:]
    }
    outputs = {dt.datetime.fromisoformat(line.split(",")[1]) for line in lines[1:]}
    assert outputs and outputs <= inputs
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["recording"]["time"] == {
        "kind": "iso8601", "epoch": "2024-05-01T12:00:00.000000Z", "zoned": True,
    }  # fmt: skip
    assert summary["recording"]["origin"]["latitude"] == pytest.approx(52.307, abs=0.01)
    manifest = json.loads((tmp_path / "r" / "manifest.json").read_text())
    assert "tracks_recording.csv" in manifest["outputs"]


def test_it_never_overwrites_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    det = _geo_file(tmp_path / "det.csv")
    out = tmp_path / "c.toml"
    out.write_text("# mine\n")
    assert main(["init-config", str(det), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"mapassoc: error: {out}: exists; init-config never overwrites a file " \
        "(give another --out)"  # fmt: skip
    assert out.read_text() == "# mine\n"


def test_a_radar_without_its_site_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    det = tmp_path / "det.csv"
    det.write_text(
        "time,sensor,lat,lon,range,azimuth\n"
        "2024-05-01T12:00:00Z,adsb,52.3,4.7,,\n"
        "2024-05-01T12:00:00Z,radar,,,1000.0,45.0\n"
    )
    assert main(["init-config", str(det), "--out", str(tmp_path / "c.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--site radar=LAT,LON[,HEIGHT]" in err[0]
    assert not (tmp_path / "c.toml").exists()
    assert main(["init-config", str(det), "--out", str(tmp_path / "c.toml"),
                 "--site", "radar=52.3,4.7"]) == 0  # fmt: skip
    data = tomllib.loads((tmp_path / "c.toml").read_text())
    radar = data["sensors"][1]
    assert radar["measurement"] == "range_bearing" and radar["latitude"] == 52.3
    assert data["recording"]["origin"]["latitude"] == 52.3  # the first site


@pytest.mark.parametrize("site", ["radar=95,4", "radar=52", "=52,4", "radar=a,b"])
def test_a_bad_site_is_one_line(
    site: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    det = _geo_file(tmp_path / "det.csv")
    assert main(["init-config", str(det), "--out", str(tmp_path / "c.toml"), "--site", site]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--site {site!r}" in err[0]


def test_a_parquet_recording_with_a_timestamp_column(tmp_path: Path) -> None:
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    frame = pd.read_csv(_geo_file(tmp_path / "det.csv"))
    frame["time"] = pd.to_datetime(frame["time"], utc=True, format="ISO8601")
    frame.to_parquet(tmp_path / "det.parquet")
    from_parquet = infer_config_text(tmp_path / "det.parquet", sites={})
    from_csv = infer_config_text(tmp_path / "det.csv", sites={})
    assert "timestamps from 2024-05-01T12:00:00.000000Z" in from_parquet
    # the same recording: the same configuration, but for the file named in the comment
    assert from_parquet.replace("det.parquet", "det.csv") == from_csv
