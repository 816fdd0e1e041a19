"""4607 -> tables -> 4607: absent stays absent, masks and metadata survive, valid files come
back byte for byte (spec-shaped fixtures of both exploitation-class masks), and NUL-padded text
reads as text."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from gmtiflow.formats import stanag4607 as s4607
from gmtiflow.formats.errors import FormatError
from tests.formats.spec4607 import dwell_segment, mission_segment, packet, segment

# GUIDE Annex C: "situation awareness" (positions only, reduced resolution) and the AFRL
# "precision targeting" profile plus RCS (every field but D10/D11 and D32.4/5)
SA_MASK = 0xFFC71FC260000000
PT_MASK = 0xFF3FFFFF9FFF0000


def mission(plan=b"PLAN 7      ", flight=b"FLIGHT 9    ", config=b"CFG A     "):
    return mission_segment(plan, flight, config, 2016, 7, 28)


def job(job_id=77, model=b"MDL 1 "):
    return segment(5, struct.pack(">IB6sBB", job_id, 255, model, 0, 1)
                   + struct.pack(">iIiIiIiI", 0x27000000, 0xFE000000, 0x27000000, 0xFE100000,
                                 0x26F00000, 0xFE100000, 0x26F00000, 0xFE000000)
                   + struct.pack(">BHHHHBHHHHBBBBB", 1, 300, 65535, 65535, 65535, 255, 65535,
                                 1234, 0x8000, 65535, 25, 255, 60, 2, 1))


def free_text(text=b"hello analyst", orig=b"ORIGINATOR", recip=b"ALL       "):
    return segment(6, orig + recip + text)


dwell = dwell_segment


DWELL_VALUES = {2: 3, 3: 0, 4: 0, 6: 1_000_000, 7: 0x27A00000, 8: 0xFE0A0000, 9: 750_000,
                10: 1000, 11: 3000, 12: 150, 13: 250, 14: 300, 15: 0x4000, 16: 123_456,
                17: -15, 18: 3, 19: 40, 20: 25, 21: 0x2000, 22: 0x0100, 23: -0x0100,
                24: 0x27000000, 25: 0xFE080000, 26: 0x0A00, 27: 0x0100, 28: 0x3000, 29: -0x0200,
                30: 0x0080, 31: 17}


def target(i):
    return {1: i, 2: 0x27000000 + 1000 * i, 3: 0xFE080000 - 777 * i, 4: -5 + i, 5: 7 - 2 * i,
            6: 120 + i, 7: -1234 + 10 * i, 8: 7500, 9: 12 + i, 10: 138, 11: 80, 12: 1234,
            13: 567, 14: 12, 15: 345, 16: 3, 17: 4242 + i if i != 2 else 0xFFFFFFFF,
            18: -13 + i}


def fixture_file(mask, text=b"hello analyst"):
    """Mission + Free Text, Job Definition, four revisit dwells (one empty, one split over two
    packets), like the AFRL sample's stream."""
    out = [packet([mission(), free_text(text)]), packet([job()])]
    for d in range(4):
        v = {**DWELL_VALUES, 3: d, 4: int(d == 3), 6: 1_000_000 + 3500 * d}
        if d == 1:
            out.append(packet([dwell(mask, v, [])], job_id=77))
        elif d == 2:         # split: D4 only on the second piece, D32.1 carries on
            out.append(packet([dwell(mask, {**v, 4: 0}, [target(i) for i in range(3)])],
                              job_id=77))
            out.append(packet([dwell(mask, v, [target(i) for i in range(3, 5)])], job_id=77))
        else:
            out.append(packet([dwell(mask, v, [target(i) for i in range(d + 1)])], job_id=77))
    return b"".join(out)


@pytest.mark.parametrize("mask", [SA_MASK, PT_MASK], ids=["situation_awareness", "precision_rcs"])
def test_valid_file_comes_back_byte_for_byte(mask):
    data = fixture_file(mask)
    tables = s4607.read_4607(data)
    assert tables["dwells"]["existence_mask"].tolist() == [mask] * 4
    assert tables["dwells"]["n_packets"].tolist() == [1, 1, 2, 1]
    again = s4607.encode_read_tables(tables)
    assert again == data


def test_absent_fields_stay_absent_and_present_ones_keep_their_values():
    t = s4607.read_4607(fixture_file(SA_MASK))["detections"]
    for col in ("height_m", "snr_db", "sigma_range_m", "sigma_cross_range_m", "sigma_height_m",
                "sigma_range_rate_mps", "los_velocity_mps", "rcs_dbsm"):
        assert np.isnan(t[col]).all(), col            # not a present zero
    assert (t["truth_id"] == -1).all() and (t["truth_application"] == -1).all()
    t = s4607.read_4607(fixture_file(PT_MASK))["detections"]
    assert t["classification"].tolist() == [138] * 10
    assert t["truth_application"].tolist() == [3] * 10
    assert t["mti_report_index"].tolist() == [0, 0, 1, 2, 3, 4, 0, 1, 2, 3]
    assert -1 in t["truth_id"].tolist()


def test_nul_padded_text_reads_as_text_and_re_encodes_field_identical():
    valid = fixture_file(PT_MASK)
    nul = (valid.replace(b"AFRLPLAT  ", b"AFRLPLAT\x00\x00")
           .replace(b"PLAN 7      ", b"PLAN 7\x00\x00\x00\x00\x00\x00")
           .replace(b"MDL 1 ", b"MDL 1\x00")
           .replace(b"hello analyst", b"hello\x00garbage"))
    assert len(nul) == len(valid) and nul != valid
    a, b = s4607.read_4607(valid), s4607.read_4607(nul)
    assert b["packets"]["platform_id"].tolist() == ["AFRLPLAT"] * len(b["packets"]["offset"])
    assert b["missions"]["mission_plan"].tolist() == ["PLAN 7"]
    assert b["jobs"]["sensor_model"].tolist() == ["MDL 1"]
    assert b["free_texts"]["text"].tolist() == ["hello"]
    for name in ("packets", "missions", "jobs"):
        for col, v in a[name].items():
            assert np.array_equal(v, b[name][col], equal_nan=v.dtype.kind == "f"), (name, col)
    # field-identical: re-encoding writes the standard's space padding
    again = s4607.read_4607(s4607.encode_read_tables(b))
    assert again["packets"]["platform_id"].tolist() == b["packets"]["platform_id"].tolist()
    assert again["free_texts"]["text"].tolist() == ["hello"]
    assert not any("\x00" in s for s in again["missions"]["mission_plan"].tolist())


def test_zero_byte_file_is_a_clear_error(tmp_path):
    p = tmp_path / "empty.4607"
    p.write_bytes(b"")
    with pytest.raises(FormatError, match=r"empty\.4607: empty \(0 bytes\)"):
        s4607.read_4607(p)
