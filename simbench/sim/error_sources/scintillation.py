"""Scintillation-like C/N0 fades (``scenario.errors.scintillation``, off by default): the example source."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.sim.error_source import Contribution, SimState


class Scintillation:
    """Fade events per satellite: Poisson onsets (``rate_per_s``), each ``duration_s`` long, ``depth_db`` deep.

    Lowers C/N0 before the receiver locks, so the loops react (more jitter, slips,
    lost lock). Label ``scintillation_fade_db``: the C/N0 drop of the observation [dB].
    """

    name = "scintillation"
    labels: Mapping[str, type] = {"scintillation_fade_db": float}

    def enabled(self, state: SimState) -> bool:
        return state.errors.scintillation.enabled

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        cfg, dt = state.errors.scintillation, state.dt_s
        # onsets so far per satellite; at most one per epoch, rate_per_s dt << 1
        started = np.cumsum(state.draw(rng.random) < cfg.rate_per_s * dt, axis=0)
        epochs = max(1, round(cfg.duration_s / dt))
        started_before = np.zeros_like(started)
        started_before[epochs:] = started[:-epochs]
        # a fade lasts while an onset lies within the last `epochs` epochs
        fade_db = np.where(started > started_before, cfg.depth_db, 0.0)
        return Contribution(cn0_dbhz=-fade_db, labels={"scintillation_fade_db": fade_db})
