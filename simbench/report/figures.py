"""Publication-quality figures from the results tables.

Each estimator keeps one colour and line style (:func:`estimator_styles`), so
14 and more estimators stay distinct. Error distributions are drawn over all
reference epochs (:func:`simbench.analysis.metrics.reference_ecdf`): a curve ends at its
estimator's availability, below 1 when it left epochs unsolved.
"""

from __future__ import annotations

import io
import textwrap
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, cast

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.colors import ListedColormap
from matplotlib.ticker import MaxNLocator

from simbench.analysis.metrics import reference_ecdf, reference_percentile
from simbench.analysis.validation import ValidationSample, cn0_by_elevation
from simbench.contract import write_bytes
from simbench.errors import SimbenchError

METRIC_LABELS = {"horizontal": "horizontal error [m]", "error_3d": "3-D error [m]"}
#: After the ten colours of tab10 the line style changes, so 40 estimators get distinct lines.
LINESTYLES = ("-", "--", ":", "-.")
#: Legends with more entries go beside the axes instead of over the curves.
LEGEND_INSIDE_MAX = 6
#: What a figure says about curves that end below 1.
REFERENCE_NOTE = "over all reference epochs: a curve ends at its availability, unsolved epochs counting as missed"


def estimator_styles(names: Iterable[str]) -> dict[str, dict[str, Any]]:
    """A distinct ``color`` and ``linestyle`` per estimator name, by sorted name (same set, same styles)."""
    tab10 = cast(ListedColormap, plt.get_cmap("tab10"))
    colors = cast(Sequence[tuple[float, float, float]], tab10.colors)  # a tuple of ten RGB triples
    return {
        name: {"color": colors[i % len(colors)], "linestyle": LINESTYLES[(i // len(colors)) % len(LINESTYLES)]}
        for i, name in enumerate(sorted(set(names)))
    }


def availability_text(fraction: float) -> str:
    """``36 % solved`` (whole percent; '< 1 %' and '> 99 %' rather than rounding to 0 or 100)."""
    if 0 < fraction < 0.01:
        return "< 1 % solved"
    if 0.99 < fraction < 1:
        return "> 99 % solved"
    return f"{fraction:.0%} solved".replace("%", " %")


def _references(epochs: pd.DataFrame, n_reference: Mapping[str, int]) -> dict[str, int]:
    missing = sorted(set(epochs["estimator"]) - set(n_reference))
    if missing:
        raise SimbenchError(
            "n_reference",
            f"has no reference epoch count for {', '.join(missing)}",
            "pass the summed n_epochs of each estimator's jobs",
        )
    return {name: int(n_reference[name]) for name in epochs["estimator"].unique()}


def ecdf_figure(
    epochs: pd.DataFrame, metric: str, path: str | Path, title: str, n_reference: Mapping[str, int]
) -> Path:
    """ECDF of one error metric per estimator over all reference epochs, log-scaled error axis.

    Parameters
    ----------
    epochs : pandas.DataFrame
        ``epochs.parquet`` rows (columns ``estimator`` and ``metric``): the solved epochs.
    metric : str
        ``horizontal`` or ``error_3d``.
    path : path-like
        PNG to write.
    title : str
    n_reference : mapping of estimator name to int
        Reference epochs of that estimator's jobs in ``epochs`` (the summed ``n_epochs``): the
        denominator, so a curve ends at the estimator's availability. The legend gives the
        availability and the median over reference epochs ('—' below 50 % availability).
    """
    counts = _references(epochs, n_reference)
    styles = estimator_styles(epochs["estimator"])
    curves = []
    for name, group in epochs.groupby("estimator"):
        values = group[metric].to_numpy(float)
        x, p = reference_ecdf(values, counts[name])
        if x.size:
            curves.append((reference_percentile(values, counts[name], 50.0), -p[-1], name, x, p))
    beside = len(curves) > LEGEND_INSIDE_MAX
    fig, ax = plt.subplots(figsize=(9.5 if beside else 6.4, 4.4), dpi=150)
    for median, _, name, x, p in sorted(curves, key=lambda c: c[:3]):
        x = np.maximum(x, 1e-3)
        shown = f"{median:.2f} m" if np.isfinite(median) else "—"
        ax.step(
            np.r_[x[0], x],
            np.r_[0.0, p],
            where="post",
            lw=1.5,
            **styles[name],
            label=f"{name} ({availability_text(p[-1])}, median {shown})",
        )
        ax.plot(x[-1], p[-1], marker="o", ms=3, color=styles[name]["color"])  # where the curve stops
    ax.set_xscale("log")
    ax.set_xlabel(METRIC_LABELS.get(metric, metric))
    ax.set_ylabel("fraction of reference epochs")
    ax.set_ylim(0, 1.01)
    ax.grid(True, which="both", alpha=0.3)
    # a legend beside the axes leaves the title about 5.5 inches
    ax.set_title(_wrap(fig, f"{title}\n({REFERENCE_NOTE})", 10, 5.5 if beside else None), fontsize=10)
    _legend(ax, len(curves), "lower right")
    return _save(fig, path)


def error_timeseries_figure(epochs: pd.DataFrame, path: str | Path, title: str) -> Path:
    """Horizontal error over time per estimator (convergence behaviour)."""
    styles = estimator_styles(epochs["estimator"])
    n = epochs["estimator"].nunique()
    fig, ax = plt.subplots(figsize=(7.0 if n <= LEGEND_INSIDE_MAX else 9.0, 3.6), dpi=150)
    ax.set_title(_wrap(fig, title, 12, 6.0 if n > LEGEND_INSIDE_MAX else None))
    for name, group in epochs.groupby("estimator"):
        ax.plot(group["t"], group["horizontal"], lw=1.0, label=name, **styles[name])
    ax.set_yscale("log")
    ax.set_xlabel("time since start [s]")
    ax.set_ylabel("horizontal error [m]")
    ax.grid(True, which="both", alpha=0.3)
    _legend(ax, n, "upper right")
    return _save(fig, path)


def _legend(ax: plt.Axes, entries: int, inside: Literal["lower right", "upper right"]) -> None:
    """Legend at ``inside`` for a few entries, beside the axes (two columns past 20) for many."""
    if entries <= LEGEND_INSIDE_MAX:
        ax.legend(loc=inside, fontsize=8, frameon=True)
    else:
        ax.legend(
            loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False, ncols=1 if entries <= 20 else 2
        )


def _wrap(fig: plt.Figure, text: str, fontsize: float, width_in: float | None = None) -> str:
    """``text`` wrapped to the figure's width, or ``width_in`` inches (titles otherwise run off narrow figures)."""
    chars = max(20, int((width_in or fig.get_figwidth()) * 72 / (0.55 * fontsize)))
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
    buffer = io.BytesIO()
    fig.savefig(buffer, format=path.suffix[1:] or "png")
    plt.close(fig)
    write_bytes(path, buffer.getvalue())  # atomic: two reports of one run never mix their figures
    return path


def box_figure(
    epochs: pd.DataFrame, path: str | Path, title: str, n_reference: Mapping[str, int], metric: str = "horizontal"
) -> Path:
    """Box plot of the solved epochs' errors per estimator (dissertation Fig. 5.3.2), log scale.

    Each label gives the estimator's availability (solved / ``n_reference`` epochs,
    as in :func:`ecdf_figure`): the boxes describe only the epochs it solved.
    """
    counts = _references(epochs, n_reference)
    order = sorted(
        epochs["estimator"].unique(), key=lambda n: np.nanmedian(epochs.loc[epochs["estimator"] == n, metric])
    )
    data = [epochs.loc[epochs["estimator"] == n, metric].dropna().to_numpy() for n in order]
    labels = [f"{n}\n{availability_text(len(d) / counts[n])}" for n, d in zip(order, data)]
    fig, ax = plt.subplots(figsize=(max(4.0, 0.9 * len(order) + 1.5), 4.2), dpi=150)
    ax.boxplot(data, whis=(5, 95), showfliers=False, medianprops={"color": "black"})
    ax.set_xticks(range(1, len(order) + 1), labels, rotation=30, ha="right", fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel(METRIC_LABELS.get(metric, metric))
    ax.grid(True, axis="y", which="both", alpha=0.3)
    # wrapped as if larger: the default font runs wider than _wrap's estimate for narrow figures
    ax.set_title(_wrap(fig, f"{title}\n(solved epochs only; box: quartiles, whiskers: 5-95 %)", 12), fontsize=10)
    return _save(fig, path)


def sensitivity_figure(curves: pd.DataFrame, path: str | Path, title: str) -> Path:
    """Median error against the a priori covariance scale per estimator (dissertation Fig. 5.3.7).

    ``curves`` has columns estimator, scale, horizontal_median_ref (over reference epochs; a
    scale whose median is undefined, inf, is left out), ci_low, ci_high.
    """
    fig, ax = plt.subplots(figsize=(6.0, 4.0), dpi=150)
    styles = estimator_styles(curves["estimator"])
    for name, group in curves.groupby("estimator"):
        group = group[np.isfinite(group["horizontal_median_ref"])].sort_values("scale")
        median = group["horizontal_median_ref"]
        ax.errorbar(
            group["scale"],
            median,
            yerr=[median - group["ci_low"], group["ci_high"] - median],
            marker="o",
            capsize=3,
            label=name,
            **styles[name],
        )
    ax.set_xscale("log")
    ax.set_xlabel("a priori covariance scale s")
    ax.set_ylabel("median horizontal error [m]\n(over reference epochs)")
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


def validation_figure(samples: Sequence[ValidationSample], path: str | Path, title: str, bin_deg: float = 10.0) -> Path:
    """Sim-vs-real panels (:mod:`simbench.analysis.validation`): ECDF of the |code residual|, C/N0 median
    (and 10-90 % band) against elevation, and the distribution of tracked satellites per epoch.

    Each world keeps one colour and line style (:func:`estimator_styles` on the world names); a
    real log is drawn thicker. The fourth panel holds the legend.
    """
    styles = estimator_styles(s.name for s in samples)
    fig, grid = plt.subplots(2, 2, figsize=(11.0, 8.0), dpi=150)
    ecdf_ax, cn0_ax, sats_ax, legend_ax = grid.ravel()
    for sample in samples:
        style = {**styles[sample.name], "linewidth": 2.4 if sample.real else 1.4}
        res = np.sort(sample.abs_residual)
        if len(res):
            ecdf_ax.plot(res, np.arange(1, len(res) + 1) / len(res), **style)
        bins = cn0_by_elevation(sample, bin_deg)
        centre = 0.5 * (bins["el_low"] + bins["el_high"])
        cn0_ax.plot(centre, bins["cn0_p50"], marker="o", markersize=3, **style)
        cn0_ax.fill_between(centre, bins["cn0_p10"], bins["cn0_p90"], color=style["color"], alpha=0.12)
        counts = np.bincount(sample.tracked_per_epoch)
        sats_ax.plot(
            np.arange(len(counts)), counts / max(counts.sum(), 1), marker="o", markersize=4, label=sample.name, **style
        )
    ecdf_ax.set_xscale("log")
    # the median satellite of an epoch has residual 0 exactly: those rows sit left of the axis
    ecdf_ax.set_xlim(left=1e-2)
    ecdf_ax.set_xlabel("|code residual| [m] (per-epoch, per-system median clock)")
    ecdf_ax.set_ylabel("ECDF")
    cn0_ax.set_xlabel(f"elevation [deg] ({bin_deg:g} deg bins)")
    cn0_ax.set_ylabel("C/N0 [dB-Hz] (median, 10-90 % band)")
    sats_ax.set_xlabel("tracked satellites per reference epoch")
    sats_ax.set_ylabel("share of epochs")
    sats_ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    for ax in (ecdf_ax, cn0_ax, sats_ax):
        ax.grid(True, which="both", alpha=0.3)
    legend_ax.axis("off")
    legend_ax.legend(
        *sats_ax.get_legend_handles_labels(),
        loc="center",
        fontsize=9,
        frameon=False,
        ncols=1 if len(samples) <= 12 else 2,
    )
    fig.suptitle(_wrap(fig, title, 11), fontsize=11)
    return _save(fig, path)
