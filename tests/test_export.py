"""The export stage: files beside run.h5, the adaptations (D32.7, frames, unlocated reports, meta),
the presets, and atomicity (a failing export leaves nothing behind)."""
import os
import shutil
import stat
import subprocess
import sys

import h5py
import numpy as np
import pytest

from gmtiflow import formats
from gmtiflow import export_tables, frames, pipeline, store
from gmtiflow.export import ExportConfig, export_run
from tests.conftest import compose_app

OVERRIDES = ["scene.duration_s=30", "fidelity.truth_output_dt_s=1.0", "progress=false"]
FOUR = {"detections.4607", "detections.xml", "detections.csv", "dwells.csv", "scene.geojson",
        "truth.geojson"}


@pytest.fixture(scope="module")
def lake_run(tmp_path_factory):
    """A short default scene with the lake's clutter (false alarms and a clutter region)."""
    cfg = compose_app(OVERRIDES + ["clutter=lake"])
    return cfg, pipeline.run(cfg, tmp_path_factory.mktemp("lake"))


def _copy(run, tmp_path):
    dest = tmp_path / "run.h5"
    shutil.copy(run, dest)
    return dest


def test_config_presets_compose():
    assert compose_app(OVERRIDES).export.formats == ["stanag4607", "xml", "csv", "geojson"]
    assert compose_app(OVERRIDES + ["export=none"]).export.formats == []
    assert compose_app(OVERRIDES + ["export=stanag4607"]).export.formats == ["stanag4607"]
    cfg = compose_app(OVERRIDES + ["export.edition=41", "export.platform_id=TAIL42"])
    assert cfg.export.edition == "41" and cfg.export.platform_id == "TAIL42"


@pytest.mark.parametrize("override, key", [
    ("export.formats=[stanag4607,kml]", "export.formats"),
    ("export.edition=31", "export.edition"),
    ("export.platform_id=ELEVENCHARS", "export.platform_id"),
    ("export.job_id=0", "export.job_id"),
    ("export.pd=1.5", "export.pd"),
])
def test_bad_export_config_names_the_key(override, key):
    from gmtiflow.errors import ConfigError
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        compose_app(OVERRIDES + [override])


def test_default_export_writes_every_file_beside_the_run(lake_run, tmp_path):
    cfg, run = lake_run
    path = _copy(run, tmp_path)
    written = export_run(cfg.export, path)       # the call the runner makes after a run
    names = {p.name for p in written}
    assert FOUR <= names and "tracks.csv" in names and "truth.csv" not in names   # opt-in
    assert all(p.parent == tmp_path for p in written)
    assert not [p for p in tmp_path.iterdir() if "part" in p.name]   # no temporary files left
    mode = stat.S_IMODE(os.stat(tmp_path / "detections.4607").st_mode)
    umask = os.umask(0)
    os.umask(umask)
    assert mode == 0o666 & ~umask
    formats.validate_xml(tmp_path / "detections.xml")


