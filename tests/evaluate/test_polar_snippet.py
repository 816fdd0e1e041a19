"""The polar-measurement snippet of docs/formats.md, run as written against Stone Soup: each
detection's bearing-range measurement maps back to its own x_m, y_m."""
import datetime
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stonesoup")

from gmtiflow import pipeline, store                      # noqa: E402
from gmtiflow.compose import compose                      # noqa: E402

DOC = Path(__file__).resolve().parents[2] / "docs" / "formats.md"


def snippet():
    text = DOC.read_text(encoding="utf-8")
    m = re.search(r"<!-- polar-snippet[^\n]*-->\n```python\n(.*?)```", text, re.S)
    assert m, "docs/formats.md lost its polar snippet"
    return m.group(1)


def test_the_docs_polar_snippet_recovers_each_detection_position(tmp_path):
    run = pipeline.run(compose(["scene.duration_s=20", "export=none", "report=none",
                                "progress=false", "cache.enabled=false"]), tmp_path)
    det, dw = store.read_table(run, "detections"), store.read_table(run, "dwells")
    import h5py
    from gmtiflow import frames
    with h5py.File(run) as f:
        radius = frames.sphere_radius_m(frames.Origin(*(float(f.attrs[f"origin_{k}"]) for k in (
            "lat_deg", "lon_deg", "height_m"))))
    ns = {}
    exec(snippet(), ns)
    rows = np.flatnonzero(np.isfinite(det["x_m"]) & ~det["implausible"])
    assert len(rows) > 20
    now = datetime.datetime(2026, 6, 1, 8)
    naive_err = []
    for i in rows:
        k = int(np.flatnonzero(dw["dwell_id"] == det["dwell_id"][i])[0])
        d = {c: det[c][i] for c in det}
        w = {c: dw[c][k] for c in dw}
        detection = ns["polar_detection"](d, w, now, radius_m=radius)
        rough = ns["polar_detection"](d, w, now)        # the default radius: centimetres
        xy_r = np.ravel(rough.measurement_model.inverse_function(rough)).astype(float)
        assert np.hypot(xy_r[0] - d["x_m"], xy_r[2] - d["y_m"]) < 0.05
        xy = np.ravel(detection.measurement_model.inverse_function(detection)).astype(float)
        assert np.hypot(xy[0] - d["x_m"], xy[2] - d["y_m"]) < 1e-6
        # the azimuth taken as a bearing with the slant range: far off
        raw = detection.measurement_model.inverse_function(type(detection)(
            np.array([[d["azimuth_rad"]], [d["range_m"]]]),
            measurement_model=detection.measurement_model))
        raw = np.ravel(raw).astype(float)
        naive_err.append(np.hypot(raw[0] - d["x_m"], raw[2] - d["y_m"]))
    assert np.median(naive_err) > 1000.0
