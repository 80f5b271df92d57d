"""``mapassoc bench-refinement``: the forward pass, the refined recording and MHT side by side.

For every family (a built-in scenario; by default the hard ones: targets that converge
and travel closely spaced at low Pd in clutter, targets meeting at one point, parallel
lanes, Pd 0.8 among dense clutter, births and deaths throughout) and seed, with the
benchmark's untuned configuration (:func:`mapassoc.evaluation.scenarios.generic_config`)
it runs

* ``forward``: the window estimator with ``refinement.passes = 0`` (each window's decision
  final);
* ``refined``: the whole recording's refinement of that forward pass
  (:mod:`mapassoc.estimator.refinement`, the estimator's default), timed on its own
  (existence and association probabilities included);
* ``r>=0.5``: the refined tracks whose existence probability is at least
  :data:`MIN_EXISTENCE` (the extraction rule ``min_existence``);
* ``mht``: the project's track-oriented MHT (:mod:`mapassoc.trackers.mht`);
* ``ss_gnn``: Stone Soup's global-nearest-neighbour tracker
  (:mod:`mapassoc.interop.stonesoup_gnn`; left out when Stone Soup, the ``stonesoup``
  extra, is not installed or the motion model is not constant velocity), the speed
  reference: its seconds stand beside mapassoc's whole run (forward pass plus
  refinement) in the summary;
* ``oracle``: the smoother on the true associations,

and prints per run GOSPA (c = :data:`GOSPA_CUTOFF` position-noise standard deviations, p = 2:
10 for the built-in families, whose length unit is that standard deviation, 500 m for a
manoeuvring family with 50 m noise) with its localisation, missed
and false parts, T-GOSPA (switching cost c), fragments per tracked target, identity
switches, track ids per true target, seconds, and the recording objective J
(:mod:`mapassoc.estimator.objective`) of every method's track set: J(refined) >=
J(forward) always, and J(oracle) beside them says whether what is left is the search's
fault (J of the truth higher) or the model's (lower).  Then per family the means over
seeds beside the goals: refined GOSPA <= 1.2 x the oracle's and <= MHT's, T-GOSPA <=
MHT's, ids <= 1.15 x the true targets, refinement time <= the forward pass's; and the
calibration of the existence probabilities: of the refined tracks in each existence bin,
the share that follow a true target (at least half their detections that target's).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

import numpy as np

from mapassoc.apps.bench_defaults import DEFAULT_REFINEMENT_FAMILIES
from mapassoc.apps.run_folders import write_json
from mapassoc.errors import InputError

if TYPE_CHECKING:  # the estimator is imported when the benchmark runs
    from mapassoc.data.config import Config, TrackerOption
    from mapassoc.data.io import Origins, TrackTable
    from mapassoc.data.outputs import TrackerOutput
    from mapassoc.estimator.objective import RecordingObjective
    from mapassoc.estimator.pipeline import EstimateResult
    from mapassoc.estimator.refinement import RefinedTracks
    from mapassoc.evaluation.simulate import Scenario

__all__ = [
    "REFINEMENT_FAMILIES",
    "GOSPA_CUTOFF",
    "METHODS",
    "RefinementRun",
    "run_refinement_benchmark",
]

REFINEMENT_FAMILIES = DEFAULT_REFINEMENT_FAMILIES
"""The default families: as hard as users' data (the documentation's refinement guide)."""

GOSPA_CUTOFF = 10.0
"""GOSPA cut-off c of the refinement benchmark's scores (alpha = 2)."""
MIN_EXISTENCE = 0.5
"""The extraction rule measured beside the refined set: tracks of existence >= this."""
RELIABILITY_BINS = 5
METHODS = ("forward", "refined", f"r>={MIN_EXISTENCE:g}", "mht", "ss_gnn", "oracle")
"""The methods the refinement benchmark compares, in table order."""


@dataclass(frozen=True)
class RefinementRun:
    """One method on one family and seed.

    Attributes
    ----------
    family, seed, method : str, int, str
    gospa, localisation, missed, false : float
        Mean GOSPA over time and the means of its squared parts.
    tgospa : float
        T-GOSPA of the trajectories (switching cost = the cut-off).
    fragments_per_target : float
    id_switches : int
    tracks, targets : int
        Track ids of the output; true targets.
    seconds : float
        For ``refined``: the refinement alone (add the forward run's for the total).
    objective : float
        J of the method's track set (``nan`` for a method without hard associations).
    cutoff : float
        The GOSPA cut-off c of the family (and T-GOSPA's switching cost).
    """

    family: str
    seed: int
    method: str
    gospa: float
    localisation: float
    missed: float
    false: float
    tgospa: float
    fragments_per_target: float
    id_switches: int
    tracks: int
    targets: int
    seconds: float
    objective: float
    cutoff: float = GOSPA_CUTOFF


