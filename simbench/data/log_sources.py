"""Real logs as scenario sources: ``scenario.source=rinex``, ``gnsslogger`` and ``librsf``.

Each has its own ``Config`` (the typed ``scenario`` node of
``conf/scenario/rinex.yaml``, ``gnsslogger.yaml`` and ``librsf.yaml``; named logs such as
``hk_tst_2019.yaml`` are presets of the same node) and checks the files it needs
before any is read: the observation file, for RINEX the navigation files, the
reference trajectory (or point), and navigation data for every system of ``systems``; each
named file must exist (:func:`~simbench.paths.require_file`), so a preset whose data home is
missing stops before any job, naming the setting, the path tried and ``SIMBENCH_DATA``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simbench.contract import Scenario
from simbench.data.gnsslogger import load_gnsslogger
from simbench.data.librsf import load_librsf
from simbench.data.reference import is_point
from simbench.data.rinex import NAV_SETTINGS, LogInputs, load_rinex_log
from simbench.errors import SimbenchError
from simbench.gnss.navigation import SYSTEM_NAMES, nav_header_system, nav_paths
from simbench.paths import require_file
from simbench.source_registry import DataConfig, Source, SourceConfig, check_source_config, scenario_config

__all__ = ["RinexConfig", "GnssLoggerConfig", "LibrsfConfig", "RinexSource", "GnssLoggerSource", "LibrsfSource"]


@dataclass
class RinexConfig(SourceConfig):
    """A RINEX 3 log with broadcast ephemeris and a reference trajectory (:func:`simbench.data.rinex.load_rinex`).

    Each navigation setting takes one file or a list of files (``scenario.nav=[a.20n,b.20n]``,
    a YAML list), mixed or per system; their records are merged (typed ``Any``: OmegaConf
    has no ``str | list[str]``; :func:`~simbench.gnss.navigation.nav_paths` reads both).
    """

    #: the scenario's name in result tables; '' names it after the observation file (its stem)
    name: str = ""
    source: str = "rinex"
    obs: str = ""  #: RINEX 3 observation file
    #: RINEX GPS navigation file(s) covering the observations, or mixed RINEX 3
    #: file(s) (type M) that also serve the systems below without files of their own, and QZSS
    nav: Any = ""
    nav_bds: Any = ""  #: RINEX 3 BeiDou navigation file(s) (when ``systems`` has C)
    nav_glo: Any = ""  #: RINEX 3 GLONASS navigation file(s) (when ``systems`` has R)
    nav_gal: Any = ""  #: RINEX 3 Galileo navigation file(s) (when ``systems`` has E)
    #: reference: a trajectory ('week,TOW,lat,lon,h' CSV or 'SOW X Y Z', GPS time), or a static
    #: antenna's one point 'lat,lon,h' (deg, deg, ellipsoidal m) or 'x,y,z' (ECEF m), or a file of that point
    truth: str = ""
    #: systems to ingest, letters of GRECJ: G (GPS L1 C/A), R (GLONASS L1 C/A), E (Galileo E1),
    #: C (BeiDou B1I: C1I in RINEX 3.02, C2I in 3.03+), J (QZSS L1 C/A, GPS-like navigation from ``nav``);
    #: each with its second frequency where the file has one (:data:`simbench.data.rinex.SECOND_SIGNALS`)
    systems: str = "G"
    truth_max_gap_s: float = 2.0  #: reference samples further apart are not interpolated [s]


@dataclass
class GnssLoggerConfig(RinexConfig):
    """An Android GnssLogger log (:func:`simbench.data.gnsslogger.load_gnsslogger`): ``obs`` is the
    GnssLogger text file (its ``Raw`` lines); navigation files, reference and systems as for RINEX
    (the phone's log carries no ephemerides)."""

    source: str = "gnsslogger"


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


def check_rinex(cfg: DataConfig) -> None:
    """The RINEX (and GnssLogger) source's check, before any file is read: the bounds and choices, every
    named file present, and navigation data for every system of ``scenario.systems``."""
    s = scenario_config(cfg, RinexConfig)
    check_source_config(cfg)
    require_files(s, ("obs", "nav", "truth"))
    require_file("scenario.obs", s.obs)
    for key in dict.fromkeys(NAV_SETTINGS.values()):
        for path in nav_paths(getattr(s, key)):
            require_file(f"scenario.{key}", path)
    if not is_point(s.truth):
        require_file("scenario.truth", s.truth)
    check_systems(s)


def check_librsf(cfg: DataConfig) -> None:
    """The libRSF source's check, before any file is read: the bounds and choices, the files present."""
    s = scenario_config(cfg, LibrsfConfig)
    check_source_config(cfg)
    require_files(s, ("obs",))
    require_file("scenario.obs", s.obs)
    if s.truth:
        require_file("scenario.truth", s.truth)


class RinexSource(Source):
    """A real RINEX 3 log (GPS, GLONASS, Galileo, BeiDou) scored against its reference trajectory."""

    name = "rinex"
    Config = RinexConfig
    #: reads the observation file and builds the scenario; a raw format of its own overrides it (same arguments)
    loader = staticmethod(load_rinex_log)

    # a function, not a method: the command line's door runs it from its schema record without the source
    check = staticmethod(check_rinex)

    def label(self, cfg: DataConfig) -> str:
        s = scenario_config(cfg, RinexConfig)
        return s.name or Path(s.obs).stem

    def input_files(self, cfg: DataConfig) -> dict[str, tuple[str, ...]]:
        s = scenario_config(cfg, RinexConfig)
        files = {f"scenario.{key}": nav_paths(getattr(s, key)) for key in dict.fromkeys(NAV_SETTINGS.values())}
        return {"scenario.obs": (s.obs,), **files, "scenario.truth": () if is_point(s.truth) else (s.truth,)}

    def load(self, cfg: DataConfig) -> Scenario:
        s = scenario_config(cfg, RinexConfig)
        inputs = LogInputs(
            s.nav, s.truth, s.systems, s.nav_bds, s.nav_glo, s.nav_gal, self.label(cfg), s.truth_max_gap_s
        )
        return self.loader(s.obs, inputs)


class GnssLoggerSource(RinexSource):
    """An Android GnssLogger "Raw" log (Google Smartphone Decimeter Challenge format) scored against its reference."""

    name = "gnsslogger"
    Config = GnssLoggerConfig

    loader = staticmethod(load_gnsslogger)


class LibrsfSource(Source):
    """A real libRSF GNSS text file (smartLoc, Chemnitz City): pre-corrected pseudoranges and odometry."""

    name = "librsf"
    Config = LibrsfConfig

    check = staticmethod(check_librsf)

    def input_files(self, cfg: DataConfig) -> dict[str, tuple[str, ...]]:
        s = scenario_config(cfg, LibrsfConfig)
        return {"scenario.obs": (s.obs,), "scenario.truth": (s.truth,) if s.truth else ()}

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


#: An example value of each file setting, for the error that asks for it.
_EXAMPLES = {"obs": "a.obs", "nav": "a.20n (or [a.20n,b.20n])", "truth": "ref.csv (or lat,lon,h)"}

#: Examples of a source whose files look otherwise.
_SOURCE_EXAMPLES = {"gnsslogger": {"obs": "gnss_log.txt"}}


def require_files(s: SourceConfig, keys: tuple[str, ...]) -> None:
    """Raise a one-line error naming the first of ``keys`` (file settings of ``s``) left empty, with an example
    command that sets every missing one."""
    missing = [key for key in keys if not getattr(s, key)]
    if missing:
        examples = _EXAMPLES | _SOURCE_EXAMPLES.get(s.source, {})
        example = " ".join(f"scenario.{k}={examples.get(k, 'path/to/file').split(' ')[0]}" for k in missing)
        raise SimbenchError(
            f"scenario.{missing[0]}",
            f"no file given for a {s.source} scenario (missing: {', '.join(missing)})",
            f"set it on the command line, e.g. python -m simbench scenario={s.source} {example}",
        )


def check_systems(s: RinexConfig) -> None:
    """Known system letters, and navigation data named for each: its own files or a mixed ``nav``."""
    letters = "".join(NAV_SETTINGS)
    unknown = sorted(set(s.systems) - set(letters))
    if unknown or not s.systems:
        raise SimbenchError(
            "scenario.systems",
            f"'{s.systems}' has " + (f"unknown letters {''.join(unknown)}" if unknown else "no letters"),
            f"use letters of {letters} (GPS, GLONASS, Galileo, BeiDou, QZSS), e.g. scenario.systems=GE",
        )
    nav_kinds = {nav_header_system(p) for p in nav_paths(s.nav)}
    for letter in dict.fromkeys(s.systems):
        key = NAV_SETTINGS[letter]
        # GPS reads scenario.nav itself; the others their own files, else a mixed (or their own) nav file
        served = bool(nav_paths(s.nav)) if letter == "G" else bool(nav_kinds & {"M", letter})
        if served or (key != "nav" and nav_paths(getattr(s, key))):
            continue
        raise SimbenchError(
            f"scenario.{key}",
            f"no {SYSTEM_NAMES[letter]} navigation file for scenario.systems='{s.systems}'",
            {
                "G": "set scenario.nav=path/to/file",
                "J": "add a QZSS or mixed RINEX 3 file to scenario.nav, e.g. scenario.nav=[a.20n,a.20q]",
            }.get(letter, f"set scenario.{key}=path/to/file, or scenario.nav to a mixed RINEX 3 file"),
        )
