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
:class:`~estimators.model.ppp_config.MotionModelConfig` the graph estimators share):
``random_walk`` (default) is the position random walk above. ``constant_velocity``
appends ``[vx, vy, vz, drift]`` to the state (ECEF velocity [m/s], receiver clock
drift times c [m/s]): per axis the exact discretisation of white acceleration
with density ``q = accel_sigma_mps2_rts^2``, ``F = [[1, dt], [0, 1]]`` and
``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]``; the drift is a random walk
(``drift_rw_mps_rts``). With ``clock_model = "random_walk"`` the clock offset and the
drift form the usual two-state clock (offset advanced by ``drift dt``, ``Q`` of the
same form plus the offset's own ``clock_noise_m_rts``; ``"two_state"`` is the same with the
oscillator's ``oscillator_noise_m_rts``, and the clock restarts where the epoch's median code
innovation exceeds ``clock_jump_m``, a receiver's millisecond jump, and at epochs with fewer than
``clock_link_min_satellites`` code rows); with the default white clock
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
from estimators.filters.configs import EkfPppConfig
from estimators.model.measurement import (
    N_BASE_STATES,
    PppObservations,
    predict_given_troposphere,
    prepare_ppp,
    zenith_wet_delay_m,
)
from estimators.model.ppp_config import (
    DIRECTION_MIN_SPEED_MPS,
    MIN_ODOMETRY_VARIANCE,
    STANDSTILL_MPS,
    ClockModel,
    MotionModel,
    WetDelayMode,
)
from estimators.model.ppp_graph import WetDelayChoice, wet_delay_choice
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
            From :func:`~estimators.model.measurement.prepare_ppp` with this config's
            :meth:`~estimators.model.ppp_config.StochasticModelConfig.prepare_kwargs`.
        anchor : EkfTrack, optional
            The code-only filter's pass over the same epochs (the phase guard): at every
            epoch where the position departs from the anchor's by more than the anchor's
            covariance allows (``d^T P_code^-1 d > GUARD_CHI2``), the filter takes the anchor's
            position and covariance and restarts every phase arc.
        wet : WetDelayChoice, optional
            The resolved ``wet_delay`` (default: :func:`~estimators.model.ppp_graph.wet_delay_choice` on ``obs``).

        Returns
        -------
        EkfTrack
        """
        f = EkfPass(self.config, obs, wet if wet is not None else wet_delay_choice(obs, self.config))
        n = obs.n_epochs
        pos_out, pos_cov = np.empty((n, 3)), np.empty((n, 3, 3))
        vel_out = np.empty((n, 3)) if f.layout.cv else None
        update_s = np.empty(n)
        t_prev = obs.epoch_t[0]
        for k, rows in obs.iter_epochs():
            tic = time.perf_counter()
            f.predict(k, rows, obs.epoch_t[k] - t_prev)
            t_prev = obs.epoch_t[k]
            epoch = f.epoch_rows(rows)
            f.update_code(epoch)
            f.update_phase(epoch)
            f.update_doppler(rows)
            if anchor is not None:
                f.guard(anchor.pos[k], anchor.pos_cov[k])
            pos_out[k], pos_cov[k] = f.kf.x[_POS], f.kf.P[_POS, _POS]
            if vel_out is not None:  # constant velocity
                vel_out[k] = f.kf.x[f.layout.vel0 : f.layout.drift]
            update_s[k] = time.perf_counter() - tic
        return EkfTrack(pos_out, pos_cov, vel_out, update_s, f.diagnostics())


@dataclass(frozen=True)
class StateLayout:
    """Where each state sits in the filter's vector: the base states (:data:`N_BASE_STATES`), one phase
    bias slot per satellite, a slant-ionosphere slot per satellite (when estimated), one clock offset
    per further GNSS system, then (constant velocity) ECEF velocity and clock drift."""

    n_slots: int  #: bias slots (one per satellite when there is phase)
    n_iono: int  #: slant-ionosphere slots
    iono0: int  #: first ionosphere slot
    isb0: int  #: first inter-system clock offset
    vel0: int  #: first velocity state
    drift: int  #: clock drift state
    nx: int  #: state dimension
    cv: bool  #: constant-velocity motion model

    @classmethod
    def of(cls, obs: PppObservations, cfg: EkfPppConfig) -> StateLayout:
        n_slots = len(obs.sat_names) if obs.n_arcs else 0
        n_iono = n_slots if cfg.estimate_iono and obs.broadcast_ionosphere else 0
        isb0 = N_BASE_STATES + n_slots + n_iono
        vel0 = isb0 + obs.n_isb
        cv = cfg.motion_model == MotionModel.constant_velocity
        return cls(n_slots, n_iono, N_BASE_STATES + n_slots, isb0, vel0, vel0 + 3, vel0 + (4 if cv else 0), cv)


@dataclass(frozen=True)
class EpochRows:
    """One epoch's rows as the measurement updates use them (after new arcs got their slots)."""

    rows: slice
    hydro: np.ndarray  #: hydrostatic delay per row [m]
    m_w: np.ndarray  #: wet mapping function per row
    isb_rows: np.ndarray  #: rows of a further system
    isb_cols: np.ndarray  #: their clock-offset state
    slots: np.ndarray  #: bias slot per row (phase rows)
    has_phase: np.ndarray  #: rows with phase, bool
    fresh: np.ndarray  #: rows whose arc starts here, bool


