"""Track ids anywhere in 0 … 2^63 − 1 score exactly as small ids; negative ids are refused.

Found 2026-11-28 (metrics audit): ids far apart (e.g. 2^63 − 1 beside 0) overflowed the int64
keys the scorer builds from ids (``OverflowError`` from ``clear_mot``, or silent wrap-around in
``unique_pairs`` and the per-track error lookup), and a negative id was read as the scorer's own
"no track" (−1 and below): a tracker numbering its tracks −1, −2, … scored coverage 0 and
MOTA < 0 without a word."""
import numpy as np
import pytest

from gmtiflow.errors import InputFileError
from gmtiflow.evaluate.config import MetricsConfig
from gmtiflow.evaluate.stage import evaluate
from gmtiflow.evaluate.synthetic import gmti_scene
from gmtiflow.evaluate.tracker import TrackerConfig, track
from gmtiflow.evaluate.tracks import validate_tracks

TOP = 2 ** 63 - 1


@pytest.fixture(scope="module")
def scored():
    scene = gmti_scene(n_vehicles=5, n_revisits=30, seed=4, blind={1: [(50.0, 75.0)]})
    tracks = track(TrackerConfig(), scene["detections"], scene["dwells"])
    until = float(scene["dwells"]["time_s"].max())
    return scene, tracks, until, evaluate(MetricsConfig(), scene["truth"], tracks, scene["looks"],
                                          until_s=until)


ID_COLUMNS = {"metrics/track_errors": ["track_id"], "metrics/association": ["track_id"],
              "metrics/track_purity": ["track_id"],
              "metrics/identity_switches": ["from_track_id", "to_track_id"],
              "metrics/events": ["track_before", "track_after"]}


@pytest.mark.parametrize("name, remap", [
    ("top and bottom", lambda i: np.where(i % 2 == 0, TOP - i, i)),
    ("near 2^62", lambda i: 2 ** 62 + 3 * i),
    ("spread", lambda i: i * (TOP // 64)),
])
def test_any_64_bit_ids_score_as_small_ids(scored, name, remap):
    scene, tracks, until, ref = scored
    ids = np.asarray(tracks["track_id"], np.int64)
    assert len(np.unique(ids)) > 5 and ids.min() >= 0 and ids.max() < 64
    big = dict(tracks, track_id=remap(ids).astype(np.int64))
    assert len(np.unique(big["track_id"])) == len(np.unique(ids))
    out = evaluate(MetricsConfig(), scene["truth"], big, scene["looks"], until_s=until)
    back = dict(zip(remap(np.arange(64)).astype(np.int64).tolist(), range(64)))
    back[-1] = -1
    for key, ref_table in ref.items():
        got = {c: np.array([back[int(v)] for v in col], np.int64)
               if c in ID_COLUMNS.get(key, ()) else col for c, col in out[key].items()}
        # tables sorted by track id list their rows in the new ids' order: compare as sets
        order_got, order_ref = (np.lexsort([np.asarray(t[c]).astype(str) for c in t][::-1])
                                for t in (got, ref_table))
        assert sorted(got) == sorted(ref_table), key
        for c, ref_col in ref_table.items():
            np.testing.assert_array_equal(np.asarray(got[c])[order_got],
                                          np.asarray(ref_col)[order_ref],
                                          err_msg=f"{name}: {key}: {c}")


@pytest.mark.parametrize("ids", [np.array([3, -1]), np.array(["3", "-7"]),
                                 np.array([3.0, -2.0]), np.array([3, -2 ** 63])])
def test_negative_track_ids_are_refused(ids):
    table = {"track_id": ids, "time_s": np.array([0.0, 1.0]), "x_m": np.zeros(2),
             "y_m": np.zeros(2)}
    with pytest.raises(InputFileError,
                       match=r"ext\.csv: column 'track_id' row 1: .* is negative; track ids are "
                             r"0 \.\. 2\^63 - 1"):
        validate_tracks(table, source="ext.csv")


def test_negative_ids_in_a_track_csv_fail_gmtiflow_evaluate_with_one_line(run, tmp_path,
                                                                           capsys):
    from gmtiflow.evaluate import cli
    path = tmp_path / "neg.csv"
    path.write_text("track_id,time_s,x_m,y_m\n-1,5.0,0,0\n-1,6.0,1,0\n")
    out = tmp_path / "neg.metrics.h5"
    assert cli.main([str(path), str(run)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is negative" in err[0], err
    assert not out.exists()


def test_unique_pairs_of_ids_across_64_bits_is_np_unique():
    from gmtiflow.evaluate.identity import unique_pairs
    rng = np.random.default_rng(5)
    a = rng.choice(np.array([0, 7, TOP, TOP - 1, 2 ** 62], np.int64), 200)
    b = rng.choice(np.array([-2 ** 63, -1, 0, 3, TOP], np.int64), 200)
    pairs, counts = unique_pairs(a, b, return_counts=True)
    ref, ref_counts = np.unique(np.stack([a, b], axis=1), axis=0, return_counts=True)
    np.testing.assert_array_equal(pairs, ref)
    np.testing.assert_array_equal(counts, ref_counts)


@pytest.mark.parametrize("col, value", [("x_m", 1e300), ("y_m", -2e8), ("x_m", 1.7e308)])
def test_positions_beyond_any_point_on_earth_are_refused(col, value):
    """A track 1e300 m away used to be scored (as a false track) with numpy's cast and overflow
    warnings from the pair search; a position farther than 1e8 m from the scene origin is a
    unit or frame error, refused naming the row."""
    table = {"track_id": np.array([1, 1]), "time_s": np.array([0.0, 1.0]),
             "x_m": np.zeros(2), "y_m": np.zeros(2)}
    table[col] = np.array([0.0, value])
    with pytest.raises(InputFileError, match=rf"ext\.csv: column '{col}' row 1: .* is farther "
                                             r"than 1e\+08 m from the scene origin"):
        validate_tracks(table, source="ext.csv")


def test_far_but_earthly_positions_score_without_warnings(scored):
    import warnings
    scene, tracks, until, ref = scored
    far = {k: np.array(v, copy=True) for k, v in tracks.items()}
    far["x_m"][::7] = 9.9e7
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        evaluate(MetricsConfig(), scene["truth"], far, scene["looks"], until_s=until)
