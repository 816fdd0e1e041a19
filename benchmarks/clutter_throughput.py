"""Clutter false alarms in the sensor stage: CPU µs per false alarm and how it scales.

Run from the repository root:

    python benchmarks/clutter_throughput.py [--quick] [--baseline REV]
    python benchmarks/clutter_throughput.py --run-share [--repeats 3]

What it measures (issue 18: "false alarms drawn directly in each dwell's footprint, vectorised
across dwells: cost per false alarm ≤ 5 µs and linear in their number"): the sensor stage of
the default sensor over an empty fleet (platform west at 200 m/s, 6 km up, 30 km south of the
scene; flat ground; the detector's noise false alarms off), with one clutter source at a time
at densities swept per km² per dwell:

* ``FoV-wide``: ``clutter.fov_density_per_km2``, over every dwell's whole cell;
* ``big region``: one polygon region of 720 km² holding every cell of the run (a land-cover
  class: forest, sea);
* ``town``: the ``clutter=urban`` preset's 3.84 km² town polygon, which most cells miss (at
  30 times the swept densities: a busy town, or a wind farm's few hundred m²).

Each figure is the CPU time (``time.process_time``) of the run with the source minus the run
without it, median of ``--repeats``, divided by the false alarms it put in /detections: all of
what a run pays per false alarm (count, placement, region and footprint tests, the exact cell
test with horizon and terrain, marks, /detections rows).  Linear means the figure stays flat as
the count grows; the log-log slope of cost against count over the densities is printed (1 =
linear).  ``--baseline REV`` loads ``gmtiflow/sensor/clutter.py`` as of git revision REV and
times it too, alternating with the working tree's module run by run (A/B under the same load;
its false-alarm counts differ only by the draws).  The 1-minute load average is printed with
every row.  Then the FoV-wide density under a platform banked 4.4° (the default platform's
circle) and −15° (a steeper turn), the sectors from the cells' geolocated edges against sectors
padded by the bank angle (as before), alternated.  Last, the clutter module alone called with polygon footprints (a library use, not
the stage's), at ten times the densities, A/B likewise.  ``--run-share`` instead times whole
runs (truth, sensor, run.h5) of 1,000 random vehicles over 10 min without clutter, with
``clutter=urban`` and with 5 FoV-wide false alarms per km² and dwell (the issue's example), and
prints what clutter adds: all the false alarms cost, /detections rows in run.h5 included.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from gmtiflow import frames
from gmtiflow.sensor import clutter as cl
from gmtiflow.sensor import effects as fx
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.model import simulate

sys.path.insert(0, str(Path(__file__).resolve().parent))
from effects_scaling import _Flat, _NoFleet, _Platform  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ORIGIN = frames.Origin(48.0, 11.0, 500.0)
#: 720 km² (40 km x 18 km less two corners' worth of a hexagon's cuts), holding every cell of a
#: run of up to 100 s along y = -30 km (cells reach y = -11 ... +5.5 km, x = -26 ... +6 km).
BIG = [[-32_000, -12_000], [8_000, -12_000], [10_000, -3_000], [8_000, 6_000],
       [-32_000, 6_000], [-34_000, -3_000]]
TOWN = [[-2100, -1100], [1100, -1100], [1100, 100], [-2100, 100]]
#: The town's densities are the swept ones times this: few cells see it, so at the FoV-wide
#: densities it would give a few dozen false alarms, below the timing noise.
TOWN_SCALE = 30.0


def load_baseline(rev: str):
    """``gmtiflow/sensor/clutter.py`` at git revision ``rev``, as a module of its own."""
    src = subprocess.run(["git", "show", f"{rev}:gmtiflow/sensor/clutter.py"], cwd=ROOT,
                         capture_output=True, text=True, check=True).stdout
    path = Path(tempfile.mkdtemp()) / "clutter_baseline.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("clutter_baseline", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod          # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


@contextlib.contextmanager
def clutter_module(mod):
    """Run the sensor stage's FalseAlarms effect with ``mod`` as its clutter module."""
    saved = fx.clutter
    fx.clutter = mod
    try:
        yield
    finally:
        fx.clutter = saved


def sources(densities):
    """(label, density, ClutterConfig built from a module) per source and density."""
    out = []
    for d in densities:
        out.append(("FoV-wide", d, lambda m, d=d: m.ClutterConfig(fov_density_per_km2=d)))
    for name, poly, scale in (("big region", BIG, 1.0), ("town", TOWN, TOWN_SCALE)):
        for d in densities:
            d = d * scale
            out.append((name, d, lambda m, d=d, poly=poly, name=name: m.ClutterConfig(
                regions=[m.ClutterRegionConfig(name=name.replace(" ", "-"), vertices_m=poly,
                                               density_per_km2=d)])))
    return out


