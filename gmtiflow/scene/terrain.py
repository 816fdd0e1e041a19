"""Terrain: ground heights and line-of-sight shadowing in the scene's map frame (issue 4).

``build_terrain(cfg, origin)`` turns a :class:`~gmtiflow.scene.terrain_config.TerrainConfig`
into a :class:`Terrain`.  Heights are map ``z`` (:mod:`gmtiflow.frames`): above the round
earth's surface through the scene origin, so a constant z is a sphere, not a plane.

* ``flat`` -- the smooth earth at ``z = flat_height_m``. No DEM; ``line_of_sight`` is
  all True and marches nothing (the radar horizon is the sensor's own test).
* ``hills`` -- synthetic Gaussian hills and ridges in map metres, generated on a grid
  (``grid_spacing_m``) that covers them; the base height elsewhere.
* ``ascii_grid`` -- an ESRI ASCII grid already in scene map metres (heights = map z).
* ``srtm`` -- SRTM ``.hgt`` tiles (stitched), heights above the EGM96 geoid. The scene and STANAG
  4607 use heights above the WGS-84 ellipsoid: ellipsoid height = DEM height + geoid
  undulation N, given explicitly as ``geoid_offset_m`` (about +50 m at Monaco). Map z is that
  height minus the origin's.

Heights (``height_at``) are the bilinear interpolant of the grid ("pixel is point"). For a
geodetic DEM the ground below map (x, y) is read at the (lat, lon) of that map point
(:func:`gmtiflow.frames.enu_to_geodetic`): z = h_DEM(lat, lon) + N − h0.

Line of sight (``line_of_sight``) is the ray march of :mod:`gmtiflow.scene.ray_march`:
rays sampled every ``step_m``, straight on a round earth of the radius the caller gives (the
sensor passes k·R, its 4/3-earth refraction model), i.e. t(1 − t)d²/(2kR) below the
map-straight line (the ground is raised by that bulge in the comparison); a ray is blocked
where the ground is more than ``clearance_m`` above it.

``intersect`` (first ground point of a ray) and ``geolocate`` (ground point at a slant range and
azimuth, as a GMTI processor places a report) give the ground points of measurements.

Points off the DEM: ``height_at`` gives NaN (hills: the base height), ``drape`` raises
InputFileError, ``line_of_sight`` treats unknown ground as not blocking, and
``check_covers`` raises InputFileError naming the DEM when the scene is not covered.
"""
from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.errors import InputFileError
from gmtiflow.scene import dem
from gmtiflow.scene.hills import HillConfig, hills_grid, hills_height
from gmtiflow.scene.ray_march import max_filter, march
from gmtiflow.scene.terrain_config import TerrainConfig, TerrainKind, VoidPolicy

__all__ = ["FlatTerrain", "GeoTerrain", "GridTerrain", "HillConfig", "SUGGESTED_STEP_M",
           "Terrain", "TerrainConfig", "TerrainKind", "VoidPolicy", "build_terrain",
           "drape_points", "hills_grid", "hills_height", "resolve_path"]

log = logging.getLogger(__name__)

#: suggested ray steps for conf/fidelity (metres): fast, standard, full
SUGGESTED_STEP_M = {"fast": 90.0, "standard": 30.0, "full": 10.0}


def _as_points(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3) or (3,), got {a.shape}")
    return a


