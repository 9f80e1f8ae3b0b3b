"""Solutions out: every ok result as an RTKLIB ``.pos`` and a TUM file in the run folder, read back
by ``simbench score`` to the run's own scores, by RTKLIB's reader and as evo's TUM layout."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import simbench
from simbench.contract import Scenario
from simbench.core.constants import SECONDS_PER_WEEK
from simbench.core.frames import dcm_ned_to_ecef, ecef_from_geodetic
from simbench.core.gpstime import gps_to_datetime64
from simbench.data.export.solution import rtklib_pos_text, tum_text
from simbench.data.rtklib_pos import parse_rtklib_pos
from simbench.runs.foreign import score_solution_file
from simbench.runs.solutions import SOLUTIONS_DIR, file_name, write_solutions

ESTIMATORS = ["l2", "ekf_ppp"]  #: one without a covariance, one with
#: The scores a read-back must reproduce [m], and the tolerance [m].
SCORES = ["horizontal_median", "horizontal_p95", "error_3d_median", "horizontal_median_ref", "error_3d_p95_ref"]
MM = 1e-3


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("solutions") / "run"
    simbench.run(estimators=ESTIMATORS, seeds=0, overrides={"scenario.duration_s": 30}, results_dir=out, progress=False)
    return out


def _folder(run_dir: Path) -> Path:
    return run_dir / SOLUTIONS_DIR / "urban_low" / "0"


def test_every_ok_result_has_a_pos_and_a_tum_file(run_dir: Path) -> None:
    summary = pd.read_parquet(run_dir / "summary.parquet")
    assert set(summary.loc[summary["status"] == "ok", "estimator"]) == set(ESTIMATORS)
    names = sorted(p.name for p in _folder(run_dir).iterdir())
    assert names == sorted(f"{n}.{s}" for n in [*ESTIMATORS, "truth"] for s in ("pos", "tum"))


def test_simbench_score_reads_the_pos_back_to_the_runs_scores(run_dir: Path) -> None:
    summary = pd.read_parquet(run_dir / "summary.parquet")
    key = str(summary["scenario_key"].iloc[0])
    for name in ESTIMATORS:
        back = score_solution_file(run_dir, key, f"back_{name}", _folder(run_dir) / f"{name}.pos").iloc[0]
        own = summary[summary["estimator"] == name].iloc[0]
        assert back["status"] == "ok" and back["n_solved"] == own["n_solved"] == 30
        for column in SCORES:
            assert back[column] == pytest.approx(own[column], abs=MM), (name, column)


def test_the_covariance_becomes_rtklibs_standard_deviations(run_dir: Path) -> None:
    lines = (_folder(run_dir) / "ekf_ppp.pos").read_text().splitlines()
    assert "sdn(m)" in lines[1] and "sdun(m)" in lines[1]
    assert "sdn(m)" not in (_folder(run_dir) / "l2.pos").read_text()  # l2 gives no covariance: no columns
    epochs = pd.read_parquet(run_dir / "epochs.parquet").query("estimator == 'ekf_ppp'").sort_values("epoch")
    sd = np.array([ln.split()[7:10] for ln in lines[2:]], float)  # sdn, sde, sdu
    row = epochs.iloc[0]
    cov = np.array([[row[f"cov_{a}{b}" if a <= b else f"cov_{b}{a}"] for b in "xyz"] for a in "xyz"])
    lat, lon = np.radians(np.array(lines[2].split()[2:4], float))
    ned = dcm_ned_to_ecef(lat, lon)
    variances = np.diag(ned.T @ cov @ ned)  # north, east, down
    assert sd[0] == pytest.approx(np.sqrt(variances[[0, 1, 2]]), abs=1e-4)


def test_rtklibs_reader_takes_the_file(run_dir: Path, tmp_path: Path) -> None:
    if shutil.which("pos2kml") is None:
        pytest.skip("RTKLIB's pos2kml is not on PATH (apt install rtklib; .ci/run installs it)")
    gpx = tmp_path / "ekf_ppp.gpx"
    # -a: ellipsoidal heights, -tg: GPS time stamps
    subprocess.run(["pos2kml", "-gpx", "-a", "-tg", "-o", str(gpx), str(_folder(run_dir) / "ekf_ppp.pos")], check=True)
    text = gpx.read_text()
    points = re.findall(r'<wpt lat="([-\d.]+)" lon="([-\d.]+)">\s*<ele>([-\d.]+)</ele>\s*<time>([^<]+)Z</time>', text)
    assert len(points) == 30
    lat, lon, h = (np.array([p[i] for p in points], float) for i in range(3))
    epochs = pd.read_parquet(run_dir / "epochs.parquet").query("estimator == 'ekf_ppp'").sort_values("epoch")
    xyz = ecef_from_geodetic(np.radians(lat), np.radians(lon), h)
    assert np.abs(xyz - epochs[["x", "y", "z"]].to_numpy()).max() < MM  # RTKLIB prints 9 decimals too
    scenario = Scenario.load(next((run_dir / "cache").iterdir()))
    start = scenario.nav.gps_week * SECONDS_PER_WEEK + scenario.nav.start_sow_s
    expected = gps_to_datetime64(start + epochs["t"].to_numpy())
    assert (np.array([p[3] for p in points], dtype="datetime64[ms]") == expected.astype("datetime64[ms]")).all()


def test_tum_files_are_the_local_frame_of_the_epoch_table(run_dir: Path) -> None:
    tum = np.loadtxt(_folder(run_dir) / "l2.tum", comments="#")
    epochs = pd.read_parquet(run_dir / "epochs.parquet").query("estimator == 'l2'").sort_values("epoch")
    assert tum.shape == (30, 8) and (tum[:, 4:] == [0, 0, 0, 1]).all()
    assert np.abs(tum[:, 1:4] - epochs[["east", "north", "up"]].to_numpy()).max() < MM
    truth = np.loadtxt(_folder(run_dir) / "truth.tum", comments="#")
    assert (truth[0, 1:4] == 0).all() and np.allclose(np.diff(truth[:, 0]), 1.0)  # origin: first truth point
    assert np.allclose(truth[:, 0], tum[:, 0])  # the same GPS time stamps


def test_a_finalize_rewrites_what_changed_and_removes_what_is_gone(run_dir: Path) -> None:
    summary = pd.read_parquet(run_dir / "summary.parquet")
    epochs = pd.read_parquet(run_dir / "epochs.parquet")
    files = {name: _folder(run_dir) / f"{name}.pos" for name in ESTIMATORS}

    def inodes() -> dict[str, int]:  # a file written again is a new file renamed over the old one
        return {name: path.stat().st_ino for name, path in files.items()}

    first = inodes()
    kept = write_solutions(run_dir, summary, epochs)
    assert inodes() == first and len(kept) == 6  # nothing changed: nothing written
    moved = epochs.assign(x=epochs["x"].where(epochs["estimator"] != "l2", epochs["x"] + 1.0))
    write_solutions(run_dir, summary, moved)
    assert inodes()["ekf_ppp"] == first["ekf_ppp"] and inodes()["l2"] != first["l2"]
    assert parse_rtklib_pos(files["l2"].read_text())["x"].iloc[0] == pytest.approx(
        moved.query("estimator == 'l2'").sort_values("epoch")["x"].iloc[0], abs=MM
    )
    write_solutions(run_dir, summary[summary["estimator"] != "l2"], epochs)
    assert not files["l2"].exists() and files["ekf_ppp"].is_file()
    write_solutions(run_dir, summary, epochs)  # the module's other tests read it as the run wrote it
    assert files["l2"].is_file()


def test_pos_text_round_trips_through_the_reader_to_a_tenth_of_a_millimetre() -> None:
    rng = np.random.default_rng(1000)
    lat, lon = np.radians(rng.uniform(-89, 89, 50)), np.radians(rng.uniform(-180, 180, 50))
    xyz = ecef_from_geodetic(lat, lon, rng.uniform(-100, 20_000, 50))
    t = 2032 * SECONDS_PER_WEEK + rng.uniform(0, SECONDS_PER_WEEK, 50).round(3)
    back = parse_rtklib_pos(rtklib_pos_text(t, xyz, np.full(50, 9), comments=["x"]))
    assert np.abs(back[["x", "y", "z"]].to_numpy() - xyz).max() < 2e-4
    assert np.abs(back["t_gps"].to_numpy() - t).max() < 1e-6 and (back["ns"] == 9).all() and (back["q"] == 5).all()
    # a north-east correlation keeps its sign, RTKLIB's sign(c) sqrt(|c|)
    ned = dcm_ned_to_ecef(lat[0], lon[0])
    cov_ne = np.array([[4.0, -1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 9.0]])  # north, east, down
    line = rtklib_pos_text(t[:1], xyz[:1], np.array([9]), (ned @ cov_ne @ ned.T)[None]).splitlines()[-1]
    assert np.array(line.split()[7:13], float) == pytest.approx([2.0, 1.0, 3.0, -1.0, 0.0, 0.0], abs=1e-4)
    assert tum_text(t[:1], np.zeros((1, 3)), ["c"]).splitlines()[1].endswith(" 0.0000 0.0000 0.0000 0 0 0 1")


def test_variant_names_become_file_names_a_shell_does_not_glob() -> None:
    assert file_name("dcs[prior_scale=10.0]") == "dcs__prior_scale=10.0"
    assert file_name("dcs[a=x/y,b=…]") == "dcs__a=x_y,b=_"
