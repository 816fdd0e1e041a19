"""Does a benchmark scenario's challenge actually happen?  Checks read from a run file's tables.

Every scenario of the suite (``conf/experiment/challenge/<name>.yaml``, docs/benchmark.md)
isolates one GMTI difficulty; a tracker comparison on it only means something if the difficulty
occurred in that run.  :func:`check` reads ``/truth``, ``/looks``, ``/detections``,
``/detection_ancestors``, ``/dwells``, ``/vehicles`` and ``/roads`` of one run and returns a
:class:`ChallengeCheck`: whether the challenge occurred, the numbers that show it, and one line
saying so.  The tests run every scenario over several seeds through these checks; the benchmark
table quotes their numbers.

Look outcomes are :class:`gmtiflow.sensor.outcome.Outcome` (docs/tables.md, ``/looks``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Dict, List

import numpy as np

from gmtiflow import store
from gmtiflow.sensor.outcome import Outcome
from gmtiflow.tables import Table

#: Minimum stop length (s) that counts for ``stop_and_go``: two 5 s revisits.
MIN_STOP_S = 10.0
#: A vehicle counts as moving above this speed (m/s), for ``tangential``.
MOVING_MPS = 5.0
#: ``offroad``: on the road within this distance of a road segment, off it beyond the second.
ON_ROAD_M, OFF_ROAD_M = 5.0, 100.0
#: ``dense_clutter``: false alarms per revisit (scan) and per target plot.
MIN_FA_PER_REVISIT, MIN_FA_PER_TARGET_PLOT = 30.0, 10.0


@dataclass
class ChallengeCheck:
    """Result of one scenario's check on one run."""

    scenario: str
    occurred: bool
    summary: str
    numbers: Dict[str, float] = field(default_factory=dict)


class RunTables:
    """Lazy, cached access to the tables of one run file."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self._cache: Dict[str, Table] = {}

    def __getitem__(self, name: str) -> Table:
        if name not in self._cache:
            self._cache[name] = store.read_table(self.path, name)
        return self._cache[name]

    def vehicle_ids(self, prefix: str = "") -> List[int]:
        v = self["vehicles"]
        return [int(i) for i, n in zip(v["vehicle_id"], v["name"]) if str(n).startswith(prefix)]

    def looks_of(self, vehicle_id: int, outcome: Outcome) -> np.ndarray:
        """Times (s) of the vehicle's looks with that outcome."""
        lk = self["looks"]
        m = (lk["vehicle_id"] == vehicle_id) & (lk["outcome"] == int(outcome))
        return np.sort(np.asarray(lk["time_s"][m], float))

    def truth_of(self, vehicle_id: int) -> Table:
        tr = self["truth"]
        m = tr["vehicle_id"] == vehicle_id
        return {k: np.asarray(v)[m] for k, v in tr.items()}

    def merged_groups(self) -> List[set]:
        """The truth ids folded into each merged report (one set per merged report)."""
        anc = self["detection_ancestors"]
        det = np.asarray(anc["det_id"], np.int64)
        tid = np.asarray(anc["truth_id"], np.int64)
        return [set(tid[det == d].tolist()) for d in np.unique(det)]


