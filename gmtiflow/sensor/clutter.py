r"""False alarms: a constant density over the field of view plus clutter regions (paper §5.4, DESIGN §5.7).

Model
-----
Per dwell, every *source* of false alarms — the whole field of view (FoV) at
``fov_density_per_km2``, and each configured region (circle, ring or polygon) at its own
``density_per_km2`` — yields a Poisson number of false alarms, uniformly placed, with a
range-rate and an SNR drawn from the source's distributions. Densities are **per dwell** (per
CPI) and per km² of ground. Nothing is reported outside the FoV.

How "nothing outside the FoV" stays exactly Poisson: for each source and dwell we draw a Poisson
count with mean ``density × area(bounding shape)``, place the points uniformly in the bounding
shape, and keep only the points inside the source's shape *and* inside the dwell's footprint
(*thinning*). A thinned Poisson process is Poisson, so the count kept is Poisson with mean
``density × area(shape ∩ FoV)`` and the kept points are uniform over ``shape ∩ FoV`` — without
ever computing polygon intersections.  The bounding shape is drawn in directly, vectorised
over the dwells, so that few draws are thinned away:

* with footprints given as annular sectors (``fov_sectors``, what the sensor stage passes: the
  platform-centred ring sector holding each dwell's beam cell), the FoV-wide draws fill each
  dwell's sector (ground range² and azimuth uniform), and a region's draws fill its *window* in
  the sector (:func:`region_windows`: the sector cut to the ground ranges and azimuths the region
  spans as seen from the platform, exact bounds) — or the region's own shape (disc, ring or
  polygon box) when that is smaller;
* with footprints given as polygons (``fov_polygons``, a library use), the FoV-wide draws fill
  each footprint polygon itself through its fan of triangles from its centroid
  (:func:`fan_triangles`: exact when the polygon is star-shaped from its centroid, as convex
  polygons and beam-wide annular sectors are; any other polygon's draws fill its bounding box
  and are thinned by it), and a region's draws its own shape.

Randomness (DESIGN §2): counter-based draws (:func:`gmtiflow.rng.pair_uniform`) with one key per
source, ``counter_key(seed, "clutter", <region name>)`` (the FoV-wide source uses the reserved
name ``"fov"``), and counters ``(dwell_id, point index, channel)``. Hence a region's false
alarms depend only on the seed, its name, its own parameters and the dwell (and the footprint
that thins them): adding, removing or reordering other regions leaves them bit-identical, and
target detections (other keys) are untouched.  A dwell's draws depend on its own footprint only
(the bounding shape is computed per dwell), never on the chunk of dwells it is drawn with.  With
``fov_polygons`` a region's draws do not depend on the footprint (widening it only adds points);
the FoV-wide draws fill the footprint (or its bounding box), and with ``fov_sectors`` both fill
the dwell's sector or window, so they change with it.

Range rate
----------
``clutter_range_rate_mps`` is the false alarm's own radial speed relative to the stationary
ground (+ = receding), drawn from the source's distribution:

* ``gaussian``: ``mean_mps + sigma_mps · N(0, 1)`` (lake waves: 0 ± 1.5 m/s);
* ``uniform``: uniform in ``[mean_mps − half_width_mps, mean_mps + half_width_mps)``;
* ``windfarm``: rotor blades, ``mean_mps + half_width_mps · ρ · sin θ`` with ρ ~ U(0, 1) the
  scatterer's position along the blade and θ ~ U(0, 2π) the blade angle: a spread up to the
  tip speed ``half_width_mps``, peaked at zero and with shoulders out to the tips.

The sensor stage turns it into a measured range rate by adding the main-lobe clutter's range
rate at that point, ``ṙ_MLC = −v_p · LOS`` (so ground-fixed clutter sits in the clutter notch as
a real processor sees it), then wraps it with :mod:`gmtiflow.sensor.ambiguity`.

SNR
---
``snr`` is the reported SNR (linear), in the targets' convention z − 1 (z the square-law
detector output over noise, :mod:`gmtiflow.sensor.detect`). ``exceedance`` (default): a sample
that crossed the sensor's threshold η = ln(1/P_FA) (``sensor.pfa``, the same threshold as the
targets'): z = η + Exp(1) (the exponential is memoryless), reported z − 1 ≥ η − 1.
``uniform_db``: uniform in dB between ``low_db`` and ``high_db`` (e.g. strong turbine returns).
A region without an ``snr`` entry uses the config-level ``snr``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, List, Optional

import math

import numpy as np

from gmtiflow import rng, schema
from gmtiflow.errors import ConfigError
from gmtiflow.schema import Problem
from gmtiflow.sensor import detect, fastnp
from gmtiflow.sensor import regions as geo
from gmtiflow.tables import Table

RANGE_RATE_KINDS = ("gaussian", "uniform", "windfarm")
SNR_KINDS = ("exceedance", "uniform_db")
SHAPES = ("circle", "ring", "polygon")
FOV_STREAM = "fov"  # reserved stream name of the FoV-wide false alarms

# Channels of the counter-based draws: (dwell_id, point index, channel).
_CH_COUNT, _CH_U1, _CH_U2, _CH_RR1, _CH_RR2, _CH_SNR, _CH_U3 = range(7)
_KM2 = 1.0e6  # m² per km²

# The config dataclasses are not frozen: OmegaConf 2.3 cannot merge YAML list items into a list of
# frozen dataclasses (ReadonlyConfigError on ``regions[i].range_rate``). Treat them as read-only.


@dataclass
class RangeRateConfig:
    """Distribution of a false alarm's own radial speed relative to the ground (m/s, + receding)."""

    kind: str = "gaussian"        # gaussian | uniform | windfarm
    mean_mps: float = 0.0
    sigma_mps: float = 1.0        # gaussian only
    half_width_mps: float = 0.0   # uniform: ± around the mean; windfarm: blade tip speed

    def problems(self) -> List[Problem]:
        out = []
        if self.kind not in RANGE_RATE_KINDS:
            out.append(Problem("kind", f"must be one of {list(RANGE_RATE_KINDS)}, got {self.kind!r}"))
        if not (isinstance(self.mean_mps, (int, float)) and math.isfinite(self.mean_mps)):
            out.append(Problem("mean_mps", f"must be a finite number, got {self.mean_mps!r}"))
        out += schema.non_negative(self, "sigma_mps", "half_width_mps")
        return out


