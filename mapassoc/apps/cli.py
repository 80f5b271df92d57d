"""The ``mapassoc`` command line.

Subcommands::

    mapassoc scenarios                               list the built-in scenarios
    mapassoc simulate NAME --out DIR [--scans N]     write a scenario folder
    mapassoc init-config DETECTIONS [--out TOML]     a starter configuration from the data
    mapassoc run CONFIG DETECTIONS --out DIR         estimate tracks
    mapassoc estimate-parameters CONFIG DETECTIONS   sensor parameters from the recording
    mapassoc batch SOURCE --out DIR [--config C]     many recordings, in parallel
    mapassoc evaluate TRACKS TRUTH [--json FILE]     GOSPA, P-GOSPA, T-GOSPA, RMSE, ...
    mapassoc demo [--scenario NAME] [--out DIR]      simulate, run, evaluate, plot
    mapassoc bench [--families ...] [--seeds N]      speed and accuracy benchmark
    mapassoc compare [--trackers ...] --out DIR      every method side by side
    mapassoc bench-reprocess                         batch, long-recording, segment timings

Errors in the input (files, configuration) and in the outputs (a folder that cannot be
written, a full disk, a closed pipe) print one line naming what is wrong and exit with
status 2; outputs already written stay on disk.  A run stopped by SIGINT or SIGTERM
prints one line and exits with status 130; ``batch`` exits with 1 when a recording
failed.
"""

from __future__ import annotations

import argparse
import os
import sys
import tomllib
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from mapassoc.apps.bench_defaults import DEFAULT_FAMILIES, DEFAULT_K_PRIORS
from mapassoc.apps.runs import RunInterrupted, RunOptions, json_dump, run_files
from mapassoc.apps.stopping import EXIT_INTERRUPTED, StopFlag, stop_on_signals
from mapassoc.data.formats import format_names
from mapassoc.errors import InputError, MapassocError, OutputError
from mapassoc.version import __version__

if TYPE_CHECKING:
    from mapassoc.data.config import TrackerOption

__all__ = ["main", "build_parser"]


def _count(number: object, noun: str) -> str:
    """``"1 track"``, ``"2 tracks"``, ``"0 tracks"``, ``"3 passes"``."""
    if number == 1:
        return f"{number} {noun}"
    return f"{number} {noun}{'es' if noun.endswith('s') else 's'}"


