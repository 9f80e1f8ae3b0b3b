"""CRT-LSS: the S step, agreement with a batch smoother, outliers ending up in S, window Jacobians, validation."""
from __future__ import annotations

import gtsam
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import simbench
from estimators.crt_lss import CrtLss, CrtLssConfig
from estimators.gnss_ins_data import prepare_gnss_ins
from estimators.gnss_ins_driver import run_gnss_ins
from estimators.window_solver import (
    CLK,
    DRIFT,
    NS,
    POS,
    VEL,
    WindowNode,
    WindowSolver,
    soft_threshold,
    window_gnss_terms,
)
from simbench.contract import Need, ReceiverData
from simbench.errors import SimbenchError
from simbench.metrics import enu_errors

DURATION_S = 50.0
#: seconds to the injected outlier: after the heading reset, inside the drive
OUTLIER_EPOCH = 40


@pytest.fixture(scope="module")
def clean() -> simbench.Scenario:
    """Open sky with no outlier sources: exact models up to the simulator's noise."""
    return simbench.simulate("open_sky", "high", seed=1000, **{"scenario.duration_s": DURATION_S})


def _cfg(**kw) -> CrtLssConfig:
    return CrtLssConfig(**kw)


def test_soft_threshold_is_the_closed_form_minimiser() -> None:
    rng = np.random.default_rng(0)
    c = rng.normal(0.0, 4.0, 40)
    lam = 1.7
    brute = np.array([minimize_scalar(lambda s, ci=ci: (ci - s) ** 2 + 2 * lam * abs(s),
                                      bounds=(-30, 30), method="bounded", options={"xatol": 1e-9}).x for ci in c])
    np.testing.assert_allclose(soft_threshold(c, lam), brute, atol=1e-5)
    assert np.all(soft_threshold(c, lam)[np.abs(c) <= lam] == 0.0)


