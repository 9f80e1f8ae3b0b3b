"""Every registered estimator honours the interface (the scikit-learn check_estimator idea).

Registered means built-in and plug-in alike (``estimators.registered()``); each runs
with the config the default run composes for it (``conf/estimator/`` or its package).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

import estimators
import simbench
from estimators.base import SOLUTION_COLUMNS, Solution
from simbench.contract import (
    MISSING_NEED_REASONS,
    NavInfo,
    Need,
    Scenario,
    available_needs,
)
from simbench.errors import SimbenchError
from simbench.runs.compose import compose_config
from simbench.runs.runner import run_estimators
from simbench.typed import to_typed

NAMES = sorted(estimators.registered())
#: The estimator configs of the default run: every registered estimator's.
DEFAULT_RUN = compose_config([]).estimator


@pytest.fixture(scope="module")
def scenario() -> simbench.Scenario:
    return simbench.simulate("open_sky", "high", seed=1000, **{"scenario.duration_s": 90})


def _config(name: str):
    cls = estimators.get(name)
    node = OmegaConf.to_container(DEFAULT_RUN[name], resolve=True)
    return cls, to_typed(node, cls.Config, f"estimator.{name}")


def _needs(name: str) -> frozenset[Need]:
    cls, cfg = _config(name)
    return cls(cfg).needs()


#: (estimator, need) for every need an estimator declares under its conf/estimator defaults.
DECLARED = [(name, need) for name in NAMES for need in sorted(_needs(name), key=lambda n: n.value)]


def _skip_unless_offered(est: estimators.Estimator, scenario: Scenario) -> None:
    """Skip an estimator whose needs no simulated scenario meets, or that cannot run here (a missing
    program: rnx2rtkp for rtklib_spp); its skip here: test_unmet_need_is_skipped_with_a_reason."""
    lacking = est.needs() - available_needs(scenario)
    if lacking:
        pytest.skip(f"the simulated scenario cannot offer {sorted(n.value for n in lacking)}")
    if est.unavailable_reason():
        pytest.skip(est.unavailable_reason())


def _without(scenario: Scenario, need: Need) -> Scenario:
    """``scenario`` with exactly what ``need`` names taken away."""
    obs, imu, labels, nav = scenario.observations, scenario.imu, scenario.labels, scenario.nav
    if need is Need.phase:
        obs = obs.assign(phase_l1=np.nan, phase_l2=np.nan)
    elif need is Need.imu:
        imu = imu.iloc[:0]
    elif need is Need.labels:
        labels = None
    elif need is Need.dual_frequency:
        obs = obs.assign(code_l2=np.nan, phase_l2=np.nan)
        nav = NavInfo(**{**nav.__dict__, "dual_frequency": False})
    elif need is Need.rinex_files:
        nav = NavInfo(**{**nav.__dict__, "ephemeris": ""})
    return dataclasses.replace(scenario, observations=obs, imu=imu, labels=labels, nav=nav)


def test_registry_is_not_empty() -> None:
    assert "ekf_ppp" in NAMES


@pytest.mark.parametrize("name", NAMES)
def test_config_is_a_dataclass_and_runs_by_default(name: str) -> None:
    # conf/estimator/<name>.yaml against the dataclass: tests/test_config_files.py
    assert dataclasses.is_dataclass(estimators.get(name).Config)
    assert name in DEFAULT_RUN, "every registered estimator runs by default"


@pytest.mark.parametrize("name", NAMES)
def test_estimate_returns_a_timed_per_epoch_solution(name: str, scenario: simbench.Scenario) -> None:
    cls, cfg = _config(name)
    est = cls(cfg)
    _skip_unless_offered(est, scenario)
    if Need.labels in est.needs():
        est.attach_labels(scenario.labels)
    data = scenario.receiver_view()
    before = data.observations.copy()
    sol = est.estimate(data)
    assert isinstance(sol, Solution)
    assert set(SOLUTION_COLUMNS) <= set(sol.epochs.columns)
    ep = sol.epochs
    assert ep["epoch"].is_unique and ep["epoch"].is_monotonic_increasing
    assert ep["epoch"].between(0, scenario.n_epochs - 1).all()
    assert len(ep) >= 0.8 * scenario.n_epochs
    assert np.isfinite(ep[["x", "y", "z"]].to_numpy()).all()
    assert (ep["update_s"] >= 0).all() and sol.total_s > 0
    pd.testing.assert_frame_equal(data.observations, before)  # inputs are not modified
    # the estimate is near the truth (loosely: every estimator must at least be in the right place)
    truth = scenario.truth.set_index("epoch").loc[ep["epoch"], ["x", "y", "z"]].to_numpy()
    assert np.median(np.linalg.norm(ep[["x", "y", "z"]].to_numpy() - truth, axis=1)) < 10.0


@pytest.mark.parametrize("name", NAMES)
def test_deterministic(name: str, scenario: simbench.Scenario) -> None:
    cls, cfg = _config(name)
    runs = []
    _skip_unless_offered(cls(cfg), scenario)
    for _ in range(2):
        est = cls(cfg)
        if Need.labels in est.needs():
            est.attach_labels(scenario.labels)
        runs.append(est.estimate(scenario.receiver_view()).epochs[["x", "y", "z"]].to_numpy())
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize("name", NAMES)
def test_labels_only_for_the_oracle(name: str, scenario: simbench.Scenario) -> None:
    cls, cfg = _config(name)
    assert cls.uses_labels == (Need.labels in cls.requires) == (name == "oracle")
    if name != "oracle":
        with pytest.raises(PermissionError):
            cls(cfg).attach_labels(scenario.labels)
        return
    with pytest.raises(SimbenchError, match="needs the error labels"):
        cls(cfg).estimate(scenario.receiver_view())
    # the oracle really reads them: labelling a third of the satellites' code 100x noisier moves the solution
    runs = []
    for factor in (1.0, 100.0):
        labels = scenario.labels.copy()
        labels.loc[labels["sat"].str.endswith(("1", "3", "5")), "sigma_code_l1"] *= factor
        est = cls(cfg)
        est.attach_labels(labels)
        sol = est.estimate(scenario.receiver_view())
        runs.append(sol.epochs[["x", "y", "z"]].to_numpy())
        assert sol.diagnostics["median_code_sigma_m"] > 0
    assert np.max(np.linalg.norm(runs[0] - runs[1], axis=1)) > 1e-3


@pytest.mark.parametrize("name", NAMES)
def test_needs_are_declared_needs(name: str) -> None:
    cls, cfg = _config(name)
    declared = cls(cfg).needs()
    assert isinstance(declared, frozenset) and declared <= frozenset(Need)
    assert all(isinstance(n, Need) for n in declared)


def test_needs_follow_the_config() -> None:
    cls = estimators.get("ekf_ppp")
    assert cls(cls.Config()).needs() == frozenset()  # measurements=auto: code wherever phase is missing
    assert cls(cls.Config(measurements="code_phase")).needs() == {Need.phase}
    assert cls(cls.Config(ionosphere="free")).needs() == {Need.dual_frequency}
    l2 = estimators.get("l2")
    assert l2(l2.Config(ionosphere="free", measurements="code_phase")).needs() == {Need.phase, Need.dual_frequency}


def test_the_simulated_scenario_offers_phase_imu_and_labels(scenario: simbench.Scenario) -> None:
    offered = available_needs(scenario)
    assert {Need.phase, Need.imu, Need.labels} <= offered
    for need in Need:
        assert need not in available_needs(_without(scenario, need))


@pytest.mark.parametrize(("name", "need"), DECLARED, ids=[f"{n}-{d.value}" for n, d in DECLARED])
def test_unmet_need_is_skipped_with_a_reason(name: str, need: Need, scenario: simbench.Scenario) -> None:
    res = run_estimators(_without(scenario, need), {name: None}, progress=False)
    row = res.summary.iloc[0]
    assert row["status"] == "skipped", row["message"]
    assert MISSING_NEED_REASONS[need] in row["message"] and "\n" not in row["message"]
    assert row["n_solved"] == 0 and res.epochs.empty


def test_runner_skips_gnss_ins_without_imu_and_phase_estimators_on_code_only_data(scenario: simbench.Scenario) -> None:
    no_imu = run_estimators(_without(scenario, Need.imu), {"ekf_ins": None, "crt_lss": None}, progress=False)
    assert list(no_imu.summary["status"]) == ["skipped", "skipped"]
    assert no_imu.summary["message"].str.contains("IMU").all()
    code_only = _without(scenario, Need.phase)
    phase_users = ["l2", "isam2_ppp", "ekf_ppp", "oracle"]
    strict = {name: {"measurements": "code_phase"} for name in phase_users}
    rows = run_estimators(code_only, strict, progress=False).summary.set_index("estimator")
    assert (rows.loc[phase_users, "status"] == "skipped").all()
    assert rows.loc[phase_users, "message"].str.contains("carrier phase").all()
    # by default (measurements=auto) they have nothing missing and run on the code
    rows = run_estimators(code_only, dict.fromkeys(phase_users), progress=False).summary.set_index("estimator")
    assert (rows["status"] == "ok").all() and (rows["n_solved"] > 0).all()
    single = run_estimators(
        _without(scenario, Need.dual_frequency), {"l2": {"ionosphere": "free"}}, progress=False
    ).summary.iloc[0]
    assert single["status"] == "skipped" and single["message"] == MISSING_NEED_REASONS[Need.dual_frequency]


def test_invalid_config_fails_at_construction() -> None:
    for name, field, value in (
        ("ekf_ppp", "code_sigma_m", 0.0),
        ("l2", "min_satellites", 0),
        ("mm", "outlier_weight", 1.5),
        ("isam2_dcs", "kernel_width", -1.0),
        ("ice", "alpha", 2.0),
        ("bce_ad", "n_features", 9),
        ("isam2_ppp", "lag_s", -1.0),
        ("ice", "lag_min_epochs", 1),
        ("isam2_mm", "outlier_weight", 0.0),
        ("bce", "fit_sample", -1),
        ("dcs", "lm_max_iterations", 0),
        ("isam2_ppp", "relinearize_skip", 0),
    ):
        cls = estimators.get(name)
        with pytest.raises(SimbenchError, match=f"estimator.{name}.{field}") as info:
            cls(cls.Config(**{field: value}))
        assert "\n" not in str(info.value)


def test_unknown_estimator_name_is_one_line() -> None:
    with pytest.raises(SimbenchError, match="unknown estimator 'kalman9'") as info:
        estimators.get("kalman9")
    assert "\n" not in str(info.value)
