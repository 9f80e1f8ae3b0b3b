"""Checks of the Klobuchar, Saastamoinen and Niell models against independent numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simbench.core.atmosphere import (
    klobuchar_l1_delay_m,
    mops_zenith_wet_m,
    niell_mapping,
    saastamoinen_zenith_m,
    standard_atmosphere,
    tropo_slant_m,
)
from simbench.core.constants import C_LIGHT
from simbench.errors import SimbenchError

# Klobuchar coefficients of wvu_drives/brdc.18n (ConstellationConfig defaults).
ALPHA = (8.382e-09, -1.490e-08, -5.960e-08, 1.192e-07)
BETA = (9.421e04, -1.311e05, -1.311e05, 8.520e05)
# Morgantown, WV (ScenarioConfig origin).
LAT_DEG, LON_DEG = 39.6295, -79.9559
SOW_NOON = 475_200.0  # 2018-12-21 12:00 GPST


def klobuchar_scalar(sow, lat_deg, lon_deg, el_deg, az_deg, alpha, beta):
    """IS-GPS-200 20.3.3.5.2.5, one ray, step by step in semicircles (independent of the module)."""
    e = el_deg / 180.0
    phi_u = lat_deg / 180.0
    lam_u = lon_deg / 180.0
    a_rad = math.radians(az_deg)
    psi = 0.0137 / (e + 0.11) - 0.022
    phi_i = phi_u + psi * math.cos(a_rad)
    if phi_i > 0.416:
        phi_i = 0.416
    elif phi_i < -0.416:
        phi_i = -0.416
    lam_i = lam_u + psi * math.sin(a_rad) / math.cos(phi_i * math.pi)
    phi_m = phi_i + 0.064 * math.cos((lam_i - 1.617) * math.pi)
    t = 4.32e4 * lam_i + sow
    t = t % 86400.0
    amp = sum(alpha[n] * phi_m**n for n in range(4))
    if amp < 0.0:
        amp = 0.0
    per = sum(beta[n] * phi_m**n for n in range(4))
    if per < 72000.0:
        per = 72000.0
    x = 2.0 * math.pi * (t - 50400.0) / per
    f = 1.0 + 16.0 * (0.53 - e) ** 3
    if abs(x) < 1.57:
        t_iono = f * (5.0e-9 + amp * (1.0 - x**2 / 2.0 + x**4 / 24.0))
    else:
        t_iono = f * 5.0e-9
    return C_LIGHT * t_iono


def obliquity(el_deg):
    return 1.0 + 16.0 * (0.53 - el_deg / 180.0) ** 3


# --------------------------------------------------------------------------- Klobuchar


def test_klobuchar_worked_example():
    # Morgantown, el 30 deg, az 135 deg, 18:00 GPST. By hand (semicircles):
    # psi = 0.0137/(0.16667+0.11) - 0.022 = 0.027518; phi_i = 0.220164 - 0.019458
    # = 0.200706; lam_i = -0.444199 + 0.019458/cos(36.13 deg) = -0.420109;
    # phi_m = 0.264271; t = 46651.3 s (12:57 local); AMP = 2.4820e-9 s;
    # PER = 72000 s (clamped); x = -0.32714; F = 1.76742;
    # T = F (5e-9 + AMP (1 - x^2/2 + x^4/24)) = 12.991 ns -> 3.8947 m.
    got = klobuchar_l1_delay_m(
        SOW_NOON + 6 * 3600.0,
        math.radians(LAT_DEG),
        math.radians(LON_DEG),
        math.radians(30.0),
        math.radians(135.0),
        ALPHA,
        BETA,
    )
    assert got == pytest.approx(3.8947, abs=5e-4)
    assert got == pytest.approx(
        klobuchar_scalar(SOW_NOON + 6 * 3600.0, LAT_DEG, LON_DEG, 30.0, 135.0, ALPHA, BETA), rel=1e-12
    )


def test_klobuchar_matches_scalar_reference_with_broadcasting():
    rng = np.random.default_rng(1)
    n, m = 40, 9
    sow = rng.uniform(0.0, 604_800.0, (n, 1))
    lat = rng.uniform(-89.0, 89.0, (n, 1))  # includes pierce points clamped at +-0.416 sc
    lon = rng.uniform(-180.0, 180.0, (n, 1))
    el = rng.uniform(0.0, 90.0, (n, m))
    az = rng.uniform(0.0, 360.0, (n, m))
    # Southern-hemisphere-like coefficients make AMP < 0 and PER > 72000 somewhere too.
    for alpha, beta in ((ALPHA, BETA), ((2.0e-8, 3.0e-8, -1.2e-7, 0.0), (1.4e5, 1.0e5, -6.0e5, 2.0e5))):
        got = klobuchar_l1_delay_m(sow, np.radians(lat), np.radians(lon), np.radians(el), np.radians(az), alpha, beta)
        assert got.shape == (n, m)
        want = np.array(
            [
                [klobuchar_scalar(sow[i, 0], lat[i, 0], lon[i, 0], el[i, j], az[i, j], alpha, beta) for j in range(m)]
                for i in range(n)
            ]
        )
        np.testing.assert_allclose(got, want, rtol=1e-9)


def test_klobuchar_night_is_5ns_times_obliquity():
    el = np.array([5.0, 10.0, 20.0, 45.0, 70.0, 90.0])
    # 02:00 local: |t - 50400| ~ 43200 s > 1.57/(2 pi) * PER for PER = 72000 s.
    sow = SOW_NOON + (2.0 - LON_DEG / 15.0 - 12.0) * 3600.0
    got = klobuchar_l1_delay_m(
        sow, math.radians(LAT_DEG), math.radians(LON_DEG), np.radians(el), math.radians(60.0), ALPHA, BETA
    )
    np.testing.assert_allclose(got, C_LIGHT * 5e-9 * obliquity(el), rtol=1e-12)
    # the slant factor F at 5 deg is about 3.0 (1.5 m night floor * 3)
    assert got[0] / got[-1] == pytest.approx(obliquity(5.0) / obliquity(90.0), rel=1e-12)
    assert 2.9 < obliquity(5.0) < 3.1


def test_klobuchar_zenith_afternoon_and_elevation_growth():
    lam_sc = LON_DEG / 180.0
    # 14:00 local time at the receiver longitude (t = 4.32e4 lam + sow = 50400 mod 86400).
    sow = SOW_NOON - SOW_NOON % 86_400.0 + (50_400.0 - 4.32e4 * lam_sc) % 86_400.0
    zenith = float(
        klobuchar_l1_delay_m(sow, math.radians(LAT_DEG), math.radians(LON_DEG), math.pi / 2, 0.0, ALPHA, BETA)
    )
    assert 1.0 < zenith < 15.0
    assert zenith == pytest.approx(2.125, abs=0.005)  # 7.09 ns: 5 ns floor + AMP 2.09 ns
    assert zenith > C_LIGHT * 5e-9  # above the night floor in daytime

    el = np.radians([5.0, 10.0, 20.0, 40.0, 60.0, 90.0])
    day = klobuchar_l1_delay_m(sow, math.radians(LAT_DEG), math.radians(LON_DEG), el, math.pi, ALPHA, BETA)
    assert np.all(np.diff(day) < 0.0)  # lower ray, longer path
    # Slant = F x vertical delay at the pierce point. Looking south at 5 deg the
    # pierce point lies psi = 0.0137/(5/180 + 0.11) - 0.022 = 0.07744 sc (13.9 deg)
    # south, at the same longitude. A receiver looking up (also southward) has its
    # own pierce point psi_z = 0.0137/0.61 - 0.022 = 0.000459 sc south of it, so
    # one placed psi - psi_z south of Morgantown sees that vertical delay.
    psi = 0.0137 / (5.0 / 180.0 + 0.11) - 0.022
    psi_z = 0.0137 / (0.5 + 0.11) - 0.022
    rx_lat = math.radians(LAT_DEG - 180.0 * (psi - psi_z))
    vertical = klobuchar_l1_delay_m(sow, rx_lat, math.radians(LON_DEG), math.pi / 2, math.pi, ALPHA, BETA)
    assert day[0] == pytest.approx(obliquity(5.0) / obliquity(90.0) * vertical, rel=1e-9)
    assert day[0] / day[-1] > obliquity(5.0) / obliquity(90.0)  # more ionosphere toward the equator


def test_klobuchar_below_horizon_is_evaluated_at_zero_elevation():
    args = (SOW_NOON, math.radians(LAT_DEG), math.radians(LON_DEG))
    below = klobuchar_l1_delay_m(*args, math.radians(-3.0), 1.0, ALPHA, BETA)
    assert below == klobuchar_l1_delay_m(*args, 0.0, 1.0, ALPHA, BETA)
    assert np.isfinite(below)


def test_klobuchar_rejects_bad_coefficients():
    with pytest.raises(SimbenchError, match="iono_alpha"):
        klobuchar_l1_delay_m(0.0, 0.7, -1.4, 0.5, 0.0, ALPHA[:3], BETA)
    with pytest.raises(SimbenchError, match="iono_beta"):
        klobuchar_l1_delay_m(0.0, 0.7, -1.4, 0.5, 0.0, ALPHA, (1.0, 2.0, float("nan"), 3.0))


# --------------------------------------------------------------------------- standard atmosphere, Saastamoinen


def test_standard_atmosphere_matches_isa_and_vapour_tables():
    p, t, e = standard_atmosphere(np.array([0.0, 1000.0, 2000.0, 5000.0]))
    # ICAO standard atmosphere tables [hPa] (geometric altitude; the polytropic
    # formula works in geopotential height, 0.06 % apart at 5 km).
    np.testing.assert_allclose(p, [1013.25, 898.76, 795.01, 540.48], rtol=1e-3)
    np.testing.assert_allclose(t, [288.15, 281.65, 275.15, 255.65], atol=1e-9)
    # Saturation vapour pressure over water at 15 C is 17.04 hPa (WMO tables);
    # 50 % of it within 1 %.
    assert e[0] == pytest.approx(0.5 * 17.04, rel=0.01)
    assert np.all(np.diff(e) < 0.0)
    _, _, e70 = standard_atmosphere(0.0, relative_humidity=0.7)
    assert e70 == pytest.approx(0.7 / 0.5 * e[0], rel=1e-12)
    with pytest.raises(SimbenchError, match="relative_humidity"):
        standard_atmosphere(0.0, relative_humidity=50.0)


def test_saastamoinen_zenith_hydrostatic_and_wet():
    zhd, zwd = saastamoinen_zenith_m(math.radians(45.0), 0.0)
    assert zhd == pytest.approx(0.0022768 * 1013.25 / (1.0 - 0.00266 * math.cos(math.pi / 2)), abs=0.01)
    assert zhd == pytest.approx(2.307, abs=0.001)
    assert 0.05 < zwd < 0.25

    # Davis et al. gravity term at another latitude and height, with the ISA pressure.
    lat, h = math.radians(10.0), 1000.0
    zhd_h, zwd_h = saastamoinen_zenith_m(lat, h)
    p = 1013.25 * (1.0 - 2.2557e-5 * h) ** 5.2568
    assert zhd_h == pytest.approx(0.0022768 * p / (1.0 - 0.00266 * math.cos(2 * lat) - 0.00028 * 1.0), abs=0.01)
    assert zhd_h < zhd and zwd_h < zwd

    lat_arr = np.radians([[10.0], [50.0]])
    zhd_b, zwd_b = saastamoinen_zenith_m(lat_arr, np.array([[0.0, 500.0, 3000.0]]))
    assert zhd_b.shape == zwd_b.shape == (2, 3)


def test_mops_zenith_wet_delay_follows_the_do229_table_by_latitude_and_season():
    """RTCA DO-229 A.4.2.4 by hand: at 15 deg (no season) e = 26.31 hPa, T = 299.65 K, beta = 6.30e-3 K/m,
    lambda = 2.77; at 30 deg N on day 28 (the seasonal minimum) each parameter is its average minus its
    variation; the south is half a year later; height lowers the delay by the table's lapse rates."""
    k2_rd = 1e-6 * 382_000.0 * 287.054
    tropic = k2_rd / (9.784 * 3.77 - 6.30e-3 * 287.054) * 26.31 / 299.65
    assert mops_zenith_wet_m(math.radians(15.0), 0.0, 100.0) == pytest.approx(tropic, rel=1e-12)
    assert tropic == pytest.approx(0.2745, abs=1e-4)
    e, t, beta, lam = 21.79 - 8.85, 294.15 - 7.0, 6.05e-3 - 0.25e-3, 3.15 - 0.33
    winter = k2_rd / (9.784 * (lam + 1.0) - beta * 287.054) * e / t
    assert mops_zenith_wet_m(math.radians(30.0), 0.0, 28.0) == pytest.approx(winter, rel=1e-12)
    assert mops_zenith_wet_m(math.radians(-30.0), 0.0, 211.0) == pytest.approx(winter, rel=1e-12)
    summer = mops_zenith_wet_m(math.radians(30.0), 0.0, 28.0 + 365.25 / 2)
    assert summer > 1.8 * winter  # humid summer, dry winter
    high = mops_zenith_wet_m(math.radians(30.0), 1000.0, 28.0)
    assert high == pytest.approx(winter * (1.0 - beta * 1000.0 / t) ** ((lam + 1.0) * 9.80665 / (287.054 * beta) - 1.0))
    grid = mops_zenith_wet_m(np.radians([[10.0], [80.0]]), np.array([0.0, 500.0]), 176.0)
    assert grid.shape == (2, 2) and grid[0, 0] == pytest.approx(tropic)  # held beyond the table


