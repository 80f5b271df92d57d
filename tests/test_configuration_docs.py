"""The configuration page's example (docs/configuration.md, "## Example") loads and lists
every key: every field of every settings record, in its table, with its default; and the
generated reference beside it documents every field."""

from __future__ import annotations

import dataclasses
import re
import tomllib
import warnings
from pathlib import Path

import pytest

from mapassoc.data.config import load_config
from mapassoc.data.settings import COMPONENTS, BirthModel, EstimatorSettings
from mapassoc.models.measurement import MEASUREMENT_REGISTRY
from mapassoc.models.motion import MOTION_REGISTRY

PAGE = Path(__file__).resolve().parent.parent / "docs" / "configuration.md"
DEFAULTS: dict[str, object] = {
    "birth": BirthModel(),
    **{f"estimator.{name}": getattr(EstimatorSettings(), name) for name in COMPONENTS},
}
"""Every settings record by its TOML table, with its defaults (the estimator's records
as ``EstimatorSettings()`` composes them)."""


def example_section() -> str:
    text = PAGE.read_text(encoding="utf-8")
    start = text.index("\n## Example\n")
    end = text.find("\n## ", start + 1)
    return text[start:] if end < 0 else text[start:end]


def toml_block() -> str:
    blocks = re.findall(r"```toml\n(.*?)```", example_section(), flags=re.DOTALL)
    assert len(blocks) == 1, f"expected one TOML block in the Example section, found {len(blocks)}"
    return blocks[0]


def test_the_readme_example_loads_without_warnings(tmp_path: Path) -> None:
    path = tmp_path / "config.toml"
    path.write_text(toml_block(), encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # both optional sections are present
        config = load_config(path)
    assert list(config.sensors) == ["radar", "esm"]


def _table(document: dict[str, object], section: str) -> dict[str, object]:
    table: object = document
    for part in section.split("."):
        assert isinstance(table, dict) and part in table, f"the example lacks [{section}]"
        table = table[part]
    assert isinstance(table, dict)
    return table


def test_the_example_has_a_table_per_record_and_nothing_else() -> None:
    document = tomllib.loads(toml_block())
    assert set(document["estimator"]) == set(COMPONENTS)  # no old flat key
    assert set(DEFAULTS) == {"birth", *(f"estimator.{name}" for name in COMPONENTS)}


@pytest.mark.parametrize("section", list(DEFAULTS))
def test_every_settings_field_is_a_key_of_the_example(section: str) -> None:
    table = _table(tomllib.loads(toml_block()), section)
    fields = [field.name for field in dataclasses.fields(DEFAULTS[section])]  # type: ignore[arg-type]
    missing = [name for name in fields if name not in table]
    assert not missing, f"the example's [{section}] lacks {missing}"
    assert list(table) == fields  # in the dataclass's order, nothing else


@pytest.mark.parametrize("section", list(DEFAULTS))
def test_the_defaults_the_example_states_are_the_defaults(section: str) -> None:
    defaults = DEFAULTS[section]
    lines = toml_block().split(f"[{section}]", 1)[1].split("\n[", 1)[0].splitlines()
    stated = {}
    for line in lines:
        found = re.match(r"(\w+) = .*\(default (.+)\)\s*$", line)
        if found and found.group(2).startswith("unset"):
            stated[found.group(1)] = None  # an optional key: unset by default
        elif found:
            stated[found.group(1)] = tomllib.loads(f"v = {found.group(2)}")["v"]
    assert set(stated) == {field.name for field in dataclasses.fields(defaults)}  # type: ignore[arg-type]
    for name, value in stated.items():
        expected = getattr(defaults, name)
        assert value == (list(expected) if isinstance(expected, tuple) else expected), name


def test_every_motion_and_sensor_key_is_in_the_example() -> None:
    block = toml_block()
    document = tomllib.loads(block)
    for spec in MOTION_REGISTRY.values():
        assert re.search(rf"\b{spec.name}\b", block), spec.name
        for key in spec.keys:  # the active model's keys as keys, the others in comments
            assert re.search(rf"^(# .*)?\b{key} = ", block, flags=re.MULTILINE), key
    sensor_keys = {key for table in document["sensors"] for key in table}
    for spec in MEASUREMENT_REGISTRY.values():
        assert spec.name in {table["measurement"] for table in document["sensors"]}, spec.name
        assert set(spec.keys) <= sensor_keys, spec.name


@pytest.mark.parametrize("section", list(DEFAULTS))
def test_the_generated_reference_documents_every_field(section: str) -> None:
    from mapassoc.apps.config_reference import configuration_reference, documented_parameters

    text = configuration_reference()
    part = text.split(f"### `[{section}]`", 1)[1].split("\n### ", 1)[0]
    cls = type(DEFAULTS[section])
    described = documented_parameters(cls)
    for field in dataclasses.fields(cls):
        row = re.search(rf"^\| `{field.name}` \|.*$", part, flags=re.MULTILINE)
        assert row, f"[{section}] {field.name} missing from the reference"
        assert described.get(field.name), f"{cls.__name__}.{field.name} has no description"
        meaning = re.sub(r":\w+:", "", described[field.name])  # markup aside
        assert re.sub(r"\W", "", meaning)[:30] in re.sub(r"\W", "", row.group(0)), field.name


def test_the_reference_lists_every_registered_model() -> None:
    from mapassoc.apps.config_reference import configuration_reference

    text = configuration_reference()
    for name in [*MOTION_REGISTRY, *MEASUREMENT_REGISTRY]:
        assert f"| `{name}` |" in text, name
