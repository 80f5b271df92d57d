"""The benchmark's default families and priors, in a module that imports nothing else.

``mapassoc.apps.bench`` runs them and ``mapassoc.apps.cli`` shows them in its help;
keeping them here lets the command line build its parser without importing the
estimator.
"""

from __future__ import annotations

__all__ = ["DEFAULT_FAMILIES", "DEFAULT_K_PRIORS", "DEFAULT_PARAMETER_FAMILIES"]

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
