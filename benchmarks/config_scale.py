"""CPU time of the config work a run does before simulating, for a scene listing many vehicles.

    python benchmarks/config_scale.py [--vehicles 10 1000] [--repeat 3] [--omegaconf]

The config: the default scene with the Stone Soup peer's vehicles (``stonesoup_peer.py``: N
explicit off-road vehicles, each with a waypoint list of lapped rectangle corners for 600 s).
Timed, in this process, CPU seconds, best of ``--repeat``:

* ``validate``: ``config.validate`` (every problem of every group);
* ``/config``: ``config.to_yaml`` (the text stored as /config in the run file);
* ``cache keys``: ``cache.to_key_text`` of every cached stage (``pipeline.stages``; the stage
  cache is on by default, docs/scale.md "Caching").

``--omegaconf`` also times the cache keys through OmegaConf's structured copies and dumper
(``cache._omegaconf_key_text``, what ``to_key_text`` did before 2026-11-25) and checks that both
give the same text.  Prints the load before and after.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def best_cpu(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicles", type=int, nargs="+", default=[10, 1000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--omegaconf", action="store_true",
                    help="also the cache keys through OmegaConf (slow: ~11 s at 1,000)")
    args = ap.parse_args(argv)
    from stonesoup_peer import peer_vehicles

    from gmtiflow import cache, config, pipeline
    from gmtiflow.compose import compose
    print(f"load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)")
    print(f"{'vehicles':>8} {'validate s':>10} {'/config s':>10} {'cache keys s':>12}"
          + (f" {'keys via OmegaConf s':>20}" if args.omegaconf else ""), flush=True)
    for n in args.vehicles:
        cfg = compose([])
        cfg.vehicles = peer_vehicles(n, 600.0)
        parts = [st.key() for st in pipeline.stages(cfg) if st.key is not None]
        row = [best_cpu(lambda: config.validate(cfg), args.repeat),
               best_cpu(lambda: config.to_yaml(cfg), args.repeat),
               best_cpu(lambda: [cache.to_key_text(**p) for p in parts], args.repeat)]
        if args.omegaconf:
            row.append(best_cpu(lambda: [cache._omegaconf_key_text(p) for p in parts], 1))
            same = all(cache.to_key_text(**p) == cache._omegaconf_key_text(p) for p in parts)
            if not same:
                raise SystemExit(f"{n} vehicles: the cache key texts differ")
        print(f"{n:8d} " + " ".join(f"{t:{w}.4f}" for t, w in zip(row, (10, 10, 12, 20))),
              flush=True)
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
