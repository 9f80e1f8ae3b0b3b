"""Command-line start-up: ``python -m simbench --help``, refused command lines and a valid run (issue 46).

Targets: ``--help`` <= 1.5 s, a refused command line <= 2 s (best of ``--repeat``, this machine).
Each command runs in a fresh interpreter, as a user types it; ``python -c pass`` is the floor
(the interpreter's own start), and the ratio to it shows what simbench adds. A misspelt name
(``scenario=urbn``, ``estimator=[l2,dsc]``) is refused from the config folder's names and the
entry points' before any estimator loads. A bad value (``scenario.duration_s=-5``,
``estimator.dcs.kernel_width=nan``) needs the composed, typed config: it is composed with the
schemas recorded at the last registration (:mod:`simbench.runs.schema_record`), so no estimator
or simulation is imported, except the class of an estimator node the record has not seen pass
(``estimator.dcs.kernel_width=-1``: ``DcsConfig``'s light module, :mod:`estimators.batch.configs`,
no solver). The first command line after a code edit imports everything once (the record is
rewritten); best of 3 shows the warm record. A valid run (10 s open sky, one per-epoch estimator,
its report) is timed whole, start-up included (no target).

    python benchmarks/cli_startup.py [--repeat 3] [--repo DIR] [--before DIR]

``--repo`` times another checkout, ``--before DIR`` one more (e.g. the main branch's) beside it, printing
both and the ratio after / before: the commands run in a checkout's folder with it first on ``PYTHONPATH``,
so ``python -m simbench`` is its code.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The example plug-in's folder in a checkout (installed editable; its code is the checkout's here too).
EXAMPLE = Path("examples") / "simbench-example-estimator"
#: (label, arguments after ``python``, target [s] or None, expected exit code)
CASES: list[tuple[str, list[str], float | None, int]] = [
    ("python -c pass (floor)", ["-c", "pass"], None, 0),
    ("--help", ["-m", "simbench", "--help"], 1.5, 0),
    ("refused: scenario=urbn", ["-m", "simbench", "scenario=urbn"], 2.0, 2),
    ("refused: estimator=[l2,dsc]", ["-m", "simbench", "estimator=[l2,dsc]"], 2.0, 2),
    ("refused: estimator.ekf_pp.x=1", ["-m", "simbench", "estimator.ekf_pp.x=1"], 2.0, 2),
    ("refused value: scenario.duration_s=-5", ["-m", "simbench", "scenario.duration_s=-5"], 2.0, 2),
    ("refused key: receiver.x=1", ["-m", "simbench", "receiver.x=1"], 2.0, 2),
    ("refused value: estimator.dcs.kernel_width=nan", ["-m", "simbench", "estimator.dcs.kernel_width=nan"], 2.0, 2),
    ("refused value: estimator.dcs.kernel_width=-1", ["-m", "simbench", "estimator.dcs.kernel_width=-1"], 2.0, 2),
    ("refused value: estimator.bce.truncation=0", ["-m", "simbench", "estimator.bce.truncation=0"], 2.0, 2),
    ("refused value: estimator.mm.outlier_weight=2", ["-m", "simbench", "estimator.mm.outlier_weight=2"], 2.0, 2),
    ("refused value: estimator.crt_lss.window=0", ["-m", "simbench", "estimator.crt_lss.window=0"], 2.0, 2),
    (
        "refused value: a log source's scenario.truth_max_gap_s=-1",
        ["-m", "simbench", "scenario=hk_tst_2019", "scenario.truth_max_gap_s=-1"],
        2.0,
        2,
    ),
    (
        "valid run: open_sky 10 s, wls_spp, report",
        [
            "-m",
            "simbench",
            "scenario=open_sky",
            "scenario.duration_s=10",
            "estimator=[wls_spp]",
            "progress=false",
            "results_dir=" + str(Path(tempfile.gettempdir()) / "simbench-cli-startup" / "${now:%H%M%S%f}"),
        ],
        None,
        0,
    ),
]


def best_time(args: list[str], code: int, repeat: int, repo: Path) -> float:
    """Best wall time of ``python <args>`` in ``repo`` over ``repeat`` runs [s]; checks the exit code."""
    best = float("inf")
    for _ in range(repeat):
        tic = time.perf_counter()
        path = os.pathsep.join([str(repo), str(repo / EXAMPLE), os.environ.get("PYTHONPATH", "")])
        env = {**os.environ, "PYTHONPATH": path}
        proc = subprocess.run([sys.executable, *args], cwd=repo, capture_output=True, text=True, env=env)
        best = min(best, time.perf_counter() - tic)
        if proc.returncode != code:
            raise SystemExit(f"{args}: exit {proc.returncode}, expected {code}: {proc.stderr[-500:]}")
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--repo", type=Path, default=ROOT, help="the checkout to time (default: this one)")
    parser.add_argument("--before", type=Path, help="another checkout to time too; prints before, after and the ratio")
    args = parser.parse_args()
    floor = None
    for label, argv, target, code in CASES:
        seconds = best_time(argv, code, args.repeat, args.repo)
        floor = seconds if floor is None else floor
        verdict = "" if target is None else f"  target <= {target:.1f} s: {'met' if seconds <= target else 'MISSED'}"
        if args.before is None:
            print(f"{label:48s} {seconds:6.2f} s  {seconds / floor:5.1f}x python's start{verdict}")
            continue
        before = best_time(argv, code, args.repeat, args.before)
        print(f"{label:48s} before {before:6.2f} s  after {seconds:6.2f} s  ratio {seconds / before:5.2f}{verdict}")


if __name__ == "__main__":
    main()
