"""Scenario generation: trajectory, sky, error sources, lock, observables, IMU, odometry.

:func:`generate` turns a typed :class:`~simbench.sim.config.SimConfig` into a
:class:`~simbench.contract.Scenario`, deterministically. It computes the
geometry (:class:`~simbench.sim.error_source.SimState`), runs the signal error
sources of :mod:`simbench.sim.error_sources`, locks the receiver's channels on
the resulting C/N0, runs the tracking error sources and writes the long tables.
Every error source draws from its own named random stream of the seed. All
physics is vectorised over (epoch, satellite) arrays of shape (n, m), the m
satellites being those of the constellation that rise above the elevation mask
at some epoch (:attr:`~simbench.sim.error_source.SimState.columns`); the
deterministic per-cell physics runs on the cells above the mask only
(:attr:`~simbench.sim.error_source.SimState.sky_cells`). Random draws span every
satellite of the constellation at every epoch, so what a cell gets never depends
on which others are kept or computed.

Measurement model (metres; ``rho`` geometric range with Earth rotation)::

    code_l1  = rho + c dt_r - c dt_s + T + NLOS + I1 + MP + e_grid + e_code
    phase_l1 = rho + c dt_r - c dt_s + T + NLOS - I1 + lambda1 N1 + mp + e_phase

In a street canyon, NLOS is the extra path of the ray the loop locks to (the
strongest when the direct one is masked; labelled NLOS when it is a reflection)
and MP adds, to the Gauss-Markov diffuse multipath, what the preset's
early-minus-late DLL makes of all rays (:func:`~simbench.sim.tracking.dll_tracking_point`);
mp likewise gets the phase of the composite prompt correlator. C/N0 follows the
prompt amplitude. L2 likewise with ``I2 = (f1/f2)^2 I1``. The receiver is handed
the product satellite position and clock (truth plus orbit/clock error), the
elevation and azimuth, C/N0 and loss-of-lock flags.
"""

from __future__ import annotations

import os
from dataclasses import asdict, replace
from typing import Any

import numpy as np
import pandas as pd

from simbench.contract import LABEL_COLUMNS, OBSERVATION_COLUMNS, TRUTH_COLUMNS, NavInfo, Scenario, empty_odometry
from simbench.core.constants import C_LIGHT, CHIP_LENGTH_CA, DEG, F_L1, F_L2, SECONDS_PER_WEEK
from simbench.core.orbits import Constellation, NominalConstellation
from simbench.errors import SimbenchError
from simbench.gnss.navigation import read_gps_navigation
from simbench.sim import tracking
from simbench.sim.config import ConstellationKind, SimConfig, TrajectoryKind
from simbench.sim.error_source import ErrorSource, Lock, SimState
from simbench.sim.error_sources import SIGNAL_SOURCES, TRACKING_SOURCES
from simbench.sim.geometry import line_of_sight
from simbench.sim.imu import simulate_imu
from simbench.sim.odometry import simulate_odometry
from simbench.sim.processes import Columns, stream
from simbench.sim.trajectory import Trajectory, flight, replay, roadside_street, urban_drive


def generate(cfg: SimConfig) -> Scenario:
    """Generate one scenario.

    Parameters
    ----------
    cfg : SimConfig
        Scenario, receiver and IMU configuration and the seed, checked by
        :func:`~simbench.sim.config.validate_sim` (once per job, where the source checks its
        config: :meth:`simbench.sim.simulator_source.Simulator.check`); the generator trusts it.

    Returns
    -------
    Scenario
        Receiver view (observations, IMU, odometry), truth and labels; with odometry,
        ``meta['odometry_errors']`` holds its true scale factor and yaw-rate bias.
    """
    state = _sky(cfg)
    _run(SIGNAL_SOURCES, state)
    state.start_tracking(_lock(state))
    _run(TRACKING_SOURCES, state)
    meta: dict[str, Any] = {"name": cfg.scenario.name, "seed": cfg.seed, "config": asdict(cfg)}
    odometry = empty_odometry()
    if cfg.scenario.odometry.enabled:
        odo = simulate_odometry(state.traj, cfg.scenario.odometry, stream(cfg.seed, "odometry"))
        odometry = odo.table
        meta["odometry_errors"] = {"scale_factor": odo.scale_factor, "yaw_rate_bias_rps": odo.yaw_rate_bias_rps}
    observations, labels = _observation_tables(state)
    return Scenario(
        observations=observations,
        imu=_imu_table(state),
        truth=_truth_table(state),
        labels=labels,
        nav=_nav_info(state),
        meta=meta,
        odometry=odometry,
    )


def _run(sources: tuple[ErrorSource, ...], state: SimState) -> None:
    """Add the contributions of the enabled sources, in order, each drawing from its own stream."""
    for source in sources:
        if source.enabled(state):
            state.add(source.apply(state, state.stream(source.name)))


