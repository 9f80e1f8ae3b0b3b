"""Strapdown IMU: ideal specific force and angular rate from a trajectory, plus sensor errors.

Sign conventions (ECEF mechanisation, Groves ch. 5):

    r_ddot = C_b^e f_b + g^e - 2 Omega_ie v^e        (g^e: gravitation + centrifugal)
    w_ib^b = w_eb^b + C_e^b w_ie^e

so a stationary IMU reads f_b = -C_e^b g^e, i.e. about +9.8 m/s^2 "up" (-z in
a level body frame), and w_ib^b is the Earth rate.

The error model per axis is: turn-on bias ~ N(0, sigma), plus a stationary
first-order Gauss-Markov bias drift, plus white noise of standard deviation
density * sqrt(rate). Biases are returned as truth, apart from the measurements.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simbench.core.constants import DEG, J2_EARTH, MU_EARTH_WGS84, OMEGA_EARTH, WGS84_A
from simbench.errors import SimbenchError
from simbench.sim.config import ImuConfig
from simbench.sim.processes import gauss_markov
from simbench.sim.trajectory import Trajectory

#: deg/h -> rad/s
DPH: float = DEG / 3600.0


@dataclass(frozen=True)
class ImuSamples:
    """Measured IMU output and the true sensor biases, on the trajectory's time grid.

    Attributes
    ----------
    t : ndarray, shape (k,)
        Time since scenario start [s].
    accel : ndarray, shape (k, 3)
        Measured specific force, body axes [m/s^2].
    gyro : ndarray, shape (k, 3)
        Measured angular rate w_ib^b, body axes [rad/s].
    accel_bias, gyro_bias : ndarray, shape (k, 3)
        True biases (turn-on + drift) [m/s^2], [rad/s]; truth only, never shown to estimators.
    """

    t: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    accel_bias: np.ndarray
    gyro_bias: np.ndarray


def gravity_ecef(pos: np.ndarray) -> np.ndarray:
    """WGS-84 gravity (J2 gravitation plus centrifugal) in ECEF.

    Groves eq. 2.142 (gravitational acceleration with the J2 term) plus the
    centrifugal acceleration of the rotating frame, eq. 2.133. Agrees with
    the normal gravity of the ellipsoid to about 1e-4 m/s^2 near the surface.

    Parameters
    ----------
    pos : ndarray, shape (k, 3) or (3,)
        ECEF position [m].

    Returns
    -------
    ndarray, same shape as ``pos``
        Acceleration due to gravity [m/s^2] (points roughly down).
    """
    pos = np.asarray(pos, dtype=float)
    x, y, z = pos[..., 0], pos[..., 1], pos[..., 2]
    r2 = x * x + y * y + z * z
    r = np.sqrt(r2)
    zr2 = z * z / r2
    j2 = 1.5 * J2_EARTH * WGS84_A**2 / r2
    scale = -MU_EARTH_WGS84 / (r2 * r)
    w2 = OMEGA_EARTH**2
    return np.stack(
        [
            scale * x * (1.0 + j2 * (1.0 - 5.0 * zr2)) + w2 * x,
            scale * y * (1.0 + j2 * (1.0 - 5.0 * zr2)) + w2 * y,
            scale * z * (1.0 + j2 * (3.0 - 5.0 * zr2)),
        ],
        axis=-1,
    )


def ideal_imu(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Error-free specific force and angular rate along a trajectory.

    Parameters
    ----------
    traj : Trajectory

    Returns
    -------
    f_b : ndarray, shape (k, 3)
        Specific force in body axes [m/s^2], f_b = C_e^b (a + 2 Omega_ie v - g).
    w_ib_b : ndarray, shape (k, 3)
        Angular rate of the body w.r.t. inertial space, body axes [rad/s].
    """
    c_b_e = traj.c_b_e
    vel = traj.vel
    coriolis = np.stack([-2.0 * OMEGA_EARTH * vel[:, 1], 2.0 * OMEGA_EARTH * vel[:, 0], np.zeros(len(vel))], axis=-1)
    f_e = traj.acc + coriolis - gravity_ecef(traj.pos)
    f_b = np.einsum("kji,kj->ki", c_b_e, f_e)
    # C_e^b [0, 0, w_ie] is w_ie times the third row of C_b^e
    w_ib_b = traj.omega_eb_b + OMEGA_EARTH * c_b_e[:, 2, :]
    return f_b, w_ib_b