class EkfPass:
    """One pass of the filter over prepared observations, in filterpy's steps: :meth:`predict`, then the
    code, phase and Doppler updates of an epoch, and the phase guard (:meth:`EkfPpp.run` sequences them).

    Parameters
    ----------
    cfg : EkfPppConfig
    obs : PppObservations
    wet : WetDelayChoice
        The resolved ``wet_delay``: ``model`` holds the modelled wet delay, which nothing then moves.
    """

    def __init__(self, cfg: EkfPppConfig, obs: PppObservations, wet: WetDelayChoice) -> None:
        assert obs.system_index is not None  # prepare_ppp always sets it
        self.cfg, self.obs, self.wet = cfg, obs, wet
        self.layout = lay = StateLayout.of(obs, cfg)
        self.doppler = lay.cv and obs.range_rate is not None and bool(np.isfinite(obs.range_rate).any())
        self.odometry = obs.odometry if lay.cv and cfg.use_odometry else None
        self.kf = ExtendedKalmanFilter(dim_x=lay.nx, dim_z=1)
        self.slot_arc = np.full(lay.n_slots, -1, np.int64)  # arc currently held by each slot
        self.arc_bias = np.full(obs.n_arcs, np.nan)  # final bias estimate of each arc [m]
        self.n_doppler = self.n_odometry = self.n_resets = self.n_fallbacks = 0
        self.estimate_zwd = wet.mode == WetDelayMode.estimate
        self.white_clock = cfg.clock_model == ClockModel.white
        self.two_state = cfg.clock_model == ClockModel.two_state
        # the offset's own noise density about the drift's prediction [m/sqrt(s)]
        self.clock_noise = cfg.oscillator_noise_m_rts if self.two_state else cfg.clock_noise_m_rts
        self.n_clock_jumps = 0
        # the time update's indices, once: it runs every epoch
        self.pos_diag, self.vel_diag = np.arange(3), lay.vel0 + np.arange(3)
        self.iono_diag, self.isb_diag = np.arange(lay.iono0, lay.isb0), np.arange(lay.isb0, lay.vel0)
        self._initialise()

    def _first_fix(self) -> tuple[Any, slice]:
        """A single point solution at the first epoch, or the nearest trusted one among the first few (an
        NLOS-ridden fix, or fewer than 4 satellites), or among all when none of those is; and its rows."""
        obs = self.obs
        assert obs.system_index is not None
        for rows in (slice(0, int(obs.epoch_stop[min(obs.n_epochs, _INIT_EPOCHS) - 1])), slice(None)):
            try:
                fix = solve_epochs(
                    obs.row_epoch[rows],
                    obs.sat_pos[rows],
                    obs.code[rows],
                    sigma=obs.sigma_code[rows],
                    el=obs.el[rows],
                    doy=obs.doy,
                    system_index=obs.system_index[rows],
                    fill_untrusted=True,
                )
                return fix, rows
            except SimbenchError:  # no trusted fix among the first epochs: search them all
                if rows == slice(None):
                    raise
        raise AssertionError("unreachable")  # the last attempt returns or raises

    def _initialise(self) -> None:
        """State and covariance at the first epoch, from the first fix."""
        cfg, obs, lay = self.cfg, self.obs, self.layout
        assert obs.system_index is not None
        fix, rows = self._first_fix()
        row_k = obs.row_epoch[rows]
        pos0 = fix.pos[0]
        lat0, _, h0 = geodetic_from_ecef(pos0)
        x = np.zeros(lay.nx)
        x[_POS], x[_CLK] = pos0, float(fix.clock_m[0, 0])
        x[lay.isb0 : lay.vel0] = system_clock_offsets(fix, row_k, obs.system_index[rows])
        if self.doppler:
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
            x[lay.drift] = drift_fix[np.argmax(known)] if known.any() else 0.0
        p_diag = np.full(lay.nx, cfg.ambiguity_sigma_m**2)
        p_diag[_POS] = cfg.pos_sigma_m**2
        p_diag[_CLK] = cfg.clock_sigma_m**2
        p_diag[_ZWD] = cfg.zwd_sigma_m**2 if self.estimate_zwd else 0.0
        x[_ZWD] = zenith_wet_delay_m(self.wet.mode, float(lat0), float(h0), obs.doy)
        p_diag[lay.iono0 :] = cfg.iono_sigma_m**2
        p_diag[lay.isb0 : lay.vel0] = cfg.isb_sigma_m**2
        if lay.cv:
            p_diag[lay.vel0 : lay.drift] = cfg.vel_sigma_mps**2
            p_diag[lay.drift] = cfg.drift_sigma_mps**2
        self.kf.x = x
        self.kf.P = np.diag(p_diag)

    def predict(self, k: int, rows: slice, dt: float) -> None:
        """Time update over ``dt`` seconds to epoch ``k`` (identity transition; constant velocity:
        position += velocity dt, with epoch ``k``'s mean wheel odometry applied at mid-interval)."""
        cfg, lay, kf = self.cfg, self.layout, self.kf
        diag, vel_diag, white_clock = self.pos_diag, self.vel_diag, self.white_clock
        if dt > 0 and lay.cv:
            q_acc, q_drift = cfg.accel_sigma_mps2_rts**2, cfg.drift_rw_mps_rts**2
            if self.odometry is not None and np.isfinite(self.odometry[k, 0]):
                # the mean speed since the previous epoch is the speed at mid-interval (for a
                # steady acceleration): update there, halfway through the exact time update
                _advance(kf, diag, vel_diag, dt / 2.0, q_acc)
                rr = self.obs.range_rate
                self.n_odometry += self.update_odometry(
                    self.odometry[k], with_doppler=rr is not None and bool(np.isfinite(rr[rows]).any())
                )
                _advance(kf, diag, vel_diag, dt / 2.0, q_acc)
            else:
                _advance(kf, diag, vel_diag, dt, q_acc)
            kf.P[lay.drift, lay.drift] += q_drift * dt
            if not white_clock:
                _advance(kf, np.array([_CLK]), np.array([lay.drift]), dt, q_drift)
        P = kf.P  # after the odometry update, which replaces the array
        if dt > 0:
            if not lay.cv:
                P[diag, diag] += cfg.pos_rw_m_rts**2 * dt
            P[_ZWD, _ZWD] += (cfg.zwd_rw_m_rts**2 if self.estimate_zwd else 0.0) * dt
            P[self.iono_diag, self.iono_diag] += cfg.iono_rw_m_rts**2 * dt
            P[self.isb_diag, self.isb_diag] += cfg.isb_rw_m_rts**2 * dt
            if white_clock:
                P[_CLK, :] = 0.0
                P[:, _CLK] = 0.0
                P[_CLK, _CLK] = cfg.clock_noise_m_rts**2 * dt
            else:
                P[_CLK, _CLK] += self.clock_noise**2 * dt

    def epoch_rows(self, rows: slice) -> EpochRows:
        """The epoch's troposphere terms at the predicted position (once per epoch: insensitive to
        metres) and its arcs; new arcs get fresh bias and ionosphere slots, no correlations (the bias
        mean is set after the code update, :meth:`update_phase`)."""
        obs, lay, kf = self.obs, self.layout, self.kf
        assert obs.system_index is not None
        lat, _, h = geodetic_from_ecef(kf.x[_POS])
        hydro, m_w = troposphere_terms(obs.el[rows], lat, h, obs.doy)
        sys_k = obs.system_index[rows]
        isb_rows = np.flatnonzero(sys_k > 0) if obs.n_isb else np.zeros(0, np.int64)
        isb_cols = lay.isb0 + sys_k[isb_rows] - 1
        none = np.zeros(len(sys_k), bool)
        if not lay.n_slots:
            return EpochRows(rows, hydro, m_w, isb_rows, isb_cols, np.zeros(0, np.int64), none, none)
        slots, arcs = obs.sat_index[rows], obs.arc[rows]
        has_phase = arcs >= 0
        fresh = has_phase & (self.slot_arc[slots] != arcs)
        if fresh.any():
            idx = N_BASE_STATES + slots[fresh]
            ended = self.slot_arc[slots[fresh]]
            self.arc_bias[ended[ended >= 0]] = kf.x[idx[ended >= 0]]
            _reset(kf, idx, 0.0, self.cfg.ambiguity_sigma_m**2)
            if lay.n_iono:
                _reset(kf, lay.iono0 + slots[fresh], 0.0, self.cfg.iono_sigma_m**2)
            self.slot_arc[slots[fresh]] = arcs[fresh]
            self.n_resets += int(fresh.sum())
        return EpochRows(rows, hydro, m_w, isb_rows, isb_cols, slots, has_phase, fresh)

    def _predicted_ranges(self, e: EpochRows) -> tuple[np.ndarray, np.ndarray]:
        """Each row's predicted code range at the current state and its Jacobian (base states and
        inter-system offsets; the caller adds slots)."""
        kf = self.kf
        pred, H5 = predict_given_troposphere(
            self.obs.sat_pos[e.rows], kf.x[_POS], kf.x[_CLK], kf.x[_ZWD], e.hydro, e.m_w
        )
        H = np.zeros((len(pred), self.layout.nx))
        H[:, :N_BASE_STATES] = H5
        H[e.isb_rows, e.isb_cols] = 1.0
        return pred, H

    def update_code(self, e: EpochRows) -> None:
        """Code update of every row of the epoch."""
        obs, lay, kf = self.obs, self.layout, self.kf
        pred, H = self._predicted_ranges(e)
        if lay.n_iono:
            # the slant ionosphere of a row without phase is not separable from its code
            H[np.flatnonzero(e.has_phase), lay.iono0 + e.slots[e.has_phase]] = 1.0
            pred = pred + np.where(e.has_phase, kf.x[lay.iono0 + e.slots], 0.0)
        pred[e.isb_rows] += kf.x[e.isb_cols]
        if self.white_clock or self.two_state:
            # a white clock keeps nothing from the last epoch: centre it on this epoch's code, so a
            # receiver that holds its clock within a millisecond by jumps (u-blox: 300-2100 km, a
            # thousand sigma of the clock's 2 km) leaks no metres into the position; a two-state
            # clock is restarted so only where the code says it jumped
            shift = float(np.median(obs.code[e.rows] - pred))
            few = len(pred) < self.cfg.clock_link_min_satellites
            if self.white_clock or few or abs(shift) > self.cfg.clock_jump_m:
                if self.two_state:
                    _reset(kf, np.array([_CLK]), kf.x[_CLK], self.cfg.clock_sigma_m**2)
                    self.n_clock_jumps += int(not few)
                kf.x[_CLK] += shift
                pred += shift
        kf.update(obs.code[e.rows], _const(H), _const(pred), R=np.diag(obs.sigma_code[e.rows] ** 2))

    def update_phase(self, e: EpochRows) -> None:
        """Phase update of the rows with phase, relinearised at the code-updated state."""
        if not (self.layout.n_slots and e.has_phase.any()):
            return
        obs, lay, kf = self.obs, self.layout, self.kf
        pred, H = self._predicted_ranges(e)
        every = np.arange(len(pred))
        H[every, N_BASE_STATES + e.slots] = 1.0
        pred = pred + kf.x[N_BASE_STATES + e.slots]
        if lay.n_iono:
            H[every, lay.iono0 + e.slots] = -1.0
            pred = pred - kf.x[lay.iono0 + e.slots]
        pred[e.isb_rows] += kf.x[e.isb_cols]
        # a new arc's bias starts at its phase minus the code-updated prediction, so its first
        # phase moves nothing (a diffuse prior, whatever the clock or the position did since
        # the last epoch); before the code update a 60-100 m clock change sat in the new bias
        new_bias = obs.phase[e.rows][e.fresh] - pred[e.fresh]
        kf.x[N_BASE_STATES + e.slots[e.fresh]] = new_bias
        pred[e.fresh] += new_bias
        use = e.has_phase
        kf.update(
            obs.phase[e.rows][use], _const(H[use]), _const(pred[use]), R=np.diag(obs.sigma_phase[e.rows][use] ** 2)
        )

    def update_doppler(self, rows: slice) -> None:
        """Range-rate update with the epoch's Doppler rows (constant velocity with Doppler only)."""
        if not self.doppler:
            return
        obs, lay, kf = self.obs, self.layout, self.kf
        assert obs.range_rate is not None and obs.sat_vel is not None  # self.doppler: both there
        rr = obs.range_rate[rows]
        use = np.isfinite(rr)
        if not use.any():
            return
        pos, vel = kf.x[_POS], kf.x[lay.vel0 : lay.drift]
        rdot, d_pos, d_vel = range_rate(obs.sat_pos[rows][use], obs.sat_vel[rows][use], pos, vel)
        H = np.zeros((int(use.sum()), kf.dim_x))
        H[:, _POS], H[:, lay.vel0 : lay.drift], H[:, lay.drift] = d_pos, d_vel, 1.0
        sigma = self.cfg.doppler_sigma_mps * obs.sigma_scale[rows][use]
        kf.update(rr[use], _const(H), _const(rdot + kf.x[lay.drift]), R=np.diag(sigma**2))
        self.n_doppler += int(use.sum())

    def update_odometry(self, sample: np.ndarray, with_doppler: bool) -> int:
        """Wheel-speed update of the velocity (one epoch's mean odometry ``sample``, the columns of
        :data:`~estimators.model.measurement.EPOCH_ODOMETRY`); the non-holonomic row only ``with_doppler`` (the
        epoch has range rates, which measure the direction it is taken along); returns 1 when an
        update was made."""
        kf, vel0 = self.kf, self.layout.vel0
        speed, _, var_speed, _, right, down, var_right, var_down = sample
        east, north, up = enu_basis(kf.x[_POS])
        vel = kf.x[vel0 : vel0 + 3]
        sig_s = float(np.sqrt(max(var_speed, MIN_ODOMETRY_VARIANCE)))
        # the reported vertical velocity, else none beyond the road grade (loosely at rest, see the config)
        vertical = self.cfg.vertical_velocity(speed, sig_s, down, var_down)
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
                    left = self.cfg.left_velocity(right, var_right)
                    rows = np.vstack([rows, np.cross(up, along)])
                    z, sigma = np.r_[z, left.value], np.r_[sigma, left.sigma]
        H = np.zeros((len(rows), kf.dim_x))
        H[:, vel0 : vel0 + 3] = rows
        kf.update(z, _const(H), _const(H @ kf.x), R=np.diag(sigma**2))
        return 1

    def guard(self, anchor_pos: np.ndarray, anchor_cov: np.ndarray) -> None:
        """The phase guard: where the position departs from the code filter's (``anchor_pos``,
        ``anchor_cov``) beyond :data:`GUARD_CHI2`, the phase holds a position the code refutes (an NLOS
        phase baked into the arcs' biases): fall back to the code filter and restart every arc."""
        kf = self.kf
        d = kf.x[_POS] - anchor_pos
        if float(d @ np.linalg.solve(anchor_cov, d)) > GUARD_CHI2:
            kf.x[_POS] = anchor_pos
            kf.P[_POS, :] = 0.0
            kf.P[:, _POS] = 0.0
            kf.P[_POS, _POS] = anchor_cov
            self.slot_arc[:] = -1
            self.n_fallbacks += 1

    def diagnostics(self) -> dict[str, Any]:
        """Counts and final state values of the pass (after its last epoch)."""
        cfg, obs, lay, kf = self.cfg, self.obs, self.layout, self.kf
        held = self.slot_arc >= 0
        self.arc_bias[self.slot_arc[held]] = kf.x[N_BASE_STATES + np.flatnonzero(held)]
        arc_sat = np.empty(obs.n_arcs, dtype=object)
        arc_sat[obs.arc[obs.has_phase]] = obs.sat[obs.has_phase]
        diagnostics = {
            "n_epochs": int(obs.n_epochs),
            "n_observations": int(obs.n_obs),
            "n_satellites": len(obs.sat_names),
            "n_arcs": int(obs.n_arcs),
            "n_ambiguity_resets": self.n_resets,
            "n_phase_fallbacks": self.n_fallbacks,
            "n_clock_jumps": self.n_clock_jumps,
            **obs.model_info(),
            **self.wet.info(),
            "iono_states": bool(lay.n_iono),
            "inter_system_bias_m": {s: float(kf.x[lay.isb0 + k]) for k, s in enumerate(obs.systems[1:])},
            "arc_sat": [str(v) for v in arc_sat] if lay.n_slots else [],
            "arc_bias_m": [float(v) for v in self.arc_bias] if lay.n_slots else [],
            "final_clock_m": float(kf.x[_CLK]),
            "final_zwd_m": float(kf.x[_ZWD]),
            "final_pos_sigma_m": [float(s) for s in np.sqrt(np.diag(kf.P)[_POS])],
            "motion_model": MotionModel(cfg.motion_model).value,
            "n_doppler_updates": self.n_doppler,
            "n_odometry_updates": self.n_odometry,
            "config": asdict(cfg),
        }
        if lay.cv:
            diagnostics["final_clock_drift_mps"] = float(kf.x[lay.drift])
        return diagnostics


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
