"""CRT-LSS: sliding-window GNSS/INS MAP with l1 soft-thresholded outliers (Roysdon & Farrell 2019).

The window holds the states of L + 1 GNSS epochs ``x_{k-L} .. x_k`` and the GNSS
measurements of the last L of them. Per state (17 error-state components, in
this order): attitude (3, body frame, GTSAM ``Pose3`` tangent), position
(3, body frame), ECEF velocity (3), accelerometer and gyro bias (3 + 3),
receiver clock (m) and clock drift (m/s). Factors, all whitened:

* a Gaussian prior on ``x_{k-L}`` (the marginal of everything that left the window);
* GTSAM ``CombinedImuFactor`` between consecutive states (IMU preintegration,
  see :mod:`estimators.ins_mechanisation`), linearised natively in C++;
* a two-state receiver clock model (bias and drift, Allan h0 / h-2);
* per satellite an L1 pseudorange (corrected code of
  :func:`estimators.measurement.prepare_ppp`, modelled troposphere) and a
  Doppler range rate ``-lambda D + satellite drift = rdot + receiver drift``,
  with Jacobians in numpy, vectorised over satellites.

Cost, with ``b`` the whitened residuals (paper eq. 6, see the deviations)::

    C(X, S) = || z - g(X) - S ||^2 + 2 sum_i lambda_i |S_i|

``S`` has one entry per GNSS residual, in whitened units. Algorithm 1: Gauss-Newton
steps on ``X`` with a backtracking line search given ``S``; when the step is
below ``tol``, the S step ``S_i = sign(c_i) max(|c_i| - lambda_i, 0)`` with
``c = z - g(X)`` (eq. 14) and another X step; stop when both changes are below
``tol`` or after ``max_iterations``. The reported estimate of epoch k is the
one when k first enters the window. When the window is full, the oldest state
is marginalised (Schur complement of the linearised system at the current
estimate) together with the GNSS measurements of the state that becomes the
new first one; measurements with a non-zero ``S`` are left out of that prior
(zero Huber curvature, see :meth:`WindowSolver._marginalise_oldest`).

The same engine runs the error-state EKF (``mode="ekf"``: L = 1, one
Gauss-Newton step from the IMU prediction, which is the EKF update in
information form, with innovation gating) and the iterated EKF (CRT with L = 1).

Deviations from the paper, on purpose:

* Undifferenced L1 code and Doppler with receiver clock and drift states (the
  paper uses double differences against a base station; the benchmark has none).
* The threshold: the paper's eq. 12 ``(c - s)^2 + |s|`` is minimised at
  threshold 1/2, while eq. 14 thresholds at 1 (the minimiser of
  ``1/2 (c - s)^2 + |s|``). Here the cost is written so that eq. 14 holds with
  per-type thresholds ``lambda_rho`` and ``lambda_d`` in whitened units (the
  paper's ``s / lambda`` scaling): residuals beyond ``lambda`` sigma are
  clipped to ``lambda`` sigma, the Huber loss with ``k = lambda``.
* Heading: see :class:`GnssInsConfig` (``align_speed_mps``).
* The paper does not say how the prior is formed from the window's residuals;
  here outliers (S != 0) leaving the window are dropped from it (see above).
* Epochs with fewer than 4 usable satellites (``prepare_ppp``'s floor) get a
  state but no GNSS rows (IMU only). One receiver clock for all rows: no
  inter-system biases (the simulator is GPS only).
* The prior's Jacobian w.r.t. the first state is taken as the identity (the
  Pose3 local-coordinate Jacobian at a small offset from the prior mean).
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any

import gtsam
import numpy as np
import pandas as pd
from gtsam.symbol_shorthand import B, V, X
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.linalg import solveh_banded as solve_banded_h

from estimators import register
from estimators.base import Estimator, solution_frame
from estimators.ins_mechanisation import (
    ImuNoise,
    attitude_ecef,
    doppler_velocity,
    level_roll_pitch,
    preintegration_params,
    range_rate,
    rotate_about_vertical,
    yaw_of,
)
from estimators.measurement import prepare_ppp, single_point_solution, troposphere_terms
from simbench.contract import ReceiverData
from simbench.errors import SimbenchError
from simbench.sim import atmosphere
from simbench.sim.constants import C_LIGHT, DEG, LAMBDA_L1, OMEGA_EARTH
from simbench.sim.frames import dcm_ned_to_ecef, geodetic_from_ecef
from simbench.sim.geometry import sagnac_range

__all__ = [
    "CrtLss",
    "CrtLssConfig",
    "GnssEpoch",
    "GnssInsConfig",
    "WindowSolver",
    "prepare_gnss_ins",
    "run_gnss_ins",
    "soft_threshold",
    "validate_gnss_ins",
    "validate_lss",
]

#: Error-state dimension per epoch and the offsets of its blocks.
NS = 17
_ROT, _POS, _VEL, _BA, _BG, _CLK, _DRIFT = 0, 3, 6, 9, 12, 15, 16
_DPH = DEG / 3600.0
#: Largest outlier estimates (S entries, in measurement units) kept in the diagnostics.
_N_LARGEST_S = 20
#: Rows kept of the paper's Table 1 style iteration record.
TABLE_COLUMNS = ("i", "b_norm", "s_l1", "dx_norm", "ds_l1")


@dataclass
class GnssInsConfig:
    """Parameters shared by the GNSS/INS estimators (EKF, IEKF, CRT-LSS).

    Heading: a consumer gyro (bias ~100 deg/h) cannot gyrocompass (Earth rate
    15 deg/h), and yaw is unobservable while the vehicle stands still. The
    filter starts levelled from the static accelerometer mean with an
    arbitrary yaw (0) and a loose yaw prior; the first time the Doppler-only
    velocity exceeds ``align_speed_mps`` the attitude (and velocity) of every
    window state and the prior mean are turned about the local vertical so the
    newest state's heading equals the course over ground (a car does not
    slide sideways), and the filter refines yaw from then on.
    """

    code_sigma_m: float = 1.0  #: zenith code sigma [m], divided by sin(elevation)
    doppler_sigma_mps: float = 0.1  #: range-rate sigma at the reference C/N0 [m/s]
    doppler_ref_cn0_dbhz: float = 45.0  #: sigma scales as 10^((ref - C/N0) / 20)
    elevation_mask_deg: float = 7.0
    # IMU stochastic model (datasheet units as conf/imu; defaults: consumer grade)
    accel_noise_mps2_rthz: float = 3.0e-3
    gyro_noise_dph_rthz: float = 60.0
    accel_bias_instability_mps2: float = 1.0e-3
    gyro_bias_instability_dph: float = 10.0
    bias_tau_s: float = 300.0
    # initial uncertainty
    pos_sigma_m: float = 10.0  #: a priori position sigma about the single point solution [m]
    vel_sigma_mps: float = 0.5  #: a priori velocity sigma [m/s]
    roll_pitch_sigma_deg: float = 2.0  #: levelling error (accelerometer bias / g plus margin) [deg]
    yaw_sigma_deg: float = 30.0  #: yaw sigma after the course-over-ground reset [deg]
    accel_bias_sigma_mps2: float = 0.1  #: turn-on accelerometer bias sigma [m/s^2]
    gyro_bias_sigma_dph: float = 100.0  #: turn-on gyro bias sigma [deg/h]
    clock_sigma_m: float = 100.0  #: a priori receiver clock sigma about the single point solution [m]
    drift_sigma_mps: float = 5.0  #: a priori clock drift sigma about the Doppler solution [m/s]
    clock_h0: float = 2e-19  #: receiver clock white frequency noise (Allan h0) [s]
    clock_h_2: float = 2e-20  #: receiver clock random-walk frequency noise (Allan h-2) [1/s]
    level_s: float = 1.0  #: static accelerometer averaging before the first solved epoch [s]
    align_speed_mps: float = 3.0  #: Doppler speed that triggers the course-over-ground heading reset [m/s]


@dataclass
class CrtLssConfig(GnssInsConfig):
    """CRT-LSS parameters (paper Sec. 4, Algorithm 1)."""

    window: int = 10  #: L, GNSS epochs in the window
    lambda_rho: float = 1.0  #: pseudorange soft threshold [whitened units] (paper eq. 14; best of 0.5/1/2 on seed 1000)
    lambda_d: float = 1.0  #: Doppler soft threshold [whitened units]
    max_iterations: int = 20  #: Algorithm 1 iteration cap
    tol: float = 1e-3  #: convergence threshold on |dX|_2 and |dS|_2


def soft_threshold(c: np.ndarray, lam: np.ndarray | float) -> np.ndarray:
    """Closed-form S step (paper eq. 14): ``sign(c) max(|c| - lambda, 0)``, element-wise."""
    return np.sign(c) * np.maximum(np.abs(c) - lam, 0.0)


# --------------------------------------------------------------------------- data


@dataclass
class GnssEpoch:
    """One epoch's GNSS measurements, ready for the window (arrays of shape (k,) or (k, 3))."""

    sat_pos: np.ndarray  #: m, satellite ECEF position at transmit time
    sat_vel: np.ndarray  #: m/s, satellite ECEF velocity
    code: np.ndarray  #: m, corrected code minus the modelled troposphere
    w_code: np.ndarray  #: 1/m, code weights (1/sigma; 0 = not used)
    rr: np.ndarray  #: m/s, observed range rate plus receiver drift (-lambda D + satellite drift)
    w_rr: np.ndarray  #: s/m, Doppler weights (0 = missing or not used)
    sat: np.ndarray  #: satellite ids


