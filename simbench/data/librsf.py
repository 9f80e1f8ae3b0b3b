"""The libRSF plain-text GNSS format (smartLoc, Chemnitz City datasets) as a Scenario.

Whitespace-separated lines, time in seconds::

    pseudorange3 t rho var_rho satX satY satZ satID [system] elevation_deg cn0
    odom3 t vx vy vz wx wy wz var_vx var_vy var_vz var_wx var_wy var_wz
    point3 t X Y Z c11 c12 ... c33

``range3`` and ``gt3`` are read as aliases of ``pseudorange3`` and ``point3``
(older smartLoc files). ``system`` is a bit flag (1 GPS, 2 SBAS, 4 GLONASS,
8 Galileo, 16 QZSS, 32 BeiDou; the smartLoc-RTKLIB readme of TUC-ProAut/libRSF);
files without it are GPS-only. Files converted with RTKLIB (smartLoc-RTKLIB)
give GLONASS satellites RTKLIB's satellite number, 32 + slot (GPS takes 1..32):
a GLONASS ID above 32 is read as slot ID - 32. Satellite positions are ECEF
metres; the pseudoranges have the satellite clock and the atmospheric delays
already removed. ``#`` starts a comment.

Mapping into the observation table (:data:`simbench.contract.OBSERVATION_COLUMNS`):

* ``sat`` is the system letter and the PRN/slot ('G05', 'R12'), so every
  system gets its own receiver clock (inter-system bias) in the shared model
  and in the reader's own single-point fix;
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

Mapping ``odom3`` into the odometry table (:data:`simbench.contract.ODOMETRY_COLUMNS`):
libRSF's vehicle frame is x forward, y left, z up (its ``OdometryModel4DOFECEF``
turns about the local up axis; in the smartLoc Berlin log a positive ``wz``
comes with a heading turning anticlockwise), the contract's is x forward,
y right, z down, so ``speed = vx``, ``vel_right = -vy``, ``vel_down = -vz``,
``roll_rate = wx``, ``pitch_rate = -wy`` and ``yaw_rate = -wz``. Columns 9-14 are
their variances ((m/s)^2, (rad/s)^2; smartLoc writes 0.0025, 0.0009, 0.0009 for the
velocities, 4e-6 for the turn rates): every component is carried. ``vy = vz = 0`` in
smartLoc is the car's non-holonomic constraint at the vehicle's own variance, which the
GNSS estimators apply in place of their road-grade and sideways defaults.
"""

from __future__ import annotations

import io
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from simbench.contract import ODOMETRY_COLUMNS, NavInfo, Scenario
from simbench.core.constants import DEG, SECONDS_PER_WEEK
from simbench.core.frames import dcm_ned_to_ecef, ecef_from_geodetic, geodetic_from_ecef
from simbench.core.gpstime import day_of_year
from simbench.core.orbits import NominalConstellation
from simbench.data.logs import EpochGrid, RoughFix, epoch_grid_of, log_scenario, log_truth, observation_table, rough_fix
from simbench.data.reference import Reference, read_reference
from simbench.errors import SimbenchError
from simbench.gnss.geometry import elevation_azimuth, sagnac_range
from simbench.gnss.troposphere import troposphere_terms

__all__ = [
    "LibrsfLog",
    "read_librsf",
    "read_librsf_points",
    "load_librsf",
    "write_synthetic_librsf",
    "SYSTEM_LETTERS",
    "SYSTEM_FLAGS",
]

