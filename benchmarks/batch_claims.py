"""Measure the dissertation's Ch. 5/6 claims for the batch estimators (prints tables; writes nothing).

Parts (``--part``):

* ``low``: urban scenario, ``low`` receiver, seeds ``0..n-1``: L2, DCS, MM, BCE, BCE-AD and the
  oracle (reads labels) -- horizontal median/mean/var/max and run time per observation.
  Claim: BCE median below L2, DCS and MM; BCE-AD at or below BCE.
* ``high``: the same with the ``high`` receiver for L2, DCS, MM, BCE. Claim: all within ~15 %.
* ``sensitivity``: ``low``, a-priori covariance scaled by s in {0.1, 0.3, 1, 3, 10, 100} for L2, DCS,
  MM, BCE (Fig. 5.3.7). Claim: BCE the least sensitive (spread of its median over s smallest).

Run e.g. ``OMP_NUM_THREADS=1 python benchmarks/batch_claims.py --part low --seeds 10``.
Evaluation seeds start at 0 (nothing here was tuned on them).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from typing import Any

import pandas as pd

import simbench
from simbench.runs.compose import preset_estimator_config
from simbench.runs.runner import run_estimators

SCALES = (0.1, 0.3, 1.0, 3.0, 10.0, 100.0)
STATS = ["horizontal_median", "horizontal_mean", "horizontal_var", "horizontal_max", "time_per_obs_s", "total_s"]


def _published(name: str, **changes: Any) -> dict[str, Any]:
    """Estimator ``name``'s settings under ``gnss_model=dissertation`` (the claims' model) with ``changes``."""
    return {**dataclasses.asdict(preset_estimator_config(name, "dissertation")), **changes}


def _run(receiver: str, seeds: range, configs: dict[str, dict], tag: dict) -> pd.DataFrame:
    rows = []
    for seed in seeds:
        scen = simbench.simulate("urban", receiver, seed=seed)
        res = run_estimators(scen, configs, receiver=receiver, progress=False)
        summ = res.summary.assign(**tag)
        failed = summ[summ["status"] != "ok"]
        for _, r in failed.iterrows():
            print(f"  seed {seed} {r['estimator']} failed: {r['message']}")
        print(
            f"  {tag} seed {seed}: "
            + ", ".join(
                f"{e} {m:.2f} m {t:.0f} s" for e, m, t in summ[["estimator", "horizontal_median", "total_s"]].to_numpy()
            ),
            flush=True,
        )
        rows.append(summ)
    return pd.concat(rows, ignore_index=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=["low", "high", "sensitivity"], required=True)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=0, help="run seeds first..first+seeds-1")
    ap.add_argument("--csv", default="", help="also write the per-seed summary here (outside the repo)")
    args = ap.parse_args()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    tic = time.perf_counter()
    if args.part in ("low", "high"):
        names = ["l2", "dcs", "mm", "bce"] + (["bce_ad", "oracle"] if args.part == "low" else [])
        df = _run(args.part, seeds, {n: _published(n) for n in names}, {"scale": 1.0})
        table = df.groupby("estimator")[STATS].median().loc[names]
        print(
            f"\n== urban / {args.part} receiver, seeds {seeds.start}..{seeds.stop - 1}: "
            "median over seeds of each statistic"
        )
        print(table.to_string(float_format=lambda v: f"{v:.4g}"))
        print("(oracle reads labels: accuracy floor)" if args.part == "low" else "")
        wins = df.pivot(index="seed", columns="estimator", values="horizontal_median")
        for other in [n for n in names if n not in ("bce", "oracle")]:
            print(f"BCE median < {other}: {int((wins['bce'] < wins[other]).sum())}/{len(wins)} seeds")
        if args.part == "high":
            med = table["horizontal_median"]
            print(f"max/min horizontal median over estimators: {med.max() / med.min():.3f}")
    else:
        names = ["l2", "dcs", "mm", "bce"]
        parts = [_run("low", seeds, {n: _published(n, prior_scale=s) for n in names}, {"scale": s}) for s in SCALES]
        df = pd.concat(parts, ignore_index=True)
        table = df.groupby(["estimator", "scale"])["horizontal_median"].median().unstack("scale").loc[names]
        print(
            f"\n== sensitivity (urban / low, seeds {seeds.start}..{seeds.stop - 1}): "
            "median over seeds of the horizontal median"
        )
        print(table.to_string(float_format=lambda v: f"{v:.3f}"))
        spread = (table.max(axis=1) - table.min(axis=1)).rename("max-min")
        print(spread.to_string(float_format=lambda v: f"{v:.3f}"))
    if args.csv:
        df.to_csv(args.csv, index=False)
    print(f"wall time {time.perf_counter() - tic:.0f} s (machine shared: timings are noisy)")


if __name__ == "__main__":
    main()
