"""Method comparison: every tracker on the same scenarios, seeds and models, one table.

:func:`compare` simulates each (scenario, seed), builds every tracker of
:data:`~mapassoc.trackers.registry.TRACKERS` named, on the same configuration, runs it and
scores its tracks against the truth (:func:`mapassoc.evaluation.scoring.score_tracks`:
GOSPA and its parts, P-GOSPA of the existence probabilities, OSPA, OSPA(2), T-GOSPA with
its fragments and switches, CLEAR-MOT, and for methods that report p(K | Z) its Brier
score and calibration).  The result is a pandas DataFrame with one row per
(scenario, seed, tracker); :func:`summarize` averages it over seeds.  ``mapassoc compare``
prints that summary and writes both tables as CSV and a figure into a compare folder
(:func:`compare_folder`, :func:`write_comparison`): a run folder of its own kind
(:mod:`mapassoc.apps.run_folders`, ``mapassoc-compare/1``), so it never writes into a
folder of the user's and replaces a previous comparison only with ``--overwrite``.
"""

from __future__ import annotations

import importlib.util
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from mapassoc.apps.run_folders import (
    COMPARE_FORMAT,
    RunFolder,
    now_text,
    write_atomically,
)
from mapassoc.data.config import Config, TrackerOption
from mapassoc.errors import InputError, MapassocError
from mapassoc.evaluation.clear_mot import motmetrics_available
from mapassoc.evaluation.scenarios import (
    build_scenario,
    generic_config,
    scenario_names,
    truncate_scenario,
)
from mapassoc.evaluation.scoring import score_tracks
from mapassoc.evaluation.simulate import Scenario
from mapassoc.trackers.registry import DEFAULT_TRACKERS, TRACKERS, build_tracker
from mapassoc.validation import check_positive
from mapassoc.version import __version__

__all__ = [
    "COMPARE_COLUMNS",
    "COMPARE_FILES",
    "compare",
    "compare_folder",
    "format_summary",
    "summarize",
    "write_comparison",
]

COMPARE_COLUMNS = ("scenario", "seed", "tracker", "status", "seconds", "scans_per_second")
"""The columns of every row, before the scores (``TrackingScores.as_row()`` without its
``seconds``: the row's ``seconds`` is the wall time of ``tracker.track`` measured here, the
same for every method, and ``scans_per_second`` is the number of scans over it)."""

COMPARE_FILES = ("compare.csv", "compare_summary.csv", "compare.png")
"""What a compare folder holds besides its ``manifest.json`` (the figure only when
plotted)."""

_SUMMARY_KEYS = ("scenario", "tracker")


def _check_names(kind: str, names: Sequence[str], known: Sequence[str]) -> list[str]:
    if isinstance(names, str):
        raise InputError(f"{kind} must be a sequence of names, got the string {names!r}")
    names = list(names)
    if not names:
        raise InputError(f"{kind} is empty: name at least one of {', '.join(known)}")
    unknown = [n for n in names if n not in known]
    if unknown:
        raise InputError(f"unknown {kind} {unknown}; known: {', '.join(known)}")
    if len(set(names)) != len(names):
        raise InputError(f"{kind} names one entry twice: {names}")
    return names


def _is_int(value: object) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _config_for(scenario: Scenario, choice: str) -> Config:
    if choice == "scenario":
        return scenario.config
    return generic_config(scenario)


def _checked_tracker_options(
    tracker_options: Mapping[str, Mapping[str, TrackerOption]] | None,
    family: str,
    config: str,
) -> dict[str, dict[str, TrackerOption]]:
    """``tracker_options`` after checking them as a configuration's tables and building
    each named tracker with them once (on the first scenario's configuration, through
    :func:`~mapassoc.trackers.registry.build_tracker`, which refuses an unknown tracker,
    option or value), so that a bad one stops the comparison before it runs."""
    if tracker_options is None:
        return {}
    if not isinstance(tracker_options, Mapping):
        raise InputError(
            f"tracker_options must be a mapping tracker name -> options, got {tracker_options!r}"
        )
    scenario = build_scenario(family, 0)
    checked = replace(_config_for(scenario, config), trackers=tracker_options)
    for name in checked.trackers:
        build_tracker(name, config=checked, origins=scenario.origins)
    return {name: dict(options) for name, options in checked.trackers.items()}


