"""The cluster path: a sweep through Hydra's submitit launcher (``submitit_local``, the code path of
``submitit_slurm`` without a scheduler), killed mid-way and resumed.

Each job runs in its own process started by submitit; the jobs share the run directory's scenario
cache and result store. Marked slow (about a minute); CI runs it (``.ci/run`` selects no markers).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from conftest import REPO_ROOT

from simbench.contract import read_parquet_metadata

#: Two jobs of very different length, so the kill lands after the short one and before the long one.
SWEEP = [
    "-m",
    "hydra/launcher=submitit_local",
    "estimator=[l2]",
    "scenario.duration_s=30,240",
    "progress=false",
    "hydra.launcher.cpus_per_task=2",
    "hydra.launcher.timeout_min=20",
]


def _results(run_dir: Path) -> list[Path]:
    return sorted(run_dir.glob("jobs/*/l2-*.summary.parquet"))


def _group_gone(pgid: int, timeout_s: float = 20.0) -> bool:
    """Whether every process of the group has exited (killed processes linger until reaped)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.1)
    return False


@pytest.mark.slow
def test_submitit_sweep_resumes_after_a_kill(tmp_path: Path) -> None:
    run_dir = tmp_path / "sweep"
    command = [sys.executable, "-m", "simbench", *SWEEP, f"results_dir={run_dir}"]
    first = subprocess.Popen(
        command, cwd=REPO_ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    deadline = time.monotonic() + 300
    while not _results(run_dir) and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    os.killpg(first.pid, signal.SIGKILL)  # the launcher, submitit's job controllers and the job processes
    first.wait()
    done = _results(run_dir)
    assert len(done) == 1, "the kill should land between the two jobs' results"
    assert _group_gone(first.pid), "a job process survived the kill of the sweep's process group"
    stamp = done[0].stat().st_mtime_ns

    second = subprocess.run(command, cwd=REPO_ROOT, capture_output=True, text=True, timeout=600)
    assert second.returncode == 0, second.stderr[-2000:]
    summary = pd.read_parquet(run_dir / "summary.parquet")
    assert len(summary) == 2 and (summary["status"] == "ok").all(), summary[
        ["scenario_key", "estimator", "status", "message"]
    ].to_string()
    assert not summary.duplicated(["scenario_key", "estimator", "overrides"]).any()
    assert sorted(summary["n_epochs"]) == [30, 240]
    assert done[0].stat().st_mtime_ns == stamp  # the finished job was skipped, not recomputed
    assert len(list((run_dir / "cache").glob("[!.]*"))) == 2  # one cached scenario per job, shared by both runs
    # the jobs ran in submitit's processes (4 job folders: 2 per attempt) ...
    assert len([d for d in (run_dir / ".submitit").iterdir() if d.name.isdigit()]) == 4
    # ... each limiting BLAS to the CPUs the launcher reserved for it
    assert [read_parquet_metadata(p)["simbench.config"]["blas_threads"] for p in _results(run_dir)] == [2, 2]
