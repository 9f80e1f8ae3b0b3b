"""RINEX 3.04 observation and navigation files from a receiver's view of a scenario.

Observation file (:func:`write_rinex_obs`), one record per epoch, one line per satellite:

* observables per system: GPS ``C1C L1C D1C S1C`` (plus ``C2W L2W`` when the
  scenario is dual-frequency: the table has L2 code and phase but no L2 Doppler
  or C/N0), Galileo ``C1C L1C D1C S1C``, BeiDou ``C2I L2I D2I S2I`` (B1I); the
  signal codes are those the reader takes (:data:`simbench.data.rinex.SIGNALS`);
* values in RINEX's F14.3 (code and phase rounding <= 0.5 mm, Doppler 0.5 mHz,
  C/N0 0.0005 dB-Hz); phase in cycles (``phase_l1`` / wavelength);
* loss-of-lock digit (bit 0) on the phase field from ``lli_l1`` / ``lli_l2``;
  signal-strength digit ``clip(floor(C/N0 / 6), 1, 9)`` (RINEX 3.04 5.7) on the
  L1 fields;
* epoch tags: scenario start (``NavInfo``) plus ``t``, GPS time, 0.1 us. The
  simulator samples its observables at these true GPS times and puts the
  receiver clock offset ``dt_r`` into code and phase (truth ``rx_clock``); a
  real receiver would tag the same observables with its own clock, ``t +
  dt_r``. A tool that takes the transmit time as tag minus code / c
  (RTKLIB, :mod:`simbench.data.rinex`) therefore places each satellite
  ``v dt_r`` off (v < 4 km/s) and its range by the range rate times ``dt_r``:
  with the default clock (30 ns, 100 ppb drift) about 2 cm and 5 mm after
  60 s, 0.5 m and 0.1 m after 20 min. Tagging with ``t + dt_r`` would need
  the truth, which the receiver view does not hold.
* ``APPROX POSITION XYZ``: the median of single-point fixes from the code
  (:func:`simbench.gnss.spp.solve_epochs`), not the truth.

GLONASS rows are refused: their phase needs the frequency channel, which the
observation table does not carry.

Navigation file:

* nominal constellation (:func:`write_nominal_navigation`): the circular
  Kepler orbits of :class:`simbench.core.orbits.NominalConstellation` are
  broadcast elements exactly (IS-GPS-200 with ``e = omega = Delta n =
  OMEGADOT = IDOT = 0`` and no harmonics: ``sqrtA = sqrt(a)``, ``M0`` = argument
  of latitude at Toe, ``OMEGA0 = lambda(Toe) + Omega_e Toe`` from the node's
  Earth-fixed longitude, with the same GM 3.986005e14 and Omega_e as the
  simulator). One record per satellite every 2 h (Toe on even GPS hours)
  covers the span; clocks and TGD are zero as in the simulator (but for an
  af0 of 1e-15 s, :data:`NOMINAL_AF0_S`, that keeps RTKLIB from reading the
  clock as missing). The D19.12
  fields keep 13 significant digits, so the file reproduces the orbits to
  well under a millimetre (``tests/test_export.py``).
* broadcast constellation (:func:`write_broadcast_navigation`): the GPS
  records of the file the scenario used, rewritten as RINEX 3.04 with TGD set
  to zero: the generator's code carries ``dt_sv`` without TGD, while RTKLIB and
  :mod:`simbench.data.rinex` apply the L1 user correction ``dt_sv - TGD``.

The simulator's orbit/clock product error (``errors.orbit_clock``, 5 cm by
default) is in the observation table's satellite states but not in the
navigation file: a tool reading the files sees the orbits the signals came from.
"""

from __future__ import annotations

import datetime as dt
import math
import os
import warnings
from pathlib import Path

import lazy_loader
import numpy as np
import pandas as pd

