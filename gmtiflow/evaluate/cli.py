"""Command-line scorer ``gmtiflow-evaluate``: tracks from outside gmtiflow against a run's truth.

``gmtiflow-evaluate TRACKS RUN.h5 [-o OUT.h5 | --csv [-o OUT.csv]]``

TRACKS is a track CSV (:func:`formats.read_tracks_csv`: ``time_utc`` optional, ``time_s
track_id x_m y_m`` required, ``vx_mps vy_mps cov_xx_m2 cov_xy_m2 cov_yy_m2 range_rate_mps
confirmed`` optional) or an HDF5 file with a ``/tracks`` table (a run file, or the output of
``gmtiflow-convert tracks.csv --to h5``).  The table is checked with
:func:`gmtiflow.evaluate.validate_tracks` and scored with :func:`gmtiflow.evaluate.evaluate`
using the run's own ``metrics`` config (so the numbers are comparable with the run's /metrics),
against the run's /truth, /looks, /vehicles and /platform.

The summary is printed as a table on stdout and written to OUT: HDF5 with every metrics table
(``/metrics``, ``/metrics/ospa`` ... as in a run file), or with ``--csv`` (or an OUT ending in
``.csv``) the summary rows ``name,value,unit``.  A bad track file (unknown columns, times going
back within a track, two rows of one track at one time, non-numbers) gives one line on stderr,
exit status 1 and no output file.
"""
from __future__ import annotations

import argparse
import csv
import io
import logging
import sys
from pathlib import Path
from typing import Optional, Sequence

import h5py
import numpy as np
import yaml
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from gmtiflow import formats
from gmtiflow.formats import write_atomic
from gmtiflow import frames
from gmtiflow.errors import GmtiflowError, InputFileError, StoreError
from gmtiflow.evaluate import evaluate, validate_tracks
from gmtiflow.evaluate.config import MetricsConfig
from gmtiflow.evaluate.external import check_times, read_track_csv
from gmtiflow.paths import refuse_same_file
from gmtiflow.store import RunWriter, open_run, read_attrs, read_table, read_text

PROG = "gmtiflow-evaluate"

EPILOG = """\
examples:
  gmtiflow-evaluate my_tracks.csv outputs/run/run.h5            # -> my_tracks.metrics.h5
  gmtiflow-evaluate my_tracks.csv outputs/run/run.h5 --csv      # -> my_tracks.metrics.csv
  gmtiflow-evaluate my_tracks.csv run.h5 -o scores/mine.h5

track CSV columns: track_id; the time as time_s (seconds from the run's scene_epoch_utc) or
time_utc (ISO 8601); the position as x_m y_m (scene ENU metres) or lat_deg lon_deg [height_m];
optional vx_mps vy_mps, cov_xx_m2 cov_xy_m2 cov_yy_m2, range_rate_mps, confirmed. Rows of a
track must be in increasing time; a track id may appear once per time. See docs/exports.md.
exit status: 0 success, 1 bad input or output (one line on stderr), 2 bad arguments.
"""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG, formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG,
        description="Score tracks produced outside gmtiflow against the truth of a gmtiflow run "
                    "(OSPA/GOSPA, track errors, identity switches, fragmentation, track loss and "
                    "re-acquisition).")
    p.add_argument("tracks", type=Path, metavar="TRACKS",
                   help="track file: .csv (formats track CSV), or an .h5 file gmtiflow wrote "
                        "with a /tracks table (a run file, or gmtiflow-convert tracks.csv "
                        "--to h5)")
    p.add_argument("run", type=Path, metavar="RUN.h5", help="the gmtiflow run file (truth)")
    p.add_argument("-o", "--output", type=Path, metavar="OUT",
                   help="output file (default: TRACKS with the suffix .metrics.h5, or "
                        ".metrics.csv with --csv)")
    p.add_argument("--csv", action="store_true",
                   help="write the summary as CSV (name,value,unit) instead of HDF5")
    p.add_argument("--all", dest="include_unconfirmed", action="store_true",
                   help="score unconfirmed track rows too (default: the run's "
                        "metrics.confirmed_only)")
    return p


def read_tracks(path: Path, epoch_utc: Optional[str] = None) -> dict:
    """A track table from a CSV or an HDF5 file (InputFileError if unreadable); a CSV's
    ``time_utc`` is counted in seconds from ``epoch_utc``."""
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if head == b"\x89HDF\r\n\x1a\n":
        try:
            return read_table(path, "tracks")
        except StoreError:
            raise
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5", ".he5"):
        raise InputFileError(f"{path}: not an HDF5 file (no HDF5 signature); give a track .csv "
                             f"or an HDF5 file with /tracks")
    if suffix == ".xml":
        raise InputFileError(f"{path}: there is no XML track form (formats' XML carries "
                             "detections); give the tracks as CSV or HDF5")
    if suffix not in (".csv", ".txt"):
        raise InputFileError(f"{path}: expected a track .csv or an .h5 file with /tracks, "
                             f"got suffix {suffix or '(none)'!r}")
    return read_track_csv(path, epoch_utc)


