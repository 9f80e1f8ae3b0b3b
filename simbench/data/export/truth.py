"""The reference trajectory of a scenario as a CSV that :func:`simbench.data.reference.read_reference` reads.

One header line, then one row per truth epoch::

    week,tow,lat_deg,lon_deg,height_m
    2032,475200.0000000,39.62950000000,-79.95590000000,290.0000

=========  ===============================================================
week       GPS week of the epoch
tow        s, GPS seconds of week (7 decimals)
lat_deg    deg, WGS-84 geodetic latitude of the antenna (11 decimals, ~1 um)
lon_deg    deg, WGS-84 longitude, east positive
height_m   m, ellipsoidal height (4 decimals)
=========  ===============================================================

This is the ``week,TOW,lat,lon,h`` layout of the UrbanNav ground truth, so
``scenario=rinex scenario.truth=<file>`` scores an exported RINEX log against it
(and ``python -m simbench score`` can take it as a solution).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from simbench.contract import NavInfo
from simbench.core.constants import SECONDS_PER_WEEK
from simbench.core.frames import geodetic_from_ecef

__all__ = ["TRUTH_CSV_COLUMNS", "write_truth_csv"]

#: Columns of the exported reference trajectory (module docstring).
TRUTH_CSV_COLUMNS: dict[str, str] = {
    "week": "GPS week",
    "tow": "s, GPS seconds of week",
    "lat_deg": "deg, geodetic latitude (WGS-84)",
    "lon_deg": "deg, longitude (east positive)",
    "height_m": "m, ellipsoidal height",
}


def write_truth_csv(path: str | os.PathLike[str], truth: pd.DataFrame, nav: NavInfo) -> Path:
    """Write a truth table (:data:`simbench.contract.TRUTH_COLUMNS`) as the documented CSV.

    Parameters
    ----------
    path : str or PathLike
    truth : pandas.DataFrame
        ``t`` [s since scenario start] and ECEF ``x, y, z`` [m]; rows without a position are left out.
    nav : NavInfo
        GPS time of the scenario start.

    Returns
    -------
    Path
    """
    ok = truth[["x", "y", "z"]].notna().all(axis=1).to_numpy()
    tr = truth[ok]
    t_gps = nav.gps_week * SECONDS_PER_WEEK + nav.start_sow_s + tr["t"].to_numpy(float)
    week = np.floor(t_gps / SECONDS_PER_WEEK).astype(np.int64)
    lat, lon, h = geodetic_from_ecef(tr[["x", "y", "z"]].to_numpy(float))
    rows = [
        f"{w},{tow:.7f},{la:.11f},{lo:.11f},{hh:.4f}"
        for w, tow, la, lo, hh in zip(
            week.tolist(),
            (t_gps - week * SECONDS_PER_WEEK).tolist(),
            np.degrees(lat).tolist(),
            np.degrees(lon).tolist(),
            h.tolist(),
        )
    ]
    out = Path(path)
    out.write_text(",".join(TRUTH_CSV_COLUMNS) + "\n" + "\n".join(rows) + "\n")
    return out
