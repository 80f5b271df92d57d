"""Tests of the track plot: units, every track identified, direction, truth under the
tracks, a legend clear of the data, and matplotlib only imported when drawing."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mapassoc.apps.plotting import TRACK_LEGEND_LIMIT, draw_tracks, plot_tracks
from mapassoc.data.io import TrackTable
from mapassoc.errors import InputError
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario
from mapassoc.evaluation.simulate import Scenario

pytest.importorskip("matplotlib")

from matplotlib.axes import Axes  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.text import Annotation  # noqa: E402


@pytest.fixture(scope="module")
def crossing() -> Scenario:
    return truncate_scenario(build_scenario("crossing", 0), 20)


@pytest.fixture(scope="module")
def few(crossing: Scenario) -> TrackTable:
    """The oracle's 4 tracks of the first 20 scans of "crossing"."""
    return oracle_tracks(crossing.scans, crossing.origins, crossing.config)


def _straight_tracks(count: int, *, first_id: int = 5) -> TrackTable:
    """``count`` tracks of 6 points, track ``first_id + i`` moving in direction i."""
    ids, times, states = [], [], []
    for i in range(count):
        angle = 2 * np.pi * i / count
        for t in range(6):
            ids.append(first_id + i)
            times.append(float(t))
            states.append([10 * i + t * np.cos(angle), -5 * i + t * np.sin(angle)])
    n = len(ids)
    return TrackTable(
        track_ids=np.array(ids, dtype=np.int64),
        times=np.array(times),
        sensors=("pos",) * n,
        states=np.array(states),
        variances=np.ones((n, 2)),
        detection_rows=-np.ones(n, dtype=np.int64),
        state_names=("x", "y"),
    )


def _draw(scenario: Scenario, tracks: TrackTable, **options: object) -> tuple[Figure, Axes]:
    fig = Figure(figsize=(10.5, 8))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    draw_tracks(
        ax, scans=scenario.scans, sensors=scenario.config.sensors, tracks=tracks,
        truth=scenario.truth, title="t", **options,  # type: ignore[arg-type]
    )  # fmt: skip
    return fig, ax


def _ends(ids: np.ndarray, times: np.ndarray, xy: np.ndarray) -> dict[int, np.ndarray]:
    """Per id, its positions in time order."""
    out = {}
    for tid in np.unique(ids):
        sel = ids == tid
        out[int(tid)] = xy[sel][np.argsort(times[sel], kind="stable")]
    return out


def _track_lines(tracks: TrackTable) -> dict[int, np.ndarray]:
    return _ends(tracks.track_ids, tracks.times, tracks.states[:, :2])


def _truth_lines(scenario: Scenario) -> dict[int, np.ndarray]:
    truth = scenario.truth
    return _ends(truth.target_ids, truth.times, truth.states[:, :2])


def _arrows(ax: Axes) -> list[Annotation]:
    return [a for a in ax.texts if isinstance(a, Annotation) and a.arrow_patch is not None]


def _labels(ax: Axes) -> list[Annotation]:
    return [a for a in ax.texts if isinstance(a, Annotation) and a.get_text()]


def _legend_texts(ax: Axes) -> list[str]:
    legend = ax.get_legend()
    assert legend is not None
    return [t.get_text() for t in legend.get_texts()]


# --------------------------------------------------------------------------- units


def test_axes_say_the_length_unit_when_given(crossing: Scenario, few: TrackTable) -> None:
    _, ax = _draw(crossing, few, length_unit="m")
    assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"


def test_axes_without_a_unit_say_it_is_the_data_s_own(
    crossing: Scenario, few: TrackTable
) -> None:
    _, ax = _draw(crossing, few)
    for label, axis in ((ax.get_xlabel(), "x"), (ax.get_ylabel(), "y")):
        assert label.startswith(axis) and "length unit" in label and "[" not in label


def test_the_time_unit_goes_with_each_track_s_time_span(
    crossing: Scenario, few: TrackTable
) -> None:
    _, ax = _draw(crossing, few, time_unit="scans")
    lines = _track_lines(few)
    spans = {
        tid: (float(few.times[few.track_ids == tid].min()),
              float(few.times[few.track_ids == tid].max()))
        for tid in lines
    }  # fmt: skip
    texts = _legend_texts(ax)
    for tid, (first, last) in spans.items():
        assert f"track {tid}  (t {first:g}\N{EN DASH}{last:g} scans)" in texts


@pytest.mark.parametrize("bad", ["", "   ", 3, b"m"])
@pytest.mark.parametrize("name", ["length_unit", "time_unit"])
def test_a_unit_that_is_not_a_nonempty_string_is_refused(
    crossing: Scenario, few: TrackTable, name: str, bad: object
) -> None:
    with pytest.raises(InputError, match=rf"{name} must be None or a non-empty string"):
        _draw(crossing, few, **{name: bad})


