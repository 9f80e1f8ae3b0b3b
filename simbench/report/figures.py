"""Publication-quality figures from the results tables.

Every figure is drawn without a title (the report's HTML carries it as a
caption, so a figure can go into a paper as it is) and written in each of the
asked formats (PNG at :data:`PNG_DPI` for the page, PDF or SVG with TrueType
fonts for a paper), at the size of the ``report.style`` preset in use
(:func:`simbench.report.style.use_style`). Each estimator keeps one colour,
line style and marker in every figure (:mod:`simbench.report.style`).
Error distributions are drawn over all reference epochs
(:func:`simbench.analysis.metrics.reference_ecdf`): a curve ends at its
estimator's availability, below 1 when it left epochs unsolved. The
comparison figure (:func:`ecdf_figure`) names every estimator in one legend
in leaderboard order; :func:`family_ecdf_figure` is the per-family view.

Every figure function returns a :class:`FigureFile`: the files written, the
series names read back from the drawn figure (legend entries, category labels
and panel titles) and each legend entry's colour, line style and marker,
which the report writes beside the figures (``figures.json``) so what a figure
shows can be checked without pixels.
"""

from __future__ import annotations

import io
import logging
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, cast

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_hex
from matplotlib.lines import Line2D
from matplotlib.ticker import LogFormatterSciNotation, LogLocator, MaxNLocator
from matplotlib.transforms import Affine2D, Bbox
from PIL import Image

from simbench.analysis.metrics import reference_ecdf
from simbench.analysis.validation import ValidationSample, cn0_by_elevation
from simbench.contract import write_bytes
from simbench.errors import SimbenchError
from simbench.report.style import LABELS_MARK, PRESETS, TRUETYPE, by_family, curve_styles, preset, sig3
from simbench.runs.checks import ReportFormat as Format

# TrueType embedding subsets each font with fontTools, which logs every table it prunes at INFO: under
# Hydra's INFO root logger, about 70 lines per PDF on the terminal
logging.getLogger("fontTools").setLevel(logging.WARNING)

METRIC_LABELS = {"horizontal": "horizontal error [m]", "error_3d": "3-D error [m]"}
#: More curves than this and the trajectory becomes small multiples, one panel per family.
SMALL_MULTIPLES_ABOVE = 8
#: What a figure says about curves that end below 1.
REFERENCE_NOTE = "over all reference epochs: a curve ends at its availability, unsolved epochs counting as missed"
#: Resolution of the PNG files [dots per inch]; PDF is vector.
PNG_DPI = 300
#: Margin around the drawn area of a saved figure [inch].
PAD_INCHES = 0.05
#: Room added around a figure's axes before it is drawn (left, bottom, right, top) [inch]: tick labels
#: and legends beside the axes then fall on the canvas, and the drawn area is cropped from it.
MARGIN_INCHES = (1.0, 0.8, 3.0, 0.4)
#: Height of a panel title over its axes [axes fraction]. Given explicitly, matplotlib places the title
#: there instead of measuring every tick label of the axes to clear them (about a third of a
#: small-multiples figure's time); no panel has tick labels on top.
PANEL_TITLE_Y = 1.0


@dataclass(frozen=True)
class FigureFile:
    """A written figure.

    Attributes
    ----------
    files : tuple of Path
        One file per format, the PNG (shown in the HTML) first.
    title : str
        The caption the report prints under it.
    series : tuple of str
        Names drawn: legend entries, category labels and panel titles (without availability
        or median suffixes), read back from the figure.
    legend : tuple of str
        The legend entries as drawn (with availability and median where the figure gives them).
    styles : dict
        Series name to its drawn ``color`` (hex), ``linestyle`` and ``marker`` (:func:`legend_styles`).
    """

    files: tuple[Path, ...]
    title: str
    series: tuple[str, ...]
    legend: tuple[str, ...] = ()
    styles: dict[str, dict[str, str]] = field(default_factory=dict)

    @property
    def path(self) -> Path:
        """The file the HTML page shows (PNG)."""
        return self.files[0]


def estimator_of(name: str) -> str:
    """The estimator of a curve name: ``dcs[prior_scale=10]`` and ``oracle†`` give ``dcs`` and ``oracle``."""
    return name.split("[")[0].rstrip(LABELS_MARK)


