"""Steps 3-4 of a sensor chunk: visibility, SNR, the detection draw and the measurements.

:func:`evaluate_block` takes the pairs of :func:`.pairs.select_pairs` for some vehicles over a
chunk's revisits and returns their ``/detections`` and ``/looks`` rows (chunk-local det ids).
Visibility in this order (the first failing test names the outcome): footprint and field of
view (azimuth sector, elevation, slant range), invisible road, terrain line of sight (skipped
entirely for a flat terrain); then SNR (:mod:`.gain`, :mod:`.snr`, :mod:`.rcs`), the Swerling-I
detection draw (:mod:`.detect`), measurement errors (:mod:`.measurement`) and geolocation
(:mod:`.geolocate`).  Draws are counter-based on (dwell_id, vehicle_id).
"""
from __future__ import annotations

import numpy as np

from gmtiflow import frames, rng
from gmtiflow.sensor import (antenna, detect, gain, geolocate, geometry, measurement, scan, snr,
                             visibility)
from gmtiflow.sensor.context import SensorRun
from gmtiflow.sensor.outcome import Outcome
from gmtiflow.sensor.pairs import select_pairs
from gmtiflow.sensor.poses import Poses


def _azimuth(east, north):
    """World azimuth clockwise from north in [0, 2π) (as frames.heading_rad, without np.mod)."""
    return _world_azimuth(np.arctan2(east, north))


def _world_azimuth(raw):
    """arctan2(east, north) in [−π, π] as [0, 2π): the negative ones get 2π, through index
    arrays (a boolean-mask ``a[m] += x``, or an ``out=``/``where=`` ufunc, costs ~5 ns per
    element in numpy 2, the index path ~1 ns)."""
    a = raw.copy()
    neg = np.flatnonzero(raw < 0)
    a[neg] = raw[neg] + 2.0 * np.pi
    return a


def _pair_counters(dwell_ids, vehicle_ids, dl, veh) -> rng.Counters:
    """The counters (dwell_ids[dl], veh) of pairs, mixed: each dwell's and each vehicle's id is
    mixed once and gathered per pair (the same values as ``rng.Counters(dwell_ids[dl], veh)``;
    vehicles indexed by id, like the run's type codes); the dwell leads, so each draw's first
    step is taken once per dwell (``rng.Counters``' ``lead``)."""
    by_id = np.zeros(int(vehicle_ids.max()) + 1 if len(vehicle_ids) else 0, np.uint64)
    by_id[vehicle_ids] = rng.mix_counter(vehicle_ids)
    return rng.Counters(mixed=[np.take(by_id, veh)], lead=(rng.mix_counter(dwell_ids), dl))


