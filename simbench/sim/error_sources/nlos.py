"""Street canyon (``scenario.errors.nlos``): masking, NLOS reception and what the loops make of the rays.

The loops lock to the direct ray when it is visible, else to the strongest
(:attr:`~simbench.sim.canyon.CanyonRays.reference`). Its extra path is a
non-dispersive delay (``nlos_delay``, labelled ``nlos`` when it is a reflection;
a ray diffracted over the roof is nearly direct); the prompt power relative to
an open-sky direct ray is added to C/N0. The DLL's and PLL's errors relative
to the locked ray are handed, as :data:`CANYON_CODE_M`, :data:`CANYON_PHASE_M`
and :data:`CANYON_SIGMA_M`, to :class:`~simbench.sim.error_sources.multipath.Multipath`,
which adds them to the diffuse multipath.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbench.core.constants import CHIP_LENGTH_CA, LAMBDA_L1
from simbench.sim import tracking
from simbench.sim.canyon import CanyonRays, canyon_rays
from simbench.sim.error_source import Contribution, SimState

#: Shared arrays (n, m): DLL code error [m], carrier error [m] relative to the locked ray, and the RMS
#: code error over carrier phase of the strongest other ray [m].
CANYON_CODE_M, CANYON_PHASE_M, CANYON_SIGMA_M = "canyon_code_m", "canyon_phase_m", "canyon_sigma_m"
#: Prompt power where nothing arrives, relative to an unobstructed direct ray [dB] (:func:`track_rays`'s floor).
NO_SIGNAL_DB = -200.0


class Nlos:
    """The canyon rays of :func:`simbench.sim.canyon.canyon_rays` (urban drives and replays with a street)."""

    name = "nlos"
    labels: Mapping[str, type] = {"nlos": bool, "nlos_delay": float}

    def enabled(self, state: SimState) -> bool:
        return state.errors.nlos.enabled and state.traj.street is not None

    def apply(self, state: SimState, rng: np.random.Generator) -> Contribution:
        st, idx, cfg = state.traj.street, state.idx, state.errors.nlos
        assert st is not None  # enabled() checks it
        t, speed = state.t, np.linalg.norm(state.traj.vel[idx], axis=1)
        travelled = np.concatenate(([0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))))
        rays = canyon_rays(
            state.los.el_rad,
            state.los.az_rad,
            st.road_heading_rad[idx],
            st.wall_left_m[idx],
            st.wall_right_m[idx],
            st.height_left_m[idx],
            st.height_right_m[idx],
            travelled,
            cfg,
            state.dt_s,
            rng,
            # what the antenna does not see is never tracked: its rays would go unused
            where=state.in_view,
            columns=state.columns,
        )
        # the loops only matter where the antenna sees the satellite: track those rays, the rest stay empty
        seen = state.in_view
        tracked = track_rays(rays, np.ones(len(rays.blocked), bool), state.spacing_chips, state.front_end_bw_hz)
        delay, code, phase, prompt_db, sigma = (np.zeros(state.shape) for _ in range(5))
        prompt_db[:] = NO_SIGNAL_DB
        for grid, values in zip((delay, code, phase, prompt_db, sigma), tracked):
            grid[seen] = values
        nlos = np.zeros(state.shape, bool)
        nlos[seen] = rays.reference > 0
        # The DLL (time constant 1/(4 B)) averages reflections that fade faster than it: a first-order
        # filter passes tau_c / (tau_c + tau_dll) of the variance of a fading with correlation time
        # tau_c = relief length / speed (first order in the reflection amplitude, where the mean over
        # the carrier phase is 0).
        tau_c = cfg.facade_relief_length_m / np.maximum(speed, 1e-6)
        averaging = np.sqrt(tau_c / (tau_c + 0.25 / state.receiver.dll_bw_hz))[:, None]
        return Contribution(
            delay_m=delay,
            cn0_dbhz=prompt_db,
            # locked to a bounce; a ray diffracted over the roof is nearly direct
            labels={"nlos": nlos, "nlos_delay": delay},
            shared={CANYON_CODE_M: code * averaging, CANYON_PHASE_M: phase, CANYON_SIGMA_M: sigma * averaging},
        )


def track_rays(
    rays: CanyonRays, in_view: np.ndarray, spacing_chips: float, front_end_bw_hz: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What the DLL and PLL make of the canyon rays, per (epoch, satellite).

    Parameters
    ----------
    rays : CanyonRays
    in_view : ndarray of bool, shape (n, m)
        Satellites the antenna sees; only these need the discriminator.
    spacing_chips : float
        Early-late spacing [chips].
    front_end_bw_hz : float
        Double-sided front-end bandwidth [Hz].

    Returns
    -------
    tuple of ndarray, shape (n, m)
        The extra path of the ray the loops lock to [m], the code error of the
        early-minus-late DLL relative to that ray [m], the carrier error of the
        composite prompt relative to its phase [m], the prompt power relative to
        an unobstructed direct ray [dB] (-200 dB where nothing arrives), and the
        RMS code error over carrier phase of the strongest other ray [m]
        (:func:`~simbench.sim.tracking.multipath_error_envelope_chips` over sqrt 2).
    """
    ref = rays.reference[..., None]
    ref_delay = np.take_along_axis(rays.delay_m, ref, -1)[..., 0]
    ref_amp = np.take_along_axis(rays.amplitude, ref, -1)[..., 0]
    code, carrier = np.zeros_like(ref_delay), np.zeros_like(ref_delay)
    prompt = ref_amp.copy()
    # A lone ray is tracked without error; only mixtures need the discriminator.
    mixed = in_view & (np.count_nonzero(rays.amplitude, axis=-1) > 1)
    if mixed.any():
        start = ref_delay[mixed] / CHIP_LENGTH_CA
        tau, prompt[mixed], prompt_phase = tracking.dll_tracking_point(
            rays.amplitude[mixed],
            rays.delay_m[mixed] / CHIP_LENGTH_CA,
            rays.phase_rad[mixed],
            start,
            spacing_chips,
            front_end_bw_hz,
        )
        code[mixed] = (tau - start) * CHIP_LENGTH_CA
        # The phase observable grows with path length: a lag of psi radians reads as +psi lambda / 2 pi.
        lag = np.take_along_axis(rays.phase_rad, ref, -1)[..., 0][mixed] - prompt_phase
        carrier[mixed] = np.angle(np.exp(1j * lag)) * (LAMBDA_L1 / (2.0 * np.pi))
    others = np.where(np.arange(rays.amplitude.shape[-1]) == ref, 0.0, rays.amplitude)
    second = np.argmax(others, axis=-1)[..., None]
    alpha = np.take_along_axis(others, second, -1)[..., 0] / np.maximum(ref_amp, 1e-10)
    offset = (np.take_along_axis(rays.delay_m, second, -1)[..., 0] - ref_delay) / CHIP_LENGTH_CA
    sigma = tracking.multipath_error_envelope_chips(alpha, offset, spacing_chips) * (CHIP_LENGTH_CA / np.sqrt(2.0))
    return ref_delay, code, carrier, 20.0 * np.log10(np.maximum(prompt, 10.0 ** (NO_SIGNAL_DB / 20.0))), sigma
