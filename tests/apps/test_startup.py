"""The command line starts fast: `--help` and input errors import no heavy library.

Every `mapassoc` command pays the import of the command line; scipy.optimize, scipy.sparse,
cvxpy, networkx and pandas cost seconds on a cold machine and are imported only by the
commands that use them.  (Time itself is measured by the benchmark, not here: these
tests check what is imported, which does not depend on the machine's speed.)
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

HEAVY = (
    "scipy.optimize",
    "scipy.sparse",
    "cvxpy",
    "highspy",
    "networkx",
    "pandas",
    "tqdm",
    "matplotlib",
    "numba",
)


def _imported_after(code: str) -> list[str]:
    probe = (
        "import sys\n"
        f"{code}\n"
        f"print(__import__('json').dumps([m for m in {HEAVY!r} if m in sys.modules]))\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=120, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("argv", [["--help"], ["run", "--help"], ["compare", "--help"],
                                  ["--version"]])
def test_help_imports_no_heavy_library(argv: list[str]) -> None:
    code = (
        "from mapassoc.apps.cli import main\n"
        "import contextlib, io\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n"
        f"        main({argv!r})\n"
        "    except SystemExit:\n"
        "        pass"
    )
    assert _imported_after(code) == []


def test_a_missing_input_fails_before_any_heavy_import(tmp_path: Path) -> None:
    code = (
        "from mapassoc.apps.cli import main\n"
        f"assert main(['run', {str(tmp_path / 'no.toml')!r}, {str(tmp_path / 'no.csv')!r},"
        f" '--out', {str(tmp_path / 'out')!r}]) == 2"
    )
    assert _imported_after(code) == []


def test_importing_the_package_is_lazy() -> None:
    assert _imported_after("import mapassoc") == []
