"""Simulated wheel odometry against its model, the generator's isolation of streams, the contract."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import simbench
from simbench.contract import ODOMETRY_COLUMNS, ReceiverData, Scenario
from simbench.errors import SimbenchError
from simbench.sim.config import NlosConfig, OdometryConfig, TrajectoryConfig
from simbench.sim.odometry import simulate_odometry
from simbench.sim.processes import stream
from simbench.sim.trajectory import Trajectory, urban_drive

IMU_RATE_HZ = 100.0
#: generous enough for the grade, large enough that the regression must find it
CFG = OdometryConfig(enabled=True, scale_factor_sigma=0.01)


@pytest.fixture(scope="module")
def drive() -> Trajectory:
    return urban_drive(TrajectoryConfig(), NlosConfig(), 900.0, IMU_RATE_HZ, stream(1, "trajectory"))


def _truth_at(traj: Trajectory, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed, body-z rate w.r.t. the Earth and heading-angle rate of ``traj`` at the sample times ``t``."""
    k = np.rint(t * IMU_RATE_HZ).astype(np.int64)
    speed = np.linalg.norm(traj.vel[k], axis=1)  # the car's body x is along its velocity
    heading_rate = np.gradient(np.unwrap(traj.att[:, 2]), traj.t)[k]
    return speed, traj.omega_eb_b[k, 2], heading_rate


def test_speed_follows_the_error_model(drive: Trajectory) -> None:
    """White noise of the configured sigma and a scale factor recovered by regression."""
    odo = simulate_odometry(drive, CFG, stream(9, "odometry"))
    tab = odo.table
    assert list(tab.columns) == list(ODOMETRY_COLUMNS)
    assert np.allclose(np.diff(tab["t"]), 1.0 / CFG.rate_hz)
    v, _, _ = _truth_at(drive, tab["t"].to_numpy())
    moving = v > 0.5
    assert moving.sum() > 5000 and (~moving).sum() > 300  # the drive stops, too
    meas = tab["speed"].to_numpy()
    # standing wheels do not turn: exactly zero, no noise
    assert (meas[v == 0.0] == 0.0).all() and (v == 0.0).sum() > 300
    # regression of the error on the true speed: slope = scale factor, residual = white noise
    A = np.column_stack([v[moving], np.ones(moving.sum())])
    (slope, intercept), *_ = np.linalg.lstsq(A, meas[moving] - v[moving], rcond=None)
    resid = meas[moving] - v[moving] - slope * v[moving] - intercept
    sxx = np.sum((v[moving] - v[moving].mean()) ** 2)
    se_slope = CFG.speed_sigma_mps / np.sqrt(sxx)
    se_intercept = CFG.speed_sigma_mps * np.sqrt(1 / moving.sum() + v[moving].mean() ** 2 / sxx)
    assert abs(slope - odo.scale_factor) < 4 * se_slope
    assert abs(odo.scale_factor) > 10 * se_slope  # a scale factor the test can see
    assert abs(intercept) < 4 * se_intercept
    assert resid.std() == pytest.approx(CFG.speed_sigma_mps, rel=0.05)
    noise = meas[moving] - (1 + odo.scale_factor) * v[moving]
    assert abs(noise.mean()) < 4 * CFG.speed_sigma_mps / np.sqrt(moving.sum())
    # reported variances are the configured noise, not the truth
    assert (tab["var_speed"] == CFG.speed_sigma_mps**2).all()
    assert (tab["var_yaw_rate"] == CFG.yaw_rate_sigma_rps**2).all()


def test_yaw_rate_is_positive_turning_right(drive: Trajectory) -> None:
    odo = simulate_odometry(drive, CFG, stream(9, "odometry"))
    t = odo.table["t"].to_numpy()
    _, w_z, heading_rate = _truth_at(drive, t)
    meas = odo.table["yaw_rate"].to_numpy()
    err = meas - w_z
    n = err.size
    assert abs(err.mean() - odo.yaw_rate_bias_rps) < 4 * CFG.yaw_rate_sigma_rps / np.sqrt(n)
    assert err.std() == pytest.approx(CFG.yaw_rate_sigma_rps, rel=0.05)
    # heading is clockwise from north: a right turn raises it, and the odometer reads it positive
    turning = np.abs(heading_rate) > 0.05
    assert turning.sum() > 200
    slope = np.polyfit(heading_rate[turning], meas[turning], 1)[0]
    assert slope == pytest.approx(1.0, abs=0.02)
    assert np.corrcoef(heading_rate[turning], meas[turning])[0, 1] > 0.99


