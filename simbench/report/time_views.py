"""Trajectory and time views of one run (one scenario and seed): where each estimator was, when it
was wrong, what the receiver saw, and whether its covariance believed it.

Every view is drawn over the scenario's reference epochs, so an epoch an
estimator did not solve is a gap in its line (a NaN breaks it), never a
straight segment across. Curves are styled as in :mod:`simbench.report.figures`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.colors import LogNorm
from matplotlib.ticker import MaxNLocator
from scipy import stats

from simbench.report.figures import (
    PANEL_TITLE_Y,
    PNG_DPI,
    SMALL_MULTIPLES_ABOVE,
    FigureFile,
    Format,
    estimator_of,
    estimator_styles,
    grid_axes,
    plain_log_ticks,
    save_figure,
)
from simbench.report.style import by_family

#: Degrees of freedom of the position NEES (east, north, up).
NEES_DOF = 3
#: Two-sided probability of the chi-square band a consistent estimator's NEES stays in.
NEES_BAND = 0.95
#: Panels per row of the small multiples.
COLUMNS = 3


def nees_band(dof: int = NEES_DOF, probability: float = NEES_BAND) -> tuple[float, float]:
    """Lower and upper bound of the central ``probability`` of a chi-square with ``dof`` degrees of freedom."""
    tail = (1.0 - probability) / 2.0
    return float(stats.chi2.ppf(tail, dof)), float(stats.chi2.ppf(1.0 - tail, dof))


def _on_reference(rows: pd.DataFrame, reference: pd.DataFrame, columns: Sequence[str]) -> pd.DataFrame:
    """``columns`` of one estimator's rows at every reference epoch: NaN where it did not solve (a gap)."""
    return reference[["epoch", "t"]].merge(rows[["epoch", *columns]], on="epoch", how="left")


def trajectory_figure(
    epochs: pd.DataFrame,
    reference: pd.DataFrame | None,
    path: str | Path,
    title: str,
    formats: Sequence[Format] = ("png",),
) -> FigureFile:
    """Reference and estimated trajectories in local east/north.

    Up to :data:`~simbench.report.figures.SMALL_MULTIPLES_ABOVE` estimators: one panel each, its
    estimates coloured by horizontal error; beyond, one panel per family, each estimator a line in
    its own style (colouring by error cannot tell overlapping estimators apart).

    Parameters
    ----------
    epochs : pandas.DataFrame
        One seed's ``epochs.parquet`` rows: ``estimator`` (curve name), ``east``, ``north``, ``horizontal`` [m].
    reference : pandas.DataFrame or None
        The reference trajectory: ``east``, ``north`` [m] in the same local frame; None when the
        scenario is not in the run's cache (then only the estimates are drawn).
    path : path-like
        PNG to write (other formats beside it).
    title : str
        Caption for the report (not drawn).
    formats : sequence of str
    """
    names = sorted(epochs["estimator"].unique())
    by_error = len(names) <= SMALL_MULTIPLES_ABOVE
    panels = [(n, [n]) for n in names] if by_error else list(by_family({n: estimator_of(n) for n in names}).items())
    fig, axes = grid_axes(len(panels), 3.2, 3.0, ncols=COLUMNS, sharex=True, sharey=True)
    errors = epochs["horizontal"].to_numpy(float)
    positive = errors[np.isfinite(errors) & (errors > 0)]
    norm = LogNorm(vmin=max(positive.min(), 1e-2), vmax=max(positive.max(), 1e-1)) if positive.size else None
    styles = estimator_styles(names)
    scatter = None
    for ax, (panel, members) in zip(axes, panels):
        if reference is not None:
            ax.plot(reference["east"], reference["north"], color="black", lw=0.8, label="reference")
        for name in members:
            rows = epochs[epochs["estimator"] == name].sort_values("epoch")
            if by_error:
                scatter = ax.scatter(
                    rows["east"], rows["north"], c=rows["horizontal"], s=3, cmap="viridis", norm=norm, linewidths=0
                )
            else:
                ax.plot(rows["east"], rows["north"], lw=0.8, label=name, **styles[name])
        ax.set_title(panel, fontsize=8, y=PANEL_TITLE_Y)
        if not by_error:
            ax.legend(fontsize=6, loc="best")
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=7)
        ax.set_xlabel("east [m]", fontsize=7)
        ax.set_ylabel("north [m]", fontsize=7)
        ax.label_outer()  # shared axes: the outer panels carry the labels
    if scatter is not None:
        bar = fig.colorbar(scatter, ax=axes, shrink=0.8, label="horizontal error [m]")
        plain_log_ticks(bar.ax.yaxis)
    how = "estimates coloured by horizontal error" if by_error else "one panel per family"
    return save_figure(
        fig, path, f"{title} (black: reference; local east/north at the first reference point; {how})", formats
    )


