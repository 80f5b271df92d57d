"""Every Python block of README.md runs as written (the quick start cannot rot).

The blocks run in order, each in a fresh namespace, in a folder where `mapassoc simulate
crossing --out scen` has run (the README says so where a block reads `scen/`).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.DOTALL)


def test_the_readme_has_python_blocks() -> None:
    assert len(BLOCKS) >= 3


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_python_block_runs(
    index: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import matplotlib

    from mapassoc.apps.cli import main

    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "crossing", "--out", "scen"]) == 0
    namespace: dict[str, object] = {"__name__": "__readme__"}
    exec(compile(BLOCKS[index], f"README.md python block {index}", "exec"), namespace)  # noqa: S102
