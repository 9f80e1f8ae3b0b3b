"""Oracle: the PPP graph weighted with the true error sigmas of the labels (reads labels).

The accuracy floor the adaptive estimators are measured against, and the only
estimator allowed to read the error labels (``requires`` holds ``Need.labels``):

* NLOS observations (label ``nlos``) are removed before preparation;
* each code measurement gets ``sqrt(sigma_code_l1^2 + sigma_multipath_code_l1^2 + g^2 + o^2)``
  (thermal jitter and the stationary multipath std of that observation, ``g``
  its sample-grid code error ``sample_grid_code_l1``, a slowly varying bias the
  oracle knows; no elevation model);
* each phase measurement gets ``sqrt(sigma_phase_l1^2 + q^2 + o^2)`` with ``q`` the RMS
  of the carrier multipath in the labels of the scenario (no per-observation carrier
  multipath sigma is labelled);
* ``o`` is the RMS of the labelled orbit/clock product error (centimetres): the same
  on code and phase, it is negligible for the code but dominates the millimetre
  phase jitter, and leaving it out makes the oracle over-trust the phase.

Labels are row-aligned with the observation table; prepared rows (dropped and
sorted by :func:`~estimators.model.measurement.prepare_ppp`) find theirs by (epoch, satellite).
One Levenberg-Marquardt solve, as ``l2``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from estimators import register
from estimators.batch.configs import OracleConfig
from estimators.batch.robust import BatchGraphEstimator
from estimators.model.measurement import prepare_ppp
from estimators.model.ppp_graph import PppGraph
from simbench.contract import Need, ReceiverData
from simbench.errors import SimbenchError

__all__ = ["Oracle"]


@register
class Oracle(BatchGraphEstimator[OracleConfig]):
    """Batch PPP with the true per-observation sigmas and NLOS removed (reads labels)."""

    name = "oracle"
    Config = OracleConfig
    requires = frozenset({Need.labels})

    def _prepare(self, data: ReceiverData):
        if self._labels is None:
            raise SimbenchError(
                "oracle", "needs the error labels", "run it through simbench.runs.runner (real data has none)"
            )
        lab = self._labels
        obs_tab = data.observations
        if len(lab) != len(obs_tab) or not (
            np.array_equal(lab["epoch"].to_numpy(), obs_tab["epoch"].to_numpy())
            and np.array_equal(lab["sat"].to_numpy(), obs_tab["sat"].to_numpy())
        ):
            raise SimbenchError(
                "labels", "not row-aligned with the observations", "pass the labels of the same scenario"
            )
        los = ~lab["nlos"].to_numpy(bool)
        clean = replace(data, observations=obs_tab.loc[los].reset_index(drop=True))
        obs = prepare_ppp(clean, **self.config.prepare_kwargs())
        return obs, PppGraph(obs, self.config)

    def _a_priori_sigmas(self, obs):
        labels = self._labels
        assert labels is not None  # _prepare refuses to run without them
        lab = labels.set_index(["epoch", "sat"])
        rows = lab.reindex(pd.MultiIndex.from_arrays([obs.epoch, obs.sat]))

        def rms(col: str) -> float:
            return float(np.sqrt(np.mean(labels[col].to_numpy(float) ** 2)))

        orbit = rms("orbit_clock_error")
        code = np.sqrt(
            rows["sigma_code_l1"].to_numpy(float) ** 2
            + rows["sigma_multipath_code_l1"].to_numpy(float) ** 2
            + rows["sample_grid_code_l1"].to_numpy(float) ** 2
            + orbit**2
        )
        phase = np.sqrt(rows["sigma_phase_l1"].to_numpy(float) ** 2 + rms("multipath_phase_l1") ** 2 + orbit**2)
        s = np.sqrt(self.config.prior_scale)
        return code * s, phase * s

    def _run(self, data, obs, g, structure):
        values = self._l2(g, structure).values
        sc, sp = self._a_priori_sigmas(obs)
        return values, {
            "iterations": 1,
            "median_code_sigma_m": float(np.median(sc)),
            "median_phase_sigma_m": float(np.median(sp)),
            "uses_labels": True,
        }
