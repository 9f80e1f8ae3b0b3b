"""Estimator variants as typed data: the settings of a result that differ from its ``Config`` defaults.

Every result row carries its estimator's overrides as a canonical JSON object
in the ``overrides`` column (sorted keys, JSON scalars; ``{}`` for the
defaults), relative to the estimator's ``Config`` dataclass defaults under the
row's ``gnss_model`` preset (:func:`simbench.runs.compose.preset_estimator_config`),
not to any estimator YAML file: an unmodified run under either preset has
none. Claims, tables and the report read settings from that column with
:func:`override_value` and pick default rows with :func:`is_default`; the
``variant`` column (:func:`variant_label`, e.g. ``window=5``) is only a label
for tables and figures and is never parsed.
"""

from __future__ import annotations

import dataclasses
import json
from enum import Enum
from typing import Any

import pandas as pd

import estimators

#: The ``overrides`` value of a result with every setting at its default.
NO_OVERRIDES = "{}"


def overrides_of(config: Any, defaults: Any = None) -> dict[str, Any]:
    """The fields of a typed estimator config that differ from its defaults.

    Parameters
    ----------
    config : dataclass instance
        An estimator ``Config`` (as :func:`simbench.typed.to_typed` returns it).
    defaults : dataclass instance of the same type, optional
        What ``config`` is compared with; None: its dataclass defaults.

    Returns
    -------
    dict
        Field name to value, as JSON scalars (an Enum becomes its YAML word, a
        tuple a list); empty when every field has its default.
    """
    if defaults is None:
        defaults = type(config)()
    return {
        f.name: _json_value(getattr(config, f.name))
        for f in dataclasses.fields(config)
        if getattr(config, f.name) != getattr(defaults, f.name)
    }


def overrides_json(overrides: dict[str, Any]) -> str:
    """The canonical JSON text of ``overrides`` (sorted keys, no spaces): the ``overrides`` column."""
    return json.dumps(overrides, sort_keys=True, separators=(",", ":"))


def variant_label(overrides: dict[str, Any]) -> str:
    """Human label of a variant for tables and figures: ``k=v`` pairs by key, ``''`` for the defaults."""
    return ",".join(f"{key}={value}" for key, value in sorted(overrides.items()))


#: Longest value text in a :func:`display_names` tag; longer values (lists, paths) are cut with '…'.
TAG_VALUE_CHARS = 12


def display_names(frame: pd.DataFrame) -> pd.Series:
    """The name of each row's estimator variant in figures and tables: short, and unique per variant.

    An estimator that ran in one variant is its name (``dcs``); one that ran in several is
    ``name[tag]``, the tag holding what tells them apart: the ``gnss_model`` preset where
    the variants' presets differ, then the explicit overrides as ``k=v`` (``dcs[prior_scale=10]``,
    ``l2[dissertation]``), never the full override text.

    Parameters
    ----------
    frame : pandas.DataFrame
        Rows with ``estimator`` and, where present, ``gnss_model`` and ``overrides`` columns.

    Returns
    -------
    pandas.Series of str
        Same index as ``frame``.
    """
    if frame.empty:
        return pd.Series([], index=frame.index, dtype=object)
    model = frame["gnss_model"].fillna("").astype(str) if "gnss_model" in frame else pd.Series("", index=frame.index)
    overrides = (
        frame["overrides"].fillna(NO_OVERRIDES) if "overrides" in frame else pd.Series(NO_OVERRIDES, index=frame.index)
    )
    keys = pd.DataFrame({"estimator": frame["estimator"].astype(str), "model": model, "overrides": overrides})
    variants = keys.drop_duplicates()
    several = variants.groupby("estimator").size() > 1
    models = variants.groupby("estimator")["model"].nunique() > 1
    texts: dict[tuple[str, str, str], str] = {}
    for name, preset, text in variants.itertuples(index=False):
        parts = [preset] if models[name] and preset else []
        parts += [f"{k}={_short(v)}" for k, v in sorted(json.loads(text).items())]
        texts[(name, preset, text)] = f"{name}[{','.join(parts)}]" if several[name] and parts else name
    return pd.Series([texts[k] for k in keys.itertuples(index=False)], index=frame.index, dtype=object)


def _short(value: Any) -> str:
    text = json.dumps(value) if isinstance(value, (list, dict)) else str(value)
    return text if len(text) <= TAG_VALUE_CHARS else text[: TAG_VALUE_CHARS - 1] + "…"


def is_default(overrides: pd.Series) -> pd.Series:
    """True for rows whose estimator ran with every setting at its default.

    Parameters
    ----------
    overrides : Series of str
        The ``overrides`` column.
    """
    return overrides.fillna(NO_OVERRIDES) == NO_OVERRIDES


def override_value(overrides: pd.Series, key: str, default: Any) -> pd.Series:
    """One setting per row, read from the ``overrides`` column: the override where given, else ``default``.

    Parameters
    ----------
    overrides : Series of str
        The ``overrides`` column.
    key : str
        Config field name, e.g. ``window``.
    default : scalar
        Its value where the row does not override it (see :func:`config_defaults`).

    Returns
    -------
    Series
        Same index as ``overrides``, dtype inferred from the values (int, float, bool or object).
    """
    values = [json.loads(text).get(key, default) for text in overrides.fillna(NO_OVERRIDES)]
    return pd.Series(values, index=overrides.index, name=key).infer_objects()


def config_defaults(estimator: str) -> dict[str, Any]:
    """Every field of the ``Config`` dataclass of ``estimator`` with its default, as JSON scalars.

    Raises
    ------
    SimbenchError
        For an unknown estimator name.
    """
    defaults = estimators.get(estimator).Config()
    return {f.name: _json_value(getattr(defaults, f.name)) for f in dataclasses.fields(defaults)}


def _json_value(value: Any) -> Any:
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, tuple):
        return list(value)
    return value
