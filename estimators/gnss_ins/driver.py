"""Run a GNSS/INS estimator over a scenario: the epoch loop around
:class:`~estimators.gnss_ins.window_solver.WindowSolver`.

Per GNSS epoch, in order: predict the next state with the IMU samples since
the previous epoch, append the epoch's GNSS measurements (marginalising the
oldest state when the window is full), turn the heading to the course over
ground the first time the vehicle moves (see
:class:`~estimators.gnss_ins.config.GnssInsConfig`), solve the window
(Algorithm 1) or make the EKF update, and record the newest state. The filter
starts at the first epoch after ``level_s`` seconds of static IMU data that has
a trusted single point solution: levelled from the mean specific force, yaw 0,
velocity and drift from the Doppler, and a prior no tighter than that fix.
"""

from __future__ import annotations

import time
from abc import abstractmethod
from bisect import bisect_left
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

import gtsam
import numpy as np
import pandas as pd

from estimators.base import Estimator, solution_frame
from estimators.gnss_ins.config import GnssInsConfig, LssConfig
from estimators.gnss_ins.data import (
    GnssEpoch,
    GnssInsData,
    SinglePointFix,
    prepare_gnss_ins,
)
from estimators.gnss_ins.mechanisation import (
    DEG_PER_HOUR,
    attitude_ecef,
    course_over_ground,
    level_roll_pitch,
    yaw_of,
)
from estimators.gnss_ins.window_solver import CLK, POS, WindowNode, WindowSolver, initial_sigmas
from simbench.contract import Need, ReceiverData
from simbench.core.constants import DEG
from simbench.errors import SimbenchError
from simbench.gnss.doppler import doppler_velocity
from simbench.gnss.geometry import sagnac_range_gradient

__all__ = ["GnssInsEstimator", "GnssInsMode", "TABLE_COLUMNS", "lss_arguments", "run_gnss_ins"]

#: ``ekf``: one update per epoch with innovation gating; ``lss``: Algorithm 1 on the window.
GnssInsMode = Literal["ekf", "lss"]
#: Columns of the paper's Table 1 style iteration record in the diagnostics.
TABLE_COLUMNS = ("i", "b_norm", "s_l1", "dx_norm", "ds_l1")
#: Largest outlier estimates (S entries, in measurement units) kept in the diagnostics.
_N_LARGEST_S = 20
#: IMU samples up to this much before an epoch's time belong to the interval ending there [s].
_IMU_TIME_EPS_S = 1e-9