def run_once(cfg, ccfg, duration_s):
    effects = [] if ccfg is None else [fx.FalseAlarms(cfg, ccfg, 3)]
    t0 = time.process_time()
    out = simulate(cfg, _NoFleet(), _Platform(), _Flat(), 3, duration_s, ORIGIN, effects=effects)
    return time.process_time() - t0, len(out["detections"]["det_id"])


#: Banks timed: the default platform's circle (4.4°, every dwell of a default-platform run)
#: and a steeper turn's.
BANKS_DEG = (4.4, -15.0)


class _Banked(_Platform):
    """The benchmark's platform with a constant bank (a turn's attitude, without the turn)."""

    def __init__(self, bank_deg):
        self.bank_rad = np.radians(bank_deg)

    def state_at(self, time_s):
        s = super().state_at(time_s)
        s["bank_rad"] = np.full(len(s["x_m"]), self.bank_rad)
        return s


class _BankPad(fx.FalseAlarms):
    """FalseAlarms with the sectors padded by the bank angle (as before the tilted cells'
    azimuths were geolocated): the A side of the banked comparison."""

    def _tilted_cell_azimuths(self, ctx, rows, lo, hi, to_world, margin):
        a0, span = super()._tilted_cell_azimuths(ctx, rows, lo, hi, to_world, margin)
        return a0, np.full_like(span, np.nan)


def banked(densities, repeats, duration_s, bank_deg):
    """FoV-wide false alarms under a platform banked ``bank_deg``: the sectors from the cells'
    geolocated edges against sectors padded by the bank angle, alternated; CPU time less the
    banked run without clutter, median of ``repeats``."""
    cfg = SensorConfig(noise_false_alarms=False)

    def once(effect):
        t0 = time.process_time()
        out = simulate(cfg, _NoFleet(), _Banked(bank_deg), _Flat(), 3, duration_s, ORIGIN,
                       effects=[] if effect is None else [effect])
        return time.process_time() - t0, len(out["detections"]["det_id"])

    rows = []
    for dens in densities:
        ccfg = cl.ClutterConfig(fov_density_per_km2=dens)
        base, per, counts = [], {"geolocated edges": [], "bank pad (before)": []}, {}
        for _ in range(repeats):
            base.append(once(None)[0])
            for name, kind in (("geolocated edges", fx.FalseAlarms), ("bank pad (before)", _BankPad)):
                t, n = once(kind(cfg, ccfg, 3))
                per[name].append(t)
                counts[name] = n
        t0 = float(np.median(base))
        for name in per:
            rows.append((name, dens, counts[name], float(np.median(per[name])) - t0,
                         os.getloadavg()[0]))
    return rows


def library_polygons(densities, repeats, impls):
    """The clutter module alone, called with polygon footprints (the library path): 100 dwells,
    each a 67.5 km² annular sector (15-30 km, 0.2 rad) as a 32-vertex polygon (effects_scaling's
    footprints), FoV-wide density only.  CPU time, median of ``repeats``, modules alternated."""
    rows = []
    for dens in densities:
        per = {name: [] for name, _ in impls}
        counts = {}
        for _ in range(repeats):
            for name, mod in impls:
                fps = np.stack([mod.annular_sector_polygon([x, -30_000.0], 15_000.0, 30_000.0,
                                                           -0.1, 0.1)
                                for x in np.linspace(0, 2000, 100)])
                ccfg = mod.ClutterConfig(fov_density_per_km2=dens)
                t0 = time.process_time()
                out = mod.false_alarms(ccfg, 7, np.arange(100), fps)
                per[name].append(time.process_time() - t0)
                counts[name] = len(out["x_m"])
        for name, _ in impls:
            rows.append((name, dens, counts[name], float(np.median(per[name])),
                         os.getloadavg()[0]))
    return rows


RUN_SCENE = ["vehicles=random", "vehicles.random.count=1000", "scene.duration_s=600",
             "vehicles.random.start_time_max_s=500", "cache.enabled=false", "tracker=none",
             "metrics.enabled=false", "report=none", "export=none", "progress=false"]
RUN_CASES = {"clutter=none": ["clutter=none"], "clutter=urban": ["clutter=urban"],
             "FoV-wide 5/km²": ["clutter=none", "clutter.fov_density_per_km2=5"],
             "FoV-wide 5/km², bank pad (before)": ["clutter=none",
                                                   "clutter.fov_density_per_km2=5"]}


