r"""Thermal-noise false alarms of the detector (paper §5.4; issue 12 §1).

A GMTI detector compares every range-Doppler cell of a dwell with the threshold
T = −ln P_FA (:mod:`gmtiflow.sensor.detect`); noise alone crosses it in a fraction P_FA of them.
Per dwell the number of noise false alarms is therefore Poisson with mean

.. math::  \bar n = P_{FA}\, N_r\, N_D\, N_a

(:attr:`SensorConfig.expected_false_alarms_per_dwell`, :attr:`SensorConfig.noise_cells`):

* N_r = (min(R_max, c·PRI/2) − R_min) / Δr, the slant-range window over the range cell
  Δr = k c/(2B) (only the unambiguous part of the window is a set of distinct range gates);
* N_D = PRF / Δf_D = PRF·CPI/k_D, the Doppler filters of the CPI (without a PRI:
  G_I/k_D, one filter per integrated pulse);
* N_a = 1, the dwell's beam: monopulse refines a detection's angle within its beam, it does
  not test separate angle cells.

With the default sensor: N_r = 16 000 m / 3.0 m = 5 333, N_D = 128, so n̄ = 0.683 per dwell at
P_FA = 1e-6 (9.6 per 14-dwell scan), ×100 per factor 100 of P_FA.

Each false alarm is placed uniformly in the dwell's resolution cells: slant range uniform in the
window, the antenna-frame scan angle uniform in *sine* space over the dwell's beam cell
(:meth:`ChunkContext.dwell_cell_rad`, the cells tile the sector, as the beams do), and its own
range rate (relative to the ground clutter, the frame the Doppler filters are centred on by the
STAP/clutter-locking processor) uniform over the searched band [−λ·band/4, +λ·band/4), i.e.
±λ·PRF/4, the unambiguous interval; the reported range rate is that plus the clutter's
ṙ_MLC = −v_p·ℓ at the point.  The ground point is where that (range, angle) meets the terrain
(:mod:`gmtiflow.sensor.geolocate`), exactly as a detection is geolocated, so its reported
position is the cell's position (no further error: a uniform point plus an error is uniform).

Masks, like a target's: a cell whose range does not reach the ground, outside the elevation
limits, beyond the radar horizon or in terrain shadow yields nothing (thinning a Poisson process
keeps it Poisson; the expectation then is n̄ times the visible fraction of the cells, exactly n̄
for the default scene over flat ground).

The reported SNR follows the targets' convention (z − 1 with z the detector output, here
z = T + Exp(1), :func:`gmtiflow.sensor.detect.false_alarm_snr`), σ's follow from it like a
target's (:func:`gmtiflow.sensor.measurement.sigmas`), ``truth_id`` = −1.

Randomness: counter-based draws keyed ``counter_key(seed, "sensor", "noise_false_alarms")`` on
(dwell_id, index, channel).  Targets use other keys, so their detections are bit-identical with
or without noise false alarms, and at any other false-alarm setting (common random numbers).
Vectorised over every false alarm of a chunk: no per-dwell Python work.
"""
from __future__ import annotations

import numpy as np

from gmtiflow import frames, rng
from gmtiflow.sensor import antenna, detect, fastnp, geolocate, measurement, scan, visibility
from gmtiflow.sensor.config import C_MPS, SensorConfig
from gmtiflow.tables import Table

STREAM = "noise_false_alarms"
_CH_COUNT, _CH_RANGE, _CH_ANGLE, _CH_RR, _CH_SNR = range(5)


def _world_azimuth(dx, dy):
    return fastnp.mod(np.arctan2(dx, dy), 2.0 * np.pi)


