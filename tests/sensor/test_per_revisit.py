"""Shortcuts of the sensor stage for many dwells: bit-identical to the general formulation.

* :func:`gmtiflow.sensor.poses.chunk_poses` evaluates the platform and the antenna axes once per
  revisit when all its dwells share one instant (``instant_scan``).
* :func:`gmtiflow.sensor.effects.append_in_dwell_order` merges the noise false alarms into the
  detections instead of sorting the concatenation (:func:`gmtiflow.sensor.effects.reindex`).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gmtiflow.scene.platform import Platform, PlatformConfig
from gmtiflow.sensor import effects, noise, poses
from gmtiflow.sensor.config import SensorConfig
from sensor_fakes import ORIGIN, LevelPlatform, grid_fleet, run


def _bits_equal(a, b):
    for t in a:
        assert a[t].keys() == b[t].keys(), t
        for c in a[t]:
            x, y = np.asarray(a[t][c]), np.asarray(b[t][c])
            assert x.dtype == y.dtype and x.shape == y.shape, (t, c)
            assert x.tobytes() == y.tobytes(), (t, c)


class _Counting:
    """A platform that records the length of every ``state_at`` call."""

    def __init__(self, platform):
        self.platform = platform
        self.sizes = []

    def state_at(self, time_s):
        self.sizes.append(len(np.atleast_1d(time_s)))
        return self.platform.state_at(time_s)


def test_shared_revisit_times_only_when_every_dwell_of_a_revisit_shares_its_time():
    t = np.repeat([0.5, 5.5, 10.5], 4)
    assert np.array_equal(poses._shared_revisit_times(t, 4), [0.5, 5.5, 10.5])
    t[5] += 1e-12                                   # one dwell off its revisit's instant
    assert poses._shared_revisit_times(t, 4) is None
    assert poses._shared_revisit_times(np.arange(8.0), 4) is None    # dwell-resolved times
    assert poses._shared_revisit_times(np.zeros(6), 4) is None       # not whole revisits
    assert poses._shared_revisit_times(np.zeros(4), 1) is None


def _turning_platform():
    # the real fixed-wing orbit: west looking north at the fleet, then turns, banks and climbs
    cfg = PlatformConfig(waypoints_m=[[20000, -30000, 6000], [-20000, -30000, 7000],
                                      [-20000, -50000, 6000], [20000, -50000, 6000]],
                         speed_mps=150.0, turn_lead_s=20.0)
    return Platform(cfg, ORIGIN)


@pytest.mark.parametrize("make_platform", [lambda: LevelPlatform(bank_deg=3.0),
                                           _turning_platform])
def test_instant_scan_poses_per_revisit_are_bit_identical_to_per_dwell(monkeypatch,
                                                                        make_platform):
    cfg = replace(SensorConfig(), revisit_s=7.0)
    fleet = grid_fleet(60)
    platform = _Counting(make_platform())
    kw = dict(duration_s=400.0, dwell_mode="instant_scan", chunk_pairs=300)
    fast = run(cfg, fleet, platform, **kw)
    n_d = cfg.normalised().n_dwells
    n_rev = len(fast["dwells"]["dwell_id"]) // n_d
    assert n_rev > 20 and sum(platform.sizes) == n_rev     # once per revisit, several chunks
    platform.sizes.clear()
    monkeypatch.setattr(poses, "_shared_revisit_times", lambda time_s, n_d: None)
    slow = run(cfg, fleet, platform, **kw)
    assert sum(platform.sizes) == n_rev * n_d               # once per dwell
    assert len(fast["detections"]["det_id"]) > 0
    _bits_equal(fast, slow)


def _tables(g, n, m, n_dwells, unsorted=False):
    d_dw = np.sort(g.integers(0, n_dwells, n)) + 100
    r_dw = np.sort(g.integers(0, n_dwells, m)) + 100
    if unsorted and n > 1:
        d_dw = d_dw[::-1].copy()
    det = {"det_id": np.arange(n, dtype=np.int64), "dwell_id": d_dw,
           "x_m": g.normal(size=n), "merged": g.random(n) < 0.5,
           "truth_id": g.integers(0, 9, n)}
    rows = {"det_id": np.arange(n, n + m, dtype=np.int64), "dwell_id": r_dw,
            "x_m": g.normal(size=m), "merged": np.zeros(m, bool),
            "truth_id": np.full(m, -1, np.int64)}
    k = 3 * n + 5
    ld = np.full(k, -1, np.int64)
    ld[g.choice(k, n, replace=False)] = g.permutation(n)
    looks = {"det_id": ld, "outcome": g.integers(0, 6, k).astype(np.uint8)}
    return det, rows, looks


@pytest.mark.parametrize("n, m, n_dwells, unsorted", [
    (50, 40, 10, False), (50, 40, 400, False), (0, 30, 5, False), (30, 0, 5, False),
    (1, 1, 1, False), (60, 25, 8, True)])
def test_append_in_dwell_order_equals_reindex_of_the_concatenation(n, m, n_dwells, unsorted):
    g = np.random.default_rng(n * 1000 + m + n_dwells)
    det, rows, looks = _tables(g, n, m, n_dwells, unsorted)
    got_d, got_l = effects.append_in_dwell_order(det, rows, looks)
    want_d, want_l = effects.reindex(noise.append_rows(det, rows), looks)
    _bits_equal({"d": got_d, "l": got_l}, {"d": want_d, "l": want_l})
    assert np.all(np.diff(got_d["dwell_id"]) >= 0)
    # a target detection keeps its values, and its look points at it
    hit = np.flatnonzero(got_l["det_id"] >= 0)
    old = looks["det_id"][hit]
    assert np.array_equal(got_d["x_m"][got_l["det_id"][hit]], det["x_m"][old])


class _Adder:
    """A row-adding effect (like the false alarms): fixed rows, numbered from next_det_id."""

    def __init__(self, rows):
        self.rows, self.calls = rows, 0

    def added_rows(self, ctx, next_det_id):
        self.calls += 1
        m = len(self.rows["dwell_id"])
        return None if m == 0 else {**self.rows, "det_id": np.arange(next_det_id,
                                                                     next_det_id + m)}

    def __call__(self, ctx, det, looks):
        rows = self.added_rows(ctx, effects._next_det_id(det))
        return (det, looks) if rows is None else effects.append_in_dwell_order(det, rows, looks)


@pytest.mark.parametrize("n, ms, n_dwells, unsorted", [
    (50, (40, 30), 10, False), (50, (40, 0, 25), 400, False), (0, (30, 5), 5, False),
    (30, (0, 0), 5, False), (1, (1, 1), 1, False), (60, (25, 9), 8, True)])
def test_row_adding_effects_merged_at_once_equal_their_merges_in_turn(n, ms, n_dwells,
                                                                      unsorted):
    """apply_effects merges the rows of consecutive false-alarm effects among themselves and
    then once into the detections: the tables of calling the effects in turn, bit for bit
    (on one dwell an earlier effect's rows first); detections out of dwell order: in turn."""
    g = np.random.default_rng(n * 100 + sum(ms) + n_dwells)
    det, _, looks = _tables(g, n, 0, n_dwells, unsorted)
    adders = [_Adder(_tables(g, 0, m, n_dwells)[1]) for m in ms]
    got_d, got_l = effects.apply_effects(None, adders, det, looks)
    want_d, want_l = det, looks
    for adder in adders:
        want_d, want_l = adder(None, want_d, want_l)
    _bits_equal({"d": got_d, "l": got_l}, {"d": want_d, "l": want_l})


def test_range_and_ground_rate_is_the_antenna_range_and_the_ground_rate_bit_for_bit():
    from gmtiflow.sensor import geometry
    seen = []

    def check(ctx, det, looks):
        if len(det["dwell_id"]) < 2:
            return det, looks
        dw, x, y, z = det["dwell_id"], det["x_m"], det["y_m"], det["z_m"] + 3.0
        rng_m, rate = ctx.range_and_ground_rate(dw, x, y, z)
        want_r, _, _ = ctx.antenna_angles(dw, x, y, z)
        # the former range_rate_of_ground, written out: −v_p·ℓ with its own line of sight
        k = np.asarray(dw, np.int64) - int(ctx.dwells["dwell_id"][0])
        plat = tuple(ctx.dwells[f"platform_{c}_m"][k] for c in "xyz")
        _, los = geometry.line_of_sight(plat, (x, y, z), ctx.radius_m)
        vel = geometry.true_velocity(tuple(ctx.dwells[f"platform_v{c}_mps"][k] for c in "xyz"),
                                     plat[2], ctx.radius_m)
        want_rate = -(vel[0] * los[0] + vel[1] * los[1] + vel[2] * los[2])
        assert rng_m.tobytes() == want_r.tobytes()
        assert rate.tobytes() == want_rate.tobytes()
        assert ctx.range_rate_of_ground(dw, x, y, z).tobytes() == want_rate.tobytes()
        assert np.ptp(rate) > 1.0                    # the platform moves: rates differ
        seen.append(len(dw))
        return det, looks

    run(SensorConfig(stap=False, mdv_mps=0.0), grid_fleet(200, speed=0.0), duration_s=11.0,
        effects=[check])
    assert sum(seen) > 0


def test_ambiguities_leave_their_input_table_untouched_and_set_folded_rows():
    # the effect shares the columns it does not change with its input: the ones it writes in
    # place (folded reports: range and ground position) must be copies
    cfg = SensorConfig(pri_s=1.8e-4, stap=False, mdv_mps=0.0)   # c·PRI/2 = 27 km: folds
    amb = effects.Ambiguities(cfg)
    seen = []

    def check(ctx, det, looks):
        before = {k: np.array(v, copy=True) for k, v in det.items()}
        out, _ = amb(ctx, det, looks)
        for k in det:
            assert np.asarray(det[k]).tobytes() == before[k].tobytes(), k
        folded = np.asarray(out["range_folded"])
        if folded.any():
            assert np.all(out["range_m"][folded] < before["range_m"][folded])
            assert not np.array_equal(out["x_m"][folded], before["x_m"][folded],
                                      equal_nan=True)
        seen.append(int(folded.sum()))
        return out, looks

    run(cfg, grid_fleet(200, speed=0.0), duration_s=11.0, effects=[check])
    assert sum(seen) > 0


def test_clutter_false_alarms_merge_in_dwell_order_as_reindex_of_the_concatenation(monkeypatch):
    """FalseAlarms sorts its false alarms by dwell (stable) and merges them into the
    detections: the same tables as its former concatenation of the rows in the clutter's own
    order (by source, then dwell) sorted by reindex."""
    from gmtiflow.sensor import clutter as cl

    cfg = SensorConfig()
    ccfg = cl.ClutterConfig(fov_density_per_km2=0.5, regions=[
        cl.ClutterRegionConfig(name="town", shape="circle", centre_m=[0.0, 0.0], radius_m=3000.0,
                               density_per_km2=3.0)])
    fleet = grid_fleet(40)
    seen = {}
    draw = cl.false_alarms

    def record(*a, **kw):
        seen["fa"] = draw(*a, **kw)
        return seen["fa"]

    def grab(ctx, det, looks):
        seen["in"] = (ctx, dict(det), dict(looks))
        return det, looks

    monkeypatch.setattr(cl, "false_alarms", record)
    out = run(cfg, fleet, duration_s=3 * cfg.revisit_s,
              effects=[grab, effects.FalseAlarms(cfg, ccfg, 7)])
    ctx, det, looks = seen["in"]
    fa = seen["fa"]
    assert not np.all(np.diff(fa["dwell_id"]) >= 0)        # by source: not in dwell order
    z = np.nan_to_num(np.asarray(ctx.terrain.height_at(fa["x_m"], fa["y_m"]), float))
    rows = noise.false_alarm_rows(ctx, cfg, fa["dwell_id"], fa["x_m"], fa["y_m"], z,
                                  fa["clutter_range_rate_mps"], fa["snr"],
                                  int(det["det_id"].max()) + 1)
    want_d, want_l = effects.reindex(noise.append_rows(det, rows), looks)
    _bits_equal({"d": out["detections"], "l": out["looks"]}, {"d": want_d, "l": want_l})


def test_per_beam_values_are_the_per_dwell_values_bit_for_bit():
    """ChunkContext.per_beam (and dwell_cell_rad through it) evaluates once per beam position
    and gathers: the values of the function at each dwell's own scan angle; without a
    dwell_index column (or with angles that are not one per position) it takes those."""
    from dataclasses import replace as dc_replace

    from gmtiflow import frames
    from gmtiflow.sensor import antenna, geolocate, scan

    cfg = SensorConfig()
    seen = {}

    def grab(ctx, det, looks):
        seen["ctx"] = ctx
        return det, looks

    out = run(cfg, grid_fleet(5), duration_s=6 * cfg.revisit_s, effects=[grab])
    ctx = seen["ctx"]
    d = ctx.dwells
    assert ctx._beam_table is not None and len(d["dwell_id"]) > 2 * scan.n_dwells(cfg)
    ids = np.repeat(d["dwell_id"], 3)[::-1]
    k = ids - d["dwell_id"][0]

    def fn(beam):
        return scan.broadened_beamwidth_rad(cfg, beam), np.sin(beam)

    want = fn(d["beam_scan_rad"][k])
    for got, w in zip(ctx.per_beam(fn, ids), want):
        assert got.tobytes() == w.tobytes()
    lo, hi = ctx.dwell_cell_rad(ids)
    w_lo, w_hi = ctx._cell_rad(d["beam_scan_rad"][k])
    assert lo.tobytes() == w_lo.tobytes() and hi.tobytes() == w_hi.tobytes()
    bare = dc_replace(ctx, dwells={c: v for c, v in d.items() if c != "dwell_index"})
    assert bare._beam_table is None
    assert bare.per_beam(np.cos, ids).tobytes() == np.cos(d["beam_scan_rad"][k]).tobytes()
    odd = dict(d, beam_scan_rad=d["beam_scan_rad"] + np.arange(len(k) // 3) * 1e-9)
    assert dc_replace(ctx, dwells=odd)._beam_table is None
    # the dwell table's per-position trigonometry: antenna.direction and geolocate per dwell
    dw = out["dwells"]
    beam = dw["beam_scan_rad"]
    st = LevelPlatform().state_at(dw["time_s"])
    b, h, u = antenna.antenna_axes(st["heading_rad"], st.get("pitch_rad", 0 * beam),
                                   st["bank_rad"], np.radians(cfg.mount_deg))
    beam_dir = antenna.direction(beam, np.zeros(len(beam)), b, h, u)
    assert frames.heading_rad(beam_dir[0], beam_dir[1]).tobytes() == dw["beam_az_rad"].tobytes()
    pos = tuple(np.asarray(st[c], float) for c in ("x_m", "y_m", "z_m"))
    centre, _, _ = geolocate.geolocate(pos, np.full(len(beam), 0.5 * (cfg.range_min_m + cfg.range_max_m)),
                                       beam, b, h, u, ctx.terrain, radius_m=ctx.radius_m)
    alat, alon, _ = frames.enu_to_geodetic(ORIGIN, *centre)
    assert alat.tobytes() == dw["area_lat_deg"].tobytes()
    assert alon.tobytes() == dw["area_lon_deg"].tobytes()
    assert (0.5 * scan.broadened_beamwidth_rad(cfg, beam)).tobytes() == dw["angle_half_extent_rad"].tobytes()
