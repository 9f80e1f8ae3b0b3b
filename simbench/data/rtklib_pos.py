"""RTKLIB solution files (``.pos``, written by ``rnx2rtkp`` and RTKPOST).

A ``.pos`` file is ``%`` header lines, then one whitespace-separated row per
solution: time, three position fields, the quality flag ``Q`` (1 fix, 2 float,
3 SBAS, 4 DGPS, 5 single, 6 PPP), the number of satellites ``ns``, then
standard deviations. The last header line names the columns, from which the
layout is read:

* time as ``week tow`` (``out-timeform = tow``) or ``yyyy/mm/dd hh:mm:ss.sss``
  (``hms``), in GPS time (``GPST``); UTC or JST output is refused, since
  converting it back would need the leap seconds of the day;
* position as ECEF ``x-ecef(m) y-ecef(m) z-ecef(m)`` (``-e``) or
  ``latitude(deg) longitude(deg) height(m)`` in decimal degrees and
  ellipsoidal metres (the default); degree-minute-second output (``-g``) and
  baselines (``-a``) are refused.
"""

from __future__ import annotations

import io
import os
from typing import Literal

import numpy as np
import pandas as pd

from simbench.core.constants import DEG, SECONDS_PER_WEEK
from simbench.core.frames import ecef_from_geodetic
from simbench.core.gpstime import datetime64_to_gps
from simbench.errors import SimbenchError

__all__ = ["POS_COLUMNS", "parse_rtklib_pos", "read_rtklib_pos"]

#: Columns of the table :func:`parse_rtklib_pos` returns.
POS_COLUMNS: dict[str, str] = {
    "t_gps": "s, solution time, continuous GPS seconds since 1980-01-06",
    "x": "m, ECEF x",
    "y": "m, ECEF y",
    "z": "m, ECEF z",
    "q": "int, RTKLIB quality flag (1 fix, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP)",
    "ns": "int, number of satellites used",
}


def _position_form(header: str, where: str) -> Literal["xyz", "llh"]:
    """Position layout from the column header line (the last ``%`` line); refuses non-GPS time."""
    words = header.lstrip("%").split()
    if not words or words[0] != "GPST":
        raise SimbenchError(
            where,
            f"solution times are not GPS time (column header '{header.strip()}')",
            "write the .pos with GPST time (rnx2rtkp without -u; out-timesys = gpst)",
        )
    if "x-ecef(m)" in words:
        pos: Literal["xyz", "llh"] = "xyz"
    elif "latitude(deg)" in words:
        pos = "llh"
    else:
        raise SimbenchError(
            where,
            f"has neither ECEF nor decimal-degree positions (column header '{header.strip()}')",
            "write the .pos with -e (ECEF) or the default lat/lon/height",
        )
    return pos


def parse_rtklib_pos(text: str, where: str = "rtklib .pos") -> pd.DataFrame:
    """Parse the text of an RTKLIB ``.pos`` file.

    Parameters
    ----------
    text : str
        Whole file content.
    where : str
        Name used in error messages (e.g. the file path).

    Returns
    -------
    pandas.DataFrame
        :data:`POS_COLUMNS`, one row per solution in file order; empty when the
        file has a header but no solutions.

    Raises
    ------
    SimbenchError
        No column header, times not in GPST, positions neither ECEF nor decimal
        latitude/longitude/height, or malformed rows.
    """
    lines = text.splitlines()
    header = [ln for ln in lines if ln.startswith("%")]
    body = [ln for ln in lines if ln.strip() and not ln.startswith("%")]
    if not header or not any(w in header[-1] for w in ("GPST", "UTC", "JST")):
        raise SimbenchError(
            where,
            "has no RTKLIB column header line ('%  GPST ...')",
            "pass a solution file written by rnx2rtkp or RTKPOST",
        )
    pos_form = _position_form(header[-1], where)
    if not body:
        return pd.DataFrame({c: np.zeros(0, dtype=np.int64 if c in ("q", "ns") else float) for c in POS_COLUMNS})
    try:
        raw = pd.read_csv(
            io.StringIO("\n".join(body)), sep=r"\s+", header=None, usecols=range(7), dtype=str, engine="c"
        )
        if "/" not in raw.iloc[0, 0]:  # 'week tow', not 'yyyy/mm/dd hh:mm:ss'; both have the same header
            t_gps = raw[0].astype(float).to_numpy() * SECONDS_PER_WEEK + raw[1].astype(float).to_numpy()
        else:
            stamps = (raw[0].str.replace("/", "-") + "T" + raw[1]).to_numpy(dtype="datetime64[ns]")
            t_gps = datetime64_to_gps(stamps)
        a, b, c = (raw[k].astype(float).to_numpy() for k in (2, 3, 4))
        q, ns = raw[5].astype(np.int64).to_numpy(), raw[6].astype(np.int64).to_numpy()
    except (ValueError, KeyError) as exc:
        raise SimbenchError(
            where,
            f"has a malformed solution row ({str(exc).splitlines()[0]})",
            "pass an unmodified rnx2rtkp solution file with space separators",
        ) from None
    xyz = np.stack([a, b, c], axis=1) if pos_form == "xyz" else ecef_from_geodetic(a * DEG, b * DEG, c)
    return pd.DataFrame({"t_gps": t_gps, "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "q": q, "ns": ns})


def read_rtklib_pos(path: str | os.PathLike[str]) -> pd.DataFrame:
    """Read an RTKLIB ``.pos`` file; see :func:`parse_rtklib_pos`.

    Parameters
    ----------
    path : str or PathLike

    Returns
    -------
    pandas.DataFrame
        :data:`POS_COLUMNS`.
    """
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise SimbenchError(f"rtklib .pos '{p}'", "file does not exist", "check the path")
    with open(p, errors="replace") as fh:
        return parse_rtklib_pos(fh.read(), f"rtklib .pos '{p}'")