@dataclass
class _Prepared:
    t: np.ndarray  #: s, time of every epoch index 0..n-1 (filled where the receiver had nothing)
    gnss: dict[int, GnssEpoch]
    spp: dict[int, tuple[np.ndarray, float]]


def prepare_gnss_ins(data: ReceiverData, cfg: GnssInsConfig) -> _Prepared:
    """Corrected code (prepare_ppp) joined with Doppler, satellite velocity and drift, per epoch.

    The modelled troposphere (Saastamoinen + Niell, hydrostatic and wet) is
    subtracted from the code here, at the epoch's single point solution: a few
    metres of position change it by far less than a millimetre.
    """
    obs = prepare_ppp(data, ionosphere_free=False, code_sigma_m=cfg.code_sigma_m, phase_sigma_m=1.0,
                      elevation_mask_deg=cfg.elevation_mask_deg, min_satellites=4, max_gap_epochs=1)
    extra = (data.observations.set_index(["epoch", "sat"])
             [["doppler_l1", "sat_vx", "sat_vy", "sat_vz", "sat_clock_drift", "cn0_l1"]]
             .reindex(pd.MultiIndex.from_arrays([obs.epoch, obs.sat])).to_numpy(float))
    rr = -LAMBDA_L1 * extra[:, 0] + extra[:, 4]
    sig_rr = cfg.doppler_sigma_mps * 10.0 ** ((cfg.doppler_ref_cn0_dbhz - extra[:, 5]) / 20.0)
    ok_rr = np.isfinite(rr) & np.isfinite(sig_rr) & np.isfinite(extra[:, 1:4]).all(axis=1)
    w_rr = np.where(ok_rr, 1.0 / np.where(ok_rr, sig_rr, 1.0), 0.0)
    rr = np.where(ok_rr, rr, 0.0)
    sat_vel = np.where(ok_rr[:, None], extra[:, 1:4], 0.0)

    times = data.epoch_times
    idx = np.arange(len(times))
    good = np.isfinite(times)
    t = np.interp(idx, idx[good], times[good]) if good.sum() > 1 else np.where(good, times, 0.0)
    gnss, spp = {}, {}
    x0 = None
    for k, rows in obs.iter_epochs():
        e = int(obs.epoch_ids[k])
        pos, clock = single_point_solution(obs.sat_pos[rows], obs.code[rows], obs.sigma_code[rows],
                                           el=obs.el[rows], doy=obs.doy, x0=x0)
        x0 = pos
        spp[e] = (pos, clock)
        lat, _, h = geodetic_from_ecef(pos)
        hydro, m_w = troposphere_terms(obs.el[rows], lat, h, obs.doy)
        zwd = float(atmosphere.saastamoinen_zenith_m(lat, h)[1])
        gnss[e] = GnssEpoch(sat_pos=obs.sat_pos[rows], sat_vel=sat_vel[rows],
                            code=obs.code[rows] - hydro - zwd * m_w, w_code=1.0 / obs.sigma_code[rows],
                            rr=rr[rows], w_rr=w_rr[rows], sat=obs.sat[rows])
    return _Prepared(t=t, gnss=gnss, spp=spp)


