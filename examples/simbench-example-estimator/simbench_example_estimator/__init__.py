"""Example simbench plug-in: epoch-by-epoch single-point positions with Cauchy-weighted code.

Installed with ``pip install -e examples/simbench-example-estimator``, it is the
estimator ``cauchy_spp`` (entry point in ``pyproject.toml``): listed by
``python -m simbench --estimators``, selected with ``estimator=[l2,cauchy_spp]``,
and part of the default run and the sweeps. Its parameters are :class:`CauchySppConfig`
(``estimator.cauchy_spp.cauchy_c=3`` on the command line); ``cauchy_spp.yaml`` beside
this file may override their defaults.

The built-in per-epoch baselines are ``wls_spp`` and ``huber_spp``
(``estimators/baselines/spp.py``); this example shows how a package adds a further
loss on the same shared measurement model: it subclasses ``wls_spp``, so it keeps its
row preparation (ionosphere mode, sigma model, per-system variance components,
elevation mask) and its diagnostics, and replaces only the per-epoch solve. Its config
extends :class:`~estimators.baselines.configs.IrlsSppConfig` (``wls_spp``'s parameters and
the IRLS passes, as ``huber_spp``'s does) by the loss's scale and its check.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from estimators.baselines.configs import IrlsSppConfig
from estimators.baselines.spp import WlsSpp
from estimators.model.measurement import PppObservations
from simbench.errors import require_positive
from simbench.gnss.spp import SppSolution


@dataclass
class CauchySppConfig(IrlsSppConfig):
    """``wls_spp``'s parameters (the shared sigma model) and the IRLS passes, plus the Cauchy scale."""

    #: Cauchy scale [standard deviations]: 95 % efficiency under Gaussian noise
    cauchy_c: float = 2.385

    def validate(self, where: str) -> None:
        """The inherited checks, then the scale's."""
        super().validate(where)
        require_positive(f"{where}.cauchy_c", self.cauchy_c, "give a scale in standard deviations, e.g. 2.385")


class CauchySpp(WlsSpp):
    """Single-point positions per epoch, code residuals Cauchy-weighted by iterative reweighting."""

    name = "cauchy_spp"
    Config = CauchySppConfig

    def _solve(self, obs: PppObservations) -> SppSolution:
        cfg = self.config
        sol = obs.single_point()
        for _ in range(cfg.reweightings):
            # Cauchy weight 1 / (1 + (z/c)^2) as an inflated sigma, sigma / sqrt(weight); rows of
            # epochs without a trusted fit (residual NaN) keep their plain weight
            z = np.nan_to_num(sol.residual_m / obs.sigma_code)
            sigma = obs.sigma_code * np.sqrt(1.0 + (z / cfg.cauchy_c) ** 2)
            sol = obs.single_point(sigma=sigma, x0=np.nan_to_num(sol.pos))
        return sol
