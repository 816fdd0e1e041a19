"""Converter toolset: gmtiflow tables <-> STANAG 4607, GMTI XML, CSV and GeoJSON.

A leaf package (numpy and lxml only; it never imports gmtiflow).  Every format has a writer and
a reader; readers raise :class:`FormatError` for malformed input.  See ``docs/formats.md``.
"""
from pathlib import Path as _Path

from ._io import atomic_path, write_atomic
from .errors import FormatError

# The writers and readers (and lxml behind the XML ones) load on first use (PEP 562): a caller
# that needs only write_atomic (gmtiflow.rundir, on every start-up) does not pay for them, and
# importing any public name from this package works as before.
_LAZY = {
    "read_csv": "csvtable", "read_detections_csv": "csvtable", "read_tracks_csv": "csvtable",
    "read_truth_csv": "csvtable", "write_csv": "csvtable", "write_detections_csv": "csvtable",
    "write_tracks_csv": "csvtable", "write_truth_csv": "csvtable",
    "read_geojson": "geojson", "write_geojson": "geojson",
    "iter_packets": "stanag4607", "read_4607": "stanag4607", "write_4607": "stanag4607",
    "read_xml": "xmldoc", "validate_xml": "xmldoc", "write_xml": "xmldoc",
    "shared_columns": "_text",
}

_SUBMODULES = frozenset(p.stem for p in _Path(__file__).parent.iterdir()
                        if p.suffix == ".py" and p.stem != "__init__" or
                        (p / "__init__.py").is_file())


def __getattr__(name: str):
    from importlib import import_module
    module = _LAZY.get(name)
    if module is None:      # a submodule (``formats.xmldoc.DETECTION_COLUMNS``) loads on use too
        if name in _SUBMODULES:
            return import_module(f".{name}", __name__)
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


__all__ = [
    "FormatError", "atomic_path", "write_atomic",
    "write_4607", "read_4607", "iter_packets",
    "write_xml", "read_xml", "validate_xml",
    "write_csv", "read_csv", "write_detections_csv", "read_detections_csv",
    "write_truth_csv", "read_truth_csv", "write_tracks_csv", "read_tracks_csv",
    "write_geojson", "read_geojson", "shared_columns",
]
