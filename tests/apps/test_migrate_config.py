"""``mapassoc migrate-config``: a file with the old flat [estimator] keys rewritten in the
current layout, which loads with no warning and gives the same configuration."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
from support import MINIMAL_CONFIG_TOML

from mapassoc.apps.cli import main
from mapassoc.data.config import config_to_toml, load_config

OLD = MINIMAL_CONFIG_TOML + """
[birth]
rate = 0.2

[estimator]
window_length = 4
time_limit = 600.0
prune_log_ratio = 7.0
refine_passes = 2
k_prior = "uniform"

[trackers.mht]
n_scan = 3
"""


def test_the_rewritten_file_loads_silently_to_the_same_config(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    old = tmp_path / "old.toml"
    old.write_text(OLD, encoding="utf-8")
    new = tmp_path / "new.toml"
    assert main(["migrate-config", str(old), "--out", str(new)]) == 0
    out, err = capsys.readouterr()
    assert out == f"{old} -> {new}\n" and err == ""  # the deprecation is what it fixes
    assert old.read_text(encoding="utf-8") == OLD  # the input is left as it is
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        migrated = load_config(new)
    with pytest.warns(DeprecationWarning):
        original = load_config(old)
    assert migrated.estimator == original.estimator
    assert migrated.birth == original.birth and migrated.trackers == original.trackers
    assert config_to_toml(migrated) == config_to_toml(original)
    text = new.read_text(encoding="utf-8")
    assert "[estimator.windows]\nwindow_length = 4\nstride = 1\ntime_limit = 600.0\n" in text
    assert "\n[estimator]\n" not in text


def test_without_out_it_prints_and_it_never_overwrites(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    old = tmp_path / "old.toml"
    old.write_text(OLD, encoding="utf-8")
    assert main(["migrate-config", str(old)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("# mapassoc configuration\n") and "[estimator.count]" in printed
    taken = tmp_path / "taken.toml"
    taken.write_text("mine\n", encoding="utf-8")
    assert main(["migrate-config", str(old), "--out", str(taken)]) == 2
    assert "taken.toml exists already" in capsys.readouterr().err
    assert taken.read_text(encoding="utf-8") == "mine\n"


def test_a_bad_old_file_is_one_line_naming_the_key(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    old = tmp_path / "old.toml"
    old.write_text(OLD.replace("window_length = 4", "window_length = 0"), encoding="utf-8")
    assert main(["migrate-config", str(old), "--out", str(tmp_path / "new.toml")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mapassoc: error: ") and "'estimator.window_length'" in err
    assert not (tmp_path / "new.toml").exists()
