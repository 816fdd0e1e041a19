"""Coordinate frames and angle conventions (DESIGN §2).

* World frame: *map* coordinates in metres around the scene's geodetic origin (WGS-84
  latitude, longitude in degrees, height above the ellipsoid in metres): ``x`` east and ``y``
  north are an azimuthal equidistant map of the earth's surface about the origin (the distance
  √(x² + y²) from the origin is the distance along the earth, its direction the azimuth there),
  and ``z`` is the height above the surface through the origin's height (``h − h0``; terrain
  heights, vehicle and aircraft altitudes are all of this kind).  The earth itself is round:
  the sensor computes slant ranges, angles and geolocation on a sphere of radius
  :func:`sphere_radius_m` (the Gaussian radius of curvature at the origin + h0;
  :mod:`gmtiflow.sensor.geometry`), so a map point 30 km away lies d²/(2R) ≈ 71 m below the
  origin's tangent plane, as it does on the real earth.
* Azimuth / heading: radians, clockwise from north, ``atan2(east, north)``, in [0, 2π).
* Geodetic conversions go through :mod:`pymap3d` (WGS-84): the map point (x, y, z) is the
  point at central angle θ = ρ/R (ρ = √(x² + y²)) from the origin on the sphere of radius R
  tangent to the ellipsoid at the origin, its latitude and longitude those pymap3d gives for
  that point, its height h0 + z.  Against pymap3d's ellipsoidal ECEF the slant range between two
  map points is good to ~1e-5 of itself (≤ 6 m at the 580 km horizon of a 20 km altitude,
  millimetres at 30 km; tests/sensor/test_curved_earth.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np
import pymap3d

from gmtiflow.sensor import fastnp


@dataclass(frozen=True)
class Origin:
    """Geodetic origin of a scene's ENU frame (WGS-84, height above the ellipsoid)."""

    lat_deg: float
    lon_deg: float
    height_m: float = 0.0

    @classmethod
    def from_attrs(cls, attrs) -> Optional["Origin"]:
        """The origin a run file's root attributes hold (``origin_lat_deg``, ``origin_lon_deg``,
        ``origin_height_m``, 0 if absent); None when the file has none."""
        if "origin_lat_deg" not in attrs:
            return None
        return cls(float(attrs["origin_lat_deg"]), float(attrs["origin_lon_deg"]),
                   float(attrs.get("origin_height_m", 0.0)))


#: Mean earth radius R1 (IUGG, m).
EARTH_RADIUS_M = 6_371_008.8


#: WGS-84 semi-major axis (m) and first eccentricity squared.
WGS84_A_M = 6_378_137.0
WGS84_E2 = 6.69437999014e-3


def sphere_radius_m(origin: Origin) -> float:
    """Radius of the scene's sphere: WGS-84's Gaussian mean radius of curvature √(MN) at the
    origin's latitude (M meridional, N prime vertical: 6,335–6,400 km; it fits the ellipsoid
    around the origin in every direction to ±0.17 %) plus the origin's height, so that z = 0
    is the surface through the origin."""
    s2 = math.sin(math.radians(float(origin.lat_deg))) ** 2
    w = 1.0 - WGS84_E2 * s2
    m = WGS84_A_M * (1.0 - WGS84_E2) / w ** 1.5
    n = WGS84_A_M / math.sqrt(w)
    return math.sqrt(m * n) + float(origin.height_m)


def _sin_ratio(theta):
    """sin θ / θ (1 at 0)."""
    small = np.abs(theta) < 1e-4
    if np.ndim(theta) == 1:     # the same values, without the masking: the few small ones set
        with np.errstate(invalid="ignore", divide="ignore"):       # 0/0 at 0: replaced
            out = np.sin(theta) / theta
        i = np.flatnonzero(small)
        if i.size:
            t = theta[i]
            out[i] = 1.0 - t * t / 6.0
        return out
    if np.ndim(theta) and not small.any():
        return np.sin(theta) / theta
    safe = np.where(small, 1.0, theta)
    return np.where(small, 1.0 - theta * theta / 6.0, np.sin(safe) / safe)


_WGS84 = pymap3d.Ellipsoid.from_name("wgs84")


