"""STANAG 4607: spec vectors, an independent decoder, the real sample, round trips, robustness."""
from __future__ import annotations

import io
import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from gmtiflow.formats import stanag4607 as s4607, synthetic
from gmtiflow.formats.errors import FormatError
from tests.formats import spec4607 as spec
from tests.formats.spec4607 import DWELL_FMT, TARGET_FMT, segment

BA32_Q = 360.0 / 2**32
SA32_Q = 180.0 / 2**32
BA16_Q = 360.0 / 2**16
SA16_Q = 180.0 / 2**16
META = {"epoch_utc": synthetic.EPOCH_UTC}


# ---------------------------------------------------------------------------------------------
# Hand-assembled packets (struct, straight from the reference layout tables)
# ---------------------------------------------------------------------------------------------

def packet(segments: list[bytes], job_id=7, version=b"30") -> bytes:
    return spec.packet(segments, job_id=job_id, version=version, platform=b"TESTPLAT  ",
                       nationality=b"XN", class_system=b"XN")


def mission(year=2024, month=2, day=29) -> bytes:
    return spec.mission_segment(b"PLAN        ", b"FLIGHT      ", b"CFG       ", year, month,
                                day)


def dmask(dwell_fields, target_fields) -> int:
    return (sum(1 << (65 - n) for n in dwell_fields)
            + sum(1 << (34 - k) for k in target_fields))


ALL_DWELL = [n for n in range(2, 32) if n not in (10, 11)]
ALL_TARGET = [k for k in range(1, 19) if k not in (4, 5)]


def dwell(dvals: dict, targets: list[dict], tfields=ALL_TARGET, count=None) -> bytes:
    return spec.dwell_segment(dmask(sorted(set(dvals) | {5}), tfields), dvals, targets, count)


# Raw values, with the engineering values they must decode to.
DWELL_RAW = {
    2: 3, 3: 5, 4: 1, 6: 45_296_789,                  # 12:34:56.789 UTC
    7: -0x1B3A_1234,                                 # SA32 south latitude
    8: 0xFA00_0000,                                  # BA32 351.5625 deg = 8.4375 W
    9: -12_345,                                      # -123.45 m HAE
    12: 150, 13: 250, 14: 300,
    15: 0x4000, 16: 123_456, 17: -15,                # track 90 deg, 123.456 m/s, -1.5 m/s
    18: 3, 19: 40, 20: 25,
    21: 0x2000, 22: 0x0800, 23: -0x1000,             # heading 45, pitch 5.625, roll -11.25
    24: 0x1000_0000, 25: 0xFFFF_0000,                # area 11.25 N, 359.9999... E
    26: 0x8000 | 0x0140,                             # B16 sign bit set: -2.5 km (we keep the sign)
    27: 0x0100,                                      # 1.40625 deg
    28: 0x8000, 29: -0x0400, 30: 0x0200, 31: 17,
}
TARGET_RAW = {
    1: 9, 2: -0x1B3A_0000, 3: 0xF9FF_0000, 6: -417, 7: -1234, 8: 7500, 9: -7, 10: 138, 11: 80,
    12: 1234, 13: 567, 14: 12, 15: 345, 16: 3, 17: 0xFFFF_FFFF, 18: -13,
}


def test_spec_worked_examples():
    assert s4607.dec_ba(0b0101100100011100, 16) == pytest.approx(125.31006, abs=1e-5)
    assert s4607.dec_sa(np.int16(np.uint16(0xCE66).view(np.int16)), 16) == pytest.approx(
        -34.876099, abs=1e-6)
    # and the encoders invert them
    assert s4607.enc_ba16(125.31006) == 0b0101100100011100
    assert s4607.enc_sa16(-34.876099) == np.uint16(0xCE66).view(np.int16)
    # B16 is sign-magnitude
    assert s4607.dec_b16(0x8000 | 0x0140) == -2.5
    assert s4607.enc_b16(-2.5) == 0x8000 | 0x0140


def test_mask_bits_follow_the_reference():
    assert s4607.dwell_mask_bit(2) == 1 << 63
    assert s4607.dwell_mask_bit(31) == 1 << 34
    assert s4607.target_mask_bit(1) == 1 << 33
    assert s4607.target_mask_bit(18) == 1 << 16
    # the spec example: 0xFF3F.. = D2-D9 and D12-D17
    assert dmask([2, 3, 4, 5, 6, 7, 8, 9, 12, 13, 14, 15, 16, 17], []) >> 48 == 0xFF3F
    # the AFRL precision-targeting mask
    assert dmask(ALL_DWELL, ALL_TARGET) == 0xFF3FFFFF9FFF0000
    assert s4607.WRITE_DWELL_MASK >> 32 == dmask(
        [2, 3, 4, 5, 6, 7, 8, 9, 12, 13, 14, 15, 16, 17, 21, 22, 23, 24, 25, 26, 27, 31], []) >> 32


