"""Command-line converter ``gmtiflow-convert`` (docs/exports.md).

* run file -> format:  ``gmtiflow-convert RUN.h5 --to 4607|xml|csv|geojson [-o PATH]``
  (``--table detections|truth|tracks`` for CSV), exactly what the export stage writes.
* format -> HDF5 tables: ``gmtiflow-convert FILE.4607|.xml|.csv|.geojson --to h5 [-o OUT.h5]``,
  for 4607 from other producers and for tracks coming back from external trackers.  The output
  has the run-file layout (one group per table, units attributes; read it with
  ``gmtiflow.store.read_table``) with root attributes ``source_file``, ``source_format`` and
  ``seed = -1`` (not a simulation).

Bad input gives one line on stderr naming the file and where (byte offset, line, feature), exit
status 1, and no output file (every output is written under a temporary name and renamed).
"""
from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path
from typing import Dict, Optional, Sequence

import numpy as np

from gmtiflow import formats
from gmtiflow import export as export_mod
from gmtiflow import export_tables
from gmtiflow import frames
from gmtiflow.errors import GmtiflowError, InputFileError
from gmtiflow.paths import refuse_same_file
from gmtiflow.store import RunWriter

PROG = "gmtiflow-convert"
TO_CHOICES = ("4607", "xml", "csv", "geojson", "h5")
_FORMAT_OF_TO = {"4607": "stanag4607", "xml": "xml", "geojson": "geojson"}
_SUFFIX_FORMAT = {".4607": "4607", ".gmti": "4607", ".s4607": "4607", ".xml": "xml",
                  ".csv": "csv", ".geojson": "geojson", ".json": "geojson", ".h5": "h5",
                  ".hdf5": "h5"}
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

EPILOG = """\
examples:
  gmtiflow-convert outputs/run/run.h5 --to 4607              # -> outputs/run/detections.4607
  gmtiflow-convert run.h5 --to csv --table truth -o truth.csv
  gmtiflow-convert run.h5 --to 4607 --edition 41 --platform-location -o run41.4607
  gmtiflow-convert other.4607 --to h5 -o other.h5            # 4607 from another producer
  gmtiflow-convert other.4607 --to h5 --origin 50.63,7.13,150 # also scene ENU x_m y_m z_m
  gmtiflow-convert my_tracks.csv --to h5 -o my_tracks.h5     # tracks of an external tracker

conventions: 4607 D32.7 carries the LOS velocity corrected for platform motion; gmtiflow
tables carry the full range rate. Both directions convert (docs/exports.md).
exit status: 0 success, 1 bad input or output (one line on stderr), 2 bad arguments.
"""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG,
        description="Convert a gmtiflow run file (run.h5) to STANAG 4607, GMTI XML, CSV or "
                    "GeoJSON, or read one of those formats back into HDF5 tables.")
    p.add_argument("input", metavar="INPUT",
                   help="run.h5, or a .4607/.gmti, .xml, .csv, .geojson/.json file, or a live "
                        "4607 stream to receive: udp://[HOST]:PORT or tcp://[HOST]:PORT")
    p.add_argument("--to", required=True, choices=TO_CHOICES,
                   help="output format: 4607, xml, csv, geojson (from a run file) or h5 "
                        "(from any of the formats)")
    p.add_argument("-o", "--output", type=Path, metavar="PATH",
                   help="output file (default: beside INPUT; detections.4607, detections.xml, "
                        "<table>.csv, scene.geojson, or INPUT with the suffix .h5)")
    p.add_argument("--from", dest="source_format", choices=("4607", "xml", "csv", "geojson", "h5"),
                   help="input format when the file suffix does not tell (default: from the "
                        "suffix; HDF5 files are also recognised by their signature)")
    p.add_argument("--table", choices=export_mod.CSV_TABLES, default=None,
                   help="CSV: which table (run.h5 -> csv: default detections; csv -> h5: "
                        "default guessed from the header's id column); GeoJSON: truth writes "
                        "truth.geojson, tracks tracks.geojson (a file of their own each)")
    p.add_argument("--edition", choices=("30", "41"), default="30",
                   help="4607 edition P1: 30 = STANAG 4607 Ed. 3 (default), 41 = AEDP-4607 Ed. A")
    p.add_argument("--platform-location", action="store_true",
                   help="4607: add a Platform Location packet per /platform row")
    p.add_argument("--platform-id", default="GMTIFLOW", help="4607/XML P8 (<= 10 characters)")
    p.add_argument("--origin", metavar="LAT,LON[,H]",
                   help="4607 -> h5: scene origin (deg, deg, m HAE) to add ENU x_m y_m z_m and "
                        "scene-frame azimuths")
    p.add_argument("--max-packets", type=int, default=None, metavar="N",
                   help="live stream: stop after N packets (default: when the sender stops)")
    p.add_argument("--idle-timeout", type=float, default=5.0, metavar="S",
                   help="live stream: stop after S seconds without a packet (default 5)")
    p.add_argument("--epoch", metavar="ISO_UTC",
                   help="4607 -> h5: count time_s from this UTC instant (default: the file's "
                        "scene_epoch_utc free text, else 00:00 UTC of the mission date)")
    return p