def _cmd_scenarios(args: argparse.Namespace) -> int:
    from mapassoc.evaluation.scenarios import DEFAULT_SCENARIO, describe_scenario, scenario_names

    for name in scenario_names():
        mark = " (default)" if name == DEFAULT_SCENARIO else ""
        print(f"{name:12s} {describe_scenario(name)}{mark}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from mapassoc.evaluation.scenarios import build_scenario, scans_for_duration
    from mapassoc.evaluation.simulate import write_scenario

    scans = args.scans
    if args.duration is not None:
        scans = scans_for_duration(args.name, args.duration)
    scenario = build_scenario(args.name, args.seed, scans=scans)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise OutputError(str(out), "is a file, not a folder; choose another --out")
    if out.is_dir() and any(out.iterdir()):
        _check_scenario_folder(out, overwrite=args.overwrite)
    paths = write_scenario(scenario, out, data_format=args.format)
    for kind, path in paths.items():
        print(f"{kind:10s} {path}")
    return 0


def _check_scenario_folder(out: Path, *, overwrite: bool) -> None:
    """Raise OutputError unless ``simulate`` may write into the non-empty folder ``out``:
    with ``--overwrite``, and only when it holds nothing but scenario files (the names
    ``simulate`` writes), so that no file of the user's is replaced."""
    from mapassoc.data.formats import file_name
    from mapassoc.evaluation.simulate import SCENARIO_FILES

    scenario_files = {"config.toml"} | {
        file_name(kind, data_format)
        for kind in SCENARIO_FILES
        if kind != "config"
        for data_format in format_names()
    }
    others = sorted(entry.name for entry in out.iterdir() if entry.name not in scenario_files)
    if others:
        raise OutputError(
            str(out),
            f"is not empty and holds files simulate does not write ({', '.join(others[:3])}"
            f"{', ...' if len(others) > 3 else ''}); mapassoc replaces only its own outputs: "
            "choose another --out, or empty it yourself",
        )
    if not overwrite:
        raise OutputError(str(out), "is not empty; pass --overwrite to replace its scenario files")


def _cmd_run(args: argparse.Namespace) -> int:
    with stop_on_signals(StopFlag()) as stop:
        options = RunOptions(
            timings=not args.no_timings,
            progress=not args.no_progress,
            overwrite=args.overwrite,
            resume=args.resume,
            checkpoint_seconds=args.checkpoint_seconds,
            segments=args.segments,
            jobs=args.jobs,
            tracks_format=args.tracks_format,
            detections_format=args.format,
        )
        outcome = run_files(args.config, args.detections, args.out, options, stop=stop)
    summary = outcome.summary
    if outcome.status == "skipped":
        print(
            f"{args.out} is complete already ({_count(summary['tracks'], 'track')}); "
            "nothing to resume"
        )
        return 0
    resumed = f" (resumed at scan {outcome.resumed_at})" if outcome.resumed_at else ""
    associations = ", associations.csv" if "confidence" in summary else ""
    print(
        f"{_count(summary['tracks'], 'track')} over {_count(summary['scans'], 'scan')} in "
        f"{_count(summary['windows'], 'window')}{resumed} -> {args.out}/tracks."
        f"{args.tracks_format}{associations}, windows.jsonl, summary.json, manifest.json"
    )
    return 0


def _cmd_estimate_parameters(args: argparse.Namespace) -> int:
    from mapassoc.apps.estimate import estimate_file_parameters

    with stop_on_signals(StopFlag()) as stop:
        report = estimate_file_parameters(
            args.config, args.detections, write=args.write, stop=stop,
            progress=not args.no_progress, detections_format=args.format,
        )  # fmt: skip
    print(report.table())
    estimate = report.estimate
    how = "converged" if estimate.converged else "pass limit"
    print(
        f"{_count(len(estimate.passes), 'pass')} ({how}) over "
        f"{_count(estimate.sample_scans, 'scan')}"
        + (f" -> {args.write}" if args.write else "")
    )
    for message in report.warnings:
        print(f"mapassoc: warning: {message}", file=sys.stderr)
    return 0


def _cmd_migrate_config(args: argparse.Namespace) -> int:
    from mapassoc.apps.run_folders import write_atomically
    from mapassoc.apps.runs import read_input
    from mapassoc.data.config import config_to_toml, load_config, parse_config

    if args.out is not None and os.path.lexists(args.out):
        raise InputError(f"{args.out} exists already; name a new file to write")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", category=ResourceWarning)  # not the input's
        warnings.filterwarnings("ignore", category=DeprecationWarning)  # what it rewrites
        content, _ = read_input(args.config)
        config = load_config(args.config, content=content)
    text = config_to_toml(config)
    again = config_to_toml(parse_config(tomllib.loads(text)))
    if again != text:  # pragma: no cover - the writer's own round trip, tested
        raise RuntimeError("migrate-config: the rewritten file does not read back alike")
    for warning in caught:
        print(f"mapassoc: warning: {warning.message}", file=sys.stderr)
    if args.out is None:
        sys.stdout.write(text)
    else:
        write_atomically(Path(args.out), text.encode("utf-8"), new=True)
        print(f"{args.config} -> {args.out}")
    return 0


def _cmd_batch(args: argparse.Namespace) -> int:
    from mapassoc.apps.batch import BATCH_SUMMARY_NAME, find_recordings, run_batch

    recordings = find_recordings(args.source)
    options = RunOptions(
        timings=not args.no_timings,
        overwrite=args.overwrite,
        resume=args.resume,
        checkpoint_seconds=args.checkpoint_seconds,
        tracks_format=args.tracks_format,
    )

    def report(row: dict[str, object]) -> None:
        if args.no_progress:
            return
        detail = {
            "complete": f"{row['tracks']} tracks, {row['scans_per_second']} scans/s",
            "skipped": "complete already",
        }.get(str(row["status"]), str(row["error"]))
        print(f"  {row['name']}: {row['status']} ({detail})", file=sys.stderr)

    rows = run_batch(
        recordings,
        args.out,
        shared_config=args.config,
        options=options,
        jobs=args.jobs,
        scheduler=args.scheduler,
        progress=not args.no_progress,
        on_row=report,
    )
    counts: dict[str, int] = {}
    for row in rows:
        counts[str(row["status"])] = counts.get(str(row["status"]), 0) + 1
    told = ", ".join(f"{n} {status}" for status, n in sorted(counts.items()))
    print(f"{_count(len(rows), 'recording')}: {told} -> {Path(args.out) / BATCH_SUMMARY_NAME}")
    return 1 if counts.get("failed") else 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from mapassoc.data.formats import read_tracks_file, read_truth_file
    from mapassoc.evaluation.metrics import format_report
    from mapassoc.evaluation.tables import evaluate_tables, pgospa_summary, pgospa_tables

    truth, tracks = read_truth_file(args.truth), read_tracks_file(args.tracks)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        summary = evaluate_tables(
            truth,
            tracks,
            c=args.cutoff,
            p=args.order,
            switch_cost=args.cutoff if args.switch_cost is None else args.switch_cost,
            tgospa_method=args.tgospa_method,
        )
        probabilistic = pgospa_tables(truth, tracks, c=args.cutoff, p=args.order)
    # Both evaluations warn about the same tables: each message once.
    for message in dict.fromkeys(str(warning.message) for warning in caught):
        print(f"mapassoc: warning: {message}", file=sys.stderr)
    report = {**summary.to_json(), "pgospa": pgospa_summary(probabilistic)}
    print(format_report(report))
    if args.json:
        json_dump(report, Path(args.json))
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from mapassoc.apps.demo import run_demo

    run_demo(
        scenario=args.scenario,
        seed=args.seed,
        out_dir=Path(args.out),
        plot=not args.no_plot,
        overwrite=args.overwrite,
    )
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from mapassoc.apps.bench import run_benchmark

    run_benchmark(
        # "crossing parallel" or "crossing,parallel", as other commands take families
        families=[name for item in args.families for name in _comma_separated(item)],
        seeds=args.seeds,
        window_length=args.window_length,
        time_limit=args.time_limit,
        config=args.config,
        scans=args.scans,
        json_path=Path(args.json) if args.json else None,
        k_priors=args.k_priors,
        motion=args.motion,
        parameters=args.parameters,
    )
    return 0


def _cmd_bench_parameters(args: argparse.Namespace) -> int:
    from mapassoc.apps.bench_parameters import run_parameter_benchmark

    run_parameter_benchmark(
        families=args.families,
        seeds=args.seeds,
        time_limit=args.time_limit,
        json_path=Path(args.json) if args.json else None,
    )
    return 0


def _cmd_bench_refinement(args: argparse.Namespace) -> int:
    from mapassoc.apps.bench_refinement import run_refinement_benchmark

    options = _tracker_options(args.option) or {}
    others = sorted(set(options) - {"mht"})
    if others:
        raise InputError(f"bench-refinement --option sets MHT's options only, got {others}")
    run_refinement_benchmark(
        families=args.families,
        seeds=args.seeds,
        time_limit=args.time_limit,
        json_path=Path(args.json) if args.json else None,
        mht_options=options.get("mht"),
    )
    return 0


def _cmd_bench_reprocess(args: argparse.Namespace) -> int:
    from mapassoc.apps.bench_reprocess import run_reprocess_benchmark

    results = run_reprocess_benchmark(
        recordings=args.recordings,
        scans=args.scans,
        long_scans=args.long_scans,
        long_family=args.long_family,
        segment_families=args.segment_families,
        segment_scans=args.segment_scans,
        jobs=args.jobs,
    )
    if args.json:
        json_dump(results, Path(args.json))
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from mapassoc.apps.compare import (
        compare,
        compare_folder,
        format_summary,
        summarize,
        write_comparison,
    )

    plot = not args.no_plot
    folder = compare_folder(args.out, overwrite=args.overwrite, plot=plot)  # before running

    def progress(row: dict[str, object]) -> None:
        note = "" if row["status"] == "ok" else f"  ({row['status']})"
        print(
            f"  {row['scenario']} seed {row['seed']} {row['tracker']}: "
            f"{row['seconds']:.2f} s{note}",
            file=sys.stderr,
        )

    try:
        table = compare(
            args.trackers,
            args.scenarios,
            list(range(args.seeds)),
            c=args.cutoff,
            config=args.config,
            scans=args.scans,
            window_length=args.window_length,
            ospa2_window=args.ospa2_window,
            tracker_options=_tracker_options(args.option),
            on_row=progress,
        )
        summary = summarize(table)
        settings = {key: getattr(args, key) for key in ("trackers", "scenarios", "seeds")}
        names = write_comparison(folder, table, summary, plot=plot, settings=settings)
    finally:
        folder.release()
    print(format_summary(summary))
    print("wrote " + ", ".join(str(Path(args.out) / name) for name in names))
    return 0


def _tracker_options(
    assignments: Sequence[str] | None,
) -> dict[str, dict[str, TrackerOption]] | None:
    """``["mht.n_scan=5", "flow.solver=ssp"]`` -> ``{"mht": {"n_scan": 5}, "flow": {...}}``.

    A value is read as a TOML value (``5``, ``2.5``, ``true``, ``"text"``) and kept as
    text when it is none (``ssp``).
    """
    if not assignments:
        return None
    options: dict[str, dict[str, TrackerOption]] = {}
    for text in assignments:
        target, sep, raw = text.partition("=")
        tracker, dot, option = target.strip().partition(".")
        if not (sep and dot and tracker and option):
            raise InputError(
                f"--option must look like TRACKER.OPTION=VALUE (such as mht.n_scan=5), "
                f"got {text!r}"
            )
        value: TrackerOption
        try:
            value = tomllib.loads(f"value = {raw.strip()}")["value"]
        except tomllib.TOMLDecodeError:
            value = raw.strip()
        except RecursionError:  # tomllib reads nested arrays recursively
            raise InputError(
                f"--option {target.strip()}: the value's arrays or tables are nested too "
                "deeply to read"
            ) from None
        options.setdefault(tracker, {})[option.strip()] = value
    return options


def _comma_separated(text: str) -> list[str]:
    """``"birth, uniform"`` -> ``["birth", "uniform"]`` (names are checked by the bench)."""
    return [item.strip() for item in text.split(",")]


Subcommands = argparse._SubParsersAction  # the type of ``parser.add_subparsers()``

_DETECTIONS_HELP = (
    "detections file, CSV or Parquet by its suffix; a stream without one (/dev/stdin, "
    "<(zcat detections.csv.gz)) by its content, or by --format"
)


def _add_detections_format(p: argparse.ArgumentParser) -> None:
    """``--format`` of a command that reads a detections file."""
    p.add_argument(
        "--format",
        choices=format_names(),
        default=None,
        help="the detections file's format (default: by its suffix; a file without one, "
        "such as a pipe, by its first bytes: Parquet's magic PAR1, else CSV)",
    )


def _add_scenarios_command(sub: Subcommands) -> None:
    """``mapassoc scenarios``."""
    p = sub.add_parser("scenarios", help="list the built-in scenarios")
    p.set_defaults(func=_cmd_scenarios)


def _add_simulate_command(sub: Subcommands) -> None:
    """``mapassoc simulate``."""
    p = sub.add_parser(
        "simulate",
        help="simulate a built-in scenario into a folder",
        description="Write detections.csv, truth.csv, origins.csv and config.toml of a "
        "built-in scenario; `mapassoc run DIR/config.toml DIR/detections.csv` reads them.",
    )
    p.add_argument("name", help="scenario name (see `mapassoc scenarios`)")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    length = p.add_mutually_exclusive_group()
    length.add_argument(
        "--scans",
        type=int,
        default=None,
        metavar="N",
        help="N scans in all (default: the scenario's own length; longer runs keep its "
        "density of targets, births and deaths, and clutter)",
    )
    length.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="T",
        help="as many scans as cover T time units at the scenario's scan period",
    )
    p.add_argument(
        "--format",
        choices=format_names(),
        default="csv",
        help="detections, truth and origins as CSV (default) or Parquet (extra 'parquet')",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the scenario files of a previous simulate in --out (never a folder "
        "holding any other file)",
    )
    p.set_defaults(func=_cmd_simulate)


def _add_run_command(sub: Subcommands) -> None:
    """``mapassoc run``."""
    p = sub.add_parser(
        "run",
        help="estimate tracks from a detections file",
        description="Estimate tracks window by window and write tracks.csv (or "
        "tracks.parquet), windows.jsonl "
        "(one line per window: p(K | Z) over the targets present and p(T | Z) over the "
        "tracks, joint MAP and marginal K, objective per number of tracks, solver status, "
        "hypothesis counts) and summary.json; with a [recording] section also "
        "tracks_recording.csv, in the recording's own time and latitude/longitude.",
    )
    p.add_argument("config", help="TOML configuration (motion, sensors, birth, estimator)")
    p.add_argument("detections", help=_DETECTIONS_HELP)
    _add_detections_format(p)
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument(
        "--no-timings",
        action="store_true",
        help="leave run times out of the outputs, so that equal inputs give byte-identical files",
    )
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress (else a bar on a terminal, a log line every 30 s otherwise)",
    )
    _add_run_session_options(p)
    p.add_argument(
        "--tracks-format",
        choices=format_names(),
        default="csv",
        help="tracks.csv (default) or tracks.parquet (extra 'parquet')",
    )
    p.set_defaults(func=_cmd_run)


