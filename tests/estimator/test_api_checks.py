"""The Python entry points check their arguments as the command line does (issue 19).

``WindowEstimator(config="x.toml")``, ``run("file.csv")``, ``run(DataFrame)`` raised raw
AttributeErrors, and ``solve_window`` accepted scans in reverse time order or the same
scan three times.  One check (:func:`mapassoc.data.scans.check_scans`) now serves
``start``, ``run``, ``solve_window`` and every tracker's ``track``; each failure is one
InputError saying what to pass.  The time-step warning of ``start`` is tested here too.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import mapassoc as ma
from mapassoc.apps.cli import main
from mapassoc.data.config import write_config
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.estimator.pipeline import WindowEstimator, time_scale_warning
from mapassoc.evaluation.scenarios import (
    build_scenario,
    generic_config,
    scenario_names,
    truncate_scenario,
)
from mapassoc.trackers.registry import TRACKERS, build_tracker

SCENARIO = truncate_scenario(build_scenario("crossing", 0), 6)


def _entry_points() -> dict[str, Callable[[object], object]]:
    """Every public function that takes a run's scans, by name."""
    estimator = WindowEstimator(config=SCENARIO.config)
    points: dict[str, Callable[[object], object]] = {
        "WindowEstimator.run": estimator.run,
        "WindowEstimator.start": estimator.start,
        "WindowEstimator.solve_window": estimator.solve_window,
    }
    for name, spec in TRACKERS.items():
        tracker = build_tracker(
            name, config=SCENARIO.config, origins=SCENARIO.origins if spec.needs_truth else None
        )
        points[f"{name}.track"] = tracker.track
    return points


ENTRY_POINTS = _entry_points()

BAD_SCANS = [
    # (what is passed, a phrase of the message: what to do instead)
    ("scen/detections.csv", "read_detections_file(path, config.sensors)"),
    (Path("scen/detections.csv"), "read_detections_file(path, config.sensors)"),
    (pd.DataFrame({"time": [0.0], "sensor": ["pos"], "x": [1.0], "y": [2.0]}),
     "scans_from_frame(frame, config.sensors)"),
    (np.zeros((4, 3)), "scans_from_arrays(times, measurements, config.sensors)"),
    (SCENARIO.scans[0], "pass [scan]"),
    ([SCENARIO.scans[0], "x"], "scans[1] must be a mapassoc.Scan"),
    (None, "must be a sequence of mapassoc.Scan"),
    (SCENARIO.scans[:5][::-1], "sorted by (time, sensor)"),
    ([SCENARIO.scans[0]] * 3, "sorted by (time, sensor) without repeats"),
    ([], "is empty"),
]  # fmt: skip
BAD_IDS = ["str", "path", "frame", "array", "one_scan", "not_scan", "none", "reversed",
           "thrice", "empty"]  # fmt: skip


@pytest.mark.parametrize("entry", sorted(ENTRY_POINTS))
@pytest.mark.parametrize(("scans", "phrase"), BAD_SCANS, ids=BAD_IDS)
def test_every_entry_point_refuses_what_is_not_a_run_of_scans(
    entry: str, scans: object, phrase: str
) -> None:
    with pytest.raises(InputError) as info:
        ENTRY_POINTS[entry](scans)
    message = str(info.value)
    assert phrase in message and "\n" not in message, message


def test_solve_window_and_run_refuse_the_same_scans_with_the_same_message() -> None:
    estimator = WindowEstimator(config=SCENARIO.config)
    for scans, _ in BAD_SCANS:
        messages = []
        for call in (estimator.run, estimator.solve_window):
            with pytest.raises(InputError) as info:
                call(scans)  # type: ignore[arg-type]
            messages.append(str(info.value).replace("solve", "estimate"))
        assert messages[0] == messages[1]
    # A proper window still solves: the first window of run() (the docstring's promise).
    window = estimator.solve_window(SCENARIO.scans[:5])
    first = estimator.run(SCENARIO.scans).windows[0]
    np.testing.assert_array_equal(
        window.posterior.probabilities[: len(first.p_k)], first.p_k
    )


@pytest.mark.parametrize(
    ("config", "phrase"),
    [
        ("x.toml", "config=mapassoc.load_config('x.toml')"),
        (Path("x.toml"), "config=mapassoc.load_config("),
        (None, "mapassoc.load_config(path)"),
        ({"motion": {}}, "mapassoc.parse_config(data)"),
    ],
)
def test_a_config_that_is_not_a_config_says_how_to_get_one(config: object, phrase: str) -> None:
    builders: list[Callable[[], object]] = [lambda: WindowEstimator(config=config)]  # type: ignore[arg-type]
    for name, spec in TRACKERS.items():
        origins = SCENARIO.origins if spec.needs_truth else None
        builders.append(lambda n=name, o=origins: build_tracker(n, config=config, origins=o))  # type: ignore[misc]
    for build in builders:
        with pytest.raises(InputError) as info:
            build()
        message = str(info.value)
        assert message.startswith("config must be a Config (mapassoc.Config), got ")
        assert phrase in message and "\n" not in message


# ------------------------------------------------------------------ time-step warning


def _timed(scenario: ma.evaluation.scenarios.Scenario, factor: float) -> list[Scan]:  # type: ignore[name-defined]
    return [Scan(s.time * factor, s.sensor, s.detections, s.rows) for s in scenario.scans]


def _unit_warnings(config: ma.Config, scans: list[Scan]) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        WindowEstimator(config=config).start(scans)
    return [str(w.message) for w in caught if "time units apart" in str(w.message)]


@pytest.mark.parametrize("name", scenario_names())
def test_no_built_in_scenario_warns_about_its_time_step(name: str) -> None:
    scenario = build_scenario(name, 0)
    for config in (scenario.config, generic_config(scenario)):
        assert _unit_warnings(config, list(scenario.scans)) == []
        assert time_scale_warning(config, scenario.scans) is None


@pytest.mark.parametrize("factor", [1e3, 1e9])
def test_times_in_milliseconds_or_nanoseconds_warn_naming_the_keys(factor: float) -> None:
    scenario = build_scenario("crossing", 0)
    messages = _unit_warnings(scenario.config, _timed(scenario, factor))
    assert len(messages) == 1
    message = messages[0]
    assert f"{factor:.6g} time units apart" in message
    assert f"velocity_std = {scenario.config.birth.velocity_std!r} per time unit" in message
    assert "time column" in message and "sensor 'pos'" in message and "\n" not in message


def test_the_warning_reaches_summary_json(tmp_path: Path) -> None:
    scenario = truncate_scenario(build_scenario("crossing", 0), 8)
    ma.write_detections_file(tmp_path / "detections.csv", _timed(scenario, 1e3),
                             scenario.config.sensors)  # fmt: skip
    write_config(tmp_path / "config.toml", scenario.config)
    out = tmp_path / "run"
    args = ["run", str(tmp_path / "config.toml"), str(tmp_path / "detections.csv")]
    assert main([*args, "--out", str(out), "--no-progress", "--no-timings"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert any("time units apart" in w for w in summary["warnings"])
