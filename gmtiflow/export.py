"""The export stage: a finished run file -> STANAG 4607, GMTI XML, CSV and GeoJSON beside it.

:func:`export_run` reads ``run.h5`` (so the stage behaves the same after a run and from
``gmtiflow-convert``), adapts the tables to what each format means, and calls the writers of
:mod:`formats`.  Every file is written under a temporary name and renamed into place when
complete; if any export fails, the files this call already wrote are removed again, so a failed
export never leaves a set of files that looks complete.

How the tables are adapted to each format (range rate, frames, meta, GeoJSON inputs):
:mod:`gmtiflow.export_tables`; the stage's settings: :mod:`gmtiflow.export_config`.
"""
from __future__ import annotations

import logging
import os
from pathlib import Path
from typing import List, Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.blind import TRUTH_DETECTION_COLUMNS, truth_free_order
from gmtiflow.console import progress
from gmtiflow.errors import InputFileError
from gmtiflow.export_config import CSV_TABLES, FILE_NAMES, FORMATS, ExportConfig
from gmtiflow.export_tables import (RunTables, clutter_regions, load_run, local_frame_dwells,
                                    meta_for, tables_for, to_4607_tables, with_geodetic)
from gmtiflow.tables import Table

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------------------------
# Converted 4607 files
# ---------------------------------------------------------------------------------------------

def is_converted_4607(run_path) -> bool:
    """Whether ``run_path`` was converted from a 4607 file (``gmtiflow-convert X.4607 --to h5``)
    and holds every table :func:`formats.stanag4607.encode_read_tables` needs."""
    from gmtiflow import formats
    from gmtiflow.store import open_run, read_attrs
    with open_run(run_path) as f:
        attrs = read_attrs(f)
        return (str(attrs.get("source_format", "")) == "4607"
                and all(name in f for name in formats.stanag4607.READ_TABLES))


def rewrite_converted_4607(run_path, dest) -> None:
    """Write a run file converted from 4607 back to 4607, losslessly.

    Packets, segments, existence masks and every field come from the stored tables; a file that
    was converted with ``--origin`` has its dwells in the scene frame, and they are rotated back
    to the sensor's local frame first.  A valid input file comes back byte for byte.
    """
    from gmtiflow import formats
    from gmtiflow.store import open_run, read_attrs, read_table
    with open_run(run_path) as f:
        attrs = read_attrs(f)
        tables = {name: read_table(f, name) for name in formats.stanag4607.READ_TABLES}
    origin = frames.Origin.from_attrs(attrs)
    if origin is not None:
        tables["dwells"] = local_frame_dwells(tables["dwells"], origin)
    data = formats.stanag4607.encode_read_tables(tables)
    formats.write_atomic(dest, data)


# ---------------------------------------------------------------------------------------------
# Writers
# ---------------------------------------------------------------------------------------------

def _csv_table(run: RunTables, name: str) -> Optional[Table]:
    from gmtiflow import formats
    table = run.tables.get(name)
    if table is None:
        return None
    cols = formats.csvtable.COLUMNS[name]
    if name == "truth" and "x_m" in table:
        table = with_geodetic(table, run.origin)
    dropped = [c for c in table if c not in cols]
    if dropped:
        log.info("%s.csv: columns %s are not part of the CSV form and are left out", name,
                 dropped)
    return {c: v for c, v in table.items() if c in cols}


def blind_run(run: RunTables) -> RunTables:
    """``run`` without truth (``export.blind``): no /truth, detections without truth columns,
    and each dwell's reports in a truth-free order (:func:`gmtiflow.blind.truth_free_order`)."""
    tables = {k: v for k, v in run.tables.items() if k != "truth"}
    if "detections" in tables:
        tables["detections"] = truth_free_order({c: v for c, v in tables["detections"].items()
                                                 if c not in TRUTH_DETECTION_COLUMNS})
    return RunTables(run.path, run.attrs, run.origin, run.epoch_utc, run.config, tables)


def write_format(fmt: str, run: RunTables, cfg: ExportConfig, dest) -> None:
    """Write one export of ``run`` to ``dest`` (a path or a binary file object).

    ``fmt`` is ``stanag4607``, ``xml``, ``geojson`` or ``csv:<table>``.
    """
    from gmtiflow import formats   # lxml, the writers: imported when exporting
    t = run.tables
    if fmt == "stanag4607":
        dw, det = to_4607_tables(run)
        formats.write_4607(dest, dw, det, meta_for(cfg, run), edition=str(cfg.edition),
                           platform=t.get("platform") if cfg.platform_location_packets else None)
    elif fmt == "xml":
        cols = formats.xmldoc.DETECTION_COLUMNS
        det = {c: v for c, v in t["detections"].items() if c in cols or c == "dwell_id"}
        dw = {c: v for c, v in t["dwells"].items() if c in formats.xmldoc.DWELL_COLUMNS}
        formats.write_xml(dest, dw, det, meta_for(cfg, run), edition=str(cfg.edition))
    elif fmt.startswith("csv:"):
        name = fmt[4:]
        table = _csv_table(run, name)
        if table is None:
            raise InputFileError(f"{run.path}: has no table /{name} to write as CSV")
        formats.write_csv(dest, table, name, epoch_utc=run.epoch_utc)
    elif fmt == "geojson:truth":
        if "truth" not in t:
            raise InputFileError(f"{run.path}: has no table /truth to write as GeoJSON")
        formats.write_geojson(dest, truth=with_geodetic(thin_truth(t["truth"],
                                                                   cfg.geojson_truth_step_s),
                                                        run.origin),
                              epoch_utc=run.epoch_utc)
    elif fmt == "geojson:tracks":
        if "tracks" not in t:
            raise InputFileError(f"{run.path}: has no table /tracks to write as GeoJSON")
        tracks = with_geodetic(t["tracks"], run.origin)
        tracks.pop("height_m")                     # tracks are 2-D: no height to draw
        formats.write_geojson(dest, tracks=tracks, epoch_utc=run.epoch_utc)
    elif fmt == "geojson":
        det = t.get("detections")
        if det is not None:
            ok = np.isfinite(np.asarray(det["lat_deg"], float)) & \
                np.isfinite(np.asarray(det["lon_deg"], float))
            if not ok.all():        # else the same columns as XML and CSV: formatted once
                det = {k: np.asarray(v)[ok] for k, v in det.items()}
        nodes = edges = None
        if cfg.geojson_roads and "roads/nodes" in t:
            nodes = with_geodetic(t["roads/nodes"], run.origin)
            edges = t.get("roads/edges")
        regions = clutter_regions(run.config, run.origin) if cfg.geojson_clutter else None
        formats.write_geojson(dest, detections=det, road_nodes=nodes,
                              road_edges=edges, clutter_regions=regions,
                              epoch_utc=run.epoch_utc)
    else:
        raise ValueError(f"unknown export format {fmt!r}")