def _add_run_session_options(p: argparse.ArgumentParser) -> None:
    """``run``'s options of the session: overwrite or resume, checkpoints, segments."""
    again = p.add_mutually_exclusive_group()
    again.add_argument(
        "--overwrite",
        action="store_true",
        help="replace what --out holds (once the new run is complete)",
    )
    again.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted run of --out (OUT.partial) from its last checkpoint; "
        "nothing to do when --out is complete",
    )
    p.add_argument(
        "--checkpoint-seconds",
        type=float,
        default=10.0,
        metavar="SECONDS",
        help="least time between two checkpoints (default 10; 0: after every window)",
    )
    p.add_argument(
        "--segments",
        type=int,
        default=1,
        metavar="K",
        help="solve the recording in K overlapping time segments on --jobs processes and "
        "stitch them (default 1: sequential; see mapassoc.estimator.segments)",
    )
    p.add_argument(
        "--jobs",
        type=int,
        default=None,
        metavar="N",
        help="worker processes for --segments (default: every usable core)",
    )


def _cmd_init_config(args: argparse.Namespace) -> int:
    from mapassoc.apps.init_config import init_config, parse_site

    sites = dict(parse_site(text) for text in args.site)
    init_config(args.detections, args.out, sites=sites)
    print(f"{args.out}: starter configuration of {args.detections}; run it with "
          f"mapassoc run {args.out} {args.detections} --out DIR")  # fmt: skip
    return 0


