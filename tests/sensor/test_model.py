"""The sensor stage end to end over small fakes: tables, outcomes, physics, reproducibility."""
import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gmtiflow.sensor import scan, visibility
from gmtiflow.sensor.config import SensorConfig
from gmtiflow.sensor.model import simulate
from gmtiflow.sensor.outcome import Outcome
from sensor_fakes import (ORIGIN, FlatTerrain, LevelPlatform, LineFleet, WallTerrain, grid_fleet,
                          ground_angles, run, still)

DOCS = Path(__file__).resolve().parents[2] / "docs" / "tables.md"
H = 6_000.0            # platform height; platform at y = -30 km flying west, looking north
HOVER = LevelPlatform(speed_mps=0.0)
NO_STAP = SensorConfig(stap=False, mdv_mps=0.0)   # no clutter at all (the paper)


def documented_columns(table):
    text = DOCS.read_text()
    section = re.split(rf"## /{table}\b[^\n]*\n", text, maxsplit=1)[1].split("\n\n", 1)[0]
    # drop the definitions after the column list ("`doppler_blind` = missed while ...")
    section = re.split(r"\n`\w+` = ", section, maxsplit=1)[0]
    names = []
    for tick in re.findall(r"`([^`]+)`", section):
        names += [w for w in tick.split() if "." not in w]
    return names


@pytest.mark.parametrize("table", ["dwells", "detections", "looks"])
def test_tables_have_exactly_the_documented_columns(table):
    out = run(SensorConfig(), grid_fleet(50))
    assert list(out[table]) == documented_columns(table)
    lengths = {len(c) for c in out[table].values()}
    assert len(lengths) == 1


def test_column_types_and_ids():
    out = run(SensorConfig(), grid_fleet(200), duration_s=11.0)
    d, det, lk = out["dwells"], out["detections"], out["looks"]
    assert np.array_equal(d["dwell_id"], np.arange(len(d["dwell_id"])))
    assert np.array_equal(det["det_id"], np.arange(len(det["det_id"])))
    assert lk["outcome"].dtype == np.uint8 and det["merged"].dtype == bool
    assert d["last_dwell"].sum() == d["revisit_id"].max() + 1
    assert len(det["det_id"]) > 0
    # looks point at their detections and vice versa
    hit = lk["det_id"] >= 0
    assert np.all(lk["outcome"][hit] == Outcome.DETECTED)
    assert np.array_equal(det["truth_id"][lk["det_id"][hit]], lk["vehicle_id"][hit])
    assert np.array_equal(det["dwell_id"][lk["det_id"][hit]], lk["dwell_id"][hit])
    # rows ordered by (dwell, vehicle)
    key = lk["dwell_id"] * 10_000 + lk["vehicle_id"]
    assert np.all(np.diff(key) > 0)
    # NaN wrap velocity only without a PRF
    assert np.allclose(d["wrap_velocity_mps"], SensorConfig().wrap_velocity_mps)


def test_dwell_geometry_columns():
    out = run(SensorConfig(), still([(0.0, 0.0)]), HOVER)
    d = out["dwells"]
    mid = np.argmin(np.abs(d["beam_scan_rad"]))
    assert d["beam_az_rad"][mid] == pytest.approx(0.0, abs=0.02)       # boresight north
    assert d["area_lat_deg"][mid] == pytest.approx(ORIGIN.lat_deg, abs=0.05)
    assert d["area_lon_deg"][mid] == pytest.approx(ORIGIN.lon_deg, abs=0.05)
    assert np.allclose(d["platform_heading_rad"], math.radians(270.0))


# --- footprint rule -----------------------------------------------------------------------

def test_vehicle_in_no_footprint_gets_one_outside_fov_row_against_the_nearest_dwell():
    cfg = SensorConfig()
    fleet = still([(20_000.0, 0.0), (-20_000.0, 0.0), (0.0, -40_000.0)])   # east, west, behind
    lk = run(cfg, fleet, HOVER)["looks"]
    n_d = scan.n_dwells(cfg)
    assert len(lk["vehicle_id"]) == 3
    assert np.all(lk["outcome"] == Outcome.OUTSIDE_FOV)
    assert lk["dwell_id"][lk["vehicle_id"] == 0][0] == n_d - 1     # east = clockwise edge
    assert lk["dwell_id"][lk["vehicle_id"] == 1][0] == 0


