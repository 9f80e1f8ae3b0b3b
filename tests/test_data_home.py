"""Named presets read their files from the data home (``SIMBENCH_DATA``, else ``../shared/data``) from any
working directory; a missing file stops the run before any job, in one line (issue 44, item 7)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from conftest import REPO_ROOT, one_line_error
from test_rinex_wild import NG_LLH, cut

import simbench
from simbench.paths import DATA_HOME_ENV, data_home, require_file
from simbench.runs.compose import compose_config
from simbench.runs.scenarios import check_scenario, scenario_settings

pytestmark = pytest.mark.usefixtures("shared_data")


def _cli(cwd: Path, *args: str, home: Path | None = None) -> subprocess.CompletedProcess:
    """``python -m simbench args`` in ``cwd``, importing this repository, with ``SIMBENCH_DATA=home`` if given."""
    env = {k: v for k, v in os.environ.items() if k != DATA_HOME_ENV}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO_ROOT), env.get("PYTHONPATH", "")]))
    if home is not None:
        env[DATA_HOME_ENV] = str(home)
    return subprocess.run(
        [sys.executable, "-m", "simbench", *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600
    )


def test_the_data_home_is_shared_data_beside_the_repository_or_the_environment_variable(tmp_path: Path) -> None:
    assert data_home({}) == (REPO_ROOT.parent / "shared" / "data").resolve()
    assert data_home({DATA_HOME_ENV: str(tmp_path)}) == tmp_path.resolve()
    assert data_home({DATA_HOME_ENV: ""}) == data_home({})


def test_a_preset_names_the_same_files_from_any_working_directory(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv(DATA_HOME_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    hk = scenario_settings(compose_config(["scenario=hk_tst_2019"])).scenario
    assert hk.obs == str(shared_data / "hk_tst_2019" / "COM3_190428_124409.obs")  # type: ignore[attr-defined]
    assert hk.nav_bds == str(shared_data / "hk_tst_2019" / "hksc1180.19b")  # type: ignore[attr-defined]
    drive = scenario_settings(compose_config(["scenario=morgantown2"])).scenario
    assert drive.trajectory.replay.path == str(shared_data / "wvu_drives" / "drive_2.xyz")  # type: ignore[attr-defined]
    for name in ("hk_tst_2019", "nagoya_static", "replay", "morgantown3"):
        check_scenario(scenario_settings(compose_config([f"scenario={name}"])))  # every file found


def test_cli_runs_a_preset_from_another_working_directory_and_data_home(tmp_path: Path) -> None:
    """The issue's command from a folder without ``../shared`` (it used to fail after the progress bar started),
    with ``SIMBENCH_DATA`` naming a data home elsewhere that holds a 20-epoch cut of the Nagoya log."""
    home, cwd, out = tmp_path / "elsewhere", tmp_path / "cwd", tmp_path / "run"
    (home / "nagoya_static").mkdir(parents=True)
    cwd.mkdir()
    default = data_home({}) / "nagoya_static"
    cut(default / "rover.obs", home / "nagoya_static" / "rover.obs", 20)
    for name in ("base.nav", "rover_position.txt"):
        (home / "nagoya_static" / name).symlink_to(default / name)
    proc = _cli(cwd, "scenario=nagoya_static", "estimator=[wls_spp]", f"results_dir={out}", "progress=false", home=home)
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = pd.read_parquet(out / "summary.parquet")
    assert summary[["scenario", "estimator", "status"]].values.tolist() == [["nagoya_static", "wls_spp", "ok"]]
    # the cut in the data home, not the 300 epochs of the log beside the repository; every epoch solved
    assert summary[["n_epochs", "n_solved"]].values.tolist() == [[20, 20]]


def test_cli_missing_data_home_is_one_line_before_any_job(tmp_path: Path) -> None:
    """No progress bar, no job folder: the one line names the setting, the path tried and SIMBENCH_DATA."""
    out, empty = tmp_path / "run", tmp_path / "no_data"
    proc = _cli(tmp_path, "scenario=hk_tst_2019", "estimator=[wls_spp]", f"results_dir={out}", home=empty)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"error: scenario.obs '{empty}/hk_tst_2019/COM3_190428_124409.obs': file does not exist -- the named logs "
        f"are read from the data home {empty} ({DATA_HOME_ENV}={empty}); put hk_tst_2019/ there, or set "
        f"{DATA_HOME_ENV} to the folder that holds hk_tst_2019/"
    ]
    assert not out.exists()


def test_a_simulated_preset_checks_its_files_before_generating(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(DATA_HOME_ENV, str(tmp_path))
    msg = one_line_error(simbench.simulate, "morgantown1")
    assert msg.startswith(f"scenario.trajectory.replay.path '{tmp_path}/wvu_drives/drive_1.xyz': file does not exist")
    assert f"set {DATA_HOME_ENV} to the folder that holds wvu_drives/" in msg


def test_a_path_on_the_command_line_starts_at_the_working_directory(
    shared_data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    cut(shared_data / "nagoya_static" / "rover.obs", here / "rover5.obs", 5)
    nav = str(shared_data / "nagoya_static" / "base.nav")
    overrides = ["scenario=rinex", "scenario.obs=rover5.obs", f"scenario.nav={nav}", f"scenario.truth='{NG_LLH}'"]
    monkeypatch.chdir(here)
    check_scenario(scenario_settings(compose_config(overrides)))
    assert simbench.scenario("rinex", **{k: v for k, v in (o.split("=", 1) for o in overrides[1:])}).meta["epochs"] == 5
    monkeypatch.chdir(there)
    msg = one_line_error(check_scenario, scenario_settings(compose_config(overrides)))
    assert msg.startswith(
        f"scenario.obs 'rover5.obs' (tried {there}/rover5.obs): file does not exist -- check the path"
    )
    assert f"a relative path starts at the working directory {there}" in msg
    # a file given by an interpolation into the data home is found from anywhere
    home_obs = "scenario.obs=${simbench_data:nagoya_static/rover.obs}"
    check_scenario(scenario_settings(compose_config(["scenario=rinex", home_obs, *overrides[2:]])))
    assert one_line_error(require_file, "scenario.nav", str(there)).startswith(
        f"scenario.nav '{there}': is a folder, not a file"
    )