def test_hand_assembled_full_mask_dwell_decodes_to_engineering_values():
    target2 = {**TARGET_RAW, 1: 10, 17: 4242, 6: 250}
    data = packet([mission()], job_id=0) + packet([dwell(DWELL_RAW, [TARGET_RAW, target2])])
    r = s4607.read_4607(data)
    assert r["missions"]["reference_date"].tolist() == ["2024-02-29"]
    assert r["missions"]["platform_type"].tolist() == [20]
    d = {k: v[0] for k, v in r["dwells"].items()}
    assert (d["revisit_id"], d["dwell_index"], d["last_dwell"], d["target_count"]) == (3, 5, True, 2)
    assert d["job_id"] == 7
    assert d["dwell_time_ms"] == 45_296_789
    assert d["time_s"] == pytest.approx(45_296.789, abs=1e-9)   # from 00:00 of the mission day
    assert d["platform_lat_deg"] == pytest.approx(-0x1B3A_1234 * SA32_Q, abs=1e-12)
    assert d["platform_lon_deg"] == pytest.approx(-8.4375, abs=1e-12)
    assert d["platform_height_m"] == pytest.approx(-123.45)
    assert (d["sigma_along_track_m"], d["sigma_cross_track_m"], d["sigma_altitude_m"]) == (
        1.5, 2.5, 3.0)
    assert d["sensor_track_rad"] == pytest.approx(np.pi / 2)
    assert d["sensor_speed_mps"] == pytest.approx(123.456)
    assert d["platform_vz_mps"] == pytest.approx(-1.5)
    assert d["platform_vx_mps"] == pytest.approx(123.456) and abs(d["platform_vy_mps"]) < 1e-9
    assert d["sigma_track_rad"] == pytest.approx(np.radians(3))
    assert d["sigma_speed_mps"] == pytest.approx(0.040)
    assert d["sigma_vz_mps"] == pytest.approx(0.25)
    assert np.degrees(d["platform_heading_rad"]) == pytest.approx(45.0)
    assert np.degrees(d["platform_pitch_rad"]) == pytest.approx(5.625)       # 180/2^16, not x2
    assert np.degrees(d["platform_bank_rad"]) == pytest.approx(-11.25)
    assert d["area_lat_deg"] == pytest.approx(11.25)
    assert d["area_lon_deg"] == pytest.approx(0xFFFF_0000 * BA32_Q - 360.0)
    assert d["range_half_extent_m"] == pytest.approx(-2500.0)
    assert np.degrees(d["angle_half_extent_rad"]) == pytest.approx(1.40625)
    assert np.degrees(d["sensor_heading_rad"]) == pytest.approx(180.0)
    assert np.degrees(d["sensor_pitch_rad"]) == pytest.approx(-0x0400 * SA16_Q)
    assert np.degrees(d["sensor_roll_rad"]) == pytest.approx(0x0200 * SA16_Q)
    assert d["mdv_mps"] == pytest.approx(1.7)

    t = r["detections"]
    assert t["mti_report_index"].tolist() == [9, 10]
    assert t["dwell_id"].tolist() == [0, 0]
    assert t["lat_deg"][0] == pytest.approx(-0x1B3A_0000 * SA32_Q, abs=1e-12)
    assert t["lon_deg"][0] == pytest.approx(0xF9FF_0000 * BA32_Q - 360.0, abs=1e-12)  # west
    assert t["height_m"].tolist() == [-417.0, 250.0]                                  # negative
    assert t["los_velocity_mps"][0] == pytest.approx(-12.34)
    assert t["wrap_velocity_mps"][0] == pytest.approx(75.0)
    assert t["snr_db"][0] == -7.0
    assert t["classification"][0] == 138
    assert t["classification_probability"][0] == pytest.approx(0.8)
    assert t["sigma_range_m"][0] == pytest.approx(12.34)
    assert t["sigma_cross_range_m"][0] == pytest.approx(56.7)
    assert t["sigma_height_m"][0] == 12.0
    assert t["sigma_range_rate_mps"][0] == pytest.approx(3.45)
    assert t["truth_application"][0] == 3
    assert t["truth_id"].tolist() == [-1, 4242]
    assert t["rcs_dbsm"][0] == -6.5
    assert np.all(t["time_s"] == d["time_s"])


def test_reduced_resolution_positions_use_scale_factors_and_wrap_longitude():
    dv = {n: v for n, v in DWELL_RAW.items() if n in s4607.MANDATORY_DWELL}
    dv[10] = 1000          # lat scale (SA32 raw)
    dv[11] = 3000          # lon scale (BA32 raw)
    dv[25] = 100           # area centre just east of Greenwich
    targets = [{1: 0, 4: -5, 5: -7}, {1: 1, 4: 32767, 5: 5}]
    data = packet([dwell(dv, targets, tfields=[1, 4, 5])])
    t = s4607.read_4607(data)["detections"]
    assert t["lat_deg"][0] == pytest.approx((DWELL_RAW[24] - 5000) * SA32_Q, abs=1e-12)
    # 100 - 7*3000 wraps modulo 2^32 to a west longitude
    assert t["lon_deg"][0] == pytest.approx(((100 - 21000) % 2**32) * BA32_Q - 360.0, abs=1e-12)
    assert t["lat_deg"][1] == pytest.approx((DWELL_RAW[24] + 32767 * 1000) * SA32_Q, abs=1e-12)
    assert t["lon_deg"][1] == pytest.approx((100 + 15000) * BA32_Q, abs=1e-12)
    assert np.isnan(t["height_m"]).all() and np.all(t["truth_id"] == -1)


def test_zero_target_dwell_with_d32_bits_set_and_minimum_mask():
    dv = {n: v for n, v in DWELL_RAW.items() if n in s4607.MANDATORY_DWELL}
    data = packet([dwell(dv, [], tfields=ALL_TARGET)]) + packet([dwell(DWELL_RAW, [])])
    r = s4607.read_4607(data)
    assert r["dwells"]["target_count"].tolist() == [0, 0]
    assert len(r["detections"]["lat_deg"]) == 0
    # minimum mask: optional fields are NaN
    assert np.isnan(r["dwells"]["platform_heading_rad"][0])
    assert np.isnan(r["dwells"]["sensor_heading_rad"][0])