def run_refinement_benchmark(
    *,
    families: Sequence[str] = REFINEMENT_FAMILIES,
    seeds: int = 5,
    time_limit: float = 2.0,
    scans: int | None = None,
    json_path: Path | str | None = None,
    out: TextIO | None = None,
    mht_options: Mapping[str, TrackerOption] | None = None,
) -> list[RefinementRun]:
    """Run and print the benchmark (module docstring); optionally write JSON rows.

    ``mht_options``: MHT's own options (a ``[trackers.mht]`` table, such as
    ``{"n_scan": 5}``); checked before anything runs.

    Raises
    ------
    InputError
        An unknown family, ``seeds < 1``, an option MHT does not take or refuses.
    """
    stream = out if out is not None else sys.stdout
    tables = _checked_tables(families, seeds, scans, mht_options)
    rows: list[RefinementRun] = []
    reliability: list[tuple[float, bool]] = []  # (existence, matches a true target) per track

    def say(text: str) -> None:
        print(text, file=stream, flush=True)

    say(
        f"bench-refinement: {len(families)} families x {seeds} seeds, generic configuration, "
        f"time limit {time_limit} s; GOSPA c = {GOSPA_CUTOFF:g} position-noise standard "
        "deviations, p = 2"
    )
    for family in families:
        for seed in range(seeds):
            runs, matches = _one_seed(family, seed, scans, time_limit, tables)
            rows += runs
            reliability += matches
            say(_run_line(family, seed, runs))
    _print_summary(rows, families, say)
    _print_reliability(reliability, say)
    if json_path is not None:
        write_json(Path(json_path), [r.__dict__ for r in rows], allow_nan=True)
    return rows


def _checked_tables(
    families: Sequence[str],
    seeds: object,
    scans: int | None,
    mht_options: Mapping[str, TrackerOption] | None,
) -> dict[str, dict[str, TrackerOption]]:
    """The ``trackers`` tables of every run's configuration (MHT's options, if any), after
    checking the families, the seeds and, on the first family, MHT's options."""
    from mapassoc.evaluation.scenarios import build_scenario, generic_config, scenario_names
    from mapassoc.trackers.registry import build_tracker

    unknown = [name for name in families if name not in scenario_names()]
    if unknown:
        raise InputError(f"unknown families {unknown}; known: {', '.join(scenario_names())}")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise InputError(f"seeds must be an integer >= 1, got {seeds!r}")
    tables = {} if mht_options is None else {"mht": dict(mht_options)}
    if tables:  # built once on the first family, so that a bad option stops it here
        first = build_scenario(families[0], 0, scans=scans)
        checked = dataclasses.replace(generic_config(first), trackers=tables)
        build_tracker("mht", config=checked)
    return tables


def _one_seed(
    family: str,
    seed: int,
    scans: int | None,
    time_limit: float,
    tables: Mapping[str, Mapping[str, TrackerOption]],
) -> tuple[list[RefinementRun], list[tuple[float, bool]]]:
    """Every method on one family and seed, scored; and each refined track's (existence,
    whether it follows a true target)."""
    from mapassoc.estimator.objective import RecordingObjective  # noqa: F811
    from mapassoc.evaluation.scenarios import build_scenario, generic_config, length_unit

    scenario = build_scenario(family, seed, scans=scans)
    config = dataclasses.replace(generic_config(scenario, time_limit=time_limit), trackers=tables)
    objective = RecordingObjective(config=config, scans=scenario.scans)
    outputs = _run_methods(scenario, config)
    confidence = outputs.refined.confidence
    existence = confidence.existence if confidence else {}
    reliability = _reliability(outputs.refined.track_rows, existence, scenario.origins)
    targets = len(np.unique(scenario.truth.target_ids))
    cutoff = GOSPA_CUTOFF * length_unit(config)
    runs = [
        _score(family, seed, run.method, scenario, run.tracks, targets, run.seconds,
               run.objective, cutoff)
        for run in _method_runs(scenario, config, objective, outputs, existence)
    ]  # fmt: skip
    return runs, reliability


