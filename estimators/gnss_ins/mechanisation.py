"""Strapdown ECEF mechanisation pieces shared by the GNSS/INS estimators.

The navigation frame is ECEF (Earth-fixed, rotating). The IMU gives specific
force ``f_b`` and angular rate ``w_ib^b`` (body x forward, y right, z down,
w.r.t. inertial space, Earth rate included), as :mod:`simbench.sim.imu`
produces them. The mechanisation

    p' = v,   v' = C_b^e f_b + g^e(p) - 2 Omega_ie v,   C_b^e' = C_b^e [w_ib^b x] - Omega_ie C_b^e

is integrated between GNSS epochs by GTSAM's IMU preintegration
(:class:`gtsam.PreintegratedCombinedMeasurements`) with the Earth rate as
GTSAM's "Coriolis" rate. GTSAM's prediction then adds the Coriolis term and
also the centrifugal one, ``-Omega_ie Omega_ie p`` (its second-order Coriolis
term, on in the Python wheel, which has no setter for it), so its
navigation-frame "gravity" is the WGS-84 gravitation alone
(:func:`gravitation_ecef`: :func:`simbench.sim.imu.gravity_ecef` minus the
centrifugal acceleration) at the start of the interval; passing the full
``g^e`` counts the centrifugal term twice, a 0.026 m/s^2 acceleration error
at 40 deg latitude. Over one second of driving the gravitation changes by
< 1e-4 m/s^2, well under a consumer accelerometer's noise.

Also here: coarse levelling from a static accelerometer mean, the heading
reset about the local vertical and the course over ground. The Doppler
range-rate model lives in :mod:`simbench.gnss.doppler`.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from simbench.core.constants import DEG, OMEGA_EARTH
from simbench.core.frames import (
    dcm_body_to_ecef,
    dcm_body_to_ned,
    dcm_ned_to_ecef,
    euler_from_dcm,
    geodetic_from_ecef,
)
from simbench.sim.imu import gravity_ecef

__all__ = [
    "DEG_PER_HOUR",
    "ImuNoise",
    "attitude_ecef",
    "course_over_ground",
    "gravitation_ecef",
    "level_roll_pitch",
    "preintegration_params",
    "rotate_about_vertical",
    "yaw_of",
]

#: One degree per hour in rad/s (multiply a deg/h value by it).
DEG_PER_HOUR = DEG / 3600.0


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
    def from_datasheet(
        cls,
        accel_noise_mps2_rthz: float,
        gyro_noise_dph_rthz: float,
        accel_bias_instability_mps2: float,
        gyro_bias_instability_dph: float,
        bias_tau_s: float,
    ) -> ImuNoise:
        """Convert datasheet-style values (the units of ``conf/imu``) into densities.

        A first-order Gauss-Markov bias of standard deviation ``sigma`` and
        correlation time ``tau`` has driving noise ``sigma sqrt(2 / tau)``; over a
        window of seconds it is indistinguishable from a random walk of that density.
        """
        root = np.sqrt(2.0 / bias_tau_s)
        return cls(
            accel_noise=accel_noise_mps2_rthz,
            gyro_noise=gyro_noise_dph_rthz * DEG_PER_HOUR,
            accel_bias_rw=accel_bias_instability_mps2 * root,
            gyro_bias_rw=gyro_bias_instability_dph * DEG_PER_HOUR * root,
        )


def gravitation_ecef(pos: np.ndarray) -> np.ndarray:
    """WGS-84 gravitation (gravity without the centrifugal acceleration) in ECEF.

    Parameters
    ----------
    pos : ndarray, shape (3,)
        ECEF position [m].

    Returns
    -------
    ndarray, shape (3,)
        Gravitational acceleration [m/s^2].
    """
    pos = np.asarray(pos, float)
    return gravity_ecef(pos) - OMEGA_EARTH**2 * np.array([pos[0], pos[1], 0.0])


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
    p = gtsam.PreintegrationCombinedParams(gravitation_ecef(pos))  # GTSAM adds the centrifugal term
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


def course_over_ground(pos: np.ndarray, vel: np.ndarray) -> tuple[float, float]:
    """Horizontal speed and course of an ECEF velocity at ECEF ``pos``.

    Parameters
    ----------
    pos : ndarray, shape (3,)
        ECEF position [m].
    vel : ndarray, shape (3,)
        ECEF velocity [m/s].

    Returns
    -------
    speed : float
        Horizontal speed [m/s].
    course : float
        Direction of travel [rad, from north, towards east].
    """
    v_ned = _ned_to_ecef(pos).T @ np.asarray(vel, float)
    return float(np.hypot(v_ned[0], v_ned[1])), float(np.arctan2(v_ned[1], v_ned[0]))


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
