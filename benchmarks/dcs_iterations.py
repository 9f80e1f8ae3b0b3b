"""How DCS's accuracy moves with its iterations: the data for an iteration cap (issue 27).

DCS re-weights by one Gauss-Newton step per iteration and runs until the relative
error change is below ``rel_tol`` or ``max_iterations`` (100, the published value)
is reached. On the drives it often runs 40-100 iterations at ~0.7 s each. This
prints, per world and seed, the horizontal median / p95 [m] of L2 (the start) and of
DCS stopped after each of ``--caps`` iterations, then where DCS stops by itself
(``max_iterations = 100``), with its iteration count and time. DCS is deterministic,
so ``DcsBatch(max_iterations=k)`` is the default run's first ``k`` iterations.
Tune on seeds >= 1000 only; the table is in docs/notebook.md ("DCS: where its
iterations go").

    OMP_NUM_THREADS=1 python benchmarks/dcs_iterations.py --worlds morgantown1 urban --seeds 1000 1001
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core per run

import numpy as np
import pandas as pd

import simbench
from estimators.base import Solution
from estimators.batch.configs import DcsConfig, L2Config
from estimators.batch.robust import DcsBatch, L2Batch
from simbench.analysis.metrics import enu_errors


def horizontal(solution: Solution, truth: pd.DataFrame) -> str:
    """``median / p95`` of the horizontal error [m]."""
    h = enu_errors(solution.epochs, truth)["horizontal"].to_numpy()
    return f"{np.median(h):.2f} / {np.percentile(h, 95):.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=["morgantown1", "morgantown2", "morgantown3", "urban"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[1000, 1001])
    ap.add_argument("--receiver", default="low")
    ap.add_argument("--caps", nargs="+", type=int, default=[10, 20, 50])
    args = ap.parse_args()
    if min(args.seeds) < 1000:
        ap.error("tune on seeds >= 1000 (0..N-1 are the evaluation seeds)")
    print(f"| world | seed | stops at | s | L2 | {' | '.join(str(c) for c in args.caps)} | at stop |")
    print("|---" * (len(args.caps) + 6) + "|")
    for world in args.worlds:
        for seed in args.seeds:
            scenario = simbench.simulate(world, args.receiver, seed=seed)
            data = scenario.receiver_view()
            l2 = L2Batch(L2Config()).estimate(data)
            full = DcsBatch(DcsConfig()).estimate(data)
            n = full.diagnostics["iterations"]
            # a cap at or beyond where DCS stops by itself changes nothing
            capped = [
                horizontal(DcsBatch(DcsConfig(max_iterations=c)).estimate(data), scenario.truth) if c < n else ""
                for c in args.caps
            ]
            print(
                f"| {world} | {seed} | {n} | {full.total_s:.0f} | {horizontal(l2, scenario.truth)} | "
                f"{' | '.join(capped)} | {horizontal(full, scenario.truth)} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
