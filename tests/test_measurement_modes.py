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

import estimators
import simbench
from estimators.measurement import prepare_ppp
from estimators.ppp_config import MeasurementMode
from simbench.metrics import enu_errors

ISB_M = 40.0


@pytest.fixture(scope="module")
def gps() -> simbench.Scenario:
    return simbench.simulate("open_sky", "high", seed=1001, **{"scenario.duration_s": 120})


def _two_systems(sc: simbench.Scenario) -> simbench.Scenario:
    obs = sc.observations.copy()
    odd = obs["sat"].str[1:].astype(int) % 2 == 1
    obs.loc[odd, "sat"] = "E" + obs.loc[odd, "sat"].str[1:]
    obs.loc[odd, ["code_l1", "phase_l1"]] += ISB_M
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
    kwargs = {"ionosphere_free": False, "code_sigma_m": 2.5, "phase_sigma_m": 0.025, "elevation_mask_deg": 7.0}
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
