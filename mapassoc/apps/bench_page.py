"""The documentation's benchmarks page, generated from what ``mapassoc bench --json`` writes.

Measurements are data: a benchmark record is the JSON of one ``mapassoc bench`` run
wrapped with where and how it was taken (:func:`benchmark_record`: date, version,
machine, command), kept under ``docs/benchmarks/``; the page is made from the records at
documentation build time (:func:`benchmark_page`), so no number on it is typed by hand
and each says when, on what and by which command it was measured.
"""

from __future__ import annotations

import datetime
import os
import platform
from collections.abc import Iterator, Mapping, Sequence
from typing import Any

from mapassoc.errors import InputError
from mapassoc.version import __version__

__all__ = ["benchmark_page", "benchmark_record"]

_COLUMNS = (
    ("family", "family", "{}"),
    ("k_prior", "prior on K", "{}"),
    ("seeds", "seeds", "{}"),
    ("targets", "targets", "{}"),
    ("gospa_ratio_mean", "GOSPA / oracle", "{:.3f}"),
    ("gospa_ratio_min", "min", "{:.3f}"),
    ("gospa_ratio_max", "max", "{:.3f}"),
    ("scans_per_second", "scans / s", "{:.1f}"),
    ("window_max_ms", "slowest window (ms)", "{:.0f}"),
    ("windows_over_limit", "windows over the limit", "{}"),
)


def benchmark_record(
    result: Mapping[str, Any], *, command: str, when: datetime.datetime | None = None
) -> dict[str, Any]:
    """``result`` (a ``mapassoc bench --json`` document) with where and how it was taken.

    Parameters
    ----------
    result : mapping
        The JSON document ``mapassoc bench --json`` wrote.
    command : str
        The command line that produced it.
    when : datetime, optional
        When it was measured (default: now, in UTC).
    """
    if not isinstance(result, Mapping) or "families" not in result:
        raise InputError(
            "result must be a mapassoc bench JSON document (a mapping with 'families'), "
            f"got {type(result).__name__}"
        )
    stamp = (when or datetime.datetime.now(datetime.UTC)).isoformat(timespec="seconds")
    machine = {
        "system": platform.system(),
        "machine": platform.machine(),
        "processor": platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "python": platform.python_version(),
    }
    return {"date": stamp, "version": __version__, "machine": machine,
            "command": command, "result": dict(result)}


def _cell(key: str, fmt: str, value: object) -> str:
    if value is None:
        return "–"
    if key == "seeds" and isinstance(value, list):
        return str(len(value))
    try:
        return fmt.format(value)
    except (TypeError, ValueError):
        return str(value)


def _table(families: Sequence[Mapping[str, Any]]) -> Iterator[str]:
    yield "| " + " | ".join(title for _, title, _ in _COLUMNS) + " |"
    yield "|" + " --- |" * len(_COLUMNS)
    for family in families:
        yield "| " + " | ".join(_cell(k, f, family.get(k)) for k, _, f in _COLUMNS) + " |"


def _record_section(record: Mapping[str, Any]) -> list[str]:
    machine = record["machine"]
    return [
        f"## {record['date']}: mapassoc {record['version']}",
        "",
        f"Command: `{record['command']}`; machine: {machine['system']} {machine['machine']}, "
        f"{machine['cores']} cores, Python {machine['python']}.",
        "",
        *_table(record["result"]["families"]),
        "",
    ]


def benchmark_page(records: Sequence[Mapping[str, Any]]) -> str:
    """The benchmarks page (Markdown) from benchmark records, newest first.

    Parameters
    ----------
    records : sequence of mapping
        Documents made by :func:`benchmark_record`.
    """
    lines = [
        "# Benchmarks",
        "",
        "Generated from the records under `docs/benchmarks/` (each the JSON of one "
        "`mapassoc bench --json` run, with its date, version, machine and command); "
        "GOSPA is divided by the oracle's (the true associations, smoothed) on the same "
        "recording. Seconds depend on the machine and its load; the ratios do not.",
        "",
    ]
    if not records:
        return "\n".join([*lines, "No benchmark has been recorded yet.", ""])
    for record in sorted(records, key=lambda r: str(r["date"]), reverse=True):
        lines += _record_section(record)
    return "\n".join(lines).rstrip() + "\n"
