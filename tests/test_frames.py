"""Frame conversions against pymap3d and against each other."""

from __future__ import annotations

import numpy as np
import pymap3d

from simbench.core.frames import dcm_body_to_ned, ecef_from_geodetic, euler_from_dcm, geodetic_from_ecef


def test_geodetic_round_trip_against_pymap3d() -> None:
    lat = np.radians([0.0, 39.6, -45.0, 89.999, -90.0])
    lon = np.radians([0.0, -79.96, 170.0, 10.0, 0.0])
    h = np.array([0.0, 290.0, -50.0, 12000.0, 3.0])
    xyz = np.stack(pymap3d.geodetic2ecef(lat, lon, h, deg=False), axis=-1)
    np.testing.assert_allclose(ecef_from_geodetic(lat, lon, h), xyz, atol=1e-6)
    la, lo, hh = geodetic_from_ecef(xyz)
    np.testing.assert_allclose(la, lat, atol=1e-12)
    np.testing.assert_allclose(hh, h, atol=1e-6)
    np.testing.assert_allclose(lo[:4], lon[:4], atol=1e-12)
    # GNSS orbit altitude too (the geometry module converts satellite positions)
    sat = ecef_from_geodetic(np.radians(20.0), np.radians(-100.0), 20_200e3)
    la, lo, hh = geodetic_from_ecef(sat)
    assert abs(hh - 20_200e3) < 1e-6 and abs(np.degrees(la) - 20.0) < 1e-12


def test_euler_round_trip() -> None:
    att = np.array([[0.1, -0.2, 2.5], [-0.4, 0.3, -1.0]])
    np.testing.assert_allclose(euler_from_dcm(dcm_body_to_ned(att)), att, atol=1e-12)
    c = dcm_body_to_ned(att)
    np.testing.assert_allclose(c @ np.swapaxes(c, -1, -2), np.broadcast_to(np.eye(3), c.shape), atol=1e-12)