def _fail(message: str) -> int:
    print(f"{PROG}: error: {message}", file=sys.stderr)
    return 1


def detect_format(path: Path, given: Optional[str] = None) -> str:
    """Input format from ``--from``, the HDF5 signature, or the suffix."""
    if given:
        return given
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if head == _HDF5_SIGNATURE:
        return "h5"
    fmt = _SUFFIX_FORMAT.get(path.suffix.lower())
    if fmt is None:
        raise InputFileError(f"{path}: cannot tell the format from the suffix "
                             f"{path.suffix or '(none)'!r}; use --from 4607|xml|csv|geojson|h5")
    return fmt


def _origin(text: Optional[str]) -> Optional[frames.Origin]:
    if text is None:
        return None
    try:
        parts = [float(v) for v in text.split(",")]
        if len(parts) not in (2, 3) or not (-90 <= parts[0] <= 90):
            raise ValueError
    except ValueError:
        raise InputFileError(f"--origin {text!r}: expected LAT,LON or LAT,LON,H in degrees and "
                             f"metres, e.g. 50.63,7.13,150") from None
    return frames.Origin(*parts)


def csv_kind(path: Path) -> str:
    """detections / truth / tracks from a CSV header's id column."""
    try:
        with open(path, "rb") as f:
            header = f.readline().decode("utf-8-sig", "replace")
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    cols = {c.strip() for c in header.strip().split(",")}
    found = [kind for kind, idc in (("detections", "det_id"), ("truth", "vehicle_id"),
                                    ("tracks", "track_id")) if idc in cols]
    if not found and "dwell_id" in cols:
        found = ["dwells"]
    if len(found) != 1:
        raise InputFileError(f"{path}: line 1: cannot tell the CSV table from the header (expected "
                             f"exactly one of the id columns det_id, vehicle_id, track_id, or "
                             f"dwell_id alone); use --table")
    return found[0]


def read_any(path: Path, fmt: str, *, table: Optional[str] = None,
             origin: Optional[frames.Origin] = None, epoch: Optional[str] = None):
    """Tables of a 4607/XML/CSV/GeoJSON file in gmtiflow's conventions: (tables, attrs, texts)."""
    texts: Dict[str, str] = {}
    attrs: dict = {"source_file": str(path), "source_format": fmt}
    if fmt == "4607":
        raw = formats.read_4607(path, epoch_utc=epoch)
        tables = export_tables.from_4607_tables(raw, origin)
        attrs.update({k: v for k, v in raw["attrs"].items() if v is not None})
        if origin is not None:     # the run-file root attributes of the scene frame
            attrs.update(origin_lat_deg=origin.lat_deg, origin_lon_deg=origin.lon_deg,
                         origin_height_m=origin.height_m)
    elif fmt == "xml":
        raw = formats.read_xml(path)
        tables = {"dwells": raw["dwells"], "detections": raw["detections"]}
        texts["meta"] = json.dumps(raw["meta"], default=str)
        attrs.update({k: v for k, v in raw["attrs"].items() if v is not None})
    elif fmt == "csv":
        kind = table or csv_kind(path)
        tables = {kind: formats.read_csv(path, kind)}
    elif fmt == "geojson":
        raw = formats.read_geojson(path)
        tables = {"detections": raw["detections"], "truth": raw["truth"],
                  "roads/nodes": raw["road_nodes"], "roads/edges": raw["road_edges"]}
        if raw.get("tracks"):
            tables["tracks"] = raw["tracks"]
        if raw["clutter_regions"]:
            texts["clutter_regions"] = json.dumps(
                [{k: (np.asarray(v).tolist() if np.ndim(v) else v) for k, v in r.items()}
                 for r in raw["clutter_regions"]])
        attrs.update({k: v for k, v in raw["attrs"].items() if v is not None})
    else:
        raise InputFileError(f"{path}: cannot read format {fmt!r} into tables")
    if "scene_epoch_utc" in attrs and attrs["scene_epoch_utc"] is None:
        del attrs["scene_epoch_utc"]
    return tables, attrs, texts


def write_tables_h5(out: Path, tables: Dict[str, dict], attrs: dict,
                    texts: Optional[Dict[str, str]] = None) -> Path:
    """HDF5 tables in the run-file layout (atomic; ``seed`` -1 marks 'not a simulation')."""
    for name, table in tables.items():
        for col, values in (table or {}).items():
            v = np.asarray(values)
            if v.dtype.kind in "UO" and any("\x00" in str(x) for x in v.ravel()):
                raise InputFileError(f"{out}: table {name!r} column {col!r} holds a NUL "
                                     "character, which HDF5 text cannot store")
    with RunWriter(out, seed=-1, attrs=attrs) as w:
        for name, text in (texts or {}).items():
            w.write_text(name, text)
        for name, table in tables.items():
            if table:                       # a table with no columns has nothing to store
                w.write_table(name, table)
        return w.commit()


