"""Elevation grids and the files they come from (terrain, issue 4).

Two kinds of regular grid, both "pixel is point" (a value sits exactly on a grid node and the
surface between nodes is the bilinear interpolant of the four surrounding nodes):

* :class:`GeoGrid` -- a geodetic grid (rows north to south, columns west to east, equal spacing in
  degrees), as SRTM ``.hgt`` tiles are. Values are metres above the EGM96 geoid.
* :class:`EnuGrid` -- a grid in the scene's ENU metres (rows south to north here, ``z[i, j]`` at
  ``y0 + i*dy, x0 + j*dx``), as the ESRI ASCII grids read by :func:`read_ascii_grid` and the
  generated ``hills`` terrain are. Values are scene ENU z (metres).

Readers raise :class:`~gmtiflow.errors.InputFileError` naming the file (and the line for text
files) whenever a file is not the grid it claims to be. Void samples are either filled by
:func:`fill_voids` (Laplace interpolation from the valid neighbours) or refused.
"""
from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import List, Optional, Sequence, Tuple

import numpy as np

from gmtiflow.errors import InputFileError
from gmtiflow.paths import check_input_file, excerpt

log = logging.getLogger(__name__)

SRTM_VOID = -32768
MAX_VOID_COMPONENT = 100_000
"""Largest connected void (samples, 4-connected) filled by one sparse solve; a bigger one
(about 316 x 316 samples, 9.5 x 9.5 km of SRTM3) is refused: no data to interpolate from."""
MAX_ASCII_GRID_BYTES = 2 * 2**30
"""ESRI ASCII grids are parsed in memory (about 12 times their size)."""
#: samples per side of an SRTM tile -> name of the product
SRTM_SIZES = {1201: "SRTM3 (3 arc-second)", 3601: "SRTM1 (1 arc-second)"}
_HGT_NAME = re.compile(r"^([NS])(\d{2})([EW])(\d{3})\.hgt$", re.IGNORECASE)


# --------------------------------------------------------------------------------------------
# bilinear interpolation on a regular grid
# --------------------------------------------------------------------------------------------
def bilinear(values: np.ndarray, row, col) -> np.ndarray:
    """Bilinear interpolation of ``values`` at fractional (row, col) indices, vectorised.

    Points outside ``[0, nrows-1] x [0, ncols-1]`` give NaN; a NaN node gives NaN for every
    point whose cell touches it. Exact for any function ``a + b*row + c*col`` (and for
    ``d*row*col``): the tests check planes.
    """
    row = np.asarray(row, dtype=float)
    col = np.asarray(col, dtype=float)
    nr, nc = values.shape
    inside = (row >= 0.0) & (row <= nr - 1) & (col >= 0.0) & (col <= nc - 1)
    r = np.where(inside, row, 0.0)
    c = np.where(inside, col, 0.0)
    # The last row/column belongs to the cell before it, so that the far edge is still inside.
    r0 = np.minimum(np.floor(r).astype(np.intp), max(nr - 2, 0))
    c0 = np.minimum(np.floor(c).astype(np.intp), max(nc - 2, 0))
    fr = r - r0
    fc = c - c0
    r1 = np.minimum(r0 + 1, nr - 1)
    c1 = np.minimum(c0 + 1, nc - 1)
    v00 = values[r0, c0]
    v01 = values[r0, c1]
    v10 = values[r1, c0]
    v11 = values[r1, c1]
    out = (v00 * (1.0 - fc) + v01 * fc) * (1.0 - fr) + (v10 * (1.0 - fc) + v11 * fc) * fr
    return np.where(inside, out, np.nan)


@dataclass
class GeoGrid:
    """A geodetic grid: ``values[i, j]`` at ``lat = lat_max_deg - i*step_deg``,
    ``lon = lon_min_deg + j*step_deg``. NaN where there is no data (outside the tiles)."""

    values: np.ndarray
    lat_max_deg: float
    lon_min_deg: float
    step_deg: float
    source: str  # file name(s), for messages

    @property
    def lat_min_deg(self) -> float:
        return self.lat_max_deg - (self.values.shape[0] - 1) * self.step_deg

    @property
    def lon_max_deg(self) -> float:
        return self.lon_min_deg + (self.values.shape[1] - 1) * self.step_deg

    def at(self, lat_deg, lon_deg) -> np.ndarray:
        """Bilinear value at (lat, lon); NaN outside the grid or in a no-data cell."""
        row = (self.lat_max_deg - np.asarray(lat_deg, float)) / self.step_deg
        col = (np.asarray(lon_deg, float) - self.lon_min_deg) / self.step_deg
        return bilinear(self.values, row, col)


