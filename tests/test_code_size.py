"""Size limits of the package's code: no function over 80 code lines, no class over 500 lines.

A function's code lines are its non-blank lines that are not comments, its docstring left
out (so that documenting a function never pushes it over); a class is measured in all its
lines, from its ``class`` line to its last.  Long functions are split into named steps
instead (the aim is under about 60 code lines each).

``ALLOWED`` lists what is still over at the time of writing, as ``"path:qualname"`` with
the size it had then.  The list only shrinks: an entry that has grown past its size, is
back within the limit or no longer exists fails :func:`test_allow_list_only_shrinks`, so
that a split is followed by removing its entry.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE_FOLDERS = ("mapassoc", "formulations", "solvers")
FUNCTION_LIMIT = 80
CLASS_LIMIT = 500

# "path:qualname" -> size when listed (code lines of a function, lines of a class).
ALLOWED: dict[str, int] = {}

Node = ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef


def code_lines(lines: list[str], node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Non-blank, non-comment lines of ``node`` (``lines``: its file's lines), without
    its docstring."""
    skip: range = range(0)
    first = node.body[0]
    if (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
    ):
        skip = range(first.lineno, (first.end_lineno or first.lineno) + 1)
    end = node.end_lineno or node.lineno
    return sum(
        1
        for number in range(node.lineno, end + 1)
        if number not in skip
        and lines[number - 1].strip()
        and not lines[number - 1].strip().startswith("#")
    )


def sizes_in(source: str, path: str) -> dict[str, tuple[str, int]]:
    """Every function and class of ``source`` as ``"path:qualname"`` -> (kind, size):
    kind ``"function"`` with its code lines or ``"class"`` with its lines.  Qualnames
    join the enclosing classes and functions with dots (a repeated name, such as a
    property's getter and setter, keeps the larger size)."""
    lines = source.splitlines()
    found: dict[str, tuple[str, int]] = {}

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                qualname = f"{prefix}{child.name}"
                if isinstance(child, ast.ClassDef):
                    item = ("class", (child.end_lineno or child.lineno) - child.lineno + 1)
                else:
                    item = ("function", code_lines(lines, child))
                key = f"{path}:{qualname}"
                if key not in found or found[key][1] < item[1]:
                    found[key] = item
                visit(child, qualname + ".")
            else:
                visit(child, prefix)

    visit(ast.parse(source), "")
    return found


def package_sizes() -> dict[str, tuple[str, int]]:
    """:func:`sizes_in` over every module of the package folders."""
    found: dict[str, tuple[str, int]] = {}
    for folder in PACKAGE_FOLDERS:
        for file in sorted((ROOT / folder).rglob("*.py")):
            found.update(
                sizes_in(file.read_text(encoding="utf-8"), file.relative_to(ROOT).as_posix())
            )
    return found


def over_limit(kind: str, size: int) -> bool:
    return size > (FUNCTION_LIMIT if kind == "function" else CLASS_LIMIT)


SIZES = package_sizes()


def test_measure_counts_code_lines_and_class_lines() -> None:
    source = '''
class Outer:
    """A class
    docstring."""

    def method(self):
        """A docstring of
        three lines
        that does not count."""
        # a comment does not count

        x = 1
        return x

    @property
    def value(self):
        return 2

    @value.setter
    def value(self, v):
        a = v
        b = a
        return None


def free(a, b):
    def inner():
        return 1
    return inner() + a + b
'''
    sizes = sizes_in(source, "m.py")
    assert sizes == {
        "m.py:Outer": ("class", 22),
        "m.py:Outer.method": ("function", 3),
        "m.py:Outer.value": ("function", 4),
        "m.py:free": ("function", 4),
        "m.py:free.inner": ("function", 2),
    }


def test_the_package_is_measured() -> None:
    # The walk finds the modules of all three folders (an empty walk would pass the
    # limits trivially).
    folders = {key.split("/", 1)[0] for key in SIZES}
    assert folders == set(PACKAGE_FOLDERS)
    assert "formulations/frontier.py:frontier_search" in SIZES


@pytest.mark.parametrize("kind", ["function", "class"])
def test_no_item_over_its_limit(kind: str) -> None:
    over = {
        key: size
        for key, (k, size) in SIZES.items()
        if k == kind and over_limit(k, size) and key not in ALLOWED
    }
    limit = FUNCTION_LIMIT if kind == "function" else CLASS_LIMIT
    assert not over, (
        f"{kind}s over {limit} {'code lines' if kind == 'function' else 'lines'} "
        f"(split them into named steps): {over}"
    )


def test_allow_list_only_shrinks() -> None:
    problems = []
    for key, listed in sorted(ALLOWED.items()):
        if key not in SIZES:
            problems.append(f"{key} no longer exists: remove it from ALLOWED")
            continue
        kind, size = SIZES[key]
        if not over_limit(kind, size):
            problems.append(f"{key} is within the limit now ({size}): remove it from ALLOWED")
        elif size > listed:
            problems.append(f"{key} grew from {listed} to {size}: split it instead")
    assert not problems, "\n".join(problems)
