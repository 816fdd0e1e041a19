"""gmtiflow against Stone Soup's own detection simulator on a matched workload (docs/scale.md).

    python benchmarks/stonesoup_peer.py [--quick] [--targets 10 1000] [--scans 1800 120]
                                        [--repeat 3]

Workload, the same for both: N targets present at every scan, S scans 5 s apart, about 10
false alarms per scan, P_D about 0.9 from the signal.  gmtiflow also models what Stone Soup's
simulator does not: targets in the clutter notch (Doppler-blind) and targets closer than a
resolution cell (merged into one report), so it reports fewer detections per target-scan
(printed: the share of each outcome of its looks); the ratio is per detection either way.

* Stone Soup (the peer): ``MultiTargetGroundTruthSimulator`` (N pre-existing targets, constant
  velocity, no births or deaths) feeding ``SimpleDetectionSimulator`` (linear position
  measurement, P_D 0.9, clutter rate 10 per scan over the 10 km x 10 km surveillance area).
* gmtiflow: the default scene and sensor, ``fidelity=fast`` (1 s motion steps, each scan at
  one instant: Stone Soup's model has no dwells either), N off-road vehicles each driving laps
  of its own 4 km x 2 km rectangle around the town for the whole scene (5 m/s), thermal-noise
  false alarms at 10 per scan (``sensor.pfa`` set from the resolution cells), no clutter
  regions; tracker, metrics, report and text exports off; run.h5 written, into an empty
  directory (as a Hydra run's own), with malloc tuned as the ``gmtiflow`` command tunes it
  (:mod:`gmtiflow.allocator`).

Both run in a fresh process each, in ``--repeat`` rounds (default 3) per target count; the two
simulators alternate which goes first from round to round.  "sim" is the simulation alone
(Stone Soup: building and iterating the simulators; gmtiflow: ``pipeline.run``, truth + sensor +
run.h5, after its imports), "process" is the whole process from launch (imports and config
included).  The figure compared is detections per second (target detections and false alarms):
ratio = gmtiflow's / Stone Soup's within a round, per wall second and per CPU second of the
simulation (the CPU ratio is the steadier one on a shared machine; gmtiflow's CPU time includes
its run-file compression threads) and per second of the whole process; the summary is the
median over the rounds with their range (either side moves by ~5 % between runs on a shared
machine, so one round is not enough to say which side of a goal a ratio falls).  "sim faults"
counts the minor page faults during the simulation (fresh memory the kernel maps and
zero-fills: a fresh process pays them as its heap grows to the run's peak).  ``--quick`` runs
one round of 10 targets x 120 scans and 1,000 targets x 3 scans.  Prints the load before and
after.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time

REVISIT_S = 5.0
FA_PER_SCAN = 10.0
GOALS = {10: 50.0, 1000: 300.0}     # issue 18: simulation-only speed-up over the peer


def stonesoup_child(n: int, scans: int) -> dict:
    import datetime

    import numpy as np
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                    ConstantVelocity)
    from stonesoup.simulator.simple import (MultiTargetGroundTruthSimulator,
                                            SimpleDetectionSimulator)
    from stonesoup.types.state import GaussianState

    start, cpu0, faults0 = time.perf_counter(), time.process_time(), minor_faults()
    g = np.random.default_rng(1)
    states = [np.array([[x], [vx], [y], [vy]])
              for x, y, vx, vy in zip(g.uniform(-3000, 1000, n), g.uniform(-1500, 500, n),
                                      g.uniform(-10, 10, n), g.uniform(-10, 10, n))]
    truth = MultiTargetGroundTruthSimulator(
        transition_model=CombinedLinearGaussianTransitionModel(
            [ConstantVelocity(0.05), ConstantVelocity(0.05)]),
        initial_state=GaussianState(np.zeros((4, 1)), np.diag([1e6, 100.0, 1e6, 100.0])),
        timestep=datetime.timedelta(seconds=REVISIT_S), number_steps=scans, birth_rate=0.0,
        death_probability=0.0, preexisting_states=states, initial_number_targets=0, seed=1)
    detector = SimpleDetectionSimulator(
        groundtruth=truth,
        measurement_model=LinearGaussian(ndim_state=4, mapping=(0, 2),
                                         noise_covar=np.diag([25.0, 25.0])),
        meas_range=np.array([[-5000.0, 5000.0], [-5000.0, 5000.0]]),
        detection_probability=0.9, clutter_rate=FA_PER_SCAN, seed=1)
    n_det = n_scan = 0
    for _, detections in detector:
        n_det += len(detections)
        n_scan += 1
    return {"sim_s": time.perf_counter() - start, "sim_cpu_s": time.process_time() - cpu0,
            "faults": minor_faults() - faults0, "detections": n_det, "scans": n_scan}


def peer_vehicles(n: int, duration_s: float):
    """The matched workload's vehicles: ``n`` off-road rectangles of 12 km lapped at 5 m/s,
    enough laps for ``duration_s``, no position noise (seeded: the same for every run)."""
    import numpy as np

    from gmtiflow.scene.vehicles import VehicleSpec, VehiclesConfig
    g = np.random.default_rng(1)
    laps = int(np.ceil(duration_s * 5.0 / 12_000.0)) + 1     # 12 km laps at 5 m/s
    specs = []
    for i, (x, y) in enumerate(zip(g.uniform(-4000, -2000, n).tolist(),
                                   g.uniform(-2500, -1500, n).tolist())):
        corners = [[x, y], [x + 4000, y], [x + 4000, y + 2000], [x, y + 2000]]
        specs.append(VehicleSpec(name=f"t{i:04d}", cruise_speed_mps=5.0,
                                 off_road=corners * laps + [[x, y]],
                                 position_noise_m=[0.0, 0.0, 0.0]))
    return VehiclesConfig(vehicles=specs)


def gmtiflow_child(n: int, scans: int, out: str) -> dict:
    import numpy as np

    from gmtiflow import pipeline
    from gmtiflow.compose import compose

    duration = scans * REVISIT_S
    base = ["fidelity=fast", "clutter=none", "tracker=none", "metrics.enabled=false",
            "report=none", "export=none", "cache.enabled=false", "progress=false",
            f"scene.duration_s={duration:g}"]
    cfg = compose(base)
    sensor = cfg.sensor.normalised()
    per_scan = sensor.expected_false_alarms_per_dwell * sensor.n_dwells
    cfg = compose(base + [f"sensor.pfa={sensor.pfa * FA_PER_SCAN / per_scan:.6g}"])
    cfg.vehicles = peer_vehicles(n, duration)
    import gmtiflow.config_yaml   # the lazy imports a run makes (its /config text, the
    import gmtiflow.evaluate      # manifest's atomic writes, the track stage): in the
    import gmtiflow.formats       # process time, not sim, as Stone Soup's imports are
    gmtiflow.evaluate.track
    from gmtiflow import allocator
    allocator.tune()              # as the gmtiflow command does before its run allocates
    start, cpu0, faults0 = time.perf_counter(), time.process_time(), minor_faults()
    path = pipeline.run(cfg, out)
    sim, sim_cpu = time.perf_counter() - start, time.process_time() - cpu0
    faults = minor_faults() - faults0
    import h5py
    from gmtiflow.sensor.outcome import Outcome
    with h5py.File(path, "r") as f:
        tid = f["detections"]["truth_id"][()]
        dwells = f["dwells"]["revisit_id"][()]
        outcome = f["looks"]["outcome"][()]
    return {"sim_s": sim, "sim_cpu_s": sim_cpu, "faults": faults, "detections": int(len(tid)),
            "false_alarms": int((tid < 0).sum()), "scans": int(len(np.unique(dwells))),
            "looks": {o.name.lower(): int(np.sum(outcome == o)) for o in Outcome}}


def minor_faults() -> int:
    """This process's minor page faults so far (fresh pages the kernel maps and zero-fills)."""
    import resource
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def run_child(kind: str, n: int, scans: int, out: str) -> dict:
    """One simulator's run in a fresh process; gmtiflow's into an empty ``out`` (as a Hydra
    run's own new directory: no earlier run's files to remove inside the timed run)."""
    if kind == "gmtiflow":
        shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, __file__, "--child", kind, str(n), str(scans), out],
                          capture_output=True, text=True, env={**os.environ,
                                                               "OMP_NUM_THREADS": "1"})
    wall = time.perf_counter() - t0
    if proc.returncode:
        print(proc.stderr[-3000:], file=sys.stderr)
        raise SystemExit(f"{kind} {n} x {scans} failed")
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    r["process_s"] = wall
    return r