@dataclass
class EnuGrid:
    """A grid in scene ENU metres: ``z[i, j]`` at ``x = x0_m + j*dx_m``, ``y = y0_m + i*dy_m``
    (row 0 is the south edge). ``outside_z_m`` is the height returned off the grid (NaN =
    unknown)."""

    z: np.ndarray
    x0_m: float
    y0_m: float
    dx_m: float
    dy_m: float
    source: str
    outside_z_m: float = math.nan

    @property
    def x1_m(self) -> float:
        return self.x0_m + (self.z.shape[1] - 1) * self.dx_m

    @property
    def y1_m(self) -> float:
        return self.y0_m + (self.z.shape[0] - 1) * self.dy_m

    def at(self, x_m, y_m) -> np.ndarray:
        """Bilinear z at (x, y); ``outside_z_m`` off the grid, NaN in a no-data cell."""
        x = np.asarray(x_m, float)
        y = np.asarray(y_m, float)
        out = bilinear(self.z, (y - self.y0_m) / self.dy_m, (x - self.x0_m) / self.dx_m)
        if not math.isnan(self.outside_z_m):
            off = (x < self.x0_m) | (x > self.x1_m) | (y < self.y0_m) | (y > self.y1_m)
            out = np.where(off, self.outside_z_m, out)
        return out


# --------------------------------------------------------------------------------------------
# voids
# --------------------------------------------------------------------------------------------
def fill_voids(values: np.ndarray, void: np.ndarray) -> np.ndarray:
    """Fill the ``void`` cells of ``values`` by Laplace interpolation, in place and returned.

    Each void cell takes the mean of its 4 neighbours (fewer at the grid edge), valid neighbours
    held fixed: the smoothest surface through the valid rim of each hole (a membrane), bounded
    by the rim's min and max, the usual way to patch SRTM voids.  The holes are independent
    (4-connected components of the void mask): they are solved in batches of at most
    :data:`MAX_VOID_COMPONENT` unknowns, so time and memory stay bounded; a single hole larger
    than that, or a grid that is all void, raises ValueError.
    """
    import scipy.ndimage
    void = np.asarray(void, bool)
    n_void = int(void.sum())
    if n_void == 0:
        return values
    if n_void == void.size:
        raise ValueError("every sample is void: nothing to interpolate from")
    labels, n_comp = scipy.ndimage.label(void)
    sizes = np.bincount(labels.ravel(), minlength=n_comp + 1)[1:]
    biggest = int(sizes.max())
    if biggest > MAX_VOID_COMPONENT:
        k = int(np.argmax(sizes)) + 1
        rows, cols = np.nonzero(labels == k)
        raise ValueError(
            f"a void of {biggest} samples (rows {rows.min()}-{rows.max()}, columns "
            f"{cols.min()}-{cols.max()}) is larger than the {MAX_VOID_COMPONENT} samples that "
            f"can be interpolated; use a DEM with fewer voids or terrain.voids=refuse")
    # batches of whole components, each at most MAX_VOID_COMPONENT unknowns
    batch_of = np.zeros(n_comp + 1, np.int64)
    total, batch = 0, 0
    for k, size in enumerate(sizes, start=1):
        if total + size > MAX_VOID_COMPONENT:
            batch, total = batch + 1, 0
        batch_of[k] = batch
        total += size
    batch_map = batch_of[labels]
    for b in range(batch + 1):
        _laplace_solve(values, void & (batch_map == b))
    return values


