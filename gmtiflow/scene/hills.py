"""Synthetic terrain: Gaussian hills and ridges in scene ENU metres (``terrain.kind: hills``).

:class:`HillConfig` is one hill's schema (listed under ``terrain.hills``); :func:`hills_height`
is the exact height and :func:`hills_grid` the generated grid that
:class:`~gmtiflow.scene.terrain.GridTerrain` interpolates.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Sequence

import numpy as np

from gmtiflow import schema
from gmtiflow.scene import dem


@dataclass
class HillConfig:
    """A Gaussian hill (``length_m = 0``) or ridge in ENU metres.

    Height ``height_m * exp(-d² / (2 sigma_m²))`` where d is the horizontal distance to the crest:
    the point (x_m, y_m) for a hill, or the segment of ``length_m`` centred there and running
    along ``azimuth_deg`` (clockwise from north: 90 = east-west) for a ridge.
    """

    x_m: float = 0.0
    y_m: float = 0.0
    height_m: float = 100.0
    sigma_m: float = 500.0
    length_m: float = 0.0
    azimuth_deg: float = 90.0

    def problems(self) -> List[schema.Problem]:
        out = schema.positive(self, "sigma_m")
        out += schema.non_negative(self, "length_m")
        for name in ("x_m", "y_m", "azimuth_deg"):
            v = getattr(self, name)
            if not math.isfinite(v):
                out.append(schema.Problem(name, f"must be finite, got {v!r}"))
        out += schema.in_range(self, "height_m", *dem.MAP_Z_RANGE_M)
        return out


def hills_extent(hills: Sequence[HillConfig], spacing: float):
    """ENU box (x0, x1, y0, y1) covering every hill to 5 sigma, on the grid."""
    xs, ys = [], []
    for h in hills:
        az = math.radians(h.azimuth_deg)
        ax, ay = 0.5 * h.length_m * math.sin(az), 0.5 * h.length_m * math.cos(az)
        r = 5.0 * h.sigma_m + spacing
        xs += [h.x_m - abs(ax) - r, h.x_m + abs(ax) + r]
        ys += [h.y_m - abs(ay) - r, h.y_m + abs(ay) + r]
    x0 = math.floor(min(xs) / spacing) * spacing
    y0 = math.floor(min(ys) / spacing) * spacing
    x1 = math.ceil(max(xs) / spacing) * spacing
    y1 = math.ceil(max(ys) / spacing) * spacing
    return x0, x1, y0, y1


def hills_height(hills: Sequence[HillConfig], x_m, y_m, base_m: float = 0.0) -> np.ndarray:
    """Exact (analytic) height of a hills terrain at ENU (x, y): base + sum of the hills."""
    x = np.asarray(x_m, float)
    y = np.asarray(y_m, float)
    z = np.full(np.broadcast_shapes(x.shape, y.shape), float(base_m))
    for h in hills:
        az = math.radians(h.azimuth_deg)
        ax, ay = math.sin(az), math.cos(az)
        dx, dy = x - h.x_m, y - h.y_m
        along = np.clip(dx * ax + dy * ay, -0.5 * h.length_m, 0.5 * h.length_m)
        ex, ey = dx - along * ax, dy - along * ay
        z = z + h.height_m * np.exp(-(ex * ex + ey * ey) / (2.0 * h.sigma_m ** 2))
    return z


def hills_grid(hills: Sequence[HillConfig], spacing_m: float, base_m: float = 0.0) -> dem.EnuGrid:
    """The generated grid of a hills terrain (covers every hill to 5 sigma; base outside)."""
    if not hills:
        x0 = y0 = -spacing_m
        x1 = y1 = spacing_m
    else:
        x0, x1, y0, y1 = hills_extent(hills, spacing_m)
    xs = x0 + spacing_m * np.arange(int(round((x1 - x0) / spacing_m)) + 1)
    ys = y0 + spacing_m * np.arange(int(round((y1 - y0) / spacing_m)) + 1)
    z = hills_height(hills, xs[None, :], ys[:, None], base_m)
    return dem.EnuGrid(z=z, x0_m=float(xs[0]), y0_m=float(ys[0]), dx_m=spacing_m, dy_m=spacing_m,
                       source=f"hills terrain ({len(hills)} hills, {spacing_m:g} m grid)",
                       outside_z_m=float(base_m))
