"""Trajectory and time views of one run (one scenario and seed): where each estimator was, when it
was wrong, what the receiver saw, and whether its covariance believed it.

Every view is drawn over the scenario's reference epochs, so an epoch an
estimator did not solve is a gap in its line (a NaN breaks it), never a
straight segment across. Curves are styled as in :mod:`simbench.report.figures`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.collections import LineCollection
from matplotlib.colors import LogNorm
from matplotlib.ticker import MaxNLocator
from scipy import stats

from simbench.report.figures import (
    PANEL_TITLE_Y,
    PNG_DPI,
    FigureFile,
    Format,
    estimator_styles,
    figsize,
    grid_axes,
    log_ticks,
    save_figure,
    style_record,
)
from simbench.report.style import REFERENCE_COLOR, line_only

#: Degrees of freedom of the position NEES (east, north, up).
NEES_DOF = 3
#: Two-sided probability of the chi-square band a consistent estimator's NEES stays in.
NEES_BAND = 0.95


def nees_band(dof: int = NEES_DOF, probability: float = NEES_BAND) -> tuple[float, float]:
    """Lower and upper bound of the central ``probability`` of a chi-square with ``dof`` degrees of freedom."""
    tail = (1.0 - probability) / 2.0
    return float(stats.chi2.ppf(tail, dof)), float(stats.chi2.ppf(1.0 - tail, dof))


@dataclass(frozen=True)
class SeedEpochs:
    """One seed's estimates as the time views draw them."""

    #: ``epochs.parquet`` rows of one seed: ``estimator`` (curve name), ``epoch`` and the drawn columns
    epochs: pd.DataFrame
    #: legend and panel order (the leaderboard's); names not in it follow, sorted
    order: Sequence[str] = ()
    #: files to write: PNG at the figure's path, other formats beside it
    formats: Sequence[Format] = ("png",)

    @property
    def names(self) -> list[str]:
        """The estimators present, in :attr:`order` and then sorted."""
        present = set(self.epochs["estimator"].unique())
        return [n for n in self.order if n in present] + sorted(present - set(self.order))


def _on_reference(rows: pd.DataFrame, reference: pd.DataFrame, columns: Sequence[str]) -> pd.DataFrame:
    """``columns`` of one estimator's rows at every reference epoch: NaN where it did not solve (a gap)."""
    return reference[["epoch", "t"]].merge(rows[["epoch", *columns]], on="epoch", how="left")


def trajectory_figure(seed: SeedEpochs, reference: pd.DataFrame | None, path: str | Path, title: str) -> FigureFile:
    """Reference and estimated trajectories in local east/north, one small panel per estimator, each
    estimate's line coloured by its horizontal error on one log scale; an unsolved epoch breaks the line.

    Parameters
    ----------
    seed : SeedEpochs
        One seed's ``epochs.parquet`` rows: ``estimator`` (curve name), ``epoch``, ``east``, ``north``,
        ``horizontal`` [m].
    reference : pandas.DataFrame or None
        The reference epochs: ``epoch``, ``east``, ``north`` [m] in the same local frame; None when the
        scenario is not in the run's cache (then only the estimates are drawn, and only solved epochs
        that follow each other are joined).
    path : path-like
        PNG to write (other formats beside it).
    title : str
        Caption for the report (not drawn).
    """
    epochs, names = seed.epochs, seed.names
    fig, axes = grid_axes(len(names), 1.9, 1.9, ncols=TRAJECTORY_COLUMNS, sharex=True, sharey=True)
    errors = epochs["horizontal"].to_numpy(float)
    positive = errors[np.isfinite(errors) & (errors > 0)]
    norm = LogNorm(vmin=max(positive.min(), 1e-2), vmax=max(positive.max(), 1e-1)) if positive.size else None
    epochs_of = reference[["epoch"]] if reference is not None else None
    lines = None
    for ax, name in zip(axes, names):
        if reference is not None:
            ax.plot(reference["east"], reference["north"], color=REFERENCE_COLOR, lw=0.6)
        rows = epochs[epochs["estimator"] == name].sort_values("epoch")
        lines = ax.add_collection(error_segments(rows, epochs_of, norm))
        ax.set_title(name, y=PANEL_TITLE_Y, fontsize="small")
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, alpha=0.3)
        ax.set_xlabel("east [m]")
        ax.set_ylabel("north [m]")
        ax.label_outer()  # shared axes: the outer panels carry the labels
    for ax in axes:
        ax.autoscale_view()
    for ax in axes[-TRAJECTORY_COLUMNS:]:  # the last row, and a panel over an empty place, keep east labelled
        ax.tick_params(labelbottom=True)
        ax.set_xlabel("east [m]")
    if lines is not None and norm is not None:
        bar = fig.colorbar(lines, ax=axes, shrink=0.6, label="horizontal error [m]")
        log_ticks(bar.ax.yaxis)
    return save_figure(
        fig,
        path,
        f"{title} (black: reference; local east/north at the first reference point; each estimate coloured "
        "by its horizontal error; gaps: epochs not solved)",
        seed.formats,
    )