def poisson_ppf(q, mean) -> np.ndarray:
    """The Poisson quantile: the least k with P(N ≤ k) ≥ q, for 0 < q < 1 and mean > 0.

    ``scipy.stats.poisson.ppf`` computed as it does (the same values, bit for bit), from
    ``scipy.special`` alone: scipy.stats costs ~1 s to import, scipy.special a tenth of it.
    k = ⌈pdtrik(q, μ)⌉ (the continuous inverse), one lower when the CDF there already reaches q.

    For a few distinct means (the noise false alarms': one) the least k comes from a table of
    ``pdtr(k, μ)`` by bisection instead, ~10× cheaper than pdtrik per value: the same k, as
    pdtrik's root is within ~1e-10 (relative) of the true one, so its ceiling can only differ
    when q lies within that of the CDF at k − 1; those q (within 1e-6) and q at the table's end
    go through pdtrik.  For many distinct means (per-dwell clutter) each value steps up its own
    CDF (``pdtr(0, μ)``, ``pdtr(1, μ)``, ... the table's entries) under the same conditions.
    tests/sensor/test_noise.py compares them with pdtrik and scipy.stats.
    """
    q, mean = np.broadcast_arrays(np.asarray(q, float), np.asarray(mean, float))
    out = np.empty(q.shape)
    slow = np.ones(q.shape, bool)
    flat = mean.ravel()
    if flat.size and (flat == flat[0]).all():     # one mean (the noise false alarms'): no sort
        means, inv = flat[:1].copy(), np.zeros(flat.size, np.intp)
    else:
        means, inv = np.unique(mean, return_inverse=True)
    if len(means) <= _PPF_TABLE_MEANS:
        from scipy import special
        inv = inv.reshape(q.shape)
        for j, m in enumerate(means.tolist()):
            if not (0.0 < m <= _PPF_TABLE_MAX_MEAN):
                continue
            sel = np.flatnonzero(inv.ravel() == j)
            qs = q.ravel()[sel]
            size = int(m + 12.0 * np.sqrt(m) + 30.0)
            cdf = special.pdtr(np.arange(size, dtype=float), m)
            k = np.searchsorted(cdf, qs, side="left")        # least k with cdf[k] >= q
            below = np.concatenate([[0.0], cdf])[k]          # cdf[k - 1] (0 for k = 0)
            ok = (k < size - 1) & (qs - below >= _PPF_MARGIN) & (qs > 0.0) & (qs < 1.0)
            out.ravel()[sel[ok]] = k[ok]
            slow.ravel()[sel[ok]] = False
    else:       # many means (per-dwell clutter): the same search, each value up its own CDF
        sel = np.flatnonzero(slow.ravel())
        k, ok = _least_k(q.ravel()[sel], mean.ravel()[sel])
        out.ravel()[sel[ok]] = k[ok]
        slow.ravel()[sel[ok]] = False
    if slow.any():
        out[slow] = _poisson_ppf_pdtrik(q[slow], mean[slow])
    return out


def _least_k(q, mean, max_steps: int = 200):
    """The table search of :func:`poisson_ppf` for one mean per value: the least k with
    ``pdtr(k, μ) >= q``, stepping k = 0, 1, 2, ... over the values not yet answered (most k are
    small), and whether it stands (``ok``: the same conditions as the table's — k below the
    table's last entry, q at least the margin above the CDF at k − 1, 0 < q < 1; the others
    go through pdtrik).  Each ``pdtr(k, μ)`` is the table's own entry, value by value."""
    from scipy import special
    n = q.size
    k = np.zeros(n, np.int64)
    ok = np.zeros(n, bool)
    valid = (mean > 0.0) & (mean <= _PPF_TABLE_MAX_MEAN) & (q > 0.0) & (q < 1.0)
    size = np.zeros(n, np.int64)
    size[valid] = (mean[valid] + 12.0 * np.sqrt(mean[valid]) + 30.0).astype(np.int64)
    rest = np.flatnonzero(valid)
    below = np.zeros(rest.size)                       # the CDF at k − 1 (0 for k = 0)
    for step in range(max_steps):
        if rest.size == 0:
            break
        inside = step < size[rest]
        rest, below = rest[inside], below[inside]     # past the table's end: pdtrik
        cdf = special.pdtr(float(step), mean[rest])
        hit = cdf >= q[rest]
        at = rest[hit]
        k[at] = step
        ok[at] = (step < size[at] - 1) & (q[at] - below[hit] >= _PPF_MARGIN)
        rest, below = rest[~hit], cdf[~hit]
    return k, ok


_PPF_TABLE_MEANS = 64
_PPF_TABLE_MAX_MEAN = 1e4
_PPF_MARGIN = 1e-6


def _poisson_ppf_pdtrik(q, mean) -> np.ndarray:
    from scipy import special
    vals = np.ceil(special.pdtrik(q, mean))
    vals1 = np.maximum(vals - 1, 0)
    return np.where(special.pdtr(vals1, mean) >= q, vals1, vals)


def poisson_counts(key, dwell_id: np.ndarray, mean) -> np.ndarray:
    """One Poisson count per dwell by inversion of a counter-based uniform (exactly Poisson)."""
    u = rng.pair_uniform(key, dwell_id, 0, _CH_COUNT)
    mean = np.broadcast_to(np.asarray(mean, float), u.shape)
    counts = np.zeros(len(dwell_id), dtype=np.int64)
    pos = mean > 0
    if np.any(pos):
        counts[pos] = poisson_ppf(u[pos], mean[pos]).astype(np.int64)
    return counts


def expand(counts: np.ndarray):
    """Per point: the position of its dwell in the batch and its index within the dwell."""
    batch = np.repeat(np.arange(len(counts)), counts)
    starts = np.cumsum(counts) - counts
    index = np.arange(int(counts.sum())) - np.repeat(starts, counts)
    return batch, index


