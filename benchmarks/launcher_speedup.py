"""Throughput of the joblib launcher (2 workers) against the serial launcher on equal jobs.

Target (sweeps issue): at least 1.6x the serial throughput. Runs the same
sweep of equal jobs twice into fresh directories and prints both wall times
and their ratio. The report callback is switched off (override
``~hydra.callbacks.finalize``): building the report is one serial step after
the jobs, the same for every launcher, and not part of the launcher's
throughput. Both cores must be otherwise idle.
Run: ``python benchmarks/launcher_speedup.py [--jobs 8]``.
Needs the ``parallel`` extra (hydra-joblib-launcher).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET = 1.6


def sweep(out: Path, jobs: int, duration: float, estimators: str, extra: list[str]) -> float:
    seeds = ",".join(str(s) for s in range(jobs))
    cmd = [
        sys.executable,
        "-m",
        "simbench",
        "-m",
        f"seed={seeds}",
        f"scenario.duration_s={duration}",
        f"estimator=[{estimators}]",
        "progress=false",
        f"results_dir={out}",
        "~hydra.callbacks.finalize",
        *extra,
    ]
    start = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, env={"OMP_NUM_THREADS": "1", **_env()})
    return time.perf_counter() - start


def _env() -> dict[str, str]:
    import os

    return dict(os.environ)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--jobs", type=int, default=8)
    parser.add_argument("--duration", type=float, default=1200.0, help="scenario length per job [s]")
    parser.add_argument(
        "--estimators",
        default="ekf_ppp,l2,dcs,mm",
        help="estimators per job; sweep jobs are seconds long, worker start-up is ~2 s",
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        serial = sweep(Path(tmp) / "serial", args.jobs, args.duration, args.estimators, [])
        parallel = sweep(
            Path(tmp) / "joblib",
            args.jobs,
            args.duration,
            args.estimators,
            ["hydra/launcher=joblib", "hydra.launcher.n_jobs=2"],
        )
    ratio = serial / parallel
    print(f"{args.jobs} equal jobs ({args.duration:.0f} s urban scenario; estimators {args.estimators})")
    print(f"serial launcher: {serial:.1f} s; joblib, 2 workers: {parallel:.1f} s")
    print(f"throughput ratio joblib/serial: {ratio:.2f} (target >= {TARGET}: {'met' if ratio >= TARGET else 'MISSED'})")


if __name__ == "__main__":
    main()
