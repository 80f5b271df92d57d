"""The README's promises on the command line: one line naming the file, warnings recorded."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mapassoc.apps.cli import main


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("scen") / "crossing"
    assert main(["simulate", "crossing", "--out", str(out), "--seed", "0"]) == 0
    return out


def _run(config: Path, detections: Path, out: Path) -> int:
    return main(["run", str(config), str(detections), "--out", str(out), "--no-progress"])


def test_header_only_detections_names_the_file_and_creates_nothing(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    empty = tmp_path / "empty.csv"
    empty.write_text("time,sensor,x,y\n")
    out = tmp_path / "out"
    assert _run(scenario / "config.toml", empty, out) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "empty.csv" in err
    assert not out.exists() and not out.with_name("out.partial").exists()


def test_unknown_solver_names_the_file(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "solver.toml"
    text = (scenario / "config.toml").read_text()
    assert 'solver = "highs"' in text
    config.write_text(text.replace('solver = "highs"', 'solver = "gurobi"'))
    assert _run(config, scenario / "detections.csv", tmp_path / "out") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "solver.toml" in err and "estimator.search.solver" in err and "gurobi" in err
    assert "highs" in err  # the known names


def test_bad_byte_is_reported_on_its_line(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = (scenario / "detections.csv").read_bytes().split(b"\n")
    data[2] = data[2].replace(b",", b",\xff", 1)
    bad = tmp_path / "bad.csv"
    bad.write_bytes(b"\n".join(data))
    assert _run(scenario / "config.toml", bad, tmp_path / "out") == 2
    err = capsys.readouterr().err
    assert "bad.csv, line 3" in err and err.count("\n") == 1


def test_run_records_warnings_on_region_and_sections(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Detections moved far outside the region, and a config without [birth].
    lines = (scenario / "detections.csv").read_text().splitlines()
    header = lines[0].split(",")
    ix = header.index("x")
    moved = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        if cells[ix]:
            cells[ix] = repr(float(cells[ix]) + 1e6)
        moved.append(",".join(cells))
    far = tmp_path / "far.csv"
    far.write_text("\n".join(moved) + "\n")
    text = (scenario / "config.toml").read_text()
    start = text.index("[birth]")
    end = text.index("[", start + 1)
    config = tmp_path / "nobirth.toml"
    config.write_text(text[:start] + text[end:])
    out = tmp_path / "out"
    assert _run(config, far, out) == 0
    summary = json.loads((out / "summary.json").read_text())
    warned = " ".join(summary["warnings"])
    assert "no [birth] section" in warned and "nobirth.toml" in warned
    assert "outside" in warned and "pos" in warned
    err = capsys.readouterr().err
    assert "mapassoc: warning:" in err and "no [birth] section" in err


def test_evaluate_warns_when_no_time_is_shared(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert _run(scenario / "config.toml", scenario / "detections.csv", out) == 0
    lines = (scenario / "truth.csv").read_text().splitlines()
    header = lines[0].split(",")
    it = header.index("time")
    shifted = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[it] = repr(float(cells[it]) + 1000.5)
        shifted.append(",".join(cells))
    truth = tmp_path / "truth.csv"
    truth.write_text("\n".join(shifted) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(out / "tracks.csv"), str(truth)]) == 0
    err = capsys.readouterr().err
    assert "mapassoc: warning:" in err and "share no time" in err


def test_evaluate_warns_on_a_header_only_truth_file(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    assert _run(scenario / "config.toml", scenario / "detections.csv", out) == 0
    truth = tmp_path / "truth.csv"
    truth.write_text((scenario / "truth.csv").read_text().splitlines()[0] + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(out / "tracks.csv"), str(truth)]) == 0
    err = capsys.readouterr().err
    assert err.startswith("mapassoc: warning: the truth has no record") and err.count("\n") == 1


def test_simulate_scans_and_duration(tmp_path: Path) -> None:
    from mapassoc.data.config import load_config
    from mapassoc.data.io import read_detections

    assert main(["simulate", "crossing", "--scans", "150", "--out", str(tmp_path / "a")]) == 0
    config = load_config(tmp_path / "a" / "config.toml")
    assert len(read_detections(tmp_path / "a" / "detections.csv", config.sensors)) == 150
    assert main(["simulate", "two_sensors", "--duration", "20", "--out",
                 str(tmp_path / "b")]) == 0
    config = load_config(tmp_path / "b" / "config.toml")
    scans = read_detections(tmp_path / "b" / "detections.csv", config.sensors)
    assert len(scans) == 40  # two sensors, one scan each per 0.5 time units -> 40 in 20
    assert main(["simulate", "crossing", "--scans", "0", "--out", str(tmp_path / "c")]) == 2


def test_parquet_detections_run_like_csv(scenario: Path, tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    from mapassoc.data.config import load_config
    from mapassoc.data.formats import read_tracks_file, write_detections_file
    from mapassoc.data.io import read_detections

    config = load_config(scenario / "config.toml")
    scans = read_detections(scenario / "detections.csv", config.sensors)
    write_detections_file(tmp_path / "d.parquet", scans, config.sensors)
    assert _run(scenario / "config.toml", tmp_path / "d.parquet", tmp_path / "pq") == 0
    assert _run(scenario / "config.toml", scenario / "detections.csv", tmp_path / "csv") == 0
    assert main(["run", str(scenario / "config.toml"), str(tmp_path / "d.parquet"), "--out",
                 str(tmp_path / "pq2"), "--no-progress", "--tracks-format", "parquet"]) == 0
    assert not (tmp_path / "pq2" / "tracks.csv").exists()
    a = read_tracks_file(tmp_path / "pq" / "tracks.csv")
    b = read_tracks_file(tmp_path / "csv" / "tracks.csv")
    c = read_tracks_file(tmp_path / "pq2" / "tracks.parquet")
    import numpy as np

    for other in (b, c):
        np.testing.assert_array_equal(a.states, other.states)
        np.testing.assert_array_equal(a.detection_rows, other.detection_rows)
        np.testing.assert_array_equal(a.track_ids, other.track_ids)


def test_simulate_parquet_runs_to_the_csv_tracks(tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    from mapassoc.data.formats import read_origins_file, read_tracks_file, read_truth_file

    assert main(["simulate", "crossing", "--out", str(tmp_path / "c"), "--seed", "5"]) == 0
    assert main(["simulate", "crossing", "--out", str(tmp_path / "p"), "--seed", "5",
                 "--format", "parquet"]) == 0
    for kind in ("truth", "origins"):
        read = read_truth_file if kind == "truth" else read_origins_file
        a, b = read(tmp_path / "c" / f"{kind}.csv"), read(tmp_path / "p" / f"{kind}.parquet")
        assert a.size == b.size
    for folder, name in (("c", "detections.csv"), ("p", "detections.parquet")):
        assert _run(tmp_path / folder / "config.toml", tmp_path / folder / name,
                    tmp_path / f"run-{folder}") == 0
    a = read_tracks_file(tmp_path / "run-c" / "tracks.csv")
    b = read_tracks_file(tmp_path / "run-p" / "tracks.csv")
    import numpy as np

    np.testing.assert_array_equal(a.detection_rows, b.detection_rows)  # same ids: CSV lines
    np.testing.assert_array_equal(a.states, b.states)
    assert main(["evaluate", str(tmp_path / "run-p" / "tracks.csv"),
                 str(tmp_path / "p" / "truth.parquet")]) == 0


def _tiny_tracks_and_truth(folder: Path) -> tuple[Path, Path]:
    tracks, truth = folder / "tracks.csv", folder / "truth.csv"
    tracks.write_text(
        "track_id,time,sensor,x,y,var_x,var_y,detection_row\n"
        "1,0.0,pos,0.5,0.0,1.0,1.0,2\n1,1.0,pos,1.5,0.0,1.0,1.0,3\n"
    )
    truth.write_text("target_id,time,x,y\n1,0.0,0.0,0.0\n1,1.0,1.0,0.0\n")
    return tracks, truth


@pytest.mark.parametrize(
    ("options", "fragment"),
    [
        (["--cutoff", "1e300"], "c^p = 1e+300^2.0 overflows"),
        (["--order", "1e300"], "c^p = 10.0^1e+300 overflows"),
        (["--order", "2000"], "c^p = 10.0^2000.0 overflows"),
        (["--cutoff", "1e-300"], "c^p = 1e-300^2.0 underflows"),
        (["--switch-cost", "1e300"], "switch_cost^p = 1e+300^2.0 overflows"),
    ],
)
def test_evaluate_refuses_costs_a_double_cannot_hold(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: list[str], fragment: str
) -> None:
    """c^p beyond a double was an OverflowError traceback; now one line and status 2."""
    tracks, truth = _tiny_tracks_and_truth(tmp_path)
    assert main(["evaluate", str(tracks), str(truth), *options]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"mapassoc: error: {fragment}") and err.count("\n") == 1
    assert main(["evaluate", str(tracks), str(truth), "--cutoff", "20", "--order", "3"]) == 0


def test_a_config_nested_too_deeply_is_one_line(
    scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A TOML value nested 500 deep was a RecursionError traceback from the TOML reader."""
    deep = tmp_path / "deep.toml"
    deep.write_text(
        (scenario / "config.toml").read_text() + "\n[trackers.mht]\nx = " + "[" * 500
        + "]" * 500 + "\n"
    )  # fmt: skip
    assert _run(deep, scenario / "detections.csv", tmp_path / "out") == 2
    err = capsys.readouterr().err
    assert err.startswith(f"mapassoc: error: {deep}: config key '<file>': invalid TOML: ")
    assert "nested too deeply" in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()
    option = "mht.x=" + "[" * 1000 + "]" * 1000
    assert main(["compare", "--option", option, "--out", str(tmp_path / "cmp")]) == 2
    assert "nested too deeply" in capsys.readouterr().err
    assert not (tmp_path / "cmp").exists()


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("tiny") / "crossing"
    assert main(["simulate", "crossing", "--out", str(out), "--seed", "1", "--scans", "8"]) == 0
    return out


