"""Small runs shared by the report tests (built once per session, in-process)."""
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from gmtiflow import pipeline
from gmtiflow.compose import compose


def make_run(out_dir: Path, overrides) -> Path:
    """A run file only: the tests build the report themselves (later overrides win)."""
    return pipeline.run(compose(["progress=false", "report=none", "export=none", *overrides]),
                        out_dir)


@pytest.fixture(scope="session")
def small_run(tmp_path_factory) -> Path:
    """The default scene for 30 s: detections, merges, tracks, metrics."""
    return make_run(tmp_path_factory.mktemp("small"), ["scene.duration_s=30"])


@pytest.fixture(scope="session")
def clutter_run(tmp_path_factory) -> Path:
    """Lake clutter (false alarms) and no tracker."""
    return make_run(tmp_path_factory.mktemp("lake"), ["scene.duration_s=30", "clutter=lake",
                                                      "tracker=none"])


@pytest.fixture(scope="session")
def empty_run(tmp_path_factory) -> Path:
    """No detections at all (a microwatt radar, no noise false alarms), so no tracks either."""
    return make_run(tmp_path_factory.mktemp("empty"), ["scene.duration_s=20",
                                                       "sensor.peak_power_w=1e-6",
                                                       "sensor.noise_false_alarms=false"])


def page_count(pdf: Path) -> int:
    """Pages of a matplotlib PDF (its page objects are written uncompressed)."""
    import re
    return len(re.findall(rb"/Type\s*/Page[^s]", pdf.read_bytes()))


def render_png(pdf: Path, out_prefix: Path, first: int, last: int):
    """Render pages with pdftoppm at 60 dpi; skip the test when poppler is missing."""
    if shutil.which("pdftoppm") is None:
        pytest.skip("pdftoppm (poppler-utils) not installed: cannot render PDF pages to PNG")
    subprocess.run(["pdftoppm", "-png", "-r", "60", "-f", str(first), "-l", str(last), str(pdf),
                    str(out_prefix)], check=True, timeout=60)
    return sorted(out_prefix.parent.glob(out_prefix.name + "-*.png"))


def pixel_std(png: Path) -> float:
    import matplotlib.image as mpimg
    img = mpimg.imread(png)
    return float(np.std(img[..., :3]))
