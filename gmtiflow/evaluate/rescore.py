"""A run file re-scored for an external tracker: the run's scene, sensor output and truth, with
``/tracks`` and the tracker's ``/metrics`` tables replaced by an external track file and its
scores.  ``gmtiflow-report RUN_DIR --tracks my_tracks.csv`` builds the usual run report from it.

The tracks are read and scored exactly as ``gmtiflow-evaluate`` does
(:func:`gmtiflow.evaluate.cli.score`: the run's own ``metrics`` config, scored up to the last
dwell), so the report's numbers are the ones ``gmtiflow-evaluate`` prints.  Every other table of
the run is copied unchanged, including the tracker-independent ``/metrics/sensors``; the copy's
``/config`` says ``tracker.name: external`` with the track file in ``tracker.tracks_file``, and
its root attributes carry ``tracks_file``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterator, Optional, Tuple

import h5py
import numpy as np
import yaml

from gmtiflow.evaluate.cli import read_tracks, score
from gmtiflow.evaluate.tracks import validate_tracks
from gmtiflow.frames import Origin
from gmtiflow.store import RunWriter, open_run, read_attrs, read_table, read_text

#: Tables of a run that belong to its tracker: replaced, not copied.
TRACKER_TABLES = ("tracks", "metrics", "metrics/ospa", "metrics/track_errors",
                  "metrics/association", "metrics/truth_identity", "metrics/track_purity",
                  "metrics/identity_switches", "metrics/events", "metrics/convoys")


def _tables(f: h5py.File) -> Iterator[str]:
    """Paths of every group of ``f`` that holds columns (a table), parents first."""
    found = []

    def visit(name, obj):
        if isinstance(obj, h5py.Group) and any(isinstance(v, h5py.Dataset)
                                               for v in obj.values()):
            found.append(name)
    f.visititems(visit)
    return iter(found)


def _texts(f: h5py.File) -> Iterator[str]:
    return (k for k, v in f.items() if isinstance(v, h5py.Dataset) and v.ndim == 0)


def external_config(config_text: str, tracks_path: Path) -> str:
    """The run's resolved config with its tracker section saying what was scored."""
    cfg = yaml.safe_load(config_text) or {}
    cfg["tracker"] = {"enabled": True, "name": "external", "tracks_file": str(tracks_path)}
    return yaml.safe_dump(cfg, sort_keys=False)


def scored_run(run_path, tracks_path, out_path, include_unconfirmed: bool = False) -> Path:
    """Write ``out_path``: the run ``run_path`` with ``tracks_path``'s tracks and their scores.

    Raises :class:`~gmtiflow.errors.InputFileError` for a bad track file and
    :class:`~gmtiflow.errors.StoreError` for a bad run file, before anything is written.
    """
    run_path, tracks_path, out_path = Path(run_path), Path(tracks_path), Path(out_path)
    scores = score(tracks_path, run_path, include_unconfirmed)
    with open_run(run_path) as f:
        attrs = read_attrs(f)
        origin = Origin.from_attrs(attrs)
        epoch = str(attrs["scene_epoch_utc"]) if "scene_epoch_utc" in attrs else None
        tracks = validate_tracks(read_tracks(tracks_path, epoch), origin, str(tracks_path))
        keep = {k: v for k, v in attrs.items()
                if k not in ("layout_version", "seed", "gmtiflow_version", "complete")}
        keep["tracks_file"] = str(tracks_path)
        with RunWriter(out_path, seed=int(attrs.get("seed", 0)), attrs=keep) as w:
            for name in _texts(f):
                text = read_text(f, name)
                w.write_text(name, external_config(text, tracks_path) if name == "config"
                             else text)
            for name in _tables(f):
                if name not in TRACKER_TABLES:
                    w.write_table(name, read_table(f, name))
            w.write_table("tracks", {k: np.asarray(v) for k, v in tracks.items()})
            for name, table in scores.items():
                w.write_table(name, table)
            return w.commit()


def summaries(run_path) -> Tuple[Optional[dict], Optional[dict], str]:
    """(the /metrics summary, the /metrics/ospa series, the tracker's name) of a run file; None
    for a table the run does not have (its tracker was off)."""
    with open_run(run_path) as f:
        summary = read_table(f, "metrics") if "metrics" in f else None
        series = read_table(f, "metrics/ospa") if "metrics/ospa" in f else None
        name = "baseline"
        if "config" in f:
            tracker = (yaml.safe_load(read_text(f, "config")) or {}).get("tracker") or {}
            if not tracker.get("enabled", False):
                summary = series = None
            name = str(tracker.get("name") or name)
    return summary, series, name
