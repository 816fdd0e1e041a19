"""Antenna frame and target angles in it (DESIGN §5 "Antenna frame").

Body frame, in world ENU, from the platform's heading ψ (clockwise from north), flight-path
pitch θ (+ nose up) and bank φ (+ right wing down, STANAG 4607 D23):

* forward  f = (sin ψ cos θ, cos ψ cos θ, sin θ)
* right    r = (cos ψ, −sin ψ, 0)                     (level, before the roll)
* up       u = r × f

Roll by φ about ``f`` (right wing down tilts ``r`` below the horizon and ``u`` towards the right):
``r' = cos φ r − sin φ u``, ``u' = sin φ r + cos φ u``.  Then turn by the mounting angle φ_d
(``mount_deg``, clockwise seen from above, in the rolled f–r' plane):

* boresight  b = cos φ_d f + sin φ_d r'    (φ_d = 90°: right side-looking)
* scan axis  h = −sin φ_d f + cos φ_d r'   (+ scan angles turn clockwise seen from above)
* antenna up u'

For a unit line of sight ℓ the target's **azimuth** (scan angle off boresight) is
``atan2(ℓ·h, ℓ·b)`` and its **elevation** ``atan2(ℓ·u', |(ℓ·b, ℓ·h)|)`` (+ up).  Banking towards
the antenna side raises a target's elevation in this frame by the bank angle (the beam points
further down), so fixed elevation limits move the covered ground strip towards the platform.
"""
from __future__ import annotations

import numpy as np


def antenna_axes(heading_rad, pitch_rad, bank_rad, mount_rad):
    """Boresight ``b``, scan axis ``h`` and antenna up ``u`` as (..., 3) ENU unit vectors."""
    psi = np.asarray(heading_rad, float)
    theta = np.asarray(pitch_rad, float)
    phi = np.asarray(bank_rad, float)
    sp, cp = np.sin(psi), np.cos(psi)
    st, ct = np.sin(theta), np.cos(theta)
    f = np.stack([sp * ct, cp * ct, st], axis=-1)
    r = np.stack([cp, -sp, np.zeros_like(sp)], axis=-1)
    u = np.cross(r, f)
    sb, cb = np.sin(phi)[..., None], np.cos(phi)[..., None]
    r1 = cb * r - sb * u
    u1 = sb * r + cb * u
    sm, cm = np.sin(mount_rad), np.cos(mount_rad)
    b = cm * f + sm * r1
    h = -sm * f + cm * r1
    return b, h, u1


def target_angles(los, b, h, u):
    """Azimuth, elevation (rad) and sine-space azimuth of unit LOS vectors (..., 3).

    Returns ``(az, el, sin_az, cos_boresight)`` where ``sin_az = sin(az)`` (the beam's sine-space
    coordinate) and ``cos_boresight = ℓ·b`` (> 0: in front of the antenna).
    """
    lb = np.einsum("...k,...k->...", los, b)
    lh = np.einsum("...k,...k->...", los, h)
    lu = np.einsum("...k,...k->...", los, u)
    horiz = np.hypot(lb, lh)
    az = np.arctan2(lh, lb)
    el = np.arctan2(lu, horiz)
    sin_az = np.divide(lh, horiz, out=np.zeros_like(lh), where=horiz > 0)
    return az, el, sin_az, lb


def direction(az_rad, el_rad, b, h, u):
    """Unit ENU vector at antenna azimuth/elevation (inverse of :func:`target_angles`)."""
    az = np.asarray(az_rad, float)[..., None]
    el = np.asarray(el_rad, float)[..., None]
    return np.cos(el) * (np.cos(az) * b + np.sin(az) * h) + np.sin(el) * u
