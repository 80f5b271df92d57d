"""Geodetic frames: WGS-84 to an east-north-up plane and back, checked with pyproj's Geod."""

from __future__ import annotations

import math

import numpy as np
import pytest

pyproj = pytest.importorskip("pyproj")

from mapassoc.data.frames import (  # noqa: E402
    GeodeticPoint,
    LocalFrame,
    plane_to_site_polar,
    site_polar_to_plane,
)
from mapassoc.errors import InputError  # noqa: E402

GEOD = pyproj.Geod(ellps="WGS84")
SITES = [
    GeodeticPoint(52.3086, 4.7639, -3.0),
    GeodeticPoint(-33.9461, 151.1772, 6.0),
    GeodeticPoint(64.13, -21.94, 50.0),
]


def _ring(site: GeodeticPoint, distance: float, count: int = 36) -> tuple[np.ndarray, ...]:
    azimuths = np.linspace(0.0, 360.0, count, endpoint=False)
    lon, lat, _ = GEOD.fwd(
        np.full(count, site.longitude), np.full(count, site.latitude), azimuths,
        np.full(count, distance),
    )  # fmt: skip
    return np.asarray(lat), np.asarray(lon), azimuths


@pytest.mark.parametrize("site", SITES)
@pytest.mark.parametrize("distance", [1.0, 20e3, 200e3])
def test_round_trip_within_a_millimetre_over_200_km(site: GeodeticPoint, distance: float) -> None:
    frame = LocalFrame(origin=site)
    lat, lon, _ = _ring(site, distance)
    height = np.full(lat.shape, 1500.0)
    back = frame.to_geodetic(frame.to_local(lat, lon, height))
    _, _, error = GEOD.inv(lon, lat, back[:, 1], back[:, 0])
    assert np.max(error) < 1e-3
    assert np.max(np.abs(back[:, 2] - height)) < 1e-3


@pytest.mark.parametrize("site", SITES)
def test_the_plane_keeps_geodesic_azimuth_and_distance_near_the_origin(
    site: GeodeticPoint,
) -> None:
    # within 2 km the tangent plane differs from the geodesic by well under a millimetre
    # in distance and a microradian in azimuth (the plane's error grows as distance^3/R^2)
    frame = LocalFrame(origin=site)
    height = 0.0 if site.height is None else site.height
    lat, lon, azimuths = _ring(site, 2000.0)
    enu = frame.to_local(lat, lon, np.full(lat.shape, height))
    assert np.allclose(np.hypot(enu[:, 0], enu[:, 1]), 2000.0, atol=1e-3)
    azimuth = np.degrees(np.arctan2(enu[:, 0], enu[:, 1])) % 360.0
    difference = (azimuth - azimuths + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(difference)) < 1e-4


def test_2d_reports_at_the_origin_height_round_trip() -> None:
    frame = LocalFrame(origin=SITES[0])
    east, north = np.array([-150e3, 0.0, 90e3]), np.array([120e3, 1.0, -200e3])
    latlon = frame.plane_to_geodetic(east, north)
    enu = frame.to_local(latlon[:, 0], latlon[:, 1])
    assert np.allclose(enu[:, 0], east, atol=1e-3) and np.allclose(enu[:, 1], north, atol=1e-3)


def test_radar_plots_from_a_site_go_to_the_origin_plane_and_back() -> None:
    origin = SITES[0]
    frame = LocalFrame(origin=origin)
    lon, lat, _ = GEOD.fwd(origin.longitude, origin.latitude, 40.0, 30e3)
    site = GeodeticPoint(float(lat), float(lon), 0.0)
    ranges = np.array([5e3, 50e3, 150e3])
    azimuths = np.radians([10.0, 135.0, 300.0])
    plane = site_polar_to_plane(frame, site, ranges, azimuths)
    polar = plane_to_site_polar(frame, site, plane[:, 0], plane[:, 1])
    # the site's plane and the origin's differ by a tilt of 30 km / R: what plane_to_site_polar
    # drops (the up of the origin's plane, ~100 m here) moves the plots by under a metre
    assert np.allclose(polar[:, 0], ranges, atol=1.0)
    turned = (polar[:, 1] - azimuths + np.pi) % (2 * np.pi) - np.pi
    assert np.max(np.abs(turned * ranges)) < 1.0
    # a plot 10 km due north of the site in its own plane is north of it in the origin's,
    # turned by the meridians' convergence (about dlon * sin(lat))
    north = site_polar_to_plane(frame, site, np.array([10e3]), np.array([0.0]))[0]
    start = frame.to_local(site.latitude, site.longitude, 0.0)[0, :2]
    turn = math.atan2(north[0] - start[0], north[1] - start[1])
    convergence = math.radians(site.longitude - origin.longitude) * math.sin(
        math.radians(origin.latitude)
    )
    assert turn == pytest.approx(-convergence, rel=0.05)


@pytest.mark.parametrize(("lat", "lon"), [(91.0, 0.0), (-90.5, 0.0), (0.0, 400.0)])
def test_a_place_outside_the_globe_is_refused(lat: float, lon: float) -> None:
    with pytest.raises(InputError, match="outside"):
        GeodeticPoint(lat, lon)
