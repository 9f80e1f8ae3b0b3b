"""BCE wall time against batch L2 on the same one-hour 1 Hz scenario (target: BCE <= 5x L2).

Prints each estimator's total wall time, its BCE iterations, time per observation and
the ratio to L2, for the default BCE and for BCE with a sub-sampled mixture fit. The
machine is shared: run with ``OMP_NUM_THREADS=1`` and read the numbers as noisy.

    OMP_NUM_THREADS=1 python benchmarks/bce_speed.py [--duration 3600] [--scenario urban]
"""
from __future__ import annotations

import argparse
import time

import simbench
from estimators.batch_robust import L2Batch
from estimators.bce import Bce, BceConfig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="urban")
    ap.add_argument("--receiver", default="low")
    ap.add_argument("--duration", type=float, default=3600.0)
    ap.add_argument("--seed", type=int, default=1000)
    args = ap.parse_args()
    tic = time.perf_counter()
    scen = simbench.simulate(args.scenario, args.receiver, seed=args.seed,
                             **{"scenario.duration_s": args.duration, "scenario.rate_hz": 1.0})
    data = scen.receiver_view()
    n_obs = len(scen.observations)
    print(f"{args.scenario}/{args.receiver}, {args.duration:.0f} s at 1 Hz, {n_obs} observations "
          f"(simulated in {time.perf_counter() - tic:.0f} s)")
    runs = {"l2": L2Batch(), "bce": Bce(), "bce fit_sample=2000": Bce(BceConfig(fit_sample=2000))}
    base = None
    for label, est in runs.items():
        sol = est.estimate(data)
        base = base or sol.total_s
        it = sol.diagnostics.get("iterations", 1)
        print(f"{label:22s} total {sol.total_s:7.2f} s  iterations {it:3d}  "
              f"{1e6 * sol.total_s / n_obs:7.1f} us/obs  ratio to L2 {sol.total_s / base:5.2f}")


if __name__ == "__main__":
    main()
