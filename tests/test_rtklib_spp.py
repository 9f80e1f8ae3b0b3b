"""rtklib_spp: the .pos reader, time matching, a missing or failing rnx2rtkp, and the Hong Kong log."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from estimators.baselines.configs import RtklibSppConfig
from estimators.baselines.rtklib_spp import EXECUTABLE, RtklibSpp, rnx2rtkp_options, run_rnx2rtkp
from simbench.contract import (
    IMU_COLUMNS,
    MISSING_NEED_REASONS,
    OBSERVATION_COLUMNS,
    TRUTH_COLUMNS,
    NavInfo,
    Need,
    RinexFiles,
    Scenario,
    available_needs,
)
from simbench.data.rinex import load_rinex
from simbench.data.rtklib_pos import parse_rtklib_pos
from simbench.data.solution_times import match_to_epochs
from simbench.errors import SimbenchError
from simbench.runs.runner import run_estimators

ECEF_POS = """\
% program   : rnx2rtkp ver.2.4.3 b34
% (x/y/z-ecef=WGS84,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)
%  GPST              x-ecef(m)      y-ecef(m)      z-ecef(m)   Q  ns   sdx(m)   sdy(m)   sdz(m)  sdxy(m)  sdyz(m)  sdzx(m) age(s)  ratio
2051  45874.000  -2419241.4643   5385492.8724   2405342.3698   5   6   9.3435  32.2673  17.1575 -15.9955  22.3887 -11.5124   0.00    0.0
2051  45875.500  -2419238.3121   5385475.4250   2405340.2691   5   7   9.3448  32.2611  17.1560 -15.9954  22.3853 -11.5129   0.00    0.0
"""

# lat/lon/height in decimal degrees, calendar GPST: the equator at Greenwich and the North pole
LLH_POS = """\
% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)
%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio
1980/01/06 00:00:01.000    0.000000000    0.000000000     0.0000   5   4   6.8701   7.4964  36.3244  -2.7140 -14.3081   9.5446   0.00    0.0
2019/04/28 12:44:34.000   90.000000000    0.000000000   100.0000   1   9   6.8703   7.4934  36.3191  -2.7121 -14.3020   9.5446   0.00    0.0
"""

HK_FILES = ("COM3_190428_124409.obs", "hksc1180.19n", "hksc1180.19b", "groundTruth_TST.csv")


def test_parse_ecef_week_tow() -> None:
    pos = parse_rtklib_pos(ECEF_POS)
    np.testing.assert_allclose(pos["t_gps"], [2051 * 604800 + 45874.0, 2051 * 604800 + 45875.5], rtol=0, atol=1e-6)
    np.testing.assert_allclose(pos.loc[1, ["x", "y", "z"]].to_numpy(float), [-2419238.3121, 5385475.4250, 2405340.2691])
    assert pos["q"].tolist() == [5, 5] and pos["ns"].tolist() == [6, 7]


def test_parse_llh_calendar_time() -> None:
    pos = parse_rtklib_pos(LLH_POS)
    np.testing.assert_allclose(pos.loc[0, ["x", "y", "z"]].to_numpy(float), [6378137.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(pos.loc[1, ["x", "y", "z"]].to_numpy(float), [0.0, 0.0, 6356752.3142 + 100.0], atol=1e-3)
    # GPS time starts 1980-01-06; 2019-04-28 12:44:34 GPST is week 2051, 45874 s (RTKLIB's own header)
    np.testing.assert_allclose(pos["t_gps"], [1.0, 2051 * 604800 + 45874.0], rtol=0, atol=1e-6)
    assert pos["q"].tolist() == [5, 1]


def test_parse_refuses_utc_and_files_without_header() -> None:
    with pytest.raises(SimbenchError, match="not GPS time"):
        parse_rtklib_pos(ECEF_POS.replace("%  GPST ", "%  UTC  "))
    with pytest.raises(SimbenchError, match="no RTKLIB column header"):
        parse_rtklib_pos("2051 45874.0 1 2 3 5 6\n")
    assert parse_rtklib_pos(ECEF_POS.split("2051")[0]).empty


def test_match_to_epochs_nearest_within_half_an_interval() -> None:
    t_epoch = np.array([100.0, 101.0, np.nan, 103.0, 104.0])  # epoch 2 has no observations
    # 3 ms clock offsets, one solution 0.7 s away from any epoch, two solutions nearest to epoch 4
    t_sol = np.array([100.003, 100.997, 102.3, 102.998, 104.2, 104.002])
    si, ei = match_to_epochs(t_sol, t_epoch, 0.5)
    assert ei.tolist() == [0, 1, 3, 4]
    assert si.tolist() == [0, 1, 3, 5]  # 104.002 beats 104.2 for epoch 4; 102.3 is 0.7 s from epoch 3
    si, ei = match_to_epochs(t_sol, t_epoch, 0.001)
    assert ei.tolist() == []  # nothing within 1 ms
    assert match_to_epochs(np.array([5.0]), np.array([5.2]), 0.5)[1].tolist() == [0]


def test_options_follow_the_config() -> None:
    opts = rnx2rtkp_options(RtklibSppConfig(), "GC")
    assert opts["pos1-posmode"] == "single" and opts["pos1-navsys"] == "33"  # GPS 1 + BeiDou 32
    assert (opts["pos1-elmask"], opts["pos1-ionoopt"], opts["pos1-tropopt"]) == ("10", "brdc", "saas")
    assert opts["pos1-frequency"] == "l1"  # auto on single-frequency rows
    for iono, dual in (("auto", True), ("free", False)):
        opts = rnx2rtkp_options(RtklibSppConfig(ionosphere=iono), "GC", dual_frequency=dual)
        assert (opts["pos1-ionoopt"], opts["pos1-frequency"]) == ("dual-freq", "l1+l2"), iono
    assert rnx2rtkp_options(RtklibSppConfig(ionosphere="broadcast"), "G", True)["pos1-ionoopt"] == "brdc"
    opts = rnx2rtkp_options(
        RtklibSppConfig(elevation_mask_deg=15, ionosphere="none", troposphere="none", raim_fde=True), "G"
    )
    assert (
        opts["pos1-elmask"],
        opts["pos1-ionoopt"],
        opts["pos1-tropopt"],
        opts["pos1-posopt5"],
        opts["pos1-navsys"],
    ) == ("15", "off", "off", "on", "1")
    with pytest.raises(SimbenchError, match="scenario.systems"):
        rnx2rtkp_options(RtklibSppConfig(), "GX")
    for field, value in (("elevation_mask_deg", 90.0), ("timeout_s", 0.0), ("ionosphere", "nequick")):
        with pytest.raises(SimbenchError, match=f"estimator.rtklib_spp.{field}"):
            RtklibSpp(RtklibSppConfig(**{field: value}))


def _tiny_scenario(rinex: RinexFiles | None) -> Scenario:
    """One epoch, one satellite: enough for the runner to decide whether to run an estimator."""
    obs = pd.DataFrame({c: [0.0] for c in OBSERVATION_COLUMNS}).assign(epoch=0, sat="G01", lli_l1=False, lli_l2=False)
    truth = pd.DataFrame({c: [0.0] for c in TRUTH_COLUMNS}).assign(epoch=0, n_visible=1)
    nav = NavInfo(gps_week=2051, start_sow_s=0.0, iono_alpha=(0.0,) * 4, iono_beta=(0.0,) * 4, dual_frequency=False)
    return Scenario(obs, pd.DataFrame({c: [] for c in IMU_COLUMNS}), truth, None, nav, rinex=rinex)


def _fake_rnx2rtkp(directory: Path, script: str) -> None:
    exe = directory / EXECUTABLE
    exe.write_text("#!/bin/sh\n" + script)
    exe.chmod(0o755)


def test_skipped_with_a_reason_without_the_executable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))  # an empty directory: no rnx2rtkp
    reason = RtklibSpp.unavailable_reason()
    assert EXECUTABLE in reason and "apt-get install rtklib" in reason
    files = RinexFiles(obs=str(tmp_path / "a.obs"), nav=(str(tmp_path / "a.nav"),), systems="G")
    assert Need.rinex_files in available_needs(_tiny_scenario(files))
    row = run_estimators(_tiny_scenario(files), {"rtklib_spp": None}, progress=False).summary.iloc[0]
    assert (row["status"], row["message"], row["n_solved"]) == ("skipped", reason, 0)
    # no RINEX files and no executable: both reasons on one line
    row = run_estimators(_tiny_scenario(None), {"rtklib_spp": None}, progress=False).summary.iloc[0]
    assert row["status"] == "skipped" and "\n" not in row["message"]
    assert MISSING_NEED_REASONS[Need.rinex_files] in row["message"] and reason in row["message"]
    # with an executable on PATH it is no longer unavailable
    _fake_rnx2rtkp(tmp_path, "exit 0\n")
    assert RtklibSpp.unavailable_reason() == ""


def test_a_failing_run_raises_with_the_tools_last_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    obs, nav = tmp_path / "a.obs", tmp_path / "a.nav"
    obs.write_text("x")
    nav.write_text("x")
    opts = rnx2rtkp_options(RtklibSppConfig(), "G")
    _fake_rnx2rtkp(tmp_path, "printf 'reading...\\rerror : no nav data\\n' >&2\nexit 3\n")
    with pytest.raises(SimbenchError, match="exited with code 3: error : no nav data") as info:
        run_rnx2rtkp(str(obs), [str(nav)], opts, 10.0)
    assert "\n" not in str(info.value)
    # exit 0 but only a header (rnx2rtkp's way of failing): the output file is named after -o
    _fake_rnx2rtkp(tmp_path, 'printf "%% header\\n" > "$4"\necho "processing : Q=0" >&2\n')
    with pytest.raises(SimbenchError, match="wrote no solution: processing : Q=0"):
        run_rnx2rtkp(str(obs), [str(nav)], opts, 10.0)
    with pytest.raises(SimbenchError, match="scenario.rinex.nav"):
        run_rnx2rtkp(str(obs), [str(tmp_path / "gone.nav")], opts, 10.0)


@pytest.fixture(scope="module")
def hk(shared_data: Path) -> Path:
    if shutil.which(EXECUTABLE) is None:
        message = f"{EXECUTABLE} is not on PATH (apt-get install rtklib)"
        if os.environ.get("CI"):
            pytest.fail(f"{message}; .ci/run installs it", pytrace=False)
        pytest.skip(message)
    return shared_data / "hk_tst_2019"


# Measured with RTKLIB 2.4.3 b34 (Debian), defaults (10 deg mask, Klobuchar, Saastamoinen), 485 reference
# epochs: G 39.0 % solved, horizontal median 4.49 m, 3-D median 14.5 m; GC 28.9 %, 3.87 m, 8.05 m.
# A one-epoch time shift moves the GPS horizontal median to 8.4-9.4 m; a frame error to kilometres.
@pytest.mark.parametrize(
    ("systems", "availability", "horizontal_m", "error_3d_m"),
    [("G", (0.33, 0.45), 5.5, 18.0), ("GC", (0.24, 0.34), 5.0, 10.0)],
)
def test_hong_kong_log(
    hk: Path, systems: str, availability: tuple[float, float], horizontal_m: float, error_3d_m: float
) -> None:
    sc = load_rinex(
        hk / HK_FILES[0],
        hk / HK_FILES[1],
        hk / HK_FILES[3],
        systems=systems,
        nav_bds_path=hk / HK_FILES[2] if "C" in systems else None,
    )
    assert sc.rinex is not None and sc.rinex.systems == systems and len(sc.rinex.nav) == len(systems)
    res = run_estimators(sc, {"rtklib_spp": None}, progress=False)
    row = res.summary.iloc[0]
    assert row["status"] == "ok", row["message"]
    assert availability[0] < row["availability"] < availability[1]
    assert row["horizontal_median"] < horizontal_m and row["error_3d_median"] < error_3d_m
    diag = res.diagnostics["rtklib_spp"]
    # every RTKLIB solution lands on an epoch of the log (a broken time origin matches none or few)
    assert diag["n_matched"] == diag["n_solutions"] > 0 and set(diag["quality_counts"]) == {"5"}
    assert "ver." in diag["program"]  # the version line of the .pos header, kept with the result


def test_rinex_files_survive_the_scenario_cache(tmp_path: Path) -> None:
    files = RinexFiles(obs="/data/a.obs", nav=("/data/a.19n", "/data/a.19b"), systems="GC")
    back = Scenario.load(_tiny_scenario(files).save(tmp_path))
    assert back.rinex == files and back.receiver_view().rinex == files
    assert Scenario.load(_tiny_scenario(None).save(tmp_path / "none")).rinex is None
