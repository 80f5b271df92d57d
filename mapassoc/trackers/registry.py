"""Tracking methods by name: one table, :data:`TRACKERS`.

Each row names a method, the module and class that implement it (imported only when the
tracker is built) and whether it needs the true associations (the oracle).  Every class
is built as ``cls(config=config, **options)`` (plus ``origins=`` for the oracle), so every
method runs on exactly the same motion, sensor, clutter and birth models; ``options`` is
the configuration's ``[trackers.<name>]`` table (``Config.trackers[name]``), checked
against the class's own keyword options (:meth:`TrackerSpec.option_names`: its
keyword-only parameters whose type is a number, a boolean or a string).  Adding a
method, with options of its own, is one module with a class implementing
:class:`~mapassoc.trackers.base.Tracker` and one row here.

===============  ============================================  =====================================
name             class                                         method
===============  ============================================  =====================================
``map``          :class:`~.map_estimator.MapTracker`           sliding-window MAP sets, p(K | Z),
                                                               refined over the recording
``map-forward``  :class:`~.map_estimator.MapForwardTracker`    the forward pass alone
``gnn``          :class:`~.gnn.GnnTracker`                     global nearest neighbour (2-D
                                                               assignment)
``jpda``         :class:`~.jpda.JpdaTracker`                   joint probabilistic data association
``mht``          :class:`~.mht.MhtTracker`                     track-oriented MHT, N-scan pruning
``flow``         :class:`~.flow.FlowTracker`                   min-cost network flow over a window
``lp``           :class:`~.lp_relaxation.LpRelaxationTracker`  LP relaxation of the MAP program
``oracle``       :class:`~.oracle.OracleTracker`               smoother on the true associations
===============  ============================================  =====================================
"""

from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mapassoc.errors import InputError

if TYPE_CHECKING:  # the table is read by the command line's parser: keep it light
    from mapassoc.data.config import Config
    from mapassoc.data.io import Origins
    from mapassoc.trackers.base import Tracker

__all__ = ["DEFAULT_TRACKERS", "TRACKERS", "TrackerSpec", "build_tracker", "tracker_names"]


@dataclass(frozen=True)
class TrackerSpec:
    """One row of :data:`TRACKERS`.

    Parameters
    ----------
    name : str
    module, class_name : str
        Where the tracker class lives; imported by :meth:`build` only.
    description : str
        One line for listings.
    needs_truth : bool
        Whether the tracker needs the true origins of the detections (simulated data).
    """

    name: str
    module: str
    class_name: str
    description: str
    needs_truth: bool = False

    def tracker_class(self) -> type:
        """The class of the row (imports its module)."""
        cls: type = getattr(importlib.import_module(self.module), self.class_name)
        return cls

    def option_names(self) -> tuple[str, ...]:
        """The options a ``[trackers.<name>]`` table may set: the class's keyword-only
        parameters (besides ``config``, ``origins`` and ``name``) annotated with numbers,
        booleans, strings or ``None`` only (a management rule object, say, is not)."""
        parameters = inspect.signature(self.tracker_class()).parameters.values()
        return tuple(
            p.name
            for p in parameters
            if p.kind is inspect.Parameter.KEYWORD_ONLY
            and p.name not in _NOT_OPTIONS
            and _is_scalar_annotation(p.annotation)
        )

    def build(self, *, config: Config, origins: Origins | None = None) -> Tracker:
        """The tracker on ``config``, with the options of its ``[trackers.<name>]`` table.

        Raises
        ------
        InputError
            An option the class does not take (the message lists those it takes), an
            option value the class refuses (key ``trackers.<name>.<option>`` where the
            class names the option), or the oracle without ``origins``.
        """
        cls = self.tracker_class()
        # Anything but a Config has no tables: the class then says what it expected.
        tables = getattr(config, "trackers", None)
        options: dict[str, object] = dict(tables.get(self.name, {})) if tables else {}
        if options:
            allowed = self.option_names()
            for option in options:
                if option not in allowed:
                    raise InputError(
                        f"trackers.{self.name}: unknown option {option!r}; options of "
                        f"'{self.name}': {', '.join(allowed) or '(none)'}",
                        key=f"trackers.{self.name}.{option}",
                    )
        if self.needs_truth:
            if origins is None:
                raise InputError(
                    f"tracker '{self.name}' needs the true origins of the detections "
                    "(simulated data); none were given"
                )
            options["origins"] = origins
        try:
            tracker: Tracker = cls(config=config, **options)
        except InputError as exc:
            # A refusal of one of the table's options names its key; any other error
            # (the configuration itself, say) stays as the class raised it.
            named = [o for o in options if o != "origins" and o in str(exc)]
            if not named:
                raise
            raise InputError(
                f"trackers.{self.name}: {exc}", key=f"trackers.{self.name}.{named[0]}"
            ) from None
        return tracker