def test_vehicle_in_the_sector_is_looked_at_by_every_beam_within_the_footprint():
    cfg = NO_STAP
    lk = run(cfg, still([(0.0, 0.0), (2_000.0, 1_000.0)]), HOVER)["looks"]
    beams = np.sin(scan.beam_centres_rad(cfg))
    for v, (x, y) in enumerate([(0.0, 0.0), (2_000.0, 1_000.0)]):
        u = x / math.hypot(x, 30_000.0 + y)
        expected = np.flatnonzero(np.abs(beams - u) <= cfg.footprint_beamwidths
                                  * cfg.beamwidth_sine)
        rows = lk["vehicle_id"] == v
        assert np.array_equal(np.sort(lk["dwell_id"][rows]), expected)
        assert np.all(lk["outcome"][rows] != Outcome.OUTSIDE_FOV)


def test_instant_scan_gives_one_look_per_vehicle_and_revisit_on_the_beam_centre():
    cfg = replace(NO_STAP, revisit_s=2.0)
    fleet = grid_fleet(300)
    out = run(cfg, fleet, duration_s=7.0, dwell_mode="instant_scan")
    lk = out["looks"]
    n_rev = out["dwells"]["revisit_id"].max() + 1
    assert n_rev == 4 and len(lk["vehicle_id"]) == 300 * n_rev
    # beam on target: no scalloping, so a vehicle's SNR is the peak at its range and azimuth
    from gmtiflow.sensor import gain, snr
    seen = ~np.isnan(lk["snr_db"])
    d = out["dwells"]
    # scan angle of the target = its azimuth off boresight; platform heading west, boresight N
    px = d["platform_x_m"][lk["dwell_id"]]
    state = fleet.state_at(lk["time_s"], lk["vehicle_id"])
    az = np.arctan2(state["x_m"] - px, state["y_m"] - d["platform_y_m"][lk["dwell_id"]])
    g = gain.transmit_gain(cfg.n_elements, az, 1.0)
    expected = snr.snr_db(cfg, lk["range_m"], g, g, 10.0)
    assert np.allclose(lk["snr_db"][seen], expected[seen], atol=1e-9)


def test_half_power_point_end_to_end_two_way_six_db():
    """A target half a beamwidth (sine space) off a beam centre loses 3 dB each way."""
    cfg = NO_STAP
    beams = scan.beam_centres_rad(cfg)
    k = len(beams) // 2
    r_ground = 30_000.0
    u0 = math.sin(beams[k])
    u1 = u0 + cfg.beamwidth_sine / 2
    pts = [(r_ground * u0, r_ground * math.cos(math.asin(u0)) - 30_000.0),
           (r_ground * u1, r_ground * math.cos(math.asin(u1)) - 30_000.0)]
    lk = run(cfg, still(pts), HOVER)["looks"]
    at_k = lk["dwell_id"] == k
    s = {int(v): x for v, x in zip(lk["vehicle_id"][at_k], lk["snr_db"][at_k])}
    assert s[0] - s[1] == pytest.approx(20 * math.log10(2), abs=1e-9)


# --- field of view ------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["az_min", "az_max", "el_min", "el_max", "range_min",
                                  "range_max"])
def test_fov_limits_are_inclusive_and_sharp(name):
    cfg = SensorConfig()
    az_min, az_max, el_min, el_max = visibility.fov_limits_rad(cfg)
    base = dict(az=0.0, el=-0.2, r=30_000.0)
    limit = {"az_min": ("az", az_min, -1), "az_max": ("az", az_max, +1),
             "el_min": ("el", el_min, -1), "el_max": ("el", el_max, +1),
             "range_min": ("r", cfg.range_min_m, -1), "range_max": ("r", cfg.range_max_m, +1)}
    key, value, outward = limit[name]

    def inside(v):
        args = dict(base, **{key: v})
        return bool(visibility.in_field_of_view(cfg, args["az"], args["el"], args["r"]))

    assert inside(value)                                           # exactly on
    assert inside(np.nextafter(value, -outward * np.inf))          # just inside
    assert not inside(np.nextafter(value, outward * np.inf))       # just outside


def place(az_deg=0.0, depression_deg=None, slant_m=None):
    """Ground point seen from the hovering platform at antenna azimuth/elevation or range, on
    the round earth (arc distance g along the azimuth, textbook triangle)."""
    if depression_deg is not None:
        g = ground_angles(H, depression_rad=math.radians(depression_deg))[0]
    else:
        g = ground_angles(H, slant_m=slant_m)[0]
    a = math.radians(az_deg)
    return (g * math.sin(a), g * math.cos(a) - 30_000.0)


