"""Stage cache: keys invalidate exactly what depends on a change; cached runs are bit-identical;
entries appear atomically; a sensor sweep computes the truth once; streaming equals whole tables."""
import logging
import pickle

import h5py
import numpy as np
import pytest

from gmtiflow import pipeline
from gmtiflow.compose import compose as compose_app
from gmtiflow.cache import StageCache
from gmtiflow.scene.vehicles import build_fleet
from gmtiflow.sensor.effects import build_effects
from gmtiflow.sensor.model import simulate



BASE = ["scene.duration_s=40", "vehicles=random", "vehicles.random.count=12",
        "vehicles.random.start_time_max_s=10", "clutter=urban",
        "report=none", "export=none"]      # the cache is about run.h5


def datasets(path):
    """Every dataset of a run file by name (values only)."""
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]
        f.visititems(visit)
    return out


def assert_same_datasets(a, b):
    """All datasets equal bit for bit, except /config (it records the cache settings too)."""
    da, db = datasets(a), datasets(b)
    da.pop("config"), db.pop("config")
    assert sorted(da) == sorted(db)
    for name in da:
        x, y = np.asarray(da[name]), np.asarray(db[name])
        assert x.dtype == y.dtype, name
        assert x.shape == y.shape, name
        if x.dtype.kind == "f":
            assert np.array_equal(x.view(np.uint8), y.view(np.uint8)), name   # bitwise, NaNs too
        else:
            assert np.array_equal(x, y), name


def keys_for(overrides):
    return pipeline.stage_keys(compose_app(BASE + list(overrides)))


def test_keys_invalidate_exactly_the_dependent_stages():
    base = keys_for([])
    changed = lambda ov: {k for k, v in keys_for(ov).items() if v != base[k]}  # noqa: E731
    assert set(base) == {"scene", "truth", "platform.main", "sensor.main"}
    assert changed([]) == set()
    assert changed(["sensor.peak_power_w=800"]) == {"sensor.main"}
    assert changed(["clutter=none"]) == {"sensor.main"}
    assert changed(["fidelity.dwell_mode=instant_scan"]) == {"sensor.main"}
    assert changed(["fidelity.truth_output_dt_s=2"]) == set()      # only the /truth sampling
    assert changed(["vehicles.random.count=13"]) == {"truth", "sensor.main"}
    assert changed(["fidelity.time_step_s=1.0"]) == {"truth", "sensor.main"}
    assert changed(["seed=2"]) == {"truth", "sensor.main"}
    assert changed(["platform.speed_mps=140"]) == {"platform.main", "sensor.main"}
    assert changed(["scene.duration_s=50"]) == {"truth", "sensor.main"}
    assert changed(["terrain=hills"]) == {"scene", "truth", "platform.main", "sensor.main"}
    assert changed(["tracker=none", "cache.dir=/elsewhere", "chunk_s=5"]) == set()


def test_cached_runs_are_bit_identical_to_uncached(tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="gmtiflow")
    cache_dir = tmp_path / "cache"
    off = pipeline.run(compose_app(BASE + ["cache.enabled=false"]), tmp_path / "off")
    assert not cache_dir.exists()
    on = [compose_app(BASE + [f"cache.dir={cache_dir}"]) for _ in range(2)]
    miss = pipeline.run(on[0], tmp_path / "miss")
    assert "cache miss truth" in caplog.text
    caplog.clear()
    hit = pipeline.run(on[1], tmp_path / "hit")
    for stage in ("scene", "truth", "platform.main", "sensor.main"):
        assert f"cache hit {stage}" in caplog.text
    assert "cache miss" not in caplog.text
    assert_same_datasets(off, miss)
    assert_same_datasets(off, hit)


@pytest.mark.slow
def test_sensor_sweep_computes_truth_once_and_matches_uncached(tmp_path, caplog):
    """A 3 x 2 sweep over sensor settings: one truth miss, five hits, outputs as uncached."""
    caplog.set_level(logging.INFO, logger="gmtiflow")
    cache_dir = tmp_path / "cache"
    points = [[f"sensor.peak_power_w={p}", f"sensor.pfa={q}"]
              for p in (100, 500, 2000) for q in ("1e-6", "1e-4")]
    n_det = set()
    for i, ov in enumerate(points):
        cached = pipeline.run(compose_app(BASE + ov + [f"cache.dir={cache_dir}"]),
                              tmp_path / f"c{i}")
        plain = pipeline.run(compose_app(BASE + ov + ["cache.enabled=false"]),
                             tmp_path / f"p{i}")
        assert_same_datasets(cached, plain)
        n_det.add(len(datasets(cached)["detections/det_id"]))
    assert caplog.text.count("cache miss truth") == 1
    assert caplog.text.count("cache hit truth") == 5
    assert caplog.text.count("cache miss sensor") == 6
    assert len(n_det) > 1     # the sweep did change the sensor output