def _laplace_solve(values: np.ndarray, void: np.ndarray) -> np.ndarray:
    """Laplace-fill the ``void`` cells of ``values`` in place: one sparse solve over them
    (each a union of whole 4-connected void components, so no void neighbour lies outside)."""
    n_void = int(void.sum())
    nr, nc = values.shape
    idx = -np.ones(values.shape, dtype=np.intp)
    rows, cols = np.nonzero(void)
    idx[rows, cols] = np.arange(n_void)
    diag = np.zeros(n_void)
    rhs = np.zeros(n_void)
    a_rows: List[np.ndarray] = []
    a_cols: List[np.ndarray] = []
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        rr = rows + dr
        cc = cols + dc
        ok = (rr >= 0) & (rr < nr) & (cc >= 0) & (cc < nc)
        diag[ok] += 1.0
        k = np.nonzero(ok)[0]
        nb_void = void[rr[k], cc[k]]
        # void neighbour: off-diagonal -1; valid neighbour: moves to the right-hand side
        a_rows.append(k[nb_void])
        a_cols.append(idx[rr[k[nb_void]], cc[k[nb_void]]])
        kv = k[~nb_void]
        np.add.at(rhs, kv, values[rr[kv], cc[kv]])
    off_r = np.concatenate(a_rows)
    off_c = np.concatenate(a_cols)
    import scipy.sparse    # imported here: scipy.sparse costs ~0.5 s at start-up
    import scipy.sparse.linalg
    mat = scipy.sparse.csr_matrix(
        (np.concatenate([diag, -np.ones(off_r.size)]),
         (np.concatenate([np.arange(n_void), off_r]), np.concatenate([np.arange(n_void), off_c]))),
        shape=(n_void, n_void))
    values[rows, cols] = scipy.sparse.linalg.spsolve(mat.tocsc(), rhs)
    return values


def _handle_voids(values: np.ndarray, void: np.ndarray, voids: str, source: str) -> np.ndarray:
    """Apply the void policy ('fill' | 'refuse') to a float grid (NaN = no data, not void)."""
    n_void = int(void.sum())
    if n_void == 0:
        return values
    if voids == "refuse":
        raise InputFileError(
            f"{source}: {n_void} void samples (no-data value) and terrain.voids=refuse; "
            f"set terrain.voids=fill to interpolate them from their neighbours")
    try:
        fill_voids(values, void)
    except ValueError as exc:
        raise InputFileError(f"{source}: cannot fill voids: {exc}") from None
    log.info("%s: filled %d void samples by Laplace interpolation from their neighbours",
             source, n_void)
    return values


# --------------------------------------------------------------------------------------------
# SRTM .hgt
# --------------------------------------------------------------------------------------------
def hgt_corner(path: Path) -> Tuple[int, int]:
    """South-west corner (lat, lon) in whole degrees from an SRTM tile name like N43E007.hgt."""
    m = _HGT_NAME.match(Path(path).name)
    if not m:
        raise InputFileError(
            f"{path}: not an SRTM tile name; expected e.g. N43E007.hgt (the name gives the "
            f"south-west corner: N/S two-digit latitude, E/W three-digit longitude)")
    lat = int(m.group(2)) * (1 if m.group(1).upper() == "N" else -1)
    lon = int(m.group(4)) * (1 if m.group(3).upper() == "E" else -1)
    if not (-90 <= lat <= 89 and -180 <= lon <= 179):
        raise InputFileError(
            f"{path}: no SRTM tile has its south-west corner at lat {lat}, lon {lon}; the "
            f"corner's latitude is in [S90, N89] and its longitude in [W180, E179]")
    return lat, lon


def read_hgt(path, voids: str = "fill") -> GeoGrid:
    """Read one SRTM ``.hgt`` tile (1201² SRTM3 or 3601² SRTM1, inferred from the file size).

    Big-endian int16, metres above the EGM96 geoid, row 0 at the north edge, the tile's name
    giving its south-west corner. Voids (-32768) are filled or refused (``voids``).
    """
    return read_hgt_tiles([path], voids=voids)


