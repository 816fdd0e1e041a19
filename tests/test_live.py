"""Live 4607 over UDP and TCP on loopback: what is sent is received byte for byte, decodes
with our reader and the PyPI decoder, is paced by dwell time, and a run streams while it
simulates.  Every test is bounded by a packet count and an idle timeout."""
from __future__ import annotations

import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from gmtiflow import live
from gmtiflow.formats import stanag4607 as s4607, synthetic
from tests.conftest import compose_app

META = {"epoch_utc": synthetic.EPOCH_UTC}


def listen(url, n_packets, idle_timeout_s=10.0):
    """Start a receiver thread; returns (received list, thread, (host, port))."""
    got: list = []
    addr: list = []
    ready = threading.Event()

    def run():
        try:
            for p in live.receive(url, max_packets=n_packets, idle_timeout_s=idle_timeout_s,
                                  ready=lambda a: (addr.append(a), ready.set())):
                got.append(p)
        except Exception as exc:          # surfaced by the test
            got.append(exc)
            ready.set()

    th = threading.Thread(target=run, daemon=True)
    th.start()
    assert ready.wait(10.0)
    return got, th, addr[0]


@pytest.mark.parametrize("scheme", ["udp", "tcp"])
def test_a_stream_is_received_byte_for_byte_and_decodes(scheme):
    dw, det = synthetic.tables(6, 4000, seed=2)          # one dwell needs several datagrams
    data = s4607.encode_4607(dw, det, META, max_packet_bytes=live.UDP_MAX_PAYLOAD)
    packets = live.split_packets(data)
    assert max(len(p) for p in packets) <= live.UDP_MAX_PAYLOAD
    got, th, (host, port) = listen(f"{scheme}://127.0.0.1:0", len(packets))
    sender = live.Sender(f"{scheme}://127.0.0.1:{port}", speed=0)
    sender.send(data)
    sender.close()
    th.join(20.0)
    assert not th.is_alive()
    assert not any(isinstance(p, Exception) for p in got), got
    assert b"".join(got) == data
    r = s4607.read_4607(b"".join(got))
    assert r["dwells"]["target_count"].sum() == 4000
    live.check_order(r["dwells"])
    assert np.all(np.diff(r["dwells"]["dwell_index"]) >= 0)      # one revisit: dwell numbers
    stanag = pytest.importorskip("stanag4607", reason="PyPI stanag4607==0.1.0 (test extra)")
    dec = stanag.PacketStreamDecoder()
    decoded = list(dec.feed(b"".join(got)))
    dec.finish()
    assert len(decoded) == len(packets)


def test_packets_are_paced_by_dwell_time():
    dw, det = synthetic.tables(5, 10, seed=1)
    dw["time_s"] = np.arange(5) * 1.0                     # 4 s of dwells
    det["time_s"] = dw["time_s"][det["dwell_id"]]
    data = s4607.encode_4607(dw, det, META)
    n = len(live.split_packets(data))
    got, th, (_, port) = listen("udp://127.0.0.1:0", n)
    sender = live.Sender(f"udp://127.0.0.1:{port}", speed=10.0)
    t0 = time.monotonic()
    sender.send(data)
    elapsed = time.monotonic() - t0
    sender.close()
    th.join(10.0)
    assert len(got) == n
    assert elapsed >= 4.0 / 10.0 * 0.95                   # 4 s of scene at 10x real time


def test_a_receiver_refuses_a_stream_whose_sequence_goes_back():
    dw, det = synthetic.tables(4, 10, seed=5)
    dwells = s4607.read_4607(s4607.encode_4607(dw, det, META))["dwells"]
    live.check_order(dwells)
    back = dict(dwells, dwell_index=dwells["dwell_index"][::-1].copy())
    with pytest.raises(ValueError, match="goes back in"):
        live.check_order(back)
    late = dict(dwells, dwell_time_ms=dwells["dwell_time_ms"][::-1].copy())
    with pytest.raises(ValueError, match="dwell times go back"):
        live.check_order(late)


def test_bad_urls_are_clear_errors():
    from gmtiflow.errors import InputFileError
    for url in ("http://x:1", "udp://127.0.0.1", "tcp://:4607"):
        with pytest.raises(InputFileError):
            live.Sender(url)


@pytest.mark.slow
@pytest.mark.parametrize("blind", [False, True])
def test_a_run_streams_while_it_simulates_and_convert_receives_it(tmp_path, blind):
    """gmtiflow export=stream ...: the run's packets arrive; gmtiflow-convert udp://... --to h5
    decodes them into the same dwells and detections as the run's own 4607 export; with
    export.blind=true, both without truth (the stream used to carry every truth tag)."""
    import socket
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    recv = subprocess.Popen([sys.executable, "-m", "gmtiflow.convert", f"udp://127.0.0.1:{port}",
                             "--to", "h5", "-o", str(tmp_path / "live.h5"),
                             "--idle-timeout", "20"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.5)                                       # the receiver binds
    from gmtiflow import pipeline, store
    cfg = compose_app(["scene.duration_s=30", "fidelity.truth_output_dt_s=1.0",
                       "progress=false", "export=stream",
                       f"export.stream.url=udp://127.0.0.1:{port}", "export.stream.speed=0",
                       "export.formats=[stanag4607]", f"export.blind={str(blind).lower()}"])
    run = pipeline.run(cfg, tmp_path / "run")
    out, err = recv.communicate(timeout=120)
    assert recv.returncode == 0, err
    got = store.read_table(tmp_path / "live.h5", "dwells")
    ref = s4607.read_4607(run.parent / "detections.4607")
    assert len(got["dwell_id"]) == len(ref["dwells"]["dwell_id"]) > 0
    assert got["dwell_time_ms"].tolist() == ref["dwells"]["dwell_time_ms"].tolist()
    for c in ("revisit_id", "dwell_index", "n_packets"):
        assert got[c].tolist() == ref["dwells"][c].tolist(), c
    live.check_order(got)                                # dwell times and sequence numbers
    det = store.read_table(tmp_path / "live.h5", "detections")
    np.testing.assert_array_equal(det["lat_deg"], ref["detections"]["lat_deg"])
    np.testing.assert_array_equal(det["los_velocity_mps"], ref["detections"]["los_velocity_mps"])
    assert det["mti_report_index"].tolist() == ref["detections"]["mti_report_index"].tolist()
    np.testing.assert_array_equal(det["truth_id"], ref["detections"]["truth_id"])
    np.testing.assert_array_equal(det["rcs_dbsm"], ref["detections"]["rcs_dbsm"])
    truth_tagged = int(np.sum(det["truth_id"] >= 0))
    assert (truth_tagged == 0) if blind else (truth_tagged > 0)


def test_a_stream_of_several_sensors_is_refused_before_any_work(tmp_path):
    """Sensors are simulated one after the other, so their packets could not be paced together:
    export.stream with two sensors is one clear error and nothing is written."""
    from gmtiflow import pipeline
    from gmtiflow.errors import ConfigError
    cfg = compose_app(["experiment=two_orbits", "scene.duration_s=5", "progress=false",
                       "export=stream", "export.stream.url=udp://127.0.0.1:9"])
    with pytest.raises(ConfigError, match="export.stream.url: a live stream carries one sensor"):
        pipeline.run(cfg, tmp_path / "run")
    assert not (tmp_path / "run" / "run.h5").exists()
