"""Stone Soup trackers behind the tracker protocol (``pip install 'gmtiflow[stonesoup]'``).

``tracker=stonesoup_gnn`` / ``stonesoup_jpda`` / ``stonesoup_gmphd`` (``conf/tracker/``) build
these classes with ``tracker.params``; each is fed the protocol's blind per-dwell batches
(:mod:`gmtiflow.evaluate.protocol`) and assembled from Stone Soup components (stonesoup ≥ 1.7;
tested with 1.9.1), so the filtering, gating and association are Stone Soup's, not ours:

* **State and motion**: ``[x, vx, y, vy]`` in the scene's ENU ground plane; two
  ``ConstantVelocity`` models (continuous white-noise acceleration, density
  ``accel_sigma_mps2``² · 1 s, as the baseline's ``cwna``).
* **Measurement model**: one ``LinearGaussian`` per detection (mapping x, y) whose covariance is
  the detection's own: σ⊥ = R·σ_az across the line of sight and σ∥ = σ_r·R/ρ along it, rotated
  by the LOS azimuth from *that detection's dwell's* platform (the baseline's formula,
  :func:`gmtiflow.evaluate.tracker._measurements`), so detections of several sensors each carry
  their own geometry.  Range rate is not used (the Stone Soup models here are linear in the
  ground plane).
* **Where the radar looked**: a track is only predicted, gated and missed by a dwell whose
  footprint covers it (the baseline's coverage test with ``footprint_margin_m``); a GMTI dwell
  sees a narrow sector, and treating every other track as missed would delete them all.
* ``StoneSoupGNN``: ``DistanceHypothesiser`` (Mahalanobis, ``missed_distance`` = the χ²
  gate ``gate_probability`` as a distance) + ``GNNWith2DAssignment``.
* ``StoneSoupJPDA``: ``PDAHypothesiser`` (``prob_detect``, ``clutter_density_per_km2``,
  ``gate_probability``) + ``JPDAwithEHM`` (stonesoup ≥ 1.7): the exact JPDA marginals, computed
  per cluster of tracks that share gated detections by efficient hypothesis management (Maskell
  et al. 2004) instead of enumerating every joint hypothesis of all covered tracks, which is
  exponential in their number and did not finish a dense-clutter scene; in a dwell whose widest
  cluster has more than ``exact_cluster_max_tracks`` tracks, ``JPDAwithLBP`` (loopy belief
  propagation: approximate marginals, polynomial cost); each track's posterior
  is the moment-matched mixture of its hypotheses (``gm_reduce_single``).
* Both initiate with ``MultiMeasurementInitiator`` (GNN on the unassociated detections; a track
  is confirmed and reported after ``min_points`` updates; like a confirmed track, a holding
  track is only offered the detections of dwells that cover it) and delete tracks without an
  update for ``delete_after_s`` (``UpdateTimeDeleter``; a JPDA update counts when its detection
  hypotheses together outweigh the miss).
* ``StoneSoupGMPHD``: Gaussian-mixture PHD (``GaussianMixtureHypothesiser``, ``PHDUpdater``,
  ``GaussianMixtureReducer``) on the covered components; a birth component per dwell spread over
  its footprint (weight ``birth_weight``); a tag's components above ``extraction_threshold``
  are reported as that track (its heaviest component).

Rows: like the baseline, one row per (confirmed track, covering dwell): the updated state, or
the prediction when the dwell missed it.  Tracks ids count from 0 in order of confirmation.
"""
from __future__ import annotations

import datetime
import logging
from typing import Dict, List, Optional

import numpy as np
from scipy.stats import chi2

from gmtiflow.evaluate.config import TrackerConfig
from gmtiflow.evaluate.protocol import Batch, SceneInfo
from gmtiflow.evaluate.tracker import TRACK_COLUMNS, _covered, _measurements

