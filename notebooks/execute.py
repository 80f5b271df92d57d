"""Re-execute every notebook in this folder in place, so the committed copies carry their
outputs (figures included) and read well on a code host.

Run through ``make notebooks`` (installs the ``notebooks`` extra: nbclient, nbformat,
ipykernel).  The test suite runs the same code cells itself and checks their numbers
(``tests/test_notebooks.py``); this script only refreshes what a reader sees.

The notebooks give their estimators a time limit no window reaches (``time_limit =
600``), so only the deterministic work limits bound a window and the outputs written here
are those of any machine, the test suite's included (its clock guard fails a notebook
whose window ran past its limit); only the measured seconds differ.
"""

from __future__ import annotations

import sys
from pathlib import Path

import nbformat
from nbclient import NotebookClient

HERE = Path(__file__).resolve().parent


def execute(path: Path, *, timeout: int = 1800) -> None:
    """Run ``path`` top to bottom in a fresh kernel and write it back with its outputs."""
    notebook = nbformat.read(path, as_version=4)
    NotebookClient(notebook, timeout=timeout, kernel_name="python3", resources={
        "metadata": {"path": str(path.parent)}
    }).execute()
    nbformat.write(notebook, path)


def main(argv: list[str]) -> int:
    paths = [Path(a) for a in argv] or sorted(HERE.glob("*.ipynb"))
    for path in paths:
        print(f"executing {path.name} ...", flush=True)
        execute(path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
