"""Scenario generation: trajectory, sky, error sources, observables, IMU, odometry.

:func:`generate` turns a typed :class:`~simbench.sim.config.SimConfig` into a
:class:`~simbench.contract.Scenario`, deterministically: every error source
draws from its own named random stream of the seed. All physics is
vectorised over (epoch, satellite) arrays of shape (n, m).

Measurement model (metres; ``rho`` geometric range with Earth rotation)::

    code_l1  = rho + c dt_r - c dt_s + T + I1 + MP + NLOS + e_code
    phase_l1 = rho + c dt_r - c dt_s + T - I1 + lambda1 N1 + mp + NLOS + e_phase

In a street canyon, NLOS is the extra path of the ray the loop locks to (the
strongest when the direct one is masked; labelled NLOS when it is a reflection) and MP adds, to the Gauss-Markov
diffuse multipath, what the preset's early-minus-late DLL makes of all rays
(:func:`~simbench.sim.tracking.dll_tracking_point`); mp likewise gets the
phase of the composite prompt correlator. C/N0 follows the prompt amplitude,
and a channel is tracked from ``reacquisition_s`` after C/N0 first holds the
acquisition threshold until it falls below the lock threshold or the DLL rule
``3 sigma_DLL <= D / 2`` fails (Kaplan & Hegarty, 2nd ed., sec. 5.6).

L2 likewise with ``I2 = (f1/f2)^2 I1``. The receiver is handed the product
satellite position and clock (truth plus orbit/clock error), the elevation and
azimuth, C/N0 and loss-of-lock flags.
"""

from __future__ import annotations

import os
from dataclasses import asdict, replace

import numpy as np
import pandas as pd
import pymap3d

from simbench.contract import NavInfo, Scenario, empty_odometry
from simbench.core import atmosphere
from simbench.core.constants import (
    C_LIGHT,
    CHIP_LENGTH_CA,
    DEG,
    IONO_L2_SCALE,
    LAMBDA_L1,
    LAMBDA_L2,
    SECONDS_PER_WEEK,
    WGS84_A,
)
from simbench.core.frames import dcm_body_to_ned
from simbench.core.gpstime import day_of_year
from simbench.core.orbits import NominalConstellation
from simbench.errors import SimbenchError
from simbench.gnss.navigation import read_gps_navigation
from simbench.sim import tracking
from simbench.sim.canyon import CanyonRays, canyon_rays
from simbench.sim.config import ConstellationKind, SimConfig, TrajectoryKind, validate_sim
from simbench.sim.geometry import line_of_sight
from simbench.sim.imu import simulate_imu
from simbench.sim.odometry import simulate_odometry
from simbench.sim.processes import gauss_markov, random_walk, receiver_clock, stream
from simbench.sim.slips import phase_arcs
from simbench.sim.trajectory import Trajectory, flight, replay, roadside_street, urban_drive

#: Ionospheric shell height of the obliquity factor [m].
IONO_SHELL_M = 350e3
#: L2 signals are weaker than L1 C/A (IS-GPS-200 minimum powers differ by 1.5-3 dB).
L2_CN0_LOSS_DB = 3.0


