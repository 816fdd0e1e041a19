"""Figure functions on small runs: the right number of points/artists, and empty tables."""
import math

import numpy as np
import pytest
from matplotlib.collections import PathCollection, PolyCollection

from gmtiflow.report import figures as F
from gmtiflow.report.data import key_numbers, load_run, n


def _points(ax, labels):
    return sum(len(c.get_offsets()) for c in ax.collections
               if isinstance(c, PathCollection) and c.get_label() in labels)


DET_LABELS = {lab for _, _, lab in F.DET_STYLE.values()}


def _map(run, **kw):
    t = run.table
    return F.map_figure(t("roads/nodes"), t("roads/edges"), t("truth"), t("platform"), t("dwells"),
                        t("detections"), t("tracks"), run.cfg("clutter.regions", []) or [],
                        run.origin, str(run.attrs.get("attribution", "")), **kw)


def test_map_has_one_point_per_detection(small_run, clutter_run):
    for path in (small_run, clutter_run):
        run = load_run(path)
        det = run.table("detections")
        assert n(det) > 0
        fig = _map(run)
        scene = fig.axes[1]
        assert _points(scene, DET_LABELS) == n(det)
        classes = F.detection_classes(det)
        assert sum(int(m.sum()) for m in classes.values()) == n(det)
    # the lake run has false alarms, drawn as their own layer, and a clutter polygon
    false = [c for c in scene.collections if c.get_label() == "false alarm"]
    assert false and len(false[0].get_offsets()) == int(np.sum(det["truth_id"] < 0)) > 0
    assert any(str(p.get_label()) == "clutter: lake" for p in scene.patches)


def test_map_subsamples_big_layers_and_says_so(small_run):
    run = load_run(small_run)
    fig = _map(run, max_points=10)
    scene = fig.axes[1]
    assert _points(scene, {"true detection"}) == 10
    assert "every" in scene.get_title()


def test_track_lines_are_the_longest_confirmed_tracks_in_row_order():
    tid = np.array([7, 3, 7, 5, 3, 7, 9, 5, 3, 1])
    tracks = {"track_id": tid, "x_m": np.arange(10.0), "y_m": -np.arange(10.0),
              "confirmed": tid != 9}
    lines = F._track_lines(tracks, 3)
    # longest first, ties by id; each track's rows in file order (a mask per id)
    for (x, y), i in zip(lines, (3, 7, 5)):
        assert np.array_equal(x, np.flatnonzero(tid == i)) and np.array_equal(y, -x)
    assert len(lines) == 3 and len(F._track_lines(tracks, 10)) == 4   # 9 is not confirmed


def test_map_draws_tracks_footprints_and_attribution(small_run):
    run = load_run(small_run)
    fig = _map(run, max_footprints=3)
    fps = F.revisit_footprints(run.table("dwells"), run.origin, 3)
    assert len(fps) == 3
    for fp in fps:  # default sensor: slant 20-36 km from 6 km altitude
        assert fp["ground_min_m"] == pytest.approx(math.sqrt(20e3 ** 2 - 6e3 ** 2), rel=0.02)
        assert 0 < fp["az_hi"] - fp["az_lo"] < math.radians(30)
    n_tracks = len(F._track_lines(run.table("tracks"), 200))
    from matplotlib.collections import LineCollection
    tracks = [c for c in fig.axes[1].collections if isinstance(c, LineCollection)]
    assert len(tracks) == 1 and len(tracks[0].get_segments()) == n_tracks > 0
    fig = F.map_figure({}, {}, {}, {}, {}, {}, {}, [], run.origin, "© OpenStreetMap contributors")
    assert any("OpenStreetMap" in t.get_text() for t in fig.axes[1].texts)


def test_sensor_figure_histograms_count_unmerged_true_detections(small_run):
    run = load_run(small_run)
    det = run.table("detections")
    fig = F.sensor_figure(run.table("looks"), det, 1e-6)
    expected = int(np.sum((det["truth_id"] >= 0) & ~det["merged"] & ~det["range_folded"]
                          & ~det["doppler_wrapped"]))
    errors = F.normalised_errors(det)
    for ax, v in zip(fig.axes[-3:], errors.values()):
        assert len(ax.patches) == 1          # one filled step outline, not a patch per bin
        density, _ = np.histogram(np.clip(v, -5, 5), bins=np.linspace(-5, 5, 41), density=True)
        tops = ax.patches[0].get_xy()[:, 1]
        assert set(np.round(density, 9)) <= set(np.round(tops, 9))
        assert f"n={expected}" in ax.get_legend().get_texts()[0].get_text()