def test_unknown_and_unparsed_segment_types_are_skipped_by_size():
    data = (packet([segment(200, b"\x01\x02\x03"), mission(), segment(3, b"\x00" * 17)], job_id=0)
            + packet([segment(6, b"ORIG      RECIP     hello"), dwell(DWELL_RAW, [TARGET_RAW])]))
    r = s4607.read_4607(data)
    assert len(r["missions"]["packet"]) == 1
    assert r["free_texts"]["text"].tolist() == ["hello"]
    assert len(r["detections"]["lat_deg"]) == 1
    assert [p.segments[0].type for p in s4607.iter_packets(data)] == [200, 6]


def test_multi_packet_dwell_pieces_merge_into_one_dwell():
    t1 = [{**TARGET_RAW, 1: i} for i in range(3)]
    t2 = [{**TARGET_RAW, 1: i} for i in range(3, 5)]
    first = {**DWELL_RAW, 4: 0}
    data = packet([dwell(first, t1)]) + packet([dwell(DWELL_RAW, t2)])
    r = s4607.read_4607(data)
    assert r["dwells"]["target_count"].tolist() == [5]
    assert r["dwells"]["n_packets"].tolist() == [2]
    assert r["dwells"]["last_dwell"].tolist() == [True]
    assert r["detections"]["mti_report_index"].tolist() == [0, 1, 2, 3, 4]
    assert r["detections"]["dwell_id"].tolist() == [0] * 5


# ---------------------------------------------------------------------------------------------
# The real sample file
# ---------------------------------------------------------------------------------------------

def test_reads_real_sample_list1(list1_path):
    r = s4607.read_4607(list1_path)
    assert r["packets"]["version"].tolist() == ["31", "31"]
    assert r["packets"]["platform_id"].tolist() == ["Pico1", "Pico1"]
    assert r["missions"]["mission_plan"].tolist() == ["Drifter 1"]
    assert r["missions"]["reference_date"].tolist() == ["2016-07-28"]
    d = r["dwells"]
    assert (d["revisit_id"][0], d["dwell_index"][0], d["target_count"][0]) == (100, 20000, 1)
    assert d["dwell_time_ms"][0] == 1_000_000
    assert d["platform_lat_deg"][0] == pytest.approx(55.92861298006028, abs=1e-12)
    assert d["platform_lon_deg"][0] == pytest.approx(357.33884003944695 - 360, abs=1e-12)
    assert d["range_half_extent_m"][0] == 2500.0
    t = r["detections"]
    assert t["lat_deg"][0] == pytest.approx(55.998699981719255, abs=1e-12)
    assert t["lon_deg"][0] == pytest.approx(357.2900000307709 - 360, abs=1e-12)
    assert (t["mti_report_index"][0], t["height_m"][0], t["snr_db"][0]) == (34, 100.0, -128.0)
    assert (t["truth_application"][0], t["truth_id"][0], t["rcs_dbsm"][0]) == (200, 10000, 5.0)
    assert t["los_velocity_mps"][0] == pytest.approx(5.30)
    assert t["sigma_cross_range_m"][0] == 200.0
    assert r["attrs"]["time_origin"] == "reference_day"
    assert t["time_s"][0] == 1000.0


# ---------------------------------------------------------------------------------------------
# Writer: structure, the independent decoder, quantisation
# ---------------------------------------------------------------------------------------------

def _stream(data):
    return list(s4607.iter_packets(data))


def test_writer_stream_structure():
    dwells, dets = synthetic.tables(21, 150, dwell_period_s=2.0)
    data = s4607.encode_4607(dwells, dets, META)
    pk = _stream(data)
    types = [p.segments[0].type for p in pk]
    assert all(len(p.segments) == 1 for p in pk)
    assert types[:3] == [1, 5, 6]
    assert types.count(2) == 21
    # Mission + Job before each revisit (3 revisits of 7 dwells)
    assert types.count(1) == 3 and types.count(5) == 3
    # P10 = job id only on dwell packets (SPEC 3.1.10)
    assert all((p.job_id == 1) == (p.segments[0].type == 2) for p in pk)
    assert {p.exercise_indicator for p in pk} == {129}
    assert {p.version for p in pk} == {"30"}
    r = s4607.read_4607(data)
    assert r["dwells"]["last_dwell"].tolist() == dwells["last_dwell"].tolist()


def test_job_definition_repeats_every_30_s_within_a_long_revisit():
    dwells, dets = synthetic.tables(7, 10, dwell_period_s=12.0)   # one revisit of 72 s
    types = [p.segments[0].type for p in _stream(s4607.encode_4607(dwells, dets, META))]
    assert types.count(5) == 3   # t = 0, 36, 72


