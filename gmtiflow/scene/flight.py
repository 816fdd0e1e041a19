"""Flight mechanics shared by the platform kinds (paper §4; docs/platform.md).

Conventions (docs/tables.md, ``/platform``): scene ENU metres; heading clockwise from north
in [0, 2π); pitch + nose up; bank + right wing down (a right turn), as STANAG 4607 D23.
Nothing here knows a config: the kinds (:mod:`gmtiflow.scene.fixed_wing`,
:mod:`~gmtiflow.scene.rotorcraft`, :mod:`~gmtiflow.scene.trajectory`) call these helpers.
"""
from __future__ import annotations

import numpy as np

from gmtiflow import frames
from gmtiflow.tables import Table

G_MPS2 = 9.80665
"""Standard gravity (m/s²) used for the coordinated-turn bank angle."""


def signed_turn_rad(h_in, h_out) -> np.ndarray:
    """Heading change from h_in to h_out in (-π, π], + = clockwise (right turn)."""
    d = frames.wrap_pi(np.asarray(h_out) - np.asarray(h_in))
    return np.where(d == -np.pi, np.pi, d)


def bank_angle_rad(speed_mps, turn_angle_rad, turn_lead_s):
    """Coordinated-turn bank φ = arctan(v tan(α/2) / (t g)) (paper eq. 5, corrected), ≥ 0."""
    return np.arctan2(np.asarray(speed_mps) * np.tan(np.abs(turn_angle_rad) / 2.0),
                      np.asarray(turn_lead_s) * G_MPS2)


def corner_turns_rad(xy_m) -> np.ndarray:
    """Signed heading change at each waypoint of a closed loop (leg i-1 -> leg i, + right)."""
    xy = np.asarray(xy_m, float)
    delta = np.roll(xy, -1, axis=0) - xy
    head = frames.heading_rad(delta[:, 0], delta[:, 1])
    return signed_turn_rad(np.roll(head, 1), head)


def coordinated_bank_rad(vx_mps, vy_mps, ax_mps2, ay_mps2) -> np.ndarray:
    """Bank of a coordinated turn from horizontal velocity and acceleration (paper eq. 3).

    φ = arctan(v ψ̇ / g) with the turn rate ψ̇ = (v_y a_x − v_x a_y) / v² (heading clockwise
    from north), i.e. eq. 3's v² / (r g) with r = v / ψ̇.  Zero where the horizontal speed is 0.
    """
    v2 = np.asarray(vx_mps) ** 2 + np.asarray(vy_mps) ** 2
    v = np.sqrt(v2)
    cross = np.asarray(vy_mps) * ax_mps2 - np.asarray(vx_mps) * ay_mps2    # = v² ψ̇
    return np.arctan2(np.where(v > 0, cross / np.where(v > 0, v, 1.0), 0.0), G_MPS2)


def state_table(origin: frames.Origin, time_s, x_m, y_m, z_m, vx_mps, vy_mps, vz_mps,
                heading_rad, pitch_rad, bank_rad) -> Table:
    """The ``/platform`` columns (docs/tables.md), with WGS-84 lat/lon/height from ENU."""
    lat, lon, h = frames.enu_to_geodetic(origin, x_m, y_m, z_m)
    return {
        "time_s": time_s, "x_m": x_m, "y_m": y_m, "z_m": z_m,
        "vx_mps": vx_mps, "vy_mps": vy_mps, "vz_mps": vz_mps,
        "heading_rad": heading_rad, "pitch_rad": pitch_rad, "bank_rad": bank_rad,
        "lat_deg": lat, "lon_deg": lon, "height_m": h,
    }


def cosine_blend(u):
    """Altitude fraction and its derivative for the vertical profile: (1 − cos πu)/2.

    Between two altitude knots the altitude follows z0 + (z1 − z0)·b(u), u ∈ [0, 1] the fraction
    of path length between the knots.  b'(0) = b'(1) = 0, so the vertical speed is 0 at every
    knot and continuous everywhere (no jump where the altitude starts or stops changing); its
    peak is π/2 times the mean climb rate.
    """
    u = np.asarray(u, float)
    return (1.0 - np.cos(np.pi * u)) / 2.0, np.pi / 2.0 * np.sin(np.pi * u)
