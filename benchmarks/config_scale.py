"""CPU time of the config work a run does before simulating, for a scene listing many vehicles.

    python benchmarks/config_scale.py [--vehicles 10 1000] [--repeat 3] [--omegaconf] [--hydra]

The config: the default scene with the Stone Soup peer's vehicles (``stonesoup_peer.py``: N
explicit off-road vehicles, each with a waypoint list of lapped rectangle corners for 600 s).
Timed, in this process, CPU seconds, best of ``--repeat``:

* ``validate``: ``config.validate`` (every problem of every group);
* ``/config``: ``config.to_yaml`` (the text stored as /config in the run file);
* ``cache keys``: ``cache.to_key_text`` of every cached stage (``pipeline.stages``; the stage
  cache is on by default, docs/scale.md "Caching").

``--omegaconf`` also times the cache keys through OmegaConf's structured copies and dumper
(``cache._omegaconf_key_text``, what ``to_key_text`` did before 2026-11-25) and checks that both
give the same text.

``--hydra`` also times what the ``gmtiflow`` command does with the same vehicles given as a
vehicles group file (``vehicles=peerN`` from a temporary config directory on
``hydra.searchpath``), once each (CPU seconds):

* ``compose``: Hydra's compose of ``conf/config.yaml`` with that file (what the command does
  before its job starts);
* ``to_object``: ``config.to_object`` of the composed DictConfig (conversion and validation);
* ``config.yaml``: ``config.omegaconf_text``, the text the command writes as
  ``.hydra/config.yaml``, and ``OmegaConf.to_yaml``'s own time for the same text (what it used
  before 2026-11-25; checked equal).

Prints the load before and after.
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
    ap.add_argument("--hydra", action="store_true",
                    help="also compose, to_object and .hydra/config.yaml (slow: ~10 s at 1,000)")
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
    if args.hydra:
        hydra_figures(args.vehicles)
    print(f"load after: {os.getloadavg()[0]:.2f}")


def hydra_figures(counts) -> None:
    """CPU seconds of compose, to_object and the .hydra/config.yaml text (module docstring)."""
    import tempfile

    from hydra import compose as hydra_compose
    from hydra import initialize_config_module
    from hydra.core.global_hydra import GlobalHydra
    from omegaconf import OmegaConf
    from stonesoup_peer import peer_vehicles

    from gmtiflow import config
    print(f"{'vehicles':>8} {'compose s':>10} {'to_object s':>11} {'config.yaml s':>13} "
          f"{'OmegaConf.to_yaml s':>19}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for n in counts:
            group = Path(tmp) / "vehicles"
            group.mkdir(exist_ok=True)
            (group / f"peer{n}.yaml").write_text(config.pyyaml_text(peer_vehicles(n, 600.0)))
            overrides = [f"hydra.searchpath=[file://{tmp}]", f"vehicles=peer{n}"]
            GlobalHydra.instance().clear()
            t0 = time.process_time()
            with initialize_config_module(config_module="gmtiflow.conf", version_base="1.3"):
                cfg = hydra_compose(config_name="config", overrides=overrides)
            t1 = time.process_time()
            GlobalHydra.instance().clear()
            config.to_object(cfg)
            t2 = time.process_time()
            text = getattr(config, "omegaconf_text", OmegaConf.to_yaml)(cfg)  # (older: none)
            t3 = time.process_time()
            old = OmegaConf.to_yaml(cfg)
            t4 = time.process_time()
            if text != old:
                raise SystemExit(f"{n} vehicles: .hydra/config.yaml texts differ")
            print(f"{n:8d} {t1 - t0:10.3f} {t2 - t1:11.3f} {t3 - t2:13.3f} {t4 - t3:19.3f}",
                  flush=True)


if __name__ == "__main__":
    main()
