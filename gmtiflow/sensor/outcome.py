"""Outcome codes of a look (/looks ``outcome`` column, docs/tables.md).

The first reason that applies wins, in this order: outside_fov, invisible_road, terrain, then the
detection draw (detected, doppler_blind, pd_miss); ``merged`` is set by the merging stage.
"""
from __future__ import annotations

from enum import IntEnum


class Outcome(IntEnum):
    DETECTED = 0        # reported as a detection
    OUTSIDE_FOV = 1     # outside the beam footprints, the azimuth sector, elevation or range limits
    INVISIBLE_ROAD = 2  # on an invisible road (tunnel, deep cut)
    TERRAIN = 3         # terrain or the earth's bulge (below the radar horizon) blocks the line of sight
    DOPPLER_BLIND = 4   # missed with |ṙ − ṙ_MLC| (folded to the nearest blind speed) below MDV
    PD_MISS = 5         # any other miss of the Swerling draw
    MERGED = 6          # detected, but merged into another report
