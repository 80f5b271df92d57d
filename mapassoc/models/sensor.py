"""Sensors: a measurement model, detection probability and Poisson clutter.

Afzal's survey, eqs. (9)-(13): each target is detected with probability ``Pd``; false
alarms are Poisson with mean ``lambda_bar`` per scan and uniform density
``f_c = 1/V`` over the surveillance region, so the clutter intensity is
``lambda = lambda_bar / V`` (eq. 13).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from mapassoc.errors import InputError
from mapassoc.models.measurement import MeasurementModel
from mapassoc.validation import (
    check_finite_array,
    check_instance,
    check_nonnegative,
    check_numeric_array,
    check_probability,
)

__all__ = ["Region", "Sensor"]


@dataclass(frozen=True, eq=False)
class Region:
    """An axis-aligned box in measurement space.

    Parameters
    ----------
    lower, upper : ndarray, shape (dz,)
        Lower and upper corners; every ``upper > lower``.
    """

    lower: NDArray[np.float64]
    upper: NDArray[np.float64]

    def __post_init__(self) -> None:
        lo = check_finite_array("region lower", self.lower)
        hi = check_finite_array("region upper", self.upper)
        if lo.ndim != 1 or lo.shape != hi.shape or lo.size == 0:
            raise InputError(
                f"region lower and upper must be 1-D of equal length, got shapes "
                f"{lo.shape} and {hi.shape}"
            )
        if np.any(hi <= lo):
            raise InputError(
                f"region is empty: every upper bound must exceed its lower bound, got "
                f"lower={lo.tolist()} upper={hi.tolist()}"
            )
        with np.errstate(over="ignore", under="ignore"):
            sides = hi - lo
            volume = float(np.prod(sides))
        if not (np.all(np.isfinite(sides)) and math.isfinite(volume) and volume > 0.0):
            raise InputError(
                f"region {[[float(a), float(b)] for a, b in zip(lo, hi, strict=True)]} has "
                f"side lengths {sides.tolist()} and volume {volume!r}; expected a volume "
                "that is finite and > 0 in double precision (the false-alarm density is "
                "false_alarms_per_scan / volume): check the region's unit"
            )
        lo.setflags(write=False)
        hi.setflags(write=False)
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", hi)

    @classmethod
    def from_bounds(cls, bounds: ArrayLike) -> Region:
        """Build from ``[[lo_1, hi_1], ..., [lo_dz, hi_dz]]``."""
        b = check_numeric_array("region bounds", bounds)
        if b.ndim != 2 or b.shape[1] != 2:
            raise InputError(f"region bounds must be a list of [low, high] pairs, got {bounds!r}")
        return cls(lower=b[:, 0], upper=b[:, 1])

    @property
    def dim(self) -> int:
        return int(self.lower.size)

    @property
    def volume(self) -> float:
        """V, the product of the side lengths."""
        return float(np.prod(self.upper - self.lower))

    def contains(self, z: ArrayLike) -> NDArray[np.bool_]:
        """Whether each point of ``z`` (shape ``(..., dz)``) lies in the closed box."""
        z = np.asarray(z, dtype=float)
        return np.all((z >= self.lower) & (z <= self.upper), axis=-1)

    def sample(self, rng: np.random.Generator, count: int) -> NDArray[np.float64]:
        """``count`` points uniform over the box, shape ``(count, dz)``."""
        return rng.uniform(self.lower, self.upper, size=(count, self.dim))

    def to_bounds(self) -> list[list[float]]:
        return [[float(a), float(b)] for a, b in zip(self.lower, self.upper, strict=True)]

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, Region)
            and np.array_equal(self.lower, other.lower)
            and np.array_equal(self.upper, other.upper)
        )

    def __hash__(self) -> int:
        return hash((self.lower.tobytes(), self.upper.tobytes()))

    def __repr__(self) -> str:
        return f"Region.from_bounds({self.to_bounds()})"


class Sensor:
    """One sensor: what it measures, how often it detects, how much clutter it sees.

    Parameters
    ----------
    name : str
        Identifier used in detections files (column ``sensor``).
    measurement : MeasurementModel
        Measurement model of this sensor.
    detection_probability : float
        Pd in (0, 1].  (Pd = 0 would make every detection clutter; it is refused.)
    false_alarms_per_scan : float
        lambda_bar >= 0, expected number of false alarms per scan.
    region : Region
        Surveillance region in measurement space; false alarms are uniform over it.
    """

    def __init__(
        self,
        *,
        name: str,
        measurement: MeasurementModel,
        detection_probability: float,
        false_alarms_per_scan: float,
        region: Region,
    ) -> None:
        if not isinstance(name, str) or not name or name != name.strip() or "," in name:
            raise InputError(
                f"sensor name must be a non-empty string without commas or surrounding "
                f"spaces, got {name!r}"
            )
        self.name = name
        check_instance(
            f"sensor '{name}' measurement",
            measurement,
            MeasurementModel,
            expected="a measurement model (mapassoc.LinearMeasurement, mapassoc.RangeBearing)",
            hint="for a position sensor: mapassoc.LinearMeasurement.position(motion, "
            "noise_std=...)",
        )
        self.measurement = measurement
        self.detection_probability = check_probability(
            f"sensor '{name}' detection_probability", detection_probability, allow_zero=False
        )
        self.false_alarms_per_scan = check_nonnegative(
            f"sensor '{name}' false_alarms_per_scan", false_alarms_per_scan
        )
        check_instance(
            f"sensor '{name}' region",
            region,
            Region,
            hint="build one with mapassoc.Region.from_bounds([[low, high], ...])",
        )
        density = self.false_alarms_per_scan / region.volume
        if self.false_alarms_per_scan > 0 and not (density > 0.0 and math.isfinite(density)):
            raise InputError(
                f"sensor '{name}' false_alarms_per_scan = {false_alarms_per_scan!r} over the "
                f"region's volume {region.volume!r} gives the false-alarm density "
                f"{density!r}; expected a finite number > 0 (or false_alarms_per_scan = 0 "
                "for no false alarms)",
                key="false_alarms_per_scan",
            )
        if region.dim != measurement.measurement_dim:
            raise InputError(
                f"sensor '{name}' region has {region.dim} dimensions but the measurement "
                f"model has {measurement.measurement_dim} components "
                f"{measurement.component_names}"
            )
        self.region = region

    @property
    def clutter_density(self) -> float:
        """lambda = lambda_bar / V, false alarms per unit measurement volume (eq. 13)."""
        return self.false_alarms_per_scan / self.region.volume

    @property
    def log_clutter_density(self) -> float:
        """log lambda; ``-inf`` when the sensor has no false alarms."""
        lam = self.clutter_density
        return math.log(lam) if lam > 0 else -math.inf

    def __repr__(self) -> str:
        return (
            f"Sensor(name={self.name!r}, measurement={self.measurement!r}, "
            f"detection_probability={self.detection_probability}, "
            f"false_alarms_per_scan={self.false_alarms_per_scan}, region={self.region!r})"
        )
