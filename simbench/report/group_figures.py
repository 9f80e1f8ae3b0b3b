"""The figures of one (sweep, scenario, receiver) group of a report, and the worker processes that draw them.

Drawing is most of a large report's time (a 5-world thesis: 194 figures, about 77 of its
100 s of CPU) and the groups are independent, so :class:`GroupDrawing` draws them in worker
processes. The workers start before the parent reads the results store, so their imports
overlap that reading, and they draw while the parent computes the claims and tables.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import pandas as pd

from estimators import registered
from simbench.analysis.metrics import local_enu
from simbench.analysis.variants import config_defaults, override_value
from simbench.report.figures import (
    FigureFile,
    Format,
    box_figure,
    ecdf_figure,
    family_ecdf_figure,
    runtime_figure,
    sensitivity_figure,
)
from simbench.report.leaderboard import ranked
from simbench.report.style import use_style
from simbench.report.time_views import (
    ALTITUDE_SPAN_M,
    SeedEpochs,
    altitude_figure,
    consistency_figure,
    enu_error_figure,
    signal_figure,
    signal_per_epoch,
    trajectory_figure,
)

__all__ = ["MIN_PARALLEL_GROUPS", "GroupDrawing", "GroupInputs", "Item", "draw_group"]


@dataclass
class GroupInputs:
    """What the figures and tables of one (sweep, scenario, receiver) group are drawn from."""

    name: str  #: heading, e.g. 'urban, receiver low (sweep ch5_bce)'
    tag: str  #: file-name part of its figures
    group: pd.DataFrame  #: its ok epochs
    shown: pd.DataFrame  #: the same, ``estimator`` replaced by the variant name
    in_group: pd.DataFrame  #: its summary rows
    n_reference: dict[str, int]  #: reference epochs per variant name
    group_stats: pd.DataFrame  #: its rows of the statistics over seeds

    def for_drawing(self) -> GroupInputs:
        """This group with only what its figures read (:data:`DRAWN_COLUMNS`): what a worker is sent."""
        columns = [c for c in DRAWN_COLUMNS if c in self.shown.columns]
        return replace(self, group=self.group.iloc[:0], shown=self.shown[columns], in_group=self.in_group.iloc[:0])


#: The epoch columns a group's figures read. A worker is sent only these: a 5-world thesis sends about
#: 600k epoch rows, and the positions, covariances and labels the figures do not read were most of them.
DRAWN_COLUMNS = (
    "estimator",
    "seed",
    "scenario_key",
    "epoch",
    "t",
    "east",
    "north",
    "up",
    "e",
    "n",
    "u",
    "horizontal",
    "error_3d",
    "nees",
)


#: What drawing a group's figures yields for the page, in order: a figure, or a note (text, class).
Item = FigureFile | tuple[str, str]


class Recorder:
    """The figure part of :class:`_Page` for a worker process: records figures and notes in order."""

    def __init__(self, formats: tuple[Format, ...], style: str = "screen") -> None:
        self.formats = formats
        self.style = style
        self.items: list[Item] = []

    @property
    def fmt(self) -> dict[str, Any]:
        return {"formats": self.formats}

    def figure(self, figure: FigureFile) -> None:
        self.items.append(figure)

    def p(self, text: str, cls: str = "") -> None:
        self.items.append((text, cls))


def draw_group(task: tuple[GroupInputs, Path, tuple[Format, ...], Mapping[str, Path], str]) -> list[Item]:
    """Draw one group's figures (:func:`group_figures`) in the ``report.style`` preset the task names;
    what they give the page, in order."""
    inputs, out, formats, scenarios, style = task
    recorder = Recorder(formats, style)
    with use_style(style):
        group_figures(recorder, out, inputs, scenarios)
    return recorder.items


#: Fewer groups are drawn in this process: a spawned worker costs ~3 s of imports, a group ~1-5 s of drawing.
MIN_PARALLEL_GROUPS = 6


def _curves(inputs: GroupInputs) -> int:
    """Curves times epochs of a group: how long its figures take to draw, roughly."""
    return int(inputs.shown["estimator"].nunique()) * len(inputs.shown)


def _ready() -> None:
    """A first task: it makes the pool spawn a worker, which imports this module while it waits."""


class GroupDrawing:
    """Draws groups' figures (:func:`draw_group`), in worker processes when ``parallel``.

    The workers are spawned when this is created, one per CPU this process may use (spawned,
    not forked: the parent holds pyarrow's and BLAS's threads). Use it as a context manager: on
    leaving, groups not yet drawn are cancelled and the workers stop.

    Parameters
    ----------
    parallel : bool
        Start worker processes (only with two CPUs or more); False: each group is drawn in this
        process when its figures are asked for.
    """

    def __init__(self, parallel: bool) -> None:
        cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        self._pool: ProcessPoolExecutor | None = None
        if parallel and cpus >= 2:
            self._pool = ProcessPoolExecutor(cpus, mp_context=multiprocessing.get_context("spawn"))
            for _ in range(cpus):
                self._pool.submit(_ready)

    def __enter__(self) -> GroupDrawing:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)

    def start(
        self,
        groups: Sequence[GroupInputs],
        out: Path,
        formats: tuple[Format, ...],
        scenarios: Mapping[str, Path],
        draw: bool = True,
        style: str = "screen",
    ) -> Callable[[], list[list[Item]]]:
        """Start drawing every group's figures into ``out`` in the ``style`` preset; the returned call
        waits for them.

        ``draw=False`` draws nothing: the call gives every group an empty list.

        Returns
        -------
        callable
            Gives, per group in order, what its figures give the page (:func:`draw_group`). Fewer
            than :data:`MIN_PARALLEL_GROUPS` groups, or no workers: drawn in this process by that call.
        """
        tasks = [(g, out, formats, scenarios, style) for g in groups]
        if not draw:
            return lambda: [[] for _ in tasks]
        if self._pool is None or len(tasks) < MIN_PARALLEL_GROUPS:
            return lambda: [draw_group(t) for t in tasks]
        # the groups with the most curves first: the last group to finish is then a small one, and no
        # worker idles while another draws a 24-curve sensitivity study
        futures: dict[int, Future[list[Item]]] = {
            k: self._pool.submit(draw_group, (groups[k].for_drawing(), out, formats, scenarios, style))
            for k in sorted(range(len(tasks)), key=lambda k: -_curves(groups[k]))
        }
        return lambda: [futures[k].result() for k in range(len(tasks))]


def group_figures(page: Recorder, out: Path, inputs: GroupInputs, scenarios: Mapping[str, Path]) -> None:
    """A group's figures: the comparison ECDF, the per-family ECDFs, box plot, time views, prior-scale
    sensitivity and run time."""
    tag, name, shown, n_reference, group_stats = (
        inputs.tag,
        inputs.name,
        inputs.shown,
        inputs.n_reference,
        inputs.group_stats,
    )
    metrics = {"horizontal": "horizontal_median_ref", "error_3d": "error_3d_median_ref"}
    medians = {m: dict(zip(group_stats["name"], group_stats[column])) for m, column in metrics.items()}
    order = [str(n) for n in ranked(group_stats)["name"]]
    page.figure(
        ecdf_figure(
            shown,
            list(metrics),
            out / f"ecdf_{tag}.png",
            f"ECDF of the horizontal (left) and 3-D (right) error, every estimator: {name}; legend in leaderboard "
            "order: availability, then the leaderboard's median horizontal / 3-D error",
            n_reference,
            medians,
            page.formats,
        )
    )
    page.figure(
        family_ecdf_figure(
            shown,
            "horizontal",
            out / f"ecdf_family_{tag}.png",
            f"ECDF of the horizontal error, one panel per family: {name}",
            n_reference,
            medians["horizontal"],
            page.formats,
        )
    )
    page.figure(
        box_figure(
            shown,
            out / f"box_{tag}.png",
            f"Horizontal error per estimator: {name} (leaderboard order)",
            n_reference,
            order=order,
            **page.fmt,
        )
    )
    time_views(page, out, tag, name, shown, scenarios, order)
    sensitivity = sensitivity_curves(group_stats)
    if sensitivity is not None:
        page.figure(
            sensitivity_figure(
                sensitivity,
                out / f"sensitivity_{tag}.png",
                f"Sensitivity to the a priori covariance: {name}",
                **page.fmt,
            )
        )
    if group_stats["time_per_obs_s"].notna().any():
        timed = group_stats.assign(estimator=group_stats["name"])
        page.figure(runtime_figure(timed, out / f"runtime_{tag}.png", f"Run time: {name}", **page.fmt))


def shown_seeds(shown: pd.DataFrame) -> list[tuple[int, str]]:
    """The seeds whose time views are drawn, each with what it is: the only seed, or the worst and the best
    (highest and lowest median horizontal error over the solved epochs of every estimator)."""
    medians = shown.groupby("seed", observed=True)["horizontal"].median().dropna()
    if len(medians) < 2:
        return [(int(shown["seed"].min()), "")]
    return [
        (int(medians.idxmax()), f"the worst of {len(medians)} seeds"),
        (int(medians.idxmin()), f"the best of {len(medians)} seeds"),
    ]


def time_views(
    page: Recorder,
    out: Path,
    tag: str,
    name: str,
    shown: pd.DataFrame,
    scenarios: Mapping[str, Path],
    order: Sequence[str] = (),
) -> None:
    """Trajectory (with altitude for a flight) and E/N/U error against time of the worst and the best seed
    (:func:`shown_seeds`); satellites and consistency of the worst."""
    for k, (seed, which) in enumerate(shown_seeds(shown)):
        one = shown[shown["seed"] == seed]
        key = str(one["scenario_key"].iloc[0])
        one = one[one["scenario_key"] == key]
        cache = scenarios.get(key)
        truth = pd.read_parquet(cache / "truth.parquet", columns=["epoch", "t", "x", "y", "z"]) if cache else None
        if truth is not None and len(truth):
            xyz = truth[["x", "y", "z"]].to_numpy(float)
            east, north, up = local_enu(xyz, xyz[0]).T
            reference = truth[["epoch", "t"]].assign(east=east, north=north, up=up)
        else:  # not in this run's cache (e.g. a scored solution's run moved): the estimates alone
            reference = one[["epoch", "t"]].drop_duplicates("epoch").sort_values("epoch")
        where = f"{name}, seed {seed}" + (f" ({which})" if which else "")
        suffix = tag if k == 0 else f"{tag}_best"
        track = reference if "east" in reference else None
        view = SeedEpochs(one, order, page.formats)
        if {"east", "north"} <= set(one.columns) and one["east"].notna().any():
            page.figure(trajectory_figure(view, track, out / f"trajectory_{suffix}.png", f"Trajectory: {where}"))
        if track is not None and "up" in one and np.ptp(track["up"].to_numpy(float)) > ALTITUDE_SPAN_M:
            page.figure(altitude_figure(view, track, out / f"altitude_{suffix}.png", f"Altitude: {where}"))
        page.figure(enu_error_figure(view, reference, out / f"enu_time_{suffix}.png", f"Error against time: {where}"))
        if k == 0:
            _signal_and_consistency(page, out, tag, where, one, reference, cache)


def _signal_and_consistency(
    page: Recorder, out: Path, tag: str, where: str, one: pd.DataFrame, reference: pd.DataFrame, cache: Path | None
) -> None:
    """Satellites, C/N0 and availability against time, and the covariance consistency, of one seed."""
    if cache is not None:
        observations = pd.read_parquet(cache / "observations.parquet", columns=["epoch", "sat", "cn0_l1"])
        page.figure(
            signal_figure(
                signal_per_epoch(observations, reference),
                one,
                reference,
                out / f"signal_time_{tag}.png",
                f"Satellites, C/N0 and availability against time: {where}",
                **page.fmt,
            )
        )
    with_cov = one["nees"].notna().groupby(one["estimator"], observed=True).any() if "nees" in one else pd.Series()
    covered = sorted(with_cov[with_cov].index)
    if covered:
        page.figure(
            consistency_figure(
                one[one["estimator"].isin(covered)],
                reference,
                out / f"consistency_{tag}.png",
                f"Consistency of the position covariance: {where}",
                **page.fmt,
            )
        )
    others = sorted(set(one["estimator"]) - set(covered))
    if others:
        page.p(
            f"No position covariance (so no consistency check) from: {', '.join(others)}.",
            cls="note",
        )


def sensitivity_curves(group_stats: pd.DataFrame) -> pd.DataFrame | None:
    """Median against the a priori covariance scale, for a group that ran at least two scales."""
    # a solution scored from a file (python -m simbench score) has no estimator class and no settings
    defaults = {
        name: config_defaults(name).get("prior_scale")
        for name in group_stats["estimator"].unique()
        if name in registered()
    }
    scaled = group_stats[group_stats["estimator"].map(defaults).notna()]
    if override_value(scaled["overrides"], "prior_scale", None).notna().sum() < 2:
        return None
    scale = pd.concat(
        [override_value(rows["overrides"], "prior_scale", defaults[name]) for name, rows in scaled.groupby("estimator")]
    ).astype(float)
    curves = scaled.assign(scale=scale)
    return curves[["estimator", "scale", "horizontal_median_ref", "ci_low", "ci_high"]]