def _two_sensors_revisiting_every(period_a_s, period_b_s):
    """Two sensors' dwells interleaved in time: sensor 0 revisits every ``period_a_s``, sensor 1
    every ``period_b_s`` (7 dwells per revisit each)."""
    a, ta = synthetic.tables(28, 40, seed=1, dwell_period_s=period_a_s / 7)
    b, tb = synthetic.tables(42, 40, seed=2, dwell_period_s=period_b_s / 7)
    b["time_s"] = b["time_s"] + 0.1
    off = int(a["dwell_id"].max()) + 1
    b["dwell_id"], tb["dwell_id"] = b["dwell_id"] + off, tb["dwell_id"] + off
    tb["det_id"] = tb["det_id"] + len(ta["det_id"])
    a["sensor_id"], b["sensor_id"] = np.zeros(28, np.int64), np.ones(42, np.int64)
    dw = {k: np.concatenate([a[k], b[k]]) for k in a}
    order = np.argsort(dw["time_s"], kind="stable")
    return {k: v[order] for k, v in dw.items()}, {k: np.concatenate([ta[k], tb[k]]) for k in ta}


def test_each_sensor_job_states_its_own_revisit_interval():
    """J15 left to the writer: each sensor's Job Definition has its own revisit (8 s and 4 s),
    and the XML's one JobDefinition the median over the sensors' revisits, not over the
    interleaved stream (where every dwell of the other sensor looks like a new revisit)."""
    dw, det = _two_sensors_revisiting_every(8.0, 4.0)
    jobs = s4607.read_4607(s4607.encode_4607(dw, det, META))["jobs"]
    got = {int(j): float(r) for j, r in zip(jobs["job_id"], jobs["revisit_interval_s"])}
    assert got == {1: 8.0, 2: 4.0}
    # pooled: 3 intervals of 8 s and 5 of 4 s
    assert s4607.resolve_meta(META, dw, det)["revisit_interval_s"] == pytest.approx(4.0)
    dw, det = _two_sensors_revisiting_every(8.0, 8.0)
    assert s4607.resolve_meta(META, dw, det)["revisit_interval_s"] == pytest.approx(8.0)


def test_large_dwell_is_split_below_65535_bytes_with_continuing_report_index():
    dwells, dets = synthetic.tables(3, 9000, seed=3, dwells_per_revisit=3)
    dets["dwell_id"] = np.repeat([0, 1, 2], [4000, 0, 5000])   # an empty dwell between two big ones
    assert dwells["last_dwell"].tolist() == [False, False, True]
    data = s4607.encode_4607(dwells, dets, META)
    pk = _stream(data)
    assert max(p.size for p in pk) <= 65_535
    dpk = [p for p in pk if p.segments[0].type == 2]
    assert len(dpk) > 3
    r = s4607.read_4607(data)
    assert r["dwells"]["target_count"].tolist() == np.bincount(dets["dwell_id"], minlength=3).tolist()
    for k in range(3):
        sel = r["detections"]["dwell_id"] == k
        assert r["detections"]["mti_report_index"][sel].tolist() == list(range(sel.sum()))
    # D4 only on the last piece of the last dwell
    lasts = [int.from_bytes(p.segments[0].body[12:13], "big") for p in dpk]
    assert lasts[-1] == 1 and lasts.count(1) == 1
    assert r["dwells"]["n_packets"].tolist()[1] == 1 and r["dwells"]["n_packets"][2] > 1


def _independent(data):
    stanag = pytest.importorskip("stanag4607", reason="PyPI stanag4607==0.1.0 (test extra)")
    dec = stanag.PacketStreamDecoder()
    out = list(dec.feed(data))
    dec.finish()
    return stanag, out


