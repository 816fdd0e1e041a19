r"""Range and Doppler ambiguities of a pulsed radar (paper §5.5, DESIGN §5.8).

A radar with pulse repetition frequency PRF (interval PRI = 1/PRF) cannot tell an echo of the last
pulse from a late echo of an earlier one, and samples the Doppler phase once per pulse:

* **Range folding.** Unambiguous range :math:`R_u = c \cdot PRI / 2`. A target at true slant range
  *R* is reported at :math:`R \bmod R_u`, fold count :math:`\lfloor R / R_u \rfloor`
  (:func:`fold_range`). A range exactly at :math:`k R_u` is reported at 0 with fold count *k*.
* **Doppler wrapping.** Range rate is measured modulo :math:`\lambda \cdot PRF / 2` and reported in
  the half-open interval :math:`[-v_w, +v_w)` with the *wrap velocity*
  :math:`v_w = \lambda \cdot PRF / 4` (STANAG 4607 D32.8, "half the velocity-aliasing period").
  Edge convention: :math:`+v_w` is reported as :math:`-v_w`; :math:`-v_w` stays. The wrap count
  *k* satisfies reported = true − 2 k v_w (:func:`wrap_range_rate`).
* **Blind speeds.** A target whose radial speed relative to the clutter is a multiple of
  :math:`\lambda \cdot PRF / 2 = 2 v_w` aliases onto the clutter ridge and falls into the STAP/MTI
  notch (:func:`blind_speeds_mps`, :func:`distance_to_blind_speed`).
* **Plausibility.** A processor geolocates a folded report taking the folded range at face value.
  If that slant range is shorter than the platform's height above the ground the range sphere does
  not reach the ground ("below the surface"); if it is longer than the distance to the radar
  horizon, the ground point would be hidden behind the curvature of the earth. Either way the
  report is implausible (:func:`implausible_range`, :func:`ground_range_from_slant`). Short
  folded ranges are the common case: with PRF = 3 kHz, :math:`R_u` ≈ 50 km and a target at
  55 km shows at 5 km — below a platform flying at 8 km.

All functions are vectorised; ``prf_hz`` may be a scalar or one value per report.
"""
from __future__ import annotations

import numpy as np

C_MPS = 299_792_458.0          # speed of light in vacuum (exact, SI)
EARTH_RADIUS_M = 6_371_008.8   # mean Earth radius (IUGG)
K_FACTOR = 4.0 / 3.0           # standard-atmosphere effective-earth-radius factor for radar


def unambiguous_range_m(prf_hz):
    """:math:`R_u = c \\cdot PRI / 2 = c / (2 \\, PRF)`, metres."""
    return C_MPS / (2.0 * np.asarray(prf_hz, dtype=float))


def fold_range(range_m, prf_hz):
    """Folded (reported) range and fold count.

    Returns ``(folded_m, folds)``: ``folded_m = range mod R_u`` in [0, R_u), ``folds`` int64 ≥ 0
    (for non-negative ranges), ``range = folded + folds · R_u``.
    """
    r = np.asarray(range_m, dtype=float)
    ru = unambiguous_range_m(prf_hz)
    inside = (r >= 0) & (r < ru)
    if r.ndim and np.ndim(ru) == 0 and inside.all():  # nothing folds: what the steps give
        return r.copy(), np.zeros(r.shape, np.int64)
    folds = np.where(inside, 0.0, np.floor(r / ru))   # inside: untouched, bit for bit
    folded = np.where(inside, r, r - folds * ru)
    # Rounding can leave folded at -tiny or at R_u; push it into [0, R_u).
    over = folded >= ru
    under = folded < 0
    folds = folds + over - under
    folded = np.where(over, folded - ru, np.where(under, folded + ru, folded))
    return folded, folds.astype(np.int64)


def wrap_velocity_mps(wavelength_m, prf_hz):
    """Wrap velocity :math:`v_w = \\lambda \\cdot PRF / 4` (STANAG 4607 D32.8), m/s."""
    return np.asarray(wavelength_m, dtype=float) * np.asarray(prf_hz, dtype=float) / 4.0


def wrap_range_rate(range_rate_mps, wavelength_m, prf_hz):
    """Range rate wrapped into [−v_w, +v_w) and the wrap count.

    Returns ``(wrapped_mps, wraps)`` with ``wrapped = range_rate − 2 · wraps · v_w``;
    ``+v_w ↦ −v_w`` (wraps = 1) and ``−v_w ↦ −v_w`` (wraps = 0). Values already inside the
    interval are returned unchanged bit for bit; wrapped values carry the rounding of one
    subtraction and are then forced into the half-open interval.
    """
    rr = np.asarray(range_rate_mps, dtype=float)
    vw = wrap_velocity_mps(wavelength_m, prf_hz)
    period = 2.0 * vw
    inside = (rr >= -vw) & (rr < vw)
    if rr.ndim and np.ndim(vw) == 0 and inside.all():  # nothing wraps: what the steps give
        return rr.copy(), np.zeros(rr.shape, np.int64)
    wraps = np.where(inside, 0.0, np.floor((rr + vw) / period))  # inside: untouched, bit for bit
    wrapped = np.where(inside, rr, rr - wraps * period)
    over = wrapped >= vw
    under = wrapped < -vw
    wraps = wraps + over - under
    wrapped = np.where(over, wrapped - period, np.where(under, wrapped + period, wrapped))
    return wrapped, wraps.astype(np.int64)


