"""RINEX 3 Galileo navigation records -> :class:`~simbench.core.galileo_orbits.GalileoEphemeris`.

The records come from the shared reader
:func:`simbench.gnss.navigation.read_rinex3_records` (Galileo-only or mixed
files); the orbit and clock computation is in :mod:`simbench.core.galileo_orbits`.

A RINEX file may hold both I/NAV (E1-B/E5b-I; clock for the E1-E5b pair) and
F/NAV (E5a-I; clock for E1-E5a) records of a satellite. An E1 user wants the
I/NAV message: when a satellite has I/NAV records only those are kept, else its
F/NAV ones, and each record's group delay is the BGD of its clock pair
(RINEX 3 "data sources" bits 8/9; Galileo OS SIS ICD 5.1.5).

Both BGDs serve a dual-frequency user (:func:`load_galileo_navigation`): I/NAV
broadcasts BGD(E1,E5a) and BGD(E1,E5b), F/NAV only BGD(E1,E5a), and RINEX writes
0 into an F/NAV record's BGD(E1,E5b) field (every F/NAV record of the Nagoya
file), so that field counts as missing there.
"""

from __future__ import annotations

import numpy as np

from simbench.core.constants import SECONDS_PER_WEEK
from simbench.core.galileo_orbits import GalileoEphemeris
from simbench.core.gpstime import datetime64_to_gps
from simbench.core.orbits import FIT_HALF_WINDOW_S
from simbench.gnss.navigation import (
    KEPLER_CLOCK_FIELDS,
    GroupDelays,
    NavPaths,
    complete_kepler_records,
    kepler_layout,
    kepler_records,
    read_system_nav,
    satellite_medians,
)

__all__ = ["read_galileo_navigation", "load_galileo_navigation"]

#: Order of the numbers of a RINEX 3 Galileo record (3 on the first line, 4 on each further line).
_LAYOUT = kepler_layout("iod", "sources", "week", "", "sisa", "health", "bgd_e5a", "bgd_e5b")
#: Record quantities the orbit and clock need.
_FIELDS = KEPLER_CLOCK_FIELDS
_INAV_CLOCK_BIT, _FNAV_CLOCK_BIT = 1 << 9, 1 << 8  # af0..af2 refer to (E5b, E1) / (E5a, E1)
_INAV_SIGNAL_BITS = 0b101  # E1-B, E5b-I


def read_galileo_navigation(
    path: NavPaths,
    max_age_s: float = FIT_HALF_WINDOW_S,
    setting: str = "scenario.nav_gal",
) -> GalileoEphemeris:
    """Read Galileo ephemerides from a RINEX 3 navigation file (Galileo-only or mixed).

    :func:`load_galileo_navigation` without the group delays; same parameters and errors.

    Returns
    -------
    GalileoEphemeris
        Toe/Toc in continuous GPS seconds (the RINEX Galileo week is the GPS
        week); ``tgd`` is BGD(E1,E5b) for I/NAV clocks, BGD(E1,E5a) for F/NAV.
    """
    return load_galileo_navigation(path, max_age_s, setting)[0]


def load_galileo_navigation(
    path: NavPaths,
    max_age_s: float = FIT_HALF_WINDOW_S,
    setting: str = "scenario.nav_gal",
) -> tuple[GalileoEphemeris, GroupDelays]:
    """Read Galileo ephemerides and both broadcast group delays from RINEX 3 navigation files.

    Parameters
    ----------
    path : str, PathLike or sequence of them
        RINEX 3 navigation file(s), records merged
        (:func:`~simbench.gnss.navigation.read_rinex3_records`); only ``E`` records are read, and unhealthy or
        incomplete ones are dropped.
    max_age_s : float
        Largest |t - Toe| at which a record may be used [s]; default 7200.
    setting : str
        Config setting that named the file, for error messages.

    Returns
    -------
    GalileoEphemeris
        Toe/Toc in continuous GPS seconds (the RINEX Galileo week is the GPS
        week); ``tgd`` is BGD(E1,E5b) for I/NAV clocks, BGD(E1,E5a) for F/NAV.
    GroupDelays
        ``bgd_e5a`` and ``bgd_e5b`` per satellite of the ephemeris, medians over its kept
        records [s]; ``bgd_e5b`` NaN for a satellite with F/NAV records only.

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 3 navigation data, a malformed record, or no healthy Galileo record.
    """
    fix = "pass a RINEX 3 Galileo or mixed navigation file (e.g. BRDC00IGS_R_<yyyydoy>0000_01D_MN.rnx)"
    nav = read_system_nav(path, "E", _LAYOUT, setting, fix)
    c = nav.columns
    src = np.nan_to_num(c["sources"]).astype(np.int64)
    inav = ((src & _INAV_CLOCK_BIT) != 0) | (((src & _FNAV_CLOCK_BIT) == 0) & ((src & _INAV_SIGNAL_BITS) != 0))
    bgd_e5a = c["bgd_e5a"]
    bgd_e5b = np.where(inav, c["bgd_e5b"], np.nan)  # F/NAV's field holds 0, not a broadcast value
    bgd = np.where(inav, bgd_e5b, bgd_e5a)
    keep = complete_kepler_records(c, _FIELDS) & (c["health"] == 0)
    # one message type per satellite, I/NAV first: the two clock models differ by the BGDs
    sv = nav.records.sv
    has_inav = {s for s, ok in zip(sv.tolist(), keep & inav) if ok}
    keep = nav.healthy(keep & (inav | ~np.isin(sv, list(has_inav))))
    toe = c["week"][keep] * SECONDS_PER_WEEK + c["toe"][keep]
    toc = datetime64_to_gps(nav.records.epoch[keep])
    sats, sat_idx, records = kepler_records(nav.records, c, _FIELDS, keep, toe, toc)
    records["tgd"] = np.nan_to_num(bgd[keep])
    eph = GalileoEphemeris(sats, records, source=nav.source, max_age_s=max_age_s)
    delays = {
        name: satellite_medians(sat_idx, x[keep], sats.size) for name, x in (("bgd_e5a", bgd_e5a), ("bgd_e5b", bgd_e5b))
    }
    return eph, delays
