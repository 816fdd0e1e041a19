"""Bad input through the real CLI: one clear message naming what and where, a non-zero exit,
and no run file (issues 2-4).  User presets come in through ``--config-dir`` as they would."""
import os
import subprocess
import sys
import textwrap

import pytest

INLINE_MAP = """
kind: inline
nodes: {a: [0, 0, 0], b: [1000, 0, 0], c: [2000, 0, 0]}
roads:
  - {from_node: a, to_node: b, oneway: true}
  - {from_node: b, to_node: c}
"""


def vehicle(**fields):
    spec = {"name": "v1", "start": "a", "end": "c", "cruise_speed_mps": 10.0, **fields}
    body = ", ".join(f"{k}: {v}" for k, v in spec.items())
    return f"vehicles:\n  - {{{body}}}\n"


CASES = {
    # name: (files under the config dir, overrides, text the error must contain)
    "unreachable": ({"roadmap/tiny.yaml": INLINE_MAP, "vehicles/back.yaml": vehicle(start="c", end="a")},
                    ["roadmap=tiny", "vehicles=back"], "v1"),
    "unknown_node": ({"roadmap/tiny.yaml": INLINE_MAP, "vehicles/lost.yaml": vehicle(end="nowhere")},
                     ["roadmap=tiny", "vehicles=lost"], "nowhere"),
    "empty_map": ({"roadmap/empty.yaml": "kind: inline\nnodes: {}\nroads: []\n",
                   "vehicles/one.yaml": vehicle()}, ["roadmap=empty", "vehicles=one"], "roadmap."),
    "negative_speed": ({"roadmap/tiny.yaml": INLINE_MAP,
                        "vehicles/slow.yaml": vehicle(cruise_speed_mps=-3.0)},
                       ["roadmap=tiny", "vehicles=slow"], "cruise_speed_mps"),
    "malformed_osm": ({"bad.osm": "<osm><way id='1'>"}, ["roadmap=osm", "roadmap.path={dir}/bad.osm"],
                      "bad.osm"),
    "unknown_option": ({}, ["terrain=everest"], "terrain has no option 'everest'"),
    "negative_power": ({}, ["sensor.peak_power_w=-1"], "sensor.peak_power_w"),
    "elevation_reversed": ({}, ["sensor.el_min_deg=-2", "sensor.el_max_deg=-20"], "sensor.el_min_deg"),
    "missing_rcs_file": ({}, ["sensor.rcs.truck.table={dir}/nope.csv"], "nope.csv"),
    "malformed_rcs_table": ({"rcs.csv": "aspect_deg,rcs_dbsm\n0,10\n90,loud\n180,12\n"},
                            ["sensor.rcs.truck.table={dir}/rcs.csv"], "rcs.csv"),
    "self_intersecting_clutter": (
        {"clutter/bowtie.yaml": textwrap.dedent("""
            regions:
              - {name: bowtie, shape: polygon, density_per_km2: 1.0,
                 vertices_m: [[0, 0], [1000, 1000], [1000, 0], [0, 1000]]}
            """)}, ["clutter=bowtie"], "clutter.regions"),
    "negative_density": ({}, ["clutter=lake", "clutter.fov_density_per_km2=-1"],
                         "clutter.fov_density_per_km2"),
    "dem_not_covering": ({}, ["terrain=monaco", "terrain.paths=[{data}/N43E007.hgt]"], "N43E007"),
    "dem_not_a_grid": ({"junk.asc": "ncols 3\nnrows 2\nhello world\n"},
                       ["terrain.kind=ascii_grid", "terrain.path={dir}/junk.asc"], "junk.asc"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_gives_one_clear_error_and_no_run_file(case, tmp_path, shared_data):
    files, overrides, needle = CASES[case]
    conf = tmp_path / "conf"
    conf.mkdir()
    for rel, text in files.items():
        path = (conf if rel.endswith(".yaml") else tmp_path) / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    out = tmp_path / "out"
    subst = {"dir": tmp_path, "data": shared_data}
    cmd = [sys.executable, "-m", "gmtiflow.cli", "--config-dir", str(conf),
           f"hydra.run.dir={out}", "scene.duration_s=20", *(o.format(**subst) for o in overrides)]
    proc = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, HYDRA_FULL_ERROR="0"))
    assert proc.returncode != 0, proc.stderr
    assert needle in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    errors = [line for line in proc.stderr.splitlines() if "ERROR" in line or "Error" in line]
    assert len(errors) <= 2, proc.stderr          # one message (Hydra may add a header line)
    assert not list(tmp_path.rglob("*.h5")) and not list(tmp_path.rglob("*.partial"))
