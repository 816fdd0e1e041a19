"""Throughput of the GMTI sensor stage: (dwell, target) pairs and detections per second.

Scene: the default sensor preset (conf/sensor/default.yaml), a platform flying west at 200 m/s,
6 km up, 30 km south of an 8 km x 8 km scene (passing broadside at mid-run), vehicles driving
straight lines at 5-25 m/s in random directions (a self-contained fake fleet: the benchmark
measures the sensor stage, not the truth model), flat terrain.

    PYTHONPATH=. python benchmarks/sensor_throughput.py [--vehicles 100 10000] [--duration 60]
                                                         [--workers 1 2] [--repeat 5]

Wall-clock and CPU times are the best of ``--repeat`` runs (CPU time sums all threads; it is
the steadier figure on a shared machine).  "pairs" are the (dwell, target) pairs whose
geometry is evaluated exactly (the candidates of the footprint search, ~2 per vehicle and
revisit here); "looks" the /looks rows kept; the coarse once-per-revisit pass over every
vehicle is included in the time but not counted.

``--plain`` also times a plain-numpy reference kernel on the same number of (dwell, target)
pairs, given as flat arrays (platform and target position and velocity, antenna axes, beam):
flat-earth range and line of sight, antenna angles, beam mismatch and scan loss, SNR, P_D, the
counter-based detection draw and the three measurement-error draws; no tables, no candidate
search, no round earth, no geolocation.  It is what one core does when only the per-pair
arithmetic is left; the model's pairs per CPU second over it says how much the model's
structure costs.  The two are alternated; both in pairs per CPU second.

``--baseline REV`` also loads the ``gmtiflow`` package (and ``conf/``) of git revision REV
under another name into the same process and alternates the two models on the same scene
(best CPU time of ``--repeat`` runs each), checking that their tables are equal: the speed-up
of the model's code alone, on the same allocator.  The malloc setting of the ``gmtiflow``
command (``gmtiflow.allocator``) is applied as the command does; ``GMTIFLOW_MALLOC=default``
leaves the C library's defaults.
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from gmtiflow import frames
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.model import simulate

CONF = Path(__file__).resolve().parents[1] / "conf" / "sensor" / "default.yaml"


class LineFleet:
    """Vehicles on straight lines at constant velocity, always active."""

    def __init__(self, n: int, seed: int = 0, extent_m: float = 8_000.0):
        g = np.random.default_rng(seed)
        self.p0 = g.uniform(-extent_m / 2, extent_m / 2, (n, 2))
        hd = g.uniform(0, 2 * np.pi, n)
        sp = g.uniform(5.0, 25.0, n)
        self.v = np.column_stack([np.sin(hd) * sp, np.cos(hd) * sp])
        self.heading = np.mod(hd, 2 * np.pi)
        self.vehicles = {"vehicle_id": np.arange(n, dtype=np.int64),
                         "vehicle_type": np.array(["car", "truck"] * (n // 2) + ["car"] * (n % 2))}

    def state_at(self, time_s, vehicle_id, columns=None):   # every column, whatever asked
        t, vid = np.broadcast_arrays(np.asarray(time_s, float), np.asarray(vehicle_id))
        x = self.p0[vid, 0] + self.v[vid, 0] * t
        y = self.p0[vid, 1] + self.v[vid, 1] * t
        zero = np.zeros(t.shape)
        return {"x_m": x, "y_m": y, "z_m": zero, "vx_mps": self.v[vid, 0],
                "vy_mps": self.v[vid, 1], "vz_mps": zero, "heading_rad": self.heading[vid],
                "invisible": np.zeros(t.shape, bool), "active": np.ones(t.shape, bool),
                "vehicle_id": vid}


class StraightPlatform:
    def __init__(self, duration_s: float, speed_mps: float = 200.0):
        self.x0 = 0.5 * duration_s * speed_mps
        self.speed = speed_mps

    def state_at(self, time_s):
        t = np.atleast_1d(np.asarray(time_s, float))
        n = t.size
        return {"x_m": self.x0 - self.speed * t, "y_m": np.full(n, -30_000.0),
                "z_m": np.full(n, 6_000.0), "vx_mps": np.full(n, -self.speed),
                "vy_mps": np.zeros(n), "vz_mps": np.zeros(n),
                "heading_rad": np.full(n, 1.5 * math.pi), "pitch_rad": np.zeros(n),
                "bank_rad": np.zeros(n)}


class FlatTerrain:
    flat = True

    def height_at(self, x_m, y_m):
        return np.zeros(np.broadcast(np.asarray(x_m), np.asarray(y_m)).shape)

    def line_of_sight(self, from_xyz, to_xyz, step_m=30.0):
        return np.ones(len(to_xyz), bool)


def plain_kernel(cfg, plat, tgt, vel_p, vel_t, b, h, u, beam, dwell_id, veh_id, seed=1):
    """The per-pair arithmetic alone (module doc): (hit, measured range, az, range rate)."""
    from gmtiflow import rng
    d = tgt - plat
    r = np.sqrt(np.einsum("ij,ij->i", d, d))
    los = d / r[:, None]
    lb = np.einsum("ij,ij->i", los, b)
    lh = np.einsum("ij,ij->i", los, h)
    lu = np.einsum("ij,ij->i", los, u)
    sin_az = lh / np.hypot(lb, lh)
    az = np.arcsin(sin_az)
    el = np.arcsin(lu)
    x = (sin_az - np.sin(beam)) / cfg.beamwidth_sine
    g = np.maximum(cfg.n_elements * np.cos(beam) ** 1.5 * np.exp(-2.772588722239781 * x * x),
                   1e-30)
    rr = np.einsum("ij,ij->i", vel_t - vel_p, los)
    snr_db = 120.0 + 20.0 * np.log10(g) - 40.0 * np.log10(r) + 10.0 * np.log10(el * el + 1.0)
    snr = 10.0 ** (snr_db / 10.0)
    log_pd = np.log(cfg.pfa) / (1.0 + snr)
    key = rng.counter_key(seed, "sensor", "pd")
    hit = np.log(rng.pair_uniform(key, dwell_id, veh_id)) < log_pd
    sig = 1.0 / np.sqrt(2.0 * snr)
    e = [rng.pair_normal(rng.counter_key(seed, "sensor", k), dwell_id, veh_id) * sig
         for k in ("error_range", "error_azimuth", "error_range_rate")]
    return hit, r + 15.0 * e[0], az + 0.01 * e[1], rr + 0.5 * e[2]


def plain_pairs(cfg, fleet, platform, duration_s, n_pairs, seed=0):
    """``n_pairs`` pairs of the benchmark's scene as flat arrays (times spread over the scene,
    random vehicles, the platform's antenna axes, a beam within the sector)."""
    from gmtiflow.sensor import antenna
    g = np.random.default_rng(seed)
    t = g.uniform(0.0, duration_s, n_pairs)
    vid = g.integers(0, len(fleet.vehicles["vehicle_id"]), n_pairs)
    st = fleet.state_at(t, vid)
    ps = platform.state_at(t)
    b, h, u = antenna.antenna_axes(ps["heading_rad"], ps["pitch_rad"], ps["bank_rad"],
                                   math.radians(cfg.mount_deg))
    col = np.column_stack
    return (col([ps["x_m"], ps["y_m"], ps["z_m"]]), col([st["x_m"], st["y_m"], st["z_m"]]),
            col([ps["vx_mps"], ps["vy_mps"], ps["vz_mps"]]),
            col([st["vx_mps"], st["vy_mps"], st["vz_mps"]]), col(b), col(h), col(u),
            g.uniform(-0.15, 0.15, n_pairs), np.arange(n_pairs), vid)