def _runs(mask: np.ndarray) -> List[tuple]:
    """(first, last) index of each run of True in ``mask``."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]]).astype(np.int8)
    starts = np.flatnonzero(np.diff(m) == 1)
    ends = np.flatnonzero(np.diff(m) == -1) - 1
    return list(zip(starts.tolist(), ends.tolist()))


def _merged_with_all(t: RunTables, ids: List[int], at_least: int) -> int:
    """Merged reports holding at least ``at_least`` of the vehicles ``ids``."""
    wanted = set(ids)
    return sum(len(g & wanted) >= at_least for g in t.merged_groups())


def check_crossing(t: RunTables) -> ChallengeCheck:
    ids = t.vehicle_ids()
    n = _merged_with_all(t, ids, 2)
    return ChallengeCheck("crossing", n >= 1,
                          f"{n} merged report(s) hold both crossing vehicles",
                          {"merged_reports_both": n})


def check_overtake(t: RunTables) -> ChallengeCheck:
    slow, fast = t.vehicle_ids("slow")[0], t.vehicle_ids("fast")[0]
    a, b = t.truth_of(slow), t.truth_of(fast)
    common, ia, ib = np.intersect1d(a["time_s"], b["time_s"], return_indices=True)
    lead = np.asarray(b["route_s_m"])[ib] - np.asarray(a["route_s_m"])[ia]
    overtaken = bool(lead.size and lead[0] < 0 and lead[-1] > 0)
    t_pass = float(common[np.argmax(lead > 0)]) if overtaken else float("nan")
    n = _merged_with_all(t, [slow, fast], 2)
    return ChallengeCheck("overtake", overtaken and n >= 1,
                          f"fast truck passes at t = {t_pass:.0f} s; {n} merged report(s) "
                          f"hold both", {"pass_time_s": t_pass, "merged_reports_both": n})


def check_convoy(t: RunTables) -> ChallengeCheck:
    ids = t.vehicle_ids("convoy")
    n = _merged_with_all(t, ids, 2)
    return ChallengeCheck("convoy", n >= 3, f"{n} merged report(s) hold two or more convoy "
                                            f"trucks", {"merged_reports": n,
                                                        "members": len(ids)})


def check_stop_and_go(t: RunTables) -> ChallengeCheck:
    n_stops, n_blind, longest = 0, 0, 0.0
    for v in t.vehicle_ids():
        tr = t.truth_of(v)
        time = np.asarray(tr["time_s"], float)
        blind = t.looks_of(v, Outcome.DOPPLER_BLIND)
        for i, j in _runs(np.asarray(tr["mode"]) == 2):
            start, end = time[i], time[min(j + 1, time.size - 1)]
            if end - start < MIN_STOP_S:
                continue
            n_stops += 1
            longest = max(longest, end - start)
            n_blind += int(np.sum((blind >= start) & (blind <= end)))
    return ChallengeCheck("stop_and_go", n_stops >= 1 and n_blind >= 1,
                          f"{n_stops} stop(s) of >= {MIN_STOP_S:.0f} s (longest {longest:.0f} s) "
                          f"with {n_blind} Doppler-blind look(s)",
                          {"long_stops": n_stops, "blind_looks_stopped": n_blind,
                           "longest_stop_s": longest})


def check_tangential(t: RunTables) -> ChallengeCheck:
    per_vehicle = []
    for v in t.vehicle_ids():
        tr = t.truth_of(v)
        blind = t.looks_of(v, Outcome.DOPPLER_BLIND)
        speed = np.interp(blind, tr["time_s"], tr["speed_mps"])
        per_vehicle.append(int(np.sum(speed > MOVING_MPS)))
    ok = bool(per_vehicle) and min(per_vehicle) >= 2
    return ChallengeCheck("tangential", ok, f"Doppler-blind looks while moving > "
                                            f"{MOVING_MPS:.0f} m/s, per vehicle: {per_vehicle}",
                          {"min_blind_looks_moving": float(min(per_vehicle, default=0))})


def _occlusion(t: RunTables, outcome: Outcome, truth_flag: str = "") -> List[dict]:
    """Per vehicle: the longest gap of looks with ``outcome`` and the detections around it."""
    out = []
    for v in t.vehicle_ids():
        hidden = t.looks_of(v, outcome)
        seen = t.looks_of(v, Outcome.DETECTED)
        row = {"vehicle_id": v, "hidden_looks": int(hidden.size),
               "span_s": float(hidden[-1] - hidden[0]) if hidden.size else 0.0,
               "seen_before": bool(hidden.size and np.any(seen < hidden[0])),
               "seen_after": bool(hidden.size and np.any(seen > hidden[-1]))}
        if truth_flag:
            tr = t.truth_of(v)
            flag = np.asarray(tr[truth_flag], bool)
            dt = float(np.median(np.diff(tr["time_s"]))) if flag.size > 1 else 0.0
            row["truth_hidden_s"] = float(flag.sum() * dt)
        out.append(row)
    return out


def check_tunnel(t: RunTables) -> ChallengeCheck:
    rows = _occlusion(t, Outcome.INVISIBLE_ROAD, "invisible")
    revisit = _revisit_s(t)
    ok = bool(rows) and all(r["seen_before"] and r["seen_after"] and
                            r["truth_hidden_s"] - 2 * revisit <= r["span_s"] <= r["truth_hidden_s"]
                            for r in rows)
    return ChallengeCheck("tunnel", ok, "tunnel looks span / time inside (s): " + ", ".join(
        f"{r['span_s']:.0f}/{r['truth_hidden_s']:.0f}" for r in rows),
        {f"tunnel_s_{i}": r["truth_hidden_s"] for i, r in enumerate(rows)})


def check_terrain_shadow(t: RunTables) -> ChallengeCheck:
    rows = _occlusion(t, Outcome.TERRAIN)
    ok = bool(rows) and all(r["seen_before"] and r["seen_after"] and r["span_s"] >= 20.0
                            for r in rows)
    return ChallengeCheck("terrain_shadow", ok, "shadowed looks span (s): " + ", ".join(
        f"{r['span_s']:.0f} ({r['hidden_looks']} looks)" for r in rows),
        {"shadow_s": float(min((r["span_s"] for r in rows), default=0.0))})


def distance_to_roads_m(t: RunTables, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Ground distance (m) of points to the nearest road segment of the run's road map."""
    nodes, edges = t["roads/nodes"], t["roads/edges"]
    idx = {int(i): k for k, i in enumerate(nodes["node_id"])}
    a = np.array([[nodes["x_m"][idx[int(i)]], nodes["y_m"][idx[int(i)]]]
                  for i in edges["from_node"]])
    b = np.array([[nodes["x_m"][idx[int(i)]], nodes["y_m"][idx[int(i)]]]
                  for i in edges["to_node"]])
    p = np.column_stack([x, y])[:, None, :]                         # (n, 1, 2)
    ab = (b - a)[None]                                              # (1, m, 2)
    s = np.clip(np.sum((p - a[None]) * ab, -1) / np.maximum(np.sum(ab * ab, -1), 1e-12), 0, 1)
    return np.min(np.linalg.norm(p - (a[None] + s[..., None] * ab), axis=-1), axis=1)