def thin_truth(truth: Table, step_s: float) -> Table:
    """Truth rows on the ``step_s`` grid plus each vehicle's first and last row (0: all)."""
    if not step_s or not len(truth["time_s"]):
        return truth
    t = np.asarray(truth["time_s"], float)
    v = np.asarray(truth["vehicle_id"])
    on_grid = np.abs(t / step_s - np.round(t / step_s)) < 1e-6
    order = np.lexsort((t, v))
    ends = np.zeros(len(t), bool)
    first = np.r_[True, v[order][1:] != v[order][:-1]]
    last = np.r_[v[order][1:] != v[order][:-1], True]
    ends[order[first | last]] = True
    keep = on_grid | ends
    return {k: np.asarray(c)[keep] for k, c in truth.items()}


def planned_files(cfg: ExportConfig) -> list:
    """(format key, file name) of every file ``cfg`` asks for, in writing order."""
    out = []
    for fmt in FORMATS:
        if fmt not in cfg.formats:
            continue
        if fmt == "csv":
            out += [(f"csv:{name}", f"{name}.csv") for name in CSV_TABLES
                    if name in cfg.csv_tables and not (cfg.blind and name == "truth")]
        else:
            out.append((fmt, FILE_NAMES[fmt]))
            if fmt == "geojson" and cfg.geojson_truth and not cfg.blind:
                out.append(("geojson:truth", FILE_NAMES["geojson:truth"]))
            if fmt == "geojson" and cfg.geojson_tracks:
                out.append(("geojson:tracks", FILE_NAMES["geojson:tracks"]))
    return out


def stream_problem(cfg: ExportConfig, n_sensors: int) -> Optional[str]:
    """Why ``export.stream`` cannot serve a run of ``n_sensors`` sensors, or None.

    A run simulates its sensors one after the other (gmtiflow.pipeline), so a live stream of
    several sensors could not be paced in scene time; it is refused before any work."""
    if cfg.stream.url and n_sensors > 1:
        return (f"export.stream.url: a live stream carries one sensor, and this run has "
                f"{n_sensors} (simulated one after the other, so they cannot be paced together); "
                "stream a one-sensor run, or write detections.4607 and send it with "
                "gmtiflow.live.Sender")
    return None


def open_live_export(cfg: ExportConfig, origin: frames.Origin, epoch_utc: str,
                     config: Optional[dict] = None):
    """The live 4607 sink of a run (:class:`gmtiflow.live.LiveExport`), or None when
    ``export.stream.url`` is not set.  The pipeline appends every simulated chunk to it."""
    if not cfg.stream.url:
        return None
    from gmtiflow.live import LiveExport
    log.info("export: streaming 4607 live to %s at %gx real time", cfg.stream.url,
             cfg.stream.speed)
    return LiveExport(cfg.stream, cfg, origin, epoch_utc, config)


def export_run(cfg: ExportConfig, run_path, out_dir=None) -> List[Path]:
    """Write the exports ``cfg`` selects for the run file ``run_path`` into ``out_dir``.

    ``out_dir`` defaults to the run file's directory.  Returns the paths written, in order.
    Each file is written atomically; if one export fails, the files written by this call are
    removed and the error is raised (a ``GmtiflowError`` for bad input, e.g. an incomplete run
    file).
    """
    problems = cfg.problems()
    if problems:
        from gmtiflow.errors import ConfigError
        raise ConfigError("invalid config: " + "; ".join(f"export.{p.key}: {p.message}"
                                                         for p in problems))
    plan = planned_files(cfg)
    if not plan:
        return []
    run = load_run(run_path, tables_for(plan))
    if cfg.blind:
        run = blind_run(run)
    out_dir = Path(out_dir) if out_dir is not None else Path(run_path).parent
    out_dir.mkdir(parents=True, exist_ok=True)
    written: List[Path] = []
    from gmtiflow import formats
    try:
        with formats.shared_columns():     # each column's text made once for every format
            for fmt, name in progress(plan, "export", "file"):   # on a terminal, after 2 s
                if fmt in ("csv:tracks", "geojson:tracks") and "tracks" not in run.tables:
                    log.info("no /tracks in %s: %s not written", run.path, name)
                    continue
                if fmt == "geojson:truth" and "truth" not in run.tables:
                    log.info("no /truth in %s: truth.geojson not written", run.path)
                    continue
                path = out_dir / name
                write_format(fmt, run, cfg, path)
                written.append(path)
                log.info("export: wrote %s (%d bytes)", path, path.stat().st_size)
    except BaseException:
        for path in written:
            try:
                os.unlink(path)
            except OSError:
                pass
        raise
    return written
