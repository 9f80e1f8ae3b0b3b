"""RINEX 3 BeiDou navigation files -> :class:`~simbench.core.beidou_orbits.BeidouEphemeris`.

The ephemeris computation (CGCS2000 constants, BDT, geostationary rotation)
lives in :mod:`simbench.core.beidou_orbits`; the records come from the shared
RINEX 3 reader :func:`simbench.gnss.navigation.read_rinex3_records`; this
module picks the fields and converts BDT weeks and seconds to continuous GPS seconds.
"""

from __future__ import annotations

import os

import numpy as np

from simbench.core.beidou_orbits import BDT_WEEK_OFFSET, GPS_MINUS_BDT_S, BeidouEphemeris
from simbench.core.constants import SECONDS_PER_WEEK
from simbench.core.gpstime import datetime64_to_gps
from simbench.core.orbits import FIT_HALF_WINDOW_S
from simbench.errors import SimbenchError
from simbench.gnss.navigation import NavPaths, check_coverage, files_field, nav_paths, read_rinex3_records

__all__ = ["read_beidou_navigation"]

#: Record quantities the orbit and clock need (``tgd`` is TGD1, the B1I group delay).
_FIELDS = (
    "af0",
    "af1",
    "af2",
    "crs",
    "dn",
    "m0",
    "cuc",
    "e",
    "cus",
    "sqrta",
    "cic",
    "omega0",
    "cis",
    "i0",
    "crc",
    "w",
    "omegadot",
    "idot",
    "tgd",
)


def read_beidou_navigation(
    path: NavPaths,
    max_age_s: float = FIT_HALF_WINDOW_S,
    setting: str = "scenario.nav_bds",
    span: tuple[float, float] | None = None,
) -> BeidouEphemeris:
    """Read BeiDou ephemerides from a RINEX 3 navigation file (BeiDou-only or mixed).

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
    span : tuple of float, optional
        First and last observation epoch [s, continuous GPS] that the records must cover
        (:func:`~simbench.gnss.navigation.check_coverage`).

    Returns
    -------
    BeidouEphemeris
        Toe/Toc converted from BDT to continuous GPS seconds; ``tgd`` is TGD1.

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 3 navigation data, or no healthy BeiDou record.
    """
    paths = nav_paths(path)
    fix = "pass a RINEX 3 BeiDou or mixed navigation file (e.g. hksc1180.19b)"
    field = files_field(setting, paths)
    nav = read_rinex3_records(paths, "C", setting, fix)
    a = nav.values
    if a.shape[1] < len(_LAYOUT):
        raise SimbenchError(field, f"has BeiDou records of {a.shape[1]} numbers, not {len(_LAYOUT)}", fix)
    col = {name: k for k, name in enumerate(_LAYOUT) if name}
    v = {key: a[:, col[key]] for key in _FIELDS}
    toc = datetime64_to_gps(nav.epoch) + GPS_MINUS_BDT_S
    week, toe_sow, health = a[:, col["week"]], a[:, col["toe"]], a[:, col["health"]]
    keep = (
        np.all(np.isfinite(np.stack(list(v.values()))), axis=0)
        & np.isfinite(week)
        & np.isfinite(toe_sow)
        & (health == 0)
        & (v["sqrta"] > 1000.0)
    )
    if not keep.any():
        raise SimbenchError(field, "has no complete healthy BeiDou record", fix)
    toe = (week[keep] + BDT_WEEK_OFFSET) * SECONDS_PER_WEEK + toe_sow[keep] + GPS_MINUS_BDT_S
    toc = toc[keep]
    toe += SECONDS_PER_WEEK * np.round((toc - toe) / SECONDS_PER_WEEK)
    check_coverage(toe, max_age_s, span, field, "C")
    sats, sat_idx = np.unique(nav.sv[keep], return_inverse=True)
    records = {k: x[keep] for k, x in v.items()}
    records.update(sat=sat_idx, toe=toe, toc=toc)
    return BeidouEphemeris(sats, records, source=", ".join(os.path.basename(p) for p in paths), max_age_s=max_age_s)


#: Order of the 31 numbers of a RINEX 3 BeiDou record (3 on the first line, 4 on each of 7 more).
_LAYOUT = (
    "af0",
    "af1",
    "af2",
    "aode",
    "crs",
    "dn",
    "m0",
    "cuc",
    "e",
    "cus",
    "sqrta",
    "toe",
    "cic",
    "omega0",
    "cis",
    "i0",
    "crc",
    "w",
    "omegadot",
    "idot",
    "",
    "week",
    "",
    "accuracy",
    "health",
    "tgd",
    "tgd2",
    "t_trans",
    "aodc",
)
