"""RINEX 3 BeiDou navigation files -> :class:`~simbench.sim.beidou_orbits.BeidouEphemeris`.

The ephemeris computation (CGCS2000 constants, BDT, geostationary rotation)
lives in :mod:`simbench.sim.beidou_orbits`; this module only parses the file
and converts BDT weeks and seconds to continuous GPS seconds.
"""
from __future__ import annotations

import os

import numpy as np

from simbench.errors import SimbenchError
from simbench.sim.beidou_orbits import BDT_WEEK_OFFSET, GPS_MINUS_BDT_S, BeidouEphemeris
from simbench.sim.constants import SECONDS_PER_WEEK
from simbench.sim.gpstime import datetime64_to_gps
from simbench.sim.orbits import FIT_HALF_WINDOW_S

__all__ = ["read_beidou_navigation"]

#: Record quantities the orbit and clock need (``tgd`` is TGD1, the B1I group delay).
_FIELDS = ("af0", "af1", "af2", "crs", "dn", "m0", "cuc", "e", "cus", "sqrta", "cic", "omega0", "cis", "i0",
           "crc", "w", "omegadot", "idot", "tgd")


def read_beidou_navigation(path: str | os.PathLike[str], max_age_s: float = FIT_HALF_WINDOW_S) -> BeidouEphemeris:
    """Read BeiDou ephemerides from a RINEX 3 navigation file.

    An own fixed-column reader: georinex 1.16 returns all-NaN records for
    files whose spare fields are blank (as in ``hksc1180.19b``).

    Parameters
    ----------
    path : str or PathLike
        RINEX 3 navigation file; only ``C`` (BeiDou) records are read, and
        unhealthy or incomplete ones are dropped.
    max_age_s : float
        Largest |t - Toe| at which a record may be used [s]; default 7200.

    Returns
    -------
    BeidouEphemeris
        Toe/Toc converted from BDT to continuous GPS seconds; ``tgd`` is TGD1.

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 3 navigation data, or no healthy BeiDou record.
    """
    p = os.fspath(path)
    field = f"scenario.nav_bds '{p}'"
    fix = "pass a RINEX 3 BeiDou navigation file (e.g. hksc1180.19b)"
    if not os.path.isfile(p):
        raise SimbenchError(field, "file does not exist", fix)
    with open(p, errors="replace") as fh:
        lines = fh.read().splitlines()
    if not lines or lines[0][20:21] != "N" or not lines[0][:9].strip().startswith("3"):
        raise SimbenchError(field, "is not RINEX 3 navigation data", fix)
    body = next((i + 1 for i, ln in enumerate(lines) if "END OF HEADER" in ln), None)
    if body is None:
        raise SimbenchError(field, "has no END OF HEADER line", fix)
    stamps, values = [], []
    i = body
    while i + 7 < len(lines) + 1:  # 8-line records; text parsing is one step per record
        head = lines[i]
        if not head.startswith("C"):
            i += 1
            continue
        rec = [_num(head[23 + 19 * k:42 + 19 * k]) for k in range(3)]
        for ln in lines[i + 1:i + 8]:
            rec += [_num(ln[4 + 19 * k:23 + 19 * k]) for k in range(4)]
        f = head[4:23].split()
        stamps.append(f"{head[:3]} {int(f[0]):04d}-{int(f[1]):02d}-{int(f[2]):02d}T{int(f[3]):02d}:"
                      f"{int(f[4]):02d}:{int(float(f[5])):02d}")
        values.append(rec)
        i += 8
    if not values:
        raise SimbenchError(field, "contains no BeiDou ephemerides", fix)
    a = np.array(values, dtype=float)
    col = {name: k for k, name in enumerate(_LAYOUT) if name}
    v = {key: a[:, col[key]] for key in _FIELDS}
    sv = np.array([st[:3] for st in stamps])
    toc = datetime64_to_gps(np.array([st[4:] for st in stamps], dtype="datetime64[s]")) + GPS_MINUS_BDT_S
    week, toe_sow, health = a[:, col["week"]], a[:, col["toe"]], a[:, col["health"]]
    keep = np.all(np.isfinite(np.stack(list(v.values()))), axis=0) & np.isfinite(week) & np.isfinite(toe_sow) \
        & (health == 0) & (v["sqrta"] > 1000.0)
    if not keep.any():
        raise SimbenchError(field, "has no complete healthy BeiDou record", fix)
    toe = (week[keep] + BDT_WEEK_OFFSET) * SECONDS_PER_WEEK + toe_sow[keep] + GPS_MINUS_BDT_S
    toc = toc[keep]
    toe += SECONDS_PER_WEEK * np.round((toc - toe) / SECONDS_PER_WEEK)
    sats, sat_idx = np.unique(sv[keep], return_inverse=True)
    records = {k: x[keep] for k, x in v.items()}
    records.update(sat=sat_idx, toe=toe, toc=toc)
    return BeidouEphemeris(sats, records, source=os.path.basename(p), max_age_s=max_age_s)


#: Order of the 31 numbers of a RINEX 3 BeiDou record (3 on the first line, 4 on each of 7 more).
_LAYOUT = ("af0", "af1", "af2", "aode", "crs", "dn", "m0", "cuc", "e", "cus", "sqrta", "toe", "cic", "omega0",
           "cis", "i0", "crc", "w", "omegadot", "idot", "", "week", "", "accuracy", "health", "tgd", "tgd2",
           "t_trans", "aodc")


def _num(text: str) -> float:
    text = text.strip().replace("D", "E").replace("d", "e")
    return float(text) if text else np.nan
