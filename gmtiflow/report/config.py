"""ReportConfig: what the run report draws and how much of a big run it draws (group ``report``)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import List

from gmtiflow.schema import Problem, non_negative, positive


@dataclass
class ReportConfig:
    """Run report (``report.pdf`` in the run dir) and sweep report options.

    Big runs are subsampled, never truncated silently: every figure that drops points says so in
    its title.
    """

    enabled: bool = True
    """Build ``report.pdf`` after the run file is written (the pipeline hook checks this)."""
    filename: str = "report.pdf"
    """Name of the run report, in the run directory."""
    max_points: int = 20000
    """Most points per scatter layer (detections, looks, tracks); more are subsampled evenly."""
    max_footprints: int = 12
    """Revisits whose beam footprints are drawn on the map (evenly spread over the run)."""
    max_timeline_vehicles: int = 40
    """Vehicles shown on the per-vehicle timeline page (the first by id)."""
    max_track_lines: int = 200
    """Longest tracks drawn on the map and on the track-error page."""
    snr_bin_db: float = 1.0
    """Bin width of the empirical Pd-vs-SNR curve, dB."""
    dpi: int = 100
    """Resolution of rasterised dense layers in the PDF."""
    animation: bool = False
    """Also write an animated GIF (``report.gif``) of truth, detections and tracks per revisit."""
    animation_max_frames: int = 60
    animation_fps: float = 4.0
    viewer: bool = False
    """Also write the interactive scene viewer (``viewer.html``, offline; ``gmtiflow-view``)."""
    viewer_filename: str = "viewer.html"
    viewer_max_frames: int = 150
    """Most viewer frames (revisits, evenly spread over the run)."""
    viewer_max_labels: int = 60
    """Id labels, trails and covariance ellipses only while a frame shows at most this many."""
    sweep_filename: str = "sweep_report.pdf"
    """Name of the comparison report written into a sweep dir by the Hydra callback."""

    def problems(self) -> List[Problem]:
        out = positive(self, "max_points", "max_footprints", "max_timeline_vehicles",
                       "max_track_lines", "snr_bin_db", "dpi", "animation_max_frames",
                       "animation_fps", "viewer_max_frames")
        out += non_negative(self, "viewer_max_labels")
        if not self.viewer_filename.endswith(".html") or "/" in self.viewer_filename:
            out.append(Problem("viewer_filename", f"must be a file name ending in .html, got "
                                                  f"{self.viewer_filename!r}"))
        for key in ("filename", "sweep_filename"):
            name = getattr(self, key)
            if not name.endswith(".pdf") or "/" in name:
                out.append(Problem(key, f"must be a file name ending in .pdf, got {name!r}"))
        return out
