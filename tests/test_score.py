"""``python -m simbench score``: a foreign solution file becomes one more result row of a run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pymap3d
import pytest
from conftest import one_line_error

import simbench
from simbench.cli.score import main
from simbench.contract import Scenario, read_parquet_metadata
from simbench.core.constants import SECONDS_PER_WEEK
from simbench.runs.foreign import score_solution_file
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS

EAST_M = 3.0  #: the solutions below are the truth moved this far east [m]
CLOCK_S = 0.002  #: and time-tagged this late, like a receiver clock offset [s]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("score") / "run"
    simbench.run(estimators=["l2"], seeds=0, overrides={"scenario.duration_s": 30}, results_dir=out, progress=False)
    return out


def _key(run_dir: Path) -> str:
    return str(pd.read_parquet(run_dir / "summary.parquet")["scenario_key"].iloc[0])


def _shifted_truth(run_dir: Path) -> tuple[pd.DataFrame, Scenario]:
    """Every other truth epoch, moved EAST_M east, with GPS week, seconds of week and geodetic coordinates."""
    scenario = Scenario.load(run_dir / "cache" / _key(run_dir))
    truth = scenario.truth.iloc[::2]
    lat, lon, h = pymap3d.ecef2geodetic(truth["x"].to_numpy(), truth["y"].to_numpy(), truth["z"].to_numpy())
    dx, dy, dz = pymap3d.enu2uvw(EAST_M, 0.0, 0.0, lat, lon)
    xyz = truth[["x", "y", "z"]].to_numpy() + np.stack([dx, dy, dz], axis=1)
    lat, lon, h = pymap3d.ecef2geodetic(xyz[:, 0], xyz[:, 1], xyz[:, 2])
    tow = scenario.nav.start_sow_s + truth["t"].to_numpy() + CLOCK_S
    return pd.DataFrame(
        {
            "week": scenario.nav.gps_week,
            "tow": tow,
            "t": scenario.nav.gps_week * SECONDS_PER_WEEK + tow,
            "x": xyz[:, 0],
            "y": xyz[:, 1],
            "z": xyz[:, 2],
            "lat": lat,
            "lon": lon,
            "h": h,
        }
    ), scenario


def _check_row(row: pd.Series, n_epochs: int) -> None:
    assert row["status"] == "ok" and row["n_epochs"] == n_epochs and row["n_solved"] == n_epochs // 2
    assert row["availability"] == pytest.approx(0.5)
    assert row["horizontal_median"] == pytest.approx(EAST_M, abs=1e-3)
    assert row["horizontal_max"] == pytest.approx(EAST_M, abs=1e-3)
    assert row["horizontal_median_ref"] == pytest.approx(EAST_M, abs=1e-3)  # half the epochs reach the median
    assert row["horizontal_p95_ref"] == np.inf  # the missed epochs count as infinite errors
    assert np.isnan(row["total_s"]) and not row["uses_labels"]


def test_csv_layouts_and_rtklib_pos_score_alike(run_dir: Path, tmp_path: Path) -> None:
    sol, scenario = _shifted_truth(run_dir)
    sol[["t", "x", "y", "z"]].to_csv(tmp_path / "xyz.csv", index=False)
    sol[["week", "tow", "lat", "lon", "h"]].to_csv(tmp_path / "llh.csv", index=False, float_format="%.10f")
    pos = [
        "% program   : RTKLIB ver.2.4.3 b34",
        "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)",
    ]
    pos += [
        f"{w} {t:10.3f} {a:14.9f} {o:14.9f} {h:10.4f} 5 {8:3d} 1.0 1.0 1.0"
        for w, t, a, o, h in sol[["week", "tow", "lat", "lon", "h"]].itertuples(index=False)
    ]
    (tmp_path / "sol.pos").write_text("\n".join(pos) + "\n")
    for name, file in (("csv_xyz", "xyz.csv"), ("csv_llh", "llh.csv"), ("rtklib", "sol.pos")):
        row = score_solution_file(run_dir, _key(run_dir), name, tmp_path / file)
        assert list(row.columns) == list(SUMMARY_COLUMNS)
        _check_row(row.iloc[0], scenario.n_epochs)
        assert row.iloc[0][["scenario", "receiver", "seed", "estimator"]].tolist() == ["urban", "low", 0, name]
    stem = next((run_dir / "jobs" / _key(run_dir)).glob("rtklib-*.epochs.parquet"))
    epochs = pd.read_parquet(stem)
    assert list(epochs.columns) == list(EPOCH_COLUMNS) and len(epochs) == scenario.n_epochs // 2
    assert (epochs["epoch"] % 2 == 0).all()  # each solution paired with its own epoch despite the 2 ms tag
    meta = read_parquet_metadata(stem.with_name(stem.name.replace("epochs", "summary")))
    assert meta["simbench.config"]["scored_solution"]["format"] == "rtklib_pos"
    assert "does not exist" in one_line_error(score_solution_file, run_dir, _key(run_dir), "x", tmp_path / "none")


def test_command_line_adds_the_row_to_the_report_once(
    run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sol, scenario = _shifted_truth(run_dir)
    sol[["t", "x", "y", "z"]].to_csv(tmp_path / "a.csv", index=False)
    args = [str(run_dir), "--scenario-key", _key(run_dir), "--name", "colleague", "--solution", str(tmp_path / "a.csv")]
    score_solution_file(run_dir, _key(run_dir), "colleague", tmp_path / "a.csv")
    assert main(args) == 0  # scoring the same name again replaces the result
    assert len(list(run_dir.glob("jobs/*/colleague-*.summary.parquet"))) == 1
    summary = pd.read_parquet(run_dir / "summary.parquet")
    assert (summary["estimator"] == "colleague").sum() == 1 and (summary["estimator"] == "l2").sum() == 1
    _check_row(summary[summary["estimator"] == "colleague"].iloc[0], scenario.n_epochs)
    assert "colleague" in (run_dir / "report" / "README.md").read_text()
    # the rebuilt aggregate keeps the run's own config
    assert read_parquet_metadata(run_dir / "summary.parquet")["simbench.config"]["scenario"]["duration_s"] == 30
    capsys.readouterr()
    bad = tmp_path / "bad.csv"
    bad.write_text("time,lat\n1,2\n")
    for argv, expected in (
        ([*args[:2], "nope", *args[3:]], "no cached scenario 'nope'"),
        ([*args[:-1], str(bad)], "has 2 columns"),
        ([*args[:4], "l2", *args[5:]], "'l2' is the name of a registered estimator"),
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert expected in err and err.count("\n") == 1 and err.startswith("error: --")


def test_bad_values_and_no_matching_epoch(run_dir: Path, tmp_path: Path) -> None:
    sol, scenario = _shifted_truth(run_dir)
    text = tmp_path / "text.csv"
    text.write_text("t,x,y,z\n1,2,3,abc\n")
    assert "no numeric rows" in one_line_error(score_solution_file, run_dir, _key(run_dir), "x", text)
    assert "letters, digits" in one_line_error(score_solution_file, run_dir, _key(run_dir), "a-b", text)
    sol.assign(t=sol["t"] + 86400.0)[["t", "x", "y", "z"]].to_csv(tmp_path / "day.csv", index=False)
    row = score_solution_file(run_dir, _key(run_dir), "late", tmp_path / "day.csv").iloc[0]
    assert row["status"] == "failed" and row["n_solved"] == 0 and "no solution within 0.5 s" in row["message"]