@dataclass
class SnrConfig:
    """Distribution of a false alarm's reported SNR (linear power over noise)."""

    kind: str = "exceedance"      # exceedance | uniform_db (threshold: sensor.pfa)
    pfa: Optional[float] = None   # removed: must stay unset (the threshold is sensor.pfa's)
    low_db: float = 10.0          # uniform_db only
    high_db: float = 20.0         # uniform_db only

    def problems(self) -> List[Problem]:
        out = []
        if self.kind not in SNR_KINDS:
            out.append(Problem("kind", f"must be one of {list(SNR_KINDS)}, got {self.kind!r}"))
        if self.pfa is not None:
            out.append(Problem("pfa", "is no longer a clutter setting: clutter false alarms use "
                                      "the detector's threshold, set sensor.pfa instead"))
        bad_db = [Problem(name, f"must be a finite number of dB, got {getattr(self, name)!r}")
                  for name in ("low_db", "high_db") if not schema.is_number(getattr(self, name))]
        out += bad_db or schema.ordered(self, "low_db", "high_db", strict=False)
        return out


@dataclass
class ClutterRegionConfig:
    """One clutter region: a circle, a ring or a polygon in scene ENU metres, with its density.

    Only the fields of its ``shape`` are read: circle — ``centre_m``, ``radius_m``; ring —
    ``centre_m``, ``inner_radius_m``, ``outer_radius_m``; polygon — ``vertices_m`` (≥ 3 points,
    simple, either winding, not closed by repeating the first point).
    """

    name: str = ""
    shape: str = "polygon"                           # circle | ring | polygon
    density_per_km2: float = 0.0                     # false alarms per km² per dwell
    centre_m: Optional[List[float]] = None           # [x, y]
    radius_m: Optional[float] = None
    inner_radius_m: Optional[float] = None
    outer_radius_m: Optional[float] = None
    vertices_m: Optional[List[Any]] = None           # [[x, y], ...] (Any: OmegaConf rejects ints in List[List[float]])
    range_rate: RangeRateConfig = field(default_factory=RangeRateConfig)
    snr: Optional[SnrConfig] = None                  # None: ClutterConfig.snr

    def problems(self) -> List[Problem]:
        out = []
        if not self.name or not isinstance(self.name, str):
            out.append(Problem("name", "must be a non-empty string (it names the region's random stream)"))
        elif self.name == FOV_STREAM:
            out.append(Problem("name", f"{FOV_STREAM!r} is reserved for the FoV-wide false alarms"))
        out += schema.in_range(self, "density_per_km2", 0.0, MAX_DENSITY_PER_KM2)
        if self.shape not in SHAPES:
            out.append(Problem("shape", f"must be one of {list(SHAPES)}, got {self.shape!r}"))
        elif self.shape in ("circle", "ring"):
            c = self.centre_m
            if c is None or len(c) != 2 or not all(_finite(v) for v in c):
                out.append(Problem("centre_m", f"must be [x, y] in metres for a {self.shape}, got {c!r}"))
            if self.shape == "circle":
                if self.radius_m is None:
                    out.append(Problem("radius_m", "is required for a circle"))
                else:
                    out += schema.positive(self, "radius_m")
            else:
                if self.inner_radius_m is None or self.outer_radius_m is None:
                    out.append(Problem("outer_radius_m" if self.inner_radius_m is not None else "inner_radius_m",
                                       "inner_radius_m and outer_radius_m are required for a ring"))
                else:
                    bad = schema.non_negative(self, "inner_radius_m") + schema.positive(self, "outer_radius_m")
                    out += bad
                    if not bad:
                        out += schema.ordered(self, "inner_radius_m", "outer_radius_m", strict=True)
        else:
            out += _polygon_problems(self.vertices_m)
        out += schema.prefixed("range_rate", self.range_rate.problems())
        if self.snr is not None:
            out += schema.prefixed("snr", self.snr.problems())
        return out

    def area_m2(self) -> float:
        """Area of the region, m² (shoelace for polygons)."""
        if self.shape == "circle":
            return geo.ring_area_m2(0.0, float(self.radius_m))
        if self.shape == "ring":
            return geo.ring_area_m2(float(self.inner_radius_m), float(self.outer_radius_m))
        return geo.polygon_area_m2(self.vertices_m)

    def contains(self, x_m, y_m) -> np.ndarray:
        """Boolean mask of points inside the region."""
        x = np.asarray(x_m, float)
        y = np.asarray(y_m, float)
        if self.shape == "polygon":
            return geo.points_in_polygon(x, y, self.vertices_m)
        r2 = (x - self.centre_m[0]) ** 2 + (y - self.centre_m[1]) ** 2
        if self.shape == "circle":
            return r2 < float(self.radius_m) ** 2
        return (r2 >= float(self.inner_radius_m) ** 2) & (r2 < float(self.outer_radius_m) ** 2)

    def bbox(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) of the region."""
        if self.shape == "polygon":
            return geo.bounding_box(self.vertices_m)
        r = float(self.radius_m if self.shape == "circle" else self.outer_radius_m)
        cx, cy = float(self.centre_m[0]), float(self.centre_m[1])
        return cx - r, cy - r, cx + r, cy + r


def _default_fov_range_rate() -> RangeRateConfig:
    return RangeRateConfig(kind="uniform", mean_mps=0.0, sigma_mps=0.0, half_width_mps=30.0)


MAX_DENSITY_PER_KM2 = 1e4
"""One false alarm per 100 m² per dwell is already far beyond any radar's clutter: the cap
bounds the Poisson draws (issue 17, item 11)."""


@dataclass
class ClutterConfig:
    """False-alarm configuration (config group ``clutter``).

    ``fov_density_per_km2``: thermal-noise/background false alarms per km² of the dwell's ground
    footprint per dwell; ``fov_range_rate`` their radial-speed distribution (default uniform
    ±30 m/s, i.e. spread over the Doppler band; the ambiguity stage wraps it); ``snr`` the default
    SNR distribution; ``regions`` the clutter regions (unique names).
    """

    fov_density_per_km2: float = 0.0
    fov_range_rate: RangeRateConfig = field(default_factory=_default_fov_range_rate)
    snr: SnrConfig = field(default_factory=SnrConfig)
    regions: List[ClutterRegionConfig] = field(default_factory=list)

    def problems(self) -> List[Problem]:
        out = schema.in_range(self, "fov_density_per_km2", 0.0, MAX_DENSITY_PER_KM2)
        out += schema.prefixed("fov_range_rate", self.fov_range_rate.problems())
        out += schema.prefixed("snr", self.snr.problems())
        seen = {}
        for i, region in enumerate(self.regions):
            out += schema.prefixed(f"regions[{i}]", region.problems())
            if region.name and region.name in seen:
                out.append(Problem(f"regions[{i}].name",
                                   f"duplicates regions[{seen[region.name]}].name {region.name!r}; "
                                   "names must be unique (each names a random stream)"))
            seen.setdefault(region.name, i)
        return out


def check(cfg: ClutterConfig, key: str = "clutter") -> None:
    """Raise one :class:`ConfigError` listing every problem of ``cfg`` under the key ``key``."""
    problems = cfg.problems()
    if problems:
        lines = [f"{key}.{p.key}: {p.message}" for p in problems]
        raise ConfigError("invalid clutter config:\n  " + "\n  ".join(lines))


def is_active(cfg: Optional[ClutterConfig]) -> bool:
    """True if the config can produce any false alarm. When False, call nothing else here."""
    return cfg is not None and (cfg.fov_density_per_km2 > 0
                                or any(r.density_per_km2 > 0 for r in cfg.regions))


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _polygon_problems(vertices) -> List[Problem]:
    if vertices is None:
        return [Problem("vertices_m", "is required for a polygon: [[x, y], ...] in metres")]
    pts = list(vertices)
    if any(not hasattr(p, "__len__") or len(p) != 2 or not all(_finite(v) for v in p) for p in pts):
        return [Problem("vertices_m", "every vertex must be [x, y] with finite numbers in metres")]
    v = geo.as_polygon(pts) if pts else np.zeros((0, 2))
    if len(v) < 3:
        return [Problem("vertices_m", f"a polygon needs at least 3 distinct vertices, got {len(v)}")]
    if geo.polygon_self_intersects(v):
        return [Problem("vertices_m", "the polygon intersects itself (edges cross or a vertex repeats); "
                                      "list the vertices in order around the boundary")]
    if geo.polygon_area_m2(v) <= 0:
        return [Problem("vertices_m", "the polygon has zero area (collinear vertices)")]
    return []


# --------------------------------------------------------------------------------------------
# Drawing


def _poisson_counts(key, dwell_id: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """One Poisson count per dwell by inversion of a counter-based uniform (exactly Poisson)."""
    u = rng.pair_uniform(key, dwell_id, 0, _CH_COUNT)
    counts = np.zeros(len(dwell_id), dtype=np.int64)
    pos = mean > 0
    if np.any(pos):
        # scipy.stats.poisson.ppf's values from scipy.special: scipy.stats costs ~1 s to import
        from gmtiflow.sensor.noise import poisson_ppf
        counts[pos] = poisson_ppf(u[pos], mean[pos]).astype(np.int64)
    return counts


def _expand(dwell_id: np.ndarray, counts: np.ndarray):
    """Per point: its dwell's batch position and its index within the dwell."""
    batch = np.repeat(np.arange(len(dwell_id)), counts)
    starts = np.cumsum(counts) - counts
    index = np.arange(int(counts.sum())) - np.repeat(starts, counts)
    return batch, index