def compare(
    trackers: Sequence[str] = DEFAULT_TRACKERS,
    scenarios: Sequence[str] = ("crossing",),
    seeds: Sequence[int] = (0,),
    *,
    c: float = 10.0,
    config: str = "scenario",
    scans: int | None = None,
    window_length: int | None = None,
    time_limit: float | None = None,
    ospa2_window: int | None = None,
    tracker_options: Mapping[str, Mapping[str, TrackerOption]] | None = None,
    on_row: Callable[[dict[str, object]], None] | None = None,
) -> pd.DataFrame:
    """Run every tracker on every (scenario, seed) and score it against the truth.

    Parameters
    ----------
    trackers : sequence of str
        Names from :data:`~mapassoc.trackers.registry.TRACKERS`.
    scenarios : sequence of str
        Built-in scenario names (:func:`~mapassoc.evaluation.scenarios.scenario_names`).
    seeds : sequence of int
        Seeds of the realisations; every tracker sees the same realisation.
    c : float
        Cut-off of GOSPA, OSPA and OSPA(2) (and the CLEAR-MOT match threshold).
    config : {"scenario", "generic"}
        The scenario's own configuration (models matching the simulation), or the
        benchmark's untuned :func:`~mapassoc.evaluation.scenarios.generic_config`.  Every
        tracker gets the same one.
    scans : int, optional
        Keep only the first ``scans`` scans of each realisation.
    window_length : int, optional
        Replace the configuration's window length (the MAP estimator, LP relaxation and
        network flow use it).
    time_limit : float, optional
        Replace the configuration's ``time_limit`` (seconds per window, > 0).  A limit no
        window reaches (for example 600) makes every number a function of the inputs
        alone; with the default 2 s, windows that need longer (the parallel scenario's)
        stop at the clock and their answers depend on the machine.
    ospa2_window : int, optional
        Score OSPA(2) as the mean over sliding windows of this many evaluation times
        (:func:`~mapassoc.evaluation.ospa.ospa2_over_time`); ``None`` (default) scores the
        whole run at once, where every unpaired trajectory, however short, costs ``c``.
    tracker_options : mapping, optional
        Tracker name -> its options (what a ``[trackers.<name>]`` table of a configuration
        file holds, :attr:`~mapassoc.data.config.Config.trackers`), for example
        ``{"mht": {"n_scan": 5}}``; replaces the configuration's tables of those
        trackers.  Checked before anything runs.
    on_row : callable, optional
        Called with each row (a dict) as soon as it is computed, e.g. to print progress.

    Returns
    -------
    pandas.DataFrame
        One row per (scenario, seed, tracker): :data:`COMPARE_COLUMNS` then the scores
        (the fields of :class:`~mapassoc.evaluation.scoring.TrackingScores` but
        ``seconds``).
        ``status`` is ``"ok"``, or the one-line error of a tracker that refused the
        data (the other trackers still run; that row's scores are missing).  The
        CLEAR-MOT columns are empty (``None``) when ``motmetrics`` is not installed.

    Raises
    ------
    InputError
        An unknown tracker or scenario, a bad seed, cut-off or configuration choice
        (checked before anything runs).
    """
    names = _check_names("trackers", trackers, list(TRACKERS))
    families = _check_names("scenarios", scenarios, scenario_names())
    seeds = _checked_seeds(seeds)
    _check_run_choices(c=c, config=config, scans=scans, window_length=window_length)
    if time_limit is not None:
        time_limit = check_positive("time_limit", time_limit, key="time_limit")
    if ospa2_window is not None and (not _is_int(ospa2_window) or ospa2_window < 1):
        raise InputError(f"ospa2_window must be an integer >= 1, got {ospa2_window!r}")
    options = _checked_tracker_options(tracker_options, families[0], config)
    # CLEAR-MOT needs the optional motmetrics; without it its columns are empty instead of
    # every run failing on it.
    with_clear_mot = motmetrics_available()
    rows: list[dict[str, object]] = []
    for family in families:
        for seed in seeds:
            scenario = build_scenario(family, int(seed))
            if scans is not None:
                scenario = truncate_scenario(scenario, int(scans))
            run_config = _run_config(
                scenario,
                config,
                window_length=window_length,
                time_limit=time_limit,
                options=options,
            )
            for name in names:
                row = _compare_row(
                    family,
                    int(seed),
                    name,
                    scenario,
                    run_config,
                    c=float(c),
                    clear_mot_scores=with_clear_mot,
                    ospa2_window=None if ospa2_window is None else int(ospa2_window),
                )
                rows.append(row)
                if on_row is not None:
                    on_row(row)
    return pd.DataFrame(rows)


def _checked_seeds(seeds: Sequence[int]) -> list[int]:
    """``seeds`` as a list (a generator or an array is read once, here), refused unless
    a non-empty sequence of integers >= 0."""
    if isinstance(seeds, (str, int)) or not isinstance(seeds, Iterable):
        raise InputError(f"seeds must be a sequence of integers >= 0, got {seeds!r}")
    seeds = list(seeds)
    if not all(_is_int(s) and s >= 0 for s in seeds):
        raise InputError(f"seeds must be a sequence of integers >= 0, got {seeds!r}")
    if not seeds:
        raise InputError("seeds is empty: give at least one seed")
    return seeds


