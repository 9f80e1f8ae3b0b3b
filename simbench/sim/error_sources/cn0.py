"""C/N0 fading and noise per satellite (``scenario.errors.cn0``), each from its own stream."""

from __future__ import annotations

import numpy as np

from simbench.sim.error_source import AlwaysOn, Contribution, SimState


class Cn0Fade(AlwaysOn):
    """Slow fading: a Gauss-Markov process per satellite, std ``fade_sigma_db`` [dB], time constant ``fade_tau_s``."""

    name = "cn0_fade"

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        c0 = state.errors.cn0
        return Contribution(cn0_dbhz=state.gauss_markov(c0.fade_sigma_db, c0.fade_tau_s, rng))


class Cn0Noise(AlwaysOn):
    """White C/N0 estimation noise, N(0, ``noise_db``^2) per epoch [dB]."""

    name = "cn0_noise"

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        return Contribution(cn0_dbhz=state.errors.cn0.noise_db * state.draw(rng.standard_normal))
