"""The speed-profile kernel's windows against its step loop, on the scenes docs/scale.md quotes.

    python benchmarks/truth_windows.py [--repeat 5] [--only NAME ...]

What it measures: the CPU time of ``gmtiflow.scene.vehicles.build_fleet`` (routing, the random
draws, the speed-profile kernel, the wander; the truth stage) with the kernel taking windows of
steps (``simulate_profiles(..., windows=True)``, the default) and one step at a time
(``windows=False``, the step loop the windows reproduce bit for bit), alternating in one
process, median of ``--repeat`` runs after a warm-up; checks that both give the same profiles
bit for bit.  Prints the load (1-min average) before and after each scene.
"""
from __future__ import annotations

import argparse
import os
import statistics
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


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--only", nargs="+", default=None, help="scene names (substrings)")
    args = ap.parse_args(argv)
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
