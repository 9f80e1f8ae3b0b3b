"""Code error of a sampling rate commensurate with the chip rate (``scenario.errors.sample_grid``)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.core.constants import CHIP_LENGTH_CA
from simbench.sim import tracking
from simbench.sim.error_source import Contribution, SimState


class SampleGrid:
    """The DLL sees the code phase on the sample grid (:func:`tracking.sample_grid_code_error_chips`).

    The sample clock's offset from the code epochs is one uniform draw per
    receiver, whatever the satellite. Adds to the code of tracked channels [m];
    label ``sample_grid_code_l1`` [m].
    """

    name = "sample_grid"
    labels: Mapping[str, type] = {"sample_grid_code_l1": float}

    def enabled(self, state: SimState) -> bool:
        return state.errors.sample_grid

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        offset_chips = rng.uniform()
        code_l1 = grid_error_m(state, state.signal_code_l1_m, state.cn0_dbhz, offset_chips)
        out = Contribution(code_l1_m=code_l1, labels={"sample_grid_code_l1": code_l1})
        if state.dual_frequency:
            out.code_l2_m = grid_error_m(state, state.signal_code_l2_m, state.cn0_l2_dbhz, offset_chips)
        return out


def grid_error_m(state: SimState, pseudorange_m: np.ndarray, cn0_dbhz: np.ndarray, offset_chips: float) -> np.ndarray:
    """Sample-grid code error of the tracked channels, 0 elsewhere, (n, m) [m].

    Parameters
    ----------
    state : SimState
        After the receiver's lock.
    pseudorange_m : ndarray, shape (n, m)
        The signal's code as it reaches the antenna [m].
    cn0_dbhz : ndarray, shape (n, m)
        C/N0 of this signal [dB-Hz].
    offset_chips : float
        Offset of the sample clock from the code epochs [chips].
    """
    rx, tracked = state.receiver, state.lock.tracked
    out = np.zeros(state.shape)
    # tracked channels only: a fifth of (epoch, satellite) or less
    out[tracked] = CHIP_LENGTH_CA * tracking.sample_grid_code_error_chips(
        pseudorange_m[tracked] / CHIP_LENGTH_CA + offset_chips,
        state.range_rate_mps[tracked] / CHIP_LENGTH_CA,
        cn0_dbhz[tracked],
        sampling_hz=rx.sampling_mhz * 1e6,
        dll_bw_hz=rx.dll_bw_hz,
        spacing_chips=state.spacing_chips,
        front_end_bw_hz=state.front_end_bw_hz,
        integration_s=rx.integration_s,
    )
    return out