def _ecef_to_lat_lon_deg(x, y, z):
    """Latitude and longitude (deg) of ECEF points: ``pymap3d.ecef2geodetic``'s own arithmetic
    (You 2000, the same operations in the same order, common subexpressions
    taken once, so the same values bit for bit) without
    the altitude, which :func:`enu_to_geodetic` does not use, and without its masked indexing,
    which only the degenerate points need (at the poles or the earth's centre: those go to
    pymap3d itself).  A sensor chunk converts every detection: this halves that cost."""
    if np.ndim(x) == 0 or np.size(x) == 0:
        lat, lon, _ = pymap3d.ecef2geodetic(x, y, z)
        return lat, lon
    a, b = _WGS84.semimajor_axis, _WGS84.semiminor_axis
    # pymap3d's expressions with their temporaries reused (in place: the same operations on
    # the same operands in the same order, so the same values; x**2 is x*x in numpy)
    r2 = x * x
    t = y * y
    r2 += t
    np.multiply(z, z, out=t)
    r2 += t
    r = np.sqrt(r2, out=r2)                 # r = √(x² + y² + z²)
    E = np.sqrt(a**2 - b**2)
    r2_e2 = np.square(r, out=r)
    r2_e2 -= E**2                           # r² − E²
    t = np.hypot(r2_e2, 2 * E * z)
    t *= 0.5
    u = r2_e2 * 0.5
    u += t
    u = np.sqrt(u, out=u)                   # √(0.5 (r² − E²) + 0.5 hypot(r² − E², 2Ez))
    hxy = np.hypot(x, y)
    huE = np.hypot(u, E)
    lim_pi2 = math.pi / 2 - np.finfo(float).eps
    # pymap3d's special cases: isclose(u, 0) | isclose(hxy, 0) (|·| <= 1e-8), |β| near π/2
    if np.any(np.abs(u) <= 1e-8) or np.any(np.abs(hxy) <= 1e-8):
        lat, lon, _ = pymap3d.ecef2geodetic(x, y, z)
        return lat, lon
    beta = huE / u
    beta *= z
    beta /= hxy
    beta = np.arctan(beta, out=beta)        # arctan(huE / u · z / hxy)
    # pymap3d writes a·huE·1/cos β − E² cos β: ·1 is exact, so cos β is taken once
    cos_beta = np.cos(beta)
    num = b * u
    num -= a * huE
    num += E**2
    num *= np.sin(beta)                     # (b u − a huE + E²) sin β
    den = a * huE
    den /= cos_beta
    cos_beta *= E**2
    den -= cos_beta                         # a huE / cos β − E² cos β
    num /= den
    beta += num
    if np.any(np.abs(beta) >= lim_pi2):
        lat, lon, _ = pymap3d.ecef2geodetic(x, y, z)
        return lat, lon
    lat = np.tan(beta, out=beta)
    lat *= a / b
    lat = np.arctan(lat, out=lat)
    lon = np.arctan2(y, x)
    return np.degrees(lat, out=lat), np.degrees(lon, out=lon)


def lon_centre_deg(lon_deg) -> float:
    """The centre longitude (degrees, in [-180, 180]) of the shortest arc of the circle that
    holds every longitude of ``lon_deg``: ``(min + max) / 2`` when they span at most 180°
    (exactly that value), else the middle of the circle minus its largest gap between two
    longitudes, so that a map across the antimeridian (179.9999° and -179.9999°) is centred at
    ±180° rather than at 0°, the other side of the earth."""
    lon = np.asarray(lon_deg, dtype=float)
    lo, hi = float(lon.min()), float(lon.max())
    if hi - lo <= 180.0:
        return 0.5 * (lo + hi)
    s = np.unique(lon)
    gaps = np.diff(s)
    i = int(np.argmax(gaps))
    if gaps[i] <= s[0] + 360.0 - s[-1]:     # the widest gap is the one across ±180°
        return 0.5 * (lo + hi)
    centre = 0.5 * (float(s[i + 1]) + float(s[i]) + 360.0)  # the arc s[i+1] -> east -> s[i]
    return centre - 360.0 if centre > 180.0 else centre