#: libRSF system bit flag -> RINEX system letter.
SYSTEM_LETTERS: dict[int, str] = {1: "G", 2: "S", 4: "R", 8: "E", 16: "J", 32: "C"}
#: RINEX system letter -> libRSF system bit flag.
SYSTEM_FLAGS: dict[str, int] = {v: k for k, v in SYSTEM_LETTERS.items()}
#: RTKLIB numbers GLONASS satellites after the 32 GPS ones (module docstring).
RTKLIB_GLONASS_OFFSET = 32
_KEYWORDS = {"pseudorange3": "range", "range3": "range", "odom3": "odom", "point3": "point", "gt3": "point"}
_FIX = "pass a libRSF GNSS text file (pseudorange3 / odom3 / point3 lines)"
#: Epochs closer than this are one epoch [s].
_EPOCH_RESOLUTION_S = 1e-3
#: The synthetic writer's stand-in for GLONASS: the nominal GPS constellation this much later
#: (another sky); the format carries satellite positions, not orbits [s].
_STANDIN_SHIFT_S = 4 * 3600.0


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
        :data:`simbench.contract.ODOMETRY_COLUMNS` (body frame x forward, y right, z down), by time.
    reference : pandas.DataFrame
        ``t, x, y, z`` (ECEF metres).
    path : str
    """

    t0: float
    ranges: pd.DataFrame
    odometry: pd.DataFrame
    reference: pd.DataFrame
    path: str


def _rsf_error(path: str, problem: str, line: int | None = None) -> SimbenchError:
    where = f"scenario.obs '{path}'" + (f" line {line}" if line is not None else "")
    return SimbenchError(where, problem, _FIX)


def _read_table(p: str) -> tuple[pd.DataFrame, np.ndarray]:
    """The non-blank, comment-free lines as a table of up to 15 tokens, and their 1-based line numbers."""
    try:
        with open(p, encoding="utf-8") as fh:
            content = [ln.split("#", 1)[0] for ln in fh.read().splitlines()]
    except UnicodeDecodeError:
        raise _rsf_error(p, "is not a text file") from None
    keep = [i for i, c in enumerate(content) if c.strip()]
    if not keep:
        raise _rsf_error(p, "contains no pseudorange3 lines")
    line_no = np.asarray(keep, np.int64) + 1
    try:
        raw = pd.read_csv(
            io.StringIO("\n".join(content[i] for i in keep)),
            sep=r"\s+",
            header=None,
            names=list(range(15)),
            engine="c",
            dtype={0: str},
            # only a missing field is NaN: a written 'nan' must reach the number check with its line
            keep_default_na=False,
            na_values=[""],
        )
    except (pd.errors.ParserError, ValueError) as exc:
        msg = str(exc).splitlines()[0]
        row = re.search(r"line (\d+)", msg)
        line = int(line_no[int(row.group(1)) - 1]) if row and int(row.group(1)) <= len(line_no) else None
        raise _rsf_error(
            p,
            "has more than 14 values after the keyword" if "Expected" in msg else f"cannot be parsed ({msg[:60]})",
            line,
        ) from None
    return raw, line_no


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
        Missing file, no pseudorange line, or a malformed line: unknown line
        type, wrong number of values, a value that is not a number, an unknown
        satellite system flag, a satellite ID that is not a positive integer,
        a pseudorange variance <= 0, a negative odometry variance or a zero
        speed or yaw-rate variance. The message names the first bad line.
    """
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise _rsf_error(p, "file does not exist")
    raw, line_no = _read_table(p)
    kind = raw[0].map(_KEYWORDS).to_numpy()
    unknown = np.flatnonzero(pd.isna(kind))
    if unknown.size:
        names = sorted(set(raw[0].iloc[unknown].astype(str)))
        raise _rsf_error(
            p,
            f"has unknown line types {names[:3]} (known: pseudorange3, range3, odom3, point3, gt3)",
            int(line_no[unknown[0]]),
        )
    present = raw.iloc[:, 1:].notna().to_numpy()
    num = raw.iloc[:, 1:].apply(pd.to_numeric, errors="coerce").to_numpy(float)
    not_number = np.argwhere(present & ~np.isfinite(num))
    if not_number.size:
        i, j = not_number[0]
        raise _rsf_error(p, f"field {j + 2} ('{raw.iat[i, j + 1]}') is not a finite number", int(line_no[i]))
    lines = _RsfLines(p, kind, num, present.sum(axis=1), line_no)
    ranges, t0 = _range_table(lines)
    odometry = _odometry_table(lines, t0)
    gi = lines.rows("point")
    if (lines.n_values[gi] < 4).any():
        raise _rsf_error(
            p, "point3 needs at least 4 values after the keyword (t X Y Z)", lines.first_bad(gi, lines.n_values[gi] < 4)
        )
    reference = pd.DataFrame(num[gi][:, :4], columns=["t", "x", "y", "z"])
    reference["t"] -= t0
    return LibrsfLog(t0=t0, ranges=ranges, odometry=odometry, reference=reference, path=p)


@dataclass(frozen=True)
class _RsfLines:
    """The lines of a libRSF file as numbers, with what their errors name."""

    path: str
    kind: np.ndarray  #: 'range', 'odom' or 'point' per line
    num: np.ndarray  #: the values after the keyword, NaN where absent
    n_values: np.ndarray  #: how many values each line has
    line_no: np.ndarray  #: the file's line number of each line

    def rows(self, kind: str) -> np.ndarray:
        return np.flatnonzero(self.kind == kind)

    def first_bad(self, rows: np.ndarray, bad: np.ndarray) -> int:
        """The file's line number of the first of ``rows`` where ``bad``."""
        return int(self.line_no[rows[np.flatnonzero(bad)[0]]])