@pytest.mark.parametrize("cfg_change, inside, outside", [
    (dict(), place(az_deg=10.0 - 1e-4, slant_m=30_000), place(az_deg=10.0 + 1e-4, slant_m=30e3)),
    (dict(), place(az_deg=-10.0 + 1e-4, slant_m=30_000), place(az_deg=-10 - 1e-4, slant_m=30e3)),
    (dict(), place(slant_m=36_000 - 0.01), place(slant_m=36_000 + 0.01)),
    (dict(range_min_m=25_000.0), place(slant_m=25_000 + 0.01), place(slant_m=25_000 - 0.01)),
    (dict(el_max_deg=-11.0), place(depression_deg=11.0 + 1e-4), place(depression_deg=11 - 1e-4)),
    (dict(el_min_deg=-12.0), place(depression_deg=12.0 - 1e-4), place(depression_deg=12 + 1e-4)),
])
def test_fov_edges_end_to_end(cfg_change, inside, outside):
    cfg = replace(NO_STAP, **cfg_change)
    lk = run(cfg, still([inside, outside]), HOVER)["looks"]
    assert np.all(lk["outcome"][lk["vehicle_id"] == 0] != Outcome.OUTSIDE_FOV)
    assert np.all(lk["outcome"][lk["vehicle_id"] == 1] == Outcome.OUTSIDE_FOV)


def test_bank_towards_the_antenna_moves_the_covered_strip_towards_the_platform():
    cfg = replace(NO_STAP, el_min_deg=-20.0, el_max_deg=-3.0, range_min_m=10_000.0)
    far, near = (0.0, 0.0), (0.0, -18_000.0)     # depression 11.3° and 26.6°
    seen = {}
    for bank in (0.0, 10.0):
        lk = run(cfg, still([far, near]), LevelPlatform(speed_mps=0.0, bank_deg=bank))["looks"]
        seen[bank] = [bool(np.any(lk["outcome"][lk["vehicle_id"] == v] != Outcome.OUTSIDE_FOV))
                      for v in (0, 1)]
    assert seen[0.0] == [True, False]
    assert seen[10.0] == [False, True]


# --- visibility: invisible roads and terrain ------------------------------------------------

def test_invisible_road_is_never_detected():
    fleet = LineFleet([(0.0, 0.0, 0.0), (500.0, 0.0, 0.0)], (0.0, 10.0, 0.0),
                      invisible=[True, False])
    lk = run(SensorConfig(), fleet, duration_s=30.0)["looks"]
    assert np.all(lk["outcome"][lk["vehicle_id"] == 0] == Outcome.INVISIBLE_ROAD)
    assert np.any(lk["outcome"][lk["vehicle_id"] == 1] == Outcome.DETECTED)


class NoRaysTerrain(FlatTerrain):
    def line_of_sight(self, *a, **k):
        raise AssertionError("a flat terrain must not be ray-marched")


def test_terrain_blocks_behind_a_wall_and_flat_terrain_is_never_ray_marched():
    fleet = still([(0.0, 0.0), (0.0, -2_000.0)])      # behind / in front of the wall
    cfg = NO_STAP
    wall = WallTerrain(wall_y_m=-1_000.0, wall_top_m=500.0)
    lk = run(cfg, fleet, HOVER, wall)["looks"]
    assert np.all(lk["outcome"][lk["vehicle_id"] == 0] == Outcome.TERRAIN)
    assert np.all(lk["outcome"][lk["vehicle_id"] == 1] != Outcome.TERRAIN)
    assert sum(wall.calls) == len(lk["outcome"])
    lk_flat = run(cfg, fleet, HOVER, NoRaysTerrain())["looks"]
    assert not np.any(lk_flat["outcome"] == Outcome.TERRAIN)


# --- Doppler: the STAP notch ----------------------------------------------------------------

def movers(n, velocity):
    xs = np.linspace(-3_000, 3_000, n)
    return LineFleet(np.column_stack([xs, np.zeros(n), np.zeros(n)]), velocity)


def outcomes(cfg, fleet, **kw):
    return run(cfg, fleet, duration_s=26.0, **kw)["looks"]["outcome"]


