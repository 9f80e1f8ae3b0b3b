"""Per-epoch update time of every incremental estimator (issue 4's and issue 27's targets).

One hour at 1 Hz under the broadcast constellation of 2018-12-21 from 18:00 GPST (~10 satellites),
open sky, low-quality receiver, single-frequency L1 (the Ch. 7 setting). Prints the
median and 95th percentile update time of each registered incremental estimator,
ICE's median over the incremental L2's (``isam2_ppp``; issue 4's target <= 2, issue 27's
<= 1) and whether ICE's median is under 10 ms. Timings on a shared machine are noisy.

    python benchmarks/incremental_timing.py [--duration 3600] [--seed 0] [--rounds 2]

Each round runs every incremental estimator once, in turn, and each estimator's figures are those of
its fastest round (median update time): on this VM one estimator's median moves by 10-20 % between
two runs in one process (ICE 4.97 then 6.08 ms, iSAM2-PPP 5.81 then 5.96 ms), more than the ratio
the targets are about.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

import estimators
import simbench
from estimators.incremental.isam2 import IncrementalGraphEstimator

TARGET_RATIO = 2.0
#: Issue 27's: ICE no slower than the incremental L2 it adapts.
TARGET_RATIO_27 = 1.0
TARGET_ICE_MS = 10.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=3600.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--receiver", default="low")
    ap.add_argument("--rounds", type=int, default=2, help="runs of every estimator; each keeps its fastest")
    a = ap.parse_args()
    sc = simbench.simulate(
        "open_sky",
        a.receiver,
        seed=a.seed,
        **{
            "scenario.duration_s": a.duration,
            "scenario.dual_frequency": False,
            "scenario.constellation.kind": "broadcast",
            "scenario.start_sow_s": 496_800.0,
            "scenario.constellation.nav_path": "${simbench_data:wvu_drives/brdc.18n}",
        },
    )
    sats = sc.observations.groupby("epoch").size()
    print(
        f"open_sky, broadcast constellation, {a.duration:.0f} s at 1 Hz, {sats.mean():.1f} satellites/epoch "
        f"(min {sats.min()}, max {sats.max()}), receiver {a.receiver}"
    )
    print(f"{'estimator':12s} {'median ms':>10s} {'p95 ms':>8s} {'last 10% median ms':>19s} {'total s':>8s}")
    incremental = {n: c for n, c in estimators.registered().items() if issubclass(c, IncrementalGraphEstimator)}
    best: dict[str, tuple[np.ndarray, float]] = {}
    for _ in range(a.rounds):
        for name, cls in incremental.items():
            sol = cls().estimate(sc.receiver_view())
            u = 1e3 * sol.epochs["update_s"].to_numpy()
            if name not in best or np.median(u) < np.median(best[name][0]):
                best[name] = (u, sol.total_s)
    med = {}
    for name, (u, total_s) in best.items():
        med[name] = float(np.median(u))
        tail = u[int(0.9 * len(u)) :]
        print(f"{name:12s} {med[name]:10.2f} {np.percentile(u, 95):8.2f} {np.median(tail):19.2f} {total_s:8.1f}")
    ratio = med["ice"] / med["isam2_ppp"]
    print(
        f"ICE median / incremental L2 median = {ratio:.3f} (issue 4's target <= {TARGET_RATIO:g}: "
        f"{'met' if ratio <= TARGET_RATIO else 'NOT met'}; issue 27's <= {TARGET_RATIO_27:g}: "
        f"{'met' if ratio <= TARGET_RATIO_27 else 'NOT met'})"
    )
    print(
        f"ICE median {med['ice']:.2f} ms (target < {TARGET_ICE_MS} ms): "
        f"{'met' if med['ice'] < TARGET_ICE_MS else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
