"""Map <-> geodetic conversions (gmtiflow.frames) against pymap3d."""
import numpy as np
import pymap3d
import pytest

from gmtiflow import frames


def _reference(origin, x, y, z):
    """enu_to_geodetic as it was written, entirely through pymap3d.enu2geodetic."""
    radius = frames.sphere_radius_m(origin)
    theta = np.hypot(x, y) / radius
    k = frames._sin_ratio(theta)
    drop = -2.0 * radius * np.sin(0.5 * theta) ** 2
    lat, lon, _ = pymap3d.enu2geodetic(x * k, y * k, drop, origin.lat_deg, origin.lon_deg,
                                       origin.height_m)
    return lat, lon


@pytest.mark.parametrize("origin", [frames.Origin(48.0, 11.0, 0.0),
                                    frames.Origin(-33.9, 151.2, 120.0),
                                    frames.Origin(0.0, -179.9, 0.0),
                                    frames.Origin(89.999, 0.0, 0.0)])
def test_enu_to_geodetic_is_pymap3d_bit_for_bit(origin):
    """The lat/lon fast path repeats pymap3d's arithmetic: the same bits, from metres to the
    horizon of a 20 km altitude, on both sides of the antimeridian and next to the pole (where
    pymap3d's special cases take over)."""
    g = np.random.default_rng(11)
    n = 20_000
    scale = np.concatenate([np.full(n // 2, 50_000.0), np.full(n - n // 2, 600_000.0)])
    x, y = g.uniform(-1, 1, n) * scale, g.uniform(-1, 1, n) * scale
    z = g.uniform(-400.0, 20_000.0, n)
    if origin.lat_deg > 89.0:       # one point exactly over the pole: the degenerate branch
        x[0], y[0] = 0.0, frames.sphere_radius_m(origin) * np.radians(90.0 - origin.lat_deg)
    lat, lon, h = frames.enu_to_geodetic(origin, x, y, z)
    want_lat, want_lon = _reference(origin, x, y, z)
    assert np.array_equal(lat, want_lat) and np.array_equal(lon, want_lon)
    assert np.array_equal(h, origin.height_m + z)
    lat1, lon1, _ = frames.enu_to_geodetic(origin, x[5], y[5], z[5])      # scalars too
    assert float(lat1) == want_lat[5] and float(lon1) == want_lon[5]


def test_ecef_to_lat_lon_is_pymap3ds_bit_for_bit():
    """frames._ecef_to_lat_lon_deg rewrites pymap3d.ecef2geodetic's arithmetic (in place, no
    altitude): the same latitudes and longitudes, bit for bit, everywhere on the earth and at
    aircraft heights, and through pymap3d itself at the poles."""
    import pymap3d

    from gmtiflow import frames
    g = np.random.default_rng(4)
    n = 5000
    lat, lon = g.uniform(-89.9, 89.9, n), g.uniform(-180.0, 180.0, n)
    h = g.uniform(-500.0, 20_000.0, n)
    x, y, z = pymap3d.geodetic2ecef(lat, lon, h)
    want_lat, want_lon, _ = pymap3d.ecef2geodetic(x, y, z)
    got_lat, got_lon = frames._ecef_to_lat_lon_deg(x, y, z)
    assert got_lat.tobytes() == np.asarray(want_lat, float).tobytes()
    assert got_lon.tobytes() == np.asarray(want_lon, float).tobytes()
    assert np.allclose(got_lat, lat, atol=1e-9) and np.allclose(got_lon, lon, atol=1e-9)
    # the inputs are not written to (the temporaries are the function's own)
    assert np.array_equal((x, y, z), pymap3d.geodetic2ecef(lat, lon, h))
    px, py, pz = (np.append(c, 0.0) for c in (x[:3], y[:3], z[:3]))     # one on the axis
    pz[-1] = 6_356_752.0
    p_lat, p_lon = frames._ecef_to_lat_lon_deg(px, py, pz)
    w_lat, w_lon, _ = pymap3d.ecef2geodetic(px, py, pz)
    assert np.array_equal(p_lat, w_lat) and np.array_equal(p_lon, w_lon)


def test_heading_and_wrap_are_np_mod_bit_for_bit():
    """heading_rad and wrap_pi take fastnp.mod's path: np.mod's values, signed zeros, the
    axes, ±π and non-finite inputs included, for arrays and scalars."""
    import numpy as np
    from gmtiflow import frames

    g = np.random.default_rng(4)
    e = np.concatenate([g.normal(size=5000), [0.0, -0.0, 0.0, -0.0, 1.0, -1.0, 0.0, np.nan, np.inf]])
    n = np.concatenate([g.normal(size=5000), [0.0, 0.0, -0.0, -0.0, 0.0, 0.0, -1.0, 1.0, 1.0]])
    want = np.mod(np.arctan2(e, n), 2.0 * np.pi)
    assert frames.heading_rad(e, n).tobytes() == want.tobytes()
    assert frames.heading_rad(-0.0, -1.0) == np.mod(np.arctan2(-0.0, -1.0), 2.0 * np.pi)
    a = np.concatenate([g.uniform(-20, 20, 5000), [np.pi, -np.pi, 0.0, -0.0, 3 * np.pi, np.nan]])
    assert frames.wrap_pi(a).tobytes() == (np.mod(a + np.pi, 2.0 * np.pi) - np.pi).tobytes()


def test_sin_ratio_is_the_masked_form_bit_for_bit():
    import numpy as np
    from gmtiflow import frames

    g = np.random.default_rng(2)
    theta = np.concatenate([g.uniform(-0.1, 0.1, 4000), g.uniform(-2e-4, 2e-4, 4000),
                            [0.0, -0.0, 1e-4, -1e-4, 1e-300, np.nan, 3.0]])
    small = np.abs(theta) < 1e-4
    with np.errstate(invalid="ignore"):
        safe = np.where(small, 1.0, theta)
        want = np.where(small, 1.0 - theta * theta / 6.0, np.sin(safe) / safe)
        got = frames._sin_ratio(theta)
    assert got.tobytes() == want.tobytes()
    assert frames._sin_ratio(theta[:50]).tobytes() == want[:50].tobytes()   # none small
