"""The libRSF text format: parsing, mapping into the observation table, scoring, bad input."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from estimators.measurement import prepare_ppp
from simbench.gnss.spp import solve_epochs
from simbench.compose import compose_config
from simbench.config import SimConfig, to_typed
from simbench.contract import OBSERVATION_COLUMNS, Scenario
from simbench.data.librsf import load_librsf, read_librsf, write_synthetic_librsf
from simbench.errors import SimbenchError
from simbench.runner import run_estimators
from simbench.scenarios import build_scenario

FIXTURE = Path(__file__).resolve().parent / "data" / "librsf_small.txt"
WEEK, SOW = 2032, 475_200.0


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return load_librsf(FIXTURE, gps_week=WEEK, start_sow_s=SOW)


def test_fixture_is_read_completely() -> None:
    log = read_librsf(FIXTURE)
    assert log.t0 == 0.0
    assert len(log.ranges) == 60 and log.ranges["sat"].str.match(r"^G\d\d$").all()
    assert len(log.odometry) == 10 and log.odometry["vx"].between(9.5, 10.5).all()
    assert len(log.reference) == 10
    assert log.ranges["var_rho"].eq(0.25).all()


def test_mapping_into_the_observation_table(scenario: Scenario) -> None:
    obs = scenario.observations
    assert list(obs.columns) == list(OBSERVATION_COLUMNS)
    assert (obs["sat_clock"] == 0).all() and obs["phase_l1"].isna().all()
    assert scenario.nav.iono_corrected and not scenario.nav.dual_frequency
    assert scenario.labels is None and len(scenario.imu) == 0
    assert len(scenario.truth) == 10 and scenario.meta["odometry_rows"] == 10
    # code = file pseudorange + the modelled hydrostatic delay (2.3-10 m at 10-85 deg elevation)
    rho = read_librsf(FIXTURE).ranges.sort_values(["t", "sat"])["rho"].to_numpy()
    added = obs["code_l1"].to_numpy() - rho
    assert np.all((added > 2.0) & (added < 12.0))
    assert np.corrcoef(added, 1 / np.sin(np.radians(obs["el"])))[0, 1] > 0.99


def test_shared_model_recovers_the_synthetic_truth(scenario: Scenario) -> None:
    """No Klobuchar applied, hydrostatic delay cancelled: the fit matches the 0.5 m code noise."""
    obs = prepare_ppp(scenario.receiver_view(), ionosphere_free=False, code_sigma_m=0.5, phase_sigma_m=0.01,
                      elevation_mask_deg=7.0, require_phase=False)
    truth = scenario.truth[["x", "y", "z"]].to_numpy()
    row_k = np.repeat(np.arange(obs.n_epochs), obs.epoch_stop - obs.epoch_start)
    fixes = solve_epochs(row_k, obs.sat_pos, obs.code, sigma=obs.sigma_code, el=obs.el, doy=obs.doy)
    assert fixes.trusted.all()
    err = np.linalg.norm(fixes.pos - truth[obs.epoch_ids], axis=1)
    clock = fixes.clock_m[:, 0] - (100.0 + obs.epoch_t)  # the fixture's receiver clock
    assert np.median(err) < 1.5
    assert abs(np.median(clock)) < 1.0
    # and an estimator run through the runner scores against the point3 lines
    res = run_estimators(scenario, {"ekf_ppp": {"use_phase": False}}, progress=False)
    row = res.summary.iloc[0]
    assert row["status"] == "ok" and row["availability"] == 1.0 and row["error_3d_median"] < 10.0


def test_phase_estimators_are_skipped_with_a_reason(scenario: Scenario) -> None:
    res = run_estimators(scenario, {"ekf_ppp": {"use_phase": True}, "l2": {}}, progress=False)
    assert (res.summary["status"] == "skipped").all()
    assert res.summary["message"].str.contains("phase").all()


def test_system_flags_and_the_old_layout(tmp_path: Path) -> None:
    sat = "13937336.4 13497913.0 18137658.6"
    p = tmp_path / "mixed.txt"
    p.write_text(f"pseudorange3 5.0 2.1e7 4.0 {sat} 11 8 45.0 40.0\n"
                 f"pseudorange3 5.0 2.1e7 4.0 {sat} 5 32 45.0 40.0\n")
    assert read_librsf(p).ranges["sat"].tolist() == ["E11", "C05"]
    old = tmp_path / "old.txt"
    old.write_text(f"range3 5.0 2.1e7 4.0 {sat} 7 45.0 40.0\ngt3 5.0 1 2 3\n")
    log = read_librsf(old)
    assert log.ranges["sat"].tolist() == ["G07"] and log.ranges["el"].iloc[0] == 45.0
    assert len(log.reference) == 1


def test_bad_input(tmp_path: Path) -> None:
    def one_line(fn, *a, **k) -> str:
        with pytest.raises(SimbenchError) as info:
            fn(*a, **k)
        assert "\n" not in str(info.value)
        return str(info.value)

    assert "does not exist" in one_line(read_librsf, tmp_path / "none.txt")
    no_ranges = tmp_path / "odo.txt"
    no_ranges.write_text("odom3 0.0 1 0 0 0 0 0 1 1 1 1 1 1\n")
    assert "no pseudorange3" in one_line(read_librsf, no_ranges)
    junk = tmp_path / "junk.txt"
    junk.write_text("satpos 1 2 3\n")
    assert "unknown line types" in one_line(read_librsf, junk)
    # a reference file whose times do not overlap the pseudoranges
    gt = tmp_path / "gt.txt"
    gt.write_text("point3 5000.0 4e6 1e6 4.8e6 0 0 0 0 0 0 0 0 0\npoint3 5001.0 4e6 1e6 4.8e6 0 0 0 0 0 0 0 0 0\n")
    assert "does not overlap" in one_line(load_librsf, FIXTURE, gt, gps_week=WEEK, start_sow_s=SOW)


def test_synthetic_writer_and_the_scenario_preset(tmp_path: Path) -> None:
    p = write_synthetic_librsf(tmp_path / "a.txt", 5.0, odometry_rate_hz=2.0, seed=3)
    log = read_librsf(p)
    assert log.ranges["t"].nunique() == 5 and len(log.odometry) == 10
    cfg = to_typed({k: v for k, v in compose_config(["scenario=librsf", f"scenario.obs={p}"]).items()
                    if k in ("scenario", "receiver", "imu", "seed")}, SimConfig, "config")
    sc = build_scenario(cfg)
    assert sc.meta["source"] == "librsf" and len(sc.truth) == 5
