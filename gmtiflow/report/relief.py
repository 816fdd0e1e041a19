"""Terrain relief for the map page and the scene viewer: the run's DEM, shaded.

The DEM is not in ``run.h5``; the run's ``/config`` names it (``terrain.kind`` and its paths or
hills), so :func:`run_terrain` rebuilds the same :class:`~gmtiflow.scene.terrain.Terrain` the
simulation used (same loader, same geoid offset, same frame) and :func:`relief_grid` samples its
heights on a coarse grid over the map's extent.  Rebuilding rather than storing a copy keeps
the run file's layout unchanged and costs a DEM read (~0.1 s for an SRTM tile); a run whose DEM
file has moved since is drawn without relief, and the page says so.

:func:`hillshade_rgba` shades the grid with matplotlib's :class:`~matplotlib.colors.LightSource`
(light from the north-west, 45° up): slopes in shadow are brown, level and lit ground white, so
the roads and detections drawn over it stay legible.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from gmtiflow.frames import Origin


@dataclass
class Relief:
    """Ground heights on a regular grid in the scene's ENU frame (row = north, column = east)."""

    x_m: np.ndarray          # (nx,) cell centres, east
    y_m: np.ndarray          # (ny,) cell centres, north
    height_m: np.ndarray     # (ny, nx) ENU z of the ground; NaN off the DEM
    source: str              # "hills", "srtm N43E007.hgt", ...

    @property
    def extent_m(self) -> Tuple[float, float, float, float]:
        """(left, right, bottom, top) of the cells' outer edges, for ``imshow``."""
        dx = self.x_m[1] - self.x_m[0] if len(self.x_m) > 1 else 1.0
        dy = self.y_m[1] - self.y_m[0] if len(self.y_m) > 1 else 1.0
        return (self.x_m[0] - dx / 2, self.x_m[-1] + dx / 2,
                self.y_m[0] - dy / 2, self.y_m[-1] + dy / 2)


def run_terrain(config: dict, origin: Origin):
    """(terrain, note): the run's terrain rebuilt from its resolved config, or (None, why not).

    Flat ground gives (None, "") — nothing to shade.  A DEM that cannot be read any more gives
    (None, the reason), for the page to show.
    """
    from omegaconf import OmegaConf
    from omegaconf.errors import OmegaConfBaseException

    from gmtiflow.errors import GmtiflowError
    from gmtiflow.scene.terrain import build_terrain
    from gmtiflow.scene.terrain_config import TerrainConfig, TerrainKind

    section = config.get("terrain") if isinstance(config, dict) else None
    if not isinstance(section, dict) or section.get("kind", "flat") == "flat":
        return None, ""
    try:
        cfg = OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(TerrainConfig), section))
        if TerrainKind(cfg.kind) is TerrainKind.flat:
            return None, ""
        return build_terrain(cfg, origin), ""
    except (GmtiflowError, OmegaConfBaseException, ValueError, OSError) as exc:
        return None, f"terrain not shaded: {str(exc).splitlines()[0][:120]}"


def terrain_source(config: dict) -> str:
    """A short name of the run's terrain for legends: ``hills``, ``srtm N43E007.hgt`` ..."""
    import os
    section = config.get("terrain") if isinstance(config, dict) else {}
    kind = str((section or {}).get("kind", "flat"))
    files = [os.path.basename(str(p)) for p in (section.get("paths") or [])] + (
        [os.path.basename(str(section["path"]))] if section.get("path") else [])
    return f"{kind} {', '.join(files)}".strip()


def relief_grid(terrain, x_lim_m: Tuple[float, float], y_lim_m: Tuple[float, float], *,
                cells: int = 160, source: str = "") -> Optional[Relief]:
    """Heights of ``terrain`` on a grid of at most ``cells`` × ``cells`` over the limits (the
    longer side gets ``cells``); None when none of it lies on the DEM."""
    (x0, x1), (y0, y1) = sorted(x_lim_m), sorted(y_lim_m)
    span = max(x1 - x0, y1 - y0, 1.0)
    step = span / cells
    x = np.arange(x0 + step / 2, x1, step)
    y = np.arange(y0 + step / 2, y1, step)
    if len(x) < 2 or len(y) < 2:
        return None
    gx, gy = np.meshgrid(x, y)
    z = np.asarray(terrain.height_at(gx.ravel(), gy.ravel()), float).reshape(gy.shape)
    if not np.isfinite(z).any():
        return None
    return Relief(x, y, z, source)


def shadow(relief: Relief) -> np.ndarray:
    """(ny, nx) in [0, 1]: 0 where the ground is level or faces the light, towards 1 the more
    a slope faces away from it (light from the north-west, 45° up; matplotlib's LightSource)."""
    from matplotlib.colors import LightSource

    z = relief.height_m
    filled = np.where(np.isfinite(z), z, np.nanmin(z))
    dx = float(relief.x_m[1] - relief.x_m[0])
    dy = float(relief.y_m[1] - relief.y_m[0])
    ls = LightSource(azdeg=315, altdeg=45)
    # LightSource takes row 0 as the north edge; the grid's row 0 is the south edge.
    intensity = ls.hillshade(filled[::-1], vert_exag=1.0, dx=dx, dy=dy, fraction=1.0)[::-1]
    level = ls.hillshade(np.zeros((3, 3)), dx=dx, dy=dy)[1, 1]       # a level cell's value
    return np.clip((level - intensity) / max(level, 1e-9), 0.0, 1.0)


def hillshade_rgba(relief: Relief, *, strength: float = 0.8) -> np.ndarray:
    """(ny, nx, 4) RGBA of :func:`shadow`: white where level or lit, brown in shadow, so roads
    and detections drawn over it stay legible; transparent off the DEM."""
    brown = np.array([0.45, 0.33, 0.2])
    rgba = np.ones(relief.height_m.shape + (4,))
    rgba[..., :3] = 1.0 - strength * shadow(relief)[..., None] * (1.0 - brown)
    rgba[..., 3] = np.where(np.isfinite(relief.height_m), 1.0, 0.0)
    return rgba