def false_alarm_rows(ctx, cfg: SensorConfig, dwell_id, x, y, z, own_rr, snr_lin,
                     first_det_id: int) -> Table:
    """/detections rows of false alarms at ground points (x, y, z) of their dwells.

    ``own_rr`` is the radial speed relative to the ground (the reported range rate adds the
    clutter's ṙ_MLC); ``snr_lin`` the reported (linear) SNR; σ's follow from it.
    """
    d = ctx.dwells
    m = len(dwell_id)
    k = np.asarray(dwell_id, np.int64) - int(d["dwell_id"][0])
    rng_m, ground_rr = ctx.range_and_ground_rate(dwell_id, x, y, z)
    az = _world_azimuth(x - d["platform_x_m"][k], y - d["platform_y_m"][k])
    rr = ground_rr + own_rr
    bw = ctx.per_beam(lambda beam: scan.broadened_beamwidth_rad(cfg, beam), dwell_id)
    s_r, s_az, s_rr = measurement.sigmas(cfg, snr_lin, bw)
    s_az = ctx.world_azimuth_sigma(dwell_id, x, y, z, s_az)     # of the reported world azimuth
    lat, lon, h = frames.enu_to_geodetic(ctx.origin, x, y, z)
    false = np.zeros(m, bool)
    return {
        "det_id": first_det_id + np.arange(m, dtype=np.int64), "dwell_id": dwell_id,
        "time_s": d["time_s"][k], "range_m": rng_m, "azimuth_rad": az,
        "range_rate_mps": rr, "true_range_m": rng_m, "true_azimuth_rad": az,
        "true_range_rate_mps": rr, "snr_db": 10.0 * np.log10(snr_lin), "sigma_range_m": s_r,
        "sigma_azimuth_rad": s_az, "sigma_range_rate_mps": s_rr, "x_m": x, "y_m": y,
        "z_m": z, "lat_deg": np.atleast_1d(lat), "lon_deg": np.atleast_1d(lon),
        "height_m": np.atleast_1d(h), "truth_id": np.full(m, -1, np.int64),
        "merged": false, "range_folded": false.copy(), "doppler_wrapped": false.copy(),
        "implausible": false.copy(), "rcs_dbsm": np.full(m, np.nan),
        "wrap_velocity_mps": np.full(m, cfg.wrap_velocity_mps),
    }


def append_rows(detections: Table, rows: Table) -> Table:
    """``detections`` with ``rows`` appended (dtypes of ``detections``)."""
    return {name: np.concatenate([np.asarray(detections[name]),
                                  np.asarray(rows[name]).astype(np.asarray(detections[name]).dtype,
                                                                copy=False)])
            for name in detections}


def draw(ctx, cfg: SensorConfig, seed: int) -> Table:
    """The noise false alarms of the chunk's dwells, as /detections rows (chunk-local ids from
    0; the caller offsets them)."""
    d = ctx.dwells
    dwell_id = np.asarray(d["dwell_id"], np.int64)
    key = rng.counter_key(seed, "sensor", STREAM)
    counts = poisson_counts(key, dwell_id, cfg.expected_false_alarms_per_dwell)
    batch, index = expand(counts)
    did = dwell_id[batch]
    # (dwell_id, index) mixed once for the four channels: rng.pair_uniform(key, did, index,
    # channel), bit for bit (rng.Counters)
    mixed = [rng.mix_counter(did), rng.mix_counter(index)]

    def uniform(channel):
        return rng.Counters(mixed=mixed + [rng.mix_counter(channel)]).uniform(key)

    r0 = cfg.range_min_m
    r1 = cfg.range_max_m if cfg.pri_s is None else min(cfg.range_max_m, C_MPS * cfg.pri_s / 2.0)
    range_m = r0 + (r1 - r0) * uniform(_CH_RANGE)
    u_lo, u_hi = ctx.per_beam(lambda beam: tuple(np.sin(c) for c in ctx._cell_rad(beam)),
                              dwell_id)
    u = u_lo[batch] + (u_hi - u_lo)[batch] * uniform(_CH_ANGLE)
    az = np.arcsin(u)
    half = cfg.range_rate_band_mps
    own_rr = half * (2.0 * uniform(_CH_RR) - 1.0)
    snr_lin = detect.false_alarm_snr(uniform(_CH_SNR), cfg.pfa)
    plat = tuple(np.asarray(d[f"platform_{c}_m"], float)[batch] for c in "xyz")
    ground, el, reached = geolocate.geolocate(plat, range_m, az,
                                              antenna.take(ctx.boresight, batch),
                                              antenna.take(ctx.scan_axis, batch),
                                              antenna.take(ctx.antenna_up, batch), ctx.terrain,
                                              radius_m=ctx.radius_m)
    ok = np.asarray(reached, bool) & visibility.in_field_of_view(cfg, az, el, range_m)
    i = np.flatnonzero(ok)
    pts = tuple(c[i] for c in ground)
    i = i[ctx.visible(did[i], *pts)]
    return false_alarm_rows(ctx, cfg, did[i], ground[0][i], ground[1][i], ground[2][i],
                            own_rr[i], snr_lin[i], 0)
