"""The built-in scenes end to end: what issues 2-4 promise a user sees in the run file."""
import numpy as np
import pytest

from gmtiflow import pipeline, store
from gmtiflow.scene.roadmap import DEFAULT_LAKE_POLYGON_M, point_in_polygon
from gmtiflow.sensor.outcome import Outcome


def run(compose_config, tmp_path, *overrides):
    cfg = compose_config(["scene.duration_s=120", "report=none", "export=none", *overrides])
    path = pipeline.run(cfg, tmp_path)
    with store.open_run(path) as f:
        return {name: store.read_table(f, name) for name in
                ("vehicles", "truth", "platform", "detections", "detection_ancestors", "looks",
                 "dwells", "tracks", "metrics")}


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    from gmtiflow.compose import compose
    return run(compose, tmp_path_factory.mktemp("default"))


def vehicle_ids(tables, prefix):
    names = tables["vehicles"]["name"]
    return tables["vehicles"]["vehicle_id"][np.char.startswith(names.astype(str), prefix)]


def test_default_scene_has_every_table_and_detections(default_run):
    t = default_run
    assert len(t["detections"]["det_id"]) > 100
    assert set(np.unique(t["looks"]["outcome"])) >= {Outcome.DETECTED, Outcome.INVISIBLE_ROAD,
                                                     Outcome.DOPPLER_BLIND, Outcome.PD_MISS}
    assert len(t["tracks"]["track_id"]) > 0
    assert "ospa_mean_m" in set(t["metrics"]["name"])


def test_the_convoy_merges_and_its_ancestors_are_recorded(default_run):
    t = default_run
    convoy = vehicle_ids(t, "convoy")
    assert len(convoy) == 3
    anc = t["detection_ancestors"]
    merged_ids = t["detections"]["det_id"][t["detections"]["merged"]]
    assert np.array_equal(np.unique(anc["det_id"]), np.sort(merged_ids))
    from_convoy = np.isin(anc["truth_id"], convoy)
    assert from_convoy.sum() >= 2 * 5          # several convoy merges, two or more each
    # a merged report's truth id is one of its ancestors
    det = t["detections"]
    for d in merged_ids[:20]:
        assert det["truth_id"][d] in anc["truth_id"][anc["det_id"] == d]
    # the absorbed ancestors' looks say "merged" and point at the merged report
    lk = t["looks"]
    absorbed = lk["outcome"] == Outcome.MERGED
    assert np.all(det["merged"][lk["det_id"][absorbed]])


def test_tunnel_car_is_never_detected_in_the_tunnel(default_run):
    t = default_run
    car = vehicle_ids(t, "car-tunnel")[0]
    lk = t["looks"]
    mine = lk["vehicle_id"] == car
    assert np.any(lk["outcome"][mine] == Outcome.INVISIBLE_ROAD)
    det = t["detections"]
    x = det["x_m"][det["truth_id"] == car]
    y = det["y_m"][det["truth_id"] == car]
    in_tunnel = (x > 1500 + 300) & (x < 2500 - 300) & (np.abs(y + 1500) < 300)
    assert not np.any(in_tunnel)


def test_sensor_preset_changes_detections_but_not_the_truth(compose_config, tmp_path, default_run):
    wide = run(compose_config, tmp_path, "sensor=wide_fov")
    for table in ("truth", "vehicles", "platform"):
        for col in default_run[table]:
            assert np.array_equal(default_run[table][col], wide[table][col]), (table, col)
    assert len(wide["dwells"]["dwell_id"]) != len(default_run["dwells"]["dwell_id"])
    assert not np.array_equal(np.sort(wide["detections"]["range_m"]),
                              np.sort(default_run["detections"]["range_m"]))


def test_lake_clutter_puts_false_alarms_on_the_lake_and_leaves_targets_alone(
        compose_config, tmp_path, default_run):
    # the detector's noise false alarms off: every false alarm left is the lake's
    lake = run(compose_config, tmp_path, "clutter=lake", "sensor.noise_false_alarms=false")
    det = lake["detections"]
    fa = det["truth_id"] < 0
    assert fa.sum() > 20
    inside = point_in_polygon(det["x_m"][fa], det["y_m"][fa], DEFAULT_LAKE_POLYGON_M)
    assert np.all(inside)
    # common random numbers: the targets' reports are bit-identical with and without clutter
    # and noise false alarms
    base = default_run["detections"]
    assert np.any(base["truth_id"] < 0)           # the default run has noise false alarms
    tgt, base_tgt = ~fa, base["truth_id"] >= 0
    for col in ("truth_id", "range_m", "azimuth_rad", "range_rate_mps", "snr_db", "merged"):
        assert np.array_equal(det[col][tgt], base[col][base_tgt]), col


def test_hills_shadow_the_ridge_road_until_the_aircraft_circles_west(compose_config, tmp_path):
    hills = run(compose_config, tmp_path, "terrain=hills", "scene.duration_s=300")
    car = vehicle_ids(hills, "car-ridge")[0]
    lk = hills["looks"]
    mine = lk["vehicle_id"] == car
    t, outcome = lk["time_s"][mine], lk["outcome"][mine]
    shadowed = t[outcome == Outcome.TERRAIN]
    seen = t[outcome == Outcome.DETECTED]
    assert shadowed.size > 0 and seen.size > 0
    assert shadowed.min() < seen.min()            # hidden first, then seen
    assert np.median(seen) > np.median(shadowed)
    # roads are draped on the DEM: every road node sits on the terrain surface
    from gmtiflow.frames import Origin
    from gmtiflow.scene.terrain import build_terrain
    cfg = compose_config(["terrain=hills"])
    nodes = store.read_table(tmp_path / "run.h5", "roads/nodes")
    with store.open_run(tmp_path / "run.h5") as f:
        origin = Origin(f.attrs["origin_lat_deg"], f.attrs["origin_lon_deg"],
                        f.attrs["origin_height_m"])
    ground = build_terrain(cfg.terrain, origin).height_at(nodes["x_m"], nodes["y_m"])
    assert np.allclose(nodes["z_m"], ground) and np.any(np.abs(ground) > 0.1)


def test_a_real_osm_extract_runs_with_the_random_fleet(compose_config, tmp_path, shared_data):
    t = run(compose_config, tmp_path, "roadmap=osm", f"roadmap.path={shared_data}/bautzen.osm",
            "vehicles.random.count=20", "scene.duration_s=60")
    assert len(t["vehicles"]["vehicle_id"]) == 20
    assert len(t["detections"]["det_id"]) > 0
    with store.open_run(tmp_path / "run.h5") as f:
        assert f.attrs["attribution"] == "© OpenStreetMap contributors"
        assert abs(f.attrs["origin_lat_deg"] - 51.19) < 0.01     # centre of the <bounds>


def test_the_monaco_experiment_drapes_osm_roads_on_srtm(compose_config, tmp_path, shared_data,
                                                          monkeypatch):
    monkeypatch.setenv("GMTIFLOW_DATA_DIR", str(shared_data))
    t = run(compose_config, tmp_path, "experiment=monaco", "vehicles.random.count=30",
            "scene.duration_s=60")
    nodes = store.read_table(tmp_path / "run.h5", "roads/nodes")
    assert nodes["height_m"].max() > 150.0          # Monaco's roads climb to ~213 m (+ geoid)
    outcomes = set(np.unique(t["looks"]["outcome"]))
    assert {Outcome.TERRAIN, Outcome.INVISIBLE_ROAD} <= outcomes   # steep terrain, tunnels
