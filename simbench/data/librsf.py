"""The libRSF plain-text GNSS format (smartLoc, Chemnitz City datasets) as a Scenario.

Whitespace-separated lines, time in seconds::

    pseudorange3 t rho var_rho satX satY satZ satID [system] elevation_deg cn0
    odom3 t vx vy vz wx wy wz var_vx var_vy var_vz var_wx var_wy var_wz
    point3 t X Y Z c11 c12 ... c33

``range3`` and ``gt3`` are read as aliases of ``pseudorange3`` and ``point3``
(older smartLoc files). ``system`` is a bit flag (1 GPS, 2 SBAS, 4 GLONASS,
8 Galileo, 16 QZSS, 32 BeiDou); files without it are GPS-only. Satellite
positions are ECEF metres; the pseudoranges have the satellite clock and the
atmospheric delays already removed.

Mapping into the observation table (:data:`simbench.contract.OBSERVATION_COLUMNS`):

* ``sat_clock = 0`` (already applied) and :attr:`NavInfo.iono_corrected` set,
  so the shared model does not remove Klobuchar a second time;
* the shared model always subtracts a Saastamoinen/Niell hydrostatic delay, so
  the ingest adds that same modelled delay back to the code (at a rough
  receiver position). The two cancel to well under a centimetre; the wet delay
  state then estimates what the file's correction left over (about zero);
* no carrier phase or Doppler (NaN): the format has none, so estimators that
  need phase fail cleanly on these data;
* ``var_rho`` is kept out of the table (the contract has no column for a
  receiver-reported variance).

Odometry (body-frame speed and turn rate) has no place in the receiver view
(:class:`~simbench.contract.ReceiverData` carries observations and IMU only):
:func:`read_librsf` returns it as a table and :func:`load_librsf` records its
size in ``meta``; no estimator uses it yet.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from simbench.contract import NavInfo, Scenario
from simbench.data.reference import Reference, match_reference, read_reference, truth_table
from simbench.data.rinex import empty_imu, epoch_grid
from simbench.errors import SimbenchError
from simbench.sim.constants import DEG, SECONDS_PER_WEEK
from simbench.sim.frames import geodetic_from_ecef
from simbench.gnss.geometry import elevation_azimuth
from simbench.gnss.spp import ROUGH_FIX_MAX_RMS_M, solve_epochs
from simbench.gnss.troposphere import troposphere_terms
from simbench.sim.gpstime import day_of_year

__all__ = ["LibrsfLog", "read_librsf", "read_librsf_points", "load_librsf", "write_synthetic_librsf",
           "SYSTEM_LETTERS", "ODOMETRY_COLUMNS"]

#: libRSF system bit flag -> RINEX system letter.
SYSTEM_LETTERS: dict[int, str] = {1: "G", 2: "S", 4: "R", 8: "E", 16: "J", 32: "C"}
#: Columns of :attr:`LibrsfLog.odometry`.
ODOMETRY_COLUMNS: dict[str, str] = {
    "t": "s, time since the first pseudorange", "vx": "m/s, body-frame velocity x (forward)",
    "vy": "m/s, body y", "vz": "m/s, body z", "wx": "rad/s, turn rate about body x", "wy": "rad/s, about y",
    "wz": "rad/s, about z (yaw rate)", "var_vx": "(m/s)^2", "var_vy": "(m/s)^2", "var_vz": "(m/s)^2",
    "var_wx": "(rad/s)^2", "var_wy": "(rad/s)^2", "var_wz": "(rad/s)^2",
}
_KEYWORDS = {"pseudorange3": "range", "range3": "range", "odom3": "odom", "point3": "point", "gt3": "point"}
#: Epochs closer than this are one epoch [s].
_EPOCH_RESOLUTION_S = 1e-3


@dataclass(frozen=True)
class LibrsfLog:
    """The contents of a libRSF file.

    Attributes
    ----------
    t0 : float
        File time of the first pseudorange [s]; every ``t`` below is relative to it.
    ranges : pandas.DataFrame
        ``t, sat, rho, var_rho, sat_x, sat_y, sat_z, el, cn0`` [s, -, m, m^2, m, m, m, deg, dB-Hz].
    odometry : pandas.DataFrame
        :data:`ODOMETRY_COLUMNS`.
    reference : pandas.DataFrame
        ``t, x, y, z`` (ECEF metres).
    path : str
    """

    t0: float
    ranges: pd.DataFrame
    odometry: pd.DataFrame
    reference: pd.DataFrame
    path: str


def _rsf_error(path: str, problem: str) -> SimbenchError:
    return SimbenchError(f"scenario.obs '{path}'", problem,
                         "pass a libRSF GNSS text file (pseudorange3 / odom3 / point3 lines)")


def read_librsf(path: str | os.PathLike[str]) -> LibrsfLog:
    """Parse a libRSF GNSS text file.

    Parameters
    ----------
    path : str or PathLike

    Returns
    -------
    LibrsfLog

    Raises
    ------
    SimbenchError
        Missing file, unparsable lines, or no pseudorange line.
    """
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise _rsf_error(p, "file does not exist")
    try:
        raw = pd.read_csv(p, sep=r"\s+", header=None, names=list(range(15)), comment="#", engine="c",
                          dtype={0: str}, skip_blank_lines=True)
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as exc:
        raise _rsf_error(p, f"cannot be parsed ({str(exc).splitlines()[0][:60]})") from None
    kind = raw[0].map(_KEYWORDS)
    unknown = raw[0][kind.isna()].unique()
    if unknown.size:
        raise _rsf_error(p, f"has unknown line types {sorted(map(str, unknown))[:3]}")
    num = raw.iloc[:, 1:].apply(pd.to_numeric, errors="coerce").to_numpy(float)

    r = num[(kind == "range").to_numpy()]
    if r.shape[0] == 0:
        raise _rsf_error(p, "contains no pseudorange3 lines")
    n_fields = np.isfinite(r).sum(axis=1)
    if np.any(n_fields != n_fields[0]) or n_fields[0] not in (9, 10):
        raise _rsf_error(p, "pseudorange3 lines must all have 9 (no system) or 10 fields after the keyword")
    with_system = n_fields[0] == 10
    if not np.isfinite(r[:, 1]).all():
        raise _rsf_error(p, "has pseudorange3 lines without a pseudorange value")
    t0 = float(r[:, 0].min())
    prn = r[:, 6].astype(np.int64)
    flags = r[:, 7].astype(np.int64) if with_system else np.ones(len(r), np.int64)
    bad = sorted(set(flags.tolist()) - set(SYSTEM_LETTERS))
    if bad:
        raise _rsf_error(p, f"has unknown system flags {bad[:3]} (1 GPS, 2 SBAS, 4 GLONASS, 8 Galileo, 16 QZSS, 32 BeiDou)")
    letters = np.array([SYSTEM_LETTERS[f] for f in flags.tolist()])
    sat = np.char.add(letters, np.char.zfill(prn.astype(str), 2))
    k = 8 if with_system else 7
    ranges = pd.DataFrame({"t": r[:, 0] - t0, "sat": sat, "rho": r[:, 1], "var_rho": r[:, 2],
                           "sat_x": r[:, 3], "sat_y": r[:, 4], "sat_z": r[:, 5], "el": r[:, k], "cn0": r[:, k + 1]})

    o = num[(kind == "odom").to_numpy()][:, :13]
    odometry = pd.DataFrame(o, columns=list(ODOMETRY_COLUMNS))
    odometry["t"] -= t0
    g = num[(kind == "point").to_numpy()][:, :4]
    reference = pd.DataFrame(g, columns=["t", "x", "y", "z"])
    reference["t"] -= t0
    return LibrsfLog(t0=t0, ranges=ranges, odometry=odometry, reference=reference, path=p)


def load_librsf(path: str | os.PathLike[str], truth_path: str | os.PathLike[str] | None = None, *,
                gps_week: int, start_sow_s: float, name: str = "librsf",
                truth_max_gap_s: float = 2.0) -> Scenario:
    """Ingest a libRSF GNSS file as a Scenario.

    Parameters
    ----------
    path : str or PathLike
        libRSF file with pseudorange3 (and optionally odom3, point3) lines.
    truth_path : str or PathLike, optional
        A separate reference file (libRSF ``point3`` lines, e.g. a smartLoc
        ``*_GT.txt``, or the layouts of :func:`~simbench.data.reference.read_reference`);
        default: the ``point3`` lines of ``path``.
    gps_week, start_sow_s : int, float
        GPS time of file time 0 (the format carries no absolute time; only
        the Niell day of year and reference files in GPS time use it).
    name : str
        Scenario name.
    truth_max_gap_s : float
        Reference samples further apart than this are not interpolated [s].

    Returns
    -------
    Scenario
        ``labels=None``, empty IMU table, ``meta['odometry_rows']``.

    Raises
    ------
    SimbenchError
        From the readers, or when the reference does not overlap the log.
    """
    log = read_librsf(path)
    rg = log.ranges
    t_key = np.round(rg["t"].to_numpy() / _EPOCH_RESOLUTION_S).astype(np.int64)
    uniq, row_epoch = np.unique(t_key, return_inverse=True)
    t_epoch = uniq * _EPOCH_RESOLUTION_S
    interval = float(np.median(np.diff(t_epoch))) if t_epoch.size > 1 else 1.0
    grid = epoch_grid(t_epoch, interval)
    n_grid = int(grid[-1]) + 1
    sat_pos = rg[["sat_x", "sat_y", "sat_z"]].to_numpy(float)
    rho = rg["rho"].to_numpy(float)
    rx = solve_epochs(row_epoch, sat_pos, rho, n_epochs=t_epoch.size, max_rms_m=ROUGH_FIX_MAX_RMS_M,
                      fill_untrusted=True).pos
    el_rad, az_rad = (a[:, 0] for a in elevation_azimuth(rx[row_epoch], sat_pos[:, None, :]))
    el_file = rg["el"].to_numpy(float)
    el_deg = np.where(np.isfinite(el_file), el_file, np.degrees(el_rad))

    # Re-insert the modelled hydrostatic delay that the shared model subtracts (module docstring).
    t0_sow = start_sow_s + log.t0
    doy = day_of_year(gps_week, t0_sow)
    lat, _, h = geodetic_from_ecef(np.median(rx, axis=0))
    code = rho + troposphere_terms(el_deg * DEG, float(lat), float(h), doy)[0]

    n = len(rg)
    nan = np.full(n, np.nan)
    observations = pd.DataFrame({
        "epoch": grid[row_epoch], "t": t_epoch[row_epoch], "sat": rg["sat"].to_numpy(),
        "code_l1": code, "phase_l1": nan, "doppler_l1": nan, "cn0_l1": rg["cn0"].to_numpy(float),
        "lli_l1": np.zeros(n, bool), "code_l2": nan, "phase_l2": nan, "lli_l2": np.zeros(n, bool),
        "sat_x": sat_pos[:, 0], "sat_y": sat_pos[:, 1], "sat_z": sat_pos[:, 2],
        "sat_vx": nan, "sat_vy": nan, "sat_vz": nan, "sat_clock": np.zeros(n), "sat_clock_drift": np.zeros(n),
        "el": el_deg, "az": np.degrees(az_rad),
    }).sort_values(["epoch", "sat"], kind="stable").reset_index(drop=True)

    t_grid = np.arange(n_grid) * interval
    t_grid[grid] = t_epoch
    t_abs0 = gps_week * SECONDS_PER_WEEK + t0_sow
    if truth_path:
        ref = _external_reference(os.fspath(truth_path), gps_week, gps_week * SECONDS_PER_WEEK + start_sow_s)
    else:
        pts = log.reference
        if pts.empty:
            raise SimbenchError(f"scenario.obs '{log.path}'", "has no point3 reference lines and no scenario.truth",
                                "pass a reference with scenario.truth=... (libRSF point3 or week,TOW,lat,lon,h)")
        ref = Reference(t_gps=t_abs0 + pts["t"].to_numpy(float), xyz=pts[["x", "y", "z"]].to_numpy(float),
                        path=log.path)
    matched = match_reference(ref, t_abs0 + t_grid, truth_max_gap_s)
    counts = np.bincount(observations["epoch"].to_numpy(), minlength=n_grid)
    truth = truth_table(t_grid, matched, counts)

    nav = NavInfo(gps_week=gps_week, start_sow_s=t0_sow, iono_alpha=(0.0,) * 4, iono_beta=(0.0,) * 4,
                  dual_frequency=False, iono_corrected=True)
    meta = {
        "name": name, "seed": 0, "source": "librsf",
        "files": {"obs": str(Path(path)), "truth": str(truth_path or "")},
        "systems": "".join(sorted({s[0] for s in observations["sat"].unique().tolist()})),
        "epochs": n_grid, "epochs_with_truth": len(truth), "odometry_rows": len(log.odometry),
        "corrections": "satellite clock, ionosphere and troposphere removed in the file; the modelled "
                       "hydrostatic delay is added back for the shared model; no carrier phase",
    }
    return Scenario(observations=observations, imu=empty_imu(), truth=truth, labels=None, nav=nav, meta=meta)


def _external_reference(p: str, gps_week: int, t_file0_gps: float) -> Reference:
    """A reference from a separate file: libRSF point3 lines (file time; ``t_file0_gps`` is the
    GPS time of file time 0) or the CSV/SOW layouts (GPS time)."""
    if not os.path.isfile(p):
        raise SimbenchError(f"scenario.truth '{p}'", "file does not exist",
                            "pass a libRSF point3 file or a 'week,TOW,lat,lon,h' / 'SOW X Y Z' reference")
    with open(p, errors="replace") as fh:
        first = fh.readline().split()
    if first and first[0] in ("point3", "gt3"):
        pts = read_librsf_points(p)
        return Reference(t_gps=t_file0_gps + pts[:, 0], xyz=pts[:, 1:4], path=p)
    return read_reference(p, week_hint=gps_week)


def read_librsf_points(path: str) -> np.ndarray:
    """``point3`` lines of a libRSF ground-truth file as (k, 4) ``t X Y Z`` (file time) [s, m]."""
    raw = pd.read_csv(path, sep=r"\s+", header=None, usecols=range(5), comment="#", engine="c")
    return raw.iloc[:, 1:5].to_numpy(float)


def write_synthetic_librsf(path: str | os.PathLike[str], duration_s: float = 10.0, *, rate_hz: float = 1.0,
                           odometry_rate_hz: float = 10.0, start_gps_s: float = 2032 * SECONDS_PER_WEEK + 475_200.0,
                           code_sigma_m: float = 0.5, seed: int = 0) -> Path:
    """Write a synthetic libRSF GNSS file (test fixtures and the ingest benchmark).

    A car drives east at 10 m/s from Chemnitz (50.83 N, 12.92 E) under the
    nominal GPS constellation; pseudoranges are the Sagnac range plus a
    receiver clock (100 m + 1 m/s drift) plus white noise, i.e. already free
    of satellite clock and atmosphere as the format specifies. Satellites below
    10 deg are left out.

    Parameters
    ----------
    path : str or PathLike
    duration_s : float
        Length [s].
    rate_hz, odometry_rate_hz : float
        Pseudorange epoch and odometry rates [Hz].
    start_gps_s : float
        GPS time of file time 0, continuous seconds [s].
    code_sigma_m : float
        Pseudorange noise [m] (written as the variance column).
    seed : int

    Returns
    -------
    Path
    """
    from simbench.sim.frames import dcm_ned_to_ecef, ecef_from_geodetic
    from simbench.gnss.geometry import sagnac_range
    from simbench.sim.orbits import NominalConstellation

    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    lat, lon = 50.83 * DEG, 12.92 * DEG
    east = dcm_ned_to_ecef(lat, lon)[:, 1]
    rx = ecef_from_geodetic(lat, lon, 300.0)[None, :] + 10.0 * t[:, None] * east[None, :]
    st = NominalConstellation().states(start_gps_s + t)
    el, _ = elevation_azimuth(rx, st.pos)
    e_idx, s_idx = np.nonzero(el > 10.0 * DEG)
    sp = st.pos[e_idx, s_idx]
    rho = sagnac_range(sp, rx[e_idx]) + 100.0 + 1.0 * t[e_idx] + code_sigma_m * rng.standard_normal(e_idx.size)
    cn0 = 35.0 + 15.0 * np.sin(el[e_idx, s_idx])
    lines = [f"pseudorange3 {t[e]:.3f} {r:.3f} {code_sigma_m**2:.4f} {p[0]:.3f} {p[1]:.3f} {p[2]:.3f} {s + 1} 1 "
             f"{np.degrees(el[e, s]):.2f} {c:.1f}"
             for e, s, r, p, c in zip(e_idx.tolist(), s_idx.tolist(), rho, sp, cn0)]
    t_odo = np.arange(0.0, duration_s, 1.0 / odometry_rate_hz)
    v = 10.0 + 0.05 * rng.standard_normal(t_odo.size)
    lines += [f"odom3 {to:.3f} {vx:.4f} 0 0 0 0 {0.001 * rng.standard_normal():.6f} 0.01 0.01 0.01 1e-4 1e-4 1e-4"
              for to, vx in zip(t_odo, v)]
    lines += [f"point3 {ti:.3f} {x[0]:.4f} {x[1]:.4f} {x[2]:.4f} 0 0 0 0 0 0 0 0 0" for ti, x in zip(t, rx)]
    out = Path(path)
    out.write_text("\n".join(lines) + "\n")
    return out
