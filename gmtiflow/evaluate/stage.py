"""The evaluation stage: ``evaluate(cfg, truth, tracks, looks, vehicles, platform) -> tables``.

Everything is scored on one evaluation grid (:func:`gmtiflow.evaluate.align.evaluation_grid`,
by default the truth's own sample times, where truth is exact): tracks are brought to each grid
time (:func:`~gmtiflow.evaluate.align.tracks_at_grid`), OSPA/GOSPA and the identity association
are computed per step, and the per-track errors are taken at the tracks' own row times with
truth interpolated there.  See ``docs/evaluation.md`` for how to read every number.

Returned tables (keys are run-file paths):

``metrics``                 summary rows ``name value unit`` (:data:`SUMMARY_NAMES`)
``metrics/ospa``            per step: time_s ospa_m gospa_m gospa_localisation gospa_missed
                            gospa_false n_truth n_tracks n_assigned
``metrics/track_errors``    per associated track row: track_id time_s vehicle_id
                            position_error_m speed_error_mps heading_error_rad range_rate_error_mps
``metrics/association``     per (step, truth): time_s vehicle_id track_id (-1 none)
``metrics/truth_identity``  per vehicle: n_steps coverage identity_switches fragmentations
                            n_track_ids
``metrics/track_purity``    per track: n_associated purity dominant_vehicle_id n_vehicles
``metrics/identity_switches`` per switch: time_s vehicle_id from_track_id to_track_id
``metrics/events``          per stop / blind gap, fused and per sensor (:mod:`gmtiflow.evaluate.events`)
``metrics/convoys``         per convoy: n_members n_tracks n_confused_tracks
"""
from __future__ import annotations

from typing import Dict, List, Mapping, Optional, Tuple

import numpy as np

from gmtiflow import frames
from gmtiflow.evaluate import (align, clearmot, events as events_mod, identity,
                               neighbours, ospa)
from gmtiflow.evaluate.config import MetricsConfig
from gmtiflow.evaluate.order import count_distinct
from gmtiflow.evaluate.track_errors import track_errors
from gmtiflow.evaluate.tracks import validate_tracks
from gmtiflow.tables import Table, concat

EVENT_KINDS = ("stop", "doppler_blind", "terrain", "invisible_road")


def _summary_spec() -> List[Tuple[str, str]]:
    spec = [("n_truths", ""), ("n_tracks", ""), ("n_steps", ""),
            ("ospa_mean_m", "m"), ("gospa_mean_m", "m"), ("gospa_localisation_mean", "m^p"),
            ("gospa_missed_mean", "m^p"), ("gospa_false_mean", "m^p"),
            ("position_rmse_m", "m"), ("speed_rmse_mps", "m/s"), ("heading_rmse_rad", "rad"),
            ("range_rate_rmse_mps", "m/s"),
            ("identity_switches", ""), ("fragmentations", ""), ("coverage_mean", ""),
            ("track_purity_mean", ""), ("convoy_confused_tracks", ""),
            ("mota", ""), ("motp_m", "m"), ("idf1", ""), ("idp", ""), ("idr", "")]
    for kind in EVENT_KINDS:
        spec += [(f"{kind}_events", ""), (f"{kind}_events_held", ""),
                 (f"{kind}_id_kept_fraction", ""), (f"{kind}_reacquired_fraction", ""),
                 (f"{kind}_reacq_delay_mean_s", "s")]
    return spec


SUMMARY_NAMES = tuple(name for name, _ in _summary_spec())


def _mean(x) -> float:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(x.mean()) if len(x) else float("nan")


def _rms(x) -> float:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x ** 2))) if len(x) else float("nan")