def metrics_config(run_file: h5py.File, include_unconfirmed: bool = False) -> MetricsConfig:
    """The run's own ``metrics`` config (defaults where the run has none), enabled."""
    base = OmegaConf.structured(MetricsConfig)
    if "config" in run_file:
        try:
            stored = OmegaConf.create(read_text(run_file, "config"))
            if "metrics" in stored:
                base = OmegaConf.merge(base, stored.metrics)
        except (OmegaConfBaseException, ValueError, yaml.YAMLError) as exc:
            raise StoreError(f"{run_file.filename}: /config metrics section is not usable "
                             f"({exc})") from None
    cfg: MetricsConfig = OmegaConf.to_object(base)
    cfg.enabled = True
    if include_unconfirmed:
        cfg.confirmed_only = False
    return cfg


def score(tracks_path: Path, run_path: Path, include_unconfirmed: bool = False) -> dict:
    """Metrics tables of the tracks in ``tracks_path`` against the run ``run_path``."""
    with open_run(run_path, require_columns=True) as f:
        attrs = read_attrs(f)           # a damaged file: StoreError naming it
        origin = frames.Origin.from_attrs(attrs)
        epoch = str(attrs["scene_epoch_utc"]) if "scene_epoch_utc" in attrs else None
        raw = read_tracks(tracks_path, epoch)
        tracks = validate_tracks(raw, origin, str(tracks_path))
        if "truth" not in f:
            raise StoreError(f"{run_path}: has no /truth table to score against")
        cfg = metrics_config(f, include_unconfirmed)
        truth = read_table(f, "truth")
        looks = read_table(f, "looks") if "looks" in f else None
        vehicles = read_table(f, "vehicles") if "vehicles" in f else None
        platform = read_table(f, "platform") if "platform" in f else None
        first_dwell_s = last_dwell_s = None     # scored over the dwells (docs/evaluation.md)
        if "dwells" in f:
            dwell_t = read_table(f, "dwells").get("time_s")
            if dwell_t is not None and len(dwell_t):
                first_dwell_s, last_dwell_s = float(np.min(dwell_t)), float(np.max(dwell_t))
    tt = np.asarray(truth["time_s"], float)
    if len(tt):
        check_times(tracks, float(tt.min()), float(tt.max()), epoch, str(tracks_path))
    return evaluate(cfg, truth, tracks, looks, vehicles, platform, origin=origin,
                    source=str(tracks_path), until_s=last_dwell_s, since_s=first_dwell_s)


def summary_text(summary: dict) -> str:
    """The summary rows as an aligned text table."""
    names = [str(n) for n in summary["name"]]
    width = max([len("metric")] + [len(n) for n in names])
    lines = [f"{'metric':<{width}}  {'value':>14}  unit"]
    for n, v, u in zip(names, summary["value"], summary["unit"]):
        lines.append(f"{n:<{width}}  {float(v):>14.6g}  {u}")
    return "\n".join(lines)


def summary_csv(summary: dict) -> bytes:
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["name", "value", "unit"])
    for n, v, u in zip(summary["name"], summary["value"], summary["unit"]):
        w.writerow([str(n), repr(float(v)), str(u)])
    return out.getvalue().encode("utf-8")


def write_metrics(path: Path, tables: dict, as_csv: bool, attrs: dict) -> Path:
    if as_csv:
        write_atomic(path, summary_csv(tables["metrics"]))
        return path
    with RunWriter(path, seed=-1, attrs=attrs) as w:
        for name, table in tables.items():
            w.write_table(name, table)
        return w.commit()


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Console script ``gmtiflow-evaluate``; returns the exit status."""
    args = _parser().parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format=f"{PROG}: %(message)s")
    as_csv = args.csv or (args.output is not None and args.output.suffix.lower() == ".csv")
    out = args.output or args.tracks.with_name(
        args.tracks.stem + (".metrics.csv" if as_csv else ".metrics.h5"))
    try:
        refuse_same_file(out, [args.tracks, args.run])
        tables = score(args.tracks, args.run, args.include_unconfirmed)
        if not tables:
            raise InputFileError("metrics are disabled")   # pragma: no cover (forced on)
        write_metrics(out, tables, as_csv, {"tracks_file": str(args.tracks),
                                            "run_file": str(args.run)})
    except (GmtiflowError, formats.FormatError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"{PROG}: error: {exc.filename or out}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    print(summary_text(tables["metrics"]))
    print(f"wrote {out}")
    return 0


def console() -> None:
    sys.exit(main())


if __name__ == "__main__":
    console()