#: Panels per row of the trajectory's small multiples.
TRAJECTORY_COLUMNS = 6


def error_segments(rows: pd.DataFrame, reference: pd.DataFrame | None, norm: LogNorm | None) -> LineCollection:
    """One estimator's track as segments between solved epochs that follow each other, coloured by the
    horizontal error of the later one: no segment crosses an unsolved epoch."""
    if reference is not None:
        rows = reference.merge(rows[["epoch", "east", "north", "horizontal"]], on="epoch", how="left")
        follows = np.ones(max(len(rows) - 1, 0), bool)
    else:  # without the reference epochs, a jump in the epoch index is a gap
        follows = np.diff(rows["epoch"].to_numpy()) == 1
    xy = rows[["east", "north"]].to_numpy(float)
    ends = np.stack([xy[:-1], xy[1:]], axis=1)
    keep = follows & np.isfinite(ends).all(axis=(1, 2))
    lines = LineCollection(list(ends[keep]), cmap="viridis", norm=norm, linewidths=1.0)
    lines.set_array(rows["horizontal"].to_numpy(float)[1:][keep])
    return lines


def altitude_figure(seed: SeedEpochs, reference: pd.DataFrame, path: str | Path, title: str) -> FigureFile:
    """Altitude (local up) against time: the reference and every estimate (legend in ``seed.order``, the
    leaderboard's), unsolved epochs as gaps.

    Parameters
    ----------
    seed : SeedEpochs
        One seed's rows: ``estimator``, ``epoch``, ``up`` [m].
    reference : pandas.DataFrame
        The reference epochs: ``epoch``, ``t`` [s] and ``up`` [m] in the same local frame.
    """
    epochs, names = seed.epochs, seed.names
    styles = estimator_styles(names)
    fig, ax = plt.subplots(figsize=figsize(7.0, 3.0), dpi=PNG_DPI)
    ax.plot(reference["t"], reference["up"], color=REFERENCE_COLOR, lw=1.4, label="reference")
    for name in names:
        rows = _on_reference(epochs[epochs["estimator"] == name], reference, ["up"])
        ax.plot(rows["t"], rows["up"], lw=0.8, label=name, **line_only(styles[name]))
    ax.set_xlabel("GPS time since the first epoch [s]")
    ax.set_ylabel("up (local, from the first reference point) [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False, ncols=1 if len(names) <= 20 else 2)
    return save_figure(fig, path, f"{title} (black: reference; gaps: epochs not solved)", seed.formats)


#: A reference whose local up spans more than this gets an altitude view [m]: a flight, not a drive.
ALTITUDE_SPAN_M = 30.0


def enu_error_figure(seed: SeedEpochs, reference: pd.DataFrame, path: str | Path, title: str) -> FigureFile:
    """East, north and up error against time: three stacked panels, one line per estimator, the legend
    in ``order`` (the leaderboard's); unsolved epochs are gaps. Each panel's scale holds the
    :data:`ENU_CLIP_PERCENTILE` % of every estimator's errors nearest zero, so one estimator's spikes
    do not flatten the others (the caption says how many epochs lie beyond).

    Parameters
    ----------
    seed : SeedEpochs
        One seed's rows: ``estimator``, ``epoch``, ``e``, ``n``, ``u`` [m].
    reference : pandas.DataFrame
        The scenario's reference epochs: ``epoch`` and ``t`` (GPS time since the first epoch [s]).
    """
    epochs, names = seed.epochs, seed.names
    styles = estimator_styles(names)
    fig, axes = plt.subplots(3, 1, figsize=figsize(7.5, 5.4), dpi=PNG_DPI, sharex=True)
    beyond = 0
    for ax, column, label in zip(axes, ("e", "n", "u"), ("east", "north", "up")):
        for name in reversed(names):  # the leaderboard's first drawn last, on top
            rows = _on_reference(epochs[epochs["estimator"] == name], reference, [column])
            ax.plot(rows["t"], rows[column], lw=0.8, label=name, **line_only(styles[name]))
        values = np.abs(epochs[column].to_numpy(float))
        values = values[np.isfinite(values)]
        if values.size:
            limit = 1.1 * max(float(np.percentile(values, ENU_CLIP_PERCENTILE)), 1e-2)
            ax.set_ylim(-limit, limit)
            beyond += int((values > limit).sum())
        ax.axhline(0.0, color=REFERENCE_COLOR, lw=0.5)
        ax.set_ylabel(f"{label} error [m]")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("GPS time since the first epoch [s]")
    handles, labels = axes[0].get_legend_handles_labels()
    axes[0].legend(
        handles[::-1],
        labels[::-1],
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        frameon=False,
        ncols=1 + len(names) // 21,
    )
    clipped = f"; {beyond} epoch errors beyond the scale, cut off" if beyond else ""
    return save_figure(fig, path, f"{title} (gaps: epochs not solved{clipped})", seed.formats)


#: The E/N/U error panels' scale holds this percentile of all estimators' absolute errors [%].
ENU_CLIP_PERCENTILE = 99.0


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
        figsize=figsize(7.0, 3.6 + 0.16 * len(names)),
        dpi=PNG_DPI,
        sharex=True,
        height_ratios=[1.0, 1.0, 0.3 + 0.08 * len(names)],
    )
    sats.step(signal["t"], signal["n_sats"], where="mid", lw=0.8, color="black")
    sats.set_ylabel("satellites\ntracked")
    sats.yaxis.set_major_locator(MaxNLocator(integer=True))
    cn0.fill_between(signal["t"], signal["cn0_p10"], signal["cn0_p90"], color="tab:blue", alpha=0.2, lw=0)
    cn0.plot(signal["t"], signal["cn0_p50"], lw=0.8, color="tab:blue")
    cn0.set_ylabel("C/N0 [dB-Hz]\n(median, 10-90 %)")
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
    solved.set_yticks(range(len(names)), names)
    solved.set_ylim(-0.6, len(names) - 0.4)
    solved.invert_yaxis()
    solved.set_xlabel("GPS time since the first epoch [s]")
    for ax in (sats, cn0, solved):
        ax.grid(True, axis="x", alpha=0.3)
        ax.tick_params(labelsize=7)
    figure = save_figure(
        fig, path, f"{title} (satellites tracked, C/N0, and the epochs each estimator solved)", formats
    )
    return replace(figure, series=tuple(names), styles=style_record({n: styles[n] for n in names}))


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
    fig, ax = plt.subplots(figsize=figsize(7.0, 3.2), dpi=PNG_DPI)
    styles = estimator_styles(names)
    for name in names:
        rows = _on_reference(epochs[epochs["estimator"] == name], reference, ["nees"])
        values = rows["nees"].to_numpy(float)
        finite = values[np.isfinite(values)]
        inside = float(np.mean((finite >= low) & (finite <= high))) if finite.size else np.nan
        label = f"{name} ({inside:.0%} inside)".replace("%", " %")
        ax.plot(rows["t"], values, lw=0.8, label=label, **line_only(styles[name]))
    ax.axhspan(low, high, color="tab:green", alpha=0.12, lw=0)
    for bound in (low, high):
        ax.axhline(bound, color="tab:green", lw=0.8, ls="--")
    ax.set_yscale("log")
    log_ticks(ax.yaxis)
    ax.set_xlabel("GPS time since the first epoch [s]")
    ax.set_ylabel(f"position NEES (chi-square, {NEES_DOF} dof)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right")
    return save_figure(
        fig,
        path,
        f"{title} (green: central {NEES_BAND:.0%} chi-square band [{low:.2f}, {high:.2f}])".replace("%", " %"),
        formats,
    )