@dataclass(frozen=True, eq=False)
class _Outputs:
    """The forward pass, its refinement (smoothed) and MHT on one recording, timed."""

    forward: EstimateResult
    forward_seconds: float
    refined: RefinedTracks
    refined_tracks: TrackTable
    refine_seconds: float
    mht: TrackerOutput
    mht_seconds: float
    gnn: TrackTable | None
    gnn_seconds: float


def _stonesoup_gnn(scenario: Scenario, config: Config) -> tuple[TrackTable | None, float]:
    """Stone Soup's GNN's tracks and seconds, or ``(None, nan)`` where it cannot run."""
    from mapassoc.interop.stonesoup_gnn import stonesoup_gnn_tracks
    from mapassoc.models.motion import ConstantVelocity

    if type(config.motion) is not ConstantVelocity:
        return None, math.nan
    started = time.perf_counter()
    try:
        tracks = stonesoup_gnn_tracks(scenario.scans, config)
    except ImportError:
        return None, math.nan
    return tracks, time.perf_counter() - started


def _run_methods(scenario: Scenario, config: Config) -> _Outputs:
    """Run the forward pass (``refinement.passes = 0``), refine and smooth its tracks, run MHT."""
    from mapassoc.estimator.pipeline import WindowEstimator
    from mapassoc.estimator.refinement import refine_track_rows
    from mapassoc.filtering.smoothing import smooth_tracks
    from mapassoc.trackers.registry import build_tracker

    no_refinement = dataclasses.replace(config.estimator.refinement, passes=0)
    forward_config = dataclasses.replace(
        config, estimator=dataclasses.replace(config.estimator, refinement=no_refinement)
    )
    where = {
        int(row): (k, j) for k, scan in enumerate(scenario.scans) for j, row in enumerate(scan.rows)
    }
    started = time.perf_counter()
    forward = WindowEstimator(config=forward_config).run(scenario.scans)
    forward_seconds = time.perf_counter() - started
    started = time.perf_counter()
    refined = refine_track_rows(config, scenario.scans, forward.track_rows)
    refined_tracks = smooth_tracks(
        scenario.scans,
        {tid: dict(where[r] for r in rows) for tid, rows in refined.track_rows.items()},
        config,
    )
    refine_seconds = time.perf_counter() - started
    started = time.perf_counter()
    mht = build_tracker("mht", config=config).track(scenario.scans)
    mht_seconds = time.perf_counter() - started
    gnn, gnn_seconds = _stonesoup_gnn(scenario, config)
    return _Outputs(
        forward, forward_seconds, refined, refined_tracks, refine_seconds, mht, mht_seconds,
        gnn, gnn_seconds,
    )  # fmt: skip


@dataclass(frozen=True, eq=False)
class _MethodRun:
    """One method's track set with its seconds and its J."""

    method: str
    tracks: TrackTable
    seconds: float
    objective: float


def _method_runs(
    scenario: Scenario,
    config: Config,
    objective: RecordingObjective,
    outputs: _Outputs,
    existence: Mapping[int, float],
) -> list[_MethodRun]:
    """The methods of :data:`METHODS`, in that order."""
    from mapassoc.evaluation.oracle import oracle_tracks

    refined_rows = outputs.refined.track_rows
    sure_ids = [t for t in refined_rows if existence.get(t, 1.0) >= MIN_EXISTENCE]
    sure_rows = {t: refined_rows[t] for t in sure_ids}
    mht_rows = {
        tid: tuple(int(scenario.scans[k].rows[j]) for k, j in sorted(a.items()))
        for tid, a in (outputs.mht.associations or {}).items()
        if a
    }
    oracle = oracle_tracks(scenario.scans, scenario.origins, config)
    forward, refine_seconds = outputs.forward, outputs.refine_seconds
    gnn = []
    if outputs.gnn is not None:
        gnn_rows = _rows_of(outputs.gnn)
        gnn = [_MethodRun("ss_gnn", outputs.gnn, outputs.gnn_seconds, _value(objective, gnn_rows))]
    return [
        _MethodRun("forward", forward.tracks, outputs.forward_seconds,
                   _value(objective, forward.track_rows)),
        _MethodRun("refined", outputs.refined_tracks, refine_seconds,
                   outputs.refined.report.objective),
        _MethodRun(METHODS[2], _only(outputs.refined_tracks, sure_ids), refine_seconds,
                   _value(objective, sure_rows)),
        _MethodRun("mht", outputs.mht.tracks, outputs.mht_seconds, _value(objective, mht_rows)),
        *gnn,
        _MethodRun("oracle", oracle, 0.0, _value(objective, _truth_rows(scenario.origins))),
    ]  # fmt: skip


