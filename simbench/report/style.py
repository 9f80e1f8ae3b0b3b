"""How the report names, groups, colours and prints its numbers.

Every estimator has one fixed colour, line style and marker, keyed by its name
(:data:`ESTIMATOR_COLORS`), so it looks the same in every figure of every
report whatever else ran. Colours come from the two palettes designed for
colour-vision deficiency, Okabe & Ito's and Paul Tol's *muted*; since no 17
colours stay apart for every reader, an estimator's family is also drawn as a
line style and marker (:data:`FAMILY_LINESTYLES`, :data:`FAMILY_MARKERS`), so
two colours a deuteranope confuses are never drawn alike. The reference
trajectory is black, a colour no estimator has. A name the table does not know
(a plug-in, a scored solution) takes a colour from :data:`OTHER_COLORS` by a
hash of its name: stable across reports, and apart from the built-in ones.

:data:`PRESETS` are the figure sizes (``report.style``): the page's, and a
single (3.5 in) or double (7 in) column of a paper. :func:`use_style` sets them
with TrueType fonts in PDF and PS and text in SVG (publishers reject Type 3).
Numbers are printed with 3 significant digits everywhere (:func:`sig3`).
"""

from __future__ import annotations

import zlib
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, cast

import matplotlib
import numpy as np

from estimators import registered
from simbench.runs.checks import check_report_style

#: Families in the order the report lists them.
FAMILIES = ("batch", "incremental", "filter", "GNSS/INS", "SPP baselines", "oracle", "other")
#: Family of the built-in estimators by package (``estimators/<family>/``), the longest matching
#: prefix of the class's module winning; a plug-in or a scored solution is ``other``. The oracle reads
#: the true error labels: an accuracy floor, a family of its own, not a batch estimator.
FAMILY_OF_PACKAGE: dict[str, str] = {
    "estimators.batch": "batch",
    "estimators.batch.oracle": "oracle",
    "estimators.incremental": "incremental",
    "estimators.filters": "filter",
    "estimators.gnss_ins": "GNSS/INS",
    "estimators.baselines": "SPP baselines",
}
#: Okabe & Ito (2008) without black: safe for the common colour-vision deficiencies.
OKABE_ITO = {
    "blue": "#0072B2",
    "vermillion": "#D55E00",
    "bluish green": "#009E73",
    "reddish purple": "#CC79A7",
    "orange": "#E69F00",
    "sky blue": "#56B4E9",
}
#: Paul Tol's muted scheme (without its pale grey), equally safe.
TOL_MUTED = {
    "indigo": "#332288",
    "rose": "#CC6677",
    "green": "#117733",
    "purple": "#AA4499",
    "wine": "#882255",
    "teal": "#44AA99",
    "olive": "#999933",
}
#: The colour of each built-in estimator. Within a family the colours come from one safe set, so members
#: differ in hue for every reader; a pair of colours that may look alike lies in two families (line style).
ESTIMATOR_COLORS: dict[str, str] = {
    "l2": OKABE_ITO["blue"],
    "dcs": OKABE_ITO["vermillion"],
    "mm": OKABE_ITO["bluish green"],
    "bce": OKABE_ITO["reddish purple"],
    "bce_ad": OKABE_ITO["orange"],
    "isam2_ppp": TOL_MUTED["indigo"],
    "isam2_dcs": TOL_MUTED["rose"],
    "isam2_mm": TOL_MUTED["green"],
    "ice": TOL_MUTED["purple"],
    "ekf_ppp": TOL_MUTED["wine"],
    "ekf_ins": TOL_MUTED["teal"],
    "iekf_ins": TOL_MUTED["olive"],
    "crt_lss": OKABE_ITO["sky blue"],
    "wls_spp": "#EE3377",  # Tol vibrant magenta
    "huber_spp": "#997700",  # Tol medium-contrast ochre
    "rtklib_spp": "#004488",  # Tol high-contrast blue
    "oracle": "#888888",  # grey: a floor, not a competitor
}
#: Colours of estimators not in :data:`ESTIMATOR_COLORS` (Tol's vibrant and light schemes), by name hash.
OTHER_COLORS = ("#EE7733", "#009988", "#CC3311", "#33BBEE", "#DDAA33", "#6699CC", "#663333", "#77AADD")
#: The reference trajectory's colour; no estimator has it.
REFERENCE_COLOR = "#000000"
#: Line style of each family (dashes in points): the family at a glance, in grey print too.
FAMILY_LINESTYLES: dict[str, Any] = {
    "batch": "-",
    "incremental": "--",
    "filter": "-.",
    "GNSS/INS": (0, (6, 1.5, 1, 1.5, 1, 1.5)),
    "SPP baselines": ":",
    "oracle": (0, (1, 1)),
    "other": (0, (3, 1, 1, 1)),
}
#: Marker of each family, drawn every few centimetres along a line.
FAMILY_MARKERS: dict[str, str] = {
    "batch": "o",
    "incremental": "s",
    "filter": "D",
    "GNSS/INS": "^",
    "SPP baselines": "v",
    "oracle": "*",
    "other": "X",
}
#: Marks an estimator that reads the true error labels (the oracle) in figure and table names.
LABELS_MARK = "†"
#: How an undefined percentile (availability below it: ``inf``) is printed.
UNDEFINED = "—"