def test_stopped_and_tangential_targets_fall_into_the_notch_radial_movers_come_back():
    cfg = SensorConfig()
    stopped = outcomes(cfg, movers(40, (0.0, 0.0, 0.0)))
    tangential = outcomes(cfg, still([(0.0, 0.0)]), platform=HOVER)
    radial = outcomes(cfg, movers(40, (0.0, 10.0, 0.0)))
    assert np.all(stopped[stopped != Outcome.OUTSIDE_FOV] == Outcome.DOPPLER_BLIND)
    tang = LineFleet([(0.0, 0.0, 0.0)], (8.0, 0.0, 0.0))
    lk = run(cfg, tang, HOVER)["looks"]
    assert np.all(lk["outcome"] == Outcome.DOPPLER_BLIND)
    assert np.all(tangential == Outcome.DOPPLER_BLIND)
    seen = radial[radial != Outcome.OUTSIDE_FOV]
    assert np.mean(seen == Outcome.DETECTED) > 0.3     # scalloping: two beams per target
    assert not np.any(seen == Outcome.DOPPLER_BLIND)
    # without STAP nothing is Doppler blind and stopped targets are seen
    nostap = outcomes(NO_STAP, movers(40, (0.0, 0.0, 0.0)))
    assert not np.any(nostap == Outcome.DOPPLER_BLIND)
    assert np.mean(nostap[nostap != Outcome.OUTSIDE_FOV] == Outcome.DETECTED) > 0.3


def test_blind_speed_needs_a_prf():
    cfg = SensorConfig()
    cos_dep = 30_000.0 / math.hypot(30_000.0, H)
    v = cfg.blind_speed_mps / cos_dep             # own radial speed = the first blind speed
    fleet = LineFleet([(0.0, 0.0, 0.0)], (0.0, v, 0.0))
    lk = run(cfg, fleet, HOVER)["looks"]
    assert np.all(lk["outcome"] == Outcome.DOPPLER_BLIND)
    no_prf = replace(cfg, pri_s=None, integration_gain_db=10 * math.log10(128))
    lk = run(no_prf, fleet, HOVER)["looks"]
    assert np.all(lk["outcome"] != Outcome.DOPPLER_BLIND)
    assert np.all(np.isnan(run(no_prf, fleet, HOVER)["dwells"]["wrap_velocity_mps"]))


# --- statistics -----------------------------------------------------------------------------

@pytest.fixture(scope="module")
def big_run():
    cfg = NO_STAP
    fleet = grid_fleet(3_000, seed=3)
    return cfg, run(cfg, fleet, duration_s=16.0)


def test_detections_agree_with_pd_over_many_looks(big_run):
    _, out = big_run
    lk = out["looks"]
    seen = ~np.isnan(lk["snr_db"])
    p = lk["pd"][seen]
    k = int(np.sum(lk["outcome"][seen] == Outcome.DETECTED))
    assert 0.2 < p.mean() < 0.98          # a mix of strong and weak looks
    assert abs(k - p.sum()) <= 4.5 * math.sqrt(np.sum(p * (1 - p)))


def test_errors_are_gaussian_with_the_reported_sigmas(big_run):
    from scipy import stats
    cfg, out = big_run
    det = out["detections"]
    n = len(det["det_id"])
    assert n > 5_000
    for meas, true, sig in (("range_m", "true_range_m", "sigma_range_m"),
                            ("range_rate_mps", "true_range_rate_mps", "sigma_range_rate_mps")):
        z = (det[meas] - det[true]) / det[sig]
        q = float(np.sum(z * z))
        assert stats.chi2.ppf(1e-5, n) <= q <= stats.chi2.ppf(1 - 1e-5, n)
        assert abs(z.mean()) < 4.5 / math.sqrt(n)
    z = _azimuth_z(det)
    q = float(np.sum(z * z))
    assert stats.chi2.ppf(1e-5, n) <= q <= stats.chi2.ppf(1 - 1e-5, n)
    assert abs(z.mean()) < 4.5 / math.sqrt(n)
    # strong detections sit on the floors
    strong = det["snr_db"] > 40
    assert np.allclose(det["sigma_range_m"][strong], cfg.kappa_r * cfg.range_resolution_m / 10)
    # reported SNR is at least the threshold's
    assert np.all(det["snr_db"] >= 10 * math.log10(-math.log(cfg.pfa) - 1) - 1e-9)
    # geolocated points on the (flat) ground, near the truth
    assert np.allclose(det["z_m"], 0.0, atol=1e-6)


