"""Atmospheric propagation delays: Klobuchar ionosphere, Saastamoinen + Niell troposphere.

All functions are vectorised and broadcast their arguments, so per-epoch
receiver quantities of shape ``(n, 1)`` combine with per-satellite quantities
of shape ``(n, m)``. Angles are in radians, heights in metres above the
ellipsoid, delays in metres (positive = longer apparent range).

References
----------
* IS-GPS-200, section 20.3.3.5.2.5 (single-frequency ionospheric algorithm).
* J. Saastamoinen (1972), "Atmospheric correction for the troposphere and
  stratosphere in radio ranging of satellites", AGU Geophys. Monogr. 15;
  with the Davis et al. (1985) latitude/height gravity correction.
* A. E. Niell (1996), "Global mapping functions for the atmosphere delay at
  radio wavelengths", J. Geophys. Res. 101(B2), 3227-3246, Tables 3 and 4.
* RTCA DO-229 (SBAS MOPS), Appendix A.4.2.4: the zenith delays of a climatology of
  pressure, temperature, water vapour pressure and their lapse rates by latitude and
  season (the UNB3 table; Leandro, Santos and Langley 2006).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simbench.core.constants import C_LIGHT, DEG, SECONDS_PER_DAY
from simbench.errors import SimbenchError

__all__ = [
    "klobuchar_l1_delay_m",
    "standard_atmosphere",
    "saastamoinen_zenith_m",
    "mops_zenith_wet_m",
    "niell_mapping",
    "tropo_slant_m",
]

FloatArray = NDArray[np.float64]

# --------------------------------------------------------------------------- ionosphere

#: Night-time (constant) vertical delay of the Klobuchar model [s].
_KLOB_NIGHT_S = 5.0e-9
#: Local time of the cosine peak [s] (14:00).
_KLOB_PEAK_S = 50_400.0
#: Lower bound of the cosine period [s].
_KLOB_MIN_PERIOD_S = 72_000.0
#: Limit of the ionospheric pierce-point latitude [semicircles].
_KLOB_MAX_IPP_LAT_SC = 0.416


def _klobuchar_coefficients(values: Sequence[float] | ArrayLike, field: str) -> FloatArray:
    coef = np.asarray(values, dtype=float).ravel()
    if coef.size != 4 or not np.all(np.isfinite(coef)):
        raise SimbenchError(
            field,
            f"expected 4 finite Klobuchar coefficients, got {coef.size} value(s)",
            "give the four ION ALPHA / ION BETA values of a RINEX navigation header",
        )
    return coef


def _horner(coef: FloatArray, x: FloatArray) -> FloatArray:
    return coef[0] + x * (coef[1] + x * (coef[2] + x * coef[3]))


def klobuchar_l1_delay_m(
    sow_s: ArrayLike,
    lat_rad: ArrayLike,
    lon_rad: ArrayLike,
    el_rad: ArrayLike,
    az_rad: ArrayLike,
    alpha: Sequence[float] | ArrayLike,
    beta: Sequence[float] | ArrayLike,
) -> FloatArray:
    """Broadcast (Klobuchar) ionospheric slant delay on GPS L1.

    Implements the IS-GPS-200 single-frequency user algorithm: a thin shell at
    350 km, half-cosine daytime vertical delay peaking at 14:00 local time on
    top of a constant 5 ns night-time floor, projected to slant by the
    obliquity factor ``F = 1 + 16 (0.53 - E)^3`` (E in semicircles).

    The delay holds for L1 code (group delay, ``+I``); carrier phase is
    advanced by the same amount (``-I``). For another frequency ``f`` the
    caller scales the result by ``(F_L1 / f)**2`` (the ionosphere is
    dispersive with delay proportional to 1/f^2), e.g.
    :data:`simbench.core.constants.IONO_L2_SCALE` for L2.

    Parameters
    ----------
    sow_s : array_like
        GPS time as seconds of week [s]. Only the time of day matters.
    lat_rad, lon_rad : array_like
        Geodetic latitude and longitude of the receiver [rad].
    el_rad, az_rad : array_like
        Elevation and azimuth of the satellite seen from the receiver [rad].
        Elevations below 0 are evaluated at 0 (the model is undefined there;
        mask such satellites).
    alpha : sequence of 4 float
        Amplitude polynomial coefficients [s, s/sc, s/sc^2, s/sc^3].
    beta : sequence of 4 float
        Period polynomial coefficients [s, s/sc, s/sc^2, s/sc^3].

    Returns
    -------
    numpy.ndarray
        L1 slant ionospheric delay [m], shape of the broadcast inputs.

    Raises
    ------
    SimbenchError
        If ``alpha`` or ``beta`` do not hold four finite numbers.
    """
    a = _klobuchar_coefficients(alpha, "iono_alpha")
    b = _klobuchar_coefficients(beta, "iono_beta")

    # The broadcast algorithm is defined in semicircles throughout.
    e_sc = np.clip(np.asarray(el_rad, dtype=float) * (1.0 / np.pi), 0.0, 0.5)
    az = np.asarray(az_rad, dtype=float)
    lat_sc = np.asarray(lat_rad, dtype=float) * (1.0 / np.pi)
    lon_sc = np.asarray(lon_rad, dtype=float) * (1.0 / np.pi)

    # Earth-central angle between receiver and pierce point.
    psi = 0.0137 / (e_sc + 0.11) - 0.022
    ipp_lat = np.clip(lat_sc + psi * np.cos(az), -_KLOB_MAX_IPP_LAT_SC, _KLOB_MAX_IPP_LAT_SC)
    ipp_lon = lon_sc + psi * np.sin(az) / np.cos(ipp_lat * np.pi)
    # Geomagnetic latitude of the pierce point (dipole pole at 78.3 N, 291 E).
    geomag_lat = ipp_lat + 0.064 * np.cos((ipp_lon - 1.617) * np.pi)

    local_time = 4.32e4 * ipp_lon + np.asarray(sow_s, dtype=float)
    # floor-based modulo: same result as np.mod, about three times faster.
    local_time -= SECONDS_PER_DAY * np.floor(local_time * (1.0 / SECONDS_PER_DAY))
    amplitude = np.maximum(_horner(a, geomag_lat), 0.0)
    period = np.maximum(_horner(b, geomag_lat), _KLOB_MIN_PERIOD_S)
    x = (2.0 * np.pi) * (local_time - _KLOB_PEAK_S) / period

    # Truncated cosine series as specified, not np.cos: the standard defines
    # the model through this polynomial and receivers evaluate it this way.
    x2 = x * x
    day = amplitude * (1.0 - 0.5 * x2 + x2 * x2 * (1.0 / 24.0))
    day *= np.abs(x) < 1.57
    slant = 0.53 - e_sc
    obliquity = 1.0 + 16.0 * slant * slant * slant
    return (C_LIGHT * obliquity) * (_KLOB_NIGHT_S + day)


# --------------------------------------------------------------------------- troposphere

#: Height range over which the polytropic standard atmosphere is evaluated [m];
#: beyond ~20 km the lapse-rate formula gives unphysical temperatures and the
#: pressure base (1 - 2.2557e-5 h) approaches zero at 44 km.
_H_MIN_M = -500.0
_H_MAX_M = 20_000.0
#: Elevation floor for the mapping functions [rad]: Niell is fitted down to 3 deg
#: and the continued fraction diverges at 0; below-horizon rays must be masked.
_EL_MIN_RAD = 1.0 * DEG
#: Relative humidity of the standard atmosphere [-] (see standard_atmosphere).
DEFAULT_RELATIVE_HUMIDITY = 0.5


def standard_atmosphere(
    h_m: ArrayLike, relative_humidity: float = DEFAULT_RELATIVE_HUMIDITY
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Standard atmosphere used with the Saastamoinen model.

    ``P = 1013.25 (1 - 2.2557e-5 h)^5.2568`` hPa and ``T = 288.15 - 6.5e-3 h``
    K (ICAO lapse rate 6.5 K/km), with the water-vapour partial pressure from
    the Magnus-type saturation formula used with Saastamoinen (e.g. RTKLIB's
    ``tropmodel``), ``e = RH * 6.108 exp((17.15 T - 4684) / (T - 38.45))`` hPa.

    The default relative humidity of 50 % is the sea-level value of the Berg
    (1948) standard atmosphere, the usual a-priori meteorology of geodetic
    GNSS software; it gives a sea-level zenith wet delay of about 8.6 cm,
    inside the 5-25 cm range of mid-latitude climatology. (RTKLIB's
    single-point default is 70 %, i.e. 40 % more wet delay.) The exact value
    matters little here: the simulated true wet delay is scaled per scenario
    and the estimators estimate a residual zenith wet delay.

    Parameters
    ----------
    h_m : array_like
        Height [m]; clipped to [-500, 20000] m where the polytropic model holds.
    relative_humidity : float, optional
        Relative humidity [-], 0..1, held constant with height.

    Returns
    -------
    pressure_hpa : numpy.ndarray
        Total pressure [hPa].
    temperature_k : numpy.ndarray
        Temperature [K].
    water_vapour_hpa : numpy.ndarray
        Partial pressure of water vapour [hPa].

    Raises
    ------
    SimbenchError
        If ``relative_humidity`` is outside [0, 1].
    """
    if not 0.0 <= relative_humidity <= 1.0:
        raise SimbenchError(
            "relative_humidity",
            f"must lie in [0, 1], got {relative_humidity}",
            "give it as a fraction, e.g. 0.5 for 50 %",
        )
    h = np.clip(np.asarray(h_m, dtype=float), _H_MIN_M, _H_MAX_M)
    pressure = 1013.25 * (1.0 - 2.2557e-5 * h) ** 5.2568
    temperature = 288.15 - 6.5e-3 * h
    water_vapour = (relative_humidity * 6.108) * np.exp((17.15 * temperature - 4684.0) / (temperature - 38.45))
    return pressure, temperature, water_vapour


