"""Reading a user's recording: times, geodetic columns, radar plots and their defects."""

from __future__ import annotations

import datetime as dt
import math
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("pyproj")

from mapassoc.data.config import config_to_toml, parse_config  # noqa: E402
from mapassoc.data.frames import GeodeticPoint, LocalFrame  # noqa: E402
from mapassoc.data.recording import (  # noqa: E402
    RecordingBase,
    read_recording,
    recording_track_columns,
    scans_from_recording_frame,
)
from mapassoc.data.records import TrackTable  # noqa: E402
from mapassoc.errors import ConfigError, DataFileError, InputError  # noqa: E402

ORIGIN = GeodeticPoint(52.3086, 4.7639, 0.0)

GEO = """
[recording]
frame = "geodetic"
origin = { latitude = 52.3086, longitude = 4.7639, height = 0.0 }

[motion]
model = "constant_velocity"
ndim = 2
noise_intensity = 1.0

[[sensors]]
name = "adsb"
measurement = "position"
noise_std = 10.0
detection_probability = 0.9
false_alarms_per_scan = 0.1
region = [[-5000.0, 5000.0], [-5000.0, 5000.0]]

[[sensors]]
name = "radar"
measurement = "range_bearing"
latitude = 52.3086
longitude = 4.7639
height = 10.0
range_std = 20.0
bearing_std = 0.002
detection_probability = 0.9
false_alarms_per_scan = 0.1
region = [[0.0, 10000.0], [-3.15, 3.15]]
"""


def _config(text: str = GEO):  # type: ignore[no-untyped-def]
    return parse_config(tomllib.loads(text), source="c.toml")


def _write(path: Path, lines: list[str]) -> Path:
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_lat_lon_and_range_azimuth_lines_become_metres_and_bearings(tmp_path: Path) -> None:
    frame = LocalFrame(origin=ORIGIN)
    lat, lon = (float(v) for v in frame.plane_to_geodetic([1000.0], [2000.0])[0])
    path = _write(tmp_path / "d.csv", [
        "time,sensor,lat,lon,range,azimuth",
        f"2024-05-01T12:00:00.5Z,adsb,{lat!r},{lon!r},,",
        "2024-05-01T12:00:01.5Z,radar,,,3000.0,90.0",
        "2024-05-01T12:00:02.5Z,radar,,,,",
    ])  # fmt: skip
    scans, base = read_recording(path, _config())
    assert base.time.epoch == "2024-05-01T12:00:00.000000Z"
    assert [(s.time, s.sensor, s.rows.tolist()) for s in scans] == [
        (0.5, "adsb", [2]), (1.5, "radar", [3]), (2.5, "radar", []),
    ]  # fmt: skip
    assert np.allclose(scans[0].detections, [[1000.0, 2000.0]], atol=1e-3)
    # 3 km due east of the site at the origin: bearing 0 (counter-clockwise from east)
    r, bearing = scans[1].detections[0]
    assert r == pytest.approx(3000.0, abs=0.01) and bearing == pytest.approx(0.0, abs=1e-6)


@pytest.mark.parametrize(
    ("line", "column", "words"),
    [
        ("2024-05-01T12:00:01Z,adsb,91.0,4.7,,", "lat", "outside [-90, 90]"),
        ("2024-05-01T12:00:01Z,adsb,52.0,east,,", "lon", "not a number"),
        ("2024-05-01T12:00:01Z,adsb,52.0,nan,,", "lon", "not a number"),
        ("2024-05-01T12:00:01Z,adsb,52.0,1_0,,", "lon", "not a number"),
        ("2024-05-01T12:00:01Z,adsb,52.0,1e999,,", "lon", "not finite"),
        ("7.0,adsb,52.0,4.7,,", "time", "another kind"),
        ("2024-05-01T12:00:01Z,adsb,52.0,,,", "lon", "empty cell"),
        ("2024-05-01T12:00:01Z,adsb,52.0,4.7,100.0,", "range", "does not measure"),
    ],
)
def test_each_defect_is_one_line_naming_file_line_and_column(
    tmp_path: Path, line: str, column: str, words: str
) -> None:
    path = _write(tmp_path / "d.csv", [
        "time,sensor,lat,lon,range,azimuth", "2024-05-01T12:00:00Z,adsb,52.3,4.76,,", line,
    ])  # fmt: skip
    with pytest.raises(DataFileError) as caught:
        read_recording(path, _config())
    message = str(caught.value)
    assert message.startswith(f"{path}, line 3, column '{column}': ") and words in message
    assert "\n" not in message


def test_elevation_needs_the_site_height(tmp_path: Path) -> None:
    text = GEO.replace("height = 10.0\n", "")
    path = _write(tmp_path / "d.csv", [
        "time,sensor,lat,lon,range,azimuth,elevation",
        "2024-05-01T12:00:00Z,radar,,,3000.0,90.0,1.0",
    ])  # fmt: skip
    with pytest.raises(DataFileError, match=r"column 'elevation'.*sensors\[1\]\.height"):
        read_recording(path, _config(text))


