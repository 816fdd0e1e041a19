"""Page 4: range rate vs azimuth (clutter notch, blind speeds, wrapping)."""
from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from gmtiflow.frames import wrap_pi
from gmtiflow.sensor.outcome import Outcome
from gmtiflow.tables import Table

from ..common import DET_STYLE, OUTCOME_STYLE, _col, _note, _scatter, detection_classes, new_figure
from ..data import DRAWN, n


def _dwell_lookup(dwells: Table, dwell_id: np.ndarray, col: str) -> np.ndarray:
    pos = np.searchsorted(_col(dwells, "dwell_id"), dwell_id)
    pos = np.clip(pos, 0, n(dwells) - 1)
    return _col(dwells, col)[pos]


def clutter_range_rate(dwells: Table, dwell_id, azimuth_rad, range_m) -> np.ndarray:
    """ṙ_MLC = −v_p·ℓ of the ground at (azimuth, slant range) seen from the dwell's platform
    (flat ground at the origin's height: depression sin δ = platform height / slant range)."""
    vx, vy, vz = (_dwell_lookup(dwells, dwell_id, f"platform_v{c}_mps") for c in "xyz")
    h = _dwell_lookup(dwells, dwell_id, "platform_z_m")
    sin_d = np.clip(h / np.maximum(range_m, 1.0), -1, 1)
    cos_d = np.sqrt(1 - sin_d ** 2)
    lx, ly, lz = np.sin(azimuth_rad) * cos_d, np.cos(azimuth_rad) * cos_d, -sin_d
    return -(vx * lx + vy * ly + vz * lz)


def _finite_median(values, default: float) -> float:
    """Median of the finite values, or ``default`` when there are none (no NaN warning)."""
    if values is None:
        return default
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if v.size else default


def range_rate_figure(looks: Table, detections: Table, dwells: Table, *,
                      max_points: int = 20000) -> Figure:
    """Range rate vs azimuth off the platform track, with the clutter notch and blind speeds.

    Left: every look on a visible target (true range rate), by outcome; the notch is
    ṙ_MLC ± MDV with ṙ_MLC = −|v_p| cos(Δaz) cos δ for the median speed and depression, and the
    blind speeds are the notch shifted by ± λ·PRF/2.  Right: the reports (measured range rate);
    where the radar is Doppler-ambiguous the processor wraps the range rate relative to the
    clutter, so the reports lie between the wrap limits ṙ_MLC ± λ·PRF/4 drawn around the notch.

    Several sensors (``sensor_id`` in the dwells): one row of the two panels per sensor, each
    with its own looks and reports (by their dwell) and its own platform speed, MDV and wrap
    limits — each sensor's processor wraps around its own clutter notch.
    """
    fig = new_figure()
    sensor_ids = (np.unique(_col(dwells, "sensor_id")) if n(dwells) and "sensor_id" in dwells
                  else np.zeros(0, np.int64))
    if len(sensor_ids) < 2:
        axl, axr = fig.subplots(1, 2, sharex=True, gridspec_kw=dict(
            left=0.07, right=0.98, top=0.86, bottom=0.1, wspace=0.15))
        if not n(dwells):
            _note(axl, "no dwells")
            return fig
        v_p, mdv, blind = _sensor_panels(axl, axr, looks, detections, dwells, max_points)
        axl.set_title("Looks: true range rate by outcome", fontsize=10)
        axr.set_title("Reports: measured range rate", fontsize=10)
        fig.suptitle(f"Range rate vs azimuth — platform {v_p:.0f} m/s, MDV {mdv:g} m/s"
                     + (f", blind speed {blind:.1f} m/s" if math.isfinite(blind)
                        else ", no PRF set"), fontsize=14, weight="bold", x=0.05, ha="left")
        return fig
    axes = fig.subplots(len(sensor_ids), 2, squeeze=False, gridspec_kw=dict(
        left=0.07, right=0.98, top=0.88, bottom=0.07, wspace=0.15, hspace=0.45))
    sensor_of_dwell = _col(dwells, "sensor_id")
    for (axl, axr), sid in zip(axes, sensor_ids):
        keep = sensor_of_dwell == sid
        own = {k: np.asarray(v)[keep] for k, v in dwells.items()}
        v_p, mdv, blind = _sensor_panels(axl, axr, _rows_of(looks, own), _rows_of(detections, own),
                                         own, max_points)
        axl.set_title(f"sensor {int(sid)} looks: true range rate — platform {v_p:.0f} m/s",
                      fontsize=9)
        axr.set_title(f"sensor {int(sid)} reports — MDV {mdv:g} m/s, "
                      + (f"blind speed {blind:.1f} m/s" if math.isfinite(blind) else "no PRF"),
                      fontsize=9)
    fig.suptitle("Range rate vs azimuth, per sensor (each its own notch and wrap limits)",
                 fontsize=14, weight="bold", x=0.05, ha="left")
    return fig


def _rows_of(table: Table, dwells: Table) -> Table:
    """The rows of ``table`` whose ``dwell_id`` is one of ``dwells``' (one sensor's)."""
    if not n(table):
        return table
    keep = np.isin(_col(table, "dwell_id"), _col(dwells, "dwell_id"))
    return {k: np.asarray(v)[keep] for k, v in table.items()}