def evaluate(cfg: MetricsConfig, truth: Mapping[str, np.ndarray],
             tracks: Mapping[str, np.ndarray], looks: Optional[Mapping[str, np.ndarray]] = None,
             vehicles: Optional[Mapping[str, np.ndarray]] = None,
             platform: Optional[Mapping[str, np.ndarray]] = None, *,
             origin: Optional[frames.Origin] = None, source: str = "tracks",
             until_s: Optional[float] = None,
             since_s: Optional[float] = None) -> Dict[str, Table]:
    """Score ``tracks`` against ``truth``; returns the tables listed in the module docstring.

    ``looks`` enables the blind-gap events, ``vehicles`` (or truth's ``convoy_id``) the convoy
    confusions, ``platform`` the range-rate errors; ``origin`` converts lat/lon track tables.
    ``until_s`` is the time of the tracker's last dwell: the grid stops there, and a track
    reported within ``max_extrapolation_s`` of it is taken as alive to the end (without it, the
    end of the truth).  ``since_s`` is the time of its first dwell: the grid starts there (or
    at the first truth sample, if earlier), and covers the window on the truth's own step
    whether or not a vehicle is on the road (:func:`~gmtiflow.evaluate.align.evaluation_grid`).
    ``cfg.min_truth_speed_mps`` gates slow truth out (MDV).
    Track tables are checked with :func:`~gmtiflow.evaluate.tracks.validate_tracks` (a bad one
    raises :class:`~gmtiflow.errors.InputFileError`).
    """
    if not cfg.enabled:
        return {}
    tracks = validate_tracks(tracks, origin, source)
    if cfg.confirmed_only and "confirmed" in tracks:
        tracks = {k: v[tracks["confirmed"]] for k, v in tracks.items()}
    whole_truth = truth
    if until_s is not None:
        keep = np.asarray(truth["time_s"], float) <= float(until_s) + 1e-9
        if not keep.all():
            truth = {k: np.asarray(v)[keep] for k, v in truth.items()}
    grid = align.evaluation_grid(truth, cfg.eval_dt_s, since_s, until_s)
    # a regular grid's instants between the last truth sample and until_s interpolate towards
    # the next sample (after until_s); the truth's own instants need no later one
    truth_at = align.truth_at_grid(truth if cfg.eval_dt_s is None else whole_truth, grid)
    open_end = until_s if until_s is not None else (float(grid[-1]) if len(grid) else None)
    tracks_at = align.tracks_at_grid(tracks, grid, cfg.max_extrapolation_s,
                                     cfg.track_end_hold_s, open_end_s=open_end)
    if cfg.min_truth_speed_mps > 0:
        truth_at, tracks_at = gate_slow_truth(truth_at, tracks_at, cfg.min_truth_speed_mps,
                                              cfg.cutoff_m)

    # OSPA's cut-off and the identity gate are one distance by default: one pair search
    pairs = (neighbours.step_pairs(truth_at, tracks_at, float(cfg.cutoff_m))
             if float(cfg.cutoff_m) == float(cfg.assoc_gate_m) else None)
    ospa_tab = ospa.series(truth_at, tracks_at, grid, cfg.cutoff_m, cfg.order_p, pairs)
    assigned = identity.associate(truth_at, tracks_at, len(grid), cfg.assoc_gate_m)
    idm = identity.identity_metrics(truth_at, assigned, grid)
    assoc = identity.association_table(truth_at, assigned, grid)
    errors = track_errors(tracks, truth, grid, truth_at["step"], truth_at["vehicle_id"], assigned,
                          platform)

    found = []
    if "mode" in truth:
        stops = events_mod.stop_events(truth)
        found.append({**stops, "sensor_id": np.full(len(stops["vehicle_id"]), events_mod.FUSED,
                                                    np.int64)})
    if looks is not None and len(looks.get("vehicle_id", ())):
        found.append(events_mod.gap_events(looks, cfg.min_gap_looks))
    ev = concat(found, columns=("vehicle_id", "kind", "sensor_id", "start_s", "end_s")) or {
        "vehicle_id": np.zeros(0, np.int64), "kind": np.zeros(0, str),
        "sensor_id": np.zeros(0, np.int64), "start_s": np.zeros(0), "end_s": np.zeros(0)}
    ev = events_mod.score_events(ev, assoc["vehicle_id"], assoc["time_s"], assoc["track_id"],
                                 cfg.event_lookback_s)

    if vehicles is not None and "convoy_id" in vehicles:
        convoy_of = dict(zip(np.asarray(vehicles["vehicle_id"]).tolist(),
                             np.asarray(vehicles["convoy_id"]).tolist()))
    elif "convoy_id" in truth:
        convoy_of = dict(zip(np.asarray(truth["vehicle_id"]).tolist(),
                             np.asarray(truth["convoy_id"]).tolist()))
    else:
        convoy_of = {}
    convoys = identity.convoy_confusions(assoc["vehicle_id"], assoc["track_id"], convoy_of)
    mot = clearmot.clear_mot(truth_at, tracks_at, assigned, idm["switches"], cfg.assoc_gate_m,
                             pairs)

    values = {
        "n_truths": count_distinct(truth_at["vehicle_id"]),
        "n_tracks": count_distinct(tracks_at["track_id"]), "n_steps": len(grid),
        "ospa_mean_m": _mean(ospa_tab["ospa_m"]), "gospa_mean_m": _mean(ospa_tab["gospa_m"]),
        "gospa_localisation_mean": _mean(ospa_tab["gospa_localisation"]),
        "gospa_missed_mean": _mean(ospa_tab["gospa_missed"]),
        "gospa_false_mean": _mean(ospa_tab["gospa_false"]),
        "position_rmse_m": _rms(errors["position_error_m"]),
        "speed_rmse_mps": _rms(errors["speed_error_mps"]),
        "heading_rmse_rad": _rms(errors["heading_error_rad"]),
        "range_rate_rmse_mps": _rms(errors["range_rate_error_mps"]),
        "identity_switches": idm["switches"], "fragmentations": idm["fragmentations"],
        "coverage_mean": _mean(idm["truth"]["coverage"]),
        "track_purity_mean": _mean(idm["tracks"]["purity"]),
        "convoy_confused_tracks": int(convoys["n_confused_tracks"].sum()),
        "mota": mot["mota"], "motp_m": mot["motp_m"], "idf1": mot["idf1"], "idp": mot["idp"],
        "idr": mot["idr"],
    }
    for kind in EVENT_KINDS:        # the fused events (all of them with one sensor)
        sel = (ev["kind"] == kind) & (ev["sensor_id"] == events_mod.FUSED)
        held = sel & (ev["track_before"] >= 0)
        values[f"{kind}_events"] = int(sel.sum())
        values[f"{kind}_events_held"] = int(held.sum())
        values[f"{kind}_id_kept_fraction"] = _mean(ev["id_kept"][held].astype(float))
        values[f"{kind}_reacquired_fraction"] = _mean(ev["reacquired"][held].astype(float))
        values[f"{kind}_reacq_delay_mean_s"] = _mean(ev["reacq_delay_s"][held])
    spec = _summary_spec()
    summary = {"name": np.array([n for n, _ in spec], dtype=str),
               "value": np.array([float(values[n]) for n, _ in spec], dtype=np.float64),
               "unit": np.array([u for _, u in spec], dtype=str)}
    return {"metrics": summary, "metrics/ospa": ospa_tab, "metrics/track_errors": errors,
            "metrics/association": assoc, "metrics/truth_identity": idm["truth"],
            "metrics/track_purity": idm["tracks"],
            "metrics/identity_switches": idm["switch_times"], "metrics/events": ev,
            "metrics/convoys": convoys}