try:
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.dataassociator._ehm import TrackClusterer   # what JPDAwithEHM clusters with
    from stonesoup.dataassociator.probability import JPDAwithEHM, JPDAwithLBP
    from stonesoup.deleter.time import UpdateTimeDeleter
    from stonesoup.functions import gm_reduce_single
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.hypothesiser.gaussianmixture import GaussianMixtureHypothesiser
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.base import Property
    from stonesoup.hypothesiser import Hypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.measures import Mahalanobis
    from stonesoup.mixturereducer.gaussianmixture import GaussianMixtureReducer
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import (CombinedLinearGaussianTransitionModel,
                                                    ConstantVelocity)
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.types.array import StateVectors
    from stonesoup.types.detection import Detection
    from stonesoup.types.state import GaussianState, TaggedWeightedGaussianState
    from stonesoup.types.update import GaussianStateUpdate
    from stonesoup.updater.kalman import KalmanUpdater
    from stonesoup.updater.pointprocess import PHDUpdater
except ImportError as exc:                       # pragma: no cover (the extra is installed in CI)
    raise ImportError("the Stone Soup trackers need the optional extra: "
                      "pip install 'gmtiflow[stonesoup]'") from exc

_BASE = datetime.datetime(2000, 1, 1)


def _stamp(t_s: float) -> datetime.datetime:
    return _BASE + datetime.timedelta(seconds=float(t_s))


class _StoneSoupTracker:
    """What the three share: models, per-detection covariances, footprint coverage, rows."""

    def __init__(self, accel_sigma_mps2: float = 1.0, init_speed_sigma_mps: float = 15.0,
                 footprint_margin_m: float = 200.0, gate_probability: float = 0.999,
                 default_sigma_range_m: float = 20.0, default_sigma_azimuth_deg: float = 0.2):
        self.accel_sigma_mps2 = float(accel_sigma_mps2)
        self.init_speed_sigma_mps = float(init_speed_sigma_mps)
        self.footprint_margin_m = float(footprint_margin_m)
        self.gate_probability = float(gate_probability)
        self._sigmas = TrackerConfig(use_range_rate=False,
                                     default_sigma_range_m=default_sigma_range_m,
                                     default_sigma_azimuth_deg=default_sigma_azimuth_deg)
        q = self.accel_sigma_mps2 ** 2
        self.transition = CombinedLinearGaussianTransitionModel(
            [ConstantVelocity(q), ConstantVelocity(q)])
        self.predictor = KalmanPredictor(self.transition)
        # The updater's own model is only a fallback: every detection carries its own.
        self.default_model = LinearGaussian(ndim_state=4, mapping=(0, 2),
                                            noise_covar=np.diag([100.0 ** 2, 100.0 ** 2]))
        self.updater = KalmanUpdater(self.default_model)

    def reset(self, scene: SceneInfo) -> None:
        self._ids: Dict[object, int] = {}

    def finish(self):
        return None

    # -- helpers ----------------------------------------------------------------------------
    def _detections(self, dw, k: int, det) -> List[Detection]:
        """Stone Soup detections of dwell ``k``, each with its own measurement covariance."""
        usable = np.isfinite(np.asarray(det["x_m"], float)) & np.isfinite(
            np.asarray(det["y_m"], float))
        if "implausible" in det:
            usable &= ~np.asarray(det["implausible"], bool)
        idx = np.flatnonzero(usable)
        if not len(idx):
            return []
        plat = np.array([dw["platform_x_m"][k], dw["platform_y_m"][k], dw["platform_z_m"][k]],
                        float)
        z, R, _, _ = _measurements(det, idx, plat, self._sigmas)
        when = _stamp(dw["time_s"][k])
        out = []
        for i in range(len(idx)):
            model = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=R[i, :2, :2])
            out.append(Detection(z[i, :2].reshape(2, 1), timestamp=when, measurement_model=model,
                                 metadata={"det_id": int(det["det_id"][idx[i]])
                                           if "det_id" in det else i}))
        return out

    def _covered_mask(self, dw, k: int, states) -> np.ndarray:
        """Which of ``states`` (GaussianStates) the footprint of dwell ``k`` covers."""
        n = len(states)
        if not n or not ("beam_az_rad" in dw and "angle_half_extent_rad" in dw):
            return np.ones(n, bool)
        t = float(dw["time_s"][k])
        pos = np.empty((n, 2))
        for i, s in enumerate(states):
            sv = np.ravel(s.state_vector).astype(float)
            dt = (t - (s.timestamp - _BASE).total_seconds())
            pos[i] = sv[0] + sv[1] * dt, sv[2] + sv[3] * dt
        plat = np.array([dw["platform_x_m"][k], dw["platform_y_m"][k], dw["platform_z_m"][k]],
                        float)
        return _covered(dw, k, pos, np.zeros(n), plat, self.footprint_margin_m)

    def _prior(self) -> GaussianState:
        v = self.init_speed_sigma_mps ** 2
        return GaussianState(np.zeros((4, 1)), np.diag([1.0, v, 1.0, v]))

    def _rows(self, ids, t: float, states) -> Optional[dict]:
        if not states:
            return None
        sv = np.array([np.ravel(s.state_vector).astype(float) for s in states])
        P = np.array([np.asarray(s.covar, float) for s in states])
        n = len(states)
        return {"track_id": np.asarray(ids, np.int64), "time_s": np.full(n, t),
                "x_m": sv[:, 0], "y_m": sv[:, 2], "vx_mps": sv[:, 1], "vy_mps": sv[:, 3],
                "cov_xx_m2": P[:, 0, 0], "cov_xy_m2": P[:, 0, 2], "cov_yy_m2": P[:, 2, 2],
                "confirmed": np.ones(n, bool)}

    def _id(self, key) -> int:
        if key not in self._ids:
            self._ids[key] = len(self._ids)
        return self._ids[key]

    def update(self, batch: Batch):
        out = []
        dw, det = batch.dwells, batch.detections
        for k, rows in batch.dwell_slices():
            sub = {name: col[rows] for name, col in det.items()}
            rows_k = self._dwell(dw, k, sub)
            if rows_k is not None:
                out.append(rows_k)
        if not out:
            return None
        cols = [c for c in TRACK_COLUMNS if c in out[0]]
        return {c: np.concatenate([o[c] for o in out]) for c in cols}


