"""Batch PPP on the shared factor graph: L2, DCS and max-mixtures (dissertation Ch. 3, eqs. 3.18-3.20).

All three solve the whole data set at once on
:class:`~estimators.model.ppp_graph.PppGraph`; they differ only in the measurement
noise models:

* ``l2``: the a-priori Gaussian model (elevation-weighted sigmas), solved by
  Gauss-Newton steps (:meth:`~estimators.batch.whitened_rows.WhitenedRows.solve`;
  Levenberg-Marquardt where an undamped step would raise the error).
* ``dcs``: the same wrapped in GTSAM's dynamic covariance scaling m-estimator
  (kernel width ``kernel_width``, phi in the DCS papers, whitened units), applied as GTSAM
  applies it when it linearises a robust factor, on the linearised rows
  (:class:`~estimators.batch.whitened_rows.DcsKernel`), so each Gauss-Newton step
  (:class:`~estimators.batch.gauss_newton.GaussNewton`) is one iteration of
  iteratively re-weighted least squares; the steps go on until the relative
  error decrease is below ``rel_tol`` or ``max_iterations`` is reached
  (:func:`stop_reason`, GTSAM's ``checkConvergence``); each iteration's total error and
  largest position step [m] go to the diagnostics (``history``). That is the path
  Levenberg-Marquardt took (its damping fell to 1e-85 on a drive, and its
  trajectory matched the steps' to 4 digits) at a third less per iteration.
* ``mm``: max-mixtures with a static two-component model per measurement (a-priori
  inlier, outlier with the covariance scaled by ``outlier_scale``, which the
  ``gnss_model`` preset sets: 10 in ``urban``, whose C/N0 sigmas already widen weak
  rows, the batch code's 1e6 in ``dissertation``; equal weights);
  each iteration every code and every phase measurement takes its most likely
  component given the current residual (eq. 3.20), then the graph is re-solved by
  one Gauss-Newton step from the previous solution (exact: the graph is Gaussian
  and linear but for the range's micrometre curvature) on its linearised rows
  (:class:`~estimators.batch.whitened_rows.WhitenedRows`: the outlier rows' sigmas change, no
  factor is rebuilt), until the relative change
  of the total error is below ``rel_tol`` or the assignment no longer changes or
  ``max_iterations`` is reached.

The robust estimators start from the L2 solution (one L2 solve, counted in their
run time): from the single point initial values the arc biases are metres off and
a robust kernel would switch every phase factor off at the first linearisation.

``prior_scale`` (s) multiplies the a-priori measurement covariance (sigmas by
``sqrt(s)``), for the sensitivity study of Fig. 5.3.7.
"""

from __future__ import annotations

import time
from dataclasses import asdict
from typing import Any, ClassVar, Generic, TypeVar

import gtsam
import numpy as np
import pandas as pd

from estimators import register
from estimators.base import Estimator, solution_frame
from estimators.batch.configs import BatchConfig, DcsConfig, L2Config, MmConfig, MmEmConfig
from estimators.batch.gauss_newton import GaussNewton
from estimators.batch.whitened_rows import DcsKernel, WhitenedRows
from estimators.model.measurement import PppObservations, prepare_ppp
from estimators.model.nlos_mixture import NlosMixture, predictors
from estimators.model.ppp_graph import PppGraph, solve
from estimators.model.robust_models import max_mixture_outliers
from simbench.contract import ReceiverData

__all__ = ["BatchGraphEstimator", "DcsBatch", "L2Batch", "MmBatch", "MmEm", "Reweighting", "stop_reason"]


#: The L2 solve stops when the relative error decrease is below this (Levenberg-Marquardt's default
#: in :func:`~estimators.model.ppp_graph.solve`).
L2_RELATIVE_TOL = 1e-6


def stop_reason(previous: float, current: float, rel_tol: float, *, on_increase: bool) -> str | None:
    """Why a robust re-weighting loop stops after an iteration, None to go on.

    Parameters
    ----------
    previous, current : float
        Total graph error after the previous and the current re-solve (GTSAM's
        ``0.5 * sum of squared whitened residuals``, dimensionless).
    rel_tol : float
        Relative tolerance on the error change.
    on_increase : bool
        Stop when the error rises by more than ``rel_tol`` too (GTSAM's ``checkConvergence``).

    Returns
    -------
    str or None
        ``"converged"`` (change within ``rel_tol``), ``"error increased"``, or None.
    """
    decrease = previous - current
    if abs(decrease) <= rel_tol * abs(previous):
        return "converged"
    return "error increased" if on_increase and decrease < 0 else None


#: The config type of a batch estimator (its ``Config``), so that ``self.config`` is typed in its methods.
C = TypeVar("C", bound=BatchConfig)


