"""Tropospheric delay (``scenario.errors.troposphere``): Saastamoinen zenith delays, Niell mapping."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.core import atmosphere
from simbench.core.gpstime import day_of_year
from simbench.sim.error_source import Contribution, SimState
from simbench.sim.processes import random_walk


class Troposphere:
    """Hydrostatic plus wet slant delay [m] on code and phase.

    The true zenith wet delay is the Saastamoinen value scaled by ``N(1, wet_scale_sigma)``
    (once per scenario) plus a random walk of ``wet_rw_mps`` [m/sqrt(s)]. Label ``tropo``
    (slant delay [m]), truth column ``zwd`` [m].
    """

    name = "troposphere"
    labels: Mapping[str, type] = {"tropo": float}

    def enabled(self, state: SimState) -> bool:
        return state.errors.troposphere.enabled

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        tr, n = state.errors.troposphere, state.shape[0]
        lat, h = state.lat_rad, state.h_m
        zhd, zwd_model = atmosphere.saastamoinen_zenith_m(lat, h)
        zwd = (
            zwd_model * max(0.0, 1.0 + tr.wet_scale_sigma * rng.standard_normal())
            + random_walk(n, 1, tr.wet_rw_mps, state.dt_s, rng)[:, 0]
        )
        zwd = np.maximum(zwd, 0.0)
        doy = day_of_year(state.cfg.scenario.gps_week, state.start_sow_s)
        ei, si = state.sky_cells
        m_h, m_w = atmosphere.niell_mapping(state.los.el_rad[ei, si], lat[ei], h[ei], doy)
        tropo = state.on_sky(zhd[ei] * m_h + zwd[ei] * m_w)
        return Contribution(delay_m=tropo, labels={"tropo": tropo}, truth={"zwd": zwd})