def _zhd_m(lat_rad: ArrayLike, h_m: ArrayLike, pressure_hpa: FloatArray) -> FloatArray:
    h = np.clip(np.asarray(h_m, dtype=float), _H_MIN_M, _H_MAX_M)
    # Gravity at the centre of mass of the air column varies with latitude and height.
    gravity = 1.0 - 0.00266 * np.cos(2.0 * np.asarray(lat_rad, dtype=float)) - 0.00028e-3 * h
    return 0.0022768 * pressure_hpa / gravity


def saastamoinen_zenith_m(
    lat_rad: ArrayLike, h_m: ArrayLike, relative_humidity: float = DEFAULT_RELATIVE_HUMIDITY
) -> tuple[FloatArray, FloatArray]:
    """Saastamoinen zenith hydrostatic and wet delays in the standard atmosphere.

    ``ZHD = 0.0022768 P / (1 - 0.00266 cos 2phi - 0.00028 h_km)`` and
    ``ZWD = 0.002277 (1255 / T + 0.05) e`` with P, T, e from
    :func:`standard_atmosphere`.

    Parameters
    ----------
    lat_rad : array_like
        Geodetic latitude [rad].
    h_m : array_like
        Height [m] (clipped as in :func:`standard_atmosphere`).
    relative_humidity : float, optional
        Relative humidity [-] of the standard atmosphere.

    Returns
    -------
    zhd_m : numpy.ndarray
        Zenith hydrostatic delay [m] (about 2.3 m at sea level).
    zwd_m : numpy.ndarray
        Zenith wet delay [m] (about 0.09 m at sea level for 50 % humidity).
    """
    pressure, temperature, water_vapour = standard_atmosphere(h_m, relative_humidity)
    zhd = _zhd_m(lat_rad, h_m, pressure)
    zwd = 0.002277 * (1255.0 / temperature + 0.05) * water_vapour
    shape = np.broadcast_shapes(zhd.shape, zwd.shape)
    return np.broadcast_to(zhd, shape).copy(), np.broadcast_to(zwd, shape).copy()


