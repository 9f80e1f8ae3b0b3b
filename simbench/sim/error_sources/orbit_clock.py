"""Error of the orbit/clock product handed to the receiver (``scenario.errors.orbit_clock``)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.core.constants import C_LIGHT
from simbench.core.frames import dot_last_axis
from simbench.sim.error_source import Contribution, SimState
from simbench.sim.processes import gauss_markov


class OrbitClockError:
    """Truth minus product: Gauss-Markov per satellite and axis (``orbit_sigma_m``) and clock (``clock_sigma_m``).

    The signal is unchanged; the product columns ``sat_x``, ``sat_y``, ``sat_z``
    and ``sat_clock`` [m] carry the error, and the label ``orbit_clock_error`` its
    line-of-sight projection plus the clock error [m].
    """

    name = "orbit_clock"
    labels: Mapping[str, type] = {"orbit_clock_error": float}

    def enabled(self, state: SimState) -> bool:
        return state.errors.orbit_clock.enabled

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        oc, los, (n, m) = state.errors.orbit_clock, state.los, state.shape
        # one process per satellite, shared by all epochs (the product is the same for everyone)
        keep, width = state.columns.keep, state.columns.width
        xyz = (3 * keep[:, None] + np.arange(3)).ravel()
        d_orbit = gauss_markov(n, 3 * width, oc.orbit_sigma_m, oc.tau_s, state.dt_s, rng, xyz).reshape(n, m, 3)
        d_clock = state.gauss_markov(oc.clock_sigma_m, oc.tau_s, rng)
        position = los.sat_pos_tx + d_orbit
        return Contribution(
            observations={
                "sat_x": position[..., 0],
                "sat_y": position[..., 1],
                "sat_z": position[..., 2],
                "sat_clock": C_LIGHT * los.sat_clock_tx + d_clock,
            },
            labels={"orbit_clock_error": dot_last_axis(los.los_unit, d_orbit) + d_clock},
        )
