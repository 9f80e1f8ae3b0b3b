"""Wheel odometry from a trajectory: speed along body x and yaw rate, with a car's sensor errors.

Measurement model per sample (body axes x forward, y right, z down, as the IMU)::

    speed    = (1 + s) v_x + e_v          v_x = (C_e^b v^e)_x, s ~ N(0, scale_factor_sigma) per seed
    yaw_rate = w_z + b + e_w              w_z = (w_eb^b)_z,    b ~ N(0, yaw_rate_bias_sigma) per seed

with white ``e_v``, ``e_w``. The yaw rate is w.r.t. the Earth; a yaw-rate gyro
also senses the Earth rate (at most 7.3e-5 rad/s), below the modelled bias. A
standing car's wheels do not turn, so the speed is exactly 0 then (no ticks,
no noise), while the gyro keeps its noise and bias. The reported variances
are the configured noise variances, as a vehicle reports them, not the truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from simbench.contract import ODOMETRY_COLUMNS, ODOMETRY_OPTIONAL_COLUMNS
from simbench.errors import SimbenchError
from simbench.sim.config import OdometryConfig
from simbench.sim.trajectory import Trajectory

#: Below this true speed the wheels stand still and the odometer reads 0 [m/s]
#: (the trajectories' stops are exactly 0; a creeping car turns its wheels).
STANDSTILL_MPS = 1e-3


@dataclass(frozen=True)
class OdometrySamples:
    """Measured odometry and the true constant errors behind it.

    Attributes
    ----------
    table : pandas.DataFrame
        :data:`simbench.contract.ODOMETRY_COLUMNS`, what the receiver view carries.
    scale_factor : float
        True speed scale-factor error ``s`` (measured = (1 + s) true) [-]; truth only.
    yaw_rate_bias_rps : float
        True constant yaw-rate bias [rad/s]; truth only.
    """

    table: pd.DataFrame
    scale_factor: float
    yaw_rate_bias_rps: float


def simulate_odometry(traj: Trajectory, cfg: OdometryConfig, rng: np.random.Generator) -> OdometrySamples:
    """Wheel speed and yaw rate at ``cfg.rate_hz``, taken from every k-th trajectory sample.

    Parameters
    ----------
    traj : Trajectory
        Sampled uniformly at a multiple of ``cfg.rate_hz`` (the IMU rate);
        samples inside replay gaps (``traj.valid`` False) give no odometry.
    cfg : OdometryConfig
        Rate, white-noise sigmas, scale-factor and yaw-rate bias sigmas.
    rng : numpy.random.Generator
        The odometry's own stream, so switching odometry on changes no other error.

    Returns
    -------
    OdometrySamples

    Raises
    ------
    SimbenchError
        A non-positive rate, a rate the trajectory's cannot be decimated to,
        or a negative sigma.
    """
    if not cfg.rate_hz > 0.0:
        raise SimbenchError(
            "scenario.odometry.rate_hz", f"must be positive, got {cfg.rate_hz}", "set e.g. scenario.odometry.rate_hz=10"
        )
    for name in ("speed_sigma_mps", "scale_factor_sigma", "yaw_rate_sigma_rps", "yaw_rate_bias_sigma_rps"):
        if not getattr(cfg, name) >= 0.0:
            raise SimbenchError(
                f"scenario.odometry.{name}",
                f"must be non-negative, got {getattr(cfg, name)}",
                "give a standard deviation >= 0 (0 switches that error off)",
            )
    traj_rate = 1.0 / float(np.median(np.diff(traj.t))) if len(traj.t) > 1 else cfg.rate_hz
    step = traj_rate / cfg.rate_hz
    if abs(step - round(step)) > 1e-6 or round(step) < 1:
        raise SimbenchError(
            "scenario.odometry.rate_hz",
            f"{cfg.rate_hz:g} Hz does not divide the {traj_rate:g} Hz trajectory (IMU) rate",
            "choose an odometry rate such that imu.rate_hz / scenario.odometry.rate_hz is an integer",
        )
    idx = traj.valid_every(step)

    # body x axis in ECEF = first column of C_b^e
    x_axis = traj.c_b_e[idx, :, 0]
    v_x = np.einsum("ki,ki->k", x_axis, traj.vel[idx])
    w_z = traj.omega_eb_b[idx, 2]

    scale = cfg.scale_factor_sigma * rng.standard_normal()
    bias = cfg.yaw_rate_bias_sigma_rps * rng.standard_normal()
    noise = rng.standard_normal((2, idx.size))
    moving = np.abs(v_x) >= STANDSTILL_MPS
    speed = np.where(moving, (1.0 + scale) * v_x + cfg.speed_sigma_mps * noise[0], 0.0)
    yaw_rate = w_z + bias + cfg.yaw_rate_sigma_rps * noise[1]
    table = pd.DataFrame(
        {
            "t": traj.t[idx],
            "speed": speed,
            "yaw_rate": yaw_rate,
            "var_speed": np.full(idx.size, cfg.speed_sigma_mps**2),
            "var_yaw_rate": np.full(idx.size, cfg.yaw_rate_sigma_rps**2),
            # a simulated car reports its wheel speed and yaw rate only (the estimators' own priors hold the rest)
            **{column: np.full(idx.size, np.nan) for column in ODOMETRY_OPTIONAL_COLUMNS},
        },
        columns=list(ODOMETRY_COLUMNS),
    )
    return OdometrySamples(table=table, scale_factor=float(scale), yaw_rate_bias_rps=float(bias))
