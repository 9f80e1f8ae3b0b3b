"""The built-in per-epoch baselines ``wls_spp`` and ``huber_spp`` (estimators/baselines/spp.py).

Simulated tuning seeds (>= 1000), the ``high`` receiver (dual frequency). Open sky: both
within a few metres of the truth on every epoch they solve. With code blunders injected on a
tenth of the rows, Huber's reweighting must beat plain weighted least squares in median and p95.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

import estimators
import simbench
from estimators.model.ppp_config import SigmaModel
from simbench.analysis.metrics import enu_errors

SEED = 1003


@pytest.fixture(scope="module")
def open_sky() -> simbench.Scenario:
    return simbench.simulate("open_sky", "high", seed=SEED, **{"scenario.duration_s": 120})


def _errors(name: str, scenario: simbench.Scenario, **config: object) -> tuple[np.ndarray, dict]:
    cls = estimators.get(name)
    sol = cls(cls.Config(**config)).estimate(scenario.receiver_view())
    return enu_errors(sol.epochs, scenario.truth)["horizontal"].to_numpy(), sol.diagnostics


@pytest.mark.parametrize("name", ["wls_spp", "huber_spp"])
def test_baselines_against_truth_in_the_open(name: str, open_sky: simbench.Scenario) -> None:
    err, info = _errors(name, open_sky)
    assert len(err) >= 0.95 * len(open_sky.truth)  # every epoch with 4 satellites is solved
    assert np.median(err) < 3.0 and np.percentile(err, 95) < 6.0, (np.median(err), np.percentile(err, 95))
    assert info["systems"] == ["G"] and info["ionosphere_free"]  # open_sky is dual-frequency: auto picks free


def test_huber_beats_wls_with_blunders(open_sky: simbench.Scenario) -> None:
    """Every satellite also seen as a Galileo one (about 16 rows per epoch, as a multi-system
    receiver has), code blunders of 30-80 m on a tenth of the rows."""
    rng = np.random.default_rng(SEED)
    obs = open_sky.observations
    obs = pd.concat([obs, obs.assign(sat="E" + obs["sat"].str[1:])], ignore_index=True)
    blunder = rng.random(len(obs)) < 1 / 10
    excess = np.where(blunder, rng.uniform(30.0, 80.0, len(obs)), 0.0)  # a longer path: on both frequencies
    hit = obs.assign(code_l1=obs["code_l1"] + excess, code_l2=obs["code_l2"] + excess)
    scenario = dataclasses.replace(open_sky, observations=hit)
    # elevation weights: the blunders do not change the C/N0, so both see the same a-priori sigmas
    wls, _ = _errors("wls_spp", scenario, sigma_model=SigmaModel.elevation)
    huber, info = _errors("huber_spp", scenario, sigma_model=SigmaModel.elevation)
    assert np.median(huber) < 0.5 * np.median(wls), (np.median(huber), np.median(wls))
    assert np.percentile(huber, 95) < 0.5 * np.percentile(wls, 95)
    assert info["downweighted_share"] > 1 / 10 and info["systems"] == ["G", "E"]
