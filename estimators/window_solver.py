"""The sliding-window GNSS/INS MAP engine behind CRT-LSS, the IEKF and the EKF.

The window holds the states of L + 1 GNSS epochs ``x_{k-L} .. x_k`` and the GNSS
measurements of the last L of them. Per state (17 error-state components, in
this order, offsets :data:`ROT` .. :data:`DRIFT`): attitude (3, body frame,
GTSAM ``Pose3`` tangent), position (3, body frame), ECEF velocity (3),
accelerometer and gyro bias (3 + 3), receiver clock (m) and clock drift (m/s).
Factors, all whitened:

* a Gaussian prior on ``x_{k-L}`` (the marginal of everything that left the window);
* GTSAM ``CombinedImuFactor`` between consecutive states (IMU preintegration,
  see :mod:`estimators.ins_mechanisation`), linearised natively in C++;
* a two-state receiver clock model (bias and drift, Allan h0 / h-2);
* per satellite an L1 pseudorange (:class:`estimators.gnss_ins_data.GnssEpoch`)
  and a Doppler range rate ``-lambda D + satellite drift = rdot + receiver drift``,
  with Jacobians in numpy, vectorised over the window's satellites
  (:func:`window_gnss_terms`; range and gradient from
  :func:`simbench.gnss.geometry.sagnac_range_gradient`).

Cost, with ``b`` the whitened residuals (paper eq. 6)::

    C(X, S) = || z - g(X) - S ||^2 + 2 sum_i lambda_i |S_i|

``S`` has one entry per GNSS residual, in whitened units. Algorithm 1
(:meth:`WindowSolver.solve`): Gauss-Newton steps on ``X`` with a backtracking
line search given ``S`` (:meth:`WindowSolver.x_step`); when the step is below
``tol``, the S step ``S_i = sign(c_i) max(|c_i| - lambda_i, 0)`` with
``c = z - g(X)`` (eq. 14, :meth:`WindowSolver.s_step`) and another X step;
stop when both changes are below ``tol`` or after ``max_iterations``. When the
window is full, the oldest state is marginalised (Schur complement of the
linearised system at the current estimate) together with the GNSS measurements
of the state that becomes the new first one; measurements with a non-zero
``S`` are left out of that prior (zero Huber curvature, see
:meth:`WindowSolver._marginalise_oldest`).

With L = 1 and one Gauss-Newton step from the IMU prediction
(:meth:`WindowSolver.ekf_update`) the same engine is the error-state EKF in
information form; with L = 1 and Algorithm 1 it is the iterated EKF.

The prior's Jacobian w.r.t. the first state is taken as the identity (the
Pose3 local-coordinate Jacobian at a small offset from the prior mean).
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any, NamedTuple

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, V, X
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.linalg import solveh_banded as solve_banded_h

from estimators.gnss_ins_config import GnssInsConfig
from estimators.gnss_ins_data import GnssEpoch
from estimators.ins_mechanisation import (
    DEG_PER_HOUR,
    ImuNoise,
    preintegration_params,
    rotate_about_vertical,
)
from simbench.gnss.doppler import range_rate
from simbench.gnss.geometry import sagnac_range_gradient
from simbench.sim.constants import C_LIGHT, DEG

__all__ = [
    "BA", "BG", "CLK", "DRIFT", "NS", "POS", "ROT", "VEL",
    "GnssTerms",
    "WindowNode",
    "WindowSolver",
    "initial_sigmas",
    "soft_threshold",
    "window_gnss_terms",
]

#: Error-state dimension per epoch.
NS = 17
#: First index of each error-state block: attitude, position, velocity, accel bias, gyro bias, clock, drift.
ROT, POS, VEL, BA, BG, CLK, DRIFT = 0, 3, 6, 9, 12, 15, 16


def soft_threshold(c: np.ndarray, lam: np.ndarray | float) -> np.ndarray:
    """Closed-form S step (paper eq. 14): ``sign(c) max(|c| - lambda, 0)``, element-wise."""
    return np.sign(c) * np.maximum(np.abs(c) - lam, 0.0)


def initial_sigmas(cfg: GnssInsConfig) -> np.ndarray:
    """A priori sigmas of the first state in the 17 error-state units (rad, m, m/s, m/s^2, rad/s, m, m/s)."""
    s = np.empty(NS)
    s[ROT:ROT + 3] = [cfg.roll_pitch_sigma_deg * DEG, cfg.roll_pitch_sigma_deg * DEG, cfg.yaw_sigma_deg * DEG]
    s[POS:POS + 3] = cfg.pos_sigma_m
    s[VEL:VEL + 3] = cfg.vel_sigma_mps
    s[BA:BA + 3] = cfg.accel_bias_sigma_mps2
    s[BG:BG + 3] = cfg.gyro_bias_sigma_dph * DEG_PER_HOUR
    s[CLK], s[DRIFT] = cfg.clock_sigma_m, cfg.drift_sigma_mps
    return s


@dataclass
class WindowNode:
    """One state of the window with the factors that lead into it."""

    pose: gtsam.Pose3
    vel: np.ndarray  #: m/s, ECEF velocity
    bias: np.ndarray  #: accel (3) then gyro (3), GTSAM ConstantBias order
    clk: np.ndarray  #: clock [m], drift [m/s]
    gnss: GnssEpoch | None = None
    s_code: np.ndarray | None = None  #: S of the code rows [whitened]
    s_rr: np.ndarray | None = None  #: S of the range-rate rows [whitened]
    imu: gtsam.CombinedImuFactor | None = None  #: factor from the previous node to this one
    clk_sqrt_info: np.ndarray | None = None  #: whitening of the clock model from the previous node
    dt: float = 0.0  #: time since the previous node [s]
    params: Any = None  #: preintegration parameters the IMU factor was built with (kept alive with it)
    imu_sqrt_info: np.ndarray | None = None  #: whitening of the IMU factor (upper Cholesky of the information)

    def copy(self) -> WindowNode:
        """A copy whose state arrays and S can change without touching this node (factors are shared)."""
        return replace(self, pose=gtsam.Pose3(self.pose), vel=self.vel.copy(), bias=self.bias.copy(),
                       clk=self.clk.copy(), s_code=None if self.s_code is None else self.s_code.copy(),
                       s_rr=None if self.s_rr is None else self.s_rr.copy())

    def retract(self, d: np.ndarray) -> WindowNode:
        """The node moved by the error-state step ``d`` (shape (17,))."""
        out = self.copy()
        out.pose = self.pose.retract(d[:6])
        out.vel = self.vel + d[VEL:VEL + 3]
        out.bias = self.bias + d[BA:BG + 3]
        out.clk = self.clk + d[CLK:]
        return out

    def attach_gnss(self, gnss: GnssEpoch | None) -> None:
        """Give the node its GNSS epoch with S = 0."""
        self.gnss = gnss
        if gnss is not None:
            self.s_code = np.zeros(len(gnss.code))
            self.s_rr = np.zeros(len(gnss.code))

    def without_outliers(self) -> GnssEpoch | None:
        """The node's GNSS with the rows whose S is non-zero given weight 0."""
        g = self.gnss
        if g is None:
            return None
        return replace(g, w_code=np.where(self.s_code != 0, 0.0, g.w_code), w_rr=np.where(self.s_rr != 0, 0.0, g.w_rr))


