"""The one-way import directions of the architecture.

* ``formulations/`` never imports a solver library or ``mapassoc.solvers``, nor domain code;
* ``solvers/`` never imports domain code (only ``mapassoc.formulations.program``);
* every layer may import ``mapassoc.array_types`` (type aliases) and
  ``mapassoc.accelerate`` (the switch of the optional compiled kernels), which import
  nothing of the package;
* domain modules never import formulations or solvers: only the pipeline (with its
  per-cluster strategy, ``cluster_solving``, its posterior marginals, ``marginals``, and
  the whole recording's refinement, ``refinement``), the trackers of ``mapassoc/trackers/`` that
  solve programs (MHT, network flow, LP relaxation) and the applications of
  ``mapassoc/apps/`` (command line, benchmark, demo) wire the three together.
"""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parent.parent
SOLVER_LIBRARIES = ("cvxpy", "clarabel", "highspy", "networkx", "scipy.optimize", "pyomo", "pulp")
WIRING_MODULES = {
    "estimator/pipeline.py",
    "estimator/cluster_solving.py",
    "estimator/refinement.py",
    "estimator/window_program.py",
    "estimator/bounded_tables.py",
    "estimator/boundaries.py",
    "estimator/confidence.py",
}
WIRING_FOLDERS = ("trackers", "apps")
PACKAGE_FOLDERS = ("mapassoc", "formulations", "solvers")
# Type aliases, and the switch of the compiled kernels: each imports nothing of the package.
SHARED_LEAVES = ("mapassoc.array_types", "mapassoc.accelerate", "mapassoc.log_space")


def shared(name: str) -> bool:
    return any(starts(name, leaf) for leaf in SHARED_LEAVES)


def is_wiring(path: Path) -> bool:
    where = path.relative_to(ROOT / "mapassoc").as_posix()
    return where in WIRING_MODULES or where.split("/")[0] in WIRING_FOLDERS


