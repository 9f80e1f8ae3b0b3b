"""RINEX 2/3 GPS navigation files -> :class:`~simbench.sim.orbits.BroadcastEphemeris`.

The file is parsed by georinex; this module turns its (time, satellite) grid
into the flat per-record arrays the ephemeris evaluator takes. The orbit and
clock computation itself (IS-GPS-200) lives in :mod:`simbench.sim.orbits`.
"""
from __future__ import annotations

import os
import warnings

import numpy as np

from simbench.errors import SimbenchError
from simbench.sim.constants import SECONDS_PER_WEEK
from simbench.sim.gpstime import datetime64_to_gps
from simbench.sim.orbits import FIT_HALF_WINDOW_S, BroadcastEphemeris

__all__ = ["read_gps_navigation"]

#: georinex variable of each record quantity that :class:`BroadcastEphemeris` takes.
_RECORD_SOURCE = {
    "af0": "SVclockBias", "af1": "SVclockDrift", "af2": "SVclockDriftRate", "crs": "Crs",
    "dn": "DeltaN", "m0": "M0", "cuc": "Cuc", "e": "Eccentricity", "cus": "Cus",
    "sqrta": "sqrtA", "cic": "Cic", "omega0": "Omega0", "cis": "Cis", "i0": "Io",
    "crc": "Crc", "w": "omega", "omegadot": "OmegaDot", "idot": "IDOT", "tgd": "TGD",
}
#: Every georinex variable a complete GPS record needs.
_NAV_FIELDS = (*_RECORD_SOURCE.values(), "Toe", "GPSWeek", "health")


def _nav_error(path: str, problem: str) -> SimbenchError:
    return SimbenchError(
        f"nav_file '{path}'", problem, "pass a RINEX 2/3 GPS navigation file (e.g. brdc<doy>0.<yy>n)"
    )


def read_gps_navigation(path: str | os.PathLike[str], max_age_s: float = FIT_HALF_WINDOW_S) -> BroadcastEphemeris:
    """Read GPS ephemerides from a RINEX 2 or 3 navigation file (via georinex).

    Parameters
    ----------
    path : str or PathLike
        RINEX navigation file (``.yyn``, ``.rnx``; gzip allowed). Only GPS
        records are kept; unhealthy or incomplete records are dropped.
    max_age_s : float
        Largest |t - Toe| at which a record may be used [s]; default 7200.

    Returns
    -------
    BroadcastEphemeris
        With the Klobuchar coefficients of the header when it has them.

    Raises
    ------
    SimbenchError
        Missing file, not a navigation file, or no healthy GPS record.
    """
    import georinex  # deferred: importing xarray/georinex costs ~1 s

    p = os.fspath(path)
    if not os.path.isfile(p):
        raise _nav_error(p, "file does not exist")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            info = georinex.rinexinfo(p)
            kind = info.get("rinextype")
            if kind != "nav":
                what = {"obs": "a RINEX observation file", "sp3": "an SP3 orbit file"}.get(
                    str(kind), "not a RINEX file"
                )
                raise _nav_error(p, f"is {what}, not RINEX navigation data")
            ds = georinex.load(p)
    except SimbenchError:
        raise
    except Exception as exc:  # georinex raises many types on malformed text
        msg = " ".join(str(exc).split()) or type(exc).__name__
        msg = msg if len(msg) <= 60 else msg[:57] + "..."
        raise _nav_error(p, f"cannot be parsed as RINEX navigation data (georinex: {msg})") from None
    if "sv" not in ds.coords or not all(k in ds for k in _NAV_FIELDS):
        raise _nav_error(p, "contains no GPS ephemerides (e.g. GLONASS/BeiDou-only file)")
    is_gps = np.char.startswith(ds.sv.values.astype(str), "G")
    if not is_gps.any():
        raise _nav_error(p, "contains no GPS ephemerides")
    ds = ds.isel(sv=np.flatnonzero(is_gps))

    # (time, sv) grid -> flat record list; georinex leaves NaN where a sat has no record.
    v = {k: ds[k].values.astype(float).ravel() for k in _NAV_FIELDS}
    n_t, n_s = ds.sizes["time"], ds.sizes["sv"]
    toc = np.repeat(datetime64_to_gps(ds.time.values), n_s)
    sv_all = np.tile(ds.sv.values.astype(str), n_t)
    complete = np.all(np.isfinite(np.stack(list(v.values()))), axis=0)
    keep = complete & (v["health"] == 0) & (v["sqrtA"] > 1000.0)
    if not keep.any():
        raise _nav_error(p, "has no complete healthy GPS ephemeris record")
    toe = v["GPSWeek"][keep] * SECONDS_PER_WEEK + v["Toe"][keep]
    toc = toc[keep]
    # GPSWeek belongs to Toe, but some writers use Toc's week; Toe and Toc are
    # within hours of each other, so fix a one-week mismatch from Toc.
    toe += SECONDS_PER_WEEK * np.round((toc - toe) / SECONDS_PER_WEEK)
    sats, sat_idx = np.unique(sv_all[keep], return_inverse=True)
    records = {k: v[src][keep] for k, src in _RECORD_SOURCE.items()}
    records.update(sat=sat_idx, toe=toe, toc=toc)
    iono = ds.attrs.get("ionospheric_corr_GPS")
    alpha = beta = None
    if iono is not None and np.size(iono) == 8 and np.all(np.isfinite(iono)):
        alpha, beta = np.asarray(iono[:4], float), np.asarray(iono[4:], float)
    return BroadcastEphemeris(sats, records, alpha, beta, source=os.path.basename(p), max_age_s=max_age_s)
