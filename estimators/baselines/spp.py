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
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from estimators import register
from estimators.base import Estimator, solution_frame
from estimators.model.measurement import PppObservations, prepare_ppp
from estimators.model.ppp_config import (
    GnssModelConfig,
    IonosphereMode,
    MeasurementMode,
    SigmaModel,
    StochasticModelConfig,
    VarianceComponents,
)
from simbench.contract import Need, ReceiverData
from simbench.errors import require_at_least, require_elevation_mask, require_positive
from simbench.gnss.spp import SppSolution
from simbench.typed import check_choices

__all__ = ["HuberSpp", "HuberSppConfig", "WlsSpp", "WlsSppConfig"]

#: A single-point fix needs position and a clock: epochs with fewer rows are not solved.
_MIN_SATELLITES = 4


@dataclass
class WlsSppConfig:
    """Parameters of ``wls_spp``: the shared sigma model (defaults of :class:`GnssModelConfig` and
    :class:`StochasticModelConfig`), so the baseline weighs rows as the other estimators do."""

    code_sigma_m: float = StochasticModelConfig.code_sigma_m  #: zenith code sigma [m], scaled by ``sigma_model``
    #: per-row scaling of the sigma: elevation | cn0 | elevation_cn0
    sigma_model: SigmaModel = GnssModelConfig.sigma_model
    cn0_ref_dbhz: float = StochasticModelConfig.cn0_ref_dbhz  #: C/N0 at which the ``cn0`` factor is 1 [dB-Hz]
    elevation_mask_deg: float = StochasticModelConfig.elevation_mask_deg  #: [deg]
    #: auto | broadcast | free (:class:`~estimators.model.ppp_config.IonosphereMode`)
    ionosphere: IonosphereMode = GnssModelConfig.ionosphere
    #: none | system | system_cn0 (:class:`~estimators.model.ppp_config.VarianceComponents`)
    variance_components: VarianceComponents = GnssModelConfig.variance_components

    def validate(self, where: str) -> None:
        """Raise a one-line :class:`SimbenchError` for the first out-of-range field."""
        check_choices(self, where)
        require_positive(f"{where}.code_sigma_m", self.code_sigma_m, "give a standard deviation in metres")
        require_positive(f"{where}.cn0_ref_dbhz", self.cn0_ref_dbhz, "give a reference C/N0 in dB-Hz, e.g. 45")
        require_elevation_mask(
            f"{where}.elevation_mask_deg", self.elevation_mask_deg, "give an elevation mask in degrees, e.g. 7"
        )

    def needs(self) -> frozenset[Need]:
        """A second frequency for ``ionosphere=free``; nothing else (code only)."""
        return frozenset({Need.dual_frequency} if self.ionosphere == IonosphereMode.free else ())


@dataclass
class HuberSppConfig(WlsSppConfig):
    """Parameters of ``huber_spp``: ``wls_spp``'s plus the Huber loss."""

    huber_k: float = 1.345  #: Huber threshold [standard deviations]: 95 % efficiency under Gaussian noise
    reweightings: int = 5  #: iteratively reweighted least-squares passes after the plain fit

    def validate(self, where: str) -> None:
        """The ``wls_spp`` checks, then the loss's."""
        super().validate(where)
        require_positive(f"{where}.huber_k", self.huber_k, "give a threshold in standard deviations, e.g. 1.345")
        require_at_least(f"{where}.reweightings", self.reweightings, 1, "give the number of IRLS passes, e.g. 5")


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
