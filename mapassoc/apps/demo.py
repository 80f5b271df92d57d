"""``mapassoc demo``: a built-in scenario end to end, next to the oracle.

Simulates the scenario into ``OUT/scenario/``, runs the estimator on those files
exactly as ``mapassoc run`` would (the run folder ``OUT/run/``), smooths the true
associations (the oracle, ``OUT/oracle_tracks.csv``), prints GOSPA of both and
plots detections, truth and tracks (``OUT/tracks.png``).

``OUT`` follows the rules of a run folder (:mod:`mapassoc.apps.run_folders`): a
non-empty ``OUT`` is refused unless ``overwrite``, and even then replaced only when it
is a previous demo's folder (its ``manifest.json`` of format ``mapassoc-demo/1``).  The
demo is built in ``OUT.partial`` and renamed into place whole, so ``OUT`` never mixes
two demos (a ``--no-plot`` demo leaves no earlier plot behind).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from mapassoc.apps.run_folders import DEMO_FORMAT, RunFolder, new_manifest, now_text
from mapassoc.apps.runs import RunInterrupted, RunOptions, run_files
from mapassoc.data.io import read_tracks, write_tracks
from mapassoc.errors import InputError
from mapassoc.evaluation.metrics import RunEvaluation
from mapassoc.evaluation.oracle import oracle_tracks
from mapassoc.evaluation.scenarios import Scenario, build_scenario, describe_scenario
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
    overwrite: bool = False,
) -> dict[str, RunEvaluation]:
    """Run the demo into ``out_dir``; returns the metrics of the estimator and the oracle.

    Raises
    ------
    InputError
        ``plot`` without matplotlib installed (checked before anything is computed).
    OutputError
        ``out_dir`` is not empty and ``overwrite`` is False, or it is not a demo folder.
    """
    if plot and importlib.util.find_spec("matplotlib") is None:
        raise InputError(
            "the demo's plot needs matplotlib: pip install 'mapassoc[plot]', or pass --no-plot"
        )
    folder = RunFolder(out_dir, kind=DEMO_FORMAT)
    folder.check_writable_place()
    if overwrite:
        folder.check_replaceable()
    else:
        folder.refuse_existing()
    built = build_scenario(scenario, seed)
    folder.begin(fresh=True)
    try:
        manifest = new_manifest(
            inputs={}, settings={"scenario": scenario, "seed": seed, "plot": plot},
            scans_total=len(built.scans), kind=DEMO_FORMAT,
        )  # fmt: skip
        folder.write_manifest(manifest)
        rows = _build_demo(built, scenario, seed, folder.partial, plot=plot)
        manifest.update(status="complete", ended=now_text(), scans_committed=len(built.scans))
        folder.write_manifest(manifest)
        folder.complete()
    except RunInterrupted:
        raise InputError(
            f"the demo was interrupted; {out_dir} is as it was (the unfinished demo is in "
            f"{folder.partial})"
        ) from None
    finally:
        folder.release()
    png = " tracks.png," if plot else ""
    print(
        f"outputs in {out_dir}/: run/ (tracks.csv, associations.csv, windows.jsonl, "
        f"summary.json, manifest.json),{png} oracle_tracks.csv, scenario/"
    )
    return rows


def _build_demo(
    built: Scenario, scenario: str, seed: int, out_dir: Path, *, plot: bool
) -> dict[str, RunEvaluation]:
    """The demo's files in ``out_dir`` (the working folder); prints as it goes."""
    print(f"scenario {scenario!r} (seed {seed}): {describe_scenario(scenario)}")
    paths = write_scenario(built, out_dir / "scenario")
    run_dir = out_dir / "run"
    summary = run_files(
        paths["config"], paths["detections"], run_dir, RunOptions(progress=True)
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

        plot_tracks(
            out_dir / "tracks.png",
            scans=built.scans,
            sensors=built.config.sensors,
            tracks=tracks,
            truth=built.truth,
            title=f"mapassoc on '{scenario}' (seed {seed}): GOSPA {ratio:.2f} x oracle",
            # The built-in scenarios' units (mapassoc.evaluation.scenarios).
            length_unit="position-noise σ",
            time_unit="scans",
        )
    return rows
