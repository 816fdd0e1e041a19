"""Accepted means runnable (issue 17, items 9 and 11; ``benchmarks/config_extremes.py``).

Every numeric leaf of the config schema, discovered from the validated default config (fields
other people add are swept too), is set to 0, a tiny value, a huge one, the largest accepted
magnitude and -1.  Validation (``config.validate`` + ``budget.check``) must either refuse it
with a ConfigError naming the key or accept it; a seeded sample of the accepted tiny and huge
values is run on a 5 s scene and must end cleanly or with a GmtiflowError.  The full run of
every accepted case is ``python benchmarks/config_extremes.py --run all``.
"""
from __future__ import annotations

import importlib.util
import math
import re
from pathlib import Path

import numpy as np
import pytest

from gmtiflow import budget, config
from gmtiflow.compose import compose
from gmtiflow.errors import ConfigError

_path = Path(__file__).resolve().parents[2] / "benchmarks" / "config_extremes.py"
_spec = importlib.util.spec_from_file_location("config_extremes", _path)
extremes = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(extremes)

N_RUN = 12


@pytest.fixture(scope="module")
def base():
    return compose(extremes.BASE)


@pytest.fixture(scope="module")
def validated(base):
    out = []
    for leaf, value in extremes.cases(base):
        cfg, err = extremes.validate_case(base, leaf, value)   # only ConfigError is caught
        out.append((leaf, value, cfg, err))
    return out


def test_the_sweep_discovers_the_schema(validated):
    leaves = {leaf for leaf, *_ in validated}
    assert len(leaves) >= 200, len(leaves)
    assert {"scene.duration_s", "fidelity.time_step_s", "sensor.bandwidth_hz",
            "clutter.fov_density_per_km2"} <= leaves


def test_refusals_name_the_key(validated):
    for leaf, value, cfg, err in validated:
        if err is None:
            continue
        holder = re.sub(r"(\[\d+\])+$", "", leaf)
        named = leaf in err or holder in err or holder.rsplit(".", 1)[0] in err \
            or "the run needs" in err
        assert named, (leaf, value, err)


def test_values_the_physics_cannot_use_are_refused(validated):
    accepted = {(leaf, value) for leaf, value, cfg, _ in validated if cfg is not None}
    for leaf in ("sensor.bandwidth_hz", "sensor.gamma_r", "sensor.kappa_r", "scene.duration_s",
                 "clutter.fov_density_per_km2", "vehicles.random.max_wait_s"):
        assert (leaf, 1e300) not in accepted, leaf
    assert ("fidelity.time_step_s", 1e-300) not in accepted


@pytest.mark.slow
def test_a_sample_of_accepted_extremes_runs_cleanly(validated):
    risky = [(leaf, value, cfg) for leaf, value, cfg, _ in validated
             if cfg is not None and value not in (0, -1)]
    rng = np.random.default_rng(17)
    pick = sorted(rng.choice(len(risky), min(N_RUN, len(risky)), replace=False))
    results = []
    for i in pick:
        leaf, value, cfg = risky[i]
        outcome, detail = extremes.run_case(cfg, timeout_s=120.0)
        results.append((leaf, value, outcome, detail))
    others = [r for r in results if r[2] == "other"]
    assert not others, others


@pytest.mark.parametrize("overrides, knob", [
    (["vehicles.random.count=1000000", "scene.duration_s=1000000"], "vehicles.random.count"),
    (["fidelity.time_step_s=1e-9"], "fidelity.time_step_s"),
    (["scene.duration_s=1e11", "scene.epoch_utc=1970-01-01T00:00:00Z"], "scene.duration_s"),
])
def test_runs_beyond_the_machine_are_refused_before_work(overrides, knob, monkeypatch):
    monkeypatch.setenv("GMTIFLOW_MEMORY_BYTES", str(8 * 2**30))
    cfg = compose(overrides)
    with pytest.raises(ConfigError, match="the run needs") as info:
        budget.check(cfg)
    assert knob in str(info.value) and "GiB" in str(info.value) or "samples" in str(info.value)


def test_the_estimate_counts_vehicles_and_steps():
    cfg = compose(["vehicles=random", "vehicles.random.count=10", "scene.duration_s=100",
                   "fidelity.time_step_s=0.5", "fidelity.truth_output_dt_s=1.0"])
    e = budget.estimate(cfg)
    assert e.n_vehicles == 10 + sum(v.convoy.count for v in cfg.vehicles.vehicles)
    assert e.profile_samples == e.n_vehicles * 201 and e.truth_rows == e.n_vehicles * 101


def test_the_sensor_chunk_is_in_the_estimate():
    """A chunk holds at least one revisit's pairs and at least chunk_pairs of them, each about
    SENSOR_PAIR_BYTES; the default scene's tiny fleet is the chunk_pairs floor."""
    cfg = compose(["tracker=none", "metrics.enabled=false"])
    e = budget.estimate(cfg)
    floor = 300_000 * budget.SENSOR_PAIR_BYTES
    assert e.sensor_bytes == pytest.approx(floor)
    budget.check(cfg)                                   # the default scene is accepted
    two = budget.estimate(compose(["tracker=none", "metrics.enabled=false", "sensor_workers=2"]))
    assert two.sensor_bytes == pytest.approx(3 * floor)   # two chunks computed + one written


def test_false_alarms_per_revisit_are_counted():
    over = ["tracker=none", "metrics.enabled=false", "sensor.pfa=0.5",
            "sensor.max_false_alarms_per_dwell=1e9"]
    cfg = compose(over)
    s = cfg.sensor
    per_revisit = s.n_dwells * s.expected_false_alarms_per_dwell + 3 * budget.n_vehicles(cfg)
    assert budget.estimate(cfg).sensor_bytes == pytest.approx(
        per_revisit * budget.SENSOR_PAIR_BYTES)


def test_a_sensor_beyond_memory_is_refused_naming_its_knobs(monkeypatch):
    monkeypatch.setenv("GMTIFLOW_MEMORY_BYTES", str(2**30))
    cfg = compose(["tracker=none", "metrics.enabled=false", "sensor.pfa=0.5",
                   "sensor.max_false_alarms_per_dwell=1e9"])
    with pytest.raises(ConfigError, match="the run needs") as info:
        budget.check(cfg)
    msg = str(info.value)
    assert "the sensor stage" in msg and "sensor.pfa" in msg \
        and "sensor.max_false_alarms_per_dwell" in msg
    # the same sensor with the tables kept for the tracker needs far more
    kept = budget.estimate(compose(["sensor.pfa=0.5", "sensor.max_false_alarms_per_dwell=1e9"]))
    assert kept.sensor_bytes > 10 * budget.estimate(cfg).sensor_bytes


def test_fov_clutter_counts_per_dwell():
    base = ["tracker=none", "metrics.enabled=false", "sensor.noise_false_alarms=false"]
    cfg = compose(base + ["clutter.fov_density_per_km2=1000"])
    s = cfg.sensor
    fov_km2 = 0.5 * math.radians(s.az_max_deg - s.az_min_deg) \
        * (s.range_max_m ** 2 - s.range_min_m ** 2) / 1e6
    assert budget.points_per_dwell(s, cfg.clutter) == pytest.approx(1000 * fov_km2 / s.n_dwells)
