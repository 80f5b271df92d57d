"""mapassoc: MAP multi-target track-set estimation by optimization.

The objects a notebook needs are importable from the package itself::

    import mapassoc as ma

    scenario = ma.build_scenario("crossing", seed=0)
    result = ma.WindowEstimator(config=scenario.config).run(scenario.scans)
    ma.evaluate_tables(scenario.truth, result.tracks)

The works the method rests on, cited by short names in the docstrings (the documentation's
references page gives them in full): "Perry's MAP formulation" is R. Perry, "Time-Recursive
Number-of-Tracks Estimation for ..." (Proceedings of SPIE, 2000; Villanova University);
"the n-object posterior" and "single-object tracking in clutter" are from L. Svensson et
al., "Multi-Object Tracking for Automotive Systems" (Chalmers University of Technology);
the association vectors are those of W. Afzal, "Track Association Problems in AD" (2022).

They are loaded on first use (PEP 562), so ``import mapassoc`` and the command line
stay fast; ``_EXPORTS`` says which module defines each.  (A function named like its
module, ``mapassoc.evaluation.simulate.simulate``, is not exported: importing the module would
replace the package attribute.)
"""

from __future__ import annotations

import importlib
from typing import Any

from mapassoc.version import __version__ as __version__

_EXPORTS: dict[str, str] = {
    # configuration and models
    "Config": "mapassoc.data.config",
    "load_config": "mapassoc.data.config",
    "parse_config": "mapassoc.data.config",
    "BirthModel": "mapassoc.models.population",
    "EstimatorSettings": "mapassoc.data.settings",
    "ConstantVelocity": "mapassoc.models.motion",
    "ConstantAcceleration": "mapassoc.models.motion",
    "RandomWalk": "mapassoc.models.motion",
    "CoordinatedTurn": "mapassoc.models.motion",
    "Singer": "mapassoc.models.motion",
    "LinearMeasurement": "mapassoc.models.measurement",
    "RangeBearing": "mapassoc.models.measurement",
    "Sensor": "mapassoc.models.sensor",
    "Region": "mapassoc.models.sensor",
    # data
    "Scan": "mapassoc.data.scans",
    "read_detections": "mapassoc.data.io",
    "write_detections": "mapassoc.data.io",
    "read_truth": "mapassoc.data.io",
    "read_tracks": "mapassoc.data.io",
    "write_tracks": "mapassoc.data.io",
    "TruthTable": "mapassoc.data.records",
    "TrackTable": "mapassoc.data.records",
    "read_detections_file": "mapassoc.data.formats",
    "write_detections_file": "mapassoc.data.formats",
    "read_tracks_file": "mapassoc.data.formats",
    "write_tracks_file": "mapassoc.data.formats",
    "read_truth_file": "mapassoc.data.formats",
    "scans_from_frame": "mapassoc.data.tables",
    "scans_from_arrays": "mapassoc.data.tables",
    # the estimator
    "WindowEstimator": "mapassoc.estimator.pipeline",
    "WindowSolution": "mapassoc.estimator.pipeline",
    "WindowReport": "mapassoc.estimator.pipeline",
    "EstimateResult": "mapassoc.estimator.pipeline",
    "RunState": "mapassoc.estimator.pipeline",
    "run_segmented": "mapassoc.estimator.segments",
    "CountPrior": "mapassoc.models.target_count",
    "KPosterior": "mapassoc.estimator.posterior",
    "k_posterior": "mapassoc.estimator.posterior",
    "UndetectedTargets": "mapassoc.models.population",
    # simulation and evaluation
    "build_scenario": "mapassoc.evaluation.scenarios",
    "scenario_names": "mapassoc.evaluation.scenarios",
    "generic_config": "mapassoc.evaluation.scenarios",
    "evaluate_tables": "mapassoc.evaluation.tables",
    "gospa": "mapassoc.evaluation.metrics",
    "oracle_tracks": "mapassoc.evaluation.oracle",
    # exact references of the theory (the n-object posterior, single-object sequences)
    "n_object_posterior": "mapassoc.reference.association",
    "single_object_sequences": "mapassoc.reference.association",
    # errors
    "InputError": "mapassoc.errors",
    "ConfigError": "mapassoc.errors",
    "DataFileError": "mapassoc.errors",
    "OutputError": "mapassoc.errors",
    # reprocessing files
    "run_files": "mapassoc.apps.runs",
    "find_recordings": "mapassoc.apps.batch",
    "run_batch": "mapassoc.apps.batch",
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