def test_none_preset_writes_nothing_and_stanag_only_one_file(lake_run, tmp_path):
    _, run = lake_run
    path = _copy(run, tmp_path)
    assert export_run(compose_app(OVERRIDES + ["export=none"]).export, path) == []
    written = export_run(compose_app(OVERRIDES + ["export=stanag4607"]).export, path)
    assert [p.name for p in written] == ["detections.4607"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["detections.4607", "run.h5"]


def test_d32_7_is_the_los_velocity_corrected_for_platform_motion(lake_run, tmp_path):
    cfg, run = lake_run
    path = _copy(run, tmp_path)
    export_run(ExportConfig(formats=["stanag4607"]), path)
    got = formats.read_4607(tmp_path / "detections.4607")
    det = store.read_table(run, "detections")
    dwells = store.read_table(run, "dwells")
    ground = export_tables.ground_range_rate_scene(dwells, det)
    own = det["range_rate_mps"] - ground
    assert len(own) == len(got["detections"]["los_velocity_mps"]) > 10
    assert np.allclose(got["detections"]["los_velocity_mps"], own, atol=0.005 + 1e-9)
    # Physics, independently of export's code: for target reports the corrected LOS velocity
    # is the vehicle's own radial speed v_t . l (up to the measurement noise).
    truth = store.read_table(run, "truth")
    k = np.flatnonzero((det["truth_id"] >= 0) & ~det["merged"])
    assert len(k) > 5
    for i in k:
        rows = np.flatnonzero(truth["vehicle_id"] == det["truth_id"][i])
        j = rows[np.argmin(np.abs(truth["time_s"][rows] - det["time_s"][i]))]
        d = dwells["dwell_id"] == det["dwell_id"][i]
        los = np.array([det["x_m"][i] - dwells["platform_x_m"][d][0],
                        det["y_m"][i] - dwells["platform_y_m"][d][0],
                        det["z_m"][i] - dwells["platform_z_m"][d][0]])
        los /= np.linalg.norm(los)
        vt = np.array([truth["vx_mps"][j], truth["vy_mps"][j], truth["vz_mps"][j]])
        tol = 5 * det["sigma_range_rate_mps"][i] + 1.0   # noise + truth sampled at 1 s
        assert abs(got["detections"]["los_velocity_mps"][i] - vt @ los) < tol
    # one meaning per name: the reader names D32.7 los_velocity_mps and never range_rate_mps
    assert "range_rate_mps" not in got["detections"]
    # ... and reading it back gives the full range rate again.
    back = export_tables.from_4607_tables(got)
    assert np.allclose(back["detections"]["range_rate_mps"], det["range_rate_mps"], atol=0.05)
    assert np.allclose(back["detections"]["los_velocity_mps"],
                       got["detections"]["los_velocity_mps"])


def test_platform_velocity_is_sent_relative_to_north_at_the_sensor(lake_run, tmp_path):
    _, run = lake_run
    path = _copy(run, tmp_path)
    export_run(ExportConfig(formats=["stanag4607"]), path)
    got = formats.read_4607(tmp_path / "detections.4607")["dwells"]
    dw = store.read_table(run, "dwells")
    with h5py.File(run) as f:
        origin = frames.Origin(f.attrs["origin_lat_deg"], f.attrs["origin_lon_deg"],
                               f.attrs["origin_height_m"])
    # a point 1 s ahead of the platform along its velocity, seen from the sensor's local ENU
    ahead = frames.enu_to_geodetic(origin, dw["platform_x_m"] + dw["platform_vx_mps"],
                                   dw["platform_y_m"] + dw["platform_vy_mps"],
                                   dw["platform_z_m"] + dw["platform_vz_mps"])
    import pymap3d
    e, n, _ = pymap3d.geodetic2enu(*ahead, dw["platform_lat_deg"], dw["platform_lon_deg"],
                                   dw["platform_height_m"])
    track = frames.heading_rad(e, n)
    err = np.abs(frames.wrap_pi(got["sensor_track_rad"] - track))
    assert err.max() < np.radians(0.01)          # BA16 quantum 0.0055 deg
    # the scene-frame heading differs from it by the meridian convergence (not zero here)
    assert np.abs(frames.wrap_pi(frames.heading_rad(dw["platform_vx_mps"], dw["platform_vy_mps"])
                                 - track)).max() > np.radians(0.02)


def test_meta_comes_from_the_run_and_the_config(lake_run, tmp_path):
    cfg, run = lake_run
    path = _copy(run, tmp_path)
    ecfg = ExportConfig(formats=["stanag4607", "xml"], edition="41", platform_id="TAIL42",
                        mission_plan="EXERCISE-7", platform_location_packets=True, pd=0.9)
    export_run(ecfg, path)
    got = formats.read_4607(tmp_path / "detections.4607")
    assert set(got["packets"]["version"]) == {"41"}
    assert set(got["packets"]["platform_id"]) == {"TAIL42"}
    assert set(got["missions"]["mission_plan"]) == {"EXERCISE-7"}
    assert got["missions"]["reference_date"][0] == "2026-06-01"
    assert got["attrs"]["scene_epoch_utc"].startswith("2026-06-01T08:00:00")
    jobs = got["jobs"]
    assert np.all(jobs["revisit_interval_s"] == cfg.sensor.revisit_s)
    assert np.allclose(jobs["mdv_mps"], cfg.sensor.mdv_mps)
    assert np.allclose(jobs["pd"], 0.9)
    assert np.all(np.isfinite(jobs["sigma_slant_range_m"]))
    assert len(got["platform_locations"]["time_s"]) == len(store.read_table(run, "platform")["time_s"])
    xml = formats.read_xml(tmp_path / "detections.xml")
    assert xml["meta"]["platform_id"] == "TAIL42" and xml["meta"]["pd"] == 0.9


def test_unlocated_reports_are_skipped_in_4607_and_geojson_kept_elsewhere(lake_run, tmp_path):
    _, run = lake_run
    path = _copy(run, tmp_path)
    with h5py.File(path, "r+") as f:           # an unlocated (e.g. folded) report
        for c in ("lat_deg", "lon_deg", "height_m", "x_m", "y_m", "z_m"):
            f["detections"][c][0] = np.nan
        f["detections"]["implausible"][0] = True
    n = len(store.read_table(path, "detections")["det_id"])
    export_run(ExportConfig(), path)
    assert len(formats.read_4607(tmp_path / "detections.4607")["detections"]["det_id"]) == n - 1
    assert len(formats.read_geojson(tmp_path / "scene.geojson")["detections"]["det_id"]) == n - 1
    csv = formats.read_detections_csv(tmp_path / "detections.csv")
    assert len(csv["det_id"]) == n and np.isnan(csv["lat_deg"][csv["det_id"] == 0]).all()
    assert len(formats.read_xml(tmp_path / "detections.xml")["detections"]["det_id"]) == n


def test_geojson_has_geodetic_truth_roads_and_the_clutter_region(lake_run, tmp_path):
    _, run = lake_run
    path = _copy(run, tmp_path)
    export_run(ExportConfig(formats=["geojson"], geojson_truth_step_s=0.0), path)
    g = formats.read_geojson(tmp_path / "scene.geojson")
    assert len(g["truth"]) == 0                    # truth is a file of its own
    g["truth"] = formats.read_geojson(tmp_path / "truth.geojson")["truth"]
    truth = store.read_table(run, "truth")
    with h5py.File(run) as f:
        origin = frames.Origin(f.attrs["origin_lat_deg"], f.attrs["origin_lon_deg"],
                               f.attrs["origin_height_m"])
    lat, lon, h = frames.enu_to_geodetic(origin, truth["x_m"], truth["y_m"], truth["z_m"])
    order = np.lexsort((truth["vehicle_id"], truth["time_s"]))
    assert np.array_equal(g["truth"]["lat_deg"], lat[order])
    assert np.array_equal(g["truth"]["lon_deg"], lon[order])
    assert np.array_equal(g["truth"]["x_m"], truth["x_m"][order])
    nodes = store.read_table(run, "roads/nodes")
    assert len(g["road_nodes"]["node_id"]) == len(nodes["node_id"])
    assert len(g["road_edges"]["edge_id"]) == len(store.read_table(run, "roads/edges")["edge_id"])
    [lake] = g["clutter_regions"]
    assert lake["name"] == "lake" and len(lake["lat_deg"]) == 5
    x, y, _ = frames.geodetic_to_enu(origin, lake["lat_deg"], lake["lon_deg"], 0.0)
    assert {(round(a), round(b)) for a, b in zip(x, y)} == {
        (1500, 1500), (3500, 1200), (4200, 2500), (3000, 3500), (1600, 3000)}


def test_a_failing_export_leaves_no_file(lake_run, tmp_path, monkeypatch):
    _, run = lake_run
    path = _copy(run, tmp_path)

    def boom(*args, **kwargs):
        raise ValueError("disk on fire")
    monkeypatch.setattr(formats, "write_geojson", boom)
    with pytest.raises(ValueError, match="disk on fire"):
        export_run(ExportConfig(), path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


def test_an_incomplete_run_file_is_a_clear_error(lake_run, tmp_path):
    _, run = lake_run
    path = _copy(run, tmp_path)
    with h5py.File(path, "r+") as f:
        f.attrs["complete"] = False
    with pytest.raises(store.StoreError, match="incomplete"):
        export_run(ExportConfig(), path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


def test_the_pipeline_has_an_export_stage_after_the_run_file():
    names = [st.name for st in pipeline.stages(compose_app(OVERRIDES))]
    assert names.index("export") == names.index("store") + 1


@pytest.mark.slow
def test_default_cli_run_leaves_the_four_files_beside_run_h5(tmp_path):
    env = dict(os.environ, HYDRA_FULL_ERROR="0")
    proc = subprocess.run([sys.executable, "-m", "gmtiflow.cli", f"hydra.run.dir={tmp_path}",
                           "scene.duration_s=20", "progress=false"], cwd=tmp_path,
                          capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert FOUR | {"run.h5", "tracks.csv", "tracks.geojson"} <= {p.name for p in tmp_path.iterdir()}


def test_geojson_truth_is_thinned_to_its_step_with_each_vehicles_ends():
    from gmtiflow.export import thin_truth
    t = np.r_[np.arange(0.0, 21.0), np.arange(3.0, 13.0)]          # vehicle 1 starts at 3 s
    v = np.r_[np.zeros(21, int), np.ones(10, int)]
    thin = thin_truth({"time_s": t, "vehicle_id": v, "x_m": t * 2}, 5.0)
    got = sorted(zip(thin["vehicle_id"].tolist(), thin["time_s"].tolist()))
    assert got == [(0, 0.0), (0, 5.0), (0, 10.0), (0, 15.0), (0, 20.0),
                   (1, 3.0), (1, 5.0), (1, 10.0), (1, 12.0)]
    assert np.array_equal(thin["x_m"], thin["time_s"] * 2)
    assert thin_truth({"time_s": t, "vehicle_id": v}, 0.0)["time_s"] is t


def test_every_export_is_read_by_gdal_tshark_and_as_a_road_map(lake_run, tmp_path):
    """The external readers: GDAL (pyogrio) opens every GeoJSON with one type per field, tshark
    finds no expert error in the 4607, and scene.geojson read back as a road map has the run's
    roads and nothing else (no truth lines)."""
    import shutil
    from gmtiflow.scene.geojson_roads import load_geojson
    from gmtiflow.errors import GmtiflowError
    _, run = lake_run
    path = _copy(run, tmp_path)
    written = export_run(ExportConfig(), path)
    names = {p.name for p in written}
    assert {"scene.geojson", "truth.geojson", "dwells.csv"} <= names
    pyogrio_raw = pytest.importorskip("pyogrio.raw")
    for name in ("scene.geojson", "truth.geojson"):
        meta, _, _, data = pyogrio_raw.read(str(tmp_path / name))
        assert len(data[0]) > 0
        assert "OFTString" not in [t for f, t in zip(meta["fields"], meta["ogr_types"])
                                   if f not in ("kind", "name", "shape", "road_class", "time_utc")]
    edges = store.read_table(run, "roads/edges")
    roads = load_geojson(tmp_path / "scene.geojson")
    assert 0 < len(roads.edges["edge_id"]) <= 2 * len(edges["edge_id"])
    with pytest.raises(GmtiflowError):
        load_geojson(tmp_path / "truth.geojson")      # trajectories are not roads
    dw = formats.read_csv(tmp_path / "dwells.csv", "dwells")
    ref = store.read_table(run, "dwells")
    assert dw["dwell_id"].tolist() == sorted(ref["dwell_id"].tolist())
    assert np.array_equal(np.sort(dw["platform_x_m"]), np.sort(ref["platform_x_m"]))
    if shutil.which("tshark") is None:
        pytest.skip("tshark is not installed (CI installs it)")
    out = subprocess.run(["tshark", "-r", str(tmp_path / "detections.4607"), "-q", "-z", "expert"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "Errors" not in out.stdout, out.stdout


def test_4607_job_of_each_sensor_states_its_own_revisit_interval(tmp_path):
    """Two sensors configured with different revisit intervals: each platform's J15 is its own
    sensor's (it was the first sensor's ``sensor.revisit_s`` for both), and the XML's one
    JobDefinition is the median over both sensors' revisits."""
    cfg = compose_app(["experiment=two_orbits", "sensors.west.sensor.revisit_s=4.0",
                       "scene.duration_s=20", "vehicles=random", "vehicles.random.count=4",
                       "progress=false", "export=none", "report.enabled=false", "tracker=none",
                       "metrics.enabled=false", "cache.enabled=false"])
    run = pipeline.run(cfg, tmp_path)
    written = export_run(ExportConfig(formats=["stanag4607", "xml"]), run)
    jobs = formats.read_4607(tmp_path / "detections.4607")["jobs"]
    got = {int(j): float(r) for j, r in zip(jobs["job_id"], jobs["revisit_interval_s"])}
    assert got == {1: 8.0, 2: 4.0}
    assert len(written) == 2
    xml = formats.read_xml(tmp_path / "detections.xml")["meta"]["revisit_interval_s"]
    assert 4.0 <= xml <= 8.0


def test_blind_exports_do_not_order_reports_by_truth(tmp_path):
    """run.h5 numbers a dwell's reports target by target (in vehicle id order), then its false
    alarms; a blind export carrying that order (det_id, CSV rows, XML and 4607 report order)
    would tell a tracker under test which reports are false alarms and which vehicle is which.
    Blind exports number each dwell's reports by measured slant range instead (det_id values
    are those of the dwell, reassigned), in every format."""
    cfg = compose_app(OVERRIDES + ["clutter=urban", "scene.duration_s=60"])
    run = pipeline.run(cfg, tmp_path / "run")
    ref = store.read_table(run, "detections")
    # the premise: in run.h5, false alarms come last in each dwell that has both
    fa_last = [np.all(np.diff((ref["truth_id"][ref["dwell_id"] == d] < 0).astype(int)) >= 0)
               for d in np.unique(ref["dwell_id"])]
    assert all(fa_last)
    out = tmp_path / "blind"
    out.mkdir()
    export_run(ExportConfig(blind=True), run, out)
    csv = formats.read_csv(out / "detections.csv", "detections")
    assert sorted(csv["det_id"].tolist()) == sorted(ref["det_id"].tolist())
    both = 0
    for d in np.unique(ref["dwell_id"]):
        mine = np.flatnonzero(csv["dwell_id"] == d)
        mine = mine[np.argsort(csv["det_id"][mine])]
        assert np.all(np.diff(csv["range_m"][mine]) >= 0), d           # by range
        assert sorted(csv["det_id"][mine].tolist()) == sorted(
            ref["det_id"][ref["dwell_id"] == d].tolist())                # the dwell's ids
        fa = ref["truth_id"][ref["dwell_id"] == d] < 0
        if fa.any() and (~fa).any():
            # the truth of each written report, found by its (dwell, range) in run.h5
            key = {r: t for r, t in zip(ref["range_m"][ref["dwell_id"] == d],
                                        ref["truth_id"][ref["dwell_id"] == d])}
            written_fa = np.array([key[r] < 0 for r in csv["range_m"][mine]])
            both += not np.all(np.diff(written_fa.astype(int)) >= 0)
    assert both > 0        # some dwell now lists a false alarm before a target
    xml = formats.read_xml(out / "detections.xml")["detections"]
    assert xml["det_id"].tolist() == csv["det_id"][np.lexsort(
        (csv["det_id"], csv["time_s"]))].tolist()
    x = formats.read_4607(out / "detections.4607")["detections"]
    order = np.argsort(csv["det_id"], kind="stable")
    located = np.isfinite(csv["lat_deg"][order])
    np.testing.assert_allclose(x["lat_deg"], csv["lat_deg"][order][located], atol=1e-7)


def test_4607_job_of_each_sensor_states_its_own_nominal_accuracies(tmp_path):
    """J21-J23 are the medians of each sensor's own reports: a second sensor with a fifth of
    the bandwidth (5x the range σ) was announced with the pooled median, ~the first sensor's.
    The XML's one JobDefinition keeps the median over all reports."""
    cfg = compose_app(["experiment=two_orbits", "sensors.west.sensor.bandwidth_hz=10e6",
                       "scene.duration_s=20", "progress=false", "export=none",
                       "report.enabled=false", "tracker=none", "metrics.enabled=false",
                       "cache.enabled=false"])
    run = pipeline.run(cfg, tmp_path)
    export_run(ExportConfig(formats=["stanag4607", "xml"]), run)
    det = store.read_table(run, "detections")
    jobs = formats.read_4607(tmp_path / "detections.4607")["jobs"]
    for s in (0, 1):
        mine = det["sensor_id"] == s
        rows = jobs["job_id"] == 1 + s
        assert np.all(np.abs(jobs["sigma_slant_range_m"][rows]
                             - np.median(det["sigma_range_m"][mine])) <= 0.005)
        assert np.all(np.abs(jobs["sigma_range_rate_mps"][rows]
                             - np.median(det["sigma_range_rate_mps"][mine])) <= 0.005)
    assert np.median(det["sigma_range_m"][det["sensor_id"] == 1]) > \
        3 * np.median(det["sigma_range_m"][det["sensor_id"] == 0])
    xml = formats.read_xml(tmp_path / "detections.xml")["meta"]
    assert xml["nominal_slant_range_sigma_m"] == float(np.median(det["sigma_range_m"]))
