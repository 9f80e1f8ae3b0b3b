"""Measurement modes and several GNSS systems in the shared PPP model (graph, iSAM2, EKF).

A second system is made from a simulated GPS scenario: the satellites with an odd
PRN are renamed to Galileo ids and the receiver sees them through a clock 40 m
later (code and phase), which is what an inter-system bias is. The estimators
must recover the 40 m and keep the single-system accuracy.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import dissertation

import estimators
import simbench
from estimators.model.measurement import prepare_ppp
from estimators.model.ppp_config import MeasurementMode
from simbench.analysis.metrics import enu_errors

ISB_M = 40.0


@pytest.fixture(scope="module")
def gps() -> simbench.Scenario:
    return simbench.simulate("open_sky", "high", seed=1001, **{"scenario.duration_s": 120})


def _two_systems(sc: simbench.Scenario) -> simbench.Scenario:
    obs = sc.observations.copy()
    odd = obs["sat"].str[1:].astype(int) % 2 == 1
    obs.loc[odd, "sat"] = "E" + obs.loc[odd, "sat"].str[1:]
    # a receiver clock offset: on every frequency alike (the ionosphere-free combination keeps it)
    obs.loc[odd, ["code_l1", "phase_l1", "code_l2", "phase_l2"]] += ISB_M
    return dataclasses.replace(sc, observations=obs)


def _horizontal_median(sc: simbench.Scenario, sol) -> float:
    err = enu_errors(sol.epochs, sc.truth)
    return float(np.median(err["horizontal"]))


@pytest.mark.parametrize("name", ["l2", "isam2_ppp"])
def test_inter_system_bias_is_recovered(name: str, gps: simbench.Scenario) -> None:
    two = _two_systems(gps)
    cls = estimators.get(name)
    sol = cls(cls.Config()).estimate(two.receiver_view())
    isb = sol.diagnostics["inter_system_bias_m"]
    assert set(isb) == {"E"}
    assert abs(isb["E"] - ISB_M) < 0.5
    one = cls(cls.Config()).estimate(gps.receiver_view())
    assert _horizontal_median(two, sol) < _horizontal_median(gps, one) + 0.1


def test_the_ekf_recovers_it_too(gps: simbench.Scenario) -> None:
    two = _two_systems(gps)
    cls = estimators.get("ekf_ppp")
    sol = cls(cls.Config()).estimate(two.receiver_view())
    assert abs(sol.diagnostics["inter_system_bias_m"]["E"] - ISB_M) < 0.5


def test_auto_keeps_code_rows_without_phase(gps: simbench.Scenario) -> None:
    obs = gps.observations.copy()
    gone = obs.index[::3]
    obs.loc[gone, "phase_l1"] = np.nan
    data = dataclasses.replace(gps, observations=obs).receiver_view()
    kwargs = {"ionosphere": "broadcast", "code_sigma_m": 2.5, "phase_sigma_m": 0.025, "elevation_mask_deg": 7.0}
    auto = prepare_ppp(data, measurements=MeasurementMode.auto, **kwargs)
    strict = prepare_ppp(data, measurements=MeasurementMode.code_phase, **kwargs)
    code = prepare_ppp(data, measurements=MeasurementMode.code, **kwargs)
    assert auto.n_obs == code.n_obs > strict.n_obs
    assert int(auto.has_phase.sum()) == strict.n_obs and not code.has_phase.any() and code.n_arcs == 0
    assert np.isnan(auto.phase[~auto.has_phase]).all() and (auto.arc[~auto.has_phase] == -1).all()
    # a phase gap ends the arc: more arcs than with continuous phase
    full = prepare_ppp(gps.receiver_view(), measurements=MeasurementMode.auto, **kwargs)
    assert auto.n_arcs > full.n_arcs
    # the graph estimators run on the mixed rows; losing a third of the phase costs accuracy, but the
    # remaining phase still helps: between the code-phase (about 1 m) and code-only (about 2 m) results
    code_only = dataclasses.replace(gps, observations=gps.observations.assign(phase_l1=np.nan)).receiver_view()
    for name in ("l2", "isam2_ppp"):
        cls = estimators.get(name)
        mixed = cls(cls.Config()).estimate(data)
        assert len(mixed.epochs) == full.n_epochs
        errors = [_horizontal_median(gps, cls(cls.Config()).estimate(d)) for d in (gps.receiver_view(), code_only)]
        assert errors[0] < _horizontal_median(gps, mixed) < errors[1], errors


def _solve_graph(sc: simbench.Scenario, **config):
    from estimators.model.ppp_graph import PppGraph, solve, vel_key

    # the graph model of Table 4.4.2 but for ``config``, on L1 code (the bounds below are sized on its noise)
    cfg = dissertation("l2", **{"ionosphere": "broadcast", **config})
    obs = prepare_ppp(sc.receiver_view(), **cfg.prepare_kwargs())
    g = PppGraph(obs, cfg)
    graph = g.structure_factors()
    graph.push_back(g.measurement_factors())
    values = solve(graph, g.initial_values())
    truth = sc.truth.set_index("epoch").loc[obs.epoch_ids]
    pos_err = np.linalg.norm(g.positions(values) - truth[["x", "y", "z"]].to_numpy(), axis=1)
    vel = (
        np.array([values.atPoint3(vel_key(k)) for k in range(obs.n_epochs)])
        if cfg.motion_model == "constant_velocity"
        else None
    )
    vel_err = None if vel is None else np.linalg.norm(vel - truth[["vx", "vy", "vz"]].to_numpy(), axis=1)
    return pos_err, vel_err


def test_constant_velocity_model_estimates_velocity_from_doppler(gps: simbench.Scenario) -> None:
    rw, _ = _solve_graph(gps, measurements="code")
    cv, vel_err = _solve_graph(gps, measurements="code", motion_model="constant_velocity")
    # simulated Doppler noise is about 0.1 m/s: the velocity follows it, and the code-only
    # position gains from the motion model
    assert np.median(vel_err[5:]) < 0.2
    assert np.median(cv) < np.median(rw)


def test_a_receiver_clock_jump_does_not_break_the_doppler_model(gps: simbench.Scenario) -> None:
    """u-blox receivers keep their clock within 1 ms by jumps; the drift is a state, not a clock difference."""
    obs = gps.observations.copy()
    later = obs["t"] >= 60.0
    obs.loc[later, ["code_l1", "phase_l1"]] += 1e-3 * 299_792_458.0
    jumped = dataclasses.replace(gps, observations=obs)
    cv, vel_err = _solve_graph(jumped, measurements="code", motion_model="constant_velocity")
    ref, _ = _solve_graph(gps, measurements="code", motion_model="constant_velocity")
    assert np.median(vel_err[5:]) < 0.2
    assert np.max(np.abs(cv - ref)) < 0.05


@pytest.fixture(scope="module")
def urban_without_doppler() -> simbench.Scenario:
    """Urban drive with wheel odometry, its Doppler removed (a libRSF log has none)."""
    sc = simbench.simulate("urban", "low", seed=1001, **{"scenario.duration_s": 120})
    assert len(sc.odometry) > 0
    return dataclasses.replace(sc, observations=sc.observations.assign(doppler_l1=np.nan))


def test_wheel_odometry_steadies_the_velocity_without_doppler(urban_without_doppler: simbench.Scenario) -> None:
    """Urban drive, code only, Doppler removed: speed, standstill and yaw-rate factors carry the velocity."""
    no_doppler = urban_without_doppler
    _, without = _solve_graph(no_doppler, measurements="code", motion_model="constant_velocity", use_odometry=False)
    _, with_odo = _solve_graph(no_doppler, measurements="code", motion_model="constant_velocity")
    assert np.median(with_odo) < 0.8 * np.median(without)
    assert np.percentile(with_odo, 95) < np.percentile(without, 95)


def test_the_road_grade_holds_the_vertical_velocity_without_doppler(urban_without_doppler: simbench.Scenario) -> None:
    """Without Doppler the wheel speed has no direction to act along; the road grade still bounds the
    vertical velocity (measured 0.49 / 1.9 m/s median / p95 against 1.3 / 8.0 m/s with the grade free)."""
    _, bounded = _solve_graph(urban_without_doppler, measurements="code", motion_model="constant_velocity")
    _, free = _solve_graph(
        urban_without_doppler, measurements="code", motion_model="constant_velocity", road_grade_sigma=1e3
    )
    assert np.median(bounded) < 0.5 * np.median(free)
    assert np.percentile(bounded, 95) < 0.4 * np.percentile(free, 95)
