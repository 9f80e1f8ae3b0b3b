"""The iSAM2 loop (iSAM2-PPP, incremental DCS/MM) and ICE's adaptive noise model."""

from __future__ import annotations

import numpy as np
import pytest

import simbench
from estimators.batch.configs import L2Config
from estimators.batch.robust import L2Batch
from estimators.incremental.configs import IceConfig, IncrementalConfig
from estimators.incremental.ice import AdaptiveNoiseModel, Ice
from estimators.incremental.isam2 import Isam2Mm, Isam2Ppp


@pytest.fixture(scope="module")
def scenario() -> simbench.Scenario:
    return simbench.simulate("open_sky", "high", seed=1001, **{"scenario.duration_s": 120})


@pytest.mark.parametrize("ionosphere_free", [False, True])
def test_isam2_ppp_matches_batch_l2_at_the_last_epoch(scenario: simbench.Scenario, ionosphere_free: bool) -> None:
    # same graph model and data: the filtered iSAM2 estimate of the last epoch is the batch smoother's
    common = {"ionosphere": "free" if ionosphere_free else "broadcast", "ambiguity_sigma_m": 10.0}
    inc = Isam2Ppp(IncrementalConfig(**common)).estimate(scenario.receiver_view()).epochs
    batch = L2Batch(L2Config(**common)).estimate(scenario.receiver_view()).epochs
    assert inc["epoch"].iloc[-1] == batch["epoch"].iloc[-1]
    diff = np.linalg.norm(inc[["x", "y", "z"]].iloc[-1].to_numpy() - batch[["x", "y", "z"]].iloc[-1].to_numpy())
    assert diff < 0.05, diff
    # earlier epochs differ (filter vs smoother), so the comparison is not vacuous
    first = np.linalg.norm(inc[["x", "y", "z"]].iloc[0].to_numpy() - batch[["x", "y", "z"]].iloc[0].to_numpy())
    assert first > diff


def test_fixed_lag_window_keeps_the_filtered_solution(scenario: simbench.Scenario) -> None:
    # marginalising everything older than 5 s (arc biases stay alive) must not change the
    # filtered positions beyond relinearisation effects (mm)
    data = scenario.receiver_view()
    full = Isam2Ppp(IncrementalConfig(lag_s=0.0)).estimate(data).epochs
    lagged = Isam2Ppp(IncrementalConfig(lag_s=5.0)).estimate(data).epochs
    diff = np.linalg.norm(full[["x", "y", "z"]].to_numpy() - lagged[["x", "y", "z"]].to_numpy(), axis=1)
    assert len(full) == len(lagged) == 120 and diff.max() < 0.01, diff.max()


def test_mm_flags_a_code_outlier(scenario: simbench.Scenario) -> None:
    data = scenario.receiver_view()
    obs = data.observations.copy()
    hit = obs["epoch"].between(60, 70) & (obs["sat"] == obs["sat"].iloc[0])
    obs.loc[hit, "code_l1"] += 80.0
    bad = simbench.contract.ReceiverData(obs, data.imu, data.nav)
    sol = Isam2Mm().estimate(bad)
    assert sol.diagnostics["outlier_code"] >= int(hit.sum())
    plain = Isam2Ppp().estimate(bad).epochs
    truth = scenario.truth.set_index("epoch").loc[sol.epochs["epoch"], ["x", "y", "z"]].to_numpy()
    err_mm = np.linalg.norm(sol.epochs[["x", "y", "z"]].to_numpy() - truth, axis=1)[60:71].max()
    err_l2 = np.linalg.norm(plain[["x", "y", "z"]].to_numpy() - truth, axis=1)[60:71].max()
    assert err_mm < err_l2, (err_mm, err_l2)


def test_ice_z_test_partitions_residuals_and_adapts_past_the_threshold() -> None:
    cfg = IceConfig(cluster_threshold=300)
    rng = np.random.default_rng(0)

    def cluster(x: np.ndarray) -> np.ndarray:  # a stand-in clustering: split at 15 m of code residual
        return (x[:, 0] > 15.0).astype(int)

    noise = AdaptiveNoiseModel(cfg, cluster)
    adapted = []
    for _ in range(60):
        good = rng.normal(0, [2.5, 0.25], size=(8, 2))
        bad = rng.normal([30.0, 0.0], [2.0, 0.2], size=(6, 2))
        res = np.vstack([good, bad])
        inlier, comp = noise.classify(res)
        assert inlier[8:].sum() <= 1 if noise.model.n_components == 1 else True
        adapted.append(noise.observe(res, inlier, comp))
    diag = noise.diagnostics()
    # 6 outliers per epoch (plus the odd 3-sigma inlier): more than 300 buffered after 50 or 51 epochs
    assert diag["n_adaptations"] == 1 and adapted.index(True) in (49, 50)
    assert diag["naive_adaptations"] == 60 * 14 // 301
    assert noise.model.n_components == 2
    # zero-mean components (estimators.incremental.ice notes): the new one is as wide as the residuals' second moment
    np.testing.assert_array_equal(noise.model.means[1], [0.0, 0.0])
    np.testing.assert_allclose(np.sqrt(noise.model.covs[1][0, 0]), np.hypot(30.0, 2.0), rtol=0.05)
    # after the adaptation the NLOS-like residuals are inliers of the new component
    inlier, comp = noise.classify(np.array([[30.0, 0.1], [0.5, 0.01]]))
    assert inlier.all() and comp.tolist() == [1, 0]
    assert len(diag["model_history"]) == 2


def test_ice_runs_and_reports_its_model(scenario: simbench.Scenario) -> None:
    sol = Ice(IceConfig(cluster_threshold=50)).estimate(scenario.receiver_view())
    d = sol.diagnostics
    assert d["n_residuals"] > 0 and d["naive_adaptations"] == d["n_residuals"] // 51
    assert len(d["model_history"]) == d["n_adaptations"] + 1
    assert np.isclose(sum(d["final_model"]["weights"]), 1.0)