def _draw_range_rate(key, d, i, cfg: RangeRateConfig) -> np.ndarray:
    if cfg.kind == "gaussian":
        return cfg.mean_mps + cfg.sigma_mps * rng.pair_normal(key, d, i, _CH_RR1)
    u1 = rng.pair_uniform(key, d, i, _CH_RR1)
    if cfg.kind == "uniform":
        return cfg.mean_mps + cfg.half_width_mps * (2.0 * u1 - 1.0)
    u2 = rng.pair_uniform(key, d, i, _CH_RR2)
    return cfg.mean_mps + cfg.half_width_mps * u1 * np.sin(2.0 * np.pi * u2)


def _draw_snr(key, d, i, cfg: SnrConfig, pfa: float) -> np.ndarray:
    u = rng.pair_uniform(key, d, i, _CH_SNR)
    if cfg.kind == "exceedance":
        return detect.false_alarm_snr(u, pfa)
    return 10.0 ** ((cfg.low_db + (cfg.high_db - cfg.low_db) * u) / 10.0)


def _empty() -> Table:
    return {"dwell_id": np.zeros(0, np.int64), "x_m": np.zeros(0), "y_m": np.zeros(0),
            "clutter_range_rate_mps": np.zeros(0), "snr": np.zeros(0), "snr_db": np.zeros(0),
            "region_index": np.zeros(0, np.int64)}


