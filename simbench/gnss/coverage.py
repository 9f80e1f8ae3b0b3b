"""Whether broadcast records serve the observations: checked per satellite at the epochs it is observed.

A navigation file need not cover the whole observation span of every system: a station's file
holds the records its receiver decoded, so a system may have hours without records in which none
of its satellites is observed (issue 44). What matters is each observed satellite at each epoch
it is observed: a record of that satellite within the ephemeris' validity (Toe +- 2 h, GLONASS
tb +- 30 min; the same selection :meth:`~simbench.core.orbits.BroadcastEphemeris.select_records`
makes when the states are computed). :func:`check_coverage` tells three cases apart:

* at some epoch at which satellites of the system that have records are observed, no record of
  the system (of any satellite) is valid: the files have a gap there, or are of another day when
  no such epoch is served: an error;
* a satellite has no healthy record at all, or none near some epochs at which other satellites
  of its system are served (unhealthy for a while): its rows are left out with a warning;
* everything else is served.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simbench.core.constants import SECONDS_PER_WEEK
from simbench.core.glonass_orbits import GlonassEphemeris
from simbench.core.gpstime import day_of_year, format_gps_time
from simbench.core.orbits import BroadcastEphemeris
from simbench.errors import SimbenchError, warn
from simbench.gnss.navigation import SYSTEM_NAMES, files_field

__all__ = ["check_coverage"]

#: Satellites a message names before it says how many more there are.
_LISTED = 8


def check_coverage(
    eph: BroadcastEphemeris | GlonassEphemeris,
    t_epoch: np.ndarray,
    row_epoch: np.ndarray,
    row_sat: np.ndarray,
    setting: str,
    paths: Sequence[str],
) -> np.ndarray:
    """Which observed rows of one system a record serves; refuse a file gap, warn about satellites left out.

    Parameters
    ----------
    eph : BroadcastEphemeris or GlonassEphemeris
        The system's ephemeris (``sats`` sorted, as the readers build it).
    t_epoch : np.ndarray, shape (n,)
        Time tag of every epoch at which records are selected, continuous GPS seconds [s].
    row_epoch : np.ndarray of int, shape (N,)
        Epoch (index into ``t_epoch``) of each observed row of the system (rows with a code).
    row_sat : np.ndarray of str, shape (N,)
        Satellite of each row (``'J02'``).
    setting : str
        The setting whose files were read (``scenario.nav``), for messages.
    paths : sequence of str
        Those files.

    Returns
    -------
    np.ndarray of bool, shape (N,)
        Rows whose satellite has a record within ``eph.max_age_s`` of the row's epoch.

    Raises
    ------
    SimbenchError
        When at some epoch at which satellites of the system that have records are observed no
        record of the system is valid: naming the first such stretch, or, when no epoch is served,
        the records' span and the observation day (navigation files of another day).

    Warns
    -----
    SimbenchWarning
        Satellites without a healthy record, and satellites not served at epochs at which others
        of their system are: their rows are left out.
    """
    if not row_sat.size:
        return np.zeros(0, bool)
    system = str(row_sat[0])[:1]
    name, field = SYSTEM_NAMES.get(system, system), files_field(setting, paths)
    col = np.minimum(np.searchsorted(eph.sats, row_sat), eph.sats.size - 1)
    known = eph.sats[col] == row_sat
    epochs, row_k = np.unique(row_epoch, return_inverse=True)
    valid = eph.select_records(t_epoch[epochs]) >= 0  # (epoch, satellite of the ephemeris)
    covered = known & valid[row_k, col]
    served = np.any(valid, axis=1)  # some record of the system is valid then, observed satellite or not
    observed = np.bincount(row_k, weights=known, minlength=epochs.size) > 0  # one with records observed
    if (observed & ~served).any():
        raise _gap_error(eph, t_epoch[epochs[observed]], served[observed], name, field, setting)
    if covered.any():  # else the caller leaves the system out, with one note for it
        _warn_left_out(row_sat, row_epoch, t_epoch, ~known, "no healthy record in the file(s)", name, field)
        age = f"no record within {eph.max_age_s / 3600.0:g} h of these rows' epochs (other {name} satellites have one)"
        _warn_left_out(row_sat, row_epoch, t_epoch, known & ~covered, age, name, field)
    return covered


def _gap_error(
    eph: BroadcastEphemeris | GlonassEphemeris,
    t: np.ndarray,
    served: np.ndarray,
    name: str,
    field: str,
    setting: str,
) -> SimbenchError:
    """The error for the observed epochs (times ``t``) that no record of the system serves (``~served``)."""
    if not served.any():
        records = f"{format_gps_time(eph.t_coverage[0])} .. {format_gps_time(eph.t_coverage[1])} GPS"
        week = int(t[0] // SECONDS_PER_WEEK)
        day, doy = format_gps_time(float(t[0]))[:10], int(day_of_year(week, float(t[0]) - week * SECONDS_PER_WEEK))
        return SimbenchError(
            field,
            f"its {name} records serve {records}, none of the {t.size} epochs at which {name} is observed "
            f"({format_gps_time(float(t[0]))} .. {format_gps_time(float(t[-1]))} GPS)",
            f"pass the navigation file(s) of the observation day, {day} (day of year {doy:03d})",
        )
    first = int(np.argmin(served))
    later = np.flatnonzero(served[first:])
    last = first + (int(later[0]) if later.size else served.size - first) - 1  # the end of the first stretch
    return SimbenchError(
        field,
        f"has no {name} record (of any satellite) within {eph.max_age_s / 3600.0:g} h of {int((~served).sum())} "
        f"epochs at which {name} satellites are observed, first {format_gps_time(float(t[first]))} .. "
        f"{format_gps_time(float(t[last]))} GPS",
        f"add the navigation file(s) of that time, e.g. {setting}=[a.rnx,b.rnx]",
    )


def _warn_left_out(
    row_sat: np.ndarray, row_epoch: np.ndarray, t_epoch: np.ndarray, out: np.ndarray, why: str, name: str, field: str
) -> None:
    """One warning naming the satellites of the rows ``out`` and why they are left out."""
    if not out.any():
        return
    sats = np.unique(row_sat[out]).tolist()
    listed = ", ".join(sats[:_LISTED]) + (f" and {len(sats) - _LISTED} more" if len(sats) > _LISTED else "")
    first = format_gps_time(float(t_epoch[row_epoch[out].min()]))
    warn(
        field,
        f"{name} satellites {listed}: {why}; {int(out.sum())} observed rows, the first at {first} GPS",
        "those rows are left out",
    )
