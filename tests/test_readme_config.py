"""The configuration example that the configuration reference shows (docs/config-example.toml,
once the README's "Files" section) loads and lists every key: every field of every settings
record, in its table, with its default; and the reference generated beside it
(docs/_ext/mapassoc_docs.py) documents every field with its type, default, meaning and
check."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
import tomllib
import warnings
from pathlib import Path
from types import ModuleType

import pytest

from mapassoc.data.config import load_config
from mapassoc.data.settings import COMPONENTS, BirthModel, EstimatorSettings
from mapassoc.models.measurement import MEASUREMENT_REGISTRY
from mapassoc.models.motion import MOTION_REGISTRY

DOCS = Path(__file__).resolve().parent.parent / "docs"
EXAMPLE = DOCS / "config-example.toml"
DEFAULTS: dict[str, object] = {
    "birth": BirthModel(),
    **{f"estimator.{name}": getattr(EstimatorSettings(), name) for name in COMPONENTS},
}
"""Every settings record by its TOML table, with its defaults (the estimator's records
as ``EstimatorSettings()`` composes them)."""


def toml_block() -> str:
    return EXAMPLE.read_text(encoding="utf-8")


def generator() -> ModuleType:
    """docs/_ext/mapassoc_docs.py, the generator of the documentation's reference pages."""
    path = DOCS / "_ext" / "mapassoc_docs.py"
    spec = importlib.util.spec_from_file_location("mapassoc_docs", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_example_loads_without_warnings(tmp_path: Path) -> None:
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
    docs = generator()
    text = docs.configuration_reference()
    part = text.split(f"### `[{section}]`", 1)[1].split("\n### ", 1)[0]
    cls = type(DEFAULTS[section])
    described = docs.parameter_docs(cls)
    for field in dataclasses.fields(cls):
        row = re.search(rf"^\| `{field.name}` \|(.*)$", part, flags=re.MULTILINE)
        assert row, f"[{section}] {field.name} missing from the reference"
        kind, default, meaning, rule = [cell.strip() for cell in row.group(1).split(" | ")][:4]
        assert described.get(field.name, ("", ""))[1], f"{cls.__name__}.{field.name}: no meaning"
        assert kind == described[field.name][0], field.name
        value = getattr(DEFAULTS[section], field.name)
        stated = default.strip("`")
        if value is None:
            assert stated == "unset", field.name
        else:
            expected = list(value) if isinstance(value, tuple) else value
            assert tomllib.loads(f"v = {stated}")["v"] == expected, field.name
        assert meaning, field.name
        assert rule, field.name


def test_the_check_column_is_what_the_validation_says() -> None:
    from mapassoc.data.settings import RefinementSettings, WindowSettings

    docs = generator()
    rule = docs.check_rule(WindowSettings, "window_length")
    assert rule == "window_length must be an integer >= 1"
    assert "must be true or false" in docs.check_rule(RefinementSettings, "scan_windows")
    rule = docs.check_rule(RefinementSettings, "stride")
    assert rule == "stride (or None) must be an integer >= 1"


def test_a_field_added_to_a_record_appears_without_editing_a_page() -> None:
    from dataclasses import dataclass

    from mapassoc.errors import InputError

    @dataclass(frozen=True)
    class Extended:
        """A record with a new key (``[estimator.extended]``).

        Parameters
        ----------
        new_key : int
            A key no page names, >= 2.
        """

        new_key: int = 3

        def __post_init__(self) -> None:
            if not isinstance(self.new_key, int) or self.new_key < 2:
                raise InputError(f"new_key must be >= 2, got {self.new_key!r}", key="new_key")

    rows = generator().record_table("estimator.extended", Extended, Extended())
    assert "| `new_key` | int | `3` | A key no page names, >= 2. | new_key must be >= 2 |" in rows


def test_the_reference_lists_every_registered_model() -> None:
    text = generator().configuration_reference()
    for name in [*MOTION_REGISTRY, *MEASUREMENT_REGISTRY]:
        assert f"| `{name}` |" in text, name


def test_the_example_and_the_reference_name_every_imm_key() -> None:
    """``model = "imm"`` is read in mapassoc.data.config, not the registry: its keys and
    its nested tables are in the example's comments and in the reference's row."""
    from mapassoc.data.config import _IMM_KEYS, IMM

    block = toml_block()
    text = generator().configuration_reference()
    assert block.splitlines()[1].endswith(f"| {IMM}")  # the model line lists it
    assert block.count("# [[motion.models]]") == 2
    row = next(line for line in text.splitlines() if line.startswith(f"| `{IMM}` |"))
    for key in _IMM_KEYS[1:]:
        assert f"`{key}`" in row, key
        if key != "models":  # the nested tables, counted above
            assert re.search(rf"^# {key} = ", block, flags=re.MULTILINE), key
