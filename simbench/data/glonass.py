"""RINEX 3 GLONASS navigation records -> :class:`~simbench.core.glonass_orbits.GlonassEphemeris`.

The records come from the shared reader
:func:`simbench.gnss.navigation.read_rinex3_records` (GLONASS-only or mixed
files); the numerical integration is in :mod:`simbench.core.glonass_orbits`.
RINEX 3 gives the record epoch (tb) in UTC, the clock as -TauN and +GammaN,
and the state in km, km/s and km/s^2.
"""

from __future__ import annotations

import numpy as np

from simbench.core.glonass_orbits import GLO_MAX_AGE_S, GlonassEphemeris
from simbench.core.gpstime import utc_to_gps
from simbench.errors import SimbenchError
from simbench.gnss.navigation import (
    NavPaths,
    read_system_nav,
)

__all__ = ["read_glonass_navigation"]

#: Order of the 15 numbers of a RINEX 3.0x GLONASS record (3.05 appends a line, ignored here).
_LAYOUT = ("clock", "gamma", "t_frame", "x", "vx", "ax", "health", "y", "vy", "ay", "freq", "z", "vz", "az", "age")
_KM = 1_000.0


def read_glonass_navigation(
    path: NavPaths,
    max_age_s: float = GLO_MAX_AGE_S,
    setting: str = "scenario.nav_glo",
) -> GlonassEphemeris:
    """Read GLONASS ephemerides from a RINEX 3 navigation file (GLONASS-only or mixed).

    Parameters
    ----------
    path : str, PathLike or sequence of them
        RINEX 3 navigation file(s), records merged
        (:func:`~simbench.gnss.navigation.read_rinex3_records`); only ``R`` records are read, and unhealthy or
        incomplete ones are dropped.
    max_age_s : float
        Largest |t - tb| at which a record may be used [s]; default 1800.
    setting : str
        Config setting that named the file, for error messages.

    Returns
    -------
    GlonassEphemeris
        tb in continuous GPS seconds (UTC epoch plus the leap seconds), state in
        metres, FDMA channel per satellite.

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 3 navigation data, a malformed record, a
        frequency number outside -7..+13, or no healthy GLONASS record.
    """
    fix = "pass a RINEX 3 GLONASS or mixed navigation file (e.g. BRDC00IGS_R_<yyyydoy>0000_01D_MN.rnx)"
    nav = read_system_nav(path, "R", _LAYOUT, setting, fix)
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
    return GlonassEphemeris(sats, records, source=nav.source, max_age_s=max_age_s)
