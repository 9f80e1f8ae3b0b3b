"""RINEX 3 navigation files -> the BeiDou, Galileo, GLONASS and QZSS ephemerides: one reader, a table of systems.

:func:`load_navigation` reads one system's records from RINEX 3 navigation files (that
system's own or mixed files, several merged: :func:`simbench.gnss.navigation.read_system_nav`),
names their numbers by the system's record layout and hands them to the system's conversion
(:data:`NAV_SYSTEMS`), which keeps the healthy, complete records and builds the ephemeris;
the orbit and clock computations are in :mod:`simbench.core` (``beidou_orbits``, ``galileo_orbits``,
``glonass_orbits``, ``orbits``). GPS is read by :func:`simbench.gnss.navigation.read_gps_navigation`
(RINEX 2 too).

BeiDou: BDT weeks and seconds become continuous GPS seconds. The B1I clock is the broadcast
clock (referred to B3I) minus TGD1; a dual-frequency user also needs TGD2, the B2I group delay
(BDS-SIS-ICD-B1I 5.2.4.10), which :func:`beidou_ephemeris` returns.

Galileo: a RINEX file may hold both I/NAV (E1-B/E5b-I; clock for the E1-E5b pair) and
F/NAV (E5a-I; clock for E1-E5a) records of a satellite. An E1 user wants the
I/NAV message: when a satellite has I/NAV records only those are kept, else its
F/NAV ones, and each record's group delay is the BGD of its clock pair
(RINEX 3 "data sources" bits 8/9; Galileo OS SIS ICD 5.1.5). Both BGDs serve a dual-frequency
user (:func:`galileo_ephemeris`): I/NAV broadcasts BGD(E1,E5a) and BGD(E1,E5b), F/NAV only
BGD(E1,E5a), and RINEX writes 0 into an F/NAV record's BGD(E1,E5b) field (every F/NAV record
of the Nagoya file), so that field counts as missing there.

GLONASS: RINEX 3 gives the record epoch (tb) in UTC, the clock as -TauN and +GammaN, and the
state in km, km/s and km/s^2.

QZSS broadcasts the GPS LNAV message layout on L1 C/A (IS-QZSS-PNT 4.1.2): the same Keplerian
set, clock polynomial and TGD, in GPS time and GPS weeks, with the WGS-84 / GPS constants, so
the IS-GPS-200 user algorithm of :class:`~simbench.core.orbits.BroadcastEphemeris` computes its
satellites.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from simbench.core.beidou_orbits import BDT_WEEK_OFFSET, GPS_MINUS_BDT_S, BeidouEphemeris
from simbench.core.constants import SECONDS_PER_WEEK
from simbench.core.galileo_orbits import GalileoEphemeris
from simbench.core.glonass_orbits import GLO_MAX_AGE_S, GlonassEphemeris
from simbench.core.gpstime import datetime64_to_gps, utc_to_gps
from simbench.core.orbits import FIT_HALF_WINDOW_S, BroadcastEphemeris
from simbench.errors import SimbenchError
from simbench.gnss.navigation import (
    KEPLER_CLOCK_FIELDS,
    GroupDelays,
    NavPaths,
    SystemNav,
    complete_kepler_records,
    kepler_layout,
    kepler_records,
    read_system_nav,
    satellite_medians,
)

__all__ = [
    "Ephemeris",
    "NavSystem",
    "NAV_SYSTEMS",
    "load_navigation",
    "read_navigation",
    "beidou_ephemeris",
    "galileo_ephemeris",
    "glonass_ephemeris",
    "qzss_ephemeris",
]

#: What a system's records become (a BeiDou or Galileo ephemeris is a :class:`BroadcastEphemeris`).
Ephemeris = BroadcastEphemeris | GlonassEphemeris
#: The file a fix names as an example: the IGS daily mixed navigation file.
_MIXED = "BRDC00IGS_R_<yyyydoy>0000_01D_MN.rnx"
#: Order of the 31 numbers of a RINEX 3 BeiDou record (3 on the first line, 4 on each of 7 more).
_BEIDOU_LAYOUT = kepler_layout("aode", "", "week", "", "accuracy", "health", "tgd", "tgd2", "t_trans", "aodc")
#: Record quantities the BeiDou and QZSS orbit and clock need: ``tgd`` is the group delay of the one
#: signal read (BeiDou TGD1 of B1I, QZSS TGD of L1 C/A).
_TGD_FIELDS = (*KEPLER_CLOCK_FIELDS, "tgd")


def beidou_ephemeris(nav: SystemNav, max_age_s: float) -> tuple[BeidouEphemeris, GroupDelays]:
    """The healthy, complete BeiDou records of ``nav`` as an ephemeris, with the B2I group delay.

    Returns
    -------
    BeidouEphemeris
        Toe/Toc converted from BDT to continuous GPS seconds; ``tgd`` is TGD1.
    GroupDelays
        ``tgd2`` per satellite of the ephemeris, the median over its kept records [s].
    """
    c = nav.columns
    keep = nav.healthy(complete_kepler_records(c, _TGD_FIELDS) & (c["health"] == 0))
    toe = (c["week"][keep] + BDT_WEEK_OFFSET) * SECONDS_PER_WEEK + c["toe"][keep] + GPS_MINUS_BDT_S
    toc = datetime64_to_gps(nav.records.epoch[keep]) + GPS_MINUS_BDT_S
    sats, sat_idx, records = kepler_records(nav.records, c, _TGD_FIELDS, keep, toe, toc)
    eph = BeidouEphemeris(sats, records, source=nav.source, max_age_s=max_age_s)
    return eph, {"tgd2": satellite_medians(sat_idx, c["tgd2"][keep], sats.size)}


#: Order of the numbers of a RINEX 3 Galileo record (3 on the first line, 4 on each further line).
_GALILEO_LAYOUT = kepler_layout("iod", "sources", "week", "", "sisa", "health", "bgd_e5a", "bgd_e5b")
_INAV_CLOCK_BIT, _FNAV_CLOCK_BIT = 1 << 9, 1 << 8  # af0..af2 refer to (E5b, E1) / (E5a, E1)
_INAV_SIGNAL_BITS = 0b101  # E1-B, E5b-I


def galileo_ephemeris(nav: SystemNav, max_age_s: float) -> tuple[GalileoEphemeris, GroupDelays]:
    """The healthy, complete Galileo records of ``nav`` as an ephemeris, one message type per satellite.

    Returns
    -------
    GalileoEphemeris
        Toe/Toc in continuous GPS seconds (the RINEX Galileo week is the GPS
        week); ``tgd`` is BGD(E1,E5b) for I/NAV clocks, BGD(E1,E5a) for F/NAV.
    GroupDelays
        ``bgd_e5a`` and ``bgd_e5b`` per satellite of the ephemeris, medians over its kept
        records [s]; ``bgd_e5b`` NaN for a satellite with F/NAV records only.
    """
    c = nav.columns
    src = np.nan_to_num(c["sources"]).astype(np.int64)
    inav = ((src & _INAV_CLOCK_BIT) != 0) | (((src & _FNAV_CLOCK_BIT) == 0) & ((src & _INAV_SIGNAL_BITS) != 0))
    bgd_e5a = c["bgd_e5a"]
    bgd_e5b = np.where(inav, c["bgd_e5b"], np.nan)  # F/NAV's field holds 0, not a broadcast value
    bgd = np.where(inav, bgd_e5b, bgd_e5a)
    keep = complete_kepler_records(c, KEPLER_CLOCK_FIELDS) & (c["health"] == 0)
    # one message type per satellite, I/NAV first: the two clock models differ by the BGDs
    sv = nav.records.sv
    has_inav = {s for s, ok in zip(sv.tolist(), keep & inav) if ok}
    keep = nav.healthy(keep & (inav | ~np.isin(sv, list(has_inav))))
    toe = c["week"][keep] * SECONDS_PER_WEEK + c["toe"][keep]
    toc = datetime64_to_gps(nav.records.epoch[keep])
    sats, sat_idx, records = kepler_records(nav.records, c, KEPLER_CLOCK_FIELDS, keep, toe, toc)
    records["tgd"] = np.nan_to_num(bgd[keep])
    eph = GalileoEphemeris(sats, records, source=nav.source, max_age_s=max_age_s)
    delays = {
        name: satellite_medians(sat_idx, x[keep], sats.size) for name, x in (("bgd_e5a", bgd_e5a), ("bgd_e5b", bgd_e5b))
    }
    return eph, delays


#: Order of the 15 numbers of a RINEX 3.0x GLONASS record (3.05 appends a line, ignored here).
_GLONASS_LAYOUT = (
    "clock",
    "gamma",
    "t_frame",
    "x",
    "vx",
    "ax",
    "health",
    "y",
    "vy",
    "ay",
    "freq",
    "z",
    "vz",
    "az",
    "age",
)
_KM = 1_000.0


def glonass_ephemeris(nav: SystemNav, max_age_s: float) -> tuple[GlonassEphemeris, GroupDelays]:
    """The healthy, complete GLONASS records of ``nav`` as an ephemeris (no group delays: none in RINEX 3).

    Returns
    -------
    GlonassEphemeris
        tb in continuous GPS seconds (UTC epoch plus the leap seconds), state in
        metres, FDMA channel per satellite.
    GroupDelays
        Empty.

    Raises
    ------
    SimbenchError
        A frequency number outside -7..+13, or no healthy complete record.
    """
    v = nav.columns
    freq = v["freq"]
    bad = np.isfinite(freq) & ((freq != np.round(freq)) | (freq < -7) | (freq > 13))
    if bad.any():
        k = int(np.argmax(bad))
        raise SimbenchError(
            nav.field,
            f"record {nav.records.sv[k]} {nav.records.epoch[k]} has frequency number {freq[k]:g}",
            "GLONASS FDMA channels are whole numbers -7..+13; check the file",
        )
    need = ("clock", "gamma", "x", "vx", "ax", "y", "vy", "ay", "z", "vz", "az", "freq")
    keep = nav.healthy(np.all(np.isfinite(np.stack([v[k] for k in need])), axis=0) & (v["health"] == 0))
    tb = utc_to_gps(nav.records.epoch[keep])
    sats, sat_idx = np.unique(nav.records.sv[keep], return_inverse=True)
    records = {
        "sat": sat_idx,
        "tb": tb,
        "pos": _KM * np.stack([v["x"], v["y"], v["z"]], axis=1)[keep],
        "vel": _KM * np.stack([v["vx"], v["vy"], v["vz"]], axis=1)[keep],
        "acc": _KM * np.stack([v["ax"], v["ay"], v["az"]], axis=1)[keep],
        "clock": v["clock"][keep],
        "gamma": v["gamma"][keep],
        "freq": v["freq"][keep].astype(int),
    }
    return GlonassEphemeris(sats, records, source=nav.source, max_age_s=max_age_s), {}


#: Order of the numbers of a RINEX 3 GPS / QZSS record (3 on the first line, 4 on each of 7 more).
_QZSS_LAYOUT = kepler_layout("iode", "codes_l2", "week", "l2p_flag", "accuracy", "health", "tgd", "iodc")
#: Health bit 0 flags L1C/B (older: LEX), a signal this reader does not use: satellites that do not
#: transmit it set the bit (every J record of the Nagoya file has health 1); RTKLIB masks it too.
_UNUSED_HEALTH_BITS = 1


def qzss_ephemeris(nav: SystemNav, max_age_s: float) -> tuple[BroadcastEphemeris, GroupDelays]:
    """The healthy, complete QZSS records of ``nav`` as an ephemeris (no group delays beside ``tgd``).

    Returns
    -------
    BroadcastEphemeris
        Toe/Toc in continuous GPS seconds; ``tgd`` is the L1 C/A group delay; no Klobuchar
        coefficients (the GPS ones serve every system).
    GroupDelays
        Empty.
    """
    c = nav.columns
    health = np.nan_to_num(c["health"], nan=1.0).astype(np.int64)
    keep = nav.healthy(complete_kepler_records(c, _TGD_FIELDS) & (health & ~_UNUSED_HEALTH_BITS == 0))
    toe = c["week"][keep] * SECONDS_PER_WEEK + c["toe"][keep]
    toc = datetime64_to_gps(nav.records.epoch[keep])
    sats, _, records = kepler_records(nav.records, c, _TGD_FIELDS, keep, toe, toc)
    return BroadcastEphemeris(sats, records, source=nav.source, max_age_s=max_age_s), {}


@dataclass(frozen=True)
class NavSystem:
    """How one system's RINEX 3 navigation records are read."""

    layout: tuple[str, ...]  #: names of the record's numbers, in file order
    setting: str  #: the config setting of the system's own files (named in errors by default)
    fix: str  #: what an error tells the user to pass
    max_age_s: float  #: largest |t - Toe| (GLONASS: |t - tb|) at which a record may be used [s]
    #: (records, max_age_s) -> the ephemeris and the group delays it does not keep
    ephemeris: Callable[[SystemNav, float], tuple[Ephemeris, GroupDelays]]