from simbench.contract import NavInfo, ReceiverData
from simbench.core.constants import F_L1, F_L2, LAMBDA_L2, OMEGA_EARTH, SECONDS_PER_WEEK
from simbench.core.gpstime import datetime64_to_gps, gps_to_datetime64
from simbench.core.orbits import NominalConstellation
from simbench.data.rinex import SIGNALS
from simbench.errors import SimbenchError
from simbench.gnss.signals import l1_wavelength_m
from simbench.gnss.spp import ROUGH_FIX_MAX_RMS_M, solve_epochs

# xarray and georinex cost ~1 s to import: loaded on first use
georinex = lazy_loader.load("georinex")

__all__ = [
    "RINEX_VERSION",
    "L2_SIGNAL",
    "NAV_RECORD_FIELDS",
    "write_rinex_obs",
    "write_nominal_navigation",
    "write_broadcast_navigation",
    "nominal_broadcast_records",
    "epoch_tag",
    "approx_position",
]

RINEX_VERSION = "3.04"
#: GPS L2 signal code of the ``*_l2`` columns (semi-codeless P(Y), RINEX ``2W``).
L2_SIGNAL = "2W"
#: Systems whose first-frequency carrier is fixed (GLONASS FDMA needs the channel).
_WRITABLE = ("G", "E", "C")
#: Spacing of the nominal records' Toe (GPS broadcasts a new ephemeris every 2 h) [s].
NOMINAL_TOE_STEP_S = 7200.0
#: af0 of the nominal records [s]: the simulated clocks are perfect, but RTKLIB 2.4.3 takes a clock of
#: exactly 0 for a missing one and then sets the variance of the epoch's first satellite to (30 m)^2
#: (``satposs``, STD_BRDCCLK), down-weighting it; 1e-15 s is 0.3 um of range.
NOMINAL_AF0_S = 1e-15
#: Fields of a GPS navigation record in file order after the clock terms (RINEX 3.04 Table A8);
#: the names are georinex's.
NAV_RECORD_FIELDS: tuple[str, ...] = (
    "SVclockBias",
    "SVclockDrift",
    "SVclockDriftRate",
    "IODE",
    "Crs",
    "DeltaN",
    "M0",
    "Cuc",
    "Eccentricity",
    "Cus",
    "sqrtA",
    "Toe",
    "Cic",
    "Omega0",
    "Cis",
    "Io",
    "Crc",
    "omega",
    "OmegaDot",
    "IDOT",
    "CodesL2",
    "GPSWeek",
    "L2Pflag",
    "SVacc",
    "health",
    "TGD",
    "IODC",
    "TransTime",
    "FitIntvl",
)
#: Largest magnitude F14.3 can hold.
_F14_MAX = 9_999_999_999.999


def _header_line(content: str, label: str) -> str:
    return f"{content:<60.60s}{label}\n"


def epoch_tag(t_gps: float) -> tuple[str, int]:
    """Calendar fields of a GPS time for RINEX epoch lines, rounded to 0.1 us.

    Parameters
    ----------
    t_gps : float
        Continuous GPS seconds [s].

    Returns
    -------
    date : str
        ``'YYYY MM DD hh mm'`` (GPS time scale).
    sec_e7 : int
        Seconds of the minute times 1e7.
    """
    units = int(round(t_gps * 1e7))
    whole, frac = divmod(units, 10_000_000)
    stamp = pd.Timestamp(gps_to_datetime64(float(whole)).astype("datetime64[s]"))
    return stamp.strftime("%Y %m %d %H %M"), stamp.second * 10_000_000 + frac


def _f14(values: np.ndarray, what: str) -> list[str]:
    """F14.3 fields; blanks for NaN."""
    big = np.abs(values) > _F14_MAX
    if np.any(big & np.isfinite(values)):
        raise SimbenchError(
            "export",
            f"a {what} value of {values[big][0]:.0f} does not fit RINEX F14.3",
            "export observations of a receiver near the Earth",
        )
    return [" " * 14 if not math.isfinite(v) else f"{v:14.3f}" for v in values.tolist()]