def _local(mean: WindowNode, node: WindowNode) -> np.ndarray:
    """Tangent-space difference ``node - mean`` (GTSAM Pose3 local coordinates for the pose)."""
    d = np.empty(NS)
    d[:6] = mean.pose.localCoordinates(node.pose)
    d[VEL:VEL + 3] = node.vel - mean.vel
    d[BA:BG + 3] = node.bias - mean.bias
    d[CLK:] = node.clk - mean.clk
    return d


class GnssTerms(NamedTuple):
    """Whitened GNSS errors of a window, R pseudorange rows then R range-rate rows."""

    e: np.ndarray  #: (2R,) whitened errors without S, ``g(X) - z`` (weight-0 rows are 0)
    J: np.ndarray | None  #: (2R, 17) whitened Jacobian w.r.t. the row's own node, or None when not asked
    w: np.ndarray  #: (2R,) weights (0: row not used)
    bounds: list[tuple[int, int, int]]  #: (node index, first row, stop row) of each GNSS node within an R-block


def window_gnss_terms(nodes: list[WindowNode], jacobian: bool = True) -> GnssTerms | None:
    """Whitened GNSS errors (and Jacobian) of every node, vectorised over the window; None without GNSS."""
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
    rng, grad = sagnac_range_gradient(sat_pos, p)
    rdot, d_pos, d_vel = range_rate(sat_pos, sat_vel, p, v)
    R = len(z_code)
    e = np.concatenate([rng + clk[:, 0] - z_code, rdot + clk[:, 1] - z_rr]) * w
    if not jacobian:
        return GnssTerms(e, None, w, bounds)
    rot = np.repeat(np.array([nodes[i].pose.rotation().matrix() for i in idx]), counts, axis=0)
    J = np.zeros((2 * R, NS))
    # the Pose3 tangent moves the position along body axes: dp = R dt
    J[:R, POS:POS + 3] = np.einsum("rj,rjk->rk", grad, rot)
    J[:R, CLK] = 1.0
    J[R:, POS:POS + 3] = np.einsum("rj,rjk->rk", d_pos, rot)
    J[R:, VEL:VEL + 3] = d_vel
    J[R:, DRIFT] = 1.0
    J *= w[:, None]
    return GnssTerms(e, J, w, bounds)


