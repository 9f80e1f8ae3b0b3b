"""Publication-quality figures from the results tables."""
from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from simbench.metrics import ecdf  # noqa: E402

METRIC_LABELS = {"horizontal": "horizontal error [m]", "error_3d": "3-D error [m]"}


def ecdf_figure(epochs: pd.DataFrame, metric: str, path: str | Path, title: str) -> Path:
    """ECDF of one error metric per estimator, log-scaled error axis.

    Parameters
    ----------
    epochs : pandas.DataFrame
        ``epochs.parquet`` rows (columns ``estimator`` and ``metric``).
    metric : str
        ``horizontal`` or ``error_3d``.
    path : path-like
        PNG to write.
    title : str
    """
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=150)
    for name, group in sorted(epochs.groupby("estimator"), key=lambda kv: np.nanmedian(kv[1][metric])):
        values = group[metric].to_numpy()
        if not np.isfinite(values).any():
            continue
        x, p = ecdf(values)
        ax.step(np.maximum(x, 1e-3), p, where="post", lw=1.6,
                label=f"{name} (median {np.nanmedian(values):.2f} m)")
    ax.set_xscale("log")
    ax.set_xlabel(METRIC_LABELS.get(metric, metric))
    ax.set_ylabel("fraction of epochs")
    ax.set_ylim(0, 1.01)
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(_wrap(fig, title, 12))
    ax.legend(loc="lower right", fontsize=8, frameon=True)
    return _save(fig, path)


def error_timeseries_figure(epochs: pd.DataFrame, path: str | Path, title: str) -> Path:
    """Horizontal error over time per estimator (convergence behaviour)."""
    fig, ax = plt.subplots(figsize=(7.0, 3.6), dpi=150)
    for name, group in epochs.groupby("estimator"):
        ax.plot(group["t"], group["horizontal"], lw=1.0, label=name)
    ax.set_yscale("log")
    ax.set_xlabel("time since start [s]")
    ax.set_ylabel("horizontal error [m]")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(_wrap(fig, title, 12))
    ax.legend(loc="upper right", fontsize=8)
    return _save(fig, path)


def _wrap(fig: plt.Figure, text: str, fontsize: float) -> str:
    """``text`` wrapped to the figure's width (titles otherwise run off narrow figures)."""
    chars = max(20, int(fig.get_figwidth() * 72 / (0.55 * fontsize)))
    return "\n".join(textwrap.fill(line, chars) for line in text.split("\n"))


def _log_x_if_wide(ax: plt.Axes, values: np.ndarray) -> None:
    """Log x axis when the values span more than a decade and a half, else linear from zero."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v) & (v > 0)]
    if len(v) and v.max() / v.min() > 30:
        ax.set_xscale("log")
    else:
        ax.set_xlim(left=0)


def _save(fig: plt.Figure, path: str | Path) -> Path:
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def box_figure(epochs: pd.DataFrame, path: str | Path, title: str, metric: str = "horizontal") -> Path:
    """Box plot of per-epoch errors per estimator (dissertation Fig. 5.3.2), log scale."""
    order = sorted(epochs["estimator"].unique(), key=lambda n: np.nanmedian(
        epochs.loc[epochs["estimator"] == n, metric]))
    data = [epochs.loc[epochs["estimator"] == n, metric].dropna().to_numpy() for n in order]
    fig, ax = plt.subplots(figsize=(max(4.0, 0.9 * len(order) + 1.5), 4.0), dpi=150)
    ax.boxplot(data, whis=(5, 95), showfliers=False, medianprops={"color": "black"})
    ax.set_xticks(range(1, len(order) + 1), order, rotation=30, ha="right")
    ax.set_yscale("log")
    ax.set_ylabel(METRIC_LABELS.get(metric, metric))
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.set_title(_wrap(fig, title, 10) + "\n(box: quartiles, whiskers: 5-95 %)", fontsize=10)
    return _save(fig, path)


def sensitivity_figure(curves: pd.DataFrame, path: str | Path, title: str) -> Path:
    """Median error against the a priori covariance scale per estimator (dissertation Fig. 5.3.7).

    ``curves`` has columns estimator, scale, horizontal_median, ci_low, ci_high.
    """
    fig, ax = plt.subplots(figsize=(6.0, 4.0), dpi=150)
    for name, group in curves.groupby("estimator"):
        group = group.sort_values("scale")
        ax.errorbar(group["scale"], group["horizontal_median"],
                    yerr=[group["horizontal_median"] - group["ci_low"], group["ci_high"] - group["horizontal_median"]],
                    marker="o", capsize=3, label=name)
    ax.set_xscale("log")
    ax.set_xlabel("a priori covariance scale s")
    ax.set_ylabel("median horizontal error [m]")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(_wrap(fig, title, 10) + "\n(per-seed medians: mean and 95 % CI over seeds)", fontsize=10)
    ax.legend(fontsize=8)
    return _save(fig, path)


def runtime_figure(stats: pd.DataFrame, path: str | Path, title: str) -> Path:
    """Run time per observation and median per-epoch update time per estimator (Figs. 5.3.8, 7.3.3)."""
    stats = stats.sort_values("time_per_obs_s")
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.8), dpi=150)
    labels = [f"{e}\n{v}" if v else e for e, v in zip(stats["estimator"], stats["variant"].fillna(""))]
    axes[0].barh(labels, stats["time_per_obs_s"] * 1e6, color="tab:blue")
    axes[0].set_xlabel("run time per observation [us]")
    axes[1].barh(labels, stats["update_median_s"] * 1e3, color="tab:orange")
    axes[1].set_xlabel("median per-epoch update [ms]")
    for ax, values in zip(axes, (stats["time_per_obs_s"], stats["update_median_s"])):
        _log_x_if_wide(ax, values.to_numpy())
        ax.grid(True, axis="x", which="both", alpha=0.3)
        ax.tick_params(axis="y", labelsize=7)
    fig.suptitle(_wrap(fig, title, 11), fontsize=11)
    return _save(fig, path)


def mixture_evolution_figure(history: list[dict], path: str | Path, title: str, xlabel: str = "iteration") -> Path:
    """Component standard deviations of the learned noise mixture per iteration (dissertation Fig. 5.3.3).

    ``history`` holds one record per iteration (or ICE adaptation, ``xlabel``) with ``mixture`` =
    {weights, covariances (K, D, D)}; the first two dimensions are the code and phase residuals [m].
    Marker area is proportional to weight.
    """
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.6), dpi=150, sharex=True)
    for record in history:
        mix = record.get("mixture") or {}
        cov = np.asarray(mix.get("covariances", []), float)
        if cov.ndim != 3 or cov.shape[1] < 2:
            continue
        w = np.asarray(mix["weights"], float)
        it = np.full(len(w), record.get("iteration", 0))
        for ax, d in zip(axes, (0, 1)):
            ax.scatter(it, np.sqrt(cov[:, d, d]), s=20 + 300 * w, alpha=0.6, color="tab:blue", edgecolor="k", lw=0.4)
    for ax, label in zip(axes, ("code residual std [m]", "phase residual std [m]")):
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(_wrap(fig, title + " (marker area ~ component weight)", 10), fontsize=10)
    return _save(fig, path)