def _draw_source(seed: int, name: str, region_index: int, dwell_id: np.ndarray, mean: np.ndarray,
                 place: Callable, keep: Callable, rr: RangeRateConfig, snr: SnrConfig,
                 pfa: float) -> Table:
    """Poisson counts, placement in the bounding shape, thinning, marks — for one source.

    ``place(u1, u2, batch, u3)`` maps two uniforms per point (``u3()`` gives a third) to
    positions; ``keep(x, y, batch)`` is the thinning mask."""
    key = rng.counter_key(seed, "clutter", name)
    counts = _poisson_counts(key, dwell_id, mean)
    batch, index = _expand(dwell_id, counts)
    d = dwell_id[batch]
    x, y = place(rng.pair_uniform(key, d, index, _CH_U1), rng.pair_uniform(key, d, index, _CH_U2),
                 batch, lambda: rng.pair_uniform(key, d, index, _CH_U3))
    ok = keep(x, y, batch)
    batch, index, d, x, y = batch[ok], index[ok], d[ok], x[ok], y[ok]
    s = _draw_snr(key, d, index, snr, pfa)
    return {"dwell_id": d.astype(np.int64), "x_m": x, "y_m": y,
            "clutter_range_rate_mps": _draw_range_rate(key, d, index, rr),
            "snr": s, "snr_db": 10.0 * np.log10(s),
            "region_index": np.full(len(d), region_index, dtype=np.int64)}


