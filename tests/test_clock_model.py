"""The two-state receiver clock of the PPP graph: jumps found, the offset chained elsewhere."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import simbench
from estimators.batch.configs import L2Config
from estimators.batch.robust import L2Batch
from estimators.filters.configs import EkfPppConfig
from estimators.filters.ekf_ppp import EkfPpp
from estimators.model.clock import clock_links, offset_step_sigma, single_point_drift
from estimators.model.ppp_config import ClockModel, MotionModel
from simbench.errors import SimbenchError

#: a millisecond of receiver clock [m], the smallest step a u-blox receiver makes
MILLISECOND_M = 299_792.458


def test_jumps_found_on_noisy_single_point_clocks() -> None:
    """Two millisecond jumps among 130 m-tailed steps: the links break there and only there."""
    rng = np.random.default_rng(1)
    t = np.arange(600.0)
    clock = 64.0 * t + rng.standard_t(2, t.size) * 20.0
    clock[200:] += MILLISECOND_M
    clock[400:] -= 10 * MILLISECOND_M
    links = clock_links(t, clock, np.full(t.size, 64.0), jump_m=1000.0)
    assert np.flatnonzero(~links).tolist() == [0, 200, 400]
    assert single_point_drift(t, clock, 1000.0) == pytest.approx(64.0, abs=2.0)


def test_offset_step_sigma_is_the_two_state_variance() -> None:
    """q_b dt + q_d dt^3 / 3 (Brown and Hwang's two-state clock, the offset's diagonal)."""
    assert offset_step_sigma(2.0, 0.1, 0.2) == pytest.approx(np.sqrt(0.01 * 2 + 0.04 * 8 / 3))
    assert offset_step_sigma(0.0, 0.1, 0.2) == 0.0


def _l2(scenario: simbench.Scenario, **fields: object) -> np.ndarray:
    cfg = dataclasses.replace(L2Config(), clock_model=ClockModel.two_state, **fields)
    return L2Batch(cfg).estimate(scenario.receiver_view()).epochs[["x", "y", "z"]].to_numpy()


def test_a_clock_jump_leaves_the_positions_unmoved() -> None:
    """A 1 ms step of the receiver clock in every code, phase and time tag: found, positions within
    centimetres of the log without it; chained through it (no detection) they are metres off."""
    sc = simbench.simulate("urban", "low", seed=1000, **{"scenario.duration_s": 60})
    obs = sc.observations.copy()
    late = obs["epoch"] >= 30
    obs.loc[late, ["code_l1", "code_l2"]] += MILLISECOND_M
    obs.loc[late, ["phase_l1", "phase_l2"]] += MILLISECOND_M
    jumped = dataclasses.replace(sc, observations=obs)
    steady = _l2(sc)
    found = _l2(jumped)
    chained = _l2(jumped, clock_jump_m=1e9)
    assert np.abs(found - steady).max() < 0.05
    assert np.linalg.norm(chained - steady, axis=1).max() > 5.0


def test_two_state_needs_the_drift_state() -> None:
    cfg = dataclasses.replace(L2Config(), clock_model=ClockModel.two_state, motion_model=MotionModel.random_walk)
    with pytest.raises(SimbenchError, match="motion_model=constant_velocity"):
        cfg.validate("estimator.l2")


def test_the_filter_restarts_its_clock_at_a_jump() -> None:
    """EKF-PPP with the two-state clock: the 1 ms jump is counted once and moves no position by more
    than 20 cm (the filter forgets the clock once); taken for a clock step it costs metres."""
    sc = simbench.simulate("urban", "low", seed=1000, **{"scenario.duration_s": 60})
    obs = sc.observations.copy()
    late = obs["epoch"] >= 30
    obs.loc[late, ["code_l1", "code_l2", "phase_l1", "phase_l2"]] += MILLISECOND_M
    cfg = dataclasses.replace(
        EkfPppConfig(), clock_model=ClockModel.two_state, motion_model=MotionModel.constant_velocity
    )
    runs = [EkfPpp(cfg).estimate(s.receiver_view()) for s in (sc, dataclasses.replace(sc, observations=obs))]
    steady, jumped = (r.epochs[["x", "y", "z"]].to_numpy() for r in runs)
    assert runs[0].diagnostics["n_clock_jumps"] == 0
    assert runs[1].diagnostics["n_clock_jumps"] == 1
    assert np.abs(jumped - steady).max() < 0.2
    blind = EkfPpp(dataclasses.replace(cfg, clock_jump_m=1e9)).estimate(dataclasses.replace(sc, observations=obs))
    assert np.linalg.norm(blind.epochs[["x", "y", "z"]].to_numpy() - steady, axis=1).max() > 5.0
