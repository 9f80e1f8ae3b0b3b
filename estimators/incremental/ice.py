"""ICE: incremental covariance estimation on iSAM2 (dissertation Sec. 7.2).

Each epoch the iSAM2 loop of :mod:`estimators.incremental.isam2` predicts the 2-D
residual ``r = (code, phase)`` of every satellite [m]. :class:`AdaptiveNoiseModel`
then

1. picks each residual's most likely component of the model ``GMM_g`` (eq. 7.1)
   and z-tests it per channel, ``|r_i - mu_i| / s_i < T_r`` (eq. 7.2), where
   ``s_i^2`` is the component's variance plus the predicted position's along the
   line of sight (the innovation's; see below);
2. sends the inliers to iSAM2 with that component's full 2x2 covariance as the
   noise model;
3. buffers the outliers (they never enter the graph); when more than ``T_c`` are
   buffered it fits a variational DP-GMM to them
   (:func:`estimators.model.clustering.fit_dpgmm`) and merges each new component into the
   model when the W covariance test accepts, else adds it
   (:meth:`estimators.model.mixture_tests.MixtureModel.adapt`, eqs. 7.4-7.12), then
   clears the buffer.

Where this departs from the text, and why (issues 44 and 48, docs/notebook.md):

* Every component is zero-mean (``MixtureModel.zero_mean``; a scale mixture whose
  widths are learned, the Hotelling test void): the residuals are ``measured -
  predicted`` of a filter, so a cluster's mean is as much the prediction's error
  as the signal's. A phase mean is an arc bias's (any constant offset is the
  bias's), and applied per epoch by the choice of component it moved a 4-5
  satellite Galileo stretch 1.4 km (AJAC day 209: 3-D RMSE 143 m, ``wls_spp`` 46
  m); a code mean learned while the filter was off made that position agree with
  its satellites (a 5 Hz code-only urban drive: 72 m).
* The z-test's variance includes ``u' P u`` of the motion model's predicted position
  (:attr:`estimators.incremental.isam2.EpochPrediction.los_var`; zero with
  ``motion_model = random_walk``), and the first-epoch position prior is 100 m
  (``pos_sigma_m``): with the component's variance alone a filter that is off gates
  out the satellites that see it and holds the error.

``nlos_model = conditioned`` (the ``urban`` preset's; ``none`` in the dissertation's; issue 48)
adds a model of late code rows beside the mixture: a LOS/NLOS
:class:`~estimators.model.nlos_mixture.NlosMixture` whose NLOS prior weight and late-only mean
depend on C/N0 and elevation, refitted each epoch on the window's predicted code residuals
(:mod:`estimators.incremental.nlos_window`). A code row more likely NLOS than LOS is z-tested and
weighted against the NLOS component (its mean subtracted; where no predictor tells the late rows the
mean is 0 and the component a broad one, as in ``mm_em``) and is neither counted nor buffered by
the mixture; every other row is the mixture's as above.

An epoch with fewer than ``min_satellites`` inlier satellites gets no GNSS
update (the motion model carries the state; 4 in the dissertation's model). The
a-priori model is one zero-mean component ``diag(2.5^2, 0.25^2)`` m^2
(REFERENCE.md); like BCE's clusters it is a model of the raw residuals, so ICE
does not scale it with elevation. With ``scaled_mixture`` (the ``urban`` GNSS
model) the mixture is a model of each residual divided by its row's a-priori sigma
factor, and a component's covariance is scaled back per row: the sigma factor
(C/N0) on both channels, times the log's code variance factor of the row's system
(``variance_components``) on the code, as every other estimator weights it. A weak
signal, or a system whose code the log shows to be noisier, is tested and weighted
against a wider component (without the system factor GLONASS's code entered the
F9P-like Nagoya cut at the GPS weight: up -5.3 m).

Choices where the text is silent:

* A satellite that starts a phase arc, or a row without carrier phase
  (``measurements = auto`` on a log with sparse phase), has no phase residual; it
  is tested on its code channel alone (marginal of the most likely component) and,
  if rejected, not buffered (the buffer holds complete 2-D residuals).
* Measurement modes: when the data carry no carrier phase at all (a code-only log,
  or ``measurements = code``) the model, the z-test, the buffer and the merge tests
  are 1-D over the code residual (a-priori component ``N(0, 2.5^2)``); otherwise
  they are 2-D over ``(code, phase)`` as above.
* ``N`` of eqs. 7.8-7.12 (points characterised by ``GMM_g``) counts the a-priori
  component as one point at the start and then every inlier residual under its
  most likely component.
* The naive adaptation count of Sec. 7.3.2 ("adapted every time the number of
  residuals were greater than the threshold") is ``n_residuals // (T_c + 1)``
  over all tested residuals.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from estimators import register
from estimators.incremental.configs import IceConfig
from estimators.incremental.isam2 import (
    EpochPrediction,
    IncrementalGraphEstimator,
)
from estimators.incremental.nlos_window import NlosAssignment, NlosWindow
from estimators.model.clustering import code_marginal_labels, fit_dpgmm
from estimators.model.mixture_tests import MixtureModel
from estimators.model.nlos_mixture import predictors
from estimators.model.ppp_config import NlosModel
from estimators.model.ppp_graph import PppGraph

__all__ = ["AdaptiveNoiseModel", "Ice"]


@dataclass
class AdaptiveNoiseModel:
    """ICE's measurement uncertainty model with its outlier buffer.

    Parameters
    ----------
    cfg : IceConfig
    cluster : callable, optional
        ``cluster(points) -> labels``; default a DP-GMM fit (:func:`fit_dpgmm`).
    """

    cfg: IceConfig
    cluster: Callable[[np.ndarray], np.ndarray] | None = None
    #: the data carry no carrier phase at all: the model is 1-D over the code residual
    code_only: bool = False
    model: MixtureModel = field(init=False)
    buffer: list[np.ndarray] = field(init=False, default_factory=list)
    n_buffered: int = field(init=False, default=0)
    n_residuals: int = field(init=False, default=0)
    n_outliers: int = field(init=False, default=0)
    adaptations: list[dict] = field(init=False, default_factory=list)

    def __post_init__(self) -> None:
        sigmas = [self.cfg.prior_code_sigma_m] + ([] if self.code_only else [self.cfg.prior_phase_sigma_m])
        prior = np.diag(np.square(sigmas))
        # every component zero-mean (module notes): a scale mixture of the residuals
        zero_mean = np.ones(len(sigmas), bool)
        self.model = MixtureModel.single(np.zeros(len(sigmas)), prior, zero_mean=zero_mean)
        self.model.history.append(self.model.snapshot())
        if self.cluster is None:
            truncation = self.cfg.dpgmm_truncation
            self.cluster = lambda x: fit_dpgmm(x, truncation=truncation).labels

    def classify(
        self, res: np.ndarray, pred_var: np.ndarray | None = None, code_z: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Most likely component and z-test of each residual.

        Parameters
        ----------
        res : ndarray, shape (m, 2), or (m, 1) with ``code_only``
            ``(code, phase)`` residuals [m]; a NaN phase tests the code alone.
        pred_var : ndarray, shape (m, 2) or (m, 1), optional
            Variance the prediction adds to each residual (the predicted position's along the
            line of sight), in the model's units: the z-test's variance is the component's plus
            this one (the innovation's). None: the component's alone.
        code_z : ndarray, shape (m,), optional
            The code channel's z-score where another model tests it (the NLOS model's for its rows,
            :mod:`estimators.incremental.nlos_window`), NaN where the component tests it; None: the
            component's everywhere.

        Returns
        -------
        inlier : ndarray of bool, shape (m,)
        component : ndarray of int, shape (m,)
        """
        mdl = self.model
        full = np.isfinite(res[:, -1])
        comp = np.zeros(len(res), np.int64)
        if mdl.n_components > 1:  # one component is every residual's most likely (the a-priori model)
            if full.any():
                comp[full] = mdl.most_likely(res[full])
            if (~full).any():
                comp[~full] = code_marginal_labels(res[~full, 0], mdl.weights, mdl.means, mdl.covs)
        var = np.diagonal(mdl.covs, axis1=1, axis2=2)[comp]
        sig = np.sqrt(var if pred_var is None else var + pred_var)
        z = np.abs(res - mdl.means[comp]) / sig
        if code_z is not None:
            z[:, 0] = np.where(np.isnan(code_z), z[:, 0], code_z)
        inlier = (z[:, 0] < self.cfg.z_threshold) & ((z[:, -1] < self.cfg.z_threshold) | ~full)
        return inlier, comp

    def observe(
        self, res: np.ndarray, inlier: np.ndarray, comp: np.ndarray, explained: np.ndarray | None = None
    ) -> bool:
        """Count the inliers, buffer the full outlier residuals, adapt past ``T_c``; True if adapted.

        ``explained``: inlier rows another model weighs (the NLOS model's), not counted as points of
        their component."""
        self.n_residuals += len(res)
        counted = inlier if explained is None else inlier & ~explained
        np.add.at(self.model.counts, comp[counted], 1.0)
        out = res[~inlier & np.isfinite(res[:, -1])]
        self.n_outliers += int((~inlier).sum())
        if len(out):
            self.buffer.append(out)
            self.n_buffered += len(out)
        if self.n_buffered <= self.cfg.cluster_threshold:
            return False
        pts = np.vstack(self.buffer)
        assert self.cluster is not None  # set in __post_init__
        labels = self.cluster(pts)
        cfg = self.cfg
        outcome = self.model.adapt(
            pts, labels, alpha=cfg.alpha, min_points=cfg.min_cluster_points, max_components=cfg.max_components
        )
        self.adaptations.append({"n_points": len(pts), "n_clusters": len(np.unique(labels)), **outcome})
        self.buffer, self.n_buffered = [], 0
        return True

    def diagnostics(self) -> dict[str, Any]:
        """Adaptation counts and the model history (one snapshot per adaptation, the prior first)."""
        return {
            "n_adaptations": len(self.adaptations),
            "naive_adaptations": self.n_residuals // (self.cfg.cluster_threshold + 1),
            "n_residuals": int(self.n_residuals),
            "n_outliers": int(self.n_outliers),
            "n_buffered_at_end": int(self.n_buffered),
            "adaptations": self.adaptations,
            "model_history": self.model.history,
            "final_model": self.model.snapshot(),
        }