def _rows_of(tracks: TrackTable) -> dict[int, list[int]]:
    """Each track's detection ids, in time order (misses left out)."""
    out: dict[int, list[int]] = {}
    order = np.lexsort((tracks.times, tracks.track_ids))
    for tid, row in zip(tracks.track_ids[order].tolist(), tracks.detection_rows[order].tolist(),
                        strict=True):  # fmt: skip
        if row >= 0:
            out.setdefault(int(tid), []).append(int(row))
    return out


def _truth_rows(origins: Origins) -> dict[int, list[int]]:
    """The true associations: each target's detection ids."""
    truth_rows: dict[int, list[int]] = {}
    for row, origin in zip(origins.rows.tolist(), origins.target_ids.tolist(), strict=True):
        if origin >= 0:
            truth_rows.setdefault(int(origin), []).append(int(row))
    return truth_rows


def _reliability(
    track_rows: Mapping[int, Sequence[int]], existence: Mapping[int, float], origins: Origins
) -> list[tuple[float, bool]]:
    """Each track's existence probability (``nan`` if unknown) and whether at least half
    its detections are one true target's."""
    origin = dict(zip(origins.rows.tolist(), origins.target_ids.tolist(), strict=True))
    out: list[tuple[float, bool]] = []
    for tid, used in track_rows.items():
        owners = [origin.get(r, -1) for r in used]
        top = max(set(owners), key=owners.count)
        matches = top >= 0 and 2 * owners.count(top) >= len(used)
        out.append((existence.get(tid, math.nan), matches))
    return out


def _only(tracks: TrackTable, ids: Sequence[int]) -> TrackTable:
    """The records of ``tracks`` whose track id is in ``ids``."""
    keep = np.isin(tracks.track_ids, np.asarray(list(ids), dtype=np.int64))
    return tracks.select(keep)


def _print_reliability(reliability: Sequence[tuple[float, bool]], say: object) -> None:
    """How often a refined track of each existence bin is a true target's."""
    edges = np.linspace(0.0, 1.0, RELIABILITY_BINS + 1)
    lines = [
        "",
        "Existence calibration (refined tracks of every run): a track matches a true target "
        "when at least half its detections are that target's; goal: the share within its bin",
        f"{'existence':>12s} {'tracks':>7s} {'matching':>9s}",
    ]
    values = np.array([r for r, _ in reliability], dtype=float)
    matches = np.array([m for _, m in reliability], dtype=bool)
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        inside = (values >= lo) & ((values < hi) | ((hi == 1.0) & (values <= hi)))
        count = int(np.count_nonzero(inside))
        share = f"{np.mean(matches[inside]):9.2f}" if count else f"{'-':>9s}"
        lines.append(f"  [{lo:.1f}, {hi:.1f}{']' if hi == 1.0 else ')'} {count:7d} {share}")
    unknown = int(np.count_nonzero(np.isnan(values)))
    if unknown:
        lines.append(f"  unknown      {unknown:7d}")
    for line in lines:
        say(line)  # type: ignore[operator]


def _value(objective: RecordingObjective, track_rows: Mapping[int, Sequence[int]]) -> float:
    """J of a track set given as detection ids (``-inf`` where the model's gate or a
    miss of probability 0 excludes one of its tracks)."""
    return objective.value([objective.path_of_rows(r) for r in track_rows.values() if len(r)])


def _score(
    family: str,
    seed: int,
    method: str,
    scenario: object,
    tracks: object,
    targets: int,
    seconds: float,
    objective: float,
    cutoff: float,
) -> RefinementRun:
    from mapassoc.evaluation.tables import evaluate_tables

    ev = evaluate_tables(
        scenario.truth,  # type: ignore[attr-defined]
        tracks,  # type: ignore[arg-type]
        c=cutoff,
        switch_cost=cutoff,
    )
    g = ev.gospa
    frag = ev.fragmentation
    tgospa = ev.tgospa
    return RefinementRun(
        family=family,
        seed=seed,
        method=method,
        gospa=g.mean_total,
        localisation=g.mean_localisation,
        missed=g.mean_missed,
        false=g.mean_false,
        tgospa=float(tgospa.total) if tgospa is not None else math.nan,
        fragments_per_target=float(frag.fragments_per_target) if frag is not None else math.nan,
        id_switches=int(frag.num_id_switches) if frag is not None else 0,
        tracks=len(np.unique(tracks.track_ids)),  # type: ignore[attr-defined]
        targets=targets,
        seconds=seconds,
        objective=objective,
        cutoff=cutoff,
    )