def generate(cfg: SimConfig) -> Scenario:
    """Generate one scenario.

    Parameters
    ----------
    cfg : SimConfig
        Scenario, receiver and IMU configuration and the seed.

    Returns
    -------
    Scenario
        Receiver view (observations, IMU, odometry), truth and labels; with odometry,
        ``meta['odometry_errors']`` holds its true scale factor and yaw-rate bias.
    """
    cfg = validate_sim(cfg)
    sc, err, rx = cfg.scenario, cfg.scenario.errors, cfg.receiver
    seed = cfg.seed

    traj, start_sow = _trajectory(cfg)
    step = cfg.imu.rate_hz / sc.rate_hz
    if abs(step - round(step)) > 1e-9:
        raise SimbenchError(
            "scenario.rate_hz",
            f"IMU rate {cfg.imu.rate_hz} Hz is not a multiple of {sc.rate_hz} Hz",
            "choose rates such that imu.rate_hz / scenario.rate_hz is an integer",
        )
    idx = np.arange(0, len(traj.t), int(round(step)))
    idx = idx[traj.valid[idx]]
    t = traj.t[idx]
    n = len(t)
    dt = 1.0 / sc.rate_hz
    pos, vel, att = traj.pos[idx], traj.vel[idx], traj.att[idx]
    lat, lon, h = pymap3d.ecef2geodetic(pos[:, 0], pos[:, 1], pos[:, 2], deg=False)

    # ------------------------------------------------------------------ sky
    constellation, alpha, beta = _constellation(cfg)
    t_gps = sc.gps_week * SECONDS_PER_WEEK + start_sow + t
    los = line_of_sight(pos, vel, t_gps, constellation)
    m = los.range_m.shape[1]
    el, az = los.el_rad, los.az_rad
    above = los.valid & (el > sc.constellation.elevation_mask_deg * DEG)

    # ------------------------------------------------------------------ antenna, canyon rays, C/N0
    off_boresight = _off_boresight(el, az, att)
    in_view = above.copy()
    if err.attitude_masking.enabled:
        in_view &= off_boresight < err.attitude_masking.max_off_boresight_deg * DEG
    else:
        off_boresight = np.pi / 2 - el  # an antenna that always points up
    fe_bw = rx.front_end_bw_mhz * 1e6
    spacing = tracking.effective_spacing_chips(rx.correlator_spacing_chips, rx.sampling_mhz * 1e6)
    reflected = np.zeros((n, m), bool)
    nlos_delay = canyon_code = canyon_phase = canyon_sigma = prompt_db = np.zeros((n, m))
    if err.nlos.enabled and traj.street is not None:
        st = traj.street
        speed = np.linalg.norm(vel, axis=1)
        travelled = np.concatenate(([0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))))
        rays = canyon_rays(
            el,
            az,
            st.road_heading_rad[idx],
            st.wall_left_m[idx],
            st.wall_right_m[idx],
            st.height_left_m[idx],
            st.height_right_m[idx],
            travelled,
            err.nlos,
            dt,
            stream(seed, "nlos"),
        )
        reflected = rays.reference > 0  # locked to a bounce; a ray diffracted over the roof is nearly direct
        nlos_delay, canyon_code, canyon_phase, prompt_db, canyon_sigma = _track_rays(rays, in_view, spacing, fe_bw)
        # The DLL (time constant 1/(4 B)) averages reflections that fade faster than it: a first-order
        # filter passes tau_c / (tau_c + tau_dll) of the variance of a fading with correlation time
        # tau_c = relief length / speed (first order in the reflection amplitude, where the mean over
        # the carrier phase is 0).
        tau_c = err.nlos.facade_relief_length_m / np.maximum(speed, 1e-6)
        averaging = np.sqrt(tau_c / (tau_c + 0.25 / rx.dll_bw_hz))[:, None]
        canyon_code, canyon_sigma = canyon_code * averaging, canyon_sigma * averaging

    c0 = err.cn0
    cn0 = (
        tracking.cn0_mean_dbhz(off_boresight, c0.received_power_dbw, c0.constant_db)
        + gauss_markov(n, m, c0.fade_sigma_db, c0.fade_tau_s, dt, stream(seed, "cn0_fade"))
        + c0.noise_db * stream(seed, "cn0_noise").standard_normal((n, m))
        + prompt_db
    )

    # ------------------------------------------------------------------ tracking noise, lock
    sig_code = tracking.dll_jitter_m(cn0, rx.dll_bw_hz, spacing, fe_bw, rx.integration_s)
    pll_rad = tracking.pll_jitter_rad(cn0, rx.pll_bw_hz, rx.integration_s)
    in_lock = in_view & (cn0 >= rx.lock_threshold_dbhz) & (3.0 * sig_code <= 0.5 * spacing * CHIP_LENGTH_CA)
    tracked = tracking.channel_lock_states(
        cn0 >= rx.acquisition_threshold_dbhz, in_lock, 1 + int(round(rx.reacquisition_s / dt))
    )
    nlos = reflected & tracked
    nlos_delay = np.where(tracked, nlos_delay, 0.0)
    # Kaplan's PLL rule of thumb 3 sigma_j + theta_e <= 45 deg, in the 1-sigma form the slip model tests.
    jerk = np.einsum("nk,nmk->nm", np.gradient(traj.acc, traj.t, axis=0)[idx], los.los_unit)
    pll_stress_rad = pll_rad + np.radians(tracking.pll_dynamic_stress_deg(jerk, rx.pll_bw_hz)) / 3.0
    sig_phase = pll_rad * LAMBDA_L1 / (2 * np.pi)
    noise_rng = stream(seed, "tracking")
    gain = 1.0 if err.tracking_noise else 0.0
    e_code = gain * sig_code * noise_rng.standard_normal((n, m))
    e_phase = gain * sig_phase * noise_rng.standard_normal((n, m))
    sig_doppler = rx.doppler_sigma_hz * 10 ** ((rx.doppler_ref_cn0_dbhz - cn0) / 20.0)
    e_doppler = gain * sig_doppler * noise_rng.standard_normal((n, m))

    # ------------------------------------------------------------------ clocks
    if err.receiver_clock.enabled:
        rc = err.receiver_clock
        clk_s, drift = receiver_clock(
            t, rc.bias0_sigma_s, rc.drift0_sigma_sps, rc.h0, rc.h_2, stream(seed, "receiver_clock")
        )
    else:
        clk_s, drift = np.zeros(n), np.zeros(n)
    rx_clock_m, rx_drift_mps = C_LIGHT * clk_s, C_LIGHT * drift

    # ------------------------------------------------------------------ atmosphere
    doy = day_of_year(sc.gps_week, start_sow)
    if err.troposphere.enabled:
        zhd, zwd_model = atmosphere.saastamoinen_zenith_m(lat, h)
        trng = stream(seed, "troposphere")
        zwd = (
            zwd_model * max(0.0, 1.0 + err.troposphere.wet_scale_sigma * trng.standard_normal())
            + random_walk(n, 1, err.troposphere.wet_rw_mps, dt, trng)[:, 0]
        )
        zwd = np.maximum(zwd, 0.0)
        m_h, m_w = atmosphere.niell_mapping(el, lat[:, None], h[:, None], doy)
        tropo = zhd[:, None] * m_h + zwd[:, None] * m_w
    else:
        zwd, tropo = np.zeros(n), np.zeros((n, m))
    if err.ionosphere.enabled:
        io = err.ionosphere
        irng = stream(seed, "ionosphere")
        klob = atmosphere.klobuchar_l1_delay_m(
            (start_sow + t)[:, None], lat[:, None], lon[:, None], el, az, np.asarray(alpha), np.asarray(beta)
        )
        obliquity = 1.0 / np.sqrt(1.0 - (WGS84_A * np.cos(el) / (WGS84_A + IONO_SHELL_M)) ** 2)
        scale = max(0.0, 1.0 + io.scale_sigma * irng.standard_normal())
        residual = gauss_markov(n, m, io.residual_sigma_m, io.residual_tau_s, dt, irng)
        iono = np.maximum(klob * scale + residual * obliquity, 0.0)
    else:
        iono = np.zeros((n, m))

    # ------------------------------------------------------------------ orbit/clock product error
    sat_pos_product = los.sat_pos_tx.copy()
    sat_clock_true_m = C_LIGHT * los.sat_clock_tx
    sat_clock_product_m = sat_clock_true_m.copy()
    if err.orbit_clock.enabled:
        oc = err.orbit_clock
        orng = stream(seed, "orbit_clock")
        # one process per satellite, shared by all epochs (the product is the same for everyone)
        d_orbit = gauss_markov(n, 3 * m, oc.orbit_sigma_m, oc.tau_s, dt, orng).reshape(n, m, 3)
        d_clock = gauss_markov(n, m, oc.clock_sigma_m, oc.tau_s, dt, orng)
        sat_pos_product += d_orbit
        sat_clock_product_m += d_clock
        orbit_clock_error = np.einsum("nmk,nmk->nm", los.los_unit, d_orbit) + d_clock
    else:
        orbit_clock_error = np.zeros((n, m))

    # ------------------------------------------------------------------ multipath
    mp = err.multipath
    if mp.enabled:
        mrng = stream(seed, "multipath")
        sigma_mp = (
            (mp.el_a_m + mp.el_b_m * np.exp(-np.degrees(el) / mp.el_c_deg))
            if mp.elevation_dependent
            else mp.code_sigma_m
        )
        sigma_mp = np.broadcast_to(sigma_mp, (n, m))
        unit = gauss_markov(n, 2 * m, 1.0, mp.tau_s, dt, mrng)
        mp_code = sigma_mp * unit[:, :m]
        mp_code_l2 = sigma_mp * unit[:, m:]
        mp_phase = gauss_markov(n, m, mp.phase_sigma_m, mp.tau_s, dt, mrng)
    else:
        sigma_mp = mp_code = mp_code_l2 = mp_phase = np.zeros((n, m))
    # Specular canyon rays on top of the diffuse process; L2 sees the same ray geometry.
    mp_code, mp_code_l2, mp_phase = mp_code + canyon_code, mp_code_l2 + canyon_code, mp_phase + canyon_phase
    sigma_mp = np.hypot(sigma_mp, canyon_sigma)

    # ------------------------------------------------------------------ phase arcs and slips
    n_freq = 2 if sc.dual_frequency else 1
    arcs = phase_arcs(tracked, cn0, pll_stress_rad, err.cycle_slips, dt, stream(seed, "cycle_slips"), n_freq)

    # ------------------------------------------------------------------ observables
    common = los.range_m + rx_clock_m[:, None] - sat_clock_true_m + tropo + nlos_delay
    pseudorange_rate = los.range_rate_mps + rx_drift_mps[:, None] - C_LIGHT * los.sat_clock_drift
    # the sample clock's offset from the code epochs: one per receiver, whatever the satellite
    grid_offset = stream(seed, "sample_grid").uniform()

    def grid_error(pseudorange: np.ndarray, cn0_dbhz: np.ndarray) -> np.ndarray:
        out = np.zeros((n, m))
        if err.sample_grid:  # tracked channels only: a fifth of (epoch, satellite) or less
            out[tracked] = CHIP_LENGTH_CA * tracking.sample_grid_code_error_chips(
                pseudorange[tracked] / CHIP_LENGTH_CA + grid_offset,
                pseudorange_rate[tracked] / CHIP_LENGTH_CA,
                cn0_dbhz[tracked],
                sampling_hz=rx.sampling_mhz * 1e6,
                dll_bw_hz=rx.dll_bw_hz,
                spacing_chips=spacing,
                front_end_bw_hz=fe_bw,
                integration_s=rx.integration_s,
            )
        return out

    e_grid = grid_error(common + iono, cn0)
    code_l1 = common + iono + mp_code + e_grid + e_code
    phase_l1 = common - iono + LAMBDA_L1 * arcs[0].ambiguity + mp_phase + e_phase
    doppler_l1 = -pseudorange_rate / LAMBDA_L1 + e_doppler
    if sc.dual_frequency:
        l2rng = stream(seed, "tracking_l2")
        cn0_l2 = cn0 - L2_CN0_LOSS_DB
        sig2 = gain * tracking.dll_jitter_m(cn0_l2, rx.dll_bw_hz, spacing, fe_bw, rx.integration_s)
        sig2p = gain * tracking.pll_jitter_m(cn0_l2, rx.pll_bw_hz, rx.integration_s)
        code_l2 = (
            common
            + IONO_L2_SCALE * iono
            + mp_code_l2
            + grid_error(common + IONO_L2_SCALE * iono, cn0_l2)
            + sig2 * l2rng.standard_normal((n, m))
        )
        phase_l2 = (
            common
            - IONO_L2_SCALE * iono
            + LAMBDA_L2 * arcs[1].ambiguity
            + mp_phase
            + sig2p * l2rng.standard_normal((n, m))
        )
        lli_l2, amb_l2 = arcs[1].lli, arcs[1].ambiguity
    else:
        code_l2 = phase_l2 = np.full((n, m), np.nan)
        lli_l2, amb_l2 = np.zeros((n, m), bool), np.zeros((n, m), np.int64)

    # ------------------------------------------------------------------ long tables
    ei, si = np.nonzero(tracked)
    sats = np.asarray(constellation.sats)

    def pick(a: np.ndarray) -> np.ndarray:
        return a[ei, si]

    observations = pd.DataFrame(
        {
            "epoch": ei.astype(np.int64),
            "t": t[ei],
            "sat": sats[si],
            "code_l1": pick(code_l1),
            "phase_l1": pick(phase_l1),
            "doppler_l1": pick(doppler_l1),
            "cn0_l1": pick(cn0),
            "lli_l1": pick(arcs[0].lli),
            "code_l2": pick(code_l2),
            "phase_l2": pick(phase_l2),
            "lli_l2": pick(lli_l2),
            "sat_x": sat_pos_product[ei, si, 0],
            "sat_y": sat_pos_product[ei, si, 1],
            "sat_z": sat_pos_product[ei, si, 2],
            "sat_vx": los.sat_vel_tx[ei, si, 0],
            "sat_vy": los.sat_vel_tx[ei, si, 1],
            "sat_vz": los.sat_vel_tx[ei, si, 2],
            "sat_clock": pick(sat_clock_product_m),
            "sat_clock_drift": C_LIGHT * pick(los.sat_clock_drift),
            "el": np.degrees(pick(el)),
            "az": np.degrees(pick(az)),
        }
    )
    labels = pd.DataFrame(
        {
            "epoch": ei.astype(np.int64),
            "sat": sats[si],
            "sigma_code_l1": gain * pick(sig_code),
            "sigma_phase_l1": gain * pick(sig_phase),
            "multipath_code_l1": pick(mp_code),
            "sigma_multipath_code_l1": pick(sigma_mp),
            "multipath_phase_l1": pick(mp_phase),
            "nlos": pick(nlos),
            "nlos_delay": pick(nlos_delay),
            "iono_l1": pick(iono),
            "tropo": pick(tropo),
            "orbit_clock_error": pick(orbit_clock_error),
            "ambiguity_l1": pick(arcs[0].ambiguity),
            "ambiguity_l2": pick(amb_l2),
            "slip": pick(arcs[0].slip),
            "noise_code_l1": pick(e_code),
            "noise_phase_l1": pick(e_phase),
            "sample_grid_code_l1": pick(e_grid),
        }
    )
    truth = pd.DataFrame(
        {
            "epoch": np.arange(n, dtype=np.int64),
            "t": t,
            "x": pos[:, 0],
            "y": pos[:, 1],
            "z": pos[:, 2],
            "vx": vel[:, 0],
            "vy": vel[:, 1],
            "vz": vel[:, 2],
            "roll": att[:, 0],
            "pitch": att[:, 1],
            "yaw": att[:, 2],
            "rx_clock": rx_clock_m,
            "zwd": zwd,
            "n_visible": above.sum(axis=1).astype(np.int64),
        }
    )
    imu = simulate_imu(traj, cfg.imu, stream(seed, "imu"))
    imu_table = pd.DataFrame(
        {
            "t": imu.t,
            "ax": imu.accel[:, 0],
            "ay": imu.accel[:, 1],
            "az": imu.accel[:, 2],
            "gx": imu.gyro[:, 0],
            "gy": imu.gyro[:, 1],
            "gz": imu.gyro[:, 2],
        }
    )
    # absolute: a cached scenario is read from other working directories
    ephemeris = (
        "nominal" if sc.constellation.kind == ConstellationKind.nominal else os.path.abspath(sc.constellation.nav_path)
    )
    nav = NavInfo(
        gps_week=sc.gps_week,
        start_sow_s=float(start_sow),
        iono_alpha=tuple(map(float, alpha)),
        iono_beta=tuple(map(float, beta)),
        dual_frequency=sc.dual_frequency,
        ephemeris=ephemeris,
    )
    meta = {"name": sc.name, "seed": seed, "config": asdict(cfg)}
    odometry = empty_odometry()
    if sc.odometry.enabled:
        odo = simulate_odometry(traj, sc.odometry, stream(seed, "odometry"))
        odometry = odo.table
        meta["odometry_errors"] = {"scale_factor": odo.scale_factor, "yaw_rate_bias_rps": odo.yaw_rate_bias_rps}
    return Scenario(
        observations=observations, imu=imu_table, truth=truth, labels=labels, nav=nav, meta=meta, odometry=odometry
    )


