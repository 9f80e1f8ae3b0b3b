"""Tests of simbench.sim.geometry: exact light-time range, range rate, Sagnac model, el/az."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pymap3d
import pytest

from simbench.core.constants import C_LIGHT, DEG, OMEGA_EARTH
from simbench.core.orbits import BroadcastEphemeris, NominalConstellation
from simbench.errors import SimbenchError
from simbench.gnss.geometry import elevation_azimuth, sagnac_range
from simbench.gnss.navigation import read_gps_navigation
from simbench.sim.geometry import line_of_sight

T0 = 2032 * 604800 + 432000.0 + 12 * 3600.0  # 2018-12-21 12:00 GPS
SITE = np.array(pymap3d.geodetic2ecef(39.6, -79.96, 290.0))


@pytest.fixture(scope="module")
def brdc(shared_data: Path) -> Path:
    return shared_data / "wvu_drives" / "brdc.18n"


@pytest.fixture(scope="module", params=["broadcast", "nominal"])
def constellation(request):
    if request.param == "broadcast":
        return read_gps_navigation(request.getfixturevalue("brdc"))
    return NominalConstellation()


def _trajectory(n: int, dt: float, speed: float = 250.0):
    """A receiver flying east at `speed` m/s (aircraft-like, to exercise rx velocity)."""
    t = T0 + dt * np.arange(n)
    lat, lon = 39.6 * DEG, -79.96 * DEG
    east = np.array([-math.sin(lon), math.cos(lon), 0.0])
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    vel = np.tile(speed * east + 3.0 * up, (n, 1))
    pos = SITE + (t - T0)[:, None] * vel
    return t, pos, vel


def _brute_force_range(c, t_rx: float, rx: np.ndarray, j: int):
    """One receiver, one satellite: plain light-time loop with an explicit rotation matrix."""
    tau = 0.0
    for _ in range(20):
        s = c.states(np.array([t_rx]), -tau).pos[0, j]
        th = OMEGA_EARTH * tau
        rot = np.array([[math.cos(th), math.sin(th), 0.0], [-math.sin(th), math.cos(th), 0.0], [0.0, 0.0, 1.0]])
        rho = float(np.linalg.norm(rot @ s - rx))
        tau = rho / C_LIGHT
    return rho, s, tau


def test_range_matches_brute_force(constellation):
    c = constellation
    t, pos, vel = _trajectory(5, 600.0)
    los = line_of_sight(pos, vel, t, c)
    rng = np.random.default_rng(3)
    checked = 0
    for i in range(t.size):
        for j in rng.choice(np.flatnonzero(los.valid[i]), 4, replace=False):
            rho, s_tx, tau = _brute_force_range(c, t[i], pos[i], j)
            assert abs(los.range_m[i, j] - rho) < 1e-6
            assert np.abs(los.sat_pos_tx[i, j] - s_tx).max() < 1e-6
            assert abs(los.tau_s[i, j] - tau) < 1e-15
            assert abs(los.t_tx[i, j] - (t[i] - tau)) < 5e-7  # float64 resolution of t_tx
            checked += 1
    assert checked == 20


def test_transmit_state_equals_direct_evaluation(constellation):
    # line_of_sight carries the state from t_rx - 75 ms to t_tx by a Taylor
    # step; it must reproduce a direct ephemeris evaluation at t_tx.
    c = constellation
    t, pos, vel = _trajectory(300, 12.0)
    los = line_of_sight(pos, vel, t, c)
    st = c.states(t, -los.tau_s)
    ok = los.valid
    np.testing.assert_array_equal(ok, st.valid)
    assert np.abs(los.sat_pos_tx - st.pos)[ok].max() < 1e-6  # measured ~2e-7 m (float64 noise)
    assert np.abs(los.sat_vel_tx - st.vel)[ok].max() < 1e-5  # J2 left out of the step: ~2e-6 m/s
    assert np.abs(los.sat_clock_tx - st.clock)[ok].max() < 1e-17
    # Drift is carried unchanged over the <= 25 ms step: its rate (~1e-15 s/s^2) is negligible.
    assert np.abs(los.sat_clock_drift - st.clock_drift)[ok].max() < 1e-16
    # Light-time equation satisfied: tau * c == range.
    assert np.abs(los.tau_s * C_LIGHT - los.range_m)[ok].max() < 1e-6


def test_range_rate_matches_finite_difference(constellation):
    c = constellation
    t, pos, vel = _trajectory(200, 17.0)
    h = 0.5
    los = line_of_sight(pos, vel, t, c)
    lp = line_of_sight(pos + h * vel, vel, t + h, c)
    lm = line_of_sight(pos - h * vel, vel, t - h, c)
    fd = (lp.range_m - lm.range_m) / (2 * h)
    ok = los.valid & lp.valid & lm.valid
    if isinstance(c, BroadcastEphemeris):
        # A switch to the next ephemeris record between t-h and t+h is a real jump.
        ok &= c.select_records(t + h) == c.select_records(t - h)
    err = np.abs(fd - los.range_rate_mps)[ok]
    assert err.max() < 1e-4  # measured ~2e-6 m/s
    # The test is sensitive to the 1/c terms: u.(v_sat - v_rx) alone is off by ~1 cm/s.
    naive = np.einsum("nmk,nmk->nm", los.los_unit, los.sat_vel_tx) - np.einsum("nmk,nk->nm", los.los_unit, vel)
    assert np.abs(fd - naive)[ok].max() > 3e-3
    assert np.abs(los.range_rate_mps[ok]).max() < 1200.0


def test_sagnac_model_agrees_with_exact_range(constellation):
    c = constellation
    t, pos, vel = _trajectory(400, 100.0, speed=0.0)
    los = line_of_sight(pos, None, t, c)
    ok = los.valid
    approx = sagnac_range(los.sat_pos_tx, pos[:, None, :])
    geo = np.linalg.norm(los.sat_pos_tx - pos[:, None, :], axis=-1)
    diff = np.abs(approx - los.range_m)[ok]
    # Earth rotation during transit matters (up to ~40 m) ...
    assert np.abs(geo - los.range_m)[ok].max() > 20.0
    # ... and the first-order model leaves only second-order terms: with
    # theta = omega_e tau <= 6.3e-6 rad, |theta^2 s / 2| <= 0.5 mm bounds them.
    # Measured max 0.12 mm (all satellites, including below the horizon).
    assert diff.max() < 0.5e-3


def test_elevation_azimuth_against_pymap3d():
    rng = np.random.default_rng(7)
    n, m = 50, 8
    lat = rng.uniform(-85, 85, n)
    lon = rng.uniform(-180, 180, n)
    h = rng.uniform(-100, 9000, n)
    rx = np.stack(pymap3d.geodetic2ecef(lat, lon, h), axis=-1)
    sat = rng.normal(size=(n, m, 3))
    sat *= 26.6e6 / np.linalg.norm(sat, axis=-1, keepdims=True)
    el, az = elevation_azimuth(rx, sat)
    az_ref, el_ref, _ = pymap3d.ecef2aer(sat[..., 0], sat[..., 1], sat[..., 2], lat[:, None], lon[:, None], h[:, None])
    np.testing.assert_allclose(el, np.radians(el_ref), atol=1e-9)
    daz = np.angle(np.exp(1j * (az - np.radians(az_ref))))
    assert np.abs(daz).max() < 1e-9
    assert az.min() >= 0.0 and az.max() < 2 * math.pi


def test_los_elevation_consistent_and_known_sky(constellation):
    c = constellation
    t, pos, vel = _trajectory(20, 30.0, speed=0.0)
    los = line_of_sight(pos, None, t, c)
    # Same el/az as elevation_azimuth on the satellite rotated into ECEF(t_rx).
    th = OMEGA_EARTH * los.tau_s
    s = los.sat_pos_tx
    q = np.stack(
        [np.cos(th) * s[..., 0] + np.sin(th) * s[..., 1], -np.sin(th) * s[..., 0] + np.cos(th) * s[..., 1], s[..., 2]],
        axis=-1,
    )
    el, az = elevation_azimuth(pos, q)
    ok = los.valid
    np.testing.assert_allclose(los.el_rad[ok], el[ok], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(los.los_unit[ok], axis=-1), 1.0, atol=1e-14)
    n_vis = (los.el_rad > 7 * DEG).sum(axis=1)
    assert n_vis.min() >= 5  # mid-latitude, 24-31 satellites
    up = los.range_m[los.el_rad > 0]
    # Zenith ~ a(1-e) - R_E, horizon ~ sqrt(r^2 - R_E^2) for r = a(1 +- e), e < 0.03.
    assert np.all((up > 19.0e6) & (up < 26.6e6))


def test_line_of_sight_bad_inputs():
    c = NominalConstellation()
    t = T0 + np.arange(3.0)
    with pytest.raises(SimbenchError, match="rx_pos") as exc:
        line_of_sight(np.zeros((2, 3)), None, t, c)
    assert "\n" not in str(exc.value)
    with pytest.raises(SimbenchError, match="rx_pos"):
        line_of_sight(np.zeros((3, 2)), None, t, c)
    with pytest.raises(SimbenchError, match="rx_vel"):
        line_of_sight(np.tile(SITE, (3, 1)), np.full((3, 3), np.nan), t, c)
    with pytest.raises(SimbenchError, match="t_rx_gps"):
        line_of_sight(SITE, None, np.array([]), c)


def test_line_of_sight_outside_ephemeris_coverage(brdc: Path):
    eph = read_gps_navigation(brdc)
    with pytest.raises(SimbenchError, match=r"^t_gps: .*brdc\.18n covers 2018-12-20 22:00:00"):
        line_of_sight(SITE, None, np.array([T0, T0 + 5 * 86400.0]), eph)