#: The systems :func:`load_navigation` reads, by RINEX letter.
NAV_SYSTEMS: dict[str, NavSystem] = {
    "C": NavSystem(
        _BEIDOU_LAYOUT,
        "scenario.nav_bds",
        "pass a RINEX 3 BeiDou or mixed navigation file (e.g. hksc1180.19b)",
        FIT_HALF_WINDOW_S,
        beidou_ephemeris,
    ),
    "E": NavSystem(
        _GALILEO_LAYOUT,
        "scenario.nav_gal",
        f"pass a RINEX 3 Galileo or mixed navigation file (e.g. {_MIXED})",
        FIT_HALF_WINDOW_S,
        galileo_ephemeris,
    ),
    "R": NavSystem(
        _GLONASS_LAYOUT,
        "scenario.nav_glo",
        f"pass a RINEX 3 GLONASS or mixed navigation file (e.g. {_MIXED})",
        GLO_MAX_AGE_S,
        glonass_ephemeris,
    ),
    "J": NavSystem(
        _QZSS_LAYOUT,
        "scenario.nav",
        f"pass a RINEX 3 mixed navigation file with QZSS (J) records (e.g. {_MIXED})",
        FIT_HALF_WINDOW_S,
        qzss_ephemeris,
    ),
}


def load_navigation(
    system: str, path: NavPaths, max_age_s: float | None = None, setting: str | None = None
) -> tuple[Ephemeris, GroupDelays]:
    """Read one system's ephemerides and broadcast group delays from RINEX 3 navigation files.

    Parameters
    ----------
    system : str
        RINEX letter of a system of :data:`NAV_SYSTEMS`: C (BeiDou), E (Galileo), R (GLONASS), J (QZSS).
    path : str, PathLike or sequence of them
        RINEX 3 navigation file(s), records merged
        (:func:`~simbench.gnss.navigation.read_rinex3_records`); only ``system``'s records are read,
        and unhealthy or incomplete ones are dropped.
    max_age_s : float, optional
        Largest |t - Toe| (GLONASS: |t - tb|) at which a record may be used [s]; default the
        system's (7200 s, GLONASS 1800 s).
    setting : str, optional
        Config setting that named the files, for error messages; default the system's own
        (``scenario.nav_bds``, ``nav_gal``, ``nav_glo``; QZSS ``scenario.nav``).

    Returns
    -------
    Ephemeris
        Times in continuous GPS seconds; what each system's ``tgd`` is says its conversion
        (:data:`NAV_SYSTEMS`).
    GroupDelays
        The second signals' group delays the ephemeris does not keep (BeiDou ``tgd2``, Galileo
        ``bgd_e5a``/``bgd_e5b``), per satellite of the ephemeris [s]; empty for GLONASS and QZSS.

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 3 navigation data, a malformed record, a GLONASS frequency
        number outside -7..+13, or no healthy record of ``system``.
    """
    spec = NAV_SYSTEMS[system]
    nav = read_system_nav(path, system, spec.layout, setting or spec.setting, spec.fix)
    return spec.ephemeris(nav, spec.max_age_s if max_age_s is None else max_age_s)


def read_navigation(
    system: str, path: NavPaths, max_age_s: float | None = None, setting: str | None = None
) -> Ephemeris:
    """:func:`load_navigation` without the group delays; same parameters and errors."""
    return load_navigation(system, path, max_age_s, setting)[0]