def _azimuth_z(det):
    """(measured − true world azimuth) / sigma_azimuth_rad, the difference wrapped to ±π."""
    e = np.angle(np.exp(1j * (det["azimuth_rad"] - det["true_azimuth_rad"])))
    return e / det["sigma_azimuth_rad"]


@pytest.mark.parametrize("bank_deg", [15.0, -10.0])
def test_azimuth_errors_follow_the_reported_sigma_when_the_antenna_is_banked(bank_deg):
    """The azimuth error is drawn in the antenna frame, but /detections reports the world
    azimuth: with the antenna rolled, one antenna-frame radian is not one world radian (15°
    of bank at these elevations: 0.90–0.95), and sigma_azimuth_rad must be the world
    azimuth's σ, or a tracker weighting azimuth by it is overconfident (the variance of the
    normalised error was 1.14 here before the fix)."""
    from scipy import stats
    cfg = replace(NO_STAP, el_min_deg=-45.0, el_max_deg=20.0, range_min_m=8_000.0)
    platform = LevelPlatform(p0=(0.0, -15_000.0, 6_000.0), bank_deg=bank_deg)
    det = run(cfg, grid_fleet(3_000, seed=5), platform, duration_s=16.0)["detections"]
    n = len(det["det_id"])
    assert n > 3_000
    z = _azimuth_z(det)
    q = float(np.sum(z * z))
    assert stats.chi2.ppf(1e-5, n) <= q <= stats.chi2.ppf(1 - 1e-5, n)
    assert abs(z.mean()) < 4.5 / math.sqrt(n)


# --- reproducibility ------------------------------------------------------------------------

def same(a, b):
    return all(np.array_equal(a[t][c], b[t][c], equal_nan=True) for t in a for c in a[t])


def test_same_seed_same_output_and_chunking_or_threads_do_not_matter():
    cfg = SensorConfig(revisit_s=2.0)
    fleet = grid_fleet(400)
    a = run(cfg, fleet, duration_s=15.0)
    b = run(cfg, fleet, duration_s=15.0, chunk_pairs=500)
    c = run(cfg, fleet, duration_s=15.0, chunk_pairs=2_000, workers=2)
    assert same(a, b) and same(a, c)
    d = run(cfg, fleet, duration_s=15.0, seed=8)
    assert not np.array_equal(a["detections"]["range_m"], d["detections"]["range_m"])


def test_changing_one_vehicle_leaves_the_others_draws_unchanged():
    cfg = SensorConfig()
    p0 = np.column_stack([np.linspace(-3e3, 3e3, 20), np.zeros(20), np.zeros(20)])
    v = np.tile([0.0, 8.0, 0.0], (20, 1))
    a = run(cfg, LineFleet(p0, v), duration_s=12.0)
    p1, v1 = p0.copy(), v.copy()
    p1[5] = (1_000.0, 2_000.0, 0.0)
    v1[5] = (-5.0, 0.0, 0.0)
    b = run(cfg, LineFleet(p1, v1), duration_s=12.0)
    for t, idcol in (("looks", "vehicle_id"), ("detections", "truth_id")):
        ka, kb = a[t][idcol] != 5, b[t][idcol] != 5
        for col in a[t]:
            if col != "det_id":
                assert np.array_equal(a[t][col][ka], b[t][col][kb], equal_nan=True), (t, col)


# --- extremes -------------------------------------------------------------------------------

def test_zero_range_and_extreme_settings_raise_no_floating_point_errors():
    cfg = replace(SensorConfig(pfa=1e-15), range_min_m=0.0, el_min_deg=-90.0, el_max_deg=90.0,
                  az_min_deg=-89.0, az_max_deg=89.0, revisit_s=10.0)
    fleet = still([(0.0, -30_000.0, 6_000.0), (0.0, -30_000.0, 0.0), (1e7, 0.0, 0.0),
                   (0.0, 0.0, 0.0)])
    with np.errstate(all="raise"):
        out = run(cfg, fleet, HOVER)
    for t in out.values():
        for name, col in t.items():
            if col.dtype.kind == "f" and name not in ("snr_db", "wrap_velocity_mps"):
                assert np.all(np.isfinite(col)), name


