"""Terrain relief on the map page and in the viewer: the run's DEM rebuilt from its config,
sampled where the map looks, shaded by a light from the north-west."""
import numpy as np
import pytest

from gmtiflow.frames import Origin
from gmtiflow.report import relief as R
from gmtiflow.report.config import ReportConfig
from gmtiflow.report.data import load_run
from gmtiflow.report.run_report import run_figures

from .conftest import make_run

RIDGE = {"kind": "hills", "hills_base_height_m": 0.0, "grid_spacing_m": 25.0,
         "hills": [{"x_m": 0.0, "y_m": 0.0, "height_m": 200.0, "sigma_m": 300.0,
                    "length_m": 4000.0, "azimuth_deg": 90.0}]}     # an east-west ridge


def test_relief_is_the_run_terrain_and_its_shadow_faces_away_from_the_light():
    assert R.run_terrain({"terrain": {"kind": "flat"}}, Origin(50.0, 7.0)) == (None, "")
    terrain, note = R.run_terrain({"terrain": RIDGE}, Origin(50.0, 7.0))
    assert note == ""
    relief = R.relief_grid(terrain, (-3000.0, 3000.0), (-1500.0, 1500.0), cells=120)
    gx, gy = np.meshgrid(relief.x_m, relief.y_m)
    assert relief.height_m == pytest.approx(terrain.height_at(gx, gy))
    assert relief.height_m.max() == pytest.approx(200.0, rel=0.05)
    s = R.shadow(relief)
    col = np.argmin(np.abs(relief.x_m))
    north, south = np.argmin(np.abs(relief.y_m - 300)), np.argmin(np.abs(relief.y_m + 300))
    assert s[north, col] == 0.0             # the north flank faces the light (north-west)
    assert s[south, col] > 0.2              # the south flank is in shadow
    rgba = R.hillshade_rgba(relief)
    assert rgba[north, col, :3] == pytest.approx(1.0) and rgba[south, col, 0] < 0.9


def test_a_dem_that_cannot_be_read_is_named_not_shaded(tmp_path):
    cfg = {"terrain": {"kind": "srtm", "paths": [str(tmp_path / "N43E007.hgt")],
                       "geoid_offset_m": 50.0}}
    terrain, note = R.run_terrain(cfg, Origin(43.7, 7.4))
    assert terrain is None and "terrain not shaded" in note and "N43E007.hgt" in note


def test_map_page_shades_the_terrain_of_a_hills_run(tmp_path):
    run = load_run(make_run(tmp_path, ["scene.duration_s=10", "terrain=hills",
                                       "report.enabled=false", "export=none", "tracker=none"]))
    fig = dict(run_figures(run, ReportConfig()))["map"]()
    scene = fig.axes[1]
    assert len(scene.images) == 1
    img = scene.images[0].get_array()
    assert img.shape[2] == 4 and np.ptp(img[..., 0]) > 0.1     # shaded, not uniform
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any(lab.startswith("terrain (hills, 0–") for lab in labels), labels