@pytest.mark.parametrize("edition", ["30", "41"])
def test_independent_decoder_reads_every_field_we_write(edition):
    dwells, dets = synthetic.tables(9, 60, seed=5)
    dets["lon_deg"][:5] = -np.abs(dets["lon_deg"][:5])   # west longitudes
    dets["height_m"][5:10] = -np.abs(dets["height_m"][5:10]) - 1
    data = s4607.encode_4607(dwells, dets, META, edition=edition)
    ours = s4607.read_4607(data)
    stanag, packets = _independent(data)
    assert len(packets) == len(ours["packets"]["offset"])
    dw_rows, tg_rows = [], []
    for p in packets:
        assert p.header.version_id == edition.encode()
        for e in stanag.iter_packet_events(p):
            v = e.value
            if isinstance(v, stanag.MissionSegment):
                assert (v.reference_year, v.reference_month, v.reference_day) == (2026, 11, 21)
            elif isinstance(v, stanag.JobDefinitionSegment):
                assert v.job_id == 1 and v.radar_mode == 1
                assert v.nominal_revisit_interval_deciseconds == ours["jobs"]["revisit_interval_s"][0] * 10
            elif isinstance(v, stanag.DwellSegment):
                dw_rows.append(v)
                tg_rows.extend(v.targets)
    d = ours["dwells"]
    f = lambda x: float(x.degrees)                                     # noqa: E731
    assert [v.revisit_index for v in dw_rows] == d["revisit_id"].tolist()
    assert [v.dwell_index for v in dw_rows] == d["dwell_index"].tolist()
    assert [bool(v.last_dwell) for v in dw_rows] == d["last_dwell"].tolist()
    assert [v.target_report_count for v in dw_rows] == d["target_count"].tolist()
    assert [v.dwell_time_milliseconds for v in dw_rows] == d["dwell_time_ms"].tolist()
    np.testing.assert_allclose([f(v.sensor_latitude) for v in dw_rows], d["platform_lat_deg"], atol=1e-12)
    np.testing.assert_allclose([f(v.sensor_longitude) for v in dw_rows], d["platform_lon_deg"] % 360, atol=1e-12)
    np.testing.assert_allclose([v.sensor_altitude_centimeters / 100 for v in dw_rows], d["platform_height_m"])
    np.testing.assert_allclose([v.sensor_speed_millimeters_per_second / 1000 for v in dw_rows], d["sensor_speed_mps"])
    np.testing.assert_allclose([np.radians(f(v.sensor_track)) for v in dw_rows], d["sensor_track_rad"], atol=1e-12)
    np.testing.assert_allclose([v.sensor_vertical_velocity_decimeters_per_second / 10 for v in dw_rows], d["platform_vz_mps"])
    np.testing.assert_allclose([np.radians(f(v.platform_heading)) for v in dw_rows], d["platform_heading_rad"], atol=1e-12)
    np.testing.assert_allclose([np.radians(f(v.platform_pitch)) for v in dw_rows], d["platform_pitch_rad"], atol=1e-12)
    np.testing.assert_allclose([np.radians(f(v.platform_roll)) for v in dw_rows], d["platform_bank_rad"], atol=1e-12)
    np.testing.assert_allclose([f(v.center_latitude) for v in dw_rows], d["area_lat_deg"], atol=1e-12)
    np.testing.assert_allclose([f(v.center_longitude) for v in dw_rows], d["area_lon_deg"] % 360, atol=1e-12)
    # B16: its decoder ignores the sign bit (reference §2); our ranges are positive
    np.testing.assert_allclose([float(v.range_half_extent_kilometers) * 1000 for v in dw_rows], d["range_half_extent_m"])
    np.testing.assert_allclose([np.radians(f(v.angle_half_extent)) for v in dw_rows], d["angle_half_extent_rad"], atol=1e-12)
    np.testing.assert_allclose([v.minimum_detectable_velocity_decimeters_per_second / 10 for v in dw_rows], d["mdv_mps"])
    t = ours["detections"]
    assert [x.report_index for x in tg_rows] == t["mti_report_index"].tolist()
    np.testing.assert_allclose([f(x.high_resolution_latitude) for x in tg_rows], t["lat_deg"], atol=1e-12)
    np.testing.assert_allclose([f(x.high_resolution_longitude) for x in tg_rows], t["lon_deg"] % 360, atol=1e-12)
    assert [x.geodetic_height_meters for x in tg_rows] == t["height_m"].tolist()
    np.testing.assert_allclose([x.radial_velocity_centimeters_per_second / 100 for x in tg_rows], t["los_velocity_mps"])
    np.testing.assert_allclose([x.wrap_velocity_centimeters_per_second / 100 for x in tg_rows], t["wrap_velocity_mps"])
    assert [x.signal_to_noise_ratio_decibels for x in tg_rows] == t["snr_db"].tolist()
    assert [x.classification for x in tg_rows] == t["classification"].tolist()
    np.testing.assert_allclose([x.slant_range_uncertainty_centimeters / 100 for x in tg_rows], t["sigma_range_m"])
    np.testing.assert_allclose([x.cross_range_uncertainty_decimeters / 10 for x in tg_rows], t["sigma_cross_range_m"])
    np.testing.assert_allclose([x.radial_velocity_uncertainty_centimeters_per_second / 100 for x in tg_rows], t["sigma_range_rate_mps"])
    ent = [x.truth_tag_entity for x in tg_rows]
    assert [(-1 if e == 0xFFFFFFFF else e) for e in ent] == t["truth_id"].tolist()
    assert [x.truth_tag_application for x in tg_rows] == t["truth_application"].tolist()
    assert [float(x.radar_cross_section_decibels) for x in tg_rows] == t["rcs_dbsm"].tolist()
    # and our values are the written ones within the quanta
    assert t["truth_id"].tolist() == dets["truth_id"].tolist()


def _check_quanta(dwells, dets, r):
    d, t = r["dwells"], r["detections"]
    np.testing.assert_allclose(d["time_s"], dwells["time_s"], atol=0.5e-3 + 1e-9)
    np.testing.assert_allclose(d["platform_lat_deg"], dwells["platform_lat_deg"], atol=SA32_Q / 2 + 1e-12)
    dl = (d["platform_lon_deg"] - dwells["platform_lon_deg"] + 180) % 360 - 180
    assert np.all(np.abs(dl) <= BA32_Q / 2 + 1e-12)
    np.testing.assert_allclose(d["platform_height_m"], dwells["platform_height_m"], atol=0.005 + 1e-9)
    np.testing.assert_allclose(d["range_half_extent_m"], dwells["range_half_extent_m"], atol=1000 / 256 + 1e-9)
    np.testing.assert_allclose(d["platform_pitch_rad"], dwells["platform_pitch_rad"], atol=np.radians(SA16_Q / 2) + 1e-12)
    np.testing.assert_allclose(d["platform_bank_rad"], dwells["platform_bank_rad"], atol=np.radians(SA16_Q / 2) + 1e-12)
    np.testing.assert_allclose(d["mdv_mps"], dwells["mdv_mps"], atol=0.05 + 1e-9)
    assert d["revisit_id"].tolist() == dwells["revisit_id"].tolist()
    np.testing.assert_allclose(t["lat_deg"], dets["lat_deg"], atol=SA32_Q / 2 + 1e-12)
    dl = (t["lon_deg"] - dets["lon_deg"] + 180) % 360 - 180
    assert np.all(np.abs(dl) <= BA32_Q / 2 + 1e-12)
    np.testing.assert_allclose(t["height_m"], dets["height_m"], atol=0.5 + 1e-9)
    np.testing.assert_allclose(t["los_velocity_mps"], dets["los_velocity_mps"], atol=0.005 + 1e-9)
    np.testing.assert_allclose(t["snr_db"], dets["snr_db"], atol=0.5 + 1e-9)
    np.testing.assert_allclose(t["sigma_range_m"], dets["sigma_range_m"], atol=0.005 + 1e-9)
    np.testing.assert_allclose(t["sigma_cross_range_m"], dets["range_m"] * dets["sigma_azimuth_rad"], atol=0.05 + 1e-9)
    np.testing.assert_allclose(t["sigma_range_rate_mps"], dets["sigma_range_rate_mps"], atol=0.005 + 1e-9)
    np.testing.assert_allclose(t["rcs_dbsm"], dets["rcs_dbsm"], atol=0.25 + 1e-9)
    np.testing.assert_allclose(t["time_s"], dets["time_s"], atol=0.5e-3 + 1e-9)
    assert t["truth_id"].tolist() == dets["truth_id"].tolist()
    assert t["dwell_id"].tolist() == dets["dwell_id"].tolist()


