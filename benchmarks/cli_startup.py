"""Command-line start-up: ``python -m simbench --help`` and refused command lines (issue 46).

Targets: ``--help`` <= 1.5 s, a refused command line <= 2 s (best of ``--repeat``, this machine).
Each command runs in a fresh interpreter, as a user types it; ``python -c pass`` is the floor
(the interpreter's own start), and the ratio to it shows what simbench adds. A misspelt name
(``scenario=urbn``, ``estimator=[l2,dsc]``) is refused from the config folder's names and the
entry points' before any estimator loads; a bad value (``scenario.duration_s=-5``) needs the
composed, typed config, so every estimator's ``Config`` is imported first (no target; reported).

    python benchmarks/cli_startup.py [--repeat 3] [--repo DIR]

``--repo`` times another checkout (e.g. the main branch's, for a before/after): the commands run in
its folder, so ``python -m simbench`` is its code.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: (label, arguments after ``python``, target [s] or None, expected exit code)
CASES: list[tuple[str, list[str], float | None, int]] = [
    ("python -c pass (floor)", ["-c", "pass"], None, 0),
    ("--help", ["-m", "simbench", "--help"], 1.5, 0),
    ("refused: scenario=urbn", ["-m", "simbench", "scenario=urbn"], 2.0, 2),
    ("refused: estimator=[l2,dsc]", ["-m", "simbench", "estimator=[l2,dsc]"], 2.0, 2),
    ("refused: estimator.ekf_pp.x=1", ["-m", "simbench", "estimator.ekf_pp.x=1"], 2.0, 2),
    ("refused value: scenario.duration_s=-5", ["-m", "simbench", "scenario.duration_s=-5"], None, 2),
]


def best_time(args: list[str], code: int, repeat: int, repo: Path) -> float:
    """Best wall time of ``python <args>`` in ``repo`` over ``repeat`` runs [s]; checks the exit code."""
    best = float("inf")
    for _ in range(repeat):
        tic = time.perf_counter()
        proc = subprocess.run([sys.executable, *args], cwd=repo, capture_output=True, text=True)
        best = min(best, time.perf_counter() - tic)
        if proc.returncode != code:
            raise SystemExit(f"{args}: exit {proc.returncode}, expected {code}: {proc.stderr[-500:]}")
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--repo", type=Path, default=ROOT, help="the checkout to time (default: this one)")
    args = parser.parse_args()
    floor = None
    for label, argv, target, code in CASES:
        seconds = best_time(argv, code, args.repeat, args.repo)
        floor = seconds if floor is None else floor
        verdict = "" if target is None else f"  target <= {target:.1f} s: {'met' if seconds <= target else 'MISSED'}"
        print(f"{label:40s} {seconds:6.2f} s  {seconds / floor:5.1f}x python's start{verdict}")


if __name__ == "__main__":
    main()