#: RTCA DO-229 Table A-2 (MOPS): mean sea level pressure [hPa], temperature [K], water vapour
#: pressure [hPa], temperature lapse rate [K/m] and water vapour lapse rate [-]; rows: their
#: averages, then their seasonal variations; columns: latitude 15, 30, 45, 60, 75 deg.
_MOPS_MET = np.array(
    [
        [[1013.25, 1017.25, 1015.75, 1011.75, 1013.00], [0.0, -3.75, -2.25, -1.75, -0.50]],
        [[299.65, 294.15, 283.15, 272.15, 263.65], [0.0, 7.0, 11.0, 15.0, 14.5]],
        [[26.31, 21.79, 11.66, 6.78, 4.11], [0.0, 8.85, 7.24, 5.36, 3.39]],
        [[6.30e-3, 6.05e-3, 5.58e-3, 5.39e-3, 4.53e-3], [0.0, 0.25e-3, 0.32e-3, 0.81e-3, 0.62e-3]],
        [[2.77, 3.15, 2.57, 1.81, 1.55], [0.0, 0.33, 0.46, 0.74, 0.30]],
    ]
)
_MOPS_LAT_DEG = np.array([15.0, 30.0, 45.0, 60.0, 75.0])
#: Day of year of the seasonal minimum of the MOPS climatology (northern hemisphere; south: 211).
_MOPS_DOY_MIN_NORTH, _MOPS_DOY_MIN_SOUTH = 28.0, 211.0
#: MOPS refractivity constant k2 [K^2/hPa], dry-air gas constant [J/(kg K)], gravity at the
#: centroid of the atmospheric column and at the surface [m/s^2].
_MOPS_K2, _MOPS_RD, _MOPS_GM, _MOPS_G = 382_000.0, 287.054, 9.784, 9.80665