#: TrueType fonts in PDF and PS, text as text in SVG: publishers reject Type 3 fonts (matplotlib's default).
TRUETYPE: dict[str, Any] = {"pdf.fonttype": 42, "ps.fonttype": 42, "svg.fonttype": "none"}


@dataclass(frozen=True)
class Preset:
    """A figure size (``report.style``): the width a figure is drawn for and its fonts.

    Attributes
    ----------
    name : str
    width_in : float
        Width of a full-width figure, legend included [inch] (a paper's column or text width).
    font_pt : float
        Base font size [pt]; tick and legend labels one point smaller.
    """

    name: str
    width_in: float
    font_pt: float

    def rc(self) -> dict[str, Any]:
        """matplotlib settings of this preset: fonts, and TrueType (not Type 3) in PDF, PS and SVG."""
        small = self.font_pt - 1
        return {
            "font.size": self.font_pt,
            "axes.labelsize": self.font_pt,
            "axes.titlesize": self.font_pt,
            "xtick.labelsize": small,
            "ytick.labelsize": small,
            "legend.fontsize": small,
            **TRUETYPE,
        }


#: ``report.style`` choices: the page (``screen``), a paper's single or double column.
PRESETS: dict[str, Preset] = {
    "screen": Preset("screen", 9.0, 9.0),
    "single": Preset("single", 3.5, 7.0),
    "double": Preset("double", 7.0, 8.0),
}
#: The preset the figures are drawn with now (:func:`use_style`).
_current = [PRESETS["screen"]]


def preset(name: str = "") -> Preset:
    """The preset ``name`` (``''``: the one in use), or a one-line error naming ``report.style``."""
    if not name:
        return _current[0]
    check_report_style(name)
    return PRESETS[name]


@contextmanager
def use_style(name: str = "screen") -> Iterator[Preset]:
    """Draw with the preset ``name`` (:data:`PRESETS`) inside the ``with`` block."""
    chosen = preset(name)
    _current.insert(0, chosen)
    try:
        with matplotlib.rc_context(cast(Any, chosen.rc())):
            yield chosen
    finally:
        _current.pop(0)


def families(estimators: Iterable[str]) -> dict[str, str]:
    """The family (one of :data:`FAMILIES`) of each estimator name: that of its package
    (:data:`FAMILY_OF_PACKAGE`), ``other`` for a plug-in or a scored solution. The registry is read
    once per call: it imports every estimator module.

    Parameters
    ----------
    estimators : iterable of str
        Estimator names, registered or not.

    Returns
    -------
    dict
        Name to family.
    """
    known = registered()
    return {name: family_of_module(known[name].__module__) if name in known else "other" for name in estimators}


def family_of_module(module: str) -> str:
    """The family of a built-in estimator's module (:data:`FAMILY_OF_PACKAGE`); ``other`` elsewhere."""
    parts = module.split(".")
    for end in range(len(parts), 0, -1):
        family = FAMILY_OF_PACKAGE.get(".".join(parts[:end]))
        if family is not None:
            return family
    return "other"