def test_s_step_equals_soft_threshold_of_whitened_residuals(clean: simbench.Scenario,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    captured = {}
    orig = WindowSolver.s_step

    def spy(self: WindowSolver) -> float:
        e, _, w, _ = window_gnss_terms(self.nodes, jacobian=False)
        out = orig(self)
        captured["c"], captured["w"] = -e, w
        captured["s"] = np.concatenate([np.concatenate([n.s_code for n in self.nodes if n.gnss is not None]),
                                        np.concatenate([n.s_rr for n in self.nodes if n.gnss is not None])])
        captured["lam"] = (self.lam_rho, self.lam_d)
        return out

    monkeypatch.setattr(WindowSolver, "s_step", spy)
    run_gnss_ins(clean.receiver_view(), _cfg(), mode="lss", window=3, lambdas=(0.5, 0.7))
    c, w, s = captured["c"], captured["w"], captured["s"]
    R = len(c) // 2
    lam = np.r_[np.full(R, 0.5), np.full(R, 0.7)]
    expected = np.sign(c) * np.maximum(np.abs(c) - lam, 0.0) * (w > 0)
    np.testing.assert_allclose(s, expected, atol=1e-12)
    assert np.count_nonzero(s) > 0  # thresholds this low must clip some residuals


def test_sliding_window_agrees_with_batch_smoother(clean: simbench.Scenario) -> None:
    """No outliers (S off): marginalisation keeps CRT(L) equal to the full batch MAP at the newest state."""
    data = clean.receiver_view()
    off = (np.inf, np.inf)
    batch, _ = run_gnss_ins(data, _cfg(), mode="lss", window=1000, lambdas=off)
    last = batch[["x", "y", "z"]].to_numpy()[-5:]
    for L in (1, 4):
        sw, _ = run_gnss_ins(data, _cfg(), mode="lss", window=L, lambdas=off)
        diff = np.linalg.norm(sw[["x", "y", "z"]].to_numpy()[-5:] - last, axis=1)
        assert diff.max() < 0.02, (L, diff)


def _with_outlier(data: ReceiverData, epoch: int, bias_m: float) -> tuple[ReceiverData, str]:
    obs = data.observations.copy()
    rows = np.flatnonzero((obs["epoch"] == epoch).to_numpy())
    j = rows[np.argmax(obs["el"].to_numpy()[rows])]  # a high satellite: strong geometry leverage on height
    obs.iloc[j, obs.columns.get_loc("code_l1")] += bias_m
    return ReceiverData(obs, data.imu, data.nav), str(obs["sat"].iloc[j])


def test_single_large_outlier_goes_into_s_not_into_the_state(clean: simbench.Scenario) -> None:
    data = clean.receiver_view()
    bad, sat = _with_outlier(data, OUTLIER_EPOCH, 60.0)
    ref, _ = run_gnss_ins(data, _cfg(), mode="lss", window=5, lambdas=(2.0, 2.0))
    lss, diag = run_gnss_ins(bad, _cfg(), mode="lss", window=5, lambdas=(2.0, 2.0))
    plain, _ = run_gnss_ins(bad, _cfg(), mode="lss", window=5, lambdas=(np.inf, np.inf))
    top = diag["largest_s"][0]
    assert (top["epoch"], top["sat"], top["kind"]) == (OUTLIER_EPOCH, sat, "code")
    assert top["s_m"] == pytest.approx(60.0, rel=0.15)
    at = (ref["epoch"] >= OUTLIER_EPOCH).to_numpy()
    moved_lss = np.linalg.norm(lss[["x", "y", "z"]].to_numpy()[at] - ref[["x", "y", "z"]].to_numpy()[at], axis=1)
    moved_plain = np.linalg.norm(plain[["x", "y", "z"]].to_numpy()[at] - ref[["x", "y", "z"]].to_numpy()[at], axis=1)
    assert moved_lss.max() < 0.5
    assert moved_plain.max() > 3.0 * moved_lss.max()


def test_crt_solution_is_accurate_on_clean_data(clean: simbench.Scenario) -> None:
    sol, diag = run_gnss_ins(clean.receiver_view(), _cfg(), mode="lss", window=5, lambdas=(2.0, 2.0))
    err = enu_errors(sol, clean.truth)
    assert np.nanmedian(err["horizontal"]) < 2.0
    assert diag["heading_aligned_epoch"] > 0
    assert diag["iterations_max"] <= 20
    table = diag["iteration_table"]
    assert table and all(set(r) == {"i", "b_norm", "s_l1", "dx_norm", "ds_l1"} for r in table)


def test_window_gnss_jacobian_matches_central_differences(clean: simbench.Scenario) -> None:
    """Code and Doppler Jacobians, Sagnac term included: a 1 m step moves the code by 6e-6 m more than without it."""
    prep = prepare_gnss_ins(clean.receiver_view(), _cfg())
    truth = clean.truth.set_index("epoch")
    e = 20
    node = WindowNode(pose=gtsam.Pose3(gtsam.Rot3.Ypr(0.3, 0.02, -0.01), truth.loc[e, ["x", "y", "z"]].to_numpy(float)),
                      vel=truth.loc[e, ["vx", "vy", "vz"]].to_numpy(float), bias=np.zeros(6),
                      clk=np.array([truth.loc[e, "rx_clock"], 0.0]))
    node.attach_gnss(prep.gnss[e])
    J = window_gnss_terms([node]).J
    for col, step in [(POS, 1.0), (POS + 1, 1.0), (POS + 2, 1.0), (VEL, 0.1), (VEL + 2, 0.1), (CLK, 1.0),
                      (DRIFT, 0.1)]:
        d = np.zeros(NS)
        d[col] = step
        numeric = (window_gnss_terms([node.retract(d)], jacobian=False).e
                   - window_gnss_terms([node.retract(-d)], jacobian=False).e) / (2 * step)
        np.testing.assert_allclose(J[:, col], numeric, rtol=0, atol=1e-7, err_msg=f"column {col}")


def test_crt_lss_declares_the_imu_and_validates_its_config() -> None:
    assert CrtLss.requires == frozenset({Need.imu})
    for field, value in (("window", 0), ("lambda_rho", 0.0), ("max_iterations", 0), ("code_sigma_m", -1.0)):
        with pytest.raises(SimbenchError, match=rf"estimator\.crt_lss\.{field}"):
            CrtLss(CrtLssConfig(**{field: value}))