def receive_stream(args) -> Path:
    """``gmtiflow-convert udp://:PORT --to h5``: receive a live 4607 stream, decode it with the
    file reader, write HDF5 tables (as for a .4607 file)."""
    from gmtiflow import live
    if args.to != "h5":
        raise InputFileError(f"{args.input}: a live stream converts to HDF5 tables only (--to h5)")
    if args.output is None:
        raise InputFileError(f"{args.input}: give the output file with -o OUT.h5")
    import math
    if not (math.isfinite(args.idle_timeout) and args.idle_timeout > 0):
        raise InputFileError(f"{args.input}: --idle-timeout must be a finite number of seconds "
                             f"> 0, got {args.idle_timeout!r}")
    if args.max_packets is not None and args.max_packets < 1:
        raise InputFileError(f"{args.input}: --max-packets must be at least 1, got "
                             f"{args.max_packets}")
    try:
        data = b"".join(live.receive(args.input, max_packets=args.max_packets,
                                     idle_timeout_s=args.idle_timeout))
    except ValueError as exc:
        msg = str(exc)       # name the address when the parser's message does not
        raise InputFileError(msg if args.input in msg else f"{args.input}: {msg}") from None
    except OSError as exc:
        raise InputFileError(f"{args.input}: cannot listen: {exc.strerror or exc}") from None
    if not data:
        raise InputFileError(f"{args.input}: no 4607 packet arrived within "
                             f"{args.idle_timeout:g} s")
    raw = formats.stanag4607.decode_4607(data, args.input, epoch_utc=args.epoch)
    origin = _origin(args.origin)
    tables = export_tables.from_4607_tables(raw, origin)
    attrs = {"source_file": args.input, "source_format": "4607"}
    attrs.update({k: v for k, v in raw["attrs"].items() if v is not None})
    if origin is not None:
        attrs.update(origin_lat_deg=origin.lat_deg, origin_lon_deg=origin.lon_deg,
                     origin_height_m=origin.height_m)
    return write_tables_h5(Path(args.output), tables, attrs)


def convert(args) -> Path:
    from gmtiflow import live
    if live.is_url(args.input):
        return receive_stream(args)
    args.input = Path(args.input)
    fmt = detect_format(args.input, args.source_format)
    if fmt == "h5":
        if args.to == "h5":
            raise InputFileError(f"{args.input}: is already HDF5; --to must be 4607, xml, csv or "
                                 "geojson")
        cfg = export_mod.ExportConfig(edition=args.edition,
                                      platform_location_packets=args.platform_location,
                                      platform_id=args.platform_id,
                                      geojson_truth_step_s=0.0)   # a conversion keeps every row
        problems = cfg.problems()
        if problems:
            raise InputFileError("; ".join(f"--{p.key.replace('_', '-')}: {p.message}"
                                           for p in problems))
        if args.to == "4607" and export_mod.is_converted_4607(args.input):
            out = args.output or args.input.parent / export_mod.FILE_NAMES["stanag4607"]
            export_mod.rewrite_converted_4607(args.input, out)
            return out
        run = export_mod.load_run(args.input)
        if args.to == "csv":
            name = args.table or "detections"
            key, default = f"csv:{name}", f"{name}.csv"
        elif args.to == "geojson" and args.table in ("truth", "tracks"):
            key = f"geojson:{args.table}"
            default = export_mod.FILE_NAMES[key]
        else:
            key = _FORMAT_OF_TO[args.to]
            default = export_mod.FILE_NAMES[key]
        out = args.output or args.input.parent / default
        refuse_same_file(out, [args.input])
        export_mod.write_format(key, run, cfg, out)
        return out
    if args.to != "h5":
        raise InputFileError(f"{args.input}: a {fmt} file converts to HDF5 tables only "
                             f"(--to h5); to change format, convert the run file")
    if args.input.is_file() and args.input.stat().st_size == 0:
        raise InputFileError(f"{args.input}: empty (0 bytes); nothing to convert")
    tables, attrs, texts = read_any(args.input, fmt, table=args.table,
                                    origin=_origin(args.origin), epoch=args.epoch)
    out = args.output or args.input.with_suffix(".h5")
    refuse_same_file(out, [args.input])
    return write_tables_h5(out, tables, attrs, texts)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Console script ``gmtiflow-convert``; returns the exit status."""
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format=f"{PROG}: %(message)s")
    try:
        out = convert(args)
    except (GmtiflowError, formats.FormatError) as exc:
        return _fail(str(exc))
    except ValueError as exc:              # a writer refusing a value (e.g. an XSD range)
        return _fail(f"{args.input}: cannot write --to {args.to}: {exc}")
    except OSError as exc:
        return _fail(f"{exc.filename or args.output or args.input}: "
                     f"{exc.strerror or exc}")
    print(out)
    return 0


def console() -> None:
    sys.exit(main())


if __name__ == "__main__":
    console()
