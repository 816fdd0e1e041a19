"""Coordinate frames and angle conventions (DESIGN §2).

* World frame: local ENU in metres (x east, y north, z up) around the scene's geodetic origin
  (WGS-84 latitude, longitude in degrees, height above the ellipsoid in metres).
* Azimuth / heading: radians, clockwise from north, ``atan2(east, north)``, in [0, 2π).
* Geodetic conversions go through :mod:`pymap3d` (WGS-84), never by hand.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymap3d


@dataclass(frozen=True)
class Origin:
    """Geodetic origin of a scene's ENU frame (WGS-84, height above the ellipsoid)."""

    lat_deg: float
    lon_deg: float
    height_m: float = 0.0


def enu_to_geodetic(origin: Origin, x_m, y_m, z_m):
    """ENU metres -> (lat_deg, lon_deg, height_m) on WGS-84, vectorised."""
    lat, lon, h = pymap3d.enu2geodetic(np.asarray(x_m, float), np.asarray(y_m, float),
                                       np.asarray(z_m, float), origin.lat_deg, origin.lon_deg,
                                       origin.height_m)
    return np.asarray(lat, float), np.asarray(lon, float), np.asarray(h, float)


def geodetic_to_enu(origin: Origin, lat_deg, lon_deg, height_m):
    """(lat_deg, lon_deg, height_m) on WGS-84 -> ENU metres, vectorised."""
    x, y, z = pymap3d.geodetic2enu(np.asarray(lat_deg, float), np.asarray(lon_deg, float),
                                   np.asarray(height_m, float), origin.lat_deg, origin.lon_deg,
                                   origin.height_m)
    return np.asarray(x, float), np.asarray(y, float), np.asarray(z, float)


def point_to_enu(point, origin: Origin) -> list:
    """A scene point as ENU metres: ``[x, y]``/``[x, y, z]`` (metres, returned as given) or the
    explicit geodetic form ``{lat_deg: .., lon_deg: .., height_m: ..}`` (WGS-84 degrees;
    ``height_m`` defaults to the origin's height), converted about ``origin``.

    The geodetic form is a mapping on purpose: a bare ``[50.63, 7.13]`` is a point 50 m east
    and 7 m north of the origin, never a latitude/longitude.
    """
    if hasattr(point, "keys"):
        lat, lon = float(point["lat_deg"]), float(point["lon_deg"])
        h = float(point.get("height_m", origin.height_m) if point.get("height_m") is not None
                  else origin.height_m)
        x, y, z = geodetic_to_enu(origin, lat, lon, h)
        return [float(x), float(y), float(z)]
    return [float(c) for c in point]


def heading_rad(east, north):
    """Azimuth of a horizontal vector, clockwise from north, in [0, 2π)."""
    return np.mod(np.arctan2(east, north), 2.0 * np.pi)


def wrap_pi(angle_rad):
    """Wrap angles into [-π, π)."""
    return np.mod(np.asarray(angle_rad) + np.pi, 2.0 * np.pi) - np.pi
