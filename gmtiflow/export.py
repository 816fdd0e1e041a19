"""The export stage: a finished run file -> STANAG 4607, GMTI XML, CSV and GeoJSON beside it.

:func:`export_run` reads ``run.h5`` (so the stage behaves the same after a run and from
``gmtiflow-convert``), adapts the tables to what each format means, and calls the writers of
:mod:`formats`.  Every file is written under a temporary name and renamed into place when
complete; if any export fails, the files this call already wrote are removed again, so a failed
export never leaves a set of files that looks complete.

Adapting the tables (docs/exports.md has the user-facing version):

* **Range rate.**  /detections ``range_rate_mps`` is the full ṙ = (v_t − v_p)·ℓ (+ receding).
  STANAG 4607 D32.7 is the LOS velocity *corrected for platform motion*, i.e. the target's own
  radial speed ṙ − ṙ_MLC = v_t·ℓ, where ṙ_MLC = −v_p·ℓ is the range rate of the ground at the
  report's position (ℓ from the dwell's platform position to the report's ground position
  ``x_m y_m z_m``).  :func:`to_4607_tables` subtracts ṙ_MLC; :func:`from_4607_tables` adds it
  back (recomputed from D7–D9, D15–D17 and the report's position, in the sensor's local ENU).
  XML and CSV carry ``range_rate_mps`` with the table's meaning (full ṙ), losslessly.
* **Platform velocity and heading** (D15–D17, D21) are sent relative to true north *at the
  sensor*, as the standard defines them; the tables hold them in the scene's ENU frame, whose
  north differs by the meridian convergence (≈0.3° 30 km from the origin), and as map rates
  (:mod:`gmtiflow.frames`).  They are converted by ``frames.map_to_local_vector`` (the
  geodetic positions a moment apart, through pymap3d) and back by ``local_to_map_vector``.
* **Unlocated reports** (NaN ``lat_deg``/``lon_deg``, e.g. folded reports that could not be
  geolocated) are skipped in 4607 (a target report must have a position; NaN would be written
  as 0°, 0°) and in GeoJSON (no geometry to draw), and kept in XML and CSV, which carry every
  row.  Located reports flagged ``implausible`` are exported like any other: a real processor
  cannot tell, and the flag is kept in XML/CSV/GeoJSON for scoring.
* **Meta** (4607 and XML): epoch = run attr ``scene_epoch_utc``; revisit interval J15 =
  ``sensor.revisit_s`` of the run's /config when every sensor has the same (else each
  sensor's median time between its revisit starts); MDV J24 = median of the
  dwells' ``mdv_mps``; false-alarm density J26 = ``clutter.fov_density_per_km2`` (per dwell)
  when > 0, else No Statement; Pd J25 only when the user states one (``export.pd``): it is
  defined for a 10 m² target and a run has no single value; nominal accuracies J21–J23 = medians
  of the written reports' σ (each sensor's own) when ``export.nominal_accuracies``; bounding
  area J6–J13 = the writer's box around the dwells, or for a run without dwells the box around
  the scene origin and the /platform positions (:func:`scene_bounding_area`).
* **GeoJSON**: truth and road nodes get ``lat_deg lon_deg height_m`` through
  :func:`gmtiflow.frames.enu_to_geodetic` with the run's origin; clutter regions of the run's
  config are drawn as polygons (circles and rings as 72-gons; a ring is its outer circle with
  ``inner_radius_m`` as a property).
"""
from __future__ import annotations

import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.blind import TRUTH_DETECTION_COLUMNS, truth_free_order
from gmtiflow.console import progress
from gmtiflow.errors import InputFileError
from gmtiflow.live import StreamConfig
from gmtiflow.schema import Problem, non_negative
from gmtiflow.sensor import geometry
from gmtiflow.tables import Table

log = logging.getLogger(__name__)

FORMATS = ("stanag4607", "xml", "csv", "geojson")
CSV_TABLES = ("detections", "dwells", "truth", "tracks")
FILE_NAMES = {"stanag4607": "detections.4607", "xml": "detections.xml",
              "geojson": "scene.geojson", "geojson:truth": "truth.geojson",
              "geojson:tracks": "tracks.geojson"}
"""Output file of each format (CSV: ``<table>.csv`` per entry of ``csv_tables``)."""


