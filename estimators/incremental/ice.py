"""ICE: incremental covariance estimation on iSAM2 (dissertation Sec. 7.2).

Each epoch the iSAM2 loop of :mod:`estimators.incremental.isam2` predicts the 2-D
residual ``r = (code, phase)`` of every satellite [m]. :class:`AdaptiveNoiseModel`
then

1. picks each residual's most likely component of the model ``GMM_g`` (eq. 7.1)
   and z-tests it per channel, ``|r_i - mu_i| / sigma_i < T_r`` (eq. 7.2);
2. sends the inliers to iSAM2 with that component's full 2x2 covariance as the
   noise model and its mean subtracted from the measurements;
3. buffers the outliers (they never enter the graph); when more than ``T_c`` are
   buffered it fits a variational DP-GMM to them
   (:func:`estimators.model.clustering.fit_dpgmm`) and merges each new component into the
   model when both the W covariance test and the Hotelling mean test accept, else
   adds it (:meth:`estimators.model.mixture_tests.MixtureModel.adapt`, eqs. 7.4-7.12),
   then clears the buffer.

An epoch with fewer than ``min_satellites`` inlier satellites gets no GNSS
update (the motion model carries the state; 4 in the dissertation's model). The
a-priori model is one zero-mean component ``diag(2.5^2, 0.25^2)`` m^2
(REFERENCE.md); like BCE's clusters it is a model of the raw residuals, so ICE
does not scale it with elevation. With ``scaled_mixture`` (the ``urban`` GNSS
model) the mixture is a model of each residual divided by its row's sigma factor
(C/N0), and a component's covariance is scaled back per row: a weak signal is
tested and weighted against a wider component.

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
from estimators.incremental.isam2 import (
    EpochPrediction,
    IncrementalConfig,
    IncrementalGraphEstimator,
)
from estimators.model.clustering import code_marginal_labels, fit_dpgmm
from estimators.model.mixture_tests import MixtureModel
from estimators.model.ppp_config import GnssModelConfig
from estimators.model.ppp_graph import PppGraph
from simbench.errors import SimbenchError

__all__ = ["AdaptiveNoiseModel", "Ice", "IceConfig"]


@dataclass
class IceConfig(IncrementalConfig):
    """ICE parameters (REFERENCE.md, original implementation) on top of the iSAM2 loop.

    The measurement noise is ICE's mixture model; ``code_sigma_m`` and
    ``phase_sigma_m`` only weight the per-epoch residual prediction.
    """

    z_threshold: float = 3.0  #: T_r, z-test threshold per channel [sigmas]
    cluster_threshold: int = 1000  #: T_c, adapt when more outliers than this are buffered
    alpha: float = 0.05  #: significance of the W and Hotelling merge tests
    max_components: int = 20  #: components of the model at most
    min_cluster_points: int = 2  #: new clusters with fewer points are dropped
    #: the mixture models residuals divided by each row's sigma factor (``sigma_model``), not metres
    scaled_mixture: bool = GnssModelConfig.scaled_mixture
    prior_code_sigma_m: float = 2.5  #: a-priori model code sigma [m] (not elevation-scaled)
    prior_phase_sigma_m: float = 0.25  #: a-priori model phase sigma [m]
    dpgmm_truncation: int = 10  #: stick-breaking truncation of the DP-GMM fit
    #: keep the per-epoch inlier/outlier residuals in the diagnostics (for a Fig. 7.3.2 scatter)
    record_residuals: bool = False

    def validate(self, where: str) -> None:
        """One-line :class:`SimbenchError` for the first out-of-range field (``where``: config node name)."""
        super().validate(where)
        checks = (
            ("z_threshold", self.z_threshold > 0),
            ("cluster_threshold", self.cluster_threshold >= 1),
            ("alpha", 0 < self.alpha < 1),
            ("max_components", self.max_components >= 1),
            ("min_cluster_points", self.min_cluster_points >= 1),
            ("prior_code_sigma_m", self.prior_code_sigma_m > 0),
            ("prior_phase_sigma_m", self.prior_phase_sigma_m > 0),
            ("dpgmm_truncation", self.dpgmm_truncation >= 1),
        )
        for name, ok in checks:
            if not ok:
                raise SimbenchError(
                    f"{where}.{name}",
                    f"out of range: {getattr(self, name)}",
                    "the defaults are in IceConfig (estimators/incremental/ice.py)",
                )


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
        self.model = MixtureModel.single(np.zeros(len(sigmas)), prior)
        self.model.history.append(self.model.snapshot())
        if self.cluster is None:
            truncation = self.cfg.dpgmm_truncation
            self.cluster = lambda x: fit_dpgmm(x, truncation=truncation).labels

    def classify(self, res: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Most likely component and z-test of each residual.

        Parameters
        ----------
        res : ndarray, shape (m, 2), or (m, 1) with ``code_only``
            ``(code, phase)`` residuals [m]; a NaN phase tests the code alone.

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
        sig = np.sqrt(np.diagonal(mdl.covs, axis1=1, axis2=2))[comp]
        z = np.abs(res - mdl.means[comp]) / sig
        inlier = (z[:, 0] < self.cfg.z_threshold) & ((z[:, -1] < self.cfg.z_threshold) | ~full)
        return inlier, comp

    def observe(self, res: np.ndarray, inlier: np.ndarray, comp: np.ndarray) -> bool:
        """Count the inliers, buffer the full outlier residuals, adapt past ``T_c``; True if adapted."""
        self.n_residuals += len(res)
        np.add.at(self.model.counts, comp[inlier], 1.0)
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
        self._records: list[dict] = []

    def _measurements(self, k: int, rows: slice, g: PppGraph, pred: EpochPrediction) -> dict[str, Any] | None:
        if self._noise is None:  # the model's dimension follows the data: code-only logs get a 1-D model
            self._noise = AdaptiveNoiseModel(self.config, code_only=g.obs.n_arcs == 0)
        code_only = self._noise.code_only
        scale = g.obs.sigma_scale[rows] if self.config.scaled_mixture else np.ones(len(pred.res_code))
        res = pred.res_code[:, None] if code_only else np.column_stack([pred.res_code, pred.res_phase])
        res = res / scale[:, None]  # the model's units
        inlier, comp = self._noise.classify(res)
        # the model used for this epoch's inliers is the one they were tested against
        means = self._noise.model.means[comp] * scale[:, None]
        covs = self._noise.model.covs[comp] * np.square(scale)[:, None, None]
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
        self._noise.observe(res, inlier, comp)
        if inlier.sum() < self.config.min_satellites:
            return None
        if code_only:  # the data have no phase rows, so there are no phase factors to weight
            return {"code_sigma": np.sqrt(covs[:, 0, 0]), "code_offset": means[:, 0], "use_code": inlier}
        return {
            "code_sigma": np.sqrt(covs[:, 0, 0]),
            "phase_sigma": np.sqrt(covs[:, 1, 1]),
            "code_phase_cov": np.where(pred.new_arc, 0.0, covs[:, 0, 1]),
            "code_offset": means[:, 0],
            "phase_offset": np.where(pred.new_arc, 0.0, means[:, 1]),
            "use_code": inlier,
            "use_phase": inlier,
        }

    def _diagnostics(self) -> dict[str, Any]:
        if self._noise is None:
            self._noise = AdaptiveNoiseModel(self.config)
        out = self._noise.diagnostics()
        if self.config.record_residuals:
            out["residuals"] = self._records
        return out