def false_alarms(cfg: ClutterConfig, seed: int, dwell_id, fov_polygons=None,
                 in_fov: Optional[Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]] = None,
                 *, fov_sectors=None, pfa: float = 1.0e-6) -> Table:
    """False alarms of a batch of dwells.

    Parameters
    ----------
    cfg : ClutterConfig
    seed : int
        The run's root seed.
    dwell_id : (n,) int array
        Ids of the dwells in the batch (unique).
    fov_polygons : (n, k, 2) array or sequence of n (k_i, 2) arrays, optional
        Each dwell's ground footprint in scene ENU metres (e.g. the annular sector between the
        near and far ground ranges and the beam's azimuth edges, as a polygon). Required when
        ``fov_density_per_km2 > 0`` (the FoV-wide draws fill it, see the module doc).
    in_fov : callable ``(dwell_id, x_m, y_m) -> bool array``, optional
        An extra FoV predicate applied to every candidate point (e.g. the sensor's exact range,
        azimuth and grazing limits, or terrain visibility). Called once per source with all the
        batch's candidate points.
    fov_sectors : (n, 6) array ``x_m, y_m, g_min_m, g_max_m, az_start_rad, span_rad``, optional
        Instead of ``fov_polygons``: an annular sector per dwell (centre, ground ranges, world
        azimuths clockwise from north) containing its footprint, with ``in_fov`` the exact
        footprint test.  FoV-wide false alarms are drawn uniformly in the sector itself, a
        region's in its window in the sector (:func:`region_windows`) or in its own shape,
        whichever is smaller (no polygon built or tested, no bounding-box rejection; what the
        sensor stage uses).
    pfa : float
        The detector's false-alarm probability (``sensor.pfa``): the threshold of the
        ``exceedance`` SNR.

    Returns
    -------
    Table
        ``dwell_id``, ``x_m``, ``y_m`` (ground, ENU), ``clutter_range_rate_mps`` (own radial speed
        relative to the ground, see the module doc), ``snr`` (linear), ``snr_db``,
        ``region_index`` (−1 for the FoV-wide density, else the index in ``cfg.regions``).
        Rows by source (FoV first, then regions in config order), then dwell, then draw index.
    """
    if not is_active(cfg):
        return _empty()
    dwell_id = np.asarray(dwell_id, dtype=np.int64).ravel()
    sectors = None
    if fov_sectors is not None:
        if fov_polygons is not None or in_fov is None:
            raise ValueError("fov_sectors goes with an exact in_fov predicate and no fov_polygons")
        sectors = np.asarray(fov_sectors, float).reshape(-1, 6)
        if len(sectors) != len(dwell_id):
            raise ValueError(f"fov_sectors has {len(sectors)} sectors for {len(dwell_id)} dwells")
    if fov_polygons is None and in_fov is None:
        raise ValueError("false_alarms needs the dwells' footprints (fov_polygons) or an in_fov "
                         "predicate: nothing may be drawn outside the field of view")
    polys = None
    if fov_polygons is not None:
        polys = geo.stack_polygons(fov_polygons)
        if len(polys) != len(dwell_id):
            raise ValueError(f"fov_polygons has {len(polys)} footprints for {len(dwell_id)} dwells")
        fx0, fy0 = polys[:, :, 0].min(axis=1), polys[:, :, 1].min(axis=1)
        fx1, fy1 = polys[:, :, 0].max(axis=1), polys[:, :, 1].max(axis=1)
    elif sectors is not None:
        fx0, fy0, fx1, fy1 = sector_boxes(sectors)

    def in_footprint(x, y, batch):
        ok = np.ones(len(x), dtype=bool)
        if polys is not None:
            ok &= geo.points_in_polygons(x, y, polys, batch)
        if in_fov is not None and len(x):
            ok &= np.asarray(in_fov(dwell_id[batch], x, y), dtype=bool)
        return ok

    out = []
    if cfg.fov_density_per_km2 > 0:
        if polys is None and sectors is None:
            raise ValueError("fov_density_per_km2 > 0 needs fov_polygons (the footprints bound the "
                             "FoV-wide draws); an in_fov predicate alone cannot give an area")
        if sectors is not None:
            cx, cy, g0, g1, a0, span = sectors.T
            fov_area = 0.5 * span * (g1 * g1 - g0 * g0)

            def place_fov(u1, u2, batch, u3=None):
                # uniform over the annulus: g^2 uniform between g0^2 and g1^2
                g = np.sqrt(g0[batch] ** 2 + u1 * (g1[batch] ** 2 - g0[batch] ** 2))
                a = a0[batch] + u2 * span[batch]
                return cx[batch] + g * np.sin(a), cy[batch] + g * np.cos(a)
            keep_fov = in_footprint
        else:
            # Each footprint polygon star-shaped from its centroid (a convex one, or the annular
            # sector of a beam) is cut into the fan of triangles (centroid, edge): a point is
            # drawn in a triangle chosen by area, uniformly in it — exactly in the polygon, no
            # thinning by it.  Any other polygon: its bounding box, thinned by the polygon.
            fan = fan_triangles(polys)
            star = fan["star"]
            fov_area = np.where(star, fan["area"], (fx1 - fx0) * (fy1 - fy0))

            def place_fov(u1, u2, batch, u3):
                x, y = fan_point(fan, polys, u1, u2, u3(), batch)
                box = ~star[batch]
                if np.any(box):
                    x[box] = fx0[batch[box]] + u1[box] * (fx1 - fx0)[batch[box]]
                    y[box] = fy0[batch[box]] + u2[box] * (fy1 - fy0)[batch[box]]
                return x, y

            def keep_fov(x, y, batch):
                ok = np.ones(len(x), dtype=bool)
                box = np.flatnonzero(~star[batch])
                ok[box] = geo.points_in_polygons(x[box], y[box], polys, batch[box])
                if in_fov is not None and len(x):
                    ok &= np.asarray(in_fov(dwell_id[batch], x, y), dtype=bool)
                return ok

        out.append(_draw_source(seed, FOV_STREAM, -1, dwell_id, cfg.fov_density_per_km2 * fov_area / _KM2,
                                place_fov, keep_fov, cfg.fov_range_rate, cfg.snr, pfa))

    for j, region in enumerate(cfg.regions):
        if region.density_per_km2 <= 0:
            continue
        if sectors is not None:
            out.append(_draw_region_in_sectors(seed, j, region, dwell_id, sectors,
                                               (fx0, fy0, fx1, fy1), in_footprint, cfg.snr, pfa))
            continue
        bx0, by0, bx1, by1 = region.bbox()
        if region.shape == "polygon":
            area = (bx1 - bx0) * (by1 - by0)

            def place(u1, u2, batch, u3=None, b=(bx0, by0, bx1, by1)):
                return b[0] + u1 * (b[2] - b[0]), b[1] + u2 * (b[3] - b[1])

            def keep(x, y, batch, r=region):
                inside = r.contains(x, y)
                out_ok = np.zeros(len(x), dtype=bool)
                out_ok[inside] = in_footprint(x[inside], y[inside], batch[inside])
                return out_ok
        else:
            inner = 0.0 if region.shape == "circle" else float(region.inner_radius_m)
            outer = float(region.radius_m if region.shape == "circle" else region.outer_radius_m)
            area = geo.ring_area_m2(inner, outer)

            def place(u1, u2, batch, u3=None, c=tuple(region.centre_m), a=inner, b=outer):
                return geo.sample_disc(u1, u2, c, a, b)

            keep = in_footprint
        mean = np.full(len(dwell_id), region.density_per_km2 * area / _KM2)
        if polys is not None or sectors is not None:  # skip dwells whose box misses the region
            mean[(fx1 < bx0) | (fx0 > bx1) | (fy1 < by0) | (fy0 > by1)] = 0.0
        out.append(_draw_source(seed, region.name, j, dwell_id, mean, place, keep,
                                region.range_rate, region.snr or cfg.snr, pfa))
    if not out:
        return _empty()
    return {name: np.concatenate([t[name] for t in out]) for name in out[0]}


