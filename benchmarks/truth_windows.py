"""The speed-profile kernel's windows against its step loop, on the scenes docs/scale.md quotes.

    python benchmarks/truth_windows.py [--repeat 5] [--only NAME ...]

What it measures: the CPU time of ``gmtiflow.scene.vehicles.build_fleet`` (routing, the random
draws, the speed-profile kernel, the wander; the truth stage) with the kernel taking windows of
steps (``simulate_profiles(..., windows=True)``, the default) and one step at a time
(``windows=False``, the step loop the windows reproduce bit for bit), alternating in one
process, median of ``--repeat`` runs after a warm-up; checks that both give the same profiles
bit for bit.  Prints the load (1-min average) before and after each scene.

    python benchmarks/truth_windows.py --against DIR [--repeat 5] [--only NAME ...]

A/B against another checkout DIR (e.g. ``git archive REV | tar -x -C DIR``): per scene, one
child process with ``PYTHONPATH=DIR`` and one with this checkout, alternating, ``--repeat``
times; each child builds the scene's road map once and prints the median CPU time of
``build_fleet`` (a fresh road map each run, so routing is counted as in a run) and of
``Fleet.truth_table`` at the fidelity's truth output step, over three runs after a warm-up.
Prints the medians over the children and the load.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time


def peer(n: int, scans: int):
    """The Stone Soup peer's workload (benchmarks/stonesoup_peer.py): off-road laps."""
    from gmtiflow.compose import compose
    from stonesoup_peer import peer_vehicles       # this script's directory is on sys.path
    duration = scans * 5.0
    cfg = compose(["fidelity=fast", "clutter=none", f"scene.duration_s={duration:g}"])
    cfg.vehicles = peer_vehicles(n, duration)
    return cfg


FIDELITY = ("vehicles=random vehicles.random.count=200 vehicles.random.start_time_max_s=120 "
            "scene.duration_s=600")
SCENES = {
    "peer 10 x 1800 scans": lambda: peer(10, 1800),
    "peer 1000 x 120 scans": lambda: peer(1000, 120),
    "default scene": lambda: [],
    "fidelity scene, full": lambda: f"{FIDELITY} fidelity=full".split(),
    "fidelity scene, fast": lambda: f"{FIDELITY} fidelity=fast".split(),
    "1000 vehicles x 30 min": lambda: ("vehicles=random vehicles.random.count=1000 "
                                       "scene.duration_s=1800 "
                                       "vehicles.random.start_time_max_s=1500").split(),
    "noisy: sigma 1, 0.1 s, stops": lambda: ("vehicles=random vehicles.random.count=100 "
                                             "scene.duration_s=900 fidelity=full "
                                             "vehicles.random.random_stop_rate_per_s=0.01 "
                                             "vehicles.random.speed_noise_mps=1.0").split(),
    "noisy: sigma 2, 1 s, stops": lambda: ("vehicles=random vehicles.random.count=50 "
                                           "scene.duration_s=600 fidelity=fast "
                                           "vehicles.random.random_stop_rate_per_s=0.02 "
                                           "vehicles.random.speed_noise_mps=2.0").split(),
}


def _scene_cfg(name):
    from gmtiflow.compose import compose
    cfg = SCENES[name]()
    return compose(cfg) if isinstance(cfg, list) else cfg


def child_times(name: str) -> dict:
    """Median CPU s of build_fleet (fresh road map each run) and truth_table, this process's
    gmtiflow, three runs after a warm-up."""
    import numpy as np

    from gmtiflow.scene import vehicles
    from gmtiflow.stages import build_scene
    cfg = _scene_cfg(name)
    times = np.arange(0.0, cfg.scene.duration_s + 1e-9, cfg.fidelity.truth_output_dt_s)
    build, table = [], []
    for r in range(4):
        roadmap, _ = build_scene(cfg)
        t = time.process_time()
        fl = vehicles.build_fleet(cfg.vehicles, roadmap, seed=cfg.seed,
                                  duration_s=cfg.scene.duration_s,
                                  dt_s=cfg.fidelity.time_step_s)
        t1 = time.process_time()
        fl.truth_table(times)
        if r:
            build.append(t1 - t)
            table.append(time.process_time() - t1)
    return {"build": statistics.median(build), "table": statistics.median(table)}


def against(other: str, repeat: int, only) -> None:
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    print(f"build_fleet / truth_table CPU s: {other} (before) against {here} (after), "
          f"{repeat} alternating child pairs, medians; load {os.getloadavg()[0]:.2f}")
    print(f"{'scene':32s} {'build before':>12} {'after':>7} {'table before':>12} {'after':>7} "
          f"{'load':>5}")
    for name in SCENES:
        if only and not any(o in name for o in only):
            continue
        res = {other: [], here: []}
        for _ in range(repeat):
            for root in (other, here):
                proc = subprocess.run(
                    [sys.executable, os.path.abspath(__file__), "--child-times", name],
                    capture_output=True, text=True, check=True,
                    env={**os.environ, "PYTHONPATH": root, "OMP_NUM_THREADS": "1"})
                res[root].append(json.loads(proc.stdout.strip().splitlines()[-1]))
        med = {root: {k: statistics.median(r[k] for r in rs) for k in ("build", "table")}
               for root, rs in res.items()}
        print(f"{name:32s} {med[other]['build']:12.3f} {med[here]['build']:7.3f} "
              f"{med[other]['table']:12.3f} {med[here]['table']:7.3f} "
              f"{os.getloadavg()[0]:5.2f}", flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--only", nargs="+", default=None, help="scene names (substrings)")
    ap.add_argument("--against", metavar="DIR", help="A/B with the checkout in DIR")
    ap.add_argument("--child-times", metavar="SCENE", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child_times:
        print(json.dumps(child_times(args.child_times)))
        return
    if args.against:
        against(os.path.abspath(args.against), args.repeat, args.only)
        return
    from gmtiflow.compose import compose
    from gmtiflow.scene import motion, vehicles
    from gmtiflow.stages import build_scene

    real = motion.simulate_profiles
    print(f"build_fleet CPU s, median of {args.repeat}, windows vs step loop, alternating")
    print(f"{'scene':32s} {'step loop':>9} {'windows':>8} {'ratio':>6} {'same':>5} {'load':>5}")
    for name, make in SCENES.items():
        if args.only and not any(o in name for o in args.only):
            continue
        cfg = make()
        cfg = compose(cfg) if isinstance(cfg, list) else cfg
        roadmap, _ = build_scene(cfg)
        times = {True: [], False: []}
        prof = {}
        for r in range(args.repeat + 1):
            for windows in (False, True):
                motion.simulate_profiles = (lambda inp, dt, progress=False, w=windows:
                                            real(inp, dt, progress, windows=w))
                t = time.process_time()
                fl = vehicles.build_fleet(cfg.vehicles, roadmap, seed=cfg.seed,
                                          duration_s=cfg.scene.duration_s,
                                          dt_s=cfg.fidelity.time_step_s)
                if r:
                    times[windows].append(time.process_time() - t)
                prof[windows] = fl.profiles
        motion.simulate_profiles = real
        same = all(getattr(prof[True], f).tobytes() == getattr(prof[False], f).tobytes()
                   for f in ("s_flat", "v_flat", "a_flat", "tau_flat", "mode_flat",
                             "noise_flat", "bridge_flat", "step_offset"))
        a, b = statistics.median(times[False]), statistics.median(times[True])
        print(f"{name:32s} {a:9.3f} {b:8.3f} {a / b:6.2f} {str(same):>5} "
              f"{os.getloadavg()[0]:5.2f}", flush=True)


if __name__ == "__main__":
    main()
