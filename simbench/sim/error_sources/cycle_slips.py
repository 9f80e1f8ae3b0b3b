"""Carrier-phase arcs, integer ambiguities and cycle slips (``scenario.errors.cycle_slips``)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.core.constants import LAMBDA_L1, LAMBDA_L2
from simbench.sim.error_source import AlwaysOn, Contribution, SimState
from simbench.sim.slips import phase_arcs


class CycleSlips(AlwaysOn):
    """``lambda N`` on each phase [m], from :func:`simbench.sim.slips.phase_arcs` on the carrier lock.

    Runs with slips off too: every arc has its ambiguity, and a phase without carrier lock is NaN. Observation columns
    ``lli_l1`` (``lli_l2``), labels ``ambiguity_l1``, ``ambiguity_l2`` [cycles] and ``slip``.
    """

    name = "cycle_slips"
    labels: Mapping[str, type] = {"ambiguity_l1": np.int64, "ambiguity_l2": np.int64, "slip": bool}

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        lock = state.lock
        n_freq = 2 if state.dual_frequency else 1
        arcs = phase_arcs(
            lock.carrier_locked, state.cn0_dbhz, state.errors.cycle_slips, state.dt_s, rng, n_freq, state.columns
        )
        # NaN where the PLL has no lock: the observation keeps its code and Doppler, not its phase
        no_phase = np.where(lock.carrier_locked, 0.0, np.nan)
        out = Contribution(
            phase_l1_m=LAMBDA_L1 * arcs[0].ambiguity + no_phase,
            observations={"lli_l1": arcs[0].lli},
            labels={"ambiguity_l1": arcs[0].ambiguity, "slip": arcs[0].slip},
        )
        if state.dual_frequency:
            out.phase_l2_m = LAMBDA_L2 * arcs[1].ambiguity + no_phase
            out.observations["lli_l2"] = arcs[1].lli
            out.labels["ambiguity_l2"] = arcs[1].ambiguity
        return out
