"""Tracker benchmarking: the baseline NN-Kalman tracker and the track-quality metrics.

Stages (docs/evaluation.md):

* :func:`track` (``tracker.py``): /detections + /dwells -> /tracks;
* :func:`evaluate` (``stage.py``): /truth + /tracks (+ /looks, /vehicles, /platform) -> /metrics;
* :func:`validate_tracks` (``tracks.py``): checks an external tracker's table.

The stages are imported on first use (scipy.optimize/scipy.stats cost seconds), so the config
schema (:mod:`gmtiflow.config` imports this package) loads fast.
"""
from gmtiflow.evaluate.config import MetricsConfig, TrackerConfig

__all__ = ["MetricsConfig", "TrackerConfig", "SUMMARY_NAMES", "evaluate", "summary_value",
           "track", "validate_tracks"]


_LAZY = {"SUMMARY_NAMES": "stage", "evaluate": "stage", "summary_value": "stage",
         "track": "tracker", "validate_tracks": "tracks"}


def __getattr__(name):
    if name in _LAZY:
        import importlib
        value = getattr(importlib.import_module(f"gmtiflow.evaluate.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
