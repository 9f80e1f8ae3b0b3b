"""The sliding-window GNSS/INS MAP engine behind CRT-LSS, the IEKF and the EKF.

The window holds the states of L + 1 GNSS epochs ``x_{k-L} .. x_k`` and the GNSS
measurements of the last L of them. Per state (17 error-state components, in
this order, offsets :data:`ROT` .. :data:`DRIFT`): attitude (3, body frame,
GTSAM ``Pose3`` tangent), position (3, body frame), ECEF velocity (3),
accelerometer and gyro bias (3 + 3), receiver clock (m) and clock drift (m/s).
Factors, all whitened:

* a Gaussian prior on ``x_{k-L}`` (the marginal of everything that left the window);
* GTSAM ``CombinedImuFactor`` between consecutive states (IMU preintegration,
  see :mod:`estimators.gnss_ins.mechanisation`), linearised natively in C++ (one
  call per pair; whitening and assembly are batched over the window,
  :func:`pair_terms`);
* a two-state receiver clock model (bias and drift, Allan h0 / h-2);
* per satellite an L1 pseudorange (:class:`estimators.gnss_ins.data.GnssEpoch`)
  and a Doppler range rate ``-lambda D + satellite drift = rdot + receiver drift``,
  with Jacobians in numpy, vectorised over the window's satellites
  (:func:`window_gnss_terms`; range and gradient from
  :func:`simbench.gnss.geometry.sagnac_range_gradient`).

Every factor touches one state or two consecutive ones, so the normal
equations are block tridiagonal: :class:`NormalEquations` keeps the diagonal
blocks and those above them, and a Gauss-Newton step is a banded Cholesky
solve, linear in the window length. What does not depend on the states (the
stacked GNSS measurements, the IMU and clock whitening) is stacked once per
window (:class:`_WindowFactors`), and the linearisation at the current states
is kept until they move (:class:`_Linearisation`: the S step and the next X
step share it).

Arithmetic: the batched products make the BLAS calls of a loop over the pairs
and nodes, with the same operands in the same memory layout, and sums run in
factor order (:func:`_mv`, :func:`_sequential_sum`), so results are those of
a per-factor loop bit for bit. That is worth keeping: the stopping rule, the
line search and the soft threshold are discontinuous, and a round-off change
in one step grows into decimetres to metres over a drive.

Cost, with ``b`` the whitened residuals (paper eq. 6)::

    C(X, S) = || z - g(X) - S ||^2 + 2 sum_i lambda_i |S_i|

``S`` has one entry per GNSS residual, in whitened units. Algorithm 1
(:meth:`WindowSolver.solve`): Gauss-Newton steps on ``X`` with a backtracking
line search given ``S`` (:meth:`WindowSolver.x_step`); when the step is below
``tol``, the S step ``S_i = sign(c_i) max(|c_i| - lambda_i, 0)`` with
``c = z - g(X)`` (eq. 14, :meth:`WindowSolver.s_step`) and another X step, that one
on ``min_S C`` (:meth:`WindowSolver.huber_step`); stop when both changes are below
``tol`` or after ``max_iterations``. When the
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

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any, NamedTuple, cast

import gtsam
import numpy as np
from gtsam.symbol_shorthand import B, V, X
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.linalg.lapack import dpbsv

from estimators.gnss_ins.config import GnssInsConfig
from estimators.gnss_ins.data import GnssEpoch
from estimators.gnss_ins.mechanisation import (
    DEG_PER_HOUR,
    ImuNoise,
    preintegration_params,
    rotate_about_vertical,
)
from simbench.core.constants import C_LIGHT, DEG
from simbench.gnss.doppler import range_rate
from simbench.gnss.geometry import sagnac_range_gradient

__all__ = [
    "BA",
    "BG",
    "CLK",
    "DRIFT",
    "NS",
    "POS",
    "ROT",
    "VEL",
    "GnssTerms",
    "NormalEquations",
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
    s[ROT : ROT + 3] = [cfg.roll_pitch_sigma_deg * DEG, cfg.roll_pitch_sigma_deg * DEG, cfg.yaw_sigma_deg * DEG]
    s[POS : POS + 3] = cfg.pos_sigma_m
    s[VEL : VEL + 3] = cfg.vel_sigma_mps
    s[BA : BA + 3] = cfg.accel_bias_sigma_mps2
    s[BG : BG + 3] = cfg.gyro_bias_sigma_dph * DEG_PER_HOUR
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
        return self._with_state(gtsam.Pose3(self.pose), self.vel.copy(), self.bias.copy(), self.clk.copy(), True)

    def retract(self, d: np.ndarray) -> WindowNode:
        """The node moved by the error-state step ``d`` (shape (17,)), S shared as in :func:`retracted`."""
        return retracted([self], d)[0]

    def _with_state(
        self, pose: gtsam.Pose3, vel: np.ndarray, bias: np.ndarray, clk: np.ndarray, copy_s: bool
    ) -> WindowNode:
        """A node with this one's factors, its S (a copy if ``copy_s``) and the given (new, unshared) state."""
        # a shallow copy by hand: dataclasses.replace (re-running __init__) and copy.copy (generic protocol)
        # cost more than the pose retraction, once per node and Gauss-Newton trial
        out = object.__new__(WindowNode)
        out.__dict__.update(self.__dict__)
        out.pose, out.vel, out.bias, out.clk = pose, vel, bias, clk
        if copy_s:
            out.s_code = None if self.s_code is None else self.s_code.copy()
            out.s_rr = None if self.s_rr is None else self.s_rr.copy()
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
    d[VEL : VEL + 3] = node.vel - mean.vel
    d[BA : BG + 3] = node.bias - mean.bias
    d[CLK:] = node.clk - mean.clk
    return d