def _sensor_panels(axl, axr, looks: Table, detections: Table, dwells: Table, max_points: int):
    """Draw one sensor's looks (``axl``) and reports (``axr``) with its notch, blind speeds
    and wrap limits; returns its (median platform speed, MDV, blind speed) for the titles."""
    if not n(dwells):
        _note(axl, "no dwells")
        return float("nan"), 0.0, float("nan")
    speed = np.hypot(_col(dwells, "platform_vx_mps"), _col(dwells, "platform_vy_mps"))
    v_p = float(np.median(speed))
    mdv = _finite_median(dwells.get("mdv_mps"), 0.0)
    wrap = _finite_median(dwells.get("wrap_velocity_mps"), float("nan"))   # NaN: no PRF
    # depression of a typical look: platform height over the looks' median slant range
    slant = _finite_median(looks.get("range_m") if n(looks) else None, float("nan"))
    height = _finite_median(dwells.get("platform_z_m"), 0.0)
    cos_d = math.sqrt(max(0.0, 1.0 - (height / slant) ** 2)) if slant > 0 else 1.0

    def rel_az(table, az_col="azimuth_rad"):
        hd = _dwell_lookup(dwells, _col(table, "dwell_id"), "platform_heading_rad")
        return np.degrees(wrap_pi(_col(table, az_col) - hd))

    xs, ys = [], []
    drawn = np.zeros(0, bool)
    if n(looks):
        outcome = _col(looks, "outcome")
        drawn = np.isin(outcome, DRAWN)
        rel = rel_az(looks)
        if n(looks) and "range_m" in looks:
            r = _col(looks, "range_m")
            cos_d = float(np.nanmedian(np.sqrt(np.clip(1 - (_dwell_lookup(
                dwells, _col(looks, "dwell_id"), "platform_z_m") / np.maximum(r, 1)) ** 2, 0, 1)))) \
                if drawn.any() else cos_d
        for code in (Outcome.DETECTED, Outcome.MERGED, Outcome.PD_MISS, Outcome.DOPPLER_BLIND):
            m = outcome == code
            if m.any():
                colour, label, _ = OUTCOME_STYLE[code]
                blind_code = code == Outcome.DOPPLER_BLIND
                _scatter(axl, rel[m], _col(looks, "range_rate_mps")[m], max_points=max_points,
                         s=22 if blind_code else 9, marker="^" if blind_code else "o",
                         color=colour, label=f"{label} ({int(m.sum())})", alpha=0.9, lw=0,
                         zorder=4 if blind_code else 3)
                xs.append(rel[m])
                ys.append(_col(looks, "range_rate_mps")[m])
    if n(detections):
        rel_d = rel_az(detections)
        xs.append(rel_d)
        for key, mask in detection_classes(detections).items():
            if mask.any():
                colour, marker, label = DET_STYLE[key]
                _scatter(axr, rel_d[mask], _col(detections, "range_rate_mps")[mask],
                         max_points=max_points, s=14 if marker == "x" else 10, marker=marker,
                         color=colour, lw=0.8 if marker == "x" else 0, alpha=0.8,
                         label=f"{label} ({int(mask.sum())})")
    allx = np.concatenate(xs) if xs else np.array([60.0, 120.0])
    allx = allx[np.isfinite(allx)]
    lo, hi = (allx.min(), allx.max()) if len(allx) else (60.0, 120.0)
    pad = max(2.0, 0.05 * (hi - lo))
    grid = np.linspace(lo - pad, hi + pad, 300)
    notch = -v_p * np.cos(np.radians(grid)) * cos_d
    blind = 2 * wrap if math.isfinite(wrap) else float("nan")
    for a, wrapped in ((axl, False), (axr, True)):
        shifts = [0.0] if (wrapped or not math.isfinite(blind)) else [0.0, -blind, blind]
        for k, s in enumerate(shifts):
            c = notch + s
            label = ("clutter notch $\\dot r_{MLC}$ ± MDV" if k == 0
                     else "blind speeds $\\dot r_{MLC}$ ± λ·PRF/2" if k == 1 else None)
            a.plot(grid, c, color="k" if k == 0 else "0.3", lw=1.0, ls="-" if k == 0 else "--",
                   label=label)
            if mdv > 0:
                a.fill_between(grid, c - mdv, c + mdv, color="0.6" if k == 0 else "0.8", alpha=0.35,
                               lw=0)
        if wrapped and math.isfinite(wrap):
            # The processor wraps the range rate relative to the ground clutter at the report's
            # position (sensor/effects.py Ambiguities): reports lie in [ṙ_MLC − v_w, ṙ_MLC + v_w).
            for w in (-wrap, wrap):
                a.plot(grid, notch + w, color="#b2182b", lw=0.9, ls=":")
            a.plot([], [], color="#b2182b", lw=0.9, ls=":",
                   label=f"wrap limits $\\dot r_{{MLC}}$ ± λ·PRF/4 (± {wrap:.1f} m/s)")
        a.set_xlabel("azimuth relative to platform heading (deg, + = right)")
        a.grid(alpha=0.3)
        a.legend(fontsize=7, loc="upper right")
    if not drawn.any():
        _note(axl, "no looks on visible targets")
    if not n(detections):
        _note(axr, "no detections")
    yv = np.concatenate(ys + [notch]) if ys else notch
    yv = yv[np.isfinite(yv)]
    axl.set_ylim(yv.min() - max(10.0, 3 * mdv), yv.max() + max(10.0, 3 * mdv))
    axl.set_ylabel("range rate (m/s, + = receding)")
    return v_p, mdv, blind
