"""Statistics tables over seeds: bootstrap confidence intervals and paired comparisons.

A group is one (sweep, scenario, receiver); within it every estimator saw the
same seeds' data, so comparisons are paired by seed. Variants are told apart
by the structured ``overrides`` column; ``variant`` is carried along as their label.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from scipy import stats

from simbench.claims import BOOTSTRAP_RESAMPLES, CONFIDENCE, CONVERGENCE_S, ratio_of_means
from simbench.variants import NO_OVERRIDES, is_default

#: Columns that identify a variant of an estimator: the structured overrides and their label.
VARIANT = ["overrides", "variant"]

GROUP = ["sweep", "scenario", "receiver"]


def _mean_ci(values: np.ndarray) -> tuple[float, float, float]:
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return np.nan, np.nan, np.nan
    if len(values) < 3 or np.ptp(values) == 0:
        return float(values.mean()), np.nan, np.nan
    res = stats.bootstrap((values,), np.mean, n_resamples=BOOTSTRAP_RESAMPLES, confidence_level=CONFIDENCE,
                          method="percentile", random_state=np.random.default_rng(0))
    return float(values.mean()), float(res.confidence_interval.low), float(res.confidence_interval.high)


def seed_statistics(summary: pd.DataFrame) -> pd.DataFrame:
    """Per group, estimator and variant: mean over seeds of each statistic, CI of the median's mean.

    Columns: group keys, estimator, overrides, variant, n_seeds, n_failed, horizontal_median (mean
    over seeds) with ci_low/ci_high, horizontal_mean, horizontal_p95, horizontal_max, error_3d_median,
    availability, time_per_obs_s, update_median_s.
    """
    out = []
    summary = summary.fillna({"overrides": NO_OVERRIDES, "variant": ""})
    for keys, rows in summary.groupby(GROUP + ["estimator"] + VARIANT, dropna=False):
        ok = rows[rows["status"] == "ok"]
        med, lo, hi = _mean_ci(ok["horizontal_median"].to_numpy(float))
        out.append({**dict(zip(GROUP + ["estimator"] + VARIANT, keys)), "n_seeds": len(ok),
                    "n_failed": int((rows["status"] != "ok").sum()), "horizontal_median": med, "ci_low": lo,
                    "ci_high": hi, **{c: float(ok[c].mean()) if len(ok) else np.nan for c in
                                      ("horizontal_mean", "horizontal_p95", "horizontal_max", "error_3d_median",
                                       "availability", "time_per_obs_s", "update_median_s")}})
    return pd.DataFrame(out)


def paired_comparisons(summary: pd.DataFrame, baseline: str) -> pd.DataFrame:
    """Each estimator against ``baseline`` on the same seeds (default variants only).

    Columns: group keys, estimator, n_seeds, ratio (mean per-seed median / baseline's), its
    bootstrap CI, wins (fraction of seeds with a lower median) and the Wilcoxon signed-rank p-value.
    """
    out = []
    ok = summary[(summary["status"] == "ok") & is_default(summary["overrides"])]
    for keys, rows in ok.groupby(GROUP, dropna=False):
        table = rows.pivot_table(index=["seed"], columns="estimator", values="horizontal_median", aggfunc="first")
        if baseline not in table:
            continue
        for name in table.columns.drop(baseline):
            pair = table[[name, baseline]].dropna()
            if pair.empty:
                continue
            ratio, lo, hi = ratio_of_means(pair, name, baseline)
            diff = pair[name] - pair[baseline]
            p = float(stats.wilcoxon(diff).pvalue) if len(pair) >= 6 and diff.abs().sum() > 0 else np.nan
            out.append({**dict(zip(GROUP, keys)), "estimator": name, "baseline": baseline, "n_seeds": len(pair),
                        "ratio": ratio, "ci_low": lo, "ci_high": hi, "wins": float((diff < 0).mean()),
                        "wilcoxon_p": p})
    return pd.DataFrame(out)


def oracle_gap(summary: pd.DataFrame, oracle: str = "oracle") -> pd.DataFrame:
    """Each estimator's mean per-seed median minus the oracle's, per group [m]."""
    ok = summary[(summary["status"] == "ok") & is_default(summary["overrides"])]
    out = []
    for keys, rows in ok.groupby(GROUP, dropna=False):
        table = rows.pivot_table(index="seed", columns="estimator", values="horizontal_median", aggfunc="first")
        if oracle not in table:
            continue
        for name in table.columns.drop(oracle):
            pair = table[[name, oracle]].dropna()
            gap = (pair[name] - pair[oracle]).to_numpy()
            mean, lo, hi = _mean_ci(gap)
            out.append({**dict(zip(GROUP, keys)), "estimator": name, "n_seeds": len(pair), "gap_m": mean,
                        "ci_low": lo, "ci_high": hi})
    return pd.DataFrame(out)


def convergence_statistics(epochs: pd.DataFrame, t_max: float = CONVERGENCE_S) -> pd.DataFrame:
    """3-D error statistics over the first ``t_max`` seconds of each run (dissertation Table 4.4.5).

    Per estimator and variant: the mean over seeds of each run's median, mean and maximum 3-D
    error for ``t < t_max`` [m], with a bootstrap CI of the mean error. Empty when no run is
    longer than 1.5 ``t_max`` (the window would be most of the run, not its convergence).
    """
    if epochs.empty or epochs["t"].max() < 1.5 * t_max:
        return pd.DataFrame()
    early = epochs[epochs["t"] < t_max].fillna({"overrides": NO_OVERRIDES, "variant": ""})
    per_run = early.groupby(["estimator"] + VARIANT + ["seed"], dropna=False)["error_3d"].agg(["median", "mean", "max"])
    out = []
    for (name, overrides, variant), runs in per_run.groupby(level=["estimator"] + VARIANT, dropna=False):
        mean, lo, hi = _mean_ci(runs["mean"].to_numpy(float))
        out.append({"estimator": name, "overrides": overrides, "variant": variant, "n_seeds": len(runs),
                    "error_3d_median": float(runs["median"].mean()), "error_3d_mean": mean, "ci_low": lo,
                    "ci_high": hi, "error_3d_max": float(runs["max"].mean())})
    return pd.DataFrame(out)