def fan_triangles(polys: np.ndarray) -> dict:
    """The fan of triangles (centroid, v_i, v_i+1) of each polygon of a (n, k, 2) stack.

    Returns ``cx, cy`` (n,) the area centroids, ``area`` (n,) the polygons' areas (m²),
    ``star`` (n,) bool: every triangle of the fan has the polygon's orientation (to 1e-12 of
    its area), i.e. the polygon is star-shaped from its centroid and the fan tiles it exactly;
    ``cum`` (n·k,) the polygons' cumulative triangle areas as fractions, offset by the
    polygon's index (sorted: the search key of :func:`fan_point`).
    """
    v = np.asarray(polys, float)
    n, k = v.shape[:2]
    w = np.roll(v, -1, axis=1)
    cross = v[..., 0] * w[..., 1] - v[..., 1] * w[..., 0]
    a2 = cross.sum(axis=1)                                   # twice the signed area
    safe = np.where(a2 != 0.0, a2, 1.0)
    cx = ((v[..., 0] + w[..., 0]) * cross).sum(axis=1) / (3.0 * safe)
    cy = ((v[..., 1] + w[..., 1]) * cross).sum(axis=1) / (3.0 * safe)
    tri = ((v[..., 0] - cx[:, None]) * (w[..., 1] - cy[:, None])
           - (v[..., 1] - cy[:, None]) * (w[..., 0] - cx[:, None])) * np.sign(a2)[:, None]
    star = (a2 != 0.0) & np.all(tri >= -1e-12 * np.abs(a2)[:, None], axis=1)
    tri = np.where(star[:, None], np.maximum(tri, 0.0), 1.0)
    frac = np.cumsum(tri, axis=1)
    frac /= frac[:, -1:]
    frac[:, -1] = 1.0
    return {"cx": cx, "cy": cy, "area": 0.5 * np.abs(a2), "star": star,
            "cum": (np.arange(n)[:, None] + frac).ravel()}


def fan_point(fan: dict, polys: np.ndarray, u1, u2, u3, batch):
    """Points uniform in polygons ``polys[batch]`` (star-shaped from their centroids, see
    :func:`fan_triangles`): ``u1`` picks the triangle by area, ``u2``, ``u3`` place the point
    in it (√u2 along the apex → edge direction, so the density is uniform)."""
    k = polys.shape[1]
    j = np.searchsorted(fan["cum"], batch + u1, side="right")
    e = np.clip(j - batch * k, 0, k - 1)
    e2 = (e + 1) % k
    cx, cy = fan["cx"][batch], fan["cy"][batch]
    s = np.sqrt(u2)
    ax, ay = polys[batch, e, 0] - cx, polys[batch, e, 1] - cy
    bx, by = polys[batch, e2, 0] - cx, polys[batch, e2, 1] - cy
    return cx + s * (ax + u3 * (bx - ax)), cy + s * (ay + u3 * (by - ay))