def _check_run_choices(
    *, c: float, config: str, scans: int | None, window_length: int | None
) -> None:
    """Refuse a cut-off ``c`` that is not finite and > 0, a ``config`` choice other than
    ``"scenario"`` or ``"generic"``, and ``scans`` or ``window_length`` not integers
    >= 1 (``None``: not given)."""
    if isinstance(c, bool) or not (isinstance(c, (int, float)) and np.isfinite(c) and c > 0):
        raise InputError(f"c must be a finite cut-off > 0, got {c!r}")
    if config not in ("scenario", "generic"):
        raise InputError(f"config must be 'scenario' or 'generic', got {config!r}")
    if scans is not None and (not _is_int(scans) or scans < 1):
        raise InputError(f"scans must be an integer >= 1, got {scans!r}")
    if window_length is not None and (not _is_int(window_length) or window_length < 1):
        raise InputError(f"window_length must be an integer >= 1, got {window_length!r}")


def _run_config(
    scenario: Scenario,
    config: str,
    *,
    window_length: int | None,
    time_limit: float | None,
    options: Mapping[str, Mapping[str, TrackerOption]],
) -> Config:
    """The configuration every tracker gets on ``scenario``: its own or the generic one,
    with the window length, time limit and tracker tables given (``None``, empty: the
    configuration's)."""
    run_config = _config_for(scenario, config)
    estimator = run_config.estimator
    if window_length is not None:
        estimator = estimator.with_window_length(int(window_length))
    if time_limit is not None:
        estimator = estimator.with_time_limit(float(time_limit))
    run_config = replace(run_config, estimator=estimator)
    if options:
        run_config = replace(run_config, trackers={**run_config.trackers, **options})
    return run_config


def _compare_row(
    family: str,
    seed: int,
    name: str,
    scenario: Scenario,
    run_config: Config,
    *,
    c: float,
    clear_mot_scores: bool,
    ospa2_window: int | None,
) -> dict[str, object]:
    """One row of the comparison: tracker ``name`` built on ``run_config``, run on the
    scenario's scans (timed here, the same for every method) and scored against its
    truth; a tracker that refuses the data gets its one-line error as ``status`` and no
    scores."""
    row: dict[str, object] = {
        "scenario": family,
        "seed": seed,
        "tracker": name,
        "status": "ok",
        "seconds": float("nan"),
        "scans_per_second": float("nan"),
    }
    try:
        tracker = build_tracker(name, config=run_config, origins=scenario.origins)
        start = time.perf_counter()
        output = tracker.track(scenario.scans)
        seconds = time.perf_counter() - start
        scores = score_tracks(
            scenario.truth,
            output,
            c=c,
            clear_mot_scores=clear_mot_scores,
            ospa2_window=ospa2_window,
        )
    except MapassocError as exc:
        row["status"] = f"{type(exc).__name__}: {exc}"
    else:
        row["seconds"] = seconds
        row["scans_per_second"] = len(scenario.scans) / seconds if seconds > 0 else float("nan")
        scored = scores.as_row()
        del scored["seconds"]  # the tracker's own timing; the row keeps ours
        row.update(scored)
    return row


def summarize(table: pd.DataFrame) -> pd.DataFrame:
    """Means over seeds per (scenario, tracker) of every numeric column, in input order.

    Rows of failed runs (``status != "ok"``) are left out of the means; the column
    ``runs`` counts the runs averaged and ``failed`` those left out.
    """
    missing = [k for k in (*_SUMMARY_KEYS, "status", "seed") if k not in table.columns]
    if missing:
        raise InputError(f"table lacks the columns {missing}: pass the result of compare()")
    ok = table[table["status"] == "ok"]
    numeric = [
        col
        for col in ok.columns
        if col not in (*_SUMMARY_KEYS, "seed", "status") and pd.api.types.is_numeric_dtype(ok[col])
    ]
    means = ok.groupby(list(_SUMMARY_KEYS), sort=False)[numeric].mean()
    counts = table.groupby(list(_SUMMARY_KEYS), sort=False).agg(
        runs=("status", lambda s: int((s == "ok").sum())),
        failed=("status", lambda s: int((s != "ok").sum())),
    )
    return counts.join(means).reset_index()