def enu_to_geodetic(origin: Origin, x_m, y_m, z_m):
    """Map metres -> (lat_deg, lon_deg, height_m) on WGS-84, vectorised (module doc)."""
    x, y, z = (np.asarray(c, float) for c in (x_m, y_m, z_m))
    radius = sphere_radius_m(origin)
    theta = np.hypot(x, y) / radius
    k = _sin_ratio(theta)                 # tangent-plane coordinates of the surface point
    drop = -2.0 * radius * np.sin(0.5 * theta) ** 2
    lat, lon = _ecef_to_lat_lon_deg(*pymap3d.enu2ecef(x * k, y * k, drop, origin.lat_deg,
                                                      origin.lon_deg, origin.height_m))
    h = origin.height_m + z
    return np.asarray(lat, float), np.asarray(lon, float), np.asarray(h, float) + 0.0 * theta


def geodetic_to_enu(origin: Origin, lat_deg, lon_deg, height_m):
    """(lat_deg, lon_deg, height_m) on WGS-84 -> map metres, vectorised (module doc)."""
    lat = np.asarray(lat_deg, float)
    e, n, u = pymap3d.geodetic2enu(lat, np.asarray(lon_deg, float),
                                   np.full(np.shape(lat), float(origin.height_m)),
                                   origin.lat_deg, origin.lon_deg, origin.height_m)
    e, n, u = (np.asarray(c, float) for c in (e, n, u))
    radius = sphere_radius_m(origin)
    rho = np.hypot(e, n)
    theta = np.arctan2(rho, radius + u)
    # map distance Rθ over the tangent-plane distance ρ = r sinθ (r = |point − centre|)
    k = radius / np.maximum(np.hypot(rho, radius + u), 1.0) / _sin_ratio(theta)
    z = np.asarray(height_m, float) - origin.height_m
    return e * k, n * k, z + 0.0 * rho


def map_to_local_vector(origin: Origin, x_m, y_m, z_m, ve, vn, vu, step_s: float = 0.5):
    """A map-rate vector (d/dt of map x, y, z) at map point (x, y, z) as the true velocity in
    the local ENU frame (true north, ellipsoid normal) there: central difference of the
    geodetic positions at ∓ ``step_s`` through pymap3d (exact for the map's own curvature and
    altitude scaling; the step's own error is O(v² step / R), < 1e-5 m/s)."""
    x, y, z = (np.asarray(c, float) for c in (x_m, y_m, z_m))
    v = [np.asarray(c, float) for c in (ve, vn, vu)]
    lat, lon, h = enu_to_geodetic(origin, x, y, z)
    ahead = enu_to_geodetic(origin, x + v[0] * step_s, y + v[1] * step_s, z + v[2] * step_s)
    back = enu_to_geodetic(origin, x - v[0] * step_s, y - v[1] * step_s, z - v[2] * step_s)
    e1, n1, u1 = pymap3d.geodetic2enu(*ahead, lat, lon, h)
    e0, n0, u0 = pymap3d.geodetic2enu(*back, lat, lon, h)
    k = 0.5 / step_s
    return (np.asarray(e1 - e0, float) * k, np.asarray(n1 - n0, float) * k,
            np.asarray(u1 - u0, float) * k)


def local_to_map_vector(origin: Origin, lat_deg, lon_deg, height_m, ve, vn, vu,
                        step_s: float = 0.5):
    """The inverse of :func:`map_to_local_vector`: a true velocity in the local ENU frame at
    (lat, lon, height) as map rates."""
    lat, lon, h = (np.asarray(c, float) for c in (lat_deg, lon_deg, height_m))
    v = [np.asarray(c, float) for c in (ve, vn, vu)]
    ends = []
    for sign in (1.0, -1.0):
        g = pymap3d.enu2geodetic(sign * v[0] * step_s, sign * v[1] * step_s,
                                 sign * v[2] * step_s, lat, lon, h)
        ends.append(geodetic_to_enu(origin, *g))
    k = 0.5 / step_s
    return tuple(np.asarray(a - b, float) * k for a, b in zip(*ends))


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
    return fastnp.mod(np.arctan2(east, north), 2.0 * np.pi)     # np.mod's values, cheaper


def wrap_pi(angle_rad):
    """Wrap angles into [-π, π)."""
    return fastnp.mod(np.asarray(angle_rad) + np.pi, 2.0 * np.pi) - np.pi