def _add_init_config_command(sub: Subcommands) -> None:
    """``mapassoc init-config``."""
    p = sub.add_parser(
        "init-config",
        help="write a starter configuration inferred from a detections file",
        description="Reads a detections file (plain seconds or ISO 8601 times; x,y, "
        "lat,lon, range,azimuth or range,bearing columns), finds its sensors and their "
        "measurement kinds, the region, the scan period, the noise and a velocity spread "
        "from the data, and writes a commented configuration with \"auto\" for the "
        "clutter rate and Pd, which the run estimates. Never overwrites a file.",
        allow_abbrev=False,
    )
    p.add_argument("detections", help=_DETECTIONS_HELP)
    p.add_argument("--out", default="config.toml", help="the configuration to write (a new "
                   "file; default config.toml)")  # fmt: skip
    p.add_argument("--site", action="append", default=[], metavar="NAME=LAT,LON[,HEIGHT]",
                   help="the place of a sensor that gives range and azimuth (degrees, "
                   "metres above the WGS-84 ellipsoid); once per such sensor")  # fmt: skip
    p.set_defaults(func=_cmd_init_config)


def _add_estimate_parameters_command(sub: Subcommands) -> None:
    """``mapassoc estimate-parameters``."""
    p = sub.add_parser(
        "estimate-parameters",
        help="estimate each sensor's false-alarm rate and Pd from a recording",
        description="Estimates every sensor's false_alarms_per_scan and "
        "detection_probability from the recording by expectation-maximisation around the "
        "estimator (mapassoc.estimator.parameters), prints them next to the configured "
        "values, warns where they disagree by more than a factor 1.5 (rate) or 0.1 (Pd), "
        "and with --write writes the configuration with the estimates filled in.",
        allow_abbrev=False,
    )
    p.add_argument("config", help="TOML configuration (numbers or \"auto\")")
    p.add_argument("detections", help=_DETECTIONS_HELP)
    _add_detections_format(p)
    p.add_argument("--write", metavar="TOML", help="write the estimated configuration here "
                   "(a new file)")  # fmt: skip
    p.add_argument("--no-progress", action="store_true", help="no line per pass on stderr")
    p.set_defaults(func=_cmd_estimate_parameters)


