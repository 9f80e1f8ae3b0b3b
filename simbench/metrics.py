"""Scoring: per-epoch ENU error against truth, summary statistics, ECDF.

Errors are taken relative to the true antenna position in the local
east-north-up frame at that position, without any alignment (dissertation
scoring); horizontal error is sqrt(dE^2 + dN^2) ("RSOS").
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import pymap3d
from scipy import stats


def enu_errors(solution: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Per-epoch east, north, up, horizontal and 3-D error [m].

    Parameters
    ----------
    solution : pandas.DataFrame
        Columns ``epoch, x, y, z`` (ECEF metres), plus any others (kept).
    truth : pandas.DataFrame
        Columns ``epoch, x, y, z``.

    Returns
    -------
    pandas.DataFrame
        The solution rows that have a truth epoch, with ``e, n, u, horizontal, error_3d`` added.
    """
    merged = solution.merge(truth[["epoch", "x", "y", "z"]], on="epoch", suffixes=("", "_true"))
    lat, lon, _ = pymap3d.ecef2geodetic(merged["x_true"].to_numpy(), merged["y_true"].to_numpy(),
                                        merged["z_true"].to_numpy())
    d = [merged[c].to_numpy() - merged[f"{c}_true"].to_numpy() for c in ("x", "y", "z")]
    e, n, u = pymap3d.ecef2enuv(d[0], d[1], d[2], lat, lon)
    out = merged.drop(columns=["x_true", "y_true", "z_true"])
    out["e"], out["n"], out["u"] = e, n, u
    out["horizontal"] = np.hypot(e, n)
    out["error_3d"] = np.sqrt(e * e + n * n + u * u)
    return out


def summary_stats(values: np.ndarray, prefix: str) -> dict[str, float]:
    """Median, mean, variance, standard deviation, p95 and max of an error series [m, m^2].

    NaNs are ignored; an empty series gives NaN statistics.
    """
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {f"{prefix}_{k}": np.nan for k in ("median", "mean", "var", "std", "p95", "max")}
    return {f"{prefix}_median": float(np.median(v)), f"{prefix}_mean": float(v.mean()),
            f"{prefix}_var": float(v.var()), f"{prefix}_std": float(v.std()),
            f"{prefix}_p95": float(np.percentile(v, 95)), f"{prefix}_max": float(v.max())}


def ecdf(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF (scipy.stats.ecdf): sorted unique values and their probabilities."""
    v = np.asarray(values, float)
    res = stats.ecdf(v[np.isfinite(v)])
    return res.cdf.quantiles, res.cdf.probabilities
