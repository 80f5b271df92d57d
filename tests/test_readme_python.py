"""Every Python block of README.md and of the documentation's getting-started and Python
pages (docs/getting-started.md, docs/guides/python.md) runs as written (the quick starts
cannot rot).

The blocks run in order, each in a fresh namespace, in a folder where `mapassoc simulate
crossing --out scen` has run (the README says so where a block reads `scen/`).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = (
    ROOT / "README.md",
    ROOT / "docs" / "getting-started.md",
    ROOT / "docs" / "guides" / "python.md",
)


def _blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.DOTALL)


BLOCKS = [block for page in PAGES for block in _blocks(page)]


def test_the_readme_starts_with_a_python_example() -> None:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert _blocks(ROOT / "README.md")
    assert text.index("```python") < len("\n".join(text.splitlines()[:60]))
    assert len(text.splitlines()) <= 150


def test_the_python_page_has_its_examples() -> None:
    assert len(_blocks(ROOT / "docs" / "guides" / "python.md")) >= 2


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
    exec(compile(BLOCKS[index], f"python block {index}", "exec"), namespace)  # noqa: S102
