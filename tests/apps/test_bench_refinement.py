"""``mapassoc bench-refinement``: its rows, and MHT's options."""

from __future__ import annotations

import io

import pytest

from mapassoc.apps.bench_refinement import run_refinement_benchmark
from mapassoc.data.config import Config
from mapassoc.errors import InputError


def test_the_benchmark_rows_and_mhts_own_options(monkeypatch: pytest.MonkeyPatch) -> None:
    import mapassoc.trackers.registry as registry

    seen: list[object] = []
    real = registry.build_tracker

    def spy(name: str, *, config: Config, origins: object = None):  # type: ignore[no-untyped-def]
        seen.append(config.trackers.get(name))
        return real(name, config=config, origins=origins)  # type: ignore[arg-type]

    monkeypatch.setattr(registry, "build_tracker", spy)
    out = io.StringIO()
    rows = run_refinement_benchmark(
        families=["crossing"], seeds=1, scans=12, out=out, mht_options={"n_scan": 2}
    )
    assert [r.method for r in rows] == ["forward", "refined", "r>=0.5", "mht", "ss_gnn", "oracle"]
    by_method = {r.method: r for r in rows}
    # The refinement never lowers the recording's objective J.
    assert by_method["refined"].objective >= by_method["forward"].objective - 1e-9
    assert seen and all(options == {"n_scan": 2} for options in seen)
    assert "J(refined) >= J(forward) in every run: True" in out.getvalue()
    # Stone Soup's GNN is timed beside mapassoc's whole run (forward + refinement).
    gnn = by_method["ss_gnn"]
    assert gnn.seconds > 0 and gnn.tracks >= 1 and gnn.cutoff == 10.0
    whole = by_method["forward"].seconds + by_method["refined"].seconds
    assert f"whole run {whole:.1f} s (forward + refinement) vs Stone Soup GNN" in out.getvalue()


def test_a_bad_mht_option_stops_the_benchmark_before_it_runs() -> None:
    out = io.StringIO()
    with pytest.raises(InputError, match="unknown option 'nscan'"):
        run_refinement_benchmark(
            families=["crossing"], seeds=1, scans=12, out=out, mht_options={"nscan": 2}
        )
    assert "crossing " not in out.getvalue()  # no run line was printed


def test_the_cutoff_is_ten_position_noise_standard_deviations() -> None:
    from mapassoc.apps.bench import GOSPA_CUTOFF as BENCH_CUTOFF
    from mapassoc.apps.bench_refinement import GOSPA_CUTOFF
    from mapassoc.evaluation.scenarios import build_scenario, length_unit

    for cutoff in (GOSPA_CUTOFF, BENCH_CUTOFF):  # the same unit in both benchmarks
        assert cutoff * length_unit(build_scenario("crossing", 0).config) == 10.0
        assert cutoff * length_unit(build_scenario("aircraft", 0).config) == 500.0
        assert cutoff * length_unit(build_scenario("ships", 0).config) == 300.0