def test_streamed_run_equals_whole_tables(tmp_path, monkeypatch):
    """Small truth chunks and many sensor chunks give the tables of one-shot evaluation."""
    import functools
    from gmtiflow.sensor import model
    from gmtiflow import stages
    monkeypatch.setattr(stages, "simulate_chunks",
                        functools.partial(model.simulate_chunks, chunk_pairs=40))
    cfg = compose_app(BASE + ["cache.enabled=false", "chunk_s=7"])
    path = pipeline.run(cfg, tmp_path)
    got = datasets(path)
    roadmap, terrain = pipeline.build_scene(cfg)
    fleet = build_fleet(cfg.vehicles, roadmap, seed=cfg.seed, duration_s=cfg.scene.duration_s,
                        dt_s=cfg.fidelity.time_step_s)
    truth = fleet.truth_table(pipeline.sample_times(cfg.scene.duration_s,
                                                    cfg.fidelity.truth_output_dt_s))
    for c, v in truth.items():
        assert np.array_equal(got[f"truth/{c}"], v, equal_nan=True), c
    from gmtiflow.scene.platform import Platform
    sensed = simulate(cfg.sensor, fleet, Platform(cfg.platform, roadmap.origin), terrain,
                      cfg.seed, cfg.scene.duration_s, roadmap.origin,
                      effects=build_effects(cfg.sensor, cfg.clutter, cfg.seed, False),
                      dwell_mode=cfg.fidelity.dwell_mode, chunk_pairs=40)
    for table in ("dwells", "detections", "looks"):
        for c, v in sensed[table].items():
            assert np.array_equal(got[f"{table}/{c}"], v, equal_nan=True), (table, c)
    anc = pipeline.detection_ancestors(sensed["detections"], sensed["looks"])
    for c, v in anc.items():
        assert np.array_equal(got[f"detection_ancestors/{c}"], v), c


def test_failed_compute_leaves_no_entry(tmp_path):
    cache = StageCache(tmp_path, True)

    def boom():
        raise RuntimeError("x")
    with pytest.raises(RuntimeError):
        cache.get_or_compute("truth", "k1", boom)
    assert not list(tmp_path.rglob("*.pkl"))
    assert not list(tmp_path.rglob("*.partial"))
    assert cache.get_or_compute("truth", "k1", lambda: 3) == 3
    assert cache.get_or_compute("truth", "k1", lambda: 4) == 3


def test_stream_entry_only_when_exhausted(tmp_path):
    cache = StageCache(tmp_path, True)
    gen = cache.stream("sensor", "k", lambda: iter(range(5)))
    assert next(gen) == 0
    gen.close()                              # consumer stopped early
    assert not list(tmp_path.rglob("*.pkl")) and not list(tmp_path.rglob("*.partial"))
    assert list(cache.stream("sensor", "k", lambda: iter(range(5)))) == list(range(5))
    assert list(cache.stream("sensor", "k", lambda: iter([]))) == list(range(5))   # hit
    assert cache.hits == ["sensor"]


def test_damaged_entry_is_a_miss(tmp_path, caplog):
    cache = StageCache(tmp_path, True)
    cache.get_or_compute("truth", "k", lambda: np.arange(1000))
    entry = next(tmp_path.rglob("k.pkl"))
    entry.write_bytes(entry.read_bytes()[:50])            # truncated by hand
    assert np.array_equal(cache.get_or_compute("truth", "k", lambda: np.arange(3)),
                          np.arange(3))
    assert "damaged" in caplog.text
    with open(entry, "rb") as f:
        assert np.array_equal(pickle.load(f), np.arange(3))


def test_concurrent_processes_compute_once(tmp_path):
    """Two processes missing the same key at once: one computes, the other waits and hits."""
    import multiprocessing as mp
    ctx = mp.get_context("fork")
    with ctx.Pool(2) as pool:
        results = pool.map(_slow_compute, [str(tmp_path)] * 2)
    assert sorted(r[1] for r in results) == [False, True]    # exactly one computed
    assert results[0][0] == results[1][0]


def _slow_compute(directory):
    import os
    import time
    cache = StageCache(directory, True)
    value = cache.get_or_compute("truth", "shared",
                                 lambda: (time.sleep(0.5), os.getpid())[1])
    return value, bool(cache.misses)


def test_scale_mode_streams_without_keeping_tables(tmp_path, monkeypatch):
    """tracker=none metrics.enabled=false: same simulated tables, empty /tracks, no /metrics,
    and no table is kept in memory (TableSink.table() refuses)."""
    kept = []
    real = pipeline.TableSink

    class Spy(real):
        def __init__(self, *a, **kw):
            super().__init__(*a, **kw)
            kept.append(self.keep)
    from gmtiflow import stages
    monkeypatch.setattr(stages, "TableSink", Spy)
    full = pipeline.run(compose_app(BASE + ["cache.enabled=false"]), tmp_path / "full")
    assert any(kept)
    kept.clear()
    lean = pipeline.run(compose_app(BASE + ["cache.enabled=false", "tracker=none",
                                            "metrics.enabled=false"]), tmp_path / "lean")
    assert kept and not any(kept)
    a, b = datasets(full), datasets(lean)
    for name in a:
        if name.split("/")[0] in ("truth", "platform", "dwells", "detections", "looks",
                                  "detection_ancestors", "vehicles", "roads"):
            assert np.array_equal(a[name], b[name], equal_nan=a[name].dtype.kind == "f"), name
    assert not any(n.startswith("metrics") for n in b)
    assert len(b["tracks/track_id"]) == 0
    with pytest.raises(RuntimeError):
        pipeline.TableSink(None, "x").table()
