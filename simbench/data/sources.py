"""Real logs as scenario sources: ``scenario.source=rinex`` and ``librsf``.

Each has its own ``Config`` (the typed ``scenario`` node of
``conf/scenario/rinex.yaml`` and ``librsf.yaml``) and checks the files it needs
before any is read: the observation file, for RINEX the reference trajectory and
a navigation file for every system of ``systems``.
"""

from __future__ import annotations

from dataclasses import dataclass

from simbench.contract import Scenario
from simbench.data.librsf import load_librsf
from simbench.data.rinex import NAV_SETTINGS, load_rinex
from simbench.errors import SimbenchError
from simbench.gnss.navigation import SYSTEM_NAMES, read_rinex_lines
from simbench.source import DataConfig, Source, SourceConfig, scenario_config

__all__ = ["RinexConfig", "LibrsfConfig", "RinexSource", "LibrsfSource", "nav_header_system"]


@dataclass
class RinexConfig(SourceConfig):
    """A RINEX 3 log with broadcast ephemeris and a reference trajectory (:func:`simbench.data.rinex.load_rinex`)."""

    name: str = "rinex"
    source: str = "rinex"
    obs: str = ""  #: RINEX 3 observation file
    #: RINEX GPS navigation file covering the observations, or a mixed RINEX 3
    #: file (type M) that also serves the systems below without a file of their own
    nav: str = ""
    nav_bds: str = ""  #: RINEX 3 BeiDou navigation file (when ``systems`` has C)
    nav_glo: str = ""  #: RINEX 3 GLONASS navigation file (when ``systems`` has R)
    nav_gal: str = ""  #: RINEX 3 Galileo navigation file (when ``systems`` has E)
    truth: str = ""  #: reference trajectory: 'week,TOW,lat,lon,h' CSV or 'SOW X Y Z' (GPS time)
    #: systems to ingest, letters of GREC: G (GPS L1 C/A), R (GLONASS L1 C/A), E (Galileo E1), C (BeiDou B1I)
    systems: str = "G"
    truth_max_gap_s: float = 2.0  #: reference samples further apart are not interpolated [s]


@dataclass
class LibrsfConfig(SourceConfig):
    """A libRSF GNSS text file (:func:`simbench.data.librsf.load_librsf`)."""

    name: str = "librsf"
    source: str = "librsf"
    obs: str = ""  #: libRSF GNSS text file
    #: reference: a libRSF point3 file, a 'week,TOW,lat,lon,h' CSV or 'SOW X Y Z'; '' the point3 lines of ``obs``
    truth: str = ""
    gps_week: int = 2032  #: GPS week of file time 0 (the format has no absolute time)
    start_sow_s: float = 475_200.0  #: GPS seconds of week of file time 0 [s]
    truth_max_gap_s: float = 2.0  #: reference samples further apart are not interpolated [s]


class RinexSource(Source):
    """A real RINEX 3 log (GPS, GLONASS, Galileo, BeiDou) scored against its reference trajectory."""

    name = "rinex"
    Config = RinexConfig

    def check(self, cfg: DataConfig) -> None:
        s = scenario_config(cfg, RinexConfig)
        super().check(cfg)
        require_files(s, ("obs", "truth"))
        check_systems(s)

    def load(self, cfg: DataConfig) -> Scenario:
        s = scenario_config(cfg, RinexConfig)
        return load_rinex(
            s.obs,
            s.nav,
            s.truth,
            systems=s.systems,
            nav_bds_path=s.nav_bds,
            nav_glo_path=s.nav_glo,
            nav_gal_path=s.nav_gal,
            name=s.name,
            truth_max_gap_s=s.truth_max_gap_s,
        )


class LibrsfSource(Source):
    """A real libRSF GNSS text file (smartLoc, Chemnitz City): pre-corrected pseudoranges and odometry."""

    name = "librsf"
    Config = LibrsfConfig

    def check(self, cfg: DataConfig) -> None:
        s = scenario_config(cfg, LibrsfConfig)
        super().check(cfg)
        require_files(s, ("obs",))

    def load(self, cfg: DataConfig) -> Scenario:
        s = scenario_config(cfg, LibrsfConfig)
        return load_librsf(
            s.obs,
            s.truth or None,
            gps_week=s.gps_week,
            start_sow_s=s.start_sow_s,
            name=s.name,
            truth_max_gap_s=s.truth_max_gap_s,
        )


def require_files(s: SourceConfig, keys: tuple[str, ...]) -> None:
    """Raise a one-line error for each of ``keys`` (file settings of ``s``) left empty."""
    for key in keys:
        if not getattr(s, key):
            raise SimbenchError(
                f"scenario.{key}",
                f"no file given for a {s.source} scenario",
                f"set it on the command line, e.g. scenario.{key}=path/to/file",
            )


def nav_header_system(path: str) -> str:
    """System letter of a RINEX navigation file's header ('M' mixed, 'G', 'R', ...), '' if unreadable.

    The file may be compressed (:func:`~simbench.gnss.navigation.read_rinex_lines`); an unreadable one
    is left to the navigation reader, whose error names the problem.
    """
    try:
        lines = read_rinex_lines(path, f"scenario.nav '{path}'", "pass a RINEX navigation file")
    except (OSError, SimbenchError):
        return ""
    first = lines[0] if lines else ""
    if first[:9].strip().startswith("3") and first[20:21] == "N":
        return first[40:41]
    return {"N": "G", "G": "R"}.get(first[20:21], "")  # RINEX 2: N is GPS, G is GLONASS


def check_systems(s: RinexConfig) -> None:
    """Known system letters, and navigation data named for each: its own file or a mixed ``nav``."""
    letters = "".join(NAV_SETTINGS)
    unknown = sorted(set(s.systems) - set(letters))
    if unknown or not s.systems:
        raise SimbenchError(
            "scenario.systems",
            f"'{s.systems}' has " + (f"unknown letters {''.join(unknown)}" if unknown else "no letters"),
            f"use letters of {letters} (GPS, GLONASS, Galileo, BeiDou), e.g. scenario.systems=GE",
        )
    nav_kind = nav_header_system(s.nav) if s.nav else ""
    for letter in dict.fromkeys(s.systems):
        key = NAV_SETTINGS[letter]
        if getattr(s, key) or (letter != "G" and nav_kind in ("M", letter)):
            continue
        raise SimbenchError(
            f"scenario.{key}",
            f"no {SYSTEM_NAMES[letter]} navigation file for scenario.systems='{s.systems}'",
            f"set scenario.{key}=path/to/file" + ("" if letter == "G" else ", or scenario.nav to a mixed RINEX 3 file"),
        )
