"""Live STANAG 4607 over the network: a run's packets sent over UDP or TCP while it simulates.

The paper's "on-line simulator": a tracker listens as it would to an aircraft's downlink.

* :class:`Sender` sends 4607 packets to ``udp://HOST:PORT`` (one packet per datagram, the
  common practice and what Wireshark's Decode-As expects) or ``tcp://HOST:PORT`` (the byte
  stream; the receiver re-frames it by P2).  It paces them by their dwell time D6: a packet is
  sent when ``(D6 - D6 of the first packet) / speed`` seconds of wall-clock time have passed
  (``speed = 0``: as fast as possible).
* :class:`LiveExport` is the export stage's sink for a running simulation: the pipeline hands
  it every chunk of dwells and detections as they are simulated; it adapts them exactly as the
  file export does (:func:`gmtiflow.export_tables.to_4607_tables`) and sends them.
* :func:`receive` is the other end: it yields whole 4607 packets from ``udp://:PORT`` or
  ``tcp://:PORT`` until a packet count, an idle timeout or the sender closes (TCP);
  ``gmtiflow-convert udp://:4607 --to h5`` decodes what it receives with our reader.

Packets: every packet fits one UDP datagram (at most 65,507 bytes of payload over IPv4), so a
large dwell is split into several Dwell packets (GUIDE Annex D).  Order: packets are sent in
stream order; within one platform the dwell times, and the (revisit, dwell) indices within a
revisit, increase (the receiver can check them: :func:`check_order`).
"""
from __future__ import annotations

import socket
import struct
import time
from dataclasses import dataclass
from typing import Iterator, List, Optional, Tuple
from urllib.parse import urlsplit

import numpy as np

from gmtiflow.errors import InputFileError

UDP_MAX_PAYLOAD = 65_507          # 65,535 - 8 (UDP header) - 20 (IPv4 header)
SCHEMES = ("udp", "tcp")


def parse_url(url: str) -> Tuple[str, str, int]:
    """(scheme, host, port) of ``udp://HOST:PORT`` or ``tcp://HOST:PORT`` (host may be empty:
    all interfaces, for a receiver)."""
    parts = urlsplit(str(url))
    if parts.scheme not in SCHEMES or parts.port is None:
        raise InputFileError(f"{url!r}: expected udp://HOST:PORT or tcp://HOST:PORT "
                             "(e.g. udp://127.0.0.1:4607; a receiver may omit HOST)")
    return parts.scheme, parts.hostname or "", int(parts.port)


def is_url(text) -> bool:
    return isinstance(text, str) and text.split("://", 1)[0] in SCHEMES and "://" in text


def split_packets(data: bytes) -> List[bytes]:
    """The packets of a 4607 byte string (framed by P2)."""
    out, pos = [], 0
    while pos + 6 <= len(data):
        size = struct.unpack_from(">I", data, pos + 2)[0]
        if size < 32 or pos + size > len(data):
            raise ValueError(f"4607 stream: bad packet size {size} at byte {pos}")
        out.append(data[pos:pos + size])
        pos += size
    if pos != len(data):
        raise ValueError(f"4607 stream: {len(data) - pos} trailing bytes")
    return out


def packet_times_ms(packets: List[bytes]) -> np.ndarray:
    """Dwell time D6 (ms) of every packet whose first segment is a Dwell; other packets take the
    time of the next dwell packet (they announce it), or of the last one at the end."""
    t = np.full(len(packets), np.nan)
    for i, p in enumerate(packets):
        if len(p) >= 32 + 5 + 8 + 9 and p[32] == 2:
            t[i] = struct.unpack_from(">I", p, 32 + 5 + 8 + 5)[0]
    ok = np.flatnonzero(np.isfinite(t))
    if not len(ok):
        return np.zeros(len(packets))
    nxt = np.searchsorted(ok, np.arange(len(packets)))
    return t[ok[np.minimum(nxt, len(ok) - 1)]]


class Sender:
    """Sends 4607 packets to a UDP or TCP url, paced by their dwell times."""

    def __init__(self, url: str, speed: float = 1.0, connect_timeout_s: float = 10.0):
        self.scheme, host, port = parse_url(url)
        if not host:
            raise InputFileError(f"{url!r}: a sender needs a host (e.g. udp://127.0.0.1:4607)")
        if speed < 0:
            raise InputFileError(f"stream speed must be >= 0 (0 = as fast as possible), got {speed}")
        self.speed = float(speed)
        self.url = url
        if self.scheme == "udp":
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            self.sock.connect((host, port))
        else:
            try:
                self.sock = socket.create_connection((host, port), timeout=connect_timeout_s)
            except OSError as exc:
                raise InputFileError(f"{url}: cannot connect: {exc.strerror or exc}") from None
        self._t0_ms: Optional[float] = None
        self._wall0 = 0.0
        self.n_packets = 0
        self.n_bytes = 0

    def send(self, data: bytes) -> None:
        """Send the packets of ``data`` (whole 4607 packets), pacing dwell packets by D6."""
        packets = split_packets(data)
        times = packet_times_ms(packets)
        for p, t_ms in zip(packets, times.tolist()):
            if self.scheme == "udp" and len(p) > UDP_MAX_PAYLOAD:
                raise ValueError(f"4607 packet of {len(p)} bytes does not fit a UDP datagram")
            self._wait(t_ms)
            if self.scheme == "udp":
                self.sock.send(p)
            else:
                self.sock.sendall(p)
            self.n_packets += 1
            self.n_bytes += len(p)

    def _wait(self, t_ms: float) -> None:
        if self.speed <= 0:
            return
        if self._t0_ms is None:
            self._t0_ms, self._wall0 = t_ms, time.monotonic()
            return
        due = self._wall0 + (t_ms - self._t0_ms) / 1000.0 / self.speed
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)

    def close(self) -> None:
        try:
            if self.scheme == "tcp":
                self.sock.shutdown(socket.SHUT_WR)
        except OSError:
            pass
        self.sock.close()