@register
class Ice(IncrementalGraphEstimator):
    """Incremental covariance estimation (Ch. 7): z-test gating and an adaptive mixture noise model."""

    name = "ice"
    Config = IceConfig

    def _start_run(self) -> None:
        self._noise: AdaptiveNoiseModel | None = None
        self._late: NlosWindow | None = None
        self._predictors = np.empty((0, 0))
        self._records: list[dict] = []

    def _start_models(self, g: PppGraph) -> AdaptiveNoiseModel:
        """ICE's mixture, its dimension following the data (code-only logs get a 1-D model), and the
        NLOS model of ``nlos_model = conditioned``."""
        cfg = self.config
        self._noise = AdaptiveNoiseModel(cfg, code_only=g.obs.n_arcs == 0)
        if NlosModel(cfg.nlos_model) == NlosModel.conditioned:
            self._predictors, names = predictors(g.obs.el, g.obs.cn0)
            self._late = NlosWindow(
                cfg.nlos_window_s, cfg.nlos_min_rows, cfg.nlos_em_iterations, cfg.nlos_weight_init, tuple(names)
            )
        return self._noise

    def _measurements(self, k: int, rows: slice, g: PppGraph, pred: EpochPrediction) -> dict[str, Any] | None:
        noise = self._noise if self._noise is not None else self._start_models(g)
        code_only = noise.code_only
        res = pred.res_code[:, None] if code_only else np.column_stack([pred.res_code, pred.res_phase])
        scale = self._channel_scales(rows, g)[:, : res.shape[1]]
        res = res / scale  # the model's units
        late = self._assign_late(k, rows, g, pred)
        # tested as an innovation: a residual measures the prediction's error as well as the row's
        code_z = None if late is None else np.where(late.nlos, late.z, np.nan)
        inlier, comp = noise.classify(res, pred.los_var[:, None] / np.square(scale), code_z)
        # the model used for this epoch's inliers is the one they were tested against (zero-mean: no offsets)
        covs = noise.model.covs[comp] * scale[:, :, None] * scale[:, None, :]
        if self.config.record_residuals:
            self._records.append(
                {
                    "epoch": int(k),
                    "code": pred.res_code.tolist(),
                    "phase": np.nan_to_num(pred.res_phase, nan=0.0).tolist(),
                    "new_arc": pred.new_arc.tolist(),
                    "inlier": inlier.tolist(),
                }
            )
        noise.observe(res, inlier, comp, None if late is None else late.nlos)
        if inlier.sum() < self.config.min_satellites:
            return None
        out: dict[str, Any] = {"code_sigma": np.sqrt(covs[:, 0, 0]), "use_code": inlier}
        cross = covs[:, 0, 1] if covs.shape[1] > 1 else None
        if late is not None:  # a late row: the NLOS mean off its code, the NLOS spread, no tie to its phase
            out.update(
                code_sigma=np.where(late.nlos, late.sigma, out["code_sigma"]), code_offset=late.offset * late.nlos
            )
            cross = None if cross is None else np.where(late.nlos, 0.0, cross)
        if cross is None:  # code only: the data have no phase rows, so there are no phase factors to weight
            return out
        return {
            **out,
            "phase_sigma": np.sqrt(covs[:, 1, 1]),
            "code_phase_cov": np.where(pred.new_arc, 0.0, cross),
            "use_phase": inlier,
        }

    def _assign_late(self, k: int, rows: slice, g: PppGraph, pred: EpochPrediction) -> NlosAssignment | None:
        """The NLOS model's verdict on the epoch's code rows from the model of the epochs before, then
        the model refitted with them; None without a NLOS model."""
        if self._late is None:
            return None
        sigma, x = g.obs.sigma_code[rows], self._predictors[rows]
        late = self._late.assign(pred.res_code, sigma, pred.los_var, x)
        self._late.add(float(g.obs.epoch_t[k]), pred.res_code, sigma, pred.los_var, x)
        return late

    def _channel_scales(self, rows: slice, g: PppGraph) -> np.ndarray:
        """Per row, the factors that turn metres into the mixture's units, shape (m, 2): code, phase.

        With ``scaled_mixture`` each channel's a-priori sigma over its zenith value: the sigma
        factor (``sigma_model``) on both, times the code's variance factor of the row's system
        (``variance_components``) on the code, so that a system whose code the log shows to be
        noisier (GLONASS's inter-frequency biases) is tested and weighted as every other
        estimator weights it; without, metres (ones).
        """
        obs = g.obs
        if not self.config.scaled_mixture:
            return np.ones((len(obs.sigma_scale[rows]), 2))
        return np.column_stack([obs.sigma_code[rows] / self.config.code_sigma_m, obs.sigma_scale[rows]])

    def _diagnostics(self) -> dict[str, Any]:
        if self._noise is None:
            self._noise = AdaptiveNoiseModel(self.config)
        out = self._noise.diagnostics()
        if self._late is not None:
            out["nlos_model"] = self._late.summary()
        if self.config.record_residuals:
            out["residuals"] = self._records
        return out