def test_pd_vs_snr_bins_and_swerling_curve():
    assert F.swerling1_pd(1e-6, 0.0) == pytest.approx(1e-6)
    assert np.isfinite(F.swerling1_pd(1e-12, 1e9)) and F.swerling1_pd(1e-12, 1e9) > 0.99999
    looks = {"outcome": np.array([0, 5, 0, 0, 1, 4, 6], np.uint8),
             "snr_db": np.array([10.2, 10.7, 20.1, 20.4, np.nan, 10.5, 20.9]),
             "pd": np.array([0.5, 0.5, 0.9, 0.9, 0.0, 0.5, 0.9])}
    centres, pd, count, model = F.pd_vs_snr(looks, 1.0)
    assert list(centres) == [10.5, 20.5]
    assert list(count) == [3, 3]                       # the outside-FoV look is not drawn
    assert pd == pytest.approx([1 / 3, 1.0])           # merged counts as detected
    assert model == pytest.approx([0.5, 0.9])


def test_timeline_rows_and_outcome_counts(small_run):
    run = load_run(small_run)
    looks = run.table("looks")
    fig = F.timeline_figure(run.table("vehicles"), run.table("truth"), looks)
    ax, bars = fig.axes[0], fig.axes[1]
    assert len(ax.get_yticks()) == n(run.table("vehicles"))
    markers = sum(len(c.get_offsets()) for c in ax.collections if isinstance(c, PathCollection))
    assert markers == n(looks)
    (stack,) = [c for c in bars.collections if isinstance(c, PolyCollection)]
    widths = sum(np.ptp(p.vertices[:, 0]) for p in stack.get_paths())
    assert widths == n(looks)                # one bar segment per vehicle and outcome
    fig = F.timeline_figure(run.table("vehicles"), run.table("truth"), looks, max_vehicles=2)
    assert len(fig.axes[0].get_yticks()) == 2
    assert "first 2 of" in fig._suptitle.get_text()


def test_track_errors_bands_are_the_per_bin_percentiles(small_run):
    from gmtiflow.report.pages import track_errors as TE
    run = load_run(small_run)
    te = run.table("metrics/track_errors")
    assert n(te) > 0
    t, v = np.asarray(te["time_s"], float), np.asarray(te["position_error_m"], float)
    edges = TE.time_bins(t)
    q = TE.binned_percentiles(t, v, edges)
    b = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, len(edges) - 2)
    for k in np.unique(b)[:10]:     # numpy's percentiles of the rows in that bin
        vals = v[(b == k) & np.isfinite(v)]
        if len(vals):
            assert q[:, k] == pytest.approx(np.percentile(vals, [5, 25, 50, 75, 95]))
    fig = F.track_errors_figure(te)
    worst = TE.worst_tracks(np.asarray(te["track_id"]), v)
    labels = [ln.get_label() for ln in fig.axes[0].lines]
    assert "median" in labels and all(f"track {int(i)}" in labels for i in worst)
    rms = {i: np.sqrt(np.nanmean(v[te["track_id"] == i] ** 2)) for i in np.unique(te["track_id"])}
    eligible = {i: r for i, r in rms.items() if np.sum(te["track_id"] == i) >= 3} or rms
    assert rms[worst[0]] == pytest.approx(max(eligible.values()))   # fewer rows: any track
    # tracker off: one note, no empty axes
    fig = F.track_errors_figure({}, tracker_enabled=False)
    assert fig.axes == [] and any("tracker off" in t.get_text() for t in fig.texts)


def test_range_rate_figure_points(small_run):
    run = load_run(small_run)
    looks, det = run.table("looks"), run.table("detections")
    fig = F.range_rate_figure(looks, det, run.table("dwells"))
    left, right = fig.axes
    drawn = int(np.isin(looks["outcome"], [0, 4, 5, 6]).sum())
    assert sum(len(c.get_offsets()) for c in left.collections if isinstance(c, PathCollection)) == drawn
    assert _points(right, {f"{lab} ({k})" for lab in DET_LABELS for k in range(n(det) + 1)}) == n(det)