class BatchGraphEstimator(Estimator, Generic[C]):
    """Shared plumbing: prepare observations, build the graph, time the run, output the solution.

    The type parameter is the subclass's ``Config``: ``self.config`` has that type.
    """

    Config: ClassVar[type[BatchConfig]] = BatchConfig
    config: C

    def _prepare(self, data: ReceiverData) -> tuple[PppObservations, PppGraph]:
        cfg = self.config
        obs = prepare_ppp(data, **cfg.prepare_kwargs())
        return obs, PppGraph(obs, cfg)

    def _a_priori_sigmas(self, obs: PppObservations) -> tuple[np.ndarray, np.ndarray]:
        s = np.sqrt(self.config.prior_scale)
        return obs.sigma_code * s, obs.sigma_phase * s

    def _a_priori_graph(self, g: PppGraph, structure: gtsam.NonlinearFactorGraph) -> gtsam.NonlinearFactorGraph:
        """Structure plus measurement factors with the a-priori noise model (scaled by ``prior_scale``)."""
        sc, sp = self._a_priori_sigmas(g.obs)
        graph = gtsam.NonlinearFactorGraph(structure)
        graph.push_back(g.measurement_factors(code_sigma=sc, phase_sigma=sp))
        return graph

    def _l2(self, g: PppGraph, structure: gtsam.NonlinearFactorGraph) -> WhitenedRows:
        """The batch graph on its linearised rows, linearised at the batch L2 solution.

        The a-priori model is solved by Gauss-Newton steps (nearly linear: 2-3 steps from the
        single point start), Levenberg-Marquardt taking over where an undamped step raises the
        error. Re-weighting changes noise models only, never which keys a factor touches, so
        the robust estimators' re-solves go on from here on the same rows and share one
        symbolic factorisation.
        """
        cfg = self.config
        initial = g.initial_values()
        rows = WhitenedRows(g, structure, GaussNewton(g.elimination_ordering), initial)
        sc, sp = self._a_priori_sigmas(g.obs)
        noise = {"code_sigma": sc, "phase_sigma": sp}
        if not rows.solve(noise, relative_tol=L2_RELATIVE_TOL, max_iterations=cfg.lm_max_iterations):
            graph = self._a_priori_graph(g, structure)
            lm = solve(
                graph,
                initial,
                ordering=g.elimination_ordering(graph),
                max_iterations=cfg.lm_max_iterations,
                relative_tol=L2_RELATIVE_TOL,
            )
            rows.linearize(lm)
        self._rows = rows
        return rows

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        tic = time.perf_counter()
        obs, g = self._prepare(data)
        structure = g.structure_factors()
        values, diag = self._run(data, obs, g, structure)
        pos = g.positions(values)
        per_epoch = (time.perf_counter() - tic) / obs.n_epochs
        frame = solution_frame(obs.epoch_ids, obs.epoch_t, pos, np.full(obs.n_epochs, per_epoch))
        isb = {name: float(np.median(v)) for name, v in g.inter_system_biases(values).items()}
        diag = {
            "n_epochs": int(obs.n_epochs),
            "n_observations": int(obs.n_obs),
            "n_arcs": int(obs.n_arcs),
            # steps that GTSAM's elimination took over from the sparse LDL' (indeterminate systems)
            "gauss_newton_fallbacks": self._rows.fallbacks,
            # GTSAM linearisations (between them, steps move the rows' residuals: WhitenedRows)
            "linearizations": self._rows.linearizations,
            "inter_system_bias_m": isb,
            **obs.model_info(),
            **g.wet_delay.info(),
            **diag,
            "config": asdict(self.config),
        }
        return frame, diag

    def _run(
        self, data: ReceiverData, obs: PppObservations, g: PppGraph, structure: gtsam.NonlinearFactorGraph
    ) -> tuple[gtsam.Values, dict[str, Any]]:
        raise NotImplementedError


class Reweighting(BatchGraphEstimator[C]):
    """A robust batch estimator: re-weights the measurements, starting from the batch L2 solution."""

    def _run(self, data, obs, g, structure):
        rows = self._l2(g, structure)
        return self._reweight(obs, rows, *self._a_priori_sigmas(obs))

    def _reweight(
        self, obs: PppObservations, rows: WhitenedRows, sc: np.ndarray, sp: np.ndarray
    ) -> tuple[gtsam.Values, dict[str, Any]]:
        """Re-weight and re-solve from the L2 solution on ``rows`` (a-priori code and phase sigmas
        ``sc``, ``sp`` [m], scaled by ``prior_scale``); the values and the diagnostics."""
        raise NotImplementedError


# --------------------------------------------------------------------------- L2


@register
class L2Batch(BatchGraphEstimator[L2Config]):
    """Batch Levenberg-Marquardt PPP with the a-priori Gaussian noise model."""

    name = "l2"
    Config = L2Config

    def _run(self, data, obs, g, structure):
        return self._l2(g, structure).values, {"iterations": 1}


# --------------------------------------------------------------------------- DCS


