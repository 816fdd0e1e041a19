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
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from gmtiflow.errors import ConfigError
from gmtiflow.resources import available_memory_bytes, human_bytes

PROFILE_BYTES = 64
TRUTH_ROW_BYTES = 18 * 8
MAX_SAMPLES = 2e9
"""Speed-profile steps plus /truth rows beyond which a run would take hours: refused."""


@dataclass(frozen=True)
class Estimate:
    n_vehicles: int
    profile_samples: float
    truth_rows: float
    peak_bytes: float


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
    return Estimate(n, profile, truth, profile * PROFILE_BYTES + truth_mem)


def check(cfg) -> Estimate:
    """The estimate, or ConfigError if the run cannot fit in memory or time."""
    e = estimate(cfg)
    memory = available_memory_bytes()
    knobs = ("scene.duration_s, fidelity.time_step_s, fidelity.truth_output_dt_s, "
             "vehicles.random.count (and convoy counts), chunk_s, tracker=none "
             "metrics.enabled=false")
    what = (f"{e.n_vehicles} vehicles x {cfg.scene.duration_s:g} s: {e.profile_samples:.3g} "
            f"speed-profile steps and {e.truth_rows:.3g} truth rows, about "
            f"{human_bytes(e.peak_bytes)} of memory")
    if e.peak_bytes > memory:
        raise ConfigError(f"invalid config: the run needs {what}, more than the "
                          f"{human_bytes(memory)} available (GMTIFLOW_MEMORY_BYTES); reduce "
                          f"{knobs}")
    if e.profile_samples + e.truth_rows > MAX_SAMPLES:
        raise ConfigError(f"invalid config: the run needs {what}; more than {MAX_SAMPLES:.0e} "
                          f"samples would take hours; reduce {knobs}")
    return e