@dataclass
class ExportConfig:
    """What the export stage writes beside ``run.h5`` (``conf/export/*.yaml``)."""

    formats: List[str] = field(default_factory=lambda: list(FORMATS))
    """Any of stanag4607, xml, csv, geojson; [] writes nothing."""
    csv_tables: List[str] = field(default_factory=lambda: ["detections", "dwells", "tracks"])
    """Tables written as CSV when ``csv`` is selected: detections, dwells, truth, tracks.  Truth is
    opt-in (``export.csv_tables=[detections,truth,tracks]``): it is in run.h5 already and a
    1,000-vehicle, 30-min scene makes a 110 MB truth.csv (``gmtiflow-convert RUN.h5 --to csv
    --table truth`` writes it on demand)."""
    edition: str = "30"
    """4607 P1: "30" (STANAG 4607 Ed. 3; what tshark reads) or "41" (AEDP-4607 Ed. A v1)."""
    platform_location_packets: bool = False
    """Add a 4607 Platform Location packet per /platform row (the spec sends them while not
    collecting; the dwells already carry the platform state)."""
    platform_id: str = "GMTIFLOW"        # P8, at most 10 ASCII characters
    mission_id: int = 1                  # P9
    job_id: int = 1                      # P10 / J1, >= 1
    nationality: str = "XN"              # P3, two letters
    exercise_indicator: int = 129        # P7: 129 = Exercise, Simulated
    mission_plan: str = "SIMULATION"     # M1, at most 12 characters
    flight_plan: str = ""                # M2, at most 12 characters
    nominal_accuracies: bool = True
    """J21–J23 = medians of the reports' σ_range, σ_cross-range, σ_range-rate (else No Statement)."""
    pd: Optional[float] = None
    """J25 detection probability statement (0..1, for a 10 m² target); None = No Statement."""
    geojson_truth: bool = True
    geojson_truth_step_s: float = 5.0
    """Truth trajectories in the GeoJSON (a map view) every this many seconds, plus each
    vehicle's first and last sample; 0 = every /truth sample.  Full-rate truth is in run.h5
    and truth.csv (a 1,000-vehicle, 30-min scene at 1 s makes a 150 MB GeoJSON)."""
    geojson_tracks: bool = True
    """tracks.geojson: the baseline tracker's tracks, one LineString per track (when the run
    has /tracks)."""
    geojson_roads: bool = True
    geojson_clutter: bool = True
    stream: StreamConfig = field(default_factory=StreamConfig)
    """Live 4607 over UDP/TCP while the run simulates (``export=stream``; gmtiflow.live)."""
    blind: bool = False
    """Exports without truth, for handing to a tracker under test: no truth.csv, no truth in
    the GeoJSON, and the detections without ``truth_id``, ``true_*``, ``merged``, the
    ambiguity flags and ``rcs_dbsm`` (so no 4607 truth tag D32.16/17 nor RCS D32.18).  Truth
    stays in run.h5 for scoring."""

    def problems(self) -> List[Problem]:
        out: List[Problem] = non_negative(self, "geojson_truth_step_s")
        bad = [f for f in self.formats if f not in FORMATS]
        if bad:
            out.append(Problem("formats", f"unknown format(s) {bad}; choose from {list(FORMATS)}"))
        bad = [t for t in self.csv_tables if t not in CSV_TABLES]
        if bad:
            out.append(Problem("csv_tables", f"unknown table(s) {bad}; choose from "
                                             f"{list(CSV_TABLES)}"))
        if str(self.edition) not in ("30", "41"):
            out.append(Problem("edition", f"must be '30' or '41', got {self.edition!r}"))
        for key, n in (("platform_id", 10), ("mission_plan", 12), ("flight_plan", 12),
                       ("nationality", 2)):
            value = getattr(self, key)
            if len(value) > n or not value.isascii():
                out.append(Problem(key, f"must be at most {n} ASCII characters, got {value!r}"))
        if not 1 <= self.job_id <= 2 ** 32 - 1:
            out.append(Problem("job_id", f"must be in 1..2^32-1, got {self.job_id}"))
        if not 0 <= self.mission_id <= 2 ** 32 - 1:
            out.append(Problem("mission_id", f"must be in 0..2^32-1, got {self.mission_id}"))
        if not 0 <= self.exercise_indicator <= 255:
            out.append(Problem("exercise_indicator", f"must be 0..255, got "
                                                     f"{self.exercise_indicator}"))
        if self.stream.url is not None:
            from gmtiflow.live import is_url
            if not is_url(self.stream.url):
                out.append(Problem("stream.url", f"must be udp://HOST:PORT or tcp://HOST:PORT, "
                                                 f"got {self.stream.url!r}"))
        if not (np.isfinite(self.stream.speed) and self.stream.speed >= 0):
            out.append(Problem("stream.speed", f"must be a finite number >= 0 (0 = unpaced), "
                                               f"got {self.stream.speed}"))
        if self.pd is not None and not 0.0 <= self.pd <= 1.0:
            out.append(Problem("pd", f"must be a probability in [0, 1], got {self.pd}"))
        return out


