"""STANAG 4607 checked against Wireshark's dissector (tshark) and, for several sensors, the
independent PyPI decoder.  The tshark tests skip only where tshark is not installed (CI
installs it: .ci/run)."""
from __future__ import annotations

import subprocess

import numpy as np
import pytest

from gmtiflow.formats import stanag4607 as s4607, synthetic
from tests.external_tools import TSHARK, needs_tshark, tshark_expert_errors, tshark_fields

META = {"epoch_utc": synthetic.EPOCH_UTC}


def two_sensor_tables():
    """Two aircraft: the second's dwells interleave in time with the first's."""
    d1, t1 = synthetic.tables(8, 60, seed=11)
    d2, t2 = synthetic.tables(6, 40, seed=12, lat0=43.9, lon0=7.6)
    d2["time_s"] = d2["time_s"] + 0.37
    off = int(d1["dwell_id"].max()) + 1
    d2["dwell_id"] = d2["dwell_id"] + off
    t2["dwell_id"] = t2["dwell_id"] + off
    t2["det_id"] = t2["det_id"] + len(t1["det_id"])
    d1["sensor_id"] = np.zeros(len(d1["dwell_id"]), np.int64)
    d2["sensor_id"] = np.ones(len(d2["dwell_id"]), np.int64)
    dw = {k: np.concatenate([d1[k], d2[k]]) for k in d1}
    det = {k: np.concatenate([t1[k], t2[k]]) for k in t1}
    return dw, det


@needs_tshark
@pytest.mark.parametrize("case", ["one", "two_sensors", "no_sigmas", "split"])
def test_tshark_reads_our_4607_without_expert_errors(tmp_path, case):
    if case == "two_sensors":
        dw, det = two_sensor_tables()
    elif case == "split":                       # a dwell over several packets
        dw, det = synthetic.tables(2, 5000, seed=3)
    else:
        dw, det = synthetic.tables(12, 150, seed=4)
        if case == "no_sigmas":
            for c in ("sigma_range_m", "sigma_range_rate_mps", "height_m"):
                det.pop(c)
    path = tmp_path / "d.4607"
    s4607.write_4607(path, dw, det, META)
    assert tshark_expert_errors(path) == []
    # and what tshark decodes is what we decode
    ours = s4607.read_4607(path)
    d, t = ours["dwells"], ours["detections"]
    got = tshark_fields(path, "s4607.dwell.time", "s4607.dwell.count", "s4607.dwell.sensor.lat",
                        "s4607.dwell.plat.pitch", "s4607.dwell.rpt.idx", "s4607.dwell.rpt.lat",
                        "s4607.dwell.rpt.lon", "s4607.dwell.rpt.tag.entity",
                        "s4607.dwell.rpt.section", "s4607.dwell.rpt.unc.slant",
                        "s4607.dwell.rpt.unc.height", "s4607.dwell.rpt.unc.radial",
                        "s4607.dwell.rpt.height", "s4607.dwell.rpt.radial",
                        "s4607.dwell.rpt.snr")
    pieces = np.repeat(np.arange(len(d["dwell_id"])), d["n_packets"])
    assert got["s4607.dwell.time"].tolist() == d["dwell_time_ms"][pieces].tolist()
    assert got["s4607.dwell.count"].sum() == len(t["det_id"])
    assert got["s4607.dwell.sensor.lat"].tolist() == s4607.enc_sa32(
        d["platform_lat_deg"][pieces]).tolist()
    assert got["s4607.dwell.plat.pitch"].tolist() == s4607.enc_sa16(
        np.degrees(d["platform_pitch_rad"][pieces])).tolist()
    assert got["s4607.dwell.rpt.idx"].tolist() == t["mti_report_index"].tolist()
    assert got["s4607.dwell.rpt.lat"].tolist() == s4607.enc_sa32(t["lat_deg"]).tolist()
    assert got["s4607.dwell.rpt.lon"].tolist() == s4607.enc_ba32(t["lon_deg"]).tolist()
    assert got["s4607.dwell.rpt.tag.entity"].tolist() == (t["truth_id"] % 2**32).tolist()
    assert got["s4607.dwell.rpt.section"].tolist() == (t["rcs_dbsm"] * 2).astype(int).tolist()
    if case == "no_sigmas":      # no sigma group and no height: nothing for tshark to misread
        assert np.isnan(t["sigma_range_m"]).all() and np.isnan(t["sigma_height_m"]).all()
        assert len(got["s4607.dwell.rpt.unc.slant"]) == 0
    else:
        assert got["s4607.dwell.rpt.unc.slant"].tolist() == np.rint(
            t["sigma_range_m"] * 100).astype(int).tolist()
        assert got["s4607.dwell.rpt.unc.height"].tolist() == t["sigma_height_m"].astype(
            int).tolist()
        assert got["s4607.dwell.rpt.unc.radial"].tolist() == np.rint(
            t["sigma_range_rate_mps"] * 100).astype(int).tolist()
        assert got["s4607.dwell.rpt.height"].tolist() == t["height_m"].astype(int).tolist()
        assert got["s4607.dwell.rpt.radial"].tolist() == np.rint(
            t["los_velocity_mps"] * 100).astype(int).tolist()
    assert got["s4607.dwell.rpt.snr"].tolist() == t["snr_db"].astype(int).tolist()