@contextlib.contextmanager
def bank_pad(on: bool):
    """Within: FalseAlarms pads banked dwells' sectors by the bank angle (as before)."""
    saved = fx.FalseAlarms._tilted_cell_azimuths

    def padded(self, *args):
        a0, span = saved(self, *args)
        return a0, np.full_like(span, np.nan)

    if on:
        fx.FalseAlarms._tilted_cell_azimuths = padded
    try:
        yield
    finally:
        fx.FalseAlarms._tilted_cell_azimuths = saved


def run_share(repeats):
    """Whole runs (truth, sensor, run.h5; tracker, metrics, report, exports off) of 1,000
    random vehicles over 10 min, without clutter, with ``clutter=urban`` and with 5 FoV-wide
    false alarms per km² and dwell (also with the banked dwells' sectors padded by the bank
    angle, as before: the default platform's circle banks 4.4°): CPU time of the process (all
    threads), median of ``repeats``, cases alternated; and the false alarms in /detections."""
    import h5py

    from gmtiflow import pipeline
    from gmtiflow.compose import compose

    cpu = {k: [] for k in RUN_CASES}
    fas = {}
    for _ in range(repeats):
        for name, extra in RUN_CASES.items():
            with tempfile.TemporaryDirectory() as d, bank_pad("before" in name):
                t0 = time.process_time()
                path = pipeline.run(compose(RUN_SCENE + extra), d)
                cpu[name].append(time.process_time() - t0)
                with h5py.File(path) as f:
                    fas[name] = int(np.sum(f["detections/truth_id"][:] < 0))
    return {k: (float(np.median(v)), fas[k], os.getloadavg()[0]) for k, v in cpu.items()}


def kept_fraction(cfg, duration_s, density=10.0):
    """Fraction of the FoV-wide draws that fall in their dwell's cell and are kept: false alarms
    over the expected draws (density × the padded sectors' areas)."""
    areas = []

    class Spy(fx.FalseAlarms):
        def footprint_sectors(self, ctx):
            s = super().footprint_sectors(ctx)
            areas.append(0.5 * s[:, 5] * (s[:, 3] ** 2 - s[:, 2] ** 2))
            return s

    out = simulate(cfg, _NoFleet(), _Platform(), _Flat(), 3, duration_s, ORIGIN,
                   effects=[Spy(cfg, cl.ClutterConfig(fov_density_per_km2=density), 3)])
    return len(out["detections"]["det_id"]) / (density * np.concatenate(areas).sum() / 1e6)