def approx_position(data: ReceiverData) -> np.ndarray:
    """Median of the per-epoch single-point fixes of the code (receiver view) [m], shape (3,)."""
    obs = data.observations
    ok = np.isfinite(obs["code_l1"].to_numpy(float)) & np.isfinite(obs["sat_x"].to_numpy(float))
    o = obs[ok]
    epochs, row_epoch = np.unique(o["epoch"].to_numpy(), return_inverse=True)
    sat_pos = o[["sat_x", "sat_y", "sat_z"]].to_numpy(float)
    system_index = np.unique(o["sat"].str[0].to_numpy(), return_inverse=True)[1]
    fix = solve_epochs(
        row_epoch,
        sat_pos,
        o["code_l1"].to_numpy(float) + o["sat_clock"].to_numpy(float),
        n_epochs=epochs.size,
        system_index=system_index,
        max_rms_m=ROUGH_FIX_MAX_RMS_M,
    )
    if not fix.trusted.any():
        raise SimbenchError(
            "export",
            "no epoch of the observations gives a single-point fix",
            "export a scenario with at least 4 satellites at some epoch",
        )
    return np.median(fix.pos[fix.trusted], axis=0)


def _observables(systems: list[str], dual: bool) -> dict[str, list[str]]:
    types = {}
    for s in systems:
        band = SIGNALS[s][0]
        types[s] = [f"{o}{band}" for o in "CLDS"] + ([f"C{L2_SIGNAL}", f"L{L2_SIGNAL}"] if dual and s == "G" else [])
    return types