def simulate_imu(traj: Trajectory, cfg: ImuConfig, rng: np.random.Generator) -> ImuSamples:
    """Measured IMU samples: ideal output plus turn-on bias, Gauss-Markov drift and white noise.

    Parameters
    ----------
    traj : Trajectory
        Sampled at ``cfg.rate_hz`` (the caller generates it at the IMU rate).
    cfg : ImuConfig
        Grade: turn-on bias sigmas, noise densities per sqrt(Hz), bias
        instability (Gauss-Markov std) and its correlation time. Gyro values
        are in deg/h (densities deg/h/sqrt(Hz)) and converted to rad/s here.
    rng : numpy.random.Generator

    Returns
    -------
    ImuSamples

    Raises
    ------
    SimbenchError
        If the trajectory is not sampled at ``cfg.rate_hz`` or a parameter is out of range.
    """
    if not cfg.rate_hz > 0.0:
        raise SimbenchError("imu.rate_hz", f"must be positive, got {cfg.rate_hz}", "set e.g. imu.rate_hz=100")
    dt = 1.0 / cfg.rate_hz
    steps = np.diff(traj.t)
    if len(steps) and np.abs(steps - dt).max() > 1e-6 * dt + 1e-9:
        raise SimbenchError(
            "imu.rate_hz",
            f"trajectory is sampled at {1.0 / np.median(steps):g} Hz, not {cfg.rate_hz:g} Hz",
            "generate the trajectory at the IMU rate",
        )
    if not cfg.bias_tau_s > 0.0:
        raise SimbenchError(
            "imu.bias_tau_s",
            f"must be positive, got {cfg.bias_tau_s}",
            "give the bias correlation time in seconds, e.g. imu.bias_tau_s=300",
        )
    for name in (
        "accel_bias_sigma_mps2",
        "gyro_bias_sigma_dph",
        "accel_noise_mps2_rthz",
        "gyro_noise_dph_rthz",
        "accel_bias_instability_mps2",
        "gyro_bias_instability_dph",
    ):
        if getattr(cfg, name) < 0.0:
            raise SimbenchError(
                f"imu.{name}", f"must be non-negative, got {getattr(cfg, name)}", "see conf/imu/ for the grades"
            )
    k = len(traj.t)
    f_b, w_ib_b = ideal_imu(traj)
    accel_bias = cfg.accel_bias_sigma_mps2 * rng.standard_normal(3) + gauss_markov(
        k, 3, cfg.accel_bias_instability_mps2, cfg.bias_tau_s, dt, rng
    )
    gyro_bias = DPH * (
        cfg.gyro_bias_sigma_dph * rng.standard_normal(3)
        + gauss_markov(k, 3, cfg.gyro_bias_instability_dph, cfg.bias_tau_s, dt, rng)
    )
    root_rate = np.sqrt(cfg.rate_hz)  # white noise of density N per sqrt(Hz) sampled at f_s has std N sqrt(f_s)
    # sums built in the noise draws' buffers: each (k, 3) temporary costs as much as the draw
    accel = rng.standard_normal((k, 3))
    accel *= cfg.accel_noise_mps2_rthz * root_rate
    accel += f_b
    accel += accel_bias
    gyro = rng.standard_normal((k, 3))
    gyro *= DPH * cfg.gyro_noise_dph_rthz * root_rate
    gyro += w_ib_b
    gyro += gyro_bias
    return ImuSamples(t=traj.t, accel=accel, gyro=gyro, accel_bias=accel_bias, gyro_bias=gyro_bias)