def _edited_detections(source: Path, target: Path, column: int, change: float,
                       scale: float = 1.0) -> Path:  # fmt: skip
    """``source`` with ``column`` of every line times ``scale`` plus ``change``."""
    lines = source.read_text().splitlines()
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[column] = repr(float(cells[column]) * scale + change)
        out.append(",".join(cells))
    target.write_text("\n".join(out) + "\n")
    return target


def _warning_lines(err: str) -> list[str]:
    lines = err.strip().splitlines()
    assert all(line.startswith("mapassoc: warning: ") for line in lines), err
    return lines


def test_estimate_parameters_prints_its_warnings_as_run_does(
    tiny: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A missing [birth] and times in milliseconds were raw UserWarning / RuntimeWarning
    lines (with the source line under them); now `mapassoc: warning: ...`, once each."""
    text = (tiny / "config.toml").read_text()
    config = tmp_path / "nobirth.toml"
    config.write_text(text[: text.index("[birth]")] + text[text.index("[estimator.") :])
    ms = _edited_detections(tiny / "detections.csv", tmp_path / "ms.csv", 0, 0.0, 1000.0)
    capsys.readouterr()
    assert main(["estimate-parameters", str(config), str(ms), "--no-progress"]) == 0
    lines = _warning_lines(capsys.readouterr().err)
    assert sum("has no [birth] section" in line for line in lines) == 1
    assert sum("not milliseconds or nanoseconds" in line for line in lines) == 1


def test_estimate_parameters_warns_when_detections_are_outside(
    tiny: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`run` warned that every detection is outside the region; estimate-parameters
    said nothing.  Both now use the same check."""
    outside = _edited_detections(tiny / "detections.csv", tmp_path / "out.csv", 2, 5000.0)
    capsys.readouterr()
    assert main(["estimate-parameters", str(tiny / "config.toml"), str(outside),
                 "--no-progress"]) == 0  # fmt: skip
    lines = _warning_lines(capsys.readouterr().err)
    assert any("detections lie outside its region" in line for line in lines)


def test_estimate_parameters_writes_the_pd_it_says_it_kept(
    tiny: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Too few track scans to estimate Pd: it keeps the configured 0.9, and --write once
    wrote 0.95 (the estimation's start) while the table said "(kept)"."""
    written = tmp_path / "estimated.toml"
    assert main(["estimate-parameters", str(tiny / "config.toml"), str(tiny / "detections.csv"),
                 "--no-progress", "--write", str(written)]) == 0  # fmt: skip
    out, err = capsys.readouterr()
    assert "0.900 0.900 (kept)" in out
    assert "detection_probability not estimable" in err and "kept 0.9\n" in err
    assert "detection_probability = 0.9\n" in written.read_text()
