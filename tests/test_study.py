"""``simbench.run``: the Python run API gives the command line's rows and shares its cache and store."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from conftest import one_line_error, simbench_summary

import simbench
from simbench.errors import SimbenchError
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS

#: Wall-time columns: they differ between two runs of the same config.
TIMING = ["total_s", "time_per_obs_s", "update_median_s", "update_p95_s"]
CONFIG = {"scenario.duration_s": 60}
KEY = ["seed", "estimator"]


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("cli") / "run"
    sweep = ("-m", "scenario=urban", "receiver=low", "estimator=[l2,dcs]", "seed=0,1", "scenario.duration_s=60")
    simbench_summary(out, *sweep)
    return out


def _deterministic(summary: pd.DataFrame) -> pd.DataFrame:
    return summary.drop(columns=TIMING).sort_values(KEY).reset_index(drop=True)


def test_run_returns_the_cli_rows(cli_run: Path, tmp_path: Path) -> None:
    result = simbench.run(
        scenario="urban",
        receiver="low",
        estimators=["l2", "dcs"],
        seeds=range(2),
        overrides=CONFIG,
        results_dir=tmp_path / "nb",
        progress=False,
    )
    cli = pd.read_parquet(cli_run / "summary.parquet")
    assert list(result.summary.columns) == list(SUMMARY_COLUMNS)
    assert len(result.summary) == 4 and (result.summary["status"] == "ok").all()
    pd.testing.assert_frame_equal(_deterministic(result.summary), _deterministic(cli))
    assert list(result.epochs.columns) == list(EPOCH_COLUMNS)
    assert result.epochs.groupby(KEY).size().tolist() == [60] * 4
    assert (result.report / "index.html").is_file() and result.report.parent == tmp_path / "nb"
    # a 60 s urban run measures none of the published claims; the table still lists each of them
    assert len(result.claims) > 0 and (result.claims["holds"] == "not measured").all()


def test_run_into_a_sweep_directory_reuses_its_results(cli_run: Path) -> None:
    files = sorted(cli_run.glob("jobs/*/*.summary.parquet"))
    stamps = [p.stat().st_mtime_ns for p in files]
    result = simbench.run(estimators=["l2", "dcs"], seeds=[0, 1], overrides=CONFIG, results_dir=cli_run, progress=False)
    assert [p.stat().st_mtime_ns for p in sorted(cli_run.glob("jobs/*/*.summary.parquet"))] == stamps
    stored = pd.read_parquet(cli_run / "summary.parquet").sort_values(KEY).reset_index(drop=True)
    # nothing recomputed: even the wall times are the stored ones
    pd.testing.assert_frame_equal(result.summary.sort_values(KEY).reset_index(drop=True), stored)


def test_run_errors_are_one_line(tmp_path: Path) -> None:
    assert "unknown scenario 'mars'" in one_line_error(simbench.run, scenario="mars", results_dir=tmp_path)
    assert "seeds" in one_line_error(simbench.run, seeds=[], results_dir=tmp_path)
    with pytest.raises(SimbenchError, match="estimator"):
        simbench.run(estimators=["nosuch"], results_dir=tmp_path, progress=False)
