"""The estimator-side Doppler model: range rate with the Earth's rotation, and a Doppler velocity fix.

A Doppler measurement gives the range rate plus the receiver clock drift,
``-lambda D + c dt_s' = rho' + c dt_r'``. The satellite state of transmit time
is turned into the receive-time ECEF frame (rotation by ``omega_e tau``) and
the range rate differentiated there; the light-time denominator is kept.
"""

from __future__ import annotations

import numpy as np

from simbench.core.constants import C_LIGHT, OMEGA_EARTH
from simbench.gnss.normal_equations import pinv_solve

__all__ = ["range_rate", "doppler_velocity", "doppler_velocities"]


def _rotated_satellite(sat_pos: np.ndarray, sat_vel: np.ndarray, rx_pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Satellite position and velocity of transmit time, turned into the receive-time ECEF frame."""
    tau = np.linalg.norm(sat_pos - rx_pos, axis=1) / C_LIGHT
    th = OMEGA_EARTH * tau
    c, s = np.cos(th), np.sin(th)
    q = np.stack([c * sat_pos[:, 0] + s * sat_pos[:, 1], c * sat_pos[:, 1] - s * sat_pos[:, 0], sat_pos[:, 2]], 1)
    w = np.stack([c * sat_vel[:, 0] + s * sat_vel[:, 1], c * sat_vel[:, 1] - s * sat_vel[:, 0], sat_vel[:, 2]], 1)
    return q, w


def range_rate(
    sat_pos: np.ndarray, sat_vel: np.ndarray, rx_pos: np.ndarray, rx_vel: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geometric range rate and its gradients, with the Earth rotation during signal transit.

    Same model as the simulator: the satellite of transmit time is rotated
    into the receive-time frame, and the range rate is
    ``(u.w - u.v_r) / (1 + (u.w - omega (u_x q_y - u_y q_x)) / c)`` (``q``, ``w``:
    rotated satellite position and velocity, ``u`` the unit line of sight).

    Parameters
    ----------
    sat_pos, sat_vel : ndarray, shape (k, 3)
        Satellite ECEF position [m] and velocity [m/s] at transmit time.
    rx_pos, rx_vel : ndarray, shape (3,)
        Receiver ECEF position [m] and velocity [m/s].

    Returns
    -------
    rdot : ndarray, shape (k,)
        Range rate [m/s] (positive when receding).
    d_pos : ndarray, shape (k, 3)
        Partials w.r.t. the receiver position [1/s].
    d_vel : ndarray, shape (k, 3)
        Partials w.r.t. the receiver velocity [-].
    """
    q, w = _rotated_satellite(sat_pos, sat_vel, rx_pos)
    d = q - rx_pos
    rng = np.linalg.norm(d, axis=1)
    u = d / rng[:, None]
    rel = w - rx_vel
    u_rel = np.einsum("ij,ij->i", u, rel)
    a = np.einsum("ij,ij->i", u, w)
    den = 1.0 + (a - OMEGA_EARTH * (u[:, 0] * q[:, 1] - u[:, 1] * q[:, 0])) / C_LIGHT
    rdot = u_rel / den
    # the denominator differs from 1 by ~1e-5: its gradient is negligible
    d_pos = -(rel - u * u_rel[:, None]) / (rng * den)[:, None]
    d_vel = -u / den[:, None]
    return rdot, d_pos, d_vel


def doppler_velocities(
    epoch: np.ndarray,
    sat_pos: np.ndarray,
    sat_vel: np.ndarray,
    rx_pos: np.ndarray,
    range_rate_obs: np.ndarray,
    sigma: np.ndarray,
    n_epochs: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares receiver velocity and clock drift of many epochs at once.

    The range rate is linear in the receiver velocity for a given receiver position
    (the light-time denominator of :func:`range_rate` does not depend on it), so one
    solve of each epoch's 4x4 normal equations is exact.

    Parameters
    ----------
    epoch : ndarray of int, shape (N,)
        Epoch index 0..n_epochs-1 of each row.
    sat_pos, sat_vel : ndarray, shape (N, 3)
        Satellite ECEF position [m] and velocity [m/s].
    rx_pos : ndarray, shape (N, 3) or (3,)
        Receiver position of each row's epoch [m] (a few metres of error do not matter).
    range_rate_obs : ndarray, shape (N,)
        Observed range rate plus receiver clock drift [m/s] (``-lambda D`` plus the satellite drift);
        non-finite rows are ignored.
    sigma : ndarray, shape (N,)
        Standard deviations [m/s].
    n_epochs : int, optional
        Number of epochs (default ``epoch.max() + 1``).

    Returns
    -------
    vel : ndarray, shape (n_epochs, 3)
        ECEF velocity [m/s]; NaN for epochs with fewer than 4 usable rows.
    drift : ndarray, shape (n_epochs,)
        Receiver clock drift times c [m/s]; NaN likewise.
    """
    epoch = np.asarray(epoch, np.int64)
    nk = int(n_epochs if n_epochs is not None else epoch.max(initial=-1) + 1)
    ok = np.isfinite(range_rate_obs) & np.isfinite(sat_vel).all(axis=1) & np.isfinite(sigma)
    rows = np.flatnonzero(ok)
    rows = rows[np.argsort(epoch[rows], kind="stable")]
    vel, drift = np.full((nk, 3), np.nan), np.full(nk, np.nan)
    if rows.size == 0:
        return vel, drift
    rx = np.broadcast_to(np.asarray(rx_pos, float), (len(epoch), 3))[rows]
    rdot0, _, d_vel = range_rate(sat_pos[rows], sat_vel[rows], rx, np.zeros((rows.size, 3)))
    A = np.column_stack([d_vel, np.ones(rows.size)])
    w = 1.0 / np.asarray(sigma, float)[rows] ** 2
    present, starts, counts = np.unique(epoch[rows], return_index=True, return_counts=True)
    N = np.add.reduceat(A[:, :, None] * A[:, None, :] * w[:, None, None], starts, axis=0)
    b = np.add.reduceat(A * (w * (range_rate_obs[rows] - rdot0))[:, None], starts, axis=0)
    solvable = counts >= 4
    # rows with negligible weight must leave a minimum-norm answer, not an error
    x = pinv_solve(N[solvable], b[solvable])
    vel[present[solvable]] = x[:, :3]
    drift[present[solvable]] = x[:, 3]
    return vel, drift


def doppler_velocity(
    sat_pos: np.ndarray, sat_vel: np.ndarray, rx_pos: np.ndarray, range_rate_obs: np.ndarray, sigma: np.ndarray
) -> tuple[np.ndarray, float]:
    """:func:`doppler_velocities` of one epoch: velocity (3,) [m/s] and clock drift times c [m/s]."""
    vel, drift = doppler_velocities(
        np.zeros(len(sigma), np.int64), sat_pos, sat_vel, rx_pos, range_rate_obs, sigma, n_epochs=1
    )
    return vel[0], float(drift[0])
