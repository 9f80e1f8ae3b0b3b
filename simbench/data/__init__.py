"""Real GNSS logs as scenarios: RINEX 3 with broadcast ephemeris (GPS, BeiDou), libRSF text, references.

:func:`load_rinex` and :func:`load_librsf` return a :class:`~simbench.contract.Scenario`
with the simulator's observation columns, ``labels=None`` and an empty IMU
table; :func:`simbench.scenarios.build_scenario` calls them for
``scenario.source=rinex`` / ``librsf``.
"""
from __future__ import annotations

from simbench.data.beidou import BeidouEphemeris
from simbench.data.librsf import LibrsfLog, load_librsf, read_librsf, write_synthetic_librsf
from simbench.data.reference import Reference, match_reference, read_reference, truth_table
from simbench.data.rinex import RinexObs, load_rinex, read_rinex_obs

__all__ = ["BeidouEphemeris", "LibrsfLog", "load_librsf", "read_librsf", "write_synthetic_librsf", "Reference",
           "match_reference", "read_reference", "truth_table", "RinexObs", "load_rinex", "read_rinex_obs"]