def _add_migrate_config_command(sub: Subcommands) -> None:
    """``mapassoc migrate-config``."""
    p = sub.add_parser(
        "migrate-config",
        help="rewrite a configuration in the current layout (estimator tables per component)",
        description="Reads a TOML configuration, the old flat [estimator] keys included "
        "(window_length = 5 directly under [estimator]: each moves to the table of what it "
        "configures, [estimator.windows], [estimator.pruning], ...), and writes it in the "
        "current layout with every key explicit (the defaults spelled out, comments not "
        "kept), so that it loads with no deprecation warning and gives the same "
        "configuration. Never overwrites a file.",
        allow_abbrev=False,
    )
    p.add_argument("config", help="TOML configuration to read (left as it is)")
    p.add_argument("--out", metavar="TOML", help="write the rewritten configuration here "
                   "(a new file; default: print it on stdout)")  # fmt: skip
    p.set_defaults(func=_cmd_migrate_config)


def _add_batch_command(sub: Subcommands) -> None:
    """``mapassoc batch``."""
    p = sub.add_parser(
        "batch",
        help="run many recordings, each into its own run folder, in parallel",
        description="Runs every recording of SOURCE (a folder of NAME/detections.csv "
        "[+ NAME/config.toml] sub-folders or NAME.csv [+ NAME.toml] files, or a CSV list "
        "with the columns name,detections[,config]) into OUT/NAME/ and writes "
        "OUT/batch_summary.csv. A failing recording is reported and the batch goes on "
        "(exit status 1 when any failed). Local process pool by default; --scheduler runs "
        "on a Dask cluster.",
        allow_abbrev=False,
    )
    p.add_argument("source", help="folder of recordings, or a CSV list of them")
    p.add_argument("--out", required=True, help="batch folder (one run folder per recording)")
    p.add_argument(
        "--config", help="shared TOML configuration, for recordings without their own"
    )
    p.add_argument(
        "--jobs",
        type=int,
        default=None,
        metavar="N",
        help="worker processes (default: every usable core; 1: one after the other here)",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="Dask distributed scheduler (tcp://host:8786) to run the recordings on "
        "(extra 'dask'); workers with one thread each",
    )
    again = p.add_mutually_exclusive_group()
    again.add_argument(
        "--resume", action="store_true", help="skip complete recordings, resume interrupted ones"
    )
    again.add_argument("--overwrite", action="store_true", help="run every recording again")
    p.add_argument("--no-timings", action="store_true", help="as for `run`")
    p.add_argument("--no-progress", action="store_true", help="no progress on stderr")
    p.add_argument(
        "--checkpoint-seconds", type=float, default=10.0, metavar="SECONDS", help="as for `run`"
    )
    p.add_argument(
        "--tracks-format", choices=format_names(), default="csv", help="as for `run`"
    )
    p.set_defaults(func=_cmd_batch)


