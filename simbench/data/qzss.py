"""RINEX 3 QZSS navigation records -> :class:`~simbench.core.orbits.BroadcastEphemeris`.

QZSS broadcasts the GPS LNAV message layout on L1 C/A (IS-QZSS-PNT 4.1.2): the
same Keplerian set, clock polynomial and TGD, in GPS time and GPS weeks, with
the WGS-84 / GPS constants, so the IS-GPS-200 user algorithm of
:class:`~simbench.core.orbits.BroadcastEphemeris` computes its satellites. The
records come from the shared reader :func:`simbench.gnss.navigation.read_rinex3_records`
(QZSS-only or mixed files, several merged).
"""

from __future__ import annotations

import numpy as np

from simbench.core.constants import SECONDS_PER_WEEK
from simbench.core.gpstime import datetime64_to_gps
from simbench.core.orbits import FIT_HALF_WINDOW_S, BroadcastEphemeris
from simbench.gnss.navigation import (
    KEPLER_CLOCK_FIELDS,
    NavPaths,
    complete_kepler_records,
    kepler_layout,
    kepler_records,
    read_system_nav,
)

__all__ = ["read_qzss_navigation"]

#: Order of the numbers of a RINEX 3 GPS / QZSS record (3 on the first line, 4 on each of 7 more).
_LAYOUT = kepler_layout("iode", "codes_l2", "week", "l2p_flag", "accuracy", "health", "tgd", "iodc")
#: Health bit 0 flags L1C/B (older: LEX), a signal this reader does not use: satellites that do not
#: transmit it set the bit (every J record of the Nagoya file has health 1); RTKLIB masks it too.
_UNUSED_HEALTH_BITS = 1
#: Record quantities the orbit and clock need.
_FIELDS = (*KEPLER_CLOCK_FIELDS, "tgd")


def read_qzss_navigation(
    path: NavPaths,
    max_age_s: float = FIT_HALF_WINDOW_S,
    setting: str = "scenario.nav",
) -> BroadcastEphemeris:
    """Read QZSS ephemerides from RINEX 3 navigation files (QZSS-only or mixed), records merged.

    Parameters
    ----------
    path : str, PathLike or sequence of them
        RINEX 3 navigation file(s); only ``J`` records are read, and unhealthy or
        incomplete ones are dropped.
    max_age_s : float
        Largest |t - Toe| at which a record may be used [s]; default 7200.
    setting : str
        Config setting that named the files, for error messages.

    Returns
    -------
    BroadcastEphemeris
        Toe/Toc in continuous GPS seconds; ``tgd`` is the L1 C/A group delay; no Klobuchar
        coefficients (the GPS ones serve every system).

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 3 navigation data, a malformed record, no healthy QZSS
        record.
    """
    fix = "pass a RINEX 3 mixed navigation file with QZSS (J) records (e.g. BRDC00IGS_R_<yyyydoy>0000_01D_MN.rnx)"
    nav = read_system_nav(path, "J", _LAYOUT, setting, fix)
    c = nav.columns
    health = np.nan_to_num(c["health"], nan=1.0).astype(np.int64)
    keep = nav.healthy(complete_kepler_records(c, _FIELDS) & (health & ~_UNUSED_HEALTH_BITS == 0))
    toe = c["week"][keep] * SECONDS_PER_WEEK + c["toe"][keep]
    toc = datetime64_to_gps(nav.records.epoch[keep])
    sats, _, records = kepler_records(nav.records, c, _FIELDS, keep, toe, toc)
    return BroadcastEphemeris(sats, records, source=nav.source, max_age_s=max_age_s)
