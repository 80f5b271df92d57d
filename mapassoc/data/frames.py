"""Geodetic frames: WGS-84 latitude, longitude and height to a local east-north-up plane.

The estimator works in metres in a local tangent plane: east-north-up (ENU) around an
*origin*, a point given by latitude, longitude and height.  A point's WGS-84 coordinates
go to Earth-centred Earth-fixed (ECEF) coordinates with pyproj (the EPSG:4979 to
EPSG:4978 transformation, pyproj being an optional extra: ``pip install
mapassoc[geodetic]``), then by the rotation of the tangent plane at the origin to ENU
(the standard local-level rotation, for example in Bar-Shalom, Li and Kirubarajan,
"Estimation with Applications to Tracking and Navigation", or any geodesy text).

Decisions
---------
* Latitudes, longitudes, azimuths and elevations in configuration and files are in
  degrees unless a ``[recording]`` says ``angles = "radians"``; heights in metres above
  the ellipsoid.
* A 2-D position report (``lat, lon`` without ``alt``) is taken at the origin's height,
  and written back at it, so a 2-D round trip is exact; the estimator tracks east and
  north and leaves out up.
* A radar plot ``range, azimuth`` is a point in the site's own tangent plane (azimuth
  clockwise from north); with ``elevation`` the range is the slant range.  The point goes
  to the origin's plane through ECEF, and the estimator sees it as range and bearing
  (counter-clockwise from east, :class:`mapassoc.models.measurement.RangeBearing`) from
  the site's place in that plane, so a site away from the origin is handled exactly
  (the two planes' norths differ by the meridians' convergence).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from mapassoc.array_types import FloatArray
from mapassoc.errors import InputError

__all__ = [
    "GeodeticPoint",
    "LocalFrame",
    "check_latitude",
    "check_longitude",
    "site_polar_to_plane",
    "plane_to_site_polar",
]


def _pyproj() -> Any:
    try:
        import pyproj
    except ImportError:  # pragma: no cover - the test extras install it
        raise InputError(
            "geodetic coordinates need pyproj: pip install 'mapassoc[geodetic]'"
        ) from None
    return pyproj


@cache
def _transformers() -> tuple[Any, Any]:
    pyproj = _pyproj()
    forward = pyproj.Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    inverse = pyproj.Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    return forward, inverse


def check_latitude(name: str, value: object) -> float:
    """A latitude in degrees within [-90, 90] (raises InputError naming ``name``)."""
    number = _finite(name, value)
    if not -90.0 <= number <= 90.0:
        raise InputError(f"{name} = {number!r} is outside [-90, 90] degrees", key=name)
    return number


def check_longitude(name: str, value: object) -> float:
    """A longitude in degrees within [-180, 360] (raises InputError naming ``name``)."""
    number = _finite(name, value)
    if not -180.0 <= number <= 360.0:
        raise InputError(f"{name} = {number!r} is outside [-180, 360] degrees", key=name)
    return number


def _finite(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"{name} must be a finite number, got {value!r}", key=name)
    return float(value)


@dataclass(frozen=True)
class GeodeticPoint:
    """A WGS-84 point: latitude and longitude in degrees, height in metres.

    ``height`` None means not given (a site whose plots have no elevation needs none).
    """

    latitude: float
    longitude: float
    height: float | None = None

    def __post_init__(self) -> None:
        check_latitude("latitude", self.latitude)
        check_longitude("longitude", self.longitude)
        if self.height is not None:
            _finite("height", self.height)

    def to_json(self) -> dict[str, float | None]:
        return {"latitude": self.latitude, "longitude": self.longitude, "height": self.height}


def _ecef(lat: ArrayLike, lon: ArrayLike, h: ArrayLike) -> FloatArray:
    forward, _ = _transformers()
    x, y, z = forward.transform(
        np.asarray(lon, dtype=float), np.asarray(lat, dtype=float), np.asarray(h, dtype=float)
    )
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1)


def _rotation(point: GeodeticPoint) -> FloatArray:
    """Rows: the east, north and up unit vectors at ``point`` in ECEF."""
    phi, lam = math.radians(point.latitude), math.radians(point.longitude)
    sp, cp, sl, cl = math.sin(phi), math.cos(phi), math.sin(lam), math.cos(lam)
    return np.array([[-sl, cl, 0.0], [-sp * cl, -sp * sl, cp], [cp * cl, cp * sl, sp]])


@dataclass(frozen=True)
class LocalFrame:
    """The east-north-up tangent plane at ``origin`` (its height: 0 when not given)."""

    origin: GeodeticPoint

    @property
    def _origin_height(self) -> float:
        return 0.0 if self.origin.height is None else self.origin.height

    def _centre(self) -> FloatArray:
        o = self.origin
        return _ecef(o.latitude, o.longitude, self._origin_height).reshape(3)

    def to_local(self, lat: ArrayLike, lon: ArrayLike, h: ArrayLike | None = None) -> FloatArray:
        """ENU metres of points, shape ``(n, 3)``; ``h`` None: the origin's height."""
        lat = np.atleast_1d(np.asarray(lat, dtype=float))
        height = np.full(lat.shape, self._origin_height) if h is None else h
        ecef = _ecef(lat, lon, height).reshape(-1, 3)
        return (ecef - self._centre()) @ _rotation(self.origin).T

    def to_geodetic(self, enu: ArrayLike) -> FloatArray:
        """``(lat, lon, h)`` of ENU points ``enu`` of shape ``(n, 3)``, shape ``(n, 3)``."""
        _, inverse = _transformers()
        enu = np.atleast_2d(np.asarray(enu, dtype=float))
        ecef = enu @ _rotation(self.origin) + self._centre()
        lon, lat, h = inverse.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2])
        return np.column_stack([lat, lon, h])

    def plane_to_geodetic(self, east: ArrayLike, north: ArrayLike) -> FloatArray:
        """``(lat, lon)`` at the origin's height whose ENU east and north are given.

        The inverse of :meth:`to_local` without heights: the point's up at the origin's
        height is found by fixed-point iteration (it changes by micrometres after three
        steps within hundreds of kilometres, where up varies slowly with east and north).
        Shape ``(n, 2)``.
        """
        east = np.atleast_1d(np.asarray(east, dtype=float))
        north = np.atleast_1d(np.asarray(north, dtype=float))
        up = np.zeros_like(east)
        for _ in range(6):
            geo = self.to_geodetic(np.column_stack([east, north, up]))
            up = self.to_local(geo[:, 0], geo[:, 1])[:, 2]
        geo = self.to_geodetic(np.column_stack([east, north, up]))
        return geo[:, :2]


