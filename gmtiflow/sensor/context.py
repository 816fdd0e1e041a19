"""What the sensor stage's pieces share: the run context and the effects' chunk view.

:class:`SensorRun` holds everything one sensor's run keeps constant over its chunks (config,
scan schedule, fleet, platform, terrain, seed, origin, RCS models); :mod:`.poses`,
:mod:`.pairs` and :mod:`.looks` take it instead of a dozen positional arguments.
:class:`ChunkContext` is what an effect (merge, clutter, ambiguity) may use about the chunk it
post-processes (:mod:`.model`, step 5).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Callable, Tuple

import numpy as np

from gmtiflow import frames
from gmtiflow.sensor import antenna, geolocate, geometry, measurement, scan, visibility
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.rcs import RcsModels
from gmtiflow.tables import Table


@dataclass(frozen=True)
class SensorRun:
    """What every chunk of one sensor's run shares (built once by ``simulate_chunks``).

    cfg         the sensor config, normalised
    sched       the scan schedule (dwell times and beam positions)
    fleet       truth: ``state_at(time_s, vehicle_id, columns=...)`` (the columns asked, or
                more), ``vehicles`` (and ``start_time_s``/``end_time_s``)
    platform    ``state_at(time_s)`` of the radar's platform
    terrain     heights and line of sight (``flat`` skips the terrain tests)
    seed        the sensor's stream seed (counter-based draws)
    origin      the scene's geodetic origin (lat/lon columns)
    rcs_models  the RCS models; ``type_codes[vehicle_id]`` is each vehicle's model code
    los_step_m  terrain line-of-sight ray step (``fidelity.terrain_step_m``)
    """

    cfg: SensorConfig
    sched: scan.Schedule
    fleet: object
    platform: object
    terrain: object
    seed: int
    origin: frames.Origin
    rcs_models: RcsModels
    type_codes: np.ndarray
    los_step_m: float = 30.0


@dataclass(frozen=True)
class ChunkContext:
    """What an effect (merge, clutter, ambiguity) may use about the chunk it post-processes.

    The helper methods take run-wide ``dwell_id`` arrays of this chunk's dwells and ENU points
    or measurements, vectorised, so that an effect sees the scene exactly as the sensor does.
    """

    cfg: SensorConfig
    seed: int
    terrain: object
    origin: frames.Origin
    dwells: Table                    # the chunk's /dwells rows
    boresight: tuple                 # antenna axes per dwell of the chunk: 3-tuples of arrays
    scan_axis: tuple
    antenna_up: tuple
    los_step_m: float = 30.0         # terrain line-of-sight ray step (fidelity.terrain_step_m)

    def _local(self, dwell_id) -> np.ndarray:
        return np.asarray(dwell_id, np.int64) - int(self.dwells["dwell_id"][0])

    @property
    def radius_m(self) -> float:
        """The round earth's radius (:func:`gmtiflow.frames.sphere_radius_m`)."""
        return frames.sphere_radius_m(self.origin)

    def _platform(self, k):
        return tuple(self.dwells[f"platform_{c}_m"][k] for c in "xyz")

    def _line_of_sight(self, k, x_m, y_m, z_m):
        """Slant range and LOS (platform frame) of points from chunk-local dwells ``k``."""
        pts = tuple(np.asarray(c, float) for c in (x_m, y_m, z_m))
        return geometry.line_of_sight(self._platform(k), pts, self.radius_m)

    def antenna_angles(self, dwell_id, x_m, y_m, z_m):
        """(slant range m, azimuth rad, elevation rad) of points in the dwell's antenna frame."""
        k = self._local(dwell_id)
        rng_m, los = self._line_of_sight(k, x_m, y_m, z_m)
        az, el, _, _ = antenna.target_angles(los, antenna.take(self.boresight, k),
                                             antenna.take(self.scan_axis, k),
                                             antenna.take(self.antenna_up, k))
        return rng_m, az, el

    def in_fov(self, dwell_id, x_m, y_m, z_m=None):
        """The sensor's field-of-view test (sector, elevation, slant range) for points of the
        dwell; ``z_m`` None = on the terrain.  Does not test the footprint or terrain LOS."""
        if z_m is None:
            z_m = np.nan_to_num(np.asarray(self.terrain.height_at(x_m, y_m), float))
        rng_m, az, el = self.antenna_angles(dwell_id, x_m, y_m, z_m)
        return visibility.in_field_of_view(self.cfg, az, el, rng_m)

    def visible(self, dwell_id, x_m, y_m, z_m):
        """Points seen from the dwell's platform position: above the radar horizon and, on a
        non-flat terrain, with a clear terrain line of sight (the targets' masks)."""
        k = self._local(dwell_id)
        pts = (np.asarray(x_m, float), np.asarray(y_m, float), np.asarray(z_m, float))
        plat = self._platform(k)
        ok = visibility.within_horizon(plat, pts, self.cfg.horizon_k_factor, self.radius_m)
        if not getattr(self.terrain, "flat", False) and np.any(ok):
            i = np.flatnonzero(ok)
            ok[i] = visibility.terrain_clear(self.terrain, antenna.take(plat, i),
                                             antenna.take(pts, i), self.los_step_m,
                                             self.cfg.horizon_k_factor * self.radius_m)
        return ok

    def dwell_cell_rad(self, dwell_id):
        """(low, high) antenna-frame scan angles of each dwell's cell: the sine-space interval
        between the midpoints to its neighbours (one beam step, ≤ the configured spacing); the
        cells tile the azimuth sector."""
        return self.per_beam(self._cell_rad, dwell_id)

    def _cell_rad(self, beam_scan_rad):
        u = np.sin(beam_scan_rad)
        u_min = math.sin(math.radians(self.cfg.az_min_deg))
        u_max = math.sin(math.radians(self.cfg.az_max_deg))
        half = 0.5 * (u_max - u_min) / scan.n_dwells(self.cfg)
        return np.arcsin(np.maximum(u - half, u_min)), np.arcsin(np.minimum(u + half, u_max))

    def per_beam(self, fn, dwell_id):
        """``fn(beam scan angles)`` (an array or a tuple of arrays, element by element) at the
        dwells ``dwell_id``: evaluated once per beam position and gathered when the dwells
        outnumber the beams (the same values), else at the dwells' own angles."""
        k = self._local(dwell_id)
        table = self._beam_table
        if table is None or len(k) <= 2 * len(table[0]):
            return fn(self.dwells["beam_scan_rad"][k])
        beams, index = table
        out = fn(beams)
        at = np.take(index, k)
        return (tuple(np.take(c, at) for c in out) if isinstance(out, tuple)
                else np.take(out, at))

    @cached_property
    def _beam_table(self):
        """(scan angle per beam position, beam position per dwell of the chunk), or None when
        the dwells' angles are not one per position."""
        index = np.asarray(self.dwells.get("dwell_index", ()), np.int64)
        beam = np.asarray(self.dwells["beam_scan_rad"], float)
        if index.size == 0 or index.size != beam.size or index.min() < 0:
            return None
        beams = np.zeros(int(index.max()) + 1)
        beams[index] = beam
        return (beams, index) if beams[index].tobytes() == beam.tobytes() else None

    def range_rate_of_ground(self, dwell_id, x_m, y_m, z_m):
        """ṙ_MLC = −v_p·ℓ of ground points (the clutter's range rate, m/s)."""
        return self.range_and_ground_rate(dwell_id, x_m, y_m, z_m)[1]

    def range_and_ground_rate(self, dwell_id, x_m, y_m, z_m):
        """(slant range m, ṙ_MLC m/s) of ground points from one line of sight: the values of
        :meth:`antenna_angles`' range and :meth:`range_rate_of_ground`, without their angles
        and without computing the line of sight twice."""
        k = self._local(dwell_id)
        rng_m, los = self._line_of_sight(k, x_m, y_m, z_m)
        vel = geometry.true_velocity(tuple(self.dwells[f"platform_v{c}_mps"][k] for c in "xyz"),
                                     self._platform(k)[2], self.radius_m)
        return rng_m, geometry.clutter_range_rate(vel, los)

    def world_azimuth_sigma(self, dwell_id, x_m, y_m, z_m, sigma_scan_rad):
        """σ (rad) of the world azimuth of reports at points (x, y, z) of the dwells, from
        their antenna-frame σ (:func:`gmtiflow.sensor.measurement.world_azimuth_sigma` at the
        line of sight to the point), as the sensor reports a detection's."""
        k = self._local(dwell_id)
        _, los = self._line_of_sight(k, x_m, y_m, z_m)
        rate = antenna.azimuth_rate(los, antenna.take(self.boresight, k),
                                    antenna.take(self.scan_axis, k))
        return measurement.world_azimuth_sigma(sigma_scan_rad, rate)

    def geolocate(self, dwell_id, range_m, azimuth_rad):
        """Ground points ``(x, y, z)`` and ``reached`` of measured slant ranges and *world*
        azimuths (as in /detections), on the terrain, as the sensor geolocates."""
        k = self._local(dwell_id)
        return geolocate.geolocate_world_azimuth(self._platform(k), range_m, azimuth_rad,
                                                 self.terrain, radius_m=self.radius_m)


Effect = Callable[[ChunkContext, Table, Table], Tuple[Table, Table]]
