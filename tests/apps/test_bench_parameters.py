"""bench-parameters on a tiny size: every row runs and the table says what it measured."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pytest

from mapassoc.apps.bench_parameters import run_parameter_benchmark
from mapassoc.errors import InputError


@pytest.mark.slow
def test_tiny_parameter_benchmark(tmp_path: Path) -> None:
    out = io.StringIO()
    rows = run_parameter_benchmark(
        families=["crossing"], seeds=1, scans=20, rate_factors=(0.5, 2.0), pd_offsets=(-0.15,),
        time_limit=600.0, json_path=tmp_path / "rows.json", out=out,
    )  # fmt: skip
    assert [r.label for r in rows] == ["true", "rate x0.5", "rate x2", "Pd -0.15", "auto"]
    true = rows[0]
    assert (true.rate, true.pd) == (true.true_rate, true.true_pd) == (10.0, 0.9)
    assert rows[1].rate == 5.0 and rows[2].rate == 20.0 and rows[3].pd == pytest.approx(0.75)
    assert all(r.gospa >= 0 and r.seconds > 0 for r in rows)
    text = out.getvalue()
    assert "crossing seed 0" in text and "rate x0.5" in text and "cost" in text
    assert len(json.loads((tmp_path / "rows.json").read_text())) == 5


def test_bad_families_are_refused() -> None:
    with pytest.raises(InputError, match="unknown families"):
        run_parameter_benchmark(families=["atlantis"], out=io.StringIO())
    with pytest.raises(InputError, match="2 sensors"):
        run_parameter_benchmark(families=["two_sensors"], seeds=1, scans=5, out=io.StringIO())