# ---------------------------------------------------------------------------------------------
# Reading the run
# ---------------------------------------------------------------------------------------------

@dataclass
class RunTables:
    """What the exports need from a run file."""

    path: Path
    attrs: dict
    origin: frames.Origin
    epoch_utc: str
    config: dict
    tables: Dict[str, Table]


EXPORT_TABLES = ("dwells", "detections", "truth", "tracks", "platform", "roads/nodes",
                 "roads/edges")
"""Every run-file table an export reads."""


def tables_for(plan) -> tuple:
    """The run-file tables the exports of ``plan`` (:func:`planned_files`) read: a 4607-only
    run does not decompress /truth."""
    need = set()
    for fmt, _ in plan:
        if fmt in ("stanag4607", "xml"):
            need |= {"dwells", "detections", "platform"}
        elif fmt.startswith("csv:"):
            need.add(fmt[4:])
        elif fmt == "geojson":
            need |= {"detections", "roads/nodes", "roads/edges"}
        elif fmt.startswith("geojson:"):
            need.add(fmt[8:])
        else:
            return EXPORT_TABLES
    return tuple(name for name in EXPORT_TABLES if name in need)


def load_run(run_path, tables=EXPORT_TABLES) -> RunTables:
    """Read the ``tables`` the exports use (those the file has) from a complete run file
    (StoreError if it is not one)."""
    from gmtiflow.store import open_run, read_attrs, read_config, read_table   # h5py: lazy
    run_path = Path(run_path)
    with open_run(run_path, require_columns=True) as f:
        attrs = read_attrs(f)
        tables = {name: read_table(f, name) for name in tables if name in f}
        try:
            # parsed and checked once by open_run (plain YAML: gmtiflow writes it with PyYAML,
            # so OmegaConf's loader would read the same values, ten times slower)
            config = read_config(f) if "config" in f else {}
        except Exception:           # a foreign or hand-edited /config: use no config values
            config = {}
    for key in ("origin_lat_deg", "origin_lon_deg", "scene_epoch_utc"):
        if key not in attrs:
            raise InputFileError(f"{run_path}: run file lacks the root attribute {key!r}")
    origin = frames.Origin(float(attrs["origin_lat_deg"]), float(attrs["origin_lon_deg"]),
                           float(attrs.get("origin_height_m", 0.0)))
    return RunTables(run_path, attrs, origin, str(attrs["scene_epoch_utc"]),
                     config if isinstance(config, dict) else {}, tables)


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
    if "origin_lat_deg" in attrs:
        origin = frames.Origin(float(attrs["origin_lat_deg"]), float(attrs["origin_lon_deg"]),
                               float(attrs.get("origin_height_m", 0.0)))
        tables["dwells"] = local_frame_dwells(tables["dwells"], origin)
    data = formats.stanag4607.encode_read_tables(tables)
    formats.write_atomic(dest, data)