def _first_det_id(track) -> int:
    """det_id of the detection a track was started from (a deterministic order of new tracks;
    Stone Soup hands them over in a set)."""
    for state in track.states:
        hyp = getattr(state, "hypothesis", None)
        meas = getattr(hyp, "measurement", None)
        if meas is not None and "det_id" in getattr(meas, "metadata", {}):
            return int(meas.metadata["det_id"])
    return -1


class _AssociatingTracker(_StoneSoupTracker):
    """GNN / JPDA: confirmed tracks updated by an associator, M-point initiation."""

    def __init__(self, min_points: int = 3, delete_after_s: float = 25.0, **kwargs):
        self.min_points = int(min_points)
        self.delete_after_s = float(delete_after_s)
        super().__init__(**kwargs)
        self.gate_distance = float(np.sqrt(chi2.ppf(self.gate_probability, 2)))
        self.gnn = GNNWith2DAssignment(DistanceHypothesiser(
            self.predictor, self.updater, measure=Mahalanobis(),
            missed_distance=self.gate_distance))
        self.reset(SceneInfo())

    def reset(self, scene: SceneInfo) -> None:
        super().reset(scene)
        self.tracks = set()
        self.deleter = UpdateTimeDeleter(
            time_since_update=datetime.timedelta(seconds=self.delete_after_s))
        self.initiator = MultiMeasurementInitiator(
            prior_state=self._prior(), deleter=self.deleter, data_associator=self.gnn,
            updater=self.updater, measurement_model=self.default_model,
            min_points=self.min_points)

    def _associate_and_update(self, tracks, detections, when) -> set:
        raise NotImplementedError

    def _dwell(self, dw, k: int, det):
        t = float(dw["time_s"][k])
        when = _stamp(t)
        detections = self._detections(dw, k, det)
        tracks = sorted(self.tracks, key=self._id)
        covered = [tr for tr, c in zip(tracks, self._covered_mask(
            dw, k, [tr.state for tr in tracks])) if c]
        # Lists in a fixed order (tracks by id, plots by det_id), not sets: a set of Stone Soup
        # objects iterates in address order, which changed the JPDA sums in the last bits from
        # one process to the next.
        used = self._associate_and_update(covered, detections, when) \
            if covered else set()
        dead = self.deleter.delete_tracks(self.tracks, timestamp=when)
        self.tracks -= dead
        new = self._initiate(dw, k, set(detections) - used, when)
        for tr in sorted(new, key=_first_det_id):
            self._id(tr)
        self.tracks |= new
        report = [tr for tr in covered if tr not in dead] + sorted(new, key=self._id)
        return self._rows([self._id(tr) for tr in report], t, [tr.state for tr in report])

    def _initiate(self, dw, k: int, detections: set, when) -> set:
        """The initiator's step with only the holding (tentative) tracks this dwell covers.

        Stone Soup's ``MultiMeasurementInitiator`` associates *every* holding track with the
        dwell's detections and predicts the ones it misses; a GMTI dwell sees a narrow sector,
        so, as for confirmed tracks, a holding track outside the footprint is neither offered
        the detections nor missed.  It is still deleted ``delete_after_s`` after its last
        update.  Without this the initiator's association dominated the run time in clutter
        (every false alarm holds a track for ``delete_after_s``, and each was hypothesised
        against each dwell's detections).
        """
        held = sorted(self.initiator.holding_tracks, key=_first_det_id)
        away = {tr for tr, c in zip(held, self._covered_mask(
            dw, k, [tr.state for tr in held])) if not c}
        self.initiator.holding_tracks -= away
        new = self.initiator.initiate(detections, when)
        away -= self.deleter.delete_tracks(away, timestamp=when)
        self.initiator.holding_tracks |= away
        return new


