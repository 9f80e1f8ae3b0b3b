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
* elevation and azimuth from a per-epoch single-point solution (a receiver
  knows no reference; tens of metres of position error move an elevation by
  far less than a millidegree);
* carrier phase cycles times wavelength, Doppler in Hz, C/N0 from the ``S``
  observable, the loss-of-lock flag from bit 0 of the RINEX LLI digit.

Klobuchar and Saastamoinen are not applied here: the observation table holds
raw observables as the simulator's does, the header's Klobuchar coefficients
go into :class:`~simbench.contract.NavInfo`, and the shared measurement model
(:func:`estimators.measurement.prepare_ppp`) applies both.

GPS (``G``, L1 C/A; L2 into the ``*_l2`` columns when the file has one of
:data:`L2_SIGNALS`), GLONASS (``R``, L1 C/A FDMA: the wavelength of each
satellite from the frequency channel of its navigation record; orbits by
numerical integration, :mod:`simbench.core.glonass_orbits`), Galileo (``E``,
E1; clock minus BGD(E1,E5b), :mod:`simbench.core.galileo_orbits`) and BeiDou
(``C``, B1I; :mod:`simbench.data.beidou`) are supported. Navigation data of a
system come from its own file (``nav_glo``, ``nav_gal``, ``nav_bds``) when
given, else from ``nav``, which may be a mixed RINEX 3 file. With several
systems the single-point solution and the shared model give every non-GPS
system its own receiver clock offset (``PppObservations.system_index``),
which absorbs the system time offsets and inter-system biases.

The RINEX observation parser is our own fixed-column reader: georinex needs
~30 s for the Hong Kong log (7 s for GPS alone) and rounds epochs to
microseconds; this reader takes well under a second.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simbench.contract import NavInfo, RinexFiles, Scenario
from simbench.core.constants import C_LIGHT, F_L1, F_L2, LAMBDA_L2, SECONDS_PER_WEEK
from simbench.core.glonass_orbits import GLO_F1_BASE_HZ, GlonassEphemeris, glonass_l1_frequency
from simbench.core.gpstime import datetime64_to_gps, format_gps_time
from simbench.core.orbits import BroadcastEphemeris
from simbench.data.beidou import read_beidou_navigation
from simbench.data.galileo import read_galileo_navigation
from simbench.data.glonass import read_glonass_navigation
from simbench.data.logs import epoch_grid_of, log_scenario, log_truth, observation_table, rough_fix
from simbench.data.reference import read_reference
from simbench.errors import SimbenchError, warn
from simbench.gnss.navigation import SYSTEM_NAMES, read_gps_navigation, read_rinex_lines

__all__ = ["RinexObs", "read_rinex_obs", "load_rinex", "SIGNALS", "L2_SIGNALS", "NAV_SETTINGS"]

#: Observation code (band + attribute) used per system and the carrier frequency [Hz]:
#: GPS L1 C/A, GLONASS L1 C/A (channel 0; each satellite's channel k adds k * 0.5625 MHz),
#: Galileo E1 (RINEX 3 code 1C: E1-C pilot) and BeiDou B1I (RINEX 3 band 2).
SIGNALS: dict[str, tuple[str, float]] = {
    "G": ("1C", F_L1),
    "R": ("1C", GLO_F1_BASE_HZ),
    "E": ("1C", F_L1),
    "C": ("2I", 1_561.098e6),
}
#: GPS L2 signals read into the ``*_l2`` columns, first present wins (P(Y) semi-codeless, L2C M+L, M, L).
L2_SIGNALS: tuple[str, ...] = ("2W", "2X", "2L", "2S", "2P")
#: Config setting of each system's own navigation file (``nav`` serves GPS and, mixed, the others).
NAV_SETTINGS: dict[str, str] = {"G": "nav", "R": "nav_glo", "E": "nav_gal", "C": "nav_bds"}
_OBS_FIX = "pass a RINEX 3 observation file (.obs, .yyo, .rnx; also gzip or Hatanaka compressed)"
_CUT_FIX = "re-export the log, or delete the incomplete epoch record at the end"
_LINE_FIX = "make each epoch header's satellite count match its lines, or re-export the log"
#: Epoch time tags closer than this are one epoch (RINEX 3 writes 0.1 us) [s].
_SAME_EPOCH_S = 1e-7
#: Transit time used when no pseudorange is available for a satellite (keeps arrays finite) [s].
_TAU_NOMINAL_S = 0.075