def _run_line(family: str, seed: int, runs: Sequence[RefinementRun]) -> str:
    parts = [
        f"{r.method} GOSPA {r.gospa:.3f} (loc {r.localisation:.2f} miss {r.missed:.2f} "
        f"false {r.false:.2f}) T-GOSPA {r.tgospa:.1f} frag {r.fragments_per_target:.2f} "
        f"idsw {r.id_switches} ids {r.tracks}/{r.targets} {r.seconds:.1f} s J {r.objective:.1f}"
        for r in runs
    ]
    return f"  {family} seed {seed} (c = {runs[0].cutoff:g}):\n    " + "\n    ".join(parts)


def _speed_line(
    family: str,
    forward: Mapping[int, RefinementRun],
    refined: Sequence[RefinementRun],
    mine: Sequence[RefinementRun],
) -> list[str]:
    """mapassoc's whole run (forward pass plus refinement) against Stone Soup's GNN."""
    gnn = {r.seed: r.seconds for r in mine if r.method == "ss_gnn"}
    whole = {r.seed: r.seconds + forward[r.seed].seconds for r in refined}
    seeds = [seed for seed in whole if seed in gnn]
    if not seeds:
        return []
    ours = float(np.mean([whole[s] for s in seeds]))
    theirs = float(np.mean([gnn[s] for s in seeds]))
    faster = sum(whole[s] <= gnn[s] for s in seeds)
    return [
        f"{family:14s} whole run {ours:.1f} s (forward + refinement) vs Stone Soup GNN "
        f"{theirs:.1f} s: ratio {ours / theirs:.2f} (goal <= 1; at least as fast in "
        f"{faster}/{len(seeds)} runs)"
    ]


def _print_summary(rows: list[RefinementRun], families: Sequence[str], say: object) -> None:
    header = (
        f"{'family':14s} {'method':8s} {'GOSPA':>7s} {'/oracle':>8s} {'loc':>6s} "
        f"{'miss':>7s} {'false':>7s} {'T-GOSPA':>8s} {'frag':>5s} {'idsw':>5s} "
        f"{'ids/tgt':>8s} {'seconds':>8s} {'J':>10s}"
    )
    lines = [
        "",
        "Means over seeds. Goals: refined GOSPA <= 1.2 x oracle and <= mht; refined "
        "T-GOSPA <= mht; ids/targets <= 1.15; refinement seconds <= forward seconds; "
        "J(refined) >= J(forward) in every run",
        header,
        "-" * len(header),
    ]
    for family in families:
        mine = [r for r in rows if r.family == family]
        oracle = float(np.mean([r.gospa for r in mine if r.method == "oracle"]))
        for method in METHODS:
            runs = [r for r in mine if r.method == method]
            if not runs:
                continue
            gospa = float(np.mean([r.gospa for r in runs]))
            ratio = gospa / oracle if oracle > 0 else math.nan
            lines.append(
                f"{family:14s} {method:8s} {gospa:7.3f} {ratio:8.2f} "
                f"{np.mean([r.localisation for r in runs]):6.2f} "
                f"{np.mean([r.missed for r in runs]):7.2f} "
                f"{np.mean([r.false for r in runs]):7.2f} "
                f"{np.mean([r.tgospa for r in runs]):8.1f} "
                f"{np.mean([r.fragments_per_target for r in runs]):5.2f} "
                f"{np.mean([r.id_switches for r in runs]):5.1f} "
                f"{np.mean([r.tracks / r.targets for r in runs]):8.2f} "
                f"{np.mean([r.seconds for r in runs]):8.1f} "
                f"{np.mean([r.objective for r in runs]):10.1f}"
            )
        forward = {r.seed: r for r in mine if r.method == "forward"}
        refined = [r for r in mine if r.method == "refined"]
        never_lower = all(r.objective >= forward[r.seed].objective - 1e-6 for r in refined)
        lines.append(
            f"{family:14s} J(refined) >= J(forward) in every run: {never_lower}; "
            "refinement / forward time: "
            f"{np.mean([r.seconds / forward[r.seed].seconds for r in refined]):.2f}"
        )
        lines.extend(_speed_line(family, forward, refined, mine))
    for line in lines:
        say(line)  # type: ignore[operator]