def evaluate_block(run: SensorRun, poses: Poses, vehicle_ids):
    """Detections and looks of some vehicles over the chunk's revisits (chunk-local det ids),
    and the number of (dwell, target) pairs evaluated."""
    cfg, sched, terrain, seed, origin = run.cfg, run.sched, run.terrain, run.seed, run.origin
    rcs_models, type_codes, los_step_m = run.rcs_models, run.type_codes, run.los_step_m
    dwell_ids = poses.dwell_ids
    n_d = sched.n_dwells
    instant = sched.instant
    dl, veh, geo, n_eval = select_pairs(run, poses, vehicle_ids)
    n = len(dl)
    veh = veh.astype(np.int64, copy=False)
    rng_m, rr = geo["range_m"], geo["rr"]
    beam_index = dl % n_d
    beam = np.take(sched.beam_scan_rad, beam_index)       # np.take: per-dwell lookups
    dwell_id = np.take(dwell_ids, dl)
    time_s = np.take(poses.time_s, dl)
    los_az = geo["los_az"]                     # arctan2(ℓ_e, ℓ_n), as the RCS aspect uses it
    true_az_world = _world_azimuth(los_az)

    # --- visibility: field of view, invisible road, terrain -------------------------------
    outcome = np.full(n, Outcome.OUTSIDE_FOV, np.uint8)
    fov = geo["fov"]         # in the footprint and the field of view (az, el, slant range)
    invisible = geo["invisible"]
    outcome[np.flatnonzero(fov & invisible)] = Outcome.INVISIBLE_ROAD
    cand = fov & ~invisible
    clear = np.zeros(n, bool)
    ci = np.flatnonzero(cand)
    dl_ci = np.take(dl, ci)
    reach_p = visibility.horizon_distance_m(poses.pos[2], cfg.horizon_k_factor,
                                            poses.radius_m)      # per dwell, not per pair
    # the pair's squared map separation as its geometry computed it (the same Δx² + Δy²)
    clear[ci] = visibility.within_reach(geo.at("ground_d2", ci), geo.at("z_m", ci),
                                        cfg.horizon_k_factor, poses.radius_m,
                                        np.take(reach_p, dl_ci))
    if not getattr(terrain, "flat", False):
        cc = ci[np.flatnonzero(clear[ci])]
        c_dl = np.take(dl, cc)
        clear[cc] = visibility.terrain_clear(terrain, antenna.take(poses.pos, c_dl),
                                             tuple(geo.at(k, cc) for k in ("x_m", "y_m", "z_m")),
                                             los_step_m, cfg.horizon_k_factor * poses.radius_m)
    outcome[np.flatnonzero(cand & ~clear)] = Outcome.TERRAIN

    # --- SNR and the Swerling-I draw for the visible pairs -------------------------------
    vis = np.flatnonzero(cand & clear)
    snr_db_col = np.full(n, np.nan)
    pd_col = np.zeros(n)
    det_local = np.full(n, -1, np.int64)
    scan_angle = geo.at("az", vis) if instant else np.take(beam, vis)
    if instant:
        f_mis, loss = 1.0, None
    else:   # per beam position, looked up: the same values as per pair
        b_vis = np.take(beam_index, vis)
        # |u_t − u_b| of the footprint test (a visible pair is in the footprint)
        f_mis = gain.mismatch_off(geo.at("beam_offset_sine", vis), cfg.beamwidth_sine)
        loss = gain.scan_loss(sched.beam_scan_rad)[b_vis]
    g_t = gain.transmit_gain(cfg.n_elements, scan_angle, f_mis, loss)
    dl_vis, veh_vis = np.take(dl, vis), np.take(veh, vis)
    mdv = np.take(poses.mdv, dl_vis)
    if cfg.stap:
        own_rr = geo.at("own_rr", vis)                                 # ṙ − ṙ_MLC at the target
    else:   # no STAP: the Doppler filter rejects the main-lobe clutter around the beam centre's
        dv = dl_vis
        l_bc = antenna.direction(scan_angle, geo.at("el", vis), antenna.take(poses.b, dv),
                                 antenna.take(poses.h, dv), antenna.take(poses.u, dv))
        # the true platform velocity, as in the target's range rate (map rates are
        # (R + z)/R slower: the band's centre was off the ground's clutter by 0.094 % at 6 km)
        vel_p = geometry.true_velocity(poses.vel, poses.pos[2], poses.radius_m)
        own_rr = np.take(rr, vis) + antenna.dot(antenna.take(vel_p, dv), l_bc)
    folded = gain.blind_offset(own_rr, cfg.blind_speed_mps)   # for the gain and the misses
    if cfg.stap:
        g_r = g_t * gain.stap_notch(own_rr, mdv, cfg.blind_speed_mps, offset=folded)
    else:
        g_r = g_t * gain.clutter_band_gain(own_rr, mdv, cfg.blind_speed_mps, folded=folded)
    rcs_v = rcs_models.rcs_dbsm(np.take(type_codes, veh_vis), geo.at("heading_rad", vis),
                                None, None, los_azimuth_rad=np.take(los_az, vis))
    s_db = snr.snr_db(cfg, np.take(rng_m, vis), g_t, g_r, rcs_v)
    s_lin = snr.db_to_linear(s_db)
    lpd = detect.log_pd(s_lin, cfg.pfa)
    pairs = _pair_counters(dwell_ids, vehicle_ids, dl_vis, veh_vis)   # for all four draws
    uni = pairs.uniform(rng.counter_key(seed, "sensor", "pd"))
    log_u = np.log(uni)
    # hits and misses as index arrays (numpy's boolean-mask gathers are ~5x slower)
    is_hit = log_u < lpd
    hit, not_hit = np.flatnonzero(is_hit), np.flatnonzero(~is_hit)
    snr_db_col[vis] = s_db
    pd_col[vis] = np.exp(lpd)
    miss = np.take(vis, not_hit)
    blind = np.abs(np.take(folded, not_hit)) < np.take(mdv, not_hit)
    outcome[miss] = np.where(blind, Outcome.DOPPLER_BLIND, Outcome.PD_MISS)

    # --- detections: reported SNR, errors, geolocation ----------------------------------
    d = np.take(vis, hit)
    k = d.size
    outcome[d] = Outcome.DETECTED
    det_local[d] = np.arange(k)
    snr_rep = detect.reported_snr(None, np.take(s_lin, hit), log_uniform=np.take(log_u, hit))
    bw_rad = (scan.broadened_beamwidth_rad(cfg, scan_angle[hit]) if instant else
              scan.broadened_beamwidth_rad(cfg, sched.beam_scan_rad)[np.take(b_vis, hit)])
    s_r, s_az, s_rr = measurement.sigmas(cfg, snr_rep, bw_rad)
    e_r, e_az, e_rr = measurement.draw_errors(seed, None, None, s_r, s_az, s_rr,
                                              counters=pairs.take(hit))
    true_r, true_rr = np.take(rng_m, d), np.take(rr, d)
    r_meas = np.maximum(true_r + e_r, 0.0)
    az_meas = geo.at("az", d) + e_az
    dd = np.take(dl, d)
    ppd = antenna.take(poses.pos, dd)
    b_dd, h_dd = antenna.take(poses.b, dd), antenna.take(poses.h, dd)
    ground, _, _ = geolocate.geolocate(ppd, r_meas, az_meas, b_dd, h_dd,
                                       antenna.take(poses.u, dd),
                                       terrain, radius_m=poses.radius_m, elevation=False)
    # σ of the reported world azimuth: the error was drawn on the antenna's scan angle
    _, los_meas = geometry.line_of_sight(ppd, ground, poses.radius_m)
    s_az_world = measurement.world_azimuth_sigma(s_az, antenna.azimuth_rate(los_meas, b_dd, h_dd))
    lat, lon, hgt = frames.enu_to_geodetic(origin, *ground)
    detections = {
        "det_id": np.arange(k, dtype=np.int64),
        "dwell_id": np.take(dwell_id, d),
        "time_s": np.take(time_s, d),
        "range_m": r_meas,
        "azimuth_rad": _azimuth(ground[0] - ppd[0], ground[1] - ppd[1]),
        "range_rate_mps": true_rr + e_rr,
        "true_range_m": true_r,
        "true_azimuth_rad": np.take(true_az_world, d),
        "true_range_rate_mps": true_rr,
        "snr_db": 10.0 * np.log10(snr_rep),
        "sigma_range_m": s_r, "sigma_azimuth_rad": s_az_world, "sigma_range_rate_mps": s_rr,
        "x_m": ground[0], "y_m": ground[1], "z_m": ground[2],
        "lat_deg": np.atleast_1d(lat), "lon_deg": np.atleast_1d(lon),
        "height_m": np.atleast_1d(hgt),
        "truth_id": np.take(veh, d),
        "merged": np.zeros(k, bool), "range_folded": np.zeros(k, bool),
        "doppler_wrapped": np.zeros(k, bool), "implausible": np.zeros(k, bool),
        "rcs_dbsm": np.take(rcs_v, hit),
        "wrap_velocity_mps": np.full(k, cfg.wrap_velocity_mps),
    }
    looks = {
        "dwell_id": dwell_id, "vehicle_id": veh, "time_s": time_s,
        "outcome": outcome, "snr_db": snr_db_col, "pd": pd_col, "range_m": rng_m,
        "azimuth_rad": true_az_world, "range_rate_mps": rr, "det_id": det_local,
    }
    return detections, looks, n_eval
