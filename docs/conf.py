"""Sphinx configuration of the mapassoc documentation (``make docs``).

Offline by design: no intersphinx, no notebook execution (the notebooks render with the
outputs stored in them), and every page that could drift from the code (the
configuration reference, the benchmarks) is generated at build time by
``_ext/mapassoc_docs.py``.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

from mapassoc.version import __version__  # noqa: E402

project = "mapassoc"
author = "the mapassoc developers"
copyright = "the mapassoc developers, BSD-3-Clause"  # noqa: A001
version = release = __version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_nb",
    "mapassoc_docs",
]

exclude_patterns = ["_build", "jupyter_execute", "**.ipynb_checkpoints", "benchmarks/*.py"]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}

autosummary_generate = True
autosummary_ignore_module_all = False
autodoc_default_options = {"members": True, "inherited-members": False}
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()
numpydoc_xref_param_type = False

myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3
nb_execution_mode = "off"
nb_merge_streams = True

html_theme = "pydata_sphinx_theme"
html_title = f"mapassoc {release}"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
html_static_path: list[str] = []

# The notebooks live in notebooks/ (their own home, run by `make notebooks`); the site
# renders copies with their stored outputs.
TUTORIALS = DOCS / "tutorials"
TUTORIALS.mkdir(exist_ok=True)
for notebook in sorted((DOCS.parent / "notebooks").glob("*.ipynb")):
    target = TUTORIALS / notebook.name
    if not target.exists() or target.read_bytes() != notebook.read_bytes():
        shutil.copyfile(notebook, target)