def local_frame_dwells(dwells: Table, origin: frames.Origin) -> Table:
    """Dwells with platform velocity and heading rotated from the scene ENU frame to the local
    ENU at the platform (true north at the sensor, as 4607 D15-D17 and D21 are defined)."""
    dw = {k: np.asarray(v) for k, v in dwells.items()}
    if not len(dw.get("dwell_id", ())):
        return dw
    xyz = tuple(np.asarray(dw[f"platform_{c}_m"], float) for c in "xyz")
    ve, vn, vu = frames.map_to_local_vector(origin, *xyz, dw["platform_vx_mps"],
                                            dw["platform_vy_mps"], dw["platform_vz_mps"])
    hd = np.asarray(dw["platform_heading_rad"], float)
    he, hn, _ = frames.map_to_local_vector(origin, *xyz, np.sin(hd), np.cos(hd), 0.0 * hd)
    heading = frames.heading_rad(he, hn)
    return dict(dw, platform_vx_mps=ve, platform_vy_mps=vn, platform_vz_mps=vu,
                platform_heading_rad=np.where(np.isfinite(hd), heading, np.nan))


def _cfg(config: dict, *keys, default=None):
    node = config
    for k in keys:
        if not isinstance(node, dict) or k not in node:
            return default
        node = node[k]
    return node


# ---------------------------------------------------------------------------------------------
# Frames and range rates
# ---------------------------------------------------------------------------------------------

def ground_range_rate_scene(dwells: Table, detections: Table) -> np.ndarray:
    """ṙ_MLC = −v_p·ℓ of each report's ground position, from the scene's map coordinates on
    the round earth, as the sensor computes it (m/s)."""
    k = _dwell_rows(dwells, detections["dwell_id"])
    platform = tuple(np.asarray(dwells[f"platform_{c}_m"], float)[k] for c in "xyz")
    _, los = geometry.line_of_sight(platform, tuple(np.asarray(detections[f"{c}_m"], float)
                                                    for c in "xyz"))
    vel = geometry.true_velocity(tuple(np.asarray(dwells[f"platform_v{c}_mps"], float)[k]
                                       for c in "xyz"), platform[2])
    return geometry.clutter_range_rate(vel, los)


def ground_range_rate_geodetic(dwells: Table, detections: Table) -> np.ndarray:
    """ṙ_MLC from geodetic positions and a sensor velocity in the sensor's local ENU (as 4607
    carries them: D7–D9, D15–D17, D32.2/3/6).  A report without height is put at 0 m HAE."""
    import pymap3d
    k = _dwell_rows(dwells, detections["dwell_id"])
    slat = np.asarray(dwells["platform_lat_deg"], float)[k]
    slon = np.asarray(dwells["platform_lon_deg"], float)[k]
    sh = np.asarray(dwells["platform_height_m"], float)[k]
    h = np.asarray(detections.get("height_m", np.zeros(len(k))), float)
    e, n, u = pymap3d.geodetic2enu(np.asarray(detections["lat_deg"], float),
                                   np.asarray(detections["lon_deg"], float),
                                   np.where(np.isfinite(h), h, 0.0), slat, slon, sh)
    # (e, n, u) is a Cartesian vector of the sensor's local ENU frame: no earth model
    _, los = geometry.line_of_sight((0.0, 0.0, 0.0), (np.asarray(e), np.asarray(n), np.asarray(u)),
                                    None)
    vel = tuple(np.asarray(dwells[f"platform_v{c}_mps"], float)[k] for c in "xyz")
    return geometry.clutter_range_rate(vel, los)


def _dwell_rows(dwells: Table, dwell_id) -> np.ndarray:
    ids = np.asarray(dwells["dwell_id"], np.int64)
    order = np.argsort(ids, kind="stable")
    want = np.asarray(dwell_id, np.int64)
    pos = np.clip(np.searchsorted(ids[order], want), 0, max(len(ids) - 1, 0))
    if len(want) and (len(ids) == 0 or np.any(ids[order][pos] != want)):
        missing = want[(len(ids) == 0) | (ids[order][pos] != want)][0]
        raise InputFileError(f"detection refers to dwell_id {missing}, which is not in /dwells")
    return order[pos]


def to_4607_tables(run: RunTables):
    """(dwells, detections) as the 4607 writer should see them (see the module docstring)."""
    dw = {k: np.asarray(v) for k, v in run.tables["dwells"].items()}
    det = {k: np.asarray(v) for k, v in run.tables["detections"].items()}
    located = np.isfinite(np.asarray(det["lat_deg"], float)) & \
        np.isfinite(np.asarray(det["lon_deg"], float))
    if not located.all():
        log.info("4607: %d unlocated report(s) skipped", int((~located).sum()))
    det = {k: v[located] for k, v in det.items()}
    dw = local_frame_dwells(dw, run.origin)
    if len(det.get("det_id", ())) and "range_rate_mps" in det and "los_velocity_mps" not in det:
        det["los_velocity_mps"] = det["range_rate_mps"] - ground_range_rate_scene(
            run.tables["dwells"], det)
    # Columns 4607 has no field for are not needed by the writer (it ignores them).
    return dw, det


