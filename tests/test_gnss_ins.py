"""GNSS/INS building blocks and the EKF / IEKF: levelling, code and Doppler models, accuracy, gating, validation."""

from __future__ import annotations

import numpy as np
import pytest

import simbench
from estimators.gnss_ins.config import CrtLssConfig, EkfInsConfig, IekfInsConfig
from estimators.gnss_ins.data import prepare_gnss_ins
from estimators.gnss_ins.driver import run_gnss_ins
from estimators.gnss_ins.ekf import EkfIns, IekfIns
from estimators.gnss_ins.mechanisation import level_roll_pitch
from estimators.gnss_ins.window_solver import WindowSolver
from simbench.analysis.metrics import enu_errors
from simbench.contract import Need, ReceiverData
from simbench.errors import SimbenchError
from simbench.gnss.doppler import range_rate
from simbench.gnss.geometry import sagnac_range
from simbench.runs.runner import score_solution


@pytest.fixture(scope="module")
def scenario() -> simbench.Scenario:
    return simbench.simulate("open_sky", "high", seed=1001, **{"scenario.duration_s": 50.0})


def test_levelling_recovers_roll_and_pitch(scenario: simbench.Scenario) -> None:
    imu = scenario.imu
    static = imu["t"].to_numpy() <= 5.0
    roll, pitch = level_roll_pitch(imu.loc[static, ["ax", "ay", "az"]].to_numpy().mean(axis=0))
    truth = scenario.truth.iloc[0]
    # consumer accelerometer bias 0.1 m/s^2 (1 sigma) tilts the solution by ~0.6 deg
    assert abs(roll - truth["roll"]) < np.radians(2.0)
    assert abs(pitch - truth["pitch"]) < np.radians(2.0)


def test_doppler_model_matches_the_simulator(scenario: simbench.Scenario) -> None:
    """Observed range rate minus the modelled one at the true state is the receiver drift plus noise."""
    prep = prepare_gnss_ins(scenario.receiver_view(), CrtLssConfig())
    truth = scenario.truth.set_index("epoch")
    clock = truth["rx_clock"].to_numpy()
    res = []
    for e in range(5, 45):
        g = prep.gnss[e]
        p = truth.loc[e, ["x", "y", "z"]].to_numpy(float)
        v = truth.loc[e, ["vx", "vy", "vz"]].to_numpy(float)
        rdot, _, _ = range_rate(g.sat_pos, g.sat_vel, p, v)
        drift = 0.5 * (clock[e + 1] - clock[e - 1])  # central difference of the true clock [m/s]
        res.append(g.rr - rdot - drift)
    res = np.concatenate(res)
    # 0.5 Hz Doppler noise = 0.1 m/s; a model error of Sagnac size (~0.01 m/s) would show in the mean
    assert abs(np.median(res)) < 0.03
    assert np.percentile(np.abs(res), 90) < 0.5


@pytest.mark.parametrize("cls", [EkfIns, IekfIns])
def test_filters_track_the_drive(cls, scenario: simbench.Scenario) -> None:
    sol = cls().estimate(scenario.receiver_view())
    err = enu_errors(sol.epochs, scenario.truth)
    assert len(sol.epochs) >= scenario.n_epochs - 2
    assert np.nanmedian(err["horizontal"]) < 2.0
    assert sol.diagnostics["heading_aligned_epoch"] > 0


def test_ekf_gate_rejects_an_injected_outlier(scenario: simbench.Scenario) -> None:
    data = scenario.receiver_view()
    obs = data.observations.copy()
    rows = np.flatnonzero((obs["epoch"] == 40).to_numpy())
    obs.iloc[rows[0], obs.columns.get_loc("code_l1")] += 80.0
    bad = ReceiverData(obs, data.imu, data.nav)
    ref = EkfIns().estimate(data)
    gated = EkfIns().estimate(bad)
    open_gate, _ = run_gnss_ins(bad, EkfInsConfig(), mode="ekf", window=1, gate=np.inf)
    assert gated.diagnostics["ekf_rejected_rows"] == ref.diagnostics["ekf_rejected_rows"] + 1
    at = (ref.epochs["epoch"] == 40).to_numpy()
    xyz = ["x", "y", "z"]
    moved_gated = np.linalg.norm(gated.epochs[xyz].to_numpy()[at] - ref.epochs[xyz].to_numpy()[at])
    moved_open = np.linalg.norm(open_gate[xyz].to_numpy()[at] - ref.epochs[xyz].to_numpy()[at])
    assert moved_gated < 0.3  # dropping one satellite changes the geometry: decimetres
    assert moved_open > 1.0


