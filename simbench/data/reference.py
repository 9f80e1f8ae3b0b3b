"""Reference trajectories of real logs: reading, time matching, the truth table.

Two file layouts are read: ``week,TOW,lat,lon,h`` CSV (degrees, ellipsoidal
metres; the Hong Kong UrbanNav-style ground truth) and ``SOW X Y Z``
(whitespace or commas, ECEF metres; the WVU drives), where a time column of
more than a week's seconds is continuous GPS seconds (``t,x,y,z``) instead.
A static receiver's reference may be one point: ``lat,lon,h`` (degrees, ellipsoidal
metres) or ``x,y,z`` (ECEF metres; told apart by magnitude), written in the setting
itself or as the one row of a file (commas or whitespace).
Epochs are matched by linear interpolation in time; an epoch further than ``max_gap_s`` from reference samples on either
side gets no truth row: its observations stay in the scenario (estimators
use them), but :func:`simbench.analysis.metrics.enu_errors` merges solutions with
truth on ``epoch``, so it is not scored, and availability is counted over the
epochs that have a reference.
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass

import numpy as np
import pandas as pd

from simbench.contract import TRUTH_COLUMNS
from simbench.core.constants import DEG, SECONDS_PER_WEEK
from simbench.core.frames import ecef_from_geodetic
from simbench.core.gpstime import format_gps_time
from simbench.errors import SimbenchError, warn

__all__ = [
    "Reference",
    "read_reference",
    "is_point",
    "check_near_fixes",
    "match_reference",
    "truth_table",
    "MAX_FIX_DISTANCE_M",
]

#: Largest median distance of a reference from the log's single-point fixes [m]: metres to
#: kilometres of error in urban canyons, thousands of kilometres for swapped columns.
MAX_FIX_DISTANCE_M = 100_000.0
#: Epochs this close outside the first/last reference sample take that sample [s].
_END_TOLERANCE_S = 0.05


@dataclass(frozen=True)
class Reference:
    """A reference trajectory.

    Attributes
    ----------
    t_gps : np.ndarray, shape (k,)
        Sample times, continuous GPS seconds, increasing [s].
    xyz : np.ndarray, shape (k, 3)
        Antenna ECEF positions [m].
    path : str
        The file, or the point as written (``'35.1,136.9,104.8'``).
    static : bool
        A static antenna: ``xyz`` holds its one position, which holds at every time.
    """

    t_gps: np.ndarray
    xyz: np.ndarray
    path: str
    static: bool = False  #: one surveyed point (``xyz`` of one row) valid at every time, ``t_gps`` empty


def _ref_error(field: str, path: str, problem: str) -> SimbenchError:
    return SimbenchError(
        f"{field} '{path}'",
        problem,
        "pass a 'week,TOW,lat,lon,h' CSV or a 'SOW X Y Z' or 't,X,Y,Z' file (GPS time, ECEF metres)",
    )


def read_reference(
    path: str | os.PathLike[str], week_hint: int | None = None, field: str = "scenario.truth"
) -> Reference:
    """Read a reference trajectory file.

    Parameters
    ----------
    path : str or PathLike
        ``week,TOW,lat,lon,h`` CSV (a header line is allowed) or ``SOW X Y Z``;
        with 4 columns, times above a week's seconds are continuous GPS seconds.
        A static antenna's one point: ``lat,lon,h`` [deg, deg, m] or ``x,y,z`` [m ECEF],
        as the string itself or a file of one such row.
    week_hint : int, optional
        GPS week for ``SOW X Y Z`` files, which carry none (e.g. the week of
        the observations).
    field : str
        The setting that named the file, for error messages.

    Returns
    -------
    Reference
        Samples by time, the first of each time kept.

    Raises
    ------
    SimbenchError
        Missing file, unknown layout, a point that is neither lat,lon,h nor ECEF, ``SOW X Y Z`` without ``week_hint``,
        a latitude beyond +-90 or a longitude beyond +-180 degrees, time going
        backwards, more than :data:`MAX_MISSING_FRACTION` of the rows lacking a value; the message names the line.

    Warns
    -----
    SimbenchWarning
        Rows that repeat the time of the row before (the first is kept); rows lacking a value (``nan``,
        an empty or text field, a short line: dropped), with their number and the first line.
    """
    p = os.fspath(path)
    point = _numbers(p)
    if point is not None and not os.path.isfile(p):
        return _static_reference(point, p, field)
    if not os.path.isfile(p):
        raise _ref_error(field, p, "file does not exist")
    with open(p, errors="replace") as fh:
        content = [ln.split("#", 1)[0] for ln in fh.read().splitlines()]
    kept = [i for i, c in enumerate(content) if c.strip()]
    comma = bool(kept) and "," in content[kept[0]]
    try:
        df = pd.read_csv(
            io.StringIO("\n".join(content[i] for i in kept)),
            sep="," if comma else r"\s+",
            header=None,
            engine="c" if comma else "python",
        )
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise _ref_error(field, p, f"cannot be parsed ({str(exc).splitlines()[0][:60]})") from None
    if len(df) and not any(_is_number(v) for v in df.iloc[0]):
        df = df.iloc[1:]  # a header line: names, no number
    df = _numeric_rows(df.apply(pd.to_numeric, errors="coerce"), content, kept, field, p)
    if df.empty:
        raise _ref_error(field, p, "contains no numeric rows")
    a = df.to_numpy(float)
    line = np.asarray(kept, np.int64)[df.index.to_numpy()] + 1
    if a.shape[1] == 5:
        for col, name, limit in ((2, "lat", 90.0), (3, "lon", 180.0)):
            bad = np.flatnonzero(np.abs(a[:, col]) > limit)
            if bad.size:
                raise SimbenchError(
                    f"{field} '{p}' line {line[bad[0]]}",
                    f"column {col + 1} ({name}) is {a[bad[0], col]:g}, beyond +-{limit:g} degrees",
                    "columns must be week,TOW,lat,lon,h (degrees); check for swapped lat and lon",
                )
        t = a[:, 0] * SECONDS_PER_WEEK + a[:, 1]
        xyz = ecef_from_geodetic(a[:, 2] * DEG, a[:, 3] * DEG, a[:, 4])
    elif a.shape == (1, 3):
        return _static_reference(list(a[0]), p, field)
    elif a.shape[1] == 4:
        if np.all(a[:, 0] >= SECONDS_PER_WEEK):  # no second of week is that large: continuous GPS seconds
            t = a[:, 0]
        elif week_hint is None:
            raise _ref_error(field, p, "has seconds of week but no week is known")
        else:
            t = week_hint * SECONDS_PER_WEEK + a[:, 0]
        xyz = a[:, 1:4]
        if np.any(np.linalg.norm(xyz, axis=1) < 6.0e6):
            raise _ref_error(field, p, "has 4 columns but they are not SOW X Y Z in ECEF metres")
    else:
        raise _ref_error(field, p, f"has {a.shape[1]} columns")
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        k = back[0] + 1
        raise SimbenchError(
            f"{field} '{p}' line {line[k]}",
            f"time {format_gps_time(t[k])} GPS is earlier than line {line[k - 1]}'s {format_gps_time(t[k - 1])}",
            "sort the reference by time",
        )
    repeat = np.flatnonzero(np.diff(t) == 0) + 1
    if repeat.size:
        warn(
            f"{field} '{p}'",
            f"{repeat.size} rows repeat the time of the row before (first at line {line[repeat[0]]})",
            "kept the first row of each time",
        )
    first = np.setdiff1d(np.arange(t.size), repeat)
    return Reference(t_gps=t[first], xyz=np.asarray(xyz)[first], path=p)


#: Most of a reference's rows may lack a value before it is refused rather than read with a warning.
MAX_MISSING_FRACTION = 0.5


def _is_number(value: object) -> bool:
    """Whether a field read from a reference file is a number (``nan`` and an empty field count)."""
    try:
        float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return True


def _numeric_rows(df: pd.DataFrame, content: list[str], kept: list[int], field: str, path: str) -> pd.DataFrame:
    """The rows of ``df`` (numbers, NaN where a field was missing, ``nan`` or text) with every value.

    A row without a value in some column (an outage written as NaN, a cut line) cannot be
    used; dropping it is said in one warning naming how many and the first, and a file where
    more than :data:`MAX_MISSING_FRACTION` of the rows lack values is refused (a wrong layout
    more likely than outages). Row ``i`` of ``df`` is line ``kept[i]`` of ``content``.
    """
    missing = df.isna().any(axis=1).to_numpy()
    n = int(missing.sum())
    if n in (0, len(df)):  # every row whole, or none (the caller refuses a file without numeric rows)
        return df[~missing]
    first = kept[int(df.index[np.argmax(missing)])]
    where = f"first at line {first + 1}: '{content[first].strip()[:60]}'"
    problem = f"{n} of {len(df)} rows lack a value ({where})"
    if n > MAX_MISSING_FRACTION * len(df):
        raise SimbenchError(f"{field} '{path}'", problem, "repair the file: every row needs a number in every column")
    warn(f"{field} '{path}'", problem, "dropped them: epochs only they would cover have no truth and are not scored")
    return df[~missing]


#: A point with a norm above this is ECEF metres, below it latitude, longitude and height [m].
_ECEF_NORM_M = 1.0e6


def is_point(text: str) -> bool:
    """Whether a reference setting is a static antenna's one point written in it (``lat,lon,h`` or ``x,y,z``),
    not a file."""
    return _numbers(text) is not None


def _numbers(text: str) -> list[float] | None:
    """The three numbers of a point written as ``a,b,c`` or ``a b c``; None for anything else."""
    parts = text.replace(",", " ").split()
    try:
        values = [float(v) for v in parts]
    except ValueError:
        return None
    return values if len(values) == 3 else None


def _static_reference(point: list[float], where: str, field: str) -> Reference:
    """The :class:`Reference` of one surveyed point: ECEF metres, or lat, lon [deg] and ellipsoidal height [m]."""
    a = np.asarray(point, float)
    if np.linalg.norm(a) > _ECEF_NORM_M:
        xyz = a
    elif abs(a[0]) <= 90.0 and abs(a[1]) <= 180.0:
        xyz = np.asarray(ecef_from_geodetic(a[0] * DEG, a[1] * DEG, a[2]), float)
    else:
        raise SimbenchError(
            f"{field} '{where}'",
            "is neither lat,lon,h (|lat| <= 90, |lon| <= 180 degrees) nor ECEF x,y,z (metres, norm > 1000 km)",
            "write the surveyed point as lat,lon,h in degrees and ellipsoidal metres, or as ECEF x,y,z",
        )
    return Reference(t_gps=np.zeros(0), xyz=xyz.reshape(1, 3), path=where, static=True)


def check_near_fixes(ref: Reference, truth_pos: np.ndarray, fix_pos: np.ndarray, field: str = "scenario.truth") -> None:
    """Refuse a reference that is not where the log's own single-point fixes are.

    A reference of another place, or one with swapped columns, would otherwise
    give every estimator errors of thousands of kilometres and the verdict
    ``diverged`` instead of naming the reference file.

    Parameters
    ----------
    ref : Reference
    truth_pos : np.ndarray, shape (n, 3)
        Reference ECEF position at n epochs (NaN where it has none) [m].
    fix_pos : np.ndarray, shape (n, 3)
        Trusted single-point fixes of the same epochs (NaN where none) [m].
    field : str
        The setting that named the reference file.

    Raises
    ------
    SimbenchError
        When the median distance exceeds :data:`MAX_FIX_DISTANCE_M`.
    """
    d = np.linalg.norm(np.asarray(truth_pos) - np.asarray(fix_pos), axis=1)
    d = d[np.isfinite(d)]
    if d.size and np.median(d) > MAX_FIX_DISTANCE_M:
        raise SimbenchError(
            f"{field} '{ref.path}'",
            f"positions are {np.median(d) / 1e3:,.0f} km from the log's single-point fixes (median over "
            f"{d.size} epochs; more than {MAX_FIX_DISTANCE_M / 1e3:g} km)",
            "pass the reference of this log; check the column order (week,TOW,lat,lon,h or SOW X Y Z)",
        )


def match_reference(ref: Reference, t_gps: np.ndarray, max_gap_s: float = 2.0) -> np.ndarray:
    """Reference position and velocity at given times by linear interpolation.

    Parameters
    ----------
    ref : Reference
    t_gps : np.ndarray, shape (n,)
        Epoch times, continuous GPS seconds [s].
    max_gap_s : float
        Largest spacing of the two bracketing reference samples [s].

    Returns
    -------
    np.ndarray, shape (n, 6)
        ECEF position [m] and velocity (slope of the bracketing segment)
        [m/s]; NaN where the reference does not cover the epoch.

    Raises
    ------
    SimbenchError
        When no epoch is covered (the reference belongs to another time).
    """
    t = np.asarray(t_gps, float)
    rt, rx = ref.t_gps, ref.xyz
    out = np.full((t.size, 6), np.nan)
    if ref.static:  # a static antenna: its point at every epoch, at rest
        out[:, :3] = rx[0]
        out[:, 3:] = 0.0
        return out
    if rt.size >= 2:
        tc = np.clip(t, rt[0], rt[-1])
        i = np.clip(np.searchsorted(rt, tc, side="right") - 1, 0, rt.size - 2)
        dt = rt[i + 1] - rt[i]
        w = (tc - rt[i]) / dt
        ok = (dt <= max_gap_s) & (t >= rt[0] - _END_TOLERANCE_S) & (t <= rt[-1] + _END_TOLERANCE_S)
        pos = rx[i] + w[:, None] * (rx[i + 1] - rx[i])
        vel = (rx[i + 1] - rx[i]) / dt[:, None]
        out[ok, :3] = pos[ok]
        out[ok, 3:] = vel[ok]
    if not np.isfinite(out[:, 0]).any():
        span = f"{format_gps_time(rt[0])} .. {format_gps_time(rt[-1])}" if rt.size else "nothing"
        raise SimbenchError(
            f"scenario.truth '{ref.path}'",
            f"does not overlap the observations: reference {span} GPS, observations "
            f"{format_gps_time(t.min())} .. {format_gps_time(t.max())} GPS",
            "pass the reference of the same log (GPS time)",
        )
    return out


def truth_table(t: np.ndarray, matched: np.ndarray | None, n_observed: np.ndarray) -> pd.DataFrame:
    """The truth table (:data:`~simbench.contract.TRUTH_COLUMNS`) of a real log.

    Only epochs with a reference position get a row. Attitude, receiver clock
    and wet delay are unknown on real data (NaN); ``n_visible`` is the number
    of satellites observed at the epoch (the number above the mask is unknown).

    Parameters
    ----------
    t : np.ndarray, shape (n,)
        Time of epoch index 0..n-1 since the log start [s].
    matched : np.ndarray, shape (n, 6), or None
        Output of :func:`match_reference`; None gives an empty table.
    n_observed : np.ndarray of int, shape (n,)
    """
    n = t.size
    m = np.full((n, 6), np.nan) if matched is None else matched
    nan = np.full(n, np.nan)
    table = pd.DataFrame(
        {
            "epoch": np.arange(n, dtype=np.int64),
            "t": t,
            "x": m[:, 0],
            "y": m[:, 1],
            "z": m[:, 2],
            "vx": m[:, 3],
            "vy": m[:, 4],
            "vz": m[:, 5],
            "roll": nan,
            "pitch": nan,
            "yaw": nan,
            "rx_clock": nan,
            "zwd": nan,
            "n_visible": np.asarray(n_observed, np.int64),
        }
    )
    return table.loc[np.isfinite(m[:, 0]), list(TRUTH_COLUMNS)].reset_index(drop=True)
