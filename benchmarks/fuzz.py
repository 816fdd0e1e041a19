"""Fuzz every reader that takes a file from a user: only the project's own errors may escape.

Targets (``TARGETS``): the STANAG-4607, XML, CSV and GeoJSON readers of :mod:`formats` (allowed:
``FormatError``) and gmtiflow's OSM, GeoJSON road-map, RCS-table and ASCII-grid DEM loaders
(allowed: ``InputFileError`` and its subclasses).  Each target has valid seed documents; a case
is a seed mutated by truncation, byte flips, splices, repeats or a random byte string.  Anything
else escaping (``struct.error``, ``IndexError``, ``KeyError``, numpy errors, ...) is a crash.

The CI tests (``tests/reliability/test_fuzz.py``) run a small fixed budget of these cases under
hypothesis; this script runs the long budget and prints the case count per reader::

    python benchmarks/fuzz.py                      # 2000 mutation cases per target
    python benchmarks/fuzz.py --cases 20000 --target 4607 xml
    python benchmarks/fuzz.py --atheris 4607 -- -runs=100000   # coverage-guided, if installed

Exit status 1 if any case crashed; each crash is written to ``fuzz-crashes/<target>-<n>.bin``.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Callable, Dict, List, Sequence, Tuple

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def _instrumented():
    """Under ``--atheris``, the project's modules are imported with coverage instrumentation
    (only ``formats`` and ``gmtiflow``: instrumenting numpy/lxml too makes it 50x slower)."""
    if __name__ == "__main__" and "--atheris" in sys.argv:
        import atheris
        return atheris.instrument_imports(include=["formats", "gmtiflow"])
    return contextlib.nullcontext()


with _instrumented():
    from gmtiflow.formats import csvtable, geojson, stanag4607, synthetic, xmldoc  # noqa: E402
    from gmtiflow.formats.errors import FormatError  # noqa: E402
    from gmtiflow.errors import InputFileError  # noqa: E402
    from gmtiflow.scene.dem import read_ascii_grid  # noqa: E402
    from gmtiflow.scene.geojson_roads import load_geojson  # noqa: E402
    from gmtiflow.scene.osm import load_osm  # noqa: E402
    from gmtiflow.sensor.rcs import load_table  # noqa: E402

META = {"epoch_utc": synthetic.EPOCH_UTC}

SMALL_OSM = b"""<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6">
 <node id="1" lat="43.7300" lon="7.4200"/>
 <node id="2" lat="43.7310" lon="7.4210"/>
 <node id="3" lat="43.7320" lon="7.4230"/>
 <way id="10"><nd ref="1"/><nd ref="2"/><nd ref="3"/>
  <tag k="highway" v="primary"/><tag k="maxspeed" v="50"/><tag k="oneway" v="yes"/></way>
 <way id="11"><nd ref="3"/><nd ref="1"/><tag k="highway" v="residential"/></way>
