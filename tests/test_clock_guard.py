"""The clock guard of ``tests/conftest.py`` fails a test whose result the wall clock changed.

Run in a pytest of its own (a subprocess) on a copy of the conftest, so the failing
test is that run's and not this suite's.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

PROBE = '''
import time

import numpy as np
import pytest
from dataclasses import replace

from support import NO_TIME_LIMIT

from mapassoc.estimator.cluster_solving import ClusterSolver
from mapassoc.estimator.pipeline import WindowEstimator
from mapassoc.evaluation.scenarios import build_scenario
from mapassoc.formulations.packing import PackingProblem
from mapassoc.solvers import HighsSolver


def window(time_limit):
    scenario = build_scenario("crossing", 0)
    config = scenario.config
    config = replace(config, estimator=replace(config.estimator, time_limit=time_limit))
    return WindowEstimator(config=config).solve_window(scenario.scans[:3])


def test_late_window_fails():
    assert window(1e-9).timed_out


@pytest.mark.clock_dependent
def test_late_window_marked_passes():
    assert window(1e-9).timed_out


def test_window_within_its_limit_passes():
    assert not window(NO_TIME_LIMIT).timed_out


def test_cluster_past_its_deadline_fails():
    n = 60
    problem = PackingProblem(
        np.full(n, 0.5), np.arange(0, 2 * n + 1, 2),
        np.array([r for i in range(n) for r in (i, i + 1)]),
        np.zeros(n + 1, bool), np.ones(n, bool),
    )
    solver = ClusterSolver(
        solver=HighsSolver(), exact_work_limit=1, beam_width=2, prune_log_ratio=float("inf")
    )
    _, report = solver.solve(problem, 3, deadline=time.perf_counter() - 1.0)
    assert report.status == "time_limit"
'''


@pytest.mark.slow
def test_clock_guard_fails_unmarked_tests_the_clock_changed(tmp_path: Path) -> None:
    tests = Path(__file__).resolve().parent
    for name in ("conftest.py", "support.py"):
        shutil.copy(tests / name, tmp_path / name)
    (tmp_path / "test_probe.py").write_text(textwrap.dedent(PROBE), encoding="utf-8")
    (tmp_path / "pytest.ini").write_text(
        "[pytest]\nmarkers =\n    clock_dependent: exempt from the clock guard\n",
        encoding="utf-8",
    )
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
         str(tmp_path)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    out = run.stdout + run.stderr
    assert run.returncode == 1, out
    assert "2 failed, 2 passed" in out, out
    assert "FAILED test_probe.py::test_late_window_fails" in out, out
    assert "FAILED test_probe.py::test_cluster_past_its_deadline_fails" in out, out
    assert "ran past its time_limit of 1e-09 s" in out, out
    assert "a cluster of 60 hypotheses ended with status time_limit" in out, out
    assert "mark the test clock_dependent" in out, out