def write_rinex_obs(
    path: str | os.PathLike[str], data: ReceiverData, *, marker: str = "SIMBENCH", receiver: str = "simbench"
) -> Path:
    """Write the observation table of ``data`` as a RINEX 3.04 observation file.

    Parameters
    ----------
    path : str or PathLike
        Output file.
    data : ReceiverData
        The receiver's view (no truth is read).
    marker : str
        ``MARKER NAME`` (e.g. the scenario name).
    receiver : str
        Receiver type for ``REC # / TYPE / VERS`` (e.g. the receiver preset).

    Returns
    -------
    Path
        The observation file written (``path``).

    Raises
    ------
    SimbenchError
        An empty table, GLONASS rows, or a value that does not fit F14.3.
    """
    obs = data.observations.sort_values(["epoch", "sat"], kind="stable")
    if obs.empty:
        raise SimbenchError("export", "the scenario has no observations", "export a scenario with observations")
    letters = obs["sat"].str[0].to_numpy()
    systems = sorted(set(letters.tolist()))
    bad = [s for s in systems if s not in _WRITABLE]
    if bad:
        raise SimbenchError(
            "export",
            f"systems {bad} cannot be written (GLONASS phase needs the frequency "
            "channel, which the observation table lacks)",
            f"export a scenario of systems {''.join(_WRITABLE)} (scenario.systems)",
        )
    # GPS L2 rows only: a real log's L5 or other systems' second signals have no C2W column here
    l2_row = (letters == "G") & np.isclose(obs["f1_f2_ratio"].to_numpy(float), F_L1 / F_L2)
    dual = bool(data.nav.dual_frequency) and bool((l2_row & np.isfinite(obs["code_l2"].to_numpy(float))).any())
    types = _observables(systems, dual)
    t0_gps = data.nav.gps_week * SECONDS_PER_WEEK + data.nav.start_sow_s
    t = obs["t"].to_numpy(float)
    t_first, t_last = t0_gps + t.min(), t0_gps + t.max()
    epoch_t = np.unique(t)
    interval = float(np.median(np.diff(epoch_t))) if epoch_t.size > 1 else 1.0
    xyz = approx_position(data)

    system = systems[0] if len(systems) == 1 else "M"
    header = [
        _header_line(f"{RINEX_VERSION:>9s}{'':11s}{'OBSERVATION DATA':20s}{system:20s}", "RINEX VERSION / TYPE"),
        _header_line(
            f"{'simbench.data.export':20s}{'':20s}{dt.datetime.now(dt.timezone.utc):%Y%m%d %H%M%S} UTC",
            "PGM / RUN BY / DATE",
        ),
        _header_line("simulated by simbench (receiver view: no truth in this file)", "COMMENT"),
        _header_line(marker, "MARKER NAME"),
        _header_line("NON_GEODETIC", "MARKER TYPE"),
        _header_line(f"{'simbench':20s}{'simbench':40s}", "OBSERVER / AGENCY"),
        _header_line(f"{'0':20s}{receiver:20s}{'':20s}", "REC # / TYPE / VERS"),
        _header_line(f"{'0':20s}{'':20s}", "ANT # / TYPE"),
        _header_line("".join(f"{v:14.4f}" for v in xyz), "APPROX POSITION XYZ"),
        _header_line("".join(f"{0.0:14.4f}" for _ in range(3)), "ANTENNA: DELTA H/E/N"),
    ]
    for s in systems:
        names = types[s]
        for k in range(0, len(names), 13):
            lead = f"{s}  {len(names):3d}" if k == 0 else " " * 6
            header.append(_header_line(lead + "".join(f" {n}" for n in names[k : k + 13]), "SYS / # / OBS TYPES"))
    header.append(_header_line("DBHZ", "SIGNAL STRENGTH UNIT"))
    header.append(_header_line(f"{interval:10.3f}", "INTERVAL"))
    for t_gps, label in ((t_first, "TIME OF FIRST OBS"), (t_last, "TIME OF LAST OBS")):
        date, sec = epoch_tag(t_gps)
        fields = "".join(f"{int(v):6d}" for v in date.split())
        header.append(_header_line(f"{fields}{sec // 10_000_000:5d}.{sec % 10_000_000:07d}{'':5s}GPS", label))
    for s in systems:
        for name in types[s]:
            if name[0] == "L":
                header.append(_header_line(f"{s} {name}", "SYS / PHASE SHIFT"))
    header.append(_header_line("", "END OF HEADER"))

    n = len(obs)
    wavelength = l1_wavelength_m(obs["sat"].to_numpy())
    cn0 = obs["cn0_l1"].to_numpy(float)
    ssi = np.where(np.isfinite(cn0), np.clip(np.floor(np.nan_to_num(cn0) / 6.0), 1, 9), 0).astype(int)
    ssi_txt = np.where(ssi > 0, ssi.astype(str), " ")
    lli1 = np.where(obs["lli_l1"].to_numpy(bool), "1", " ")
    lli2 = np.where(obs["lli_l2"].to_numpy(bool), "1", " ")
    code1 = _f14(obs["code_l1"].to_numpy(float), "code_l1")
    phase1 = obs["phase_l1"].to_numpy(float) / wavelength
    phase1_txt = _f14(phase1, "phase_l1")
    dop1 = _f14(obs["doppler_l1"].to_numpy(float), "doppler_l1")
    cn01 = _f14(cn0, "cn0_l1")
    # the loss-of-lock digit is written even beside a blank phase, as receivers do (the Hong Kong u-blox log)
    cols = [
        f"{code1[i]} {ssi_txt[i]}{phase1_txt[i]}{lli1[i]}{ssi_txt[i]}{dop1[i]} {ssi_txt[i]}{cn01[i]}  "
        for i in range(n)
    ]
    if dual:
        code2 = _f14(np.where(l2_row, obs["code_l2"].to_numpy(float), np.nan), "code_l2")
        phase2 = _f14(np.where(l2_row, obs["phase_l2"].to_numpy(float), np.nan) / LAMBDA_L2, "phase_l2")
        cols = [c + (f"{code2[i]}  {phase2[i]}{lli2[i]} " if letters[i] == "G" else "") for i, c in enumerate(cols)]
    sats = obs["sat"].to_numpy()
    body = []
    epoch_of_row = obs["epoch"].to_numpy()
    starts = np.flatnonzero(np.r_[True, epoch_of_row[1:] != epoch_of_row[:-1]])
    stops = np.r_[starts[1:], n]
    for a, b in zip(starts.tolist(), stops.tolist()):
        date, sec = epoch_tag(t0_gps + t[a])
        body.append(f"> {date}{sec // 10_000_000:3d}.{sec % 10_000_000:07d}  0{b - a:3d}\n")
        body += [f"{sats[i]}{cols[i]}".rstrip() + "\n" for i in range(a, b)]
    out = Path(path)
    out.write_text("".join(header) + "".join(body))
    return out


