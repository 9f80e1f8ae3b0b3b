"""Roysdon & Farrell's claims on the urban drive: 3-D error CDF points of EKF, IEKF and CRT-LSS(L).

Runs ``ekf_ins``, ``iekf_ins`` and ``crt_lss`` with L in {1, 2, 5, 10, 20} on the
default urban scenario (street-canyon NLOS), the ``low`` receiver and the
consumer IMU at 100 Hz, over evaluation seeds 0..N-1, through
:func:`simbench.runs.runner.run_estimators` with the configs of ``conf/estimator``.
Prints the pooled 3-D error percentiles (p50, p90, p97, max) and the per-seed
medians; writes nothing into the repository (``--out`` for a Parquet copy).

    OMP_NUM_THREADS=1 python benchmarks/crt_lss_claims.py --seeds 10
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

import simbench
from simbench.runs.compose import CONF_DIR
from simbench.runs.runner import run_estimators

WINDOWS = (1, 2, 5, 10, 20)


def _configs() -> dict[str, dict]:
    node = {
        n: yaml.safe_load((CONF_DIR / "estimator" / f"{n}.yaml").read_text())[n]
        for n in ("ekf_ins", "iekf_ins", "crt_lss")
    }
    return node


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10, help="evaluation seeds 0..N-1")
    ap.add_argument("--first-seed", type=int, default=0, help="start at this seed (split a run over processes)")
    ap.add_argument("--duration", type=float, default=600.0, help="scenario length [s]")
    ap.add_argument("--out", type=Path, default=None, help="optional Parquet file for the per-epoch errors")
    args = ap.parse_args()
    base = _configs()
    frames = []
    for seed in range(args.first_seed, args.seeds):
        sc = simbench.simulate("urban", "low", seed=seed, imu="consumer", **{"scenario.duration_s": args.duration})
        runs = {"ekf_ins": base["ekf_ins"], "iekf_ins": base["iekf_ins"]}
        for L in WINDOWS:
            res = run_estimators(sc, {"crt_lss": {**base["crt_lss"], "window": L}}, receiver="low", progress=False)
            ep = res.epochs.assign(estimator=f"crt_lss_L{L}")
            frames.append(ep)
            summary = res.summary[["status", "error_3d_median", "update_median_s"]].to_dict("records")
            print(seed, f"crt_lss_L{L}", summary, flush=True)
        res = run_estimators(sc, runs, receiver="low", progress=False)
        frames.append(res.epochs)
        print(
            seed,
            res.summary[["estimator", "status", "error_3d_median", "update_median_s"]].to_dict("records"),
            flush=True,
        )
    ep = pd.concat(frames, ignore_index=True)
    if args.out:
        ep.to_parquet(args.out)
    order = ["ekf_ins", "iekf_ins", *[f"crt_lss_L{L}" for L in WINDOWS]]
    rows = []
    for name in order:
        e = ep.loc[ep["estimator"] == name, "error_3d"].to_numpy()
        e = e[np.isfinite(e)]
        per_seed = ep[ep["estimator"] == name].groupby("seed")["error_3d"].median()
        upd = ep.loc[ep["estimator"] == name, "update_s"]
        rows.append(
            {
                "estimator": name,
                "epochs": len(e),
                "p50": np.percentile(e, 50),
                "p90": np.percentile(e, 90),
                "p97": np.percentile(e, 97),
                "max": e.max(),
                "frac_lt_1m": float(np.mean(e < 1.0)),
                "seed_median_p50": float(per_seed.median()),
                "update_mean_ms": 1e3 * float(upd.mean()),
            }
        )
    table = pd.DataFrame(rows)
    print(
        f"\nurban / low receiver / consumer IMU 100 Hz / 1 Hz GNSS, seeds {args.first_seed}..{args.seeds - 1}, "
        f"{args.duration:g} s each; pooled 3-D error [m]"
    )
    print(table.to_string(index=False, float_format=lambda v: f"{v:.2f}"))


if __name__ == "__main__":
    main()