def test_ospa_figure_series(small_run):
    run = load_run(small_run)
    ospa = run.table("metrics/ospa")
    fig = F.ospa_figure(ospa, run.table("metrics/identity_switches"), run.table("metrics/events"),
                        cutoff_m=100.0)
    assert len(fig.axes[0].lines[0].get_xdata()) == n(ospa)
    assert "OSPA (c = 100 m)" in [t.get_text() for t in fig.axes[0].get_legend().get_texts()]


def test_every_figure_copes_with_empty_tables():
    from gmtiflow.frames import Origin
    e = {}
    figs = [F.title_figure({}, {}, {}, {}, "x"),
            F.map_figure(e, e, e, e, e, e, e, [], Origin(0, 0), ""),
            F.sensor_figure(e, e, 1e-6), F.range_rate_figure(e, e, e),
            F.timeline_figure(e, e, e), F.track_errors_figure(e, tracker_enabled=False),
            F.ospa_figure(e, e, e)]
    for fig in figs:
        fig.canvas.draw()


def test_key_numbers(small_run, empty_run):
    k = key_numbers(load_run(small_run))
    assert k["detections"] > 0 and 0 < k["pd_achieved"] <= 1
    assert abs(k["pd_achieved"] - k["pd_model_mean"]) < 0.25
    k = key_numbers(load_run(empty_run))
    assert k["detections"] == 0 and k["tracks"] == 0


def test_physics_page_shows_false_alarms_against_their_expectation(small_run):
    """The run's false-alarm count next to the detector's P_FA x cells x dwells."""
    from gmtiflow.report.run_report import _expected_false_alarms
    from gmtiflow.sensor.config import SensorConfig
    run = load_run(small_run)
    expected = _expected_false_alarms(run)
    sensor = SensorConfig(pfa=float(run.cfg("sensor.pfa")))
    assert expected == pytest.approx(sensor.expected_false_alarms_per_dwell
                                     * n(run.table("dwells")))
    det = run.table("detections")
    fig = F.sensor_figure(run.table("looks"), det, float(run.cfg("sensor.pfa")),
                          expected_false_alarms=expected)
    text = " ".join(t.get_text() for t in fig.texts)
    n_fa = int(np.sum(det["truth_id"] < 0))
    assert f"False alarms: {n_fa} in the run" in text and f"{expected:.4g}" in text


def test_title_page_shows_the_command_line_references_and_how_to_read(small_run, tmp_path):
    import shutil

    from gmtiflow.report.config import ReportConfig
    from gmtiflow.report.run_report import run_figures
    run_dir = tmp_path / "job"
    (run_dir / ".hydra").mkdir(parents=True)
    shutil.copy(small_run, run_dir / "run.h5")
    (run_dir / ".hydra" / "overrides.yaml").write_text("- scene.duration_s=30\n- seed=7\n")
    pages = dict(run_figures(load_run(run_dir / "run.h5"), ReportConfig()))
    texts = " ".join(t.get_text() for t in pages["title"]().texts)
    assert "gmtiflow scene.duration_s=30 seed=7" in texts
    assert "0 = perfect; c = 200 m" in texts                 # OSPA against its cut-off
    assert "one report's σ: range" in texts                  # position RMSE against σ
    assert "How to read this report" in texts and "Units:" in texts
    (run_dir / ".hydra" / "overrides.yaml").unlink()        # a run made from Python
    texts = " ".join(t.get_text() for t in pages["title"]().texts)
    assert "not recorded" in texts


def test_footprints_and_platform_tracks_of_two_sensors_are_never_mixed(tmp_path):
    from gmtiflow.report.pages.map import revisit_footprints

    from .conftest import make_run
    run = load_run(make_run(tmp_path, ["experiment=two_orbits", "scene.duration_s=20",
                                       "report.enabled=false", "export=none", "tracker=none"]))
    dwells = run.table("dwells")
    fps = revisit_footprints(dwells, run.origin, 12)
    sensor_of_x = dict(zip(np.asarray(dwells["platform_x_m"]).tolist(),
                           np.asarray(dwells["sensor_id"]).tolist()))
    assert {sensor_of_x[fp["x"]] for fp in fps} == {0, 1}     # both aircraft, each its own
    for fp in fps:      # one sensor's scan: within its ±45° field of view plus a beam
        assert fp["az_hi"] - fp["az_lo"] < math.radians(90 + 10)
    assert [fp["time_s"] for fp in fps] == sorted(fp["time_s"] for fp in fps)
    fig = F.map_figure(run.table("roads/nodes"), run.table("roads/edges"), run.table("truth"),
                       run.table("platform"), dwells, run.table("detections"), {}, [],
                       run.origin)
    tracks = [ln for ln in fig.axes[0].lines if str(ln.get_color()) == "k" and len(ln.get_xdata()) > 1]
    assert len(tracks) == 2                                   # one line per aircraft
    for ln in tracks:                                         # no jump between the aircraft
        assert np.max(np.hypot(np.diff(ln.get_xdata()), np.diff(ln.get_ydata()))) < 1.0  # km


