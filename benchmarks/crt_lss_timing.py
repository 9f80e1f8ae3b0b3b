"""CRT-LSS per-epoch update time up to L = 20 (100 Hz IMU, 1 Hz GNSS) and its ratio to the EKF's.

Target (issue 5): under 100 ms per epoch, i.e. ten times faster than real time
at 1 Hz GNSS. The update time of an epoch covers the IMU preintegration since
the previous epoch, the heading check, Algorithm 1 on the window and the
marginalisation. Prints mean / median / p95 per estimator and the ratios, and
the CPU time of the whole run per epoch (this process only: on a shared machine
the steadiest of the numbers) with its ratio. Issue 27's target: L = 20 at most
10x the EKF. Timings on a shared machine are noisy: compare medians and CPU.

    python benchmarks/crt_lss_timing.py [--duration 300] [--seed 1000] [--windows 1 5 20]
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")  # one core
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

import simbench
from estimators.gnss_ins.config import CrtLssConfig
from estimators.gnss_ins.crt_lss import CrtLss
from estimators.gnss_ins.ekf import EkfIns, IekfIns

TARGET_S = 0.100


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=300.0, help="urban drive length [s]")
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--windows", type=int, nargs="+", default=[2, 5, 10, 20], help="CRT-LSS window lengths L")
    args = ap.parse_args()
    longest = max(args.windows)
    sc = simbench.simulate(
        "urban", "low", seed=args.seed, imu="consumer", **{"scenario.duration_s": args.duration, "imu.rate_hz": 100.0}
    )
    data = sc.receiver_view()
    runs = {
        "ekf_ins": EkfIns(),
        "iekf_ins": IekfIns(),
        **{f"crt_lss_L{L}": CrtLss(CrtLssConfig(window=L)) for L in args.windows},
    }
    stats = {}
    for name, est in runs.items():
        start = time.process_time()
        sol = est.estimate(data)
        cpu = (time.process_time() - start) / len(sol.epochs)
        u = sol.epochs["update_s"].to_numpy()[1:]  # the first epoch is the initialisation
        stats[name] = (u.mean(), np.median(u), np.percentile(u, 95), sol.diagnostics["iterations_mean"], cpu)
    ekf_mean, ekf_med, ekf_cpu = stats["ekf_ins"][0], stats["ekf_ins"][1], stats["ekf_ins"][4]
    print(f"urban, low receiver, consumer IMU 100 Hz, 1 Hz GNSS, {args.duration:g} s, seed {args.seed}")
    print(
        f"{'estimator':>14} {'mean ms':>8} {'median ms':>9} {'p95 ms':>8} {'iters':>6} {'x EKF(mean)':>11} "
        f"{'x EKF(med)':>10} {'CPU ms':>7} {'x EKF(CPU)':>10}"
    )
    for name, (mean, med, p95, it, cpu) in stats.items():
        print(
            f"{name:>14} {1e3 * mean:8.2f} {1e3 * med:9.2f} {1e3 * p95:8.2f} {it:6.2f} {mean / ekf_mean:11.1f} "
            f"{med / ekf_med:10.1f} {1e3 * cpu:7.2f} {cpu / ekf_cpu:10.1f}"
        )
    mean, cpu = stats[f"crt_lss_L{longest}"][0], stats[f"crt_lss_L{longest}"][4]
    print(
        f"CRT-LSS L={longest} mean update {1e3 * mean:.1f} ms vs target {1e3 * TARGET_S:.0f} ms: "
        f"{'met' if mean < TARGET_S else 'NOT met'} ({TARGET_S / mean:.1f}x margin); "
        f"ratio to EKF {mean / ekf_mean:.1f}x (CPU {cpu / ekf_cpu:.1f}x; issue 27 target 10x)"
    )


if __name__ == "__main__":
    main()
