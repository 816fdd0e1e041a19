"""Software we did not write, as the tests call it: Wireshark's 4607 dissector (tshark) and
GDAL (pyogrio).  Shared by tests/formats/test_tshark.py and tests/test_export_tools.py."""
from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

TSHARK = shutil.which("tshark")
needs_tshark = pytest.mark.skipif(TSHARK is None, reason="tshark is not installed "
                                  "(apt-get install tshark; CI installs it)")


def tshark_expert_errors(path) -> list:
    """The error lines of ``tshark -r FILE -q -z expert`` (empty when the file is clean)."""
    out = subprocess.run([TSHARK, "-r", str(path), "-q", "-z", "expert"], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    if "Errors" not in "".join(lines):
        return []
    i = next(k for k, line in enumerate(lines) if line.startswith("Errors"))
    errs = []
    for line in lines[i + 3:]:
        if not line.strip() or line.startswith(("Warns", "Notes", "Chats", "=")):
            break
        errs.append(line.strip())
    return errs


def tshark_fields(path, *fields) -> dict:
    """Raw values of tshark fields over all packets, each as one flat int array."""
    cmd = [TSHARK, "-r", str(path), "-T", "fields", "-E", "separator=|", "-E", "aggregator=,"]
    for f in fields:
        cmd += ["-e", f]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    cols = {f: [] for f in fields}
    for line in out.stdout.splitlines():
        for f, cell in zip(fields, line.split("|")):
            cols[f] += [int(v, 0) for v in cell.split(",") if v]
    return {f: np.array(v, dtype=np.int64) for f, v in cols.items()}


def gdal_read(path) -> tuple:
    """(field name -> values, OGR type of each field, geometry type) as GDAL reads the file."""
    pyogrio_raw = pytest.importorskip("pyogrio.raw", reason="pyogrio (GDAL) is in the test extra")
    meta, _, _, data = pyogrio_raw.read(str(path))
    fields = dict(zip(meta["fields"].tolist(), data))
    return fields, dict(zip(meta["fields"].tolist(), meta["ogr_types"])), meta["geometry_type"]