def estimator_styles(names: Iterable[str]) -> dict[str, dict]:
    """A distinct ``color`` and ``linestyle`` per curve name (:func:`simbench.report.style.curve_styles`)."""
    unique = names.unique() if isinstance(names, pd.Series) else set(names)  # a column has a row per epoch
    return curve_styles({n: estimator_of(n) for n in unique})


def availability_text(fraction: float) -> str:
    """``36 % solved`` (whole percent; '< 1 %' and '> 99 %' rather than rounding to 0 or 100)."""
    if 0 < fraction < 0.01:
        return "< 1 % solved"
    if 0.99 < fraction < 1:
        return "> 99 % solved"
    return f"{fraction:.0%} solved".replace("%", " %")


def _references(epochs: pd.DataFrame, n_reference: Mapping[str, int]) -> dict[str, int]:
    missing = sorted(set(epochs["estimator"].unique()) - set(n_reference))
    if missing:
        raise SimbenchError(
            "n_reference",
            f"has no reference epoch count for {', '.join(missing)}",
            "pass the summed n_epochs of each estimator's jobs",
        )
    return {name: int(n_reference[name]) for name in epochs["estimator"].unique()}


def _panels(names: Sequence[str]) -> list[tuple[str, list[str]]]:
    """One panel per family (titled by it), families in :data:`~simbench.report.style.FAMILIES` order."""
    return list(by_family({n: estimator_of(n) for n in names}).items())


def figsize(width: float, height: float) -> tuple[float, float]:
    """A figure's size [inch] for the preset in use: ``width`` x ``height`` on the page (``screen``),
    scaled to a paper's column (:data:`~simbench.report.style.PRESETS`)."""
    scale = preset().width_in / PRESETS["screen"].width_in
    return width * scale, height * scale


def grid_axes(
    n: int, width: float, height: float, ncols: int = 2, sharex: bool = False, sharey: bool = False
) -> tuple[plt.Figure, list[plt.Axes]]:
    """``n`` axes in rows of ``ncols`` (one column for a single panel), each ``width`` x ``height`` inches
    on the page (:func:`figsize`)."""
    cols = 1 if n == 1 else ncols
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(
        rows,
        cols,
        figsize=figsize(width * cols, height * rows),
        dpi=PNG_DPI,
        squeeze=False,
        sharex=sharex,
        sharey=sharey,
    )
    # room for each panel's title and tick labels; the saved figure is cropped to what is drawn
    fig.subplots_adjust(hspace=0.45 if rows > 1 else 0.2, wspace=0.3)
    flat = list(axes.ravel())
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


@dataclass(frozen=True)
class Curves:
    """The ECDFs of a group over its reference epochs: per curve name, per metric, (errors, fractions)."""

    curves: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]]
    metrics: list[str]
    order: list[str]  #: leaderboard order: by median of the first metric, then of the second, then name

    @classmethod
    def of(
        cls,
        epochs: pd.DataFrame,
        metrics: Sequence[str],
        n_reference: Mapping[str, int],
        medians: Mapping[str, Mapping[str, float]],
    ) -> Curves:
        counts = _references(epochs, n_reference)
        curves: dict[str, dict[str, tuple[np.ndarray, np.ndarray]]] = {}
        for name, group in epochs.groupby("estimator", observed=True):
            for metric in metrics:
                x, p = reference_ecdf(group[metric].to_numpy(float), counts[str(name)])
                if x.size:
                    curves.setdefault(str(name), {})[metric] = (x, p)

        def rank(name: str) -> tuple:
            # the oracle (labels mark) last, apart, as in the leaderboard: a floor, not a competitor
            keys = [medians.get(m, {}).get(name, np.inf) for m in metrics]
            return (name.endswith(LABELS_MARK), *keys, -_solved(curves[name]), name)

        return cls(curves, list(metrics), sorted(curves, key=rank))

    def left(self) -> float:
        """Left end of the error axes [m]: the decade holding the smallest curve's 1st percentile."""
        firsts = [x[np.searchsorted(p, 0.01 * p[-1])] for c in self.curves.values() for x, p in c.values() if x.size]
        positive = [v for v in firsts if v > 0]
        return 10.0 ** np.floor(np.log10(min(positive))) if positive else 1e-3

    def draw(self, ax: plt.Axes, name: str, metric: str, style: Mapping[str, Any], label: str = "") -> None:
        """One curve, a dot where it stops (its availability)."""
        if metric not in self.curves[name]:
            return
        x, p = self.curves[name][metric]
        x = np.maximum(x, self.left())
        ax.step(np.r_[x[0], x], np.r_[0.0, p], where="post", label=label, **{"lw": preset().font_pt / 7.5, **style})
        ax.plot(x[-1], p[-1], marker="o", ms=3, color=style["color"])


