"""CSV tables: exact round trips, pandas and Stone Soup read them as is, errors name line/column."""
from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from gmtiflow.formats import csvtable, synthetic
from gmtiflow.formats.errors import FormatError

EPOCH = synthetic.EPOCH_UTC


def _equal(expected, got):
    for c, a in expected.items():
        a = np.asarray(a)
        if a.dtype.kind == "f":
            np.testing.assert_array_equal(a, got[c], err_msg=c)
        else:
            assert a.tolist() == got[c].tolist(), c
        assert got[c].dtype.kind == a.dtype.kind or (a.dtype.kind in "iu" and got[c].dtype.kind in "iu"), c


@pytest.mark.parametrize("kind,make", [
    ("detections", lambda: synthetic.tables(8, 60, seed=2)[1]),
    ("truth", lambda: synthetic.truth(4, 10)),
    ("tracks", lambda: synthetic.tracks(3, 6)),
])
def test_round_trip_is_exact(kind, make, tmp_path):
    table = make()
    table[next(c for c, k in csvtable.COLUMNS[kind].items() if k == "float" and c != "time_s")][0] = np.nan
    path = tmp_path / f"{kind}.csv"
    csvtable.write_csv(path, table, kind, epoch_utc=EPOCH)
    _equal(table, csvtable.read_csv(path, kind))


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31), n=st.integers(0, 50),
       x=st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=1, max_size=1))
def test_round_trip_random_detections(seed, n, x):
    _, dets = synthetic.tables(5, n, seed=seed)
    if n:
        dets["snr_db"][0] = x[0]
    _equal(dets, csvtable.read_csv(csvtable.encode_csv(dets, "detections", epoch_utc=EPOCH),
                                   "detections"))


def test_header_and_time_columns():
    _, dets = synthetic.tables(3, 5)
    lines = csvtable.encode_csv(dets, "detections", epoch_utc=EPOCH).decode().splitlines()
    assert lines[0].split(",")[:6] == ["time_utc", "time_s", "det_id", "dwell_id", "lat_deg", "lon_deg"]
    t0 = datetime(2026, 11, 21, 13, 0, 0, 250000) + timedelta(seconds=float(dets["time_s"][0]))
    assert lines[1].split(",")[0] == t0.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def test_pandas_reads_it_as_is(tmp_path):
    pd = pytest.importorskip("pandas", reason="pandas is not installed (it comes with the "
                             "stonesoup test extra on most platforms)")
    _, dets = synthetic.tables(6, 40)
    path = tmp_path / "d.csv"
    csvtable.write_detections_csv(path, dets, epoch_utc=EPOCH)
    df = pd.read_csv(path, parse_dates=["time_utc"])
    assert len(df) == 40
    np.testing.assert_array_equal(df["lat_deg"].to_numpy(), dets["lat_deg"])
    assert df["truth_id"].dtype.kind == "i" and df["merged"].dtype == bool
    assert df["time_utc"].iloc[0].year == 2026
    dt = (df["time_utc"] - df["time_utc"].iloc[0]).dt.total_seconds().to_numpy()
    np.testing.assert_allclose(dt, dets["time_s"] - dets["time_s"][0], atol=1e-6)


def test_stone_soup_csv_detection_reader_reads_it_as_is(tmp_path):
    try:
        from stonesoup.reader.generic import CSVDetectionReader
    except Exception as exc:                     # pragma: no cover - depends on the environment
        pytest.skip(f"stonesoup cannot be imported ({exc!r}); install the test extra")
    _, dets = synthetic.tables(6, 40, seed=7)
    path = tmp_path / "d.csv"
    csvtable.write_detections_csv(path, dets, epoch_utc=EPOCH)
    reader = CSVDetectionReader(path, state_vector_fields=("x_m", "y_m"), time_field="time_utc")
    got = [(t, d) for t, ds in reader for d in ds]
    assert len(got) == 40
    by_id = {int(d.metadata["det_id"]): (t, d) for t, d in got}
    epoch = datetime(2026, 11, 21, 13, 0, 0, 250000)
    for i in range(40):
        t, d = by_id[int(dets["det_id"][i])]
        assert d.state_vector.ravel().tolist() == [dets["x_m"][i], dets["y_m"][i]]
        assert abs((t - epoch).total_seconds() - dets["time_s"][i]) < 1e-6
        assert int(d.metadata["truth_id"]) == dets["truth_id"][i]
    # range/azimuth as the state works the same way
    reader = CSVDetectionReader(path, state_vector_fields=("azimuth_rad", "range_m"),
                                time_field="time_utc")
    assert sum(len(ds) for _, ds in reader) == 40


def test_errors_name_line_and_column():
    _, dets = synthetic.tables(3, 4)
    text = csvtable.encode_csv(dets, "detections", epoch_utc=EPOCH).decode()
    lines = text.splitlines()
    cells = lines[2].split(",")
    cells[5] = "abc"                                   # lon_deg of the second row
    bad = "\n".join(lines[:2] + [",".join(cells)] + lines[3:])
    with pytest.raises(FormatError, match=r"line 3, column 6 \(lon_deg\): 'abc' is not a number"):
        csvtable.read_detections_csv(bad.encode())
    cells = lines[1].split(",")
    cells[2] = "1.5"                                   # det_id must be an integer
    bad = "\n".join([lines[0], ",".join(cells)] + lines[2:])
    with pytest.raises(FormatError, match=r"line 2, column 3 \(det_id\): '1.5' is not an integer"):
        csvtable.read_detections_csv(bad.encode())
    with pytest.raises(FormatError, match=r"line 1, column 2: unknown column 'colour'"):
        csvtable.read_detections_csv(b"time_s,colour\n1,red\n")
    with pytest.raises(FormatError, match=r"missing required columns \['det_id', 'dwell_id'\]"):
        csvtable.read_detections_csv(b"time_s\n1\n")
    with pytest.raises(FormatError, match=r"line 3: 2 fields, expected 3"):
        csvtable.read_detections_csv(b"time_s,det_id,dwell_id\n1,2,3\n1,2\n")
    with pytest.raises(FormatError, match="duplicate column"):
        csvtable.read_detections_csv(b"time_s,det_id,dwell_id,det_id\n")
    with pytest.raises(FormatError, match="line 1: empty"):
        csvtable.read_detections_csv(b"")
    with pytest.raises(FormatError, match="not UTF-8"):
        csvtable.read_detections_csv(b"time_s,det_id,dwell_id\n\xff,1,2\n")
    with pytest.raises(FormatError, match=r"column 3 \(merged\): 'maybe' is not True or False"):
        csvtable.read_detections_csv(b"time_s,det_id,merged,dwell_id\n1,2,maybe,0\n")


def test_writer_refuses_unknown_columns_and_sorts_by_time():
    _, dets = synthetic.tables(3, 4)
    with pytest.raises(ValueError, match="colour"):
        csvtable.encode_csv(dict(dets, colour=np.zeros(4)), "detections", epoch_utc=EPOCH)
    rev = {k: np.asarray(v)[::-1] for k, v in dets.items()}
    back = csvtable.read_csv(csvtable.encode_csv(rev, "detections", epoch_utc=EPOCH), "detections")
    assert np.all(np.diff(back["time_s"]) >= 0)
