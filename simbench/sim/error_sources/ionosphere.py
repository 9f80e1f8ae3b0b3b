"""Ionospheric delay (``scenario.errors.ionosphere``): Klobuchar, scaled, plus a residual per satellite."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.core import atmosphere
from simbench.core.constants import WGS84_A
from simbench.sim.error_source import Contribution, SimState

#: Ionospheric shell height of the obliquity factor [m].
IONO_SHELL_M = 350e3


class Ionosphere:
    """Slant L1 delay ``I1`` [m]: code +I1, phase -I1, L2 ``(f1/f2)^2`` times that.

    The broadcast Klobuchar delay the receiver can model, scaled by ``N(1, scale_sigma)``
    once per scenario, plus a Gauss-Markov zenith residual per satellite (std
    ``residual_sigma_m``, time constant ``residual_tau_s``) times the obliquity factor
    of a thin shell at :data:`IONO_SHELL_M`. Label ``iono_l1`` [m].
    """

    name = "ionosphere"
    labels: Mapping[str, type] = {"iono_l1": float}

    def enabled(self, state: SimState) -> bool:
        return state.errors.ionosphere.enabled

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        io = state.errors.ionosphere
        ei, si = state.sky_cells
        el = state.los.el_rad[ei, si]
        klob = atmosphere.klobuchar_l1_delay_m(
            state.start_sow_s + state.t[ei],
            state.lat_rad[ei],
            state.lon_rad[ei],
            el,
            state.los.az_rad[ei, si],
            np.asarray(state.iono_alpha),
            np.asarray(state.iono_beta),
        )
        obliquity = state.on_sky(1.0 / np.sqrt(1.0 - (WGS84_A * np.cos(el) / (WGS84_A + IONO_SHELL_M)) ** 2))
        scale = max(0.0, 1.0 + io.scale_sigma * rng.standard_normal())
        residual = state.gauss_markov(io.residual_sigma_m, io.residual_tau_s, rng)
        iono = np.maximum(state.on_sky(klob * scale) + residual * obliquity, 0.0)
        return Contribution(iono_l1_m=iono, labels={"iono_l1": iono})
