"""The configuration reference, generated from the settings records and the model registries.

The documentation's configuration page includes what :func:`configuration_reference`
returns, so a field added to a settings record (or a model added to a registry) appears
in the reference without editing a page, and cannot drift from the code: every key's
type and default are read from the record's dataclass fields and its meaning from the
record's numpydoc ``Parameters`` section, where the checks a value must pass are stated
(the ``__post_init__`` of each record enforces them, naming the key).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterator
from typing import Any

from mapassoc.data.settings import COMPONENTS, BirthModel
from mapassoc.models.measurement import MEASUREMENT_REGISTRY
from mapassoc.models.motion import MOTION_REGISTRY

__all__ = ["configuration_reference", "documented_parameters", "settings_tables"]

_KINDS = {"ndim": "TOML integer 1, 2 or 3", "positive": "number > 0"}


def settings_tables() -> dict[str, type[Any]]:
    """Every settings record by the TOML table that holds it, in file order."""
    return {"birth": BirthModel, **{f"estimator.{name}": cls for name, cls in COMPONENTS.items()}}


def documented_parameters(cls: type[Any]) -> dict[str, str]:
    """``{name: description}`` from the numpydoc ``Parameters`` section of ``cls``.

    The description is the indented paragraph under ``name : type``, joined on one line.
    """
    doc = cls.__doc__ or ""
    match = re.search(r"\n\s*Parameters\n\s*-+\n(.*?)(\n\s*\n\s*[A-Z][a-z]+\n\s*-+\n|$)", doc, re.S)
    if match is None:
        return {}
    found: dict[str, list[str]] = {}
    current: list[str] | None = None
    for line in match.group(1).splitlines():
        entry = re.match(r"^\s{4}(\w+)\s*:", line)
        if entry:
            current = found.setdefault(entry.group(1), [])
        elif current is not None and line.strip():
            current.append(line.strip())
    return {name: " ".join(words) for name, words in found.items()}


def _default_text(field: dataclasses.Field[Any]) -> str:
    if field.default is not dataclasses.MISSING:
        value: object = field.default
    elif field.default_factory is not dataclasses.MISSING:
        value = field.default_factory()
    else:
        return "required"
    if value is None:
        return "unset"
    if isinstance(value, str):
        return f'`"{value}"`'
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    if isinstance(value, tuple):
        value = list(value)
    return f"`{value}`"


def _markdown(text: str) -> str:
    """reStructuredText's roles and double backticks as Markdown code."""
    text = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", text)
    return text.replace("``", "`")


def _cell(text: str) -> str:
    return _markdown(text).replace("|", "\\|").replace("\n", " ")


def _record_rows(cls: type[Any]) -> Iterator[str]:
    described = documented_parameters(cls)
    for field in dataclasses.fields(cls):
        meaning = described.get(field.name, "")
        type_name = field.type if isinstance(field.type, str) else field.type.__name__
        yield (
            f"| `{field.name}` | `{_cell(str(type_name))}` | {_default_text(field)} "
            f"| {_cell(meaning)} |"
        )


def _record_section(table: str, cls: type[Any]) -> list[str]:
    summary = _markdown(" ".join((cls.__doc__ or "").strip().split("\n\n")[0].split()))
    return [
        f"### `[{table}]`",
        "",
        f"{summary} Record: `{cls.__module__}.{cls.__qualname__}`.",
        "",
        "| key | type | default | meaning and rule |",
        "| --- | --- | --- | --- |",
        *_record_rows(cls),
        "",
    ]


def _motion_section() -> list[str]:
    lines = [
        "### `[motion]`",
        "",
        "`model` names a registered motion model; its other keys are:",
        "",
        "| model | keys | class |",
        "| --- | --- | --- |",
    ]
    for spec in MOTION_REGISTRY.values():
        keys = ", ".join(f"`{s.key}` ({_KINDS.get(s.kind, s.kind)})" for s in spec.settings)
        lines.append(f"| `{spec.name}` | {keys} | `{spec.cls.__module__}.{spec.cls.__name__}` |")
    return [*lines, ""]


def _sensor_section() -> list[str]:
    lines = [
        "### `[[sensors]]`",
        "",
        "One table per sensor. Every sensor has `name`, `measurement`, "
        "`detection_probability` (in (0, 1], or `\"auto\"`), `false_alarms_per_scan` "
        "(> 0, or `\"auto\"`) and `region`; `measurement` names a registered measurement "
        "model, which adds its own keys:",
        "",
        "| measurement | keys | class |",
        "| --- | --- | --- |",
    ]
    for spec in MEASUREMENT_REGISTRY.values():
        keys = ", ".join(f"`{key}`" for key in spec.keys)
        lines.append(f"| `{spec.name}` | {keys} | `{spec.cls.__module__}.{spec.cls.__name__}` |")
    return [*lines, ""]


def configuration_reference() -> str:
    """The reference of every configuration key, as Markdown (MyST) text.

    Returns
    -------
    str
        A section per table: ``[motion]`` and ``[[sensors]]`` from the model registries,
        then ``[birth]`` and each ``[estimator.*]`` record with every field's key, type,
        default and meaning.
    """
    lines = ["## Every key", "", *_motion_section(), *_sensor_section()]
    for table, cls in settings_tables().items():
        lines += _record_section(table, cls)
    return "\n".join(lines).rstrip() + "\n"
