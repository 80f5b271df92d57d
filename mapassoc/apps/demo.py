"""``mapassoc demo``: a built-in scenario end to end, next to the oracle.

Simulates the scenario into ``OUT/scenario/``, runs the estimator on those files
exactly as ``mapassoc run`` would (the run folder ``OUT/run/``), smooths the true
associations (the oracle, ``OUT/oracle_tracks.csv``), prints GOSPA of both and
plots detections, truth and tracks (``OUT/tracks.png``).
"""

from __future__ import annotations

from pathlib import Path

from mapassoc.apps.runs import run_files
from mapassoc.data.io import read_tracks, write_tracks
from mapassoc.evaluation.metrics import RunEvaluation
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import build_scenario, describe_scenario
from mapassoc.evaluation.simulate import write_scenario
from mapassoc.evaluation.tables import evaluate_tables

__all__ = ["run_demo", "comparison_table"]

GOSPA_CUTOFF = 10.0


def comparison_table(rows: dict[str, RunEvaluation]) -> str:
    """Aligned text table of GOSPA parts, RMSE and cardinality error per method."""
    header = (
        f"{'method':10s} {'GOSPA':>8s} {'local.':>8s} {'missed':>8s} {'false':>8s} "
        f"{'RMSE':>8s} {'|dK|':>6s}"
    )
    lines = [header, "-" * len(header)]
    for name, ev in rows.items():
        g = ev.gospa
        rmse = ev.position_rmse
        lines.append(
            f"{name:10s} {g.mean_total:8.3f} {g.mean_localisation:8.3f} "
            f"{g.mean_missed:8.3f} {g.mean_false:8.3f} "
            f"{(rmse if rmse is not None else float('nan')):8.3f} "
            f"{ev.mean_abs_cardinality_error:6.3f}"
        )
    return "\n".join(lines)


def run_demo(
    *,
    scenario: str = "crossing",
    seed: int = 0,
    out_dir: Path = Path("demo-out"),
    plot: bool = True,
) -> dict[str, RunEvaluation]:
    """Run the demo; returns the metrics of the estimator and of the oracle."""
    built = build_scenario(scenario, seed)
    print(f"scenario {scenario!r} (seed {seed}): {describe_scenario(scenario)}")
    paths = write_scenario(built, out_dir / "scenario")
    run_dir = out_dir / "run"
    summary = run_files(
        paths["config"], paths["detections"], run_dir, progress=True, overwrite=True
    ).summary
    tracks = read_tracks(run_dir / "tracks.csv")
    oracle = oracle_tracks(built.scans, built.origins, built.config)
    write_tracks(out_dir / "oracle_tracks.csv", oracle)
    rows = {
        "mapassoc": evaluate_tables(built.truth, tracks, c=GOSPA_CUTOFF),
        "oracle": evaluate_tables(built.truth, oracle, c=GOSPA_CUTOFF),
    }
    print(
        f"{summary['scans']} scans, {summary['windows']} windows, {summary['tracks']} tracks, "
        f"{summary.get('scans_per_second', 0):.1f} scans/s"
    )
    print(f"GOSPA (c = {GOSPA_CUTOFF}, p = 2, alpha = 2), mean over scans:")
    print(comparison_table(rows))
    ratio = rows["mapassoc"].gospa.mean_total / rows["oracle"].gospa.mean_total
    print(f"mapassoc / oracle GOSPA: {ratio:.3f}")
    if plot:
        from mapassoc.apps.plotting import plot_tracks

        png = plot_tracks(
            out_dir / "tracks.png",
            scans=built.scans,
            sensors=built.config.sensors,
            tracks=tracks,
            truth=built.truth,
            title=f"mapassoc on '{scenario}' (seed {seed}): GOSPA {ratio:.2f} x oracle",
        )
        print(f"plot: {png}")
    print(
        f"outputs: {run_dir}/ (tracks.csv, windows.jsonl, summary.json, manifest.json), "
        f"{out_dir}/oracle_tracks.csv, {out_dir}/scenario/"
    )
    return rows