_NOT_OPTIONS = frozenset({"config", "origins", "name"})
_SCALAR_TYPES = frozenset({"int", "float", "bool", "str", "None"})


def _is_scalar_annotation(annotation: object) -> bool:
    """Whether a parameter's annotation (a string under ``from __future__ import
    annotations``) is a union of int, float, bool, str and None."""
    text = annotation if isinstance(annotation, str) else getattr(annotation, "__name__", "")
    parts = [part.strip() for part in str(text).split("|")]
    return bool(parts) and all(part in _SCALAR_TYPES for part in parts)


TRACKERS: dict[str, TrackerSpec] = {
    spec.name: spec
    for spec in (
        TrackerSpec(
            "map",
            "mapassoc.trackers.map_estimator",
            "MapTracker",
            "sliding-window MAP track sets with the posterior over K (this library)",
        ),
        TrackerSpec(
            "map-forward",
            "mapassoc.trackers.map_estimator",
            "MapForwardTracker",
            "the MAP estimator's forward pass alone (no refinement of the whole recording)",
        ),
        TrackerSpec(
            "gnn",
            "mapassoc.trackers.gnn",
            "GnnTracker",
            "global nearest neighbour: 2-D assignment per scan, score-based track management",
        ),
        TrackerSpec(
            "jpda",
            "mapassoc.trackers.jpda",
            "JpdaTracker",
            "joint probabilistic data association, exact marginals per cluster",
        ),
        TrackerSpec(
            "mht",
            "mapassoc.trackers.mht",
            "MhtTracker",
            "track-oriented MHT: hypothesis trees, N-scan pruning, set-packing global hypothesis",
        ),
        TrackerSpec(
            "flow",
            "mapassoc.trackers.flow",
            "FlowTracker",
            "min-cost network flow over detections, every number of tracks in one pass",
        ),
        TrackerSpec(
            "lp",
            "mapassoc.trackers.lp_relaxation",
            "LpRelaxationTracker",
            "LP relaxation of the MAP program (cvxpy + Clarabel) with integrality certificates",
        ),
        TrackerSpec(
            "oracle",
            "mapassoc.trackers.oracle",
            "OracleTracker",
            "Kalman smoother on the true associations (simulated data only)",
            needs_truth=True,
        ),
    )
}
"""Every tracking method by name (the table of the module docstring)."""


DEFAULT_TRACKERS: tuple[str, ...] = (
    "map",
    "map-forward",
    "gnn",
    "jpda",
    "mht",
    "flow",
    "lp",
    "oracle",
)
"""The methods ``mapassoc compare`` runs when none are named."""


def tracker_names() -> list[str]:
    """Names of every tracker, in table order."""
    return list(TRACKERS)


def build_tracker(name: str, *, config: Config, origins: Origins | None = None) -> Tracker:
    """Build the tracker ``name`` with the options of the configuration's
    ``[trackers.<name>]`` table (its defaults for the rest).

    Raises
    ------
    InputError
        Unknown name (the message lists the known ones), an option the tracker does not
        take or refuses (:meth:`TrackerSpec.build`), or the oracle without origins.
    """
    spec = TRACKERS.get(name)
    if spec is None:
        raise InputError(f"unknown tracker {name!r}; known trackers: {', '.join(TRACKERS)}")
    return spec.build(config=config, origins=origins)