def _add_evaluate_command(sub: Subcommands) -> None:
    """``mapassoc evaluate``."""
    p = sub.add_parser(
        "evaluate",
        help="compare tracks with truth (GOSPA, P-GOSPA, T-GOSPA, RMSE, cardinality, fragments)",
        description="GOSPA (alpha = 2) with its localisation, missed and false parts; "
        "P-GOSPA (Xia et al., probabilistic GOSPA), which also scores the tracks' existence "
        "probabilities (the tracks file's existence column; 1 without it, where P-GOSPA "
        "equals GOSPA), with its existence-mismatch part; position RMSE over assigned pairs "
        "and the cardinality error, averaged over time; then T-GOSPA of the trajectories "
        "(the same c and p, switching cost gamma) with its switching part, the fragments "
        "(track ids) per tracked target and the identity switches of its assignment.  The "
        "T-GOSPA settings of Xia, García-Fernández, Svensson et al. are --cutoff 10 "
        "--order 1 --switch-cost 2.",
    )
    p.add_argument(
        "tracks", help="tracks file, CSV or Parquet by its suffix (as `mapassoc run` writes)"
    )
    p.add_argument(
        "truth", help="truth file, CSV or Parquet by its suffix (as `mapassoc simulate` writes)"
    )
    p.add_argument("--cutoff", type=float, default=10.0, help="GOSPA cut-off c (default 10)")
    p.add_argument("--order", type=float, default=2.0, help="GOSPA order p (default 2)")
    p.add_argument(
        "--switch-cost",
        type=float,
        default=None,
        metavar="GAMMA",
        help="T-GOSPA switching cost gamma: a track switch costs gamma^p (default: the "
        "cut-off; Xia et al. use --cutoff 10 --order 1 --switch-cost 2)",
    )
    p.add_argument(
        "--tgospa-method",
        choices=("milp", "lp"),
        default="milp",
        help="milp: exact T-GOSPA (default); lp: its LP relaxation, a lower bound for huge runs",
    )
    p.add_argument("--json", help="also write the metrics to this JSON file")
    p.set_defaults(func=_cmd_evaluate)


def _add_demo_command(sub: Subcommands) -> None:
    """``mapassoc demo``."""
    p = sub.add_parser(
        "demo",
        help="run the built-in demo scenario end to end",
        description="Simulate a scenario, estimate tracks, compare GOSPA with the oracle "
        "(Kalman smoother on the true associations) and plot detections, truth and tracks.",
    )
    p.add_argument("--scenario", default="crossing", help="scenario name (default crossing)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--out", default="demo-out", help="output folder (default demo-out; parents created)"
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace --out when it holds a previous demo (never any other folder)",
    )
    p.add_argument("--no-plot", action="store_true", help="skip the PNG plot")
    p.set_defaults(func=_cmd_demo)


def _add_bench_command(sub: Subcommands) -> None:
    """``mapassoc bench``."""
    p = sub.add_parser(
        "bench",
        help="speed, accuracy and p(K | Z) over scenario families, seeds and priors on K",
        description="Runs every family (a built-in scenario) with seeds 0..N-1 and prints, "
        "per run, scans per second, window time p50/p95/max and windows over the time "
        "limit, hypotheses, the largest cluster, the window status mix, the smallest "
        "captured mass, GOSPA (loc/missed/false) next to the oracle's, and the Brier score "
        "of p(K | Z) against the true number of targets per window with the fraction of "
        "windows whose marginal K is right; every family runs once per prior on K "
        "(--k-priors).  Then per family and prior the mean GOSPA ratio over seeds with its "
        "spread, the mean Brier score and the mean throughput, the growth of time per scan "
        "over scale20 -> scale50 -> scale100, the goals beside the numbers (judged on the "
        "first prior), and a comparison of the priors: mean GOSPA ratio and Brier score per "
        "family and which prior is lower on each over all families.",
        # No abbreviations: the former `--seed S` must not silently mean `--seeds S`.
        allow_abbrev=False,
    )
    _add_bench_run_options(p)
    p.add_argument(
        "--k-priors",
        type=_comma_separated,
        default=",".join(DEFAULT_K_PRIORS),
        metavar="PRIOR,...",
        help="comma-separated priors on the number of targets per window "
        "(estimator.count.k_prior: birth, uniform, poisson with the configuration's "
        "k_prior_mean) to run every family with; the first is the one the goals judge "
        f"(default {','.join(DEFAULT_K_PRIORS)})",
    )
    p.add_argument(
        "--motion",
        choices=("configured", "imm"),
        default="configured",
        help="the motion model of every run: the configuration's, or a set of it at two "
        "process-noise levels (interacting multiple models; default configured)",
    )
    p.add_argument(
        "--parameters",
        type=_comma_separated,
        default="given",
        metavar="CHOICE,...",
        help="comma-separated: given (the configuration's values) and/or auto (every "
        "sensor's false-alarm rate and Pd, position sensors' noise_std and the motion's "
        "noise_intensity estimated from the recording first, the estimates printed beside "
        "the truth; with --motion imm each model of the set's noise_intensity); "
        "with given,auto each family's summary adds auto's GOSPA over given's "
        "(default given)",
    )
    p.add_argument("--json", metavar="PATH", help="also write the results to this JSON file")
    p.set_defaults(func=_cmd_bench)


def _add_bench_run_options(p: argparse.ArgumentParser) -> None:
    """``bench``'s options of what runs: families, seeds, window, time limit, scans."""
    p.add_argument(
        "--families",
        "--scenarios",
        nargs="+",
        default=list(DEFAULT_FAMILIES),
        metavar="NAME",
        help="scenario families to run, space- or comma-separated (default: "
        f"{' '.join(DEFAULT_FAMILIES)})",
    )
    p.add_argument(
        "--seeds", type=int, default=5, metavar="N", help="seeds 0..N-1 per family (default 5)"
    )
    p.add_argument(
        "--window-length",
        type=int,
        default=5,
        metavar="N",
        help="scans per window for every family (default 5, the window of the speed goals)",
    )
    p.add_argument(
        "--time-limit",
        type=float,
        default=2.0,
        metavar="SECONDS",
        help="estimator time limit in seconds (estimator.windows.time_limit and "
        "estimator.search.program_time_limit), also the "
        "per-window budget counted (default 2.0)",
    )
    p.add_argument(
        "--config",
        choices=("generic", "scenario"),
        default="generic",
        help="generic: the same untuned configuration for every family "
        "(mapassoc.evaluation.scenarios.generic_config); scenario: each scenario's own "
        "(default generic)",
    )
    p.add_argument(
        "--scans",
        type=int,
        default=None,
        metavar="N",
        help="keep only the first N scans of every scenario (quick checks)",
    )