@register
class DcsBatch(Reweighting[DcsConfig]):
    """Batch PPP with GTSAM's DCS m-estimator on every code and phase factor."""

    name = "dcs"
    Config = DcsConfig

    def _reweight(self, obs, rows, sc, sp):
        noise, kernel = {"code_sigma": sc, "phase_sigma": sp}, DcsKernel(self.config.kernel_width)
        err = rows.error(noise, kernel)
        stop, iterations = "max_iterations", 0
        positions = rows.positions()
        history = []
        for iterations in range(1, self.config.max_iterations + 1):
            accepted = rows.snapshot()
            rows.step(noise, kernel)
            stepped_err = rows.error(noise, kernel)
            reason = stop_reason(err, stepped_err, self.config.rel_tol, on_increase=True)
            step = 0.0
            if reason != "error increased":  # a rise is rejected, as Levenberg-Marquardt would
                err = stepped_err
                moved = rows.positions()
                step, positions = float(np.linalg.norm(moved - positions, axis=1).max()), moved
            else:
                rows.restore(accepted)
            # a run that stops at max_iterations while its steps still move epochs by decimetres has not
            # converged: IRLS under a non-convex kernel can wander as rows are switched off one by one
            history.append({"iteration": iterations, "error": float(err), "max_position_step_m": step})
            if reason is not None:
                stop = reason
                break
        r_c, r_p = rows.residuals
        return rows.values, {
            "iterations": iterations,
            "stop_reason": stop,
            "history": history,
            "downweighted_code": int(np.sum(np.abs(r_c / sc) > self.config.kernel_width)),
            "downweighted_phase": int(np.sum(np.abs(r_p / sp) > self.config.kernel_width)),
        }


# --------------------------------------------------------------------------- max-mixtures


@register
class MmBatch(Reweighting[MmConfig]):
    """Batch max-mixtures (static two-component model), iterated to convergence."""

    name = "mm"
    Config = MmConfig

    def _reweight(self, obs, rows, sc, sp):
        scale, weight = self.config.outlier_scale, self.config.outlier_weight
        inflate = np.sqrt(scale)
        prev_out: tuple[np.ndarray, np.ndarray] | None = None
        prev_err = None
        history = []
        for it in range(self.config.max_iterations):
            r_c, r_p = rows.residuals
            out_c = max_mixture_outliers(r_c / sc, scale, weight)
            out_p = max_mixture_outliers(r_p / sp, scale, weight)
            if prev_out is not None and np.array_equal(out_c, prev_out[0]) and np.array_equal(out_p, prev_out[1]):
                break
            prev_out = out_c, out_p
            noise = {"code_sigma": np.where(out_c, sc * inflate, sc), "phase_sigma": np.where(out_p, sp * inflate, sp)}
            rows.step(noise)
            err = rows.error(noise)
            history.append(
                {
                    "iteration": it + 1,
                    "error": float(err),
                    "outlier_code": int(out_c.sum()),
                    "outlier_phase": int(out_p.sum()),
                }
            )
            if prev_err is not None and stop_reason(prev_err, err, self.config.rel_tol, on_increase=False):
                break
            prev_err = err
        return rows.values, {"iterations": len(history), "history": history}


# --------------------------------------------------------------------------- self-tuning max-mixtures


@register
class MmEm(Reweighting[MmEmConfig]):
    """Self-tuning max-mixtures: a LOS/NLOS code model conditioned on C/N0 and elevation, learned by EM
    from the residuals of the whole graph, alternating with the solve (libRSF's EM-tuned mixtures)."""

    name = "mm_em"
    Config = MmEmConfig

    def _reweight(self, obs, rows, sc, sp):
        cfg = self.config
        x, names = predictors(obs.el, obs.cn0) if cfg.conditioned else (None, [])
        r_c, r_p = rows.residuals
        model = NlosMixture.start(r_c, sc, x, names, weight=cfg.nlos_weight_init, one_sided=cfg.one_sided)
        inflate = np.sqrt(cfg.outlier_scale)
        prev_err, stop, history = None, "max_iterations", []
        for it in range(cfg.max_iterations):
            r_c, r_p = rows.residuals
            model = model.fit(r_c, sc, x, iterations=cfg.em_iterations, learn_los_scale=cfg.learn_los_scale)
            code_sigma, code_offset, nlos = model.code_noise(r_c, sc, x, cfg.assignment)
            out_p = max_mixture_outliers(r_p / sp, cfg.outlier_scale, cfg.outlier_weight)
            noise = {
                "code_sigma": code_sigma,
                "code_offset": code_offset,
                "phase_sigma": np.where(out_p, sp * inflate, sp),
            }
            rows.step(noise)
            err = rows.error(noise)
            history.append(
                {
                    "iteration": it + 1,
                    "error": float(err),
                    "nlos_code": int(np.sum(nlos > 0.5)),
                    "outlier_phase": int(out_p.sum()),
                    "los_scale": model.los_scale,
                    "los_spread_m": model.los_spread,
                    "nlos_tau_m": model.tau,
                }
            )
            if prev_err is not None:
                reason = stop_reason(prev_err, err, cfg.rel_tol, on_increase=False)
                if reason is not None:
                    stop = reason
                    break
            prev_err = err
        r_c, _ = rows.residuals
        self._model = model  # the learned model, for a caller that checks it against labels
        return rows.values, {
            "iterations": len(history),
            "stop_reason": stop,
            "history": history,
            "nlos_model": model.summary(r_c, sc, x),
        }
