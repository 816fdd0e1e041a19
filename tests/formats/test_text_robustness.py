"""Text formats: truncated, bit-flipped or random input raises FormatError and nothing else."""
from __future__ import annotations

import numpy as np
import pytest

from gmtiflow.formats import csvtable, geojson, synthetic, xmldoc
from gmtiflow.formats.errors import FormatError

META = {"epoch_utc": synthetic.EPOCH_UTC}


def _documents():
    dwells, dets = synthetic.tables(3, 6)
    truth = synthetic.truth(2, 3)
    return {
        "xml": (xmldoc.encode_xml(dwells, dets, META), xmldoc.read_xml),
        "csv": (csvtable.encode_csv(dets, "detections", epoch_utc=META["epoch_utc"]),
                csvtable.read_detections_csv),
        # truth lives in a GeoJSON file of its own: mutate a truth document too
        "geojson": (geojson.encode_geojson(detections=dets, epoch_utc=META["epoch_utc"])
                    if truth is None else geojson.encode_geojson(truth=truth,
                                                                 epoch_utc=META["epoch_utc"]),
                    geojson.read_geojson),
    }


@pytest.mark.parametrize("fmt", ["xml", "csv", "geojson"])
def test_mutations_raise_only_format_error(fmt):
    data, read = _documents()[fmt]
    rng = np.random.default_rng(0)
    alphabet = np.frombuffer(b'0123456789.,-+eE"<>/=:[]{} \nabcxyzINFnulltrue\xff', np.uint8)
    for k in range(250):
        b = bytearray(data)
        if k % 3 == 0:
            b = b[: rng.integers(0, len(b))]
        else:
            for i in rng.integers(0, len(b), rng.integers(1, 4)):
                b[i] = alphabet[rng.integers(0, len(alphabet))]
        try:
            read(bytes(b))
        except FormatError:
            pass


@pytest.mark.parametrize("fmt", ["xml", "csv", "geojson"])
def test_random_bytes_raise_only_format_error(fmt):
    _, read = _documents()[fmt]
    rng = np.random.default_rng(1)
    for _ in range(100):
        try:
            read(rng.integers(0, 256, rng.integers(0, 200), dtype=np.uint8).tobytes())
        except FormatError:
            pass
