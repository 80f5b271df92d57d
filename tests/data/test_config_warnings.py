"""load_config: warnings for the optional sections it defaults, and the solver-name check."""

from __future__ import annotations

import tomllib
import warnings
from pathlib import Path

import pytest
from support import MINIMAL_CONFIG_TOML

from mapassoc.data.config import load_config, parse_config
from mapassoc.data.settings import EstimatorSettings
from mapassoc.errors import ConfigError, InputError
from mapassoc.solvers import SOLVER_NAMES, available_solvers

BASE = MINIMAL_CONFIG_TOML
BIRTH = "\n[birth]\nrate = 0.2\n"
ESTIMATOR = "\n[estimator.windows]\nwindow_length = 4\n"


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "config.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_missing_estimator_section_warns_with_the_file_and_the_defaults(
    tmp_path: Path,
) -> None:
    path = write(tmp_path, BASE + BIRTH)
    with pytest.warns(UserWarning) as caught:
        config = load_config(path)
    messages = [str(w.message) for w in caught]
    assert messages == [
        f"{path} has no [estimator] section: the defaults of EstimatorSettings are used "
        "(windows.window_length 5, windows.stride 1, windows.time_limit 2.0, "
        "pruning.gate_probability 0.999, pruning.max_hypotheses_per_tree 64, "
        "pruning.prune_log_ratio 9.0, search.solver 'highs', search.exact_work_limit 500000, "
        "search.beam_width 200, search.bound_prune_log_ratio 9.0, "
        "search.program_time_limit 2.0, search.beam_entry_margin 40.0, "
            "search.mass_bound_multiplier_limit 30.0, search.mass_bound_multipliers 25, "
            "count.max_tracks 20, count.k_prior 'birth', "
        "count.k_prior_mean 5.0, count.k_prior_weights [], count.k_estimate 'marginal', "
        "refinement.passes 6, refinement.scan_windows True, refinement.link_gap 10, "
        "refinement.refilter_detections 15, refinement.prune_log_ratio 18.0, "
        "refinement.long_prune_log_ratio 9.0, refinement.identity_moves True, "
        "refinement.group_moves True, refinement.min_existence 0.0, "
        "parameters.rate_tolerance 0.02, parameters.pd_tolerance 0.005, "
        "parameters.max_passes 3, parameters.sample_scans 600, "
        "parameters.sample_blocks_count 6, parameters.soft_counts True)"
    ]
    assert config.estimator == EstimatorSettings()  # still optional: the defaults are used
    assert config.birth.rate == 0.2


def test_a_missing_birth_section_warns_with_the_file_and_the_defaults(tmp_path: Path) -> None:
    path = write(tmp_path, BASE + ESTIMATOR)
    with pytest.warns(
        UserWarning,
        match=r"config\.toml has no \[birth\] section: the defaults of BirthModel are used "
        r"\(rate 0\.1, initial_count 0\.0, velocity_std 10\.0, acceleration_std 1\.0, "
        r"speed_std 10\.0, turn_rate_std 0\.1, survival_probability 0\.99\)",
    ):
        load_config(path)


def test_both_sections_missing_give_two_warnings_and_both_present_none(tmp_path: Path) -> None:
    with pytest.warns(UserWarning) as caught:
        load_config(write(tmp_path, BASE))
    messages = [str(w.message) for w in caught]
    assert len(messages) == 2
    assert messages[0].startswith(f"{tmp_path / 'config.toml'} has no [birth] section")
    assert messages[1].startswith(f"{tmp_path / 'config.toml'} has no [estimator] section")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_config(write(tmp_path, BASE + BIRTH + ESTIMATOR))
        document = tomllib.loads(BASE)
        parse_config(document)  # a parsed mapping is not a file: no warning


def test_an_unknown_solver_names_the_file_the_key_the_value_and_the_known_solvers(
    tmp_path: Path,
) -> None:
    path = write(tmp_path, BASE + BIRTH + '\n[estimator]\nsolver = "gurobi"\n')
    names = available_solvers()
    with pytest.raises(ConfigError) as info:
        load_config(path, solver_names=names)
    assert str(info.value) == (
        f"{path}: config key 'estimator.solver': unknown solver 'gurobi'; known solvers: "
        + ", ".join(names)
    )
    assert info.value.key == "estimator.solver" and info.value.source == str(path)
    assert "highs" in str(info.value)


def test_known_solvers_pass_and_without_names_the_check_is_left_to_the_pipeline(
    tmp_path: Path,
) -> None:
    for name in available_solvers():
        path = write(tmp_path, BASE + BIRTH + f'\n[estimator.search]\nsolver = "{name}"\n')
        config = load_config(path, solver_names=SOLVER_NAMES)
        assert config.estimator.search.solver == name
    path = write(tmp_path, BASE + BIRTH + '\n[estimator.search]\nsolver = "gurobi"\n')
    assert load_config(path).estimator.search.solver == "gurobi"


def test_the_default_solver_is_checked_too_and_solver_names_must_be_names(tmp_path: Path) -> None:
    path = write(tmp_path, BASE + BIRTH + ESTIMATOR)
    message = r"estimator\.search\.solver': unknown solver 'highs'; known solvers: cvxpy-clarabel$"
    with pytest.raises(ConfigError, match=message):
        load_config(path, solver_names=["cvxpy-clarabel"])
    with pytest.raises(InputError, match=r"solver_names must be a collection of names, got 'hi"):
        load_config(path, solver_names="highs")
