"""External trackers given as a command: blind inputs in, a track CSV out, scored like the rest.

For every (scenario, seed) of a benchmark sweep, :func:`score_command` writes the run's
detections and dwells *without truth* into ``<sweep>/external/<name>/<scenario>-<seed>/``, runs
the command there, reads the track CSV it wrote with ``gmtiflow-evaluate``'s reader and scores it
against the run's truth with the run's own metrics config
(:func:`gmtiflow.evaluate.cli.score`).  The scores go to ``bench.json`` beside it, which
:mod:`gmtiflow.bench.collect` reads as one more job.

The command is a shell command line with placeholders (``str.format``), run with that folder as
its working directory:

``{detections}``  ``detections.csv``: the formats detection CSV (docs/exports.md) restricted to
                  :data:`BLIND_COLUMNS` (the tracker protocol's blind columns: no ``truth_id``,
                  ``true_*``, ``merged``, folding/wrapping flags or RCS), each dwell's reports
                  by measured slant range with the dwell's ``det_id`` values handed out in
                  that order (:func:`gmtiflow.blind.truth_free_order`, as the batches of the
                  tracker protocol and ``export.blind`` files);
``{dwells}``      ``dwells.csv``: the /dwells table (time, beam, footprint, platform state);
``{scene}``       ``scene.json``: ENU origin, epoch, scenario and seed;
``{tracks}``      where to write the track CSV (``time_s track_id x_m y_m`` + optional columns);
``{python}``      the Python interpreter running gmtiflow.
"""
from __future__ import annotations

import csv
import io
import json
import logging
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Dict, Tuple

import numpy as np

from gmtiflow import formats, store
from gmtiflow.blind import BLIND_DETECTION_COLUMNS, truth_free_order
from gmtiflow.errors import GmtiflowError
from gmtiflow.formats import write_atomic

from .collect import EXTERNAL_FILE, RUN_FILE, collect
from .metrics import derived_values

log = logging.getLogger(__name__)

#: Detection columns an external tracker receives: what the tracker protocol's batches carry
#: (the radar's report, nothing from the truth) that the detection CSV has.
BLIND_COLUMNS = tuple(c for c in BLIND_DETECTION_COLUMNS
                      if c in formats.csvtable.COLUMNS["detections"])


class ExternalTrackerError(GmtiflowError):
    """An external tracker command failed or wrote no usable track file."""


def _table_csv(table: dict) -> bytes:
    names = list(table)
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(names)
    cols = []
    for c in names:
        v = np.asarray(table[c])
        cols.append(v.tolist() if v.dtype.kind in "iub" else [repr(float(x)) for x in v])
    for row in zip(*cols):
        w.writerow(row)
    return out.getvalue().encode()


def write_blind_inputs(run_file: Path, folder: Path, scenario: str, seed: int) -> Dict[str, Path]:
    """The blind inputs of one run (see the module docstring); returns the placeholder paths."""
    folder.mkdir(parents=True, exist_ok=True)
    with store.open_run(run_file) as f:
        attrs = store.read_attrs(f)
        det = store.read_table(f, "detections")
        dwells = store.read_table(f, "dwells")
    epoch = str(attrs.get("scene_epoch_utc", "2000-01-01T00:00:00Z"))
    paths = {"detections": folder / "detections.csv", "dwells": folder / "dwells.csv",
             "scene": folder / "scene.json", "tracks": folder / "tracks.csv"}
    formats.write_csv(paths["detections"],
                      truth_free_order({c: det[c] for c in BLIND_COLUMNS if c in det}),
                      "detections", epoch_utc=epoch)
    write_atomic(paths["dwells"], _table_csv(dwells))
    scene = {"origin_lat_deg": float(attrs["origin_lat_deg"]),
             "origin_lon_deg": float(attrs["origin_lon_deg"]),
             "origin_height_m": float(attrs.get("origin_height_m", 0.0)),
             "scene_epoch_utc": epoch, "scenario": scenario, "seed": int(seed)}
    write_atomic(paths["scene"], (json.dumps(scene, indent=1) + "\n").encode())
    if paths["tracks"].exists():
        paths["tracks"].unlink()
    return paths


def run_one(name: str, template: str, run_file: Path, folder: Path, scenario: str, seed: int,
            timeout: float = 600.0) -> Dict[str, float]:
    """Run the command on one run's blind inputs and score its tracks; returns the values."""
    paths = write_blind_inputs(run_file, folder, scenario, seed)
    subs = {k: shlex.quote(str(v.resolve())) for k, v in paths.items()}
    subs["python"] = shlex.quote(sys.executable)
    try:
        cmd = template.format(**subs)
    except (KeyError, IndexError, ValueError) as exc:
        raise ExternalTrackerError(f"external tracker {name!r}: bad placeholder in the command "
                                   f"{template!r} ({exc}); known: "
                                   f"{', '.join('{' + k + '}' for k in subs)}") from None
    where = f"external tracker {name!r} on {scenario} seed {seed}"
    try:
        proc = subprocess.run(cmd, shell=True, cwd=folder, capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        raise ExternalTrackerError(f"{where}: no result within {timeout:g} s") from None
    (folder / "command.log").write_text(f"$ {cmd}\n{proc.stdout}\n{proc.stderr}")
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["(no stderr)"])[-1]
        raise ExternalTrackerError(f"{where}: exit status {proc.returncode}: {tail}")
    if not paths["tracks"].is_file():
        raise ExternalTrackerError(f"{where}: wrote no track file {paths['tracks']}")
    from gmtiflow.evaluate.cli import metrics_config, score
    tables = score(paths["tracks"], run_file)
    with store.open_run(run_file) as f:
        mcfg = metrics_config(f)
    summary = {str(n): float(v) for n, v in zip(tables["metrics"]["name"],
                                                 tables["metrics"]["value"])}
    return derived_values(summary, mcfg.cutoff_m, mcfg.order_p)


def score_command(name: str, template: str, sweep_dir, timeout: float = 600.0) -> int:
    """Score command tracker ``name`` on every (scenario, seed) of the sweep; returns how many.

    Each (scenario, seed) is taken from one completed job of the sweep (any tracker: truth and
    detections are the same for all of them).  Results: ``<sweep>/external/<name>/...``.
    """
    sweep_dir = Path(sweep_dir)
    runs: Dict[Tuple[str, int], Path] = {}
    for rec in collect([sweep_dir]):
        if rec.ok and (rec.dir / RUN_FILE).is_file():
            runs.setdefault((rec.scenario, rec.seed), rec.dir / RUN_FILE)
    if not runs:
        raise ExternalTrackerError(f"{sweep_dir}: no completed runs to give external tracker "
                                   f"{name!r}")
    for (scenario, seed), run_file in sorted(runs.items()):
        folder = sweep_dir / "external" / name / f"{scenario}-{seed}"
        values = run_one(name, template, run_file, folder, scenario, seed, timeout)
        doc = {"scenario": scenario, "tracker": name, "seed": seed, "run": str(run_file),
               "values": values}
        write_atomic(folder / EXTERNAL_FILE, (json.dumps(doc, indent=1) + "\n").encode())
        log.info("%s: %s seed %d scored", name, scenario, seed)
    return len(runs)