def gate_slow_truth(truth_at: Mapping[str, np.ndarray], tracks_at: Mapping[str, np.ndarray],
                    min_speed_mps: float, cutoff_m: float):
    """MDV gating: drop truth rows slower than ``min_speed_mps`` and the track rows whose nearest
    truth at that step is such a one, closer than ``cutoff_m`` (one k-d tree for all steps)."""
    from scipy.spatial import cKDTree
    speed = np.hypot(truth_at["vx_mps"], truth_at["vy_mps"])
    slow = speed < float(min_speed_mps)
    if not slow.any():
        return truth_at, tracks_at
    lift = 4.0 * float(cutoff_m)
    if len(tracks_at["step"]):
        pts = np.stack([truth_at["x_m"], truth_at["y_m"], truth_at["step"] * lift], axis=1)
        q = np.stack([tracks_at["x_m"], tracks_at["y_m"], tracks_at["step"] * lift], axis=1)
        d, j = cKDTree(pts).query(q, distance_upper_bound=float(cutoff_m))
        found = np.isfinite(d) & (d < float(cutoff_m))
        drop = np.zeros(len(d), bool)
        drop[found] = slow[j[found]]
        tracks_at = {k: v[~drop] for k, v in tracks_at.items()}
    truth_at = {k: v[~slow] for k, v in truth_at.items()}
    return truth_at, tracks_at


def summary_value(tables: Mapping[str, Table], name: str) -> float:
    """Look a number up in the ``metrics`` summary table by name."""
    summary = tables["metrics"]
    hit = np.flatnonzero(summary["name"] == name)
    if not len(hit):
        raise KeyError(f"no metric named {name!r}; known: {', '.join(summary['name'])}")
    return float(summary["value"][hit[0]])
