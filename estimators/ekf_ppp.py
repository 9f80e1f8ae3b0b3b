"""Extended Kalman filter PPP: the dissertation's reference estimator (Ch. 4, Table 4.4.2).

State: ``[x, y, z, clock_m, zwd_m, B_0 .. B_{S-1}]`` with one float carrier-phase
bias slot per satellite that appears in the data (``S`` <= 32 for GPS). A slot
holds the bias of its satellite's *current* arc; when the satellite starts a
new arc (first tracking, a gap, or a loss-of-lock flag) the slot's mean is set
to ``phase - predicted range`` at the code-updated state (so the arc's first phase
moves nothing) and its row and column of the covariance are reset to the a-priori
variance with no correlation. A fixed-size state keeps
the bookkeeping trivial and the matrices small (at most 37 x 37 for GPS), while the biases
of a continuous arc are still constants (dissertation's "landmark" view).

With ``estimate_iono`` (single frequency with the broadcast delay only; not part of Table 4.4.2) a second
block of per-satellite slots holds a slant ionosphere residual (code ``+I``,
phase ``-I``, random walk, reset with the arc): after the Klobuchar correction
the residual ionosphere changes by metres per hour, and without such a state
the phase, trusted at centimetres, turns that code-phase divergence into
position error (several metres on the simulator's open-sky scenario).

Stochastic model (Table 4.4.2): position random walk, zenith wet delay random
walk (``wet_delay = estimate``; with ``model``, the default, the state holds the
modelled wet delay at zero variance), phase biases constant. The receiver clock
has "correlation time 0", i.e. it is white noise: with ``clock_model="white"``
(default) it is re-initialised every epoch (correlations removed, variance
``clock_noise_m_rts^2 dt``, the previous estimate kept as the linearisation point,
which the linear clock term makes irrelevant); ``"random_walk"`` adds that variance
instead. The a priori 3e6 m is the variance at the first epoch.

Motion model (``motion_model``, the fields of
:class:`~estimators.ppp_config.MotionModelConfig` the graph estimators share):
``random_walk`` (default) is the position random walk above. ``constant_velocity``
appends ``[vx, vy, vz, drift]`` to the state (ECEF velocity [m/s], receiver clock
drift times c [m/s]): per axis the exact discretisation of white acceleration
with density ``q = accel_sigma_mps2_rts^2``, ``F = [[1, dt], [0, 1]]`` and
``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]``; the drift is a random walk
(``drift_rw_mps_rts``). With ``clock_model = "random_walk"`` the clock offset and the
drift form the usual two-state clock (offset advanced by ``drift dt``, ``Q`` of the
same form plus the offset's own ``clock_noise_m_rts``); with the default white clock
the offset is re-initialised each epoch, so the drift is seen through the
Doppler only (the graph keeps the drift apart from the clock in both cases, for
receivers whose clock jumps by milliseconds). Each epoch's Doppler rows give
range-rate updates ``rr = rdot(p, v) + drift``
(:func:`simbench.gnss.doppler.range_rate`, vectorised over the epoch's rows;
sigma ``doppler_sigma_mps`` times the row's ``sigma_scale``; rows without a Doppler are skipped).
With ``use_odometry`` and odometry samples since the previous epoch, their
mean wheel speed updates the horizontal velocity halfway through the time
update, where a mean over the interval applies for a steady acceleration
(updating at the epoch instead lags by half an interval and made the velocity
worse than the Doppler alone: 0.33 against 0.22 m/s median on urban seeds
1000-1003): zero velocity (all three axes) when standing (``|s| < STANDSTILL_MPS``),
otherwise the speed along the filter's direction of travel (the graph takes it
from a per-epoch Doppler fix; the filter's velocity is that fix plus the motion
model; none slower than ``DIRECTION_MIN_SPEED_MPS``) and the non-holonomic
constraint, no velocity across it (``nhc_sigma_mps``), and while the wheels turn no
vertical velocity beyond the road grade (``road_grade_sigma`` times the speed). The
non-holonomic row needs Doppler at the epoch: its direction is the filter's own velocity,
and without range rates nothing measures that direction, so the row would only shrink
the cross-track variance around it and keep the filter from turning (libRSF exports,
which have no Doppler, of urban_deep seed 1000 at 5 Hz: 62.9 -> 11.3 m median, at 1 Hz
35.2 -> 8.7 m; with Doppler the row steadies the heading and stays). The yaw rate, which ties
two epochs' velocities, is a graph-only factor; the filter state holds one epoch.

Filter mechanics come from filterpy's :class:`~filterpy.kalman.ExtendedKalmanFilter`
(``update`` with a Joseph-form covariance update, variable-length measurement
vectors through the ``HJacobian``/``Hx`` callables). The time update is done
here on the covariance diagonal (the state transition is the identity, so
filterpy's ``F P F^T + Q`` would only cost a full matrix product) together with
the slot resets filterpy has no notion of; the constant-velocity transition
touches only the position (and clock) rows and columns, added in place.

Each epoch is updated sequentially: the code block first, then the phase
block relinearised at the code-updated state. For uncorrelated measurement
noise this equals the joint update, and it keeps the first epoch well
conditioned: with the 3e6 m clock prior a joint innovation covariance would mix
9e12 m^2 with 6e-4 m^2 phase variances, beyond double precision.

Phase guard (``phase_guard``, not in the dissertation): the phase can only make a fix
worse than code alone when the arcs' biases hold an error the code no longer
supports, e.g. a reflected (NLOS) path's phase, which changes with the excess path
while its bias keeps the value of the arc's start (simulated urban_deep seeds
1000-1001: 10.4 and 15.4 m median against 5.8 and 5.4 m code-only; with the NLOS rows'
phase removed by their labels 3.9 m on seed 1001). The code-only filter runs first over
the same epochs; wherever the phase filter's position departs from it by more than its
covariance allows (a chi-square test, ``GUARD_CHI2``), the phase filter takes the
code filter's position and covariance and restarts every arc (then 4.5 and 5.3 m; the
guard bounds what the phase can do at a few sigmas of the code filter, it does not
pick out the one bad arc).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np
import pandas as pd
from filterpy.kalman import ExtendedKalmanFilter

from estimators import register
from estimators.base import Estimator, solution_frame
from estimators.measurement import (
    N_BASE_STATES,
    PppObservations,
    predict_given_troposphere,
    prepare_ppp,
    zenith_wet_delay_m,
)
from estimators.ppp_config import (
    DIRECTION_MIN_SPEED_MPS,
    MIN_ODOMETRY_VARIANCE,
    STANDSTILL_MPS,
    ClockModel,
    MotionModel,
    MotionModelConfig,
    WetDelayMode,
)
from estimators.ppp_graph import WetDelayChoice, wet_delay_choice
from simbench.contract import ReceiverData
from simbench.core.frames import geodetic_from_ecef
from simbench.errors import SimbenchError
from simbench.gnss.doppler import doppler_velocities, range_rate
from simbench.gnss.geometry import enu_basis
from simbench.gnss.spp import solve_epochs, system_clock_offsets
from simbench.gnss.troposphere import troposphere_terms

#: Epochs searched for a trusted first fix.
_INIT_EPOCHS = 30
#: Chi-square of the phase guard's position test: 3 degrees of freedom at a false-alarm rate of
#: 1e-5, about one needless fallback a day at 1 Hz (each one costs the arcs' accumulated precision)
GUARD_CHI2 = 25.9
#: Indices of the base states.
_POS, _CLK, _ZWD = slice(0, 3), 3, 4


@dataclass
class EkfPppConfig(MotionModelConfig):
    """EKF-PPP parameters: the shared model of :class:`~estimators.ppp_config.MotionModelConfig`.

    ``measurements = code`` makes it a code-only filter (no bias states);
    ``motion_model = constant_velocity`` adds velocity and clock drift states.
    """

    #: with carrier phase, run the code-only filter too and fall back to it wherever the phase
    #: filter's position departs from it beyond its covariance (:meth:`EkfPpp.run`'s ``anchor``)
    phase_guard: bool = True


@dataclass
class EkfTrack:
    """What one filter pass produces, per solved epoch.

    Attributes
    ----------
    pos : ndarray, shape (n_epochs, 3)
        Receiver ECEF position after the epoch's updates [m].
    pos_cov : ndarray, shape (n_epochs, 3, 3)
        Its covariance [m^2].
    vel : ndarray, shape (n_epochs, 3) or None
        ECEF velocity [m/s] (constant-velocity model only).
    update_s : ndarray, shape (n_epochs,)
        Wall time of each epoch's time and measurement updates [s].
    diagnostics : dict
        Counts and final state values (see :meth:`EkfPpp.run`).
    """

    pos: np.ndarray
    pos_cov: np.ndarray
    vel: np.ndarray | None
    update_s: np.ndarray
    diagnostics: dict[str, Any]


@register
class EkfPpp(Estimator):
    """Kinematic PPP with an extended Kalman filter (code + carrier phase, float biases)."""

    name = "ekf_ppp"
    Config = EkfPppConfig

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        obs = prepare_ppp(data, **self.config.prepare_kwargs())
        wet = wet_delay_choice(obs, self.config)  # decided on all the rows, kept by the phase guard's pass
        anchor = None
        if obs.n_arcs and self.config.phase_guard:
            anchor = self.run(code_only(obs), wet=wet)
        track = self.run(obs, anchor, wet=wet)
        if anchor is not None:
            track.update_s += anchor.update_s
        # the filter's own position covariance goes out with the positions (the report's consistency check)
        return solution_frame(obs.epoch_ids, obs.epoch_t, track.pos, track.update_s, track.pos_cov), track.diagnostics

    def run(self, obs: PppObservations, anchor: EkfTrack | None = None, wet: WetDelayChoice | None = None) -> EkfTrack:
        """Filter prepared observations epoch by epoch.

        Parameters
        ----------
        obs : PppObservations
            From :func:`~estimators.measurement.prepare_ppp` with this config's
            :meth:`~estimators.ppp_config.StochasticModelConfig.prepare_kwargs`.
        anchor : EkfTrack, optional
            The code-only filter's pass over the same epochs (the phase guard): at every
            epoch where the position departs from the anchor's by more than the anchor's
            covariance allows (``d^T P_code^-1 d > GUARD_CHI2``), the filter takes the anchor's
            position and covariance and restarts every phase arc.
        wet : WetDelayChoice, optional
            The resolved ``wet_delay`` (default: :func:`~estimators.ppp_graph.wet_delay_choice` on ``obs``).

        Returns
        -------
        EkfTrack
        """
        cfg: EkfPppConfig = self.config
        assert obs.system_index is not None  # prepare_ppp always sets it
        n_slots = len(obs.sat_names) if obs.n_arcs else 0
        # slant-ionosphere slots follow the bias slots, one per satellite, reset with the arc
        n_iono = n_slots if cfg.estimate_iono and obs.broadcast_ionosphere else 0
        iono0 = N_BASE_STATES + n_slots
        # one receiver clock offset per further GNSS system (inter-system bias, random walk), last
        isb0 = N_BASE_STATES + n_slots + n_iono
        # constant velocity: ECEF velocity and clock drift after everything else
        cv = cfg.motion_model == MotionModel.constant_velocity
        vel0 = isb0 + obs.n_isb
        drift = vel0 + 3
        nx = vel0 + (4 if cv else 0)
        doppler = cv and obs.range_rate is not None and bool(np.isfinite(obs.range_rate).any())
        odometry = obs.odometry if cv and cfg.use_odometry else None
        kf = ExtendedKalmanFilter(dim_x=nx, dim_z=1)

        # ---- initialisation from a single point solution at the first epoch, or the nearest
        # trusted one among the first few (an NLOS-ridden fix, or fewer than 4 satellites), or
        # among all when none of those is
        all_k = obs.row_epoch
        for rows in (slice(0, int(obs.epoch_stop[min(obs.n_epochs, _INIT_EPOCHS) - 1])), slice(None)):
            row_k = all_k[rows]
            try:
                fix = solve_epochs(
                    row_k,
                    obs.sat_pos[rows],
                    obs.code[rows],
                    sigma=obs.sigma_code[rows],
                    el=obs.el[rows],
                    doy=obs.doy,
                    system_index=obs.system_index[rows],
                    fill_untrusted=True,
                )
                break
            except SimbenchError:  # no trusted fix among the first epochs: search them all
                if rows == slice(None):
                    raise
        pos0, clock0 = fix.pos[0], float(fix.clock_m[0, 0])
        lat0, _, h0 = geodetic_from_ecef(pos0)
        x = np.zeros(nx)
        x[_POS], x[_CLK] = pos0, clock0
        x[isb0:vel0] = system_clock_offsets(fix, row_k, obs.system_index[rows])
        if doppler:
            assert obs.range_rate is not None and obs.sat_vel is not None  # Doppler rows come with both
            # the drift of a receiver clock can be anything up to km/s: start at the first Doppler fix
            _, drift_fix = doppler_velocities(
                row_k,
                obs.sat_pos[rows],
                obs.sat_vel[rows],
                fix.pos[row_k],
                obs.range_rate[rows],
                cfg.doppler_sigma_mps * obs.sigma_scale[rows],
            )
            known = np.isfinite(drift_fix)
            x[drift] = drift_fix[np.argmax(known)] if known.any() else 0.0
        p_diag = np.full(nx, cfg.ambiguity_sigma_m**2)
        p_diag[_POS] = cfg.pos_sigma_m**2
        p_diag[_CLK] = cfg.clock_sigma_m**2
        # wet_delay resolved to model: the state holds the modelled wet delay, which nothing then moves
        wet = wet if wet is not None else wet_delay_choice(obs, cfg)
        estimate_zwd = wet.mode == WetDelayMode.estimate
        p_diag[_ZWD] = cfg.zwd_sigma_m**2 if estimate_zwd else 0.0
        x[_ZWD] = zenith_wet_delay_m(wet.mode, float(lat0), float(h0), obs.doy)
        p_diag[iono0:] = cfg.iono_sigma_m**2
        p_diag[isb0:vel0] = cfg.isb_sigma_m**2
        if cv:
            p_diag[vel0:drift] = cfg.vel_sigma_mps**2
            p_diag[drift] = cfg.drift_sigma_mps**2
        kf.x = x
        kf.P = np.diag(p_diag)

        slot_arc = np.full(n_slots, -1, np.int64)  # arc currently held by each slot
        amb_var = cfg.ambiguity_sigma_m**2
        q_pos, q_clk = cfg.pos_rw_m_rts**2, cfg.clock_noise_m_rts**2
        q_zwd = cfg.zwd_rw_m_rts**2 if estimate_zwd else 0.0
        q_iono, iono_var = cfg.iono_rw_m_rts**2, cfg.iono_sigma_m**2
        iono_diag = np.arange(iono0, isb0)
        isb_diag = np.arange(isb0, vel0)
        q_isb = cfg.isb_rw_m_rts**2
        white_clock = cfg.clock_model == ClockModel.white
        diag = np.arange(3)
        vel_diag = vel0 + diag
        q_acc, q_drift = cfg.accel_sigma_mps2_rts**2, cfg.drift_rw_mps_rts**2
        rw_clock_drift = cv and not white_clock

        n = obs.n_epochs
        pos_out = np.empty((n, 3))
        pos_cov = np.empty((n, 3, 3))
        vel_out = np.empty((n, 3)) if cv else None
        n_doppler = n_odometry = 0
        update_s = np.empty(n)
        n_resets = n_fallbacks = 0
        arc_bias = np.full(obs.n_arcs, np.nan)  # final bias estimate of each arc [m]
        arc_sat = np.empty(obs.n_arcs, dtype=object)
        arc_sat[obs.arc[obs.has_phase]] = obs.sat[obs.has_phase]
        t_prev = obs.epoch_t[0]
        for k, rows in obs.iter_epochs():
            tic = time.perf_counter()
            # ---- time update (identity transition; constant velocity: position += velocity dt)
            dt = obs.epoch_t[k] - t_prev
            t_prev = obs.epoch_t[k]
            if dt > 0 and cv:
                if odometry is not None and np.isfinite(odometry[k, 0]):
                    # the mean speed since the previous epoch is the speed at mid-interval (for a
                    # steady acceleration): update there, halfway through the exact time update
                    _advance(kf, diag, vel_diag, dt / 2.0, q_acc)
                    with_doppler = obs.range_rate is not None and bool(np.isfinite(obs.range_rate[rows]).any())
                    n_odometry += self._odometry_update(kf, odometry[k], vel0, with_doppler)
                    _advance(kf, diag, vel_diag, dt / 2.0, q_acc)
                else:
                    _advance(kf, diag, vel_diag, dt, q_acc)
                kf.P[drift, drift] += q_drift * dt
                if rw_clock_drift:
                    _advance(kf, np.array([_CLK]), np.array([drift]), dt, q_drift)
            P = kf.P  # after the odometry update, which replaces the array
            if dt > 0:
                if not cv:
                    P[diag, diag] += q_pos * dt
                P[_ZWD, _ZWD] += q_zwd * dt
                P[iono_diag, iono_diag] += q_iono * dt
                P[isb_diag, isb_diag] += q_isb * dt
                if white_clock:
                    P[_CLK, :] = 0.0
                    P[:, _CLK] = 0.0
                    P[_CLK, _CLK] = q_clk * dt
                else:
                    P[_CLK, _CLK] += q_clk * dt

            sat_pos, el = obs.sat_pos[rows], obs.el[rows]
            lat, _, h = geodetic_from_ecef(kf.x[_POS])
            hydro, m_w = troposphere_terms(el, lat, h, obs.doy)  # once per epoch (insensitive to metres)
            m = len(el)
            H = np.zeros((m, nx))
            rng_m = np.arange(m)
            if obs.n_isb:
                sys_k = obs.system_index[rows]
                other = np.flatnonzero(sys_k > 0)
                H[other, isb0 + sys_k[other] - 1] = 1.0

            if n_slots:
                # ---- new arcs get fresh bias and ionosphere slots, no correlations; the bias mean is
                # set after the code update (below)
                slots = obs.sat_index[rows]
                arcs = obs.arc[rows]
                has_phase = arcs >= 0
                fresh = has_phase & (slot_arc[slots] != arcs)
                if fresh.any():
                    idx = N_BASE_STATES + slots[fresh]
                    ended = slot_arc[slots[fresh]]
                    arc_bias[ended[ended >= 0]] = kf.x[idx[ended >= 0]]
                    _reset(kf, idx, 0.0, amb_var)
                    if n_iono:
                        _reset(kf, iono0 + slots[fresh], 0.0, iono_var)
                    slot_arc[slots[fresh]] = arcs[fresh]
                    n_resets += int(fresh.sum())

            # ---- code update
            pred, H5 = predict_given_troposphere(sat_pos, kf.x[_POS], kf.x[_CLK], kf.x[_ZWD], hydro, m_w)
            H[:, :N_BASE_STATES] = H5
            if n_iono:
                # the slant ionosphere of a row without phase is not separable from its code
                H[rng_m[has_phase], iono0 + slots[has_phase]] = 1.0
                pred = pred + np.where(has_phase, kf.x[iono0 + slots], 0.0)
            if obs.n_isb:
                pred[other] += kf.x[isb0 + sys_k[other] - 1]
            if white_clock:
                # a white clock keeps nothing from the last epoch: centre it on this epoch's code, so a
                # receiver that holds its clock within a millisecond by jumps (u-blox: 300-2100 km, a
                # thousand sigma of the clock's 2 km) leaks no metres into the position
                shift = float(np.median(obs.code[rows] - pred))
                kf.x[_CLK] += shift
                pred += shift
            kf.update(obs.code[rows], _const(H), _const(pred), R=np.diag(obs.sigma_code[rows] ** 2))

            if n_slots and has_phase.any():
                # ---- phase update of the rows with phase, relinearised at the code-updated state
                pred, H5 = predict_given_troposphere(sat_pos, kf.x[_POS], kf.x[_CLK], kf.x[_ZWD], hydro, m_w)
                H[:, :N_BASE_STATES] = H5
                H[rng_m, N_BASE_STATES + slots] = 1.0
                pred = pred + kf.x[N_BASE_STATES + slots]
                if n_iono:
                    H[rng_m, iono0 + slots] = -1.0
                    pred = pred - kf.x[iono0 + slots]
                if obs.n_isb:
                    pred[other] += kf.x[isb0 + sys_k[other] - 1]
                # a new arc's bias starts at its phase minus the code-updated prediction, so its first
                # phase moves nothing (a diffuse prior, whatever the clock or the position did since
                # the last epoch); before the code update a 60-100 m clock change sat in the new bias
                new_bias = obs.phase[rows][fresh] - pred[fresh]
                kf.x[N_BASE_STATES + slots[fresh]] = new_bias
                pred[fresh] += new_bias
                kf.update(
                    obs.phase[rows][has_phase],
                    _const(H[has_phase]),
                    _const(pred[has_phase]),
                    R=np.diag(obs.sigma_phase[rows][has_phase] ** 2),
                )

            if doppler:
                n_doppler += self._doppler_update(kf, obs, rows, vel0, drift)

            if anchor is not None:
                d = kf.x[_POS] - anchor.pos[k]
                if float(d @ np.linalg.solve(anchor.pos_cov[k], d)) > GUARD_CHI2:
                    # the phase holds a position the code refutes (an NLOS phase baked into the
                    # arcs' biases): fall back to the code filter and restart every arc
                    kf.x[_POS] = anchor.pos[k]
                    kf.P[_POS, :] = 0.0
                    kf.P[:, _POS] = 0.0
                    kf.P[_POS, _POS] = anchor.pos_cov[k]
                    slot_arc[:] = -1
                    n_fallbacks += 1
            pos_out[k] = kf.x[_POS]
            pos_cov[k] = kf.P[_POS, _POS]
            if vel_out is not None:  # constant velocity
                vel_out[k] = kf.x[vel0:drift]
            update_s[k] = time.perf_counter() - tic

        held = slot_arc >= 0
        arc_bias[slot_arc[held]] = kf.x[N_BASE_STATES + np.flatnonzero(held)]
        diagnostics = {
            "n_epochs": int(n),
            "n_observations": int(obs.n_obs),
            "n_satellites": len(obs.sat_names),
            "n_arcs": int(obs.n_arcs),
            "n_ambiguity_resets": n_resets,
            "n_phase_fallbacks": n_fallbacks,
            **obs.model_info(),
            **wet.info(),
            "iono_states": bool(n_iono),
            "inter_system_bias_m": {s: float(kf.x[isb0 + k]) for k, s in enumerate(obs.systems[1:])},
            "arc_sat": [str(v) for v in arc_sat] if n_slots else [],
            "arc_bias_m": [float(v) for v in arc_bias] if n_slots else [],
            "final_clock_m": float(kf.x[_CLK]),
            "final_zwd_m": float(kf.x[_ZWD]),
            "final_pos_sigma_m": [float(s) for s in np.sqrt(np.diag(kf.P)[_POS])],
            "motion_model": MotionModel(cfg.motion_model).value,
            "n_doppler_updates": n_doppler,
            "n_odometry_updates": n_odometry,
            "config": asdict(cfg),
        }
        if cv:
            diagnostics["final_clock_drift_mps"] = float(kf.x[drift])
        return EkfTrack(pos_out, pos_cov, vel_out, update_s, diagnostics)

    def _doppler_update(
        self, kf: ExtendedKalmanFilter, obs: PppObservations, rows: slice, vel0: int, drift: int
    ) -> int:
        """Range-rate update with the epoch's Doppler rows; returns the number of rows used."""
        assert obs.range_rate is not None and obs.sat_vel is not None  # called with Doppler rows only
        rr = obs.range_rate[rows]
        use = np.isfinite(rr)
        if not use.any():
            return 0
        pos, vel = kf.x[_POS], kf.x[vel0:drift]
        rdot, d_pos, d_vel = range_rate(obs.sat_pos[rows][use], obs.sat_vel[rows][use], pos, vel)
        H = np.zeros((int(use.sum()), kf.dim_x))
        H[:, _POS], H[:, vel0:drift], H[:, drift] = d_pos, d_vel, 1.0
        sigma = self.config.doppler_sigma_mps * obs.sigma_scale[rows][use]
        kf.update(rr[use], _const(H), _const(rdot + kf.x[drift]), R=np.diag(sigma**2))
        return int(use.sum())

    def _odometry_update(self, kf: ExtendedKalmanFilter, sample: np.ndarray, vel0: int, with_doppler: bool) -> int:
        """Wheel-speed update of the velocity (one epoch's mean odometry ``sample``:
        speed, yaw rate and their variances); the non-holonomic row only ``with_doppler`` (the
        epoch has range rates, which measure the direction it is taken along); returns 1 when an
        update was made."""
        speed, _, var_speed, _, right, down, var_right, var_down = sample
        east, north, up = enu_basis(kf.x[_POS])
        vel = kf.x[vel0 : vel0 + 3]
        sig_s = float(np.sqrt(max(var_speed, MIN_ODOMETRY_VARIANCE)))
        # the reported vertical velocity, else none beyond the road grade (loosely at rest, see the config)
        vertical = self.config.vertical_velocity(speed, sig_s, down, var_down)
        if abs(speed) < STANDSTILL_MPS:
            # wheels at rest: no horizontal velocity
            rows, z = np.vstack([east, north, up]), np.array([0.0, 0.0, vertical.value])
            sigma = np.array([sig_s, sig_s, vertical.sigma])
        else:
            rows, z, sigma = up[None, :], np.array([vertical.value]), np.array([vertical.sigma])
            horizontal = east * (east @ vel) + north * (north @ vel)
            moving = float(np.linalg.norm(horizontal))
            if moving >= DIRECTION_MIN_SPEED_MPS:
                along = horizontal / moving
                rows, z, sigma = np.vstack([rows, along]), np.r_[z, abs(speed)], np.r_[sigma, sig_s]
                if with_doppler:
                    left = self.config.left_velocity(right, var_right)
                    rows = np.vstack([rows, np.cross(up, along)])
                    z, sigma = np.r_[z, left.value], np.r_[sigma, left.sigma]
        H = np.zeros((len(rows), kf.dim_x))
        H[:, vel0 : vel0 + 3] = rows
        kf.update(z, _const(H), _const(H @ kf.x), R=np.diag(sigma**2))
        return 1