class Terrain:
    """Ground heights and line of sight in the scene's ENU frame (see the module docstring)."""

    flat: bool = False
    kind: str = ""
    source: str = ""            # the DEM file(s) or a description, for messages
    cell_m: float = 0.0         # grid spacing (the larger of the two axes), metres
    clearance_m: float = 1.0
    end_skip_m: float = 0.0
    chunk_samples: int = 2_000_000
    z_ceiling_m: float = math.inf  # no ground point has ENU z above this
    ray_sag_m: float = 0.0      # how far the ground coordinate c sags below a segment's chord

    # -- heights --------------------------------------------------------------------------
    def height_at(self, x_m, y_m) -> np.ndarray:
        """Ground height (scene ENU z, metres) below ENU (x, y), vectorised; NaN off the DEM."""
        raise NotImplementedError

    def drape(self, x_m, y_m) -> np.ndarray:
        """Ground z for points that must be on the DEM (road nodes): InputFileError if any is
        off it, naming the DEM, the count and the first such point."""
        z = np.asarray(self.height_at(x_m, y_m), float)
        bad = np.isnan(z)
        if bad.any():
            x = np.broadcast_to(np.asarray(x_m, float), z.shape)[bad]
            y = np.broadcast_to(np.asarray(y_m, float), z.shape)[bad]
            raise InputFileError(
                f"{self.source}: {int(bad.sum())} of {z.size} points lie outside the DEM "
                f"(first at ENU x={x.flat[0]:.1f} m, y={y.flat[0]:.1f} m)")
        return z

    def check_covers(self, x_min: float, x_max: float, y_min: float, y_max: float) -> None:
        """Raise InputFileError naming the DEM unless it covers the ENU rectangle."""
        if self.flat:
            return
        n_x = int(min(max((x_max - x_min) / max(self.cell_m, 1.0), 1), 1000)) + 1
        n_y = int(min(max((y_max - y_min) / max(self.cell_m, 1.0), 1), 1000)) + 1
        gx, gy = np.meshgrid(np.linspace(x_min, x_max, n_x), np.linspace(y_min, y_max, n_y))
        z = self.height_at(gx.ravel(), gy.ravel())
        bad = np.isnan(z)
        if bad.any():
            raise InputFileError(
                f"{self.source}: the DEM does not cover the scene x {x_min:.0f}..{x_max:.0f} m, "
                f"y {y_min:.0f}..{y_max:.0f} m ({100.0 * bad.mean():.1f} % of it is outside; "
                f"{self._coverage_text()})")

    def _coverage_text(self) -> str:
        return "add the missing tiles or shrink the scene"

    # -- line of sight --------------------------------------------------------------------
    def line_of_sight(self, from_xyz, to_xyz, step_m: Optional[float] = None,
                      earth_radius_m: Optional[float] = None) -> np.ndarray:
        """True where the straight segment from ``from_xyz`` to ``to_xyz`` clears the ground.

        ``from_xyz``, ``to_xyz``: (n, 3) or (3,) map metres (:mod:`gmtiflow.frames`), broadcast
        together (one platform position against n targets). ``step_m``: sample spacing along
        the ray (default: half a grid cell). ``earth_radius_m``: the ray is straight on a round
        earth of that (effective) radius a, so at fraction t of its ground length d it lies
        t(1 − t)·d²/(2a) lower over the ground than the straight line in map coordinates (the
        earth's bulge; None: map-straight, no bulge). Zero-length rays are True; rays with a
        non-finite end are False.
        """
        p_from = _as_points(from_xyz, "from_xyz")
        p_to = _as_points(to_xyz, "to_xyz")
        p_from, p_to = np.broadcast_arrays(p_from, p_to)
        if self.flat:
            return np.ones(len(p_from), dtype=bool)
        if step_m is None:
            step_m = 0.5 * self.cell_m
        if not (math.isfinite(step_m) and step_m > 0):
            raise ValueError(f"step_m must be a finite number > 0, got {step_m!r}")
        return ~march(self, p_from, p_to, float(step_m), earth_radius_m)

    # Hooks of the march. "Terrain coordinates" (a, b, c) are (x, y, z) for ENU grids and
    # (lat, lon, h above the ellipsoid) for geodetic DEMs: c is what the ground is compared with.
    def _coords(self, pts: np.ndarray):
        return pts[:, 0], pts[:, 1], pts[:, 2]

    def _ground(self, a, b) -> np.ndarray:
        """Ground c at terrain coordinates (a, b); NaN where unknown."""
        raise NotImplementedError

    def _ground_bound(self, a, b, radius_m: float) -> np.ndarray:
        """An upper bound of the ground c within ``radius_m`` (horizontally) of (a, b)."""
        raise NotImplementedError

    def _above_ground_m(self, pts: np.ndarray) -> np.ndarray:
        """Per (n, 3) ENU point: its height above the ground (NaN off the DEM), exact per point
        (geodetic DEMs: along the local normal, through pymap3d)."""
        return pts[:, 2] - self.height_at(pts[:, 0], pts[:, 1])

    # -- ground points of measurements ------------------------------------------------------
    def intersect(self, origin_xyz, direction_xyz, max_range_m: float = 200e3,
                  step_m: Optional[float] = None) -> np.ndarray:
        """First ground point along each ray ``origin + s * direction`` (s in [0, max_range_m]).

        Marches at ``step_m`` (default half a grid cell), then bisects the crossing to < 1 mm.
        A ray whose origin is below the ground, or that does not reach known ground within
        ``max_range_m``, gives a NaN row (it may start off the DEM and land on it). Grazing crossings of a ridge thinner than
        ``step_m`` can be missed, as in :meth:`line_of_sight`. Returns (n, 3) ENU metres.
        """
        p0 = _as_points(origin_xyz, "origin_xyz")
        d = _as_points(direction_xyz, "direction_xyz")
        p0, d = np.broadcast_arrays(p0, d)
        norm = np.linalg.norm(d, axis=1)
        u = np.divide(d, norm[:, None], out=np.zeros(d.shape), where=norm[:, None] > 0)
        n = len(p0)
        if step_m is None:
            step_m = 0.5 * self.cell_m if self.cell_m > 0 else 10.0
        out = np.full((n, 3), np.nan)
        if self.flat:
            with np.errstate(divide="ignore", invalid="ignore"):
                s = (self.height_m - p0[:, 2]) / u[:, 2]
            ok = (u[:, 2] < 0) & (p0[:, 2] >= self.height_m) & (s <= max_range_m)
            out[ok] = p0[ok] + u[ok] * s[ok, None]
            return out
        # descending rays are sampled from where they drop below the highest ground
        room = p0[:, 2] - self.z_ceiling_m
        s_lo = np.where((u[:, 2] < 0) & (room > 0),
                        np.divide(room, -u[:, 2], out=np.zeros(n), where=u[:, 2] < 0), 0.0)
        live = np.isfinite(p0).all(axis=1) & (norm > 0) & (s_lo <= max_range_m)
        above = np.full(n, np.nan)
        above[live] = self._above_ground_m(p0[live] + u[live] * s_lo[live, None])
        s_hit = np.full(n, np.nan)
        # coming down from above the highest ground, a ray on the ground at s_lo lands there
        touch = live & (s_lo > 0) & (above <= 0)
        s_hit[touch] = s_lo[touch]
        live &= ~(above <= 0)  # start above the ground, or over unknown ground (off the DEM)
        # march in blocks of samples; a ray leaves the march at its first sample below ground
        block = 128
        s_next = s_lo.copy()
        lo_all = s_lo.copy()
        idx = np.nonzero(live)[0]
        while len(idx):
            r = idx[: max(1, self.chunk_samples // block)]
            s = np.minimum(s_next[r, None] + step_m * np.arange(block)[None, :], max_range_m)
            pts = p0[r, None, :] + u[r, None, :] * s[..., None]
            below = self._above_ground_m(pts.reshape(-1, 3)).reshape(s.shape) <= 0
            first = np.argmax(below, axis=1)
            rows = np.arange(len(r))
            hit = below[rows, first]
            lo = np.where(first > 0, s[rows, np.maximum(first - 1, 0)], lo_all[r])
            hi = s[rows, first]
            done = hit | (s[:, -1] >= max_range_m)
            lo_all[r] = s[:, -1]
            s_next[r] = s[:, -1] + step_m
            rh, lo, hi = r[hit], lo[hit], hi[hit]
            for _ in range(60):
                if len(rh) == 0 or np.max(hi - lo) < 1e-3:
                    break
                mid = 0.5 * (lo + hi)
                b = self._above_ground_m(p0[rh] + u[rh] * mid[:, None]) <= 0
                hi = np.where(b, mid, hi)
                lo = np.where(b, lo, mid)
            s_hit[rh] = hi
            idx = idx[~np.isin(idx, r[done])]
        ok = np.isfinite(s_hit)
        out[ok] = p0[ok] + u[ok] * s_hit[ok, None]
        return out

    def geolocate(self, platform_xyz, range_m, azimuth_rad, iterations: int = 50) -> np.ndarray:
        """Ground point at slant range ``range_m`` and world azimuth ``azimuth_rad`` (clockwise
        from north) from the platform, as a GMTI processor places a report: a point of the
        terrain on the range sphere, in the vertical half-plane of the azimuth. Solved for the
        horizontal distance rho by bisection on ``z_p - sqrt(R² - rho²) - ground(rho)`` over
        [0, R] (< 0.1 mm). NaN where the range does not reach the ground, or where the ground
        straight below the platform (rho = 0) or at rho = R is unknown (off the DEM): the bracket
        needs both. Returns (n, 3) ENU metres.

        Where the terrain puts several points at the same range and azimuth (layover), this
        returns one of them, not necessarily the true one: a radar cannot tell either.
        """
        p = _as_points(platform_xyz, "platform_xyz")
        r_m = np.asarray(range_m, float).ravel()
        az = np.asarray(azimuth_rad, float).ravel()
        n = np.broadcast_shapes((len(p),), r_m.shape, az.shape)[0]
        p = np.broadcast_to(p, (n, 3))
        r_m = np.broadcast_to(r_m, (n,))
        az = np.broadcast_to(az, (n,))
        sin_a, cos_a = np.sin(az), np.cos(az)

        def point(rho):
            drop = np.sqrt(np.maximum(r_m ** 2 - rho ** 2, 0.0))
            return np.c_[p[:, 0] + rho * sin_a, p[:, 1] + rho * cos_a, p[:, 2] - drop]

        lo = np.zeros(len(r_m))
        hi = np.where(np.isfinite(r_m), r_m, np.nan)
        g_lo = self._above_ground_m(point(lo))
        g_hi = self._above_ground_m(point(hi))
        ok = (g_lo <= 0) & (g_hi > 0)
        for _ in range(iterations):
            if not ok.any() or np.nanmax(np.where(ok, hi - lo, 0.0)) < 1e-4:
                break
            mid = 0.5 * (lo + hi)
            g = self._above_ground_m(point(mid))
            ok &= np.isfinite(g)
            below = g <= 0
            lo = np.where(below, mid, lo)
            hi = np.where(below, hi, mid)
        out = point(0.5 * (lo + hi))
        out[~ok] = np.nan
        return out


class FlatTerrain(Terrain):
    flat = True
    kind = "flat"

    def __init__(self, height_m: float = 0.0):
        self.height_m = float(height_m)
        self.source = f"flat terrain at z={self.height_m:g} m"
        self.z_ceiling_m = self.height_m

    def height_at(self, x_m, y_m) -> np.ndarray:
        shape = np.broadcast_shapes(np.shape(x_m), np.shape(y_m))
        return np.full(shape, self.height_m)


class GridTerrain(Terrain):
    """Terrain on an :class:`~gmtiflow.scene.dem.EnuGrid` (ASCII grids, generated hills)."""

    def __init__(self, grid: dem.EnuGrid, kind: str, *, clearance_m=1.0, end_skip_m=None,
                 chunk_samples=2_000_000):
        self.grid = grid
        self.kind = kind
        self.source = grid.source
        self.cell_m = max(grid.dx_m, grid.dy_m)
        self.clearance_m = float(clearance_m)
        self.end_skip_m = self.cell_m if end_skip_m is None else float(end_skip_m)
        self.chunk_samples = int(chunk_samples)
        top = float(np.nanmax(grid.z))
        if not math.isnan(grid.outside_z_m):
            top = max(top, grid.outside_z_m)
        self.z_ceiling_m = top

    def height_at(self, x_m, y_m) -> np.ndarray:
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        return self.grid.at(x, y)

    def _coverage_text(self) -> str:
        g = self.grid
        return (f"the grid covers x {g.x0_m:.0f}..{g.x1_m:.0f} m, y {g.y0_m:.0f}..{g.y1_m:.0f} m "
                f"of the scene frame")

    def _ground(self, a, b) -> np.ndarray:
        return self.grid.at(a, b)

    def _ground_bound(self, a, b, radius_m: float) -> np.ndarray:
        g = self.grid
        hx = int(math.ceil(radius_m / g.dx_m)) + 2
        hy = int(math.ceil(radius_m / g.dy_m)) + 2
        top = max_filter(self, (hy, hx), g.z)
        i = np.clip(np.round((np.asarray(b) - g.y0_m) / g.dy_m), 0, g.z.shape[0] - 1).astype(np.intp)
        j = np.clip(np.round((np.asarray(a) - g.x0_m) / g.dx_m), 0, g.z.shape[1] - 1).astype(np.intp)
        bound = top[i, j]
        if not math.isnan(g.outside_z_m):
            bound = np.maximum(bound, g.outside_z_m)
        return bound


class GeoTerrain(Terrain):
    """Terrain on a geodetic grid of heights above the geoid (SRTM)."""

    kind = "srtm"
    ray_sag_m = 0.05   # a height above the ellipsoid sags < 5 cm below its chord over 1 km

    def __init__(self, grid: dem.GeoGrid, origin: frames.Origin, geoid_offset_m: float, *,
                 clearance_m=1.0, end_skip_m=None, chunk_samples=2_000_000):
        self.grid = grid
        self.origin = origin
        self.geoid_offset_m = float(geoid_offset_m)
        self.source = grid.source
        mid_lat = math.radians(0.5 * (grid.lat_min_deg + grid.lat_max_deg))
        self.cell_m = math.radians(grid.step_deg) * 6_371_000.0  # N-S spacing (the larger)
        self.cell_ew_m = self.cell_m * math.cos(mid_lat)
        far_lat = math.radians(max(abs(grid.lat_min_deg), abs(grid.lat_max_deg)))
        self.cell_ew_min_m = max(self.cell_m * math.cos(far_lat), 1e-3)  # smallest E-W spacing
        self.clearance_m = float(clearance_m)
        self.end_skip_m = self.cell_m if end_skip_m is None else float(end_skip_m)
        self.chunk_samples = int(chunk_samples)
        # map z = h - h0 (frames): 1 m of margin
        self.z_ceiling_m = float(np.nanmax(grid.values)) + self.geoid_offset_m - origin.height_m + 1.0

    def ellipsoid_height_at(self, lat_deg, lon_deg) -> np.ndarray:
        """Ground height above the WGS-84 ellipsoid at (lat, lon): DEM + geoid offset."""
        return self.grid.at(lat_deg, lon_deg) + self.geoid_offset_m

    def height_at(self, x_m, y_m) -> np.ndarray:
        """Map z of the ground: its height above the ellipsoid minus the origin's (frames)."""
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        lat, lon, _ = frames.enu_to_geodetic(self.origin, x, y, np.zeros(x.shape))
        return self.ellipsoid_height_at(lat, lon) - self.origin.height_m

    def _above_ground_m(self, pts: np.ndarray) -> np.ndarray:
        lat, lon, h = frames.enu_to_geodetic(self.origin, pts[:, 0], pts[:, 1], pts[:, 2])
        return np.asarray(h, float) - self.ellipsoid_height_at(lat, lon)

    def _coverage_text(self) -> str:
        g = self.grid
        return (f"the DEM spans {g.lat_min_deg:g}..{g.lat_max_deg:g} N, "
                f"{g.lon_min_deg:g}..{g.lon_max_deg:g} E; add the missing tiles or shrink the scene")

    def _coords(self, pts: np.ndarray):
        lat, lon, h = frames.enu_to_geodetic(self.origin, pts[:, 0], pts[:, 1], pts[:, 2])
        return np.asarray(lat, float), np.asarray(lon, float), np.asarray(h, float)

    def _ground(self, a, b) -> np.ndarray:
        return self.ellipsoid_height_at(a, b)

    def _ground_bound(self, a, b, radius_m: float) -> np.ndarray:
        g = self.grid
        hy = int(math.ceil(radius_m / self.cell_m)) + 2
        hx = int(math.ceil(radius_m / self.cell_ew_min_m)) + 2
        top = max_filter(self, (hy, hx), g.values)
        i = np.clip(np.round((g.lat_max_deg - np.asarray(a)) / g.step_deg), 0,
                    g.values.shape[0] - 1)
        j = np.clip(np.round((np.asarray(b) - g.lon_min_deg) / g.step_deg), 0,
                    g.values.shape[1] - 1)
        return top[i.astype(np.intp), j.astype(np.intp)] + self.geoid_offset_m


def resolve_path(path: str) -> Path:
    """A DEM path as given: absolute, or relative to the current directory (``~`` expanded)."""
    p = Path(path).expanduser()
    return p if p.is_absolute() else Path.cwd() / p


def build_terrain(cfg: TerrainConfig, origin: frames.Origin) -> Terrain:
    """The :class:`Terrain` a validated config describes, in the frame of ``origin``."""
    kind = TerrainKind(cfg.kind)
    voids = VoidPolicy(cfg.voids).value
    los = dict(clearance_m=cfg.clearance_m, end_skip_m=cfg.end_skip_m,
               chunk_samples=cfg.chunk_samples)
    if kind is TerrainKind.flat:
        return FlatTerrain(cfg.flat_height_m)
    if kind is TerrainKind.hills:
        grid = hills_grid(cfg.hills, cfg.grid_spacing_m, cfg.hills_base_height_m)
        return GridTerrain(grid, "hills", **los)
    if kind is TerrainKind.ascii_grid:
        if not cfg.path:
            raise InputFileError("terrain.path: kind=ascii_grid needs the grid file")
        grid = dem.read_ascii_grid(resolve_path(cfg.path), voids=voids)
        return GridTerrain(grid, "ascii_grid", **los)
    if cfg.geoid_offset_m is None:
        raise InputFileError("terrain.geoid_offset_m: kind=srtm needs the geoid undulation (m)")
    grid = dem.read_hgt_tiles([resolve_path(p) for p in cfg.paths], voids=voids)
    return GeoTerrain(grid, origin, cfg.geoid_offset_m, **los)


def drape_points(terrain: Terrain, x_m, y_m) -> np.ndarray:
    """Ground z for points (road nodes) that must lie on the DEM; see :meth:`Terrain.drape`."""
    return terrain.drape(x_m, y_m)
