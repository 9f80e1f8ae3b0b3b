"""Publication-quality figures from the results tables."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
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
    ax.set_title(title)
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
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize=8)
    return _save(fig, path)


def _save(fig: plt.Figure, path: str | Path) -> Path:
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