def test_determinism_and_seed_dependence(drive: Trajectory) -> None:
    a = simulate_odometry(drive, CFG, stream(3, "odometry"))
    b = simulate_odometry(drive, CFG, stream(3, "odometry"))
    c = simulate_odometry(drive, CFG, stream(4, "odometry"))
    pd.testing.assert_frame_equal(a.table, b.table)
    assert a.scale_factor == b.scale_factor and a.yaw_rate_bias_rps == b.yaw_rate_bias_rps
    assert a.scale_factor != c.scale_factor
    assert not np.allclose(a.table["yaw_rate"], c.table["yaw_rate"])


@pytest.mark.parametrize(
    "change, field",
    [
        ({"rate_hz": 7.0}, "scenario.odometry.rate_hz"),
        ({"rate_hz": 0.0}, "scenario.odometry.rate_hz"),
        ({"speed_sigma_mps": -0.1}, "scenario.odometry.speed_sigma_mps"),
    ],
)
def test_bad_odometry_config_is_one_line(drive: Trajectory, change: dict, field: str) -> None:
    cfg = OdometryConfig(enabled=True, **change)
    with pytest.raises(SimbenchError) as info:
        simulate_odometry(drive, cfg, stream(0, "odometry"))
    assert str(info.value).startswith(field) and "\n" not in str(info.value)


# ---------------------------------------------------------------------------- generator and contract


@pytest.fixture(scope="module")
def pair() -> tuple[Scenario, Scenario]:
    short = {"scenario.duration_s": 60}
    return (
        simbench.simulate("urban", "low", seed=2, **short),
        simbench.simulate("urban", "low", seed=2, **short, **{"scenario.odometry.enabled": False}),
    )


def test_switching_odometry_on_changes_nothing_else(pair: tuple[Scenario, Scenario]) -> None:
    on, off = pair
    assert len(on.odometry) == 600 and len(off.odometry) == 0
    assert list(off.odometry.columns) == list(ODOMETRY_COLUMNS)
    for name in ("observations", "imu", "truth", "labels"):
        pd.testing.assert_frame_equal(getattr(on, name), getattr(off, name))
    assert "odometry_errors" in on.meta and "odometry_errors" not in off.meta


def test_generated_odometry_matches_truth_at_epochs(pair: tuple[Scenario, Scenario]) -> None:
    on, _ = pair
    odo = on.odometry.set_index(np.rint(on.odometry["t"] * 10).astype(int))
    truth = on.truth.set_index(np.rint(on.truth["t"] * 10).astype(int))
    both = truth.join(odo[["speed"]], how="inner")
    assert len(both) == len(on.truth)
    v = np.linalg.norm(both[["vx", "vy", "vz"]].to_numpy(), axis=1)
    err = both["speed"].to_numpy() - (1 + on.meta["odometry_errors"]["scale_factor"]) * v
    sigma = on.meta["config"]["scenario"]["odometry"]["speed_sigma_mps"]
    assert np.all(np.abs(err) < 5 * sigma)


def test_receiver_view_save_load_and_leak_check(pair: tuple[Scenario, Scenario], tmp_path: Path) -> None:
    on, off = pair
    view = on.receiver_view()
    pd.testing.assert_frame_equal(view.odometry, on.odometry)
    assert len(off.receiver_view().odometry) == 0
    on.save(tmp_path / "s")
    back = Scenario.load(tmp_path / "s")
    pd.testing.assert_frame_equal(back.odometry, on.odometry)
    with pytest.raises(ValueError, match="nlos"):
        ReceiverData(on.observations, on.imu, on.nav, odometry=on.odometry.assign(nlos=False))


def test_flight_has_no_odometry() -> None:
    sc = simbench.simulate("flight", "low", seed=0, **{"scenario.duration_s": 40})
    assert len(sc.odometry) == 0 and list(sc.odometry.columns) == list(ODOMETRY_COLUMNS)