def _wrap(a):
    """Angles wrapped to [−π, π)."""
    return fastnp.mod(a + np.pi, 2.0 * np.pi) - np.pi


def region_windows(region: ClutterRegionConfig, sectors: np.ndarray):
    """Per dwell, the part of its annular sector that can hold points of ``region``.

    ``sectors`` (n, 6) ``x, y, g_min, g_max, az_start, span`` as in :func:`false_alarms`.
    Returns ``(g0, g1, a0, span)`` arrays: an annular sector (same centre) containing
    ``region ∩ sector``, the sector cut to the region's ground ranges and azimuths seen from the
    sector's centre; ``span = 0`` where they cannot meet.  Exact bounds, no sampling:

    * ranges: the farthest point of a polygon is a vertex, the nearest (centre outside it) lies on
      an edge; a circle or ring at distance D spans D − R … D + R (0 … when the centre is inside);
    * azimuths (centre outside the region): every ray to a polygon's point crosses its boundary,
      so the polygon's directions are the union of its edges' (each < π wide, the centre being
      on no edge); a disc at distance D > R spans its centre's azimuth ± asin(R/D).  With the
      centre inside the region (or within a metre of its boundary) every azimuth of the sector
      stays.
    """
    cx, cy, g0, g1, a0, span = np.asarray(sectors, float).T
    half = 0.5 * span
    psi = a0 + half                                      # each sector's central azimuth
    # (vertex or edge, dwell) arrays: the reductions over a dwell's few vertices are then
    # element-wise over rows (numpy reduces a short last axis row by row, far slower)
    if region.shape == "polygon":
        v = geo.as_polygon(region.vertices_m)
        dx = v[:, 0, None] - cx
        dy = v[:, 1, None] - cy
        far = np.hypot(dx, dy).max(axis=0)
        ex, ey = np.roll(dx, -1, axis=0) - dx, np.roll(dy, -1, axis=0) - dy
        t = np.clip(-(dx * ex + dy * ey) / (ex * ex + ey * ey), 0.0, 1.0)
        near = np.hypot(dx + t * ex, dy + t * ey).min(axis=0)
        inside = region.contains(cx, cy)
        around = inside | (near < 1.0)
        near = np.where(inside, 0.0, near)
        rel = _wrap((np.arctan2(dx, dy) - psi).ravel()).reshape(dx.shape)  # about psi
        turn = _wrap((np.roll(rel, -1, axis=0) - rel).ravel()).reshape(dx.shape)  # edge widths
        lo_e, hi_e = np.minimum(rel, rel + turn), np.maximum(rel, rel + turn)
    else:
        ccx, ccy = float(region.centre_m[0]), float(region.centre_m[1])
        outer = float(region.radius_m if region.shape == "circle" else region.outer_radius_m)
        inner = 0.0 if region.shape == "circle" else float(region.inner_radius_m)
        dist = np.hypot(ccx - cx, ccy - cy)
        far = dist + outer
        near = np.maximum(np.maximum(dist - outer, inner - dist), 0.0)
        around = dist <= outer * (1.0 + 1e-9) + 1.0
        rel = _wrap(np.arctan2(ccx - cx, ccy - cy) - psi)[None, :]
        w = np.arcsin(np.minimum(outer / np.maximum(dist, 1e-300), 1.0))[None, :]
        lo_e, hi_e = rel - w, rel + w
    # The edges' (or the disc's) azimuth intervals cut to the sector [−half, half] around psi;
    # an interval reaching past ±π is also tried one turn round.
    lo = np.full(len(cx), np.inf)
    hi = np.full(len(cx), -np.inf)
    for shift in (0.0, 2.0 * np.pi, -2.0 * np.pi):
        l = np.maximum(lo_e + shift, -half)
        u = np.minimum(hi_e + shift, half)
        ok = u >= l
        lo = np.minimum(lo, np.where(ok, l, np.inf).min(axis=0))
        hi = np.maximum(hi, np.where(ok, u, -np.inf).max(axis=0))
    lo = np.where(around, -half, lo)
    hi = np.where(around, half, hi)
    # a hair of margin against rounding (the exact tests thin the draws anyway)
    lo = np.maximum(lo - 1e-9, -half)
    hi = np.minimum(hi + 1e-9, half)
    w0 = np.maximum(g0, near * (1.0 - 1e-12) - 1e-6)
    w1 = np.minimum(g1, far * (1.0 + 1e-12) + 1e-6)
    empty = ~((hi > lo) & (w1 > w0))
    w_span = np.where(empty, 0.0, hi - lo)
    return (np.where(empty, g0, w0), np.where(empty, g0, w1), psi + np.where(empty, 0.0, lo),
            w_span)


