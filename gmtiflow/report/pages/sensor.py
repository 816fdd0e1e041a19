"""Page 3: physics sanity (P_D vs SNR, normalised measurement errors)."""
from __future__ import annotations

import math
from typing import Dict, Optional

import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from gmtiflow.frames import wrap_pi
from gmtiflow.tables import Table

from ..common import SNR_FLOOR_DB, _col, _note, new_figure, rectangles
from ..data import DETECTED, DRAWN, n


# ----------------------------------------------------------------------------- page 3: sensor

def swerling1_pd(pfa: float, snr_linear) -> np.ndarray:
    """P_D = P_FA^{1/(1+SNR)} (DESIGN eq. 11), in log space."""
    return np.exp(math.log(pfa) / (1.0 + np.asarray(snr_linear, float)))


def pd_vs_snr(looks: Table, bin_db: float):
    """Binned empirical P_D of the looks where the draw happened: (centres, pd, count, model)."""
    if not n(looks):
        return (np.zeros(0),) * 4
    outcome = _col(looks, "outcome")
    snr = _col(looks, "snr_db").astype(float)
    keep = np.isin(outcome, DRAWN) & np.isfinite(snr)
    if not keep.any():
        return (np.zeros(0),) * 4
    snr, det, pd = snr[keep], np.isin(outcome[keep], DETECTED), _col(looks, "pd")[keep]
    edges = np.arange(math.floor(snr.min() / bin_db) * bin_db, snr.max() + bin_db, bin_db)
    if len(edges) < 2:
        edges = np.array([snr.min() - bin_db / 2, snr.min() + bin_db / 2])
    which = np.clip(np.digitize(snr, edges) - 1, 0, len(edges) - 2)
    count = np.bincount(which, minlength=len(edges) - 1)
    hits = np.bincount(which, weights=det, minlength=len(edges) - 1)
    model = np.bincount(which, weights=pd, minlength=len(edges) - 1)
    ok = count > 0
    centres = 0.5 * (edges[:-1] + edges[1:])
    return centres[ok], hits[ok] / count[ok], count[ok], model[ok] / count[ok]


def normalised_errors(det: Table) -> Dict[str, np.ndarray]:
    """(measured − true)/σ of unmerged true detections without range folding/Doppler wrapping."""
    if not n(det):
        return {"range": np.zeros(0), "azimuth": np.zeros(0), "range rate": np.zeros(0)}
    ok = (np.asarray(det["truth_id"]) >= 0) & ~np.asarray(det["merged"], bool)
    for flag in ("range_folded", "doppler_wrapped"):
        if flag in det:
            ok &= ~np.asarray(det[flag], bool)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = {
            "range": (_col(det, "range_m") - _col(det, "true_range_m")) / _col(det, "sigma_range_m"),
            "azimuth": wrap_pi(_col(det, "azimuth_rad") - _col(det, "true_azimuth_rad"))
            / _col(det, "sigma_azimuth_rad"),
            "range rate": (_col(det, "range_rate_mps") - _col(det, "true_range_rate_mps"))
            / _col(det, "sigma_range_rate_mps"),
        }
    return {k: v[ok & np.isfinite(v)] for k, v in out.items()}


