"""The merging effect in the sensor stage: Doppler-aware by default, σ's from the merged SNR."""
import numpy as np

from gmtiflow.sensor import measurement, scan
from gmtiflow.sensor.config import MergeCells, MergeConfig, MergeMode, SensorConfig
from gmtiflow.sensor.effects import Merging
from gmtiflow.sensor.model import simulate
from sensor_fakes import ORIGIN, FlatTerrain, LevelPlatform, LineFleet

HOVER = LevelPlatform(speed_mps=0.0)


def _pairs_run(cells):
    """30 pairs of vehicles, each pair starting at one point and driving away from the radar at
    8 and 9.5 m/s: 3.2 Doppler cells apart (λ/(2 CPI) = 0.47 m/s) but < 0.7 m apart in range
    during the scan (Δr = 3 m) and at the same azimuth; pairs 100 m apart in range."""
    y = np.repeat(np.arange(-1500.0, 1500.0, 100.0), 2)
    p0 = np.column_stack([np.zeros_like(y), y, np.zeros_like(y)])
    v = np.zeros_like(p0)
    v[:, 1] = np.tile([8.0, 9.5], len(y) // 2)
    cfg = SensorConfig(merge=MergeConfig(mode=MergeMode.threshold, cells=MergeCells(cells)))
    out = simulate(cfg, LineFleet(p0, v), HOVER, FlatTerrain(), 2, scan.n_dwells(cfg) * cfg.cpi_s,
                   ORIGIN, effects=[Merging(cfg, 2, iterate=False)])
    return cfg, out


def test_targets_in_different_doppler_cells_are_resolved_by_default():
    cfg, out = _pairs_run("range_azimuth_range_rate")
    assert cfg.merge.use_range_rate
    det = out["detections"]
    assert len(det["det_id"]) > 40 and not det["merged"].any()
    _, old = _pairs_run("range_azimuth")
    assert old["detections"]["merged"].sum() >= 10


def test_merged_sigmas_follow_the_merged_snr():
    cfg, out = _pairs_run("range_azimuth")
    det, dw = out["detections"], out["dwells"]
    m = det["merged"]
    k = det["dwell_id"][m] - dw["dwell_id"][0]
    bw = scan.broadened_beamwidth_rad(cfg, dw["beam_scan_rad"][k])
    s_r, s_az, s_rr = measurement.sigmas(cfg, 10 ** (det["snr_db"][m] / 10), bw)
    assert np.allclose(det["sigma_range_m"][m], s_r, rtol=1e-9)
    assert np.allclose(det["sigma_azimuth_rad"][m], s_az, rtol=1e-9)
    assert np.allclose(det["sigma_range_rate_mps"][m], s_rr, rtol=1e-9)
    assert m.sum() >= 10


def test_merging_renumbers_the_same_with_ids_in_any_order():
    """Detections numbered 0..n-1 in dwell order take the direct path; the same detections
    with their ids shuffled go through reindex: the same tables (ids aside, which are the
    row numbers either way) and the same looks."""
    from gmtiflow.sensor.context import ChunkContext
    from gmtiflow.sensor.model import DETECTION_COLUMNS

    cfg = SensorConfig(merge=MergeConfig(mode=MergeMode.threshold, cells=MergeCells("range_azimuth")))
    y = np.repeat(np.arange(-1500.0, 1500.0, 100.0), 2)
    p0 = np.column_stack([np.zeros_like(y), y, np.zeros_like(y)])
    v = np.zeros_like(p0)
    v[:, 1] = np.tile([8.0, 9.5], len(y) // 2)
    seen = {}

    def grab(ctx, det, looks):
        seen["args"] = (ctx, det, looks)
        return det, looks

    simulate(cfg, LineFleet(p0, v), HOVER, FlatTerrain(), 2, scan.n_dwells(cfg) * cfg.cpi_s,
             ORIGIN, effects=[grab])
    ctx, det, looks = seen["args"]
    assert isinstance(ctx, ChunkContext) and set(det) == set(DETECTION_COLUMNS)
    merging = Merging(cfg, 2, iterate=False)
    plain_det, plain_looks = merging(ctx, dict(det), dict(looks))
    perm = np.random.default_rng(1).permutation(len(det["det_id"]))
    ids = det["det_id"][perm]                      # det i gets id ids[i]
    shuffled = dict(det, det_id=ids)
    lk = dict(looks)
    has = lk["det_id"] >= 0
    lk["det_id"] = np.where(has, ids[np.maximum(lk["det_id"], 0)], -1)
    other_det, other_looks = merging(ctx, shuffled, lk)
    assert plain_det["merged"].sum() >= 10
    for name in plain_det:
        assert plain_det[name].tobytes() == other_det[name].tobytes(), name
    for name in plain_looks:
        assert np.asarray(plain_looks[name]).tobytes() == np.asarray(other_looks[name]).tobytes(), name
