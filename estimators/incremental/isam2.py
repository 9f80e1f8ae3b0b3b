"""Incremental PPP on iSAM2: iSAM2-PPP (incremental L2), incremental DCS and max-mixtures.

All incremental estimators share one loop over the epochs of the shared PPP graph
(:class:`~estimators.model.ppp_graph.PppGraph`) updated with :class:`gtsam.ISAM2`
(dissertation Ch. 4 and the Ch. 7 comparators):

1. *Predict*: a snapshot solve of the new epoch's position and clock from its code
   and the phase of continuing arcs, holding the zenith wet delay, the arc biases and
   the ionosphere residuals at their current iSAM2 estimates (Gauss-Newton with
   Huber re-weighting, numpy). It gives the initial values of the epoch's new keys
   (a new arc's bias starts at ``phase - predicted range`` instead of ``phase -
   code``, metres closer) and the residuals ``measured - predicted`` that the
   gating estimators (MM, ICE) test. A new arc's phase residual is undefined (NaN).
2. *Gate*: a subclass hook turns the residuals into the epoch's measurement noise
   models (:meth:`IncrementalGraphEstimator._measurements`).
3. *Update*: the window's ``update(new factors, new values)``; the epoch's position is
   read with ``calculateEstimatePoint3`` (the filtered estimate; no full-estimate copy).

Estimators:

* ``isam2_ppp``: a-priori Gaussian noise (elevation-weighted sigmas). With
  ``ionosphere = free`` it is the Ch. 4 iSAM2-PPP (IF code and phase, 2.5 m /
  0.025 m over sin(el), 7 deg mask); with ``broadcast`` the Ch. 7 single-frequency L1
  incremental L2 comparator.
* ``isam2_dcs``: the same noise wrapped in GTSAM's DCS m-estimator (kernel width
  ``kernel_width`` in whitened units); iSAM2 re-weights whenever it relinearises.
* ``isam2_mm``: max-mixtures with a static inlier/outlier model per measurement
  (outlier covariance = inlier times ``outlier_scale``, 10 in the incremental code
  and in both ``gnss_model`` presets, equal weights). The component is chosen once, when the measurement enters the
  graph, from its predicted residual (iSAM2 cannot swap a factor's noise model at
  each relinearisation without removing and re-adding it).

Cost: every arc bias is a "landmark" seen at every epoch of its arc, so in plain
iSAM2 (``lag_s = 0``) each update scans all factors of the continuing arcs and the
back-substitution of the changed biases reaches every past epoch of the arc: the
update time grows with the run (measured in IF mode: ~0.6 ms per update at the start,
~30 ms after 850 epochs). By default the loop runs iSAM2 in a fixed-lag window
(:mod:`estimators.incremental.fixed_lag`): keys last used more than ``lag_s`` seconds and
``lag_min_epochs`` epochs ago are marginalised, the arc biases of tracked arcs stay
alive as long as their arc, an arc that resumes after its bias left the window starts
anew, and the update cost is bounded by the window. The window is decided from the
epoch times alone, so two runs on the same data give the same positions bit for bit
(GTSAM's ``IncrementalFixedLagSmoother`` did not). The filtered position of each epoch
is what the estimators output; marginalisation is exact for the linear part of the
model, so it is the same as plain iSAM2's up to relinearisation of positions older
than the lag.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import gtsam
import numpy as np
import pandas as pd

from estimators import register
from estimators.base import Estimator, solution_frame
from estimators.incremental.configs import IncrementalConfig, Isam2DcsConfig, Isam2MmConfig
from estimators.incremental.fixed_lag import FixedLagSmoother, LagSchedule, restart_stale_arcs
from estimators.model.measurement import predict_given_troposphere, prepare_ppp
from estimators.model.ppp_graph import (
    ZERO_KEY,
    PppGraph,
    amb_key,
    clock_key,
    drift_key,
    insert_double,
    iono_key,
    isb_key,
    pos_key,
    sysclock_key,
    vel_key,
    zwd_key,
)
from estimators.model.robust_models import max_mixture_outliers
from simbench.contract import ReceiverData
from simbench.core.constants import C_LIGHT

__all__ = ["EpochPrediction", "IncrementalGraphEstimator", "Isam2Dcs", "Isam2Mm", "Isam2Ppp"]

#: Huber threshold of the snapshot prediction, whitened units.
_HUBER_K = 1.5
#: Gauss-Newton iterations of the snapshot prediction.
_SNAPSHOT_ITERATIONS = 4


def _huber_weight(u: np.ndarray) -> np.ndarray:
    """IRLS weight of Huber's loss at whitened residuals ``u`` (threshold ``_HUBER_K``)."""
    a = np.abs(u)
    return np.where(a <= _HUBER_K, 1.0, _HUBER_K / np.maximum(a, 1e-12))


