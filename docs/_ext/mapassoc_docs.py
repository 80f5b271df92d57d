"""Pages of the documentation generated from the code and from data, so they cannot drift.

* :func:`configuration_reference`: every key of every settings record (its TOML table,
  type, default, meaning and the rule it is checked against), read from the records
  themselves: the dataclass fields of :class:`mapassoc.models.population.BirthModel` and
  of :data:`mapassoc.data.settings.COMPONENTS`, the meaning from each record's numpydoc
  ``Parameters`` section, the rule from the :class:`mapassoc.errors.InputError` that the
  record's own validation raises for values that break it.  A field added to a record
  appears on the page at the next build, with no page edited.
* :func:`benchmarks_page`: the tables of a ``mapassoc bench --json`` file, with the date,
  version, machine and command that :mod:`record_bench` stored beside it.

As a Sphinx extension (``setup``) it writes both pages into the source folder when the
build starts; ``tests/test_docs.py`` tests the generators without building.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import typing
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

DOCS = Path(__file__).resolve().parent.parent
GENERATED = ("configuration.md", "benchmarks.md", "api.rst", "api/")
PACKAGES = ("mapassoc",)
_PROBES: tuple[object, ...] = (-1, 0, -0.5, 1.5, math.nan, "?", None, True, [])
"""Values tried on each field to provoke its check; each refusal's message is the rule."""


def records() -> dict[str, tuple[type, object]]:
    """Every settings record by its TOML table: ``{table: (class, defaults)}``, the
    estimator's records with the defaults ``EstimatorSettings()`` composes."""
    from mapassoc.data.settings import COMPONENTS, EstimatorSettings
    from mapassoc.models.population import BirthModel

    estimator = EstimatorSettings()
    found: dict[str, tuple[type, object]] = {"birth": (BirthModel, BirthModel())}
    for name, cls in COMPONENTS.items():
        found[f"estimator.{name}"] = (cls, getattr(estimator, name))
    return found


def parameter_docs(cls: type) -> dict[str, tuple[str, str]]:
    """``{name: (type text, description)}`` from the numpydoc ``Parameters`` section of
    ``cls``'s docstring (descriptions joined into one line)."""
    doc = typing.cast(str, cls.__doc__ or "")
    lines = [line.rstrip() for line in dedent_doc(doc).splitlines()]
    try:
        start = next(i for i, line in enumerate(lines) if line.strip() == "Parameters") + 2
    except StopIteration:
        return {}
    found: dict[str, tuple[str, str]] = {}
    name = ""
    for line in lines[start:]:
        if line and not line.startswith(" "):
            if set(line.strip()) == {"-"} or not re.match(r"^\w+\s*:", line):
                break  # the next section
            name, _, kind = line.partition(":")
            name = name.strip()
            found[name] = (kind.strip(), "")
        elif name and line.strip():
            kind, text = found[name]
            found[name] = (kind, f"{text} {line.strip()}".strip())
    return found


def dedent_doc(doc: str) -> str:
    """A docstring without its indentation (the first line kept as it is)."""
    import inspect

    return inspect.cleandoc(doc)


def check_rule(cls: type, name: str) -> str:
    """What ``cls``'s validation says of field ``name`` when probed with values that break
    common rules (its messages without their ``got ...`` part), or "any value"."""
    from mapassoc.errors import InputError

    rules: list[str] = []
    for probe in _PROBES:
        try:
            cls(**{name: probe})
        except InputError as exc:
            if getattr(exc, "key", name) not in (name, None):
                continue
            rule = re.sub(r",? *(got|not) .*$", "", str(exc), flags=re.DOTALL).strip()
            if rule and rule not in rules:
                rules.append(rule)
        except (TypeError, ValueError):
            continue
    return "; ".join(rules) if rules else "not checked"


def toml_value(value: object) -> str:
    """``value`` as it is written in a TOML file (``unset`` for None)."""
    if value is None:
        return "unset"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(toml_value(item) for item in value) + "]"
    return repr(value)


