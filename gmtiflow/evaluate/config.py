"""Config schemas of the evaluation stages: the baseline tracker and the track-quality metrics.

Both are plain dataclasses in the style of every other group (``gmtiflow/schema.py``): unit
suffixes in the field names, degrees in config, and a ``problems()`` method for range and
cross-field checks.  ``TrackerConfig`` is the ``tracker`` group (``conf/tracker/nn_kalman.yaml``,
``conf/tracker/none.yaml``); ``MetricsConfig`` is meant for a ``metrics`` key of the app config.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

from gmtiflow.schema import Problem, in_range, non_negative, positive


@dataclass
class TrackerConfig:
    """The tracker stage: the baseline NN-Kalman tracker (``gmtiflow.evaluate.tracker``, a
    baseline, not the product) or any tracker of the protocol (``target``,
    :mod:`gmtiflow.evaluate.protocol`)."""

    enabled: bool = True
    """Run a tracker (``conf/tracker/none.yaml`` switches it off)."""
    name: str = "nn_kalman"
    """Label of the tracker (the config file's name; shown in reports)."""
    target: Optional[str] = None
    """Import path of a tracker class or factory (``mypkg.MyTracker`` or ``mypkg:MyTracker``),
    built with ``params`` as keyword arguments; empty: the baseline below."""
    params: Dict[str, Any] = field(default_factory=dict)
    """Keyword arguments of ``target`` (the baseline uses the fields below instead)."""
    per: str = "dwell"
    """What one protocol batch holds: ``dwell`` or ``revisit`` (one sensor's revisit)."""
    accel_sigma_mps2: float = 1.0
    """White-acceleration σ of the constant-velocity model (per axis; with ``cwna`` the noise
    density is σ²·1 s)."""
    process_noise: str = "cwna"
    """``cwna`` continuous white-noise acceleration (full-rank Q) or ``dwna`` discrete
    (acceleration constant over a step, rank-1 Q per axis); see :mod:`gmtiflow.evaluate.kalman`."""
    gate_probability: float = 0.999
    """Chi-square gate on the normalised innovation (probability mass inside the gate)."""
    use_range_rate: bool = True
    """Also update with the measured range rate (EKF; LOS from the dwell's platform position)."""
    init_speed_sigma_mps: float = 15.0
    """Velocity prior σ (per axis) of a track started from one detection (velocity mean 0)."""
    confirm_m: int = 3
    """M of M-of-N confirmation: hits needed among the first N covering revisits."""
    confirm_n: int = 5
    """N of M-of-N confirmation; a tentative track that cannot reach M hits in N is deleted."""
    delete_misses: int = 5
    """K: a confirmed track is deleted after K consecutive revisits that covered it (one of their
    dwells' footprints held it) without updating it."""
    max_coast_s: float = 120.0
    """Any track not updated for this long is deleted, covered or not (so tracks that no later
    footprint covers do not live on in memory)."""
    footprint_margin_m: float = 200.0
    """Margin added around a dwell's footprint when deciding whether it covered a track."""
    default_sigma_range_m: float = 20.0
    """Range σ when a detection carries none (column missing or NaN)."""
    default_sigma_azimuth_deg: float = 0.2
    """Azimuth σ when a detection carries none."""
    default_sigma_range_rate_mps: float = 1.0
    """Range-rate σ when a detection carries none."""

    def problems(self) -> List[Problem]:
        out = positive(self, "accel_sigma_mps2", "init_speed_sigma_mps", "max_coast_s",
                       "default_sigma_range_m",
                       "default_sigma_azimuth_deg", "default_sigma_range_rate_mps")
        out += non_negative(self, "footprint_margin_m")
        if self.per not in ("dwell", "revisit"):
            out.append(Problem("per", f"must be 'dwell' or 'revisit', got {self.per!r}"))
        if (self.target is not None and not str(self.target).strip()) or (
                self.target is None and self.name == "python"):
            out.append(Problem("target", "must be the import path of your tracker class, e.g. "
                                         "tracker.target=mypkg.MyTracker"))
        if self.process_noise not in ("cwna", "dwna"):
            out.append(Problem("process_noise", f"must be 'cwna' or 'dwna', got "
                                                f"{self.process_noise!r}"))
        out += in_range(self, "gate_probability", 0.0, 1.0, lo_open=True, hi_open=True)
        for name in ("confirm_m", "confirm_n", "delete_misses"):
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= 1):
                out.append(Problem(name, f"must be an integer >= 1, got {value!r}"))
        if not out and self.confirm_m > self.confirm_n:
            out.append(Problem("confirm_m", f"must be <= confirm_n ({self.confirm_n}), "
                                            f"got {self.confirm_m}"))
        if not out and self.confirm_n > 62:
            out.append(Problem("confirm_n", f"must be at most 62, got {self.confirm_n}"))
        return out


