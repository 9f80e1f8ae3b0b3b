"""CRT-LSS: S step, batch-smoother agreement, outliers in S, window Jacobians and normal equations, validation."""

from __future__ import annotations

import copy

import gtsam
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import simbench
from estimators.gnss_ins.config import CrtLssConfig
from estimators.gnss_ins.crt_lss import CrtLss
from estimators.gnss_ins.data import prepare_gnss_ins
from estimators.gnss_ins.driver import run_gnss_ins
from estimators.gnss_ins.window_solver import (
    BA,
    BG,
    CLK,
    DRIFT,
    NS,
    POS,
    ROT,
    VEL,
    WindowNode,
    WindowSolver,
    pair_terms,
    retracted,
    soft_threshold,
    upper_cholesky,
    window_factors,
    window_gnss_terms,
)
from simbench.analysis.metrics import enu_errors
from simbench.contract import Need, ReceiverData
from simbench.errors import SimbenchError

DURATION_S = 50.0
#: seconds to the injected outlier: after the heading reset, inside the drive
OUTLIER_EPOCH = 40


@pytest.fixture(scope="module")
def clean() -> simbench.Scenario:
    """Open sky with no outlier sources: exact models up to the simulator's noise."""
    return simbench.simulate("open_sky", "high", seed=1000, **{"scenario.duration_s": DURATION_S})


def _cfg(**kw) -> CrtLssConfig:
    return CrtLssConfig(**kw)


@pytest.fixture(scope="module")
def full_window(clean: simbench.Scenario) -> WindowSolver:
    """The solver as Algorithm 1 starts on the last full window of the clean drive.

    L = 4, thresholds low enough that S is non-zero.
    """
    return _last_full_window(clean, _cfg(), 4, (0.5, 0.7))


def _copy(window: WindowSolver) -> WindowSolver:
    """An independent copy of a solver (its own nodes; it computes its own linearisation)."""
    s = copy.copy(window)
    s.nodes = [n.copy() for n in window.nodes]
    s._factors_changed()
    return s


def _last_full_window(
    sc: simbench.Scenario, cfg: CrtLssConfig, window: int, lambdas: tuple[float, float]
) -> WindowSolver:
    """A copy of the solver as Algorithm 1 starts on the last full window of a run."""
    seen: list[WindowSolver] = []
    orig = WindowSolver.solve

    def spy(self: WindowSolver, record: bool = False) -> tuple[int, list[tuple[float, ...]]]:
        if self.full:
            seen[:] = [_copy(self)]
        return orig(self, record)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(WindowSolver, "solve", spy)
        run_gnss_ins(sc.receiver_view(), cfg, mode="lss", window=window, lambdas=lambdas)
    return seen[0]


def test_soft_threshold_is_the_closed_form_minimiser() -> None:
    rng = np.random.default_rng(0)
    c = rng.normal(0.0, 4.0, 40)
    lam = 1.7
    brute = np.array(
        [
            minimize_scalar(
                lambda s, ci=ci: (ci - s) ** 2 + 2 * lam * abs(s),
                bounds=(-30, 30),
                method="bounded",
                options={"xatol": 1e-9},
            ).x
            for ci in c
        ]
    )
    np.testing.assert_allclose(soft_threshold(c, lam), brute, atol=1e-5)
    assert np.all(soft_threshold(c, lam)[np.abs(c) <= lam] == 0.0)


