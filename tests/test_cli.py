"""``python -m simbench`` end to end, and its one-line errors."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd

from simbench.contract import read_parquet_metadata
from simbench.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS

ROOT = Path(__file__).resolve().parent.parent


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "simbench", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=600)


def test_cli_writes_store_and_report(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = _run("scenario.duration_s=120", f"results_dir={out}", "progress=false", "seed=2")
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = pd.read_parquet(out / "summary.parquet")
    epochs = pd.read_parquet(out / "epochs.parquet")
    assert list(summary.columns) == list(SUMMARY_COLUMNS)
    assert list(epochs.columns) == list(EPOCH_COLUMNS)
    assert (summary["status"] == "ok").all()
    assert set(summary["estimator"]) == set(epochs["estimator"])
    assert (summary["seed"] == 2).all() and (summary["scenario"] == "urban").all()
    meta = read_parquet_metadata(out / "summary.parquet")
    assert meta["simbench.config"]["scenario"]["duration_s"] == 120
    assert len(meta["simbench.git_sha"]) >= 7 and "numpy" in meta["simbench.versions"]
    assert (out / "report" / "ecdf_horizontal_urban_low.png").stat().st_size > 10_000
    assert "horizontal_median" in (out / "report" / "README.md").read_text()
    assert "ekf_ppp" in proc.stdout


def test_cli_overrides_scenario_and_receiver(tmp_path: Path) -> None:
    out = tmp_path / "flight"
    proc = _run("scenario=flight", "receiver=high", "seed=3", "scenario.duration_s=90", f"results_dir={out}",
                "progress=false")
    assert proc.returncode == 0, proc.stderr[-2000:]
    summary = pd.read_parquet(out / "summary.parquet")
    assert (summary["scenario"] == "flight").all() and (summary["receiver"] == "high").all()


def test_cli_unknown_scenario_is_one_line() -> None:
    proc = _run("scenario=mars")
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0
    assert "unknown scenario 'mars'" in proc.stderr and "urban" in proc.stderr


def test_cli_negative_duration_is_one_line(tmp_path: Path) -> None:
    proc = _run("scenario.duration_s=-3", f"results_dir={tmp_path}")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines()[-1].startswith("error: scenario.duration_s")
    assert "Traceback" not in proc.stderr
