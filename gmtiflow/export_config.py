"""What the export stage writes beside ``run.h5``: the ``export`` config group
(``conf/export/*.yaml``; :mod:`gmtiflow.export` writes it, docs/exports.md lists every key)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional

from gmtiflow.live import StreamConfig
from gmtiflow.schema import Problem, non_negative

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
    1,000-vehicle, 30-min scene makes a 124 MB truth.csv (``gmtiflow-convert RUN.h5 --to csv
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
        if not (math.isfinite(self.stream.speed) and self.stream.speed >= 0):
            out.append(Problem("stream.speed", f"must be a finite number >= 0 (0 = unpaced), "
                                               f"got {self.stream.speed}"))
        if self.pd is not None and not 0.0 <= self.pd <= 1.0:
            out.append(Problem("pd", f"must be a probability in [0, 1], got {self.pd}"))
        return out