# --------------------------------------------------------------------------- Niell


def straight_ray_mapping(el_rad, scale_height_m):
    """Path integral of an exponential atmosphere along a straight ray over a
    spherical Earth divided by its vertical integral (no bending)."""
    r_e = 6_371e3
    s = np.linspace(0.0, 600e3, 300_001)
    h = np.sqrt(r_e**2 + s**2 + 2.0 * r_e * s * math.sin(el_rad)) - r_e
    f = np.exp(-h / scale_height_m)
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(s)) / scale_height_m)


def test_niell_zenith_is_one():
    lat = np.radians([[-70.0], [-20.0], [0.0], [33.0], [51.0], [80.0]])
    m_h, m_w = niell_mapping(math.pi / 2, lat, np.array([[0.0, 1500.0, 4000.0]]), 200.0)
    assert m_h.shape == m_w.shape == (6, 3)
    np.testing.assert_allclose(m_h, 1.0, atol=1e-3)
    np.testing.assert_allclose(m_w, 1.0, atol=1e-3)


def test_niell_low_elevation_against_straight_ray_geometry():
    # A hydrostatic refractivity scale height of ~8 km gives 10.14 at 5 deg for a
    # straight ray (7-10 km: 10.27-9.91); 1/sin(5 deg) = 11.47 would be far off.
    reference = straight_ray_mapping(math.radians(5.0), 8_000.0)
    assert reference == pytest.approx(10.14, abs=0.02)
    lat = np.radians(np.array([[30.0], [39.6], [45.0], [60.0], [-45.0]]))
    doy = np.array([[15.0, 105.0, 196.0, 288.0]])
    m_h, m_w = niell_mapping(math.radians(5.0), lat, 0.0, doy)
    assert np.all((m_h > 9.5) & (m_h < 10.5))
    np.testing.assert_allclose(m_h, reference, rtol=0.02)
    # Wet vapour sits low (scale height ~2 km) so its mapping is larger.
    assert np.all(m_w > m_h)
    assert np.all((m_w > 10.3) & (m_w < 11.2))