# --------------------------------------------------------------------------- navigation


def _nav_header(nav: NavInfo) -> list[str]:
    return [
        _header_line(f"{RINEX_VERSION:>9s}{'':11s}{'N: GNSS NAV DATA':20s}{'G: GPS':20s}", "RINEX VERSION / TYPE"),
        _header_line(
            f"{'simbench.data.export':20s}{'':20s}{dt.datetime.now(dt.timezone.utc):%Y%m%d %H%M%S} UTC",
            "PGM / RUN BY / DATE",
        ),
        _header_line("GPSA " + "".join(f"{v:12.4E}" for v in nav.iono_alpha), "IONOSPHERIC CORR"),
        _header_line("GPSB " + "".join(f"{v:12.4E}" for v in nav.iono_beta), "IONOSPHERIC CORR"),
        _header_line("", "END OF HEADER"),
    ]


def _nav_records_text(sats: np.ndarray, toc_gps: np.ndarray, values: np.ndarray) -> list[str]:
    """RINEX 3.04 GPS records: ``values`` (R, 29) in :data:`NAV_RECORD_FIELDS` order, NaN written as 0."""
    out = []
    vals = np.nan_to_num(values)
    for sat, toc, row in zip(sats.tolist(), toc_gps.tolist(), vals):
        date, sec = epoch_tag(toc)
        fields = [f"{v:19.12E}" for v in row.tolist()]
        lines = [f"{sat} {date} {sec // 10_000_000:02d}" + "".join(fields[:3])]
        lines += ["    " + "".join(fields[k : k + 4]) for k in range(3, len(fields), 4)]
        out.append("\n".join(ln.rstrip() for ln in lines) + "\n")
    return out


def nominal_broadcast_records(constellation: NominalConstellation, toe_gps: np.ndarray) -> pd.DataFrame:
    """Broadcast elements that reproduce the nominal constellation's circular orbits exactly.

    Parameters
    ----------
    constellation : NominalConstellation
    toe_gps : np.ndarray, shape (k,)
        Reference times, continuous GPS seconds [s].

    Returns
    -------
    pandas.DataFrame
        One row per (Toe, satellite): ``sat``, ``toc_gps`` and the columns of
        :data:`NAV_RECORD_FIELDS` (radians, metres, seconds as RINEX wants).
    """
    toe = np.asarray(toe_gps, float)
    st = constellation.states(toe)
    a, si, ci = constellation.a_m, math.sin(constellation.incl_rad), math.cos(constellation.incl_rad)
    n = constellation.mean_motion_rad_s
    # z = a sin(u) sin(i) and vz = n a cos(u) sin(i) for a circular orbit; vz is the same in ECEF and inertial
    u = np.arctan2(st.pos[..., 2] / (a * si), st.vel[..., 2] / (n * a * si))
    # (x, y) is the in-plane (a cos u, a sin u cos i) turned by the node's Earth-fixed longitude
    lam = np.arctan2(st.pos[..., 1], st.pos[..., 0]) - np.arctan2(a * np.sin(u) * ci, a * np.cos(u))
    week = np.floor(toe / SECONDS_PER_WEEK)
    toe_sow = toe - week * SECONDS_PER_WEEK
    omega0 = np.angle(np.exp(1j * (lam + OMEGA_EARTH * toe_sow[:, None])))
    k, m = u.shape
    rows = pd.DataFrame({f: np.zeros(k * m) for f in NAV_RECORD_FIELDS})
    rows.insert(0, "sat", np.tile(constellation.sats, k))
    rows.insert(1, "toc_gps", np.repeat(toe, m))
    iod = np.repeat(np.mod(np.round(toe / NOMINAL_TOE_STEP_S), 256), m)
    rows["SVclockBias"] = NOMINAL_AF0_S
    rows["IODE"] = rows["IODC"] = iod
    rows["M0"] = np.angle(np.exp(1j * u)).ravel()
    rows["sqrtA"] = math.sqrt(a)
    rows["Toe"] = rows["TransTime"] = np.repeat(toe_sow, m)
    rows["Omega0"] = omega0.ravel()
    rows["Io"] = constellation.incl_rad
    rows["GPSWeek"] = np.repeat(week, m)
    rows["CodesL2"] = 1.0
    rows["SVacc"] = 2.0
    rows["FitIntvl"] = 4.0
    return rows