class StoneSoupGNN(_AssociatingTracker):
    """Global nearest neighbour (Stone Soup ``GNNWith2DAssignment``)."""

    def _associate_and_update(self, tracks, detections, when) -> set:
        used = set()
        for track, hyp in self.gnn.associate(tracks, detections, when).items():
            if hyp:
                track.append(self.updater.update(hyp))
                used.add(hyp.measurement)
            else:
                track.append(hyp.prediction)
        return used


class _OncePerDwell(Hypothesiser):
    """Answers each track once per dwell (:meth:`clear` between dwells): the JPDA's cluster test
    and its associator then share one set of hypotheses (their Kalman predictions and
    likelihoods are most of a JPDA dwell's cost) instead of computing them twice."""

    hypothesiser: Hypothesiser = Property(doc="The hypothesiser that does the work.")

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._memo = {}

    def clear(self) -> None:
        self._memo.clear()

    def hypothesise(self, track, detections, timestamp, **kwargs):
        if track not in self._memo:
            self._memo[track] = self.hypothesiser.hypothesise(track, detections, timestamp,
                                                              **kwargs)
        return self._memo[track]


class StoneSoupJPDA(_AssociatingTracker):
    """Joint probabilistic data association: Stone Soup's ``JPDAwithEHM`` (exact marginals), or
    ``JPDAwithLBP`` in dwells with a cluster wider than ``exact_cluster_max_tracks``."""

    def __init__(self, prob_detect: float = 0.6, clutter_density_per_km2: float = 0.01,
                 exact_cluster_max_tracks: int = 8, **kwargs):
        self.prob_detect = float(prob_detect)
        self.clutter_density_per_km2 = float(clutter_density_per_km2)
        self.exact_cluster_max_tracks = int(exact_cluster_max_tracks)
        super().__init__(**kwargs)
        self.hypotheses = _OncePerDwell(PDAHypothesiser(
            self.predictor, self.updater, clutter_spatial_density=self.clutter_density_per_km2
            / 1e6, prob_detect=self.prob_detect, prob_gate=self.gate_probability))
        self.jpda = JPDAwithEHM(self.hypotheses)
        self.jpda_lbp = JPDAwithLBP(self.hypotheses)

    def reset(self, scene: SceneInfo) -> None:
        super().reset(scene)
        self.n_dwells_exact = self.n_dwells_approx = 0

    def finish(self):
        if self.n_dwells_approx:
            logging.getLogger(__name__).info(
                "stonesoup_jpda: %d of %d dwells had a cluster of more than %d tracks sharing "
                "plots; their marginals came from loopy belief propagation",
                self.n_dwells_approx, self.n_dwells_approx + self.n_dwells_exact,
                self.exact_cluster_max_tracks)
        return None

    def _associator(self, tracks, detections, when):
        """Exact JPDA (EHM) unless a cluster of tracks sharing gated plots is wider than
        ``exact_cluster_max_tracks``: EHM's cost grows exponentially with such a cluster (a town
        of false tracks made one dwell take minutes), so those dwells use Stone Soup's
        ``JPDAwithLBP`` (loopy belief propagation, Williams & Lau 2014: approximate marginals,
        polynomial cost)."""
        self.hypotheses.clear()                     # a new dwell: its own hypotheses
        hyps = self.jpda.generate_hypotheses(tracks, detections, when)
        widest = max((len(c) for c in TrackClusterer(hyps).clustered_hypotheses), default=0)
        if widest <= self.exact_cluster_max_tracks:
            self.n_dwells_exact += 1
            return self.jpda
        self.n_dwells_approx += 1
        return self.jpda_lbp

    def _associate_and_update(self, tracks, detections, when) -> set:
        used = set()
        jpda = self._associator(tracks, detections, when)
        for track, multi in jpda.associate(tracks, detections, when).items():
            states, weights = [], []
            missed = None
            for hyp in multi:
                if not hyp:
                    states.append(hyp.prediction)
                    missed = hyp
                else:
                    states.append(self.updater.update(hyp))
                    used.add(hyp.measurement)
                weights.append(float(hyp.probability))
            means = StateVectors([s.state_vector for s in states])
            covars = np.stack([s.covar for s in states], axis=2)
            mean, covar = gm_reduce_single(means, covars, np.asarray(weights))
            # The deleter counts a state as an update when its hypothesis is truthy, and a
            # MultipleHypothesis always is (it holds the missed-detection one): a covered JPDA
            # track was never deleted, coasted on with a growing gate and pulled every plot
            # of the dwell into one cluster.  It counts as updated when the detections
            # together are more probable than the miss.
            p_missed = sum(w for w, h in zip(weights, multi) if not h)
            track.append(GaussianStateUpdate(
                mean, covar, multi if p_missed < 0.5 or missed is None else missed, when))
        return used


