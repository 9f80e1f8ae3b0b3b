"""Example simbench plug-in: epoch-by-epoch single-point positions with Huber-weighted code.

Installed with ``pip install -e examples/simbench-example-estimator``, it is the
estimator ``huber_spp`` (entry point in ``pyproject.toml``): listed by
``python -m simbench --estimators``, selected with ``estimator=[l2,huber_spp]``,
and part of the default run and the sweeps. Its parameters are :class:`HuberSppConfig`
(``estimator.huber_spp.huber_k=2`` on the command line); ``huber_spp.yaml`` beside
this file may override their defaults.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from estimators.base import Estimator, solution_frame
from estimators.measurement import prepare_ppp
from estimators.ppp_config import MeasurementMode
from simbench.contract import ReceiverData
from simbench.core.frames import geodetic_from_ecef
from simbench.errors import require_positive
from simbench.gnss.geometry import sagnac_range
from simbench.gnss.spp import solve_epochs
from simbench.gnss.troposphere import troposphere_terms


@dataclass
class HuberSppConfig:
    code_sigma_m: float = 3.0  #: zenith code standard deviation, scaled by 1/sin(el) [m]
    elevation_mask_deg: float = 10.0
    huber_k: float = 1.345  #: Huber threshold [standard deviations]: 95 % efficiency under Gaussian noise
    reweightings: int = 5  #: iteratively reweighted least-squares passes after the plain fit

    def validate(self, where: str) -> None:
        for key in ("code_sigma_m", "huber_k"):
            require_positive(f"{where}.{key}", getattr(self, key), "give a positive value")


class HuberSpp(Estimator):
    """Single-point positions per epoch, code residuals Huber-weighted by iterative reweighting."""

    name = "huber_spp"
    Config = HuberSppConfig

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        start, cfg = time.perf_counter(), self.config
        obs = prepare_ppp(
            data,
            ionosphere_free=False,
            code_sigma_m=cfg.code_sigma_m,
            phase_sigma_m=1.0,
            elevation_mask_deg=cfg.elevation_mask_deg,
            measurements=MeasurementMode.code,
        )
        rows = dict(
            epoch=obs.epoch,
            sat_pos=obs.sat_pos,
            code=obs.code,
            n_epochs=int(obs.epoch_ids.max()) + 1,
            system_index=obs.system_index,
            el=obs.el,
            doy=obs.doy,
        )
        sol = solve_epochs(sigma=obs.sigma_code, **rows)
        for _ in range(cfg.reweightings):
            # rows of epochs without a trusted fit (position NaN) keep their plain weight
            ok = sol.trusted[obs.epoch]
            at = sol.pos[obs.epoch[ok]]
            lat, _, h = geodetic_from_ecef(at)
            residual = (
                obs.code[ok]
                - sagnac_range(obs.sat_pos[ok], at)
                - sol.clock_m[obs.epoch[ok], obs.system_index[ok]]
                - troposphere_terms(obs.el[ok], lat, h, obs.doy)[0]
            )
            # Huber weight min(1, k/|z|) as an inflated sigma: sigma / sqrt(weight)
            sigma = obs.sigma_code.copy()
            sigma[ok] *= np.sqrt(np.maximum(1.0, np.abs(residual) / obs.sigma_code[ok] / cfg.huber_k))
            sol = solve_epochs(sigma=sigma, x0=np.nan_to_num(sol.pos), **rows)
        solved = np.flatnonzero(sol.trusted)
        t = pd.Series(obs.epoch_t, index=obs.epoch_ids).loc[solved].to_numpy()
        update_s = np.full(len(solved), (time.perf_counter() - start) / max(len(solved), 1))
        return solution_frame(solved, t, sol.pos[solved], update_s), {"n_trusted": int(len(solved))}