def check_offroad(t: RunTables) -> ChallengeCheck:
    both = []
    for v in t.vehicle_ids():
        tr = t.truth_of(v)
        d = distance_to_roads_m(t, tr["x_m"], tr["y_m"])
        both.append((float(np.mean(d < ON_ROAD_M)), float(np.mean(d > OFF_ROAD_M))))
    ok = bool(both) and all(on > 0 and off > 0 for on, off in both)
    return ChallengeCheck("offroad", ok, "share of time on / far off the road per vehicle: " +
                          ", ".join(f"{on:.2f}/{off:.2f}" for on, off in both),
                          {"min_off_road_share": min((o for _, o in both), default=0.0)})


def check_dense_clutter(t: RunTables) -> ChallengeCheck:
    det = t["detections"]
    fa = np.asarray(det["truth_id"]) < 0
    n_revisits = np.unique(np.asarray(t["dwells"]["revisit_id"])).size
    per_revisit = float(fa.sum() / max(n_revisits, 1))
    per_target = float(fa.sum() / max(int((~fa).sum()), 1))
    ok = per_revisit >= MIN_FA_PER_REVISIT and per_target >= MIN_FA_PER_TARGET_PLOT
    return ChallengeCheck("dense_clutter", ok, f"{per_revisit:.0f} false alarms per revisit, "
                                               f"{per_target:.0f} per target plot",
                          {"false_alarms_per_revisit": per_revisit,
                           "false_alarms_per_target_plot": per_target})


def check_two_sensors(t: RunTables) -> ChallengeCheck:
    """Each sensor alone has Doppler-blind looks of a vehicle that another sensor detects within
    one revisit (the fused picture bridges what each radar loses)."""
    lk, dw = t["looks"], t["dwells"]
    order = np.argsort(dw["dwell_id"])
    sensor = np.asarray(dw["sensor_id"])[order][np.searchsorted(
        np.asarray(dw["dwell_id"])[order], lk["dwell_id"])]
    vid, time = np.asarray(lk["vehicle_id"]), np.asarray(lk["time_s"], float)
    outcome = np.asarray(lk["outcome"])
    revisit = _revisit_s(t)
    sensors = np.unique(np.asarray(dw["sensor_id"]))
    bridged = {}
    for s in sensors:
        n = 0
        for i in np.flatnonzero((sensor == s) & (outcome == int(Outcome.DOPPLER_BLIND))):
            other = (sensor != s) & (vid == vid[i]) & (outcome == int(Outcome.DETECTED))
            n += bool(np.any(np.abs(time[other] - time[i]) <= revisit))
        bridged[int(s)] = n
    ok = len(sensors) >= 2 and min(bridged.values()) >= 2
    return ChallengeCheck("two_sensors", ok, "Doppler-blind looks another sensor detects within "
                                             "a revisit, per sensor: " + ", ".join(
        f"{s}: {n}" for s, n in bridged.items()),
        {"min_bridged_blind_looks": float(min(bridged.values(), default=0))})


def _revisit_s(t: RunTables) -> float:
    """The revisit time (s): the median time between a sensor's consecutive scans."""
    dw = t["dwells"]
    first = np.asarray(dw["dwell_index"]) == 0
    sensor = np.asarray(dw["sensor_id"]) if "sensor_id" in dw else np.zeros(first.size)
    sensor_first = sensor[first]
    gaps = [np.diff(np.asarray(dw["time_s"])[first][sensor_first == s])
            for s in np.unique(sensor_first)]
    gaps = np.concatenate(gaps) if gaps else np.zeros(0)
    return float(np.median(gaps)) if gaps.size else 0.0


CHECKS: Dict[str, Callable[[RunTables], ChallengeCheck]] = {
    "crossing": check_crossing, "overtake": check_overtake, "convoy": check_convoy,
    "stop_and_go": check_stop_and_go, "tangential": check_tangential,
    "tunnel": check_tunnel, "terrain_shadow": check_terrain_shadow,
    "offroad": check_offroad, "dense_clutter": check_dense_clutter,
    "two_sensors": check_two_sensors,
}


def check(scenario: str, run_file) -> ChallengeCheck:
    """The challenge check of ``scenario`` (a name of :data:`CHECKS`) on one run file."""
    return CHECKS[scenario](RunTables(Path(run_file)))
