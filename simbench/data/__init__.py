"""File readers and real GNSS logs as scenarios: RINEX 3 with broadcast ephemeris, Android
GnssLogger Raw logs, libRSF text, reference trajectories, SP3 orbits, RTKLIB solutions; and the
writers of those formats (:mod:`simbench.data.export`). Beside :mod:`simbench.sim`, never importing it.

:func:`load_rinex`, :func:`load_gnsslogger` and :func:`load_librsf` return a
:class:`~simbench.contract.Scenario` with the simulator's observation columns, ``labels=None`` and
an empty IMU table; :mod:`simbench.data.log_sources` makes them the scenario sources
``scenario.source=rinex`` / ``gnsslogger`` / ``librsf`` (:mod:`simbench.source_registry`), and
:mod:`simbench.data.logs` holds the raw-log -> scenario steps they share.
"""

from __future__ import annotations

from simbench.data.broadcast import load_navigation, read_navigation
from simbench.data.gnsslogger import load_gnsslogger, read_gnsslogger
from simbench.data.librsf import LibrsfLog, load_librsf, read_librsf, write_synthetic_librsf
from simbench.data.reference import Reference, match_reference, read_reference, truth_table
from simbench.data.rinex import RinexObs, load_rinex, read_rinex_obs
from simbench.data.sp3 import Sp3Orbits, read_sp3

__all__ = [
    "load_navigation",
    "read_navigation",
    "load_gnsslogger",
    "read_gnsslogger",
    "LibrsfLog",
    "load_librsf",
    "read_librsf",
    "write_synthetic_librsf",
    "Reference",
    "match_reference",
    "read_reference",
    "truth_table",
    "RinexObs",
    "load_rinex",
    "read_rinex_obs",
    "Sp3Orbits",
    "read_sp3",
]