def ecdf_figure(
    epochs: pd.DataFrame,
    metrics: str | Sequence[str],
    path: str | Path,
    title: str,
    n_reference: Mapping[str, int],
    medians: Mapping[str, Mapping[str, float]] | None = None,
    formats: Sequence[Format] = ("png",),
) -> FigureFile:
    """The comparison figure: ECDF of each error metric over all reference epochs, every estimator in
    one panel per metric, named in one legend beside them in leaderboard order, log error axes.

    Parameters
    ----------
    epochs : pandas.DataFrame
        ``epochs.parquet`` rows (columns ``estimator``, the curve name, and each metric): the solved epochs.
    metrics : str or sequence of str
        ``horizontal`` and/or ``error_3d``, one panel each, side by side on one scale.
    path : path-like
        PNG to write (other formats beside it).
    title : str
        Caption for the report (not drawn).
    n_reference : mapping of curve name to int
        Reference epochs of that curve's jobs in ``epochs`` (the summed ``n_epochs``): the
        denominator, so a curve ends at the estimator's availability (the same in every panel).
    medians : mapping of metric to (mapping of curve name to float), optional
        The leaderboard's medians [m]: they order the legend, and on the page (``screen`` preset)
        the legend prints them; '—' for inf (availability below 50 %). A paper preset's legend
        names the estimator and, below 100 %, its availability.
    formats : sequence of str
        File formats to write.
    """
    metrics = [metrics] if isinstance(metrics, str) else list(metrics)
    if preset().name == "single":  # a 3.5 in column holds one panel and its legend: the first metric
        metrics = metrics[:1]
    given = medians or {}
    data = Curves.of(epochs, metrics, n_reference, given)
    styles = estimator_styles(data.order)
    paper = preset().name != "screen"
    size = (5.2, 4.4) if preset().name == "single" else (3.4, 3.0)  # single: one panel, the column's width
    fig, axes = grid_axes(len(metrics), *size, ncols=len(metrics), sharex=True, sharey=True)
    for i, (ax, metric) in enumerate(zip(axes, metrics)):
        for name in data.order:
            shown = None if medians is None or paper else [given.get(m, {}).get(name, np.nan) for m in metrics]
            label = _ecdf_label(name, _solved(data.curves[name]), shown, brief=paper) if i == 0 else ""
            data.draw(ax, name, metric, styles[name], label)
        _ecdf_axes(ax, metric, data.left())
        ax.label_outer()  # shared axes: the outer panels carry the labels
    handles, labels = axes[0].get_legend_handles_labels()
    # one legend for the figure, beside the last panel, in leaderboard order
    axes[-1].legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    return save_figure(fig, path, f"{title} ({REFERENCE_NOTE})", formats)


def family_ecdf_figure(
    epochs: pd.DataFrame,
    metric: str,
    path: str | Path,
    title: str,
    n_reference: Mapping[str, int],
    medians: Mapping[str, float] | None = None,
    formats: Sequence[Format] = ("png",),
) -> FigureFile:
    """The secondary view: one ECDF panel per family, its members named, the other families in grey.

    Parameters are those of :func:`ecdf_figure` for one ``metric``; ``medians`` only orders the legends.
    """
    data = Curves.of(epochs, [metric], n_reference, {metric: medians or {}})
    styles = estimator_styles(data.order)
    panels = _panels(data.order)
    fig, axes = grid_axes(len(panels), 2.6, 2.2, ncols=3, sharex=True, sharey=True)
    for ax, (panel, members) in zip(axes, panels):
        for other in data.order:  # every panel on one scale: the other families in grey, unnamed
            if other not in members:
                data.draw(ax, other, metric, {"color": "0.85", "linestyle": "-", "lw": 0.6, "marker": ""})
        for name in (n for n in data.order if n in members):
            data.draw(ax, name, metric, styles[name], name)
        _ecdf_axes(ax, metric, data.left())
        ax.set_title(panel, y=PANEL_TITLE_Y)
        ax.legend(loc="lower right", frameon=True, fontsize="small")
        ax.label_outer()
    for ax in axes[-3:]:  # the last row, and a panel over an empty place, keep their error axis labelled
        ax.tick_params(labelbottom=True)
        ax.set_xlabel(METRIC_LABELS.get(metric, metric))
    return save_figure(fig, path, f"{title} ({REFERENCE_NOTE}; grey: the other families)", formats)