def mops_zenith_wet_m(lat_rad: ArrayLike, h_m: ArrayLike, day_of_year: ArrayLike) -> FloatArray:
    """Zenith wet delay of the RTCA MOPS climatology (DO-229 A.4.2.4) [m].

    Each meteorological parameter is ``avg - amp cos(2 pi (doy - D_min) / 365.25)``, interpolated
    linearly in ``|latitude|`` between the tabulated 15-75 deg (held outside), ``D_min`` 28 in
    the north and 211 in the south; ``ZWD = 1e-6 k2 Rd / (g_m (lambda + 1) - beta Rd) e / T`` at
    sea level, times ``(1 - beta H / T)^((lambda + 1) g / (Rd beta) - 1)`` at height ``H``. A
    standard atmosphere of one humidity has no season or latitude: 8.6 cm at sea level against,
    e.g., 22 cm here for Nagoya in June and 24 cm for Hong Kong in April.

    Parameters
    ----------
    lat_rad : array_like
        Geodetic latitude [rad].
    h_m : array_like
        Height [m] (MOPS takes it above sea level; 50 m of geoid undulation changes a
        wet delay by about 2 %); clipped to [-500, 20000] m.
    day_of_year : array_like
        Day of year [day], fractional allowed.

    Returns
    -------
    numpy.ndarray
        Zenith wet delay [m], broadcast shape of the arguments.
    """
    lat_deg = np.asarray(lat_rad, dtype=float) * (1.0 / DEG)
    abs_lat = np.clip(np.abs(lat_deg), _MOPS_LAT_DEG[0], _MOPS_LAT_DEG[-1])
    doy_min = np.where(lat_deg < 0.0, _MOPS_DOY_MIN_SOUTH, _MOPS_DOY_MIN_NORTH)
    season = np.cos((2.0 * np.pi / _DAYS_PER_YEAR) * (np.asarray(day_of_year, dtype=float) - doy_min))
    _, temperature, water_vapour, beta, lam = (
        np.interp(abs_lat, _MOPS_LAT_DEG, avg) - np.interp(abs_lat, _MOPS_LAT_DEG, amp) * season
        for avg, amp in _MOPS_MET
    )
    sea_level = 1e-6 * _MOPS_K2 * _MOPS_RD / (_MOPS_GM * (lam + 1.0) - beta * _MOPS_RD) * water_vapour / temperature
    h = np.clip(np.asarray(h_m, dtype=float), _H_MIN_M, _H_MAX_M)
    return np.asarray(sea_level * (1.0 - beta * h / temperature) ** ((lam + 1.0) * _MOPS_G / (_MOPS_RD * beta) - 1.0))


