"""GPS time: continuous GPS seconds, calendar epochs and day of year.

``t_gps`` everywhere is continuous GPS seconds since 1980-01-06 00:00:00 GPS
(``week * 604800 + seconds of week``).
"""

from __future__ import annotations

import numpy as np

from simbench.core.constants import GPS_EPOCH_ISO, SECONDS_PER_WEEK

_GPS_EPOCH = np.datetime64(GPS_EPOCH_ISO, "ns")
#: UTC dates from which GPS - UTC grew by one second (IERS Bulletin C); 18 s since 2017-01-01.
_LEAP_SECOND_DATES = np.array(
    [
        "1981-07-01",
        "1982-07-01",
        "1983-07-01",
        "1985-07-01",
        "1988-01-01",
        "1990-01-01",
        "1991-01-01",
        "1992-07-01",
        "1993-07-01",
        "1994-07-01",
        "1996-01-01",
        "1997-07-01",
        "1999-01-01",
        "2006-01-01",
        "2009-01-01",
        "2012-07-01",
        "2015-07-01",
        "2017-01-01",
    ],
    dtype="datetime64[s]",
)


def datetime64_to_gps(t: np.ndarray | np.datetime64 | str) -> np.ndarray:
    """Convert calendar times already in the GPS time scale to continuous GPS seconds.

    Parameters
    ----------
    t : array_like of datetime64 or ISO strings
        Calendar epochs labelled in GPS time (as RINEX and SP3 files do).

    Returns
    -------
    t_gps : np.ndarray of float
        Seconds since 1980-01-06 00:00:00 GPS [s].
    """
    ns = (np.asarray(t, dtype="datetime64[ns]") - _GPS_EPOCH).astype(np.int64)
    # Whole seconds and the sub-second part separately: int64 ns -> float64
    # directly would round to ~256 ns.
    sec, frac = np.divmod(ns, 1_000_000_000)
    return sec.astype(float) + frac * 1e-9


def utc_to_gps(t_utc: np.ndarray | np.datetime64 | str) -> np.ndarray:
    """Convert UTC calendar times to continuous GPS seconds (leap seconds from a table).

    Parameters
    ----------
    t_utc : array_like of datetime64 or ISO strings
        Calendar epochs in UTC (e.g. the GLONASS records of a RINEX 3 navigation file).

    Returns
    -------
    t_gps : np.ndarray of float
        Seconds since 1980-01-06 00:00:00 GPS [s]: the calendar value plus GPS - UTC
        (the leap seconds announced up to 2017-01-01; none were added since).
    """
    t = np.asarray(t_utc, dtype="datetime64[ns]")
    leap = np.searchsorted(_LEAP_SECOND_DATES.astype("datetime64[ns]"), t, side="right")
    return datetime64_to_gps(t) + leap


def gps_to_datetime64(t_gps: np.ndarray | float) -> np.ndarray:
    """Inverse of :func:`datetime64_to_gps` (millisecond resolution, for messages/plots).

    Parameters
    ----------
    t_gps : array_like of float
        Continuous GPS seconds [s].

    Returns
    -------
    t : np.ndarray of datetime64[ms]
        Calendar epochs in the GPS time scale.
    """
    ms = np.round(np.asarray(t_gps, dtype=float) * 1e3).astype(np.int64)
    return _GPS_EPOCH.astype("datetime64[ms]") + ms.astype("timedelta64[ms]")


def format_gps_time(t_gps: float) -> str:
    """``t_gps`` (continuous GPS seconds [s]) as ``'YYYY-MM-DD hh:mm:ss'`` in the GPS time scale, truncated to
    the second, for error messages."""
    return str(gps_to_datetime64(t_gps).astype("datetime64[s]")).replace("T", " ")


def day_of_year(gps_week: int, sow_s: float) -> float:
    """Day of year (1-based, fractional) of a GPS time, as the Niell mapping wants it.

    Leap seconds (GPS - UTC) are ignored: they shift the day by < 1e-3 d.
    """
    t = gps_to_datetime64(gps_week * SECONDS_PER_WEEK + sow_s)
    return float((t - t.astype("datetime64[Y]")) / np.timedelta64(1, "D")) + 1.0
