"""The documentation's generated parts: every public name has a docstring and a place in the
API reference, and the benchmarks page shows the recorded numbers with where they came from.

The generator (docs/_ext/mapassoc_docs.py) is imported as the Sphinx build imports it;
these tests need no build.
"""

from __future__ import annotations

import importlib.util
import inspect
import json
from pathlib import Path
from types import ModuleType

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
RECORDS = sorted((DOCS / "benchmarks").glob("*.json"))


def generator() -> ModuleType:
    """docs/_ext/mapassoc_docs.py, the generator of the documentation's reference pages."""
    path = DOCS / "_ext" / "mapassoc_docs.py"
    spec = importlib.util.spec_from_file_location("mapassoc_docs", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


DOCS_MODULE = generator()
MODULES = DOCS_MODULE.public_modules()
PUBLIC = [(module.__name__, name) for module in MODULES for name in module.__all__]


def test_the_public_modules_include_every_layer() -> None:
    names = {module.__name__ for module in MODULES}
    for package in ("mapassoc", "mapassoc.estimator.pipeline", "mapassoc.data.settings"):
        assert package in names
    assert len(PUBLIC) > 300  # the union of the __all__s, not a sample


@pytest.mark.parametrize(("module_name", "name"), PUBLIC)
def test_every_public_name_has_a_docstring(module_name: str, name: str) -> None:
    module = next(module for module in MODULES if module.__name__ == module_name)
    obj = getattr(module, name)
    if inspect.isclass(obj) or inspect.isfunction(obj) or inspect.ismodule(obj):
        assert inspect.getdoc(obj), f"{module_name}.{name} has no docstring"
    else:  # a variable: documented by the string after its assignment where it is defined
        home = DOCS_MODULE.home_module(module, name, MODULES)
        docs = DOCS_MODULE.attribute_docs(home)
        assert docs.get(name, "").strip(), f"{module_name}.{name}: no docstring in {home}"


def test_every_public_name_appears_in_the_api_reference() -> None:
    pages = DOCS_MODULE.api_pages()
    index = pages["api.rst"]
    missing = []
    for module in MODULES:
        assert f"   api/{module.__name__}\n" in index, module.__name__
        page = pages[f"api/{module.__name__}.rst"]
        for name in module.__all__:
            home = DOCS_MODULE.home_module(module, name, MODULES)
            if home == module.__name__:  # documented here in full
                found = f":: {module.__name__}.{name}\n" in page
            else:  # a link to where it is defined, which documents it in full
                found = f"<{home}.{name}>`" in page and f":: {home}.{name}\n" in pages.get(
                    f"api/{home}.rst", ""
                )
            if not found:
                missing.append(f"{module.__name__}.{name}")
    assert not missing, missing


def test_there_is_a_recorded_benchmark() -> None:
    assert RECORDS, "docs/benchmarks holds no mapassoc bench record"


@pytest.mark.parametrize("path", RECORDS, ids=[path.stem for path in RECORDS])
def test_the_benchmarks_page_shows_each_record(path: Path) -> None:
    record = json.loads(path.read_text(encoding="utf-8"))
    page = DOCS_MODULE.benchmarks_page([path])
    assert f"## {path.stem}" in page
    assert record["date"] in page and record["version"] in page
    assert f"`{record['command']}`" in page and record["command"].startswith("mapassoc bench")
    assert f"cores {record['machine']['cores']}" in page
    families = record["result"]["families"]
    runs = record["result"]["runs"]
    assert families and runs
    for row in families:  # each family and prior's mean GOSPA ratio, as recorded
        ratio = DOCS_MODULE._number(row["gospa_ratio_mean"])
        assert f"| {row['family']} | {row['k_prior']} | {len(row['seeds'])} |" in page
        assert f"| {ratio} |" in page
    table = page.split("| family | seed |", 1)[1]
    assert table.count("\n| ") == len(runs) + 1  # the separator, then one row per run


def test_a_record_without_provenance_says_so() -> None:
    page = DOCS_MODULE.benchmarks_page([])
    assert "# Benchmarks" in page
    section = "\n".join(DOCS_MODULE.benchmarks_section("bare", {"families": [], "runs": []}))
    assert section.count("not recorded") == 4
