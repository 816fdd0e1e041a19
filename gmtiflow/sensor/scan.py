"""Scan schedule: revisits, dwells and beam centres (DESIGN §5 "Scan").

A revisit starts every ``revisit_s`` seconds (the first at t = 0).  A scan steps the beam across
the azimuth sector ``[az_min_deg, az_max_deg]`` of the antenna frame from ``az_min`` to
``az_max``, one dwell (one CPI) per beam position, back to back: dwell ``i`` of revisit ``r`` has
its CPI centred at ``t = r * revisit_s + (i + 1/2) * cpi_s``.

Beam positions are uniform in *sine space* (u = sin(scan angle)), where an electronically steered
array's beam keeps a constant width k λ / d_a; in angle that width broadens as 1/cos(scan), so
the beams spread out towards the sector edges exactly as their footprints do.  The sector
[sin az_min, sin az_max] is cut into ``n = ceil(span / (spacing * BW))`` equal cells and a beam sits
in the centre of each, so no point of the sector is further than half a spacing from a beam.

``instant_scan`` (the cheap fidelity) keeps the same dwells for bookkeeping but evaluates the
whole scan at one instant, the scan's middle, with the beam centred on each target.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gmtiflow.sensor.config import SensorConfig

DWELL_MODES = ("dwell_resolved", "instant_scan")


def n_dwells(cfg: SensorConfig) -> int:
    """Number of beam positions (dwells) in one scan (:attr:`SensorConfig.n_dwells`)."""
    return cfg.n_dwells


def beam_centres_rad(cfg: SensorConfig) -> np.ndarray:
    """Beam-centre scan angles (antenna frame, + clockwise from boresight), ascending."""
    u_min = math.sin(math.radians(cfg.az_min_deg))
    u_max = math.sin(math.radians(cfg.az_max_deg))
    n = n_dwells(cfg)
    u = u_min + (np.arange(n) + 0.5) * (u_max - u_min) / n
    return np.arcsin(u)


def broadened_beamwidth_rad(cfg: SensorConfig, scan_rad) -> np.ndarray:
    """3-dB beamwidth in angle at a scan angle: k λ / (d_a cos(scan)) (eq. 9, DESIGN §5.3)."""
    cos = np.maximum(np.cos(np.asarray(scan_rad, float)), 1e-6)
    return cfg.beamwidth_sine / cos


@dataclass(frozen=True)
class Schedule:
    """Dwell schedule of a run (all dwells; dwell_id = revisit * n_dwells + index)."""

    n_revisits: int
    n_dwells: int                 # per revisit
    beam_scan_rad: np.ndarray     # (n_dwells,) beam centres, antenna frame
    time_offset_s: np.ndarray     # (n_dwells,) dwell time relative to the revisit start
    revisit_start_s: np.ndarray   # (n_revisits,)
    instant: bool = False         # instant_scan: the whole scan at one instant

    @property
    def n_total(self) -> int:
        return self.n_revisits * self.n_dwells

    def dwell_time_s(self, dwell_id) -> np.ndarray:
        dwell_id = np.asarray(dwell_id)
        return (self.revisit_start_s[dwell_id // self.n_dwells]
                + self.time_offset_s[dwell_id % self.n_dwells])


def build_schedule(cfg: SensorConfig, duration_s: float, dwell_mode=DWELL_MODES[0]) -> Schedule:
    """All revisits whose last dwell time is within ``[0, duration_s]``.

    ``dwell_mode`` (chosen by the fidelity preset): ``dwell_resolved`` gives each dwell its own
    time; ``instant_scan`` puts every dwell of a scan at the scan's middle instant.
    """
    dwell_mode = getattr(dwell_mode, "value", dwell_mode)
    if dwell_mode not in DWELL_MODES:
        raise ValueError(f"dwell_mode must be one of {DWELL_MODES}, got {dwell_mode!r}")
    instant = dwell_mode == "instant_scan"
    n = n_dwells(cfg)
    scan = beam_centres_rad(cfg)
    if instant:
        offsets = np.full(n, 0.5 * n * cfg.cpi_s)
    else:
        offsets = (np.arange(n) + 0.5) * cfg.cpi_s
    last = float(offsets.max())
    if duration_s < last:
        n_rev = 0
    else:
        n_rev = int(math.floor((duration_s - last) / cfg.revisit_s + 1e-9)) + 1
    starts = np.arange(n_rev) * cfg.revisit_s
    return Schedule(n_rev, n, scan, offsets, starts, instant)