def write_nominal_navigation(path: str | os.PathLike[str], nav: NavInfo, t_first_gps: float, t_last_gps: float) -> Path:
    """Write broadcast records of the nominal constellation covering ``[t_first_gps, t_last_gps]``.

    Parameters
    ----------
    path : str or PathLike
    nav : NavInfo
        Klobuchar coefficients for the header.
    t_first_gps, t_last_gps : float
        Span to cover, continuous GPS seconds [s]; records every 2 h from the
        even hour at or before the start to the one at or after the end.

    Returns
    -------
    Path
    """
    k0 = math.floor(t_first_gps / NOMINAL_TOE_STEP_S)
    k1 = math.ceil(t_last_gps / NOMINAL_TOE_STEP_S)
    toe = np.arange(k0, k1 + 1) * NOMINAL_TOE_STEP_S
    rows = nominal_broadcast_records(NominalConstellation(), toe).sort_values(["sat", "toc_gps"], kind="stable")
    text = _nav_records_text(
        rows["sat"].to_numpy(), rows["toc_gps"].to_numpy(), rows[list(NAV_RECORD_FIELDS)].to_numpy(float)
    )
    out = Path(path)
    out.write_text("".join(_nav_header(nav)) + "".join(text))
    return out


def write_broadcast_navigation(path: str | os.PathLike[str], nav: NavInfo, source: str | os.PathLike[str]) -> Path:
    """Rewrite the GPS records of a RINEX 2/3 navigation file as RINEX 3.04 with TGD = 0 (module docstring).

    Parameters
    ----------
    path : str or PathLike
        Output file.
    nav : NavInfo
        Klobuchar coefficients for the header.
    source : str or PathLike
        The navigation file the scenario's orbits came from.

    Returns
    -------
    Path
        The navigation file written (``path``).

    Raises
    ------
    SimbenchError
        When ``source`` is missing or holds no GPS record.
    """
    src = os.fspath(source)
    if not os.path.isfile(src):
        raise SimbenchError(
            "scenario.constellation.nav_path",
            f"'{src}' does not exist",
            "regenerate the scenario from an existing navigation file",
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = georinex.load(src, use={"G"})
    missing = [f for f in NAV_RECORD_FIELDS if f not in ds and f != "FitIntvl"]
    if missing:
        raise SimbenchError(
            "scenario.constellation.nav_path",
            f"'{src}' has no GPS records with {missing[:3]}",
            "pass a RINEX GPS navigation file",
        )
    frame = ds.to_dataframe().reset_index()
    frame = frame[frame["sv"].astype(str).str.startswith("G") & frame["sqrtA"].notna()]
    values = np.stack(
        [frame[f].to_numpy(float) if f in frame else np.zeros(len(frame)) for f in NAV_RECORD_FIELDS], axis=1
    )
    values[:, NAV_RECORD_FIELDS.index("TGD")] = 0.0
    toc = datetime64_to_gps(frame["time"].to_numpy("datetime64[ns]"))
    text = _nav_records_text(frame["sv"].astype(str).to_numpy(), np.asarray(toc, float), values)
    out = Path(path)
    out.write_text("".join(_nav_header(nav)) + "".join(text))
    return out
