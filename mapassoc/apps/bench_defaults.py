"""The benchmark's default families and priors, in a module that imports nothing else.

``mapassoc.apps.bench`` runs them and ``mapassoc.apps.cli`` shows them in its help;
keeping them here lets the command line build its parser without importing the
estimator.
"""

from __future__ import annotations

__all__ = [
    "DEFAULT_FAMILIES",
    "DEFAULT_K_PRIORS",
    "DEFAULT_PARAMETER_FAMILIES",
    "DEFAULT_REFINEMENT_FAMILIES",
]

#: Families run by default, in this order.
DEFAULT_FAMILIES: tuple[str, ...] = (
    "crossing",
    "parallel",
    "dense_pd08",
    "scale20",
    "scale50",
    "scale100",
    "burst",
    "dense",
    "dense50",
)
#: Priors compared by default, in this order (the first is the one the goals judge).
DEFAULT_K_PRIORS: tuple[str, ...] = ("birth", "uniform")

DEFAULT_PARAMETER_FAMILIES = ("crossing", "parallel", "dense_pd08", "dense", "scale20", "burst")
"""Families of ``mapassoc bench-parameters`` (one sensor each): sparse and dense clutter,
closely spaced lanes, low Pd, many targets, and a clutter burst (a rate that is not
constant, where "true" is only the background rate)."""

DEFAULT_REFINEMENT_FAMILIES = (
    "converging",
    "meeting",
    "parallel",
    "parallel_pd08",
    "dense_pd08",
    "dense_radar",
    "staggered",
    "crossing",
    "aircraft",
    "ships",
    "crossing_turns",
    "converging_turns",
)
"""Families of ``mapassoc bench-refinement``, as hard as users' data: targets that converge
and travel closely spaced at Pd 0.7 in clutter, four targets meeting at one point,
parallel lanes (at Pd 0.9 and 0.8), Pd 0.8 among dense clutter, births and deaths
throughout, crossing pairs, and targets that manoeuvre (aircraft-like turns and speed
changes, ship-like slow turners, crossings in a turn, merges onto one track:
:mod:`mapassoc.evaluation.manoeuvres`)."""