def imported_modules(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
            names.extend(f"{node.module}.{alias.name}" for alias in node.names)
    return names


def files(folder: str) -> list[Path]:
    found = sorted((ROOT / folder).rglob("*.py"))
    assert found, f"no Python files under {folder}/"
    return found


def starts(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


@pytest.mark.parametrize("path", files("formulations"), ids=lambda p: p.name)
def test_formulations_import_no_solver_and_no_domain(path: Path) -> None:
    for name in imported_modules(path):
        assert not any(starts(name, lib) for lib in SOLVER_LIBRARIES), f"{path.name}: {name}"
        if starts(name, "mapassoc") and not shared(name):
            assert starts(name, "mapassoc.formulations"), f"{path.name} imports {name}"


@pytest.mark.parametrize("path", files("solvers"), ids=lambda p: p.name)
def test_solvers_import_no_domain(path: Path) -> None:
    for name in imported_modules(path):
        if starts(name, "mapassoc") and not shared(name):
            assert starts(name, "mapassoc.solvers") or starts(
                name, "mapassoc.formulations.program"
            ), f"{path.name} imports {name}"


@pytest.mark.parametrize("leaf", SHARED_LEAVES)
def test_the_shared_leaves_import_nothing_of_the_package(leaf: str) -> None:
    names = imported_modules(ROOT / "mapassoc" / f"{leaf.split('.')[-1]}.py")
    assert names and not any(starts(name, "mapassoc") for name in names)


@pytest.mark.parametrize(
    "path",
    [p for p in files("mapassoc") if not is_wiring(p)],
    ids=lambda p: p.name,
)
def test_domain_imports_neither_formulations_nor_solvers(path: Path) -> None:
    for name in imported_modules(path):
        assert not starts(name, "mapassoc.formulations"), f"{path.name} imports {name}"
        assert not starts(name, "mapassoc.solvers"), f"{path.name} imports {name}"
        # scipy.optimize stays allowed here: GOSPA uses linear_sum_assignment.
        optimisers = [lib for lib in SOLVER_LIBRARIES if lib != "scipy.optimize"]
        assert not any(starts(name, lib) for lib in optimisers), f"{path.name} imports {name}"


def test_no_generic_top_level_packages_are_shipped() -> None:
    import tomllib

    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    packages = data["tool"]["setuptools"]["packages"]
    assert all(p == "mapassoc" or p.startswith("mapassoc.") for p in packages)
    mapping = data["tool"]["setuptools"]["package-dir"]
    assert mapping["mapassoc.formulations"] == "formulations"
    assert mapping["mapassoc.solvers"] == "solvers"


def test_the_installed_package_exposes_no_generic_top_level_name() -> None:
    """In the installed environment (the editable install of ``make setup``), the
    folders are importable only under ``mapassoc``: ``import formulations`` and
    ``import solvers`` fail from a directory outside the checkout."""
    import subprocess
    import sys

    code = (
        "import importlib.util as u; "
        "assert u.find_spec('mapassoc.formulations') and u.find_spec('mapassoc.solvers'); "
        "assert u.find_spec('formulations') is None, 'formulations'; "
        "assert u.find_spec('solvers') is None, 'solvers'"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd="/")


def _conftest_shared_names(conftest: Path) -> set[str]:
    """The classes, type aliases and ``@pytest.fixture`` functions that conftest defines."""
    names: set[str] = set()
    for node in ast.parse(conftest.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.FunctionDef) and any(
            "fixture" in ast.unparse(d) for d in node.decorator_list
        ):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            if "TypeAlias" in ast.unparse(node.annotation):
                names.add(node.target.id)
        elif isinstance(node, getattr(ast, "TypeAlias", ())):
            names.add(node.name.id)
    return names


def test_test_modules_import_no_other_test_module() -> None:
    """Shared builders live in ``tests/support.py``: no file under ``tests/`` imports a
    ``test_*`` module, and ``conftest`` is imported only for its fixtures and types."""
    tests = ROOT / "tests"
    allowed = _conftest_shared_names(tests / "conftest.py")
    bad: list[str] = []
    for path in sorted(tests.rglob("*.py")):
        where = path.relative_to(tests).as_posix()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    top = alias.name.split(".")[0]
                    if top.startswith("test_") or top == "conftest":
                        bad.append(f"{where}: import {alias.name}")
            elif isinstance(node, ast.ImportFrom):
                top = (node.module or "").split(".")[0]
                if node.level or top.startswith("test_"):
                    bad.append(f"{where}: from {'.' * node.level}{node.module or ''} import ...")
                elif top == "conftest":
                    names = [a.name for a in node.names if a.name not in allowed]
                    if names:
                        bad.append(f"{where}: from conftest import {', '.join(names)}")
    assert not bad, "test modules must import shared code from support:\n" + "\n".join(bad)


def _module_name(path: Path) -> str:
    """The installed name of a source file (``formulations/x.py`` is
    ``mapassoc.formulations.x``; a package's ``__init__`` is the package)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[0] in ("formulations", "solvers"):
        parts.insert(0, "mapassoc")
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def import_graph() -> nx.DiGraph:
    """Module -> module it imports, over every import of the package: module level,
    deferred into a function, and under ``TYPE_CHECKING`` alike."""
    modules = {
        _module_name(path): path for folder in PACKAGE_FOLDERS for path in files(folder)
    }
    graph = nx.DiGraph()
    graph.add_nodes_from(modules)
    for name, path in modules.items():
        for imported in imported_modules(path):
            if imported in modules and imported != name:
                graph.add_edge(name, imported)
    return graph


def test_no_import_cycles() -> None:
    """No module imports itself back through others, type-only imports included: each
    module can be read, and changed, knowing only what it imports."""
    graph = import_graph()
    assert graph.number_of_edges() > 100  # the walk found the package's imports
    cycles = sorted(" -> ".join([*c, c[0]]) for c in nx.simple_cycles(graph))
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_the_cycle_check_sees_a_deferred_type_only_cycle(tmp_path: Path) -> None:
    """The walk counts an import inside a function under ``TYPE_CHECKING``."""
    source = tmp_path / "one.py"
    source.write_text(
        "def f():\n    if TYPE_CHECKING:\n        from mapassoc.models.motion import X\n",
        encoding="utf-8",
    )
    assert "mapassoc.models.motion" in imported_modules(source)


LAYERS = (
    (
        "base",
        (
            "mapassoc.errors",
            "mapassoc.validation",
            "mapassoc.array_types",
            "mapassoc.log_space",
            "mapassoc.accelerate",
            "mapassoc.version",
        ),
    ),
    ("models", ("mapassoc.models",)),
    ("data", ("mapassoc.data",)),
    ("filtering", ("mapassoc.filtering",)),
    ("formulations", ("mapassoc.formulations",)),
    ("solvers", ("mapassoc.solvers",)),
    ("estimator", ("mapassoc.estimator",)),
    ("reference", ("mapassoc.reference",)),
    ("evaluation", ("mapassoc.evaluation",)),
    ("trackers", ("mapassoc.trackers",)),
    ("interop", ("mapassoc.interop",)),
    ("apps", ("mapassoc.apps", "mapassoc.__main__")),  # python -m mapassoc: the command
    ("public API", ("mapassoc",)),
)
"""The package's layers from the bottom up: a module imports only its own layer and the
ones below (the public API, ``mapassoc/__init__``, sits on top: it re-exports everything,
lazily)."""


def layer_of(module: str) -> int:
    """Index in :data:`LAYERS` of a module (the layer of its longest matching prefix)."""
    best, best_length = -1, -1
    for index, (_, prefixes) in enumerate(LAYERS):
        for prefix in prefixes:
            if starts(module, prefix) and len(prefix) > best_length:
                best, best_length = index, len(prefix)
    return best


def layer_violations(edges: list[tuple[str, str]]) -> list[str]:
    """The imports of ``edges`` (importer, imported) that go up a layer."""
    return sorted(
        f"{a} ({LAYERS[layer_of(a)][0]}) imports {b} ({LAYERS[layer_of(b)][0]})"
        for a, b in edges
        if layer_of(b) > layer_of(a)
    )


def test_every_module_has_a_layer() -> None:
    top = len(LAYERS) - 1
    unplaced = [m for m in import_graph() if layer_of(m) in (-1, top) and m != "mapassoc"]
    assert not unplaced, f"modules outside every layer of LAYERS: {unplaced}"


def test_no_layer_imports_one_above_it() -> None:
    """Models know nothing of data files, data nothing of the estimator, evaluation
    nothing of the trackers it scores, and so on up (type-only imports included)."""
    graph = import_graph()
    violations = layer_violations(list(graph.edges))
    assert not violations, "imports that go up a layer:\n" + "\n".join(violations)


def test_the_layer_check_catches_an_upward_import() -> None:
    assert layer_violations([("mapassoc.models.motion", "mapassoc.data.scans")]) == [
        "mapassoc.models.motion (models) imports mapassoc.data.scans (data)"
    ]
    assert layer_violations([("mapassoc.apps.cli", "mapassoc")])  # the public API is on top
    assert not layer_violations([("mapassoc", "mapassoc.apps.cli")])
    assert not layer_violations([("mapassoc.solvers.highs", "mapassoc.formulations.program")])
