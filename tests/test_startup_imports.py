"""What `gmtiflow` imports before it can answer ``--help`` or reject a config (issue 18/19:
both within 1.5 s).  Nothing here is timed (benchmarks/startup_time.py measures): the test
runs the real entry point in a fresh interpreter and checks which modules it loaded, so a heavy
import moved back to the top of a module fails here however fast the machine is."""
import json
import subprocess
import sys

import pytest

# What a config error must not pay for: plotting, routing graphs, scipy (interpolation,
# optimisation, statistics), HDF5, the viewer, the package metadata (~0.05 s: read for
# gmtiflow.__version__ on first use), lxml and the format writers (gmtiflow.rundir needs only
# gmtiflow.formats.write_atomic) and the simulation itself.
HEAVY = ("matplotlib", "networkx", "scipy", "h5py", "plotly", "PIL", "importlib.metadata", "lxml",
         "gmtiflow.formats.stanag4607", "gmtiflow.formats.xmldoc",
         "gmtiflow.pipeline", "gmtiflow.sensor.model", "gmtiflow.evaluate.tracker",
         "gmtiflow.report.run_report", "gmtiflow.scene.trajectory")

PROBE = """
import json, sys
sys.argv = ["gmtiflow", *json.loads(sys.argv[1])]
from gmtiflow.cli import main
code = 0
try:
    main()
except SystemExit as exc:
    code = exc.code
print("\\n" + json.dumps({"code": code, "modules": sorted(sys.modules)}))
"""


def loaded_modules(args, cwd):
    proc = subprocess.run([sys.executable, "-c", PROBE, json.dumps(args)], cwd=cwd,
                          capture_output=True, text=True, timeout=120)
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    return out["code"], out["modules"]


def heavy_in(modules):
    return sorted(m for m in modules if any(m == h or m.startswith(h + ".") for h in HEAVY))


@pytest.mark.parametrize("args", [["sensor.peak_power_w=-1"], ["sensor.nosuch=1"]],
                         ids=["range-error", "unknown-key"])
def test_config_error_imports_nothing_heavy(tmp_path, args):
    code, modules = loaded_modules(args + [f"hydra.run.dir={tmp_path}/run"], tmp_path)
    assert code not in (0, None), "the bad config was accepted"
    assert "gmtiflow.config" in modules        # the probe really reached validation
    assert heavy_in(modules) == []


def test_help_imports_neither_hydra_nor_numpy(tmp_path):
    code, modules = loaded_modules(["--help"], tmp_path)
    assert code in (0, None)
    assert [m for m in modules if m.split(".")[0] in ("hydra", "numpy", "omegaconf")] == []


def test_a_run_without_tracker_and_metrics_does_not_load_them(tmp_path):
    # tracker=none metrics.enabled=false: the baseline tracker, its assignment (scipy.optimize)
    # and the metrics are not imported at all.
    code, modules = loaded_modules(
        ["tracker=none", "metrics.enabled=false", "report=none", "export=none",
         "scene.duration_s=20", "progress=false", f"hydra.run.dir={tmp_path}/run"], tmp_path)
    assert code in (0, None)
    assert "gmtiflow.sensor.model" in modules          # the run really ran
    assert [m for m in modules if m.startswith(("scipy.optimize", "gmtiflow.evaluate.tracker",
                                                "gmtiflow.evaluate.stage"))] == []
    # The default scene routes its vehicles on RoadMap.arcs(): networkx (~0.15 s) stays out.
    assert [m for m in modules if m.split(".")[0] == "networkx"] == []
    # Merging builds its kd-tree only when many reports share a range: not in this scene, so
    # scipy.spatial (qhull, distance, the kd-tree) is not imported.
    assert [m for m in modules if m.startswith("scipy.spatial")] == []


def test_checking_a_run_files_columns_loads_no_simulation(tmp_path):
    # The report (and every reader) checks a run file's columns against the writers' lists
    # first: those lists live in light modules, so a fresh report does not pay for the sensor
    # model and its merge's scipy.spatial (~0.2 s).
    probe = ("import json, sys\nfrom gmtiflow.store import required_columns\n"
             "cols = required_columns()\n"
             "print(json.dumps({'dwells': len(cols['dwells']), 'modules': sorted(sys.modules)}))")
    proc = subprocess.run([sys.executable, "-c", probe], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["dwells"] > 20                            # the lists really were read
    assert [m for m in out["modules"] if m.startswith(("gmtiflow.sensor.model",
                                                       "gmtiflow.sensor.merge",
                                                       "scipy.spatial"))] == []