def ratios(res: dict) -> dict:
    """gmtiflow's detections per second over Stone Soup's, per second of simulation wall time
    ("sim"), of simulation CPU time ("cpu") and of the whole process ("process")."""
    def rate(kind, key):
        return res[kind]["detections"] / res[kind][key]
    return {name: rate("gmtiflow", key) / rate("stonesoup", key)
            for name, key in (("sim", "sim_s"), ("cpu", "sim_cpu_s"), ("process", "process_s"))}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, nargs="+", default=[10, 1000])
    ap.add_argument("--scans", type=int, nargs="+", default=[1800, 120],
                    help="scans per target count (same order)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="rounds per target count, the two simulators alternating (default 3)")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default="outputs/benchmarks/stonesoup_peer")
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        kind, n, scans, out = args.child
        fn = stonesoup_child if kind == "stonesoup" else gmtiflow_child
        res = fn(int(n), int(scans)) if kind == "stonesoup" else fn(int(n), int(scans), out)
        print(json.dumps(res))
        return
    scans = [120, 3] if args.quick else args.scans
    repeat = 1 if args.quick else max(args.repeat, 1)
    print(f"load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)")
    print(f"{'targets':>7} {'scans':>6} {'round':>5} {'simulator':>10} {'detections':>10} "
          f"{'sim s':>8} {'sim CPU s':>9} {'process s':>9} {'det/s sim':>10} "
          f"{'det/s sim CPU':>13} {'det/s process':>13} {'sim faults':>10}")
    for n, s in zip(args.targets, scans):
        rounds = []
        for k in range(repeat):
            res = {}
            # Alternate which simulator goes first, so neither always runs after the other.
            for kind in ("stonesoup", "gmtiflow")[::1 if k % 2 == 0 else -1]:
                r = run_child(kind, n, s, os.path.join(args.out, f"{n}_{s}"))
                res[kind] = r
                print(f"{n:7d} {s:6d} {k + 1:5d} {kind:>10} {r['detections']:10d} "
                      f"{r['sim_s']:8.3f} {r['sim_cpu_s']:9.3f} {r['process_s']:9.2f} "
                      f"{r['detections'] / r['sim_s']:10.3g} "
                      f"{r['detections'] / r['sim_cpu_s']:13.3g} "
                      f"{r['detections'] / r['process_s']:13.3g} {r['faults']:10d}", flush=True)
            rounds.append((res, ratios(res)))
        goal = GOALS.get(n)
        summary = []
        for name, label in (("sim", "simulation"), ("cpu", "simulation CPU time"),
                            ("process", "whole process")):
            values = sorted(r[name] for _, r in rounds)
            spread = (f" (rounds {values[0]:.1f}-{values[-1]:.1f}x)" if repeat > 1 else "")
            summary.append(f"{label} {statistics.median(values):.1f}x{spread}")
        res = rounds[-1][0]
        print(f"  {n} targets: gmtiflow / Stone Soup detections per second, "
              f"{'median of ' + str(repeat) + ' rounds' if repeat > 1 else 'one round'}: "
              + "; ".join(summary) + (f"; goal (simulation) >= {goal:g}x" if goal else ""))
        print(f"  gmtiflow scans {res['gmtiflow']['scans']}, false alarms "
              f"{res['gmtiflow']['false_alarms']}")
        looks = res["gmtiflow"]["looks"]
        shares = ", ".join(f"{k} {v / max(sum(looks.values()), 1):.1%}"
                           for k, v in looks.items() if v)
        print(f"  gmtiflow's {sum(looks.values())} looks (target, scan): {shares}")
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