def test_s_step_equals_soft_threshold_of_whitened_residuals(
    clean: simbench.Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    captured = {}
    orig = WindowSolver.s_step

    def spy(self: WindowSolver) -> float:
        e, _, w, _ = window_gnss_terms(self.nodes, jacobian=False)
        out = orig(self)
        captured["c"], captured["w"] = -e, w
        captured["s"] = np.concatenate(
            [
                np.concatenate([n.s_code for n in self.nodes if n.gnss is not None]),
                np.concatenate([n.s_rr for n in self.nodes if n.gnss is not None]),
            ]
        )
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
    node = WindowNode(
        pose=gtsam.Pose3(gtsam.Rot3.Ypr(0.3, 0.02, -0.01), truth.loc[e, ["x", "y", "z"]].to_numpy(float)),
        vel=truth.loc[e, ["vx", "vy", "vz"]].to_numpy(float),
        bias=np.zeros(6),
        clk=np.array([truth.loc[e, "rx_clock"], 0.0]),
    )
    node.attach_gnss(prep.gnss[e])
    J = window_gnss_terms([node]).J
    for col, step in [(POS, 1.0), (POS + 1, 1.0), (POS + 2, 1.0), (VEL, 0.1), (VEL + 2, 0.1), (CLK, 1.0), (DRIFT, 0.1)]:
        d = np.zeros(NS)
        d[col] = step
        numeric = (
            window_gnss_terms([node.retract(d)], jacobian=False).e
            - window_gnss_terms([node.retract(-d)], jacobian=False).e
        ) / (2 * step)
        np.testing.assert_allclose(J[:, col], numeric, rtol=0, atol=1e-7, err_msg=f"column {col}")


def test_crt_lss_declares_the_imu_and_validates_its_config() -> None:
    assert CrtLss.requires == frozenset({Need.imu})
    for field, value in (("window", 0), ("lambda_rho", 0.0), ("max_iterations", 0), ("code_sigma_m", -1.0)):
        with pytest.raises(SimbenchError, match=rf"estimator\.crt_lss\.{field}"):
            CrtLss(CrtLssConfig(**{field: value}))


def test_stacked_pair_terms_are_a_loop_over_the_gtsam_factors(full_window: WindowSolver) -> None:
    """Bit for bit: the batched whitening and placement make the BLAS calls of a per-pair loop."""
    nodes = full_window.nodes
    A, b = pair_terms(nodes, full_window._stacked_factors())
    for k in range(len(nodes) - 1):
        a, n = nodes[k], nodes[k + 1]
        H = np.zeros((15, 30), order="F")
        e = n.imu.evaluateError(
            a.pose,
            a.vel,
            n.pose,
            n.vel,
            gtsam.imuBias.ConstantBias(a.bias[:3], a.bias[3:]),
            gtsam.imuBias.ConstantBias(n.bias[:3], n.bias[3:]),
            *(H[:, lo:hi] for lo, hi in ((0, 6), (6, 9), (9, 15), (15, 18), (18, 24), (24, 30))),
        )
        WH = n.imu_sqrt_info @ H
        F = np.array([[1.0, n.dt], [0.0, 1.0]])
        expected = np.zeros((NS, 2 * NS))
        expected[:15, ROT : VEL + 3] = WH[:, 0:9]  # GTSAM's key order: pose_i, vel_i, pose_j, vel_j, bias_i, bias_j
        expected[:15, NS + ROT : NS + VEL + 3] = WH[:, 9:18]
        expected[:15, BA : BG + 3] = WH[:, 18:24]
        expected[:15, NS + BA : NS + BG + 3] = WH[:, 24:30]
        expected[15:, CLK : CLK + 2] = -n.clk_sqrt_info @ F
        expected[15:, NS + CLK : NS + CLK + 2] = n.clk_sqrt_info
        np.testing.assert_array_equal(A[k], expected, err_msg=f"pair {k}")
        np.testing.assert_array_equal(b[k], np.r_[-n.imu_sqrt_info @ e, -n.clk_sqrt_info @ (n.clk - F @ a.clk)])


def test_window_normal_equations_are_the_cost_gradient_and_solve_banded(full_window: WindowSolver) -> None:
    """eta is minus half the cost gradient (central differences); the banded solve solves the dense system."""
    s = full_window
    rng = np.random.default_rng(1)
    # away from the solution, so that every factor (the IMU ones above all) has a sizeable residual
    nodes = retracted(s.nodes, 1e-3 * rng.normal(size=NS * len(s.nodes)))
    ne = s._normal_equations(nodes, s._linearise(nodes, s._stacked_factors()), s._stacked_factors())
    assert ne.sq + 2.0 * s._weighted_s_l1(nodes) == pytest.approx(s.cost(nodes), rel=1e-12)
    assert s.s_l1_norm() > 0.0
    h = 1e-6  # round-off of ECEF positions limits the differences to ~1e-5: a misplaced block is off by O(1)
    for _ in range(5):
        v = rng.normal(size=NS * len(nodes))
        v[:NS] = 0.0  # the prior's Jacobian is taken as the identity: exact only at its mean
        slope = (s.cost(retracted(nodes, h * v)) - s.cost(retracted(nodes, -h * v))) / (2 * h)
        assert slope == pytest.approx(-2.0 * ne.eta @ v, rel=1e-3)
    H = ne.dense()
    np.testing.assert_allclose(H, H.T, rtol=0, atol=1e-12 * np.abs(H).max())
    dx = ne.solve()
    assert np.linalg.norm(H @ dx - ne.eta) < 1e-9 * np.linalg.norm(ne.eta)


@pytest.fixture(scope="module")
def urban_window() -> WindowSolver:
    """The default CRT-LSS (L = 10, lambda = 1) as Algorithm 1 starts on its window 46 s into an urban drive."""
    sc = simbench.simulate("urban", "low", seed=1000, **{"scenario.duration_s": 46, "imu.rate_hz": 100.0})
    cfg = _cfg()
    return _last_full_window(sc, cfg, cfg.window, (cfg.lambda_rho, cfg.lambda_d))


def test_algorithm_1_stops_on_its_tolerance_at_the_huber_minimum(urban_window: WindowSolver) -> None:
    """With the S step's X step taken on min_S C (Huber), Algorithm 1 stops on its tolerance in 6 iterations
    on a window with outliers, where the alternation with S fixed runs into the cap of 20 (|dS| still
    above the tolerance), and ends no higher in cost, where the gradient of min_S C vanishes."""

    def gradient_norm(s: WindowSolver) -> float:
        factors = s._stacked_factors()
        lin = s._linearise(s.nodes, factors)
        assert lin.gnss is not None
        return float(np.linalg.norm(s._normal_equations(s.nodes, lin, factors, s=s._thresholded(lin.gnss)).eta))

    huber, fixed = _copy(urban_window), _copy(urban_window)
    fixed.huber_step = fixed.x_step  # type: ignore[method-assign]  # Algorithm 1 with S fixed in every X step
    start = gradient_norm(huber)
    iterations, table = huber.solve(record=True)
    assert any(row[4] > 0 for row in table), "an S step moved S: the window has outliers"
    assert iterations <= 10 < huber.max_iterations
    assert fixed.solve()[0] == fixed.max_iterations
    assert huber.cost() <= fixed.cost()
    assert gradient_norm(huber) < 1e-3 * start


def test_a_window_without_gnss_rows_solves_on_the_imu_and_clock_alone(full_window: WindowSolver) -> None:
    """Epochs with fewer than 4 satellites have no GNSS rows: a window can hold none (seen on long urban drives)."""
    s = full_window
    nodes = [n.copy() for n in s.nodes]
    for n in nodes:
        n.gnss = None
    assert window_gnss_terms(nodes) is None
    factors = window_factors(nodes)
    ne = s._normal_equations(nodes, s._linearise(nodes, factors), factors)
    assert ne.sq == pytest.approx(s.cost(nodes), rel=1e-12)
    assert np.all(np.isfinite(ne.solve()))


def test_marginal_information_left_indefinite_by_rounding_still_factors() -> None:
    """A positive definite information gives the plain Cholesky factor; one with a tiny negative
    eigenvalue (Schur-complement cancellation) gives R^T R equal to it with that eigenvalue floored."""
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.standard_normal((NS, NS)))
    w = np.logspace(-4, 10, NS)
    info = (q * w) @ q.T
    np.testing.assert_array_equal(upper_cholesky(info), np.linalg.cholesky(info + 1e-12 * np.eye(NS)).T)
    w[0] = -1e-3
    bad = (q * w) @ q.T
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(bad + 1e-12 * np.eye(NS))
    r = upper_cholesky(bad)
    assert np.allclose(np.tril(r, -1), 0.0)
    floored = (q * np.maximum(w, 1e-9 * w.max())) @ q.T
    np.testing.assert_allclose(r.T @ r, floored, rtol=0, atol=1e-6 * w.max())