def _track_rays(
    rays: CanyonRays, in_view: np.ndarray, spacing_chips: float, front_end_bw_hz: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What the DLL and PLL make of the canyon rays, per (epoch, satellite).

    Returns the extra path of the ray the loops lock to [m], the code error of
    the early-minus-late DLL relative to that ray [m], the carrier error of the
    composite prompt relative to its phase [m], the prompt power relative
    to an unobstructed direct ray [dB] (-200 dB where nothing arrives), and the
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
    return ref_delay, code, carrier, 20.0 * np.log10(np.maximum(prompt, 1e-10)), sigma


def _trajectory(cfg: SimConfig) -> tuple[Trajectory, float]:
    sc = cfg.scenario
    rng = stream(cfg.seed, "trajectory")
    kind = sc.trajectory.kind
    if kind == TrajectoryKind.urban_drive:
        return urban_drive(sc.trajectory, sc.errors.nlos, sc.duration_s, cfg.imu.rate_hz, rng), sc.start_sow_s
    if kind == TrajectoryKind.flight:
        return flight(sc.trajectory, sc.duration_s, cfg.imu.rate_hz, rng), sc.start_sow_s
    traj, t0_sow = replay(sc.trajectory.replay, cfg.imu.rate_hz, sc.duration_s)
    if sc.errors.nlos.enabled:
        traj = replace(traj, street=roadside_street(traj, sc.errors.nlos, rng))
    return traj, t0_sow


def _constellation(cfg: SimConfig):
    con = cfg.scenario.constellation
    if con.kind == ConstellationKind.nominal:
        return NominalConstellation(), con.iono_alpha, con.iono_beta
    eph = read_gps_navigation(con.nav_path)
    alpha = eph.iono_alpha if eph.iono_alpha is not None else con.iono_alpha
    beta = eph.iono_beta if eph.iono_beta is not None else con.iono_beta
    return eph, alpha, beta


def _off_boresight(el: np.ndarray, az: np.ndarray, att: np.ndarray) -> np.ndarray:
    """Angle between the line of sight and the antenna boresight (body -z axis) [rad]."""
    # body -z (up) axis resolved in NED: minus the third column of C_b^n
    up = -dcm_body_to_ned(att)[:, :, 2]
    up_n, up_e, up_d = up[:, 0, None], up[:, 1, None], up[:, 2, None]
    los_n, los_e, los_d = np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)
    return np.arccos(np.clip(up_n * los_n + up_e * los_e + up_d * los_d, -1.0, 1.0))