@dataclass
class _ImuStream:
    """The IMU table as arrays, handed out in the intervals between GNSS epochs."""

    t: np.ndarray  #: s, sample times
    f_b: np.ndarray  #: m/s^2, (n, 3) specific force, body axes
    w_b: np.ndarray  #: rad/s, (n, 3) angular rate, body axes
    dt: np.ndarray  #: s, time to the next sample (0 for the last)
    next_sample: int = 0

    @classmethod
    def of(cls, data: ReceiverData) -> _ImuStream:
        if data.imu is None or len(data.imu) < 2:
            raise SimbenchError("imu", "the GNSS/INS estimators need the IMU table", "simulate with an IMU")
        t = data.imu["t"].to_numpy(float)
        return cls(
            t=t,
            f_b=data.imu[["ax", "ay", "az"]].to_numpy(float),
            w_b=data.imu[["gx", "gy", "gz"]].to_numpy(float),
            dt=np.diff(t, append=t[-1]),
        )

    def static_mean_specific_force(self, until_s: float) -> np.ndarray:
        """Mean specific force of the samples up to ``until_s`` (the vehicle stands still) [m/s^2]."""
        return self.f_b[self.t <= until_s].mean(axis=0)

    def start_at(self, t_s: float) -> None:
        self.next_sample = int(np.searchsorted(self.t, t_s - _IMU_TIME_EPS_S))

    def take_until(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Specific force, angular rate and sample intervals from the last call up to time ``t_s``."""
        stop = int(np.searchsorted(self.t, t_s - _IMU_TIME_EPS_S))
        seg = slice(self.next_sample, stop)
        self.next_sample = stop
        return self.f_b[seg], self.w_b[seg], self.dt[seg]


@dataclass
class _Track:
    """The solutions and the counters behind the diagnostics, filled epoch by epoch."""

    epoch: list[int] = field(default_factory=list)
    pos: list[np.ndarray] = field(default_factory=list)
    cov: list[np.ndarray] = field(default_factory=list)  #: ECEF position covariance of each recorded state [m^2]
    update_s: list[float] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    n_capped: int = 0
    n_rejected: int = 0
    code_rows: int = 0
    code_rows_with_s: int = 0
    doppler_rows: int = 0
    doppler_rows_with_s: int = 0
    aligned_epoch: int = -1
    heading_reset_deg: float = 0.0
    table: list[tuple[float, ...]] = field(default_factory=list)
    table_s_l1: float = -1.0
    table_epoch: int = -1
    outliers: list[dict[str, Any]] = field(default_factory=list)
    lost_epoch: int = -1  #: first epoch whose normal equations could not be factorised; -1 when none
    lost_reason: str = ""

    def lose(self, epoch: int, n_epochs: int, reason: str) -> None:
        """Record epochs ``epoch`` .. ``n_epochs - 1`` as unsolved (NaN): the filter has lost its state."""
        kept = bisect_left(self.epoch, epoch)  # epochs are recorded in order; ``epoch``'s may be partly written
        del self.epoch[kept:], self.pos[kept:], self.cov[kept:], self.update_s[kept:]
        lost = range(epoch, n_epochs)
        self.epoch.extend(lost)
        self.pos.extend(np.full(3, np.nan) for _ in lost)
        self.cov.extend(np.full((3, 3), np.nan) for _ in lost)
        self.update_s.extend(np.nan for _ in lost)
        self.lost_epoch, self.lost_reason = epoch, reason


def run_gnss_ins(
    data: ReceiverData,
    cfg: GnssInsConfig,
    *,
    mode: GnssInsMode,
    window: int,
    lambdas: tuple[float, float] = (np.inf, np.inf),
    max_iterations: int = 20,
    tol: float = 1e-3,
    gate: float = np.inf,
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Run a GNSS/INS estimator over a scenario.

    Parameters
    ----------
    data : ReceiverData
        Needs the IMU table (at least 2 samples).
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
    if mode not in ("ekf", "lss"):
        raise SimbenchError("mode", f"unknown GNSS/INS mode '{mode}'", "use 'ekf' or 'lss'")
    imu = _ImuStream.of(data)
    prep = prepare_gnss_ins(data, cfg)
    first = _first_epoch(prep, imu.t[0] + cfg.level_s)
    solver = WindowSolver(cfg, window, lambdas, max_iterations, tol)
    track = _Track()

    e = first
    try:
        tic = time.perf_counter()
        _initialise(solver, cfg, imu, prep.gnss[first], prep.fixes[first], prep.t[first])
        _update(solver, track, mode, gate, first)
        _record(solver, track, first, prep.gnss[first], tic)
        imu.start_at(prep.t[first])
        for e in range(first + 1, len(prep.t)):
            tic = time.perf_counter()
            gnss = prep.gnss.get(e)
            solver.append(solver.predict(*imu.take_until(prep.t[e])), gnss)
            if track.aligned_epoch < 0:
                _align_heading_once_moving(solver, track, cfg, e, gnss)
            _update(solver, track, mode, gate, e)
            _record(solver, track, e, gnss, tic)
    except np.linalg.LinAlgError as exc:
        # a filter that has run away in a canyon ends with normal equations no Cholesky accepts; that is a
        # divergence of the estimator (NaN from here on, scored as `diverged`), not a failure of the run
        track.lose(e, len(prep.t), str(exc))
    return _solution(prep, track), _diagnostics(solver, track, cfg, prep, mode, first)


def _first_epoch(prep: GnssInsData, after_s: float) -> int:
    """First epoch with a trusted single point fix once the IMU has levelled."""
    first = next((e for e in sorted(prep.fixes) if prep.t[e] >= after_s), None)
    if first is None:
        raise SimbenchError(
            "scenario.duration_s",
            "no GNSS epoch with a trusted fix after the levelling interval",
            "give a longer scenario or a shorter level_s",
        )
    return first


def _initialise(
    solver: WindowSolver, cfg: GnssInsConfig, imu: _ImuStream, g0: GnssEpoch, fix: SinglePointFix, t0: float
) -> None:
    """First state: levelled attitude with yaw 0, the fix's position and clock, the Doppler velocity and drift."""
    roll, pitch = level_roll_pitch(imu.static_mean_specific_force(t0))
    vel0, drift0 = doppler_velocity(g0.sat_pos, g0.sat_vel, fix.pos, g0.rr, 1.0 / np.maximum(g0.w_rr, 1e-9))
    node0 = WindowNode(
        pose=gtsam.Pose3(gtsam.Rot3(attitude_ecef(fix.pos, roll, pitch, 0.0)), fix.pos),
        vel=vel0,
        bias=np.zeros(6),
        clk=np.array([fix.clock_m, drift0]),
    )
    sigmas = initial_sigmas(cfg)
    pos_sd, clock_sd = _fix_sigmas(g0, fix)
    sigmas[POS : POS + 3] = np.maximum(sigmas[POS : POS + 3], pos_sd)
    sigmas[CLK] = max(sigmas[CLK], clock_sd)
    solver.start(node0, sigmas, g0)


def _fix_sigmas(g: GnssEpoch, fix: SinglePointFix) -> tuple[float, float]:
    """Position (largest axis) and clock sigma of a single point solution, scaled by its a posteriori variance factor.

    In a street canyon the first fix can be tens of metres off (NLOS); a prior
    at the nominal code sigma would then be confidently wrong and make gating
    or soft-thresholding reject the good measurements that follow.
    """
    rho, grad = sagnac_range_gradient(g.sat_pos, fix.pos)
    A = np.hstack([grad, np.ones((len(rho), 1))]) * g.w_code[:, None]
    r = (g.code - rho - fix.clock_m) * g.w_code
    dof = len(r) - 4
    var_factor = float(r @ r) / dof if dof > 0 else 1.0
    P = max(var_factor, 1.0) * np.linalg.inv(A.T @ A)
    return float(np.sqrt(np.linalg.eigvalsh(P[:3, :3]).max())), float(np.sqrt(P[3, 3]))


def _align_heading_once_moving(
    solver: WindowSolver, track: _Track, cfg: GnssInsConfig, epoch: int, gnss: GnssEpoch | None
) -> None:
    """Turn the window's heading to the Doppler course over ground once the speed exceeds ``align_speed_mps``."""
    if gnss is None or np.count_nonzero(gnss.w_rr) < 4:
        return
    node = solver.nodes[-1]
    p = node.pose.translation()
    v, _ = doppler_velocity(gnss.sat_pos, gnss.sat_vel, p, gnss.rr, 1.0 / np.maximum(gnss.w_rr, 1e-9))
    speed, course = course_over_ground(p, v)
    if speed > cfg.align_speed_mps:
        delta = float(np.angle(np.exp(1j * (course - yaw_of(p, node.pose.rotation().matrix())))))
        solver.rotate_heading(delta)
        track.aligned_epoch, track.heading_reset_deg = epoch, delta / DEG


def _update(solver: WindowSolver, track: _Track, mode: GnssInsMode, gate: float, epoch: int) -> None:
    """The EKF update or Algorithm 1 on the window; keeps the iteration table of the largest |S|_1."""
    if mode == "ekf":
        track.n_rejected += solver.ekf_update(gate)
        track.iterations.append(1)
        return
    full = solver.full
    iterations, table = solver.solve(record=full)
    track.iterations.append(iterations)
    track.n_capped += iterations >= solver.max_iterations
    if full:
        s = solver.s_l1_norm()
        if s > track.table_s_l1:
            track.table_s_l1, track.table, track.table_epoch = s, table, epoch


def _record(solver: WindowSolver, track: _Track, epoch: int, gnss: GnssEpoch | None, tic: float) -> None:
    """Store the newest state and count rows; the S of the state about to leave the window is final, count it."""
    track.epoch.append(epoch)
    track.pos.append(solver.nodes[-1].pose.translation().copy())
    track.update_s.append(time.perf_counter() - tic)
    # after the clock stops: the covariance is for scoring consistency, not part of the estimator's update
    track.cov.append(solver.newest_position_covariance())
    if gnss is not None:
        track.code_rows += len(gnss.code)
        track.doppler_rows += int(np.count_nonzero(gnss.w_rr))
    leaving = solver.nodes[1] if solver.full and len(solver.nodes) > 1 else None
    if leaving is not None and leaving.gnss is not None:
        assert leaving.s_code is not None and leaving.s_rr is not None  # a node with GNSS has its S
        track.code_rows_with_s += int(np.count_nonzero(leaving.s_code))
        track.doppler_rows_with_s += int(np.count_nonzero(leaving.s_rr))
        _keep_outliers(track.outliers, epoch - (len(solver.nodes) - 2), leaving)


def _keep_outliers(out: list[dict[str, Any]], epoch: int, node: WindowNode) -> None:
    """Append the non-zero S entries of a node leaving the window; keep the largest few."""
    g = node.gnss
    assert g is not None and node.s_code is not None and node.s_rr is not None  # called for a GNSS node
    for kind, s, w, unit in (("code", node.s_code, g.w_code, "m"), ("doppler", node.s_rr, g.w_rr, "m/s")):
        for j in np.flatnonzero(s):
            out.append(
                {
                    "epoch": int(epoch),
                    "sat": str(g.sat[j]),
                    "kind": kind,
                    "s_whitened": float(s[j]),
                    "s_m": float(s[j] / w[j]),
                    "unit": unit,
                }
            )
    if len(out) > 4 * _N_LARGEST_S:
        out.sort(key=lambda r: -abs(r["s_m"]))
        del out[_N_LARGEST_S:]


def _solution(prep: GnssInsData, track: _Track) -> pd.DataFrame:
    epochs = np.asarray(track.epoch)
    return solution_frame(
        epochs, prep.t[epochs], np.asarray(track.pos), np.asarray(track.update_s), np.asarray(track.cov)
    )


def _diagnostics(
    solver: WindowSolver, track: _Track, cfg: GnssInsConfig, prep: GnssInsData, mode: GnssInsMode, first: int
) -> dict[str, Any]:
    last = solver.nodes[-1]
    return {
        "mode": mode,
        "window": int(solver.window),
        "n_epochs": len(track.epoch),
        "first_epoch": int(first),
        "gnss_epochs": len(prep.gnss),
        "rows_without_cn0": prep.rows_without_cn0,
        "iterations_mean": float(np.mean(track.iterations)) if track.iterations else 0.0,
        "iterations_max": max(track.iterations, default=0),
        "n_iteration_capped": int(track.n_capped),
        "heading_aligned_epoch": int(track.aligned_epoch),
        "heading_reset_deg": float(track.heading_reset_deg),
        "ekf_rejected_rows": int(track.n_rejected),
        "code_rows": int(track.code_rows),
        "code_rows_with_s": int(track.code_rows_with_s),
        "doppler_rows": int(track.doppler_rows),
        "doppler_rows_with_s": int(track.doppler_rows_with_s),
        "iteration_table_epoch": int(track.table_epoch),
        "iteration_table": [dict(zip(TABLE_COLUMNS, (int(r[0]), *map(float, r[1:])))) for r in track.table],
        "largest_s": sorted(track.outliers, key=lambda r: -abs(r["s_m"]))[:_N_LARGEST_S],
        "final_accel_bias_mps2": [float(v) for v in last.bias[:3]],
        "final_gyro_bias_dph": [float(v / DEG_PER_HOUR) for v in last.bias[3:]],
        "config": asdict(cfg),
        # only when the filter was lost: the report's diagnostics tables show no empty cells
        **({"lost_epoch": track.lost_epoch, "lost_reason": track.lost_reason} if track.lost_epoch >= 0 else {}),
    }


def lss_arguments(cfg: LssConfig, window: int) -> dict[str, Any]:
    """:func:`run_gnss_ins` arguments of Algorithm 1 on a window of ``window`` GNSS epochs."""
    return {
        "mode": "lss",
        "window": window,
        "lambdas": (cfg.lambda_rho, cfg.lambda_d),
        "max_iterations": cfg.max_iterations,
        "tol": cfg.tol,
    }


class GnssInsEstimator(Estimator):
    """Base of the GNSS/INS estimators: they need the IMU and differ only in how the driver runs."""

    requires = frozenset({Need.imu})

    @abstractmethod
    def driver_arguments(self) -> dict[str, Any]:
        """Keyword arguments of :func:`run_gnss_ins` besides the data and the config."""

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        return run_gnss_ins(data, self.config, **self.driver_arguments())
