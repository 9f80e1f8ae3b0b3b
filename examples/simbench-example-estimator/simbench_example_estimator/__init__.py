"""Example simbench plug-in: epoch-by-epoch single-point positions with Cauchy-weighted code.

Installed with ``pip install -e examples/simbench-example-estimator``, it is the
estimator ``cauchy_spp`` (entry point in ``pyproject.toml``): listed by
``python -m simbench --estimators``, selected with ``estimator=[l2,cauchy_spp]``,
and part of the default run and the sweeps. Its parameters are :class:`CauchySppConfig`
(``estimator.cauchy_spp.cauchy_c=3`` on the command line); ``cauchy_spp.yaml`` beside
this file may override their defaults.

The built-in per-epoch baselines are ``wls_spp`` and ``huber_spp``
(``estimators/spp_baselines.py``); this example shows how a package adds a further
loss on the same shared measurement model.
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
from simbench.errors import require_positive
from simbench.gnss.spp import solve_epochs


@dataclass
class CauchySppConfig:
    code_sigma_m: float = 3.0  #: zenith code standard deviation, scaled by 1/sin(el) [m]
    elevation_mask_deg: float = 10.0
    #: Cauchy scale [standard deviations]: 95 % efficiency under Gaussian noise
    cauchy_c: float = 2.385
    reweightings: int = 5  #: iteratively reweighted least-squares passes after the plain fit

    def validate(self, where: str) -> None:
        for key in ("code_sigma_m", "cauchy_c"):
            require_positive(f"{where}.{key}", getattr(self, key), "give a positive value")


class CauchySpp(Estimator):
    """Single-point positions per epoch, code residuals Cauchy-weighted by iterative reweighting."""

    name = "cauchy_spp"
    Config = CauchySppConfig

    def _estimate(self, data: ReceiverData) -> tuple[pd.DataFrame, dict[str, Any]]:
        start, cfg = time.perf_counter(), self.config
        obs = prepare_ppp(
            data,
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
            # Cauchy weight 1 / (1 + (z/c)^2) as an inflated sigma: sigma / sqrt(weight); rows of
            # epochs without a trusted fit (residual NaN) keep their plain weight
            z = np.nan_to_num(sol.residual_m / obs.sigma_code)
            sigma = obs.sigma_code * np.sqrt(1.0 + (z / cfg.cauchy_c) ** 2)
            sol = solve_epochs(sigma=sigma, x0=np.nan_to_num(sol.pos), **rows)
        solved = np.flatnonzero(sol.trusted)
        t = pd.Series(obs.epoch_t, index=obs.epoch_ids).loc[solved].to_numpy()
        update_s = np.full(len(solved), (time.perf_counter() - start) / max(len(solved), 1))
        return solution_frame(solved, t, sol.pos[solved], update_s), {"n_trusted": int(len(solved))}
