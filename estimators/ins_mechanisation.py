"""Strapdown ECEF mechanisation pieces shared by the GNSS/INS estimators.

The navigation frame is ECEF (Earth-fixed, rotating). The IMU gives specific
force ``f_b`` and angular rate ``w_ib^b`` (body x forward, y right, z down,
w.r.t. inertial space, Earth rate included), as :mod:`simbench.sim.imu`
produces them. The mechanisation

    p' = v,   v' = C_b^e f_b + g^e(p) - 2 Omega_ie v,   C_b^e' = C_b^e [w_ib^b x] - Omega_ie C_b^e

is integrated between GNSS epochs by GTSAM's IMU preintegration
(:class:`gtsam.PreintegratedCombinedMeasurements`) with the navigation-frame
gravity set to the WGS-84 gravity (gravitation plus centrifugal,
:func:`simbench.sim.imu.gravity_ecef`) at the start of the interval and the
Earth rate as GTSAM's "Coriolis" rate; GTSAM's second-order (centrifugal) term
stays off because ``g^e`` already contains it. Over one second of driving the
gravity vector changes by < 1e-4 m/s^2, well under a consumer accelerometer's
noise.

Also here: coarse levelling from a static accelerometer mean, the heading
reset about the local vertical, the Doppler range-rate model and a
Doppler-only least-squares velocity (course over ground for the heading).
"""
from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from simbench.sim.constants import C_LIGHT, DEG, OMEGA_EARTH
from simbench.sim.frames import (
    dcm_body_to_ecef,
    dcm_body_to_ned,
    dcm_ned_to_ecef,
    euler_from_dcm,
    geodetic_from_ecef,
)
from simbench.sim.imu import gravity_ecef

__all__ = [
    "ImuNoise",
    "attitude_ecef",
    "doppler_velocity",
    "level_roll_pitch",
    "preintegration_params",
    "range_rate",
    "rotate_about_vertical",
    "yaw_of",
]

#: deg/h -> rad/s
_DPH = DEG / 3600.0


@dataclass(frozen=True)
class ImuNoise:
    """IMU stochastic model in the units GTSAM wants (continuous-time densities).

    Attributes
    ----------
    accel_noise : float
        Accelerometer white noise density [m/s^2/sqrt(Hz)].
    gyro_noise : float
        Gyro white noise density [rad/s/sqrt(Hz)].
    accel_bias_rw : float
        Accelerometer bias random walk [m/s^2/sqrt(s)].
    gyro_bias_rw : float
        Gyro bias random walk [rad/s/sqrt(s)].
    """

    accel_noise: float
    gyro_noise: float
    accel_bias_rw: float
    gyro_bias_rw: float

    @classmethod
    def from_datasheet(cls, accel_noise_mps2_rthz: float, gyro_noise_dph_rthz: float,
                       accel_bias_instability_mps2: float, gyro_bias_instability_dph: float,
                       bias_tau_s: float) -> ImuNoise:
        """Convert datasheet-style values (the units of ``conf/imu``) into densities.

        A first-order Gauss-Markov bias of standard deviation ``sigma`` and
        correlation time ``tau`` has driving noise ``sigma sqrt(2 / tau)``; over a
        window of seconds it is indistinguishable from a random walk of that density.
        """
        root = np.sqrt(2.0 / bias_tau_s)
        return cls(accel_noise=accel_noise_mps2_rthz, gyro_noise=gyro_noise_dph_rthz * _DPH,
                   accel_bias_rw=accel_bias_instability_mps2 * root,
                   gyro_bias_rw=gyro_bias_instability_dph * _DPH * root)


def preintegration_params(noise: ImuNoise, pos: np.ndarray) -> gtsam.PreintegrationCombinedParams:
    """GTSAM preintegration parameters for an ECEF navigation frame near ``pos``.

    Parameters
    ----------
    noise : ImuNoise
    pos : ndarray, shape (3,)
        ECEF position [m] where the gravity vector is evaluated.

    Returns
    -------
    gtsam.PreintegrationCombinedParams
    """
    p = gtsam.PreintegrationCombinedParams(gravity_ecef(np.asarray(pos, float)))
    p.setOmegaCoriolis(np.array([0.0, 0.0, OMEGA_EARTH]))
    eye = np.eye(3)
    p.setAccelerometerCovariance(noise.accel_noise**2 * eye)
    p.setGyroscopeCovariance(noise.gyro_noise**2 * eye)
    # integration of velocity into position is exact up to the sample rate: tiny, for conditioning only
    p.setIntegrationCovariance(1e-10 * eye)
    p.setBiasAccCovariance(noise.accel_bias_rw**2 * eye)
    p.setBiasOmegaCovariance(noise.gyro_bias_rw**2 * eye)
    return p


def level_roll_pitch(f_mean: np.ndarray) -> tuple[float, float]:
    """Coarse levelling: roll and pitch from the mean specific force of a static IMU.

    A static IMU reads ``f_b = -C_n^b g^n``, i.e. minus gravity in body axes,
    so the body components of "up" are ``f_b / |f_b|``.

    Parameters
    ----------
    f_mean : ndarray, shape (3,)
        Mean specific force, body axes [m/s^2].

    Returns
    -------
    roll, pitch : float
        [rad]. An accelerometer bias ``b`` tilts them by about ``b / g`` rad.
    """
    fx, fy, fz = f_mean
    return float(np.arctan2(-fy, -fz)), float(np.arctan2(fx, np.hypot(fy, fz)))


def attitude_ecef(pos: np.ndarray, roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Body-to-ECEF rotation C_b^e at ECEF ``pos`` [m] for local-NED Euler angles [rad]."""
    return dcm_body_to_ecef(np.asarray(pos, float)[None], np.array([[roll, pitch, yaw]]))[0]


def _ned_to_ecef(pos: np.ndarray) -> np.ndarray:
    lat, lon, _ = geodetic_from_ecef(np.asarray(pos, float))
    return dcm_ned_to_ecef(lat, lon)


def yaw_of(pos: np.ndarray, c_b_e: np.ndarray) -> float:
    """Heading [rad, from north] of a body-to-ECEF rotation at ECEF ``pos``."""
    return float(euler_from_dcm(_ned_to_ecef(pos).T @ c_b_e)[2])


def rotate_about_vertical(pos: np.ndarray, angle: float) -> np.ndarray:
    """ECEF rotation by ``angle`` [rad] about the local down axis at ``pos`` (positive: heading increases).

    Returns
    -------
    ndarray, shape (3, 3)
        ``R`` such that ``R @ C_b^e`` has its heading increased by ``angle`` and
        ``R @ v`` turns a velocity the same way.
    """
    c_n_e = _ned_to_ecef(pos)
    rz = dcm_body_to_ned(np.array([0.0, 0.0, angle]))
    return c_n_e @ rz @ c_n_e.T


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