# --------------------------------------------------------------------------- window engine


@dataclass
class _Node:
    pose: gtsam.Pose3
    vel: np.ndarray
    bias: np.ndarray  #: accel (3) then gyro (3), GTSAM ConstantBias order
    clk: np.ndarray  #: clock [m], drift [m/s]
    gnss: GnssEpoch | None = None
    s_code: np.ndarray | None = None
    s_rr: np.ndarray | None = None
    imu: gtsam.CombinedImuFactor | None = None  #: factor from the previous node to this one
    clk_sqrt_info: np.ndarray | None = None  #: whitening of the clock model from the previous node
    dt: float = 0.0  #: time since the previous node [s]
    params: Any = None  #: preintegration parameters the IMU factor was built with (kept alive with it)
    imu_sqrt_info: np.ndarray | None = None  #: whitening of the IMU factor (upper Cholesky of the information)

    def copy(self) -> _Node:
        return _Node(gtsam.Pose3(self.pose), self.vel.copy(), self.bias.copy(), self.clk.copy(), self.gnss,
                     None if self.s_code is None else self.s_code.copy(),
                     None if self.s_rr is None else self.s_rr.copy(), self.imu, self.clk_sqrt_info, self.dt,
                     self.params, self.imu_sqrt_info)

    def retract(self, d: np.ndarray) -> _Node:
        out = self.copy()
        out.pose = self.pose.retract(d[:6])
        out.vel = self.vel + d[_VEL:_VEL + 3]
        out.bias = self.bias + d[_BA:_BG + 3]
        out.clk = self.clk + d[_CLK:]
        return out


def _local(mean: _Node, node: _Node) -> np.ndarray:
    """Tangent-space difference ``node - mean`` (GTSAM Pose3 local coordinates for the pose)."""
    d = np.empty(NS)
    d[:6] = mean.pose.localCoordinates(node.pose)
    d[_VEL:_VEL + 3] = node.vel - mean.vel
    d[_BA:_BG + 3] = node.bias - mean.bias
    d[_CLK:] = node.clk - mean.clk
    return d


def _window_gnss(nodes: list[_Node], jacobian: bool = True) -> tuple[np.ndarray, ...] | None:
    """Whitened GNSS errors without S (``g - z``) of every node, vectorised over the window.

    Returns
    -------
    None when no node carries GNSS, else
    e : ndarray, shape (2R,)
        R pseudorange errors, then R range-rate errors (weight-0 rows are 0).
    J : ndarray, shape (2R, 17) or None
        Whitened Jacobian w.r.t. the row's own node.
    w : ndarray, shape (2R,)
        Weights (0: row not used).
    bounds : list of (node index, first row, stop row)
        Rows of each node within the R-blocks.
    """
    idx = [i for i, n in enumerate(nodes) if n.gnss is not None]
    if not idx:
        return None
    gs = [nodes[i].gnss for i in idx]
    counts = np.array([len(g.code) for g in gs])
    stops = np.cumsum(counts)
    bounds = [(i, int(b - c), int(b)) for i, b, c in zip(idx, stops, counts)]
    sat_pos = np.concatenate([g.sat_pos for g in gs])
    sat_vel = np.concatenate([g.sat_vel for g in gs])
    z_code = np.concatenate([g.code for g in gs])
    z_rr = np.concatenate([g.rr for g in gs])
    w = np.concatenate([np.concatenate([g.w_code for g in gs]), np.concatenate([g.w_rr for g in gs])])
    p = np.repeat(np.array([nodes[i].pose.translation() for i in idx]), counts, axis=0)
    v = np.repeat(np.array([nodes[i].vel for i in idx]), counts, axis=0)
    clk = np.repeat(np.array([nodes[i].clk for i in idx]), counts, axis=0)
    d = sat_pos - p
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))
    rng = sagnac_range(sat_pos, p)
    rdot, d_pos, d_vel = range_rate(sat_pos, sat_vel, p, v)
    R = len(z_code)
    e = np.concatenate([rng + clk[:, 0] - z_code, rdot + clk[:, 1] - z_rr]) * w
    if not jacobian:
        return e, None, w, bounds
    grad = -d / dist[:, None]
    om = OMEGA_EARTH / C_LIGHT
    grad[:, 0] -= om * sat_pos[:, 1]
    grad[:, 1] += om * sat_pos[:, 0]
    rot = np.repeat(np.array([nodes[i].pose.rotation().matrix() for i in idx]), counts, axis=0)
    J = np.zeros((2 * R, NS))
    # the Pose3 tangent moves the position along body axes: dp = R dt
    J[:R, _POS:_POS + 3] = np.einsum("rj,rjk->rk", grad, rot)
    J[:R, _CLK] = 1.0
    J[R:, _POS:_POS + 3] = np.einsum("rj,rjk->rk", d_pos, rot)
    J[R:, _VEL:_VEL + 3] = d_vel
    J[R:, _DRIFT] = 1.0
    J *= w[:, None]
    return e, J, w, bounds


