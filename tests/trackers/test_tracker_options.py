"""Each tracker's own options from the configuration's ``[trackers.<name>]`` tables."""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from dataclasses import replace

import pytest
from support import MINIMAL_CONFIG_TOML

from mapassoc.apps.cli import _tracker_options
from mapassoc.apps.compare import compare
from mapassoc.data.config import Config, parse_config
from mapassoc.data.outputs import TrackerOutput
from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.trackers.gnn import GnnTracker
from mapassoc.trackers.jpda import JpdaTracker
from mapassoc.trackers.mht import MhtTracker
from mapassoc.trackers.registry import TRACKERS, TrackerSpec, build_tracker


def _config(tables: str = "") -> Config:
    return parse_config(tomllib.loads(MINIMAL_CONFIG_TOML + tables))


def test_a_trackers_table_reaches_the_tracker() -> None:
    config = _config("[trackers.mht]\nn_scan = 5\nm_best = 2\n[trackers.jpda]\nmax_events = 77\n")
    mht = build_tracker("mht", config=config)
    assert isinstance(mht, MhtTracker) and (mht.n_scan, mht.m_best) == (5, 2)
    jpda = build_tracker("jpda", config=config)
    assert isinstance(jpda, JpdaTracker) and jpda.max_events == 77
    # Without a table: the class's defaults.
    default = build_tracker("mht", config=_config())
    assert isinstance(default, MhtTracker) and (default.n_scan, default.m_best) == (3, 1)


def test_an_unknown_option_lists_the_trackers_options() -> None:
    config = _config("[trackers.mht]\nnscan = 5\n")
    listed = "unknown option 'nscan'; options of 'mht': gate_probability, n_scan,"
    with pytest.raises(InputError, match=listed) as info:
        build_tracker("mht", config=config)
    assert info.value.key == "trackers.mht.nscan"
    # A method without options of its own says so.
    with pytest.raises(InputError, match=r"options of 'map': \(none\)"):
        build_tracker("map", config=_config("[trackers.map]\nwindow_length = 3\n"))


def test_a_refused_value_names_its_key() -> None:
    with pytest.raises(InputError, match="trackers.mht: n_scan must be an integer >= 1") as info:
        build_tracker("mht", config=_config("[trackers.mht]\nn_scan = 0\n"))
    assert info.value.key == "trackers.mht.n_scan"


def test_only_scalar_keyword_options_are_settable() -> None:
    # MHT's management rule is an object, not a TOML value: not an option of the table.
    options = TRACKERS["mht"].option_names()
    assert "n_scan" in options and "solver" in options
    assert "management" not in options and "config" not in options and "name" not in options


class ThrowawayTracker:
    """A tracker with an option of its own, registered by the test below only."""

    def __init__(self, *, config: Config, level: float = 1.0, label: str = "x") -> None:
        if not level > 0:
            raise InputError(f"level must be > 0, got {level!r}")
        self.config = config
        self.level = level
        self.label = label
        self.name = "throwaway"

    def track(self, scans: Sequence[Scan]) -> TrackerOutput:
        return GnnTracker(config=self.config).track(scans)


def test_a_new_tracker_with_its_own_options_is_one_class_and_one_row(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    spec = TrackerSpec("throwaway", __name__, "ThrowawayTracker", "a test's tracker")
    monkeypatch.setitem(TRACKERS, "throwaway", spec)
    assert spec.option_names() == ("level", "label")
    config = _config('[trackers.throwaway]\nlevel = 2.5\nlabel = "y"\n')
    tracker = build_tracker("throwaway", config=config)
    assert isinstance(tracker, ThrowawayTracker)
    assert (tracker.level, tracker.label) == (2.5, "y")
    with pytest.raises(InputError, match="trackers.throwaway: level must be > 0") as info:
        build_tracker("throwaway", config=replace(config, trackers={"throwaway": {"level": -1}}))
    assert info.value.key == "trackers.throwaway.level"


def test_compare_hands_its_tracker_options_to_the_trackers(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    seen: list[tuple[str, object]] = []
    real = build_tracker

    def spy(name: str, *, config: Config, origins: object = None):  # type: ignore[no-untyped-def]
        seen.append((name, config.trackers.get(name)))
        return real(name, config=config, origins=origins)  # type: ignore[arg-type]

    monkeypatch.setattr("mapassoc.apps.compare.build_tracker", spy)
    table = compare(["mht"], ["crossing"], [0], scans=6, tracker_options={"mht": {"n_scan": 2}})
    assert list(table["status"]) == ["ok"]
    assert seen and all(options == {"n_scan": 2} for _, options in seen)


def test_compare_checks_tracker_options_before_running() -> None:
    with pytest.raises(InputError, match="unknown option 'nscan'"):
        compare(["mht"], ["crossing"], [0], scans=6, tracker_options={"mht": {"nscan": 2}})
    with pytest.raises(InputError, match="unknown tracker 'mhtt'"):
        compare(["mht"], ["crossing"], [0], scans=6, tracker_options={"mhtt": {"n_scan": 2}})


def test_the_command_lines_options_are_toml_values() -> None:
    assert _tracker_options(None) is None
    assert _tracker_options(["mht.n_scan=5", "mht.solver=highs", "flow.max_gap = 3"]) == {
        "mht": {"n_scan": 5, "solver": "highs"},
        "flow": {"max_gap": 3},
    }
    assert _tracker_options(["lp.time_limit=2.5", "mht.m_best_pruning=true"]) == {
        "lp": {"time_limit": 2.5},
        "mht": {"m_best_pruning": True},
    }
    with pytest.raises(InputError, match="TRACKER.OPTION=VALUE"):
        _tracker_options(["n_scan=5"])


@pytest.mark.parametrize("name", ["gnn", "jpda", "mht", "flow"])
def test_each_baseline_gates_at_its_own_probability(name: str) -> None:
    config = _config(f"[trackers.{name}]\ngate_probability = 0.9\n")
    own = build_tracker(name, config=config)
    assert own.config.estimator.gate_probability == 0.9  # type: ignore[attr-defined]
    assert config.estimator.gate_probability == 0.999  # the estimator's own is untouched
    default = build_tracker(name, config=_config())
    assert default.config.estimator.gate_probability == 0.999  # type: ignore[attr-defined]
    with pytest.raises(InputError, match="gate_probability") as info:
        build_tracker(name, config=_config(f"[trackers.{name}]\ngate_probability = 1.5\n"))
    assert info.value.key == f"trackers.{name}.gate_probability"


def test_a_narrow_gate_changes_what_gnn_associates() -> None:
    from mapassoc.evaluation.scenarios import build_scenario, truncate_scenario

    scenario = truncate_scenario(build_scenario("crossing", 0), 20)
    wide = GnnTracker(config=scenario.config).track(scenario.scans)
    narrow = GnnTracker(config=scenario.config, gate_probability=0.05).track(scenario.scans)

    def associated(output: TrackerOutput) -> int:
        return sum(len(rows) for rows in (output.associations or {}).values())

    assert associated(narrow) < associated(wide)
