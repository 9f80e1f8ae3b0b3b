"""Antenna: C/N0 through the gain pattern, and attitude masking (``scenario.errors.attitude_masking``)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.core.constants import DEG
from simbench.core.frames import dcm_body_to_ned
from simbench.sim import tracking
from simbench.sim.error_source import Contribution, SimState


class Antenna:
    """Mean C/N0 of each satellite from the antenna gain at its off-boresight angle (:func:`tracking.cn0_mean_dbhz`).

    With attitude masking the boresight follows the body's -z axis and satellites
    more than ``max_off_boresight_deg`` from it are not seen; without, the antenna
    always points up. The C/N0 it adds is the starting value the other sources
    (fading, canyon) change. No random numbers.
    """

    name = "antenna"
    labels: Mapping[str, type] = {}

    def enabled(self, state: SimState) -> bool:
        return True  # every satellite's C/N0 starts here

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        masking = state.errors.attitude_masking
        ei, si = state.sky_cells
        el = state.los.el_rad[ei, si]
        visible = None
        if masking.enabled:
            off_boresight = off_boresight_rad(el, state.los.az_rad[ei, si], state.traj.att[state.idx], ei)
            visible = state.on_sky(off_boresight < masking.max_off_boresight_deg * DEG)
        else:
            off_boresight = np.pi / 2 - el
        c0 = state.errors.cn0
        cn0 = tracking.cn0_mean_dbhz(off_boresight, c0.received_power_dbw, c0.constant_db)
        return Contribution(cn0_dbhz=state.on_sky(cn0), visible=visible)


def off_boresight_rad(el: np.ndarray, az: np.ndarray, att: np.ndarray, epoch: np.ndarray) -> np.ndarray:
    """Angle between the line of sight and the antenna boresight (body -z axis) [rad].

    Parameters
    ----------
    el, az : ndarray, shape (k,)
        Elevation and azimuth of the satellites [rad].
    att : ndarray, shape (n, 3)
        Roll, pitch, yaw of the body w.r.t. local NED at each epoch [rad].
    epoch : ndarray of int, shape (k,)
        The epoch (row of ``att``) of each satellite.
    """
    # body -z (up) axis resolved in NED: minus the third column of C_b^n
    up = -dcm_body_to_ned(att)[epoch, :, 2]
    los_n, los_e, los_d = np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)
    return np.arccos(np.clip(up[:, 0] * los_n + up[:, 1] * los_e + up[:, 2] * los_d, -1.0, 1.0))
