"""Sweeps: store layout, resume after a kill, failure isolation, report rebuild."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from conftest import run_simbench

from simbench.analysis.claims import CLAIM_COLUMNS
from simbench.contract import read_parquet_metadata

ROOT = Path(__file__).resolve().parent.parent
SHORT = ["scenario.duration_s=40", "progress=false", "estimator=[ekf_ppp]"]


def test_multirun_writes_store_claims_and_report(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    proc = run_simbench("-m", "seed=0,1", "receiver=low,high", f"results_dir={out}", "sweep_name=mini", *SHORT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = pd.read_parquet(out / "summary.parquet")
    assert len(summary) == 4 and (summary["status"] == "ok").all()
    assert set(summary["receiver"]) == {"low", "high"} and set(summary["sweep"]) == {"mini"}
    # one cached scenario per (receiver, seed), shared by the estimators of that job
    assert len(list((out / "cache").iterdir())) == 4
    assert summary["scenario_key"].nunique() == 4
    claims = pd.read_csv(out / "claims.csv")
    assert list(claims.columns) == CLAIM_COLUMNS
    assert (claims["holds"] == "not measured").all()  # none of the papers' sweeps ran here
    html = (out / "report" / "index.html").read_text()
    # none measured: no claims section (claims.csv lists them)
    assert "Statistics over seeds" in html and "Published claims" not in html
    # the terminal ends with each group's leaderboard, with the page's numbers (leaderboard.csv), not an
    # average over the groups
    board = pd.read_csv(out / "report" / "leaderboard.csv", dtype=str)
    assert sorted(board["group"]) == ["urban, high receiver (sweep mini)", "urban, low receiver (sweep mini)"]
    for _, row in board.iterrows():
        line = next(ln for ln in proc.stdout.split(row["group"] + "\n")[1].splitlines() if ln.startswith("ekf_ppp"))
        assert row["horizontal median [m]"] in line.split() and row["horizontal RMSE [m]"] in line.split()
    assert "git_sha" in str(read_parquet_metadata(out / "summary.parquet"))


@pytest.mark.slow
def test_killed_sweep_resumes_without_recomputing(tmp_path: Path) -> None:
    out = tmp_path / "killed"
    args = [sys.executable, "-m", "simbench", "-m", "seed=0,1,2,3,4,5", f"results_dir={out}", *SHORT]
    proc = subprocess.Popen(
        args, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and len(list(out.glob("jobs/*/*.summary.parquet"))) < 2:
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    finished = {p: p.stat().st_mtime_ns for p in out.glob("jobs/*/*.summary.parquet")}
    assert 2 <= len(finished) < 6, "the kill should land mid-sweep"
    rerun = run_simbench("-m", "seed=0,1,2,3,4,5", f"results_dir={out}", *SHORT)
    assert rerun.returncode == 0, rerun.stderr[-2000:]
    summary = pd.read_parquet(out / "summary.parquet")
    assert sorted(summary["seed"]) == [0, 1, 2, 3, 4, 5]
    assert (summary["status"] == "ok").all()
    for path, mtime in finished.items():
        assert path.stat().st_mtime_ns == mtime, f"{path.name} was recomputed"
    assert not list(out.glob("**/*.tmp*")), "no half-written files remain"


def test_failing_job_leaves_a_status_row_and_the_report_builds(tmp_path: Path) -> None:
    out = tmp_path / "failing"
    # a mask no satellite clears: the estimator raises inside its run, the sweep goes on;
    # ionosphere-free processing of single-frequency data is an unmet need: skipped, not failed
    proc = run_simbench(
        "-m", "estimator.ekf_ppp.elevation_mask_deg=10,89", "gnss_model=dissertation", f"results_dir={out}", *SHORT
    )
    assert proc.returncode == 1, proc.stderr[-2000:]  # a failed row: exit 1, after every job ran
    assert "1 of 2 rows failed: see " in proc.stderr
    summary = pd.read_parquet(out / "summary.parquet").set_index("status")
    assert set(summary.index) == {"ok", "failed"}
    assert "mask" in summary.loc["failed", "message"]
    assert summary.loc["ok", "variant"] == "elevation_mask_deg=10.0"
    assert json.loads(summary.loc["ok", "overrides"]) == {"elevation_mask_deg": 10.0}
    assert "Jobs not ok" in (out / "report" / "index.html").read_text()


def test_report_rebuilds_from_job_files(tmp_path: Path) -> None:
    out = tmp_path / "rebuild"
    assert run_simbench(f"results_dir={out}", *SHORT).returncode == 0
    (out / "summary.parquet").unlink()
    (out / "report" / "index.html").unlink()
    proc = subprocess.run(
        [sys.executable, "-m", "simbench", "report", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert len(pd.read_parquet(out / "summary.parquet")) == 1
    assert (out / "report" / "index.html").stat().st_size > 1000
    bad = subprocess.run(
        [sys.executable, "-m", "simbench", "report", str(tmp_path / "nothing")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2 and bad.stderr.strip().startswith("error: run_dir")


def test_a_result_from_before_the_overrides_column_is_recomputed(tmp_path: Path) -> None:
    from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS
    from simbench.runs.store import is_finished, write_result

    stem = tmp_path / "jobs" / "0123456789abcdef" / "l2-fedcba9876543210"
    row = pd.DataFrame([{c: None for c in SUMMARY_COLUMNS}]).assign(status="ok", overrides="{}", seed=0)
    epochs = pd.DataFrame(columns=list(EPOCH_COLUMNS))
    write_result(stem, row, epochs, {}, {})
    assert is_finished(stem)
    write_result(stem, row.drop(columns=["overrides"]), epochs, {}, {})
    assert not is_finished(stem)
    write_result(stem, row.assign(status="failed"), epochs, {}, {})
    assert not is_finished(stem)
