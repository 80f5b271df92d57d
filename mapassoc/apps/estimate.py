"""``mapassoc estimate-parameters``: sensor parameters from a recording, next to the configured.

Estimates every sensor's false-alarm rate and detection probability from the recording
(:mod:`mapassoc.estimator.parameters`), and the noise levels the configuration leaves
"auto" (``[motion] noise_intensity`` or a set's ``[[motion.models]]``' own, a position
sensor's ``noise_std``: only those, since
a configured noise level is not a guess the way a clutter rate is) and the ``[birth]``
keys it leaves "auto" (``rate``, ``initial_count``, ``survival_probability``,
``velocity_std``, likewise only those), prints them beside
the configured values, warns
where a configured number and its estimate disagree by more than
:data:`RATE_DISAGREEMENT` (a factor, either way) or :data:`PD_DISAGREEMENT` (an absolute
difference), and writes a configuration with the estimates filled in.
"""

from __future__ import annotations

import os
import warnings as _warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mapassoc.errors import InputError
from mapassoc.trackers.registry import tracker_names

__all__ = [
    "RATE_DISAGREEMENT",
    "PD_DISAGREEMENT",
    "ParameterReport",
    "estimate_file_parameters",
    "disagreements",
]

RATE_DISAGREEMENT = 1.5
"""A configured false-alarm rate more than this factor above or below its estimate is
reported: a factor 2 in dense clutter costs 1.7 to 3.5 times the GOSPA."""
PD_DISAGREEMENT = 0.1
"""A configured detection probability further than this from its estimate is reported."""


@dataclass(frozen=True)
class ParameterReport:
    """What :func:`estimate_file_parameters` found.

    Attributes
    ----------
    estimate : ParameterEstimate
        The estimates, passes and notes.
    configured : dict of str to (float or None, float or None)
        Per sensor, the configured ``(false_alarms_per_scan, detection_probability)``;
        None where the configuration says "auto".
    warnings : tuple of str
        The disagreements (:func:`disagreements`) and the estimation's own notes.
    """

    estimate: Any
    configured: dict[str, tuple[float | None, float | None]]
    warnings: tuple[str, ...]

    def table(self) -> str:
        """An aligned text table: sensor, configured and estimated values."""
        header = (
            f"{'sensor':12s} {'false alarms/scan':>18s} {'estimated':>10s} "
            f"{'Pd':>8s} {'estimated':>10s}"
        )
        lines = [header, "-" * len(header)]
        for name, found in self.estimate.sensors.items():
            rate, pd = self.configured[name]
            lines.append(
                f"{name:12s} {_text(rate, '.4g'):>18s} "
                f"{_text(found.false_alarms_per_scan, '.4g', found.rate_estimated):>10s} "
                f"{_text(pd, '.3f'):>8s} "
                f"{_text(found.detection_probability, '.3f', found.pd_estimated):>10s}"
            )
        return "\n".join(lines + self.noise_lines() + self.birth_lines())

    def noise_lines(self) -> list[str]:
        """The "auto" noise levels, configured ("auto") beside estimated (none asked: no
        line)."""
        noise = self.estimate.noise
        if noise is None:
            return []
        rows = [] if noise.noise_intensity is None else [
            ("motion.noise_intensity", f"{noise.noise_intensity:.4g}")
        ]  # fmt: skip
        rows += [(f"motion.models[{index}].noise_intensity", f"{value:.4g}")
                 for index, value in noise.model_intensities.items()]  # fmt: skip
        rows += [(f"sensor '{name}' noise_std", ", ".join(f"{v:.4g}" for v in stds))
                 for name, stds in noise.noise_std.items()]  # fmt: skip
        header = f"{'noise level':28s} {'configured':>10s} {'estimated':>12s}"
        return ["", header, "-" * len(header),
                *(f"{key:28s} {'auto':>10s} {value:>12s}" for key, value in rows)]  # fmt: skip

    def birth_lines(self) -> list[str]:
        """The "auto" birth keys, configured ("auto") beside estimated (none asked: no
        line)."""
        birth = self.estimate.birth
        if birth is None:
            return []
        header = f"{'birth':28s} {'configured':>10s} {'estimated':>12s}"
        return ["", header, "-" * len(header),
                *(f"{'birth.' + key:28s} {'auto':>10s} {value:>12.4g}"
                  for key, value in birth.values.items())]  # fmt: skip


def _text(value: float | None, spec: str, estimated: bool = True) -> str:
    if value is None:
        return "auto"
    return format(value, spec) + ("" if estimated else " (kept)")