def estimator_color(name: str) -> str:
    """The colour of estimator ``name`` (hex): its own (:data:`ESTIMATOR_COLORS`), else one by name hash."""
    if name in ESTIMATOR_COLORS:
        return ESTIMATOR_COLORS[name]
    return OTHER_COLORS[zlib.crc32(name.encode()) % len(OTHER_COLORS)]


#: Spacing of the family markers along a line (fraction of the axes' diagonal).
MARKEVERY = 0.1
#: Dash patterns of the second, third... variant of one estimator (the first keeps its family's style).
VARIANT_LINESTYLES: tuple[Any, ...] = ((0, (8, 2)), (0, (2, 2)), (0, (8, 2, 2, 2)), (0, (4, 1)))


def curve_styles(names: Mapping[str, str]) -> dict[str, dict[str, Any]]:
    """``color``, ``linestyle`` and ``marker`` per curve: its estimator's colour, its family's line style
    and marker (:data:`FAMILY_LINESTYLES`, :data:`FAMILY_MARKERS`).

    Parameters
    ----------
    names : mapping of str to str
        Curve name (e.g. ``dcs[prior_scale=10]``) to its estimator name (``dcs``).

    Returns
    -------
    dict
        Curve name to matplotlib keyword arguments. A curve's style depends only on its estimator
        and on the other variants of that estimator (sorted by name): the variants of one estimator
        share its colour and differ in line style (:data:`VARIANT_LINESTYLES`).
    """
    of = families(set(names.values()))
    variants: dict[str, list[str]] = {}
    for curve in sorted(names):
        variants.setdefault(names[curve], []).append(curve)
    out: dict[str, dict[str, Any]] = {}
    for estimator, curves in variants.items():
        family = of[estimator]
        for i, curve in enumerate(curves):
            style = FAMILY_LINESTYLES[family] if i == 0 else VARIANT_LINESTYLES[(i - 1) % len(VARIANT_LINESTYLES)]
            out[curve] = {
                "color": estimator_color(estimator),
                "linestyle": style,
                "marker": FAMILY_MARKERS[family],
                # a marker every tenth of the axes' diagonal: a line of thousands of epochs stays a line
                "markevery": MARKEVERY,
                "markersize": 0.4 * preset().font_pt,
            }
    return out


def line_only(style: Mapping[str, Any]) -> dict[str, Any]:
    """``style`` without its marker: for a line against time, whose zigzag would carry a marker every few
    millimetres (markers are spaced along the drawn path); colour and line style still tell it apart."""
    return {k: v for k, v in style.items() if k not in ("marker", "markevery", "markersize")}


def by_family(names: Mapping[str, str]) -> dict[str, list[str]]:
    """Curve names grouped by family, families in :data:`FAMILIES` order, names sorted."""
    of = families(set(names.values()))
    grouped = {fam: sorted(n for n in names if of[names[n]] == fam) for fam in FAMILIES}
    return {fam: curves for fam, curves in grouped.items() if curves}


def sig3(value: Any) -> str:
    """A number with 3 significant digits (``2.33``, ``0.0512``, ``1.23e+04``); ``—`` for ``inf``, ``''`` for NaN."""
    if value is None:
        return ""
    v = float(value)
    if np.isnan(v):
        return ""
    if np.isinf(v):
        return UNDEFINED
    v = float(f"{v:.3g}")  # rounded first, so 99.96 prints as 100, not 100.0
    if v == 0 or 1e-3 <= abs(v) < 1e5:
        digits = max(0, 2 - int(np.floor(np.log10(abs(v))))) if v else 0
        return f"{v:.{digits}f}"
    return f"{v:.2e}"


def with_ci(value: float, low: float, high: float) -> str:
    """``2.33 [2.10, 2.51]``: a value with its CI, or the value alone when the CI is undefined."""
    text = sig3(value)
    if np.isfinite(low) and np.isfinite(high) and np.isfinite(value):
        return f"{text} [{sig3(low)}, {sig3(high)}]"
    return text