def from_4607_tables(tables: dict, origin: Optional[frames.Origin] = None) -> dict:
    """Tables read by :func:`formats.read_4607` in gmtiflow's conventions.

    ``detections``: ``los_velocity_mps`` keeps D32.7 as sent (corrected for platform motion);
    ``range_rate_mps`` becomes the full ṙ = D32.7 + ṙ_MLC (NaN where the dwell lacks D15–D17).
    With a scene ``origin``: ``x_m y_m z_m`` on detections, ``platform_x_m ...`` and scene-ENU
    ``platform_v*_mps`` / ``platform_heading_rad`` on dwells, and detection ``azimuth_rad``
    from the platform in the scene frame (the reader's is relative to true north at the sensor).
    """
    out = {k: v for k, v in tables.items() if k != "attrs"}
    dw = dict(out["dwells"])
    det = dict(out["detections"])
    if len(det.get("det_id", ())):
        los = np.asarray(det["los_velocity_mps"], float)
        det["range_rate_mps"] = los + ground_range_rate_geodetic(dw, det)
    if origin is not None:
        h = np.asarray(det.get("height_m", np.zeros(len(det["det_id"]))), float)
        det["x_m"], det["y_m"], det["z_m"] = frames.geodetic_to_enu(
            origin, det["lat_deg"], det["lon_deg"], np.where(np.isfinite(h), h, 0.0))
        px, py, pz = frames.geodetic_to_enu(origin, dw["platform_lat_deg"],
                                            dw["platform_lon_deg"], dw["platform_height_m"])
        dw["platform_x_m"], dw["platform_y_m"], dw["platform_z_m"] = px, py, pz
        # local ENU at the sensor -> map rates: the inverse of local_frame_dwells
        geo = (dw["platform_lat_deg"], dw["platform_lon_deg"], dw["platform_height_m"])
        ve, vn, vu = frames.local_to_map_vector(origin, *geo, dw["platform_vx_mps"],
                                                dw["platform_vy_mps"], dw["platform_vz_mps"])
        dw["platform_vx_mps"], dw["platform_vy_mps"], dw["platform_vz_mps"] = ve, vn, vu
        hd = np.asarray(dw["platform_heading_rad"], float)
        he, hn, _ = frames.local_to_map_vector(origin, *geo, np.sin(hd), np.cos(hd),
                                               np.zeros_like(hd))
        dw["platform_heading_rad"] = frames.heading_rad(np.asarray(he), np.asarray(hn))
        if len(det.get("det_id", ())):
            k = _dwell_rows(dw, det["dwell_id"])
            det["azimuth_rad"] = frames.heading_rad(det["x_m"] - px[k], det["y_m"] - py[k])
    out["dwells"], out["detections"] = dw, det
    return out


# ---------------------------------------------------------------------------------------------
# Meta
# ---------------------------------------------------------------------------------------------

def meta_for(cfg: ExportConfig, run: RunTables) -> dict:
    """The 4607/XML meta dict (``formats.stanag4607.DEFAULT_META`` keys) of a run."""
    meta = {"epoch_utc": run.epoch_utc, "platform_id": cfg.platform_id,
            "mission_id": int(cfg.mission_id), "job_id": int(cfg.job_id),
            "nationality": cfg.nationality, "exercise_indicator": int(cfg.exercise_indicator),
            "mission_plan": cfg.mission_plan, "flight_plan": cfg.flight_plan}
    # J15 from the config only when every sensor is configured with the same revisit: a meta
    # value applies to every sensor's Job Definition; left None, the writer takes each
    # sensor's from its own dwells (the XML's one JobDefinition: the median over the sensors)
    revisits = {_cfg(run.config, "sensor", "revisit_s")}
    for extra in (_cfg(run.config, "sensors", default=None) or {}).values():
        revisits.add(_cfg(extra, "sensor", "revisit_s"))
    revisit = revisits.pop() if len(revisits) == 1 else None
    if isinstance(revisit, (int, float)) and revisit > 0:
        meta["revisit_interval_s"] = float(revisit)
    fa = _cfg(run.config, "clutter", "fov_density_per_km2")
    if isinstance(fa, (int, float)) and fa > 0:
        meta["false_alarm_density_per_m2"] = float(fa) / 1e6
    if cfg.pd is not None:
        meta["pd"] = float(cfg.pd)
    # J21-J23: the writer takes the medians of the reports it writes, each sensor's own
    meta["nominal_sigmas_from_reports"] = bool(cfg.nominal_accuracies)
    area = scene_bounding_area(run)
    if area is not None:
        meta["bounding_area"] = area
    return meta


