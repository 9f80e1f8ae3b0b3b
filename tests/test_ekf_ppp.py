"""EKF PPP: convergence on exact synthetic data, fresh biases for new arcs, configuration."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pymap3d
import pytest
from conftest import dissertation

import estimators
import simbench
from estimators.base import COVARIANCE_INDEX
from estimators.filters.configs import EkfPppConfig
from estimators.filters.ekf_ppp import EkfPpp
from simbench.analysis.metrics import nees
from simbench.core.constants import IF_A1, IF_A2, LAMBDA_L1, LAMBDA_L2
from simbench.errors import SimbenchError

# the synthetic-data builder lives with the measurement-model tests
if "test_measurement" not in sys.modules:
    _spec = importlib.util.spec_from_file_location("test_measurement", Path(__file__).with_name("test_measurement.py"))
    _mod = importlib.util.module_from_spec(_spec)
    sys.modules["test_measurement"] = _mod
    _spec.loader.exec_module(_mod)
from test_measurement import horizontal_error, synthetic_data


@pytest.mark.parametrize("dual", [True, False])
def test_converges_on_exact_data(dual: bool) -> None:
    data, truth = synthetic_data(600, dual=dual, seed=1)
    sol = EkfPpp(dissertation("ekf_ppp", ionosphere="free" if dual else "broadcast")).estimate(data)
    ep = sol.epochs
    assert len(ep) == 600 and ep["epoch"].is_monotonic_increasing
    err = horizontal_error(ep, truth)
    assert err[300:].max() < 0.3, err[300:].max()
    assert np.median(err[-100:]) < 0.1
    d = sol.diagnostics
    assert d["n_epochs"] == 600 and d["n_arcs"] == d["n_satellites"] == d["n_ambiguity_resets"]
    assert abs(d["final_zwd_m"] - truth["zwd"]) < 0.05
    assert abs(d["final_clock_m"] - truth["rx_clock"][-1]) < 1.0
    assert (ep["update_s"] > 0).all() and ep["update_s"].sum() <= sol.total_s


@pytest.mark.parametrize("dual", [True, False])
def test_position_covariance_is_stored_and_not_overconfident_on_exact_data(dual: bool) -> None:
    """The filter's 3x3 position covariance reaches the epoch table (the report's consistency check):
    positive definite at every epoch, and on data that follow its model the mean NEES over the
    converged half is below its 3 degrees of freedom (random-walk process noise on a static receiver
    makes it conservative: about 0.2 measured)."""
    data, truth = synthetic_data(600, dual=dual, seed=1)
    ep = EkfPpp(dissertation("ekf_ppp", ionosphere="free" if dual else "broadcast")).estimate(data).epochs
    cov = np.zeros((len(ep), 3, 3))
    for column, (i, j) in COVARIANCE_INDEX.items():
        cov[:, i, j] = cov[:, j, i] = ep[column].to_numpy(float)
    assert (np.linalg.eigvalsh(cov) > 0).all()
    error = nees(ep[["x", "y", "z"]].to_numpy() - np.asarray(truth["pos"]), cov)
    assert 0.01 < error[300:].mean() < 3.0, error[300:].mean()


def test_loss_of_lock_starts_a_fresh_bias() -> None:
    data, truth = synthetic_data(600, dual=True, seed=2, slip=(300, "G15"))
    sol = EkfPpp(dissertation("ekf_ppp", ionosphere="free")).estimate(data)
    d = sol.diagnostics
    assert d["n_arcs"] == d["n_satellites"] + 1 == d["n_ambiguity_resets"]
    g15 = [b for s, b in zip(d["arc_sat"], d["arc_bias_m"]) if s == "G15"]
    jump = IF_A1 * LAMBDA_L1 * 7 + IF_A2 * LAMBDA_L2 * 3  # +7 L1, -3 L2 cycles in the IF combination
    assert len(g15) == 2 and abs(g15[1] - g15[0] - jump) < 0.1
    err = horizontal_error(sol.epochs, truth)
    assert err[300:].max() < 0.3  # the slip does not disturb the position
    # the same slip without the flag: the old bias is kept and the position is pulled away
    data_unflagged, _ = synthetic_data(600, dual=True, seed=2, slip=(300, "G15"), flag_slip=False)
    bad = horizontal_error(EkfPpp(dissertation("ekf_ppp", ionosphere="free")).estimate(data_unflagged).epochs, truth)
    assert bad[300:].max() > 3 * err[300:].max()


def test_code_only_filter() -> None:
    data, truth = synthetic_data(300, dual=False, seed=3)
    sol = EkfPpp(dissertation("ekf_ppp", measurements="code")).estimate(data)
    assert sol.diagnostics["n_arcs"] == 0
    assert np.median(horizontal_error(sol.epochs, truth)) < 2.0


def test_random_walk_clock_model_agrees() -> None:
    data, truth = synthetic_data(300, dual=True, seed=4)
    err = horizontal_error(
        EkfPpp(dissertation("ekf_ppp", ionosphere="free", clock_model="random_walk")).estimate(data).epochs, truth
    )
    assert err[150:].max() < 0.3


def test_errors_and_registry() -> None:
    single, _ = synthetic_data(5, dual=False)
    with pytest.raises(SimbenchError, match="ionosphere"):
        EkfPpp(dissertation("ekf_ppp", ionosphere="free")).estimate(single)
    with pytest.raises(SimbenchError, match="clock_model"):
        EkfPpp(EkfPppConfig(clock_model="pink")).estimate(single)
    assert estimators.get("ekf_ppp") is EkfPpp


def test_iono_states_absorb_code_phase_divergence() -> None:
    # a slant ionosphere ramp the Klobuchar model misses: +I on code, -I on phase
    data, truth = synthetic_data(600, dual=False, seed=6, iono_drift_mps=0.003)
    plain = horizontal_error(EkfPpp(dissertation("ekf_ppp", estimate_iono=False)).estimate(data).epochs, truth)
    sol = EkfPpp(dissertation("ekf_ppp", estimate_iono=True)).estimate(data)
    with_iono = horizontal_error(sol.epochs, truth)
    assert sol.diagnostics["iono_states"]
    assert np.median(with_iono[300:]) < 0.3 < 3.0 < np.median(plain[300:])


def test_open_sky_dual_frequency_converges_below_a_metre() -> None:
    sc = simbench.simulate(
        "open_sky",
        "high",
        seed=11,
        **{
            "scenario.duration_s": 900,
            "scenario.dual_frequency": True,
            "++scenario.errors.nlos.enabled": False,
            "++scenario.errors.attitude_masking.enabled": False,
        },
    )
    ep = EkfPpp(dissertation("ekf_ppp", ionosphere="free")).estimate(sc.receiver_view()).epochs
    assert len(ep) >= 0.95 * sc.n_epochs
    truth = sc.truth.set_index("epoch").loc[ep["epoch"]]
    lat, lon, h = pymap3d.ecef2geodetic(truth["x"].iloc[0], truth["y"].iloc[0], truth["z"].iloc[0])
    est = np.array(pymap3d.ecef2enu(ep["x"].to_numpy(), ep["y"].to_numpy(), ep["z"].to_numpy(), lat, lon, h))
    ref = np.array(pymap3d.ecef2enu(truth["x"].to_numpy(), truth["y"].to_numpy(), truth["z"].to_numpy(), lat, lon, h))
    horizontal = np.hypot(*(est - ref)[:2])
    assert np.median(horizontal[len(horizontal) // 2 :]) < 1.0