def _add_bench_parameters_command(sub: Subcommands) -> None:
    """``mapassoc bench-parameters``."""
    from mapassoc.apps.bench_defaults import DEFAULT_PARAMETER_FAMILIES

    p = sub.add_parser(
        "bench-parameters",
        help="misstated clutter rate and Pd against \"auto\" and the truth, per family",
        description="Per family and seed (generic configuration): GOSPA of runs with the "
        "rate x0.25, x0.5, x2, x4 and Pd -0.15, +0.15 and of the \"auto\" estimate, "
        "each divided by the run with the true values; the estimates beside the truth; "
        "the cost of \"auto\" in true runs' time.",
        allow_abbrev=False,
    )
    p.add_argument("--families", type=_comma_separated,
                   default=",".join(DEFAULT_PARAMETER_FAMILIES), metavar="NAME,...",
                   help=f"one-sensor scenario families (default "
                   f"{','.join(DEFAULT_PARAMETER_FAMILIES)})")
    p.add_argument("--seeds", type=int, default=2, metavar="N",
                   help="seeds 0..N-1 per family (default 2)")
    p.add_argument("--time-limit", type=float, default=2.0, metavar="SECONDS",
                   help="estimator time limit per window (default 2.0)")
    p.add_argument("--json", metavar="PATH", help="also write the runs to this JSON file")
    p.set_defaults(func=_cmd_bench_parameters)



def _add_bench_refinement_command(sub: Subcommands) -> None:
    """``mapassoc bench-refinement``."""
    from mapassoc.apps.bench_defaults import DEFAULT_REFINEMENT_FAMILIES

    p = sub.add_parser(
        "bench-refinement",
        help="the forward pass, the refined recording and MHT side by side on hard families",
        description="Per family and seed (generic configuration): GOSPA and its parts, "
        "T-GOSPA, fragments, identity switches, track ids per target, seconds and the "
        "recording objective J of the forward pass alone, of its refinement, of MHT and of "
        "the oracle, then the means beside the goals.",
        allow_abbrev=False,
    )
    p.add_argument("--families", type=_comma_separated,
                   default=",".join(DEFAULT_REFINEMENT_FAMILIES), metavar="NAME,...",
                   help=f"scenario families (default {','.join(DEFAULT_REFINEMENT_FAMILIES)})")
    p.add_argument("--seeds", type=int, default=5, metavar="N",
                   help="seeds 0..N-1 per family (default 5)")
    p.add_argument("--time-limit", type=float, default=2.0, metavar="SECONDS",
                   help="estimator time limit per window (default 2.0)")
    p.add_argument("--json", metavar="PATH", help="also write the runs to this JSON file")
    p.add_argument(
        "--option",
        action="append",
        metavar="mht.OPTION=VALUE",
        help="an option of MHT, as a [trackers.mht] table sets it (such as mht.n_scan=5); "
        "repeatable",
    )
    p.set_defaults(func=_cmd_bench_refinement)


def _add_bench_reprocess_command(sub: Subcommands) -> None:
    """``mapassoc bench-reprocess``."""
    p = sub.add_parser(
        "bench-reprocess",
        help="throughput and memory of reprocessing: batch pool vs sequential, a long "
        "recording, segments",
        description="Simulates recordings and times `mapassoc batch` with one process and "
        "with the pool, `mapassoc run` on one long recording (wall time and peak memory) "
        "and `run --segments` against the sequential run (speed-up, GOSPA, same tracks); "
        "every command runs in a child process.",
        allow_abbrev=False,
    )
    p.add_argument("--recordings", type=int, default=6, metavar="R",
                   help="batch recordings (default 6; 0 skips the batch)")
    p.add_argument("--scans", type=int, default=300, metavar="S",
                   help="scans per batch recording (default 300)")
    p.add_argument("--long-scans", type=int, default=10_000, metavar="L",
                   help="scans of the long recording (default 10000; 0 skips it)")
    p.add_argument("--long-family", default="crossing", metavar="NAME",
                   help="scenario of the long recording (default crossing)")
    p.add_argument("--segment-families", type=_comma_separated, default="crossing,dense",
                   metavar="NAME,...", help="scenarios of the segments comparison")
    p.add_argument("--segment-scans", type=int, default=1000, metavar="M",
                   help="scans of each segments recording (default 1000; 0 skips it)")
    p.add_argument("--jobs", type=int, default=None, metavar="N",
                   help="pool size (default: every usable core)")
    p.add_argument("--json", metavar="PATH", help="also write the numbers to this JSON file")
    p.set_defaults(func=_cmd_bench_reprocess)