@dataclass
class MetricsConfig:
    """Track-quality metrics (``gmtiflow.evaluate.stage.evaluate``)."""

    enabled: bool = True
    cutoff_m: float = 200.0
    """OSPA/GOSPA cut-off c: a localisation error is capped at c; a miss or false track costs c.
    200 m suits GMTI: a plot's cross-range σ is R·σ_az ≈ 74 m at 30 km and a working CV track
    is ~30–50 m off (RMS) with tails past 100 m; c well below that would score a held vehicle
    as missed plus a false track (docs/evaluation.md, "Choosing c and the gate")."""
    order_p: float = 2.0
    """OSPA/GOSPA order p (>= 1)."""
    gospa_alpha: float = 2.0
    """GOSPA α; only 2 is supported (the value that splits GOSPA into localisation, missed and
    false-track parts)."""
    assoc_gate_m: float = 200.0
    """Identity association gate: a track and a truth are associated at a time step only when
    they are closer than this (CLEAR-MOT: a still-valid pairing is kept, the rest by optimal
    assignment of the pairs inside the gate: as many pairs as can be matched, then the least
    total distance, as py-motmetrics does).  Equal to ``cutoff_m`` by
    default, so identity uses GOSPA's own assignment threshold; 50 m (the old default) cut a
    correctly held GMTI track in and out at every step (coverage 0.35, 100+ fragmentations on
    the default scene)."""
    confirmed_only: bool = True
    """Score only confirmed track rows when the track table has a ``confirmed`` column."""
    eval_dt_s: Optional[float] = None
    """Step of the evaluation grid; ``None``: the truth table's own sample times."""
    max_extrapolation_s: float = 10.0
    """A track takes part at a grid time t when it has a row at or before t no older than this;
    its state is extrapolated to t at constant velocity."""
    track_end_hold_s: float = 1.0
    """A track still takes part at the grid times less than this after its last row (then it has
    ended).  The default is the default truth step, so a track ending between two grid times is
    counted at the next, and one ending at a grid time (the perfect track of a vehicle that
    leaves the road there) is not."""
    event_lookback_s: float = 15.0
    """How far before a stop / blind gap to look for the track that held the vehicle."""
    min_gap_looks: int = 1
    """Blind gaps shorter than this many looks are not scored as events."""
    min_truth_speed_mps: float = 0.0
    """MDV-gated truth: a vehicle slower than this at a grid step (ground speed; stopped) is
    not scored there — neither a miss nor a hold — and a track whose nearest vehicle is such a
    one (within ``cutoff_m``) is not a false track there.  0 (default): every truth sample is
    scored.  Real-data GMTI scoring sets it near the sensor's MDV (e.g. 2 m/s)."""

    def problems(self) -> List[Problem]:
        out = positive(self, "cutoff_m", "assoc_gate_m", "max_extrapolation_s", "event_lookback_s")
        out += positive(self, "eval_dt_s")
        out += non_negative(self, "track_end_hold_s", "min_truth_speed_mps")
        out += in_range(self, "order_p", 1.0, float("inf"), hi_open=True)
        if self.gospa_alpha != 2.0:
            out.append(Problem("gospa_alpha", f"only 2 is supported, got {self.gospa_alpha!r}"))
        if not (isinstance(self.min_gap_looks, int) and self.min_gap_looks >= 1):
            out.append(Problem("min_gap_looks", f"must be an integer >= 1, got "
                                                f"{self.min_gap_looks!r}"))
        return out