#: Niell (1996) Tables 3 and 4. Rows: hydrostatic average a, b, c; hydrostatic
#: seasonal amplitude a, b, c; wet a, b, c. Columns: latitude 15, 30, 45, 60, 75 deg.
_NIELL_COEF = np.array(
    [
        [1.2769934e-3, 1.2683230e-3, 1.2465397e-3, 1.2196049e-3, 1.2045996e-3],
        [2.9153695e-3, 2.9152299e-3, 2.9288445e-3, 2.9022565e-3, 2.9024912e-3],
        [62.610505e-3, 62.837393e-3, 63.721774e-3, 63.824265e-3, 64.258455e-3],
        [0.0, 1.2709626e-5, 2.6523662e-5, 3.4000452e-5, 4.1202191e-5],
        [0.0, 2.1414979e-5, 3.0160779e-5, 7.2562722e-5, 11.723375e-5],
        [0.0, 9.0128400e-5, 4.3497037e-5, 84.795348e-5, 170.37206e-5],
        [5.8021897e-4, 5.6794847e-4, 5.8118019e-4, 5.9727542e-4, 6.1641693e-4],
        [1.4275268e-3, 1.5138625e-3, 1.4572752e-3, 1.5007428e-3, 1.7599082e-3],
        [4.3472961e-2, 4.6729510e-2, 4.3908931e-2, 4.4626982e-2, 5.4736038e-2],
    ]
)
#: Change of each coefficient over each 15-deg latitude interval.
_NIELL_STEP = np.diff(_NIELL_COEF, axis=1)
#: Hydrostatic height-correction coefficients a_ht, b_ht, c_ht (per km).
_NIELL_HEIGHT = (2.53e-5, 5.49e-3, 1.14e-3)
#: Day of year of the seasonal minimum of the hydrostatic coefficients (northern hemisphere).
_NIELL_DOY0 = 28.0
_DAYS_PER_YEAR = 365.25


def _collapse_repeats(x: ArrayLike) -> FloatArray:
    """View of ``x`` with every axis along which it is constant cut to length 1.

    Receiver quantities (latitude, height, day of year) often arrive expanded
    to the per-satellite shape; the latitude-dependent Niell coefficients cost
    ~20 operations per element, so evaluating them once per epoch and letting
    broadcasting expand the result saves most of the work. The test costs one
    comparison per element and axis.
    """
    arr = np.asarray(x, dtype=float)
    for axis in range(arr.ndim):
        if arr.shape[axis] > 1:
            first = arr[(slice(None),) * axis + (slice(0, 1),)]
            if arr.strides[axis] == 0 or bool(np.all(arr == first)):
                arr = first
    return arr


def _expand(x: FloatArray, shape: tuple[int, ...]) -> FloatArray:
    # Outputs take the broadcast shape of all inputs, even those a result does
    # not depend on or that were collapsed, so callers can index them uniformly.
    return x if x.shape == shape else np.broadcast_to(x, shape).copy()


def _marini(sin_el: FloatArray, a: FloatArray | float, b: FloatArray | float, c: FloatArray | float) -> FloatArray:
    # Normalised continued fraction (Marini/Herring form): equals 1 at zenith.
    top = 1.0 + a / (1.0 + b / (1.0 + c))
    return top / (sin_el + a / (sin_el + b / (sin_el + c)))


