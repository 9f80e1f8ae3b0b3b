"""The shared PPP factor-graph model used by every GTSAM estimator (batch and incremental).

The model is the one of :mod:`estimators.model.measurement` (dissertation eqs. 4.1-4.4),
written with GTSAM's native C++ GNSS factors so that no Python callback sits in
the optimiser's hot path.

Variables and keys
------------------
All keys are :func:`gtsam.symbol` keys; ``k`` is the index of a *solved* epoch
(row ``k`` of ``obs.epoch_ids``), ``r`` an observation row of
:class:`~estimators.model.measurement.PppObservations`, ``a`` an arc id (``obs.arc``).

=================  ==========  ===============================================
key                type        meaning
=================  ==========  ===============================================
``pos_key(k)``     Point3      receiver ECEF position [m]
``clock_key(k)``   double      receiver clock offset **in seconds** (GTSAM's convention)
``zwd_key(k)``     double      zenith wet delay [m] (``wet_delay = estimate`` only; with
                               ``model`` the modelled wet delay leaves the measurements and
                               the factors' ZWD slot is ``ZERO_KEY``)
``iono_key(r)``    double      slant ionosphere residual of row ``r`` [m] (L1 with
                               ``estimate_iono`` only; code ``+I``, phase ``-I``)
``amb_key(a)``     double      float carrier-phase bias of arc ``a`` [m]; one key per
                               continuous arc, i.e. a "landmark" seen over the arc
``sysclock_key(s, k)`` double  receiver clock of further GNSS system ``s`` (1..) in seconds;
                               rows of system ``s`` use it in place of ``clock_key(k)``
``isb_key(s, k)``  double      inter-system bias of system ``s`` [m]: ``c sysclock - c clock``
``ZERO_KEY``       double      held at 0 by a tight prior; fills the ionosphere slot
                               of the native factors when no ionosphere is estimated
                               (ionosphere coefficient 0)
=================  ==========  ===============================================

Factors
-------
* code: ``gtsam.UndifferencedPseudorangeFactor`` -- ``rho = geodist + c dt + m_w ZWD + I``;
  ``geodist`` includes the Sagnac term (checked against
  :func:`simbench.gnss.geometry.sagnac_range` in the tests), so nothing is pre-applied for
  Earth rotation. The satellite clock is already in ``obs.code`` (``prepare_ppp``), so the
  factor's satellite clock argument is 0. The modelled slant hydrostatic delay
  (Saastamoinen + Niell at a per-epoch single point position), and with ``wet_delay = model``
  the modelled wet delay (:attr:`PppGraph.zwd0` times the Niell wet mapping), is subtracted from
  the measurement (:attr:`PppGraph.code_z`).
* phase: ``gtsam.UndifferencedCarrierPhaseFactor`` -- ``phi = geodist + c dt + m_w ZWD
  - I + lambda N`` (the factor flips the ionosphere sign itself) with ``lambda = 1`` and
  ``N`` the arc bias in metres (:attr:`PppGraph.phase_z`).
* motion: ``BetweenFactorPoint3`` (position random walk), ``BetweenFactorDouble``
  (ZWD random walk; clock random walk when ``clock_model = "random_walk"``; ionosphere
  random walk between consecutive rows of an arc). With ``clock_model = "white"``
  (Table 4.4.2, correlation time 0) each epoch's clock is free apart from a loose prior.
* measurement modes: a row without carrier phase (``obs.has_phase`` False: code-only
  logs, sparse phase, ``measurements = code``) has a code factor only, no arc and no
  ionosphere key (its slant ionosphere is not separable from its code).
* several GNSS systems: the rows of each further system ``s`` use their own clock key,
  tied to the first system's clock by an inter-system bias,
  ``c sysclock_s(k) - c clock(k) - isb_s(k) = 0`` (a linear factor, native
  ``JacobianFactor`` in a ``LinearContainerFactor``, sigma 1 mm), with a random walk
  (``isb_rw_m_rts``) between epochs and a loose prior (``isb_sigma_m``) at the first.
* priors: ``PriorFactorPoint3`` / ``PriorFactorDouble`` on the first position and ZWD,
  every clock (loose), each new arc's bias (``phase - code``, very loose) and each arc's
  first ionosphere residual.

Conditioning: the clock is in seconds and enters with Jacobian ``c`` (whitened
by a 2.5 cm phase sigma: 1.2e10 per second, against order 1-100 for everything
else). Multifrontal Cholesky of the normal equations (GTSAM's default) squares that
spread and fails (GTSAM reports an indeterminate system; LM then raises lambda for
100 iterations). Sequential Cholesky (one variable per elimination step) does not
fail: :func:`solve` (Levenberg-Marquardt) uses it, in the
clocks-first ordering of :meth:`PppGraph.elimination_ordering`. Against the multifrontal
QR that :func:`solve` used before, the L2 solve of the Hong Kong log took 3.0 s instead of
5.6 s (the same 3 iterations, positions within 3e-7 m).
**Incremental users: set** ``gtsam.ISAM2Params().setFactorization("QR")``.
Batch L2 agrees with the EKF at the last epoch to below a millimetre
(``tests/test_batch_estimators.py``).

Batch use
---------
>>> obs = prepare_ppp(data, **graph_cfg.prepare_kwargs())
>>> g = PppGraph(obs, graph_cfg)
>>> graph = g.structure_factors()               # priors + motion model, all epochs
>>> graph.push_back(g.measurement_factors())    # a-priori noise models, all rows
>>> values = solve(graph, g.initial_values())
>>> pos = g.positions(values)                   # (n_epochs, 3)
>>> r_code, r_phase = g.residuals(values)        # measured - predicted, per row [m]

Per-measurement noise models: :meth:`PppGraph.measurement_factors` takes per-row
sigmas, an optional code-phase covariance (exact 2x2 coupling with native factors,
see :meth:`~PppGraph.measurement_factors`), per-row offsets subtracted from the
measurements (cluster means) and an optional robust kernel. Rebuilding the
measurement factors (a few microseconds each) is as cheap as cloning them; for a
single factor ``factor.cloneWithNewNoiseModel(noise)`` also works.

Incremental use (iSAM2)
-----------------------
>>> for k in range(obs.n_epochs):
...     graph, values = g.epoch_factors(k, previous=isam.calculateEstimate() if k else None)
...     isam.update(graph, values)

:meth:`PppGraph.epoch_factors` returns epoch ``k``'s new factors (priors at the start,
motion from epoch ``k-1``, new-arc priors, measurement factors with the a-priori
noise or the given sigmas) and initial values for the keys that appear for the
first time at ``k`` (:meth:`PppGraph.new_values`). Pieces are also available
separately (:meth:`motion_factors`, :meth:`prior_factors`, :meth:`measurement_factors`
with ``rows=obs.epoch_slice(k)``) for estimators that gate or reweight measurements.
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import gtsam
import numpy as np

from estimators.model.clock import clock_links, offset_step_sigma, single_point_drift
from estimators.model.measurement import PppObservations, content_digest, zenith_wet_delay_m
from estimators.model.ppp_config import (
    DIRECTION_MIN_SPEED_MPS,
    MIN_ODOMETRY_VARIANCE,
    STANDSTILL_MPS,
    WET_DELAY_CLIMATOLOGY_SIGMA_M,
    WET_DELAY_GATE_SIGMAS,
    ClockModel,
    MotionModel,
    MotionModelConfig,
    PppGraphConfig,
    WetDelayMode,
)
from simbench.core.constants import C_LIGHT
from simbench.core.frames import geodetic_from_ecef
from simbench.errors import SimbenchError, warn
from simbench.gnss.doppler import doppler_velocities, range_rate
from simbench.gnss.geometry import enu_basis, sagnac_range
from simbench.gnss.spp import solve_epochs, system_clock_offsets
from simbench.gnss.troposphere import troposphere_terms

__all__ = [
    "ZERO_KEY",
    "PppGraph",
    "WetDelayChoice",
    "amb_key",
    "isb_key",
    "sysclock_key",
    "vel_key",
    "drift_key",
    "MotionModel",
    "clock_key",
    "conditional_split",
    "insert_double",
    "iono_key",
    "pos_key",
    "solve",
    "wet_delay_choice",
    "zwd_key",
]


# One gtsam key per variable: its letter and an index (a solved epoch ``k``, an observation row, a phase arc).
#: Position key of solved epoch ``k``.
pos_key = functools.partial(gtsam.symbol, "x")
#: Receiver clock key (seconds) of solved epoch ``k``.
clock_key = functools.partial(gtsam.symbol, "c")
#: Zenith wet delay key of solved epoch ``k``.
zwd_key = functools.partial(gtsam.symbol, "w")
#: Slant ionosphere residual key of observation row ``row``.
iono_key = functools.partial(gtsam.symbol, "i")
#: Carrier-phase bias key (metres) of phase arc ``arc``.
amb_key = functools.partial(gtsam.symbol, "b")
#: Velocity key (Point3, ECEF m/s) of solved epoch ``k`` (constant-velocity model only).
vel_key = functools.partial(gtsam.symbol, "v")
#: Receiver clock drift key (double, m/s) of solved epoch ``k`` (constant-velocity model only).
drift_key = functools.partial(gtsam.symbol, "f")


def sysclock_key(system: int, k: int) -> int:
    """Receiver clock key (seconds) of further GNSS system ``system`` (1..) at solved epoch ``k``."""
    return gtsam.symbol("s", (system << 32) | k)


def isb_key(system: int, k: int) -> int:
    """Inter-system bias key (metres) of further GNSS system ``system`` (1..) at solved epoch ``k``."""
    return gtsam.symbol("j", (system << 32) | k)


#: Key held at zero; the ionosphere slot of the native factors when no ionosphere is estimated.
ZERO_KEY = gtsam.symbol("z", 0)


@dataclass
class _NoiseModels:
    """One (robust) scalar noise model per distinct sigma: the rows of one cluster share their sigma."""

    def __init__(self, robust: gtsam.noiseModel.mEstimator.Base | None) -> None:
        self.robust = robust
        self.models: dict[float, gtsam.noiseModel.Base] = {}

    def __call__(self, sigma: float) -> gtsam.noiseModel.Base:
        """The model of standard deviation ``sigma`` [m]."""
        model = self.models.get(sigma)
        if model is None:
            base = gtsam.noiseModel.Isotropic.Sigma(1, sigma)
            robust = self.robust
            model = self.models[sigma] = base if robust is None else gtsam.noiseModel.Robust.Create(robust, base)
        return model


# The split pair's factor inputs are returned as plain Python lists: numpy scalar access per
# argument dominates the build time of the factor loop.


def _split_code(
    zc: np.ndarray, zp: np.ndarray, sc: np.ndarray, rho_c: np.ndarray, iono_c: np.ndarray
) -> tuple[list[float], list[float], list[float], list[float]]:
    """Measurement, sigma, ionosphere and bias coefficients of each row's code factor (the conditional
    ``(code - rho phase) / (1 - rho)`` where ``rho_c`` is not 0; :meth:`PppGraph.measurement_factors`)."""
    fac = 1.0 - rho_c
    meas = np.where(rho_c == 0.0, zc, (zc - rho_c * zp) / fac)
    iono = np.where(rho_c == 0.0, iono_c, -iono_c * (1.0 + rho_c) / fac)
    return meas.tolist(), (sc / np.abs(fac)).tolist(), iono.tolist(), (-rho_c / fac).tolist()


def _split_phase(
    zc: np.ndarray, zp: np.ndarray, sp: np.ndarray, rho_p: np.ndarray, iono_c: np.ndarray
) -> tuple[list[float], list[float], list[float], list[float]]:
    """Measurement, sigma, ionosphere and bias coefficients of each row's phase factor (the conditional
    ``(phase - rho' code) / (1 - rho')``; plain phase where ``rho_p`` is 0)."""
    fac = 1.0 - rho_p
    meas = (zp - rho_p * zc) / fac
    return meas.tolist(), (sp / np.abs(fac)).tolist(), (iono_c * (1.0 + rho_p) / fac).tolist(), (1.0 / fac).tolist()


#: Random-walk sigmas never go below this (two epochs with the same time) [m or s].
_MIN_RW_SIGMA = 1e-9
#: Sigma of the factor tying a further system's clock to the first clock plus its bias [m].
_ISB_TIE_SIGMA_M = 1e-3
#: Sigma of the prior holding ZERO_KEY at zero [m].
_ZERO_SIGMA = 1e-6


class PppGraph:
    """Factor and value factory for the PPP graph of one set of prepared observations.

    Parameters
    ----------
    obs : PppObservations
        From :func:`~estimators.model.measurement.prepare_ppp`.
    cfg : PppGraphConfig

    Attributes
    ----------
    code_z, phase_z : ndarray, shape (N,)
        Measurements handed to the factors [m]: ``obs.code`` / ``obs.phase`` minus the
        modelled slant hydrostatic delay, and with ``wet_delay = model`` the modelled wet one.
    wet_mapping : ndarray, shape (N,)
        Niell wet mapping per row.
    wet_delay : WetDelayChoice
        What ``cfg.wet_delay`` resolved to on these observations (:func:`wet_delay_choice`).
    zwd0 : float
        Zenith wet delay at the first single point fix [m]: the modelled one (``wet_delay`` resolved
        to ``model``) or the ZWD state's prior mean (``estimate``),
        :func:`~estimators.model.measurement.zenith_wet_delay_m`.
    estimate_zwd : bool
        Whether there are ZWD states (``zwd_key``); else the factors' ZWD slot is ``ZERO_KEY``.
    row_epoch : ndarray of int, shape (N,)
        Solved-epoch index ``k`` of each row.
    prev_row : ndarray of int, shape (N,)
        Previous row of the same arc, -1 at an arc's first row.
    arc_first_row : ndarray of int, shape (n_arcs,)
        First row of each arc.
    spp_pos : ndarray, shape (n_epochs, 3)
        Code-only single point position per epoch [m] (initial values, troposphere).
    spp_clock_m : ndarray, shape (n_epochs,)
        Single point receiver clock times c [m].
    clock_link : ndarray of bool, shape (n_epochs,)
        Whether epoch ``k``'s clock offset is predicted from ``k - 1``'s (``clock_model = two_state``:
        no jump between them and at least ``clock_link_min_satellites`` rows at ``k``; else all False).
    with_iono : bool
        Whether per-row ionosphere keys are estimated.
    """

    def __init__(self, obs: PppObservations, cfg: PppGraphConfig) -> None:
        self.obs = obs
        self.cfg = cfg
        self.constant_velocity = cfg.motion_model == MotionModel.constant_velocity
        self.with_iono = bool(cfg.estimate_iono and obs.broadcast_ionosphere)
        n, nk = obs.n_obs, obs.n_epochs
        self.row_epoch = np.repeat(np.arange(nk), obs.epoch_stop - obs.epoch_start)
        # epochs without a trusted fit (four satellites in a bad geometry, NLOS) start from the
        # nearest trusted epoch's position; the graph does the rest
        self.row_system = np.zeros(n, np.int64) if obs.system_index is None else np.asarray(obs.system_index, np.int64)
        spp = solve_epochs(
            self.row_epoch,
            obs.sat_pos,
            obs.code,
            n_epochs=nk,
            sigma=obs.sigma_code,
            el=obs.el,
            doy=obs.doy,
            system_index=self.row_system,
            fill_untrusted=True,
        )
        self.spp_pos, self.spp_clock_m = spp.pos, spp.clock_m[:, 0]
        self.with_odometry = bool(self.constant_velocity and cfg.use_odometry and obs.odometry is not None)
        if self.constant_velocity:
            assert obs.sat_vel is not None and obs.range_rate is not None  # prepare_ppp always sets them
            # one Doppler fix per epoch: the drift's start values and the odometry's direction of travel
            doppler_vel, drift = doppler_velocities(
                self.row_epoch,
                obs.sat_pos,
                obs.sat_vel,
                self.spp_pos[self.row_epoch],
                obs.range_rate,
                cfg.doppler_sigma_mps * obs.sigma_scale,
                nk,
            )
            self.drift0 = _carry_forward(drift)
            if not np.isfinite(drift).any():  # no Doppler (a libRSF log): the single point clocks' rate
                self.drift0[:] = single_point_drift(obs.epoch_t, self.spp_clock_m, cfg.clock_jump_m)
            if self.with_odometry:
                self.enu = enu_basis(self.spp_pos)
                self.heading_ref = self._directions_of_travel(doppler_vel)
        # where the clock offset is predicted from the last epoch's (two_state only)
        self.clock_link = np.zeros(nk, bool)
        if cfg.clock_model == ClockModel.two_state:
            self.clock_link = clock_links(obs.epoch_t, self.spp_clock_m, self.drift0, cfg.clock_jump_m)
            self.clock_link &= obs.epoch_stop - obs.epoch_start >= cfg.clock_link_min_satellites
        self.isb0_m = system_clock_offsets(spp, self.row_epoch, self.row_system)
        lat, _, h = geodetic_from_ecef(self.spp_pos)
        hydro, self.wet_mapping = troposphere_terms(obs.el, lat[self.row_epoch], h[self.row_epoch], obs.doy)
        lat0, _, h0 = geodetic_from_ecef(self.spp_pos[0])
        self.wet_delay = wet_delay_choice(obs, cfg)
        self.zwd0 = zenith_wet_delay_m(self.wet_delay.mode, float(lat0), float(h0), obs.doy)
        #: a zenith wet delay state per epoch (``wet_delay = estimate``); else the modelled one is applied
        self.estimate_zwd = self.wet_delay.mode == WetDelayMode.estimate
        modelled = hydro if self.estimate_zwd else hydro + self.zwd0 * self.wet_mapping
        self.code_z = obs.code - modelled
        self.phase_z = obs.phase - modelled
        self.has_phase = obs.has_phase
        prev = obs.previous_rows()
        self.prev_row = prev
        #: rows that start an arc (need a bias prior and value)
        self.arc_start = self.has_phase & (prev < 0)
        first = np.full(obs.n_arcs, -1, np.int64)
        starts = np.flatnonzero(self.arc_start)
        first[obs.arc[starts]] = starts
        self.arc_first_row = first
        #: rows with an ionosphere key: phase rows when the slant ionosphere is estimated
        self.iono_rows = self.has_phase & self.with_iono
        self._unit = gtsam.noiseModel.Unit.Create(1)
        self._row_keys = self._measurement_keys()

    def _measurement_keys(self) -> tuple[list[int], list[int], list[int], list[int], list[int]]:
        """Position, clock, ZWD, ionosphere and arc-bias key of every row's measurement factors.

        Built once: the batch estimators rebuild every measurement factor on each
        re-weighting iteration, and making these keys was a third of that.
        """
        obs = self.obs
        epochs = self.row_epoch.tolist()
        pos = [pos_key(k) for k in epochs]
        clock = [clock_key(k) if s == 0 else sysclock_key(s, k) for k, s in zip(epochs, self.row_system.tolist())]
        zwd = [zwd_key(k) for k in epochs] if self.estimate_zwd else [ZERO_KEY] * len(epochs)
        iono = [iono_key(r) if w else ZERO_KEY for r, w in enumerate(self.iono_rows.tolist())]
        bias = [amb_key(a) if a >= 0 else ZERO_KEY for a in obs.arc.tolist()]  # code-only rows have no arc
        return pos, clock, zwd, iono, bias

    # ------------------------------------------------------------------ noise helpers

    @staticmethod
    def _sigma1(s: float) -> gtsam.noiseModel.Base:
        return gtsam.noiseModel.Isotropic.Sigma(1, float(s))

    def _rw(self, density: float, dt: float) -> float:
        return max(density * np.sqrt(max(dt, 0.0)), _MIN_RW_SIGMA)

    # ------------------------------------------------------------------ structural factors

    def prior_factors(self, k: int) -> gtsam.NonlinearFactorGraph:
        """Priors introduced at epoch ``k``: start priors (k = 0), clock, new arcs, first iono of new arcs;
        with the constant-velocity model also the epoch's Doppler factor."""
        cfg, obs = self.cfg, self.obs
        g = gtsam.NonlinearFactorGraph()
        if k == 0:
            g.add(
                gtsam.PriorFactorPoint3(
                    pos_key(0), gtsam.Point3(*self.spp_pos[0]), gtsam.noiseModel.Isotropic.Sigma(3, cfg.pos_sigma_m)
                )
            )
            if self.constant_velocity:
                g.add(
                    gtsam.PriorFactorPoint3(
                        vel_key(0), gtsam.Point3(0.0, 0.0, 0.0), gtsam.noiseModel.Isotropic.Sigma(3, cfg.vel_sigma_mps)
                    )
                )
                g.add(gtsam.PriorFactorDouble(drift_key(0), float(self.drift0[0]), self._sigma1(cfg.drift_sigma_mps)))
            if self.estimate_zwd:
                g.add(gtsam.PriorFactorDouble(zwd_key(0), self.zwd0, self._sigma1(cfg.zwd_sigma_m)))
            g.add(gtsam.PriorFactorDouble(ZERO_KEY, 0.0, self._sigma1(_ZERO_SIGMA)))
        if self.constant_velocity:  # the epoch's range rates (a measurement, but not reweighted)
            g.push_back(self._doppler_factor(k))
        if k == 0 or (cfg.clock_model != ClockModel.random_walk and not self.clock_link[k]):
            g.add(
                gtsam.PriorFactorDouble(
                    clock_key(k), self.spp_clock_m[k] / C_LIGHT, self._sigma1(cfg.clock_sigma_m / C_LIGHT)
                )
            )
        for s in range(1, obs.n_isb + 1):
            if k == 0:
                g.add(gtsam.PriorFactorDouble(isb_key(s, 0), float(self.isb0_m[s - 1]), self._sigma1(cfg.isb_sigma_m)))
            g.add(self._isb_tie(s, k))
        rows = obs.epoch_slice(k)
        amb_noise = self._sigma1(cfg.ambiguity_sigma_m)
        iono_noise = self._sigma1(cfg.iono_sigma_m)
        for r in np.flatnonzero(self.arc_start[rows]) + rows.start:
            g.add(gtsam.PriorFactorDouble(amb_key(int(obs.arc[r])), self._amb0(r), amb_noise))
            if self.with_iono:
                g.add(gtsam.PriorFactorDouble(iono_key(int(r)), 0.0, iono_noise))
        return g

    def _isb_tie(self, s: int, k: int) -> gtsam.NonlinearFactor:
        """``c sysclock_s(k) - c clock(k) - isb_s(k) = 0``: a linear factor in GTSAM's native containers."""
        keys = (sysclock_key(s, k), clock_key(k), isb_key(s, k))
        linear = gtsam.JacobianFactor(
            keys[0],
            np.array([[C_LIGHT]]),
            keys[1],
            np.array([[-C_LIGHT]]),
            keys[2],
            np.array([[-1.0]]),
            np.zeros(1),
            gtsam.noiseModel.Isotropic.Sigma(1, _ISB_TIE_SIGMA_M),
        )
        return _linear(linear, dict.fromkeys(keys, 0.0))

    def motion_factors(self, k: int) -> gtsam.NonlinearFactorGraph:
        """Random-walk factors linking epoch ``k`` to ``k - 1`` (empty for k = 0)."""
        g = gtsam.NonlinearFactorGraph()
        if k == 0:
            return g
        cfg, obs = self.cfg, self.obs
        dt = float(obs.epoch_t[k] - obs.epoch_t[k - 1])
        if self.constant_velocity:
            g.push_back(self._constant_velocity_factors(k, dt))
        else:
            g.add(
                gtsam.BetweenFactorPoint3(
                    pos_key(k - 1),
                    pos_key(k),
                    gtsam.Point3(0, 0, 0),
                    gtsam.noiseModel.Isotropic.Sigma(3, self._rw(cfg.pos_rw_m_rts, dt)),
                )
            )
        if self.estimate_zwd:
            g.add(
                gtsam.BetweenFactorDouble(zwd_key(k - 1), zwd_key(k), 0.0, self._sigma1(self._rw(cfg.zwd_rw_m_rts, dt)))
            )
        if cfg.clock_model == ClockModel.random_walk:
            g.add(
                gtsam.BetweenFactorDouble(
                    clock_key(k - 1), clock_key(k), 0.0, self._sigma1(self._rw(cfg.clock_noise_m_rts, dt) / C_LIGHT)
                )
            )
        elif self.clock_link[k]:
            g.add(self._oscillator_factor(k, dt))
        for s in range(1, obs.n_isb + 1):
            g.add(
                gtsam.BetweenFactorDouble(
                    isb_key(s, k - 1), isb_key(s, k), 0.0, self._sigma1(self._rw(cfg.isb_rw_m_rts, dt))
                )
            )
        if self.with_iono:
            rows = obs.epoch_slice(k)
            for r in np.flatnonzero(self.prev_row[rows] >= 0) + rows.start:
                p = int(self.prev_row[r])
                dti = float(obs.t[r] - obs.t[p])
                g.add(
                    gtsam.BetweenFactorDouble(
                        iono_key(p), iono_key(int(r)), 0.0, self._sigma1(self._rw(cfg.iono_rw_m_rts, dti))
                    )
                )
        return g

    def _oscillator_factor(self, k: int, dt: float) -> gtsam.NonlinearFactor:
        """``c clock(k) - c clock(k - 1) - drift(k - 1) dt ~ N(0, sigma^2)``, the two-state clock's offset
        step (:func:`~estimators.model.clock.offset_step_sigma`); a linear factor on three keys."""
        cfg = self.cfg
        keys = (clock_key(k - 1), drift_key(k - 1), clock_key(k))
        sigma = max(offset_step_sigma(dt, cfg.oscillator_noise_m_rts, cfg.drift_rw_mps_rts), _MIN_RW_SIGMA)
        step = gtsam.JacobianFactor(
            keys[0],
            np.array([[-C_LIGHT]]),
            keys[1],
            np.array([[-dt]]),
            keys[2],
            np.array([[C_LIGHT]]),
            np.zeros(1),
            gtsam.noiseModel.Isotropic.Sigma(1, sigma),
        )
        return _linear(step, dict.fromkeys(keys, 0.0))

    def _constant_velocity_factors(self, k: int, dt: float) -> gtsam.NonlinearFactorGraph:
        """White-acceleration motion and clock-drift random walk from ``k - 1`` to ``k``.

        ``p_k - p_{k-1} - v_{k-1} dt ~ N(0, q dt^3/3)`` (a linear factor on three keys,
        native ``JacobianFactor`` in a ``LinearContainerFactor``) and ``v_k - v_{k-1} ~
        N(0, q dt)``; the cross-covariance of the exact discretisation is dropped.
        """
        cfg = self.cfg
        g = gtsam.NonlinearFactorGraph()
        q = cfg.accel_sigma_mps2_rts
        eye = np.eye(3)
        keys = (pos_key(k - 1), vel_key(k - 1), pos_key(k))
        tie = gtsam.JacobianFactor(
            keys[0],
            -eye,
            keys[1],
            -dt * eye,
            keys[2],
            eye,
            np.zeros(3),
            gtsam.noiseModel.Isotropic.Sigma(3, max(q * np.sqrt(dt**3 / 3.0), _MIN_RW_SIGMA)),
        )
        g.add(_linear(tie, {key: gtsam.Point3(0.0, 0.0, 0.0) for key in keys}))
        g.add(
            gtsam.BetweenFactorPoint3(
                vel_key(k - 1), vel_key(k), gtsam.Point3(0, 0, 0), gtsam.noiseModel.Isotropic.Sigma(3, self._rw(q, dt))
            )
        )
        g.add(
            gtsam.BetweenFactorDouble(
                drift_key(k - 1), drift_key(k), 0.0, self._sigma1(self._rw(cfg.drift_rw_mps_rts, dt))
            )
        )
        if self.with_odometry:
            g.push_back(self._odometry_factors(k, dt))
        return g

    def _odometry_factors(self, k: int, dt: float) -> gtsam.NonlinearFactorGraph:
        """Wheel speed, non-holonomic and yaw-rate constraints on the velocities of ``k - 1`` and ``k``.

        With ``H`` the local east/north projection and ``s``, ``omega`` the mean speed and
        yaw rate since the previous epoch (all linear in the velocity keys):

        * standstill (``|s| < 0.2 m/s``): ``H v_k = 0`` and, loosely, no vertical velocity
          (``standstill_vertical_sigma_mps``);
        * moving: ``up . v_k = 0`` at ``road_grade_sigma |s|`` (a car follows the road), and with a
          direction ``u`` from the epoch's Doppler velocity fix also ``u . v_k = |s|`` and
          ``(up x u) . v_k = 0`` (no sideways motion, ``nhc_sigma_mps``);
        * turning: ``H v_k = (s_k / s_{k-1}) R(omega dt) H v_{k-1}`` (heading clockwise from
          north advances by ``omega dt``; the speed ratio carries the along-track change).
        """
        g = gtsam.NonlinearFactorGraph()
        odo = self.obs.odometry
        assert odo is not None  # built with_odometry only
        speed, yaw_rate, var_speed, var_yaw, right, down, var_right, var_down = odo[k]
        if not np.isfinite(speed):
            return g
        horizontal = self.enu[k, :2]
        sig_s = float(np.sqrt(max(var_speed, MIN_ODOMETRY_VARIANCE)))
        vertical = self.cfg.vertical_velocity(speed, sig_s, down, var_down)
        zero = gtsam.Point3(0.0, 0.0, 0.0)
        if abs(speed) < STANDSTILL_MPS:
            sigmas = np.array([sig_s, sig_s, vertical.sigma])
            g.add(
                _linear(
                    gtsam.JacobianFactor(
                        vel_key(k),
                        self.enu[k],
                        np.array([0.0, 0.0, vertical.value]),
                        gtsam.noiseModel.Diagonal.Sigmas(sigmas),
                    ),
                    {vel_key(k): zero},
                )
            )
        else:
            up = self.enu[k, 2]
            rows, z = up[None, :], np.array([vertical.value])
            sigmas = np.array([vertical.sigma])
            if np.isfinite(self.heading_ref[k]).all():
                u = self.heading_ref[k]
                left = self.cfg.left_velocity(right, var_right)
                rows = np.vstack([rows, u, np.cross(up, u)])
                z = np.array([vertical.value, abs(speed), left.value])
                sigmas = np.r_[sigmas, sig_s, left.sigma]
            g.add(
                _linear(
                    gtsam.JacobianFactor(vel_key(k), rows, z, gtsam.noiseModel.Diagonal.Sigmas(sigmas)),
                    {vel_key(k): zero},
                )
            )
        prev_speed = odo[k - 1, 0]
        if np.isfinite(yaw_rate) and np.isfinite(prev_speed) and abs(prev_speed) >= STANDSTILL_MPS and dt > 0:
            turn = yaw_rate * dt
            rot = np.array([[np.cos(turn), np.sin(turn)], [-np.sin(turn), np.cos(turn)]])
            ratio = speed / prev_speed
            sigma = float(np.sqrt(2.0 * var_speed + (speed * dt) ** 2 * max(var_yaw, 0.0)) + 1e-3)
            g.add(
                _linear(
                    gtsam.JacobianFactor(
                        vel_key(k - 1),
                        -ratio * rot @ self.enu[k - 1, :2],
                        vel_key(k),
                        horizontal,
                        np.zeros(2),
                        gtsam.noiseModel.Isotropic.Sigma(2, sigma),
                    ),
                    {vel_key(k - 1): zero, vel_key(k): zero},
                )
            )
        return g

    def _directions_of_travel(self, vel: np.ndarray) -> np.ndarray:
        """Unit ECEF direction of each epoch's horizontal Doppler velocity ``vel`` (n_epochs, 3); NaN
        when slower than ``DIRECTION_MIN_SPEED_MPS`` or without a fix."""
        east = np.einsum("ki,ki->k", self.enu[:, 0], vel)
        north = np.einsum("ki,ki->k", self.enu[:, 1], vel)
        speed = np.hypot(east, north)
        fast = speed >= DIRECTION_MIN_SPEED_MPS  # False for NaN
        out = np.full((self.obs.n_epochs, 3), np.nan)
        out[fast] = (east[fast, None] * self.enu[fast, 0] + north[fast, None] * self.enu[fast, 1]) / speed[fast, None]
        return out

    def _doppler_factor(self, k: int) -> gtsam.NonlinearFactorGraph:
        """The range-rate rows of epoch ``k`` as one linear factor on its velocity and clock drift.

        ``rr = rdot(p, v) + drift`` is linear in ``v`` for a fixed line of sight; the line of
        sight is taken at the single-point position (tens of metres move it by ~1e-5 rad)
        with the Earth's rotation during transit (:func:`simbench.gnss.doppler.range_rate`).
        """
        g = gtsam.NonlinearFactorGraph()
        obs = self.obs
        rows = obs.epoch_slice(k)
        assert obs.range_rate is not None and obs.sat_vel is not None  # prepare_ppp always sets them
        rr = obs.range_rate[rows]
        use = np.flatnonzero(np.isfinite(rr)) + rows.start
        if use.size == 0:
            return g
        pos = np.broadcast_to(self.spp_pos[k], (use.size, 3))
        rdot0, _, d_vel = range_rate(obs.sat_pos[use], obs.sat_vel[use], pos, np.zeros((use.size, 3)))
        sigma = self.cfg.doppler_sigma_mps * obs.sigma_scale[use]
        linear = gtsam.JacobianFactor(
            vel_key(k),
            d_vel,
            drift_key(k),
            np.ones((use.size, 1)),
            obs.range_rate[use] - rdot0,
            gtsam.noiseModel.Diagonal.Sigmas(sigma),
        )
        g.add(_linear(linear, {vel_key(k): gtsam.Point3(0.0, 0.0, 0.0), drift_key(k): 0.0}))
        return g

    def structure_factors(self) -> gtsam.NonlinearFactorGraph:
        """All priors and motion factors of all epochs (the batch graph without measurements)."""
        g = gtsam.NonlinearFactorGraph()
        for k in range(self.obs.n_epochs):
            g.push_back(self.prior_factors(k))
            g.push_back(self.motion_factors(k))
        return g

    # ------------------------------------------------------------------ measurement factors

    def measurement_factors(
        self,
        rows: slice | np.ndarray | None = None,
        *,
        code_sigma: np.ndarray | None = None,
        phase_sigma: np.ndarray | None = None,
        code_phase_cov: np.ndarray | None = None,
        code_offset: np.ndarray | None = None,
        phase_offset: np.ndarray | None = None,
        robust: gtsam.noiseModel.mEstimator.Base | None = None,
        use_code: np.ndarray | None = None,
        use_phase: np.ndarray | None = None,
    ) -> gtsam.NonlinearFactorGraph:
        """Code and phase factors of the selected rows.

        Parameters
        ----------
        rows : slice or int array, optional
            Observation rows (default all); per-row arguments below are aligned with the
            *selected* rows.
        code_sigma, phase_sigma : ndarray, optional
            Standard deviations [m]; default the a-priori ``obs.sigma_code`` / ``obs.sigma_phase``.
        code_phase_cov : ndarray, optional
            Code-phase covariance [m^2] of each row's residual pair. The pair is then
            factored exactly into a marginal and a conditional, both native factors: with
            the smaller of ``rho = cov / var_phase`` and ``rho' = cov / var_code`` in
            magnitude, either ``phase ~ N(., var_p)`` and
            ``(code - rho phase) / (1 - rho) ~ N(., (var_c - cov^2/var_p) / (1 - rho)^2)``
            (an ``UndifferencedCarrierPhaseFactor`` with ionosphere coefficient
            ``-(1 + rho)/(1 - rho)`` and bias multiplier ``-rho/(1 - rho)``), or the same
            with code and phase swapped. Where ``|1 - rho| < 0.1`` (code and phase errors
            nearly equal, e.g. an NLOS delay on both) the native factors cannot express the
            pair (the geometry coefficient ``1 - rho`` vanishes); ``rho`` is then clipped to
            ``1 -/+ 0.1``, shrinking the covariance towards zero for those rows.
        code_offset, phase_offset : ndarray, optional
            Subtracted from the measurements [m] (a cluster's residual mean).
        robust : gtsam mEstimator, optional
            Wraps every measurement noise model (e.g. ``mEstimator.DCS.Create(2.5)``).
        use_code, use_phase : bool ndarray, optional
            Rows whose code / phase factor is added (default all), e.g. to exclude outliers.

        Returns
        -------
        gtsam.NonlinearFactorGraph
            Code factors first (selected rows, in order), then phase factors.
        """
        obs = self.obs
        idx = np.arange(obs.n_obs)[rows if rows is not None else slice(None)]
        m = len(idx)
        sc = obs.sigma_code[idx] if code_sigma is None else np.broadcast_to(np.asarray(code_sigma, float), (m,))
        sp = obs.sigma_phase[idx] if phase_sigma is None else np.broadcast_to(np.asarray(phase_sigma, float), (m,))
        zc = self.code_z[idx] - (0.0 if code_offset is None else np.asarray(code_offset, float))
        zp = self.phase_z[idx] - (0.0 if phase_offset is None else np.asarray(phase_offset, float))
        ones = np.ones(m, bool)
        uc = ones if use_code is None else np.asarray(use_code, bool)
        up = ones if use_phase is None else np.asarray(use_phase, bool)
        up = up & self.has_phase[idx]  # a row without carrier phase has a code factor only
        if np.any(~(sc[uc] > 0)) or np.any(~(sp[up] > 0)):
            raise SimbenchError(
                "measurement sigma", "non-positive or NaN standard deviation", "give positive per-row sigmas"
            )
        iono_c = self.iono_rows[idx].astype(float)
        selected = idx.tolist()
        pk, ck, wk, ikeys, bk = ([keys[r] for r in selected] for keys in self._row_keys)
        sat = obs.sat_pos[idx]
        mw = self.wet_mapping[idx].tolist()

        sc, rho_c, sp, rho_p = conditional_split(sc, sp, code_phase_cov, uc & up)

        noise = _NoiseModels(robust)
        code_meas, code_sig, code_iono, code_bias = _split_code(zc, zp, sc, rho_c, iono_c)
        phase_meas, phase_sig, phase_iono, phase_bias = _split_phase(zc, zp, sp, rho_p, iono_c)
        iono_c = iono_c.tolist()
        coupled = (rho_c != 0.0).tolist()
        g = gtsam.NonlinearFactorGraph()

        def carrier(j: int, meas: list[float], iono: list[float], bias: list[float], sig: list[float]) -> Any:
            keys = (pk[j], ck[j], wk[j], ikeys[j], bk[j])
            return gtsam.UndifferencedCarrierPhaseFactor(
                *keys, meas[j], sat[j], mw[j], iono[j], bias[j], 0.0, noise(sig[j])
            )

        for j in np.flatnonzero(uc).tolist():
            if coupled[j]:  # the conditional code factor has the phase's bias term
                g.add(carrier(j, code_meas, code_iono, code_bias, code_sig))
            else:
                g.add(
                    gtsam.UndifferencedPseudorangeFactor(
                        pk[j], ck[j], wk[j], ikeys[j], code_meas[j], sat[j], mw[j], iono_c[j], 0.0, noise(code_sig[j])
                    )
                )
        for j in np.flatnonzero(up).tolist():
            g.add(carrier(j, phase_meas, phase_iono, phase_bias, phase_sig))
        return g

    # ------------------------------------------------------------------ values

    def _amb0(self, row: int) -> float:
        return float(self.phase_z[row] - self.code_z[row])

    def new_values(self, k: int, previous: gtsam.Values | None = None) -> gtsam.Values:
        """Initial values of the keys first appearing at epoch ``k``.

        Position and clock come from the epoch's single point solution, unless
        ``previous`` holds epoch ``k - 1``: then its position and ZWD are carried over
        (the clock still comes from the single point solution: it is white noise).
        """
        obs = self.obs
        v = gtsam.Values()
        pos = self.spp_pos[k]
        zwd = self.zwd0
        if previous is not None and k > 0 and previous.exists(pos_key(k - 1)):
            pos = previous.atPoint3(pos_key(k - 1))
            if self.estimate_zwd:
                zwd = previous.atDouble(zwd_key(k - 1))
        v.insert(pos_key(k), gtsam.Point3(*np.asarray(pos, float)))
        insert_double(v, clock_key(k), self.spp_clock_m[k] / C_LIGHT)
        if self.estimate_zwd:
            insert_double(v, zwd_key(k), zwd)
        if self.constant_velocity:
            vel = np.zeros(3)
            if previous is not None and k > 0 and previous.exists(vel_key(k - 1)):
                vel = previous.atPoint3(vel_key(k - 1))
            v.insert(vel_key(k), gtsam.Point3(*np.asarray(vel, float)))
            insert_double(v, drift_key(k), self.drift0[k])
        for s in range(1, obs.n_isb + 1):
            isb = self.isb0_m[s - 1]
            if previous is not None and k > 0 and previous.exists(isb_key(s, k - 1)):
                isb = previous.atDouble(isb_key(s, k - 1))
            insert_double(v, isb_key(s, k), isb)
            insert_double(v, sysclock_key(s, k), (self.spp_clock_m[k] + isb) / C_LIGHT)
        if k == 0:
            insert_double(v, ZERO_KEY, 0.0)
        rows = obs.epoch_slice(k)
        for r in range(rows.start, rows.stop):
            p = int(self.prev_row[r])
            if self.arc_start[r]:
                insert_double(v, amb_key(int(obs.arc[r])), self._amb0(r))
            if self.iono_rows[r]:
                iono = (
                    previous.atDouble(iono_key(p))
                    if (previous is not None and p >= 0 and previous.exists(iono_key(p)))
                    else 0.0
                )
                insert_double(v, iono_key(r), iono)
        return v

    def initial_values(self) -> gtsam.Values:
        """Initial values of every key (batch)."""
        v = gtsam.Values()
        for k in range(self.obs.n_epochs):
            v.insert(self.new_values(k))
        return v

    def epoch_factors(
        self, k: int, previous: gtsam.Values | None = None, **measurement_kwargs: Any
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        """New factors and new values of epoch ``k`` for an incremental solver.

        ``measurement_kwargs`` go to :meth:`measurement_factors` (aligned with the epoch's rows).
        """
        g = self.prior_factors(k)
        g.push_back(self.motion_factors(k))
        g.push_back(self.measurement_factors(self.obs.epoch_slice(k), **measurement_kwargs))
        return g, self.new_values(k, previous)

    def elimination_ordering(self, graph: gtsam.NonlinearFactorGraph) -> gtsam.Ordering:
        """COLAMD ordering of ``graph`` with every receiver clock that no clock factor chains eliminated first.

        Computing it costs about a tenth of a linear solve; iterative batch estimators
        compute it once (the structure does not change between their solves). With the
        clocks first, sequential Cholesky (:func:`solve`) eliminates their
        ``c``-sized columns before anything else and was slightly faster than plain COLAMD.
        """
        nk = self.obs.n_epochs
        # a two-state clock chains the epochs: eliminating a chained clock first would join every
        # earlier epoch's states into one dense factor, so only the clocks that stand alone go first
        alone = ~(self.clock_link | np.r_[self.clock_link[1:], False])
        clocks = gtsam.KeyVector(
            [clock_key(k) for k in np.flatnonzero(alone)]
            + [sysclock_key(s, k) for s in range(1, self.obs.n_isb + 1) for k in range(nk)]
        )
        return gtsam.Ordering.ColamdConstrainedFirstNonlinearFactorGraph(graph, clocks)

    # ------------------------------------------------------------------ read-out

    def positions(self, values: gtsam.Values) -> np.ndarray:
        """Estimated position of every solved epoch, shape (n_epochs, 3) [m]."""
        return np.array([values.atPoint3(pos_key(k)) for k in range(self.obs.n_epochs)])

    def wet_delays(self, values: gtsam.Values) -> np.ndarray:
        """Estimated zenith wet delay of every solved epoch beyond what the measurements had removed [m]:
        the ZWD states (``wet_delay = estimate``), else zeros (the modelled delay left the measurements)."""
        if not self.estimate_zwd:
            return np.zeros(self.obs.n_epochs)
        return np.array([values.atDouble(zwd_key(k)) for k in range(self.obs.n_epochs)])

    def inter_system_biases(self, values: gtsam.Values) -> dict[str, list[float]]:
        """Estimated inter-system bias of each further system at every epoch [m].

        Keyed by system letter (``obs.systems[1:]``); empty for single-system data.
        """
        return {
            name: [values.atDouble(isb_key(s, k)) for k in range(self.obs.n_epochs)]
            for s, name in enumerate(self.obs.systems[1:], start=1)
        }

    def residuals(self, values: gtsam.Values) -> tuple[np.ndarray, np.ndarray]:
        """Code and phase residuals ``measured - predicted`` per row [m] (a-priori measurements).

        Uses the same model as the factors (Sagnac range, wet mapping, ionosphere and
        arc bias), evaluated with numpy on all rows at once.
        """
        obs = self.obs
        nk = obs.n_epochs
        pos = self.positions(values)
        clock = np.array([values.atDouble(clock_key(k)) for k in range(nk)]) * C_LIGHT
        zwd = self.wet_delays(values)
        amb = np.array([values.atDouble(amb_key(a)) for a in range(obs.n_arcs)])
        iono = np.zeros(obs.n_obs)
        iono_keys = self._row_keys[3]
        for r in np.flatnonzero(self.iono_rows).tolist():
            iono[r] = values.atDouble(iono_keys[r])
        e = self.row_epoch
        clocks = np.column_stack(
            [clock]
            + [clock + np.array([values.atDouble(isb_key(s, k)) for k in range(nk)]) for s in range(1, obs.n_isb + 1)]
        )
        geo = sagnac_range(obs.sat_pos, pos[e]) + clocks[e, self.row_system] + zwd[e] * self.wet_mapping
        bias = np.where(self.has_phase, amb[np.maximum(obs.arc, 0)] if amb.size else 0.0, np.nan)
        return self.code_z - (geo + iono), self.phase_z - (geo - iono + bias)


@dataclass(frozen=True)
class WetDelayChoice:
    """What a ``wet_delay`` setting resolved to on one set of prepared observations."""

    mode: WetDelayMode  #: ``model`` or ``estimate``
    #: median ZWD of the batch L2 solve with the state that decided ``auto`` [m] (NaN otherwise)
    estimate_m: float = float("nan")
    #: the MOPS climatology's zenith wet delay at the first fix [m] (NaN unless ``auto``)
    climatology_m: float = float("nan")

    def info(self) -> dict[str, Any]:
        """For an estimator's diagnostics (JSON values)."""
        out: dict[str, Any] = {"wet_delay": self.mode.value}
        if np.isfinite(self.estimate_m):
            out["wet_delay_estimate_m"] = round(self.estimate_m, 3)
            out["wet_delay_climatology_m"] = round(self.climatology_m, 3)
        return out


def wet_delay_choice(obs: PppObservations, cfg: MotionModelConfig) -> WetDelayChoice:
    """Resolve ``cfg.wet_delay`` on ``obs``: ``model`` and ``estimate`` as they are; ``auto`` by the log itself.

    ``auto`` solves the batch L2 graph with the ZWD state (Levenberg-Marquardt, the a-priori noise
    model) and keeps the state (``estimate``) when the median of its estimate lies within
    ``WET_DELAY_GATE_SIGMAS`` x ``WET_DELAY_CLIMATOLOGY_SIGMA_M`` (0.36 m) of the MOPS climatology's
    wet delay at the first fix; else the state took up an elevation-dependent error, not the
    atmosphere, and the wet delay is modelled (``model``), with a one-line warning. The decision of
    one set of observations and model is cached, so every estimator of a job that shares them
    solves once, and the warning is said once (not once per estimator: 11 lines in the smoke sweep).

    Parameters
    ----------
    obs : PppObservations
    cfg : MotionModelConfig
        The estimator's model (its :class:`~estimators.model.ppp_config.MotionModelConfig` fields are used).

    Returns
    -------
    WetDelayChoice
    """
    requested = WetDelayMode(cfg.wet_delay)
    if requested != WetDelayMode.auto:
        return WetDelayChoice(requested)
    model = PppGraphConfig(**{f.name: getattr(cfg, f.name) for f in fields(MotionModelConfig)})
    model = replace(model, wet_delay=WetDelayMode.estimate)
    key = content_digest(
        obs.epoch, obs.sat_pos, obs.code, obs.phase, obs.sigma_code, obs.sigma_phase, obs.arc, obs.el
    ) + repr(sorted(asdict(model).items()))
    if key in _WET_DELAY_CACHE:  # decided, and said, for an earlier estimator of the job
        return _WET_DELAY_CACHE[key]
    if len(_WET_DELAY_CACHE) >= _WET_DELAY_CACHE_SIZE:
        del _WET_DELAY_CACHE[next(iter(_WET_DELAY_CACHE))]
    choice = _WET_DELAY_CACHE[key] = _decide_wet_delay(obs, model)
    if choice.mode == WetDelayMode.model:
        bound = WET_DELAY_GATE_SIGMAS * WET_DELAY_CLIMATOLOGY_SIGMA_M
        warn(
            "gnss_model.wet_delay",
            f"auto: the log's zenith wet delay estimate {choice.estimate_m:+.2f} m is "
            f"{abs(choice.estimate_m - choice.climatology_m):.2f} m from the MOPS climatology's "
            f"{choice.climatology_m:.2f} m (beyond {bound:.2f} m): the state took up an elevation-dependent "
            "error, not the atmosphere",
            "the wet delay is modelled (wet_delay=model); set wet_delay=estimate to keep the state",
        )
    return choice


def _decide_wet_delay(obs: PppObservations, model: PppGraphConfig) -> WetDelayChoice:
    """``auto``'s decision: the L2 graph's ZWD estimate against the climatology (see :func:`wet_delay_choice`)."""
    g = PppGraph(obs, model)
    graph = g.structure_factors()
    graph.push_back(g.measurement_factors())
    estimate = float(np.median(g.wet_delays(solve(graph, g.initial_values(), ordering=g.elimination_ordering(graph)))))
    lat0, _, h0 = geodetic_from_ecef(g.spp_pos[0])
    climatology = zenith_wet_delay_m(WetDelayMode.model, float(lat0), float(h0), obs.doy)
    plausible = abs(estimate - climatology) <= WET_DELAY_GATE_SIGMAS * WET_DELAY_CLIMATOLOGY_SIGMA_M
    return WetDelayChoice(WetDelayMode.estimate if plausible else WetDelayMode.model, estimate, climatology)


#: :func:`wet_delay_choice` of the last few inputs (every graph estimator of a job asks for the same one).
_WET_DELAY_CACHE: dict[str, WetDelayChoice] = {}
_WET_DELAY_CACHE_SIZE = 8


def _carry_forward(x: np.ndarray) -> np.ndarray:
    """``x`` with each NaN replaced by the last finite value before it (the first finite one at the
    start); zeros when nothing is finite."""
    known = np.isfinite(x)
    if not known.any():
        return np.zeros_like(x)
    last = np.maximum.accumulate(np.where(known, np.arange(len(x)), -1))
    return np.where(last >= 0, x[np.maximum(last, 0)], x[np.argmax(known)])


def insert_double(values: gtsam.Values, key: int, x: float) -> None:
    """``values.insert(key, x)`` for a double (a receiver clock in seconds, a bias or delay in metres).

    By keyword: a positional float is tried against GTSAM's 45 other ``insert`` overloads
    first, which made an insert take about 60 us and the initial values of 10 minutes of
    1 Hz urban data a quarter of a second; by keyword it takes about 18 us.
    """
    values.insert(key, c=float(x))


def _linear(factor: gtsam.GaussianFactor, at: dict[int, Any]) -> gtsam.LinearContainerFactor:
    """A linear factor in a nonlinear graph, linearised at ``at`` (zero: exact wherever evaluated,
    since its keys are vector spaces)."""
    values = gtsam.Values()
    for key, value in at.items():
        if isinstance(value, float):
            insert_double(values, key, value)
        else:
            values.insert(key, value)
    return gtsam.LinearContainerFactor(factor, values)


def conditional_split(
    code_sigma: np.ndarray, phase_sigma: np.ndarray, code_phase_cov: np.ndarray | None, both: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each row's (code, phase) covariance as a marginal and a conditional (see :meth:`PppGraph.measurement_factors`).

    Parameters
    ----------
    code_sigma, phase_sigma : ndarray, shape (n,)
        Standard deviations [m].
    code_phase_cov : ndarray, shape (n,), optional
        Code-phase covariance [m^2]; None: uncorrelated.
    both : bool ndarray, shape (n,)
        Rows with a code and a phase factor (the others keep their sigmas).

    Returns
    -------
    code_sigma, rho_c, phase_sigma, rho_p : ndarray, shape (n,)
        The code factor is ``(code - rho_c phase)`` with ``code_sigma`` (conditional where
        ``rho_c != 0``), the phase factor ``(phase - rho_p code)`` with ``phase_sigma``; at most
        one of ``rho_c``, ``rho_p`` is non-zero per row.
    """
    n = len(both)
    sc = np.broadcast_to(np.asarray(code_sigma, float), (n,))
    sp = np.broadcast_to(np.asarray(phase_sigma, float), (n,))
    rho_c = np.zeros(n)  # code | phase
    rho_p = np.zeros(n)  # phase | code
    if code_phase_cov is None:
        return sc, rho_c, sp, rho_p
    # code marginal + phase conditional (rho_p) or phase marginal + code conditional (rho_c)
    cov = np.broadcast_to(np.asarray(code_phase_cov, float), (n,))
    a, b = sc**2, sp**2
    code_first = np.abs(cov / a) <= np.abs(cov / b)
    rho_p = np.where(both & code_first, cov / a, 0.0)
    rho_c = np.where(both & ~code_first, cov / b, 0.0)
    # rho -> 1 (code and phase errors equal, e.g. an NLOS delay on both) makes the
    # conditional's geometry coefficient 1 - rho vanish: clip rho to 1 -/+ _RHO_GAP,
    # i.e. shrink the covariance towards zero there (keeps it positive definite)
    rho_p = _clip_rho(rho_p)
    rho_c = _clip_rho(rho_c)
    sp = np.where(rho_p != 0, np.sqrt(np.maximum(b - rho_p**2 * a, 1e-12)), sp)
    sc = np.where(rho_c != 0, np.sqrt(np.maximum(a - rho_c**2 * b, 1e-12)), sc)
    return sc, rho_c, sp, rho_p


#: Smallest |1 - rho| of a conditional code/phase factor (see measurement_factors).
_RHO_GAP = 0.1


def _clip_rho(rho: np.ndarray) -> np.ndarray:
    near = np.abs(1.0 - rho) < _RHO_GAP
    return np.where(near, np.where(rho <= 1.0, 1.0 - _RHO_GAP, 1.0 + _RHO_GAP), rho)


def solve(
    graph: gtsam.NonlinearFactorGraph,
    initial: gtsam.Values,
    *,
    ordering: gtsam.Ordering | None = None,
    max_iterations: int = 100,
    relative_tol: float = 1e-6,
) -> gtsam.Values:
    """Levenberg-Marquardt from ``initial`` with sequential Cholesky (see the module notes).

    Parameters
    ----------
    graph, initial : the factor graph and the initial values.
    ordering : gtsam.Ordering, optional
        Elimination ordering, e.g. :meth:`PppGraph.elimination_ordering` (default COLAMD);
        an iterative estimator passes the one its re-solves use.
    max_iterations : int
        Levenberg-Marquardt iterations at most.
    relative_tol : float
        Stop when the relative error decrease is below this.
    """
    params = gtsam.LevenbergMarquardtParams()
    params.setLinearSolverType("SEQUENTIAL_CHOLESKY")
    if ordering is not None:
        params.setOrdering(ordering)
    params.setMaxIterations(max_iterations)
    params.setRelativeErrorTol(relative_tol)
    params.setAbsoluteErrorTol(0.0)
    return gtsam.LevenbergMarquardtOptimizer(graph, initial, params).optimize()