def _range_table(lines: _RsfLines) -> tuple[pd.DataFrame, float]:
    """The ``pseudorange3`` lines as a table (time since the first of them) and that first time [s]."""
    p = lines.path
    ri = lines.rows("range")
    if ri.size == 0:
        raise _rsf_error(p, "contains no pseudorange3 lines")
    nr = lines.n_values[ri]
    if not np.isin(nr, (9, 10)).all():
        k = int(nr[~np.isin(nr, (9, 10))][0])
        raise _rsf_error(
            p,
            f"pseudorange3 has {k} values after the keyword; expected 9 (t rho var x y z id el "
            "cn0) or 10 (... id system el cn0)",
            lines.first_bad(ri, ~np.isin(nr, (9, 10))),
        )
    if (nr != nr[0]).any():
        raise _rsf_error(
            p,
            f"pseudorange3 has {int(nr[nr != nr[0]][0])} values after the keyword, the first "
            f"pseudorange3 line {int(nr[0])}; one file has one layout",
            lines.first_bad(ri, nr != nr[0]),
        )
    r = lines.num[ri]
    with_system = nr == 10
    t0 = float(r[:, 0].min())
    sat_id = r[:, 6]
    bad_id = (sat_id != np.round(sat_id)) | (sat_id < 1)
    if bad_id.any():
        raise _rsf_error(
            p,
            f"field 8 (satellite ID) is {sat_id[bad_id][0]:g}; expected a positive integer",
            lines.first_bad(ri, bad_id),
        )
    bad_var = ~(r[:, 2] > 0.0)
    if bad_var.any():
        raise _rsf_error(
            p,
            f"field 4 (pseudorange variance) is {r[:, 2][bad_var][0]:g}; variances are > 0",
            lines.first_bad(ri, bad_var),
        )
    flags = np.where(with_system, r[:, 7], 1.0)
    bad_flag = ~np.isin(flags, list(SYSTEM_LETTERS))
    if bad_flag.any():
        raise _rsf_error(
            p,
            f"field 9 (satellite system) is {flags[bad_flag][0]:g}; expected 1 GPS, 2 SBAS, "
            "4 GLONASS, 8 Galileo, 16 QZSS or 32 BeiDou",
            lines.first_bad(ri, bad_flag),
        )
    letters = np.array([SYSTEM_LETTERS[int(f)] for f in flags.tolist()])
    prn = sat_id.astype(np.int64)
    prn = np.where((letters == "R") & (prn > RTKLIB_GLONASS_OFFSET), prn - RTKLIB_GLONASS_OFFSET, prn)
    sat = np.char.add(letters, np.char.zfill(prn.astype(str), 2))
    el = np.where(with_system, r[:, 8], r[:, 7])
    cn0 = np.where(with_system, r[:, 9], r[:, 8])
    ranges = pd.DataFrame(
        {
            "t": r[:, 0] - t0,
            "sat": sat,
            "rho": r[:, 1],
            "var_rho": r[:, 2],
            "sat_x": r[:, 3],
            "sat_y": r[:, 4],
            "sat_z": r[:, 5],
            "el": el,
            "cn0": cn0,
        }
    )
    return ranges, t0


def _odometry_table(lines: _RsfLines, t0: float) -> pd.DataFrame:
    """The ``odom3`` lines as the odometry table (:data:`simbench.contract.ODOMETRY_COLUMNS`), by time."""
    oi = lines.rows("odom")
    if (lines.n_values[oi] != 13).any():
        bad = lines.n_values[oi] != 13
        raise _rsf_error(
            lines.path,
            f"odom3 has {int(lines.n_values[oi][bad][0])} values after the keyword; expected 13 "
            "(t, velocity xyz, turn rate xyz, their 6 variances)",
            lines.first_bad(oi, bad),
        )
    o = lines.num[oi][:, :13]
    # the speed (field 9) and yaw rate (field 14) variances weight the odometry: zero is refused there too
    bad_odo = (o[:, 7:13] < 0.0) | (np.isin(np.arange(7, 13), (7, 12)) & (o[:, 7:13] <= 0.0))
    if bad_odo.any():
        row = np.flatnonzero(bad_odo.any(axis=1))
        j = int(np.flatnonzero(bad_odo[row[0]])[0])
        raise _rsf_error(
            lines.path,
            f"odom3 variance field {j + 9} is {o[row[0], 7 + j]:g}; variances are >= 0, the speed (9) and "
            "yaw rate (14) ones > 0",
            int(lines.line_no[oi[row[0]]]),
        )
    odometry = pd.DataFrame(odometry_columns(o, t0), columns=list(ODOMETRY_COLUMNS))
    return odometry.sort_values("t", kind="stable").reset_index(drop=True)