def _in_value_order(components) -> list:
    """The mixture's components by weight (highest first), then state and covariance.

    Stone Soup's ``GaussianMixtureReducer`` hands back the merged mixture in the iteration order
    of a set of tags: string hashes, salted per process, and new tags are uuid4.  That order
    fed the next dwell's sums (different last bits, then different tracks from one process to
    the next) and the order new tags are named in.  An order of the values alone repeats."""
    return sorted(components, key=lambda c: (-float(c.weight), *np.ravel(c.state_vector),
                                             *np.ravel(c.covar)))


class StoneSoupGMPHD(_StoneSoupTracker):
    """Gaussian-mixture PHD filter with tagged components (Stone Soup PHD components)."""

    def __init__(self, prob_detect: float = 0.6, prob_survival: float = 0.999,
                 clutter_density_per_km2: float = 0.01, birth_weight: float = 0.05,
                 extraction_threshold: float = 0.5, prune_threshold: float = 1e-6,
                 merge_threshold: float = 16.0, **kwargs):
        self.prob_detect = float(prob_detect)
        self.prob_survival = float(prob_survival)
        self.clutter_density_per_km2 = float(clutter_density_per_km2)
        self.birth_weight = float(birth_weight)
        self.extraction_threshold = float(extraction_threshold)
        super().__init__(**kwargs)
        self.hypothesiser = GaussianMixtureHypothesiser(DistanceHypothesiser(
            self.predictor, self.updater, measure=Mahalanobis(),
            missed_distance=float(np.sqrt(chi2.ppf(self.gate_probability, 2)))),
            order_by_detection=True)
        self.phd = PHDUpdater(self.updater, clutter_spatial_density=self.clutter_density_per_km2
                              / 1e6, prob_detection=self.prob_detect,
                              prob_survival=self.prob_survival)
        self.reducer = GaussianMixtureReducer(prune_threshold=prune_threshold,
                                              pruning=True, merge_threshold=merge_threshold,
                                              merging=True)
        self.reset(SceneInfo())

    def reset(self, scene: SceneInfo) -> None:
        super().reset(scene)
        self.components: list = []
        self._known: set = set()

    def _birth(self, dw, k: int, when) -> TaggedWeightedGaussianState:
        """A birth component spread over dwell ``k``'s footprint (uniform-equivalent σ)."""
        v = self.init_speed_sigma_mps ** 2
        if all(c in dw for c in ("area_x_m", "area_range_m", "range_half_extent_m",
                                 "beam_az_rad", "angle_half_extent_rad")):
            cx, cy = float(dw["area_x_m"][k]), float(dw["area_y_m"][k])
            along = float(dw["range_half_extent_m"][k]) / np.sqrt(3.0)
            cross = float(dw["area_range_m"][k]) * float(dw["angle_half_extent_rad"][k]) \
                / np.sqrt(3.0)
            az = float(dw["beam_az_rad"][k])
        else:
            cx = cy = 0.0
            along = cross = 20000.0
            az = 0.0
        u = np.array([np.sin(az), np.cos(az)])          # along the beam (east, north)
        w = np.array([np.cos(az), -np.sin(az)])
        C = along ** 2 * np.outer(u, u) + cross ** 2 * np.outer(w, w)
        P = np.diag([0.0, v, 0.0, v])
        P[np.ix_([0, 2], [0, 2])] = C
        return TaggedWeightedGaussianState(np.array([[cx], [0.0], [cy], [0.0]]), P,
                                           weight=self.birth_weight, tag="birth",
                                           timestamp=when)

    def _dwell(self, dw, k: int, det):
        t = float(dw["time_s"][k])
        when = _stamp(t)
        detections = self._detections(dw, k, det)          # a list, in det_id order
        mask = self._covered_mask(dw, k, self.components)
        inside = [c for c, m in zip(self.components, mask) if m]
        outside = [c for c, m in zip(self.components, mask) if not m]
        if not inside and not detections:
            return None
        hyps = self.hypothesiser.hypothesise(inside + [self._birth(dw, k, when)], detections,
                                             when)
        updated = self.phd.update(hyps).components
        updated = _in_value_order(self.reducer.reduce(updated))
        fresh: Dict[str, str] = {}      # Stone Soup's new tags are uuid4: name them in order
        for c in updated:
            if c.tag != c.BIRTH and c.tag not in self._known:
                if c.tag not in fresh:
                    fresh[c.tag] = f"t{len(self._known) + len(fresh)}"
                c.tag = fresh[c.tag]
        self._known |= set(fresh.values())
        self.components = outside + updated
        best: Dict[object, TaggedWeightedGaussianState] = {}
        for c in updated:
            if c.weight > self.extraction_threshold and (
                    c.tag not in best or c.weight > best[c.tag].weight):
                best[c.tag] = c
        tags = sorted(best, key=lambda g: int(g[1:]))
        return self._rows([self._id(g) for g in tags], t, [best[g] for g in tags])
