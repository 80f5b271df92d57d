"""Every notebook's code cells run top to bottom without error (they cannot rot), and
what they compute is what their text says.

The notebooks give their estimators a time limit no window reaches, so their numbers are
a function of the input alone; the clock guard of ``conftest.py`` fails a notebook whose
window ran past its limit (only windows solved in this process are watched, not those of
the process pools in ``reprocessing.ipynb``, which get the same time limit).

``compare_methods.ipynb`` runs every method on full-length scenarios, minutes of work; the
suite runs it with ``MAPASSOC_NOTEBOOK_QUICK=1`` (a few scans, one seed) and checks what
the short run computes, and checks the text's numbers against the notebook's *stored*
outputs, a machine-readable record its run printed, one (scenario, seed) of which it
re-runs at full length: stored outputs of another run (older code, other seeds, the quick
version) fail.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    import pandas as pd

NOTEBOOKS = sorted((Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))
QUICK = "MAPASSOC_NOTEBOOK_QUICK"
"""Environment variable the notebooks read: ``1`` runs their short version."""


def test_there_is_a_notebook() -> None:
    assert NOTEBOOKS


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_code_cells_run(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import matplotlib

    matplotlib.use("Agg")
    monkeypatch.setenv(QUICK, "1")
    notebook = json.loads(path.read_text(encoding="utf-8"))
    namespace: dict[str, object] = {"__name__": "__notebook__"}
    for index, cell in enumerate(notebook["cells"]):
        if cell["cell_type"] != "code":
            continue
        source = "".join(cell["source"])
        exec(compile(source, f"{path.name}[cell {index}]", "exec"), namespace)  # noqa: S102
    check = RESULT_CHECKS.get(path.name)
    assert check is not None, f"{path.name}: add a check of what the notebook computes"
    check(namespace)


def _check_window_posterior(ns: dict) -> None:  # type: ignore[type-arg]
    """What the notebook shows is right: p(K | Z) per window sums to 1, the plotted
    marginal K is its argmax, it matches the targets present in most windows, and the
    printed track set has the committed number of tracks."""
    import numpy as np

    P, marginal, truth = ns["P"], ns["marginal"], ns["truth_count"]
    np.testing.assert_allclose(P.sum(axis=0), 1.0, atol=1e-9)
    assert np.array_equal(np.argmax(P, axis=0), marginal)
    assert np.mean(marginal == truth) >= 0.8
    window = ns["window"]
    assert len(ns["chosen"]) == window.posterior.marginal_tracks


def _check_hard_window(ns: dict) -> None:  # type: ignore[type-arg]
    """The hard window's posterior is a distribution whose argmax is the printed marginal
    K, the k best sets come in order of score, and the best of them is the window's own
    selection (the exact per-T optimum the notebook says it is)."""
    import numpy as np

    post, report = ns["post"], ns["report"]
    np.testing.assert_allclose(post.probabilities.sum(), 1.0, atol=1e-9)
    assert post.marginal_k == int(np.argmax(post.probabilities))
    assert report.marginal_k == int(np.argmax(report.p_k))
    scores = ns["scores"]
    assert scores.size == 5 and np.all(np.diff(scores) <= 1e-9)
    best = ns["decode_selection"](ns["best_sets"][0].solution)
    assert sorted(best.tolist()) == sorted(np.asarray(ns["chosen"]).tolist())


def _check_k_estimates(ns: dict) -> None:  # type: ignore[type-arg]
    """What the notebook's text claims from its table: for every prior, windows of the
    longest length find the true K more often, and score a lower Brier, than one-scan
    windows; rates are fractions and Brier scores lie in [0, 2]."""
    summary, priors = ns["summary"], ns["PRIORS"]
    one, longest = ns["one_scan"], ns["longest"]
    assert ((summary["marginal_hit"] >= 0) & (summary["marginal_hit"] <= 1)).all()
    assert ((summary["brier"] >= 0) & (summary["brier"] <= 2)).all()
    for prior in priors:
        assert longest.loc[prior, "marginal_hit"] > one.loc[prior, "marginal_hit"]
        assert longest.loc[prior, "joint_hit"] > one.loc[prior, "joint_hit"]
        assert longest.loc[prior, "brier"] < one.loc[prior, "brier"]


def _check_solver_comparison(ns: dict) -> None:  # type: ignore[type-arg]
    """What the notebook's text claims: every ILP is optimal and equals enumeration
    wherever both ran (1e-9) and the frontier search on exact windows; the LP (simplex
    and Clarabel) is >= the ILP everywhere; the relaxation is tight on the crossing and
    dense windows and not on the parallel ones; Clarabel's fractional points with an
    integral simplex vertex are ties (gap 0); the flow's cost is convex, its chosen set
    scored by the Kalman model is no better than the ILP optimum for its K, and equals
    it where the text says so; the tracks' true origins are as the text describes them
    (the flow's extra paths, the hops on parallel, the swap at the crossing)."""
    import numpy as np

    results, windows = ns["results"], ns["windows"]
    assert len(results) == len(windows) * len(ns["T_VALUES"])
    assert (results["ilp_status"] == "optimal").all()
    assert (results["lp_simplex"] >= results["ilp"] - 1e-7).all()
    assert (results["lp_clarabel"] >= results["ilp"] - 1e-7).all()
    np.testing.assert_allclose(results["lp_clarabel"], results["lp_simplex"], atol=1e-5)
    share = results["simplex_integral"].mean()
    assert 0.5 < share < 1.0
    tight = results["window"].str.startswith(("crossing", "dense"))
    assert results.loc[tight, "gap"].abs().max() <= 1e-7
    assert results.loc[tight, "simplex_integral"].all()
    assert (results.loc[~tight].groupby("window")["gap"].max() > 1e-3).all()
    # A fractional simplex vertex exactly where the LP is not tight.
    assert ((results["gap"] > 1e-7) == ~results["simplex_integral"]).all()
    ties = results[results["simplex_integral"] & ~results["clarabel_integral"]]
    assert len(ties) > 0 and ties["gap"].abs().max() <= 1e-7
    exact = results["window"].map(lambda n: windows[n][2].status == "exact")
    np.testing.assert_allclose(
        results.loc[exact, "ilp"], results.loc[exact, "table_best"], atol=1e-9
    )
    assert (results["ilp"] <= results["table_upper"] + 1e-7).all()
    finite = np.isfinite(results["table_best"])
    assert (results.loc[finite, "ilp"] >= results.loc[finite, "table_best"] - 1e-7).all()

    enum_table = ns["enum_table"]
    assert len(enum_table) > 100
    assert (enum_table["enum_status"] == enum_table["ilp_status"]).all()
    both = enum_table[enum_table["enum_status"] == "optimal"]
    assert len(both) > 100
    np.testing.assert_allclose(both["ilp"], both["enumeration"], atol=1e-9, rtol=0)

    flow = ns["flow_table"]
    assert flow["flow_convex"].all() and flow["ilp_concave"].all()
    assert (flow["flow_K"] >= 1).all()
    kalman = flow["flow_set_kalman"].dropna()
    assert (kalman <= flow.loc[kalman.index, "ilp_best_at_flow_K"] + 1e-9).all()
    for name in ("crossing@0", "crossing@28", "dense@10"):
        assert abs(flow.loc[name, "flow_set_kalman"] - flow.loc[name, "ilp_best_at_flow_K"]) < 1e-9
        assert flow.loc[name, "flow_K"] == flow.loc[name, "map_joint_T"]
        assert flow.loc[name, "max_flow_minus_ilp"] < 0
    for name in ("parallel@20", "parallel@30"):
        assert flow.loc[name, "flow_K"] == flow.loc[name, "map_joint_T"] + 1
        assert np.isnan(flow.loc[name, "flow_set_kalman"])
    assert flow.loc["parallel@30", "max_flow_minus_ilp"] > 0
    for name in ("crossing@0", "crossing@28", "dense@10"):
        assert flow.loc[name, "shared_with_map"] == flow.loc[name, "flow_K"]
    assert flow.loc["parallel@20", "shared_with_map"] == 4
    assert flow.loc["crossing@0", "flow_K"] < flow.loc["crossing@0", "targets"]
    assert flow.loc["dense@10", "flow_K"] < flow.loc["dense@10", "targets"]

    origins = ns["track_origins"]
    extra = origins[(origins["method"] == "flow") & ~origins["hypothesis"]]
    assert extra.groupby("window").size().to_dict() == {"parallel@20": 1, "parallel@30": 1}
    assert extra.set_index("window").loc["parallel@20", "false_alarms_only"]
    assert set(extra.set_index("window").loc["parallel@30", "origins"]) == {-1, 3, 4}
    hop = origins[(origins["window"] == "parallel@20")]
    assert not hop["one_target"].any()
    swapped = origins[origins["window"] == "crossing@28"]["origins"].map(tuple)
    assert swapped.value_counts()[(4, 4, 3, 4, 4)] == 2  # MAP and flow


def _check_compare_methods(ns: dict) -> None:  # type: ignore[type-arg]
    """The short run (``MAPASSOC_NOTEBOOK_QUICK=1``) computes what the full one does: one
    run per (scenario, seed, tracker), all ok and all with tracks; one summary row per
    (scenario, tracker); the printed table is the summary's numbers; the oracle's GOSPA
    is the lowest in every scenario (ties allowed on a few scans); the record line is the
    table; the drawn tracks are the ones scored in the table.  The numbers the text quotes
    are checked against the stored full-length run (``test_compare_methods_stored_run``)."""
    import numpy as np

    assert ns["QUICK"] is True  # the notebook read the switch
    table, summary = ns["table"], ns["summary"]
    names, scenarios, seeds = ns["TRACKER_NAMES"], list(ns["SCENARIOS"]), ns["SEEDS"]
    assert {"map", "gnn", "jpda", "flow", "oracle"} <= set(names)
    assert len(table) == len(scenarios) * len(seeds) * len(names)
    assert (table["status"] == "ok").all() and (table["num_tracks"] > 0).all()
    assert len(summary) == len(scenarios) * len(names)
    assert not summary.duplicated(["scenario", "tracker"]).any()
    assert (summary["runs"] == len(seeds)).all()
    _check_printed_table(ns["text"], summary, with_seconds=True)

    gospa = summary.set_index(["scenario", "tracker"])["gospa"].unstack("tracker")
    for family in scenarios:
        others = gospa.loc[family].drop("oracle")
        assert gospa.loc[family, "oracle"] <= others.min() + 1e-12
        assert sorted(ns["best"][family]) == sorted(others.index[others == others.min()])
    # Seconds are measured, not computed: only that every run has a time is checked.
    assert (summary["seconds"] > 0).all() and np.isfinite(summary["seconds"]).all()

    # The record line is the table, row for row.
    runs = ns["record"]["runs"]
    assert len(runs) == len(table)
    for run, (_, row) in zip(runs, table.iterrows(), strict=True):
        assert (run["scenario"], run["seed"], run["tracker"]) == (
            row["scenario"], row["seed"], row["tracker"]
        )
        assert run["gospa"] == row["gospa"] and run["tgospa"] == row["tgospa"]

    # The drawn tracks are the table's seed-0 crossing runs.
    first = table[(table["scenario"] == "crossing") & (table["seed"] == 0)].set_index("tracker")
    for name, value in ns["replayed"].items():
        np.testing.assert_allclose(value, first.loc[name, "gospa"], rtol=0, atol=1e-9)


def _check_printed_table(text: str, summary: pd.DataFrame, *, with_seconds: bool) -> None:
    """Every number of ``format_summary``'s table ``text`` is ``summary``'s, at the
    printed precision (``seconds`` only when ``with_seconds``: a stored run's times are
    not recomputed)."""
    from mapassoc.apps.compare import _FORMAT_COLUMNS

    lines = text.strip("\n").splitlines()[2:]
    assert len(lines) == len(summary)
    for line, (_, row) in zip(lines, summary.iterrows(), strict=True):
        tokens = line.split()
        assert tokens[:3] == [row["scenario"], row["tracker"], str(int(row["runs"]))]
        for token, (column, _, fmt) in zip(tokens[3:], _FORMAT_COLUMNS, strict=True):
            if column == "seconds" and not with_seconds:
                continue
            value = row.get(column)
            if token == "-":
                assert value is None or math.isnan(value), (line, column)
            else:
                decimals = int(fmt.split(".")[1][0])
                assert abs(float(token) - float(value)) <= 0.5 * 10.0**-decimals + 1e-12, (
                    line, column
                )


def _stored_output(notebook: dict, marker: str) -> str:  # type: ignore[type-arg]
    """The stored stream output of the one code cell whose source contains ``marker``."""
    cells = [
        c for c in notebook["cells"] if c["cell_type"] == "code" and marker in "".join(c["source"])
    ]
    assert len(cells) == 1, f"{len(cells)} code cells contain {marker!r}"
    streams = [o for o in cells[0].get("outputs", []) if o.get("output_type") == "stream"]
    assert streams, f"the cell with {marker!r} has no stored output: run `make notebooks`"
    return "".join("".join(o["text"]) for o in streams)


RECORD_PREFIX = "compare-record: "


@pytest.mark.slow
def test_compare_methods_stored_run() -> None:
    """The stored outputs of ``compare_methods.ipynb`` are a full-length run of this code,
    and what its text says is what they show.

    The record line its run printed (every run's scores, full precision) must name every
    scenario at its native length and five seeds; the stored printed table must be the
    means of those runs; one run, ``crossing`` seed 0 with ``map`` and ``oracle`` at full
    length, is re-run here and must give the recorded scores (1e-9): stored outputs of an
    older version, another scenario length or seed fail.  Then the claims of the text's
    "Reading the results" are checked on the recorded means."""
    import numpy as np
    import pandas as pd

    from mapassoc.apps.compare import compare
    from mapassoc.evaluation.scenarios import native_scan_count

    path = next(p for p in NOTEBOOKS if p.name == "compare_methods.ipynb")
    notebook = json.loads(path.read_text(encoding="utf-8"))
    lines = [
        line for line in _stored_output(notebook, "RECORD_COLUMNS").splitlines()
        if line.startswith(RECORD_PREFIX)
    ]
    assert len(lines) == 1
    record = json.loads(lines[0][len(RECORD_PREFIX) :])
    families = ("crossing", "dense", "parallel")
    assert record["scans"] == {f: native_scan_count(f) for f in families}
    assert record["seeds"] == [0, 1, 2, 3, 4]
    runs = pd.DataFrame(record["runs"])
    assert len(runs) == len(families) * len(record["seeds"]) * len(record["trackers"])
    columns = [c for c in runs.columns if c not in ("scenario", "seed", "tracker")]
    means = runs.groupby(["scenario", "tracker"], sort=False)[columns].mean().reset_index()
    means.insert(2, "runs", len(record["seeds"]))
    stored_table = _stored_output(notebook, "format_summary(summary)")
    _check_printed_table(
        stored_table[stored_table.index("scenario ") :], means, with_seconds=False
    )

    again = compare(
        ["map", "oracle"], ["crossing"], [0], scans=record["scans"]["crossing"],
        time_limit=600.0,
    ).set_index("tracker")  # fmt: skip
    stored = runs[(runs["scenario"] == "crossing") & (runs["seed"] == 0)].set_index("tracker")
    for name in ("map", "oracle"):
        for column in ("gospa", "ospa2", "tgospa", "fragments_per_target"):
            np.testing.assert_allclose(
                again.loc[name, column], stored.loc[name, column], rtol=0, atol=1e-9,
                err_msg=f"crossing seed 0 {name} {column}: re-run the notebook",
            )  # fmt: skip
    _check_compare_claims(means.set_index(["scenario", "tracker"]).drop(columns="runs"), runs)


def _check_compare_claims(means: pd.DataFrame, runs: pd.DataFrame) -> None:
    """The claims of compare_methods' text, on the stored run: ``means`` per (scenario,
    tracker) over the seeds, ``runs`` one row per (scenario, seed, tracker)."""
    mean_gospa = means["gospa"].unstack("scenario")
    ratio = mean_gospa / mean_gospa.loc["oracle"]
    missed = (means["gospa_missed"] / 50).unstack("scenario")
    false = (means["gospa_false"] / 50).unstack("scenario")
    unstack = {name: means[name].unstack("scenario") for name in means.columns}
    gospa = runs.pivot_table(index=["scenario", "seed"], columns="tracker", values="gospa")
    methods = gospa.drop(columns="oracle")

    def quoted(table: pd.DataFrame, decimals: int, expected: dict[str, dict[str, float]]) -> None:
        for family, values in expected.items():
            for name, value in values.items():
                assert round(table.loc[name, family], decimals) == value, (family, name)

    # The oracle's mean is the lowest everywhere, but not every run's.
    for family in ("crossing", "dense", "parallel"):
        assert ratio[family].drop("oracle").min() > 1.0
    lower = gospa["map"] - gospa["oracle"]
    assert round(gospa.loc[("crossing", 1), "map"], 2) == 0.78
    assert round(gospa.loc[("crossing", 1), "oracle"], 2) == 0.81
    assert round(gospa.loc[("parallel", 3), "map"], 2) == 1.07
    assert round(gospa.loc[("parallel", 3), "oracle"], 2) == 1.08
    assert round(lower[("dense", 3)], 3) == -0.007
    quoted(ratio, 2, {
        "crossing": {"map-forward": 1.24, "flow": 1.24, "lp": 1.25, "mht": 1.46, "gnn": 1.59,
                     "jpda": 2.32},
        "dense": {"mht": 1.28, "map-forward": 1.53, "lp": 1.53, "gnn": 1.83, "jpda": 2.36,
                  "flow": 2.14},
        "parallel": {"mht": 2.83, "map": 2.88, "flow": 3.69, "gnn": 4.02, "map-forward": 4.14,
                     "lp": 4.28, "jpda": 5.38},
    })  # fmt: skip
    assert round(ratio.loc["map", "crossing"], 3) == 1.003
    assert round(ratio.loc["map", "dense"], 3) == 1.017
    # The order of the means on parallel, as the text lists it.
    order = ["mht", "map", "flow", "gnn", "map-forward", "lp", "jpda"]
    assert ratio["parallel"].drop("oracle").sort_values().index.tolist() == order
    assert ratio["parallel"].drop("oracle").min() >= 2.8
    # The MAP estimator: the oracle's missed targets and no false track on crossing and
    # dense; the missed targets on parallel.
    for family in ("crossing", "dense"):
        assert missed.loc["map", family] == missed.loc["oracle", family]
        assert false.loc["map", family] == 0
    assert round(missed.loc["map", "crossing"], 3) == 0.023
    assert round(missed.loc["map", "dense"], 2) == 0.07
    assert round(missed.loc["map-forward", "dense"], 2) == 0.16
    assert round(false.loc["map-forward", "dense"], 2) == 0.04
    assert (missed.loc[["gnn", "jpda"], "dense"].round(2) == 0.25).all()
    assert round(missed.loc["map", "parallel"], 3) == 0.300
    assert round(missed.loc["oracle", "parallel"], 3) == 0.045
    parts = means[["gospa_localisation", "gospa_missed", "gospa_false"]]
    assert (parts.loc["parallel"].drop("oracle").idxmax(axis=1) == "gospa_missed").all()
    # JPDA's localisation part is the largest in every scenario.
    localisation = unstack["gospa_localisation"]
    assert (localisation.idxmax() == "jpda").all()
    assert round(localisation.loc["jpda", "crossing"], 2) == 2.78
    assert round(localisation.loc["map", "crossing"], 2) == 0.66
    # Per seed: the lowest of the methods.
    best = methods.eq(methods.min(axis=1), axis=0)
    assert best.loc[["crossing", "dense"], "map"].sum() == 9
    assert not best.loc[("crossing", 2), "map"] and best.loc[("crossing", 2), "mht"]
    assert round(methods.loc[("crossing", 2), "mht"], 2) == 0.93
    assert round(methods.loc[("crossing", 2), "map"], 2) == 0.94
    winners = methods.loc["parallel"].idxmin(axis=1).to_dict()
    assert winners == {0: "gnn", 1: "map", 2: "mht", 3: "map", 4: "map"}
    assert round(methods.loc["parallel", "map"].min(), 2) == 1.07
    assert round(methods.loc["parallel", "map"].max(), 2) == 4.69
    assert round(gospa.loc["parallel", "oracle"].min(), 2) == 0.65
    assert round(gospa.loc["parallel", "oracle"].max(), 2) == 1.18
    # Whole trajectories.
    ospa2 = unstack["ospa2"]
    assert (ospa2.drop("oracle").idxmin() == "map").all()
    quoted(ospa2, 2, {
        "crossing": {"map": 0.47, "oracle": 0.46},
        "dense": {"map": 0.47, "oracle": 0.46},
        "parallel": {"map": 1.94, "oracle": 0.43, "jpda": 3.17, "flow": 3.17},
    })  # fmt: skip
    assert ospa2["parallel"].drop(["oracle", "map"]).nsmallest(2).index.tolist() in (
        ["jpda", "flow"], ["flow", "jpda"]
    )
    # Identity.
    fragments = runs.pivot_table(
        index=["scenario", "seed"], columns="tracker", values="fragments_per_target"
    )
    whole = (fragments.loc[["crossing", "dense"]] == 1.0).all()
    assert whole["map"] and whole["oracle"]
    per_family = (fragments == 1.0).groupby(level="scenario").all()
    assert per_family.loc["crossing"].drop(["map", "oracle"]).tolist().count(True) == 1
    assert per_family.loc["crossing", "jpda"]
    assert not per_family.loc["dense"].drop(["map", "oracle"]).any()
    frag = unstack["fragments_per_target"]
    assert frag["parallel"].drop("oracle").idxmin() == "map"
    assert round(frag.loc["map", "parallel"], 2) == 1.08
    assert frag["parallel"].idxmax() == "gnn" and round(frag.loc["gnn", "parallel"], 2) == 1.40
    tgospa = unstack["tgospa"]
    for family in ("crossing", "dense", "parallel"):
        assert tgospa[family].drop("oracle").idxmin() == "map"
    assert tgospa["parallel"].drop(["oracle", "map"]).idxmin() == "mht"
    quoted(tgospa, 2, {
        "crossing": {"map": 10.26, "oracle": 10.20},
        "dense": {"map": 17.22, "oracle": 17.11},
        "parallel": {"mht": 26.52, "map": 24.23, "oracle": 10.18},
    })  # fmt: skip
    # Existence: only the MAP estimator reports it; its P-GOSPA is above its GOSPA.
    pgospa = unstack["pgospa"]
    quoted(pgospa, 2, {
        "crossing": {"map": 0.93}, "dense": {"map": 2.27}, "parallel": {"map": 5.53}
    })  # fmt: skip
    assert (pgospa.drop("map") - mean_gospa.drop("map")).abs().max().max() < 1e-9
    assert (pgospa.loc["map"] > mean_gospa.loc["map"]).all()
    switches = unstack["id_switches"]
    assert round(switches.max().max(), 2) == 1.4
    # The posterior over K.
    quoted(unstack["k_brier"], 3, {
        "crossing": {"map": 0.230}, "dense": {"map": 0.385}, "parallel": {"map": 0.620}
    })  # fmt: skip
    # LP and the forward pass: equal on every dense run, on four crossing and two
    # parallel ones.
    scores = [c for c in runs.columns if c not in ("scenario", "seed", "tracker")]
    lp = runs[runs["tracker"] == "lp"].set_index(["scenario", "seed"])[scores]
    forward = runs[runs["tracker"] == "map-forward"].set_index(["scenario", "seed"])[scores]
    same = ((lp == forward) | (lp.isna() & forward.isna())).all(axis=1)
    assert same.loc["dense"].all()
    assert same.loc["crossing"].tolist() == [True, True, True, False, True]
    assert same.loc["parallel"].tolist() == [False, False, False, True, True]
    assert round(gospa.loc[("crossing", 3), "lp"], 2) == 1.28
    assert round(gospa.loc[("crossing", 3), "map-forward"], 2) == 1.22


def _check_reprocessing(ns: dict) -> None:  # type: ignore[type-arg]
    """The frame gives the simulated scans; the continued run equals the whole one; the
    stitched segments are the sequential run's tracks; the broken recording alone fails."""
    assert ns["same"] is True
    assert ns["continued"].track_rows == ns["whole"].track_rows
    assert len(ns["same_tracks"]) >= 0.95 * len(ns["sequential"].track_rows)
    assert abs(ns["gospa"]["segmented"] - ns["gospa"]["sequential"]) <= 0.02 * ns["gospa"][
        "sequential"
    ]
    status = dict(zip(ns["summary"]["name"], ns["summary"]["status"], strict=True))
    assert status == {"broken": "failed", "north": "complete", "south": "complete"}


RESULT_CHECKS = {
    "reprocessing.ipynb": _check_reprocessing,
    "compare_methods.ipynb": _check_compare_methods,
    "window_posterior.ipynb": _check_window_posterior,
    "hard_window.ipynb": _check_hard_window,
    "k_estimates.ipynb": _check_k_estimates,
    "solver_comparison.ipynb": _check_solver_comparison,
}