def test_d32_14_is_written_whenever_d32_12_is():
    dw, det = synthetic.tables(6, 80, seed=8)
    assert "sigma_height_m" not in det
    r = s4607.read_4607(s4607.encode_4607(dw, det, META))
    for mask in r["dwells"]["existence_mask"].tolist():
        has = [bool(mask & s4607.target_mask_bit(k)) for k in (6, 7, 12, 13, 14, 15)]
        assert all(has), hex(mask)
        assert s4607.tshark_safe_mask(mask) == mask
    # the height sigma is the vertical part of the slant-range sigma, at least 1 m
    t = r["detections"]
    dep = (np.asarray(r["dwells"]["platform_height_m"])[t["dwell_id"]] - t["height_m"]) / t["range_m"]
    np.testing.assert_allclose(t["sigma_height_m"], np.maximum(np.rint(t["sigma_range_m"] * dep), 1),
                               atol=1.0)
    assert t["sigma_height_m"].min() >= 1


def test_d32_14_is_at_least_1_m_when_the_range_sigma_is_sub_metre():
    """A run's σ_range is ~0.3 m, so σ_r·sin(depression) is a few cm: D32.14 must still say
    1 m, not a present 0 (a singular covariance); np.rint(0.5) is 0, so 0.5 was not a floor."""
    dw, det = synthetic.tables(6, 80, seed=8)
    det["sigma_range_m"] = np.full(len(det["det_id"]), 0.3)
    t = s4607.read_4607(s4607.encode_4607(dw, det, META))["detections"]
    assert t["sigma_height_m"].tolist() == [1.0] * len(det["det_id"])


def test_a_given_d32_14_of_0_m_is_re_encoded_as_it_is():
    """The 1 m floor is for the σ the writer derives from σ_range; a table that carries
    ``sigma_height_m`` (one read from 4607, e.g. a file of gmtiflow before 7ac1919, whose
    D32.14 was 0) is written as it is, so re-encoding stays byte for byte."""
    dw, det = synthetic.tables(6, 80, seed=8)
    det["sigma_height_m"] = np.zeros(len(det["det_id"]))
    data = s4607.encode_4607(dw, det, META)
    back = s4607.read_4607(data)
    assert back["detections"]["sigma_height_m"].tolist() == [0.0] * len(det["det_id"])
    assert s4607.encode_read_tables(back) == data


def test_two_sensors_are_two_platforms_in_time_order_for_the_independent_decoder():
    stanag = pytest.importorskip("stanag4607", reason="PyPI stanag4607==0.1.0 (test extra)")
    dw, det = two_sensor_tables()
    data = s4607.encode_4607(dw, det, dict(META, platform_id="RADAR"))
    dec = stanag.PacketStreamDecoder()
    packets = list(dec.feed(data))
    dec.finish()
    per_platform: dict = {}
    times = []
    for p in packets:
        pid = p.header.platform_id.decode().strip()
        for e in stanag.iter_packet_events(p):
            v = e.value
            if isinstance(v, stanag.DwellSegment):
                c = per_platform.setdefault(pid, [0, 0])
                c[0] += 1
                c[1] += v.target_report_count
                times.append(v.dwell_time_milliseconds)
    sensor = dw["sensor_id"]
    expect = {f"RADAR{s}": [int((sensor == s).sum()), int(np.isin(det["dwell_id"],
                                                                  dw["dwell_id"][sensor == s]).sum())]
              for s in (0, 1)}
    assert per_platform == expect
    assert times == sorted(times)                     # interleaved by time across sensors
    ours = s4607.read_4607(data)
    d = ours["dwells"]
    assert sorted(set(d["platform_id"].tolist())) == ["RADAR0", "RADAR1"]
    order = np.argsort(dw["time_s"], kind="stable")
    assert d["sensor_id"].tolist() == sensor[order].tolist()
    assert d["target_count"].sum() == len(det["det_id"])
    # each platform has its own mission and job definition, with its own job id
    assert sorted(set(ours["jobs"]["job_id"].tolist())) == [1, 2]
    assert set(d["job_id"][d["sensor_id"] == 1].tolist()) == {2}


