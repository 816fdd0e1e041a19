"""The scene viewer: its content from the run file, and a real browser (headless Chromium)
loading it offline with no errors, drawing a map that changes when the slider moves."""
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from gmtiflow.report import viewer as V
from gmtiflow.report.data import load_run

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def _figure_json(html: str) -> dict:
    """The data and frames plotly.newPlot receives (the figure JSON in the HTML)."""
    m = re.search(r"Plotly\.newPlot\(\s*\"[^\"]+\",\s*(\[.*?\]),\s*(\{.*?\}),\s*\{", html, re.S)
    assert m, "no Plotly.newPlot call"
    return json.loads(m.group(1))


def test_detection_kinds_partition_and_ellipses():
    det = {"truth_id": np.array([3, -1, 4, 5, -1]), "merged": np.array([0, 0, 1, 0, 0], bool),
           "range_folded": np.array([0, 0, 0, 1, 0], bool),
           "doppler_wrapped": np.array([0, 0, 0, 0, 1], bool)}
    k = V.detection_kinds(det)
    assert [np.flatnonzero(k[x]).tolist() for x in ("target", "false", "merged", "folded")] == \
        [[0], [1], [2], [3, 4]]
    # a 2σ ellipse of diag(9, 4) about (10, 20) has semi-axes 6 and 4 along x and y
    ex, ey = V.covariance_ellipses([10.0], [20.0], [9.0], [0.0], [4.0], points=25)
    ok = np.isfinite(ex)
    assert np.max(ex[ok]) == pytest.approx(16.0) and np.min(ex[ok]) == pytest.approx(4.0)
    assert np.max(ey[ok]) == pytest.approx(24.0, abs=0.05)
    # rotated: covariance with correlation keeps the same area-scaled extents (eigenvalues)
    ex, ey = V.covariance_ellipses([0.0], [0.0], [5.0], [4.0], [5.0], points=721)
    r = np.hypot(ex[np.isfinite(ex)], ey[np.isfinite(ey)])
    assert r.max() == pytest.approx(2 * 3.0, rel=1e-3) and r.min() == pytest.approx(2 * 1.0, rel=1e-3)


def test_viewer_file_holds_every_layer_offline(small_run, tmp_path):
    out = V.build_viewer(small_run, tmp_path / "viewer.html", max_frames=20)
    html = out.read_text()
    assert not re.search(r"<script[^>]*\ssrc=", html)                      # offline: JS inline
    assert len(html) > 1_000_000                                           # plotly.js embedded
    data = _figure_json(html)
    names = [t.get("name") for t in data]
    for want in ("road", "tunnel (invisible road)", "beam footprint", "platform", "truth vehicle",
                 "truth trail", "detection: target", "track (confirmed)", "track 2σ ellipse"):
        assert want in names, (want, names)
    run = load_run(small_run)
    frames = len(re.findall(r'"name":"\d+"', html))
    assert frames == min(20, len(np.unique(run.table("dwells")["revisit_id"])))
    assert "look: " in html and ("missed:" in html or "outside the beam" in html)


def test_gmtiflow_view_command(small_run, tmp_path):
    assert V.main([str(small_run.parent), "-o", str(tmp_path / "v.html"), "--max-frames", "3"]) == 0
    assert (tmp_path / "v.html").stat().st_size > 0
    assert V.main([str(tmp_path / "missing"), "-o", str(tmp_path / "w.html")]) == 1
    assert not (tmp_path / "w.html").exists()


def _chromium(args, profile):
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={profile}", "--hide-scrollbars", "--window-size=1300,900",
           "--virtual-time-budget=10000", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=240)


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed (Debian package chromium)")
def test_browser_loads_viewer_without_errors_and_slider_changes_the_map(small_run, tmp_path):
    import matplotlib.image as mpimg
    out = V.build_viewer(small_run, tmp_path / "viewer.html", max_frames=30)
    last = len(re.findall(r'"name":"\d+"', out.read_text())) - 1
    assert last >= 3
    url = out.resolve().as_uri()
    dom = _chromium(["--dump-dom", url + f"#frame={last}"], tmp_path / "p0")
    body = re.search(r"<body[^>]*>", dom.stdout).group(0)
    assert f'data-frame-shown="{last}"' in body, body   # the slider moved to the last frame
    assert 'data-errors="[]"' in body, body             # no uncaught error in the page
    assert "Uncaught" not in dom.stderr, dom.stderr[-2000:]
    shots = []
    for i, frag in enumerate(("", f"#frame={last}")):
        png = tmp_path / f"shot{i}.png"
        proc = _chromium([f"--screenshot={png}", url + frag], tmp_path / f"p{i + 1}")
        assert png.is_file(), proc.stderr[-2000:]
        shots.append(mpimg.imread(png)[..., :3])
    first, moved = shots
    assert np.std(moved) > 0.02                          # not blank
    changed = np.mean(np.any(np.abs(first - moved) > 0.1, axis=-1))
    assert changed > 0.001, changed                      # the map changed with the slider


def test_frames_follow_the_first_sensor_and_take_every_sensor_dwell():
    # sensor 0 revisits end at 4 s and 8 s; sensor 1's dwells fall into the frame that ends next
    dwells = {"revisit_id": np.array([0, 0, 1, 1, 0, 0, 1]),
              "sensor_id": np.array([0, 0, 0, 0, 1, 1, 1]),
              "time_s": np.array([1.0, 4.0, 5.0, 8.0, 2.0, 4.5, 7.0]), "dwell_id": np.arange(7)}
    assert V.frame_of_dwells(dwells).tolist() == [0, 0, 1, 1, 0, 1, 1]
    one = {k: v[:4] for k, v in dwells.items()}
    assert V.frame_of_dwells(one).tolist() == one["revisit_id"].tolist()   # frame = revisit


def test_viewer_of_two_sensors_shows_each_platform_and_footprint_and_the_terrain(tmp_path):
    from .conftest import make_run
    run = make_run(tmp_path / "run", ["experiment=two_orbits", "scene.duration_s=20",
                                      "terrain=hills", "report.enabled=false", "export=none"])
    html = V.build_viewer(run, tmp_path / "viewer.html", max_frames=5).read_text()
    names = [t.get("name") for t in _figure_json(html)]
    sensors = V.sensor_names(load_run(run))
    assert len(sensors) == 2
    for name in sensors.values():
        for layer in ("beam footprint", "platform", "platform track"):
            assert f"{layer}: {name}" in names, (layer, name, names)
    assert names[0] == "terrain (hills)"                  # under everything else
    assert re.search(r"look \((%s)\): " % "|".join(sensors.values()), html)  # whose look
    data = _figure_json(html)
    plat = [t for t in data if str(t.get("name", "")).startswith("platform: ")]
    assert all(len(t["x"]["bdata"] if isinstance(t["x"], dict) else t["x"]) for t in plat)
