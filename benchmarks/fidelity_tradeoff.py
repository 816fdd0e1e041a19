"""Speed vs accuracy of the fidelity presets, measured against ``fidelity=full``.

    python benchmarks/fidelity_tradeoff.py [--out DIR] [--seeds 1 2 3] [--repeat R]
        [--variant LABEL=PRESET:K=V,...] [-- extra overrides]

For every preset (fast, standard, full) and seed, the same scene runs in this process and is
compared with the ``full`` run of the same seed.  What is timed is the simulation: truth, sensor
with clutter and the run file; the tracker, the metrics, the report and the exports are off
(``tracker=none metrics.enabled=false report=none export=none``; each has its own benchmark),
stage cache off.  The presets alternate within each seed (fast, standard, full, fast, ...);
``--variant`` adds a row of a preset with overrides of its own (a trade study: e.g.
``fast-2s5s=fast:fidelity.time_step_s=2.0,fidelity.truth_output_dt_s=5.0``), run in turn
with the others and compared with ``full`` the same way.

* wall and CPU time of ``pipeline.run`` (mean over seeds, after one warm-up run) and the
  speed-up over ``full`` (ratio of the means).  ``--repeat R`` times every (preset, seed) R
  times, the presets alternating within each round, and takes each one's median over the
  rounds (one run of ``full`` at 1,000 vehicles moved by up to a third between runs on this
  shared machine); it also prints the speed-up of each round (full's and the preset's runs of
  the same round and seed) with its median and range;
* truth position error (RMS and max over the (time, vehicle) rows both runs hold): what coarser
  motion steps change in the vehicles' paths (their speed noise is drawn per step);
* truth position error with the vehicles' noise and random stops off (the same overrides
  plus ``NOISE_OFF``): what the motion step alone changes (discretisation);
* the same, with the preset's truth interpolated linearly at every row of full's (0.5 s) truth,
  as the metrics interpolate it: the motion step and the coarser truth output together;
* target detection count and scan-level P_D ((vehicle, revisit) pairs seen by some dwell with
  at least one detection or merge) and their difference to full;
* measurement statistics: RMS of the normalised range, azimuth and range-rate errors
  ((measured - true) / sigma, 1 for a consistent simulator) and the mean reported SNR;
* where the speed-up comes from: each stage's wall seconds per preset (the run's own "stage"
  log lines; a stage includes writing its tables to run.h5) and full / fast per stage.

Prints a table and writes ``fidelity_tradeoff.png`` (time vs truth error and |ΔP_D|) and
``fidelity_tradeoff.json`` in ``--out``.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import time
from pathlib import Path

import numpy as np

PRESETS = ("fast", "standard", "full")
SCENE = ["vehicles=random", "vehicles.random.count=200", "vehicles.random.start_time_max_s=120",
         "scene.duration_s=600", "clutter=urban"]
NOISE_OFF = ["vehicles.random.speed_noise_mps=0", "vehicles.random.position_noise_m=[0.0,0.0,0.0]",
             "vehicles.random.random_stop_rate_per_s=0"]
FIXED = ["tracker=none", "metrics.enabled=false", "report=none", "export=none",
         "cache.enabled=false", "progress=false"]


def compose(overrides):
    from gmtiflow.compose import compose as app_compose
    return app_compose(overrides)


class StageTimes(logging.Handler):
    """The wall seconds of each stage, from the run's own "stage NAME SECONDS" log lines."""

    def __init__(self):
        super().__init__(logging.INFO)
        self.seconds = {}

    def emit(self, record):
        if record.msg.startswith("stage ") and len(record.args) == 2:
            name, sec = record.args
            self.seconds[name] = self.seconds.get(name, 0.0) + sec