def niell_mapping(
    el_rad: ArrayLike, lat_rad: ArrayLike, h_m: ArrayLike, day_of_year: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Niell (1996) hydrostatic and wet mapping functions.

    The coefficients are interpolated linearly in ``|latitude|`` between the
    tabulated 15, 30, 45, 60 and 75 deg (held constant outside); the
    hydrostatic ones vary as ``avg - amp cos(2 pi (doy - 28) / 365.25)``,
    shifted by half a year in the southern hemisphere, and get Niell's height
    correction ``(1/sin el - f(el; a_ht, b_ht, c_ht)) h_km``.

    Parameters
    ----------
    el_rad : array_like
        Elevation [rad]; evaluated at no less than 1 deg (Niell is fitted down
        to 3 deg; mask lower rays).
    lat_rad : array_like
        Geodetic latitude [rad].
    h_m : array_like
        Station height [m] (Niell uses height above sea level; the geoid
        undulation changes the result by < 1e-4 at 5 deg).
    day_of_year : array_like
        Day of year [day], fractional allowed (1.0 = 1 January 00:00).

    Returns
    -------
    m_hydrostatic : numpy.ndarray
        Hydrostatic mapping function [-].
    m_wet : numpy.ndarray
        Wet mapping function [-].
    """
    shape = np.broadcast_shapes(np.shape(el_rad), np.shape(lat_rad), np.shape(h_m), np.shape(day_of_year))
    lat = _collapse_repeats(lat_rad)
    abs_lat_deg = np.abs(lat) * (1.0 / DEG)
    # One set of interval indices and weights serves all nine coefficient rows
    # (np.take on a 1-D row is an order of magnitude faster than a 2-D gather).
    pos = np.clip(abs_lat_deg * (1.0 / 15.0) - 1.0, 0.0, 4.0)
    i0 = np.minimum(pos.astype(np.intp), 3)
    w = pos - i0
    coef = [np.take(_NIELL_COEF[k, :4], i0) + w * np.take(_NIELL_STEP[k], i0) for k in range(9)]

    season = np.cos((2.0 * np.pi / _DAYS_PER_YEAR) * (_collapse_repeats(day_of_year) - _NIELL_DOY0))
    # Half a year of phase shift flips the sign of the cosine in the south.
    season = season * np.where(lat < 0.0, -1.0, 1.0)
    ah = coef[0] - coef[3] * season
    bh = coef[1] - coef[4] * season
    ch = coef[2] - coef[5] * season

    sin_el = np.sin(np.maximum(np.asarray(el_rad, dtype=float), _EL_MIN_RAD))
    h_km = np.asarray(h_m, dtype=float) * 1e-3
    height_corr = (1.0 / sin_el - _marini(sin_el, *_NIELL_HEIGHT)) * h_km
    m_hydrostatic = _marini(sin_el, ah, bh, ch) + height_corr
    m_wet = _marini(sin_el, coef[6], coef[7], coef[8])
    return _expand(m_hydrostatic, shape), _expand(m_wet, shape)


def tropo_slant_m(
    el_rad: ArrayLike,
    lat_rad: ArrayLike,
    h_m: ArrayLike,
    day_of_year: ArrayLike,
    zwd_m: ArrayLike,
) -> FloatArray:
    """Slant tropospheric delay ``ZHD * m_h + ZWD * m_w``.

    The hydrostatic part is Saastamoinen in the standard atmosphere; the wet
    zenith delay is given by the caller (e.g. the "true" simulated value, or
    :func:`saastamoinen_zenith_m`'s nominal one).

    Parameters
    ----------
    el_rad : array_like
        Elevation [rad].
    lat_rad : array_like
        Geodetic latitude [rad].
    h_m : array_like
        Height [m].
    day_of_year : array_like
        Day of year [day].
    zwd_m : array_like
        Zenith wet delay [m].

    Returns
    -------
    numpy.ndarray
        Slant tropospheric delay [m].
    """
    shape = np.broadcast_shapes(
        np.shape(el_rad), np.shape(lat_rad), np.shape(h_m), np.shape(day_of_year), np.shape(zwd_m)
    )
    lat = _collapse_repeats(lat_rad)
    h = _collapse_repeats(h_m)
    pressure, _, _ = standard_atmosphere(h)
    zhd = _zhd_m(lat, h, pressure)
    m_h, m_w = niell_mapping(el_rad, lat, h, day_of_year)
    return _expand(zhd * m_h + np.asarray(zwd_m, dtype=float) * m_w, shape)
