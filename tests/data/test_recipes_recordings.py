"""The recipes of docs/recipes-recordings.md run as written, and give what they say."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

pytest.importorskip("pyproj")

RECIPES = Path(__file__).resolve().parents[2] / "docs" / "recipes-recordings.md"


def _blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", RECIPES.read_text(encoding="utf-8"), re.S)


def test_the_pandas_and_stone_soup_recipes_run(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("stonesoup")
    blocks = _blocks()
    assert len(blocks) == 2
    namespace: dict[str, object] = {}
    exec(compile(blocks[0], f"{RECIPES}:pandas", "exec"), namespace)
    scans, base = namespace["scans"], namespace["base"]
    # two scans of the log (12:00:00 with two reports, 12:00:10 with one), epoch 12:00:00
    assert [(scan.time, scan.size) for scan in scans] == [(0.0, 2), (10.0, 1)]  # type: ignore[attr-defined]
    assert base.time.epoch == "2024-05-01T12:00:00.000000Z"  # type: ignore[attr-defined]
    # the first report is 52.3010 N, 4.7102 E: west and south of the origin 52.31 N, 4.75 E
    x, y = scans[0].detections[0]  # type: ignore[index]
    assert -2800 < x < -2600 and -1100 < y < -900
    exec(compile(blocks[1], f"{RECIPES}:stonesoup", "exec"), namespace)
    stream_scans = namespace["scans"]
    assert [scan.time for scan in stream_scans] == [0.0, 10.0]  # type: ignore[attr-defined]
    assert abs(stream_scans[0].detections[0][0] - x) < 1e-6  # type: ignore[index]
    assert "[0.0, 10.0]" in capsys.readouterr().out

