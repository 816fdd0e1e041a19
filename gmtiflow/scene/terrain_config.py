"""The ``terrain`` config group: which DEM (or none) and how line of sight is tested.

The kinds and what they read are described in :mod:`gmtiflow.scene.terrain` and docs/terrain.md.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import List, Optional

from gmtiflow import schema
from gmtiflow.scene import dem
from gmtiflow.scene.hills import HillConfig, hills_extent


class TerrainKind(enum.Enum):
    flat = "flat"
    srtm = "srtm"
    ascii_grid = "ascii_grid"
    hills = "hills"


class VoidPolicy(enum.Enum):
    fill = "fill"      # Laplace interpolation from the neighbours, logged with the count
    refuse = "refuse"  # InputFileError naming the file and the count


@dataclass
class TerrainConfig:
    """Terrain config group (``conf/terrain/*.yaml``). Units in the field names."""

    kind: TerrainKind = TerrainKind.flat
    #: flat: ENU z of the ground plane
    flat_height_m: float = 0.0
    #: srtm: .hgt tiles (absolute, or relative to the current directory), stitched into one grid
    paths: List[str] = field(default_factory=list)
    #: ascii_grid: ESRI ASCII grid in scene ENU metres (heights = ENU z)
    path: Optional[str] = None
    #: void samples (SRTM -32768, ASCII NODATA): fill (interpolate) or refuse (error)
    voids: VoidPolicy = VoidPolicy.fill
    #: srtm: geoid undulation N (m), ellipsoid height = DEM height + N; required for srtm
    geoid_offset_m: Optional[float] = None
    #: hills: the hills and ridges, the base height around them, the grid spacing
    hills: List[HillConfig] = field(default_factory=list)
    hills_base_height_m: float = 0.0
    grid_spacing_m: float = 25.0
    #: line of sight: blocked only where the ground is more than this above the ray
    clearance_m: float = 1.0
    #: line of sight: untested length at each end of a ray (None = one grid cell)
    end_skip_m: Optional[float] = None
    #: line of sight: samples per vectorised chunk (memory bound: ~100 B per sample)
    chunk_samples: int = 2_000_000

    def problems(self) -> List[schema.Problem]:
        out: List[schema.Problem] = []
        out += schema.positive(self, "grid_spacing_m")
        out += schema.non_negative(self, "clearance_m", "end_skip_m")
        # map z on the earth (dem.MAP_Z_RANGE_M); NaN and inf are refused too
        out += schema.in_range(self, "flat_height_m", *dem.MAP_Z_RANGE_M)
        out += schema.in_range(self, "hills_base_height_m", *dem.MAP_Z_RANGE_M)
        if not (isinstance(self.chunk_samples, int) and self.chunk_samples >= 1000):
            out.append(schema.Problem("chunk_samples", f"must be an integer >= 1000, "
                                                       f"got {self.chunk_samples!r}"))
        kind = TerrainKind(self.kind)
        if kind is TerrainKind.srtm:
            if not self.paths:
                out.append(schema.Problem("paths", "kind=srtm needs at least one .hgt tile"))
            if self.geoid_offset_m is None:
                out.append(schema.Problem(
                    "geoid_offset_m", "kind=srtm needs the geoid undulation N in metres "
                    "(SRTM heights are above EGM96; ellipsoid height = DEM height + N; "
                    "about +50 at Monaco)"))
            else:
                out += schema.in_range(self, "geoid_offset_m", -110.0, 90.0)
        if kind is TerrainKind.ascii_grid and not schema.optional_path(self.path):
            out.append(schema.Problem("path", "kind=ascii_grid needs the grid file"))
        if kind is TerrainKind.hills:
            for i, hill in enumerate(self.hills):
                out += schema.prefixed(f"hills[{i}]", hill.problems())
            if not out and self.hills:
                x0, x1, y0, y1 = hills_extent(self.hills, self.grid_spacing_m)
                cells = ((x1 - x0) / self.grid_spacing_m + 1) * ((y1 - y0) / self.grid_spacing_m + 1)
                if cells > 50e6:
                    out.append(schema.Problem(
                        "grid_spacing_m", f"the hills grid would have {cells:.3g} nodes "
                        f"(> 5e7); use a coarser spacing or narrower hills"))
        return out