def blind_speeds_mps(wavelength_m, prf_hz, n_max: int):
    """Blind speeds :math:`n \\lambda \\cdot PRF / 2` for n = 0 … n_max (m/s, radial, relative to clutter)."""
    return np.arange(n_max + 1) * (float(wavelength_m) * float(prf_hz) / 2.0)


def distance_to_blind_speed(own_range_rate_mps, wavelength_m, prf_hz):
    """|ṙ_own − nearest blind speed|, m/s: the target's radial speed relative to the clutter,
    measured from the nearest notch replica. Compare with the MDV to decide Doppler blindness
    under ambiguity (DESIGN §5.3: the notch repeats every λ·PRF/2)."""
    wrapped, _ = wrap_range_rate(own_range_rate_mps, wavelength_m, prf_hz)
    return np.abs(wrapped)


def radar_horizon_m(height_m, k_factor: float = K_FACTOR, earth_radius_m: float = EARTH_RADIUS_M):
    """Slant distance from a radar at ``height_m`` above a smooth earth to its horizon point.

    :math:`\\sqrt{(R' + h)^2 - R'^2}` with the effective radius :math:`R' = k R_E` (k = 4/3
    models standard refraction). NaN for negative heights.
    """
    h = np.asarray(height_m, dtype=float)
    re = k_factor * earth_radius_m
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.where(h >= 0, h * (2.0 * re + h), np.nan))


def implausible_range(slant_range_m, height_agl_m, k_factor: float = K_FACTOR,
                      earth_radius_m: float = EARTH_RADIUS_M):
    """Flags of a (folded) slant range a processor takes at face value.

    Returns ``(below_surface, beyond_horizon)``: the range is shorter than the platform's height
    above the ground under it (the range sphere misses the ground), or longer than the radar
    horizon (:func:`radar_horizon_m`). ``implausible = below_surface | beyond_horizon``.
    """
    s = np.asarray(slant_range_m, dtype=float)
    h = np.asarray(height_agl_m, dtype=float)
    below = s < h
    beyond = s > radar_horizon_m(h, k_factor, earth_radius_m)
    return below, beyond


def ground_range_from_slant(slant_range_m, height_agl_m, k_factor: float = K_FACTOR,
                            earth_radius_m: float = EARTH_RADIUS_M):
    """Ground (arc) distance from the nadir to where a slant range meets a smooth effective earth.

    Law of cosines on the sphere of radius R' = k R_E: the central angle γ satisfies
    cos γ = ((R'+h)² + R'² − s²) / (2 R' (R'+h)); ground range = R' γ. NaN where the slant range
    is below the surface (s < h) or beyond the horizon — the geolocation a processor would attempt
    with a folded range fails there, which is what :func:`implausible_range` flags.
    """
    s = np.asarray(slant_range_m, dtype=float)
    h = np.asarray(height_agl_m, dtype=float)
    re = k_factor * earth_radius_m
    below, beyond = implausible_range(s, h, k_factor, earth_radius_m)
    cos_g = ((re + h) ** 2 + re ** 2 - s ** 2) / (2.0 * re * (re + h))
    gamma = np.arccos(np.clip(cos_g, -1.0, 1.0))
    return np.where(below | beyond, np.nan, re * gamma)


def apply_ambiguities(range_m, range_rate_mps, wavelength_m, prf_hz, height_agl_m=None):
    """Everything at once for a batch of reports: the columns the detection table needs.

    Returns a dict with ``range_m`` (folded), ``range_folds``, ``range_folded`` (bool),
    ``range_rate_mps`` (wrapped), ``doppler_wraps``, ``doppler_wrapped`` (bool),
    ``wrap_velocity_mps``, and — when ``height_agl_m`` is given — ``below_surface``,
    ``beyond_horizon`` and ``implausible`` (bool; only folded reports can be implausible: an
    unfolded target the sensor saw is in its field of view by construction).
    """
    folded, folds = fold_range(range_m, prf_hz)
    wrapped, wraps = wrap_range_rate(range_rate_mps, wavelength_m, prf_hz)
    out = {
        "range_m": folded, "range_folds": folds, "range_folded": folds != 0,
        "range_rate_mps": wrapped, "doppler_wraps": wraps, "doppler_wrapped": wraps != 0,
        "wrap_velocity_mps": np.broadcast_to(wrap_velocity_mps(wavelength_m, prf_hz), folded.shape).copy(),
    }
    if height_agl_m is not None:
        below, beyond = implausible_range(folded, height_agl_m)
        below = below & out["range_folded"]
        beyond = beyond & out["range_folded"]
        out.update(below_surface=below, beyond_horizon=beyond, implausible=below | beyond)
    return out