def enu_error_figure(
    epochs: pd.DataFrame, reference: pd.DataFrame, path: str | Path, title: str, formats: Sequence[Format] = ("png",)
) -> FigureFile:
    """East, north and up error against time: three stacked panels, one line per estimator; unsolved
    epochs are gaps.

    Parameters
    ----------
    epochs : pandas.DataFrame
        One seed's rows: ``estimator``, ``epoch``, ``e``, ``n``, ``u`` [m].
    reference : pandas.DataFrame
        The scenario's reference epochs: ``epoch`` and ``t`` (GPS time since the first epoch [s]).
    """
    names = sorted(epochs["estimator"].unique())
    styles = estimator_styles(names)
    fig, axes = plt.subplots(3, 1, figsize=(7.5, 5.4), dpi=PNG_DPI, sharex=True)
    for name in names:
        rows = _on_reference(epochs[epochs["estimator"] == name], reference, ["e", "n", "u"])
        for ax, column in zip(axes, ("e", "n", "u")):
            ax.plot(rows["t"], rows[column], lw=0.8, label=name, **styles[name])
    for ax, label in zip(axes, ("east", "north", "up")):
        ax.axhline(0.0, color="black", lw=0.5)
        ax.set_ylabel(f"{label} error [m]", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=7)
    axes[-1].set_xlabel("GPS time since the first epoch [s]", fontsize=8)
    axes[0].legend(
        loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False, ncols=1 if len(names) <= 20 else 2
    )
    return save_figure(fig, path, f"{title} (gaps: epochs not solved)", formats)


def signal_figure(
    signal: pd.DataFrame,
    epochs: pd.DataFrame,
    reference: pd.DataFrame,
    path: str | Path,
    title: str,
    formats: Sequence[Format] = ("png",),
) -> FigureFile:
    """Satellites tracked, C/N0 and each estimator's availability against time.

    Parameters
    ----------
    signal : pandas.DataFrame
        Per epoch: ``t`` [s], ``n_sats``, ``cn0_p10``, ``cn0_p50``, ``cn0_p90`` [dB-Hz]
        (:func:`signal_per_epoch`).
    epochs : pandas.DataFrame
        One seed's rows: ``estimator``, ``epoch``.
    reference : pandas.DataFrame
        ``epoch`` and ``t`` of the reference epochs.
    """
    names = sorted(epochs["estimator"].unique())
    fig, (sats, cn0, solved) = plt.subplots(
        3,
        1,
        figsize=(7.0, 3.6 + 0.16 * len(names)),
        dpi=PNG_DPI,
        sharex=True,
        height_ratios=[1.0, 1.0, 0.3 + 0.08 * len(names)],
    )
    sats.step(signal["t"], signal["n_sats"], where="mid", lw=0.8, color="black")
    sats.set_ylabel("satellites\ntracked", fontsize=7)
    sats.yaxis.set_major_locator(MaxNLocator(integer=True))
    cn0.fill_between(signal["t"], signal["cn0_p10"], signal["cn0_p90"], color="tab:blue", alpha=0.2, lw=0)
    cn0.plot(signal["t"], signal["cn0_p50"], lw=0.8, color="tab:blue")
    cn0.set_ylabel("C/N0 [dB-Hz]\n(median, 10-90 %)", fontsize=7)
    styles = estimator_styles(names)
    t = reference["t"].to_numpy(float)
    step = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    for row, name in enumerate(names):
        done = reference["epoch"].isin(epochs.loc[epochs["estimator"] == name, "epoch"]).to_numpy()
        # one bar per run of solved epochs (not per epoch: thousands of bars are slow to draw);
        # gaps show where the estimator gave no solution
        edges = np.flatnonzero(np.diff(np.r_[0, done.astype(np.int8), 0]))
        runs = [(t[a] - step / 2, t[b - 1] - t[a] + step) for a, b in zip(edges[::2], edges[1::2])]
        solved.broken_barh(runs, (row - 0.4, 0.8), color=styles[name]["color"])
    solved.set_yticks(range(len(names)), names, fontsize=7)
    solved.set_ylim(-0.6, len(names) - 0.4)
    solved.invert_yaxis()
    solved.set_xlabel("GPS time since the first epoch [s]", fontsize=7)
    for ax in (sats, cn0, solved):
        ax.grid(True, axis="x", alpha=0.3)
        ax.tick_params(labelsize=7)
    figure = save_figure(
        fig, path, f"{title} (satellites tracked, C/N0, and the epochs each estimator solved)", formats
    )
    return FigureFile(figure.files, figure.title, tuple(names), figure.legend)


