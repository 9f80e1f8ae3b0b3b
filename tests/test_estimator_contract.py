"""Every registered estimator honours the interface (the scikit-learn check_estimator idea)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
import yaml

import estimators
import simbench
from estimators.base import SOLUTION_COLUMNS, Solution
from simbench.compose import CONF_DIR
from simbench.config import to_typed
from simbench.errors import SimbenchError

NAMES = sorted(estimators.registered())


@pytest.fixture(scope="module")
def scenario() -> simbench.Scenario:
    return simbench.simulate("open_sky", "high", seed=1000, **{"scenario.duration_s": 90})


def _config(name: str):
    cls = estimators.get(name)
    node = yaml.safe_load((CONF_DIR / "estimator" / f"{name}.yaml").read_text())[name]
    return cls, to_typed(node, cls.Config, f"estimator.{name}")


def test_registry_is_not_empty() -> None:
    assert "ekf_ppp" in NAMES


@pytest.mark.parametrize("name", NAMES)
def test_config_file_matches_config_class(name: str) -> None:
    cls = estimators.get(name)
    assert dataclasses.is_dataclass(cls.Config)
    node = yaml.safe_load((CONF_DIR / "estimator" / f"{name}.yaml").read_text())
    assert list(node) == [name], "estimator yaml must nest its fields under its own name"
    assert set(node[name]) == {f.name for f in dataclasses.fields(cls.Config)}
    defaults = yaml.safe_load((CONF_DIR / "config.yaml").read_text())["defaults"]
    selected = next(d["estimator"] for d in defaults if isinstance(d, dict) and "estimator" in d)
    assert name in selected, "every registered estimator runs by default"


@pytest.mark.parametrize("name", NAMES)
def test_estimate_returns_a_timed_per_epoch_solution(name: str, scenario: simbench.Scenario) -> None:
    cls, cfg = _config(name)
    est = cls(cfg)
    if cls.uses_labels:
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
    for _ in range(2):
        est = cls(cfg)
        if cls.uses_labels:
            est.attach_labels(scenario.labels)
        runs.append(est.estimate(scenario.receiver_view()).epochs[["x", "y", "z"]].to_numpy())
    np.testing.assert_array_equal(runs[0], runs[1])


@pytest.mark.parametrize("name", NAMES)
def test_labels_only_for_the_oracle(name: str, scenario: simbench.Scenario) -> None:
    cls, cfg = _config(name)
    if not cls.uses_labels:
        with pytest.raises(PermissionError):
            cls(cfg).attach_labels(scenario.labels)


def test_unknown_estimator_name_is_one_line() -> None:
    with pytest.raises(SimbenchError, match="unknown estimator 'kalman9'") as info:
        estimators.get("kalman9")
    assert "\n" not in str(info.value)
