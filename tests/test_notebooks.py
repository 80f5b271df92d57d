"""Every notebook's code cells run top to bottom without error (they cannot rot)."""

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


RESULT_CHECKS = {
    "window_posterior.ipynb": _check_window_posterior,
    "hard_window.ipynb": _check_hard_window,
    "k_estimates.ipynb": _check_k_estimates,
}