def signal_per_epoch(observations: pd.DataFrame, reference: pd.DataFrame) -> pd.DataFrame:
    """Satellites tracked and C/N0 percentiles per reference epoch (0 satellites where none was tracked).

    Parameters
    ----------
    observations : pandas.DataFrame
        Columns ``epoch``, ``sat``, ``cn0_l1`` [dB-Hz].
    reference : pandas.DataFrame
        ``epoch`` and ``t`` of the reference epochs.

    Returns
    -------
    pandas.DataFrame
        ``epoch``, ``t``, ``n_sats``, ``cn0_p10``, ``cn0_p50``, ``cn0_p90``.
    """
    grouped = observations.groupby("epoch")
    per_epoch = pd.DataFrame(
        {
            "n_sats": grouped["sat"].nunique(),
            "cn0_p10": grouped["cn0_l1"].quantile(0.1),
            "cn0_p50": grouped["cn0_l1"].median(),
            "cn0_p90": grouped["cn0_l1"].quantile(0.9),
        }
    ).reset_index()
    out = reference[["epoch", "t"]].merge(per_epoch, on="epoch", how="left")
    return out.fillna({"n_sats": 0})


def consistency_figure(
    epochs: pd.DataFrame, reference: pd.DataFrame, path: str | Path, title: str, formats: Sequence[Format] = ("png",)
) -> FigureFile:
    """Position NEES against time per estimator with a covariance, and the chi-square band.

    A consistent estimator's NEES (``nees`` column, 3 degrees of freedom) stays inside the
    central 95 % band about 95 % of the time; above it the covariance is too optimistic,
    below it too pessimistic. The legend gives each estimator's share inside.

    Parameters
    ----------
    epochs : pandas.DataFrame
        One seed's rows with ``estimator``, ``epoch``, ``nees``; estimators without a NaN-free
        ``nees`` are left out by the caller.
    reference : pandas.DataFrame
        ``epoch`` and ``t`` of the reference epochs.
    """
    names = sorted(epochs["estimator"].unique())
    low, high = nees_band()
    fig, ax = plt.subplots(figsize=(7.0, 3.2), dpi=PNG_DPI)
    styles = estimator_styles(names)
    for name in names:
        rows = _on_reference(epochs[epochs["estimator"] == name], reference, ["nees"])
        values = rows["nees"].to_numpy(float)
        finite = values[np.isfinite(values)]
        inside = float(np.mean((finite >= low) & (finite <= high))) if finite.size else np.nan
        ax.plot(rows["t"], values, lw=0.8, label=f"{name} ({inside:.0%} inside)".replace("%", " %"), **styles[name])
    ax.axhspan(low, high, color="tab:green", alpha=0.12, lw=0)
    for bound in (low, high):
        ax.axhline(bound, color="tab:green", lw=0.8, ls="--")
    ax.set_yscale("log")
    plain_log_ticks(ax.yaxis)
    ax.set_xlabel("GPS time since the first epoch [s]")
    ax.set_ylabel(f"position NEES (chi-square, {NEES_DOF} dof)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    return save_figure(
        fig,
        path,
        f"{title} (green: central {NEES_BAND:.0%} chi-square band [{low:.2f}, {high:.2f}])".replace("%", " %"),
        formats,
    )
