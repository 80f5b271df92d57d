"""mapassoc: MAP multi-target track-set estimation by optimization.

The objects a notebook needs are importable from the package itself::

    import mapassoc as ma

    scenario = ma.build_scenario("crossing", seed=0)
    result = ma.WindowEstimator(config=scenario.config).run(scenario.scans)
    ma.evaluate_tables(scenario.truth, result.tracks)

They are loaded on first use (PEP 562), so ``import mapassoc`` and the command line
stay fast; ``_EXPORTS`` says which module defines each.  (A function named like its
module, ``mapassoc.simulate.simulate``, is not exported: importing the module would
replace the package attribute.)
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

_EXPORTS: dict[str, str] = {
    # configuration and models
    "Config": "mapassoc.config",
    "load_config": "mapassoc.config",
    "parse_config": "mapassoc.config",
    "BirthModel": "mapassoc.settings",
    "EstimatorSettings": "mapassoc.settings",
    "ConstantVelocity": "mapassoc.motion",
    "ConstantAcceleration": "mapassoc.motion",
    "RandomWalk": "mapassoc.motion",
    "CoordinatedTurn": "mapassoc.motion",
    "Singer": "mapassoc.motion",
    "LinearMeasurement": "mapassoc.measurement",
    "RangeBearing": "mapassoc.measurement",
    "Sensor": "mapassoc.sensor",
    "Region": "mapassoc.sensor",
    # data
    "Scan": "mapassoc.scans",
    "read_detections": "mapassoc.io",
    "write_detections": "mapassoc.io",
    "read_truth": "mapassoc.io",
    "read_tracks": "mapassoc.io",
    "write_tracks": "mapassoc.io",
    "TruthTable": "mapassoc.io",
    "TrackTable": "mapassoc.io",
    # the estimator
    "WindowEstimator": "mapassoc.pipeline",
    "WindowSolution": "mapassoc.pipeline",
    "WindowReport": "mapassoc.pipeline",
    "EstimateResult": "mapassoc.pipeline",
    "CountPrior": "mapassoc.posterior",
    "KPosterior": "mapassoc.posterior",
    "k_posterior": "mapassoc.posterior",
    "UndetectedTargets": "mapassoc.population",
    # simulation and evaluation
    "build_scenario": "mapassoc.scenarios",
    "scenario_names": "mapassoc.scenarios",
    "generic_config": "mapassoc.scenarios",
    "evaluate_tables": "mapassoc.evaluation",
    "gospa": "mapassoc.metrics",
    "oracle_tracks": "mapassoc.oracle",
    # the seeds' exact references
    "n_object_posterior": "mapassoc.association",
    "single_object_sequences": "mapassoc.association",
    # errors
    "InputError": "mapassoc.errors",
    "ConfigError": "mapassoc.errors",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'mapassoc' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted([*globals(), *_EXPORTS])