def _read_hgt_raw(path: Path) -> Tuple[np.ndarray, int]:
    if not path.is_file():
        raise InputFileError(f"{path}: SRTM tile not found (relative paths are taken from the "
                             f"current directory {Path.cwd()}; pass an absolute path)")
    size = path.stat().st_size
    for n in SRTM_SIZES:
        if size == 2 * n * n:
            break
    else:
        expected = " or ".join(f"{2 * n * n} B ({name}, {n}x{n})" for n, name in SRTM_SIZES.items())
        raise InputFileError(f"{path}: {size} B is not an SRTM .hgt tile; expected {expected}")
    raw = np.fromfile(path, dtype=">i2").reshape(n, n)
    _check_heights(path, raw)
    return raw, n


MAP_Z_RANGE_M = (-11000.0, 11000.0)
"""Terrain heights as map z (metres above the surface through the scene origin) that lie on the
earth: its surface spans about -430 to 8,849 m and the origin's height is within -1,000..10,000 m
(``roadmap.origin_height_m``).  Beyond them (-1e7 m, 1e30 m, heights in millimetres) the run
used to end in an unrelated error ("tracker ...: negative variance") or see nothing."""

SURFACE_HEIGHT_RANGE_M = (-1000, 9000)
"""Heights of the earth's surface, above the geoid or the WGS-84 ellipsoid alike (the Dead Sea
shore is about -430 m, Everest 8,849 m; the two datums differ by at most ~100 m): what an SRTM
tile can hold, voids aside, and what a GeoJSON road map's heights can be."""


def _check_heights(path: Path, raw: np.ndarray) -> None:
    """InputFileError for a height outside :data:`SURFACE_HEIGHT_RANGE_M` (not a void): a tile
    written little-endian (150 m reads as -27,136 m) or damaged; such tiles used to be used as
    they were, hiding every vehicle behind tens of kilometres of terrain."""
    lo, hi = SURFACE_HEIGHT_RANGE_M
    bad = ((raw < lo) | (raw > hi)) & (raw != SRTM_VOID)
    if bad.any():
        r, c = np.unravel_index(int(np.argmax(bad)), raw.shape)
        raise InputFileError(
            f"{path}: {int(bad.sum())} heights outside {lo}..{hi} m, the first {int(raw[r, c])} m "
            f"at row {r}, column {c}; is the tile byte-swapped (SRTM is big-endian int16) or "
            f"damaged?")


def read_hgt_tiles(paths: Sequence, voids: str = "fill") -> GeoGrid:
    """Read SRTM tiles and stitch them into one :class:`GeoGrid`.

    Neighbouring tiles share their edge row/column (both hold the samples on the whole-degree
    line); the stitched grid holds each shared sample once. Where both tiles have a value they
    should agree; a void on one side is taken from the other. Cells of the bounding rectangle
    that no tile covers are NaN (no data: outside the DEM). With ``voids="refuse"`` the first
    tile with voids raises InputFileError naming it and its void count; with ``"fill"`` voids
    left after stitching are filled by :func:`fill_voids` and logged with their count.
    """
    paths = [Path(p) for p in paths]
    if not paths:
        raise InputFileError("terrain.paths: no SRTM tile given")
    tiles = []
    n_ref = None
    for p in paths:
        corner = hgt_corner(p)
        raw, n = _read_hgt_raw(p)
        if n_ref is None:
            n_ref = n
        elif n != n_ref:
            raise InputFileError(f"{p}: {SRTM_SIZES[n]} cannot be stitched with "
                                 f"{SRTM_SIZES[n_ref]} tiles ({paths[0]})")
        void = raw == SRTM_VOID
        if voids == "refuse" and void.any():
            _handle_voids(raw.astype(float), void, "refuse", str(p))
        tiles.append((p, corner, raw))
    assert n_ref is not None
    per_deg = n_ref - 1
    lat_lo = min(c[0] for _, c, _ in tiles)
    lat_hi = max(c[0] for _, c, _ in tiles) + 1
    lon_lo = min(c[1] for _, c, _ in tiles)
    lon_hi = max(c[1] for _, c, _ in tiles) + 1
    shape = ((lat_hi - lat_lo) * per_deg + 1, (lon_hi - lon_lo) * per_deg + 1)
    values = np.full(shape, np.nan)
    void = np.zeros(shape, bool)
    seen = set()
    for p, (lat, lon), raw in tiles:
        if (lat, lon) in seen:
            raise InputFileError(f"{p}: tile {p.name} given twice in terrain.paths")
        seen.add((lat, lon))
        r0 = (lat_hi - (lat + 1)) * per_deg
        c0 = (lon - lon_lo) * per_deg
        win = (slice(r0, r0 + n_ref), slice(c0, c0 + n_ref))
        tile_void = raw == SRTM_VOID
        old = values[win]
        old_void = void[win]
        new = raw.astype(float)
        # keep an existing real value where this tile is void on a shared edge
        keep_old = tile_void & ~np.isnan(old) & ~old_void
        values[win] = np.where(keep_old, old, new)
        void[win] = np.where(keep_old, False, tile_void)
    source = ", ".join(str(p) for p in paths)
    values = _handle_voids(values, void, voids, source)
    return GeoGrid(values=values, lat_max_deg=float(lat_hi), lon_min_deg=float(lon_lo),
                   step_deg=1.0 / per_deg, source=source)