def _cell(text: str) -> str:
    """One table cell: reST roles as MyST roles, no pipes or line breaks."""
    text = re.sub(r":(\w+):`([^`]+)`", r"{\1}`\2`", text)
    return text.replace("|", "\\|").replace("\n", " ")


def record_table(table: str, cls: type, defaults: object) -> list[str]:
    """The Markdown section of one record: its summary line and one row per field."""
    summary = dedent_doc(cls.__doc__ or "").split("\n\n", 1)[0].replace("\n", " ")
    docs = parameter_docs(cls)
    lines = [
        f"### `[{table}]`",
        "",
        f"{summary} Record: {{class}}`~{cls.__module__}.{cls.__qualname__}`.",
        "",
        "| key | type | default | meaning | checked |",
        "| --- | --- | --- | --- | --- |",
    ]
    for field in dataclasses.fields(typing.cast(Any, cls)):
        kind, meaning = docs.get(field.name, ("", ""))
        default = toml_value(getattr(defaults, field.name))
        rule = check_rule(cls, field.name)
        lines.append(
            f"| `{field.name}` | {_cell(kind)} | `{default}` | {_cell(meaning)} | {_cell(rule)} |"
        )
    return [*lines, ""]


def model_tables() -> list[str]:
    """The motion and measurement models a configuration names, with their keys."""
    from mapassoc.data.config import IMM
    from mapassoc.models.measurement import MEASUREMENT_REGISTRY
    from mapassoc.models.motion import MOTION_REGISTRY

    lines = ["### `[motion]`", "", "| `model` | its keys |", "| --- | --- |"]
    for spec in MOTION_REGISTRY.values():
        keys = ", ".join(f"`{setting.key}` ({setting.kind})" for setting in spec.settings)
        lines.append(f"| `{spec.name}` | {keys or 'none'} |")
    lines.append(
        f"| `{IMM}` | `switch_probability` (probability of leaving the current model within "
        "one unit of time) or `matrix` (M x M switching matrix per unit of time, an array of "
        "arrays); `initial_probabilities` (optional, M numbers summing to 1, default "
        "uniform); `models` (M >= 1 `[[motion.models]]` tables, each one of the models above "
        "with its keys, all in one state space; the first starts every track) |"
    )
    lines += ["", "### `[[sensors]]`", "", "| `measurement` | its keys |", "| --- | --- |"]
    for mspec in MEASUREMENT_REGISTRY.values():
        lines.append(f"| `{mspec.name}` | {', '.join(f'`{k}`' for k in mspec.keys) or 'none'} |")
    return [*lines, ""]


def configuration_reference() -> str:
    """The configuration reference page (Markdown), generated from the settings records."""
    lines = [
        "<!-- Generated at build time by docs/_ext/mapassoc_docs.py from the settings",
        "records; do not edit. -->",
        "",
        "# Configuration reference",
        "",
    ]
    lines += [
        "A configuration is one TOML file. {doc}`formats` gives the rules of the file (unknown",
        "keys are errors, integers must be TOML integers, missing `[birth]` and `[estimator]`",
        "tables take the defaults below with a warning, old flat `[estimator]` keys load with a",
        "deprecation warning and `mapassoc migrate-config` rewrites them). A complete example,",
        "every key with its default or a typical value, is loaded by the tests as written:",
        "",
        "```{literalinclude} config-example.toml",
        ":language: toml",
        "```",
        "",
        "## Models",
        "",
        *model_tables(),
        "## Settings records",
        "",
        "Each table below is read from its record: the type and meaning from the record's",
        "docstring, the default from the record (the estimator's as `EstimatorSettings()`",
        "composes them), and the rule from the message the record's validation gives a",
        "value that breaks it.",
        "",
    ]
    for table, (cls, defaults) in records().items():
        lines += record_table(table, cls, defaults)
    return "\n".join(lines)


