"""Code and carrier multipath (``scenario.errors.multipath``), plus the loops' errors on the canyon rays."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.sim.error_source import Contribution, SimState
from simbench.sim.error_sources.nlos import CANYON_CODE_M, CANYON_PHASE_M, CANYON_SIGMA_M
from simbench.sim.processes import gauss_markov


class Multipath:
    """Diffuse Gauss-Markov multipath (time constant ``tau_s``) plus the specular canyon rays' errors.

    The code process has std ``code_sigma_m``, or ``a + b exp(-el / c)`` when
    ``elevation_dependent``, independent on L1 and L2; the carrier one
    ``phase_sigma_m``, shared by L1 and L2. The DLL/PLL errors on the canyon rays
    (:mod:`~simbench.sim.error_sources.nlos`) come on top, the same on L1 and L2
    (the same ray geometry). Labels ``multipath_code_l1``, ``multipath_phase_l1``
    and ``sigma_multipath_code_l1`` [m]. Runs when either part is there.
    """

    name = "multipath"
    labels: Mapping[str, type] = {
        "multipath_code_l1": float,
        "sigma_multipath_code_l1": float,
        "multipath_phase_l1": float,
    }

    def enabled(self, state: SimState) -> bool:
        return state.errors.multipath.enabled or CANYON_CODE_M in state.shared

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        mp, (n, m) = state.errors.multipath, state.shape
        zeros = np.zeros((n, m))
        if mp.enabled:
            if mp.elevation_dependent:
                el_deg = np.degrees(state.los.el_rad[state.sky_cells])
                sigma = state.on_sky(mp.el_a_m + mp.el_b_m * np.exp(-el_deg / mp.el_c_deg))
            else:
                sigma = np.broadcast_to(mp.code_sigma_m, (n, m))
            keep, width = state.columns.keep, state.columns.width
            unit = gauss_markov(n, 2 * width, 1.0, mp.tau_s, state.dt_s, rng, np.r_[keep, keep + width])
            code, code_l2 = sigma * unit[:, :m], sigma * unit[:, m:]
            phase = state.gauss_markov(mp.phase_sigma_m, mp.tau_s, rng)
        else:
            sigma = code = code_l2 = phase = zeros
        canyon_code = state.shared.get(CANYON_CODE_M, zeros)
        code, code_l2 = code + canyon_code, code_l2 + canyon_code
        phase = phase + state.shared.get(CANYON_PHASE_M, zeros)
        sigma = np.hypot(sigma, state.shared.get(CANYON_SIGMA_M, zeros))
        return Contribution(
            code_l1_m=code,
            phase_l1_m=phase,
            code_l2_m=code_l2,
            phase_l2_m=phase,
            labels={"multipath_code_l1": code, "sigma_multipath_code_l1": sigma, "multipath_phase_l1": phase},
        )
