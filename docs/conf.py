"""Sphinx configuration of mapassoc's documentation (``make docs``).

The build is offline and reads no notebook kernel: the notebooks are rendered with their
stored outputs (myst-nb, ``nb_execution_mode = "off"``). Two pages are generated before
the build from the code and from data, so they cannot drift: the configuration reference
from the settings records (:mod:`mapassoc.apps.config_reference`) and the benchmarks page
from the records under ``docs/benchmarks/`` (:mod:`mapassoc.apps.bench_page`).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from mapassoc.apps.bench_page import benchmark_page
from mapassoc.apps.config_reference import configuration_reference
from mapassoc.version import __version__

HERE = Path(__file__).resolve().parent

project = "mapassoc"
author = "the mapassoc developers"
copyright = "2026, the mapassoc developers"  # noqa: A001 (Sphinx's name)
version = release = __version__

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
]
source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "benchmarks/*.json", "**/.ipynb_checkpoints"]
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]
nb_execution_mode = "off"
autosummary_generate = True
autodoc_default_options = {"members": True, "inherited-members": False}
numpydoc_show_class_members = False
numpydoc_validation_checks: set[str] = set()
html_theme = "pydata_sphinx_theme"
html_static_path = ["_static"]
html_title = f"mapassoc {__version__}"


def _write_generated_pages() -> None:
    generated = HERE / "_generated"
    generated.mkdir(exist_ok=True)
    (generated / "configuration-reference.md").write_text(configuration_reference())
    records = [json.loads(p.read_text()) for p in sorted((HERE / "benchmarks").glob("*.json"))]
    (HERE / "benchmarks.md").write_text(benchmark_page(records))
    notebooks = HERE / "tutorials"
    notebooks.mkdir(exist_ok=True)
    for notebook in sorted((HERE.parent / "notebooks").glob("*.ipynb")):
        shutil.copyfile(notebook, notebooks / notebook.name)


_write_generated_pages()
