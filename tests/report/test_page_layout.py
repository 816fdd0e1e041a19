"""Every run-report page stays on the page: for the default scene, an OpenStreetMap scene
(Bautzen) and a racetrack orbit over wind-farm clutter and hills, each page's tight bounding box (every
axes, label, legend, title and text) lies within the figure."""
import os
from pathlib import Path

import pytest

from gmtiflow.report.config import ReportConfig
from gmtiflow.report.data import load_run
from gmtiflow.report.run_report import run_figures

from .conftest import make_run

REPO = Path(__file__).resolve().parents[2]
DATA = Path(os.environ.get("GMTIFLOW_DATA_DIR") or REPO.parent / "shared/data")
BAUTZEN = DATA / "bautzen.osm"

SCENES = {
    "default": ["scene.duration_s=40"],
    "racetrack_windfarm": ["scene.duration_s=40", "platform=racetrack", "clutter=windfarm",
                           "terrain=hills"],      # and the terrain relief with its legend entry
    "osm_bautzen": ["scene.duration_s=40", "roadmap=osm", f"roadmap.path={BAUTZEN}",
                    "vehicles.random.count=60"],
    "tracker_off": ["scene.duration_s=20", "tracker=none"],
}


def _off_page(fig, tol_in=0.02):
    """How far (inches) the figure's tight bounding box reaches beyond each edge."""
    renderer = fig.canvas.get_renderer()
    fig.canvas.draw()
    bb = fig.get_tightbbox(renderer)
    w, h = fig.get_size_inches()
    return {edge: round(v, 3) for edge, v in (("left", -bb.x0), ("bottom", -bb.y0),
                                              ("right", bb.x1 - w), ("top", bb.y1 - h))
            if v > tol_in}


@pytest.mark.slow
@pytest.mark.parametrize("scene", list(SCENES))
def test_every_page_stays_within_the_figure(scene, tmp_path):
    if scene.startswith("osm") and not BAUTZEN.is_file():
        pytest.skip(f"{BAUTZEN} absent: set GMTIFLOW_DATA_DIR to the project's shared data")
    run = load_run(make_run(tmp_path, SCENES[scene] + ["report.enabled=false", "export=none"]))
    problems = {}
    for page, build in run_figures(run, ReportConfig()):
        fig = build()
        out = _off_page(fig)
        if out:
            problems[page] = out
    assert not problems, f"{scene}: text or legends beyond the page edge (inches): {problems}"
