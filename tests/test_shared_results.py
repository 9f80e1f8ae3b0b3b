"""Runs that share results: a row computed by one study of a world is copied, not recomputed, by the next."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from simbench.runs.compose import compose_config
from simbench.runs.jobs import run_job
from simbench.runs.store import job_stems, provenance_of

BASE = ["scenario.duration_s=30", "progress=false", "estimator=[l2,wls_spp]"]


def _run(root: Path, *extra: str) -> pd.DataFrame:
    return run_job(compose_config([*BASE, f"results_dir={root}", *extra]))


@pytest.fixture(scope="module")
def first(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("shared") / "ch5_bce"
    assert (_run(root, "sweep_name=ch5_bce")["status"] == "ok").all()
    return root


def test_a_finished_row_of_another_run_is_copied_with_this_runs_tags(first: Path) -> None:
    second = first.parent / "ch5_sensitivity"
    rows = _run(second, "sweep_name=ch5_sensitivity", f"shared_results=['{first}']")
    mine, theirs = job_stems(second), job_stems(first)
    assert [s.name for s in mine] == [s.name for s in theirs] and len(mine) == 2
    for a, b in zip(mine, theirs):
        copied = pd.read_parquet(a.with_suffix(".summary.parquet"))
        original = pd.read_parquet(b.with_suffix(".summary.parquet"))
        assert copied["sweep"].tolist() == ["ch5_sensitivity"] and original["sweep"].tolist() == ["ch5_bce"]
        # the copy is the computed row, wall times included (a recomputation would differ in them)
        pd.testing.assert_frame_equal(copied.drop(columns="sweep"), original.drop(columns="sweep"))
        epochs = pd.read_parquet(a.with_suffix(".epochs.parquet"))
        assert len(epochs) == 30 and set(epochs["sweep"]) == {"ch5_sensitivity"}
        assert json.loads(a.with_suffix(".diagnostics.json").read_text()) == json.loads(
            b.with_suffix(".diagnostics.json").read_text()
        )
        assert provenance_of(a.with_suffix(".summary.parquet"))["simbench.adopted_from"] == str(b)
    assert rows["sweep"].tolist() == ["ch5_sensitivity"] * 2
    # the cached scenario comes along (the report draws the truth from it), as hard links
    (cache,) = (second / "cache").iterdir()
    table = next(p for p in cache.iterdir() if p.suffix == ".parquet")
    assert table.stat().st_ino == (first / "cache" / cache.name / table.name).stat().st_ino


def test_another_config_or_a_damaged_row_is_computed(first: Path) -> None:
    third = first.parent / "other_config"
    _run(third, f"shared_results=['{first}']", "estimator.l2.elevation_mask_deg=12")
    adopted = {
        s.name.split("-")[0]: "simbench.adopted_from" in provenance_of(s.with_suffix(".summary.parquet"))
        for s in job_stems(third)
    }
    assert adopted == {"l2": False, "wls_spp": True}
    damaged = first.parent / "damaged_source"
    _run(damaged)
    (wls,) = [s for s in job_stems(damaged) if s.name.startswith("wls_spp")]
    wls.with_suffix(".epochs.parquet").write_bytes(b"garbage")
    fourth = first.parent / "fourth"
    with pytest.warns(UserWarning, match="epochs.parquet"):
        _run(fourth, f"shared_results=['{damaged}']")
    provenance = {s.name.split("-")[0]: provenance_of(s.with_suffix(".summary.parquet")) for s in job_stems(fourth)}
    assert "simbench.adopted_from" in provenance["l2"] and "simbench.adopted_from" not in provenance["wls_spp"]