def _sky(cfg: SimConfig) -> SimState:
    """Trajectory at the GNSS epochs and the line of sight to every satellite: the state before any error."""
    sc = cfg.scenario
    traj, start_sow = _trajectory(cfg)
    step = cfg.imu.rate_hz / sc.rate_hz
    if abs(step - round(step)) > 1e-9:
        raise SimbenchError(
            "scenario.rate_hz",
            f"IMU rate {cfg.imu.rate_hz} Hz is not a multiple of {sc.rate_hz} Hz",
            "choose rates such that imu.rate_hz / scenario.rate_hz is an integer",
        )
    idx = traj.valid_every(step)
    pos = traj.pos[idx]
    constellation, alpha, beta = _constellation(cfg)
    t_gps = sc.gps_week * SECONDS_PER_WEEK + start_sow + traj.t[idx]
    los = line_of_sight(pos, traj.vel[idx], t_gps, constellation)
    above = los.valid & (los.el_rad > sc.constellation.elevation_mask_deg * DEG)
    # the grids keep the satellites that rise above the mask at some epoch (8 of 24 in an hour on
    # the ground); the others are never seen, and every random draw still spans all of them
    keep = np.flatnonzero(above.any(axis=0))
    return SimState(
        cfg=cfg,
        traj=traj,
        idx=idx,
        start_sow_s=start_sow,
        los=los.satellites(keep),
        constellation=constellation,
        iono_alpha=alpha,
        iono_beta=beta,
        above=above[:, keep],
        columns=Columns(len(constellation.sats), keep),
    )


def _lock(state: SimState) -> Lock:
    """Which channels the receiver tracks, and its loops' jitter, from the final C/N0.

    A channel is tracked from ``reacquisition_s`` after C/N0 first holds the
    acquisition threshold until it falls below the lock threshold or the DLL rule
    ``3 sigma_DLL <= D / 2`` fails (Kaplan & Hegarty, 2nd ed., sec. 5.6). A tracked
    channel has a phase while the PLL rule holds (``receiver.carrier_lock_threshold_deg``):
    a weak signal keeps its code and Doppler (the DLL and FLL hold longer) but loses its carrier.
    """
    rx, cn0, spacing = state.receiver, state.cn0_dbhz, state.spacing_chips
    sig_code = state.code_jitter_m(cn0)
    pll_rad = tracking.pll_jitter_rad(cn0, rx.pll_bw_hz, rx.integration_s)
    in_lock = state.in_view & (cn0 >= rx.lock_threshold_dbhz) & (3.0 * sig_code <= 0.5 * spacing * CHIP_LENGTH_CA)
    tracked = tracking.channel_lock_states(
        cn0 >= rx.acquisition_threshold_dbhz, in_lock, 1 + int(round(rx.reacquisition_s / state.dt_s))
    )
    # Kaplan's PLL rule of thumb 3 sigma_j + theta_e <= 45 deg, in its 1-sigma form
    traj = state.traj
    jerk = np.einsum("nk,nmk->nm", _rate_at(traj.acc, traj.t, state.idx), state.los.los_unit)
    pll_stress_rad = pll_rad + np.radians(tracking.pll_dynamic_stress_deg(jerk, rx.pll_bw_hz)) / 3.0
    carrier_locked = tracked & (pll_stress_rad <= np.radians(rx.carrier_lock_threshold_deg))
    return Lock(
        tracked=tracked,
        carrier_locked=carrier_locked,
        sigma_code_m=sig_code,
        pll_jitter_rad=pll_rad,
        pll_stress_rad=pll_stress_rad,
    )