def test_a_scan_of_an_unknown_sensor_is_named(crossing: Scenario, few: TrackTable) -> None:
    fig = Figure()
    with pytest.raises(InputError, match=r"sensor 'pos'.*not in sensors \(got \['radar'\]\)"):
        draw_tracks(
            fig.add_subplot(), scans=crossing.scans,
            sensors={"radar": crossing.config.sensors["pos"]}, tracks=few,
        )  # fmt: skip


# --------------------------------------------------------------------------- identity


def test_every_track_has_a_legend_entry_and_its_id_at_both_ends(
    crossing: Scenario, few: TrackTable
) -> None:
    _, ax = _draw(crossing, few)
    lines = _track_lines(few)
    assert 1 < len(lines) <= TRACK_LEGEND_LIMIT
    texts = _legend_texts(ax)
    for tid in lines:
        assert sum(t.startswith(f"track {tid}  (") for t in texts) == 1
    for tid, line in lines.items():
        at = [np.asarray(a.xy) for a in _labels(ax) if a.get_text() == str(tid)]
        assert len(at) == 2
        assert {tuple(p) for p in at} == {tuple(line[0]), tuple(line[-1])}


def test_track_labels_are_legible(crossing: Scenario, few: TrackTable) -> None:
    _, ax = _draw(crossing, few)
    labels = _labels(ax)
    assert labels
    for label in labels:
        assert label.get_fontsize() >= 9
        assert label.get_path_effects(), "a label needs a halo to read over the data"


def test_many_tracks_share_one_legend_entry_and_each_is_labelled(crossing: Scenario) -> None:
    count = TRACK_LEGEND_LIMIT + 3
    tracks = _straight_tracks(count)
    _, ax = _draw(crossing, tracks)
    texts = _legend_texts(ax)
    assert f"tracks ({count}), id at end" in texts
    assert not any(re.match(r"track \d", t) for t in texts)
    lines = _track_lines(tracks)
    for tid, line in lines.items():
        at = [np.asarray(a.xy) for a in _labels(ax) if a.get_text() == str(tid)]
        assert len(at) == 1 and np.array_equal(at[0], line[-1])


def test_the_detections_entry_counts_every_detection(
    crossing: Scenario, few: TrackTable
) -> None:
    _, ax = _draw(crossing, few)
    total = sum(scan.detections.shape[0] for scan in crossing.scans)
    assert total > 0 and f"detections ({total})" in _legend_texts(ax)


# --------------------------------------------------------------------------- direction


def test_one_arrow_per_track_and_target_pointing_along_its_motion(
    crossing: Scenario, few: TrackTable
) -> None:
    _, ax = _draw(crossing, few)
    arrows = _arrows(ax)
    lines = list(_track_lines(few).values()) + list(_truth_lines(crossing).values())
    assert len(arrows) == len(lines)
    for line in lines:
        heads = [a for a in arrows if np.array_equal(np.asarray(a.xy), line[-1])]
        assert len(heads) >= 1
        motion = line[-1] - line[0]
        assert any(np.dot(np.asarray(a.xy) - np.asarray(a.xyann), motion) > 0 for a in heads)


def test_a_track_that_never_moves_has_no_arrow_but_keeps_its_label(
    crossing: Scenario,
) -> None:
    still = TrackTable(
        track_ids=np.array([7, 7], dtype=np.int64), times=np.array([0.0, 1.0]),
        sensors=("pos", "pos"), states=np.array([[3.0, 4.0], [3.0, 4.0]]),
        variances=np.ones((2, 2)), detection_rows=-np.ones(2, dtype=np.int64),
        state_names=("x", "y"),
    )  # fmt: skip
    _, ax = _draw(crossing, still)
    assert len(_arrows(ax)) == len(_truth_lines(crossing))
    assert [a.get_text() for a in _labels(ax)].count("7") >= 1


# --------------------------------------------------------------------------- layering


def test_truth_is_drawn_under_thinner_see_through_tracks(
    crossing: Scenario, few: TrackTable
) -> None:
    _, ax = _draw(crossing, few)

    def drawn(lines: dict[int, np.ndarray]) -> list:  # type: ignore[type-arg]
        out = []
        for line in lines.values():
            match = [
                artist for artist in ax.get_lines()
                if np.array_equal(np.asarray(artist.get_xydata()), line)
            ]  # fmt: skip
            assert len(match) == 1
            out.append(match[0])
        return out

    truth_lines = drawn(_truth_lines(crossing))
    track_lines = drawn(_track_lines(few))
    assert max(t.get_zorder() for t in truth_lines) < min(t.get_zorder() for t in track_lines)
    assert min(t.get_linewidth() for t in truth_lines) > max(
        t.get_linewidth() for t in track_lines
    )
    assert all(t.get_alpha() is not None and t.get_alpha() < 1 for t in track_lines)


