"""Static checks that run with the suite: ruff, and mypy on the installed package layout.

``formulations/`` and ``solvers/`` are installed as ``mapassoc.formulations`` and
``mapassoc.solvers`` (pyproject's ``package-dir``).  An editable install maps them with an
import hook that the type checker cannot follow, so the check builds that layout from
symbolic links in a temporary folder and checks ``mapassoc`` there, with the project's
``[tool.mypy]`` settings.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow


def _installed_layout(folder: Path) -> Path:
    """``folder/mapassoc`` holding the package as it is installed (links to the sources)."""
    package = folder / "mapassoc"
    package.mkdir()
    for entry in (ROOT / "mapassoc").iterdir():
        if entry.name != "__pycache__":
            (package / entry.name).symlink_to(entry)
    for sub in ("formulations", "solvers"):
        (package / sub).symlink_to(ROOT / sub)
    return package


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", *args], cwd=cwd, capture_output=True, text=True, check=False
    )


def test_the_package_type_checks(tmp_path: Path) -> None:
    _installed_layout(tmp_path)
    result = _run(
        [
            "mypy",
            "mapassoc",
            "--config-file",
            str(ROOT / "pyproject.toml"),
            "--cache-dir",
            str(tmp_path / ".mypy_cache"),
        ],
        cwd=tmp_path,
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_ruff_passes() -> None:
    result = _run(["ruff", "check", "mapassoc", "formulations", "solvers", "tests"], cwd=ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
