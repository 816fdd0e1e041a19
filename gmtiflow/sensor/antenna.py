"""Antenna frame and target angles in it (DESIGN §5 "Antenna frame").

Vectors are 3-tuples of equal-shape arrays ``(east, north, up)`` (structure of arrays: fast
column arithmetic over millions of pairs).

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

from gmtiflow.sensor import fastnp


def dot(a, b):
    """Dot product of two vectors given as 3-tuples of arrays."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def take(v, index):
    """Rows ``index`` (integers, or a boolean mask) of each component of a vector."""
    index = np.asarray(index)
    if index.dtype.kind in "iu" and index.ndim == 1 and all(np.ndim(c) == 1 for c in v):
        # np.take: the same rows as fancy indexing, ~25 % cheaper on long index arrays
        return (np.take(v[0], index), np.take(v[1], index), np.take(v[2], index))
    return (v[0][index], v[1][index], v[2][index])


def antenna_axes(heading_rad, pitch_rad, bank_rad, mount_rad):
    """Boresight ``b``, scan axis ``h`` and antenna up ``u`` (3-tuples of arrays, ENU)."""
    psi, theta, phi = np.broadcast_arrays(np.asarray(heading_rad, float),
                                          np.asarray(pitch_rad, float),
                                          np.asarray(bank_rad, float))
    sp, cp = np.sin(psi), np.cos(psi)
    st, ct = np.sin(theta), np.cos(theta)
    f = (sp * ct, cp * ct, st)
    r = (cp, -sp, np.zeros_like(sp))
    u = (r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0])
    sb, cb = np.sin(phi), np.cos(phi)
    r1 = tuple(cb * r[k] - sb * u[k] for k in range(3))
    u1 = tuple(sb * r[k] + cb * u[k] for k in range(3))
    sm, cm = np.sin(mount_rad), np.cos(mount_rad)
    b = tuple(cm * f[k] + sm * r1[k] for k in range(3))
    h = tuple(-sm * f[k] + cm * r1[k] for k in range(3))
    return b, h, u1


def target_angles(los, b, h, u):
    """Azimuth, elevation (rad) and sine-space azimuth of unit LOS vectors.

    Returns ``(az, el, sin_az, cos_boresight)`` where ``sin_az = sin(az)`` (the beam's sine-space
    coordinate) and ``cos_boresight = ℓ·b`` (> 0: in front of the antenna).
    """
    lb, lh, lu = dot(los, b), dot(los, h), dot(los, u)
    horiz = np.hypot(lb, lh)
    az = np.arctan2(lh, lb)
    el = np.arctan2(lu, horiz)
    sin_az = fastnp.ratio(lh, horiz)
    return az, el, sin_az, lb



def azimuth_rate(los, b, h):
    """dα/dA: the change of the antenna azimuth α = atan2(ℓ·h, ℓ·b) per unit change of the
    world azimuth A of the unit LOS ℓ (platform frame) turned about the local vertical at a
    fixed world elevation, dℓ/dA = (ℓ_n, −ℓ_e, 0):

        dα/dA = ((t·h)(ℓ·b) − (t·b)(ℓ·h)) / ((ℓ·b)² + (ℓ·h)²),   t = (ℓ_n, −ℓ_e, 0).

    Exactly 1 for a level antenna (b and h horizontal); with bank or pitch the antenna's
    azimuth plane is tilted and it differs from 1 (0.90–0.95 at 15° of bank and elevations of
    −10° to −30°).  The ground points at one slant range from the platform lie at one world
    elevation on the round earth, so an antenna-frame azimuth error e moves the geolocated
    point's world azimuth by e / (dα/dA) (to first order; over a DEM approximately)."""
    lb, lh = dot(los, b), dot(los, h)
    tb = los[1] * b[0] - los[0] * b[1]
    th = los[1] * h[0] - los[0] * h[1]
    return (th * lb - tb * lh) / (lb * lb + lh * lh)


def direction(az_rad, el_rad, b, h, u):
    """Unit ENU vector at antenna azimuth/elevation (inverse of :func:`target_angles`)."""
    ce = np.cos(el_rad)
    ca, sa, se = ce * np.cos(az_rad), ce * np.sin(az_rad), np.sin(el_rad)
    return tuple(ca * b[k] + sa * h[k] + se * u[k] for k in range(3))
