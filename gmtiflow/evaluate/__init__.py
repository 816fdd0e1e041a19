"""Tracker benchmarking: the baseline NN-Kalman tracker and the track-quality metrics.

Stages (docs/evaluation.md):

* :func:`track` (``tracker.py``): /detections + /dwells -> /tracks;
* :func:`evaluate` (``stage.py``): /truth + /tracks (+ /looks, /vehicles, /platform) -> /metrics;
* :func:`validate_tracks` (``tracks.py``): checks an external tracker's table.
"""
from gmtiflow.evaluate.config import MetricsConfig, TrackerConfig
from gmtiflow.evaluate.stage import SUMMARY_NAMES, evaluate, summary_value
from gmtiflow.evaluate.tracker import track
from gmtiflow.evaluate.tracks import validate_tracks

__all__ = ["MetricsConfig", "TrackerConfig", "SUMMARY_NAMES", "evaluate", "summary_value",
           "track", "validate_tracks"]
