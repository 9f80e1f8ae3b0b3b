"""Two sweeps started at once into one results directory against the same two one after the other.

Target (issue 15, thread discipline): on 2 cores the two concurrent sweeps
finish within 1.3x the time of running them one after the other. Before each
job limited its own BLAS/OpenMP threads (``blas_threads``,
:func:`simbench.runs.jobs.run_job`), two smoke sweeps started at once took more than
11 minutes for their first job each (a job takes about 15 s alone): every
process ran OpenBLAS's busy threads on both cores.

The sweeps are smoke-like (urban and flight, 90 s, every registered estimator)
and differ only in their seeds (0,1 and 2,3), so they share the directory's
cache and store without sharing work. The child processes get no
``OPENBLAS_NUM_THREADS``/``OMP_NUM_THREADS``/``MKL_NUM_THREADS``: the limit under
test is the jobs' own. Each mode writes into a fresh directory; the script
checks that every result row is there once and prints both wall times and
their ratio. The cores must be otherwise idle for a timing.
Run: ``python benchmarks/concurrent_sweeps.py`` (``--quick`` for a check that it works:
one 30 s open-sky scenario, ``l2`` only).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

TARGET = 1.3
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
#: Seeds of the two sweeps: distinct, so neither finds the other's results.
SEEDS = ("0,1", "2,3")
REPO = Path(__file__).resolve().parent.parent


def sweep_command(out: Path, name: str, seeds: str, quick: bool) -> list[str]:
    """The command line of one sweep into ``out``."""
    config = (
        ["scenario=open_sky", "scenario.duration_s=30", "estimator=[l2]"]
        if quick
        else ["scenario=urban,flight", "scenario.duration_s=90"]
    )
    return [
        sys.executable,
        "-m",
        "simbench",
        "-m",
        *config,
        f"seed={seeds}",
        f"sweep_name={name}",
        "progress=false",
        f"results_dir={out}",
    ]


def run_sweeps(out: Path, quick: bool, concurrent: bool) -> float:
    """Run both sweeps into ``out``, at once or one after the other; return the wall time [s]."""
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}
    commands = [sweep_command(out, f"sweep_{i}", seeds, quick) for i, seeds in enumerate(SEEDS)]
    start = time.perf_counter()
    if concurrent:
        procs = [
            subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            for cmd in commands
        ]
        errors = [p.communicate()[1] for p in procs]
        codes = [p.returncode for p in procs]
    else:
        done = [subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True) for cmd in commands]
        errors, codes = [d.stderr for d in done], [d.returncode for d in done]
    elapsed = time.perf_counter() - start
    for code, err in zip(codes, errors):
        if code:
            sys.exit(f"a sweep exited with {code}:\n{err[-2000:]}")
    return elapsed


def check_rows(out: Path) -> str:
    """Count the result rows of ``out`` by status; fail on a result stored twice."""
    rows = pd.concat([pd.read_parquet(p) for p in sorted(out.glob("jobs/*/*.summary.parquet"))], ignore_index=True)
    duplicated = int(rows.duplicated(["sweep", "scenario_key", "estimator", "overrides"]).sum())
    if duplicated or rows["seed"].nunique() != 4:
        sys.exit(f"{out}: {duplicated} duplicated rows, seeds {sorted(rows['seed'].unique())}")
    counts = rows["status"].value_counts()
    return f"{len(rows)} rows (" + ", ".join(f"{n} {status}" for status, n in counts.items()) + "), no duplicates"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="tiny sweeps, to check the script works")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        sequential = run_sweeps(Path(tmp) / "sequential", args.quick, concurrent=False)
        print(f"one after the other: {sequential:.1f} s; {check_rows(Path(tmp) / 'sequential')}")
        concurrent = run_sweeps(Path(tmp) / "concurrent", args.quick, concurrent=True)
        print(f"at once:             {concurrent:.1f} s; {check_rows(Path(tmp) / 'concurrent')}")
    ratio = concurrent / sequential
    print(
        f"ratio at once / one after the other: {ratio:.2f} (target <= {TARGET}: "
        f"{'met' if ratio <= TARGET else 'MISSED'}; {os.cpu_count()} cores)"
    )


if __name__ == "__main__":
    main()
