"""Coordinate frames: WGS-84 geodetic <-> ECEF, local NED, body attitude.

Body axes are x forward, y right, z down; attitude is roll, pitch, yaw
(z-y-x Euler angles) of the body with respect to the local NED frame. The
``*_from_trig`` variants take precomputed sines and cosines, for hot loops
that already have them.
"""

from __future__ import annotations

import math

import numpy as np

from simbench.core.constants import WGS84_A, WGS84_E2


def geodetic_trig(pos: np.ndarray) -> tuple[np.ndarray, ...]:
    """sin/cos of geodetic latitude and longitude and the height, without trigonometric calls.

    Bowring's iteration written with tangents: tan(beta) = (b/a) tan(lat), so every
    sine and cosine comes from a square root. Two passes reach 1e-15 rad from the
    ground to GNSS orbit altitude.
    """
    pos = np.asarray(pos, dtype=float)
    x, y, z = pos[..., 0], pos[..., 1], pos[..., 2]
    p = np.sqrt(x * x + y * y)
    b = WGS84_A * math.sqrt(1.0 - WGS84_E2)
    ep2 = WGS84_E2 / (1.0 - WGS84_E2)
    # sqrt of a sum of squares (not hypot) and cubes as products (not power): several times
    # faster, and nothing here is near overflow
    # (num, den) is a vector along (cos, sin) of the reduced latitude, then of the latitude
    cb, sb = p * b, z * WGS84_A
    for _ in range(2):
        norm = np.sqrt(cb * cb + sb * sb)
        cb, sb = cb / norm, sb / norm
        num = z + ep2 * b * (sb * sb * sb)
        den = p - WGS84_E2 * WGS84_A * (cb * cb * cb)
        cb, sb = WGS84_A * den, b * num  # tan(beta) = (b/a) tan(lat)
    norm = np.sqrt(den * den + num * num)
    sl, cl = num / norm, den / norm
    h = p * cl + z * sl - WGS84_A * np.sqrt(1.0 - WGS84_E2 * sl * sl)
    on_axis = p == 0.0
    so = np.where(on_axis, 0.0, y / np.where(on_axis, 1.0, p))
    co = np.where(on_axis, 1.0, x / np.where(on_axis, 1.0, p))
    return sl, cl, so, co, h


def dot_last_axis(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Sum of ``a * b`` over a short last axis (vectors, rays), added left to right one column at a time.

    The same sum as ``(a * b).sum(-1)`` for a few columns, several times faster than numpy's
    reduction over a short last axis (and than ``einsum``).
    """
    out = a[..., 0] * b[..., 0]
    for k in range(1, b.shape[-1]):
        out += a[..., k] * b[..., k]
    return out


def geodetic_from_ecef(pos: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """WGS-84 geodetic coordinates of ECEF points (Bowring, two iterations).

    Parameters
    ----------
    pos : ndarray, shape (k, 3)
        ECEF position [m].

    Returns
    -------
    lat, lon : ndarray, shape (k,)
        Geodetic latitude and longitude [rad].
    h : ndarray, shape (k,)
        Ellipsoidal height [m]. Accurate to well below a millimetre from the
        ground to GNSS orbit altitude.
    """
    sl, cl, so, co, h = geodetic_trig(pos)
    return np.arctan2(sl, cl), np.arctan2(so, co), h


def ecef_from_geodetic(lat: np.ndarray | float, lon: np.ndarray | float, h: np.ndarray | float) -> np.ndarray:
    """ECEF position of WGS-84 geodetic coordinates.

    Parameters
    ----------
    lat, lon : float or ndarray, shape (k,)
        Geodetic latitude and longitude [rad].
    h : float or ndarray, shape (k,)
        Ellipsoidal height [m].

    Returns
    -------
    ndarray, shape (..., 3)
        ECEF position [m].
    """
    sl, cl = np.sin(lat), np.cos(lat)
    rn = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sl * sl)
    return np.stack(
        [(rn + h) * cl * np.cos(lon), (rn + h) * cl * np.sin(lon), (rn * (1.0 - WGS84_E2) + h) * sl], axis=-1
    )


def dcm_ned_to_ecef(lat: np.ndarray | float, lon: np.ndarray | float) -> np.ndarray:
    """Rotation matrix C_n^e from the local NED frame to ECEF.

    Parameters
    ----------
    lat, lon : float or ndarray, shape (k,)
        Geodetic latitude and longitude [rad].

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Columns are the north, east and down unit vectors in ECEF.
    """
    return dcm_ned_to_ecef_from_trig(np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon))


def dcm_ned_to_ecef_from_trig(sl: np.ndarray, cl: np.ndarray, so: np.ndarray, co: np.ndarray) -> np.ndarray:
    # filled as (3, 3, k) with contiguous writes, returned as a (k, 3, 3) view: ~10x faster
    # than stacking (k,) arrays along trailing axes
    c = np.empty((3, 3) + np.shape(sl))
    c[0, 0], c[0, 1], c[0, 2] = -sl * co, -so, -cl * co
    c[1, 0], c[1, 1], c[1, 2] = -sl * so, co, -cl * so
    c[2, 0], c[2, 1], c[2, 2] = cl, 0.0, -sl
    return np.moveaxis(c, (0, 1), (-2, -1))


def dcm_body_to_ned(att: np.ndarray) -> np.ndarray:
    """Rotation matrix C_b^n from roll, pitch, yaw (z-y-x Euler angles).

    Parameters
    ----------
    att : ndarray, shape (..., 3)
        Roll, pitch, yaw [rad].

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    att = np.asarray(att, dtype=float)
    return dcm_body_to_ned_from_trig(
        np.sin(att[..., 0]),
        np.cos(att[..., 0]),
        np.sin(att[..., 1]),
        np.cos(att[..., 1]),
        np.sin(att[..., 2]),
        np.cos(att[..., 2]),
    )


def dcm_body_to_ned_from_trig(
    sr: np.ndarray, cr: np.ndarray, sp: np.ndarray, cp: np.ndarray, sy: np.ndarray, cy: np.ndarray
) -> np.ndarray:
    c = np.empty((3, 3) + np.shape(sr))
    c[0, 0], c[0, 1], c[0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    c[1, 0], c[1, 1], c[1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    c[2, 0], c[2, 1], c[2, 2] = -sp, cp * sr, cp * cr
    return np.moveaxis(c, (0, 1), (-2, -1))


def euler_from_dcm(c_b_n: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw [rad] of a body-to-NED rotation matrix, shape (..., 3, 3) -> (..., 3)."""
    return np.stack(
        [
            np.arctan2(c_b_n[..., 2, 1], c_b_n[..., 2, 2]),
            -np.arcsin(np.clip(c_b_n[..., 2, 0], -1.0, 1.0)),
            np.arctan2(c_b_n[..., 1, 0], c_b_n[..., 0, 0]),
        ],
        axis=-1,
    )


def dcm_body_to_ecef(pos: np.ndarray, att: np.ndarray) -> np.ndarray:
    """Rotation matrix C_b^e of a body at ECEF ``pos`` [m] with local-NED attitude ``att`` [rad]."""
    sl, cl, so, co, _ = geodetic_trig(pos)
    return np.matmul(dcm_ned_to_ecef_from_trig(sl, cl, so, co), dcm_body_to_ned(att))