#: libRSF's vehicle frame (x forward, y left, z up) to the contract's (x forward, y right, z down) and back:
#: the y and z components of a velocity or turn rate change sign.
LIBRSF_AXES = np.array([1.0, -1.0, -1.0])


def odometry_columns(o: np.ndarray, t0: float) -> dict[str, np.ndarray]:
    """The odometry table's columns from ``odom3`` values ``o`` (rows: t, v xyz, w xyz, their 6 variances).

    libRSF's x forward, y left, z up becomes the contract's x forward, y right, z down: the y and z
    components change sign, the variances do not.
    """
    vel, rate, var_vel, var_rate = o[:, 1:4] * LIBRSF_AXES, o[:, 4:7] * LIBRSF_AXES, o[:, 7:10], o[:, 10:13]
    return {
        "t": o[:, 0] - t0,
        "speed": vel[:, 0],
        "yaw_rate": rate[:, 2],
        "var_speed": var_vel[:, 0],
        "var_yaw_rate": var_rate[:, 2],
        "vel_right": vel[:, 1],
        "vel_down": vel[:, 2],
        "roll_rate": rate[:, 0],
        "pitch_rate": rate[:, 1],
        "var_vel_right": var_vel[:, 1],
        "var_vel_down": var_vel[:, 2],
        "var_roll_rate": var_rate[:, 0],
        "var_pitch_rate": var_rate[:, 1],
    }


