"""The estimator-side Doppler model: range rate with the Earth's rotation, and a Doppler velocity fix.

A Doppler measurement gives the range rate plus the receiver clock drift,
``-lambda D + c dt_s' = rho' + c dt_r'``. The satellite state of transmit time
is turned into the receive-time ECEF frame (rotation by ``omega_e tau``) and
the range rate differentiated there; the light-time denominator is kept.
"""
from __future__ import annotations

import numpy as np

from simbench.sim.constants import C_LIGHT, OMEGA_EARTH

__all__ = ["range_rate", "doppler_velocity"]


def _rotated_satellite(sat_pos: np.ndarray, sat_vel: np.ndarray,
                       rx_pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Satellite position and velocity of transmit time, turned into the receive-time ECEF frame."""
    tau = np.linalg.norm(sat_pos - rx_pos, axis=1) / C_LIGHT
    th = OMEGA_EARTH * tau
    c, s = np.cos(th), np.sin(th)
    q = np.stack([c * sat_pos[:, 0] + s * sat_pos[:, 1], c * sat_pos[:, 1] - s * sat_pos[:, 0], sat_pos[:, 2]], 1)
    w = np.stack([c * sat_vel[:, 0] + s * sat_vel[:, 1], c * sat_vel[:, 1] - s * sat_vel[:, 0], sat_vel[:, 2]], 1)
    return q, w


def range_rate(sat_pos: np.ndarray, sat_vel: np.ndarray, rx_pos: np.ndarray,
               rx_vel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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


def doppler_velocity(sat_pos: np.ndarray, sat_vel: np.ndarray, rx_pos: np.ndarray, range_rate_obs: np.ndarray,
                     sigma: np.ndarray, iterations: int = 3) -> tuple[np.ndarray, float]:
    """Least-squares receiver velocity and clock drift from one epoch's Doppler.

    Parameters
    ----------
    sat_pos, sat_vel : ndarray, shape (k, 3)
        Satellite ECEF position [m] and velocity [m/s].
    rx_pos : ndarray, shape (3,)
        Receiver position [m] (a few metres of error do not matter).
    range_rate_obs : ndarray, shape (k,)
        Observed range rate plus receiver clock drift [m/s] (``-lambda D`` plus the satellite drift).
    sigma : ndarray, shape (k,)
        Standard deviations [m/s].

    Returns
    -------
    vel : ndarray, shape (3,)
        ECEF velocity [m/s].
    drift : float
        Receiver clock drift times c [m/s].
    """
    vel, drift = np.zeros(3), 0.0
    w = 1.0 / sigma
    A = np.empty((len(sigma), 4))
    A[:, 3] = 1.0
    for _ in range(iterations):
        rdot, _, d_vel = range_rate(sat_pos, sat_vel, rx_pos, vel)
        A[:, :3] = d_vel
        dx, *_ = np.linalg.lstsq(A * w[:, None], (range_rate_obs - rdot - drift) * w, rcond=None)
        vel = vel + dx[:3]
        drift += float(dx[3])
    return vel, drift