@dataclass
class EpochPrediction:
    """Snapshot prediction of one epoch (see the module docstring).

    Attributes
    ----------
    pos : ndarray, shape (3,)
        Predicted receiver position [m].
    clock_m : float
        Predicted receiver clock times c [m].
    res_code, res_phase : ndarray, shape (m,)
        ``measured - predicted`` of the epoch's rows [m]; phase NaN on new arcs.
    new_arc : ndarray of bool, shape (m,)
        Rows that start an arc.
    amb_new : ndarray, shape (m,)
        Initial bias of new arcs (``phase - predicted range``) [m]; NaN elsewhere.
    los_var : ndarray, shape (m,)
        Variance of the motion model's predicted position along each row's line of sight
        [m^2] (``u' P u``, before this epoch's measurements); 0 where there is no motion
        prediction (the first epoch, or ``motion_model = random_walk``).
    """

    pos: np.ndarray
    clock_m: float
    res_code: np.ndarray
    res_phase: np.ndarray
    new_arc: np.ndarray
    amb_new: np.ndarray
    los_var: np.ndarray


class IncrementalGraphEstimator(Estimator):
    """The shared iSAM2 loop; subclasses choose the measurement noise of each epoch."""

    Config: ClassVar[type[IncrementalConfig]] = IncrementalConfig

    # ------------------------------------------------------------------ hooks

    def _start_run(self) -> None:
        """Reset a subclass's per-run state before the first epoch."""

    def _measurements(self, k: int, rows: slice, g: PppGraph, pred: EpochPrediction) -> dict[str, Any] | None:
        """Keyword arguments of :meth:`PppGraph.measurement_factors` for epoch ``k``; None: no GNSS update."""
        return {}

    def _diagnostics(self) -> dict[str, Any]:
        """Subclass diagnostics merged into the solution's."""
        return {}

    # ------------------------------------------------------------------ loop

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        cfg: IncrementalConfig = self.config
        self._start_run()
        obs = prepare_ppp(data, **cfg.prepare_kwargs())
        schedule = LagSchedule.of(obs.epoch_t, cfg.lag_s, cfg.lag_min_epochs)
        obs, restarted = restart_stale_arcs(obs, schedule)
        g = PppGraph(obs, cfg)
        isam = FixedLagSmoother(isam2_params(cfg), schedule)

        n = obs.n_epochs
        pos_out = np.empty((n, 3))
        update_s = np.empty(n)
        skipped = 0
        for k, rows in obs.iter_epochs():
            tic = time.perf_counter()
            pred = self._predict(k, rows, g, isam)
            kwargs = self._measurements(k, rows, g, pred)
            graph = g.prior_factors(k)
            graph.push_back(g.motion_factors(k))
            if kwargs is None:
                skipped += 1
            else:
                graph.push_back(g.measurement_factors(rows, **kwargs))
            isam.update(k, graph, self._initial_values(k, rows, g, isam, pred), _reused_keys(g, rows))
            pos_out[k] = isam.point3(pos_key(k))
            update_s[k] = time.perf_counter() - tic

        frame = solution_frame(obs.epoch_ids, obs.epoch_t, pos_out, update_s)
        isb = {name: isam.double(isb_key(s, n - 1)) for s, name in enumerate(obs.systems[1:], start=1)}
        diagnostics = {
            "n_epochs": int(n),
            "n_observations": int(obs.n_obs),
            "n_arcs": int(obs.n_arcs),
            "inter_system_bias_m": isb,
            "epochs_without_gnss_update": int(skipped),
            "arcs_restarted_after_window": restarted,
            **obs.model_info(),
            **g.wet_delay.info(),
            "config": asdict(cfg),
            **self._diagnostics(),
        }
        return frame, diagnostics

    def _predict(self, k: int, rows: slice, g: PppGraph, isam: FixedLagSmoother) -> EpochPrediction:
        obs = g.obs
        prev = g.prev_row[rows]
        has_phase = g.has_phase[rows]
        new_arc = has_phase & (prev < 0)
        cont = has_phase & (prev >= 0)
        arcs = obs.arc[rows]
        m = len(prev)
        # further systems' rows carry their inter-system bias (the latest estimate)
        isb = np.r_[
            0.0,
            [isam.double(isb_key(s, k - 1)) if k else g.isb0_m[s - 1] for s in range(1, obs.n_isb + 1)],
        ]
        offset = isb[g.row_system[rows]]
        prior_pos, prior_root, prior_cov = None, None, np.zeros((3, 3))
        # the ZWD state beyond what code_z/phase_z had removed (wet_delay=model: nothing)
        zwd = 0.0
        if k == 0:
            pos, clock = g.spp_pos[0].copy(), float(g.spp_clock_m[0])
            if g.estimate_zwd:
                zwd = g.zwd0
        else:
            pos = np.asarray(isam.point3(pos_key(k - 1)), float).copy()
            if g.estimate_zwd:
                zwd = isam.double(zwd_key(k - 1))
            clock = float(g.spp_clock_m[k])
            if g.constant_velocity:
                prior_pos, prior_cov = self._motion_prior(k, g, isam, pos)
                prior_root = np.linalg.inv(np.linalg.cholesky(prior_cov))
                pos = prior_pos.copy()
        amb = np.full(m, np.nan)
        iono = np.zeros(m)
        for j in np.flatnonzero(cont):
            amb[j] = isam.double(amb_key(int(arcs[j])))
            if g.with_iono:
                iono[j] = isam.double(iono_key(int(prev[j])))
        sat, mw = obs.sat_pos[rows], g.wet_mapping[rows]
        zc, zp = g.code_z[rows], g.phase_z[rows]
        sc, sp = obs.sigma_code[rows], obs.sigma_phase[rows]
        zeros = np.zeros(m)
        # stacked code rows then continuing phase rows; unknowns dx, dy, dz, clock
        for _ in range(_SNAPSHOT_ITERATIONS):
            p, H = predict_given_troposphere(sat, pos, clock, zwd, zeros, mw)
            p = p + offset
            res = np.r_[zc - (p + iono), (zp - (p - iono + amb))[cont]]
            sig = np.r_[sc, sp[cont]]
            A = np.vstack([H[:, :4], H[cont, :4]])
            w = _huber_weight(res / sig) / sig
            A, b = A * w[:, None], res * w
            if prior_pos is not None:  # whitened rows root @ (prior_pos - pos - dx) = 0; the clock stays free
                # Huber-weighted too: when the satellites agree far from it, the prediction is the outlier
                rp = prior_root @ (prior_pos - pos)
                wp = _huber_weight(rp)
                A = np.vstack([A, np.column_stack([prior_root * wp[:, None], np.zeros(3)])])
                b = np.r_[b, rp * wp]
            dx, *_ = np.linalg.lstsq(A, b, rcond=None)
            pos += dx[:3]
            clock += dx[3]
            if np.linalg.norm(dx[:3]) < 1e-4:
                break
        p = predict_given_troposphere(sat, pos, clock, zwd, zeros, mw)[0] + offset
        res_code = zc - (p + iono)
        res_phase = zp - (p - iono + amb)
        amb_new = np.where(new_arc, zp - (p - iono), np.nan)
        los = sat - pos
        los /= np.linalg.norm(los, axis=1, keepdims=True)
        los_var = np.einsum("ij,jk,ik->i", los, prior_cov, los)
        return EpochPrediction(pos, clock, res_code, res_phase, new_arc, amb_new, los_var)

    @staticmethod
    def _motion_prior(k: int, g: PppGraph, isam: FixedLagSmoother, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Constant-velocity prediction of epoch ``k``'s position and its covariance.

        ``p = p_{k-1} + v_{k-1} dt`` with ``P = P_p + dt^2 P_v + q^2 dt^3 / 3 I`` from the filtered
        marginals (their cross-covariance dropped). Without it a snapshot of four or fewer
        satellites fits them exactly and every residual looks like an inlier.
        """
        dt = float(g.obs.epoch_t[k] - g.obs.epoch_t[k - 1])
        vel = np.asarray(isam.point3(vel_key(k - 1)), float)
        q = g.cfg.accel_sigma_mps2_rts
        joint = isam.joint_marginal_covariance([pos_key(k - 1), vel_key(k - 1)])
        cov = joint[:3, :3] + dt * dt * joint[3:, 3:] + (q * q * dt**3 / 3.0) * np.eye(3)
        return pos + vel * dt, cov

    def _initial_values(
        self, k: int, rows: slice, g: PppGraph, isam: FixedLagSmoother, pred: EpochPrediction
    ) -> gtsam.Values:
        v = g.new_values(k, self._previous(k, rows, g, isam))
        v.update(pos_key(k), gtsam.Point3(*pred.pos))
        v.update(clock_key(k), pred.clock_m / C_LIGHT)
        for s in range(1, g.obs.n_isb + 1):
            v.update(sysclock_key(s, k), (pred.clock_m + v.atDouble(isb_key(s, k))) / C_LIGHT)
        arcs = g.obs.arc[rows]
        for j in np.flatnonzero(pred.new_arc):
            v.update(amb_key(int(arcs[j])), float(pred.amb_new[j]))
        return v

    @staticmethod
    def _previous(k: int, rows: slice, g: PppGraph, isam: FixedLagSmoother) -> gtsam.Values | None:
        """The few estimates :meth:`PppGraph.new_values` carries over (no full-estimate copy)."""
        if k == 0:
            return None
        v = gtsam.Values()
        v.insert(pos_key(k - 1), isam.point3(pos_key(k - 1)))
        if g.estimate_zwd:
            insert_double(v, zwd_key(k - 1), isam.double(zwd_key(k - 1)))
        if g.constant_velocity:
            v.insert(vel_key(k - 1), isam.point3(vel_key(k - 1)))
            insert_double(v, drift_key(k - 1), isam.double(drift_key(k - 1)))
        for s in range(1, g.obs.n_isb + 1):
            insert_double(v, isb_key(s, k - 1), isam.double(isb_key(s, k - 1)))
        if g.with_iono:
            for p in g.prev_row[rows]:
                if p >= 0:
                    insert_double(v, iono_key(int(p)), isam.double(iono_key(int(p))))
        return v


def _reused_keys(g: PppGraph, rows: slice) -> list[int]:
    """Keys made before epoch ``rows`` that its factors use again: the biases of its continuing arcs
    and the zero key (a landmark seen again stays in the window)."""
    arcs = g.obs.arc[rows]
    return [ZERO_KEY, *(amb_key(int(a)) for a in arcs[g.prev_row[rows] >= 0])]


def isam2_params(cfg: IncrementalConfig) -> gtsam.ISAM2Params:
    """iSAM2 parameters: QR elimination, relinearisation of the positions only.

    QR, not GTSAM's default Cholesky: the clock key is in seconds (Jacobian ``c``)
    next to centimetre phase sigmas, and forming the Hessian squares a condition
    number that Cholesky then reports as an indeterminate system.

    Only the position enters the factors nonlinearly (range); the clock, zenith wet
    delay, ionosphere and arc biases enter linearly, so relinearising them changes
    nothing but the cost, and their thresholds are infinite. The position default is
    1 m, not the original code's 0.01: the range's curvature makes the error of a
    linearisation point 1 m off below 1e-7 m, while at 0.01 every centimetre the
    converging arc biases move the past positions by makes iSAM2 re-eliminate those
    epochs (measured on open_sky, IF: 67 ms against 6 ms per update after 1200 epochs).
    """
    params = gtsam.ISAM2Params()
    thresholds = gtsam.ISAM2ThresholdMap()
    thresholds.insert(("x", np.full(3, cfg.relinearize_threshold)))
    for linear in "cwibzsjf":
        thresholds.insert((linear, np.array([np.inf])))
    thresholds.insert(("v", np.full(3, np.inf)))
    params.setRelinearizeThreshold(thresholds)
    params.relinearizeSkip = cfg.relinearize_skip
    params.setFactorization("QR")
    params.setOptimizationParams(gtsam.ISAM2GaussNewtonParams(cfg.wildfire_threshold))
    params.enablePartialRelinearizationCheck = cfg.partial_relinearization_check
    return params


# --------------------------------------------------------------------------- estimators


@register
class Isam2Ppp(IncrementalGraphEstimator):
    """iSAM2-PPP: the PPP graph with the a-priori Gaussian noise, updated incrementally (Ch. 4; Ch. 7 L2)."""

    name = "isam2_ppp"
    Config = IncrementalConfig


@register
class Isam2Dcs(IncrementalGraphEstimator):
    """iSAM2 with GTSAM's DCS m-estimator on every code and phase factor."""

    name = "isam2_dcs"
    Config = Isam2DcsConfig

    def _measurements(self, k, rows, g, pred):
        return {"robust": gtsam.noiseModel.mEstimator.DCS.Create(self.config.kernel_width)}


@register
class Isam2Mm(IncrementalGraphEstimator):
    """iSAM2 with max-mixtures: each measurement takes its most likely component when it enters."""

    name = "isam2_mm"
    Config = Isam2MmConfig

    def _start_run(self) -> None:
        self._n_out = np.zeros(2, np.int64)

    def _measurements(self, k, rows, g, pred):
        cfg = self.config
        sc, sp = g.obs.sigma_code[rows], g.obs.sigma_phase[rows]
        out_c = max_mixture_outliers(pred.res_code / sc, cfg.outlier_scale, cfg.outlier_weight)
        # a new arc's phase has no residual yet: inlier
        out_p = max_mixture_outliers(np.nan_to_num(pred.res_phase / sp), cfg.outlier_scale, cfg.outlier_weight)
        self._n_out += [out_c.sum(), out_p.sum()]
        inflate = np.sqrt(cfg.outlier_scale)
        return {"code_sigma": np.where(out_c, sc * inflate, sc), "phase_sigma": np.where(out_p, sp * inflate, sp)}

    def _diagnostics(self) -> dict[str, Any]:
        return {"outlier_code": int(self._n_out[0]), "outlier_phase": int(self._n_out[1])}