def _s_of(nodes: list[_Node]) -> np.ndarray:
    """S of every GNSS node in :func:`_window_gnss` row order (codes, then range rates)."""
    with_g = [n for n in nodes if n.gnss is not None]
    if not with_g:
        return np.zeros(0)
    return np.concatenate([np.concatenate([n.s_code for n in with_g]), np.concatenate([n.s_rr for n in with_g])])


def _solve_block_tridiagonal(H: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """Solve ``H dx = eta`` for the window's block-tridiagonal information matrix (banded Cholesky)."""
    bw = min(2 * NS, len(eta))
    ab = np.zeros((bw, len(eta)))
    for k in range(bw):
        ab[bw - 1 - k, k:] = np.diagonal(H, k)
    ab[-1] += 1e-12  # the prior and IMU chain make H positive definite; guard round-off only
    return solve_banded_h(ab, eta, check_finite=False)


def _clock_model(dt: float, h0: float, h_2: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition ``F`` and upper Cholesky factor of the inverse process covariance of the clock [m, m/s]."""
    qb, qd = C_LIGHT**2 * h0 / 2.0, C_LIGHT**2 * 2.0 * np.pi**2 * h_2
    dt = max(dt, 1e-3)
    Q = np.array([[qb * dt + qd * dt**3 / 3.0, qd * dt**2 / 2.0], [qd * dt**2 / 2.0, qd * dt]])
    F = np.array([[1.0, dt], [0.0, 1.0]])
    return F, np.linalg.cholesky(np.linalg.inv(Q)).T


class WindowSolver:
    """The CRT-LSS window: nodes, prior, factors, Algorithm 1 and marginalisation.

    Parameters
    ----------
    cfg : GnssInsConfig
    window : int
        L, number of GNSS epochs in the window (L + 1 states).
    lambdas : tuple of float
        Soft thresholds ``(lambda_rho, lambda_d)`` [whitened]; ``inf`` disables the S step.
    max_iterations : int
    tol : float
    """

    def __init__(self, cfg: GnssInsConfig, window: int, lambdas: tuple[float, float], max_iterations: int,
                 tol: float) -> None:
        self.cfg = cfg
        self.window = window
        self.lam_rho, self.lam_d = lambdas
        self.max_iterations = max_iterations
        self.tol = tol
        self.noise = ImuNoise.from_datasheet(cfg.accel_noise_mps2_rthz, cfg.gyro_noise_dph_rthz,
                                             cfg.accel_bias_instability_mps2, cfg.gyro_bias_instability_dph,
                                             cfg.bias_tau_s)
        self.nodes: list[_Node] = []
        self.prior_mean: _Node | None = None
        self.prior_R = np.eye(NS)
        self.prior_r = np.zeros(NS)
        self._ne = None

    # ---------------------------------------------------------------- building

    def start(self, node: _Node, sigmas: np.ndarray) -> None:
        """First state and its diagonal prior (sigmas in the 17 error-state units)."""
        self.nodes = [node]
        self.prior_mean = node.copy()
        self.prior_R = np.diag(1.0 / np.asarray(sigmas, float))
        self.prior_r = np.zeros(NS)

    def predict(self, f_b: np.ndarray, w_b: np.ndarray, dt: np.ndarray) -> _Node:
        """Preintegrate IMU samples from the newest node and return the predicted next node."""
        last = self.nodes[-1]
        params = preintegration_params(self.noise, last.pose.translation())
        bias = gtsam.imuBias.ConstantBias(last.bias[:3], last.bias[3:])
        pim = gtsam.PreintegratedCombinedMeasurements(params, bias)
        for i in range(len(dt)):
            pim.integrateMeasurement(f_b[i], w_b[i], dt[i])
        ns = pim.predict(gtsam.NavState(last.pose, last.vel), bias)
        n = len(self.nodes)
        total = float(np.sum(dt))
        F, sqrt_info = _clock_model(total, self.cfg.clock_h0, self.cfg.clock_h_2)
        node = _Node(pose=ns.pose(), vel=np.asarray(ns.velocity()), bias=last.bias.copy(), clk=F @ last.clk,
                     imu=gtsam.CombinedImuFactor(X(n - 1), V(n - 1), X(n), V(n), B(n - 1), B(n), pim),
                     clk_sqrt_info=sqrt_info, dt=total, params=params,
                     imu_sqrt_info=np.linalg.cholesky(np.linalg.inv(pim.preintMeasCov())).T)
        return node

    def append(self, node: _Node, gnss: GnssEpoch | None) -> None:
        """Add a predicted node with its GNSS epoch; marginalise the oldest when the window overflows."""
        node.gnss = gnss
        if gnss is not None:
            node.s_code = np.zeros(len(gnss.code))
            node.s_rr = np.zeros(len(gnss.code))
        self.nodes.append(node)
        self._ne = None
        if len(self.nodes) > self.window + 1:
            self._marginalise_oldest()

    def rotate_heading(self, angle: float) -> None:
        """Turn every state's attitude and velocity, and the prior mean, about the local vertical."""
        R = rotate_about_vertical(self.nodes[-1].pose.translation(), angle)
        for node in [*self.nodes, self.prior_mean]:
            node.pose = gtsam.Pose3(gtsam.Rot3(R @ node.pose.rotation().matrix()), node.pose.translation())
            node.vel = R @ node.vel
        self._ne = None

    # ---------------------------------------------------------------- linearisation

    def _pair_terms(self, nodes: list[_Node], i: int, jacobian: bool = True) -> tuple[np.ndarray | None, ...]:
        """IMU and clock factors into node ``i``: whitened Jacobian over nodes ``i-1, i`` (17 x 34), b = -error."""
        a, b = nodes[i - 1], nodes[i]
        bi = gtsam.imuBias.ConstantBias(a.bias[:3], a.bias[3:])
        bj = gtsam.imuBias.ConstantBias(b.bias[:3], b.bias[3:])
        W = b.imu_sqrt_info
        F = np.array([[1.0, b.dt], [0.0, 1.0]])
        Wc = b.clk_sqrt_info
        rhs = np.empty(17)
        rhs[15:] = -Wc @ (b.clk - F @ a.clk)
        sl = slice(NS * (i - 1), NS * (i + 1))
        if not jacobian:
            rhs[:15] = -W @ b.imu.evaluateError(a.pose, a.vel, b.pose, b.vel, bi, bj)
            return None, rhs, sl
        Hall = np.zeros((15, 30), order="F")  # column blocks of an F-ordered array are F-contiguous views
        Hs = [Hall[:, a:b] for a, b in ((0, 6), (6, 9), (9, 15), (15, 18), (18, 24), (24, 30))]
        rhs[:15] = -W @ b.imu.evaluateError(a.pose, a.vel, b.pose, b.vel, bi, bj, *Hs)
        WH = W @ Hall
        A = np.zeros((17, 2 * NS))
        # GTSAM's key order: pose_i, vel_i, pose_j, vel_j, bias_i, bias_j
        A[:15, 0:9] = WH[:, 0:9]
        A[:15, NS:NS + 9] = WH[:, 9:18]
        A[:15, _BA:_BA + 6] = WH[:, 18:24]
        A[:15, NS + _BA:NS + _BA + 6] = WH[:, 24:30]
        A[15:, _CLK:_CLK + 2] = -Wc @ F
        A[15:, NS + _CLK:NS + _CLK + 2] = Wc
        return A, rhs, sl

    def _prior_terms(self, nodes: list[_Node]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        e = self.prior_R @ _local(self.prior_mean, nodes[0]) - self.prior_r
        return self.prior_R, -e, slice(0, NS)

    def _terms(self, nodes: list[_Node], jacobian: bool = True):
        """Prior, IMU and clock factors as (A, b, columns); GNSS is handled vectorised."""
        yield self._prior_terms(nodes)
        for i in range(1, len(nodes)):
            yield self._pair_terms(nodes, i, jacobian)

    def _normal_equations(self, nodes: list[_Node],
                          gnss_nodes: set[int] | None = None) -> tuple[np.ndarray, np.ndarray, float]:
        """``G^T G``, ``G^T b`` and ``|b|^2`` of the window (GNSS of ``gnss_nodes`` only, default all)."""
        N = NS * len(nodes)
        H = np.zeros((N, N))
        eta = np.zeros(N)
        sq = 0.0
        for A, b, sl in self._terms(nodes):
            H[sl, sl] += A.T @ A
            eta[sl] += A.T @ b
            sq += float(b @ b)
        g = _window_gnss(nodes)
        if g is not None:
            e, J, w, bounds = g
            b = -(e + _s_of(nodes) * (w > 0))
            R = len(e) // 2
            for i, lo, hi in bounds:
                if gnss_nodes is not None and i not in gnss_nodes:
                    continue
                Jc, Jr, bc, br = J[lo:hi], J[R + lo:R + hi], b[lo:hi], b[R + lo:R + hi]
                sl = slice(NS * i, NS * (i + 1))
                H[sl, sl] += Jc.T @ Jc + Jr.T @ Jr
                eta[sl] += Jc.T @ bc + Jr.T @ br
                sq += float(bc @ bc + br @ br)
        return H, eta, sq

    def _s_l1(self, nodes: list[_Node]) -> float:
        """``sum lambda_i |S_i|`` over the window."""
        tot = 0.0
        for n in nodes:
            # with an infinite threshold S stays 0 and adds nothing (inf * 0 would be NaN)
            if n.gnss is not None and np.isfinite(self.lam_rho):
                tot += self.lam_rho * np.abs(n.s_code).sum()
            if n.gnss is not None and np.isfinite(self.lam_d):
                tot += self.lam_d * np.abs(n.s_rr).sum()
        return float(tot)

    def cost(self, nodes: list[_Node] | None = None) -> float:
        """``|z - g(X) - S|^2 + 2 sum lambda |S|`` of the window."""
        nodes = self.nodes if nodes is None else nodes
        sq = 0.0
        for _, b, _ in self._terms(nodes, jacobian=False):
            sq += float(b @ b)
        g = _window_gnss(nodes, jacobian=False)
        if g is not None:
            e, _, w, _ = g
            sq += float(np.sum((e + _s_of(nodes) * (w > 0)) ** 2))
        return sq + 2.0 * self._s_l1(nodes)

    # ---------------------------------------------------------------- solving

    def _x_step(self, line_search: bool = True) -> tuple[float, float]:
        """One Gauss-Newton step on X given S, with backtracking. Returns (|b|_2 before, |dX|_2 taken).

        The normal equations of an accepted trial point are kept for the next
        step: the line search's cost evaluation is then free.
        """
        if self._ne is None:
            self._ne = self._normal_equations(self.nodes)
        H, eta, sq = self._ne
        dx = _solve_block_tridiagonal(H, eta)
        self._ne = None
        # a step below the tolerance cannot change the cost beyond round-off: take it as is
        if not line_search or np.linalg.norm(dx) < self.tol:
            self.nodes = [n.retract(dx[NS * i:NS * (i + 1)]) for i, n in enumerate(self.nodes)]
            return float(np.sqrt(sq)), float(np.linalg.norm(dx))
        s_pen = 2.0 * self._s_l1(self.nodes)  # S is fixed during the X step
        c0 = sq + s_pen
        alpha = 1.0
        for _ in range(6):
            trial = [n.retract(alpha * dx[NS * i:NS * (i + 1)]) for i, n in enumerate(self.nodes)]
            ne = self._normal_equations(trial)
            if ne[2] + s_pen <= c0 * (1.0 + 1e-12):
                self.nodes, self._ne = trial, ne
                return float(np.sqrt(sq)), float(alpha * np.linalg.norm(dx))
            alpha *= 0.5
        self._ne = (H, eta, sq)
        return float(np.sqrt(sq)), 0.0

    def _s_step(self) -> float:
        """Closed-form S update (eq. 14) on all GNSS residuals; returns |dS|_2."""
        g = _window_gnss(self.nodes, jacobian=False)
        if g is None:
            return 0.0
        e, _, w, bounds = g
        R = len(e) // 2
        lam = np.concatenate([np.full(R, self.lam_rho), np.full(R, self.lam_d)])
        new = soft_threshold(-e, lam) * (w > 0)  # c = z - g(X), whitened
        old = _s_of(self.nodes)
        for i, lo, hi in bounds:
            self.nodes[i].s_code, self.nodes[i].s_rr = new[lo:hi], new[R + lo:R + hi]
        self._ne = None
        return float(np.linalg.norm(new - old))

    def solve(self, record: bool = False) -> tuple[int, list[tuple[float, ...]]]:
        """Algorithm 1 on the current window. Returns the iteration count and (if asked) the table rows."""
        table: list[tuple[float, ...]] = []
        use_s = np.isfinite(self.lam_rho) or np.isfinite(self.lam_d)
        i = 0
        while i < self.max_iterations:
            i += 1
            s_before = self._s_l1_plain()
            b_norm, dx = self._x_step()
            if record:
                table.append((i, b_norm, s_before, dx, 0.0))
            if dx < self.tol:
                if not use_s:
                    break
                s_old = self._s_vector()
                ds = self._s_step()
                b_norm, dx = self._x_step()
                if record:
                    table.append((i, b_norm, self._s_l1_plain(), dx, float(np.abs(self._s_vector() - s_old).sum())))
                if dx < self.tol and ds < self.tol:
                    break
        return i, table

    def _s_vector(self) -> np.ndarray:
        parts = [np.concatenate([n.s_code, n.s_rr]) for n in self.nodes if n.gnss is not None]
        return np.concatenate(parts) if parts else np.zeros(0)

    def _s_l1_plain(self) -> float:
        return float(np.abs(self._s_vector()).sum())

    def ekf_update(self, gate: float) -> int:
        """EKF update of the newest node (one linearisation at the prediction), with innovation gating.

        Returns the number of GNSS rows rejected by the gate.
        """
        last = len(self.nodes) - 1
        node = self.nodes[last]
        if node.gnss is not None:
            H0, _, _ = self._normal_equations(self.nodes, gnss_nodes=set(range(last)))
            P = np.linalg.inv(H0)[-NS:, -NS:]
            e, J, w, bounds = _window_gnss(self.nodes)
            R = len(e) // 2
            _, lo, hi = bounds[-1]
            rows = np.r_[lo:hi, R + lo:R + hi]
            e, J, w = e[rows], J[rows], w[rows]
            var = np.einsum("ij,jk,ik->i", J, P, J) + (w > 0)
            bad = (np.abs(e) > gate * np.sqrt(np.maximum(var, 1e-30))) & (w > 0)
            if bad.any():
                k = len(node.gnss.code)
                g = node.gnss
                node.gnss = GnssEpoch(g.sat_pos, g.sat_vel, g.code, np.where(bad[:k], 0.0, g.w_code), g.rr,
                                      np.where(bad[k:], 0.0, g.w_rr), g.sat)
                self._ne = None
            self._x_step(line_search=False)
            return int(bad.sum())
        self._x_step(line_search=False)
        return 0

    def _marginalise_oldest(self) -> None:
        """Fold node 0 and the GNSS of node 1 into a Gaussian prior on node 1 (Schur complement).

        Measurements with a non-zero S leave the window as outliers and are not
        folded in: for fixed X the S-minimised cost of a row is the Huber loss,
        whose curvature is zero beyond the threshold, so such a row carries no
        information (Laplace approximation). Folding ``z - S`` in at full
        weight instead makes the prior confidently wrong after a run of
        outliers; with L = 1 that diverges (seen on the urban drive).
        """
        pair = [n.copy() for n in self.nodes[:2]]
        for n in pair:
            if n.gnss is not None:
                g = n.gnss
                n.gnss = GnssEpoch(g.sat_pos, g.sat_vel, g.code, np.where(n.s_code != 0, 0.0, g.w_code), g.rr,
                                   np.where(n.s_rr != 0, 0.0, g.w_rr), g.sat)
        H, eta, _ = self._normal_equations(pair)
        H00, H01, H11 = H[:NS, :NS], H[:NS, NS:], H[NS:, NS:]
        c = cho_factor(H00 + 1e-12 * np.eye(NS))
        lam = H11 - H01.T @ cho_solve(c, H01)
        eta1 = eta[NS:] - H01.T @ cho_solve(c, eta[:NS])
        lam = 0.5 * (lam + lam.T)
        R = np.linalg.cholesky(lam + 1e-12 * np.eye(NS)).T
        self.prior_R = R
        self.prior_r = solve_triangular(R, eta1, trans="T")
        self.prior_mean = self.nodes[1].copy()
        self.nodes = self.nodes[1:]
        self._ne = None
        first = self.nodes[0]
        first.gnss, first.s_code, first.s_rr, first.imu, first.clk_sqrt_info = None, None, None, None, None


# --------------------------------------------------------------------------- driver


def _initial_sigmas(cfg: GnssInsConfig) -> np.ndarray:
    s = np.empty(NS)
    s[_ROT:_ROT + 3] = [cfg.roll_pitch_sigma_deg * DEG, cfg.roll_pitch_sigma_deg * DEG, cfg.yaw_sigma_deg * DEG]
    s[_POS:_POS + 3] = cfg.pos_sigma_m
    s[_VEL:_VEL + 3] = cfg.vel_sigma_mps
    s[_BA:_BA + 3] = cfg.accel_bias_sigma_mps2
    s[_BG:_BG + 3] = cfg.gyro_bias_sigma_dph * _DPH
    s[_CLK], s[_DRIFT] = cfg.clock_sigma_m, cfg.drift_sigma_mps
    return s


def _spp_sigmas(g: GnssEpoch, pos: np.ndarray, clock: float) -> tuple[float, float]:
    """Position (largest axis) and clock sigma of a single point solution, scaled by its a posteriori variance factor.

    In a street canyon the first fix can be tens of metres off (NLOS); a prior
    at the nominal code sigma would then be confidently wrong and make gating
    or soft-thresholding reject the good measurements that follow.
    """
    d = g.sat_pos - pos
    grad = -d / np.linalg.norm(d, axis=1)[:, None]
    A = np.hstack([grad, np.ones((len(d), 1))]) * g.w_code[:, None]
    r = (g.code - sagnac_range(g.sat_pos, pos) - clock) * g.w_code
    dof = len(r) - 4
    var_factor = float(r @ r) / dof if dof > 0 else 1.0
    P = max(var_factor, 1.0) * np.linalg.inv(A.T @ A)
    return float(np.sqrt(np.linalg.eigvalsh(P[:3, :3]).max())), float(np.sqrt(P[3, 3]))


def _record_outliers(out: list[dict[str, Any]], epoch: int, node: _Node) -> None:
    """Append the non-zero S entries of a node leaving the window; keep the largest few."""
    g = node.gnss
    for kind, s, w, unit in (("code", node.s_code, g.w_code, "m"), ("doppler", node.s_rr, g.w_rr, "m/s")):
        for j in np.flatnonzero(s):
            out.append({"epoch": int(epoch), "sat": str(g.sat[j]), "kind": kind, "s_whitened": float(s[j]),
                        "s_m": float(s[j] / w[j]), "unit": unit})
    if len(out) > 4 * _N_LARGEST_S:
        out.sort(key=lambda r: -abs(r["s_m"]))
        del out[_N_LARGEST_S:]


def validate_gnss_ins(cfg: GnssInsConfig, where: str) -> None:
    """One-line errors for out-of-range shared parameters."""
    for name in ("code_sigma_m", "doppler_sigma_mps", "pos_sigma_m", "vel_sigma_mps", "roll_pitch_sigma_deg",
                 "yaw_sigma_deg", "accel_bias_sigma_mps2", "gyro_bias_sigma_dph", "clock_sigma_m",
                 "drift_sigma_mps", "accel_noise_mps2_rthz", "gyro_noise_dph_rthz", "bias_tau_s", "clock_h0",
                 "clock_h_2", "level_s"):
        if not getattr(cfg, name) > 0:
            raise SimbenchError(f"{where}.{name}", f"must be positive, got {getattr(cfg, name)}",
                                f"see conf/estimator/{where.rsplit('.', 1)[-1]}.yaml")


def run_gnss_ins(data: ReceiverData, cfg: GnssInsConfig, *, mode: str, window: int,
                 lambdas: tuple[float, float] = (np.inf, np.inf), max_iterations: int = 20, tol: float = 1e-3,
                 gate: float = np.inf) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Run a GNSS/INS estimator over a scenario.

    Parameters
    ----------
    data : ReceiverData
    cfg : GnssInsConfig
    mode : {"ekf", "lss"}
        ``ekf``: one update per epoch with innovation gating; ``lss``: Algorithm 1.
    window : int
        L (the EKF uses 1).
    lambdas : (float, float)
        ``(lambda_rho, lambda_d)`` soft thresholds [whitened]; inf disables the S step.
    max_iterations, tol : Algorithm 1 stopping rule.
    gate : float
        EKF innovation gate in innovation sigmas.

    Returns
    -------
    epochs : pandas.DataFrame (:func:`estimators.base.solution_frame`)
    diagnostics : dict
    """
    if data.imu is None or len(data.imu) < 2:
        raise SimbenchError("imu", "the GNSS/INS estimators need the IMU table", "simulate with an IMU")
    prep = prepare_gnss_ins(data, cfg)
    imu = data.imu
    t_imu = imu["t"].to_numpy(float)
    f_b = imu[["ax", "ay", "az"]].to_numpy(float)
    w_b = imu[["gx", "gy", "gz"]].to_numpy(float)
    dt_imu = np.diff(t_imu, append=t_imu[-1])

    epochs = sorted(prep.gnss)
    first = next((e for e in epochs if prep.t[e] >= t_imu[0] + cfg.level_s), None)
    if first is None:
        raise SimbenchError("scenario.duration_s", "no GNSS epoch after the levelling interval",
                            "give a longer scenario or a shorter level_s")
    t0 = prep.t[first]
    static = t_imu <= t0
    roll, pitch = level_roll_pitch(f_b[static].mean(axis=0))
    pos0, clock0 = prep.spp[first]
    g0 = prep.gnss[first]
    vel0, drift0 = doppler_velocity(g0.sat_pos, g0.sat_vel, pos0, g0.rr, 1.0 / np.maximum(g0.w_rr, 1e-9))
    node0 = _Node(pose=gtsam.Pose3(gtsam.Rot3(attitude_ecef(pos0, roll, pitch, 0.0)), pos0), vel=vel0,
                  bias=np.zeros(6), clk=np.array([clock0, drift0]))
    solver = WindowSolver(cfg, window, lambdas, max_iterations, tol)
    sigmas = _initial_sigmas(cfg)
    pos_sd, clock_sd = _spp_sigmas(g0, pos0, clock0)
    sigmas[_POS:_POS + 3] = np.maximum(sigmas[_POS:_POS + 3], pos_sd)
    sigmas[_CLK] = max(sigmas[_CLK], clock_sd)
    solver.start(node0, sigmas)
    node0.gnss = g0
    node0.s_code, node0.s_rr = np.zeros(len(g0.code)), np.zeros(len(g0.code))

    tic = time.perf_counter()
    iters, _ = solver.solve() if mode == "lss" else (1, [])
    if mode == "ekf":
        solver.ekf_update(gate)
    out_epoch, out_pos, out_s = [first], [solver.nodes[-1].pose.translation().copy()], [time.perf_counter() - tic]
    n_iter, n_capped, n_rejected = [iters], 0, 0
    aligned_at, align_deg = -1, 0.0
    best_table: list[tuple[float, ...]] = []
    best_s, best_epoch = -1.0, -1
    n_code = n_code_s = n_rr = n_rr_s = 0
    outliers: list[dict[str, Any]] = []
    start_idx = np.searchsorted(t_imu, t0 - 1e-9)
    for e in range(first + 1, len(prep.t)):
        tic = time.perf_counter()
        stop_idx = np.searchsorted(t_imu, prep.t[e] - 1e-9)
        seg = slice(start_idx, stop_idx)
        start_idx = stop_idx
        node = solver.predict(f_b[seg], w_b[seg], dt_imu[seg])
        gnss = prep.gnss.get(e)
        solver.append(node, gnss)
        if aligned_at < 0 and gnss is not None and np.count_nonzero(gnss.w_rr) >= 4:
            p = node.pose.translation()
            v, _ = doppler_velocity(gnss.sat_pos, gnss.sat_vel, p, gnss.rr, 1.0 / np.maximum(gnss.w_rr, 1e-9))
            lat, lon, _ = geodetic_from_ecef(p)
            v_ned = dcm_ned_to_ecef(lat, lon).T @ v
            if np.hypot(v_ned[0], v_ned[1]) > cfg.align_speed_mps:
                course = float(np.arctan2(v_ned[1], v_ned[0]))
                delta = float(np.angle(np.exp(1j * (course - yaw_of(p, node.pose.rotation().matrix())))))
                solver.rotate_heading(delta)
                aligned_at, align_deg = e, delta / DEG
        full = len(solver.nodes) == window + 1
        if mode == "ekf":
            n_rejected += solver.ekf_update(gate)
            iters, table = 1, []
        else:
            iters, table = solver.solve(record=full)
        out_pos.append(solver.nodes[-1].pose.translation().copy())
        out_s.append(time.perf_counter() - tic)
        out_epoch.append(e)
        n_iter.append(iters)
        n_capped += iters >= max_iterations and mode == "lss"
        if gnss is not None:
            n_code += len(gnss.code)
            n_rr += int(np.count_nonzero(gnss.w_rr))
        if full and mode == "lss":
            s = solver._s_l1_plain()
            if s > best_s:
                best_s, best_table, best_epoch = s, table, e
        # S of the epoch about to leave the window is final: count it then
        leaving = solver.nodes[1] if full and len(solver.nodes) > 1 else None
        if leaving is not None and leaving.gnss is not None:
            n_code_s += int(np.count_nonzero(leaving.s_code))
            n_rr_s += int(np.count_nonzero(leaving.s_rr))
            _record_outliers(outliers, e - (len(solver.nodes) - 2), leaving)

    epochs_arr = np.asarray(out_epoch)
    frame = solution_frame(epochs_arr, prep.t[epochs_arr], np.asarray(out_pos), np.asarray(out_s))
    last = solver.nodes[-1]
    diagnostics = {
        "mode": mode, "window": int(window), "n_epochs": len(out_epoch), "first_epoch": int(first),
        "gnss_epochs": len(prep.gnss),
        "iterations_mean": float(np.mean(n_iter)), "iterations_max": int(np.max(n_iter)),
        "n_iteration_capped": int(n_capped),
        "heading_aligned_epoch": int(aligned_at), "heading_reset_deg": float(align_deg),
        "ekf_rejected_rows": int(n_rejected),
        "code_rows": int(n_code), "code_rows_with_s": int(n_code_s),
        "doppler_rows": int(n_rr), "doppler_rows_with_s": int(n_rr_s),
        "iteration_table_epoch": int(best_epoch),
        "iteration_table": [dict(zip(TABLE_COLUMNS, (int(r[0]), *map(float, r[1:])))) for r in best_table],
        "largest_s": sorted(outliers, key=lambda r: -abs(r["s_m"]))[:_N_LARGEST_S],
        "final_accel_bias_mps2": [float(v) for v in last.bias[:3]],
        "final_gyro_bias_dph": [float(v / _DPH) for v in last.bias[3:]],
        "config": asdict(cfg),
    }
    return frame, diagnostics


@register
class CrtLss(Estimator):
    """CRT-LSS: sliding-window GNSS/INS MAP with l1 soft-thresholded outliers (Roysdon & Farrell)."""

    name = "crt_lss"
    Config = CrtLssConfig

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        cfg: CrtLssConfig = self.config
        validate_lss(cfg, f"estimator.{self.name}", cfg.window)
        return run_gnss_ins(data, cfg, mode="lss", window=cfg.window, lambdas=(cfg.lambda_rho, cfg.lambda_d),
                            max_iterations=cfg.max_iterations, tol=cfg.tol)


def validate_lss(cfg: Any, where: str, window: int) -> None:
    """One-line errors for the window and Algorithm 1 parameters (plus the shared ones)."""
    validate_gnss_ins(cfg, where)
    if int(window) < 1:
        raise SimbenchError(f"{where}.window", f"must be at least 1, got {window}", "the paper uses L = 1..20")
    for name in ("lambda_rho", "lambda_d", "tol"):
        if not getattr(cfg, name) > 0:
            raise SimbenchError(f"{where}.{name}", f"must be positive, got {getattr(cfg, name)}",
                                "thresholds are in whitened units (sigmas), e.g. 2")
    if int(cfg.max_iterations) < 1:
        raise SimbenchError(f"{where}.max_iterations", f"must be at least 1, got {cfg.max_iterations}",
                            "the paper caps Algorithm 1 at 20")
