"""Work and memory of a run, estimated from its config before any work (issue 17, item 9).

A config can be valid value by value and still ask for more than a machine has:
``vehicles.random.count=1000000`` over ``scene.duration_s=1e9`` with
``fidelity.time_step_s=1e-3``.  :func:`check` estimates the samples the truth stage integrates
and the bytes the largest in-memory tables take, and refuses (one ConfigError naming the
estimate and the knobs) a run that needs more memory than is available
(:func:`gmtiflow.resources.available_memory_bytes`, ``GMTIFLOW_MEMORY_BYTES`` to override) or
more than :data:`MAX_SAMPLES` samples (hours of work).

The estimate is a lower bound from the table layouts (docs/tables.md): per vehicle and speed
profile step about :data:`PROFILE_BYTES`, per /truth row :data:`TRUTH_ROW_BYTES` (18 columns),
with the whole /truth kept in memory when the tracker or the metrics need it, else one
``chunk_s`` block at a time.

The sensor stage works on chunks of whole revisits (:func:`gmtiflow.sensor.model.simulate_chunks`):
a chunk holds at least one revisit, i.e. every vehicle's candidate (dwell, target) pairs (1 per
vehicle in ``instant_scan``, up to 3 in ``dwell_resolved``) plus the false alarms and clutter
points drawn for each dwell of the scan (``P_FA`` × cells per dwell, capped by
``max_false_alarms_per_dwell``; ``fov_density_per_km2`` × the dwell's share of the field of
view; each region's density × its bounding box), and at least ``chunk_pairs`` pairs.  Each pair
costs about :data:`SENSOR_PAIR_BYTES` of working arrays (tracemalloc peak over a 40,000-vehicle
run: 350–420 B per pair), and ``sensor_workers`` > 1 keeps that many chunks (plus the one being
written) alive.  When the tracker or the metrics keep the whole tables, /dwells, /looks and
/detections are counted at their row sizes too.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from gmtiflow.errors import ConfigError
from gmtiflow.resources import available_memory_bytes, human_bytes

PROFILE_BYTES = 64
TRUTH_ROW_BYTES = 18 * 8
SENSOR_PAIR_BYTES = 512
"""Working memory of one (dwell, target) pair or false alarm inside a sensor chunk (measured
350–420 B with tracemalloc, rounded up for the effects' copies)."""
MAX_SAMPLES = 2e9
"""Speed-profile steps plus /truth rows beyond which a run would take hours: refused."""


@dataclass(frozen=True)
class Estimate:
    n_vehicles: int
    profile_samples: float
    truth_rows: float
    peak_bytes: float
    sensor_bytes: float = 0.0
    """The largest sensor's chunk working memory plus the kept sensor tables (bytes)."""


def n_vehicles(cfg) -> int:
    v = cfg.vehicles
    n = int(getattr(getattr(v, "random", None), "count", 0) or 0)
    for spec in getattr(v, "vehicles", []) or []:
        convoy = getattr(spec, "convoy", None)
        n += int(getattr(convoy, "count", 1) or 1)
    return n


def estimate(cfg) -> Estimate:
    """Work and peak memory of ``cfg`` (an AppConfig that passed validation)."""
    n = n_vehicles(cfg)
    duration = float(cfg.scene.duration_s)
    steps = math.floor(duration / float(cfg.fidelity.time_step_s)) + 1
    rows_per_vehicle = math.floor(duration / float(cfg.fidelity.truth_output_dt_s)) + 1
    profile = float(n) * steps
    truth = float(n) * rows_per_vehicle
    keep = bool(cfg.tracker.enabled or cfg.metrics.enabled)
    if keep:
        truth_mem = truth * TRUTH_ROW_BYTES
    else:
        chunk = min(float(cfg.chunk_s), duration)
        truth_mem = float(n) * (math.floor(chunk / float(cfg.fidelity.truth_output_dt_s)) + 1) \
            * TRUTH_ROW_BYTES * 2
    sensor = max((sensor_bytes(cfg, s, n, keep) for s in sensor_configs(cfg)), default=0.0)
    return Estimate(n, profile, truth, profile * PROFILE_BYTES + truth_mem + sensor, sensor)


def sensor_configs(cfg) -> list:
    """The run's sensor configs: ``sensor`` and every ``sensors.<name>.sensor``."""
    extra = [getattr(slot, "sensor", None) for slot in (getattr(cfg, "sensors", None) or {}).values()]
    return [s for s in [cfg.sensor, *extra] if s is not None]


def _row_bytes(columns) -> int:
    import numpy as np
    return sum(np.dtype(t).itemsize for t in columns.values())


def points_per_dwell(sensor, clutter) -> float:
    """Noise false alarms and clutter points drawn per dwell, before any mask."""
    n = 0.0
    if sensor.noise_false_alarms:
        n += min(sensor.expected_false_alarms_per_dwell, sensor.max_false_alarms_per_dwell)
    if clutter is not None:
        density = float(getattr(clutter, "fov_density_per_km2", 0.0) or 0.0)
        if density > 0:      # the dwell's share of the field of view's ground sector
            span = math.radians(float(sensor.az_max_deg) - float(sensor.az_min_deg))
            fov_m2 = 0.5 * abs(span) * (float(sensor.range_max_m) ** 2
                                        - min(float(sensor.range_min_m), float(sensor.range_max_m)) ** 2)
            n += density * fov_m2 / 1e6 / max(int(sensor.n_dwells), 1)
        for region in getattr(clutter, "regions", None) or []:
            d = float(getattr(region, "density_per_km2", 0.0) or 0.0)
            if d > 0:
                x0, y0, x1, y1 = region.bbox()
                n += d * (x1 - x0) * (y1 - y0) / 1e6
    return n


def sensor_bytes(cfg, sensor, n_vehicles: int, keep: bool) -> float:
    """Peak working memory of one sensor's chunks, plus its whole tables when ``keep``."""
    import inspect

    from gmtiflow.sensor import model

    chunk_pairs = inspect.signature(model.simulate_chunks).parameters["chunk_pairs"].default
    mode = getattr(cfg.fidelity.dwell_mode, "value", cfg.fidelity.dwell_mode)
    per_vehicle = 1 if mode == "instant_scan" else 3
    n_dwells = max(int(sensor.n_dwells), 1)
    extra = points_per_dwell(sensor, getattr(cfg, "clutter", None))
    per_revisit = n_vehicles * per_vehicle + n_dwells * extra
    workers = int(getattr(cfg, "sensor_workers", 1) or 1)
    in_flight = workers + 1 if workers > 1 else 1
    total = max(per_revisit, float(chunk_pairs)) * SENSOR_PAIR_BYTES * in_flight
    if keep:
        duration = float(cfg.scene.duration_s)
        n_rev = math.floor(duration / float(sensor.revisit_s)) + 1
        total += n_rev * (n_dwells * _row_bytes(model.DWELL_COLUMNS)
                          + n_vehicles * _row_bytes(model.LOOK_COLUMNS)
                          + n_dwells * extra * _row_bytes(model.DETECTION_COLUMNS))
    return total


def check(cfg) -> Estimate:
    """The estimate, or ConfigError if the run cannot fit in memory or time."""
    e = estimate(cfg)
    memory = available_memory_bytes()
    knobs = ("scene.duration_s, fidelity.time_step_s, fidelity.truth_output_dt_s, "
             "vehicles.random.count (and convoy counts), chunk_s, tracker=none "
             "metrics.enabled=false")
    if e.sensor_bytes > 0.5 * e.peak_bytes:
        knobs = ("vehicles.random.count (and convoy counts), sensor.pfa, "
                 "sensor.max_false_alarms_per_dwell, sensor.range_min_m/range_max_m, "
                 "clutter.fov_density_per_km2, clutter region density_per_km2, sensor.revisit_s, "
                 "sensor_workers, scene.duration_s, tracker=none metrics.enabled=false")
    what = (f"{e.n_vehicles} vehicles x {cfg.scene.duration_s:g} s: {e.profile_samples:.3g} "
            f"speed-profile steps and {e.truth_rows:.3g} truth rows, about "
            f"{human_bytes(e.peak_bytes)} of memory (the sensor stage "
            f"{human_bytes(e.sensor_bytes)})")
    if e.peak_bytes > memory:
        raise ConfigError(f"invalid config: the run needs {what}, more than the "
                          f"{human_bytes(memory)} available (GMTIFLOW_MEMORY_BYTES); reduce "
                          f"{knobs}")
    if e.profile_samples + e.truth_rows > MAX_SAMPLES:
        raise ConfigError(f"invalid config: the run needs {what}; more than {MAX_SAMPLES:.0e} "
                          f"samples would take hours; reduce {knobs}")
    return e