def _s_of(nodes: list[WindowNode]) -> np.ndarray:
    """S of every GNSS node in :func:`window_gnss_terms` row order (codes, then range rates)."""
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
    """The window: nodes, prior, factors, Algorithm 1, the EKF update and marginalisation.

    Parameters
    ----------
    cfg : GnssInsConfig
        IMU stochastic model and clock noise.
    window : int
        L, number of GNSS epochs in the window (L + 1 states).
    lambdas : tuple of float
        Soft thresholds ``(lambda_rho, lambda_d)`` [whitened]; ``inf`` disables the S step.
    max_iterations : int
        Algorithm 1 iteration cap.
    tol : float
        Convergence threshold on ``|dX|_2`` and ``|dS|_2``.
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
        self.nodes: list[WindowNode] = []
        self.prior_mean: WindowNode | None = None
        self.prior_R = np.eye(NS)
        self.prior_r = np.zeros(NS)
        self._ne = None

    # ---------------------------------------------------------------- building

    @property
    def full(self) -> bool:
        """The window holds L + 1 states: the next epoch marginalises the oldest."""
        return len(self.nodes) == self.window + 1

    def start(self, node: WindowNode, sigmas: np.ndarray, gnss: GnssEpoch | None) -> None:
        """First state, its diagonal prior (sigmas in the 17 error-state units) and its GNSS epoch."""
        self.nodes = [node]
        self.prior_mean = node.copy()
        self.prior_R = np.diag(1.0 / np.asarray(sigmas, float))
        self.prior_r = np.zeros(NS)
        node.attach_gnss(gnss)
        self._ne = None

    def predict(self, f_b: np.ndarray, w_b: np.ndarray, dt: np.ndarray) -> WindowNode:
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
        return WindowNode(pose=ns.pose(), vel=np.asarray(ns.velocity()), bias=last.bias.copy(), clk=F @ last.clk,
                          imu=gtsam.CombinedImuFactor(X(n - 1), V(n - 1), X(n), V(n), B(n - 1), B(n), pim),
                          clk_sqrt_info=sqrt_info, dt=total, params=params,
                          imu_sqrt_info=np.linalg.cholesky(np.linalg.inv(pim.preintMeasCov())).T)

    def append(self, node: WindowNode, gnss: GnssEpoch | None) -> None:
        """Add a predicted node with its GNSS epoch; marginalise the oldest when the window overflows."""
        node.attach_gnss(gnss)
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

    def _pair_terms(self, nodes: list[WindowNode], i: int,
                    jacobian: bool = True) -> tuple[np.ndarray | None, np.ndarray, slice]:
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
        Hs = [Hall[:, lo:hi] for lo, hi in ((0, 6), (6, 9), (9, 15), (15, 18), (18, 24), (24, 30))]
        rhs[:15] = -W @ b.imu.evaluateError(a.pose, a.vel, b.pose, b.vel, bi, bj, *Hs)
        WH = W @ Hall
        A = np.zeros((17, 2 * NS))
        # GTSAM's key order: pose_i, vel_i, pose_j, vel_j, bias_i, bias_j
        A[:15, 0:9] = WH[:, 0:9]
        A[:15, NS:NS + 9] = WH[:, 9:18]
        A[:15, BA:BA + 6] = WH[:, 18:24]
        A[:15, NS + BA:NS + BA + 6] = WH[:, 24:30]
        A[15:, CLK:CLK + 2] = -Wc @ F
        A[15:, NS + CLK:NS + CLK + 2] = Wc
        return A, rhs, sl

    def _prior_terms(self, nodes: list[WindowNode]) -> tuple[np.ndarray, np.ndarray, slice]:
        e = self.prior_R @ _local(self.prior_mean, nodes[0]) - self.prior_r
        return self.prior_R, -e, slice(0, NS)

    def _terms(self, nodes: list[WindowNode],
               jacobian: bool = True) -> Iterator[tuple[np.ndarray | None, np.ndarray, slice]]:
        """Prior, IMU and clock factors as (A, b, columns); GNSS is handled vectorised."""
        yield self._prior_terms(nodes)
        for i in range(1, len(nodes)):
            yield self._pair_terms(nodes, i, jacobian)

    def _normal_equations(self, nodes: list[WindowNode],
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
        g = window_gnss_terms(nodes)
        if g is not None:
            b = -(g.e + _s_of(nodes) * (g.w > 0))
            R = len(g.e) // 2
            for i, lo, hi in g.bounds:
                if gnss_nodes is not None and i not in gnss_nodes:
                    continue
                Jc, Jr, bc, br = g.J[lo:hi], g.J[R + lo:R + hi], b[lo:hi], b[R + lo:R + hi]
                sl = slice(NS * i, NS * (i + 1))
                H[sl, sl] += Jc.T @ Jc + Jr.T @ Jr
                eta[sl] += Jc.T @ bc + Jr.T @ br
                sq += float(bc @ bc + br @ br)
        return H, eta, sq

    def _weighted_s_l1(self, nodes: list[WindowNode]) -> float:
        """``sum lambda_i |S_i|`` over the window."""
        tot = 0.0
        for n in nodes:
            # with an infinite threshold S stays 0 and adds nothing (inf * 0 would be NaN)
            if n.gnss is not None and np.isfinite(self.lam_rho):
                tot += self.lam_rho * np.abs(n.s_code).sum()
            if n.gnss is not None and np.isfinite(self.lam_d):
                tot += self.lam_d * np.abs(n.s_rr).sum()
        return float(tot)

    def cost(self, nodes: list[WindowNode] | None = None) -> float:
        """``|z - g(X) - S|^2 + 2 sum lambda |S|`` of the window."""
        nodes = self.nodes if nodes is None else nodes
        sq = 0.0
        for _, b, _ in self._terms(nodes, jacobian=False):
            sq += float(b @ b)
        g = window_gnss_terms(nodes, jacobian=False)
        if g is not None:
            sq += float(np.sum((g.e + _s_of(nodes) * (g.w > 0)) ** 2))
        return sq + 2.0 * self._weighted_s_l1(nodes)

    # ---------------------------------------------------------------- solving

    def x_step(self, line_search: bool = True) -> tuple[float, float]:
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
        s_pen = 2.0 * self._weighted_s_l1(self.nodes)  # S is fixed during the X step
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

    def s_step(self) -> float:
        """Closed-form S update (eq. 14) on all GNSS residuals; returns |dS|_2."""
        g = window_gnss_terms(self.nodes, jacobian=False)
        if g is None:
            return 0.0
        R = len(g.e) // 2
        lam = np.concatenate([np.full(R, self.lam_rho), np.full(R, self.lam_d)])
        new = soft_threshold(-g.e, lam) * (g.w > 0)  # c = z - g(X), whitened
        old = _s_of(self.nodes)
        for i, lo, hi in g.bounds:
            self.nodes[i].s_code, self.nodes[i].s_rr = new[lo:hi], new[R + lo:R + hi]
        self._ne = None
        return float(np.linalg.norm(new - old))

    def solve(self, record: bool = False) -> tuple[int, list[tuple[float, ...]]]:
        """Algorithm 1 on the current window. Returns the iteration count and (if asked) the table rows.

        Table rows are ``(i, |b|_2, |S|_1, |dX|_2, |dS|_1)`` (the paper's Table 1).
        """
        table: list[tuple[float, ...]] = []
        use_s = np.isfinite(self.lam_rho) or np.isfinite(self.lam_d)
        i = 0
        while i < self.max_iterations:
            i += 1
            s_before = self.s_l1_norm()
            b_norm, dx = self.x_step()
            if record:
                table.append((i, b_norm, s_before, dx, 0.0))
            if dx < self.tol:
                if not use_s:
                    break
                s_old = _s_of(self.nodes)
                ds = self.s_step()
                b_norm, dx = self.x_step()
                if record:
                    table.append((i, b_norm, self.s_l1_norm(), dx, float(np.abs(_s_of(self.nodes) - s_old).sum())))
                if dx < self.tol and ds < self.tol:
                    break
        return i, table

    def s_l1_norm(self) -> float:
        """``|S|_1`` over the window [whitened units]."""
        return float(np.abs(_s_of(self.nodes)).sum())

    def ekf_update(self, gate: float) -> int:
        """EKF update of the newest node (one linearisation at the prediction), with innovation gating.

        Returns the number of GNSS rows rejected by the gate.
        """
        last = len(self.nodes) - 1
        node = self.nodes[last]
        if node.gnss is None:
            self.x_step(line_search=False)
            return 0
        H0, _, _ = self._normal_equations(self.nodes, gnss_nodes=set(range(last)))
        P = np.linalg.inv(H0)[-NS:, -NS:]
        g = window_gnss_terms(self.nodes)
        R = len(g.e) // 2
        _, lo, hi = g.bounds[-1]
        rows = np.r_[lo:hi, R + lo:R + hi]
        e, J, w = g.e[rows], g.J[rows], g.w[rows]
        var = np.einsum("ij,jk,ik->i", J, P, J) + (w > 0)
        bad = (np.abs(e) > gate * np.sqrt(np.maximum(var, 1e-30))) & (w > 0)
        if bad.any():
            k = len(node.gnss.code)
            node.gnss = replace(node.gnss, w_code=np.where(bad[:k], 0.0, node.gnss.w_code),
                                w_rr=np.where(bad[k:], 0.0, node.gnss.w_rr))
            self._ne = None
        self.x_step(line_search=False)
        return int(bad.sum())

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
            n.gnss = n.without_outliers()
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
