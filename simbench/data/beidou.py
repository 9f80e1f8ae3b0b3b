"""RINEX 3 BeiDou navigation files -> :class:`~simbench.core.beidou_orbits.BeidouEphemeris`.

The ephemeris computation (CGCS2000 constants, BDT, geostationary rotation)
lives in :mod:`simbench.core.beidou_orbits`; the records come from the shared
RINEX 3 reader :func:`simbench.gnss.navigation.read_rinex3_records`; this
module picks the fields and converts BDT weeks and seconds to continuous GPS seconds.

The B1I clock is the broadcast clock (referred to B3I) minus TGD1; a dual-frequency
user also needs TGD2, the B2I group delay (BDS-SIS-ICD-B1I 5.2.4.10), which
:func:`load_beidou_navigation` returns.
"""

from __future__ import annotations

from simbench.core.beidou_orbits import BDT_WEEK_OFFSET, GPS_MINUS_BDT_S, BeidouEphemeris
from simbench.core.constants import SECONDS_PER_WEEK
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

__all__ = ["read_beidou_navigation", "load_beidou_navigation"]

#: Record quantities the orbit and clock need (``tgd`` is TGD1, the B1I group delay).
_FIELDS = (*KEPLER_CLOCK_FIELDS, "tgd")


def read_beidou_navigation(
    path: NavPaths,
    max_age_s: float = FIT_HALF_WINDOW_S,
    setting: str = "scenario.nav_bds",
) -> BeidouEphemeris:
    """Read BeiDou ephemerides from a RINEX 3 navigation file (BeiDou-only or mixed).

    :func:`load_beidou_navigation` without the group delays; same parameters and errors.

    Returns
    -------
    BeidouEphemeris
        Toe/Toc converted from BDT to continuous GPS seconds; ``tgd`` is TGD1.
    """
    return load_beidou_navigation(path, max_age_s, setting)[0]


def load_beidou_navigation(
    path: NavPaths,
    max_age_s: float = FIT_HALF_WINDOW_S,
    setting: str = "scenario.nav_bds",
) -> tuple[BeidouEphemeris, GroupDelays]:
    """Read BeiDou ephemerides and both broadcast group delays from RINEX 3 navigation files.

    Parameters
    ----------
    path : str, PathLike or sequence of them
        RINEX 3 navigation file(s), records merged
        (:func:`~simbench.gnss.navigation.read_rinex3_records`); only ``C`` (BeiDou) records are read, and
        unhealthy or incomplete ones are dropped.
    max_age_s : float
        Largest |t - Toe| at which a record may be used [s]; default 7200.
    setting : str
        Config setting that named the file, for error messages.

    Returns
    -------
    BeidouEphemeris
        Toe/Toc converted from BDT to continuous GPS seconds; ``tgd`` is TGD1.
    GroupDelays
        ``tgd2`` per satellite of the ephemeris, the median over its kept records [s].

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 3 navigation data, or no healthy BeiDou record.
    """
    fix = "pass a RINEX 3 BeiDou or mixed navigation file (e.g. hksc1180.19b)"
    nav = read_system_nav(path, "C", _LAYOUT, setting, fix)
    c = nav.columns
    keep = nav.healthy(complete_kepler_records(c, _FIELDS) & (c["health"] == 0))
    toe = (c["week"][keep] + BDT_WEEK_OFFSET) * SECONDS_PER_WEEK + c["toe"][keep] + GPS_MINUS_BDT_S
    toc = datetime64_to_gps(nav.records.epoch[keep]) + GPS_MINUS_BDT_S
    sats, sat_idx, records = kepler_records(nav.records, c, _FIELDS, keep, toe, toc)
    eph = BeidouEphemeris(sats, records, source=nav.source, max_age_s=max_age_s)
    return eph, {"tgd2": satellite_medians(sat_idx, c["tgd2"][keep], sats.size)}


#: Order of the 31 numbers of a RINEX 3 BeiDou record (3 on the first line, 4 on each of 7 more).
_LAYOUT = kepler_layout("aode", "", "week", "", "accuracy", "health", "tgd", "tgd2", "t_trans", "aodc")