@dataclass(frozen=True)
class RinexObs:
    """One signal per satellite from a RINEX 3 observation file, as flat rows.

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
        Pseudorange [m], carrier phase [cycles], Doppler [Hz], C/N0 [dB-Hz]; NaN when blank.
    lli : np.ndarray of bool, shape (N,)
        Bit 0 of the phase observation's loss-of-lock digit.
    code_l2, phase_l2_cycles : np.ndarray, shape (N,)
        GPS L2 pseudorange [m] and carrier phase [cycles] (first of :data:`L2_SIGNALS` in the file);
        NaN when blank, for other systems or when the file has no L2.
    lli_l2 : np.ndarray of bool, shape (N,)
        Bit 0 of the L2 phase's loss-of-lock digit.
    approx_position : np.ndarray, shape (3,)
        ``APPROX POSITION XYZ`` of the header (zeros when absent) [m].
    interval_s : float
        Nominal epoch interval (header ``INTERVAL`` or the median spacing) [s].
    path : str
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


def _obs_error(path: str, problem: str, fix: str = _OBS_FIX) -> SimbenchError:
    return SimbenchError(f"scenario.obs '{path}'", problem, fix)


def _float(text: str) -> float:
    text = text.strip()
    return float(text) if text else np.nan


def read_rinex_obs(path: str | os.PathLike[str], systems: str = "G") -> RinexObs:
    """Read the signals of :data:`SIGNALS` from a RINEX 3 observation file.

    Parameters
    ----------
    path : str or PathLike
        RINEX 3.0x observation file, time system GPS: plain text with any line
        ending, or gzip / Hatanaka compressed (:func:`~simbench.gnss.navigation.read_rinex_lines`).
    systems : str
        System letters to keep; each needs an entry in :data:`SIGNALS`.

    Returns
    -------
    RinexObs

    Raises
    ------
    SimbenchError
        Missing file, not RINEX 3 observation data, a time system other than
        GPS, no pseudorange observable for the requested systems, or no data;
        a cut file (an epoch with fewer satellite lines than its header
        announces, a line ending inside a number), a satellite count that does
        not match the lines, epochs out of time order. The message names the line.

    Warns
    -----
    SimbenchWarning
        Epoch records that repeat an earlier time tag, or a satellite repeated
        within one epoch: the first record is kept.
    """
    p = os.fspath(path)
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
    version, kind = lines[0][:9].strip(), lines[0][20:21]
    if kind != "O" or not version.startswith("3"):
        raise _obs_error(p, f"is RINEX {version} type '{kind}', not RINEX 3 observation data")

    types: dict[str, list[str]] = {}
    approx = np.zeros(3)
    interval = np.nan
    last_sys = ""
    body = None
    for i, ln in enumerate(lines):
        label = ln[60:].strip()
        if label == "SYS / # / OBS TYPES":
            if ln[0] != " ":
                last_sys = ln[0]
                types[last_sys] = []
            types[last_sys] += ln[7:60].split()
        elif label == "APPROX POSITION XYZ":
            approx = np.array([_float(ln[k : k + 14]) for k in (0, 14, 28)])
        elif label == "INTERVAL":
            interval = _float(ln[:10])
        elif label == "TIME OF FIRST OBS":
            tsys = ln[48:51].strip()
            if tsys not in ("GPS", ""):
                raise _obs_error(p, f"time system {tsys} is not supported", "convert the file to GPS time")
        elif label == "END OF HEADER":
            body = i + 1
            break
    if body is None:
        raise _obs_error(p, "has no END OF HEADER line")

    # Column of each wanted observable per system (16 characters per field after the 3-char sat id).
    cols: dict[str, tuple[int, int, int, int, int, int]] = {}
    for s in systems:
        band = SIGNALS[s][0]
        have = types.get(s, [])
        if f"C{band}" not in have:
            continue
        l2 = next((b for b in L2_SIGNALS if f"C{b}" in have), None) if s == "G" else None
        cols[s] = tuple(
            have.index(f"{o}{b}") if b is not None and f"{o}{b}" in have else -1  # type: ignore[assignment]
            for o, b in (("C", band), ("L", band), ("D", band), ("S", band), ("C", l2), ("L", l2))
        )
    if not cols:
        wanted = ", ".join(f"{s}: C{SIGNALS[s][0]}" for s in systems)
        raise _obs_error(
            p,
            f"has no pseudorange observable for the requested systems ({wanted})",
            "pass a file with code observations, or other scenario.systems",
        )

    stamps: list[str] = []
    fracs: list[float] = []
    e_line: list[int] = []  #: 1-based line number of each epoch header
    r_epoch: list[int] = []
    r_sat: list[str] = []
    r_num: list[list[float]] = []  #: code, phase, Doppler, C/N0, L2 code, L2 phase per row
    r_lli: list[tuple[bool, bool]] = []  #: L1 and L2 loss-of-lock flags per row
    i, n_lines = body, len(lines)
    while i < n_lines:  # text parsing: one Python step per line is unavoidable
        ln = lines[i]
        i += 1
        if not ln.startswith(">"):
            if not ln.strip():
                continue
            where = (
                f"the epoch at line {e_line[-1]} announces fewer satellites" if e_line else "no epoch header before it"
            )
            raise _obs_error(p, f"line {i} is outside any epoch record ({where}): '{ln[:20].strip()}'", _LINE_FIX)
        try:
            flag = int(ln[31:32].strip() or 0)
            count = int(ln[32:35])
            if flag > 1:  # event records carry header lines, not observations
                i += count
                continue
            f = ln[1:29].split()
            whole, _, frac = f[5].partition(".")
            stamps.append(
                f"{int(f[0]):04d}-{int(f[1]):02d}-{int(f[2]):02d}T{int(f[3]):02d}:{int(f[4]):02d}:{int(whole):02d}"
            )
            fracs.append(float("0." + frac) if frac else 0.0)
        except (ValueError, IndexError):
            raise _obs_error(p, f"has a malformed epoch line {i}: '{ln[:35].strip()}'", _LINE_FIX) from None
        e_line.append(i)
        e = len(stamps) - 1
        block = lines[i : i + count]
        # a record with fewer satellite lines than announced: the file was cut, or lines were lost
        short = next((k for k, b in enumerate(block) if b.startswith(">")), len(block))
        if short == len(block) < count:
            raise _obs_error(
                p,
                f"epoch at line {i} announces {count} satellites but the file ends after {short} (cut file)",
                _CUT_FIX,
            )
        if short < count:
            raise _obs_error(
                p,
                f"epoch at line {i} announces {count} satellites but the next epoch header follows "
                f"after {short} (line {i + short + 1})",
                _LINE_FIX,
            )
        for row, ln in enumerate(block, start=i + 1):
            c = cols.get(ln[:1])
            if c is None:
                continue
            # fields are right-aligned F14.3 plus 2 flag columns: a line ending inside a number was cut
            if 0 < (len(ln) - 3) % 16 < 14:
                raise _obs_error(p, f"line {row} ends inside an observation field (cut line)", _CUT_FIX)
            try:
                r_num.append([_float(ln[3 + 16 * k : 17 + 16 * k]) if k >= 0 else np.nan for k in c])
            except ValueError:
                raise _obs_error(p, f"line {row} has a malformed observation: '{ln[:40].strip()}'", _LINE_FIX) from None
            l1, l2 = (ln[17 + 16 * j : 18 + 16 * j].strip() if j >= 0 else "" for j in (c[1], c[5]))
            r_epoch.append(e)
            r_sat.append(ln[:3].replace(" ", "0"))
            r_lli.append((bool(int(l1) & 1) if l1.isdigit() else False, bool(int(l2) & 1) if l2.isdigit() else False))
        i += count
    if not r_epoch:
        raise _obs_error(p, f"contains no observations of systems '{systems}'")
    t_int = datetime64_to_gps(np.array(stamps, dtype="datetime64[s]")).astype(np.int64)
    t_frac = np.array(fracs)
    row_epoch = np.array(r_epoch, dtype=np.int64)
    sat = np.array(r_sat)
    epochs, rows = _first_records(p, t_int, t_frac, np.array(e_line), row_epoch, sat)
    renumber = np.full(t_int.size, -1, np.int64)
    renumber[epochs] = np.arange(epochs.size)
    t_int, t_frac, row_epoch, sat = t_int[epochs], t_frac[epochs], renumber[row_epoch[rows]], sat[rows]
    vals = np.array(r_num, dtype=float)[rows]
    flags = np.array(r_lli, dtype=bool)[rows]
    code = vals[:, 0]
    if not np.isfinite(code).any():
        raise _obs_error(
            p, "has no pseudorange values (all code fields are blank)", "pass a file with code observations"
        )
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
        approx_position=approx,
        interval_s=float(interval),
        path=p,
        code_l2=vals[:, 4],
        phase_l2_cycles=vals[:, 5],
        lli_l2=flags[:, 1],
    )


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


Ephemeris = BroadcastEphemeris | GlonassEphemeris
#: Navigation reader of each system but GPS, called with ``(path, setting=...)``.
_READERS: dict[str, Callable[..., Ephemeris]] = {
    "R": read_glonass_navigation,
    "E": read_galileo_navigation,
    "C": read_beidou_navigation,
}


def _load_ephemeris(nav_path: str, own_file: bool, obs: RinexObs, system: str) -> Ephemeris:
    """Ephemeris of one system from ``nav_path``, checked to cover the whole observation span.

    ``own_file`` says whether ``nav_path`` is the system's own setting or ``scenario.nav`` standing in for it.
    """
    key = f"scenario.{NAV_SETTINGS[system]}"
    if not nav_path:
        raise SimbenchError(
            key,
            f"no {SYSTEM_NAMES[system]} navigation file given",
            f"set {key} to a RINEX navigation file holding {SYSTEM_NAMES[system]} records, "
            "or scenario.nav to a mixed RINEX 3 navigation file",
        )
    setting = key if own_file else f"scenario.nav (no {key} given)"
    eph = read_gps_navigation(nav_path) if system == "G" else _READERS[system](nav_path, setting=setting)
    t0 = float(obs.epoch_t_int[0]) + obs.epoch_t_frac[0]
    t1 = float(obs.epoch_t_int[-1]) + obs.epoch_t_frac[-1]
    lo, hi = eph.t_coverage
    if t0 < lo or t1 > hi:
        raise SimbenchError(
            f"{setting} '{nav_path}'",
            f"covers {format_gps_time(lo)} .. {format_gps_time(hi)} GPS with its "
            f"{SYSTEM_NAMES[system]} records, the observations span {format_gps_time(t0)} .. "
            f"{format_gps_time(t1)} GPS",
            "pass the navigation file of the observation day",
        )
    return eph


def satellite_states(obs: RinexObs, ephs: dict[str, Ephemeris]) -> dict[str, np.ndarray]:
    """Per-row satellite state at transmit time (NaN where the ephemeris has no record)."""
    out = {k: np.full(obs.sat.size, np.nan) for k in ("x", "y", "z", "vx", "vy", "vz", "clock", "drift")}
    n = obs.epoch_t_int.size
    for eph in ephs.values():
        m = eph.sats.size
        col = {s: j for j, s in enumerate(eph.sats.tolist())}
        j = np.array([col.get(s, -1) for s in obs.sat.tolist()])
        has = (j >= 0) & np.isfinite(obs.code)
        e_r, j_r = obs.row_epoch[has], j[has]
        # (epoch, satellite) grid of transit offsets relative to the whole-second tag.
        tau = np.full((n, m), _TAU_NOMINAL_S)
        tau[e_r, j_r] = obs.code[has] / C_LIGHT
        t_ref = obs.epoch_t_int.astype(float)
        base = obs.epoch_t_frac[:, None] - tau
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
    nav_path: str | os.PathLike[str],
    truth_path: str | os.PathLike[str] | None = None,
    *,
    systems: str = "G",
    nav_bds_path: str | os.PathLike[str] | None = None,
    nav_glo_path: str | os.PathLike[str] | None = None,
    nav_gal_path: str | os.PathLike[str] | None = None,
    name: str = "rinex",
    truth_max_gap_s: float = 2.0,
) -> Scenario:
    """Ingest a RINEX 3 observation file, its navigation file and a reference trajectory.

    Parameters
    ----------
    obs_path : str or PathLike
        RINEX 3 observation file.
    nav_path : str or PathLike
        RINEX 2/3 GPS navigation file covering the observation span, or a mixed
        RINEX 3 file that also serves the systems without a file of their own.
    truth_path : str or PathLike, optional
        Reference trajectory (``week,TOW,lat,lon,h`` CSV or ``SOW X Y Z``); see
        :func:`simbench.data.reference.read_reference`. Without it the truth
        table is empty (nothing can be scored).
    systems : str
        Systems to ingest, letters of ``'GREC'`` (GPS, GLONASS, Galileo, BeiDou).
    nav_bds_path, nav_glo_path, nav_gal_path : str or PathLike, optional
        RINEX 3 BeiDou, GLONASS, Galileo navigation files; when one is not
        given, the records of that system come from ``nav_path``.
    name : str
        Scenario name for the result tables.
    truth_max_gap_s : float
        Reference samples further apart than this are not interpolated [s].

    Returns
    -------
    Scenario
        Observations in the simulator's columns, ``truth`` with one row per
        epoch that the reference covers (epochs on the nominal grid of the
        log's interval), ``labels=None`` and an empty IMU table.
    """
    obs = read_rinex_obs(obs_path, systems)
    own = {
        "G": os.fspath(nav_path or ""),
        "C": os.fspath(nav_bds_path or ""),
        "R": os.fspath(nav_glo_path or ""),
        "E": os.fspath(nav_gal_path or ""),
    }
    # the navigation file actually read for each system
    paths = {s: own[s] or own["G"] for s in own}
    ephs = {s: _load_ephemeris(paths[s], bool(own[s]), obs, s) for s in systems}
    st = satellite_states(obs, ephs)
    keep = np.isfinite(st["x"])
    n_dropped = int((~keep).sum())

    t_rel_epoch = (obs.epoch_t_int - obs.epoch_t_int[0]) + (obs.epoch_t_frac - obs.epoch_t_frac[0])
    grid = epoch_grid_of(t_rel_epoch, obs.interval_s)
    re = obs.row_epoch[keep]
    sat_pos = np.stack([st[k][keep] for k in "xyz"], axis=1)
    corrected = obs.code[keep] + st["clock"][keep]
    letters = np.array([s[:1] for s in obs.sat[keep].tolist()])
    system_index = np.searchsorted(np.array(sorted(set(systems))), letters)
    x0 = obs.approx_position if obs.approx_position is not None and np.any(obs.approx_position) else None
    rough = rough_fix(re, sat_pos, corrected, n_epochs=obs.epoch_t_int.size, system_index=system_index, x0=x0)
    no_l2 = np.full(obs.sat.size, np.nan)
    code_l2 = obs.code_l2 if obs.code_l2 is not None else no_l2
    phase_l2 = obs.phase_l2_cycles if obs.phase_l2_cycles is not None else no_l2
    lli_l2 = obs.lli_l2 if obs.lli_l2 is not None else np.zeros(obs.sat.size, bool)
    freq = np.array([SIGNALS[s[0]][1] for s in obs.sat[keep].tolist()])
    glo = ephs.get("R")
    if isinstance(glo, GlonassEphemeris):  # FDMA: each satellite's own L1 carrier
        is_r = letters == "R"
        channel = dict(zip(glo.sats.tolist(), glo.freq_number.tolist()))
        freq[is_r] = glonass_l1_frequency(np.array([channel[s] for s in obs.sat[keep][is_r].tolist()]))
    observations = observation_table(
        {
            "epoch": grid.index[re],
            "t": t_rel_epoch[re],
            "sat": obs.sat[keep],
            "code_l1": obs.code[keep],
            "phase_l1": obs.phase_cycles[keep] * (C_LIGHT / freq),
            "doppler_l1": obs.doppler_hz[keep],
            "cn0_l1": obs.cn0_dbhz[keep],
            "lli_l1": obs.lli[keep],
            "code_l2": code_l2[keep],
            "phase_l2": phase_l2[keep] * LAMBDA_L2,
            "lli_l2": lli_l2[keep],
            "f1_f2_ratio": np.where(np.isfinite(code_l2[keep]), F_L1 / F_L2, np.nan),
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

    t0_gps = float(obs.epoch_t_int[0]) + obs.epoch_t_frac[0]
    week_hint = int(obs.epoch_t_int[0] // SECONDS_PER_WEEK)
    ref = read_reference(truth_path, week_hint=week_hint) if truth_path else None
    truth = log_truth(grid, t0_gps, ref, truth_max_gap_s, observations["epoch"].to_numpy(), rough)

    week = int(obs.epoch_t_int[0] // SECONDS_PER_WEEK)
    # GPS Klobuchar for every system (the BDS coefficients are not in NavInfo's model)
    klob = ephs.get("G")
    alpha = klob.iono_alpha if klob is not None and klob.iono_alpha is not None else np.zeros(4)
    beta = klob.iono_beta if klob is not None and klob.iono_beta is not None else np.zeros(4)
    nav = NavInfo(
        gps_week=week,
        start_sow_s=t0_gps - week * SECONDS_PER_WEEK,
        iono_alpha=tuple(map(float, alpha)),
        iono_beta=tuple(map(float, beta)),
        dual_frequency=bool(np.isfinite(code_l2[keep]).any()),
    )
    meta = {
        "name": name,
        "seed": 0,
        "source": "rinex",
        "files": {
            "obs": str(Path(obs_path)),
            "nav": paths["G"],
            "nav_bds": paths["C"],
            "nav_glo": paths["R"],
            "nav_gal": paths["E"],
            "truth": str(truth_path or ""),
        },
        "systems": systems,
        "signals": {s: SIGNALS[s][0] for s in systems},
        "rows_without_ephemeris_or_code": n_dropped,
        "epochs_with_truth": len(truth),
        "epochs": grid.n,
        "corrections": "raw observables; Klobuchar (NavInfo) and Saastamoinen applied by the estimator model",
    }
    # absolute paths: tools run in their own working directory, and a cached scenario outlives the cwd
    rinex = RinexFiles(
        obs=os.path.abspath(obs_path),
        nav=tuple(dict.fromkeys(os.path.abspath(paths[s]) for s in systems if paths.get(s))),
        systems=systems,
    )
    return log_scenario(observations, truth, nav, meta, rinex=rinex)
