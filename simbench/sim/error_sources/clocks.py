"""Receiver clock (``scenario.errors.receiver_clock``) and the true satellite clocks in the signal."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.core.constants import C_LIGHT
from simbench.sim.error_source import Contribution, SimState
from simbench.sim.processes import receiver_clock


class ReceiverClock:
    """TCXO bias and drift (:func:`simbench.sim.processes.receiver_clock`), on every satellite alike.

    Adds ``c dt_r`` to code and phase [m] and ``c d(dt_r)/dt`` to the pseudorange rate [m/s];
    truth column ``rx_clock`` [m].
    """

    name = "receiver_clock"
    labels: Mapping[str, type] = {}

    def enabled(self, state: SimState) -> bool:
        return state.errors.receiver_clock.enabled

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        rc = state.errors.receiver_clock
        clk_s, drift = receiver_clock(state.t, rc.bias0_sigma_s, rc.drift0_sigma_sps, rc.h0, rc.h_2, rng)
        clock_m, drift_mps = C_LIGHT * clk_s, C_LIGHT * drift
        return Contribution(delay_m=clock_m[:, None], range_rate_mps=drift_mps[:, None], truth={"rx_clock": clock_m})


class SatelliteClock:
    """The satellites' true clock offsets (relativity included): ``-c dt_s`` [m] and ``-c d(dt_s)/dt`` [m/s].

    Not an error but part of the signal; the receiver is handed it, up to the product
    error of :class:`~simbench.sim.error_sources.orbit_clock.OrbitClockError`. No random numbers.
    """

    name = "satellite_clock"
    labels: Mapping[str, type] = {}

    def enabled(self, state: SimState) -> bool:
        return True

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        los = state.los
        return Contribution(delay_m=-(C_LIGHT * los.sat_clock_tx), range_rate_mps=-(C_LIGHT * los.sat_clock_drift))
