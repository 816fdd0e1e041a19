"""What the benchmark compares: the metrics per scenario, their units and which way is better.

Values come from each run's ``/metrics`` summary (docs/evaluation.md).  Two are derived from it
with the run's GOSPA cut-off c and order p: ``false_tracks_per_step`` = ``gospa_false_mean`` /
(c^p/2) and ``missed_per_step`` = ``gospa_missed_mean`` / (c^p/2), the mean number of false
tracks and of missed vehicles per evaluation step.

Every scenario is judged first on its *challenge* metrics (the paper's "loss of track identities
after stop events" and its kin), then on the common ones.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, List, Mapping, Tuple

import numpy as np


@dataclass(frozen=True)
class Metric:
    name: str
    label: str
    unit: str
    higher_is_better: bool
    #: The values the metric can take: fractions in [0, 1], MOTA in (-inf, 1], the rest >= 0.
    bounds: Tuple[float, float] = (0.0, math.inf)


FRACTION = (0.0, 1.0)


def _event_metrics(prefix: str, kept_label: str, delay_label: str) -> List[Metric]:
    """An event kind's pair: identity kept through it, and the re-acquisition delay after it."""
    return [Metric(f"{prefix}_id_kept_fraction", f"id kept {kept_label}", "", True, FRACTION),
            Metric(f"{prefix}_reacq_delay_mean_s", f"re-acquisition delay {delay_label}", "s",
                   False)]


_ALL = [
    Metric("identity_switches", "identity switches", "", False),
    Metric("track_purity_mean", "track purity", "", True, FRACTION),
    Metric("convoy_confused_tracks", "convoy-confused tracks", "", False),
    *_event_metrics("stop", "after stops", "after stops"),
    *_event_metrics("doppler_blind", "after Doppler-blind gaps", "after blind gaps"),
    *_event_metrics("invisible_road", "through tunnels", "after tunnels"),
    *_event_metrics("terrain", "through terrain shadow", "after shadow"),
    Metric("false_tracks_per_step", "false tracks per step", "", False),
    Metric("missed_per_step", "missed vehicles per step", "", False),
    Metric("ospa_mean_m", "OSPA mean", "m", False),
    Metric("coverage_mean", "coverage", "", True, FRACTION),
    Metric("fragmentations", "fragmentations", "", False),
    Metric("position_rmse_m", "position RMSE", "m", False),
    Metric("mota", "MOTA", "", True, (-math.inf, 1.0)),
    Metric("idf1", "IDF1", "", True, FRACTION),
]
METRICS: Dict[str, Metric] = {m.name: m for m in _ALL}

#: Metrics every scenario reports, after its challenge metrics.
COMMON = ("ospa_mean_m", "coverage_mean", "identity_switches", "false_tracks_per_step",
          "position_rmse_m", "mota", "idf1")

#: The challenge metrics of each scenario; the first is its headline in the summary.
CHALLENGE: Dict[str, tuple] = {
    "crossing": ("identity_switches", "track_purity_mean"),
    "overtake": ("identity_switches", "track_purity_mean"),
    "convoy": ("convoy_confused_tracks", "track_purity_mean", "identity_switches"),
    "stop_and_go": ("stop_id_kept_fraction", "stop_reacq_delay_mean_s"),
    "tangential": ("doppler_blind_id_kept_fraction", "doppler_blind_reacq_delay_mean_s"),
    "tunnel": ("invisible_road_id_kept_fraction", "invisible_road_reacq_delay_mean_s"),
    "terrain_shadow": ("terrain_id_kept_fraction", "terrain_reacq_delay_mean_s"),
    "offroad": ("coverage_mean", "position_rmse_m", "fragmentations"),
    "dense_clutter": ("false_tracks_per_step", "missed_per_step"),
    "two_sensors": ("coverage_mean", "identity_switches", "position_rmse_m"),
}


def scenario_metrics(scenario: str) -> List[str]:
    """Challenge metrics of ``scenario`` then the common ones, without repeats."""
    return list(dict.fromkeys([*CHALLENGE.get(scenario, ()), *COMMON]))


def headline(scenario: str) -> str:
    return CHALLENGE.get(scenario, COMMON)[0]


def derived_values(summary: Mapping[str, float], cutoff_m: float, order_p: float) -> Dict[str, float]:
    """The run's summary values plus the derived per-step counts (see the module docstring)."""
    out = {k: float(v) for k, v in summary.items()}
    unit = cutoff_m ** order_p / 2.0
    for name, source in (("false_tracks_per_step", "gospa_false_mean"),
                         ("missed_per_step", "gospa_missed_mean")):
        out[name] = out.get(source, np.nan) / unit if unit > 0 else np.nan
    return out