# --------------------------------------------------------------------------- legend


@pytest.mark.parametrize("count", [3, TRACK_LEGEND_LIMIT, TRACK_LEGEND_LIMIT + 8])
def test_the_legend_is_clear_of_the_data_area(crossing: Scenario, count: int) -> None:
    fig, ax = _draw(crossing, _straight_tracks(count))
    fig.tight_layout()
    fig.canvas.draw()
    legend = ax.get_legend()
    assert legend is not None
    box, data = legend.get_window_extent(), ax.get_window_extent()
    assert not box.overlaps(data)
    assert box.x0 >= data.x1  # beside the axes, to the right
    inside = fig.bbox
    assert inside.x0 <= box.x0 and box.x1 <= inside.x1 and box.y0 >= inside.y0


def test_no_legend_when_asked(crossing: Scenario, few: TrackTable) -> None:
    _, ax = _draw(crossing, few, legend=False)
    assert ax.get_legend() is None and len(_arrows(ax)) > 0


# --------------------------------------------------------------------------- files


def test_plot_tracks_writes_a_png_with_the_legend_beside(
    tmp_path: Path, crossing: Scenario, few: TrackTable
) -> None:
    from matplotlib.image import imread

    out = plot_tracks(
        tmp_path / "sub" / "tracks.png", scans=crossing.scans, sensors=crossing.config.sensors,
        tracks=few, truth=crossing.truth, title="crossing", length_unit="m", time_unit="s",
    )  # fmt: skip
    assert out == tmp_path / "sub" / "tracks.png"
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = imread(out)
    height, width = image.shape[:2]
    assert width > height  # the square data area plus the legend to its right
    assert image[..., :3].std() > 0.05  # something is drawn


def test_the_module_imports_without_matplotlib_and_plotting_names_the_extra() -> None:
    script = (
        "import sys\n"
        "import mapassoc.apps.plotting as p\n"
        "assert 'matplotlib' not in sys.modules, 'imported matplotlib at import time'\n"
        "sys.modules['matplotlib'] = None\n"
        "sys.modules['matplotlib.figure'] = None\n"
        "from mapassoc.errors import InputError\n"
        "try:\n"
        "    p._figure(figsize=(2, 2), dpi=50)\n"
        "except InputError as e:\n"
        "    assert \"mapassoc[plot]\" in str(e), str(e)\n"
        "else:\n"
        "    raise AssertionError('no InputError')\n"
        "print('ok')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


def test_up_to_the_legend_limit_every_track_has_its_own_colour(crossing: Scenario) -> None:
    from matplotlib.colors import to_rgba

    tracks = _straight_tracks(TRACK_LEGEND_LIMIT)
    _, ax = _draw(crossing, tracks)
    colours = {
        to_rgba(line.get_color())
        for line in ax.get_lines()
        if re.match(r"track \d", str(line.get_label()))
    }
    assert len(colours) == TRACK_LEGEND_LIMIT


def test_a_geodetic_recording_plots_metres_east_and_north_of_its_origin() -> None:
    from matplotlib.figure import Figure

    from mapassoc.apps.plotting import draw_tracks
    from mapassoc.data.frames import GeodeticPoint
    from mapassoc.data.records import TrackTable
    from mapassoc.data.scans import Scan
    from mapassoc.models.measurement import LinearMeasurement
    from mapassoc.models.motion import ConstantVelocity
    from mapassoc.models.sensor import Region, Sensor

    motion = ConstantVelocity(ndim=2, noise_intensity=1.0)
    sensor = Sensor(
        name="adsb", measurement=LinearMeasurement.position(motion, noise_std=10.0),
        detection_probability=0.9, false_alarms_per_scan=0.1,
        region=Region.from_bounds([[-1e3, 1e3], [-1e3, 1e3]]),
    )  # fmt: skip
    tracks = TrackTable(
        track_ids=np.array([1, 1]), times=np.array([0.0, 1.0]), sensors=("adsb", "adsb"),
        states=np.array([[0.0, 0.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0]]),
        variances=np.ones((2, 4)), detection_rows=np.array([-1, -1]),
        state_names=("x", "y", "vx", "vy"),
    )  # fmt: skip
    scans = [Scan(time=0.0, sensor="adsb", detections=np.zeros((0, 2)), rows=np.zeros(0, int))]
    ax = Figure().add_subplot()
    draw_tracks(ax, scans=scans, sensors={"adsb": sensor}, tracks=tracks,
                origin=GeodeticPoint(52.3086, -4.7639, 0.0))  # fmt: skip
    assert ax.get_xlabel() == "east of 52.3086\N{DEGREE SIGN}N 4.7639\N{DEGREE SIGN}W [m]"
    assert ax.get_ylabel() == "north of 52.3086\N{DEGREE SIGN}N 4.7639\N{DEGREE SIGN}W [m]"
