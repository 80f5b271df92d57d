"""Every notebook's code cells run top to bottom without error (they cannot rot), and
what they compute is what their text says.

The notebooks give their estimators a time limit no window reaches, so their numbers are
a function of the input alone; the clock guard of ``conftest.py`` fails a notebook whose
window ran past its limit (only windows solved in this process are watched, not those of
the process pools in ``reprocessing.ipynb``, which get the same time limit).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))


def test_there_is_a_notebook() -> None:
    assert NOTEBOOKS


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_code_cells_run(path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
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
    """What the notebook prints and claims: one run per (scenario, seed, tracker), all
    ok and all with tracks; one summary row per (scenario, tracker); the printed table
    is the summary's numbers; the oracle has the lowest GOSPA in every scenario; MAP and
    LP agree where the text says so; the per-scenario claims of the reading hold; the
    drawn tracks are the ones scored in the table."""
    import math

    import numpy as np

    from mapassoc.apps.compare import _FORMAT_COLUMNS

    table, summary = ns["table"], ns["summary"]
    names, scenarios, seeds = ns["TRACKER_NAMES"], list(ns["SCENARIOS"]), ns["SEEDS"]
    assert {"map", "gnn", "jpda", "flow", "oracle"} <= set(names)
    assert len(table) == len(scenarios) * len(seeds) * len(names)
    assert (table["status"] == "ok").all() and (table["num_tracks"] > 0).all()
    assert len(summary) == len(scenarios) * len(names)
    assert not summary.duplicated(["scenario", "tracker"]).any()
    assert (summary["runs"] == len(seeds)).all()

    # The printed table: every number is the summary's, at the printed precision.
    lines = ns["text"].splitlines()[2:]
    assert len(lines) == len(summary)
    for line, (_, row) in zip(lines, summary.iterrows(), strict=True):
        tokens = line.split()
        assert tokens[:3] == [row["scenario"], row["tracker"], str(int(row["runs"]))]
        for token, (column, _, fmt) in zip(tokens[3:], _FORMAT_COLUMNS, strict=True):
            value = row.get(column)
            if token == "-":
                assert value is None or math.isnan(value)
            else:
                decimals = int(fmt.split(".")[1][0])
                assert abs(float(token) - float(value)) <= 0.5 * 10.0**-decimals + 1e-12

    gospa = summary.set_index(["scenario", "tracker"])["gospa"].unstack("tracker")
    for family in scenarios:
        others = gospa.loc[family].drop("oracle")
        assert gospa.loc[family, "oracle"] < others.min()
        assert sorted(ns["best"][family]) == sorted(others.index[others == others.min()])

    per_scan = ns["per_scan"]
    ratio = per_scan["GOSPA / oracle"]
    missed = per_scan["missed targets / scan"]
    false = per_scan["false tracks / scan"]
    loc = summary.set_index(["scenario", "tracker"])["gospa_localisation"].unstack("tracker")
    assert ratio.loc["map", "crossing"] < 1.04 and ratio.loc["flow", "crossing"] < 1.07
    assert ratio.loc["map", "crossing"] == ratio.loc["map-forward", "crossing"]
    assert (false.loc[["gnn", "jpda", "mht"], "crossing"] > 0).all()
    assert false.loc["map", "crossing"] == 0
    assert loc.loc["crossing"].drop("oracle").idxmax() == "jpda"
    # dense: the refinement makes the MAP estimator the closest to the oracle.
    assert ratio["dense"].drop("oracle").idxmin() == "map"
    assert round(ratio.loc["map", "dense"], 2) == 1.11
    assert round(ratio.loc["mht", "dense"], 2) == 1.18
    assert round(ratio.loc["map-forward", "dense"], 2) == 2.63
    assert round(missed.loc["map-forward", "dense"], 2) == 0.33
    assert round(false.loc["map-forward", "dense"], 2) == 0.18
    assert round(missed.loc["map", "dense"], 2) == 0.03
    assert round(false.loc["map", "dense"], 2) == 0.02
    assert (missed.loc[["gnn", "jpda"], "dense"].round(2) == 0.47).all()
    assert (false.loc[["gnn", "jpda"], "dense"] == 0).all()
    assert (ratio["parallel"].drop("oracle") >= 4.5).all()
    assert missed["parallel"].drop("oracle").idxmin() == "jpda"
    assert loc.loc["parallel"].drop("oracle").idxmax() == "jpda"
    assert (missed.loc[["map", "gnn", "mht", "flow"], "parallel"] >= 0.75).all()
    assert round(ratio.loc["map-forward", "parallel"], 2) == 6.13
    assert round(ratio.loc["map", "parallel"], 2) == 5.68
    brier = summary.set_index(["scenario", "tracker"])["k_brier"]
    # parallel's bounded windows take p(K | Z) from LP bounds whose duals are not unique,
    # and which optimal duals HiGHS returns moves with the inputs' last bits: 1.573, 1.560
    # and 1.553 were seen with the same tracks and GOSPA (1.553 on a fresh machine and
    # install of 2026-12-03, the previous day's code included).  The notebook claims
    # "about 1.56".
    assert 1.54 <= brier[("parallel", "map")] <= 1.58
    assert round(brier[("crossing", "map")], 2) == 0.25
    switches = summary.set_index(["scenario", "tracker"])["id_switches"]
    assert switches[("parallel", "map-forward")] == 0.5
    assert (switches.drop(("parallel", "map-forward")) == 0).all()
    if "lp" in names:
        rows = summary.set_index(["scenario", "tracker"])
        for family in ("crossing", "dense"):
            for column in ("gospa", "gospa_localisation", "ospa2", "mota", "k_brier"):
                assert rows.loc[(family, "map-forward"), column] == rows.loc[(family, "lp"), column]
        forward, lp = rows.loc[("parallel", "map-forward")], rows.loc[("parallel", "lp")]
        assert forward["gospa"] != lp["gospa"]
    # Seconds are measured, not computed: only that every run has a time is checked (the
    # text's remarks on speed hold on this machine's printed table, not on every machine).
    assert (summary["seconds"] > 0).all() and np.isfinite(summary["seconds"]).all()

    # The drawn tracks are the table's seed-0 crossing runs.
    first = table[(table["scenario"] == "crossing") & (table["seed"] == 0)].set_index("tracker")
    for name, value in ns["replayed"].items():
        np.testing.assert_allclose(value, first.loc[name, "gospa"], rtol=0, atol=1e-9)


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
