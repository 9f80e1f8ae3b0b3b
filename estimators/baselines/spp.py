"""Per-epoch single-point baselines: weighted least squares (``wls_spp``) and Huber IRLS (``huber_spp``).

Every epoch is solved on its own from its code rows (no motion model, no phase):
position plus one receiver clock per GNSS system, by
:func:`simbench.gnss.spp.solve_epochs` on the shared measurement preparation
(:func:`estimators.model.measurement.prepare_ppp`: the same corrections, ionosphere
mode, sigma model and variance components as every other GNSS estimator). They
are the floor a real-log table needs: an estimator with a motion model and a
robust loss that loses to a per-epoch fix on the same rows has a defect in its
model. ``huber_spp`` re-weights each row by ``min(1, huber_k / |residual / sigma|)``
for a few passes (iteratively reweighted least squares).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pandas as pd

from estimators import register
from estimators.base import Estimator, solution_frame
from estimators.baselines.configs import HuberSppConfig, WlsSppConfig
from estimators.model.measurement import PppObservations, prepare_ppp
from estimators.model.ppp_config import MeasurementMode
from simbench.contract import ReceiverData
from simbench.gnss.spp import SppSolution

__all__ = ["HuberSpp", "WlsSpp"]

#: A single-point fix needs position and a clock: epochs with fewer rows are not solved.
_MIN_SATELLITES = 4


@register
class WlsSpp(Estimator):
    """Weighted least-squares single-point position of every epoch on its own (code only)."""

    name = "wls_spp"
    Config = WlsSppConfig

    def _solve(self, obs: PppObservations) -> SppSolution:
        """Per-epoch fixes on the prepared rows: plain weighted least squares (subclasses add a loss)."""
        return obs.single_point()

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        start, cfg = time.perf_counter(), self.config
        obs = prepare_ppp(
            data,
            ionosphere=cfg.ionosphere,
            code_sigma_m=cfg.code_sigma_m,
            phase_sigma_m=1.0,  # no phase is used
            elevation_mask_deg=cfg.elevation_mask_deg,
            min_satellites=_MIN_SATELLITES,
            measurements=MeasurementMode.code,
            sigma_model=cfg.sigma_model,
            cn0_ref_dbhz=cfg.cn0_ref_dbhz,
            variance_components=cfg.variance_components,
        )
        sol = self._solve(obs)
        ok = sol.trusted
        update_s = np.full(int(ok.sum()), (time.perf_counter() - start) / max(int(ok.sum()), 1))
        frame = solution_frame(obs.epoch_ids[ok], obs.epoch_t[ok], sol.pos[ok], update_s)
        downweighted = sol.weight[np.repeat(ok, obs.epoch_stop - obs.epoch_start)] < 1.0
        diagnostics = {
            "n_epochs": int(obs.n_epochs),
            "n_trusted": int(ok.sum()),
            "n_observations": int(obs.n_obs),
            "downweighted_share": float(downweighted.mean()) if downweighted.size else 0.0,
            **obs.model_info(),
        }
        return frame, diagnostics


@register
class HuberSpp(WlsSpp):
    """Single-point position of every epoch on its own, code residuals Huber-weighted (IRLS)."""

    name = "huber_spp"
    Config = HuberSppConfig

    def _solve(self, obs: PppObservations) -> SppSolution:
        return obs.single_point(huber_k=float(self.config.huber_k), reweightings=int(self.config.reweightings))