def write_hgt(path, values: np.ndarray) -> None:
    """Write an SRTM tile (int16 big-endian, NaN -> -32768); used by the tests."""
    v = np.where(np.isnan(values), SRTM_VOID, np.round(values)).astype(">i2")
    v.tofile(path)


# --------------------------------------------------------------------------------------------
# ESRI ASCII grid
# --------------------------------------------------------------------------------------------
_ASC_KEYS = ("ncols", "nrows", "xllcorner", "xllcenter", "yllcorner", "yllcenter", "cellsize",
             "nodata_value")


def read_ascii_grid(path, voids: str = "fill") -> EnuGrid:
    """Read an ESRI ASCII grid whose coordinates are the scene's ENU metres.

    Header lines ``ncols nrows xllcorner|xllcenter yllcorner|yllcenter cellsize
    [NODATA_value]`` (keys case-insensitive, any order), then ``nrows`` rows of ``ncols`` values,
    the first row at the north edge. With ``xllcorner`` the values are cell centres
    (``xllcorner + (j + 1/2) cellsize``); with ``xllcenter`` the lower-left value sits at
    ``xllcenter``. Values are heights in the scene's ENU z (metres): the grid is taken as already
    projected into the scene frame (no geoid or curvature correction). NODATA cells are voids.
    """
    path = Path(path)
    if not path.is_file():
        raise InputFileError(f"{path}: ASCII grid not found (relative paths are taken from the "
                             f"current directory {Path.cwd()}; pass an absolute path)")
    check_input_file(path, "ASCII grid", MAX_ASCII_GRID_BYTES, memory_factor=12.0)
    try:
        lines = path.read_text().splitlines()
    except UnicodeDecodeError:
        raise InputFileError(f"{path}: not a text file (ESRI ASCII grid expected)") from None
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    header = {}
    header_line = {}
    lineno = 0
    while lineno < len(lines):
        text = lines[lineno].strip()
        if not text:
            lineno += 1
            continue
        if not text[0].isalpha():
            break
        parts = text.split()
        key = parts[0].lower()
        if key not in _ASC_KEYS:
            raise InputFileError(f"{path}, line {lineno + 1}: unknown header key "
                                 f"{excerpt(parts[0])}; "
                                 f"expected one of ncols nrows xllcorner yllcorner cellsize "
                                 f"NODATA_value")
        if len(parts) != 2:
            raise InputFileError(f"{path}, line {lineno + 1}: header line must be 'KEY VALUE', "
                                 f"got {len(parts)} fields")
        try:
            value = float(parts[1])
        except ValueError:
            raise InputFileError(f"{path}, line {lineno + 1}: {parts[0]} must be a number, got "
                                 f"{excerpt(parts[1])}") from None
        header[key] = value
        header_line[key] = lineno + 1
        lineno += 1
    for need in ("ncols", "nrows", "cellsize"):
        if need not in header:
            raise InputFileError(f"{path}: header has no {need} line (ESRI ASCII grid expected)")
    for axis in "xy":
        if (f"{axis}llcorner" in header) == (f"{axis}llcenter" in header):
            raise InputFileError(f"{path}: header needs exactly one of {axis}llcorner, "
                                 f"{axis}llcenter")
    for key in ("ncols", "nrows"):
        v = header[key]
        if not (math.isfinite(v) and v == int(v) and v >= 2):
            raise InputFileError(f"{path}, line {header_line[key]}: {key} must be an integer >= 2,"
                                 f" got {v:g}")
    ncols, nrows = int(header["ncols"]), int(header["nrows"])
    cell = header["cellsize"]
    if not (math.isfinite(cell) and cell > 0):
        raise InputFileError(f"{path}, line {header_line['cellsize']}: cellsize must be > 0, "
                             f"got {cell:g}")
    for key in ("xllcorner", "xllcenter", "yllcorner", "yllcenter"):
        if key in header and not math.isfinite(header[key]):
            raise InputFileError(f"{path}, line {header_line[key]}: {key} must be a finite "
                                 f"number of metres, got {header[key]:g}")
    rows: List[np.ndarray] = []
    row_line: List[int] = []
    for k in range(lineno, len(lines)):
        text = lines[k].strip()
        if not text:
            continue
        try:
            rows.append(np.array(text.split(), dtype=float))
        except ValueError:
            bad = next(t for t in text.split() if not _is_number(t))
            raise InputFileError(f"{path}, line {k + 1}: {excerpt(bad)} is not a number") from None
        row_line.append(k + 1)
    data = np.concatenate(rows) if rows else np.zeros(0)
    if data.size != nrows * ncols:
        wrong = [(ln, r.size) for ln, r in zip(row_line, rows) if r.size != ncols]
        if wrong:
            ln, size = wrong[0]
            raise InputFileError(f"{path}, line {ln}: {size} values, but the header says "
                                 f"ncols={ncols}")
        raise InputFileError(f"{path}: {len(rows)} data rows of {ncols} values, but the header "
                             f"says nrows={nrows}")
    grid = data.reshape(nrows, ncols)[::-1].copy()  # row 0 = south
    void = np.zeros(grid.shape, bool)
    if "nodata_value" in header:
        void = grid == header["nodata_value"]
    if not np.all(np.isfinite(grid[~void])):
        raise InputFileError(f"{path}: non-finite height values (nan/inf) outside NODATA")
    lo, hi = MAP_Z_RANGE_M
    off = ((grid < lo) | (grid > hi)) & ~void
    if off.any():
        in_file = off[::-1]             # rows as the file lists them, the first at the north
        r, c = np.unravel_index(int(np.argmax(in_file)), in_file.shape)
        raise InputFileError(f"{path}: {int(off.sum())} heights outside {lo:g}..{hi:g} m, the "
                             f"first {grid[::-1][r, c]:.6g} m at row {r}, column {c} (data rows "
                             f"from the north); heights are scene map z in metres")
    grid = _handle_voids(grid, void, voids, str(path))
    half = 0.5 * cell
    x0 = header["xllcenter"] if "xllcenter" in header else header["xllcorner"] + half
    y0 = header["yllcenter"] if "yllcenter" in header else header["yllcorner"] + half
    return EnuGrid(z=grid, x0_m=x0, y0_m=y0, dx_m=cell, dy_m=cell, source=str(path))


def _is_number(token: str) -> bool:
    try:
        float(token)
        return True
    except ValueError:
        return False


def write_ascii_grid(path, grid: EnuGrid, nodata_value: Optional[float] = -9999.0) -> None:
    """Write an :class:`EnuGrid` (square cells) as an ESRI ASCII grid with ``xllcorner``."""
    if not math.isclose(grid.dx_m, grid.dy_m):
        raise ValueError("ESRI ASCII grids have square cells (dx_m == dy_m)")
    nrows, ncols = grid.z.shape
    z = grid.z[::-1]
    lines = [f"ncols {ncols}", f"nrows {nrows}", f"xllcorner {grid.x0_m - 0.5 * grid.dx_m!r}",
             f"yllcorner {grid.y0_m - 0.5 * grid.dy_m!r}", f"cellsize {grid.dx_m!r}"]
    if nodata_value is not None:
        lines.append(f"NODATA_value {nodata_value!r}")
        z = np.where(np.isnan(z), nodata_value, z)
    lines += [" ".join(repr(float(v)) for v in row) for row in z]
    Path(path).write_text("\n".join(lines) + "\n")