def slope(counts, costs):
    c, t = np.asarray(counts, float), np.asarray(costs, float)
    ok = (c > 0) & (t > 0)
    return float(np.polyfit(np.log(c[ok]), np.log(t[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--densities", type=float, nargs="+", default=[1.0, 3.0, 10.0, 30.0])
    ap.add_argument("--revisits", type=int, default=20, help="revisits of 14 dwells (5 s each)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--baseline", metavar="REV", default=None,
                    help="also time gmtiflow/sensor/clutter.py as of this git revision (A/B)")
    ap.add_argument("--quick", action="store_true",
                    help="densities 1 and 10, 10 revisits, 3 repeats")
    ap.add_argument("--run-share", action="store_true",
                    help="only clutter's share of whole runs (1,000 vehicles, 10 min)")
    args = ap.parse_args(argv)
    if args.run_share:
        rows = run_share(args.repeats)
        print(f"# Clutter's share of whole runs ({' '.join(RUN_SCENE)}), CPU time of the "
              f"process, median of {args.repeats}\n")
        print("| clutter | false alarms in /detections | CPU s | more than clutter=none "
              "| load |\n|---|---|---|---|---|")
        t_none, fa_none, _ = rows["clutter=none"]
        for name, (t, n, load) in rows.items():
            extra = "" if name == "clutter=none" else (
                f"{t - t_none:+.2f} s ({100 * (t - t_none) / t:.0f} % of the run; "
                f"{1e6 * (t - t_none) / max(n - fa_none, 1):.1f} µs per added false alarm)")
            print(f"| {name} | {n:,} | {t:.2f} | {extra} | {load:.1f} |")
        return 0
    if args.quick:
        args.densities, args.revisits, args.repeats = [1.0, 10.0], 10, 3
    cfg = SensorConfig(noise_false_alarms=False)
    duration = args.revisits * 5.0 - 1.0
    impls = [("new", cl)]
    if args.baseline:
        impls.append((f"baseline {args.baseline}", load_baseline(args.baseline)))
    rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                         text=True).stdout.strip()
    print(f"# Clutter false alarms in the sensor stage (HEAD {rev}; "
          f"{args.revisits * 14} dwells of the default sensor, CPU time, median of "
          f"{args.repeats})\n")
    run_once(cfg, None, duration)                 # warm-up: imports, caches
    rows = {}
    for label, dens, build in sources(args.densities):
        base, per = [], {name: [] for name, _ in impls}
        counts = {}
        for _ in range(args.repeats):             # alternate: empty run, then each module
            base.append(run_once(cfg, None, duration)[0])
            for name, mod in impls:
                with clutter_module(mod):
                    t, n = run_once(cfg, build(mod), duration)
                per[name].append(t)
                counts[name] = n
        t0 = float(np.median(base))
        for name, _ in impls:
            rows.setdefault((label, name), []).append(
                (dens, counts[name], float(np.median(per[name])) - t0, os.getloadavg()[0]))
    print("| source | module | density (/km²/dwell) | false alarms | CPU s (less empty run) "
          "| µs CPU per false alarm | load |\n|---|---|---|---|---|---|---|")
    worst = 0.0
    for (label, name), rs in rows.items():
        for dens, n, t, load in rs:
            print(f"| {label} | {name} | {dens:g} | {n:,} | {t:.4f} | "
                  f"{1e6 * t / max(n, 1):.2f} | {load:.1f} |")
            if name == "new" and n >= 1000:
                worst = max(worst, 1e6 * t / n)
        s = slope([r[1] for r in rs], [r[2] for r in rs])
        print(f"| {label} | {name} | **log-log slope, cost vs false alarms** | | | **{s:.2f}** | |")
    if args.baseline:
        print("\n| source | density | CPU baseline / new |\n|---|---|---|")
        for label in dict.fromkeys(k[0] for k in rows):
            new = rows[(label, "new")]
            old = rows[(label, impls[1][0])]
            for (dens, _, tn, _), (_, _, to, _) in zip(new, old):
                print(f"| {label} | {dens:g} | {to / tn:.1f}× |" if tn > 0 else
                      f"| {label} | {dens:g} | (new below timing noise) |")
    print("\n## FoV-wide false alarms, platform banked (sensor stage, same dwells)\n")
    print("| bank | sectors | density (/km²/dwell) | false alarms | CPU s (less empty run) "
          "| µs CPU per false alarm | load |\n|---|---|---|---|---|---|---|")
    for bank in BANKS_DEG:
        bank_rows = banked(args.densities, args.repeats, duration, bank)
        for name, dens, n, t, load in bank_rows:
            print(f"| {bank:g}° | {name} | {dens:g} | {n:,} | {t:.4f} | "
                  f"{1e6 * t / max(n, 1):.2f} | {load:.1f} |")
            if name == "geolocated edges" and n >= 1000:
                worst = max(worst, 1e6 * t / n)
        for name in ("geolocated edges", "bank pad (before)"):
            mine = [r for r in bank_rows if r[0] == name]
            print(f"| {bank:g}° | {name} | **log-log slope** | | | "
                  f"**{slope([r[2] for r in mine], [r[3] for r in mine]):.2f}** | |")
    lib = library_polygons([d * 10 for d in args.densities], args.repeats, impls)
    print("\n## The clutter module alone, with polygon footprints (a library use; the stage "
          "passes sectors)\n\n100 dwells of a 67.5 km² annular sector each, as a 32-vertex "
          "polygon; FoV-wide density; CPU time, median.\n")
    print("| module | density (/km²/dwell) | false alarms | CPU s | µs CPU per false alarm "
          "| load |\n|---|---|---|---|---|---|")
    for name, dens, n, t, load in lib:
        print(f"| {name} | {dens:g} | {n:,} | {t:.4f} | {1e6 * t / max(n, 1):.2f} | {load:.1f} |")
    for name, _ in impls:
        mine = [r for r in lib if r[0] == name]
        print(f"| {name} | **log-log slope** | | | **{slope([r[2] for r in mine], [r[3] for r in mine]):.2f}** | |")
    print(f"\nFoV-wide draws kept (in their cell) of those drawn in the padded sectors: "
          f"{100 * kept_fraction(cfg, duration):.0f} %")
    print(f"\nworst µs CPU per false alarm (new, rows with ≥ 1,000 false alarms): {worst:.2f} "
          f"(goal ≤ 5: {'met' if worst <= 5.0 else 'NOT met'}); load {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
