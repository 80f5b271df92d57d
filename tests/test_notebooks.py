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


RESULT_CHECKS = {"window_posterior.ipynb": _check_window_posterior}