def _ecdf_axes(ax: plt.Axes, metric: str, left: float) -> None:
    ax.set_xscale("log")
    log_ticks(ax.xaxis)
    ax.set_xlim(left=left)
    ax.set_xlabel(METRIC_LABELS.get(metric, metric))
    ax.set_ylabel("fraction of reference epochs")
    ax.set_ylim(0, 1.01)
    ax.grid(True, which="major", alpha=0.3)


def _solved(curves: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> float:
    """A curve's availability: where its ECDF ends (the same for every metric)."""
    return float(next(iter(curves.values()))[1][-1])


def _ecdf_label(name: str, availability: float, medians: Sequence[float] | None, brief: bool = False) -> str:
    """``dcs (98 % solved, median 2.3 / 3.1 m)``: availability, then the median of each metric.

    ``brief``: the name alone, with the availability only below 100 % (a paper's legend).
    """
    if brief:
        return name if availability >= 1 else f"{name} ({availability_text(availability)})"
    if medians is None:
        return f"{name} ({availability_text(availability)})"
    return f"{name} ({availability_text(availability)}, median {' / '.join(sig3(m) for m in medians)} m)"


#: Up to this many decades on a log axis are each ticked and labelled (matplotlib skips some on a short axis).
LOG_DECADES_MAX = 12


def log_ticks(axis: Any) -> None:
    """A log axis labelled by matplotlib's own locator and formatter: decades as 10^k, and the 2-9 x 10^k
    ticks labelled only where the axis spans few decades (its ``minor_thresholds``), so labels never run
    together; minor ticks unlabelled otherwise."""
    axis.set_major_locator(LogLocator(base=10.0, numticks=LOG_DECADES_MAX))  # every decade, also on a small axis
    # minor ticks at 2 and 5 x 10^k only: each tick is drawn (most of a small figure's time) and 2, 5 guide the eye
    axis.set_minor_locator(LogLocator(base=10.0, subs=(2.0, 5.0)))
    axis.set_major_formatter(LogFormatterSciNotation(base=10.0))
    axis.set_minor_formatter(LogFormatterSciNotation(base=10.0, labelOnlyBase=False, minor_thresholds=(1, 0.4)))


def _log_x_if_wide(ax: plt.Axes, values: np.ndarray) -> None:
    """Log x axis when the values span more than a decade and a half, else linear from zero."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v) & (v > 0)]
    if len(v) and v.max() / v.min() > 30:
        ax.set_xscale("log")
        log_ticks(ax.xaxis)
    else:
        ax.set_xlim(left=0)


def legend_texts(fig: plt.Figure) -> tuple[str, ...]:
    """Every legend entry of a figure as drawn, figure legends first."""
    texts: list[str] = []
    for legend in [*fig.legends, *(ax.get_legend() for ax in fig.axes)]:
        if legend is not None:
            texts += [t.get_text() for t in legend.get_texts()]
    return tuple(texts)


def style_record(styles: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, str]]:
    """``figures.json``'s record of series styles drawn without a legend (e.g. boxes named on an axis)."""
    return {
        name: {
            "color": to_hex(s["color"]),
            "linestyle": str(s.get("linestyle", "")),
            "marker": str(s.get("marker", "")),
        }
        for name, s in styles.items()
    }


def legend_styles(fig: plt.Figure) -> dict[str, dict[str, str]]:
    """Colour (hex), line style and marker of each named legend entry, read from the drawn handles.

    The name is the entry's text before `` (``; the first legend naming a series wins.
    """
    out: dict[str, dict[str, str]] = {}
    for legend in [*fig.legends, *(ax.get_legend() for ax in fig.axes)]:
        if legend is None:
            continue
        for text, handle in zip(legend.get_texts(), legend.legend_handles):
            name = text.get_text().split(" (")[0].strip()
            if name and isinstance(handle, Line2D) and name not in out:
                out[name] = {
                    "color": to_hex(handle.get_color()),
                    "linestyle": str(handle.get_linestyle()),
                    "marker": str(handle.get_marker()),
                }
    return out


def drawn_series(fig: plt.Figure) -> tuple[str, ...]:
    """The names a figure shows: legend entries, category tick labels and panel titles, in order.

    A legend entry ``dcs (98 % solved, median 2.3 m)`` and a tick label ``dcs\n98 % solved`` both give ``dcs``.
    """
    texts = list(legend_texts(fig))
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        texts.append(ax.get_title())
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_major_formatter().__class__.__name__ == "StrCategoryFormatter":
                texts += [t.get_text() for t in axis.get_ticklabels()]
    names = [t.split("\n")[0].split(" (")[0].strip() for t in texts]
    return tuple(dict.fromkeys(n for n in names if n))


def save_figure(fig: plt.Figure, path: str | Path, title: str, formats: Sequence[Format] = ("png",)) -> FigureFile:
    """Write ``fig`` as ``path`` (PNG) and in the other ``formats`` beside it, each cropped to what is
    drawn (legends beside the axes included); close it.

    The figure is drawn once: the PNG is that canvas cropped to the drawn area when the area lies on
    it (``bbox_inches="tight"`` would draw it twice, once to measure, and the report's time is
    mostly drawing). A vector format is saved with that area; a figure drawn past its canvas (more
    than :data:`MARGIN_INCHES` beside its axes) is measured and drawn again by ``bbox_inches="tight"``.
    """
    path = Path(path).with_suffix(".png")
    _add_margin(fig, MARGIN_INCHES)
    canvas = cast(FigureCanvasAgg, fig.canvas)  # matplotlib.use("Agg") above
    canvas.draw()
    series, legend, styles = drawn_series(fig), legend_texts(fig), legend_styles(fig)
    rgba = np.asarray(canvas.buffer_rgba())
    # the drawn area from the pixels: Figure.get_tightbbox would lay out every tick and text again
    # one 32-bit word per RGBA pixel: a quarter of the comparisons, and no reduction over 4-byte rows
    pixels = rgba.view(np.uint32)[..., 0]
    inked = pixels != pixels[0, 0]
    inked[[0, -1], [0, -1]] |= ~inked.any()  # a blank figure keeps its whole canvas
    rows, cols = np.flatnonzero(inked.any(axis=1)), np.flatnonzero(inked.any(axis=0))
    pad = int(np.ceil(PAD_INCHES * fig.dpi))
    top, left = max(rows[0] - pad, 0), max(cols[0] - pad, 0)
    bottom, right = min(rows[-1] + 1 + pad, rgba.shape[0]), min(cols[-1] + 1 + pad, rgba.shape[1])
    on_canvas = rows[0] > 0 and cols[0] > 0 and rows[-1] < rgba.shape[0] - 1 and cols[-1] < rgba.shape[1] - 1
    # the same area in inches from the figure's lower left corner, for the other formats
    box = Bbox.from_extents(left, rgba.shape[0] - bottom, right, rgba.shape[0] - top).transformed(
        Affine2D().scale(1.0 / fig.dpi)
    )
    files = []
    for fmt in dict.fromkeys(["png", *formats]):
        buffer = io.BytesIO()
        if fmt == "png" and on_canvas:
            # zlib level 1: about 40 % less encoding time than the default 6, files 5-20 % larger; RGB,
            # not RGBA: the canvas is opaque, and a fourth channel is 20 % more to encode
            Image.fromarray(rgba[top:bottom, left:right, :3]).save(
                buffer, format="png", compress_level=1, dpi=(fig.dpi, fig.dpi)
            )
        else:
            # what is drawn past the canvas is measured by matplotlib (one more drawing)
            area = box if on_canvas else "tight"
            with matplotlib.rc_context(cast(Any, TRUETYPE)):  # whatever the preset: a vector file never embeds Type 3
                fig.savefig(buffer, format=fmt, dpi=PNG_DPI, bbox_inches=area, pad_inches=PAD_INCHES)
        target = path.with_suffix(f".{fmt}")
        write_bytes(target, buffer.getvalue())  # atomic: two reports of one run never mix their figures
        files.append(target)
    plt.close(fig)
    return FigureFile(tuple(files), title, series, legend, styles)


def _add_margin(fig: plt.Figure, margin: tuple[float, float, float, float]) -> None:
    """Grow the canvas by ``margin`` (left, bottom, right, top) [inch], every axes keeping its size and
    place in inches, so what is drawn past the axes (tick labels, legends beside them) lands on it."""
    width, height = fig.get_size_inches()
    left, bottom, right, top = margin
    grown_w, grown_h = width + left + right, height + bottom + top
    boxes = [ax.get_position() for ax in fig.axes]
    fig.set_size_inches(grown_w, grown_h)
    for ax, box in zip(fig.axes, boxes):
        ax.set_position(
            (
                (box.x0 * width + left) / grown_w,
                (box.y0 * height + bottom) / grown_h,
                box.width * width / grown_w,
                box.height * height / grown_h,
            )
        )


def box_figure(
    epochs: pd.DataFrame,
    path: str | Path,
    title: str,
    n_reference: Mapping[str, int],
    metric: str = "horizontal",
    formats: Sequence[Format] = ("png",),
    order: Sequence[str] = (),
) -> FigureFile:
    """Box plot of the solved epochs' errors per estimator (dissertation Fig. 5.3.2), log scale.

    Each label gives the estimator's availability (solved / ``n_reference`` epochs,
    as in :func:`ecdf_figure`): the boxes describe only the epochs it solved. Boxes in ``order``
    (the leaderboard's), names not in it after them by their median.
    """
    counts = _references(epochs, n_reference)
    present = [str(n) for n in epochs["estimator"].unique()]
    rest = sorted(set(present) - set(order), key=lambda n: np.nanmedian(epochs.loc[epochs["estimator"] == n, metric]))
    order = [n for n in order if n in present] + rest
    styles = estimator_styles(order)
    data = [epochs.loc[epochs["estimator"] == n, metric].dropna().to_numpy() for n in order]
    labels = [f"{n}\n{availability_text(len(d) / counts[n])}" for n, d in zip(order, data)]
    fig, ax = plt.subplots(figsize=figsize(max(4.0, 0.55 * len(order) + 1.5), 3.6), dpi=PNG_DPI)
    boxes = ax.boxplot(data, whis=(5, 95), showfliers=False, medianprops={"color": "black"}, patch_artist=True)
    for patch, name in zip(boxes["boxes"], order):
        patch.set_facecolor(styles[name]["color"])
        patch.set_alpha(0.6)
    ax.set_xticks(range(1, len(order) + 1), labels, rotation=35, ha="right")
    ax.set_yscale("log")
    log_ticks(ax.yaxis)
    ax.set_ylabel(METRIC_LABELS.get(metric, metric))
    ax.grid(True, axis="y", which="both", alpha=0.3)
    series = tuple(order)
    figure = save_figure(fig, path, f"{title} (solved epochs only; box: quartiles, whiskers: 5-95 %)", formats)
    return replace(figure, series=series, styles=style_record(styles))


def sensitivity_figure(
    curves: pd.DataFrame, path: str | Path, title: str, formats: Sequence[Format] = ("png",)
) -> FigureFile:
    """Median error against the a priori covariance scale per estimator (dissertation Fig. 5.3.7).

    ``curves`` has columns estimator, scale, horizontal_median_ref (over reference epochs; a
    scale whose median is undefined, inf, is left out), ci_low, ci_high.
    """
    fig, ax = plt.subplots(figsize=figsize(5.6, 3.6), dpi=PNG_DPI)
    styles = estimator_styles(curves["estimator"])
    for name, group in curves.groupby("estimator"):
        group = group[np.isfinite(group["horizontal_median_ref"])].sort_values("scale")
        median = group["horizontal_median_ref"]
        ax.errorbar(
            group["scale"],
            median,
            yerr=[median - group["ci_low"], group["ci_high"] - median],
            capsize=3,
            label=name,
            **styles[str(name)],
        )
    ax.set_xscale("log")
    log_ticks(ax.xaxis)
    ax.set_xlabel("a priori covariance scale s")
    ax.set_ylabel("median horizontal error [m]\n(over reference epochs)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return save_figure(fig, path, f"{title} (per-seed medians: mean and 95 % CI over seeds)", formats)


def runtime_figure(
    stats: pd.DataFrame, path: str | Path, title: str, formats: Sequence[Format] = ("png",)
) -> FigureFile:
    """Run time per observation and median per-epoch update time per estimator (Figs. 5.3.8, 7.3.3).

    ``stats`` has one row per curve: ``estimator`` (the curve's short name), ``time_per_obs_s``
    and ``update_median_s`` [s].
    """
    stats = stats.sort_values("time_per_obs_s")
    styles = estimator_styles(stats["estimator"])
    colors = [styles[n]["color"] for n in stats["estimator"]]
    fig, axes = plt.subplots(1, 2, figsize=figsize(8.0, 0.9 + 0.22 * len(stats)), dpi=PNG_DPI, sharey=True)
    labels = list(stats["estimator"])
    axes[0].barh(labels, stats["time_per_obs_s"] * 1e6, color=colors)
    axes[0].set_xlabel("run time per observation [us]")
    axes[1].barh(labels, stats["update_median_s"] * 1e3, color=colors)
    axes[1].set_xlabel("median per-epoch update [ms]")
    for ax, values in zip(axes, (stats["time_per_obs_s"], stats["update_median_s"])):
        _log_x_if_wide(ax, values.to_numpy())
        ax.grid(True, axis="x", which="both", alpha=0.3)
        ax.tick_params(axis="y", labelsize=7)
    return save_figure(fig, path, title, formats)


def mixture_evolution_figure(
    history: list[dict],
    path: str | Path,
    title: str,
    xlabel: str = "iteration",
    formats: Sequence[Format] = ("png",),
) -> FigureFile:
    """Component standard deviations of the learned noise mixture per iteration (dissertation Fig. 5.3.3).

    ``history`` holds one record per iteration (or ICE adaptation, ``xlabel``) with ``mixture`` =
    {weights, covariances (K, D, D)}; the first two dimensions are the code and phase residuals [m].
    Marker area is proportional to weight.
    """
    fig, axes = plt.subplots(1, 2, figsize=figsize(8.0, 3.2), dpi=PNG_DPI, sharex=True)
    iterations, weights, sigmas = [], [], []
    for record in history:
        mix = record.get("mixture") or {}
        cov = np.asarray(mix.get("covariances", []), float)
        if cov.ndim != 3 or cov.shape[1] < 2:
            continue
        weights.append(np.asarray(mix["weights"], float))
        iterations.append(np.full(len(weights[-1]), record.get("iteration", 0)))
        sigmas.append(np.sqrt(np.stack([cov[:, 0, 0], cov[:, 1, 1]], axis=1)))
    if sigmas:
        # one collection per panel, points in iteration order (one per iteration took ~1 s a figure)
        it, w, sd = np.concatenate(iterations), np.concatenate(weights), np.concatenate(sigmas)
        for ax, d in zip(axes, (0, 1)):
            ax.scatter(it, sd[:, d], s=20 + 300 * w, alpha=0.6, color="tab:blue", edgecolor="k", lw=0.4)
    for ax, label in zip(axes, ("code residual std [m]", "phase residual std [m]")):
        ax.set_yscale("log")
        log_ticks(ax.yaxis)
        ax.set_xlabel(xlabel)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    return save_figure(fig, path, f"{title} (marker area ~ component weight)", formats)


def validation_figure(
    samples: Sequence[ValidationSample],
    path: str | Path,
    title: str,
    bin_deg: float = 10.0,
    formats: Sequence[Format] = ("png",),
) -> FigureFile:
    """Sim-vs-real panels (:mod:`simbench.analysis.validation`): ECDF of the |code residual|, C/N0 median
    (and 10-90 % band) against elevation, and the distribution of tracked satellites per epoch.

    Each world keeps one colour and line style (:func:`world_styles`); a real log is drawn thicker.
    The fourth panel holds the legend.
    """
    styles = world_styles(s.name for s in samples)
    fig, grid = plt.subplots(2, 2, figsize=figsize(10.0, 7.2), dpi=PNG_DPI)
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
    log_ticks(ecdf_ax.xaxis)
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
        frameon=False,
        ncols=1 if len(samples) <= 12 else 2,
    )
    return save_figure(fig, path, title, formats)


def world_styles(names: Iterable[str]) -> dict[str, dict]:
    """A ``color`` (tab10) and line style per world name, by sorted name (worlds have no family)."""
    colors = plt.get_cmap("tab10").colors  # type: ignore[attr-defined]
    styles = ("-", "--", ":", "-.")
    return {
        name: {"color": colors[i % len(colors)], "linestyle": styles[(i // len(colors)) % len(styles)]}
        for i, name in enumerate(sorted(set(names)))
    }
