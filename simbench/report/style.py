"""How the report names, groups, colours and prints its numbers.

Estimators are grouped into families by the module that defines them
(:data:`FAMILY_OF_MODULE`); each family has one hue (:data:`FAMILY_COLORMAPS`) and its members
differ by shade and line style, so 16 curves stay apart and a reader sees the
family at a glance. Numbers are printed with 3 significant digits everywhere
(:func:`sig3`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from matplotlib import colormaps

from estimators import registered

#: Families in the order the report lists them.
FAMILIES = ("batch", "incremental", "filter", "GNSS/INS", "baselines", "other")
#: Family of each built-in estimator module; a plug-in or a scored solution is ``other``.
FAMILY_OF_MODULE: dict[str, str] = {
    "estimators.batch_robust": "batch",
    "estimators.bce": "batch",
    "estimators.incremental": "incremental",
    "estimators.ice": "incremental",
    "estimators.ekf_ppp": "filter",
    "estimators.gnss_ins_ekf": "GNSS/INS",
    "estimators.crt_lss": "GNSS/INS",
    "estimators.oracle": "baselines",
    "estimators.rtklib_spp": "baselines",
}
#: One matplotlib colormap (a hue) per family; members take shades from its darker half.
FAMILY_COLORMAPS: dict[str, str] = {
    "batch": "Blues",
    "incremental": "Greens",
    "filter": "Oranges",
    "GNSS/INS": "Purples",
    "baselines": "Greys",
    "other": "copper",
}
#: Line styles of the members of one family, in order.
LINESTYLES: tuple[Any, ...] = ("-", "--", ":", "-.", (0, (5, 1, 1, 1, 1, 1)), (0, (8, 2)))
#: How an undefined percentile (availability below it: ``inf``) is printed.
UNDEFINED = "—"


def families(estimators: Iterable[str]) -> dict[str, str]:
    """The family (one of :data:`FAMILIES`) of each estimator name: that of its module
    (:data:`FAMILY_OF_MODULE`), ``other`` for a plug-in or a scored solution. The registry is read
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
    return {
        name: FAMILY_OF_MODULE.get(known[name].__module__, "other") if name in known else "other" for name in estimators
    }


def curve_styles(names: Mapping[str, str]) -> dict[str, dict[str, Any]]:
    """A ``color`` and ``linestyle`` per curve: the family's hue, a shade and line style per member.

    Parameters
    ----------
    names : mapping of str to str
        Curve name (e.g. ``dcs[prior_scale=10]``) to its estimator name (``dcs``).

    Returns
    -------
    dict
        Curve name to matplotlib keyword arguments; the same set of names always gets the same styles.
    """
    members: dict[str, list[str]] = {}
    of = families(set(names.values()))
    for name in sorted(names):
        members.setdefault(of[names[name]], []).append(name)
    out: dict[str, dict[str, Any]] = {}
    for fam, curves in members.items():
        cmap = colormaps[FAMILY_COLORMAPS[fam]]
        # dark to mid shades: the light end of a sequential map vanishes on white
        shades = np.linspace(0.95, 0.55, max(len(curves), 2))
        for i, name in enumerate(curves):
            out[name] = {"color": cmap(shades[i]), "linestyle": LINESTYLES[i % len(LINESTYLES)]}
    return out


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
