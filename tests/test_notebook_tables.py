"""``python -m simbench tables RUN_DIR``: the lab notebook's tables printed from a run folder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from simbench.analysis.claims import claims_table
from simbench.cli import tables
from simbench.runs.runner import EPOCH_COLUMNS, SUMMARY_COLUMNS
from simbench.runs.studies import STUDY_TIMES


def _row(**values: object) -> dict[str, object]:
    row: dict[str, object] = {c: np.nan for c in SUMMARY_COLUMNS}
    row.update(overrides="{}", variant="", status="ok", availability=1.0, total_s=2.0, **values)
    return row


@pytest.fixture()
def run_dir(tmp_path: Path) -> Path:
    rows = [
        _row(
            sweep=sweep,
            scenario=f"morgantown{drive}",
            receiver=rx,
            seed=seed,
            estimator=est,
            horizontal_median_ref=1.0 + seed,
        )
        for sweep, names in (("ch5_bce", ("l2", "dcs")), ("ch7_ice", ("ice",)), ("ch6_bce_ad", ("bce_ad",)))
        for est in names
        for rx in ("high", "low")
        for drive in (1, 2)
        for seed in (0, 1)
    ]
    summary = pd.DataFrame(rows)
    summary.to_parquet(tmp_path / "summary.parquet")
    claims_table(summary, pd.DataFrame(columns=list(EPOCH_COLUMNS)), {}).to_csv(tmp_path / "claims.csv", index=False)
    pd.DataFrame(
        [
            {
                "study": "ch5_bce",
                "world": "morgantown1",
                "started": "",
                "wall_s": 138.2,
                "peak_rss_mb": 1534.4,
                "exit_code": 0,
            },
            {
                "study": "ch4_convergence",
                "world": "",
                "started": "",
                "wall_s": 20.0,
                "peak_rss_mb": 612.0,
                "exit_code": 0,
            },
        ]
    ).to_csv(tmp_path / STUDY_TIMES, index=False)
    return tmp_path


def test_tables_prints_claims_drives_and_times(run_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert tables.main([str(run_dir)]) == 0
    out = capsys.readouterr().out
    assert "## Claims per world" in out and "| morgantown1 " in out
    assert "### Published: Ch.5 / Ch.7 tables and the ICE paper (sweeps ch5_bce, ch7_ice)" in out
    assert "### Published: Ch.6 Table 6.3.1 (sweeps ch6_bce_ad)" in out
    assert "1.50 (2.57)" in out  # l2, low, drive 1: mean of the seeds' medians (published 2.57)
    assert out.index("| low ") < out.index("| high ")  # low receiver first, as the notebook
    assert "(own scenario)" in out and "138" in out


def test_tables_only_one(run_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert tables.main([str(run_dir), "--only", "times"]) == 0
    out = capsys.readouterr().out
    assert "Wall time per study" in out and "Claims per world" not in out
    assert "Peak memory per study and world [MB]" in out and "largest 1534 MB" in out
    memory = out[out.index("Peak memory") :]
    assert "| ch4_convergence |              612 |" in memory and "|          1534 |" in memory


def test_tables_of_a_folder_without_results_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert tables.main([str(tmp_path)]) == 2
    assert "error: run_dir:" in capsys.readouterr().err