def test_round_trip_within_the_quanta_and_the_quanta_are_tight():
    dwells, dets = synthetic.tables(30, 500, seed=1)
    r = s4607.read_4607(s4607.encode_4607(dwells, dets, META))
    _check_quanta(dwells, dets, r)
    # the bound is attained (errors use most of the quantum, so it is not a loose tolerance)
    err = np.abs(r["detections"]["lat_deg"] - dets["lat_deg"]).max()
    assert err > 0.3 * SA32_Q
    err = np.abs(r["detections"]["rcs_dbsm"] - dets["rcs_dbsm"]).max()
    assert err > 0.2


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31), n_dwells=st.integers(1, 15), n_dets=st.integers(0, 80),
       lat=st.floats(-89.0, 89.0), lon=st.floats(-179.9, 179.9))
def test_round_trip_random_tables(seed, n_dwells, n_dets, lat, lon):
    dwells, dets = synthetic.tables(n_dwells, n_dets, seed=seed, lat0=lat, lon0=lon)
    # keep synthetic positions inside the field ranges near the poles
    for tb, cols in ((dwells, ("platform_lat_deg", "area_lat_deg")), (dets, ("lat_deg",))):
        for c in cols:
            tb[c] = np.clip(tb[c], -89.99, 89.99)
    r = s4607.read_4607(s4607.encode_4607(dwells, dets, META))
    _check_quanta(dwells, dets, r)


def test_out_of_range_values_saturate_and_nan_becomes_zero():
    dwells, dets = synthetic.tables(2, 4, seed=2)
    dets["snr_db"][:] = [500.0, -500.0, np.nan, 12.4]
    dets["los_velocity_mps"][:] = [1e4, -1e4, 0.0, 1.0]
    dets["rcs_dbsm"][:] = [100.0, -100.0, 0.0, 0.0]
    dets["height_m"][:] = [1e6, -5000.0, 0.0, 0.0]
    dets["lat_deg"][0] = 90.0
    t = s4607.read_4607(s4607.encode_4607(dwells, dets, META))["detections"]
    assert t["snr_db"].tolist() == [127.0, -128.0, 0.0, 12.0]
    assert t["los_velocity_mps"].tolist()[:2] == [327.67, -327.68]
    assert t["rcs_dbsm"].tolist()[:2] == [63.5, -64.0]
    assert t["height_m"].tolist()[:2] == [32767.0, -1000.0]
    assert t["lat_deg"][0] == pytest.approx(90.0 - SA32_Q)


def test_platform_location_segments_round_trip_interleaved_by_time():
    dwells, dets = synthetic.tables(4, 10)
    platform = {"time_s": np.array([-1.0, 0.7, 5.0]), "lat_deg": np.array([43.0, 43.1, -12.5]),
                "lon_deg": np.array([7.0, -7.1, 179.9]), "height_m": np.array([7000.0, 7001.0, -3.0]),
                "vx_mps": np.array([100.0, 0.0, -3.0]), "vy_mps": np.array([0.0, 50.0, -4.0]),
                "vz_mps": np.array([1.0, -2.0, 0.0])}
    data = s4607.encode_4607(dwells, dets, META, platform=platform)
    types = [p.segments[0].type for p in _stream(data)]
    assert types.count(13) == 3
    assert types.index(13) < types.index(2)                  # t = -1 s comes first
    pl = s4607.read_4607(data)["platform_locations"]
    np.testing.assert_allclose(pl["time_s"], platform["time_s"], atol=0.5e-3 + 1e-9)
    np.testing.assert_allclose(pl["lat_deg"], platform["lat_deg"], atol=SA32_Q)
    np.testing.assert_allclose(pl["lon_deg"], platform["lon_deg"], atol=BA32_Q)
    np.testing.assert_allclose(pl["height_m"], platform["height_m"], atol=0.005)
    np.testing.assert_allclose(pl["speed_mps"], np.hypot(platform["vx_mps"], platform["vy_mps"]), atol=5e-4)
    np.testing.assert_allclose(pl["vx_mps"], platform["vx_mps"], atol=0.02)
    np.testing.assert_allclose(pl["vz_mps"], platform["vz_mps"], atol=0.05)