def receive(url: str, *, max_packets: Optional[int] = None, idle_timeout_s: float = 5.0,
            ready=None) -> Iterator[bytes]:
    """Yield whole 4607 packets arriving at ``udp://[HOST]:PORT`` or ``tcp://[HOST]:PORT``.

    Stops after ``max_packets``, after ``idle_timeout_s`` without data, or (TCP) when the
    sender closes the connection.  ``ready`` (optional callable) is called once the socket
    listens, so a caller can start the sender then.  A UDP datagram that is not exactly one
    4607 packet (P2 = its length) is a ValueError naming the datagram.
    """
    scheme, host, port = parse_url(url)
    n = 0
    if scheme == "udp":
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
        sock.bind((host, port))
        sock.settimeout(idle_timeout_s)
        if ready:
            ready(sock.getsockname())
        try:
            while max_packets is None or n < max_packets:
                try:
                    dgram = sock.recv(65_535)
                except socket.timeout:
                    return
                if len(dgram) < 32 or struct.unpack_from(">I", dgram, 2)[0] != len(dgram):
                    raise ValueError(f"{url}: datagram {n} of {len(dgram)} bytes is not one 4607 "
                                     "packet (its P2 must equal its length)")
                n += 1
                yield dgram
        finally:
            sock.close()
        return
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    srv.bind((host, port))
    srv.listen(1)
    srv.settimeout(idle_timeout_s)
    if ready:
        ready(srv.getsockname())
    try:
        try:
            conn, _ = srv.accept()
        except socket.timeout:
            return
        conn.settimeout(idle_timeout_s)
        buf = bytearray()
        with conn:
            while max_packets is None or n < max_packets:
                while len(buf) >= 6:
                    size = struct.unpack_from(">I", buf, 2)[0]
                    if size < 32:
                        raise ValueError(f"{url}: packet {n}: P2 {size} < 32, not a 4607 stream")
                    if len(buf) < size:
                        break
                    pkt = bytes(buf[:size])
                    del buf[:size]
                    n += 1
                    yield pkt
                    if max_packets is not None and n >= max_packets:
                        return
                try:
                    chunk = conn.recv(1 << 16)
                except socket.timeout:
                    return
                if not chunk:
                    if buf:
                        raise ValueError(f"{url}: stream ended inside a packet "
                                         f"({len(buf)} bytes left)")
                    return
                buf += chunk
    finally:
        srv.close()


def check_order(dwells: dict) -> None:
    """ValueError unless, per platform, dwell times never go back and the dwell sequence
    numbers (revisit index D2, dwell index D3) never go back either (a receiver's sanity check;
    the Dwell packets of a split dwell repeat its numbers)."""
    t = np.asarray(dwells.get("dwell_time_ms", []), np.int64)
    pid = np.asarray(dwells.get("sensor_id", np.zeros(len(t))), np.int64)
    seq = (np.asarray(dwells["revisit_id"], np.int64) * 65536
           + np.asarray(dwells["dwell_index"], np.int64)) if "revisit_id" in dwells else None
    for s in np.unique(pid):
        mine = pid == s
        if np.any(np.diff(t[mine]) < 0):
            raise ValueError(f"platform {int(s)}: dwell times go back")
        if seq is not None and np.any(np.diff(seq[mine]) < 0):
            k = int(np.flatnonzero(np.diff(seq[mine]) < 0)[0]) + 1
            raise ValueError(f"platform {int(s)}: dwell {k} goes back in (revisit, dwell index)")


@dataclass
class StreamConfig:
    """``export.stream``: send the run's 4607 packets live while it simulates."""

    url: Optional[str] = None
    """udp://HOST:PORT or tcp://HOST:PORT; null = no live stream."""
    speed: float = 1.0
    """Pace: scene seconds per wall-clock second (10 = ten times real time); 0 = unpaced."""


class LiveExport:
    """The export stage's live sink: :meth:`append` a chunk of dwells and detections as the
    simulation produces it; they are adapted as for the file export (``export.blind``
    included: a chunk holds whole dwells, so its reports come out as the file's) and sent."""

    def __init__(self, stream: StreamConfig, export_cfg, origin, epoch_utc: str,
                 config: Optional[dict] = None):
        from gmtiflow import export, export_tables
        self._export, self._tables = export, export_tables
        self.cfg = export_cfg
        self.origin = origin
        self.epoch_utc = epoch_utc
        self.config = config or {}
        self.sender = Sender(stream.url, stream.speed)
        self._first = True

    def append(self, dwells: dict, detections: dict) -> None:
        from gmtiflow import formats
        if not len(dwells.get("dwell_id", ())):
            return
        run = self._tables.RunTables(None, {}, self.origin, self.epoch_utc, self.config,
                                     {"dwells": dwells, "detections": detections})
        if self.cfg.blind:        # as the file export: no truth, each dwell's reports by range
            run = self._export.blind_run(run)
        dw, det = self._tables.to_4607_tables(run)
        meta = self._tables.meta_for(self.cfg, run)
        meta["write_epoch_text"] = self._first
        data = formats.stanag4607.encode_4607(dw, det, meta, edition=str(self.cfg.edition),
                                              max_packet_bytes=UDP_MAX_PAYLOAD)
        self.sender.send(data)
        self._first = False

    def close(self) -> None:
        self.sender.close()