def site_polar_to_plane(
    frame: LocalFrame,
    site: GeodeticPoint,
    slant_range: FloatArray,
    azimuth: FloatArray,
    elevation: FloatArray | None = None,
) -> FloatArray:
    """East and north in ``frame`` of radar plots from ``site``, shape ``(n, 2)``.

    ``azimuth`` and ``elevation`` in radians, azimuth clockwise from the site's north;
    without ``elevation`` the plot lies in the site's horizontal plane.
    """
    r = np.asarray(slant_range, dtype=float)
    az = np.asarray(azimuth, dtype=float)
    el = np.zeros_like(r) if elevation is None else np.asarray(elevation, dtype=float)
    local = np.column_stack(
        [r * np.cos(el) * np.sin(az), r * np.cos(el) * np.cos(az), r * np.sin(el)]
    )
    site_frame = LocalFrame(origin=site)
    geo = site_frame.to_geodetic(local)
    return frame.to_local(geo[:, 0], geo[:, 1], geo[:, 2])[:, :2]


def plane_to_site_polar(
    frame: LocalFrame, site: GeodeticPoint, east: FloatArray, north: FloatArray
) -> FloatArray:
    """Range and azimuth (radians, clockwise from north) from ``site`` of points of
    ``frame``'s plane at up = 0, in the site's horizontal plane: the inverse of
    :func:`site_polar_to_plane` without elevation to within the up the site's plane
    drops.  Shape ``(n, 2)``."""
    e = np.atleast_1d(np.asarray(east, dtype=float))
    n = np.atleast_1d(np.asarray(north, dtype=float))
    geo = frame.to_geodetic(np.column_stack([e, n, np.zeros_like(e)]))
    local = LocalFrame(origin=site).to_local(geo[:, 0], geo[:, 1], geo[:, 2])
    return np.column_stack(
        [np.hypot(local[:, 0], local[:, 1]), np.arctan2(local[:, 0], local[:, 1])]
    )
