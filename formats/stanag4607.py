"""STANAG 4607 / AEDP-4607 (GMTIF) writer and reader: the public API.

Layout, scalings and rules follow AEDP-4607 Ed. A v1, whose field layout equals STANAG 4607
Ed. 3.  All multi-byte fields are big-endian.  The codec lives in :mod:`formats.s4607`, split
along its seams (layout and scalings, packet framing, the small segments, the Dwell segment,
the writer, the reader); this module is the public API and re-exports them.

Writer (:func:`write_4607`, :func:`encode_4607`)
------------------------------------------------
One segment per packet, every packet <= 65,535 bytes (AEDP-4607.1 G.7.3 minimum capability).
Stream: ``Mission, Job Definition, [Free Text with the scene epoch, first time only]``, then the
Dwell packets; Mission + Job Definition are repeated at the start of every revisit and before any
dwell that comes >= 30 s after the last repetition (SPEC 3.3: Mission every 2 min; 3.7: Job
Definition every 30 s).  Mission, Job Definition, Free Text and Platform Location packets carry
P10 = 0 and Dwell packets P10 = job id (SPEC 3.1.10).  Every dwell is sent, even without targets.

Several sensors (a ``sensor_id`` column on the dwells, 0..S-1): each sensor is its own platform
(P8 ``platform_id`` + sensor number, its own P9 mission id and job id), with its own Mission
and Job Definition packets, and the dwells of all sensors are interleaved in time order, as a
recording of several aircraft would be.

Existence masks: one per dwell (:func:`formats.s4607.dwell.generated_masks`; absent stays
absent), or the ``existence_mask`` column of tables read from 4607, which makes
:func:`encode_read_tables` re-create a file read by :func:`read_4607` byte for byte.

Reader (:func:`iter_packets`, :func:`read_4607`)
------------------------------------------------
Parses any conforming file: every segment is framed by its S2 size, unknown types are skipped,
dwells are decoded for any existence mask (per-mask structured dtypes, targets decoded
vectorised), hi-res or reduced-resolution (D10/D11 + D32.4/5) positions, D5 = 0 with D32 bits
set.  :func:`read_4607` frames the whole buffer in one linear pass and decodes every segment
type vectorised.  Malformed input raises :class:`~formats.errors.FormatError` naming the byte
offset.
"""
from __future__ import annotations

from .s4607.dwell import WRITE_DWELL_MASK, tshark_safe_mask
from .s4607.layout import (MANDATORY_DWELL, MAX_PACKET_BYTES, dec_b16, dec_ba, dec_sa,
                           dwell_mask_bit, enc_b16, enc_ba16, enc_ba32, enc_sa16, enc_sa32,
                           target_mask_bit)
from .s4607.packet import Packet, Segment, iter_packets
from .s4607.reader import READ_TABLES, decode_4607, encode_read_tables, read_4607
from .s4607.writer import (DEFAULT_META, REQUIRED_META, encode_4607, platform_location_packets,
                           resolve_meta, sensor_meta, write_4607)

__all__ = [
    "write_4607", "encode_4607", "encode_read_tables", "resolve_meta", "sensor_meta",
    "platform_location_packets", "iter_packets", "read_4607", "decode_4607", "Packet", "Segment",
    "DEFAULT_META", "REQUIRED_META", "READ_TABLES", "MAX_PACKET_BYTES", "MANDATORY_DWELL",
    "WRITE_DWELL_MASK", "dwell_mask_bit", "target_mask_bit", "tshark_safe_mask",
    # field codecs (AEDP-4607 binary angle / signed binary angle / integer scalings)
    "enc_b16", "enc_ba16", "enc_ba32", "enc_sa16", "enc_sa32", "dec_b16", "dec_ba", "dec_sa",
]
