"""The libRSF text format: parsing, mapping into the observation table, scoring, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import one_line_error, single_point_fixes

from simbench.contract import OBSERVATION_COLUMNS, ODOMETRY_COLUMNS, Scenario
from simbench.data.librsf import load_librsf, read_librsf, write_synthetic_librsf
from simbench.errors import SimbenchError
from simbench.gnss.geometry import elevation_azimuth
from simbench.gnss.spp import solve_epochs
from simbench.runs.compose import compose_config
from simbench.runs.runner import run_estimators
from simbench.runs.scenarios import build_scenario, scenario_settings

FIXTURE = Path(__file__).resolve().parent / "data" / "librsf_small.txt"
#: 6 s at 5 Hz, GPS + GLONASS (RTKLIB IDs, 40 m inter-system clock offset), 10 Hz odometry:
#: write_synthetic_librsf(path, 6.0, rate_hz=5.0, odometry_rate_hz=10.0, systems="GR",
#: glonass_bias_m=40.0, seed=7)
GLONASS_FIXTURE = FIXTURE.with_name("librsf_glonass.txt")
WEEK, SOW = 2032, 475_200.0


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return load_librsf(FIXTURE, gps_week=WEEK, start_sow_s=SOW)


def test_fixture_is_read_completely() -> None:
    log = read_librsf(FIXTURE)
    assert log.t0 == 0.0
    assert len(log.ranges) == 60 and log.ranges["sat"].str.match(r"^G\d\d$").all()
    assert len(log.odometry) == 10 and log.odometry["speed"].between(9.5, 10.5).all()
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
    obs, fixes = single_point_fixes(scenario.receiver_view(), 0.5, 0.01, 7.0)
    truth = scenario.truth[["x", "y", "z"]].to_numpy()
    assert fixes.trusted.all()
    err = np.linalg.norm(fixes.pos - truth[obs.epoch_ids], axis=1)
    clock = fixes.clock_m[:, 0] - (100.0 + obs.epoch_t)  # the fixture's receiver clock
    assert np.median(err) < 1.5
    assert abs(np.median(clock)) < 1.0
    # and an estimator run through the runner scores against the point3 lines
    res = run_estimators(scenario, {"ekf_ppp": {"measurements": "code"}}, progress=False)
    row = res.summary.iloc[0]
    assert row["status"] == "ok" and row["availability"] == 1.0 and row["error_3d_median"] < 10.0


def test_phase_estimators_are_skipped_with_a_reason(scenario: Scenario) -> None:
    res = run_estimators(
        scenario, {"ekf_ppp": {"measurements": "code_phase"}, "l2": {"measurements": "code_phase"}}, progress=False
    )
    assert (res.summary["status"] == "skipped").all()
    assert res.summary["message"].str.contains("phase").all()


def test_every_gnss_estimator_runs_code_only_by_default(scenario: Scenario) -> None:
    """measurements=auto: a pseudorange-only log runs every GNSS estimator without flags."""
    names = ["ekf_ppp", "l2", "dcs", "mm", "bce", "isam2_ppp", "isam2_dcs", "ice"]
    rows = run_estimators(scenario, dict.fromkeys(names), progress=False).summary.set_index("estimator")
    assert (rows["status"] == "ok").all(), rows["message"].to_dict()
    assert (rows["availability"] == 1.0).all()
    # 0.5 m code noise on a clean synthetic drive: every estimator within a few metres
    assert (rows["error_3d_median"] < 5.0).all(), rows["error_3d_median"].to_dict()


def test_system_flags_and_the_old_layout(tmp_path: Path) -> None:
    sat = "13937336.4 13497913.0 18137658.6"
    p = tmp_path / "mixed.txt"
    p.write_text(f"pseudorange3 5.0 2.1e7 4.0 {sat} 11 8 45.0 40.0\npseudorange3 5.0 2.1e7 4.0 {sat} 5 32 45.0 40.0\n")
    assert read_librsf(p).ranges["sat"].tolist() == ["E11", "C05"]
    old = tmp_path / "old.txt"
    old.write_text(f"range3 5.0 2.1e7 4.0 {sat} 7 45.0 40.0\ngt3 5.0 1 2 3\n")
    log = read_librsf(old)
    assert log.ranges["sat"].tolist() == ["G07"] and log.ranges["el"].iloc[0] == 45.0
    assert len(log.reference) == 1


def test_bad_input(tmp_path: Path) -> None:
    assert "does not exist" in one_line_error(read_librsf, tmp_path / "none.txt")
    no_ranges = tmp_path / "odo.txt"
    no_ranges.write_text("odom3 0.0 1 0 0 0 0 0 1 1 1 1 1 1\n")
    assert "no pseudorange3" in one_line_error(read_librsf, no_ranges)
    junk = tmp_path / "junk.txt"
    junk.write_text("satpos 1 2 3\n")
    assert "unknown line types" in one_line_error(read_librsf, junk)
    # a reference file whose times do not overlap the pseudoranges
    gt = tmp_path / "gt.txt"
    gt.write_text("point3 5000.0 4e6 1e6 4.8e6 0 0 0 0 0 0 0 0 0\npoint3 5001.0 4e6 1e6 4.8e6 0 0 0 0 0 0 0 0 0\n")
    assert "does not overlap" in one_line_error(load_librsf, FIXTURE, gt, gps_week=WEEK, start_sow_s=SOW)


def test_synthetic_writer_and_the_scenario_preset(tmp_path: Path) -> None:
    p = write_synthetic_librsf(tmp_path / "a.txt", 5.0, odometry_rate_hz=2.0, seed=3)
    log = read_librsf(p)
    assert log.ranges["t"].nunique() == 5 and len(log.odometry) == 10
    cfg = scenario_settings(compose_config(["scenario=librsf", f"scenario.obs={p}"]))
    sc = build_scenario(cfg)
    assert sc.meta["source"] == "librsf" and len(sc.truth) == 5


@pytest.fixture(scope="module")
def glonass() -> Scenario:
    return load_librsf(GLONASS_FIXTURE, gps_week=WEEK, start_sow_s=SOW)


def test_glonass_rows_get_their_own_system_and_clock(glonass: Scenario) -> None:
    log = read_librsf(GLONASS_FIXTURE)
    sats = log.ranges["sat"]
    # file IDs 33.. with system flag 4 are RTKLIB numbers: slot = ID - 32
    raw_ids = np.array(
        [ln.split()[7:9] for ln in GLONASS_FIXTURE.read_text().splitlines() if ln.startswith("pseudorange3")], float
    )
    assert set(sats.str[0]) == {"G", "R"} and (sats.str.len() == 3).all()
    glo_ids = raw_ids[raw_ids[:, 1] == 4, 0]
    assert glo_ids.size == 180 and (glo_ids > 32).all()
    assert sorted(sats[sats.str[0] == "R"].str[1:].astype(int).unique()) == sorted(set((glo_ids - 32).astype(int)))
    assert glonass.meta["systems"] == "GR" and glonass.n_epochs == 30
    # one clock per system absorbs the 40 m offset: the rough fixes fit to the 0.5 m noise;
    # one clock for both would leave about 20 m
    assert glonass.meta["rough_fix_rms_m"] < 1.0
    rg = log.ranges
    ep = np.unique(np.round(rg["t"].to_numpy() * 1000), return_inverse=True)[1]
    shared = solve_epochs(ep, rg[["sat_x", "sat_y", "sat_z"]].to_numpy(), rg["rho"].to_numpy())
    assert np.median(shared.rms_m) > 10.0
    # elevation and azimuth as seen from the true positions
    obs = glonass.observations
    truth = glonass.truth.set_index("epoch").loc[obs["epoch"], ["x", "y", "z"]].to_numpy()
    sat_pos = obs[["sat_x", "sat_y", "sat_z"]].to_numpy()[:, None]
    el, az = (np.degrees(a[:, 0]) for a in elevation_azimuth(truth, sat_pos))
    assert np.abs(obs["el"].to_numpy() - el).max() < 0.01
    assert np.abs((obs["az"].to_numpy() - az + 180) % 360 - 180).max() < 0.01


def test_odometry_lines_become_the_odometry_table(glonass: Scenario, tmp_path: Path) -> None:
    odo = glonass.odometry
    assert list(odo.columns) == list(ODOMETRY_COLUMNS) and len(odo) == 60
    assert np.allclose(odo["t"], np.arange(60) * 0.1)
    raw = np.array([ln.split()[1:] for ln in GLONASS_FIXTURE.read_text().splitlines() if ln.startswith("odom3")], float)
    assert np.array_equal(odo["speed"], raw[:, 1]) and np.array_equal(odo["yaw_rate"], -raw[:, 6])
    assert (odo["var_speed"] == 0.0025).all() and (odo["var_yaw_rate"] == 4e-6).all()
    assert abs(odo["speed"].mean() - 10.0) < 4 * 0.05 / np.sqrt(60)
    view = glonass.receiver_view()
    assert len(view.odometry) == 60
    glonass.save(tmp_path / "s")
    assert Scenario.load(tmp_path / "s").odometry.equals(odo)
    # libRSF turns about z up: a left turn (positive wz) is a negative yaw rate here; times from the
    # first pseudorange, sorted
    sat = "13937336.4 13497913.0 18137658.6"
    p = tmp_path / "turn.txt"
    p.write_text(
        f"odom3 2.5 4.0 0 0 0 0 0.1 0.0025 0.0009 0.0009 4e-06 4e-06 4e-06\n"
        f"odom3 0.5 5.0 0 0 0 0 -0.2 0.0025 0.0009 0.0009 4e-06 4e-06 4e-06\n"
        f"pseudorange3 2.0 2.1e7 4.0 {sat} 11 1 45.0 40.0\n"
    )
    got = read_librsf(p).odometry
    assert got["t"].tolist() == [-1.5, 0.5] and got["speed"].tolist() == [5.0, 4.0]
    assert got["yaw_rate"].tolist() == [0.2, -0.1]
    # every component and variance is carried, y and z flipped into x forward, y right, z down
    p.write_text(
        "odom3 1.0 4.0 0.3 -0.2 0.01 0.02 0.1 0.0025 0.0009 0.0016 1e-06 2e-06 4e-06\n"
        f"pseudorange3 1.0 2.1e7 4.0 {sat} 11 1 45.0 40.0\n"
    )
    row = read_librsf(p).odometry.iloc[0]
    assert row[["speed", "vel_right", "vel_down"]].tolist() == [4.0, -0.3, 0.2]
    assert row[["roll_rate", "pitch_rate", "yaw_rate"]].tolist() == [0.01, -0.02, -0.1]
    assert row[["var_speed", "var_vel_right", "var_vel_down"]].tolist() == [0.0025, 0.0009, 0.0016]
    assert row[["var_roll_rate", "var_pitch_rate", "var_yaw_rate"]].tolist() == [1e-06, 2e-06, 4e-06]
    # a file without odom3 lines gives the empty table
    p.write_text(f"pseudorange3 2.0 2.1e7 4.0 {sat} 11 1 45.0 40.0\n")
    none = read_librsf(p).odometry
    assert len(none) == 0 and list(none.columns) == list(ODOMETRY_COLUMNS)


@pytest.mark.parametrize(
    "lines, bad_line, words",
    [
        (
            ["pseudorange3 5.0 2.1e7 4.0 {sat} 11 1 45.0 40.0", "pseudorange3 5.0 2.1e7 4.0 {sat} 12 64 45.0 40.0"],
            2,
            ["field 9 (satellite system) is 64"],
        ),
        (
            ["# a comment", "", "   # indented comment", "pseudorange3 5.0 2.1e7 4.0 {sat} 11.5 1 45.0 40.0"],
            4,
            ["field 8 (satellite ID) is 11.5"],
        ),
        (
            [
                "pseudorange3 5.0 2.1e7 4.0 {sat} 11 1 45.0 40.0",
                "odom3 5.0 1 0 0 0 0 0 0.0025 0.0009 0.0009 -4e-06 4e-06 4e-06",
            ],
            2,
            ["odom3 variance field 12", "-4e-06"],
        ),
        (
            [
                "pseudorange3 5.0 2.1e7 4.0 {sat} 11 1 45.0 40.0",
                "odom3 5.0 1 0 0 0 0 0 0.0025 0.0009 0.0009 4e-06 4e-06 inf",
            ],
            2,
            ["field 14 ('inf') is not a finite number"],
        ),
        (
            [
                "pseudorange3 5.0 2.1e7 4.0 {sat} 11 1 45.0 40.0",
                "odom3 5.0 1 0 0 0 0 0 0.0025 0.0009 0.0009 4e-06 4e-06 nan",
            ],
            2,
            ["field 14 ('nan') is not a finite number"],
        ),
        (
            ["pseudorange3 5.0 2.1e7 4.0 {sat} 11 1 45.0 40.0", "pseudorange3 5.0 2.1e7 4.0 {sat} 11"],
            2,
            ["pseudorange3 has 7 values"],
        ),
        (
            ["pseudorange3 5.0 2.1e7 4.0 {sat} 11 1 45.0 40.0", "pseudorange3 5.0 2.1e7 4.0 {sat} 11 1 45.0"],
            2,
            ["pseudorange3 has 9 values", "the first pseudorange3 line 10"],
        ),
        (
            ["pseudorange3 5.0 2.1e7 4.0 {sat} 11 1 45.0 40.0", "pseudorange3 5.0 2.1e7 x {sat} 11 1 45.0 40.0"],
            2,
            ["field 4 ('x') is not a finite number"],
        ),
        (["pseudorange3 5.0 2.1e7 4.0 {sat} 11 1 45.0 40.0", "satpos 1 2 3"], 2, ["unknown line types ['satpos']"]),
    ],
)
def test_bad_lines_are_named_in_one_line(tmp_path: Path, lines: list[str], bad_line: int, words: list[str]) -> None:
    sat = "13937336.4 13497913.0 18137658.6"
    p = tmp_path / "bad.txt"
    p.write_text("\n".join(ln.format(sat=sat) for ln in lines) + "\n")
    with pytest.raises(SimbenchError) as info:
        read_librsf(p)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"scenario.obs '{p}' line {bad_line}:"), msg
    assert all(w in msg for w in words), msg
