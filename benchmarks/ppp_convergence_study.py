"""Dissertation Ch. 4 study: EKF-PPP vs iSAM2-PPP on Monte-Carlo flights (Tables 4.4.4-4.4.5).

Each seed simulates one flight (``conf/scenario/flight.yaml``: attitude masking,
phase breaks, the Table 4.4.1 error budget, dual frequency) and runs both
estimators on the ionosphere-free combination with the same stochastic model
(Table 4.4.2: ambiguity sigma 100 m for both). Prints the 3-D RSOS error
statistics (cm) over all epochs and over the first 15 minutes of every flight,
pooled over the seeds, and the per-seed medians.

    OMP_NUM_THREADS=1 python benchmarks/ppp_convergence_study.py --seeds 20 --duration 1800 --jobs 2

Evaluation seeds are 0..N-1 (nothing was tuned on them). Result files are not written.
"""

from __future__ import annotations

import argparse
import dataclasses
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

import simbench
from estimators.filters.ekf_ppp import EkfPpp
from estimators.incremental.isam2 import Isam2Ppp
from estimators.model.ppp_config import IonosphereMode
from simbench.runs.compose import preset_estimator_config

CONVERGENCE_S = 900.0


def _table_4_4_2(name: str) -> Any:
    """Estimator ``name``'s config under ``gnss_model=dissertation``, dual frequency, ambiguity sigma 100 m."""
    return dataclasses.replace(
        preset_estimator_config(name, "dissertation"), ionosphere=IonosphereMode.free, ambiguity_sigma_m=100.0
    )


def _errors(scenario: simbench.Scenario, epochs) -> tuple[np.ndarray, np.ndarray]:
    truth = scenario.truth.set_index("epoch").loc[epochs["epoch"], ["x", "y", "z"]].to_numpy()
    err = np.linalg.norm(epochs[["x", "y", "z"]].to_numpy() - truth, axis=1)
    return err, epochs["t"].to_numpy()


def run_seed(args: tuple[int, float, str]) -> dict[str, np.ndarray]:
    seed, duration, receiver = args
    sc = simbench.simulate("flight", receiver, seed=seed, **{"scenario.duration_s": duration})
    data = sc.receiver_view()
    out: dict[str, np.ndarray] = {}
    estimators = {
        "iSAM2-PPP": Isam2Ppp(_table_4_4_2("isam2_ppp")),
        "EKF-PPP": EkfPpp(_table_4_4_2("ekf_ppp")),
    }
    for name, est in estimators.items():
        sol = est.estimate(data)
        err, t = _errors(sc, sol.epochs)
        out[name] = err
        out[name + ":t"] = t - sc.truth["t"].iloc[0]
        out[name + ":update_ms"] = np.array([1e3 * sol.epochs["update_s"].median()])
    return out


def _stats(e: np.ndarray) -> str:
    cm = 100.0 * e
    return f"{np.median(cm):9.2f} {cm.mean():9.2f} {cm.std():9.2f} {cm.max():10.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--duration", type=float, default=1800.0, help="flight length [s]")
    ap.add_argument("--receiver", default="high")
    ap.add_argument("--jobs", type=int, default=1)
    a = ap.parse_args()
    jobs = [(s, a.duration, a.receiver) for s in range(a.seeds)]
    with ProcessPoolExecutor(a.jobs) as pool:
        results = list(pool.map(run_seed, jobs))
    names = ("iSAM2-PPP", "EKF-PPP")
    print(f"{a.seeds} flights x {a.duration:.0f} s, receiver {a.receiver}; 3-D RSOS error [cm]")
    for title, window in (("all epochs (Table 4.4.4)", None), ("first 15 min (Table 4.4.5)", CONVERGENCE_S)):
        print(f"\n{title}\n{'':12s} {'median':>9s} {'mean':>9s} {'std':>9s} {'max':>10s}")
        for n in names:
            e = np.concatenate([r[n][r[n + ":t"] < window] if window else r[n] for r in results])
            print(f"{n:12s} {_stats(e)}")
    print("\nper-seed median / mean / max over all epochs [cm]; iSAM2 | EKF")
    for s, r in enumerate(results):
        print(
            f"seed {s:3d}: "
            + " | ".join(
                f"{100 * np.median(r[n]):7.1f} {100 * r[n].mean():7.1f} {100 * r[n].max():8.1f}" for n in names
            )
        )
    wins = sum(r["iSAM2-PPP"].mean() < r["EKF-PPP"].mean() for r in results)
    print(f"\niSAM2 mean error below the EKF's in {wins}/{len(results)} flights")
    for n in names:
        print(f"{n} median update time over flights: {np.median([r[n + ':update_ms'][0] for r in results]):.2f} ms")


if __name__ == "__main__":
    main()