def _number(value: object, digits: int = 3) -> str:
    if value is None:
        return "–"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def benchmarks_section(title: str, record: Mapping[str, Any]) -> list[str]:
    """The Markdown of one recorded benchmark: where it came from, then its tables."""
    bench = record.get("result", record)
    lines = [f"## {title}", ""]
    for key in ("date", "version", "machine", "command"):
        value = record.get(key, "not recorded")
        if isinstance(value, Mapping):
            value = ", ".join(f"{name} {item}" for name, item in value.items())
        lines.append(f"- **{key}**: `{value}`" if key == "command" else f"- **{key}**: {value}")
    lines += [
        "",
        "| family | prior on K | seeds | scans/s | GOSPA / oracle | Brier of p(K\\|Z) "
        "| windows over limit | statuses |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in bench.get("families", []):
        statuses = ", ".join(f"{k} {v}" for k, v in sorted(row.get("status_counts", {}).items()))
        lines.append(
            f"| {row.get('family')} | {row.get('k_prior')} | {len(row.get('seeds', []))} "
            f"| {_number(row.get('scans_per_second'))} | {_number(row.get('gospa_ratio_mean'))} "
            f"| {_number(row.get('brier_mean'))} | {row.get('windows_over_limit', '–')} "
            f"| {statuses} |"
        )
    lines += [
        "",
        "| family | seed | prior on K | targets | scans | detections/scan | window p50 ms "
        "| window p95 ms | GOSPA | oracle GOSPA |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for run in bench.get("runs", []):
        lines.append(
            f"| {run.get('family')} | {run.get('seed')} | {run.get('k_prior')} "
            f"| {run.get('targets')} | {run.get('scans')} "
            f"| {_number(run.get('detections_per_scan'))} | {_number(run.get('window_p50_ms'))} "
            f"| {_number(run.get('window_p95_ms'))} | {_number(run.get('gospa'))} "
            f"| {_number(run.get('oracle_gospa'))} |"
        )
    return [*lines, ""]


def benchmarks_page(files: Iterable[Path]) -> str:
    """The benchmarks page (Markdown) from recorded ``mapassoc bench --json`` files."""
    lines = [
        "<!-- Generated at build time by docs/_ext/mapassoc_docs.py from docs/benchmarks/*.json;",
        "do not edit. -->",
        "",
        "# Benchmarks",
        "",
        "Measurements are data: each section below is generated from a JSON file that",
        "`mapassoc bench --json` wrote, recorded with `python docs/benchmarks/record_bench.py`",
        "(which stores the date, the package version, the machine and the command beside the",
        "numbers). Numbers depend on the machine; rerun the command to compare on yours.",
        "Columns: scans per second of the whole run; GOSPA (cut-off 10, α = 2) over the",
        "oracle's (a Kalman smoother given the true associations), 1 is the oracle; the Brier",
        "score of p(K | Z) against the true number of targets per window; windows that ran",
        "past their time limit; the windows' statuses ({doc}`model`).",
        "",
    ]
    for path in sorted(files):
        record = json.loads(Path(path).read_text(encoding="utf-8"))
        lines += benchmarks_section(Path(path).stem, record)
    return "\n".join(lines)


def public_modules() -> list[Any]:
    """Every module of the package that declares ``__all__``, by name (the package's
    public names are the union of their ``__all__``)."""
    import importlib
    import pkgutil

    import mapassoc

    modules = [mapassoc]
    for info in pkgutil.walk_packages(mapassoc.__path__, "mapassoc."):
        if any(part.startswith("_") for part in info.name.split(".")):
            continue
        module = importlib.import_module(info.name)
        if hasattr(module, "__all__"):
            modules.append(module)
    return sorted(modules, key=lambda module: module.__name__)


def attribute_docs(module_name: str) -> dict[str, str]:
    """The docstrings of ``module_name``'s module-level variables (``NAME = ...`` followed
    by a string), as autodoc reads them."""
    from sphinx.pycode import ModuleAnalyzer

    try:
        found = ModuleAnalyzer.for_module(module_name).find_attr_docs()
    except Exception:  # a module without source: no attribute docs
        return {}
    return {name: "\n".join(lines) for (scope, name), lines in found.items() if not scope}


def home_module(module: Any, name: str, modules: list[Any]) -> str:
    """The module that defines public name ``name`` of ``module``: a class's or function's
    ``__module__`` (an alias's own module), a variable's documenting module (the first
    that holds a docstring for the same object), else ``module`` itself."""
    import inspect

    obj = getattr(module, name)
    if inspect.isclass(obj) or inspect.isfunction(obj):
        # an alias under another name (``BatchOptions = RunOptions``) is documented here
        return str(obj.__module__) if obj.__name__ == name else str(module.__name__)
    if name in attribute_docs(module.__name__):
        return str(module.__name__)
    for other in modules:
        if name in getattr(other, "__all__", ()) and getattr(other, name, None) is obj:
            if name in attribute_docs(other.__name__):
                return str(other.__name__)
    return str(module.__name__)


def _is_alias(obj: Any) -> bool:
    """A type alias such as ``tuple[int, ...]`` or ``numpy.typing.NDArray[...]``."""
    import types

    return isinstance(obj, types.GenericAlias) or type(obj).__module__ == "typing"


def _directive(obj: Any) -> str:
    import inspect

    if _is_alias(obj):
        return "autodata"
    if inspect.isclass(obj):
        return "autoclass"
    if inspect.isfunction(obj) or inspect.isbuiltin(obj):
        return "autofunction"
    return "autodata"


def module_page(module: Any, modules: list[Any]) -> str:
    """The reST API page of one module: its docstring, a summary table of its ``__all__``
    and the full documentation of each name it defines (names defined elsewhere link to
    their home)."""
    name = module.__name__
    own: list[str] = []
    elsewhere: list[tuple[str, str]] = []
    for public in sorted(module.__all__):
        home = home_module(module, public, modules)
        (own.append(public) if home == name else elsewhere.append((public, home)))
    title = f"``{name}``"
    lines = [title, "=" * len(title), "", f".. automodule:: {name}", "   :no-members:", ""]
    listed = [public for public in own if not _is_alias(getattr(module, public))]
    if listed:
        lines += [".. autosummary::", "", *(f"   {public}" for public in listed), ""]
    if elsewhere:
        lines += ["Also exported here, documented where they are defined:", ""]
        lines += [f"- :py:obj:`{public} <{home}.{public}>`" for public, home in elsewhere]
        lines.append("")
    docs = attribute_docs(name)
    for public in own:
        obj = getattr(module, public)
        if _is_alias(obj):  # autodoc cannot format an alias's signature: its text as written
            text = docs.get(public, "").splitlines()
            lines += [f".. py:data:: {name}.{public}", "", *(f"   {t}" for t in text), ""]
        else:
            lines += [f".. {_directive(obj)}:: {name}.{public}", ""]
    return "\n".join(lines)


def api_pages() -> dict[str, str]:
    """``{relative path: reST}`` of the API reference: an index and a page per module."""
    modules = public_modules()
    pages = {f"api/{module.__name__}.rst": module_page(module, modules) for module in modules}
    index = [
        "API reference",
        "=============",
        "",
        "Every module that declares public names (its ``__all__``), generated from the",
        "docstrings. ``import mapassoc as ma`` gives the most used of them directly.",
        "",
        ".. toctree::",
        "   :maxdepth: 1",
        "",
        *(f"   api/{module.__name__}" for module in modules),
        "",
    ]
    pages["api.rst"] = "\n".join(index)
    return pages


def write_pages(source: Path = DOCS) -> None:
    """Write the generated pages into ``source`` (only where their text changed)."""
    (source / "api").mkdir(exist_ok=True)
    pages = {
        **api_pages(),
        "configuration.md": configuration_reference(),
        "benchmarks.md": benchmarks_page((source / "benchmarks").glob("*.json")),
    }
    for name, text in pages.items():
        path = source / name
        if not path.exists() or path.read_text(encoding="utf-8") != text:
            path.write_text(text, encoding="utf-8")


def _on_builder_inited(app: Any) -> None:
    write_pages(Path(app.srcdir))


def setup(app: Any) -> dict[str, object]:
    """Sphinx entry point: generate the pages when the build starts."""
    app.connect("builder-inited", _on_builder_inited)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