def scene_bounding_area(run: RunTables) -> Optional[list]:
    """J6-J13 of a run whose dwells give no position (a run without dwells), else None (the
    writer's box around the dwells and detections).

    The box around the scene origin (where the sensor looks) and the /platform positions
    (where it flew), as the writer's box spans the dwell area centres and platform positions:
    the job's area is where the scene is, not 0 deg N 0 deg E."""
    dw = run.tables.get("dwells", {})
    for lat, lon in (("area_lat_deg", "area_lon_deg"), ("platform_lat_deg", "platform_lon_deg")):
        if lat in dw and lon in dw and np.any(np.isfinite(np.asarray(dw[lat], float))
                                              & np.isfinite(np.asarray(dw[lon], float))):
            return None
    plat = run.tables.get("platform", {})
    lats = np.r_[run.origin.lat_deg, np.asarray(plat.get("lat_deg", []), float)]
    lons = np.r_[run.origin.lon_deg, np.asarray(plat.get("lon_deg", []), float)]
    ok = np.isfinite(lats) & np.isfinite(lons)
    s, n = float(lats[ok].min()), float(lats[ok].max())
    w, e = float(lons[ok].min()), float(lons[ok].max())
    return [(n, w), (n, e), (s, e), (s, w)]


# ---------------------------------------------------------------------------------------------
# GeoJSON inputs
# ---------------------------------------------------------------------------------------------

def with_geodetic(table: Table, origin: frames.Origin, xyz=("x_m", "y_m", "z_m")) -> Table:
    """``table`` plus ``lat_deg lon_deg height_m`` from its ENU columns (z 0 when absent)."""
    if "lat_deg" in table and "lon_deg" in table and "height_m" in table:
        return dict(table)
    n = len(table[xyz[0]])
    z = table.get(xyz[2], np.zeros(n))
    lat, lon, h = frames.enu_to_geodetic(origin, table[xyz[0]], table[xyz[1]], z)
    return dict(table, lat_deg=lat, lon_deg=lon, height_m=h)


def clutter_regions(config: dict, origin: frames.Origin) -> list:
    """Clutter regions of a run's config as GeoJSON writer regions (lat/lon rings)."""
    regions = _cfg(config, "clutter", "regions", default=None) or []
    out = []
    for i, reg in enumerate(regions):
        if not isinstance(reg, dict):
            continue
        shape = reg.get("shape", "polygon")
        props = {"name": str(reg.get("name") or f"region-{i}"), "shape": shape,
                 "density_per_km2": float(reg.get("density_per_km2") or 0.0)}
        if shape == "polygon" and reg.get("vertices_m"):
            xy = np.asarray(reg["vertices_m"], float).reshape(-1, 2)
        elif shape in ("circle", "ring") and reg.get("centre_m") is not None:
            r = reg.get("radius_m") if shape == "circle" else reg.get("outer_radius_m")
            if r is None:
                continue
            a = np.linspace(0.0, 2 * np.pi, 72, endpoint=False)
            c = np.asarray(reg["centre_m"], float)
            xy = np.c_[c[0] + r * np.sin(a), c[1] + r * np.cos(a)]
            if shape == "ring":
                props["inner_radius_m"] = float(reg.get("inner_radius_m") or 0.0)
                props["outer_radius_m"] = float(r)
            else:
                props["radius_m"] = float(r)
        else:
            continue
        lat, lon, _ = frames.enu_to_geodetic(origin, xy[:, 0], xy[:, 1], np.zeros(len(xy)))
        out.append(dict(props, lat_deg=lat, lon_deg=lon))
    return out


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