def test_write_to_path_and_file_object_and_stream_back(tmp_path):
    dwells, dets = synthetic.tables(5, 30)
    path = tmp_path / "run.4607"
    s4607.write_4607(path, dwells, dets, META)
    buf = io.BytesIO()
    s4607.write_4607(buf, dwells, dets, META)
    assert path.read_bytes() == buf.getvalue()
    with open(path, "rb") as f:
        assert sum(1 for _ in s4607.iter_packets(f)) == len(_stream(buf.getvalue()))
    r = s4607.read_4607(path, epoch_utc="2026-11-21T00:00:00Z")
    np.testing.assert_allclose(r["dwells"]["time_s"], dwells["time_s"] + 13 * 3600 + 0.25, atol=1e-3)


def test_writer_rejects_bad_input():
    dwells, dets = synthetic.tables(3, 5)
    with pytest.raises(ValueError, match="epoch_utc"):
        s4607.encode_4607(dwells, dets, {})
    with pytest.raises(ValueError, match="unknown keys"):
        s4607.encode_4607(dwells, dets, dict(META, colour="red"))
    with pytest.raises(ValueError, match="edition"):
        s4607.encode_4607(dwells, dets, META, edition="50")
    bad = dict(dets, dwell_id=dets["dwell_id"] + 100)
    with pytest.raises(ValueError, match="dwell_id"):
        s4607.encode_4607(dwells, bad, META)


def test_a_job_area_is_never_made_up_at_0_n_0_e():
    """No dwell or detection position to put a box around (a run without dwells): the writers
    ask for ``bounding_area`` instead of sending 0 deg N 0 deg E (the Gulf of Guinea)."""
    from gmtiflow.formats import xmldoc
    for encode in (s4607.encode_4607, xmldoc.encode_xml):
        with pytest.raises(ValueError, match="bounding_area"):
            encode({}, {}, META)
    dwells, dets = synthetic.tables(3, 0)
    for c in ("area_lat_deg", "platform_lat_deg"):
        dwells[c] = np.full(3, np.nan)
    with pytest.raises(ValueError, match="bounding_area"):
        s4607.encode_4607(dwells, dets, META)


def test_a_sensor_without_dwells_gets_the_files_area():
    """Two sensors, the second without dwells (sensor ids 0 and 2: sensor 1 has none): no job
    of the file is at 0 deg N 0 deg E."""
    dwells, dets = synthetic.tables(4, 20)
    dwells["sensor_id"] = np.array([0, 2, 0, 2])
    r = s4607.read_4607(s4607.encode_4607(dwells, dets, META))
    assert np.all(np.abs(r["jobs"]["a_lat_deg"]) > 1.0)


def test_no_detections_and_empty_tables():
    dwells, dets = synthetic.tables(3, 0)
    r = s4607.read_4607(s4607.encode_4607(dwells, dets, META))
    assert r["dwells"]["target_count"].tolist() == [0, 0, 0]
    area = [(43.8, 7.3), (43.8, 7.5), (43.7, 7.5), (43.7, 7.3)]
    r = s4607.read_4607(s4607.encode_4607({}, {}, dict(META, bounding_area=area)))
    assert len(r["dwells"]["dwell_id"]) == 0 and len(r["missions"]["packet"]) == 1
    assert r["jobs"]["a_lat_deg"][0] == pytest.approx(43.8, abs=1e-7)
    assert 2 not in r["segments"]["seg_type"].tolist()            # no Dwell segment
    assert s4607.decode_4607(b"")["packets"]["offset"].size == 0
    # an empty file is not a 4607 file (it would convert to an empty run file posing as one)
    with pytest.raises(FormatError, match="empty"):
        s4607.read_4607(b"")


# ---------------------------------------------------------------------------------------------
# Robustness: only FormatError, naming an offset, and quickly
# ---------------------------------------------------------------------------------------------

def test_every_truncation_raises_format_error_naming_an_offset():
    dwells, dets = synthetic.tables(2, 3)
    data = s4607.encode_4607(dwells, dets, META)
    cuts = set(np.cumsum([p.size for p in _stream(data)]).tolist())
    for n in range(1, len(data)):
        if n in cuts:                 # a whole number of packets is a valid file
            s4607.read_4607(data[:n])
            continue
        with pytest.raises(FormatError, match="offset"):
            s4607.read_4607(data[:n])


def test_random_garbage_raises_format_error():
    rng = np.random.default_rng(0)
    for _ in range(300):
        data = rng.integers(0, 256, rng.integers(1, 400), dtype=np.uint8).tobytes()
        try:
            s4607.read_4607(data)
        except FormatError:
            pass


def test_bit_flips_in_a_valid_file_raise_only_format_error():
    dwells, dets = synthetic.tables(3, 8)
    data = bytearray(s4607.encode_4607(dwells, dets, META))
    rng = np.random.default_rng(1)
    for _ in range(400):
        b = bytearray(data)
        for i in rng.integers(0, len(b), 3):
            b[i] = rng.integers(0, 256)
        try:
            s4607.read_4607(bytes(b))
        except FormatError:
            pass


def test_lying_packet_size_fails_without_allocating_it():
    good = packet([mission()], job_id=0)
    lying = good[:2] + struct.pack(">I", 2**32 - 1) + good[6:]
    with pytest.raises(FormatError, match=r"truncated packet body at byte offset 32"):
        s4607.read_4607(lying)
    with pytest.raises(FormatError, match="P2 packet size 31"):
        s4607.read_4607(good[:2] + struct.pack(">I", 31) + good[6:])
    with pytest.raises(FormatError, match="outside"):
        s4607.read_4607(lying, max_packet_size=65_535)