def test_platform_locations_of_two_sensors_carry_each_sensors_platform_id(tmp_path):
    """A two-sensor /platform table: each Platform Location packet is its own sensor's platform
    (P8 GMTIFLOW0 / GMTIFLOW1, P9 1 / 2), as its Dwell packets are; they were all sent as a
    third platform, GMTIFLOW, mission 1, jumping between the two orbits."""
    dw, det = two_sensor_tables()
    n = 6
    platform = {"time_s": np.repeat([0.0, 1.0, 2.0], 2), "sensor_id": np.tile([0, 1], 3),
                "lat_deg": np.tile([43.7, 43.9], 3), "lon_deg": np.tile([7.4, 7.6], 3),
                "height_m": np.full(n, 7000.0), "vx_mps": np.full(n, 100.0),
                "vy_mps": np.zeros(n), "vz_mps": np.zeros(n)}
    data = s4607.encode_4607(dw, det, META, platform=platform)
    r = s4607.read_4607(data)
    pk = r["packets"]
    rows = r["platform_locations"]["packet"]
    assert [str(p).strip() for p in pk["platform_id"][rows]] == ["GMTIFLOW0", "GMTIFLOW1"] * 3
    assert pk["mission_id"][rows].tolist() == [1, 2] * 3
    assert pk["job_id"][rows].tolist() == [0] * n
    # one sensor: the plain platform id, as before
    first = {k: v[::2] for k, v in platform.items()}
    one = s4607.read_4607(s4607.platform_location_packets(first, META))["packets"]
    assert {str(p).strip() for p in one["platform_id"]} == {"GMTIFLOW"}
    if TSHARK is not None:
        path = tmp_path / "two.4607"
        path.write_bytes(data)
        got = subprocess.run([TSHARK, "-r", str(path), "-T", "fields", "-e", "s4607.seg.type",
                              "-e", "s4607.platform"], capture_output=True, text=True).stdout
        plats = {line.split("\t")[1].strip() for line in got.splitlines()}
        assert plats == {"GMTIFLOW0", "GMTIFLOW1"}


def test_platform_locations_of_two_sensors_without_dwells_keep_each_sensors_platform(tmp_path):
    """The same two-sensor /platform table and no dwell (``experiment=two_orbits
    scene.duration_s=0.2 export.platform_location_packets=true``): each aircraft is still its
    own platform, with its own Mission and Job Definition; they were both sent as GMTIFLOW,
    mission 1, one platform in two places at the same instant."""
    n = 4
    platform = {"time_s": np.repeat([0.0, 1.0], 2), "sensor_id": np.tile([0, 1], 2),
                "lat_deg": np.tile([43.7, 43.9], 2), "lon_deg": np.tile([7.4, 7.6], 2),
                "height_m": np.full(n, 7000.0), "vx_mps": np.full(n, 100.0),
                "vy_mps": np.zeros(n), "vz_mps": np.zeros(n)}
    area = [(44.0, 7.3), (44.0, 7.7), (43.6, 7.7), (43.6, 7.3)]
    data = s4607.encode_4607({}, {}, dict(META, bounding_area=area), platform=platform)
    r = s4607.read_4607(data)
    pk = r["packets"]
    rows = r["platform_locations"]["packet"]
    assert [str(p).strip() for p in pk["platform_id"][rows]] == ["GMTIFLOW0", "GMTIFLOW1"] * 2
    assert pk["mission_id"][rows].tolist() == [1, 2] * 2
    assert sorted(r["jobs"]["job_id"].tolist()) == [1, 2]
    assert np.allclose(r["jobs"]["a_lat_deg"], 44.0, atol=1e-6)
    assert len(r["dwells"]["dwell_id"]) == 0
    if TSHARK is not None:
        path = tmp_path / "two_empty.4607"
        path.write_bytes(data)
        assert tshark_expert_errors(path) == []
