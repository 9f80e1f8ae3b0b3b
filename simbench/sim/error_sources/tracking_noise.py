"""Thermal noise of the DLL, PLL and frequency discriminator (``scenario.errors.tracking_noise``)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.core.constants import LAMBDA_L1
from simbench.sim import tracking
from simbench.sim.error_source import Contribution, SimState


class TrackingNoise:
    """L1 code, phase and Doppler noise, white, with the stds the receiver's loops give at the C/N0.

    Code: the DLL jitter of the lock state [m]; phase: the PLL jitter [m];
    Doppler: ``doppler_sigma_hz`` at ``doppler_ref_cn0_dbhz``, scaling as
    ``10^((ref - C/N0) / 20)`` [Hz]. Labels ``sigma_code_l1``, ``sigma_phase_l1``,
    ``noise_code_l1``, ``noise_phase_l1`` [m].
    """

    name = "tracking"
    labels: Mapping[str, type] = {
        "sigma_code_l1": float,
        "sigma_phase_l1": float,
        "noise_code_l1": float,
        "noise_phase_l1": float,
    }

    def enabled(self, state: SimState) -> bool:
        return state.errors.tracking_noise

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        lock, rx = state.lock, state.receiver
        sig_phase = lock.pll_jitter_rad * LAMBDA_L1 / (2 * np.pi)
        sig_doppler = rx.doppler_sigma_hz * 10 ** ((rx.doppler_ref_cn0_dbhz - state.cn0_dbhz) / 20.0)
        # drawn in this order from the stream: code, phase, Doppler
        code = lock.sigma_code_m * state.draw(rng.standard_normal)
        phase = sig_phase * state.draw(rng.standard_normal)
        doppler = sig_doppler * state.draw(rng.standard_normal)
        return Contribution(
            code_l1_m=code,
            phase_l1_m=phase,
            doppler_l1_hz=doppler,
            labels={
                "sigma_code_l1": lock.sigma_code_m,
                "sigma_phase_l1": sig_phase,
                "noise_code_l1": code,
                "noise_phase_l1": phase,
            },
        )


class TrackingNoiseL2:
    """L2 code and phase noise, at the L2 C/N0 (dual frequency only)."""

    name = "tracking_l2"
    labels: Mapping[str, type] = {}

    def enabled(self, state: SimState) -> bool:
        return state.errors.tracking_noise and state.dual_frequency

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        rx, cn0 = state.receiver, state.cn0_l2_dbhz
        sig_code = state.code_jitter_m(cn0)
        sig_phase = tracking.pll_jitter_m(cn0, rx.pll_bw_hz, rx.integration_s)
        return Contribution(
            code_l2_m=sig_code * state.draw(rng.standard_normal), phase_l2_m=sig_phase * state.draw(rng.standard_normal)
        )