def load_librsf(
    path: str | os.PathLike[str],
    truth_path: str | os.PathLike[str] | None = None,
    *,
    gps_week: int,
    start_sow_s: float,
    name: str = "librsf",
    truth_max_gap_s: float = 2.0,
) -> Scenario:
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
        ``labels=None``, empty IMU table, the ``odom3`` lines as the odometry table,
        ``meta['odometry_rows']`` and ``meta['rough_fix_rms_m']`` (median post-fit RMS of the
        reader's single-point fixes, one clock per system).

    Raises
    ------
    SimbenchError
        From the readers, or when the reference does not overlap the log.
    """
    log = read_librsf(path)
    epochs = _librsf_epochs(log)
    t0_sow = start_sow_s + log.t0
    observations = _librsf_observations(log, epochs, day_of_year(gps_week, t0_sow))
    t_abs0 = gps_week * SECONDS_PER_WEEK + t0_sow
    if truth_path:
        ref = _external_reference(os.fspath(truth_path), gps_week, gps_week * SECONDS_PER_WEEK + start_sow_s)
    else:
        ref = _point3_reference(log, t_abs0)
    truth = log_truth(
        epochs.grid,
        t_abs0,
        ref,
        truth_max_gap_s,
        observations["epoch"].to_numpy(),
        epochs.rough,
        field="scenario.truth" if truth_path else "scenario.obs",
    )
    nav = NavInfo(
        gps_week=gps_week,
        start_sow_s=t0_sow,
        iono_alpha=(0.0,) * 4,
        iono_beta=(0.0,) * 4,
        dual_frequency=False,
        iono_corrected=True,
    )
    meta = {
        "name": name,
        "seed": 0,
        "source": "librsf",
        "files": {"obs": str(Path(path)), "truth": str(truth_path or "")},
        "systems": "".join(sorted({s[0] for s in observations["sat"].unique().tolist()})),
        "epochs": epochs.grid.n,
        "epochs_with_truth": len(truth),
        "odometry_rows": len(log.odometry),
        "rough_fix_rms_m": float(np.nanmedian(epochs.rough.fix.rms_m[epochs.rough.fix.trusted])),
        "corrections": "satellite clock, ionosphere and troposphere removed in the file; the modelled "
        "hydrostatic delay is added back for the shared model; no carrier phase",
    }
    return log_scenario(observations, truth, nav, meta, odometry=log.odometry)


@dataclass(frozen=True)
class _LibrsfEpochs:
    """The epochs of a libRSF log's pseudorange rows and the reader's single-point fix on them."""

    grid: EpochGrid
    t_epoch: np.ndarray  #: file time of each epoch [s]
    row_epoch: np.ndarray  #: epoch index of each row of ``ranges``
    rough: RoughFix


def _librsf_epochs(log: LibrsfLog) -> _LibrsfEpochs:
    """Group the rows into epochs (times rounded to the file's resolution) and fix each epoch roughly."""
    rg = log.ranges
    t_key = np.round(rg["t"].to_numpy() / _EPOCH_RESOLUTION_S).astype(np.int64)
    uniq, row_epoch = np.unique(t_key, return_inverse=True)
    t_epoch = uniq * _EPOCH_RESOLUTION_S
    interval = float(np.median(np.diff(t_epoch))) if t_epoch.size > 1 else 1.0
    # one receiver clock per system: GLONASS (and any other) pseudoranges carry an inter-system bias
    system_index = np.unique(rg["sat"].str[0].to_numpy(), return_inverse=True)[1]
    rough = rough_fix(
        row_epoch,
        rg[["sat_x", "sat_y", "sat_z"]].to_numpy(float),
        rg["rho"].to_numpy(float),
        n_epochs=t_epoch.size,
        system_index=system_index,
    )
    return _LibrsfEpochs(epoch_grid_of(t_epoch, interval), t_epoch, row_epoch, rough)


def _librsf_observations(log: LibrsfLog, epochs: _LibrsfEpochs, doy: float) -> pd.DataFrame:
    """The observation table of the pseudorange rows: code only, elevation from the file or the rough fix."""
    rg = log.ranges
    sat_pos = rg[["sat_x", "sat_y", "sat_z"]].to_numpy(float)
    el_file = rg["el"].to_numpy(float)
    el_deg = np.where(np.isfinite(el_file), el_file, np.degrees(epochs.rough.el))
    # Re-insert the modelled hydrostatic delay that the shared model subtracts (module docstring).
    lat, _, h = geodetic_from_ecef(np.median(epochs.rough.fix.pos, axis=0))
    code = rg["rho"].to_numpy(float) + troposphere_terms(el_deg * DEG, float(lat), float(h), doy)[0]
    n = len(rg)
    nan = np.full(n, np.nan)
    row_epoch = epochs.row_epoch
    return observation_table(
        {
            "epoch": epochs.grid.index[row_epoch],
            "t": epochs.t_epoch[row_epoch],
            "sat": rg["sat"].to_numpy(),
            "code_l1": code,
            "phase_l1": nan,
            "doppler_l1": nan,
            "cn0_l1": rg["cn0"].to_numpy(float),
            "lli_l1": np.zeros(n, bool),
            "code_l2": nan,
            "phase_l2": nan,
            "lli_l2": np.zeros(n, bool),
            "f1_f2_ratio": nan,
            "sat_x": sat_pos[:, 0],
            "sat_y": sat_pos[:, 1],
            "sat_z": sat_pos[:, 2],
            "sat_vx": nan,
            "sat_vy": nan,
            "sat_vz": nan,
            "sat_clock": np.zeros(n),
            "sat_clock_drift": np.zeros(n),
            "el": el_deg,
            "az": np.degrees(epochs.rough.az),
        }
    )


def _point3_reference(log: LibrsfLog, t_abs0: float) -> Reference:
    """The reference of the log's own ``point3`` lines (``t_abs0``: GPS time of the log's first row [s])."""
    pts = log.reference
    if pts.empty:
        raise SimbenchError(
            f"scenario.obs '{log.path}'",
            "has no point3 reference lines and no scenario.truth",
            "pass a reference with scenario.truth=... (libRSF point3 or week,TOW,lat,lon,h)",
        )
    return Reference(t_gps=t_abs0 + pts["t"].to_numpy(float), xyz=pts[["x", "y", "z"]].to_numpy(float), path=log.path)


def _external_reference(p: str, gps_week: int, t_file0_gps: float) -> Reference:
    """A reference from a separate file: libRSF point3 lines (file time; ``t_file0_gps`` is the
    GPS time of file time 0) or the CSV/SOW layouts (GPS time)."""
    if not os.path.isfile(p):
        raise SimbenchError(
            f"scenario.truth '{p}'",
            "file does not exist",
            "pass a libRSF point3 file or a 'week,TOW,lat,lon,h' / 'SOW X Y Z' reference",
        )
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


def write_synthetic_librsf(
    path: str | os.PathLike[str],
    duration_s: float = 10.0,
    *,
    rate_hz: float = 1.0,
    odometry_rate_hz: float = 10.0,
    start_gps_s: float = 2032 * SECONDS_PER_WEEK + 475_200.0,
    code_sigma_m: float = 0.5,
    systems: str = "G",
    glonass_bias_m: float = 0.0,
    speed_sigma_mps: float = 0.05,
    yaw_rate_sigma_rps: float = 0.002,
    seed: int = 0,
) -> Path:
    """Write a synthetic libRSF GNSS file (test fixtures and the ingest benchmark).

    A car drives east at 10 m/s from Chemnitz (50.83 N, 12.92 E); pseudoranges
    are the Sagnac range plus a receiver clock (100 m + 1 m/s drift) plus white
    noise, i.e. already free of satellite clock and atmosphere as the format
    specifies. GPS is the nominal constellation; GLONASS (``'R'`` in
    ``systems``) is a stand-in with another sky (the nominal constellation 4 h
    later), written as smartLoc-RTKLIB does (system flag 4, ID 32 + slot) and
    with ``glonass_bias_m`` added (an inter-system clock offset). Satellites
    below 10 deg are left out. Odometry lines carry the true speed and yaw rate
    (0) plus white noise, with the noise variances, in libRSF's x-forward,
    y-left, z-up frame.

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
    systems : str
        ``'G'`` or ``'GR'``.
    glonass_bias_m : float
        Added to every GLONASS pseudorange [m].
    speed_sigma_mps, yaw_rate_sigma_rps : float
        Odometry noise [m/s], [rad/s] (their squares are written as the variances).
    seed : int

    Returns
    -------
    Path
        The synthetic log written (``path``).

    Raises
    ------
    SimbenchError
        For a system other than G and R.
    """
    if not systems or set(systems) - {"G", "R"}:
        raise SimbenchError("systems", f"'{systems}' is not supported by the synthetic writer", "use 'G' or 'GR'")
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    lat, lon = 50.83 * DEG, 12.92 * DEG
    east = dcm_ned_to_ecef(lat, lon)[:, 1]
    rx = ecef_from_geodetic(lat, lon, 300.0)[None, :] + 10.0 * t[:, None] * east[None, :]
    constellation = NominalConstellation()
    lines = []
    for letter in systems:
        shift, bias, id0 = (0.0, 0.0, 0) if letter == "G" else (_STANDIN_SHIFT_S, glonass_bias_m, RTKLIB_GLONASS_OFFSET)
        st = constellation.states(start_gps_s + shift + t)
        el, _ = elevation_azimuth(rx, st.pos)
        e_idx, s_idx = np.nonzero(el > 10.0 * DEG)
        sp = st.pos[e_idx, s_idx]
        rho = (
            sagnac_range(sp, rx[e_idx]) + 100.0 + 1.0 * t[e_idx] + bias + code_sigma_m * rng.standard_normal(e_idx.size)
        )
        cn0 = 35.0 + 15.0 * np.sin(el[e_idx, s_idx])
        lines += [
            f"pseudorange3 {t[e]:.3f} {r:.3f} {code_sigma_m**2:.4f} {q[0]:.3f} {q[1]:.3f} {q[2]:.3f} "
            f"{id0 + s + 1} {SYSTEM_FLAGS[letter]} {np.degrees(el[e, s]):.2f} {c:.1f}"
            for e, s, r, q, c in zip(e_idx.tolist(), s_idx.tolist(), rho, sp, cn0)
        ]
    t_odo = np.arange(0.0, duration_s, 1.0 / odometry_rate_hz)
    v = 10.0 + speed_sigma_mps * rng.standard_normal(t_odo.size)
    wz = yaw_rate_sigma_rps * rng.standard_normal(t_odo.size)
    var_v, var_w = speed_sigma_mps**2, yaw_rate_sigma_rps**2
    lines += [
        f"odom3 {to:.3f} {vx:.4f} 0 0 0 0 {w:.6f} {var_v:.6g} {var_v:.6g} {var_v:.6g} {var_w:.6g} "
        f"{var_w:.6g} {var_w:.6g}"
        for to, vx, w in zip(t_odo, v, wz)
    ]
    lines += [f"point3 {ti:.3f} {x[0]:.4f} {x[1]:.4f} {x[2]:.4f} 0 0 0 0 0 0 0 0 0" for ti, x in zip(t, rx)]
    out = Path(path)
    out.write_text("\n".join(lines) + "\n")
    return out
