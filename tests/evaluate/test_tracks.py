"""Validation of external track tables: one clear InputFileError naming column and row."""
import numpy as np
import pytest

from gmtiflow import frames
from gmtiflow.errors import InputFileError
from gmtiflow.evaluate.tracks import validate_tracks

ORIGIN = frames.Origin(48.0, 11.0, 500.0)


def good():
    return {"track_id": np.array([2, 1, 1, 2]), "time_s": np.array([0.0, 0.0, 1.0, 1.0]),
            "x_m": np.array([0.0, 10.0, 11.0, 1.0]), "y_m": np.zeros(4),
            "vx_mps": np.ones(4), "vy_mps": np.zeros(4), "confirmed": np.array([1, 0, 1, 1])}


def test_good_table_is_sorted_and_typed():
    out = validate_tracks(good())
    assert list(out["track_id"]) == [1, 1, 2, 2]
    assert list(out["time_s"]) == [0.0, 1.0, 0.0, 1.0]
    assert out["track_id"].dtype == np.int64 and out["confirmed"].dtype == bool
    assert list(out["confirmed"]) == [False, True, True, True]


@pytest.mark.parametrize("edit, pattern", [
    (lambda t: t.update(speed_kts=np.zeros(4)), r"unknown column\(s\) 'speed_kts'"),
    (lambda t: t.pop("time_s"), r"missing required column 'time_s'"),
    (lambda t: t.pop("y_m"), r"missing column 'y_m'"),
    (lambda t: t.pop("vy_mps"), r"vx_mps given without vy_mps"),
    (lambda t: t["x_m"].__setitem__(2, np.nan), r"column 'x_m' row 2: nan is not a finite"),
    (lambda t: t.update(track_id=np.array([2.0, 1.5, 1.0, 2.0])),
     r"column 'track_id' row 1: 1.5 is not an integer"),
    (lambda t: t.update(track_id=np.array([2, 1.5, 1, 2], dtype=object)),
     r"column 'track_id' row 1: 1.5 is not an integer"),
    (lambda t: t.update(time_s=np.array(["0", "zero", "1", "1"], dtype=object)),
     r"column 'time_s' row 1: 'zero' is not a number"),
    (lambda t: t.update(time_s=np.array([0.0, 1.0, 0.5, 1.0])),
     r"column 'time_s' row 2: track 1 goes back in time"),
    (lambda t: t.update(time_s=np.array([0.0, 1.0, 1.0, 1.0])),
     r"rows 1 and 2 are both track 1 at time_s 1.0 \(ids collide\)"),
    (lambda t: t.update(x_m=np.zeros(3)), r"different lengths"),
    (lambda t: t.update(confirmed=np.array([1, 0, 2, 1])), r"column 'confirmed' row 2"),
])
def test_bad_tables_name_the_problem(edit, pattern):
    table = good()
    edit(table)
    with pytest.raises(InputFileError, match=pattern):
        validate_tracks(table, source="ext.csv")


def test_text_columns_as_a_csv_reader_gives_them():
    table = {k: np.asarray([str(v) for v in col], dtype=object) for k, col in good().items()}
    table["confirmed"] = np.array(["true", "False", " 1", "0"], dtype=object)
    out = validate_tracks(table)
    assert list(out["confirmed"]) == [False, True, True, False]     # sorted by (id, time)
    assert out["x_m"].dtype == np.float64
    table["confirmed"][1] = "maybe"
    with pytest.raises(InputFileError, match=r"column 'confirmed' row 1: 'maybe'"):
        validate_tracks(table)


def test_message_names_the_source():
    table = good()
    table["x_m"][0] = np.inf
    with pytest.raises(InputFileError, match=r"^ext\.csv: column 'x_m' row 0"):
        validate_tracks(table, source="ext.csv")


def test_lat_lon_are_converted_with_the_origin():
    x = np.array([100.0, -2500.0])
    y = np.array([2000.0, 30.0])
    lat, lon, h = frames.enu_to_geodetic(ORIGIN, x, y, np.zeros(2))
    table = {"track_id": np.array([1, 1]), "time_s": np.array([0.0, 1.0]), "lat_deg": lat,
             "lon_deg": lon, "height_m": h}
    out = validate_tracks(table, ORIGIN)
    np.testing.assert_allclose(out["x_m"], x, atol=1e-6)
    np.testing.assert_allclose(out["y_m"], y, atol=1e-6)
    assert "lat_deg" not in out
    with pytest.raises(InputFileError, match="no scene origin"):
        validate_tracks(table)


def test_empty_table_is_fine():
    out = validate_tracks({"track_id": np.zeros(0), "time_s": np.zeros(0), "x_m": np.zeros(0),
                           "y_m": np.zeros(0)})
    assert len(out["track_id"]) == 0


def test_a_run_file_with_a_trackers_own_columns_opens(tmp_path):
    # The Stone Soup trackers report no range rate; their run files must read like any other
    # (the benchmark collects them with require_columns).
    from gmtiflow import store
    tracks = {"track_id": np.array([1, 1]), "time_s": np.array([0.0, 5.0]),
              "x_m": np.zeros(2), "y_m": np.ones(2), "confirmed": np.ones(2, bool)}
    with store.RunWriter(tmp_path / "run.h5", seed=1) as w:
        w.write_table("tracks", tracks)
        path = w.commit()
    with store.open_run(path, require_columns=True) as f:
        assert "range_rate_mps" not in f["tracks"]
    del tracks["x_m"]
    with store.RunWriter(tmp_path / "bad.h5", seed=1) as w:
        w.write_table("tracks", tracks)
        bad = w.commit()
    with pytest.raises(store.StoreError, match="lacks the column"):
        store.open_run(bad, require_columns=True).close()


BIG = 2 ** 60


@pytest.mark.parametrize("as_text", [False, True])
def test_64_bit_track_ids_stay_apart(as_text):
    """Ids went through float64, where 2^60 and 2^60 + 1 are one number: two tracks that never
    share an instant were silently scored as one (n_tracks 1 instead of 2)."""
    ids = np.array([BIG, BIG, BIG + 1, BIG + 1], dtype=np.int64)
    table = {"track_id": ids, "time_s": np.array([0.0, 1.0, 2.0, 3.0]),
             "x_m": np.zeros(4), "y_m": np.zeros(4)}
    if as_text:        # as the evaluate CLI's CSV reader gives them
        table = {k: np.asarray([str(v) for v in col]) for k, col in table.items()}
    out = validate_tracks(table, source="ext.csv")
    assert out["track_id"].tolist() == [BIG, BIG, BIG + 1, BIG + 1]


@pytest.mark.parametrize("ids, pattern", [
    (np.array([2.0 ** 60, 1.0]), r"column 'track_id' row 0: .* beyond 2\^53"),
    (np.array(["99999999999999999999999", "1"]), r"column 'track_id' row 0: .* 64-bit"),
    (np.array([2 ** 64 - 1, 1], dtype=np.uint64), r"column 'track_id' row 0: .* 64-bit"),
])
def test_track_ids_a_float_or_int64_cannot_hold_are_refused(ids, pattern):
    """A 23-digit id used to print numpy's cast warning and then report a collision of ids
    -9223372036854775808."""
    table = {"track_id": ids, "time_s": np.array([0.0, 1.0]), "x_m": np.zeros(2),
             "y_m": np.zeros(2)}
    with pytest.raises(InputFileError, match=pattern):
        validate_tracks(table, source="ext.csv")