def test_elevation_makes_the_range_a_slant_range(tmp_path: Path) -> None:
    path = _write(tmp_path / "d.csv", [
        "time,sensor,lat,lon,range,azimuth,elevation",
        "2024-05-01T12:00:00Z,radar,,,2000.0,0.0,60.0",
    ])  # fmt: skip
    scans, _ = read_recording(path, _config())
    r, bearing = scans[0].detections[0]
    assert r == pytest.approx(1000.0, abs=0.5) and bearing == pytest.approx(math.pi / 2, abs=1e-4)


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("latitude = 52.3086\n", "latitude = 95.0\n", "sensors[1].latitude"),
        ("{ latitude = 52.3086,", "{ latitude = -91.0,", "recording.origin.latitude"),
        ('frame = "geodetic"', 'frame = "mercator"', "recording.frame"),
        ("longitude = 4.7639\nheight", "height", "sensors[1].longitude"),
        ("height = 10.0\n", "height = 10.0\nposition = [0.0, 0.0]\n", "sensors[1].position"),
    ],
)
def test_configuration_defects_name_the_key(old: str, new: str, key: str) -> None:
    with pytest.raises(ConfigError) as caught:
        _config(GEO.replace(old, new, 1))
    assert caught.value.key == key


def test_the_configuration_round_trips_with_its_recording() -> None:
    config = _config()
    again = parse_config(tomllib.loads(config_to_toml(config)), source="again")
    assert again.recording == config.recording
    assert np.array_equal(
        again.sensors["radar"].measurement.sensor_position,
        config.sensors["radar"].measurement.sensor_position,
    )


def test_a_frame_of_datetime64_and_a_parquet_timestamp_column(tmp_path: Path) -> None:
    times = pd.to_datetime(
        ["2024-05-01 12:00:00.000001", "2024-05-01 12:00:01"], utc=True, format="ISO8601"
    )
    frame = pd.DataFrame(
        {"time": times, "sensor": ["adsb", "adsb"], "lat": [52.30, 52.31], "lon": [4.76, 4.77],
         "range": [np.nan, np.nan], "azimuth": [np.nan, np.nan]}
    )  # fmt: skip
    scans, base = scans_from_recording_frame(frame, _config())
    assert base.time.kind == "datetime64" and [s.time for s in scans] == [1e-6, 1.0]
    pytest.importorskip("pyarrow")
    frame.to_parquet(tmp_path / "d.parquet")
    again, base2 = read_recording(tmp_path / "d.parquet", _config())
    assert base2 == base and [s.time for s in again] == [1e-6, 1.0]


def test_tracks_come_back_in_the_recording_time_and_lat_lon() -> None:
    frame = LocalFrame(origin=ORIGIN)
    seconds = np.array([0.000001, 59.999999])
    base = RecordingBase(
        time=__import__("mapassoc.data.times", fromlist=["TimeBase"]).TimeBase(
            kind="iso8601", epoch_us=1_714_564_800_000_000
        ),
        frame=frame,
    )
    table = TrackTable(
        track_ids=np.array([1, 1]),
        times=seconds,
        sensors=("adsb", "adsb"),
        states=np.array([[100.0, -200.0, 1.0, 2.0], [40e3, 30e3, 1.0, 2.0]]),
        variances=np.ones((2, 4)),
        detection_rows=np.array([2, -1]),
        state_names=("x", "y", "vx", "vy"),
    )
    columns = recording_track_columns(table, base)
    assert list(columns)[:5] == ["track_id", "time", "sensor", "lat", "lon"]
    assert columns["time"] == ["2024-05-01T12:00:00.000001Z", "2024-05-01T12:00:59.999999Z"]
    parsed = [dt.datetime.fromisoformat(t) for t in columns["time"]]
    assert parsed[1] - parsed[0] == dt.timedelta(microseconds=59_999_998)
    enu = frame.to_local([float(v) for v in columns["lat"]], [float(v) for v in columns["lon"]])
    assert np.allclose(enu[:, :2], table.states[:, :2], atol=1e-3)
    assert columns["detection_row"] == ["2", ""]


def test_a_frame_without_a_recording_section_is_refused() -> None:
    plain = GEO.split("[motion]")[1].split("[[sensors]]\nname = \"radar\"")[0]
    with pytest.raises(InputError, match="no \\[recording\\]"):
        scans_from_recording_frame(pd.DataFrame({"time": [0.0]}), _config("[motion]" + plain))


LOCAL_RADAR = """
[recording]
frame = "local"
angles = "radians"

[motion]
model = "constant_velocity"
ndim = 2
noise_intensity = 1.0

[[sensors]]
name = "radar"
measurement = "range_bearing"
position = [100.0, -50.0]
range_std = 20.0
bearing_std = 0.002
detection_probability = 0.9
false_alarms_per_scan = 0.1
region = [[0.0, 10000.0], [-3.15, 3.15]]
"""


def test_decoded_radar_plots_with_range_and_azimuth_work_as_they_are(tmp_path: Path) -> None:
    path = _write(tmp_path / "plots.csv", [
        "time,sensor,range,azimuth",
        f"2024-05-01T12:00:00.125Z,radar,1000.0,{math.pi / 2!r}",
        "2024-05-01T12:00:04.125Z,radar,2000.0,0.0",
    ])  # fmt: skip
    scans, base = read_recording(path, _config(LOCAL_RADAR))
    assert base.frame is None and base.time.kind == "iso8601"
    assert [s.time for s in scans] == [0.125, 4.125]
    # azimuth clockwise from north (the y axis) to bearing counter-clockwise from east
    assert scans[0].detections[0].tolist() == [1000.0, 0.0]
    assert scans[1].detections[0][1] == pytest.approx(math.pi / 2)


def test_a_naive_timestamp_is_utc_and_said_so(tmp_path: Path) -> None:
    path = _write(tmp_path / "plots.csv", [
        "time,sensor,range,bearing", "2024-05-01T12:00:00,radar,1000.0,0.5",
    ])  # fmt: skip
    with pytest.warns(UserWarning, match="taken as UTC"):
        _, base = read_recording(path, _config(LOCAL_RADAR))
    assert not base.time.zoned