def one_run(preset, seed, out, extra, label=None, read=True):
    """((wall s, CPU s) of ``pipeline.run``, the run's tables (None with ``read=False``: a
    repeated round, timed only), its stage seconds)."""
    from gmtiflow import pipeline, store
    cfg = compose(SCENE + FIXED + [f"fidelity={preset}", f"seed={seed}", *extra])
    stages = StageTimes()
    logger = logging.getLogger("gmtiflow.pipeline")
    logger.addHandler(stages)
    level, logger.level = logger.level, logging.INFO
    try:
        start, cpu0 = time.perf_counter(), time.process_time()
        path = pipeline.run(cfg, out / f"{label or preset}_{seed}")
        wall = (time.perf_counter() - start, time.process_time() - cpu0)
    finally:
        logger.removeHandler(stages)
        logger.level = level
    tables = ({t: store.read_table(path, t) for t in ("truth", "detections", "looks", "dwells")}
              if read else None)
    return wall, tables, stages.seconds


def stats(tables):
    det, looks, dwells = tables["detections"], tables["looks"], tables["dwells"]
    o = looks["outcome"]
    hit = np.isin(o, [0, 6])
    seen = o != 1
    # Scan-level P_D: (vehicle, revisit) pairs seen by any dwell that gave at least one hit.
    # (Per look, dwell_resolved counts up to 3 scalloped looks per scan, instant_scan one
    # beam-centred look, so per-look P_D is not comparable across presets.)
    order = np.argsort(dwells["dwell_id"])
    rev = dwells["revisit_id"][order][np.searchsorted(dwells["dwell_id"][order],
                                                      looks["dwell_id"])]
    key = rev * 10_000_000 + looks["vehicle_id"]
    k_seen = np.unique(key[seen])
    k_hit = np.unique(key[hit])
    pd_scan = len(k_hit) / len(k_seen) if len(k_seen) else float("nan")
    target = det["truth_id"] >= 0
    wrap = lambda a: np.angle(np.exp(1j * a))  # noqa: E731
    nr = (det["range_m"] - det["true_range_m"])[target] / det["sigma_range_m"][target]
    na = wrap(det["azimuth_rad"] - det["true_azimuth_rad"])[target] / det["sigma_azimuth_rad"][
        target]
    ok = target & ~det["doppler_wrapped"]
    nrr = (det["range_rate_mps"] - det["true_range_rate_mps"])[ok] / det[
        "sigma_range_rate_mps"][ok]
    rms = lambda x: float(np.sqrt(np.mean(x[np.isfinite(x)] ** 2))) if len(x) else float("nan")  # noqa: E731,E501
    return {"n_target_det": int(target.sum()), "pd": pd_scan, "nerr_range": rms(nr), "nerr_az": rms(na), "nerr_rr": rms(nrr),
            "snr_mean_db": float(np.mean(det["snr_db"][target])) if target.any() else float("nan")}


def truth_error(a, b):
    """Position differences at the (time, vehicle) rows both truth tables hold."""
    ka = a["time_s"] * 1e7 + a["vehicle_id"]
    kb = b["time_s"] * 1e7 + b["vehicle_id"]
    common, ia, ib = np.intersect1d(ka, kb, return_indices=True)
    d = np.sqrt(sum((a[c][ia] - b[c][ib]) ** 2 for c in ("x_m", "y_m", "z_m")))
    return float(np.sqrt(np.mean(d ** 2))), float(np.max(d)), len(common)