def _rate_at(x: np.ndarray, t: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Time derivative of samples ``x`` (k, 3) at samples ``idx``: central differences, one-sided at the ends.

    ``np.gradient`` at the GNSS epochs only (a tenth of the IMU samples), for a uniform grid.
    """
    before, after = np.maximum(idx - 1, 0), np.minimum(idx + 1, len(t) - 1)
    return (x[after] - x[before]) / (t[after] - t[before])[:, None]


def _observation_tables(state: SimState) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Observation and label tables: one row per tracked (epoch, satellite), epoch-major.

    A contract label column whose source did not run is zero; a source's further
    label columns follow the contract's, only in scenarios where it ran.
    """
    los = state.los
    # flat positions into the (n, m) grids: one take per column is a fifth of grid[ei, si]'s time
    flat = np.flatnonzero(state.lock.tracked)
    ei, si = np.divmod(flat, state.shape[1])
    # the satellite names converted to pandas' string array once (m names), then repeated per row: a
    # conversion of every row's name, in each of the two tables, costs more than the rest of them
    sats = pd.Series(np.asarray(state.los.sats)).array
    keys = {"epoch": ei.astype(np.int64), "sat": sats.take(si)}
    grids = {
        "code_l1": state.code_l1_m,
        "phase_l1": state.phase_l1_m,
        "doppler_l1": state.doppler_l1_hz,
        "cn0_l1": state.cn0_dbhz,
        "code_l2": state.code_l2_m,
        "phase_l2": state.phase_l2_m,
        "sat_vx": los.sat_vel_tx[..., 0],
        "sat_vy": los.sat_vel_tx[..., 1],
        "sat_vz": los.sat_vel_tx[..., 2],
        "sat_clock_drift": C_LIGHT * los.sat_clock_drift,
        "el": np.degrees(los.el_rad),
        "az": np.degrees(los.az_rad),
        # columns sources own, as they are when those sources are off: a perfect product, no L2 flags
        "sat_x": los.sat_pos_tx[..., 0],
        "sat_y": los.sat_pos_tx[..., 1],
        "sat_z": los.sat_pos_tx[..., 2],
        "sat_clock": C_LIGHT * los.sat_clock_tx,
        "lli_l2": np.zeros(state.shape, bool),
        "f1_f2_ratio": np.where(np.isfinite(state.code_l2_m), F_L1 / F_L2, np.nan),
        **state.observations,
    }
    columns = {**keys, "t": state.t[ei], **{name: np.take(grid, flat) for name, grid in grids.items()}}
    observations = pd.DataFrame({name: columns[name] for name in OBSERVATION_COLUMNS})
    dtypes = {name: dtype for source in SIGNAL_SOURCES + TRACKING_SOURCES for name, dtype in source.labels.items()}
    names = [name for name in LABEL_COLUMNS if name not in keys]
    names += [name for name in state.labels if name not in LABEL_COLUMNS]
    picked = {
        name: np.take(state.labels[name], flat) if name in state.labels else np.zeros(len(ei), dtypes[name])
        for name in names
    }
    return observations, pd.DataFrame({**keys, **picked})


def _truth_table(state: SimState) -> pd.DataFrame:
    """The trajectory at the GNSS epochs, with the truth columns of the sources (zero when they did not run)."""
    n, idx = state.shape[0], state.idx
    pos, vel, att = state.traj.pos[idx], state.traj.vel[idx], state.traj.att[idx]
    columns = {
        "epoch": np.arange(n, dtype=np.int64),
        "t": state.t,
        **{name: pos[:, k] for k, name in enumerate("xyz")},
        **{name: vel[:, k] for k, name in enumerate(("vx", "vy", "vz"))},
        **{name: att[:, k] for k, name in enumerate(("roll", "pitch", "yaw"))},
        "rx_clock": np.zeros(n),
        "zwd": np.zeros(n),
        **state.truth,
        "n_visible": state.above.sum(axis=1).astype(np.int64),
    }
    return pd.DataFrame({name: columns[name] for name in TRUTH_COLUMNS})


def _imu_table(state: SimState) -> pd.DataFrame:
    imu = simulate_imu(state.traj, state.cfg.imu, stream(state.cfg.seed, "imu"))
    axes = {f"a{axis}": imu.accel[:, k] for k, axis in enumerate("xyz")}
    rates = {f"g{axis}": imu.gyro[:, k] for k, axis in enumerate("xyz")}
    return pd.DataFrame({"t": imu.t, **axes, **rates})


def _nav_info(state: SimState) -> NavInfo:
    sc = state.cfg.scenario
    # absolute: a cached scenario is read from other working directories
    ephemeris = (
        "nominal" if sc.constellation.kind == ConstellationKind.nominal else os.path.abspath(sc.constellation.nav_path)
    )
    return NavInfo(
        gps_week=sc.gps_week,
        start_sow_s=float(state.start_sow_s),
        iono_alpha=tuple(map(float, state.iono_alpha)),
        iono_beta=tuple(map(float, state.iono_beta)),
        dual_frequency=sc.dual_frequency,
        ephemeris=ephemeris,
    )


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


def _constellation(cfg: SimConfig) -> tuple[Constellation, tuple[float, ...], tuple[float, ...]]:
    """The orbits and the Klobuchar coefficients handed to the receiver (a broadcast file's own, if it has them)."""
    con = cfg.scenario.constellation
    if con.kind == ConstellationKind.nominal:
        return NominalConstellation(), tuple(con.iono_alpha), tuple(con.iono_beta)
    eph = read_gps_navigation(con.nav_path)
    alpha = eph.iono_alpha if eph.iono_alpha is not None else con.iono_alpha
    beta = eph.iono_beta if eph.iono_beta is not None else con.iono_beta
    return eph, tuple(alpha), tuple(beta)