def test_a_filter_whose_normal_equations_break_is_lost_from_that_epoch(
    scenario: simbench.Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A run-away filter ends in normal equations Cholesky refuses (seen in ``urban_deep``): the
    epochs from there are NaN and the run is scored ``diverged``, not a ``failed`` row."""
    data = scenario.receiver_view()
    ref, _ = run_gnss_ins(data, EkfInsConfig(), mode="ekf", window=1)
    update, calls = WindowSolver.ekf_update, []

    def breaks_at_epoch_30(solver: WindowSolver, gate: float) -> int:  # one update per solved epoch
        calls.append(gate)
        if len(calls) > 30:
            raise np.linalg.LinAlgError("banded Cholesky failed: LAPACK pbsv info 33")
        return update(solver, gate)

    monkeypatch.setattr(WindowSolver, "ekf_update", breaks_at_epoch_30)
    lost, diagnostics = run_gnss_ins(data, EkfInsConfig(), mode="ekf", window=1)
    xyz = ["x", "y", "z"]
    assert lost["epoch"].tolist() == ref["epoch"].tolist()
    np.testing.assert_array_equal(lost[xyz].to_numpy()[:30], ref[xyz].to_numpy()[:30])
    assert np.isnan(lost[xyz].to_numpy()[30:]).all()
    assert diagnostics["lost_epoch"] == ref["epoch"].iloc[30]
    assert "pbsv info 33" in diagnostics["lost_reason"]
    scores, _ = score_solution(scenario, lost, total_s=1.0)
    assert scores["status"] == "diverged"
    assert scores["availability"] == pytest.approx(30 / scenario.n_epochs)


def test_prepared_code_is_range_plus_clock_after_the_troposphere(scenario: simbench.Scenario) -> None:
    """Code minus the true range and clock is noise plus the Klobuchar residual; an unmodelled
    troposphere would leave its ~2.5 m zenith delay mapped up (>= 2.5 m) in the median."""
    prep = prepare_gnss_ins(scenario.receiver_view(), CrtLssConfig())
    truth = scenario.truth.set_index("epoch")
    assert len(prep.fixes) == len(prep.gnss) == scenario.n_epochs  # open sky: every epoch fixes
    res, fix_err = [], []
    for e, g in prep.gnss.items():
        p = truth.loc[e, ["x", "y", "z"]].to_numpy(float)
        res.append(g.code - sagnac_range(g.sat_pos, p) - truth.loc[e, "rx_clock"])
        fix_err.append(np.linalg.norm(prep.fixes[e].pos - p))
    assert abs(np.median(np.concatenate(res))) < 1.0
    assert np.median(fix_err) < 5.0


@pytest.mark.parametrize(
    ("cls", "cfg", "field"),
    [
        (EkfIns, EkfInsConfig(gate=0.0), "gate"),
        (EkfIns, EkfInsConfig(level_s=0.0), "level_s"),
        (IekfIns, IekfInsConfig(lambda_d=-1.0), "lambda_d"),
        (IekfIns, IekfInsConfig(tol=0.0), "tol"),
    ],
)
def test_filters_declare_the_imu_and_reject_bad_configs(cls, cfg, field: str) -> None:
    assert cls.requires == frozenset({Need.imu})
    with pytest.raises(SimbenchError, match=rf"^estimator\.{cls.name}\.{field}: must be"):
        cls(cfg)


def test_an_imu_table_of_one_row_is_a_one_line_error(scenario: simbench.Scenario) -> None:
    data = scenario.receiver_view()
    short = ReceiverData(data.observations, data.imu.iloc[:1], data.nav)
    with pytest.raises(SimbenchError, match=r"^imu: the GNSS/INS estimators need the IMU table"):
        EkfIns().estimate(short)
