"""Record a benchmark for the documentation: run ``mapassoc bench --json`` and store its JSON
with the date, the package version, the machine and the command beside it.

    python docs/benchmarks/record_bench.py NAME -- --families crossing --seeds 1 --scans 20

writes ``docs/benchmarks/NAME.json``; the benchmarks page is generated from these files at
the next ``make docs``.  ``--from FILE`` wraps a JSON file that ``mapassoc bench --json``
already wrote (the command is then the one given after ``--``).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def machine() -> dict[str, object]:
    """What the numbers were measured on."""
    return {
        "system": platform.system(),
        "machine": platform.machine(),
        "processor": platform.processor() or platform.machine(),
        "cores": os.cpu_count(),
        "python": platform.python_version(),
    }


def record(
    result: dict[str, object], command: list[str], *, when: datetime.datetime
) -> dict[str, object]:
    """The stored record: provenance and the bench's own JSON under ``result``."""
    from mapassoc.version import __version__

    return {
        "date": when.isoformat(timespec="seconds"),
        "version": __version__,
        "machine": machine(),
        "command": " ".join(["mapassoc", "bench", *command]),
        "result": result,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("name", help="the record's name: docs/benchmarks/NAME.json")
    parser.add_argument("--from", dest="source", type=Path, help="an existing bench JSON file")
    argv = list(sys.argv[1:] if argv is None else argv)
    split = argv.index("--") if "--" in argv else len(argv)
    args = parser.parse_args(argv[:split])
    bench_args = argv[split + 1 :]
    if args.source is None:
        with tempfile.TemporaryDirectory() as folder:
            out = Path(folder) / "bench.json"
            script = Path(sys.executable).parent / "mapassoc"
            command = [str(script), "bench", *bench_args]
            subprocess.run([*command, "--json", str(out)], check=True)
            result = json.loads(out.read_text(encoding="utf-8"))
            when = datetime.datetime.fromtimestamp(out.stat().st_mtime, datetime.UTC)
    else:  # measured when the file was written
        result = json.loads(args.source.read_text(encoding="utf-8"))
        when = datetime.datetime.fromtimestamp(args.source.stat().st_mtime, datetime.UTC)
    target = HERE / f"{args.name}.json"
    text = json.dumps(record(result, bench_args, when=when), indent=1)
    target.write_text(text + "\n", encoding="utf-8")
    print(target)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