def sensor_figure(looks: Table, detections: Table, pfa: float, *, snr_bin_db: float = 1.0,
                  expected_false_alarms: Optional[float] = None) -> Figure:
    """Empirical P_D vs model SNR against Swerling I; normalised measurement errors vs N(0, 1);
    with ``expected_false_alarms`` (the detector's P_FA × cells × dwells) the run's false-alarm
    count against it."""
    fig = new_figure()
    if expected_false_alarms is not None:
        n_fa = int(np.sum(_col(detections, "truth_id") < 0)) if n(detections) else 0
        e = float(expected_false_alarms)
        fig.text(0.05, 0.925, f"False alarms: {n_fa} in the run; the detector's expectation "
                 f"P_FA × range × Doppler cells × dwells = {e:.4g} ± {math.sqrt(max(e, 0.0)):.2g}"
                 "\n(Poisson; fewer where the horizon or terrain masks cells, more with clutter "
                 "regions)", fontsize=8, color="0.2", va="center")
    gs = fig.add_gridspec(2, 3, height_ratios=[1.25, 1], left=0.07, right=0.93, top=0.88,
                          bottom=0.08, hspace=0.42, wspace=0.28)
    ax = fig.add_subplot(gs[0, :])
    centres, pd_emp, count, model = pd_vs_snr(looks, snr_bin_db)
    low = centres < SNR_FLOOR_DB
    n_low = int(count[low].sum())
    low_hits = float(np.sum(pd_emp[low] * count[low]))
    centres, pd_emp, count, model = centres[~low], pd_emp[~low], count[~low], model[~low]
    if n_low:
        ax.text(0.01, 0.97, f"{n_low} looks below {SNR_FLOOR_DB:g} dB not shown (deep in the "
                f"clutter notch or beam edge; {low_hits:.0f} detected)", transform=ax.transAxes,
                va="top", fontsize=8, color="0.3")
    if len(centres):
        grid = np.linspace(min(centres.min(), 0) - 2, max(centres.max(), 20) + 2, 400)
        ax.plot(grid, swerling1_pd(pfa, 10 ** (grid / 10)), "k-", lw=1.5,
                label=f"Swerling I: $P_D = P_{{FA}}^{{1/(1+SNR)}}$, $P_{{FA}}$ = {pfa:g}")
        ax.plot(centres, model, "s", mfc="none", color="0.4", ms=5, label="mean model $P_D$ of the bin")
        err = np.sqrt(np.clip(pd_emp * (1 - pd_emp), 0.25 / count, None) / count)
        ax.errorbar(centres, pd_emp, yerr=err, fmt="o", color="#d73027", ms=5, capsize=2,
                    label=f"empirical: detected / looks ({int(count.sum())} looks, ±1σ binomial)")
        ax2 = ax.twinx()
        half = 0.45 * snr_bin_db
        ax2.add_collection(PolyCollection(rectangles(centres - half, centres + half, 0, count),
                                          facecolor="0.85", lw=0, zorder=0))
        ax2.set_ylim(0, 1.05 * float(count.max()))
        ax2.set_ylabel("looks per bin", color="0.5")
        ax2.tick_params(axis="y", colors="0.5")
        ax.set_zorder(ax2.get_zorder() + 1)
        ax.patch.set_visible(False)
        ax.legend(loc="center left", fontsize=8)
        ax.set_ylim(-0.03, 1.03)
    else:
        _note(ax, "no looks above the SNR floor: nothing to compare" if n_low
              else "no looks on visible targets: nothing to compare")
    ax.set_xlabel(f"model SNR of the look (dB, bins of {snr_bin_db:g} dB; incl. beam and STAP losses)")
    ax.set_ylabel("$P_D$")
    ax.set_title("Detection probability vs SNR (looks with a detection draw: detected, "
                 "merged, notch, $P_D$ miss)", fontsize=10)
    ax.grid(alpha=0.3)

    errs = normalised_errors(detections)
    x = np.linspace(-4.5, 4.5, 200)
    for i, (name, v) in enumerate(errs.items()):
        a = fig.add_subplot(gs[1, i])
        if len(v):
            a.hist(np.clip(v, -5, 5), bins=np.linspace(-5, 5, 41), density=True, color="#4393c3",
                   alpha=0.8, histtype="stepfilled",    # one polygon, not a patch per bin
                   label=f"n={len(v)}\nmean {v.mean():+.2f}\nstd {v.std():.2f}")
            a.plot(x, np.exp(-x * x / 2) / math.sqrt(2 * math.pi), "k-", lw=1.3, label="N(0, 1)")
            a.legend(fontsize=7, loc="upper right")
        else:
            _note(a, "no unmerged true detections")
        a.set_xlabel(f"({name} measured − true) / σ")
        a.set_ylabel("density")
        a.set_title(f"{name.capitalize()} error / σ", fontsize=10)
        a.grid(alpha=0.3)
    fig.suptitle("Physics sanity: detection and measurement errors", fontsize=14, weight="bold",
                 x=0.05, ha="left")
    return fig