</osm>
"""

SMALL_ROADS_GEOJSON = json.dumps({"type": "FeatureCollection", "features": [
    {"type": "Feature", "properties": {"highway": "primary", "maxspeed": "50"},
     "geometry": {"type": "LineString",
                  "coordinates": [[7.42, 43.73], [7.421, 43.731], [7.423, 43.732]]}},
    {"type": "Feature", "properties": {"oneway": "yes"},
     "geometry": {"type": "MultiLineString",
                  "coordinates": [[[7.423, 43.732], [7.42, 43.73]]]}}]}).encode()

RCS_TABLE = b"aspect_deg,rcs_dbsm\n# a truck\n0,20\n45,14.5\n90,25\n180,18\n270,25\n"

ASCII_GRID = (b"ncols 4\nnrows 3\nxllcorner -1000\nyllcorner -500\ncellsize 250\n"
              b"NODATA_value -9999\n10 11 12 13\n9 -9999 11 12\n8 9 10 11\n")


def _seeds_4607() -> List[bytes]:
    dwells, dets = synthetic.tables(3, 8)
    out = [stanag4607.encode_4607(dwells, dets, META)]
    list1 = ROOT.parent.parent / "shared/data/list1.4607"
    if not list1.is_file():
        list1 = Path("/work/shared/data/list1.4607")
    if list1.is_file():
        out.append(list1.read_bytes()[:4096])
    return out


def _seeds_xml() -> List[bytes]:
    dwells, dets = synthetic.tables(2, 4)
    return [xmldoc.encode_xml(dwells, dets, META)]


def _seeds_csv() -> List[bytes]:
    dwells, dets = synthetic.tables(2, 6)
    return [csvtable.encode_csv(dets, "detections", epoch_utc=META["epoch_utc"])]


def _seeds_csv_truth() -> List[bytes]:
    return [csvtable.encode_csv(synthetic.truth(2, 3), "truth", epoch_utc=META["epoch_utc"])]


def _seeds_geojson() -> List[bytes]:
    dwells, dets = synthetic.tables(2, 4)
    # scene.geojson and truth.geojson are separate documents (truth's per-vertex list
    # properties would clash with the detections' scalars: one property, one type)
    return [geojson.encode_geojson(detections=dets, epoch_utc=META["epoch_utc"]),
            geojson.encode_geojson(truth=synthetic.truth(2, 3), epoch_utc=META["epoch_utc"]),
            geojson.encode_geojson(tracks=_tracks_geodetic(), epoch_utc=META["epoch_utc"])]


def _tracks_geodetic() -> dict:
    """synthetic tracks with the 2-D positions tracks.geojson draws."""
    t = synthetic.tracks(2, 3)
    return dict(t, lat_deg=43.7 + t["y_m"] / 111e3, lon_deg=7.4 + t["x_m"] / 80e3)


def _on_file(loader: Callable, suffix: str) -> Callable[[bytes], object]:
    """Run a path-taking loader on bytes written to a temporary file."""
    def call(data: bytes):
        fd, name = tempfile.mkstemp(suffix=suffix)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            return loader(name)
        finally:
            os.unlink(name)
    return call


def _roadmap_ok(roadmap) -> None:
    """A road map a loader accepted must be usable: finite coordinates, edges on its nodes."""
    nodes, edges = roadmap.nodes, roadmap.edges
    for c in ("x_m", "y_m", "z_m"):
        if c in nodes and not np.all(np.isfinite(nodes[c])):
            raise AssertionError(f"accepted road map has non-finite node {c}")
    ids = set(np.asarray(nodes["node_id"]).tolist())
    for c in ("from_node", "to_node"):
        if c in edges and not set(np.asarray(edges[c]).tolist()) <= ids:
            raise AssertionError(f"accepted road map has edges to unknown nodes ({c})")


def _osm(data: bytes):
    _roadmap_ok(_on_file(load_osm, ".osm")(data))


def _roads_geojson(data: bytes):
    _roadmap_ok(_on_file(load_geojson, ".geojson")(data))


def _rcs(data: bytes):
    aspect, rcs = _on_file(load_table, ".csv")(data)
    if not (np.all(np.isfinite(aspect)) and np.all(np.isfinite(rcs))
            and np.all(np.diff(aspect) > 0)):
        raise AssertionError("accepted RCS table is not finite and sorted")


def _dem(data: bytes):
    grid = _on_file(read_ascii_grid, ".asc")(data)
    z = np.asarray(grid.z)
    if z.size and not np.all(np.isfinite(z)):
        raise AssertionError("accepted DEM (voids=fill) still holds NaN cells")


TARGETS: Dict[str, Tuple[Callable[[], List[bytes]], Callable[[bytes], object], tuple]] = {
    "4607": (_seeds_4607, stanag4607.read_4607, (FormatError,)),
    "xml": (_seeds_xml, xmldoc.read_xml, (FormatError,)),
    "csv": (_seeds_csv, csvtable.read_detections_csv, (FormatError,)),
    "csv_truth": (_seeds_csv_truth, csvtable.read_truth_csv, (FormatError,)),
    "geojson": (_seeds_geojson, geojson.read_geojson, (FormatError,)),
    "osm": (lambda: [SMALL_OSM], _osm, (InputFileError,)),
    "roads_geojson": (lambda: [SMALL_ROADS_GEOJSON], _roads_geojson, (InputFileError,)),
    "rcs": (lambda: [RCS_TABLE], _rcs, (InputFileError,)),
    "dem_ascii": (lambda: [ASCII_GRID], _dem, (InputFileError,)),
}

_TOKENS = [b"0", b"-1", b"1e308", b"nan", b"inf", b"-inf", b"\xff\xfe", b"\x00", b"<", b">",
           b"&amp;", b'"', b",", b"\n", b"{", b"}", b"[", b"]", b"null", b"true", b"9" * 30,
           b"\xff" * 4, b"\x7f\xff\xff\xff", b"\x00\x00\x00\x00", b"ref=\"999\"", b"lat=\"91\"",
           b"<!DOCTYPE x [<!ENTITY e \"e\">]>", b"&e;", b"highway"]


def mutate(seed: bytes, rng: np.random.Generator) -> bytes:
    """One mutated case: a mix of truncations, byte flips, token insertions, splices, repeats."""
    b = bytearray(seed)
    kind = int(rng.integers(0, 7))
    if kind == 0:
        return bytes(b[: int(rng.integers(0, len(b) + 1))])
    if kind == 1:
        return rng.integers(0, 256, int(rng.integers(0, 300)), dtype=np.uint8).tobytes()
    for _ in range(int(rng.integers(1, 5))):
        if not b:
            break
        i = int(rng.integers(0, len(b)))
        if kind == 2:
            b[i] = int(rng.integers(0, 256))
        elif kind == 3:
            b[i:i] = _TOKENS[int(rng.integers(0, len(_TOKENS)))]
        elif kind == 4:
            j = int(rng.integers(i, min(len(b), i + 64) + 1))
            del b[i:j]
        elif kind == 5:
            j = int(rng.integers(i, min(len(b), i + 64) + 1))
            b[i:i] = b[i:j] * int(rng.integers(2, 5))
        else:                       # overwrite a 4-byte field (lying size/count fields in 4607)
            b[i:i + 4] = bytes(rng.integers(0, 256, 4, dtype=np.uint8))
    return bytes(b)


def run_case(target: str, data: bytes):
    """Feed ``data`` to ``target``; returns None (accepted or refused properly) or the exception."""
    _, call, allowed = TARGETS[target]
    try:
        call(data)
    except allowed:
        return None
    except Exception as exc:        # noqa: BLE001 - anything else is the finding
        return exc
    return None


def fuzz(target: str, cases: int, seed: int = 0, crash_dir: Path | None = None) -> Tuple[int, int]:
    """Run ``cases`` mutation cases on ``target``; returns (cases run, crashes)."""
    rng = np.random.default_rng([seed, sum(target.encode())])
    seeds = TARGETS[target][0]()
    crashes = 0
    for n in range(cases):
        data = mutate(seeds[n % len(seeds)], rng)
        exc = run_case(target, data)
        if exc is not None:
            crashes += 1
            print(f"{target} case {n}: {type(exc).__name__}: {exc}", file=sys.stderr)
            if crash_dir is not None:
                crash_dir.mkdir(parents=True, exist_ok=True)
                (crash_dir / f"{target}-{n}.bin").write_bytes(data)
    return cases, crashes


def run_atheris(target: str, argv: Sequence[str]) -> None:  # pragma: no cover - optional
    import atheris

    seeds = TARGETS[target][0]()

    def one(data: bytes) -> None:
        fdp = atheris.FuzzedDataProvider(data)
        pick = fdp.ConsumeIntInRange(0, 2)
        body = fdp.ConsumeBytes(len(data))
        case = body if pick == 0 else seeds[0][: len(body)] + body if pick == 1 else \
            bytes(a ^ b for a, b in zip(seeds[0], body + bytes(len(seeds[0]))))
        exc = run_case(target, case)
        if exc is not None:
            raise exc

    atheris.Setup([sys.argv[0], *argv], one)
    atheris.Fuzz()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=2000, help="mutation cases per target")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--target", nargs="*", default=sorted(TARGETS), choices=sorted(TARGETS))
    ap.add_argument("--crash-dir", type=Path, default=Path("fuzz-crashes"))
    ap.add_argument("--atheris", metavar="TARGET", choices=sorted(TARGETS),
                    help="run coverage-guided fuzzing of one target with atheris (optional)")
    args, rest = ap.parse_known_args(argv)
    if args.atheris:
        run_atheris(args.atheris, rest)
        return 0
    total_crashes = 0
    print(f"{'target':<14} {'cases':>8} {'crashes':>8} {'seconds':>8}")
    for target in args.target:
        start = time.perf_counter()
        try:
            n, crashes = fuzz(target, args.cases, args.seed, args.crash_dir)
        except Exception:               # a broken seed is a bug of this script
            traceback.print_exc()
            return 2
        total_crashes += crashes
        print(f"{target:<14} {n:>8} {crashes:>8} {time.perf_counter() - start:>8.1f}")
    return 1 if total_crashes else 0


if __name__ == "__main__":
    sys.exit(main())