def test_niell_at_30_deg_is_close_to_cosecant():
    lat = np.radians(np.linspace(-80.0, 80.0, 17))
    m_h, m_w = niell_mapping(math.radians(30.0), lat, 300.0, 355.0)
    np.testing.assert_allclose(m_h, 2.0, rtol=0.01)
    np.testing.assert_allclose(m_w, 2.0, rtol=0.01)


def cf(sin_el, a, b, c):
    return (1 + a / (1 + b / (1 + c))) / (sin_el + a / (sin_el + b / (sin_el + c)))


def test_niell_wet_latitude_interpolation_uses_published_table():
    s5 = math.sin(math.radians(5.0))
    # Niell (1996) Table 4, wet coefficients at 15, 45, 60, 75 deg.
    w15 = (5.8021897e-4, 1.4275268e-3, 4.3472961e-2)
    w45 = (5.8118019e-4, 1.4572752e-3, 4.3908931e-2)
    w60 = (5.9727542e-4, 1.5007428e-3, 4.4626982e-2)
    w75 = (6.1641693e-4, 1.7599082e-3, 5.4736038e-2)
    mid = [(x + y) / 2 for x, y in zip(w45, w60)]
    quarter = [0.75 * x + 0.25 * y for x, y in zip(w45, w60)]
    cases = [(52.5, mid), (-48.75, quarter), (5.0, w15), (-15.0, w15), (82.0, w75), (75.0, w75)]
    for lat_deg, coef in cases:
        m_w = niell_mapping(math.radians(5.0), math.radians(lat_deg), 0.0, 1.0)[1]
        assert m_w == pytest.approx(cf(s5, *coef), rel=1e-12), lat_deg