class GnssTerms(NamedTuple):
    """Whitened GNSS errors of a window, R pseudorange rows then R range-rate rows."""

    e: np.ndarray  #: (2R,) whitened errors without S, ``g(X) - z`` (weight-0 rows are 0)
    J: np.ndarray | None  #: (2R, 17) whitened Jacobian w.r.t. the row's own node, or None when not asked
    w: np.ndarray  #: (2R,) weights (0: row not used)
    bounds: list[tuple[int, int, int]]  #: (node index, first row, stop row) of each GNSS node within an R-block


class _GnssLayout(NamedTuple):
    """The GNSS measurements of a window stacked in :func:`window_gnss_terms` row order.

    They change when a node gets, loses or reweights its GNSS epoch, not when
    the states move: one layout serves every Gauss-Newton step and line-search
    trial of a window.
    """

    idx: list[int]  #: window index of each GNSS node
    node: np.ndarray  #: (m,) ``idx`` as an index array
    bounds: list[tuple[int, int, int]]  #: (node index, first row, stop row) of each GNSS node within an R-block
    counts: np.ndarray  #: (m,) satellites of each GNSS node
    width: int  #: most satellites of a node
    padded: np.ndarray  #: (2R,) flat position of each row in a zero-padded (m, code / range rate, width) stack
    sat_pos: np.ndarray  #: (R, 3) m, satellite ECEF position at transmit time
    sat_vel: np.ndarray  #: (R, 3) m/s
    z_code: np.ndarray  #: (R,) m
    z_rr: np.ndarray  #: (R,) m/s
    w: np.ndarray  #: (2R,) weights of the code then the range-rate rows (0: row not used)
    used: np.ndarray  #: (2R,) ``w > 0``, the rows in use


def _gnss_layout(nodes: list[WindowNode]) -> _GnssLayout:
    """:class:`_GnssLayout` of a window (``idx`` empty without GNSS)."""
    idx = [i for i, n in enumerate(nodes) if n.gnss is not None]
    gs = [g for n in nodes if (g := n.gnss) is not None]
    counts = np.array([len(g.code) for g in gs], dtype=np.int_)
    stops = np.cumsum(counts)
    bounds = [(i, int(b - c), int(b)) for i, b, c in zip(idx, stops, counts)]
    if not idx:
        none = np.zeros(0)
        return _GnssLayout(
            idx=idx,
            node=np.zeros(0, int),
            bounds=bounds,
            counts=counts,
            width=0,
            padded=np.zeros(0, int),
            sat_pos=np.zeros((0, 3)),
            sat_vel=np.zeros((0, 3)),
            z_code=none,
            z_rr=none,
            w=none,
            used=np.zeros(0, bool),
        )
    width = int(counts.max())
    slot = np.arange(stops[-1]) - np.repeat(stops - counts, counts)  # row number within its node
    first = np.repeat(2 * width * np.arange(len(idx)), counts) + slot
    w = np.concatenate([np.concatenate([g.w_code for g in gs]), np.concatenate([g.w_rr for g in gs])])
    w.flags.writeable = False  # handed out in every GnssTerms of the window
    return _GnssLayout(
        idx,
        np.array(idx),
        bounds,
        counts,
        width,
        np.concatenate([first, first + width]),
        np.concatenate([g.sat_pos for g in gs]),
        np.concatenate([g.sat_vel for g in gs]),
        np.concatenate([g.code for g in gs]),
        np.concatenate([g.rr for g in gs]),
        w,
        w > 0,
    )


def window_gnss_terms(
    nodes: list[WindowNode], jacobian: bool = True, layout: _GnssLayout | None = None
) -> GnssTerms | None:
    """Whitened GNSS errors (and Jacobian) of every node, vectorised over the window; None without GNSS.

    ``layout`` is :func:`_gnss_layout` of ``nodes`` when the caller keeps it.
    """
    lay = _gnss_layout(nodes) if layout is None else layout
    if not lay.idx:
        return None
    poses = np.array([nodes[i].pose.matrix() for i in lay.idx])  # (m, 4, 4): rotation and translation in one call
    p = np.repeat(poses[:, :3, 3], lay.counts, axis=0)
    v = np.repeat(np.array([nodes[i].vel for i in lay.idx]), lay.counts, axis=0)
    clk = np.repeat(np.array([nodes[i].clk for i in lay.idx]), lay.counts, axis=0)
    rng, grad = sagnac_range_gradient(lay.sat_pos, p)
    rdot, d_pos, d_vel = range_rate(lay.sat_pos, lay.sat_vel, p, v)
    R = len(lay.z_code)
    e = np.concatenate([rng + clk[:, 0] - lay.z_code, rdot + clk[:, 1] - lay.z_rr]) * lay.w
    if not jacobian:
        return GnssTerms(e, None, lay.w, lay.bounds)
    rot = np.repeat(poses[:, :3, :3], lay.counts, axis=0)
    J = np.zeros((2 * R, NS))
    # the Pose3 tangent moves the position along body axes: dp = R dt
    J[:R, POS : POS + 3] = np.einsum("rj,rjk->rk", grad, rot)
    J[:R, CLK] = 1.0
    J[R:, POS : POS + 3] = np.einsum("rj,rjk->rk", d_pos, rot)
    J[R:, VEL : VEL + 3] = d_vel
    J[R:, DRIFT] = 1.0
    J *= lay.w[:, None]
    return GnssTerms(e, J, lay.w, lay.bounds)


