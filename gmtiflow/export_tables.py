"""A run file's tables as the exports need them: read once (:func:`load_run`), then adapted to
what each format means (:mod:`gmtiflow.export` writes them; docs/exports.md has the user-facing
version).

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
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, Optional

import numpy as np

from gmtiflow import frames
from gmtiflow.errors import InputFileError
from gmtiflow.export_config import ExportConfig
from gmtiflow.sensor import geometry
from gmtiflow.tables import Table

log = logging.getLogger("gmtiflow.export")

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
    """The run-file tables the exports of ``plan`` (:func:`gmtiflow.export.planned_files`)
    read: a 4607-only
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
    origin = frames.Origin.from_attrs(attrs)
    return RunTables(run_path, attrs, origin, str(attrs["scene_epoch_utc"]),
                     config if isinstance(config, dict) else {}, tables)


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
