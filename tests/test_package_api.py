"""The package's public names: every one resolves, and importing the package is cheap."""

from __future__ import annotations

import subprocess
import sys

import pytest

import mapassoc


@pytest.mark.parametrize("name", mapassoc.__all__)
def test_every_public_name_is_the_defining_modules_object(name: str) -> None:
    import importlib

    module = importlib.import_module(mapassoc._EXPORTS[name])
    assert getattr(mapassoc, name) is getattr(module, name)


def test_an_unknown_name_is_an_attribute_error_naming_it() -> None:
    with pytest.raises(AttributeError, match="no_such_thing"):
        mapassoc.no_such_thing  # type: ignore[attr-defined]  # noqa: B018


def test_importing_the_package_loads_no_numerics() -> None:
    """``import mapassoc`` (and so ``mapassoc --help``) does not load numpy, scipy or the
    estimator; the first use of a name does."""
    code = (
        "import sys, mapassoc; "
        "heavy = [m for m in ('numpy', 'scipy', 'mapassoc.estimator.pipeline') "
        "if m in sys.modules]; "
        "assert not heavy, heavy; "
        "mapassoc.CountPrior; "
        "assert 'mapassoc.models.target_count' in sys.modules"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_the_notebook_example_runs_from_the_package_alone() -> None:
    scenario = mapassoc.build_scenario("crossing", 0)
    result = mapassoc.WindowEstimator(config=scenario.config).run(scenario.scans[:8])
    assert result.num_scans == 8 and result.windows
