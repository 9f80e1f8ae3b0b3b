"""Dissertation Ch. 7 study: ICE vs incremental L2 (iSAM2-PPP), DCS and MM on low and high receivers.

Each seed simulates the replay scenario (drive 1's trajectory under the broadcast
orbits of 2018-12-21, single-frequency L1) for both receiver presets of Table 5.3.1
and runs the four iSAM2 estimators with their default configs. Prints the
horizontal RSOS error statistics (median / std / max, m, pooled over the seeds
as Tables 7.3.1-7.3.2), per-seed medians, how often ICE has the lowest median,
and ICE's adaptation count against the naive "adapt every T_c residuals" count.

    OMP_NUM_THREADS=1 python benchmarks/ice_study.py --seeds 20 --duration 600 --jobs 1

Evaluation seeds are 0..N-1. Result files are not written.
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pymap3d

import simbench
from estimators.incremental.ice import Ice
from estimators.incremental.isam2 import Isam2Dcs, Isam2Mm, Isam2Ppp

ESTIMATORS = {"L2": Isam2Ppp, "DCS": Isam2Dcs, "MM": Isam2Mm, "ICE": Ice}


def _horizontal(scenario: simbench.Scenario, epochs) -> np.ndarray:
    truth = scenario.truth.set_index("epoch").loc[epochs["epoch"], ["x", "y", "z"]].to_numpy()
    est = epochs[["x", "y", "z"]].to_numpy()
    lat, lon, _ = pymap3d.ecef2geodetic(*truth[0])
    e, n, _ = pymap3d.ecef2enuv(*(est - truth).T, lat, lon)
    return np.hypot(e, n)


def run_seed(args: tuple[int, str, str, float]) -> dict:
    seed, receiver, scenario, duration = args
    sc = simbench.simulate(scenario, receiver, seed=seed, **{"scenario.duration_s": duration})
    out: dict = {"seed": seed, "receiver": receiver}
    for name, cls in ESTIMATORS.items():
        sol = cls().estimate(sc.receiver_view())
        out[name] = _horizontal(sc, sol.epochs)
        if name == "ICE":
            d = sol.diagnostics
            out["ice"] = {
                k: d[k]
                for k in (
                    "n_adaptations",
                    "naive_adaptations",
                    "n_residuals",
                    "n_outliers",
                    "epochs_without_gnss_update",
                )
            }
            out["ice"]["n_components"] = len(d["final_model"]["weights"])
            out["ice"]["weights"] = d["final_model"]["weights"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--scenario", default="replay")
    ap.add_argument("--receivers", default="low,high")
    ap.add_argument("--jobs", type=int, default=1)
    a = ap.parse_args()
    receivers = a.receivers.split(",")
    jobs = [(s, r, a.scenario, a.duration) for r in receivers for s in range(a.seeds)]
    with ProcessPoolExecutor(a.jobs) as pool:
        results = list(pool.map(run_seed, jobs))
    print(f"{a.scenario}, {a.seeds} seeds x {a.duration:.0f} s; horizontal RSOS error [m]")
    for rx in receivers:
        res = [r for r in results if r["receiver"] == rx]
        print(f"\nreceiver {rx}: pooled over seeds\n{'':8s}" + "".join(f"{n:>8s}" for n in ESTIMATORS))
        for stat, f in (("median", np.median), ("std", np.std), ("max", np.max)):
            print(f"{stat:8s}" + "".join(f"{f(np.concatenate([r[n] for r in res])):8.2f}" for n in ESTIMATORS))
        med = np.array([[np.median(r[n]) for n in ESTIMATORS] for r in res])
        best = np.argmin(med, axis=1)
        print("median of per-seed medians " + " ".join(f"{n} {v:.2f}" for n, v in zip(ESTIMATORS, np.median(med, 0))))
        print("lowest per-seed median: " + ", ".join(f"{n} {int((best == i).sum())}" for i, n in enumerate(ESTIMATORS)))
        ice = [r["ice"] for r in res]
        print(
            f"ICE adaptations: total {sum(d['n_adaptations'] for d in ice)} vs naive "
            f"{sum(d['naive_adaptations'] for d in ice)}; "
            f"per seed median {np.median([d['n_adaptations'] for d in ice]):.0f}"
            f" vs {np.median([d['naive_adaptations'] for d in ice]):.0f}; outlier fraction "
            f"{sum(d['n_outliers'] for d in ice) / sum(d['n_residuals'] for d in ice):.3f}; epochs without GNSS "
            f"update {sum(d['epochs_without_gnss_update'] for d in ice)}; final components per seed "
            f"{[d['n_components'] for d in ice]}"
        )


if __name__ == "__main__":
    main()