def test_niell_seasons_and_height():
    el = np.radians([5.0, 10.0, 20.0])
    for lat_deg in (20.0, 45.0, 52.5, 70.0):
        north = niell_mapping(el, math.radians(lat_deg), 0.0, 100.0)[0]
        south = niell_mapping(el, math.radians(-lat_deg), 0.0, 100.0 + 365.25 / 2)[0]
        np.testing.assert_allclose(north, south, rtol=1e-12)
    # Seasonal term: hydrostatic coefficients are lowest on day 28 (a = avg - amp),
    # so mapping is largest then, and in phase opposition half a year later.
    winter = niell_mapping(math.radians(5.0), math.radians(60.0), 0.0, 28.0)[0]
    summer = niell_mapping(math.radians(5.0), math.radians(60.0), 0.0, 28.0 + 365.25 / 2)[0]
    assert winter > summer
    # Height correction: above ~0 m the thinner air column maps more steeply.
    low = niell_mapping(math.radians(5.0), math.radians(45.0), 0.0, 100.0)[0]
    high = niell_mapping(math.radians(5.0), math.radians(45.0), 2000.0, 100.0)[0]
    assert 0.01 < high - low < 0.1


def test_niell_expanded_receiver_arrays_match_per_epoch_ones():
    rng = np.random.default_rng(3)
    n, m = 50, 8
    lat = rng.uniform(-1.4, 1.4, (n, 1))
    h = rng.uniform(0.0, 3000.0, (n, 1))
    doy = rng.uniform(1.0, 366.0, (n, 1))
    el = rng.uniform(0.1, 1.5, (n, m))
    a = niell_mapping(el, lat, h, doy)
    b = niell_mapping(el, np.repeat(lat, m, 1), np.repeat(h, m, 1), np.repeat(doy, m, 1))
    c = niell_mapping(el, np.broadcast_to(lat, (n, m)), h, doy)
    for x, y, z in zip(a, b, c):
        assert x.shape == y.shape == z.shape == (n, m)
        np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(x, z)
    # Genuinely per-element latitudes still go element by element.
    lat_full = rng.uniform(-1.4, 1.4, (n, m))
    full = niell_mapping(el, lat_full, 0.0, 100.0)[0]
    single = [niell_mapping(el[i, j], lat_full[i, j], 0.0, 100.0)[0] for i, j in ((0, 0), (7, 5), (49, 7))]
    np.testing.assert_allclose([full[0, 0], full[7, 5], full[49, 7]], single, rtol=1e-14)


def test_tropo_slant_combines_parts():
    el = np.radians([[7.0, 30.0, 90.0]])
    lat, h, doy = math.radians(39.6), np.array([[290.0]]), 355.0
    zhd, _ = saastamoinen_zenith_m(lat, h)
    m_h, m_w = niell_mapping(el, lat, h, doy)
    got = tropo_slant_m(el, lat, h, doy, 0.12)
    np.testing.assert_allclose(got, zhd * m_h + 0.12 * m_w, rtol=1e-14)
    assert got[0, 2] == pytest.approx(2.307 * 0.966 + 0.12, abs=0.02)  # ~300 m up: 3.4 % less air