def interpolated_truth_error(a, b):
    """Position error of truth table ``a`` interpolated linearly (as the metrics do,
    ``gmtiflow.evaluate.align.interpolate_truth``) at every (time, vehicle) row of ``b`` inside
    ``a``'s span: what a preset's coarser truth output adds between its rows."""
    from gmtiflow.evaluate.align import interpolate_truth
    at = interpolate_truth(a, b["vehicle_id"], b["time_s"])
    ok = at["valid"]
    d = np.sqrt(sum((at[c][ok] - np.asarray(b[c], float)[ok]) ** 2 for c in ("x_m", "y_m", "z_m")))
    return float(np.sqrt(np.mean(d ** 2))), float(np.max(d)), int(ok.sum())


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="outputs/benchmarks/fidelity_tradeoff")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--variant", action="append", default=[], metavar="LABEL=PRESET:K=V,...",
                    help="one more row: PRESET with these overrides, e.g. "
                         "fast-2s=fast:fidelity.time_step_s=2.0 (repeatable)")
    ap.add_argument("--repeat", type=int, default=1, metavar="R",
                    help="timed rounds per (preset, seed), presets alternating; times are the "
                         "medians over the rounds (default 1)")
    ap.add_argument("extra", nargs="*", help="more Hydra overrides for every run")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from gmtiflow import allocator
    tuned = allocator.tune()        # as the gmtiflow command runs
    print(f"load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores); "
          f"malloc tuned as by the gmtiflow command: {tuned}")
    rows_of = {p: (p, []) for p in PRESETS}        # row label -> (preset, its own overrides)
    for v in args.variant:
        label, _, spec = v.partition("=")
        preset, _, overrides = spec.partition(":")
        if not label or preset not in PRESETS:
            ap.error(f"--variant {v!r}: expected LABEL=PRESET:K=V,... with PRESET one of "
                     f"{', '.join(PRESETS)}")
        rows_of[label] = (preset, [o for o in overrides.split(",") if o])
    labels = list(rows_of)
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    one_run("fast", args.seeds[0], out / "warmup", args.extra)      # imports, caches warm
    runs = {(p, s): one_run(rows_of[p][0], s, out, args.extra + rows_of[p][1], label=p)
            for s in args.seeds for p in labels}
    timed = {key: [run[0]] for key, run in runs.items()}     # (wall, CPU) of every round
    for r in range(1, args.repeat):
        for s in args.seeds:
            for p in labels:
                where = out / "repeats" / f"round{r}"
                wall = one_run(rows_of[p][0], s, where, args.extra + rows_of[p][1], label=p,
                               read=False)[0]
                timed[(p, s)].append(wall)
                shutil.rmtree(where / f"{p}_{s}")           # after the timed run
    quiet = {(p, s): one_run(rows_of[p][0], s, out / "noise_off",
                             args.extra + NOISE_OFF + rows_of[p][1], label=p)[1]
             for s in args.seeds for p in labels}
    rows = []
    for p in labels:
        walls, cpus, terr, tmax, st, dpd, ddet, qerr, qmax = [], [], [], [], [], [], [], [], []
        ierr, imax = [], []
        for s in args.seeds:
            tab = runs[(p, s)][1]
            ref = runs[("full", s)][1]
            walls.append(float(np.median([w for w, _ in timed[(p, s)]])))
            cpus.append(float(np.median([c for _, c in timed[(p, s)]])))
            e_rms, e_max, _ = truth_error(tab["truth"], ref["truth"])
            terr.append(e_rms)
            tmax.append(e_max)
            q_rms, q_max, _ = truth_error(quiet[(p, s)]["truth"], quiet[("full", s)]["truth"])
            qerr.append(q_rms)
            qmax.append(q_max)
            i_rms, i_max, _ = interpolated_truth_error(quiet[(p, s)]["truth"],
                                                       quiet[("full", s)]["truth"])
            ierr.append(i_rms)
            imax.append(i_max)
            a, r = stats(tab), stats(ref)
            st.append(a)
            dpd.append(a["pd"] - r["pd"])
            ddet.append((a["n_target_det"] - r["n_target_det"]) / max(r["n_target_det"], 1))
        mean = lambda k: float(np.mean([x[k] for x in st]))  # noqa: E731
        rows.append({"preset": p, "wall_s": float(np.mean(walls)), "cpu_s": float(np.mean(cpus)),
                     "truth_rms_m": float(np.mean(terr)), "truth_max_m": float(np.max(tmax)),
                     "quiet_rms_m": float(np.mean(qerr)), "quiet_max_m": float(np.max(qmax)),
                     "interp_rms_m": float(np.mean(ierr)), "interp_max_m": float(np.max(imax)),
                     "n_target_det": mean("n_target_det"), "det_diff_pct": 100 * np.mean(ddet),
                     "pd": mean("pd"), "pd_diff": float(np.mean(dpd)),
                     "nerr_range": mean("nerr_range"), "nerr_az": mean("nerr_az"),
                     "nerr_rr": mean("nerr_rr"), "snr_mean_db": mean("snr_mean_db")})
    full_wall, full_cpu = rows[labels.index("full")]["wall_s"], rows[labels.index("full")]["cpu_s"]
    print(f"scene: {' '.join(SCENE + FIXED + args.extra)}; seeds {args.seeds}"
          + (f"; times: medians of {args.repeat} alternated rounds" if args.repeat > 1 else ""))
    head = ("| preset | wall s | CPU s | × full (wall / CPU) | truth err RMS / max (m) | same, noise off | "
            "noise off, interpolated at full's rows | "
            "target dets | Δdets vs full | scan P_D | ΔP_D | norm. err r / az / ṙ | "
            "mean SNR dB |")
    print(head)
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['preset']} | {r['wall_s']:.2f} | {r['cpu_s']:.2f} | "
              f"{full_wall / r['wall_s']:.1f} / {full_cpu / r['cpu_s']:.1f} | "
              f"{r['truth_rms_m']:.1f} / {r['truth_max_m']:.1f} | "
              f"{r['quiet_rms_m']:.2f} / {r['quiet_max_m']:.2f} | "
              f"{r['interp_rms_m']:.2f} / {r['interp_max_m']:.2f} | {r['n_target_det']:.0f} | "
              f"{r['det_diff_pct']:+.1f} % | {r['pd']:.3f} | {r['pd_diff']:+.3f} | "
              f"{r['nerr_range']:.2f} / {r['nerr_az']:.2f} / {r['nerr_rr']:.2f} | "
              f"{r['snr_mean_db']:.1f} |")
    if args.repeat > 1:
        print("\n× full per round (full's run / the preset's, same round and seed), wall and CPU:")
        for p in labels:
            per = [(timed[("full", s)][r][i] / timed[(p, s)][r][i]) for i in (0, 1)
                   for s in args.seeds for r in range(args.repeat)]
            n = len(args.seeds) * args.repeat
            w, c = per[:n], per[n:]
            print(f"  {p}: wall median {np.median(w):.1f} ({min(w):.1f}-{max(w):.1f}), "
                  f"CPU median {np.median(c):.1f} ({min(c):.1f}-{max(c):.1f}) over {n} rounds")
    # Where the ratio comes from: each stage's wall seconds (the run's log), mean over seeds.
    names = list(dict.fromkeys(n for (p, s), r in runs.items() for n in r[2]))
    stage_s = {p: {n: float(np.mean([runs[(p, s)][2].get(n, 0.0) for s in args.seeds]))
                   for n in names} for p in labels}
    print("\nstage wall seconds (the run's own stage timings of the first round, mean over "
          "seeds; a stage includes writing its tables):")
    print("| stage | " + " | ".join(labels) + " | full / fast |")
    print("|---|" + "---|" * (len(labels) + 1))
    for n in names + ["all stages"]:
        v = ({p: sum(stage_s[p].values()) for p in labels} if n == "all stages"
             else {p: stage_s[p][n] for p in labels})
        ratio = f"{v['full'] / v['fast']:.1f}" if v["fast"] >= 0.0005 else "-"
        print(f"| {n} | " + " | ".join(f"{v[p]:.3f}" for p in labels) + f" | {ratio} |")
    for r in rows:
        r["stage_s"] = stage_s[r["preset"]]
    print(f"load after: {os.getloadavg()[0]:.2f}")
    (out / "fidelity_tradeoff.json").write_text(json.dumps(rows, indent=1))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.6))
    for r in rows:
        ax[0].plot(r["wall_s"], r["quiet_rms_m"], "o")
        ax[0].annotate(r["preset"], (r["wall_s"], r["quiet_rms_m"]), textcoords="offset points",
                       xytext=(5, 5))
        ax[1].plot(r["wall_s"], abs(r["pd_diff"]), "o")
        ax[1].annotate(r["preset"], (r["wall_s"], abs(r["pd_diff"])),
                       textcoords="offset points", xytext=(5, 5))
    ax[0].set(xlabel="wall time per run (s)", ylabel="truth position error vs full, RMS (m)",
              title="motion step (noise off)")
    ax[1].set(xlabel="wall time per run (s)", ylabel="|scan P_D - full|", title="detection")
    for a in ax:
        a.grid(alpha=0.3)
    fig.suptitle("gmtiflow fidelity presets: speed vs accuracy")
    fig.tight_layout()
    fig.savefig(out / "fidelity_tradeoff.png", dpi=120)
    print(f"wrote {out / 'fidelity_tradeoff.png'}")


if __name__ == "__main__":
    main()
