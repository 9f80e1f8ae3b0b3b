"""RINEX 3 observation ingest: a real receiver log as a :class:`~simbench.contract.Scenario`.

The observation table gets exactly the simulator's columns
(:data:`simbench.contract.OBSERVATION_COLUMNS`), so every estimator runs
unchanged on real data:

* satellite position, velocity and clock from the broadcast ephemeris
  (IS-GPS-200 user algorithm, :class:`simbench.core.orbits.BroadcastEphemeris`)
  at the signal transmit time ``t_tx = t_rx - P / c - dt_sv(t_tx)``, in the
  Earth-fixed frame of ``t_tx``; the receiver clock error cancels in
  ``t_rx - P / c`` because the pseudorange carries it too;
* ``sat_clock = c (dt_sv - TGD)``: the L1 single-frequency user correction of
  IS-GPS-200 20.3.3.3.3.2, relativistic eccentricity term included;
* ``sat_dcb = c (T2 - T1)``, the broadcast group delay of the row's second signal minus
  the first's (:func:`second_group_delays`), which the ionosphere-free combination
  needs on top of ``sat_clock``; written when the log has a second frequency;
* elevation and azimuth from a per-epoch single-point solution (a receiver
  knows no reference; tens of metres of position error move an elevation by
  far less than a millidegree);
* carrier phase cycles times wavelength, Doppler in Hz, C/N0 from the ``S``
  observable, the loss-of-lock flag from bit 0 of the RINEX LLI digit.

Klobuchar and Saastamoinen are not applied here: the observation table holds
raw observables as the simulator's does, the header's Klobuchar coefficients
go into :class:`~simbench.contract.NavInfo`, and the shared measurement model
(:func:`estimators.model.measurement.prepare_ppp`) applies both.

GPS (``G``, L1 C/A), GLONASS (``R``, L1 C/A FDMA: the wavelength of each
satellite from the frequency channel of its navigation record; orbits by
numerical integration, :mod:`simbench.core.glonass_orbits`), Galileo (``E``,
E1; clock minus BGD(E1,E5b), :mod:`simbench.core.galileo_orbits`), BeiDou
(``C``, B1I: ``C1I`` in RINEX 3.02, ``C2I`` in 3.01 and 3.03+, :func:`first_signals`;
:mod:`simbench.core.beidou_orbits`) and QZSS (``J``, L1 C/A; GPS-like records) are supported
(their navigation records: :mod:`simbench.data.broadcast`). Each satellite's second frequency
(:data:`SECOND_SIGNALS`: GPS L2 else L5, Galileo E5a else E5b, BeiDou B3I else
B2I, GLONASS G2, QZSS L2C else L5) goes into the ``*_l2`` columns with its
``f1_f2_ratio``; a satellite keeps one second signal for the whole log (the one
with the most code values), so its inter-frequency bias stays constant.
A requested system without usable rows is left out with a one-line warning and
a line in ``meta['system_notes']``. Navigation data of a system come from its own
files (``nav_glo``, ``nav_gal``, ``nav_bds``) when given, else from ``nav``, which
may be mixed RINEX 3 files; several files have their records merged, and each
observed satellite must have a record near each epoch it is observed at
(:func:`served_rows`; a system's hours without records in which none of its
satellites is observed are no gap). With several
systems the single-point solution and the shared model give every non-GPS
system its own receiver clock offset (``PppObservations.system_index``),
which absorbs the system time offsets and inter-system biases.

RINEX 2.1x observation files are rewritten in RINEX 3 layout first (:func:`_rinex2_as_rinex3`:
RINEX 2 types mapped to RINEX 3 codes), so one reader serves both.

The RINEX observation parser is our own fixed-column reader: georinex needs
~30 s for the Hong Kong log (7 s for GPS alone) and rounds epochs to
microseconds; this reader takes well under a second.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from simbench.contract import NavInfo, RinexFiles, Scenario
from simbench.core.constants import C_LIGHT, F_B1I, F_L1, F_L2, SECONDS_PER_WEEK
from simbench.core.glonass_orbits import GLO_F1_BASE_HZ, GlonassEphemeris, glonass_l1_frequency
from simbench.core.gpstime import datetime64_to_gps
from simbench.data.broadcast import Ephemeris, load_navigation
from simbench.data.logs import epoch_grid_of, log_scenario, log_truth, observation_table, rough_fix
from simbench.data.reference import read_reference
from simbench.errors import SimbenchError, warn
from simbench.gnss.coverage import check_coverage
from simbench.gnss.navigation import (
    SYSTEM_NAMES,
    GroupDelays,
    NavPaths,
    nav_paths,
    read_gps_navigation,
    read_rinex_lines,
)

__all__ = [
    "RinexObs",
    "read_rinex_obs",
    "load_rinex",
    "load_rinex_log",
    "LogInputs",
    "rinex_scenario",
    "first_signals",
    "second_frequency",
    "second_group_delays",
    "second_group_delay_sigmas",
    "CIVIL_CODE_BIAS_RMS_M",
    "INTER_FREQUENCY_BIAS_RMS_M",
    "served_rows",
    "SIGNALS",
    "SECOND_SIGNALS",
    "NAV_SETTINGS",
]

#: Observation code (band + attribute) written per system and the carrier frequency [Hz]:
#: GPS and QZSS L1 C/A, GLONASS L1 C/A (channel 0; each satellite's channel k adds k * 0.5625 MHz),
#: Galileo E1 (RINEX 3 code 1C: E1-C pilot) and BeiDou B1I (RINEX 3.03+ band 2). The reader also
#: takes the other labels of :func:`first_signals`.
SIGNALS: dict[str, tuple[str, float]] = {
    "G": ("1C", F_L1),
    "R": ("1C", GLO_F1_BASE_HZ),
    "E": ("1C", F_L1),
    "C": ("2I", F_B1I),
    "J": ("1C", F_L1),
}
F_L5 = 1_176.45e6  #: GPS / QZSS L5 and Galileo E5a carrier [Hz]
F_E5B = 1_207.14e6  #: Galileo E5b and BeiDou B2I carrier [Hz]
F_B3I = 1_268.52e6  #: BeiDou B3I carrier [Hz]
#: GLONASS G2 / G1 of every FDMA channel k: (1246 + 0.4375 k) / (1602 + 0.5625 k) MHz = 7/9.
GLO_F2_OVER_F1 = 7.0 / 9.0
#: Second-frequency signals per system, in order of preference: RINEX codes of one band and the
#: carrier [Hz] (GLONASS: of channel 0; each satellite's own is 7/9 of its L1 carrier).
SECOND_SIGNALS: dict[str, tuple[tuple[tuple[str, ...], float], ...]] = {
    "G": ((("2W", "2X", "2L", "2S", "2P"), F_L2), (("5Q", "5X", "5I"), F_L5)),
    "J": ((("2L", "2X", "2S"), F_L2), (("5Q", "5X", "5I"), F_L5)),
    "E": ((("5Q", "5X", "5I"), F_L5), (("7Q", "7X", "7I"), F_E5B)),
    "C": ((("6I", "6Q", "6X"), F_B3I), (("7I", "7Q", "7X"), F_E5B)),
    "R": ((("2C", "2P"), GLO_F1_BASE_HZ * GLO_F2_OVER_F1),),
}
#: Config setting of each system's own navigation file (``nav`` serves GPS and, mixed, the others;
#: QZSS records always come from ``nav``).
NAV_SETTINGS: dict[str, str] = {"G": "nav", "R": "nav_glo", "E": "nav_gal", "C": "nav_bds", "J": "nav"}
_OBS_FIX = "pass a RINEX 2, 3 or 4 observation file (.obs, .yyo, .rnx; also gzip or Hatanaka compressed)"
_CUT_FIX = "re-export the log, or delete the incomplete epoch record at the end"
_LINE_FIX = "make each epoch header's satellite count match its lines, or re-export the log"
#: Epoch time tags closer than this are one epoch (RINEX 3 writes 0.1 us) [s].
_SAME_EPOCH_S = 1e-7
#: Transit time used when no pseudorange is available for a satellite (keeps arrays finite) [s].
_TAU_NOMINAL_S = 0.075


def first_signals(system: str, version: float) -> tuple[str, ...]:
    """RINEX codes (band + attribute) of the first-frequency signal of ``system``, in order of preference.

    BeiDou B1I (1561.098 MHz) is band 1 in RINEX 3.02 (``C1I``, ``C1Q``, ``C1X``: I, Q and
    I+Q) and band 2 in RINEX 2.12, 3.01, 3.03+ and 4 (``C2I``, ``C2Q``, ``C2X``; from 3.04 band 1
    is B1C at 1575.42 MHz, another signal). Galileo E1 is
    written ``1C`` (pilot) or ``1X`` (data + pilot) by most receivers, ``1B`` (data) by some.
    GPS and GLONASS fall back to the P code on L1 (``1W``, ``1P``) in a file without C/A code.

    Parameters
    ----------
    system : str
        System letter.
    version : float
        RINEX version of the observation file (``3.02``).
    """
    if system == "C":
        b1i = ("2I", "2Q", "2X")
        return ("1I", "1Q", "1X", *b1i) if round(version, 2) == 3.02 else b1i
    if system == "E":
        return ("1C", "1X", "1B")
    if system == "G":  # P(Y) when a file has no C/A code (RINEX 2 'P1' only): the broadcast clock's own code
        return ("1C", "1W")
    if system == "R":
        return ("1C", "1P")
    return ("1C",)


def second_frequency(system: str, code: str) -> float:
    """Carrier frequency [Hz] of second-frequency signal ``code`` of ``system`` (:data:`SECOND_SIGNALS`).

    GLONASS: of channel 0 (each satellite's own carrier is 7/9 of its L1 carrier); NaN for an unknown code.
    """
    return next((f for codes, f in SECOND_SIGNALS.get(system, ()) if code in codes), np.nan)


@dataclass(frozen=True)
class RinexObs:
    """Two signals per satellite from a RINEX 3 observation file, as flat rows.

    Attributes
    ----------
    epoch_t_int : np.ndarray of int64, shape (n,)
        Whole GPS seconds of each epoch's time tag (continuous GPS time) [s].
    epoch_t_frac : np.ndarray, shape (n,)
        Sub-second part of each time tag [s]; kept apart for full precision.
    row_epoch : np.ndarray of int, shape (N,)
        Epoch (index into the ``epoch_*`` arrays) of each row.
    sat : np.ndarray of str, shape (N,)
        Satellite ids, RINEX system letter kept (``'G05'``).
    code, phase_cycles, doppler_hz, cn0_dbhz : np.ndarray, shape (N,)
        First-frequency pseudorange [m], carrier phase [cycles], Doppler [Hz], C/N0 [dB-Hz]; NaN when blank.
    lli : np.ndarray of bool, shape (N,)
        Bit 0 of the phase observation's loss-of-lock digit.
    approx_position : np.ndarray, shape (3,)
        ``APPROX POSITION XYZ`` of the header (zeros when absent) [m].
    interval_s : float
        Nominal epoch interval (header ``INTERVAL`` or the median spacing) [s].
    path : str
    code_l2, phase_l2_cycles : np.ndarray, shape (N,)
        Second-frequency pseudorange [m] and carrier phase [cycles] of the satellite's one
        second signal (``signal_l2``); NaN when blank or when the satellite has none.
    lli_l2 : np.ndarray of bool, shape (N,)
        Bit 0 of the second phase's loss-of-lock digit.
    signal_l2 : np.ndarray of str, shape (N,)
        RINEX code of each row's second signal (``'2W'``), ``''`` without one. One per
        satellite for the whole log (constant biases): the candidate of
        :data:`SECOND_SIGNALS` with the most code values, ties to the preferred one.
    signals : dict of str -> str
        First-frequency code used per system kept (``{'C': '1I'}``).
    version : float
        RINEX version of the file.
    header_codes : dict of str -> list of str
        Observation codes of the header per system (``SYS / # / OBS TYPES``).
    system_notes : list of str
        Why a requested system has no rows (one sentence each, e.g.
        ``'no BeiDou rows with a known code (codes in the file: C1X L1X)'``).
    unread_systems : dict of str -> int
        Satellite lines of systems simbench does not read (SBAS ``S``, NavIC ``I``), per system letter.
    """

    epoch_t_int: np.ndarray
    epoch_t_frac: np.ndarray
    row_epoch: np.ndarray
    sat: np.ndarray
    code: np.ndarray
    phase_cycles: np.ndarray
    doppler_hz: np.ndarray
    cn0_dbhz: np.ndarray
    lli: np.ndarray
    approx_position: np.ndarray
    interval_s: float
    path: str
    code_l2: np.ndarray | None = None
    phase_l2_cycles: np.ndarray | None = None
    lli_l2: np.ndarray | None = None
    signal_l2: np.ndarray | None = None
    signals: dict[str, str] = field(default_factory=dict)
    version: float = 3.0
    header_codes: dict[str, list[str]] = field(default_factory=dict)
    system_notes: list[str] = field(default_factory=list)
    unread_systems: dict[str, int] = field(default_factory=dict)


def _obs_error(path: str, problem: str, fix: str = _OBS_FIX) -> SimbenchError:
    return SimbenchError(f"scenario.obs '{path}'", problem, fix)


def _float(text: str) -> float:
    """An observation field: blank or zero is missing (RINEX 3.05 sec. 5.6: "missing observations
    are written as 0.0 or blanks"); an IGS station's ``0.000`` L2 codes read as ranges diverged
    every estimator."""
    text = text.strip()
    value = float(text) if text else 0.0
    return value if value != 0.0 else np.nan


def _codes_note(system: str, have: list[str]) -> str:
    """Why ``system`` gives no rows: the file's header has none of its codes we know."""
    name = SYSTEM_NAMES[system]
    if not have:
        return f"no {name} observations in the file"
    return f"no {name} rows with a known code (codes in the file: {' '.join(have)})"


def read_rinex_obs(path: str | os.PathLike[str], systems: str = "G") -> RinexObs:
    """Read a first and a second signal per satellite of ``systems`` from a RINEX 3 observation file.

    Parameters
    ----------
    path : str or PathLike
        RINEX 3.0x or 4.0x (or 2.x, read as its RINEX 3 codes) observation file, time system GPS: plain
        text with any line ending, or gzip / Hatanaka compressed
        (:func:`~simbench.gnss.navigation.read_rinex_lines`).
    systems : str
        System letters to keep; each needs an entry in :data:`SIGNALS`. The first
        signal of a system is the first of :func:`first_signals` that the header lists
        (RINEX version aware); a system without one, or without code values, is left
        out and said why in ``system_notes``.

    Returns
    -------
    RinexObs

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 2/3/4 observation data, a time system other than
        GPS, no pseudorange observable for any requested system (naming the codes
        found), observation types redefined by an event record, or no data; a cut file (an epoch
        with fewer satellite lines than its header announces, a line ending inside a number), a
        satellite count that does not match the lines, epochs out of time order. The message names the line.

    Event records (epoch flags 2-5: moving antenna, new site, header lines, external event) are
    skipped, as the standard says; a flag 6 record (cycle slips) sets the loss-of-lock flag of the
    phases it names at its epoch, and flag 1 (power failure since the previous epoch) that of every
    phase of its epoch. Rows of systems simbench does not read (SBAS, NavIC) are counted in
    ``unread_systems``.

    Warns
    -----
    SimbenchWarning
        Epoch records that repeat an earlier time tag, or a satellite repeated
        within one epoch: the first record is kept.
    """
    p = os.fspath(path)
    lines, version_text = _observation_lines(p, systems)
    version = float(version_text)
    header = _read_header(p, lines)
    wanted = _wanted_columns(p, header.types, systems, version, version_text)
    rec = _read_records(p, lines, header.body, wanted.cols, header.types)
    if not rec.r_epoch:
        if not rec.stamps and rec.events:
            raise _obs_error(
                p,
                f"has no observation epochs: its {rec.events} epoch records are all event records (flags 2-5: "
                "antenna moved, new site, header lines, external event)",
                "pass the log's observation file",
            )
        raise _obs_error(p, f"contains no observations of systems '{systems}'")
    t_int = datetime64_to_gps(np.array(rec.stamps, dtype="datetime64[s]")).astype(np.int64)
    t_frac = np.array(rec.fracs)
    row_epoch = np.array(rec.r_epoch, dtype=np.int64)
    sat = np.array(rec.r_sat)
    flags = np.array(rec.r_lli, dtype=bool)
    flags[np.isin(row_epoch, rec.power_failures)] = True
    flags |= _slipped(rec, t_int, t_frac, row_epoch, sat, flags.shape[1])
    epochs, rows = _first_records(p, t_int, t_frac, np.array(rec.e_line), row_epoch, sat)
    renumber = np.full(t_int.size, -1, np.int64)
    renumber[epochs] = np.arange(epochs.size)
    t_int, t_frac, row_epoch, sat = t_int[epochs], t_frac[epochs], renumber[row_epoch[rows]], sat[rows]
    vals = np.array(rec.r_num, dtype=float)[rows]
    flags = flags[rows]
    code = vals[:, 0]
    signals, notes = dict(wanted.signals), dict(wanted.notes)
    letters = np.array([x[:1] for x in sat.tolist()])
    seen = set(np.unique(letters).tolist()) | set(rec.other_rows)
    for s in list(signals):
        if not np.isfinite(code[letters == s]).any():
            notes[s] = f"no {SYSTEM_NAMES[s]} rows with a C{signals.pop(s)} pseudorange"
    notes |= {s: f"no {SYSTEM_NAMES[s]} satellites in the file" for s in systems if s not in seen}
    if not signals:
        raise _obs_error(
            p, "has no pseudorange values (all code fields are blank)", "pass a file with code observations"
        )
    code_l2, phase_l2, lli_l2, signal_l2 = _second_signal(sat, vals, flags, wanted.second)
    interval = header.interval
    if not np.isfinite(interval) or interval <= 0:
        d = np.diff(t_int) + np.diff(t_frac)
        interval = float(np.median(d)) if d.size else 1.0
    return RinexObs(
        epoch_t_int=t_int,
        epoch_t_frac=t_frac,
        row_epoch=row_epoch,
        sat=sat,
        code=code,
        phase_cycles=vals[:, 1],
        doppler_hz=vals[:, 2],
        cn0_dbhz=vals[:, 3],
        lli=flags[:, 0],
        approx_position=header.approx,
        interval_s=float(interval),
        path=p,
        code_l2=code_l2,
        phase_l2_cycles=phase_l2,
        lli_l2=lli_l2,
        signal_l2=signal_l2,
        signals=signals,
        version=version,
        header_codes=header.types,
        system_notes=[notes[s] for s in dict.fromkeys(systems) if s in notes],
        unread_systems={s: n for s, n in sorted(rec.other_rows.items()) if s not in SIGNALS},
    )


def _observation_lines(p: str, systems: str) -> tuple[list[str], str]:
    """The lines of observation file ``p`` in RINEX 3 layout, and its version as written (``'2.11'``)."""
    if not os.path.isfile(p):
        raise _obs_error(p, "file does not exist", "check the path (relative paths start at the working directory)")
    unknown = sorted(set(systems) - set(SIGNALS))
    if unknown:
        raise SimbenchError(
            "scenario.systems", f"systems {unknown} are not supported", f"use a subset of '{''.join(SIGNALS)}'"
        )
    lines = read_rinex_lines(p, f"scenario.obs '{p}'", _OBS_FIX)
    if not lines:
        raise _obs_error(p, "is empty")
    if "RINEX VERSION / TYPE" not in lines[0]:
        raise _obs_error(p, "has no RINEX header")
    version_text, kind = lines[0][:9].strip(), lines[0][20:21]
    try:
        float(version_text)
    except ValueError:
        raise _obs_error(p, f"has no RINEX version number in its first line ('{version_text}')") from None
    if kind != "O" or not version_text.startswith(("2", "3", "4")):
        raise _obs_error(p, f"is RINEX {version_text} type '{kind}', not RINEX 2/3/4 observation data")
    return (_rinex2_as_rinex3(p, lines) if version_text.startswith("2") else lines), version_text


@dataclass(frozen=True)
class _Header:
    """What an observation header (RINEX 3 layout) tells the reader."""

    types: dict[str, list[str]]  #: observation codes per system
    approx: np.ndarray  #: APPROX POSITION XYZ, zeros when absent [m]
    interval: float  #: INTERVAL, NaN when absent [s]
    body: int  #: index of the first line after END OF HEADER


def _read_header(p: str, lines: list[str]) -> _Header:
    types: dict[str, list[str]] = {}
    approx = np.zeros(3)
    interval = np.nan
    last_sys = ""
    for i, ln in enumerate(lines):
        label = ln[60:].strip()
        if label == "SYS / # / OBS TYPES":
            if ln[0] != " ":
                last_sys = ln[0]
                types[last_sys] = []
            types[last_sys] += ln[7:60].split()
        elif label == "APPROX POSITION XYZ":
            approx = np.array([_float(ln[k : k + 14]) for k in (0, 14, 28)])
            approx = np.nan_to_num(approx)  # blank or zero fields: no position
        elif label == "INTERVAL":
            interval = _float(ln[:10])
        elif label == "TIME OF FIRST OBS":
            tsys = ln[48:51].strip()
            if tsys not in ("GPS", ""):
                raise _obs_error(p, f"time system {tsys} is not supported", "convert the file to GPS time")
        elif label == "END OF HEADER":
            return _Header(types, approx, interval, i + 1)
    raise _obs_error(p, "has no END OF HEADER line")


@dataclass(frozen=True)
class _Wanted:
    """The columns to read per system and why a requested system has none."""

    #: per system: columns of the first signal's C, L, D, S, then C and L of each second candidate (-1: absent)
    cols: dict[str, list[int]]
    second: dict[str, list[str]]  #: second-signal candidates per system, in order of preference
    signals: dict[str, str]  #: first signal per system
    notes: dict[str, str]  #: why a requested system has no columns


def _wanted_columns(p: str, types: dict[str, list[str]], systems: str, version: float, version_text: str) -> _Wanted:
    cols: dict[str, list[int]] = {}
    second: dict[str, list[str]] = {}
    signals: dict[str, str] = {}
    notes: dict[str, str] = {}
    for s in dict.fromkeys(systems):
        have = types.get(s, [])
        band = next((b for b in first_signals(s, version) if f"C{b}" in have), None)
        if band is None:
            notes[s] = _codes_note(s, have)
            continue
        signals[s] = band
        second[s] = [b for codes, _ in SECOND_SIGNALS.get(s, ()) for b in codes if f"C{b}" in have]
        cols[s] = [_column(have, f"{o}{band}", version) for o in "CLDS"]
        cols[s] += [_column(have, f"{o}{b}", version) for b in second[s] for o in "CL"]
    if not cols:
        wanted = "; ".join(f"{SYSTEM_NAMES[s]}: C{' or C'.join(first_signals(s, version))}" for s in systems)
        found = "; ".join(f"{s}: {' '.join(types[s])}" for s in dict.fromkeys(systems) if types.get(s)) or "none"
        raise _obs_error(
            p,
            f"has no pseudorange observable for the requested systems (RINEX {version_text}; known: {wanted}; "
            f"codes in the file: {found})",
            "pass a file with code observations, or other scenario.systems",
        )
    return _Wanted(cols, second, signals, notes)


def _column(have: list[str], code: str, version: float) -> int:
    """Index of observable ``code`` (``'L2C'``) among the file's codes ``have``, -1 when absent.

    RINEX 2 names one phase, Doppler and strength per band (``L2``) whatever code is tracked: there it
    serves every code of the band (the attribute given by :func:`_rinex3_code` is a guess).
    """
    if code in have:
        return have.index(code)
    if version < 3 and code[0] != "C":
        return next((k for k, h in enumerate(have) if h[:2] == code[:2]), -1)
    return -1


@dataclass
class _Records:
    """The observation records of a file as lists (one Python step per line is unavoidable)."""

    stamps: list[str] = field(default_factory=list)  #: ISO time tag of each epoch, whole seconds
    fracs: list[float] = field(default_factory=list)  #: sub-second part of each time tag [s]
    e_line: list[int] = field(default_factory=list)  #: 1-based line number of each epoch header
    r_epoch: list[int] = field(default_factory=list)
    r_sat: list[str] = field(default_factory=list)
    r_num: list[list[float]] = field(default_factory=list)  #: numbers of the wanted columns per row
    r_lli: list[list[bool]] = field(default_factory=list)  #: first and each second candidate's loss of lock
    power_failures: list[int] = field(default_factory=list)  #: epochs of flag 1
    #: flag 6 records: time tag, satellite and which phases slipped (first, each second candidate)
    slips: list[tuple[str, float, str, list[bool]]] = field(default_factory=list)
    other_rows: dict[str, int] = field(default_factory=dict)  #: rows of systems not read, per letter
    events: int = 0  #: event records (flags 2-5) skipped


def _read_records(
    p: str, lines: list[str], body: int, cols: dict[str, list[int]], types: dict[str, list[str]]
) -> _Records:
    """Every epoch record after the header: observations (flags 0, 1), cycle slips (6); events (2-5) skipped."""
    rec = _Records()
    width = max(len(c) for c in cols.values())
    i, n_lines = body, len(lines)
    while i < n_lines:  # text parsing: one Python step per line is unavoidable
        ln = lines[i]
        i += 1
        if not ln.startswith(">"):
            if not ln.strip():
                continue
            where = (
                f"the epoch at line {rec.e_line[-1]} announces fewer satellites"
                if rec.e_line
                else "no epoch header before it"
            )
            raise _obs_error(p, f"line {i} is outside any epoch record ({where}): '{ln[:20].strip()}'", _LINE_FIX)
        try:
            flag, count = int(ln[31:32].strip() or 0), int(ln[32:35])
        except ValueError:
            raise _obs_error(p, f"has a malformed epoch line {i}: '{ln[:35].strip()}'", _LINE_FIX) from None
        if 2 <= flag <= 5:  # events: a moving antenna, a new site, header lines, an external event
            _check_event(p, lines[i : i + count], i, types)
            rec.events += 1
            i += count
            continue
        stamp, frac = _epoch_time(p, ln, i)
        block = _satellite_block(p, lines, i, count)
        rows = _satellite_rows(p, block, i + 1, cols, width, rec.other_rows)
        if flag == 6:
            # a slip record holds a value where a phase slipped: first phase, then each second candidate's
            rec.slips += [(stamp, frac, sat, np.isfinite([nums[1], *nums[5::2]]).tolist()) for sat, nums, _ in rows]
        else:
            rec.stamps.append(stamp)
            rec.fracs.append(frac)
            rec.e_line.append(i)
            e = len(rec.stamps) - 1
            if flag == 1:
                rec.power_failures.append(e)
            for sat, nums, lli in rows:
                rec.r_epoch.append(e)
                rec.r_sat.append(sat)
                rec.r_num.append(nums)
                rec.r_lli.append(lli)
        i += count
    return rec


_NO_NEW_COLUMNS = "a change of columns within one file is not supported"


def _check_event(p: str, block: list[str], line: int, types: dict[str, list[str]]) -> None:
    """Refuse an event record that redefines a system's observation types: the columns would change mid-file.

    A header line repeating the file's own types (a splice of files of one receiver) passes.
    """
    fix = "split the file at that line (e.g. with gfzrnx or teqc) and run each part"
    again: dict[str, list[str]] = {}
    last = ""
    for k, ln in enumerate(block, start=line + 1):
        label = ln[60:].strip()
        if label == "# / TYPES OF OBSERV":  # RINEX 2 (its repetitions of the header's types were dropped)
            problem = f"redefines its observation types in an event record (line {k}); {_NO_NEW_COLUMNS}"
            raise _obs_error(p, problem, fix)
        if label == "SYS / # / OBS TYPES":
            last = ln[0] if ln[0] != " " else last
            again.setdefault(last, []).extend(ln[7:60].split())
    changed = [s for s in again if again[s] != types.get(s)]
    if changed:
        where = f"the event record at line {line}"
        raise _obs_error(p, f"redefines its {', '.join(changed)} observation types in {where}; {_NO_NEW_COLUMNS}", fix)


def _epoch_time(p: str, ln: str, line: int) -> tuple[str, float]:
    """The time tag of epoch header ``ln`` (RINEX 3 layout): ISO whole seconds and the fraction [s]."""
    try:
        f = ln[1:29].split()
        whole, _, frac = f[5].partition(".")
        stamp = f"{int(f[0]):04d}-{int(f[1]):02d}-{int(f[2]):02d}T{int(f[3]):02d}:{int(f[4]):02d}:{int(whole):02d}"
        return stamp, (float("0." + frac) if frac else 0.0)
    except (ValueError, IndexError):
        raise _obs_error(p, f"has a malformed epoch line {line}: '{ln[:35].strip()}'", _LINE_FIX) from None


def _satellite_block(p: str, lines: list[str], start: int, count: int) -> list[str]:
    """The ``count`` satellite lines from index ``start``, checked to be all there (a cut file, lost lines)."""
    block = lines[start : start + count]
    short = next((k for k, b in enumerate(block) if b.startswith(">")), len(block))
    if short == len(block) < count:
        problem = f"epoch at line {start} announces {count} satellites but the file ends after {short} (cut file)"
        raise _obs_error(p, problem, _CUT_FIX)
    if short < count:
        raise _obs_error(
            p,
            f"epoch at line {start} announces {count} satellites but the next epoch header follows "
            f"after {short} (line {start + short + 1})",
            _LINE_FIX,
        )
    return block


def _satellite_rows(
    p: str, block: list[str], first_line: int, cols: dict[str, list[int]], width: int, other: dict[str, int]
) -> list[tuple[str, list[float], list[bool]]]:
    """Satellite id, wanted numbers (padded to ``width``) and loss-of-lock flags of each line of a record.

    Lines of systems without wanted columns are counted in ``other`` (per system letter).
    """
    rows = []
    for row, ln in enumerate(block, start=first_line):
        c = cols.get(ln[:1])
        if c is None:
            other[ln[:1]] = other.get(ln[:1], 0) + 1
            continue
        # fields are right-aligned F14.3 plus 2 flag columns: a line ending inside a number was cut
        # (trailing blanks are padding: a software receiver pads its lines to 80 columns)
        if 0 < (len(ln.rstrip()) - 3) % 16 < 14:
            raise _obs_error(p, f"line {row} ends inside an observation field (cut line)", _CUT_FIX)
        try:
            nums = [_float(ln[3 + 16 * k : 17 + 16 * k]) if k >= 0 else np.nan for k in c]
        except ValueError:
            raise _obs_error(p, f"line {row} has a malformed observation: '{ln[:40].strip()}'", _LINE_FIX) from None
        digits = (ln[17 + 16 * j : 18 + 16 * j].strip() if j >= 0 else "" for j in (c[1], *c[5::2]))
        lli = [d.isdigit() and bool(int(d) & 1) for d in digits] + [False] * ((width - len(c)) // 2)
        rows.append((ln[:3].replace(" ", "0"), nums + [np.nan] * (width - len(c)), lli))
    return rows


def _slipped(
    rec: _Records, t_int: np.ndarray, t_frac: np.ndarray, row_epoch: np.ndarray, sat: np.ndarray, n_phases: int
) -> np.ndarray:
    """Loss-of-lock flags (rows x phases) set by the flag 6 records: the phases each names at its time tag."""
    out = np.zeros((sat.size, n_phases), bool)
    if not rec.slips:
        return out
    key = t_int * 10_000_000 + np.round(t_frac / _SAME_EPOCH_S).astype(np.int64)
    row_of = {(int(key[e]), s): r for r, (e, s) in enumerate(zip(row_epoch.tolist(), sat.tolist()))}
    s_int = datetime64_to_gps(np.array([x[0] for x in rec.slips], dtype="datetime64[s]")).astype(np.int64)
    s_key = s_int * 10_000_000 + np.round(np.array([x[1] for x in rec.slips]) / _SAME_EPOCH_S).astype(np.int64)
    for k, (_, _, s, phases) in zip(s_key.tolist(), rec.slips):
        r = row_of.get((k, s))
        if r is not None:
            out[r, : len(phases)] |= np.array(phases[:n_phases])
    return out


def _rinex3_code(kind: str, system: str, types: list[str]) -> str:
    """The RINEX 3 code of RINEX 2 observation type ``kind`` (``'P2'``) of ``system``, given the file's ``types``.

    RINEX 2 names no tracking mode: ``C1`` is C/A (``1C``), ``P1``/``P2`` the P(Y) code (GPS ``W``,
    GLONASS ``P``), GPS ``C2`` the civil L2C (``X``), GLONASS ``C2`` its C/A on G2 (``C``); phase,
    Doppler and strength of band 2 take the mode of the band's code (P2 when the file has it).
    Bands 5, 6, 7, 8 take ``X``. BeiDou (RINEX 2.12) bands 2, 7, 6 are B1I, B2I, B3I (``I``);
    ``''`` for a type without a RINEX 3 code.
    """
    obs, band = kind[:1], kind[1:]
    if obs not in "CLDSP" or not band.isdigit():
        return ""
    if system == "C":  # RINEX 2.12 BeiDou: bands 2 (B1I), 7 (B2I), 6 (B3I) as in RINEX 3.01; no P code
        return f"{obs}{band}I" if obs != "P" and band in "276" else ""
    if band == "1":
        mode = "W" if obs == "P" else "C"
    elif band == "2":
        p_code = "P" if system == "R" else "W"
        mode = p_code if obs == "P" or (obs != "C" and "P2" in types) else ("C" if system == "R" else "X")
    else:
        mode = "X"
    return f"{'C' if obs == 'P' else obs}{band}{mode}"


def _rinex2_as_rinex3(path: str, lines: list[str]) -> list[str]:
    """The lines of a RINEX 2.1x observation file rewritten in RINEX 3 layout (one shared reader).

    The header's ``# / TYPES OF OBSERV`` becomes one ``SYS / # / OBS TYPES`` list per system
    (:func:`_rinex3_code`), each epoch header a ``>`` line, each satellite's records of up to 5
    fields per 80-column line one line after its id (blank system letter: GPS). Error
    messages then count lines of this rewritten text.
    """
    end = next((i for i, ln in enumerate(lines) if ln[60:].strip() == "END OF HEADER"), None)
    if end is None:
        raise _obs_error(path, "has no END OF HEADER line")
    kinds = [k for ln in lines[:end] if ln[60:].strip() == "# / TYPES OF OBSERV" for k in ln[6:60].split()]
    if not kinds:
        raise _obs_error(path, f"is RINEX {lines[0][:9].strip()} without a '# / TYPES OF OBSERV' header line")
    header = [ln for ln in lines[:end] if ln[60:].strip() != "# / TYPES OF OBSERV"]
    for system in SIGNALS:
        codes = [_rinex3_code(k, system, kinds) or "X0X" for k in kinds]  # X0X: a column no signal reads
        for k in range(0, len(codes), 13):
            lead = f"{system}  {len(codes):3d}" if k == 0 else " " * 6
            header.append(f"{lead + ''.join(f' {c}' for c in codes[k : k + 13]):60s}SYS / # / OBS TYPES")
    out = [*header, lines[end]]
    per_sat = -(-len(kinds) // 5)
    i, n_lines = end + 1, len(lines)
    while i < n_lines:  # text parsing: one Python step per line is unavoidable
        ln = lines[i]
        i += 1
        if not ln.strip():
            continue
        try:
            flag, count = int(ln[28:29].strip() or 0), int(ln[29:32])
        except ValueError:
            raise _obs_error(path, f"has a malformed RINEX 2 epoch line {i}: '{ln[:32].strip()}'", _LINE_FIX) from None
        if 2 <= flag <= 5:  # events carry header lines (their date fields may be blank), not observations
            event = lines[i : i + count]
            again = [k for e in event if e[60:].strip() == "# / TYPES OF OBSERV" for k in e[6:60].split()]
            if again == kinds:  # a splice repeating the file's own types: nothing changes
                event = [e for e in event if e[60:].strip() != "# / TYPES OF OBSERV"]
            out.append(f">{'':30s}{flag:1d}{len(event):3d}")
            out += event
            i += count
            continue
        try:
            yy = int(ln[1:3])
        except ValueError:
            raise _obs_error(path, f"has a malformed RINEX 2 epoch line {i}: '{ln[:32].strip()}'", _LINE_FIX) from None
        stamp = f"{yy + (1900 if yy >= 80 else 2000):04d}{ln[3:26]}"  # ' mm dd hh mi ss.sssssss' as RINEX 3
        out.append(f"> {stamp}  {flag:1d}{count:3d}")
        chunks = [ln[32:68].ljust(36)]  # 12 satellite ids per line, continued on the next lines
        while 12 * len(chunks) < count and i < n_lines:
            chunks.append(lines[i][32:68].ljust(36))
            i += 1
        sats = "".join(chunks)
        for k in range(count):
            sat = sats[3 * k : 3 * k + 3]
            rows = lines[i : i + per_sat]
            i += per_sat
            text = "".join(r.ljust(80) for r in rows[:-1]) + (rows[-1] if rows else "")
            out.append((sat[0].strip() or "G") + sat[1:] + text)
    return out


def _second_signal(
    sat: np.ndarray, vals: np.ndarray, flags: np.ndarray, second: dict[str, list[str]]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each satellite's one second signal: code [m], phase [cycles], loss of lock and code per row.

    ``vals`` holds per row the first signal's four numbers, then code and phase of each candidate
    of ``second[system]``; ``flags`` the first and each candidate's loss-of-lock flag. A satellite
    keeps the candidate with the most code values over the whole log (a change of signal would
    change its inter-frequency bias), ties to the earlier (preferred) one.
    """
    n = sat.size
    code_l2, phase_l2 = np.full(n, np.nan), np.full(n, np.nan)
    lli_l2, signal_l2 = np.zeros(n, bool), np.full(n, "", dtype="<U2")
    sat_ids, sat_of_row = np.unique(sat, return_inverse=True)
    for j, name in enumerate(sat_ids.tolist()):
        candidates = second.get(name[:1], [])
        if not candidates:
            continue
        rows = np.flatnonzero(sat_of_row == j)
        counts = np.isfinite(vals[np.ix_(rows, 4 + 2 * np.arange(len(candidates)))]).sum(axis=0)
        if not counts.max():
            continue
        k = int(np.argmax(counts))
        code_l2[rows], phase_l2[rows] = vals[rows, 4 + 2 * k], vals[rows, 5 + 2 * k]
        lli_l2[rows], signal_l2[rows] = flags[rows, 1 + k], candidates[k]
    return code_l2, phase_l2, lli_l2, signal_l2


def _first_records(
    path: str, t_int: np.ndarray, t_frac: np.ndarray, line: np.ndarray, row_epoch: np.ndarray, sat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The epochs and rows to keep: the first record of each time tag and of each satellite in it.

    Parameters
    ----------
    path : str
    t_int, t_frac : np.ndarray, shape (n,)
        Epoch time tags, whole and fractional GPS seconds [s].
    line : np.ndarray of int, shape (n,)
        1-based line number of each epoch header.
    row_epoch, sat : np.ndarray, shape (N,)
        Epoch and satellite of each row.

    Returns
    -------
    epochs : np.ndarray of int
        Kept epochs, increasing.
    rows : np.ndarray of int
        Kept rows, increasing.

    Raises
    ------
    SimbenchError
        When the kept epochs are not in time order.
    """
    field = f"scenario.obs '{path}'"
    key = t_int * 10_000_000 + np.round(t_frac / _SAME_EPOCH_S).astype(np.int64)
    epochs = np.sort(np.unique(key, return_index=True)[1])
    if epochs.size < key.size:
        repeat = np.setdiff1d(np.arange(key.size), epochs)
        warn(
            field,
            f"{repeat.size} epoch records repeat the time tag of an earlier one (first at line {line[repeat[0]]})",
            "kept the first record of each time tag",
        )
    back = np.flatnonzero(np.diff(key[epochs]) < 0)
    if back.size:
        j, k = epochs[back[0]], epochs[back[0] + 1]
        raise _obs_error(
            path,
            f"epoch at line {line[k]} is earlier than the epoch at line {line[j]}",
            "sort the epoch records by time (or re-export the log)",
        )
    sat_code = np.unique(sat, return_inverse=True)[1]
    kept_epoch = np.isin(row_epoch, epochs)
    pair = row_epoch * (int(sat_code.max(initial=0)) + 1) + sat_code
    rows = np.flatnonzero(kept_epoch)
    rows = np.sort(rows[np.unique(pair[rows], return_index=True)[1]])
    twice = int(kept_epoch.sum()) - rows.size
    if twice:
        warn(field, f"{twice} satellite lines repeat a satellite of the same epoch", "kept the first line of each")
    return epochs, rows


def _load_ephemeris(paths: tuple[str, ...], setting: str, system: str) -> tuple[Ephemeris, GroupDelays]:
    """Ephemeris of one system from ``paths`` (records merged), read for ``setting`` (the parameter that named
    them: the system's own, or ``scenario.nav`` standing in for it), and its group delays
    (:data:`~simbench.gnss.navigation.GroupDelays`, ``tgd`` from the ephemeris)."""
    key = f"scenario.{NAV_SETTINGS[system]}"
    if not paths:
        raise SimbenchError(
            key,
            f"no {SYSTEM_NAMES[system]} navigation file given",
            f"set {key} to a RINEX navigation file holding {SYSTEM_NAMES[system]} records, "
            "or scenario.nav to a mixed RINEX 3 navigation file",
        )
    delays: GroupDelays = {}
    if system == "G":
        eph: Ephemeris = read_gps_navigation(paths, setting=setting)
    else:
        eph, delays = load_navigation(system, paths, setting=setting)
    return eph, {"tgd": eph.tgd, **delays}


def served_rows(
    obs: RinexObs, ephs: dict[str, Ephemeris], settings: dict[str, str], paths: dict[str, tuple[str, ...]]
) -> np.ndarray:
    """Rows with a code whose satellite has a record within validity at the row's epoch
    (:func:`~simbench.gnss.coverage.check_coverage` per system, which refuses a file gap and warns about
    satellites left out)."""
    letters = obs.sat.astype("<U1")
    t_epoch = obs.epoch_t_int.astype(float)  # the states select records at the whole-second tag too
    out = np.zeros(obs.sat.size, bool)
    for system, eph in ephs.items():
        rows = np.flatnonzero((letters == system) & np.isfinite(obs.code))
        out[rows] = check_coverage(eph, t_epoch, obs.row_epoch[rows], obs.sat[rows], settings[system], paths[system])
    return out


def second_group_delays(
    sat: np.ndarray,
    signal_l2: np.ndarray,
    f1_f2_ratio: np.ndarray,
    ephs: dict[str, Ephemeris],
    delays: dict[str, GroupDelays],
) -> np.ndarray:
    """``sat_dcb`` of each row: c (T2 - T1), the broadcast group delay of its second signal minus its first's.

    With the clock reference of the broadcast message, P_i = rho + c dt_r - c (dt_sv - T_i) + I_i; the
    ionosphere-free combination's clock is c (dt_sv - T1) + c (T2 - T1) / (gamma - 1), i.e.
    ``sat_clock + sat_dcb / (gamma - 1)``. Per system:

    * GPS and QZSS L1 C/A with any L2 code: T2 = gamma TGD, so (gamma - 1) c TGD; with L5 NaN
      (LNAV carries no inter-signal corrections);
    * Galileo E1 with E5a: (gamma - 1) c BGD(E1,E5a), with E5b: (gamma - 1) c BGD(E1,E5b), whichever
      of the I/NAV and F/NAV clocks the ephemeris uses;
    * BeiDou B1I (clock reference B3I, T1 = TGD1): with B3I -c TGD1, with B2I c (TGD2 - TGD1);
    * GLONASS: NaN (no broadcast inter-frequency bias); rows without a second signal: NaN.

    Parameters
    ----------
    sat : np.ndarray of str, shape (N,)
        Satellite id of each row (``'G05'``).
    signal_l2 : np.ndarray of str, shape (N,)
        RINEX code of each row's second signal (``'2W'``), ``''`` without one.
    f1_f2_ratio : np.ndarray, shape (N,)
        Carrier frequency ratio of each row's two signals (NaN without a second one).
    ephs : dict of str -> Ephemeris
        Ephemeris of each system letter; satellites it lacks get NaN.
    delays : dict of str -> GroupDelays
        Group delays of each system of ``ephs`` but GLONASS, aligned with its ephemeris' ``sats``
        (``tgd``, and ``bgd_e5a``, ``bgd_e5b`` for Galileo, ``tgd2`` for BeiDou) [s].

    Returns
    -------
    np.ndarray, shape (N,)
        ``sat_dcb`` [m].
    """
    out = np.full(sat.size, np.nan)
    letters = sat.astype("<U1")
    band = signal_l2.astype("<U1")
    for system, eph in ephs.items():
        rows = np.flatnonzero(letters == system)
        if system not in "GJEC" or not rows.size or not eph.sats.size:
            continue
        # ephemeris satellites are sorted (np.unique)
        j = np.minimum(np.searchsorted(eph.sats, sat[rows]), eph.sats.size - 1)
        found = eph.sats[j] == sat[rows]
        rows, j, d = rows[found], j[found], delays[system]
        b, gamma_1 = band[rows], f1_f2_ratio[rows] ** 2 - 1.0
        if system == "C":
            t2 = np.where(b == "6", 0.0, np.where(b == "7", d["tgd2"][j], np.nan))
            out[rows] = C_LIGHT * (t2 - d["tgd"][j])
        elif system == "E":
            bgd = np.where(b == "5", d["bgd_e5a"][j], np.where(b == "7", d["bgd_e5b"][j], np.nan))
            out[rows] = C_LIGHT * gamma_1 * bgd
        else:
            out[rows] = C_LIGHT * gamma_1 * np.where(b == "2", d["tgd"][j], np.nan)
    return out


#: Stated RMS of a GPS C/A code's group delay against the P(Y) code's, which the LNAV TGD and clock refer to
#: (the inter-signal correction ISC_L1CA is in CNAV only) [m]: CODE's monthly P1-C1 differential code biases
#: of December 2018 (``../shared/data/wvu_drives/p1c1_12.DCB``), 32 satellites, RMS 1.14 ns. L2C against P2
#: (ISC_L2C, CNAV only) is taken to be of the same order.
CIVIL_CODE_BIAS_RMS_M = 0.34
#: Stated RMS of a GPS/QZSS L5 code's group delay relative to L1, which LNAV does not give (ISC_L5 is in CNAV
#: only) [m]: the size of the L1-L2 ones it does give, CODE's P1-P2 differential code biases of December 2018
#: (``../shared/data/wvu_drives/p1p2_12.DCB``), 32 satellites, RMS 5.37 ns.
INTER_FREQUENCY_BIAS_RMS_M = 1.61


def second_group_delay_sigmas(sat: np.ndarray, signal_l1: np.ndarray, signal_l2: np.ndarray) -> np.ndarray:
    """``sat_dcb_sigma`` of each row: the stated RMS of what :func:`second_group_delays` misses [m].

    * GPS and QZSS: TGD is the P(Y) codes' (P1, P2); a C/A first code (``1C``) adds
      :data:`CIVIL_CODE_BIAS_RMS_M`, an L2C second code (``2L``, ``2S``, ``2X``) as much again (in
      quadrature); an L5 second code, whose group delay LNAV does not give, :data:`INTER_FREQUENCY_BIAS_RMS_M`;
    * Galileo (BGD) and BeiDou (TGD1, TGD2): 0, the message gives the pair's;
    * GLONASS: NaN, nothing stated (its L1-L2 satellite delays are not in RINEX 3 navigation, and the
      receiver's own differ per FDMA channel; no source here gives their size);
    * rows without a second signal: NaN.

    Parameters
    ----------
    sat : np.ndarray of str, shape (N,)
        Satellite id of each row.
    signal_l1, signal_l2 : np.ndarray of str, shape (N,)
        RINEX code of each row's first and second signal (``'1C'``, ``'2W'``); ``''`` without a second one.

    Returns
    -------
    np.ndarray, shape (N,)
        ``sat_dcb_sigma`` [m].
    """
    letters = sat.astype("<U1")
    gps_like = np.isin(letters, ["G", "J"])
    civil_first = gps_like & (signal_l1 == "1C")
    civil_second = gps_like & np.isin(signal_l2, ["2L", "2S", "2X"])
    l5 = gps_like & (signal_l2.astype("<U1") == "5")
    out = np.sqrt(
        CIVIL_CODE_BIAS_RMS_M**2 * (civil_first.astype(float) + civil_second) + INTER_FREQUENCY_BIAS_RMS_M**2 * l5
    )
    return np.where((signal_l2 != "") & (letters != "R"), out, np.nan)


def satellite_states(obs: RinexObs, ephs: dict[str, Ephemeris], served: np.ndarray) -> dict[str, np.ndarray]:
    """Satellite state at transmit time of each ``served`` row (:func:`served_rows`); NaN elsewhere.

    Each ephemeris is evaluated at the epochs its served rows have only: between them its records may
    serve no satellite at all (a station's file without records where the system is not observed).
    """
    out = {k: np.full(obs.sat.size, np.nan) for k in ("x", "y", "z", "vx", "vy", "vz", "clock", "drift")}
    for eph in ephs.values():
        m = eph.sats.size
        col = {s: j for j, s in enumerate(eph.sats.tolist())}
        j = np.array([col.get(s, -1) for s in obs.sat.tolist()])
        has = (j >= 0) & served
        if not has.any():
            continue
        epochs, e_r = np.unique(obs.row_epoch[has], return_inverse=True)
        j_r = j[has]
        # (epoch, satellite) grid of transit offsets relative to the whole-second tag.
        tau = np.full((epochs.size, m), _TAU_NOMINAL_S)
        tau[e_r, j_r] = obs.code[has] / C_LIGHT
        t_ref = obs.epoch_t_int[epochs].astype(float)
        base = obs.epoch_t_frac[epochs, None] - tau
        # The satellite clock moves the transmit time by up to ~1 ms (4 m of orbit);
        # one fixed-point step converges it to < 1e-12 s.
        st = eph.states(t_ref, base)
        st = eph.states(t_ref, base - np.nan_to_num(st.clock))
        for k, name in enumerate("xyz"):
            out[name][has] = st.pos[e_r, j_r, k]
            out["v" + name][has] = st.vel[e_r, j_r, k]
        # IS-GPS-200 20.3.3.3.3.2, BDS B1I and Galileo E1 (OS SIS ICD 5.1.5): the single-frequency
        # user's clock is dt_sv - TGD (resp. TGD1, BGD); GLONASS has tgd = 0
        out["clock"][has] = C_LIGHT * (st.clock[e_r, j_r] - np.nan_to_num(eph.tgd[j_r]))
        out["drift"][has] = C_LIGHT * st.clock_drift[e_r, j_r]
    return out


def load_rinex(
    obs_path: str | os.PathLike[str],
    nav_path: NavPaths,
    truth_path: str | os.PathLike[str] | None = None,
    *,
    systems: str = "G",
    nav_bds_path: NavPaths | None = None,
    nav_glo_path: NavPaths | None = None,
    nav_gal_path: NavPaths | None = None,
    name: str = "",
    truth_max_gap_s: float = 2.0,
) -> Scenario:
    """Ingest a RINEX 3 observation file, its navigation files and a reference trajectory or point.

    Parameters
    ----------
    obs_path : str or PathLike
        RINEX 3 observation file.
    nav_path : str, PathLike or sequence of them
        RINEX 2/3 GPS navigation file(s) of the observation time, or mixed
        RINEX 3 files that also serve the systems without files of their own (QZSS
        always comes from here); several files have their records merged.
    truth_path : str or PathLike, optional
        Reference trajectory (``week,TOW,lat,lon,h`` CSV or ``SOW X Y Z``) or a static
        antenna's one point (``lat,lon,h`` or ``x,y,z``, or a file of it); see
        :func:`simbench.data.reference.read_reference`. Without it the truth
        table is empty (nothing can be scored).
    systems : str
        Systems to ingest, letters of ``'GRECJ'`` (GPS, GLONASS, Galileo, BeiDou, QZSS).
        A system without usable rows is left out with a warning
        (:class:`~simbench.errors.SimbenchWarning`) and a line in ``meta['system_notes']``.
    nav_bds_path, nav_glo_path, nav_gal_path : str, PathLike or sequence of them, optional
        RINEX 3 BeiDou, GLONASS, Galileo navigation files; when not
        given, the records of that system come from ``nav_path``.
    name : str
        Scenario name for the result tables; ``''``: the observation file's stem.
    truth_max_gap_s : float
        Reference samples further apart than this are not interpolated [s].

    Returns
    -------
    Scenario
        Observations in the simulator's columns (the second frequency, where a
        satellite has one, in ``code_l2``/``phase_l2``/``lli_l2`` with its ``f1_f2_ratio``; a log
        with a second frequency also gets the optional ``sat_dcb``, :func:`second_group_delays`),
        ``truth`` with one row per epoch that the reference covers (epochs on the
        nominal grid of the log's interval), ``labels=None`` and an empty IMU table.

    Raises
    ------
    SimbenchError
        Unreadable files, navigation records that serve none of a system's observed satellites
        at some epoch it is observed at, or none of its epochs (another day's file;
        :func:`served_rows`), a reference far from the log's own fixes (> 100 km), and the
        errors of :func:`read_rinex_obs`.

    Warns
    -----
    SimbenchWarning
        Observed satellites without a record near their epochs: their rows are left out.
    """
    inputs = LogInputs(nav_path, truth_path, systems, nav_bds_path, nav_glo_path, nav_gal_path, name, truth_max_gap_s)
    return load_rinex_log(obs_path, inputs)


def load_rinex_log(obs_path: str | os.PathLike[str], inputs: LogInputs) -> Scenario:
    """:func:`load_rinex` with its parameters after ``obs_path`` in one :class:`LogInputs` (the form a log
    source calls, shared with :func:`simbench.data.gnsslogger.load_gnsslogger`)."""
    return rinex_scenario(read_rinex_obs(obs_path, inputs.systems), inputs)


@dataclass(frozen=True)
class LogInputs:
    """What makes a log's observations a scenario besides them: :func:`load_rinex`'s parameters after
    ``obs_path`` (the same meaning; the file parameters without their ``_path``)."""

    nav: NavPaths
    truth: str | os.PathLike[str] | None = None
    systems: str = "G"
    nav_bds: NavPaths | None = None
    nav_glo: NavPaths | None = None
    nav_gal: NavPaths | None = None
    name: str = ""
    truth_max_gap_s: float = 2.0


def rinex_scenario(obs: RinexObs, inputs: LogInputs) -> Scenario:
    """The :class:`~simbench.contract.Scenario` of observations already read into a :class:`RinexObs`.

    Every step of :func:`load_rinex` after the observation file is read: ephemerides, satellite
    states at transmit time, the rough fix, the observation and truth tables. Another reader of
    raw observables (:mod:`simbench.data.gnsslogger`) fills a :class:`RinexObs` and comes here,
    so one pipeline serves every format. ``obs.path`` stands for the observation file (the default
    name is its stem).
    """
    systems = inputs.systems
    paths, settings = _navigation_plan(inputs.nav, inputs.nav_bds, inputs.nav_glo, inputs.nav_gal)
    used = [s for s in dict.fromkeys(systems) if s in obs.signals]
    loaded = {s: _load_ephemeris(paths[s], settings[s], s) for s in used}
    ephs = {s: eph for s, (eph, _) in loaded.items()}
    st = satellite_states(obs, ephs, served_rows(obs, ephs, settings, paths))
    keep = np.isfinite(st["x"])
    all_letters = np.array([s[:1] for s in obs.sat.tolist()])
    used, notes = _usable_systems(obs, systems, used, keep, all_letters, paths)

    t_rel_epoch = (obs.epoch_t_int - obs.epoch_t_int[0]) + (obs.epoch_t_frac - obs.epoch_t_frac[0])
    grid = epoch_grid_of(t_rel_epoch, obs.interval_s)
    re = obs.row_epoch[keep]
    sat_pos = np.stack([st[k][keep] for k in "xyz"], axis=1)
    letters = all_letters[keep]
    system_index = np.searchsorted(np.array(sorted(used)), letters)
    x0 = obs.approx_position if obs.approx_position is not None and np.any(obs.approx_position) else None
    corrected = obs.code[keep] + st["clock"][keep]
    rough = rough_fix(re, sat_pos, corrected, n_epochs=obs.epoch_t_int.size, system_index=system_index, x0=x0)
    second = _second_signal_rows(obs, keep, letters, ephs)
    observations = observation_table(
        {
            "epoch": grid.index[re],
            "t": t_rel_epoch[re],
            "sat": obs.sat[keep],
            "code_l1": obs.code[keep],
            "phase_l1": obs.phase_cycles[keep] * (C_LIGHT / second.freq),
            "doppler_l1": obs.doppler_hz[keep],
            "cn0_l1": obs.cn0_dbhz[keep],
            "lli_l1": obs.lli[keep],
            "code_l2": np.where(second.has_l2, second.code, np.nan),
            "phase_l2": np.where(second.has_l2, second.phase_cycles * (C_LIGHT / second.freq2), np.nan),
            "lli_l2": second.lli & second.has_l2,
            "f1_f2_ratio": np.where(second.has_l2, second.freq / second.freq2, np.nan),
            "sat_x": sat_pos[:, 0],
            "sat_y": sat_pos[:, 1],
            "sat_z": sat_pos[:, 2],
            "sat_vx": st["vx"][keep],
            "sat_vy": st["vy"][keep],
            "sat_vz": st["vz"][keep],
            "sat_clock": st["clock"][keep],
            "sat_clock_drift": st["drift"][keep],
            "el": np.degrees(rough.el),
            "az": np.degrees(rough.az),
        }
    )
    if second.has_l2.any():
        delays = {s: d for s, (_, d) in loaded.items()}
        _add_second_group_delays(observations, obs, keep, letters, second, ephs, delays, grid.index[re])

    t0_gps = float(obs.epoch_t_int[0]) + obs.epoch_t_frac[0]
    week_hint = int(obs.epoch_t_int[0] // SECONDS_PER_WEEK)
    ref = read_reference(inputs.truth, week_hint=week_hint) if inputs.truth else None
    truth = log_truth(grid, t0_gps, ref, inputs.truth_max_gap_s, observations["epoch"].to_numpy(), rough)
    nav = _nav_info(obs, ephs, t0_gps, bool(second.has_l2.any()))
    second_used = {s: sorted(set(second.signal[(letters == s) & second.has_l2].tolist())) for s in used}
    used_text = "".join(used)
    meta = {
        "name": inputs.name or Path(obs.path).stem,
        "seed": 0,
        "source": "rinex",
        "files": {
            "obs": str(Path(obs.path)),
            "nav": ", ".join(paths["G"]),
            "nav_bds": ", ".join(paths["C"]),
            "nav_glo": ", ".join(paths["R"]),
            "nav_gal": ", ".join(paths["E"]),
            "truth": str(inputs.truth or ""),
        },
        "rinex_version": obs.version,
        "systems": used_text,
        "systems_asked": "".join(dict.fromkeys(systems)),
        "systems_used": used_text,
        "system_notes": notes,
        "unread_systems": obs.unread_systems,
        "signals": {s: obs.signals[s] for s in used},
        "second_signals": {s: codes for s, codes in second_used.items() if codes},
        "rows_without_ephemeris_or_code": int((~keep).sum()),
        "epochs_with_truth": len(truth),
        "epochs": grid.n,
        "static_truth": bool(ref is not None and ref.static),
        "corrections": "raw observables; Klobuchar (NavInfo) and Saastamoinen applied by the estimator model; "
        "sat_dcb: broadcast group delays of the second signals",
    }
    # absolute paths: tools run in their own working directory, and a cached scenario outlives the cwd
    rinex = RinexFiles(
        obs=os.path.abspath(obs.path),
        nav=tuple(dict.fromkeys(os.path.abspath(f) for s in used for f in paths[s])),
        systems=used_text,
    )
    return log_scenario(observations, truth, nav, meta, rinex=rinex)


def _navigation_plan(
    nav_path: NavPaths, nav_bds_path: NavPaths | None, nav_glo_path: NavPaths | None, nav_gal_path: NavPaths | None
) -> tuple[dict[str, tuple[str, ...]], dict[str, str]]:
    """The navigation files read for each system (its own, else ``nav``), and the setting that named them."""
    own = {
        "G": nav_paths(nav_path),
        "C": nav_paths(nav_bds_path),
        "R": nav_paths(nav_glo_path),
        "E": nav_paths(nav_gal_path),
        "J": (),
    }
    paths = {s: own[s] or own["G"] for s in own}
    settings = {s: f"scenario.{NAV_SETTINGS[s]}" if own[s] else "scenario.nav" for s in own}
    return paths, settings


def _usable_systems(
    obs: RinexObs,
    systems: str,
    used: list[str],
    keep: np.ndarray,
    letters: np.ndarray,
    paths: dict[str, tuple[str, ...]],
) -> tuple[list[str], list[str]]:
    """The systems of ``used`` with at least one row that has a satellite state (``keep``), and the notes
    on those left out (each said once as a warning); a one-line error when none is left."""
    used = list(used)
    notes = list(obs.system_notes)
    for s in list(used):
        if not keep[letters == s].any():
            used.remove(s)
            notes.append(f"no {SYSTEM_NAMES[s]} row has a broadcast ephemeris in {list(paths[s])}")
    if not used:
        raise SimbenchError(
            f"scenario.obs '{obs.path}'",
            f"no row of systems '{systems}' can be used: " + "; ".join(notes),
            "pass the navigation files of the observation day, or other scenario.systems",
        )
    asked, used_text = "".join(dict.fromkeys(systems)), "".join(used)
    notes = [f"asked {asked}, used {used_text}: {note}" for note in notes]
    for note in notes:
        warn("scenario.systems", note, "the run goes on without that system")
    return used, notes


@dataclass(frozen=True)
class SecondSignal:
    """The kept rows' carriers and second-frequency observables."""

    freq: np.ndarray  #: first carrier [Hz] (GLONASS: each satellite's FDMA channel)
    freq2: np.ndarray  #: second carrier [Hz], NaN without one
    code: np.ndarray  #: second code [m], NaN without one
    phase_cycles: np.ndarray  #: second phase [cycles]
    lli: np.ndarray  #: second signal's loss of lock, bool
    signal: np.ndarray  #: second signal's RINEX code ('' without one)
    has_l2: np.ndarray  #: a usable second code and carrier, bool


def _second_signal_rows(
    obs: RinexObs, keep: np.ndarray, letters: np.ndarray, ephs: dict[str, Ephemeris]
) -> SecondSignal:
    """Carriers and second-frequency observables of the rows ``keep`` (of systems ``letters``)."""
    no_l2 = np.full(obs.sat.size, np.nan)
    code_l2 = (obs.code_l2 if obs.code_l2 is not None else no_l2)[keep]
    phase_l2 = (obs.phase_l2_cycles if obs.phase_l2_cycles is not None else no_l2)[keep]
    lli_l2 = obs.lli_l2[keep] if obs.lli_l2 is not None else np.zeros(letters.size, bool)
    signal_l2 = obs.signal_l2[keep] if obs.signal_l2 is not None else np.full(letters.size, "")
    freq = np.array([SIGNALS[s][1] for s in letters.tolist()])
    glo = ephs.get("R")
    is_r = letters == "R"
    if isinstance(glo, GlonassEphemeris):  # FDMA: each satellite's own L1 carrier
        channel = dict(zip(glo.sats.tolist(), glo.freq_number.tolist()))
        freq[is_r] = glonass_l1_frequency(np.array([channel[s] for s in obs.sat[keep][is_r].tolist()]))
    freq2 = np.array([second_frequency(s, c) for s, c in zip(letters.tolist(), signal_l2.tolist())])
    freq2[is_r] = np.where(signal_l2[is_r] != "", freq[is_r] * GLO_F2_OVER_F1, np.nan)
    has_l2 = np.isfinite(code_l2) & np.isfinite(freq2)
    return SecondSignal(freq, freq2, code_l2, phase_l2, lli_l2, signal_l2, has_l2)


def _add_second_group_delays(
    observations: pd.DataFrame,
    obs: RinexObs,
    keep: np.ndarray,
    letters: np.ndarray,
    second: SecondSignal,
    ephs: dict[str, Ephemeris],
    delays: dict[str, GroupDelays],
    epoch: np.ndarray,
) -> None:
    """Add ``sat_dcb`` (the broadcast group delays of the second signals) and ``sat_dcb_sigma`` to the
    observation table, whose rows :func:`observation_table` sorted: aligned by (epoch, satellite)."""
    signal = np.where(second.has_l2, second.signal, "")
    dcb = second_group_delays(obs.sat[keep], signal, second.freq / second.freq2, ephs, delays)
    by_row = pd.Series(dcb, index=pd.MultiIndex.from_arrays([epoch, obs.sat[keep]]))
    rows = pd.MultiIndex.from_frame(observations[["epoch", "sat"]])
    observations["sat_dcb"] = by_row.reindex(rows).to_numpy()
    first = np.array([obs.signals[s] for s in letters.tolist()])
    sigma = second_group_delay_sigmas(obs.sat[keep], first, signal)
    observations["sat_dcb_sigma"] = pd.Series(sigma, index=by_row.index).reindex(rows).to_numpy()


def _nav_info(obs: RinexObs, ephs: dict[str, Ephemeris], t0_gps: float, dual_frequency: bool) -> NavInfo:
    """What the receiver decodes besides the observables: the GPS Klobuchar coefficients serve every
    system (the BDS ones are not in NavInfo's model)."""
    week = int(obs.epoch_t_int[0] // SECONDS_PER_WEEK)
    klob = ephs.get("G")
    alpha = klob.iono_alpha if klob is not None and klob.iono_alpha is not None else np.zeros(4)
    beta = klob.iono_beta if klob is not None and klob.iono_beta is not None else np.zeros(4)
    return NavInfo(
        gps_week=week,
        start_sow_s=t0_gps - week * SECONDS_PER_WEEK,
        iono_alpha=tuple(map(float, alpha)),
        iono_beta=tuple(map(float, beta)),
        dual_frequency=dual_frequency,
    )
