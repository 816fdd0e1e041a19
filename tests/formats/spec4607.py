"""Hand-assembled STANAG 4607 bytes for the format tests, straight from the reference layout
tables with ``struct`` (independent of the codec under test): packets, segments, Mission,
Dwell segments under any existence mask."""
from __future__ import annotations

import struct

DWELL_FMT = {2: "H", 3: "H", 4: "B", 5: "H", 6: "I", 7: "i", 8: "I", 9: "i", 10: "i", 11: "I",
             12: "I", 13: "I", 14: "H", 15: "H", 16: "I", 17: "b", 18: "B", 19: "H", 20: "H",
             21: "H", 22: "h", 23: "h", 24: "i", 25: "I", 26: "H", 27: "H", 28: "H", 29: "h",
             30: "h", 31: "B"}
"""struct code of each dwell field Dn."""
TARGET_FMT = {1: "H", 2: "i", 3: "I", 4: "h", 5: "h", 6: "h", 7: "h", 8: "H", 9: "b", 10: "B",
              11: "B", 12: "H", 13: "H", 14: "B", 15: "H", 16: "B", 17: "I", 18: "b"}
"""struct code of each target report field D32.k."""


def packet(segments, *, job_id=0, platform=b"AFRLPLAT  ", mission_id=42, version=b"30",
           nationality=b"US", class_system=b"  ") -> bytes:
    """A packet header (P1-P10) followed by ``segments``."""
    body = b"".join(segments)
    return struct.pack(">2sI2sB2sHB10sII", version, 32 + len(body), nationality, 5,
                       class_system, 0, 129, platform, mission_id, job_id) + body


def segment(seg_type: int, body: bytes) -> bytes:
    return struct.pack(">BI", seg_type, 5 + len(body)) + body


def mission_segment(plan: bytes, flight: bytes, config: bytes, year: int, month: int,
                    day: int) -> bytes:
    return segment(1, struct.pack(">12s12sB10sHBB", plan, flight, 20, config, year, month, day))


def dwell_segment(mask: int, values: dict, targets: list, count=None) -> bytes:
    """A Dwell segment with existence mask ``mask``: ``values`` gives each present Dn (D5 is
    the report count, ``len(targets)`` unless ``count``), each target a dict of its D32.k."""
    dnums = [n for n in range(2, 32) if mask & (1 << (65 - n))]
    tnums = [k for k in range(1, 19) if mask & (1 << (34 - k))]
    v = dict(values)
    v[5] = len(targets) if count is None else count
    body = struct.pack(">Q", mask) + b"".join(struct.pack(">" + DWELL_FMT[n], v[n]) for n in dnums)
    for t in targets:
        body += b"".join(struct.pack(">" + TARGET_FMT[k], t[k]) for k in tnums)
    return segment(2, body)