def test_lying_segment_and_count_fields():
    seg = mission()
    too_big = struct.pack(">BI", 1, 2**32 - 1) + seg[5:]
    with pytest.raises(FormatError, match=r"byte offset 33: S2 segment size"):
        s4607.read_4607(packet([too_big]))
    wrong = struct.pack(">BI", 1, 43) + seg[5:-1]
    with pytest.raises(FormatError, match="expected 44"):
        s4607.read_4607(packet([wrong]))
    # D5 claims more reports than the segment holds
    d = dwell(DWELL_RAW, [TARGET_RAW], count=60000)
    with pytest.raises(FormatError, match="D5 = 60000"):
        s4607.read_4607(packet([d]))
    # mask without mandatory fields
    d = segment(2, struct.pack(">Q", 1 << 63) + b"\x00\x01")
    with pytest.raises(FormatError, match="lacks mandatory"):
        s4607.read_4607(packet([d]))
    # bad mission date
    with pytest.raises(FormatError, match="not a date"):
        s4607.read_4607(packet([mission(2023, 2, 30)]))
    with pytest.raises(FormatError, match="version id"):
        s4607.read_4607(b"XX" + packet([mission()])[2:])
    with pytest.raises(FormatError, match="not a binary file"):
        s4607.read_4607(io.StringIO("30 text"))


# ---------------------------------------------------------------------------------------------
# Any conforming mask: random existence masks, hand-assembled, against the independent decoder
# ---------------------------------------------------------------------------------------------

_RANGES = {"H": (0, 65535), "B": (0, 255), "I": (0, 2**32 - 1), "i": (-2**31, 2**31 - 1),
           "h": (-32768, 32767), "b": (-128, 127)}


@st.composite
def random_dwell(draw):
    optional_groups = [(10, 11), (12, 13, 14), (15, 16, 17), (18, 19, 20), (21, 22, 23),
                       (28,), (29,), (30,), (31,)]
    position = draw(st.sampled_from(["hires", "delta", "none"]))
    fields = set(s4607.MANDATORY_DWELL)
    for g in optional_groups:
        if g == (10, 11):
            if position == "delta":
                fields.update(g)
        elif draw(st.booleans()):
            fields.update(g)
    tfields = {k for k in (1, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18) if draw(st.booleans())}
    if position == "hires":
        tfields |= {2, 3}
    elif position == "delta":
        tfields |= {4, 5}
    values = {n: draw(st.integers(*_RANGES[DWELL_FMT[n]])) for n in fields if n != 5}
    values[4] = draw(st.integers(0, 1))
    n_targets = draw(st.integers(0, 4))
    targets = [{k: draw(st.integers(*_RANGES[TARGET_FMT[k]])) for k in tfields}
               for _ in range(n_targets)]
    return values, targets, sorted(tfields)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=random_dwell())
def test_any_existence_mask_decodes_like_the_independent_decoder(case):
    values, targets, tfields = case
    data = packet([mission()], job_id=0) + packet([dwell(values, targets, tfields=tfields)])
    if 4 in tfields and any(not -2**31 <= values[24] + x[4] * values[10] < 2**31 for x in targets):
        # not conforming: the scale factor does not fit the dwell (GUIDE Annex E)
        with pytest.raises(FormatError, match="outside the SA32 range"):
            s4607.read_4607(data)
        return
    r = s4607.read_4607(data)
    d, t = r["dwells"], r["detections"]
    assert d["target_count"].tolist() == [len(targets)]
    assert d["dwell_time_ms"].tolist() == [values[6]]
    assert d["platform_height_m"][0] == values[9] / 100
    assert d["range_half_extent_m"][0] == s4607.dec_b16(values[26]) * 1000
    assert np.isnan(d["mdv_mps"][0]) == (31 not in values)
    assert np.isnan(d["platform_heading_rad"][0]) == (21 not in values)
    stanag, packets = _independent(data)
    ev = [e.value for p in packets for e in stanag.iter_packet_events(p)][-1]
    assert ev.target_report_count == len(targets)
    for i in range(len(targets)):
        loc = ev.target_location(i)
        if loc is None:
            assert np.isnan(t["lat_deg"][i])
            continue
        assert t["lat_deg"][i] == pytest.approx(float(loc.latitude.degrees), abs=1e-9)
        lon = float(loc.longitude.degrees) % 360
        assert t["lon_deg"][i] % 360 == pytest.approx(lon, abs=1e-9)
        x = ev.targets[i]
        h = x.geodetic_height_meters
        assert (np.isnan(t["height_m"][i]) if h is None else t["height_m"][i] == h)
        e = x.truth_tag_entity
        assert t["truth_id"][i] == (-1 if e is None else (e - 2**32 if e >= 2**31 else e))
        rcs = x.radar_cross_section_decibels
        assert (np.isnan(t["rcs_dbsm"][i]) if rcs is None else t["rcs_dbsm"][i] == float(rcs))
        v = x.radial_velocity_centimeters_per_second
        assert (np.isnan(t["los_velocity_mps"][i]) if v is None else t["los_velocity_mps"][i] == v / 100)


def test_iter_packets_is_lazy():
    good = packet([mission()], job_id=0)
    stream = io.BytesIO(good + b"\x00" * 10)     # a valid packet, then a torn header
    it = s4607.iter_packets(stream)
    first = next(it)
    assert first.segments[0].type == 1 and stream.tell() == len(good)
    with pytest.raises(FormatError, match=f"truncated packet header at byte offset {len(good)}"):
        next(it)