def _draw_region_in_sectors(seed, j, region, dwell_id, sectors, boxes, in_footprint, snr_default,
                            pfa) -> Table:
    """One region's false alarms for dwells whose footprints come as annular sectors: per dwell,
    candidates drawn in the smaller of the region's own bounding shape (disc, ring or polygon
    box) and its window in the dwell's sector (:func:`region_windows`), then thinned by the
    region and the exact footprint test."""
    cx, cy = sectors[:, 0], sectors[:, 1]
    g0, g1, a0, span = region_windows(region, sectors)
    window_area = 0.5 * span * (g1 * g1 - g0 * g0)
    bx0, by0, bx1, by1 = region.bbox()
    fx0, fy0, fx1, fy1 = boxes
    if region.shape == "polygon":
        own_area = (bx1 - bx0) * (by1 - by0)
        inner = outer = 0.0
    else:
        inner = 0.0 if region.shape == "circle" else float(region.inner_radius_m)
        outer = float(region.radius_m if region.shape == "circle" else region.outer_radius_m)
        own_area = geo.ring_area_m2(inner, outer)
    misses = (fx1 < bx0) | (fx0 > bx1) | (fy1 < by0) | (fy0 > by1) | (span <= 0.0)
    polar = window_area < own_area
    area = np.where(misses, 0.0, np.where(polar, window_area, own_area))
    centre = tuple(region.centre_m) if region.shape != "polygon" else None

    def place(u1, u2, batch, u3=None):
        p = polar[batch]
        g = np.sqrt(g0[batch] ** 2 + u1 * (g1[batch] ** 2 - g0[batch] ** 2))
        a = a0[batch] + u2 * span[batch]
        x, y = cx[batch] + g * np.sin(a), cy[batch] + g * np.cos(a)
        if np.all(p):
            return x, y
        if centre is None:
            xo, yo = bx0 + u1 * (bx1 - bx0), by0 + u2 * (by1 - by0)
        else:
            xo, yo = geo.sample_disc(u1, u2, centre, inner, outer)
        return np.where(p, x, xo), np.where(p, y, yo)

    def keep(x, y, batch):
        inside = region.contains(x, y)
        if centre is not None:          # points drawn in the disc or ring itself are in it
            inside |= ~polar[batch]
        ok = np.zeros(len(x), dtype=bool)
        ok[inside] = in_footprint(x[inside], y[inside], batch[inside])
        return ok

    return _draw_source(seed, region.name, j, dwell_id, region.density_per_km2 * area / _KM2,
                        place, keep, region.range_rate, region.snr or snr_default, pfa)


def sector_boxes(sectors: np.ndarray, n_arc: int = 16):
    """Bounding boxes ``(x_min, y_min, x_max, y_max)`` of annular sectors
    ``(x, y, g_min, g_max, az_start, span)`` (arrays over the sectors, no Python loop): the
    extremes of ``n_arc`` points per arc, the far arc pushed out by its chord sag."""
    cx, cy, g0, g1, a0, span = np.asarray(sectors, float).T
    # (n_arc, n): an arc point a row, so the extremes are element-wise minima and maxima of
    # rows (numpy reduces a short last axis row by row, ~10x slower)
    az = a0 + span * np.linspace(0.0, 1.0, n_arc)[:, None]
    sag = g1 * (1.0 - np.cos(0.5 * span / (n_arc - 1)))
    far = g1 + sag
    sin_az, cos_az = np.sin(az), np.cos(az)          # once each (the same values)
    x_far, x_near = far * sin_az + cx, g0 * sin_az + cx
    y_far, y_near = far * cos_az + cy, g0 * cos_az + cy
    return (np.minimum(x_far.min(axis=0), x_near.min(axis=0)),
            np.minimum(y_far.min(axis=0), y_near.min(axis=0)),
            np.maximum(x_far.max(axis=0), x_near.max(axis=0)),
            np.maximum(y_far.max(axis=0), y_near.max(axis=0)))


def annular_sector_polygon(centre_m, range_min_m: float, range_max_m: float, az_min_rad: float,
                           az_max_rad: float, n_arc: int = 16) -> np.ndarray:
    """Polygon of a ground footprint between two ground ranges and two world azimuths.

    Azimuth clockwise from north; ``az_max_rad`` is taken after ``az_min_rad`` going clockwise.
    ``n_arc`` vertices per arc: the chord error at range R over a beam of width w is R·w²/(8 n²).
    """
    span = np.mod(az_max_rad - az_min_rad, 2.0 * np.pi)
    az = az_min_rad + span * np.linspace(0.0, 1.0, n_arc)
    far = np.column_stack([range_max_m * np.sin(az), range_max_m * np.cos(az)])
    near = np.column_stack([range_min_m * np.sin(az[::-1]), range_min_m * np.cos(az[::-1])])
    return np.vstack([far, near]) + np.asarray(centre_m, float)[:2]