def disagreements(
    configured: dict[str, tuple[float | None, float | None]], estimate: Any
) -> list[str]:
    """Messages where a configured number and its estimate disagree (module docstring)."""
    out = []
    for name, found in estimate.sensors.items():
        rate, pd = configured[name]
        new_rate = found.false_alarms_per_scan
        if found.rate_estimated and rate is not None:
            low, high = sorted((rate, new_rate))
            if high > RATE_DISAGREEMENT * low or (low == 0 < high):
                out.append(
                    f"sensor '{name}': configured false_alarms_per_scan = {rate:.4g}, the "
                    f"recording says {new_rate:.4g} (more than a factor {RATE_DISAGREEMENT} "
                    "apart)"
                )
        if found.pd_estimated and pd is not None:
            if abs(pd - found.detection_probability) > PD_DISAGREEMENT:
                out.append(
                    f"sensor '{name}': configured detection_probability = {pd:.3f}, the "
                    f"recording says {found.detection_probability:.3f} (more than "
                    f"{PD_DISAGREEMENT} apart)"
                )
    return out


def estimate_file_parameters(
    config_path: str | os.PathLike[str],
    detections_path: str | os.PathLike[str],
    *,
    write: str | os.PathLike[str] | None = None,
    stop: Any = None,
    progress: bool = True,
    detections_format: str | None = None,
) -> ParameterReport:
    """Estimate every sensor's rate and ``Pd`` from a recording; optionally write them.

    Parameters
    ----------
    config_path, detections_path : path
        The TOML configuration ("auto" or numbers) and the detections file.
    write : path, optional
        Write the configuration with the estimates filled in (numbers) to this file;
        it must not exist yet.  Written atomically: a failure (a full disk) leaves no
        file behind.
    stop : callable, optional
        Polled between windows (SIGINT, SIGTERM).
    progress : bool
        A line per pass on stderr.
    detections_format : {"csv", "parquet"}, optional
        The detections file's format (``--format``); None: by its suffix, else its bytes.

    Raises
    ------
    InputError, ConfigError, DataFileError
        Bad inputs, or ``write`` names an existing file (nothing is overwritten).
    OutputError
        ``write`` cannot be written (its folder is missing, the disk is full, ...).
    """
    from mapassoc.apps.run_folders import write_atomically
    from mapassoc.apps.runs import read_input
    from mapassoc.data.checks import detections_outside_region
    from mapassoc.data.config import config_to_toml, load_config
    from mapassoc.data.formats import read_detections_file

    if write is not None and os.path.lexists(write):
        raise InputError(f"{os.fspath(write)} exists already; name a new file to write")
    # Warnings are kept for the report, as `run` keeps them for summary.json (a missing
    # [birth], times that look like milliseconds: once per message).
    with _warnings.catch_warnings(record=True) as caught:
        _warnings.simplefilter("always")
        _warnings.filterwarnings("ignore", category=ResourceWarning)  # not the inputs'
        config_bytes, _ = read_input(config_path, stop=stop)
        config = load_config(config_path, tracker_names=tracker_names(), content=config_bytes)
        detections_bytes, _ = read_input(detections_path, stop=stop)
        scans = read_detections_file(detections_path, config.sensors, content=detections_bytes,
                                     format_name=detections_format)  # fmt: skip
        outside = detections_outside_region(scans, config.sensors)
        estimate, configured = _estimate(config, scans, stop=stop, progress=progress)
    warnings = (
        *(str(w.message) for w in caught), *outside, *disagreements(configured, estimate),
        *estimate.warnings,
    )  # fmt: skip
    if write is not None:  # whole or not at all: a failure leaves no file (write_atomically)
        text = config_to_toml(estimate.config)
        write_atomically(Path(write), text.encode("utf-8"), new=True)
    return ParameterReport(
        estimate=estimate, configured=configured, warnings=tuple(dict.fromkeys(warnings))
    )


def _estimate(
    config: Any, scans: list[Any], *, stop: Any, progress: bool
) -> tuple[Any, dict[str, tuple[float | None, float | None]]]:
    """Every sensor's estimates, and its configured values (None: "auto")."""
    from mapassoc.apps.runs import estimate_with_progress

    auto_rates = set(config.auto.false_alarms)
    auto_pds = config.auto.pd_starts()
    configured = {
        name: (
            None if name in auto_rates else sensor.false_alarms_per_scan,
            None if name in auto_pds else sensor.detection_probability,
        )
        for name, sensor in config.sensors.items()
    }
    estimate = estimate_with_progress(
        config, scans, stop=stop, progress=progress, every_sensor=True
    )
    return estimate, configured
