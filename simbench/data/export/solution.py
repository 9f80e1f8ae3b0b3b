"""A position solution as an RTKLIB ``.pos`` file (rtkplot, pos2kml) or a TUM trajectory (evo).

RTKLIB ``.pos`` (:func:`rtklib_pos_text`), as ``rnx2rtkp`` writes it with ``out-timeform = tow``
and decimal degrees, and as :func:`simbench.data.rtklib_pos.parse_rtklib_pos` and RTKLIB's own
reader (``readsol``) read it back::

    %  GPST                  latitude(deg)  longitude(deg)   height(m)   Q  ns   sdn(m)   sde(m)   sdu(m) ...
    2053   95400.000000   22.301443725  114.179003671    3.4231   5  14   1.0232   0.8911   2.3110 ...

=============  ================================================================================
GPST           GPS week and GPS seconds of week [s] (6 decimals)
latitude(deg)  WGS-84 geodetic latitude [deg] (9 decimals, 0.1 mm)
longitude(deg) longitude, east positive [deg] (9 decimals)
height(m)      ellipsoidal height [m] (4 decimals)
Q              RTKLIB quality flag (5: single, no ambiguity fixing)
ns             number of satellites (the caller says which: observed or used)
sdn ... sdun   standard deviations north, east, up [m] and the signed square roots of the
               north-east, east-up and up-north covariances [m], RTKLIB's convention; left out
               where the solution has no covariance
=============  ================================================================================

TUM (:func:`tum_text`), one pose per line, ``#`` comments::

    timestamp x y z qx qy qz qw

``timestamp`` continuous GPS seconds since 1980-01-06 [s] (6 decimals); ``x y z`` whatever frame
the caller passes [m] (4 decimals); the orientation is unknown and written as the identity
(``0 0 0 1``), so evo's position metrics (``evo_ape tum ... -a``) apply, not its rotation ones.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simbench.core.constants import SECONDS_PER_WEEK
from simbench.core.frames import dcm_ned_to_ecef, geodetic_from_ecef

__all__ = ["POS_QUALITY_SINGLE", "rtklib_pos_text", "tum_text"]

#: RTKLIB's quality flag of a single-point solution (no ambiguity fixed).
POS_QUALITY_SINGLE = 5
#: The column header RTKLIB's reader takes the layout from (time system, position form, separator).
POS_HEADER = "%  GPST                  latitude(deg)  longitude(deg)   height(m)   Q  ns"
POS_STD_HEADER = "   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m)"


def _enu_covariance(xyz: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """ECEF covariances (n, 3, 3) [m^2] rotated into the local east-north-up frame of each position."""
    lat, lon, _ = geodetic_from_ecef(xyz)
    ned = dcm_ned_to_ecef(lat, lon)  # columns north, east, down in ECEF
    enu = np.stack([ned[..., 1], ned[..., 0], -ned[..., 2]], axis=-1)  # columns east, north, up
    return np.swapaxes(enu, -1, -2) @ covariance @ enu


def rtklib_pos_text(
    t_gps: np.ndarray,
    xyz: np.ndarray,
    ns: np.ndarray,
    covariance: np.ndarray | None = None,
    comments: Sequence[str] = (),
    quality: int = POS_QUALITY_SINGLE,
) -> str:
    """The text of an RTKLIB ``.pos`` file (module docstring).

    Parameters
    ----------
    t_gps : numpy.ndarray, shape (n,)
        Solution times, continuous GPS seconds since 1980-01-06 [s].
    xyz : numpy.ndarray, shape (n, 3)
        ECEF positions [m], all finite.
    ns : numpy.ndarray of int, shape (n,)
        Satellites per solution.
    covariance : numpy.ndarray, shape (n, 3, 3), optional
        ECEF position covariances [m^2]; None (or NaN rows) leaves the standard-deviation columns out.
    comments : sequence of str
        Header lines before the column header, each written as ``% <line>``.
    quality : int
        RTKLIB quality flag of every row.

    Returns
    -------
    str
    """
    xyz = np.asarray(xyz, float).reshape(-1, 3)
    week = np.floor(np.asarray(t_gps, float) / SECONDS_PER_WEEK).astype(np.int64)
    tow = np.asarray(t_gps, float) - week * SECONDS_PER_WEEK
    lat, lon, h = geodetic_from_ecef(xyz)
    columns = [week, tow, np.degrees(lat), np.degrees(lon), h, np.full(len(xyz), quality), np.asarray(ns, np.int64)]
    row = "{:4d} {:14.6f} {:14.9f} {:15.9f} {:11.4f} {:3d} {:3d}"
    with_std = covariance is not None and len(xyz) > 0 and bool(np.isfinite(covariance).all())
    if with_std:
        enu = _enu_covariance(xyz, np.asarray(covariance, float))
        std = np.sqrt(np.maximum(np.diagonal(enu, axis1=-2, axis2=-1), 0.0))  # e, n, u
        cross = enu[:, [1, 0, 2], [0, 2, 1]]  # north-east, east-up, up-north
        signed = np.sign(cross) * np.sqrt(np.abs(cross))  # RTKLIB: sign(c) sqrt(|c|)
        columns += [std[:, 1], std[:, 0], std[:, 2], *signed.T]
        row += " {:8.4f}" * 6
    lines = [f"% {line}" for line in comments]
    lines.append(POS_HEADER + (POS_STD_HEADER if with_std else ""))
    lines += [row.format(*values) for values in zip(*(c.tolist() for c in columns))]
    return "\n".join(lines) + "\n"


def tum_text(t_gps: np.ndarray, xyz: np.ndarray, comments: Sequence[str] = ()) -> str:
    """The text of a TUM trajectory file: ``timestamp x y z 0 0 0 1`` per row (module docstring).

    Parameters
    ----------
    t_gps : numpy.ndarray, shape (n,)
        Continuous GPS seconds since 1980-01-06 [s].
    xyz : numpy.ndarray, shape (n, 3)
        Positions in the frame the comments name [m].
    comments : sequence of str
        Lines written first as ``# <line>``.
    """
    xyz = np.asarray(xyz, float).reshape(-1, 3)
    rows = [
        f"{t:.6f} {x:.4f} {y:.4f} {z:.4f} 0 0 0 1"
        for t, x, y, z in zip(np.asarray(t_gps, float).tolist(), *(c.tolist() for c in xyz.T))
    ]
    return "\n".join([*(f"# {line}" for line in comments), *rows]) + "\n"