def _add_compare_command(sub: Subcommands) -> None:
    """``mapassoc compare``."""
    from mapassoc.trackers.registry import DEFAULT_TRACKERS, tracker_names

    p = sub.add_parser(
        "compare",
        help="every tracking method side by side: GOSPA, OSPA(2), CLEAR-MOT, p(K | Z), time",
        description="Runs each tracker (the MAP estimator and the GNN, JPDA, MHT, network-flow "
        "and LP-relaxation baselines, and the oracle) on the same simulated scenarios, seeds "
        "and models, prints the means over seeds and writes compare.csv (one row per run), "
        "compare_summary.csv and compare.png.",
        allow_abbrev=False,
    )
    p.add_argument(
        "--trackers",
        type=_comma_separated,
        default=",".join(DEFAULT_TRACKERS),
        metavar="NAME,...",
        help=f"trackers to compare, from {', '.join(tracker_names())} "
        f"(default {','.join(DEFAULT_TRACKERS)})",
    )
    _add_compare_run_options(p)
    p.add_argument(
        "--option",
        action="append",
        metavar="TRACKER.OPTION=VALUE",
        help="an option of one tracker, as a [trackers.TRACKER] table of a configuration "
        "file sets it (such as mht.n_scan=5 or jpda.max_events=50000); repeatable",
    )
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace --out when it holds a previous comparison (never any other folder)",
    )
    p.add_argument("--no-plot", action="store_true", help="skip compare.png")
    p.set_defaults(func=_cmd_compare)


def _add_compare_run_options(p: argparse.ArgumentParser) -> None:
    """``compare``'s options of what runs and how it is scored."""
    p.add_argument(
        "--scenarios",
        type=_comma_separated,
        default="crossing",
        metavar="NAME,...",
        help="built-in scenarios (see `mapassoc scenarios`; default crossing)",
    )
    p.add_argument(
        "--seeds", type=int, default=1, metavar="N", help="seeds 0..N-1 per scenario (default 1)"
    )
    p.add_argument("--cutoff", type=float, default=10.0, help="metric cut-off c (default 10)")
    p.add_argument(
        "--config",
        choices=("scenario", "generic"),
        default="scenario",
        help="each scenario's own configuration or the untuned generic one (default scenario)",
    )
    p.add_argument("--scans", type=int, default=None, metavar="N", help="first N scans only")
    p.add_argument(
        "--window-length", type=int, default=None, metavar="N", help="scans per window"
    )
    p.add_argument(
        "--ospa2-window",
        type=int,
        default=None,
        metavar="N",
        help="OSPA(2) as the mean over sliding windows of N scan times (default: the whole "
        "run at once, where every unpaired track, however short, costs the cut-off)",
    )


COMMANDS = (
    _add_scenarios_command,
    _add_simulate_command,
    _add_init_config_command,
    _add_run_command,
    _add_estimate_parameters_command,
    _add_migrate_config_command,
    _add_batch_command,
    _add_evaluate_command,
    _add_demo_command,
    _add_bench_command,
    _add_bench_parameters_command,
    _add_bench_refinement_command,
    _add_bench_reprocess_command,
    _add_compare_command,
)
"""Each subcommand's parser, in the order ``mapassoc --help`` lists them: one function per
command adds its parser (arguments, help and the ``func`` that runs it)."""


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``mapassoc`` command."""
    parser = argparse.ArgumentParser(
        prog="mapassoc",
        description="MAP multi-target track-set estimation by optimization: sliding windows "
        "of scans solved as set-packing programs for every number of tracks K.",
    )
    parser.add_argument("--version", action="version", version=f"mapassoc {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add_command in COMMANDS:
        add_command(sub)
    return parser


def _close_stdout_quietly() -> None:
    """Point stdout at /dev/null so that Python's exit flush does not fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # stdout is no file: nothing to flush at exit either
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mapassoc`` command; returns the exit status.

    Input errors and output errors print one line naming the file (or ``<stdout>``) and
    return 2; a run stopped by a signal prints one line and returns 130.
    """
    if sys.stderr is None:  # started with stderr closed (2>&-): messages go nowhere
        sys.stderr = open(os.devnull, "w", encoding="utf-8")  # noqa: SIM115
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        status = int(args.func(args))
        sys.stdout.flush()
        return status
    except RunInterrupted as exc:
        print(f"mapassoc: {exc}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except KeyboardInterrupt:  # a second Ctrl-C, or one outside a run's window loop
        print("mapassoc: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        _close_stdout_quietly()
        error = OutputError("<stdout>", "broken pipe: the reader closed it before the end")
        print(f"mapassoc: error: {error}", file=sys.stderr)
        return 2
    except MapassocError as exc:
        notes = "".join(f"; {note}" for note in getattr(exc, "__notes__", ()))
        print(f"mapassoc: error: {exc}{notes}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = exc.filename if exc.filename is not None else "mapassoc"
        print(f"mapassoc: error: {where}: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
