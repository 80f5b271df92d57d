"""Plausibility checks of data against its configuration, as warning messages.

These are not errors: the data can be processed, but a result computed from it is
probably not what the analyst meant.  Each check returns its messages (one line each,
naming the sensor, the numbers and what to check); the caller decides whether to
``warnings.warn`` them, print them or write them to a run summary.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from mapassoc.data.scans import Scan
from mapassoc.errors import InputError
from mapassoc.models.sensor import Sensor

__all__ = ["MOSTLY_OUTSIDE_SHARE", "detections_outside_region", "inside_region"]

MOSTLY_OUTSIDE_SHARE = 0.5
"""Share of a sensor's detections outside its region above which
:func:`detections_outside_region` warns (see its docstring for the choice)."""


def inside_region(sensor: Sensor, detections: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Whether each detection lies in the sensor's region, in the region's own convention.

    The region is a box in measurement space (``range, bearing`` for a range-bearing
    sensor, not Cartesian), the space the detections are written in, so the two are
    compared directly.  Angular components (the bearing) are first brought to their
    representative nearest the middle of the region's interval by the model's own
    residual (``z -> c + residual(z, c)``, ``c`` the box centre), so a bearing written as
    ``-pi/2`` is inside a region ``[4.0, 5.0]`` that holds ``3 pi/2``; linear components
    are unchanged.

    Parameters
    ----------
    sensor : Sensor
    detections : ndarray, shape (m, dz)

    Returns
    -------
    ndarray of bool, shape (m,)
    """
    z = np.asarray(detections, dtype=float)
    dz = sensor.measurement.measurement_dim
    if z.ndim != 2 or z.shape[1] != dz:
        raise InputError(
            f"detections of sensor {sensor.name!r} must have shape (m, {dz}), got {z.shape}"
        )
    region = sensor.region
    centre = 0.5 * (region.lower + region.upper)
    if z.shape[0] == 0:
        return np.zeros(0, dtype=bool)
    anchor = np.broadcast_to(centre, z.shape)
    residual = sensor.measurement.residual(z, anchor)
    # Components the residual leaves alone keep their value exactly (no round-off at the
    # boundary); the wrapped ones take the representative near the centre.
    representative = np.where(residual == z - anchor, z, anchor + residual)
    return region.contains(representative)


def _span(names: tuple[str, ...], z: NDArray[np.float64]) -> str:
    return ", ".join(
        f"{name} {low:.6g} to {high:.6g}"
        for name, low, high in zip(names, z.min(axis=0), z.max(axis=0), strict=True)
    )


def detections_outside_region(
    scans: Sequence[Scan],
    sensors: Mapping[str, Sensor],
    *,
    share: float = MOSTLY_OUTSIDE_SHARE,
) -> list[str]:
    """One message per sensor whose detections lie outside its configured region.

    Every false alarm is uniform over the region and the clutter density of every score
    is ``lambda_bar / V`` with ``V`` the region's volume, and a sensor reports only inside
    its surveillance region, so with a right region no detection lies outside it.  Two
    cases get a message (at most one per sensor, sensors in ``sensors`` order):

    * **every** detection of the sensor is outside: the region is surely wrong (units,
      components in the wrong order, a Cartesian box for a range-bearing sensor);
    * **more than** ``share`` (default ``MOSTLY_OUTSIDE_SHARE`` = one half) of them are
      outside.  A right region still leaves a few outside when the recording's region
      is slightly larger than the configured one, or target detections near the edge
      carry noise across it; those are a few percent, and a box drawn around the area of
      interest that cuts off part of the coverage can leave tens of percent outside on
      purpose.  More than half means that most of the data contradicts the region, and
      ``V`` (hence every track score) is then wrong by more than a factor of two in the
      clutter density, so this is the line past which a configuration error is far more
      likely than a deliberate choice; below it the check stays silent rather than
      warning on every run of a slightly tight region.

    Inside or outside is judged in the region's own convention (:func:`inside_region`).
    Sensors without detections get no message.

    Parameters
    ----------
    scans : sequence of Scan
    sensors : mapping of str to Sensor
        The configuration's sensors; every scan's sensor must be among them.
    share : float
        Threshold of the second case, in [0, 1).

    Returns
    -------
    list of str
        Messages naming the sensor, the counts, the region and the span of the
        detections.

    Raises
    ------
    InputError
        A scan of a sensor not in ``sensors``, or a bad ``share``.
    """
    if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0 <= share < 1:
        raise InputError(f"share must be a number in [0, 1), got {share!r}")
    groups: dict[str, list[NDArray[np.float64]]] = {name: [] for name in sensors}
    for index, scan in enumerate(scans):
        if not isinstance(scan, Scan):
            raise InputError(f"scans[{index}] must be a Scan, got {scan!r}")
        if scan.sensor not in groups:
            raise InputError(
                f"scans[{index}] (time {scan.time}) is of sensor {scan.sensor!r}, which is not "
                f"in the configuration (sensors: {', '.join(sensors)})"
            )
        if scan.size:
            groups[scan.sensor].append(scan.detections)
    messages: list[str] = []
    for name, parts in groups.items():
        if not parts:
            continue
        sensor = sensors[name]
        z = np.concatenate(parts)
        total = z.shape[0]
        outside = int(total - np.count_nonzero(inside_region(sensor, z)))
        names = sensor.measurement.component_names
        region = ", ".join(
            f"{n} [{low:.6g}, {high:.6g}]"
            for n, low, high in zip(names, sensor.region.lower, sensor.region.upper, strict=True)
        )
        if outside == total:
            messages.append(
                f"sensor {name!r}: all {total} detections lie outside its region ({region}); "
                f"the detections span {_span(names, z)}; check the region's units and "
                "component order (a range-bearing region is a box in range and bearing, "
                "radians)"
            )
        elif outside > share * total:
            messages.append(
                f"sensor {name!r}: {outside} of {total} detections "
                f"({100.0 * outside / total:.1f}%, more than {100.0 * share:g}%) lie outside "
                f"its region ({region}); the detections span {_span(names, z)}; false alarms "
                "are modelled as uniform over the region, so its volume sets every track "
                "score: check the region"
            )
    return messages
