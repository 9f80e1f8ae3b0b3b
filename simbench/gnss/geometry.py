"""Receiver-satellite geometry of the estimator-side measurement model.

The simulator computes the exact transit geometry
(:func:`simbench.sim.geometry.line_of_sight`); everything that *models* a
measurement (log readers, single-point solutions, estimators) uses the
first-order Sagnac range of this module and its gradient, so there is one
range model and one Jacobian in the project.
"""

from __future__ import annotations

import numpy as np

from simbench.core.constants import C_LIGHT, OMEGA_EARTH
from simbench.core.frames import geodetic_from_ecef
from simbench.errors import SimbenchError

__all__ = ["sagnac_range", "sagnac_range_gradient", "elevation_azimuth", "enu_basis", "as_xyz"]


def sagnac_range(sat_pos_tx: np.ndarray, rx_pos: np.ndarray) -> np.ndarray:
    """Estimator-side range model with the first-order Earth-rotation correction.

    ``|s - r| + omega_e (s_x r_y - s_y r_x) / c`` with the satellite at transmit
    time in ECEF(t_tx) and the receiver at receive time (RTKLIB ``geodist``).
    Differs from the exact rotation by second-order terms, < 0.5 mm for
    receivers near the Earth (measured <= 0.12 mm).

    Parameters
    ----------
    sat_pos_tx : np.ndarray, shape (..., 3)
        Satellite position at transmit time in ECEF(t_tx) [m].
    rx_pos : np.ndarray, shape (..., 3)
        Receiver position at receive time in ECEF(t_rx) [m]; broadcastable.

    Returns
    -------
    rho : np.ndarray, shape (...)
        Range including the Sagnac term [m].
    """
    s = np.asarray(sat_pos_tx, dtype=float)
    r = np.asarray(rx_pos, dtype=float)
    d = s - r
    return np.sqrt(np.sum(d * d, axis=-1)) + OMEGA_EARTH * (s[..., 0] * r[..., 1] - s[..., 1] * r[..., 0]) / C_LIGHT


def sagnac_range_gradient(sat_pos_tx: np.ndarray, rx_pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sagnac_range` and its gradient with respect to the receiver position.

    Parameters
    ----------
    sat_pos_tx : np.ndarray, shape (..., 3)
        Satellite position at transmit time in ECEF(t_tx) [m].
    rx_pos : np.ndarray, shape (..., 3)
        Receiver position [m]; broadcastable against ``sat_pos_tx``.

    Returns
    -------
    rho : np.ndarray, shape (...)
        Range including the Sagnac term [m].
    grad : np.ndarray, shape (..., 3)
        d rho / d rx_pos [-]: minus the line-of-sight unit vector plus the
        Sagnac term's ``omega_e / c (-s_y, s_x, 0)``.
    """
    s = np.asarray(sat_pos_tx, dtype=float)
    r = np.asarray(rx_pos, dtype=float)
    d = s - r
    dist = np.sqrt(np.sum(d * d, axis=-1))
    # the same expression as sagnac_range, so both give the same bits
    rho = dist + OMEGA_EARTH * (s[..., 0] * r[..., 1] - s[..., 1] * r[..., 0]) / C_LIGHT
    w = OMEGA_EARTH / C_LIGHT
    grad = -d / dist[..., None]
    grad[..., 0] -= w * s[..., 1]
    grad[..., 1] += w * s[..., 0]
    return rho, grad


def as_xyz(name: str, a: np.ndarray | None, n: int | None) -> np.ndarray:
    """Validate ECEF coordinates as an (n, 3) float array; one-line error naming ``name``.

    A single (3,) row is accepted as shape (1, 3); with ``n`` given, (1, 3) or (n, 3).
    """
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        raise SimbenchError(name, "is not numeric", "pass an (n, 3) array of ECEF coordinates") from None
    if arr.ndim == 1 and arr.shape == (3,):
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3 or (n is not None and arr.shape[0] not in (1, n)):
        want = "(n, 3)" if n is None else f"({n}, 3)"
        # arr is still np.asarray(a) here: the (3,) -> (1, 3) promotion always passes this test
        raise SimbenchError(name, f"has shape {arr.shape}, expected {want}", "pass one ECEF xyz row per epoch")
    if not np.all(np.isfinite(arr)):
        raise SimbenchError(name, "contains NaN or infinite values", "remove non-finite epochs")
    return arr


def enu_basis(rx_pos: np.ndarray) -> np.ndarray:
    """Rows east, north, up of the local geodetic frame at each position, shape (n, 3, 3)."""
    lat, lon, _ = geodetic_from_ecef(rx_pos)
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    zero = np.zeros_like(sl)
    return np.stack(
        [
            np.stack([-so, co, zero], axis=-1),
            np.stack([-sl * co, -sl * so, cl], axis=-1),
            np.stack([cl * co, cl * so, sl], axis=-1),
        ],
        axis=-2,
    )


def elevation_azimuth(rx_pos: np.ndarray, sat_pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elevation and azimuth of satellites seen from receivers (local geodetic frame).

    Parameters
    ----------
    rx_pos : np.ndarray, shape (n, 3)
        Receiver ECEF positions [m].
    sat_pos : np.ndarray, shape (n, m, 3)
        Satellite ECEF positions in the same frame [m].

    Returns
    -------
    el : np.ndarray, shape (n, m)
        Elevation above the ellipsoidal horizon [rad].
    az : np.ndarray, shape (n, m)
        Azimuth clockwise from north, in [0, 2 pi) [rad].
    """
    rx = as_xyz("rx_pos", rx_pos, None)
    sat = np.asarray(sat_pos, dtype=float)
    if sat.ndim == 2:
        sat = sat[None]
    d = sat - rx[:, None, :]
    u = d / np.linalg.norm(d, axis=-1, keepdims=True)
    enu = np.einsum("nij,nmj->nmi", enu_basis(rx), u, optimize=False)
    el = np.arcsin(np.clip(enu[..., 2], -1.0, 1.0))
    az = np.mod(np.arctan2(enu[..., 0], enu[..., 1]), 2.0 * np.pi)
    return el, az