@pytest.fixture(scope="module")
def two_sensor_run(tmp_path_factory):
    """Two sensors (experiment=two_orbits) with different MDVs, 20 s, no tracker."""
    from .conftest import make_run
    return load_run(make_run(tmp_path_factory.mktemp("two"), [
        "experiment=two_orbits", "scene.duration_s=20", "tracker=none",
        "sensors.west.sensor.mdv_mps=5.0"]))


def test_range_rate_page_draws_each_sensor_with_its_own_notch_and_points(two_sensor_run):
    """Two sensors with different MDVs: one row per sensor, each row holding that sensor's
    looks and reports only and a notch band as wide as its own MDV (the old page drew both
    sensors' points in one pair of panels around the median MDV)."""
    run = two_sensor_run
    looks, det, dwells = run.table("looks"), run.table("detections"), run.table("dwells")
    fig = F.range_rate_figure(looks, det, dwells)
    assert len(fig.axes) == 4
    sensor_of_dwell = dict(zip(np.asarray(dwells["dwell_id"]).tolist(),
                               np.asarray(dwells["sensor_id"]).tolist()))
    for sid, (left, right) in enumerate(zip(fig.axes[0::2], fig.axes[1::2])):
        mine = np.array([sensor_of_dwell[d] == sid for d in np.asarray(looks["dwell_id"]).tolist()])
        drawn = int(np.isin(np.asarray(looks["outcome"])[mine], [0, 4, 5, 6]).sum())
        assert drawn > 0
        assert sum(len(c.get_offsets()) for c in left.collections
                   if isinstance(c, PathCollection)) == drawn
        det_mine = int(sum(sensor_of_dwell[d] == sid for d in np.asarray(det["dwell_id"]).tolist()))
        assert _points(right, {f"{lab} ({k})" for lab in DET_LABELS
                               for k in range(n(det) + 1)}) == det_mine
        mdv = 2.0 if sid == 0 else 5.0
        band = next(c for c in right.collections if isinstance(c, PolyCollection))
        y = band.get_paths()[0].vertices[:, 1]
        notch = right.lines[0].get_ydata()
        assert np.isclose(np.max(y[: len(notch)] - notch), mdv) or \
            np.isclose((y.max() - y.min()) - (notch.max() - notch.min()), 2 * mdv)
        assert f"MDV {mdv:g} m/s" in right.get_title()


def test_timeline_gives_each_sensor_its_own_lane_and_counts(two_sensor_run):
    """Two sensors: each vehicle row has one lane per sensor (sensor 0 above), holding that
    sensor's looks, and one stacked bar per sensor counting them (the old page mixed them)."""
    run = two_sensor_run
    looks = run.table("looks")
    fig = F.timeline_figure(run.table("vehicles"), run.table("truth"), looks)
    ax, bx = fig.axes
    ys = np.concatenate([c.get_offsets()[:, 1] for c in ax.collections
                         if isinstance(c, PathCollection)])
    lane = np.round(ys - np.round(ys), 6)
    sid = np.asarray(looks["sensor_id"])
    assert len(ys) == n(looks)
    assert sorted(set(lane.tolist())) == [-0.175, 0.175]
    assert np.sum(lane < 0) == np.sum(sid == 0) and np.sum(lane > 0) == np.sum(sid == 1)
    bars = next(c for c in bx.collections if isinstance(c, PolyCollection)).get_paths()
    width = np.array([p.vertices[:, 0].max() - p.vertices[:, 0].min() for p in bars])
    top = np.array([p.vertices[:, 1].min() for p in bars])
    frac = np.round(top - np.round(top), 6)
    assert width[frac == -0.35].sum() == np.sum(sid == 0)      # sensor 0's lane: its looks
    assert width[frac == 0.0].sum() == np.sum(sid == 1)