def test_empty_fleet_and_zero_duration():
    out = run(SensorConfig(), LineFleet(np.zeros((0, 3)), np.zeros(3)))
    assert len(out["dwells"]["dwell_id"]) == scan.n_dwells(SensorConfig())
    assert len(out["looks"]["dwell_id"]) == 0 and len(out["detections"]["det_id"]) == 0
    out = simulate(SensorConfig(), grid_fleet(5), LevelPlatform(), FlatTerrain(), 1, 0.0, ORIGIN)
    assert all(len(c) == 0 for t in out.values() for c in t.values())


def test_vehicles_active_only_part_of_the_time():
    fleet = LineFleet([(0.0, 0.0, 0.0)] * 2, (0.0, 10.0, 0.0), start_s=[0.0, 6.0],
                      end_s=[4.0, 100.0])
    lk = run(SensorConfig(), fleet, duration_s=16.0)["looks"]
    t0 = lk["time_s"][lk["vehicle_id"] == 0]
    t1 = lk["time_s"][lk["vehicle_id"] == 1]
    assert t0.size and np.all(t0 <= 4.0)
    assert t1.size and np.all(t1 >= 6.0)


def test_vehicles_leaving_or_appearing_mid_scan_keep_one_look_row_per_revisit():
    """A vehicle at the sector's far edge that leaves just after the middle dwell is inactive
    at its candidate dwells (the last beams); one appearing just before the middle at the near
    edge is inactive at the first beams: each still gets its one look row, at the middle dwell
    (docs/tables.md: every active vehicle, one row per revisit at least)."""
    cfg = SensorConfig()
    n_d = scan.n_dwells(cfg)
    t_mid = (n_d // 2 + 0.5) * cfg.cpi_s
    fleet = LineFleet([(4_600.0, 0.0, 0.0), (-4_600.0, 0.0, 0.0), (0.0, 0.0, 0.0)],
                      (0.0, 0.0, 0.0), start_s=[0.0, t_mid - 0.01, 0.0],
                      end_s=[t_mid + 0.01, 100.0, 100.0])
    lk = run(cfg, fleet, platform=HOVER, duration_s=n_d * cfg.cpi_s)["looks"]
    for v in (0, 1):
        rows = lk["vehicle_id"] == v
        assert rows.sum() == 1, (v, lk["dwell_id"][rows])
        assert lk["dwell_id"][rows][0] == n_d // 2
        assert lk["outcome"][rows][0] == Outcome.OUTSIDE_FOV
    assert np.sum(lk["vehicle_id"] == 2) >= 1
    key = lk["dwell_id"] * 10 + lk["vehicle_id"]
    assert np.all(np.diff(key) > 0)


# --- the effects seam -----------------------------------------------------------------------

def test_effects_post_process_each_chunk_and_ids_are_renumbered():
    from gmtiflow.sensor.outcome import Outcome as O

    def drop_first(ctx, det, looks):
        if len(det["det_id"]) < 2:
            return det, looks
        assert set(np.unique(det["dwell_id"])) <= set(ctx.dwells["dwell_id"])
        gone = det["det_id"][0]
        keep = det["det_id"] != gone
        det = {k: v[keep] for k, v in det.items()}
        det["merged"][0] = True
        looks = dict(looks)
        hit = looks["det_id"] == gone
        looks["outcome"] = np.where(hit, O.MERGED, looks["outcome"]).astype(np.uint8)
        looks["det_id"] = np.where(hit, det["det_id"][0], looks["det_id"])
        return det, looks

    out = run(SensorConfig(revisit_s=1.0), grid_fleet(100), duration_s=6.0,
              effects=[drop_first], chunk_pairs=300)
    det, lk = out["detections"], out["looks"]
    assert np.array_equal(det["det_id"], np.arange(len(det["det_id"])))
    assert np.sum(lk["outcome"] == Outcome.MERGED) > 1
    hit = lk["det_id"] >= 0
    assert np.all(np.isin(lk["det_id"][hit], det["det_id"]))


def test_look_range_rates_include_the_platform_motion():
    """Flying west, a target east of broadside recedes: ṙ = (v_t − v_p)·ℓ > 0.  Checked as the
    time derivative of the slant range between the two positions in WGS-84 ECEF (pymap3d,
    central difference), i.e. independently of the sensor's round-earth frames."""
    import pymap3d
    from gmtiflow import frames
    fleet = LineFleet([(3_000.0, 0.0, 0.0), (-3_000.0, 0.0, 0.0)], (0.0, 5.0, 0.0))
    plat = LevelPlatform()
    out = run(NO_STAP, fleet, plat)
    lk = out["looks"]

    def slant(t):
        st, ps = fleet.state_at(t, lk["vehicle_id"]), plat.state_at(t)
        ends = [pymap3d.geodetic2ecef(*frames.enu_to_geodetic(
            ORIGIN, *(s[f"{c}_m"] for c in "xyz"))) for s in (st, ps)]
        return np.linalg.norm(np.subtract(ends[0], ends[1]), axis=0)

    h = 1e-2
    rr = (slant(lk["time_s"] + h) - slant(lk["time_s"] - h)) / (2 * h)
    # sphere vs ellipsoid and the map's distortion: ~1e-5 of the speeds (200 m/s)
    assert np.allclose(lk["range_rate_mps"], rr, atol=5e-3)
    assert np.all(lk["range_rate_mps"][lk["vehicle_id"] == 0] > 15.0)
    assert np.all(lk["range_rate_mps"][lk["vehicle_id"] == 1] < -10.0)


@pytest.mark.parametrize("change, mode", [
    (dict(az_min_deg=-45.0, az_max_deg=45.0, el_min_deg=-45.0, el_max_deg=-1.0,
          range_min_m=8_000.0, range_max_m=37_000.0, revisit_s=8.0), "dwell_resolved"),
    (dict(snr_form="reference"), "dwell_resolved"),
    (dict(pri_s=None, integration_gain_db=21.0), "instant_scan")])
def test_other_settings_run_end_to_end(change, mode):
    cfg = replace(SensorConfig(), **change)
    assert cfg.problems() == []
    out = run(cfg, grid_fleet(500, extent=30_000.0), duration_s=20.0, dwell_mode=mode)
    oc = out["looks"]["outcome"]
    assert np.any(oc == Outcome.DETECTED) and np.any(oc == Outcome.OUTSIDE_FOV)
    assert np.all(np.isfinite(out["detections"]["x_m"]))


def test_chunk_context_sees_the_scene_as_the_sensor_does():
    """The effects' helpers: geolocation inverts the reported (range, azimuth), antenna angles
    and FoV agree with the looks, the dwell cells tile the sector, ground range rates."""
    cfg = SensorConfig()
    seen = []

    def check(ctx, det, looks):
        x, y, z = ctx.geolocate(det["dwell_id"], det["range_m"], det["azimuth_rad"])[0]
        assert np.allclose(x, det["x_m"], atol=1e-6) and np.allclose(y, det["y_m"], atol=1e-6)
        assert np.allclose(z, det["z_m"], atol=1e-6)
        rng_m, az, el = ctx.antenna_angles(det["dwell_id"], det["x_m"], det["y_m"], det["z_m"])
        assert np.allclose(rng_m, det["range_m"], rtol=1e-12)
        d = ctx.dwells["dwell_id"]
        lo, hi = ctx.dwell_cell_rad(d)
        n_d = scan.n_dwells(cfg)
        assert lo[0] == pytest.approx(math.radians(cfg.az_min_deg))
        assert hi[n_d - 1] == pytest.approx(math.radians(cfg.az_max_deg))
        assert np.allclose(hi[:n_d - 1], lo[1:n_d])
        # a stopped target moves with the ground: its true range rate is the clutter's
        st = fleet.state_at(det["time_s"], det["truth_id"])
        mlc = ctx.range_rate_of_ground(det["dwell_id"], st["x_m"], st["y_m"], st["z_m"])
        assert np.allclose(mlc, det["true_range_rate_mps"], atol=1e-9)
        assert np.all(ctx.in_fov(det["dwell_id"], st["x_m"], st["y_m"], st["z_m"]))
        assert np.all(ctx.in_fov(det["dwell_id"], st["x_m"], st["y_m"]))
        far = ctx.in_fov(d, ctx.dwells["platform_x_m"], ctx.dwells["platform_y_m"] + 50_000.0)
        assert not np.any(far)
        seen.append(len(det["det_id"]))
        return det, looks

    fleet = grid_fleet(200, speed=0.0)
    run(NO_STAP, fleet, duration_s=11.0, effects=[check])
    assert sum(seen) > 0


def test_an_enum_dwell_mode_selects_the_instant_scan():
    import enum

    class DwellMode(enum.Enum):
        instant_scan = "instant_scan"

    lk = run(SensorConfig(), grid_fleet(50), dwell_mode=DwellMode.instant_scan)["looks"]
    assert len(lk["vehicle_id"]) == 50