def _norm(x: np.ndarray) -> float:
    """``np.linalg.norm`` of a vector (the same ``sqrt(x . x)``) without its generic dispatch."""
    return math.sqrt(float(x.dot(x)))


def _mv(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Stacked matrix-vector products ``M[k] @ v[k]``, one BLAS call per k like a loop (einsum sums otherwise)."""
    return (M @ v[..., None])[..., 0]


def _sequential_sum(values: np.ndarray) -> float:
    """Left-to-right sum, the order of a loop over the factors (``np.sum`` is pairwise)."""
    return float(np.add.accumulate(values)[-1])


def _gnss_blocks(
    g: GnssTerms, b: np.ndarray, lay: _GnssLayout, curvature: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Normal-equation terms of each GNSS node's code and range-rate rows.

    The rows are scattered into a zero-padded (node, code / range rate, row, 17)
    stack so that batched products replace a loop over the nodes; padding rows
    add exact zeros.

    Parameters
    ----------
    g : GnssTerms
        The window's GNSS terms with their Jacobian.
    b : ndarray, shape (2R,)
        Whitened right-hand side of the rows, ``-(e + S)``.
    lay : _GnssLayout
        The window's GNSS layout.
    curvature : ndarray of bool, shape (2R,), optional
        Rows that enter ``JtJ`` (default all); every row enters ``Jtb`` and ``bb``.

    Returns
    -------
    JtJ : ndarray, shape (m, 17, 17)
    Jtb : ndarray, shape (m, 17)
    bb : ndarray, shape (m,)
        ``|b|^2`` of each node's rows [whitened, dimensionless], nodes in ``lay.idx`` order.
    """
    shape = (len(lay.idx), 2, lay.width)
    J: np.ndarray = np.zeros((np.prod(shape), NS))
    r: np.ndarray = np.zeros(len(J))
    J[lay.padded] = g.J
    r[lay.padded] = b
    J, r = J.reshape(*shape, NS), r.reshape(shape)
    Jt = J.swapaxes(-1, -2)
    Jtb, bb = _mv(Jt, r), (r[..., None, :] @ r[..., None])[..., 0, 0]
    if curvature is None:
        JtJ = Jt @ J
    else:
        keep = np.zeros(r.size)
        keep[lay.padded] = curvature
        Jc = J * keep.reshape(shape)[..., None]
        JtJ = Jc.swapaxes(-1, -2) @ Jc
    return JtJ[:, 0] + JtJ[:, 1], Jtb[:, 0] + Jtb[:, 1], bb[:, 0] + bb[:, 1]


def _s_of(nodes: list[WindowNode]) -> np.ndarray:
    """S of every GNSS node in :func:`window_gnss_terms` row order (codes, then range rates)."""
    with_g = [n for n in nodes if n.gnss is not None]
    if not with_g:
        return np.zeros(0)
    # a node with GNSS has its S (attach_gnss)
    return np.concatenate([cast(np.ndarray, n.s_code) for n in with_g] + [cast(np.ndarray, n.s_rr) for n in with_g])


#: Row ranges, in a (30, 15) slab per pair, of GTSAM's CombinedImuFactor Jacobians w.r.t. pose_i, vel_i, pose_j,
#: vel_j, bias_i and bias_j: each range transposed is the column-major (15, k) array GTSAM writes into.
_IMU_BLOCKS = ((0, 6), (6, 9), (9, 15), (15, 18), (18, 24), (24, 30))
#: Column of a pair's Jacobian (the 17 error states of node i-1, then those of node i) of each of those 30 columns.
_IMU_COLUMNS = np.r_[ROT : VEL + 3, NS + ROT : NS + VEL + 3, BA : BG + 3, NS + BA : NS + BG + 3]


class _WindowFactors(NamedTuple):
    """The factors of a window, stacked: they stay while its states move.

    One instance serves every Gauss-Newton step and line-search trial of a
    window; it changes when a node is added or leaves, or when a node's GNSS
    rows change. P = n - 1 pairs of consecutive nodes.
    """

    gnss: _GnssLayout  #: the GNSS measurements
    W: np.ndarray  #: (P, 15, 15) whitening of each pair's IMU factor
    Wc: np.ndarray  #: (P, 2, 2) whitening of each pair's clock model
    F: np.ndarray  #: (P, 2, 2) clock transition over each pair's interval
    slab: np.ndarray  #: (P, 30, 15) where GTSAM writes each pair's IMU Jacobians (scratch)
    outputs: list[list[np.ndarray]]  #: per pair, the six column-major views of its slab GTSAM writes into


def window_factors(nodes: list[WindowNode]) -> _WindowFactors:
    """:class:`_WindowFactors` of a window (node ``k >= 1`` holds the factors from node ``k - 1``)."""
    later = nodes[1:]
    # stacked column-major like each factor (a transposed Cholesky factor): the batched products then run the
    # BLAS kernels of per-pair ones and give the same bits
    W = np.array([cast(np.ndarray, n.imu_sqrt_info).T for n in later]).reshape(-1, 15, 15).swapaxes(-1, -2)
    Wc = np.array([cast(np.ndarray, n.clk_sqrt_info).T for n in later]).reshape(-1, 2, 2).swapaxes(-1, -2)
    F = np.tile(np.eye(2), (len(later), 1, 1))
    F[:, 0, 1] = [n.dt for n in later]
    slab = np.zeros((len(later), 30, 15))
    outputs = [[slab[k, lo:hi].T for lo, hi in _IMU_BLOCKS] for k in range(len(later))]
    return _WindowFactors(_gnss_layout(nodes), W, Wc, F, slab, outputs)


class _Linearisation(NamedTuple):
    """A window's whitened factors linearised at its states; S enters when the normal equations are assembled."""

    R0: np.ndarray  #: (17, 17) Jacobian of the prior w.r.t. the first node
    b0: np.ndarray  #: (17,) minus the prior's whitened error
    A: np.ndarray  #: (n - 1, 17, 34) IMU and clock Jacobians of each pair (:func:`pair_terms`)
    b: np.ndarray  #: (n - 1, 17) minus their whitened errors
    gnss: GnssTerms | None  #: GNSS rows with their Jacobian, None without GNSS


def pair_terms(
    nodes: list[WindowNode], factors: _WindowFactors, jacobian: bool = True
) -> tuple[np.ndarray | None, np.ndarray]:
    """IMU and clock factors of every two consecutive nodes, stacked over the window.

    GTSAM evaluates each ``CombinedImuFactor`` (one C++ call per pair: every
    Gauss-Newton step moves every state, so each pair is relinearised); the
    whitening and the placement into the pair's columns are batched.

    Parameters
    ----------
    nodes : list of WindowNode
        The window.
    factors : _WindowFactors
        Its factors.
    jacobian : bool
        Also return the Jacobians.

    Returns
    -------
    A : ndarray, shape (n - 1, 17, 34), or None when not asked
        Whitened Jacobian of pair ``k`` w.r.t. the error states of nodes ``k``
        and ``k + 1``: 15 IMU rows (GTSAM's error order), then clock and drift.
    b : ndarray, shape (n - 1, 17)
        Minus the whitened errors [dimensionless].
    """
    pairs = len(nodes) - 1
    biases = [gtsam.imuBias.ConstantBias(n.bias[:3], n.bias[3:]) for n in nodes]
    err = np.empty((pairs, 15))
    for k in range(pairs):
        a, b = nodes[k], nodes[k + 1]
        assert b.imu is not None  # every node after the first holds the IMU factor leading into it
        err[k] = b.imu.evaluateError(
            a.pose, a.vel, b.pose, b.vel, biases[k], biases[k + 1], *(factors.outputs[k] if jacobian else ())
        )
    clk = np.array([n.clk for n in nodes])
    rhs = np.empty((pairs, NS))
    rhs[:, :15] = -_mv(factors.W, err)
    rhs[:, 15:] = -_mv(factors.Wc, clk[1:] - _mv(factors.F, clk[:-1]))
    if not jacobian:
        return None, rhs
    A = np.zeros((pairs, NS, 2 * NS))
    A[:, :15, _IMU_COLUMNS] = factors.W @ factors.slab.swapaxes(-1, -2)
    A[:, 15:, CLK : CLK + 2] = -factors.Wc @ factors.F
    A[:, 15:, NS + CLK : NS + CLK + 2] = factors.Wc
    return A, rhs


@lru_cache(maxsize=4)  # a window grows one state per epoch, then keeps its size
def _band_layout(n: int) -> tuple[int, np.ndarray, np.ndarray]:
    """Where the upper triangle of an n-state block-tridiagonal H goes in LAPACK upper band storage.

    Returns
    -------
    bw : int
        Rows of the band storage ``ab`` (17 n columns), ``ab[bw - 1 + r - c, c] = H[r, c]``.
    dst, src : ndarray of int
        ``ab.ravel()[dst] = concatenate([D.ravel(), U.ravel()])[src]`` fills
        ``ab`` with the upper triangles of the diagonal blocks and the blocks
        above them (read-only: shared by every call).
    """
    bw = min(2 * NS, NS * n)  # a block above the diagonal reaches 2 NS - 1 columns right of it
    cols = NS * n
    k = np.arange(n)[:, None]
    i, j = np.triu_indices(NS)  # diagonal blocks, upper triangle
    d_dst = (bw - 1 + i - j) * cols + NS * k + j
    d_src = NS * NS * k + NS * i + j
    iu, ju = np.divmod(np.arange(NS * NS), NS)  # blocks above the diagonal: node k's rows, node k + 1's columns
    u_dst = (bw - 1 + iu - ju - NS) * cols + NS * k[:-1] + NS + ju
    u_src = NS * NS * n + np.arange(NS * NS * (n - 1))
    dst, src = np.concatenate([d_dst.ravel(), u_dst.ravel()]), np.concatenate([d_src.ravel(), u_src])
    dst.flags.writeable = src.flags.writeable = False
    return bw, dst, src


class NormalEquations(NamedTuple):
    """Gauss-Newton normal equations ``H dx = eta`` (``H = G^T G``, ``eta = G^T b``) of a window of n states.

    The prior and the GNSS rows touch one state, the IMU and clock factors two
    consecutive ones: H is block tridiagonal and only its diagonal blocks and
    the blocks above them are kept.
    """

    D: np.ndarray  #: (n, 17, 17) diagonal blocks of H
    U: np.ndarray  #: (n - 1, 17, 17) blocks ``H[k, k + 1]`` above the diagonal
    eta: np.ndarray  #: (17 n,) ``G^T b``
    sq: float  #: ``|b|^2``, the cost without the S penalty

    def solve(self) -> np.ndarray:
        """``dx`` (17 n,) by banded Cholesky (LAPACK ``pbsv``): linear in n where a dense solve is cubic."""
        n = len(self.D)
        bw, dst, src = _band_layout(n)
        ab = np.zeros((bw, NS * n))
        ab.ravel()[dst] = np.concatenate([self.D.ravel(), self.U.ravel()])[src]
        ab[-1] += 1e-12  # the prior and IMU chain make H positive definite; guard round-off only
        # LAPACK's pbsv as scipy.linalg.solveh_banded calls it, without its per-call validation
        _, dx, info = dpbsv(ab, self.eta, lower=0, overwrite_ab=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"banded Cholesky failed: LAPACK pbsv info {info}")
        return cast(np.ndarray, dx)

    def dense(self) -> np.ndarray:
        """H as a dense (17 n, 17 n) array."""
        n = len(self.D)
        k = np.arange(n)
        H = np.zeros((n, NS, n, NS))
        H[k, :, k, :] = self.D
        H[k[:-1], :, k[1:], :] = self.U
        H[k[1:], :, k[:-1], :] = self.U.transpose(0, 2, 1)
        return H.reshape(NS * n, NS * n)


def upper_cholesky(info: np.ndarray) -> np.ndarray:
    """Upper triangular ``R`` with ``R^T R = info`` for a marginal information matrix.

    The Schur complement of a window whose states span metres and
    microradians can come out a hair indefinite by cancellation; then its
    eigenvalues are floored at 1e-9 of the largest (the nearest positive
    definite matrix keeps every direction the data inform) before the
    factorisation.
    """
    jitter = 1e-12 * np.eye(len(info))
    try:
        return np.linalg.cholesky(info + jitter).T
    except np.linalg.LinAlgError:
        w, v = np.linalg.eigh(info)
        w = np.maximum(w, 1e-9 * w.max())
        return np.linalg.cholesky((v * w) @ v.T + jitter).T


def retracted(nodes: list[WindowNode], dx: np.ndarray) -> list[WindowNode]:
    """The nodes moved by the error-state step ``dx`` (shape (17 n,)), sharing their S arrays.

    S is never changed in place (:meth:`WindowSolver.s_step` hands each node new
    arrays), so a retracted window and the one it came from can share it.
    """
    d = dx.reshape(len(nodes), NS)
    # the vector states move in one addition each; only the pose retraction (GTSAM) is per node
    vel = np.array([n.vel for n in nodes]) + d[:, VEL : VEL + 3]
    bias = np.array([n.bias for n in nodes]) + d[:, BA : BG + 3]
    clk = np.array([n.clk for n in nodes]) + d[:, CLK:]
    return [n._with_state(n.pose.retract(dn[:6]), v, b, c, False) for n, dn, v, b, c in zip(nodes, d, vel, bias, clk)]


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

    def __init__(
        self, cfg: GnssInsConfig, window: int, lambdas: tuple[float, float], max_iterations: int, tol: float
    ) -> None:
        self.cfg = cfg
        self.window = window
        self.lam_rho, self.lam_d = lambdas
        self.max_iterations = max_iterations
        self.tol = tol
        self.noise = ImuNoise.from_datasheet(
            cfg.accel_noise_mps2_rthz,
            cfg.gyro_noise_dph_rthz,
            cfg.accel_bias_instability_mps2,
            cfg.gyro_bias_instability_dph,
            cfg.bias_tau_s,
        )
        self.nodes: list[WindowNode] = []
        self.prior_mean: WindowNode | None = None
        self.prior_R = np.eye(NS)
        self.prior_r = np.zeros(NS)
        self._ne: NormalEquations | None = None  # at the current nodes
        self._lin: _Linearisation | None = None  # at the current nodes
        self._factors: _WindowFactors | None = None  # of the current nodes
        self._s_penalty: float | None = None  # 2 sum lambda |S| of the current nodes
        self._s: np.ndarray | None = None  # S of the current nodes in GNSS row order (_s_of)

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
        self._factors_changed()

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
        return WindowNode(
            pose=ns.pose(),
            vel=np.asarray(ns.velocity()),
            bias=last.bias.copy(),
            clk=F @ last.clk,
            imu=gtsam.CombinedImuFactor(X(n - 1), V(n - 1), X(n), V(n), B(n - 1), B(n), pim),
            clk_sqrt_info=sqrt_info,
            dt=total,
            params=params,
            imu_sqrt_info=np.linalg.cholesky(np.linalg.inv(pim.preintMeasCov())).T,
        )

    def append(self, node: WindowNode, gnss: GnssEpoch | None) -> None:
        """Add a predicted node with its GNSS epoch; marginalise the oldest when the window overflows."""
        node.attach_gnss(gnss)
        self.nodes.append(node)
        self._factors_changed()
        if len(self.nodes) > self.window + 1:
            self._marginalise_oldest()

    def rotate_heading(self, angle: float) -> None:
        """Turn every state's attitude and velocity, and the prior mean, about the local vertical."""
        R = rotate_about_vertical(self.nodes[-1].pose.translation(), angle)
        assert self.prior_mean is not None  # set by start
        for node in [*self.nodes, self.prior_mean]:
            node.pose = gtsam.Pose3(gtsam.Rot3(R @ node.pose.rotation().matrix()), node.pose.translation())
            node.vel = R @ node.vel
        self._ne, self._lin = None, None

    def _factors_changed(self) -> None:
        """A node came or left, or its GNSS rows changed: drop everything derived from the window."""
        self._ne, self._lin, self._factors, self._s_penalty, self._s = None, None, None, None, None

    def _s_vector(self) -> np.ndarray:
        """:func:`_s_of` the current nodes, kept until an S step or a change of the window.

        X steps and retractions keep S.
        """
        if self._s is None:
            self._s = _s_of(self.nodes)
        return self._s

    def _stacked_factors(self) -> _WindowFactors:
        """:func:`window_factors` of the current nodes, kept until :meth:`_factors_changed`."""
        if self._factors is None:
            self._factors = window_factors(self.nodes)
        return self._factors

    # ---------------------------------------------------------------- linearisation

    def _prior_terms(self, nodes: list[WindowNode]) -> tuple[np.ndarray, np.ndarray]:
        """Whitened Jacobian (17 x 17) of the prior w.r.t. the first node and b = -error."""
        assert self.prior_mean is not None  # set by start
        e = self.prior_R @ _local(self.prior_mean, nodes[0]) - self.prior_r
        return self.prior_R, -e

    def _linearise(self, nodes: list[WindowNode], factors: _WindowFactors) -> _Linearisation:
        """Every factor of a window with the given factors, linearised at its states."""
        R, b0 = self._prior_terms(nodes)
        A, b = pair_terms(nodes, factors)
        assert A is not None  # asked for
        return _Linearisation(R, b0, A, b, window_gnss_terms(nodes, layout=factors.gnss))

    def _linearised(self) -> _Linearisation:
        """:meth:`_linearise` at the current nodes, kept until they move or change."""
        if self._lin is None:
            self._lin = self._linearise(self.nodes, self._stacked_factors())
        return self._lin

    def _normal_equations(
        self,
        nodes: list[WindowNode],
        lin: _Linearisation,
        factors: _WindowFactors,
        gnss_nodes: set[int] | None = None,
        s: np.ndarray | None = None,
        curvature: np.ndarray | None = None,
    ) -> NormalEquations:
        """:class:`NormalEquations` of a window from its linearisation and S (GNSS of ``gnss_nodes`` only).

        ``s`` is :func:`_s_of` ``nodes`` when the caller has it; ``curvature`` (GNSS rows, bool)
        leaves the rows it marks False out of ``H`` but not out of ``eta`` (:meth:`WindowSolver.huber_step`).
        """
        n = len(nodes)
        D = np.zeros((n, NS, NS))
        eta = np.zeros((n, NS))
        R, b0, A, b, g = lin
        D[0] = R.T @ R
        eta[0] = R.T @ b0
        At = A.swapaxes(-1, -2)
        AtA, Atb = At @ A, _mv(At, b)
        D[:-1] += AtA[:, :NS, :NS]
        D[1:] += AtA[:, NS:, NS:]
        eta[:-1] += Atb[:, :NS]
        eta[1:] += Atb[:, NS:]
        squares = [[b0 @ b0], (b[:, None] @ b[..., None]).ravel()]
        if g is not None:
            node = factors.gnss.node
            s = _s_of(nodes) if s is None else s
            JtJ, Jtb, bb = _gnss_blocks(g, -(g.e + s * factors.gnss.used), factors.gnss, curvature)
            if gnss_nodes is not None:
                keep = np.isin(node, sorted(gnss_nodes))
                node, JtJ, Jtb, bb = node[keep], JtJ[keep], Jtb[keep], bb[keep]
            D[node] += JtJ
            eta[node] += Jtb
            squares.append(bb)
        return NormalEquations(D, AtA[:, :NS, NS:], eta.ravel(), _sequential_sum(np.concatenate(squares)))

    def _weighted_s_l1(self, nodes: list[WindowNode]) -> float:
        """``sum lambda_i |S_i|`` over the window."""
        # with an infinite threshold S stays 0 and adds nothing (inf * 0 would be NaN)
        code, rr = np.isfinite(self.lam_rho), np.isfinite(self.lam_d)
        tot = 0.0
        for n in nodes:
            if n.gnss is None:
                continue
            if code:
                tot += self.lam_rho * np.abs(cast(np.ndarray, n.s_code)).sum()
            if rr:
                tot += self.lam_d * np.abs(cast(np.ndarray, n.s_rr)).sum()
        return float(tot)

    def cost(self, nodes: list[WindowNode] | None = None) -> float:
        """``|z - g(X) - S|^2 + 2 sum lambda |S|`` of the window."""
        nodes = self.nodes if nodes is None else nodes
        _, b0 = self._prior_terms(nodes)
        _, b = pair_terms(nodes, window_factors(nodes), jacobian=False)
        sq = float(b0 @ b0) + float(np.sum(b * b))
        g = window_gnss_terms(nodes, jacobian=False)
        if g is not None:
            sq += float(np.sum((g.e + _s_of(nodes) * (g.w > 0)) ** 2))
        return sq + 2.0 * self._weighted_s_l1(nodes)

    # ---------------------------------------------------------------- solving

    def x_step(self, line_search: bool = True) -> tuple[float, float]:
        """One Gauss-Newton step on X given S, with backtracking. Returns (|b|_2 before, |dX|_2 taken).

        The linearisation and normal equations of an accepted trial point are
        kept for the next step: the line search's cost evaluation is then free.
        """
        if self._ne is None:
            self._ne = self._normal_equations(
                self.nodes, self._linearised(), self._stacked_factors(), s=self._s_vector()
            )
        ne = self._ne
        dx = ne.solve()
        step = _norm(dx)
        self._ne = None
        # a step below the tolerance cannot change the cost beyond round-off: take it as is
        if not line_search or step < self.tol:
            self.nodes, self._lin = retracted(self.nodes, dx), None
            return float(np.sqrt(ne.sq)), step
        if self._s_penalty is None:  # S is fixed during X steps: one sum per S step
            self._s_penalty = 2.0 * self._weighted_s_l1(self.nodes)
        s_pen = self._s_penalty
        c0 = ne.sq + s_pen
        factors = self._stacked_factors()  # a retraction keeps the factors
        alpha = 1.0
        for _ in range(6):
            trial = retracted(self.nodes, alpha * dx)
            lin = self._linearise(trial, factors)
            trial_ne = self._normal_equations(trial, lin, factors, s=self._s_vector())  # a retraction keeps S
            if trial_ne.sq + s_pen <= c0 * (1.0 + 1e-12):
                self.nodes, self._lin, self._ne = trial, lin, trial_ne
                return float(np.sqrt(ne.sq)), alpha * step
            alpha *= 0.5
        self._ne = ne
        return float(np.sqrt(ne.sq)), 0.0

    def _thresholded(self, g: GnssTerms) -> np.ndarray:
        """Eq. 14 on the window's whitened GNSS residuals ``c = z - g(X)``: the S that minimises C at X."""
        R = len(g.e) // 2
        lam = np.concatenate([np.full(R, self.lam_rho), np.full(R, self.lam_d)])
        return soft_threshold(-g.e, lam) * (g.w > 0)

    @staticmethod
    def _assign_s(nodes: list[WindowNode], g: GnssTerms, new: np.ndarray) -> None:
        """Hand each GNSS node its slice of ``new`` (new arrays: S is never changed in place)."""
        R = len(g.e) // 2
        for i, lo, hi in g.bounds:
            nodes[i].s_code, nodes[i].s_rr = new[lo:hi], new[R + lo : R + hi]

    def s_step(self) -> float:
        """Closed-form S update (eq. 14) on all GNSS residuals; returns |dS|_2."""
        g = self._linearised().gnss  # the next X step's linearisation: X does not move here
        if g is None:
            return 0.0
        new = self._thresholded(g)
        old = self._s_vector()
        self._assign_s(self.nodes, g, new)
        # the bounds cover the rows in order: the nodes' S, concatenated, is new
        self._ne, self._s_penalty, self._s = None, None, new
        return _norm(new - old)

    def huber_step(self) -> tuple[float, float]:
        """One Gauss-Newton step on ``h(X) = min_S C(X, S)``, S re-thresholded (eq. 14) at every point.

        Minimised over S in closed form, C is Huber's cost of the whitened GNSS residuals: a row
        whose S is non-zero contributes ``2 lambda |c| - lambda^2``, linear in its residual, so it
        has a gradient but no curvature. The step therefore leaves those rows out of ``H`` and
        keeps them in ``eta`` (which, with S from the S step just taken, is the gradient of h).
        Plain X steps with S fixed move along the valley between X and S by a ratio of about
        0.85 per S step (20 iterations left ``|dS|`` at 0.1); this step crosses it, and C
        decreases at every accepted step as in Algorithm 1. The backtracking tests h, with S
        thresholded at each trial point. Returns (|b|_2 before, |dX|_2 taken), S set at the new X.
        """
        lin = self._linearised()
        if lin.gnss is None:
            return self.x_step()
        factors = self._stacked_factors()
        s = self._s_vector()
        ne = self._normal_equations(self.nodes, lin, factors, s=s, curvature=(s == 0))
        dx = ne.solve()
        step = _norm(dx)
        h0 = ne.sq + 2.0 * self._weighted_s_l1(self.nodes)
        alpha = 1.0
        for _ in range(6):
            trial = retracted(self.nodes, alpha * dx)
            trial_lin = self._linearise(trial, factors)
            assert trial_lin.gnss is not None  # a retraction keeps the GNSS rows
            trial_s = self._thresholded(trial_lin.gnss)
            self._assign_s(trial, trial_lin.gnss, trial_s)
            trial_ne = self._normal_equations(trial, trial_lin, factors, s=trial_s)
            if trial_ne.sq + 2.0 * self._weighted_s_l1(trial) <= h0 * (1.0 + 1e-12):
                self.nodes, self._lin, self._ne = trial, trial_lin, trial_ne
                self._s, self._s_penalty = trial_s, None
                return float(np.sqrt(ne.sq)), alpha * step
            alpha *= 0.5
        # no decrease: the S of the trials went to their own nodes, the current ones keep theirs
        return float(np.sqrt(ne.sq)), 0.0

    def solve(self, record: bool = False) -> tuple[int, list[tuple[float, ...]]]:
        """Algorithm 1 on the current window. Returns the iteration count and (if asked) the table rows.

        Table rows are ``(i, |b|_2, |S|_1, |dX|_2, |dS|_1)`` (the paper's Table 1).
        """
        table: list[tuple[float, ...]] = []
        use_s = np.isfinite(self.lam_rho) or np.isfinite(self.lam_d)
        i = 0
        while i < self.max_iterations:
            i += 1
            s_before = self.s_l1_norm() if record else 0.0
            b_norm, dx = self.x_step()
            if record:
                table.append((i, b_norm, s_before, dx, 0.0))
            if dx < self.tol:
                if not use_s:
                    break
                s_old = self._s_vector() if record else None
                ds = self.s_step()
                b_norm, dx = self.huber_step()
                if s_old is not None:
                    table.append((i, b_norm, self.s_l1_norm(), dx, float(np.abs(self._s_vector() - s_old).sum())))
                if dx < self.tol and ds < self.tol:
                    break
        return i, table

    def newest_position_covariance(self) -> np.ndarray:
        """ECEF covariance of the newest state's position [m^2]: its marginal under the window's normal equations.

        The block-tridiagonal information is reduced onto the newest state by forward Schur
        complements (linear in the window length, where a dense inverse is cubic). GTSAM's
        Pose3 tangent holds the translation in the body frame, so the block is rotated to ECEF.
        """
        # the information does not depend on S: the kept normal equations serve when there are any
        ne = self._ne or self._normal_equations(self.nodes, self._linearised(), self._stacked_factors())
        schur = ne.D[0]
        for k in range(1, len(ne.D)):
            schur = ne.D[k] - ne.U[k - 1].T @ np.linalg.solve(schur, ne.U[k - 1])
        body = np.linalg.inv(schur + 1e-12 * np.eye(NS))[POS : POS + 3, POS : POS + 3]
        rotation = self.nodes[-1].pose.rotation().matrix()
        return cast(np.ndarray, rotation @ body @ rotation.T)

    def s_l1_norm(self) -> float:
        """``|S|_1`` over the window [whitened units]."""
        return float(np.abs(self._s_vector()).sum())

    def ekf_update(self, gate: float) -> int:
        """EKF update of the newest node (one linearisation at the prediction), with innovation gating.

        Returns the number of GNSS rows rejected by the gate.
        """
        last = len(self.nodes) - 1
        node = self.nodes[last]
        if node.gnss is None:
            self.x_step(line_search=False)
            return 0
        lin = self._linearised()
        H0 = self._normal_equations(self.nodes, lin, self._stacked_factors(), gnss_nodes=set(range(last))).dense()
        P = np.linalg.inv(H0)[-NS:, -NS:]
        g = lin.gnss
        assert g is not None and g.J is not None  # the newest node has GNSS; linearised with the Jacobian
        R = len(g.e) // 2
        _, lo, hi = g.bounds[-1]
        rows = np.r_[lo:hi, R + lo : R + hi]
        e, J, w = g.e[rows], g.J[rows], g.w[rows]
        var = np.einsum("ij,jk,ik->i", J, P, J) + (w > 0)
        bad = (np.abs(e) > gate * np.sqrt(np.maximum(var, 1e-30))) & (w > 0)
        if bad.any():
            k = len(node.gnss.code)
            node.gnss = replace(
                node.gnss, w_code=np.where(bad[:k], 0.0, node.gnss.w_code), w_rr=np.where(bad[k:], 0.0, node.gnss.w_rr)
            )
            self._factors_changed()
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
        factors = window_factors(pair)
        ne = self._normal_equations(pair, self._linearise(pair, factors), factors)
        H00, H01, H11 = ne.D[0], ne.U[0], ne.D[1]
        c = cho_factor(H00 + 1e-12 * np.eye(NS))
        lam = H11 - H01.T @ cho_solve(c, H01)
        eta1 = ne.eta[NS:] - H01.T @ cho_solve(c, ne.eta[:NS])
        R = upper_cholesky(0.5 * (lam + lam.T))
        self.prior_R = R
        self.prior_r = solve_triangular(R, eta1, trans="T")
        self.prior_mean = self.nodes[1].copy()
        self.nodes = self.nodes[1:]
        self._factors_changed()
        first = self.nodes[0]
        first.gnss, first.s_code, first.s_rr, first.imu, first.clk_sqrt_info = None, None, None, None, None