def load_baseline(rev: str):
    """``gmtiflow.sensor.model`` and ``gmtiflow.frames`` of git revision ``rev``, imported as
    the package ``gmtiflow_<rev>`` from a temporary export of that revision."""
    import importlib
    import io
    import re
    import subprocess
    import sys
    import tarfile
    import tempfile
    root = Path(__file__).resolve().parents[1]
    data = subprocess.run(["git", "-C", str(root), "archive", rev, "gmtiflow", "conf"],
                          check=True, capture_output=True).stdout
    tmp = Path(tempfile.mkdtemp())
    tarfile.open(fileobj=io.BytesIO(data)).extractall(tmp)
    name = "gmtiflow_" + re.sub(r"\W", "_", rev)
    (tmp / "gmtiflow").rename(tmp / name)
    for path in (tmp / name).rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        text = re.sub(r"\bgmtiflow(?=[. ])", name, text)
        path.write_text(text, encoding="utf-8")
    sys.path.insert(0, str(tmp))
    return (importlib.import_module(f"{name}.sensor.model"),
            importlib.import_module(f"{name}.sensor.config"),
            importlib.import_module(f"{name}.frames"))


def compare_baseline(rev, args, cfg, fleet, platform, origin) -> None:
    """Alternate the model of ``rev`` and this one, in this process (module doc)."""
    model_b, config_b, frames_b = load_baseline(rev)
    cfg_b = OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(config_b.SensorConfig),
                                                OmegaConf.load(CONF)))
    origin_b = frames_b.Origin(origin.lat_deg, origin.lon_deg, origin.height_m)
    runs = {rev: (model_b.simulate, cfg_b, origin_b), "this": (simulate, cfg, origin)}
    best, out, stats = {k: math.inf for k in runs}, {}, {}
    for _ in range(args.repeat):
        for k, (sim, c, o) in runs.items():
            stats[k] = {}
            c0 = time.process_time()
            out[k] = sim(c, fleet, platform, FlatTerrain(), 1, args.duration, o,
                         dwell_mode=args.mode, stats=stats[k])
            best[k] = min(best[k], time.process_time() - c0)
    same = all(np.array_equal(np.asarray(out[rev][t][c]), np.asarray(out["this"][t][c]),
                              equal_nan=True) for t in out["this"] for c in out["this"][t])
    pairs = stats["this"]["pairs_evaluated"]
    print(f"{'':>9} model of {rev}: {pairs / best[rev]:.3g} pairs/cpu-s; this one "
          f"{pairs / best['this']:.3g} pairs/cpu-s: {best[rev] / best['this']:.2f}x "
          f"(alternated, best of {args.repeat}); tables equal: {same}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--vehicles", type=int, nargs="+", default=[100, 10_000])
    ap.add_argument("--duration", type=float, default=60.0, help="scene seconds")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, default=5, help="runs per case; the best is shown")
    ap.add_argument("--mode", default="dwell_resolved", choices=["dwell_resolved", "instant_scan"])
    ap.add_argument("--plain", action="store_true", help="also time the plain-numpy kernel")
    ap.add_argument("--baseline", metavar="REV", default=None,
                    help="also time the model of git revision REV, alternated (module doc)")
    args = ap.parse_args()
    import os
    from gmtiflow import allocator
    tuned = allocator.tune()    # as the gmtiflow command runs (both kernels benefit alike)
    print(f"load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores); "
          f"malloc tuned as by the gmtiflow command: {tuned}")

    cfg = OmegaConf.to_object(OmegaConf.merge(OmegaConf.structured(SensorConfig),
                                              OmegaConf.load(CONF)))
    origin = frames.Origin(48.0, 11.0, 0.0)
    platform = StraightPlatform(args.duration)
    print(f"sensor preset default ({args.mode}), {args.duration:g} s scene, "
          f"revisit {cfg.revisit_s:g} s, best of {args.repeat}")
    print(f"{'vehicles':>9} {'workers':>7} {'pairs':>9} {'looks':>9} {'dets':>8} {'wall s':>8} "
          f"{'pairs/s':>10} {'looks/s':>10} {'dets/s':>10} {'cpu s':>8} {'pairs/cpu-s':>11}")
    for n in args.vehicles:
        fleet = LineFleet(n)
        for w in args.workers:
            best, cpu, stats, out = math.inf, math.inf, {}, None
            for _ in range(args.repeat):
                stats = {}
                t0, c0 = time.perf_counter(), time.process_time()
                out = simulate(cfg, fleet, platform, FlatTerrain(), 1, args.duration, origin,
                               workers=w, stats=stats, dwell_mode=args.mode)
                best = min(best, time.perf_counter() - t0)
                cpu = min(cpu, time.process_time() - c0)
            pairs = stats["pairs_evaluated"]
            looks = len(out["looks"]["dwell_id"])
            dets = len(out["detections"]["det_id"])
            print(f"{n:>9} {w:>7} {pairs:>9} {looks:>9} {dets:>8} {best:>8.3f} "
                  f"{pairs / best:>10.3g} {looks / best:>10.3g} {dets / best:>10.3g} "
                  f"{cpu:>8.3f} {pairs / cpu:>11.3g}")
            if args.plain and w == 1:
                arrays = plain_pairs(cfg, fleet, platform, args.duration, pairs)
                p_cpu, m_cpu = math.inf, math.inf
                for _ in range(args.repeat):      # alternated: plain kernel, model
                    c0 = time.process_time()
                    plain_kernel(cfg, *arrays)
                    p_cpu = min(p_cpu, time.process_time() - c0)
                    c0 = time.process_time()
                    simulate(cfg, fleet, platform, FlatTerrain(), 1, args.duration, origin,
                             dwell_mode=args.mode)
                    m_cpu = min(m_cpu, time.process_time() - c0)
                print(f"{'':>9} plain-numpy kernel on {pairs} pairs: {pairs / p_cpu:.3g} "
                      f"pairs/cpu-s; model {pairs / m_cpu:.3g} pairs/cpu-s = "
                      f"{p_cpu / m_cpu:.0%} of the plain kernel's rate")
            if args.baseline and w == 1:
                compare_baseline(args.baseline, args, cfg, fleet, platform, origin)
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
