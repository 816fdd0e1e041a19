"""Converter toolset: gmtiflow tables <-> STANAG 4607, GMTI XML, CSV and GeoJSON.

A leaf package (numpy and lxml only; it never imports gmtiflow).  Every format has a writer and
a reader; readers raise :class:`FormatError` for malformed input.  See ``docs/formats.md``.
"""
from ._io import atomic_path, write_atomic
from .csvtable import (read_csv, read_detections_csv, read_tracks_csv, read_truth_csv,
                       write_csv, write_detections_csv, write_tracks_csv, write_truth_csv)
from .errors import FormatError
from .geojson import read_geojson, write_geojson
from .stanag4607 import iter_packets, read_4607, write_4607
from .xmldoc import read_xml, validate_xml, write_xml

__all__ = [
    "FormatError", "atomic_path", "write_atomic",
    "write_4607", "read_4607", "iter_packets",
    "write_xml", "read_xml", "validate_xml",
    "write_csv", "read_csv", "write_detections_csv", "read_detections_csv",
    "write_truth_csv", "read_truth_csv", "write_tracks_csv", "read_tracks_csv",
    "write_geojson", "read_geojson",
]