def code_only(obs: PppObservations) -> PppObservations:
    """``obs`` without its carrier phase (every row code-only, no arcs)."""
    return replace(obs, phase=np.full_like(obs.phase, np.nan), arc=np.full_like(obs.arc, -1), n_arcs=0)


def _advance(kf: ExtendedKalmanFilter, level: np.ndarray, rate: np.ndarray, dt: float, q: float) -> None:
    """Time update of integrated pairs ``level += rate dt`` with white noise of density ``q`` on the rate.

    ``P <- F P F^T + Q`` with ``F`` the identity plus ``dt`` at (level, rate), done on the
    affected rows and columns only; per pair ``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]``.
    """
    kf.x[level] += dt * kf.x[rate]
    P = kf.P
    P[level, :] += dt * P[rate, :]
    P[:, level] += dt * P[:, rate]
    P[level, level] += q * dt**3 / 3.0
    P[level, rate] += q * dt**2 / 2.0
    P[rate, level] += q * dt**2 / 2.0
    P[rate, rate] += q * dt


def _reset(kf: ExtendedKalmanFilter, idx: np.ndarray, mean: np.ndarray | float, var: float) -> None:
    """Re-initialise states ``idx``: new mean, a-priori variance, no correlation with the rest."""
    kf.x[idx] = mean
    kf.P[idx, :] = 0.0
    kf.P[:, idx] = 0.0
    kf.P[idx, idx] = var


def _const(value: np.ndarray):
    """filterpy wants callables for H(x) and h(x); ours are computed before the call."""
    return lambda _x: value