_FORMAT_COLUMNS = (
    ("gospa", "GOSPA", "{:7.2f}"),
    ("gospa_localisation", "loc^p", "{:7.2f}"),
    ("gospa_missed", "miss^p", "{:7.2f}"),
    ("gospa_false", "false^p", "{:7.2f}"),
    ("pgospa", "P-GOSPA", "{:7.2f}"),
    ("ospa2", "OSPA2", "{:6.2f}"),
    ("tgospa", "T-GOSPA", "{:7.2f}"),
    ("tgospa_id_switches", "T-IDsw", "{:6.1f}"),
    ("fragments_per_target", "frag", "{:5.2f}"),
    ("mota", "MOTA", "{:6.3f}"),
    ("id_switches", "IDsw", "{:5.1f}"),
    ("k_brier", "Brier", "{:6.3f}"),
    ("seconds", "seconds", "{:8.2f}"),
)


def format_summary(summary: pd.DataFrame) -> str:
    """An aligned text table of the main columns of :func:`summarize` (blank if missing).

    ``loc^p``, ``miss^p`` and ``false^p`` are the means of GOSPA's p-th power parts (at
    each time they add up to GOSPA^p), so they are not on the scale of the GOSPA column.
    ``P-GOSPA`` scores the existence probabilities a tracker reports as well (it equals
    GOSPA for one that reports none); ``T-IDsw`` counts the identity switches of the
    T-GOSPA assignment, ``IDsw`` CLEAR-MOT's.
    """
    header = f"{'scenario':12s} {'tracker':11s} {'runs':>4s}"
    widths = []
    for _, label, fmt in _FORMAT_COLUMNS:
        width = len(fmt.format(0.0))
        widths.append(width)
        header += " " + label.rjust(width)
    lines = [header, "-" * len(header)]
    for _, row in summary.iterrows():
        line = f"{row['scenario']:12s} {row['tracker']:11s} {int(row['runs']):4d}"
        for (column, _, fmt), width in zip(_FORMAT_COLUMNS, widths, strict=True):
            value = row.get(column)
            ok = value is not None and not pd.isna(value)
            line += " " + (fmt.format(float(value)) if ok else "-".rjust(width))
        lines.append(line)
    return "\n".join(lines)


def _older_comparison(folder: Path) -> bool:
    """Whether ``folder`` holds only what ``mapassoc compare`` wrote before it wrote a
    manifest: some of :data:`COMPARE_FILES`, ``compare.csv`` with its columns."""
    names = {entry.name for entry in folder.iterdir()}
    if not names <= set(COMPARE_FILES) or "compare.csv" not in names:
        return False
    try:
        with open(folder / "compare.csv", encoding="utf-8") as handle:
            header = handle.readline(4096)
    except (OSError, UnicodeDecodeError):
        return False
    return header.startswith(",".join(COMPARE_COLUMNS))


def compare_folder(
    out: str | os.PathLike[str], *, overwrite: bool = False, plot: bool = True
) -> RunFolder:
    """The folder ``mapassoc compare`` writes, checked and locked before anything runs.

    Raises
    ------
    OutputError
        ``out`` is not empty and holds no comparison (whatever ``overwrite``), holds one
        and ``overwrite`` is False, or another comparison is writing it.
    InputError
        ``plot`` without matplotlib installed.
    """
    if plot and importlib.util.find_spec("matplotlib") is None:
        raise InputError(
            "the comparison's figure needs matplotlib: pip install 'mapassoc[plot]', or "
            "pass --no-plot"
        )
    folder = RunFolder(out, kind=COMPARE_FORMAT, adopt=_older_comparison)
    folder.check_writable_place()
    if overwrite:
        folder.check_replaceable()
    else:
        folder.refuse_existing()
    folder.lock()
    return folder


def write_comparison(
    folder: RunFolder,
    table: pd.DataFrame,
    summary: pd.DataFrame,
    *,
    plot: bool = True,
    settings: Mapping[str, object] | None = None,
) -> list[str]:
    """Write the tables (and the figure) into ``folder``; the names of the files written.

    They go to ``OUT.partial`` first, which replaces ``OUT`` once all are written, so
    ``OUT`` holds one whole comparison (the previous one until then).
    """
    folder.begin(fresh=True)
    manifest: dict[str, object] = {
        "format": COMPARE_FORMAT,
        "status": "running",
        "mapassoc_version": __version__,
        "settings": dict(settings or {}),
        "started": now_text(),
        "ended": None,
    }
    folder.write_manifest(manifest)
    names = list(COMPARE_FILES if plot else COMPARE_FILES[:2])
    for name, frame in zip(names, (table, summary), strict=False):
        write_atomically(folder.partial / name, frame.to_csv(index=False).encode("utf-8"))
    if plot:
        from mapassoc.apps.plotting import plot_comparison

        plot_comparison(folder.partial / COMPARE_FILES[2], summary)
    folder.write_manifest({**manifest, "status": "complete", "ended": now_text()})
    folder.complete()
    return names
